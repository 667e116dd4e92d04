// Regions and merging (docs/production.md "Regions and merging"): `render --region`
// writes the pixels of a window of the frame - the EXR's data window, its
// display window the frame - bit for bit as the full render writes them
// (every sample is keyed by its pixel's image coordinates); `merge`
// assembles such tiles into the frame, bit for bit the full render, and
// refuses tiles that do not belong together.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "app/exr_header.h"
#include "app/merge.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A 37x23 frame: odd sizes, so neither the tiles of the render loop (16 px)
// nor the merge's tiles line up with anything.
constexpr int kW = 37, kH = 23;
const std::vector<std::string> kCommon = {"render", "-q", "--res", "37x23", "--spp", "2"};
// A ratio estimator (transfer) alone, through the Gaussian pixel filter
// (whose samples land beyond their pixel's square); and two ray-traced
// passes in layers, the first a ratio estimator too, with the Cryptomatte
// object layers.
const std::vector<std::string> kTransfer = {"-i", "transfer", "--filter", "gaussian"};
const std::vector<std::string> kLayers = {"--pass", "tr=transfer", "--pass", "ao=ao:distance=2", "--cryptomatte", "object"};

// kCommon, the config, and `extra`, whose --res or --spp replaces kCommon's.
std::vector<std::string> args(const std::string& out, std::vector<std::string> config, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> a = kCommon;
  a.insert(a.end(), config.begin(), config.end());
  for (size_t i = 0; i < extra.size(); ++i) {
    const auto at = std::find(a.begin(), a.begin() + ptrdiff_t(kCommon.size()), extra[i]);
    if (at != a.begin() + ptrdiff_t(kCommon.size()) && at[0].rfind("--", 0) == 0 && i + 1 < extra.size()) {
      at[1] = extra[++i];
      continue;
    }
    a.push_back(extra[i]);
  }
  a.push_back("-o");
  a.push_back(out);
  return a;
}

std::string regionText(int x0, int y0, int x1, int y1) {
  return std::to_string(x0) + "," + std::to_string(y0) + "," + std::to_string(x1) + "," + std::to_string(y1);
}

// Bits, not values: NaN-safe and -0 != +0.
bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every channel of `region` equals the same pixels of `full`, bit for bit;
// the region's data window is [x0, x1) x [y0, y1) and its display window
// the frame.
void expectRegionOfFull(const ReadBack& region, const ReadBack& full, int x0, int y0, int x1, int y1) {
  ASSERT_TRUE(region.ok && full.ok);
  EXPECT_EQ(region.spec.x, x0);
  EXPECT_EQ(region.spec.y, y0);
  EXPECT_EQ(region.spec.width, x1 - x0);  // the film holds the region only
  EXPECT_EQ(region.spec.height, y1 - y0);
  EXPECT_EQ(region.spec.full_x, 0);
  EXPECT_EQ(region.spec.full_y, 0);
  EXPECT_EQ(region.spec.full_width, kW);
  EXPECT_EQ(region.spec.full_height, kH);
  EXPECT_EQ(region.spec.get_string_attribute("obscura:region"), regionText(x0, y0, x1, y1));
  ASSERT_EQ(region.spec.channelnames, full.spec.channelnames);
  for (const auto& [name, plane] : full.planes) {
    const std::vector<float>& r = region.planes.at(name);
    size_t differ = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x)
        differ += !sameBits(r[size_t(y - y0) * size_t(x1 - x0) + size_t(x - x0)], plane[size_t(y) * kW + size_t(x)]);
    EXPECT_EQ(differ, 0u) << "channel " << name;
  }
}

// Four tiles of uneven sizes covering the 37x23 frame once: the top row
// split at x = 13, the bottom (from y = 9) at x = 20.
const int kTiles[4][4] = {{0, 0, 13, 9}, {13, 0, kW, 9}, {0, 9, 20, kH}, {20, 9, kW, kH}};

