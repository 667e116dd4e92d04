// Resumable renders (docs/production.md "Checkpoints"): `render --checkpoint SECONDS`
// saves finished tiles to OUT.exr.checkpoint; a render stopped by SIGKILL or
// Ctrl-C and run again with the same command ends bit for bit equal, on
// every channel, to the render that was never stopped. A checkpoint of
// another render, or a damaged one, is refused with one line; the file is
// gone once the EXR is written.
//
// The interruption is deterministic: OBSCURA_TEST_CHECKPOINT_KILL=N[:INT]
// (core/render/checkpoint.h, tests only) makes the process send itself SIGKILL (or
// SIGINT) right after writing a checkpoint of at least N tiles. One test
// also kills the process from outside as soon as the file appears.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>

#include "tests/gltf_builder.h"
#include "tests/scoped_env.h"
#include "tests/support.h"

namespace obscura::test {
namespace fs = std::filesystem;
namespace {

// 40x30 pixels in 8-pixel tiles: 5 x 4 = 20 tiles, the bottom row 6 high;
// with --region, tiles clipped at the region's edges too.
const std::vector<std::string> kCommon = {"render", "-q", "--res", "40x30", "--spp", "4", "--tile", "8"};
// A ratio estimator through the Gaussian pixel filter (samples beyond their
// pixel's square), with the AOVs.
const std::vector<std::string> kTransfer = {"-i", "transfer", "--filter", "gaussian"};
// Two ray-traced passes in layers and Cryptomatte object layers.
const std::vector<std::string> kLayers = {"--pass", "tr=transfer", "--pass", "ao=ao:distance=2", "--cryptomatte", "object"};

// kCommon, then `config` and `extra`, whose --res, --spp or --tile replace
// kCommon's (an option may be given once).
std::vector<std::string> args(const std::string& out, const std::vector<std::string>& config,
                              const std::vector<std::string>& extra = {}) {
  std::vector<std::string> a = kCommon;
  std::vector<std::string> more = config;
  more.insert(more.end(), extra.begin(), extra.end());
  for (size_t i = 0; i < more.size(); ++i) {
    const auto at = std::find(a.begin(), a.begin() + ptrdiff_t(kCommon.size()), more[i]);
    if (at != a.begin() + ptrdiff_t(kCommon.size()) && i + 1 < more.size()) {
      at[1] = more[++i];
      continue;
    }
    a.push_back(more[i]);
  }
  a.push_back("-o");
  a.push_back(out);
  return a;
}


bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every channel of a equals b's bit for bit; so do the data windows and the
// ray counts (a resumed render counts each tile's rays once).
void expectSameImage(const std::string& a, const std::string& b) {
  const ReadBack x = readExr(a), y = readExr(b);
  ASSERT_TRUE(x.ok && y.ok);
  EXPECT_EQ(x.spec.x, y.spec.x);
  EXPECT_EQ(x.spec.y, y.spec.y);
  EXPECT_EQ(x.spec.width, y.spec.width);
  EXPECT_EQ(x.spec.height, y.spec.height);
  ASSERT_EQ(x.spec.channelnames, y.spec.channelnames);
  for (const auto& [name, plane] : y.planes) {
    const std::vector<float>& p = x.planes.at(name);
    ASSERT_EQ(p.size(), plane.size());
    size_t differ = 0;
    for (size_t i = 0; i < p.size(); ++i) differ += !sameBits(p[i], plane[i]);
    EXPECT_EQ(differ, 0u) << "channel " << name;
  }
  for (const char* k : {"obscura:rays:camera", "obscura:rays:occlusion", "obscura:rays:closest"})
    EXPECT_EQ(x.spec.get_string_attribute(k), y.spec.get_string_attribute(k)) << k;
}

size_t lines(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')); }

// The reference: `config` rendered once, without --checkpoint, with all
// threads; then the same render with --checkpoint 0 on one thread, stopped
// after `stops[0]` tiles, resumed and stopped after stops[1], ... and
// resumed to the end: equal to the reference, the checkpoint gone.
void killResumeEqual(const std::string& name, const std::vector<std::string>& config, const std::vector<std::string>& stops,
                     bool ctrlC) {
  const std::string dir = tempDir(name);
  const std::string ref = dir + "/ref.exr", out = dir + "/out.exr", ckpt = out + ".checkpoint";
  const CliResult r = runCli(args(ref, config), dir + "/ref.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const std::vector<std::string> resumable = args(out, config, {"--checkpoint", "0", "--threads", "1"});
  for (const std::string& n : stops) {
    const ScopedEnv kill("OBSCURA_TEST_CHECKPOINT_KILL", n + (ctrlC ? ":INT" : ""));
    const CliResult k = runCli(resumable, dir + "/kill.txt");
    if (ctrlC) {
      EXPECT_EQ(k.exitCode, 130) << k.stderrText;
      EXPECT_EQ(lines(k.stderrText), 1u) << k.stderrText;
      EXPECT_NE(k.stderrText.find("was not written"), std::string::npos) << k.stderrText;
      EXPECT_NE(k.stderrText.find("tiles saved in " + ckpt), std::string::npos) << k.stderrText;
    } else {
      EXPECT_EQ(k.signal, SIGKILL) << k.stderrText;
    }
    EXPECT_TRUE(fs::exists(ckpt)) << "after stopping at " << n << " tiles";
    EXPECT_FALSE(fs::exists(out));
  }
  const CliResult done = runCli(resumable, dir + "/resume.txt");
  ASSERT_EQ(done.exitCode, 0) << done.stderrText;
  EXPECT_FALSE(fs::exists(ckpt)) << "the checkpoint outlived the image";
  EXPECT_FALSE(fs::exists(ckpt + ".tmp"));
  expectSameImage(out, ref);
  // Every run that rendered tiles is on record.
  EXPECT_EQ(readExr(out).spec.get_int_attribute("obscura:checkpointRuns"), int(stops.size()) + 1);
}

TEST(Checkpoint, KilledTwiceAndResumedEqualsUninterrupted) {
  killResumeEqual("ckpt_kill", kTransfer, {"5", "12"}, false);
}

TEST(Checkpoint, MultiPassWithCryptomatteAfterCtrlC) { killResumeEqual("ckpt_layers", kLayers, {"7"}, true); }

TEST(Checkpoint, RegionKilledAndResumed) {
  std::vector<std::string> config = kLayers;
  config.insert(config.end(), {"--region", "5,3,33,26"});  // 28x23: tiles clipped at the region's edges
  killResumeEqual("ckpt_region", config, {"4"}, false);
}

// Without an interruption: the same image, no checkpoint left, no
// checkpointRuns in the header.
TEST(Checkpoint, UninterruptedLeavesNoFile) {
  const std::string dir = tempDir("ckpt_plain");
  const std::string ref = dir + "/ref.exr", out = dir + "/out.exr";
  ASSERT_EQ(runCli(args(ref, kTransfer), dir + "/ref.txt").exitCode, 0);
  const CliResult r = runCli(args(out, kTransfer, {"--checkpoint", "0"}), dir + "/out.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  EXPECT_FALSE(fs::exists(out + ".checkpoint"));
  expectSameImage(out, ref);
  EXPECT_FALSE(readExr(out).spec.find_attribute("obscura:checkpointRuns"));
}

// A real SIGKILL from outside, as soon as the first checkpoint is on disk:
// a render long enough (one thread, 300 tiles) that it is still running.
TEST(Checkpoint, ExternalSigkillWhenTheFileAppears) {
  const std::string dir = tempDir("ckpt_external");
  const std::string ref = dir + "/ref.exr", out = dir + "/out.exr", ckpt = out + ".checkpoint";
  const std::vector<std::string> config = {"-i", "transfer", "--res", "160x120", "--spp", "16"};
  CliResult k;
  const pid_t pid = startCli(args(out, config, {"--checkpoint", "0", "--threads", "1"}), dir + "/kill.txt", k);
  ASSERT_GT(pid, 0) << k.stderrText;
  bool seen = false;
  for (int i = 0; i < 60000 && !seen; ++i) {
    seen = fs::exists(ckpt);
    if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  kill(pid, SIGKILL);
  finishCli(pid, dir + "/kill.txt", k);
  ASSERT_TRUE(seen) << "no checkpoint appeared: " << k.stderrText;
  if (k.exitCode == 0) GTEST_SKIP() << "the render finished before the kill reached it";
  EXPECT_EQ(k.signal, SIGKILL);
  ASSERT_TRUE(fs::exists(ckpt));
  ASSERT_EQ(runCli(args(ref, config), dir + "/ref.txt").exitCode, 0);
  const CliResult done = runCli(args(out, config, {"--checkpoint", "0"}), dir + "/resume.txt");
  ASSERT_EQ(done.exitCode, 0) << done.stderrText;
  EXPECT_FALSE(fs::exists(ckpt));
  expectSameImage(out, ref);
}

// A checkpoint left by a SIGKILL of kTransfer after 5 tiles. One thread:
// with more, a thread skips its write while another one writes, and the last
// tiles may all finish during a write of fewer than 5 (the render then ends
// normally and deletes its checkpoint).
std::string killedCheckpoint(const std::string& dir, const std::string& out) {
  const ScopedEnv kill("OBSCURA_TEST_CHECKPOINT_KILL", "5");
  const CliResult k = runCli(args(out, kTransfer, {"--checkpoint", "0", "--threads", "1"}), dir + "/kill.txt");
  EXPECT_EQ(k.signal, SIGKILL) << k.stderrText;
  EXPECT_TRUE(fs::exists(out + ".checkpoint"));
  return out + ".checkpoint";
}

// One error line naming the file and `why`, exit 1, no image, the
// checkpoint kept (it may be the user's only copy of hours of work).
void expectRefused(const CliResult& r, const std::string& ckpt, const std::string& why) {
  EXPECT_EQ(r.exitCode, 1) << r.stderrText;
  EXPECT_EQ(r.signal, 0);
  EXPECT_EQ(lines(r.stderrText), 1u) << r.stderrText;
  EXPECT_EQ(r.stderrText.rfind("obscura: error: " + ckpt + ": ", 0), 0u) << r.stderrText;
  EXPECT_NE(r.stderrText.find(why), std::string::npos) << r.stderrText;
  EXPECT_NE(r.stderrText.find("delete it to start over"), std::string::npos) << r.stderrText;
  EXPECT_TRUE(fs::exists(ckpt));
}

TEST(Checkpoint, OfAnotherRenderIsRefused) {
  const std::string dir = tempDir("ckpt_mismatch");
  const std::string out = dir + "/out.exr";
  const std::string ckpt = killedCheckpoint(dir, out);
  // Each names the setting that differs.
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--spp", "8"}, "obscura:spp"},
      {{"--seed", "3"}, "obscura:seed"},
      {{"--tile", "16"}, "tile size"},
      {{"--no-aovs"}, "AOVs"},
      {{"--no-albedo"}, "AOVs"},
      {{"-p", "depth=2"}, "obscura:param:depth"},
  };
  for (const auto& [extra, key] : cases) {
    std::vector<std::string> a = args(out, kTransfer, extra);
    a.insert(a.end() - 2, {"--checkpoint", "0"});
    const CliResult r = runCli(a, dir + "/mismatch.txt");
    expectRefused(r, ckpt, "checkpoint of a different render (" + key);
    EXPECT_FALSE(fs::exists(out));
  }
  // A changed scene file: a copy of the bundled scene (its buffers and
  // images are data: uris), checkpointed, then one byte added.
  const std::string scene = dir + "/scene.gltf";
  fs::copy_file(sourcePath("scenes/default.gltf"), scene);
  const std::string out2 = dir + "/out2.exr";
  {
    const ScopedEnv kill("OBSCURA_TEST_CHECKPOINT_KILL", "5");
    std::vector<std::string> a = args(out2, kTransfer, {"--checkpoint", "0", "--threads", "1"});
    a.insert(a.begin() + 1, scene);
    ASSERT_EQ(runCli(a, dir + "/kill2.txt").signal, SIGKILL);
  }
  const std::vector<unsigned char> text = readBytes(scene);
  writeText(scene, std::string(text.begin(), text.end()) + " ");  // JSON that means the same
  std::vector<std::string> a = args(out2, kTransfer, {"--checkpoint", "0"});
  a.insert(a.begin() + 1, scene);
  expectRefused(runCli(a, dir + "/scene.txt"), out2 + ".checkpoint", "(scene file:");
}

// A file the scene names changed between the kill and the resume: the
// height map of extras.obscura.displacement.map, then the external buffer.
// The fingerprint hashed the scene file only (the buffer by size and time,
// the map not at all), so a replaced map resumed into an image half of the
// old surface, half of the new. Each is refused naming the file; with both
// restored the render resumes and ends equal to one never stopped.
TEST(Checkpoint, ResumeWithAChangedInputFileIsRefused) {
  const std::string dir = tempDir("ckpt_inputs");
  const std::string map = writeRipples(dir);
  GltfBuilder g;
  const int mesh = g.quadMesh(1.0f, -1, true);
  g.doc["meshes"][size_t(mesh)]["extras"] = {
      {"obscura", {{"subdivision", {{"level", 2}}}, {"displacement", {{"map", fs::path(map).filename().string()}, {"scale", 0.2}}}}}};
  g.scene({g.node({{"mesh", mesh}})});
  const std::string scene = g.writeGltf(dir, "disp");
  const std::string bin = dir + "/disp.bin";
  const auto withScene = [&](std::vector<std::string> a) {
    a.insert(a.begin() + 1, scene);
    return a;
  };
  const std::string ref = dir + "/ref.exr", out = dir + "/out.exr", ckpt = out + ".checkpoint";
  ASSERT_EQ(runCli(withScene(args(ref, kTransfer)), dir + "/ref.txt").exitCode, 0);
  {
    const ScopedEnv kill("OBSCURA_TEST_CHECKPOINT_KILL", "5");
    ASSERT_EQ(runCli(withScene(args(out, kTransfer, {"--checkpoint", "0", "--threads", "1"})), dir + "/kill.txt").signal, SIGKILL);
  }
  const std::vector<unsigned char> mapBytes = readBytes(map), binBytes = readBytes(bin);
  const std::vector<std::string> resume = withScene(args(out, kTransfer, {"--checkpoint", "0"}));
  writeHeightMap(map, 16, 16, [](double u, double v) { return u * v; });
  expectRefused(runCli(resume, dir + "/map.txt"), ckpt, "(" + scene + " meshes[0].extras.obscura.displacement.map " + map + ": '");
  writeBytes(map, mapBytes.data(), mapBytes.size());
  std::vector<unsigned char> moved = binBytes;
  moved[0] ^= 1;  // the first position's lowest bit: the same size, another file
  writeBytes(bin, moved.data(), moved.size());
  expectRefused(runCli(resume, dir + "/bin.txt"), ckpt, "(" + scene + " buffers[0] " + bin + ": '");
  writeBytes(bin, binBytes.data(), binBytes.size());
  const CliResult done = runCli(resume, dir + "/resume.txt");
  ASSERT_EQ(done.exitCode, 0) << done.stderrText;
  EXPECT_FALSE(fs::exists(ckpt));
  expectSameImage(out, ref);
}

TEST(Checkpoint, DamagedIsRefused) {
  const std::string dir = tempDir("ckpt_corrupt");
  const std::string out = dir + "/out.exr";
  const std::string ckpt = killedCheckpoint(dir, out);
  const std::vector<unsigned char> good = readBytes(ckpt);
  ASSERT_GT(good.size(), 100u);
  const std::vector<std::string> a = args(out, kTransfer, {"--checkpoint", "0"});
  const auto refusedAs = [&](std::vector<unsigned char> bytes, const std::string& why) {
    writeBytes(ckpt, bytes.data(), bytes.size());
    expectRefused(runCli(a, dir + "/corrupt.txt"), ckpt, why);
    EXPECT_FALSE(fs::exists(out));
  };
  refusedAs({}, "not an Obscura checkpoint");
  refusedAs(std::vector<unsigned char>(good.begin(), good.begin() + 10), "truncated");
  refusedAs(std::vector<unsigned char>(good.begin(), good.begin() + ptrdiff_t(good.size() / 2)), "corrupt");
  refusedAs(std::vector<unsigned char>(good.begin(), good.end() - 1), "corrupt");
  std::vector<unsigned char> flipped = good;
  flipped[flipped.size() / 2] ^= 0x40;
  refusedAs(flipped, "corrupt");
  std::vector<unsigned char> version = good;
  version[8] += 1;  // the u32 after the magic
  refusedAs(version, "format version");
  std::vector<unsigned char> garbage(good.size(), 0x5a);
  refusedAs(garbage, "not an Obscura checkpoint");
  // The good file still resumes.
  writeBytes(ckpt, good.data(), good.size());
  const CliResult r = runCli(a, dir + "/good.txt");
  EXPECT_EQ(r.exitCode, 0) << r.stderrText;
  EXPECT_FALSE(fs::exists(ckpt));
}

TEST(Checkpoint, ScreenSpacePassesAreRefused) {
  const std::string dir = tempDir("ckpt_vo");
  const CliResult r = runCli(args(dir + "/out.exr", {"-i", "vo"}, {"--checkpoint", "10"}), dir + "/vo.txt");
  EXPECT_EQ(r.exitCode, 1) << r.stderrText;
  EXPECT_EQ(lines(r.stderrText), 1u) << r.stderrText;
  EXPECT_NE(r.stderrText.find("--checkpoint: not available with a screen-space pass"), std::string::npos) << r.stderrText;
  const CliResult b = runCli(args(dir + "/out.exr", {"--checkpoint", "-1"}), dir + "/neg.txt");
  EXPECT_EQ(b.exitCode, 1) << b.stderrText;
  EXPECT_NE(b.stderrText.find("--checkpoint"), std::string::npos) << b.stderrText;
}

}  // namespace
}  // namespace obscura::test
