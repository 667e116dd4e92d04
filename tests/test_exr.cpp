// The EXR pass: channel names and layout, values, header metadata, half
// output, atomic replacement, and the CLI's output for the default scene.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cstdio>

#include <filesystem>

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

Film sampleFilm() {
  Film f(5, 3, true);
  for (int c : f.channels())
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 5; ++x) f.at(c, x, y) = float(c) + 0.125f * float(x) - 0.0625f * float(y) + 1e-3f;
  f.at(kZ, 4, 2) = kInfinity;  // background depth
  return f;
}

TEST(Exr, FloatChannelsAndHeaderRoundTrip) {
  const std::string dir = tempDir("exr_float");
  const Film film = sampleFilm();
  ExrOptions o;
  o.attributes = {{"obscura:integrator", std::string("ao")}, {"obscura:spp", 16}, {"obscura:renderTime", 1.5f}};
  writeExr(dir + "/a.exr", film, o);
  const ReadBack r = readExr(dir + "/a.exr");
  ASSERT_EQ(r.spec.nchannels, int(kChannelCount));
  EXPECT_EQ(r.spec.format, OIIO::TypeDesc::FLOAT);
  for (int c = 0; c < kChannelCount; ++c) {
    ASSERT_TRUE(r.planes.count(film.name(c))) << film.name(c);
    const auto& p = r.planes.at(film.name(c));
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 5; ++x) EXPECT_EQ(p[size_t(y) * 5 + x], film.at(c, x, y)) << film.name(c);
  }
  EXPECT_EQ(r.spec.get_string_attribute("obscura:integrator"), "ao");
  EXPECT_EQ(r.spec.get_int_attribute("obscura:spp"), 16);
  EXPECT_EQ(r.spec.get_float_attribute("obscura:renderTime"), 1.5f);
  EXPECT_EQ(r.spec.alpha_channel >= 0 ? r.spec.channelnames[size_t(r.spec.alpha_channel)] : "", "A");
}

TEST(Exr, HalfOutputIsWithinHalfPrecision) {
  const std::string dir = tempDir("exr_half");
  const Film film = sampleFilm();
  ExrOptions o;
  o.half = true;
  writeExr(dir + "/h.exr", film, o);
  const ReadBack r = readExr(dir + "/h.exr");
  // Half but for the normal and the depth (tests/test_exr_conventions.cpp).
  ASSERT_EQ(r.spec.channelformats.size(), size_t(kChannelCount));
  for (int i = 0; i < kChannelCount; ++i)
    EXPECT_EQ(r.spec.channelformats[size_t(i)], exrKeepsFloat(film.find(r.spec.channelnames[size_t(i)])) ? OIIO::TypeDesc::FLOAT
                                                                                                         : OIIO::TypeDesc::HALF);
  for (int c = 0; c < kChannelCount; ++c) {
    const auto& p = r.planes.at(film.name(c));
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 5; ++x) {
        const float v = film.at(c, x, y);
        if (std::isinf(v)) {
          EXPECT_TRUE(std::isinf(p[size_t(y) * 5 + x]));
          continue;
        }
        // Half has an 11-bit significand: relative rounding error <= 2^-11.
        EXPECT_NEAR(p[size_t(y) * 5 + x], v, std::abs(v) * 0x1p-11f) << film.name(c);
      }
  }
}

TEST(Exr, FailedWriteLeavesNoFileAndReplacementIsWhole) {
  const std::string dir = tempDir("exr_atomic");
  const Film film = sampleFilm();
  EXPECT_THROW(writeExr(dir + "/missing_dir/x.exr", film, {}), Error);
  EXPECT_FALSE(std::filesystem::exists(dir + "/missing_dir"));
  // Replacing a file goes through a temporary sibling: afterwards only the
  // destination exists, complete.
  writeExr(dir + "/x.exr", film, {});
  Film other(2, 2, false);
  writeExr(dir + "/x.exr", other, {});
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
  EXPECT_EQ(readExr(dir + "/x.exr").spec.width, 2);
}