TEST(Regions, RegionEqualsTheFullRenderBitForBit) {
  const std::string dir = tempDir("regions_equal");
  // The region crosses the full render's 16-pixel tile borders, and is
  // itself cut into 8-pixel tiles: neither changes a pixel.
  const int x0 = 5, y0 = 3, x1 = 29, y1 = 20;
  const std::vector<CliResult> runs =
      runClis({args(dir + "/transfer.exr", kTransfer),
               args(dir + "/transfer_region.exr", kTransfer, {"--region", regionText(x0, y0, x1, y1), "--tile", "8"}),
               args(dir + "/layers.exr", kLayers),
               args(dir + "/layers_region.exr", kLayers, {"--region", regionText(x0, y0, x1, y1), "--tile", "8"})},
              dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack full = readExr(dir + "/transfer.exr");
  EXPECT_EQ(full.spec.get_string_attribute("obscura:region"), regionText(0, 0, kW, kH));
  expectRegionOfFull(readExr(dir + "/transfer_region.exr"), full, x0, y0, x1, y1);
  const ReadBack layers = readExr(dir + "/layers.exr");
  ASSERT_TRUE(layers.planes.count("tr.R") && layers.planes.count("ao.R") && layers.planes.count("CryptoObject00.R"));
  expectRegionOfFull(readExr(dir + "/layers_region.exr"), layers, x0, y0, x1, y1);
}

TEST(Regions, MergeOfFourTilesEqualsTheFullRender) {
  const std::string dir = tempDir("regions_merge");
  std::vector<std::vector<std::string>> runs = {args(dir + "/full.exr", kLayers)};
  std::vector<std::string> merge = {"merge", dir + "/merged.exr"};
  for (int i = 0; i < 4; ++i) {
    const std::string tile = dir + "/tile" + std::to_string(i) + ".exr";
    runs.push_back(args(tile, kLayers, {"--region", regionText(kTiles[i][0], kTiles[i][1], kTiles[i][2], kTiles[i][3])}));
    merge.push_back(tile);
  }
  for (const CliResult& r : runClis(runs, dir)) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const CliResult m = runCli(merge, dir + "/merge_stderr.txt");
  ASSERT_EQ(m.exitCode, 0) << m.stderrText;

  const ReadBack full = readExr(dir + "/full.exr"), merged = readExr(dir + "/merged.exr");
  ASSERT_TRUE(full.ok && merged.ok);
  EXPECT_EQ(merged.spec.x, 0);
  EXPECT_EQ(merged.spec.y, 0);
  EXPECT_EQ(merged.spec.width, kW);
  EXPECT_EQ(merged.spec.height, kH);
  EXPECT_EQ(merged.spec.full_width, kW);
  EXPECT_EQ(merged.spec.full_height, kH);
  ASSERT_EQ(merged.spec.channelnames, full.spec.channelnames);
  for (int c = 0; c < full.spec.nchannels; ++c) EXPECT_EQ(merged.spec.channelformat(c), full.spec.channelformat(c)) << c;
  for (const auto& [name, plane] : full.planes) {
    const std::vector<float>& p = merged.planes.at(name);
    ASSERT_EQ(p.size(), plane.size());
    EXPECT_EQ(std::memcmp(p.data(), plane.data(), p.size() * sizeof(float)), 0) << "channel " << name;
  }
  // The header: the full render's, attribute for attribute, but for the
  // per-tile ones; the region is the frame; one camera ray per sample in
  // all (the tiles' counts summed: 37 x 23 pixels x 2 spp).
  for (const OIIO::ParamValue& p : full.spec.extra_attribs) {
    const std::string name = p.name().string();
    if (isPerTileAttribute(name) && name != "obscura:region") continue;
    const OIIO::ParamValue* q = merged.spec.find_attribute(name);
    ASSERT_TRUE(q) << name;
    EXPECT_EQ(q->get_string(1 << 20), p.get_string(1 << 20)) << name;
  }
  for (const OIIO::ParamValue& q : merged.spec.extra_attribs)
    EXPECT_TRUE(full.spec.find_attribute(q.name().string())) << q.name().string();
  EXPECT_EQ(merged.spec.get_string_attribute("obscura:region"), regionText(0, 0, kW, kH));
  EXPECT_EQ(merged.spec.get_string_attribute("obscura:rays:camera"), std::to_string(kW * kH * 2));
  EXPECT_EQ(merged.spec.get_string_attribute("obscura:rays:camera"), full.spec.get_string_attribute("obscura:rays:camera"));
}

// Each refusal: exit 1, one line naming the offending file (or the output,
// for a gap) and why, and no output written.
TEST(Regions, MergeRefusesTilesThatDoNotBelongTogether) {
  const std::string dir = tempDir("regions_refuse");
  std::vector<std::vector<std::string>> runs;
  std::vector<std::string> tiles;
  for (int i = 0; i < 4; ++i) {
    tiles.push_back(dir + "/tile" + std::to_string(i) + ".exr");
    runs.push_back(args(tiles.back(), kTransfer, {"--region", regionText(kTiles[i][0], kTiles[i][1], kTiles[i][2], kTiles[i][3])}));
  }
  const std::string tile1 = regionText(kTiles[1][0], kTiles[1][1], kTiles[1][2], kTiles[1][3]);
  runs.push_back(args(dir + "/spp.exr", kTransfer, {"--region", tile1, "--spp", "3"}));
  runs.push_back(args(dir + "/seed.exr", kTransfer, {"--region", tile1, "--seed", "7"}));
  runs.push_back(args(dir + "/integrator.exr", {"-i", "ao", "--filter", "gaussian"}, {"--region", tile1}));
  runs.push_back(args(dir + "/res.exr", kTransfer, {"--region", tile1, "--res", "38x23"}));
  runs.push_back(args(dir + "/overlap.exr", kTransfer, {"--region", "10,5,20,12"}));
  runs.push_back(args(dir + "/channels.exr", kTransfer, {"--region", tile1, "--no-aovs"}));
  for (const CliResult& r : runClis(runs, dir)) ASSERT_EQ(r.exitCode, 0) << r.stderrText;

  struct Case {
    std::vector<std::string> tiles;
    std::string names, says;
  };
  const auto with1 = [&](const std::string& t) { return std::vector<std::string>{tiles[0], t, tiles[2], tiles[3]}; };
  const std::string out = dir + "/merged.exr";
  const std::vector<Case> cases = {
      {{tiles[0], tiles[1], tiles[2]}, out, "pixels uncovered, the first (20,9)"},
      {{tiles[0], tiles[1], tiles[2], tiles[3], dir + "/overlap.exr"}, dir + "/overlap.exr", "overlaps " + tiles[0]},
      {with1(dir + "/spp.exr"), dir + "/spp.exr", "header: obscura:spp is 3, but 2"},
      {with1(dir + "/seed.exr"), dir + "/seed.exr", "header: obscura:seed"},
      {with1(dir + "/integrator.exr"), dir + "/integrator.exr", "header: obscura:integrator is ao, but transfer in " + tiles[0]},
      {with1(dir + "/res.exr"), dir + "/res.exr", "display window 38x23 at (0,0) differs"},
      {with1(dir + "/channels.exr"), dir + "/channels.exr", "channels R,G,B,A differ from " + tiles[0] + "'s"},
      {with1(dir + "/missing.exr"), dir + "/missing.exr", "cannot open"},
  };
  std::vector<std::vector<std::string>> merges;
  for (const Case& c : cases) {
    merges.push_back({"merge", out});
    merges.back().insert(merges.back().end(), c.tiles.begin(), c.tiles.end());
  }
  const std::vector<CliResult> results = runClis(merges, dir);
  for (size_t i = 0; i < cases.size(); ++i) {
    const CliResult& r = results[i];
    EXPECT_EQ(r.exitCode, 1) << cases[i].says;
    EXPECT_NE(r.stderrText.find(cases[i].names + ": "), std::string::npos) << r.stderrText;
    EXPECT_NE(r.stderrText.find(cases[i].says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
  EXPECT_FALSE(std::filesystem::exists(out));
  // The four tiles themselves merge (the refusals above are the odd ones out).
  const CliResult ok = runCli({"merge", out, tiles[3], tiles[1], tiles[0], tiles[2]}, dir + "/ok_stderr.txt");
  EXPECT_EQ(ok.exitCode, 0) << ok.stderrText;
}

TEST(Regions, RegionValidation) {
  const std::string dir = tempDir("regions_validate");
  struct Bad {
    std::vector<std::string> extra;
    std::string says;
  };
  const std::vector<Bad> bad = {
      {{"--region", "1,2,3"}, "--region 1,2,3: expected X0,Y0,X1,Y1"},
      {{"--region", "a,0,4,4"}, "--region a,0,4,4: expected X0,Y0,X1,Y1"},
      {{"--region", "0,0,4,4,5"}, "--region 0,0,4,4,5: expected X0,Y0,X1,Y1"},
      {{"--region=-1,0,4,4"}, "--region -1,0,4,4: expected X0,Y0,X1,Y1"},
      {{"--region", "5,5,5,9"}, "--region 5,5,5,9: empty"},
      {{"--region", "0,9,4,3"}, "--region 0,9,4,3: empty"},
      {{"--region", "0,0,38,23"}, "--region 0,0,38,23: outside the 37x23 image"},
      {{"--region", "0,20,37,24"}, "--region 0,20,37,24: outside the 37x23 image"},
      // A screen-space pass renders regions through its guard band; without one it cannot.
      {{"--region", "0,0,8,8", "-i", "vo", "-p", "guard-band=0"}, "--region: this screen-space pass has no guard band"},
      {{"--region", "0,0,8,8", "--pass", "a=ao", "--pass", "b=vo:guard-band=0"},
       "--region: this screen-space pass has no guard band"},
  };
  std::vector<std::vector<std::string>> runs;
  for (const Bad& b : bad) runs.push_back(args(dir + "/bad.exr", {}, b.extra));
  const std::vector<CliResult> results = runClis(runs, dir);
  for (size_t i = 0; i < bad.size(); ++i) {
    const CliResult& r = results[i];
    EXPECT_EQ(r.exitCode, 1) << bad[i].says;
    EXPECT_NE(r.stderrText.find(bad[i].says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad.exr"));
}

}  // namespace
}  // namespace obscura::test