// The default scene through the CLI: every channel and the metadata the
// README documents; alpha-premultiplied pass within [0, A].
TEST(Exr, CliRendersDefaultSceneWithChannelsAndMetadata) {
  const std::string dir = tempDir("cli_default");
  const CliResult cli = runCli({"render", "-o", dir + "/ao.exr", "--res", "64x36", "--spp", "4", "--seed", "9", "-p",
                                "rays=2", "--preview", dir + "/ao.png", "--quiet"},
                               dir + "/stderr.txt");
  ASSERT_EQ(cli.exitCode, 0) << cli.stderrText;
  EXPECT_TRUE(std::filesystem::exists(dir + "/ao.png"));
  const ReadBack r = readExr(dir + "/ao.exr");
  EXPECT_EQ(r.spec.width, 64);
  EXPECT_EQ(r.spec.height, 36);
  for (const char* c : {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z", "shaded.R",
                        "shaded.G", "shaded.B"})
    EXPECT_TRUE(r.planes.count(c)) << c;
  EXPECT_EQ(r.spec.get_string_attribute("obscura:integrator"), "ao");
  EXPECT_EQ(r.spec.get_string_attribute("obscura:param:distance"), "inf");
  EXPECT_EQ(r.spec.get_string_attribute("obscura:param:rays"), "2");
  EXPECT_EQ(r.spec.get_int_attribute("obscura:spp"), 4);
  EXPECT_EQ(r.spec.get_int_attribute("obscura:seed"), 9);
  EXPECT_EQ(r.spec.get_string_attribute("obscura:resolution"), "64x36");
  EXPECT_EQ(r.spec.get_string_attribute("obscura:camera"), "main");
  EXPECT_GT(r.spec.get_float_attribute("obscura:renderTime", -1.0f), 0.0f);
  // Ray counts: one camera ray per sample, `rays` AO rays per camera hit.
  const long long cam = std::stoll(r.spec.get_string_attribute("obscura:rays:camera"));
  const long long occ = std::stoll(r.spec.get_string_attribute("obscura:rays:occlusion"));
  EXPECT_EQ(cam, 64LL * 36 * 4);
  double hits = 0;
  for (float a : r.planes.at("A")) hits += double(a) * 4.0;
  EXPECT_EQ(occ, 2LL * std::llround(hits));
  for (size_t i = 0; i < r.planes.at("A").size(); ++i) {
    const float a = r.planes.at("A")[i];
    ASSERT_GE(a, 0.0f);
    ASSERT_LE(a, 1.0f);
    for (const char* c : {"R", "G", "B"}) {
      const float v = r.planes.at(c)[i];
      ASSERT_TRUE(std::isfinite(v));
      ASSERT_GE(v, 0.0f);
      ASSERT_LE(v, a);  // premultiplied: W in [0,1] times coverage
    }
    if (a == 0.0f) {
      EXPECT_EQ(r.planes.at("Z")[i], kBackgroundDepth);
    }
  }
}

// Every built-in ambient integrator renders the default scene and each scene
// of ../shared/scenes that is present, through the CLI: exit 0 and a pass
// that is finite and in [0, A] (gi, a plain Monte Carlo mean with roulette
// weights, only finite and >= 0).
TEST(Exr, CliRendersEveryIntegratorOnEveryScene) {
  const std::string dir = tempDir("cli_all");
  std::vector<std::string> scenes = {sourcePath("scenes/default.gltf")};
  // The third-party scenes run when present (and must be under
  // OBSCURA_REQUIRE_SCENES); the bundled scene always runs.
  for (const char* s : {"cornell_box_classic/cornell-box.gltf", "cornell_box_suzanne/cornell-box.glb",
                        "damaged_helmet/DamagedHelmet.gltf", "suzanne/Suzanne.gltf", "viking_room/viking_room.glb"}) {
    const std::string path = sharedScene(s);
    if (const std::string why = missingSharedScene(path); why.empty())
      scenes.push_back(path);
    else if (sharedScenesRequired())
      ADD_FAILURE() << why;
    else
      std::printf("%s\n", why.c_str());
  }
  const std::vector<std::vector<std::string>> integrators = {
      {"ao"}, {"obscurance", "-p", "falloff=exponential"}, {"transfer"}, {"transfer", "-p", "depth=2"},
      {"gi"}, {"gi", "-p", "sigma=1"}, {"multibounce"}, {"multibounce", "-p", "mapping=improved"}};
  std::vector<std::vector<std::string>> runs;
  std::vector<std::string> outputs;
  for (size_t s = 0; s < scenes.size(); ++s)
    for (size_t i = 0; i < integrators.size(); ++i) {
      outputs.push_back(dir + "/s" + std::to_string(s) + "_i" + std::to_string(i) + ".exr");
      std::vector<std::string> a = {"render", scenes[s], "-o", outputs.back(), "--res", "48x27", "--spp", "2",
                                    "--quiet", "-i"};
      a.insert(a.end(), integrators[i].begin(), integrators[i].end());
      runs.push_back(a);
    }
  const std::vector<CliResult> results = runClis(runs, dir);
  for (size_t r = 0; r < runs.size(); ++r) {
    const std::string what = runs[r][1] + " -i " + runs[r].back();
    ASSERT_EQ(results[r].exitCode, 0) << what << ": " << results[r].stderrText;
    const ReadBack img = readExr(outputs[r]);
    ASSERT_TRUE(img.ok) << what;
    const bool bounded = img.spec.get_string_attribute("obscura:integrator") != "gi";
    const std::vector<float>& A = img.planes.at("A");
    for (size_t p = 0; p < A.size(); ++p)
      for (const char* c : {"R", "G", "B"}) {
        const float v = img.planes.at(c)[p];
        ASSERT_TRUE(std::isfinite(v)) << what;
        ASSERT_GE(v, 0.0f) << what;
        if (bounded) {
          ASSERT_LE(v, A[p]) << what << " channel " << c;
        }
      }
  }
}

}  // namespace
}  // namespace obscura::test
