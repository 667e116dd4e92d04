// The render's outputs as a unit: a pass and its preview land together or not
// at all, outputs are checked before the render (writable, not the scene, not
// each other), a film larger than the available memory is refused up front,
// and the EXR is written in bands (large images round-trip).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "core/util/large_vector.h"
#include "tests/gltf_builder.h"
#include "tests/scoped_env.h"
#include "tests/png_crc.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

std::string fileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// Files in `dir` but the ones named: temporaries left behind.
std::vector<std::string> otherFiles(const std::string& dir, const std::vector<std::string>& keep) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (std::find(keep.begin(), keep.end(), e.path().filename().string()) == keep.end())
      out.push_back(e.path().filename().string());
  return out;
}

// Runs `body` in a child process whose files may not grow past `limit`
// bytes (RLIMIT_FSIZE: a write beyond it fails with EFBIG, as on a full
// disk, with SIGXFSZ ignored); returns the child's exit code.
template <class F>
int inChildWithFileLimit(rlim_t limit, F body) {
  const pid_t pid = fork();
  if (pid == 0) {
    signal(SIGXFSZ, SIG_IGN);
    const rlimit r{limit, limit};
    if (setrlimit(RLIMIT_FSIZE, &r) != 0) _exit(100);
    _exit(body());
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

// The obscura program with `args` under a file-size limit; stderr to
// stderrPath.
CliResult runCliWithFileLimit(const std::vector<std::string>& args, const std::string& stderrPath, rlim_t limit) {
  CliResult r;
  r.exitCode = inChildWithFileLimit(limit, [&] {
    const int err = ::open(stderrPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int null = ::open("/dev/null", O_WRONLY);
    if (err < 0 || null < 0) return 101;
    dup2(null, 1);
    dup2(err, 2);
    std::vector<std::string> all = {obscuraBinary()};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(obscuraBinary(), argv.data());
    return 102;
  });
  r.stderrText = fileBytes(stderrPath);
  return r;
}

Film rampFilm(int w, int h, bool aovs) {
  Film f(w, h, aovs);
  for (int c : f.channels())
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) f.at(c, x, y) = float(c) * 0.01f + float(x) / float(w) + float(y) * 1e-4f;
  return f;
}

// A new film's planes are zero wherever its memory comes from (a guard for
// any cheaper zeroing of the film's huge-page planes, docs/performance.md
// "Where the render loop's time goes"). Films are built where films just as large were filled with non-zero values and
// freed, so the allocator hands back dirty memory; every pixel of every
// plane, the fixed channels and added ones, must read 0, at sizes above and
// below the 2 MiB of a huge page.
TEST(Outputs, NewFilmPlanesAreZeroOnReusedMemory) {
  for (auto [w, h] : {std::pair{1024, 1024}, std::pair{1000, 701}, std::pair{100, 30}}) {
    for (int round = 0; round < 3; ++round) {
      {
        Film dirty = rampFilm(w, h, true);
        const int extra = dirty.addPlane("extra.R");
        std::fill_n(dirty.plane(extra), size_t(w) * size_t(h), 7.0f);
      }
      Film f(w, h, true);
      const int extra = f.addPlane("extra.R");
      ASSERT_GE(extra, 0);
      for (int c : f.channels()) {
        const float* p = f.plane(c);
        size_t nonzero = 0;
        for (size_t i = 0; i < size_t(w) * size_t(h); ++i) nonzero += p[i] != 0.0f;
        ASSERT_EQ(nonzero, 0u) << w << "x" << h << " plane " << f.name(c) << " round " << round;
      }
    }
  }
}

// Whole-image blocks freed by one render are handed to the next allocation
// of the same rounded size (core/util/large_vector.h): a process that renders
// again finds its pages faulted in. Past the cap the oldest go; a size no
// kept block has hands back the oldest, as many bytes as it allocates. In
// builds without NDEBUG and in the sanitized ones every block comes out
// filled with 0xff bytes, fresh or kept, so that reading an element before
// writing it shows in the tests; the film's planes are zeroed all the same
// (the test above). Sanitized builds keep nothing.
TEST(Outputs, LargeBlocksAreKeptForTheNextAllocation) {
  constexpr size_t kMiB = size_t(1) << 20;
  detail::releaseKeptBlocks();
  const size_t n = 3 * kMiB / sizeof(float);  // 3 MiB: a 4 MiB block
#if defined(OBSCURA_SANITIZED_BUILD) || defined(__SANITIZE_ADDRESS__)
  { LargeVector<float> a(n); }
  EXPECT_EQ(detail::keptCapacity(), 0u);
  EXPECT_EQ(detail::releaseKeptBlocks(), 0u);  // nothing kept: AddressSanitizer sees every free
#else
  const size_t cap = detail::setKeptCapacity(64 * kMiB);  // whatever OBSCURA_KEEP_MEMORY says
  const float* first = nullptr;
  {
    LargeVector<float> a(n);
    std::fill(a.begin(), a.end(), 2.0f);
    first = a.data();
  }
  EXPECT_EQ(detail::keptBytes(), 4 * kMiB);
  {
    LargeVector<float> b(n - 1000);  // another size, the same 4 MiB block
    EXPECT_EQ(b.data(), first);
    EXPECT_EQ(detail::keptBytes(), 0u);
#ifndef NDEBUG
    size_t unpoisoned = 0;
    for (float x : b) unpoisoned += !std::isnan(x);
    EXPECT_EQ(unpoisoned, 0u);
#endif
  }
  { LargeVector<uint8_t> c(10 * kMiB); }  // a miss: the kept 4 MiB block goes back first
  EXPECT_EQ(detail::keptBytes(), 10 * kMiB);
  // Past the cap the oldest go.
  detail::setKeptCapacity(16 * kMiB);
  { LargeVector<uint8_t> d(8 * kMiB); }  // a miss that frees the 10 MiB block, then kept: 8 MiB
  EXPECT_EQ(detail::keptBytes(), 8 * kMiB);
  {
    LargeVector<uint8_t> e(8 * kMiB), f(6 * kMiB);  // e takes the kept block; f misses with none left
    EXPECT_EQ(detail::keptBytes(), 0u);
  }  // freed f (6 MiB), then e (8 MiB): 14 MiB fits under 16
  EXPECT_EQ(detail::keptBytes(), 14 * kMiB);
  { LargeVector<uint8_t> g(4 * kMiB - 1); }  // a miss: the oldest (f, 6 MiB) goes; then g's 4 MiB kept
  EXPECT_EQ(detail::keptBytes(), 12 * kMiB);
  EXPECT_EQ(detail::releaseKeptBlocks(), 12 * kMiB);
  EXPECT_EQ(detail::keptBytes(), 0u);
  detail::setKeptCapacity(cap);
#endif
}

// When the second of two staged files cannot be moved into place, the first
// destination gets its previous bytes back and no temporary is left behind.
TEST(Outputs, FailedSecondMoveRestoresTheFirstFile) {
  const std::string dir = tempDir("outputs_rollback");
  const std::string exr = dir + "/pass.exr", png = dir + "/pass.png";
  writeExr(exr, rampFilm(8, 4, true), {});
  const std::string good = fileBytes(exr);
  {
    OutputSet out;
    out.addExr(exr, rampFilm(3, 2, false), {});
    out.addPreviewPng(png, rampFilm(3, 2, false));
    // The preview's destination turns into a non-empty directory after it
    // was staged: renaming a file over it fails.
    std::filesystem::create_directories(png + "/occupied");
    EXPECT_THROW(out.commit(), Error);
  }
  EXPECT_EQ(fileBytes(exr), good);
  size_t entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    ++entries;
    EXPECT_TRUE(e.path() == exr || e.path() == png) << "left behind: " << e.path();
  }
  EXPECT_EQ(entries, 2u);
}

// Without commit() nothing reaches the destinations.
TEST(Outputs, UncommittedSetLeavesNothing) {
  const std::string dir = tempDir("outputs_uncommitted");
  {
    OutputSet out;
    out.addExr(dir + "/a.exr", rampFilm(4, 4, true), {});
    out.addPreviewPng(dir + "/a.png", rampFilm(4, 4, true));
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

// A PNG that cannot be written whole (here a file-size limit; a full disk
// alike) is an error naming it, and the previous file stays as it was with
// no temporary left: stbi_write_png ignored fwrite's and fclose's results,
// so a cut PNG replaced a good one and the write "succeeded". The same for
// the text files (compare's SVG and JSON, fit's coefficients).
TEST(Outputs, PreviewWriteFailureKeepsThePreviousPreview) {
  const std::string dir = tempDir("outputs_png_limit");
  const std::string png = dir + "/preview.png", svg = dir + "/sheet.svg";
  const int w = 200, h = 100;
  std::vector<unsigned char> noise(size_t(w) * h * 3);
  uint32_t x = 1;
  for (unsigned char& b : noise) b = (unsigned char)((x = x * 1664525u + 1013904223u) >> 24);
  writePngRgb8(png, w, h, noise.data());
  writeTextFile(svg, "<svg/>\n");
  const std::string good = fileBytes(png), goodSvg = fileBytes(svg);
  ASSERT_GT(good.size(), 16384u);
  std::reverse(noise.begin(), noise.end());
  const int code = inChildWithFileLimit(4096, [&] {
    try {
      writePngRgb8(png, w, h, noise.data());
    } catch (const Error& e) {
      const std::string m = e.what();
      if (m.find(png) == std::string::npos || m.find("File too large") == std::string::npos) return 3;
      try {
        writeTextFile(svg, std::string(8192, 'x'));
      } catch (const Error& e2) {
        return std::string(e2.what()).find(svg) == std::string::npos ? 4 : 2;
      }
      return 5;
    }
    return 0;
  });
  EXPECT_EQ(code, 2) << "0: the cut PNG was reported written; 3/4: the message does not name the file; 5: the text write";
  EXPECT_EQ(fileBytes(png), good);
  EXPECT_EQ(fileBytes(svg), goodSvg);
  EXPECT_EQ(otherFiles(dir, {"preview.png", "sheet.svg"}), std::vector<std::string>{});
}

// The same through the CLI: a render whose EXR fits but whose --preview
// does not exits 1 with one line naming the preview, and both the previous
// pass and preview are kept. The camera looks away from the scene's one
// triangle, so the image is flat: OpenEXR's zlib packs 1000 x 1000 pixels
// into 20 kB, stb's PNG encoder into 29 kB; the limit is between.
TEST(Outputs, CliPreviewWriteFailureExitsNonZero) {
  const std::string dir = tempDir("outputs_cli_png_limit");
  const std::string scene = dir + "/away.gltf";
  {
    std::ofstream f(scene);
    f << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],)"
         R"("nodes":[{"mesh":0},{"camera":0,"translation":[0,0,-5]}],)"
         R"("cameras":[{"type":"perspective","perspective":{"yfov":0.8,"znear":0.01}}],)"
         R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
         R"("buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],)"
         R"("bufferViews":[{"buffer":0,"byteLength":36}],)"
         R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]})";
  }
  const std::string exr = dir + "/pass.exr", png = dir + "/pass.png";
  std::vector<std::string> args = {"render", scene, "-o", exr, "--preview", png, "--res", "1000x1000", "--spp", "1", "--no-aovs", "-q"};
  ASSERT_EQ(runCli(args, dir + "/e0.txt").exitCode, 0);
  const std::string goodExr = fileBytes(exr), goodPng = fileBytes(png);
  ASSERT_LT(goodExr.size(), 24000u);
  ASSERT_GT(goodPng.size(), 26000u);
  args.insert(args.end(), {"--seed", "7"});
  const CliResult r = runCliWithFileLimit(args, dir + "/e1.txt", 24000);
  EXPECT_EQ(r.exitCode, 1) << r.stderrText;
  EXPECT_NE(r.stderrText.find(png + ": write failed: File too large"), std::string::npos) << r.stderrText;
  EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  EXPECT_EQ(fileBytes(exr), goodExr);
  EXPECT_EQ(fileBytes(png), goodPng);
  EXPECT_EQ(otherFiles(dir, {"away.gltf", "pass.exr", "pass.png", "e0.txt", "e1.txt"}), std::vector<std::string>{});
}

// An output name that fits the file system but not the hidden temporary
// written beside it (".NAME.tmpPID", 12 bytes more) is refused before the
// scene loads, naming the option and the limit; it used to fail after the
// render reached 100 %. The longest name that fits still renders.
TEST(Outputs, LongOutputNamesAreRefusedBeforeLoading) {
  const std::string dir = tempDir("outputs_long_names");
  const std::string scene = sourcePath("scenes/default.gltf");
  const auto name = [&](size_t bytes, const std::string& ext) { return dir + "/" + std::string(bytes - ext.size(), 'n') + ext; };
  const std::string missing = dir + "/no_such_scene.gltf";  // an error about it would mean the scene was read first
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"-o", name(250, ".exr")}, "-o " + name(250, ".exr") + ": the file name is 250 bytes; at most 243 fit"},
      {{"-o", name(255, ".exr")}, "the file name is 255 bytes; at most 243 fit (the file system's limit of 255 bytes"},
      {{"-o", dir + "/p.exr", "--preview", name(249, ".png")}, "--preview " + name(249, ".png") + ": the file name is 249"},
      {{"-o", name(241, ".exr"), "--checkpoint", "5"}, "--checkpoint: " + name(241, ".exr") + ".checkpoint.tmp: the file name is 256 bytes; at most 255"},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args = {"render", missing, "-q", "--res", "16x9", "--spp", "1"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const CliResult r = runCli(args, dir + "/err" + std::to_string(k++) + ".txt");
    EXPECT_EQ(r.exitCode, 1) << c.says << ": " << r.stderrText;
    EXPECT_NE(r.stderrText.find(c.says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
  const std::string longest = name(243, ".exr");
  const CliResult ok = runCli({"render", scene, "-o", longest, "--preview", name(243, ".png"), "-q", "--res", "16x9", "--spp", "1"},
                              dir + "/ok.txt");
  EXPECT_EQ(ok.exitCode, 0) << ok.stderrText;
  EXPECT_TRUE(std::filesystem::exists(longest));
}

// An output that names a file the command reads is refused before any
// work, naming both options, and the input is left as it was: a height map
// (--displace, containment's map= by -p or --pass), an environment map, a
// merge tile. merge also refuses an output not named .exr (it writes
// OpenEXR). All of these used to exit 0 having replaced the input.
TEST(Outputs, OutputEqualToAnInputIsRefused) {
  const std::string dir = tempDir("outputs_inputs");
  const std::string scene = sourcePath("scenes/default.gltf");
  const std::string h = dir + "/h.exr", env = dir + "/env.exr", t0 = dir + "/t0.exr", t1 = dir + "/t1.exr";
  const std::vector<float> rgb(8 * 4 * 3, 0.5f);
  for (const std::string& f : {h, env, t0, t1}) writeRgbExr(f, 8, 4, rgb, {});
  std::map<std::string, std::string> before;
  for (const std::string& f : {h, env, t0, t1}) before[f] = fileBytes(f);
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"render", scene, "-o", h, "--displace", h}, "-o " + h + ": is the same file as --displace " + h},
      {{"render", scene, "-o", dir + "/./h.exr", "-i", "containment", "-p", "distance=1", "-p", "map=" + h}, "is the same file as -p map= " + h},
      {{"render", scene, "-o", h, "--pass", "c=containment:distance=1,map=" + h}, "is the same file as --pass c:map= " + h},
      {{"render", scene, "-o", dir + "/p.exr", "--preview", env, "--environment", env}, "--preview " + env + ": is the same file as --environment"},
      {{"render", scene, "-o", env, "--environment", env}, "-o " + env + ": is the same file as --environment " + env},
      {{"merge", t1, t0, t1}, "merge: OUT.exr " + t1 + ": is the same file as TILE 2 " + t1},
      {{"merge", dir + "/full.png", t0, t1}, "merge: OUT.exr " + dir + "/full.png: must end in .exr"},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args = c.args;
    args.push_back(args[0] == "render" ? "-q" : t1);
    if (args[0] == "merge") args.pop_back();
    const CliResult r = runCli(args, dir + "/err" + std::to_string(k++) + ".txt");
    EXPECT_EQ(r.exitCode, 1) << c.says << ": " << r.stderrText;
    EXPECT_NE(r.stderrText.find(c.says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
  for (const auto& [f, bytes] : before) EXPECT_EQ(fileBytes(f), bytes) << f;
  EXPECT_FALSE(std::filesystem::exists(dir + "/full.png"));
}

// A disk that fills at the EXR's last bytes (here a file-size limit one
// byte short of the file) is an error naming the file, and the previous EXR
// stays as it was with no temporary left. OpenEXR's own stream flushed its
// last buffer, and wrote the line-offset table, in ~OutputFile, where errors
// are swallowed: the cut file was renamed over the good one, "written".
TEST(Outputs, ExrFinalFlushFailureKeepsThePreviousFile) {
  const std::string dir = tempDir("outputs_exr_final_flush");
  const std::string exr = dir + "/pass.exr";
  // A small file (RGBA, 4 pixels wide, uncompressed: the same size for any
  // pixels): every write fits a stream buffer, so the bytes reach the disk
  // only when the file is flushed and closed at the end.
  ExrOptions o;
  o.compression = ExrCompression::None;
  writeExr(exr, rampFilm(4, 48, false), o);
  const std::string good = fileBytes(exr);
  Film other = rampFilm(4, 48, false);
  for (int c : other.channels()) other.at(c, 3, 5) += 1.0f;
  // In this process (OpenEXR's thread pool does not survive a fork): the
  // soft limit lowered for the one write, then restored.
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  const auto oldHandler = signal(SIGXFSZ, SIG_IGN);
  rlimit cut = saved;
  cut.rlim_cur = rlim_t(good.size() - 1);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &cut), 0);
  std::string message = "(none: the cut EXR was reported written)";
  try {
    writeExr(exr, other, o);
  } catch (const Error& e) {
    message = e.what();
  }
  setrlimit(RLIMIT_FSIZE, &saved);
  signal(SIGXFSZ, oldHandler);
  EXPECT_NE(message.find(exr + ": write failed: File too large"), std::string::npos) << message;
  EXPECT_TRUE(fileBytes(exr) == good) << "the previous EXR was replaced (" << fileBytes(exr).size() << " of " << good.size()
                                      << " bytes)";
  EXPECT_EQ(otherFiles(dir, {"pass.exr"}), std::vector<std::string>{});
  // Without the limit the same write lands, whole.
  writeExr(exr, other, o);
  EXPECT_EQ(fileBytes(exr).size(), good.size());
  EXPECT_EQ(readExr(exr).planes.at("R")[5 * 4 + 3], other.at(kR, 3, 5));
}

namespace {

std::vector<std::string> smallRender(const std::string& exr, const std::string& png, int seed) {
  return {"render", sourcePath("scenes/default.gltf"), "-o", exr, "--preview", png, "--res", "48x32", "--spp", "1",
          "--seed", std::to_string(seed), "-q"};
}
}  // namespace

// A process killed with its temporaries written (SIGKILL, the OOM killer)
// leaves ".NAME.tmpPID" files as large as the outputs; the next write of the
// same output removes them (their process is gone) and leaves only its own
// files.
TEST(Outputs, KilledWriteTemporariesAreRemovedByTheNextWrite) {
  const std::string dir = tempDir("outputs_killed_tmp");
  const std::string exr = dir + "/out.exr", png = dir + "/out.png";
  {
    const ScopedEnv kill("OBSCURA_TEST_COMMIT", "kill");
    const CliResult k = runCli(smallRender(exr, png, 1), dir + "/kill.txt");
    ASSERT_EQ(k.signal, SIGKILL) << k.stderrText;
  }
  const std::vector<std::string> left = otherFiles(dir, {"kill.txt"});
  ASSERT_EQ(left.size(), 2u);
  for (const std::string& f : left) EXPECT_TRUE(f.rfind(".out.exr.tmp", 0) == 0 || f.rfind(".out.png.tmp", 0) == 0) << f;
  const CliResult r = runCli(smallRender(exr, png, 1), dir + "/again.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  EXPECT_EQ(otherFiles(dir, {"kill.txt", "again.txt", "out.exr", "out.png"}), std::vector<std::string>{});
}

// Two processes writing the same -o and --preview: each pass lands with its
// own preview. The first is held between its two moves (its EXR in place,
// its PNG not yet) while the second renders and commits; without a lock
// around the moves the second's pair landed in between and the first's PNG
// came last, beside the second's EXR.
TEST(Outputs, ConcurrentWritersLandTheirPairsWhole) {
  const std::string dir = tempDir("outputs_concurrent");
  const std::string exr = dir + "/out.exr", png = dir + "/out.png";
  // Each seed's pair, written alone.
  for (int seed : {1, 2})
    ASSERT_EQ(runCli(smallRender(dir + "/ref" + std::to_string(seed) + ".exr", dir + "/ref" + std::to_string(seed) + ".png", seed),
                     dir + "/ref.txt").exitCode, 0);
  ASSERT_NE(fileBytes(dir + "/ref1.png"), fileBytes(dir + "/ref2.png"));
  CliResult first, second;
  pid_t a = 0;
  {
    const ScopedEnv pause("OBSCURA_TEST_COMMIT", "pause:3");
    a = startCli(smallRender(exr, png, 1), dir + "/a.txt", first);
  }
  // The first has moved its EXR and is held before its PNG.
  for (int i = 0; i < 600 && !std::filesystem::exists(exr); ++i) usleep(10000);
  ASSERT_TRUE(std::filesystem::exists(exr));
  EXPECT_FALSE(std::filesystem::exists(png));
  const CliResult b = runCli(smallRender(exr, png, 2), dir + "/b.txt");
  finishCli(a, dir + "/a.txt", first);
  ASSERT_EQ(first.exitCode, 0) << first.stderrText;
  ASSERT_EQ(b.exitCode, 0) << b.stderrText;
  // The second committed last, both files.
  const std::string landed = fileBytes(png);
  EXPECT_TRUE(landed == fileBytes(dir + "/ref2.png"))
      << (landed == fileBytes(dir + "/ref1.png") ? "the first process's PNG beside the second's EXR" : "a PNG of neither");
  EXPECT_EQ(readExr(exr).planes.at("R"), readExr(dir + "/ref2.exr").planes.at("R"));
}

// An output that is a file the scene names - an external buffer, an image
// (a texture or cut-out), a height map of extras.obscura.displacement.map,
// in a .gltf or a .glb - is refused before any work like the other inputs,
// naming the scene and the field; so is a compare directory whose report
// files would replace one. These outputs used to be written over the input.
TEST(Outputs, OutputEqualToAFileTheSceneNamesIsRefused) {
  const std::string dir = tempDir("outputs_scene_files");
  const std::vector<float> rgb(8 * 4 * 3, 0.5f);
  writeRgbExr(dir + "/h.exr", 8, 4, rgb, {});
  std::filesystem::create_directories(dir + "/report");
  std::filesystem::create_directories(dir + "/page/report_data");
  const std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};  // never decoded here
  writeBytes(dir + "/tex.png", png.data(), png.size());
  writeBytes(dir + "/report/contact_sheet.png", png.data(), png.size());
  writeBytes(dir + "/page/report_data/t.png", png.data(), png.size());
  GltfBuilder g;
  const int mesh = g.quadMesh(1.0f, -1, true);
  g.doc["meshes"][size_t(mesh)]["extras"] = {{"obscura", {{"subdivision", {{"level", 1}}}, {"displacement", {{"map", "h.exr"}}}}}};
  g.doc["images"] = json::array({{{"uri", "tex.png"}}, {{"uri", "report/contact_sheet.png"}}, {{"uri", "page/report_data/t.png"}}});
  g.scene({g.node({{"mesh", mesh}})});
  const std::string gltf = g.writeGltf(dir, "s"), glb = g.writeGlb(dir, "b");
  const std::string bin = dir + "/s.bin", tex = dir + "/tex.png", h = dir + "/h.exr", sheet = dir + "/report/contact_sheet.png";
  const std::string pageData = dir + "/page/report_data/t.png";
  std::map<std::string, std::string> before;
  for (const std::string& f : {gltf, glb, bin, tex, h, sheet, pageData}) before[f] = fileBytes(f);
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"render", gltf, "-o", bin}, "-o " + bin + ": is the same file as " + gltf + " buffers[0] " + bin},
      {{"render", gltf, "-o", dir + "/p.exr", "--preview", tex}, "--preview " + tex + ": is the same file as " + gltf + " images[0] " + tex},
      {{"render", gltf, "-o", h}, "-o " + h + ": is the same file as " + gltf + " meshes[0].extras.obscura.displacement.map " + h},
      {{"render", glb, "-o", tex}, "-o " + tex + ": is the same file as " + glb + " images[0] " + tex},
      {{"compare", gltf, "-o", dir + "/report", "-c", "ao"},
       "-o " + dir + "/report: compare writes " + dir + "/report/contact_sheet.png, which is " + gltf + " images[1] " + sheet},
      {{"compare", gltf, "-o", dir + "/page", "-c", "ao"},
       "-o " + dir + "/page: compare writes " + dir + "/page/report_data/t.png, which is " + gltf + " images[2] " + pageData},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args = c.args;
    args.push_back("-q");
    const CliResult r = runCli(args, dir + "/err" + std::to_string(k++) + ".txt");
    EXPECT_EQ(r.exitCode, 1) << c.says << ": " << r.stderrText;
    EXPECT_NE(r.stderrText.find(c.says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
  for (const auto& [f, bytes] : before) EXPECT_EQ(fileBytes(f), bytes) << f;
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.exr"));
}

// Bands of 64 scanlines: a film of several bands and a ragged last band
// round-trips every value of every channel.
TEST(Outputs, BandedExrRoundTripsEveryPixel) {
  const std::string dir = tempDir("outputs_bands");
  const Film film = rampFilm(37, 64 * 3 + 5, true);
  writeExr(dir + "/b.exr", film, {});
  const ReadBack r = readExr(dir + "/b.exr");
  ASSERT_TRUE(r.ok);
  for (int c : film.channels()) {
    const std::vector<float>& p = r.planes.at(film.name(c));
    for (int y = 0; y < film.height(); ++y)
      for (int x = 0; x < film.width(); ++x)
        ASSERT_EQ(p[size_t(y) * film.width() + x], film.at(c, x, y)) << film.name(c) << " " << x << "," << y;
  }
}

// The CLI refuses, before loading or rendering, outputs that would clobber
// the scene or each other or cannot be written, and a film that does not fit
// in memory; a good existing pass is left as it was.
TEST(Outputs, CliRefusesBadOutputsBeforeRendering) {
  const std::string dir = tempDir("outputs_cli");
  const std::string scene = sourcePath("scenes/default.gltf");
  const std::string exr = dir + "/good.exr";
  ASSERT_EQ(runCli({"render", scene, "-o", exr, "--res", "16x9", "--spp", "1", "-q"}, dir + "/e0.txt").exitCode, 0);
  const std::string good = fileBytes(exr);
  std::filesystem::create_directories(dir + "/a_directory");
  const std::string sceneCopy = dir + "/scene.gltf";
  std::filesystem::copy_file(scene, sceneCopy);
  const std::string sceneBytes = fileBytes(sceneCopy);
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"--preview", exr}, "same file as -o"},
      {{"--preview", dir + "/a_directory"}, "it is a directory"},
      {{"--preview", dir + "/missing/p.png"}, "does not exist"},
      {{"--res", "60000x60000"}, "--res 60000x60000: the film needs"},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args = {"render", scene, "-o", exr, "-q"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const CliResult r = runCli(args, dir + "/err" + std::to_string(k++) + ".txt");
    EXPECT_EQ(r.exitCode, 1) << c.says << ": " << r.stderrText;
    EXPECT_NE(r.stderrText.find(c.says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
    EXPECT_EQ(fileBytes(exr), good) << c.says;
  }
  // -o naming the scene itself (via another spelling of its path).
  const CliResult r = runCli({"render", sceneCopy, "-o", dir + "/./scene.gltf", "-q"}, dir + "/errs.txt");
  EXPECT_EQ(r.exitCode, 1) << r.stderrText;
  EXPECT_NE(r.stderrText.find("is the scene file"), std::string::npos) << r.stderrText;
  EXPECT_EQ(fileBytes(sceneCopy), sceneBytes);
}


namespace {

uint32_t bigEndian32(const std::string& b, size_t at) {
  return uint32_t((unsigned char)b[at]) << 24 | uint32_t((unsigned char)b[at + 1]) << 16 |
         uint32_t((unsigned char)b[at + 2]) << 8 | uint32_t((unsigned char)b[at + 3]);
}

struct PngChunk {
  std::string type, data;
};

// The chunks of a PNG file, each CRC checked (a failure is reported and
// the chunk still listed).
std::vector<PngChunk> pngChunks(const std::string& file) {
  std::vector<PngChunk> chunks;
  EXPECT_EQ(file.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  for (size_t at = 8; at + 12 <= file.size();) {
    const uint32_t n = bigEndian32(file, at);
    if (at + 12 + n > file.size()) {
      ADD_FAILURE() << "chunk at " << at << " runs past the end";
      break;
    }
    PngChunk c{file.substr(at + 4, 4), file.substr(at + 8, n)};
    EXPECT_EQ(bigEndian32(file, at + 8 + n), bitwiseCrc32(reinterpret_cast<const unsigned char*>(file.data()) + at + 4, n + 4))
        << c.type << " chunk's CRC";
    chunks.push_back(std::move(c));
    at += 12 + n;
  }
  return chunks;
}

// Every PNG Obscura writes holds sRGB-encoded bytes (linearToSrgb8), so it
// says so: sRGB after IHDR, with the gAMA and cHRM the PNG specification
// pairs with it for decoders that ignore sRGB, every CRC right, and the
// pixels read back unchanged through libpng (OpenImageIO).
void expectSrgbPng(const std::string& path, int w, int h, const std::vector<unsigned char>* rgb) {
  SCOPED_TRACE(path);
  const std::vector<PngChunk> chunks = pngChunks(fileBytes(path));
  std::vector<std::string> order;
  for (const PngChunk& c : chunks)
    if (order.empty() || order.back() != c.type) order.push_back(c.type);
  EXPECT_EQ(order, (std::vector<std::string>{"IHDR", "cHRM", "gAMA", "sRGB", "IDAT", "IEND"}));
  for (const PngChunk& c : chunks) {
    if (c.type == "sRGB") {
      EXPECT_EQ(c.data, std::string(1, '\0'));  // rendering intent 0: perceptual
    }
    if (c.type == "gAMA") {
      ASSERT_EQ(c.data.size(), 4u);
      EXPECT_EQ(bigEndian32(c.data, 0), 45455u);  // 1/2.2 x 100000, the spec's value with sRGB
    }
    if (c.type == "cHRM") {
      ASSERT_EQ(c.data.size(), 32u);
      // White D65, then red, green, blue: Rec.709 (x, y) x 100000.
      const uint32_t want[8] = {31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000};
      for (int k = 0; k < 8; ++k) EXPECT_EQ(bigEndian32(c.data, size_t(4 * k)), want[k]) << "cHRM value " << k;
    }
  }
  auto in = OIIO::ImageInput::open(path);
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.width, w);
  EXPECT_EQ(spec.height, h);
  EXPECT_EQ(spec.get_string_attribute("oiio:ColorSpace"), "sRGB");
  std::vector<unsigned char> back(size_t(w) * h * 3);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, back.data())) << in->geterror();
  EXPECT_FALSE(in->has_error()) << in->geterror();
  if (rgb) {
    EXPECT_EQ(back, *rgb);
  }
}

}  // namespace

// Issue #37: the preview PNG carried no colour-space chunk.
TEST(Outputs, PngsAreTaggedSrgb) {
  // The closed form the CRC check rests on: every PNG ends in IEND's CRC.
  EXPECT_EQ(bitwiseCrc32(reinterpret_cast<const unsigned char*>("IEND"), 4), 0xAE426082u);
  const std::string dir = tempDir("outputs_png_srgb");
  const int w = 7, h = 5;
  std::vector<unsigned char> rgb(size_t(w) * h * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = (unsigned char)(i * 37 % 256);
  writePngRgb8(dir + "/bytes.png", w, h, rgb.data());
  expectSrgbPng(dir + "/bytes.png", w, h, &rgb);

  Film film(w, h, false);
  for (int c = 0; c < 3; ++c)
    for (int p = 0; p < w * h; ++p) film.plane(kR + c)[p] = float(p % 11) / 10.0f * (c + 1) / 3.0f;
  writePreviewPng(dir + "/preview.png", film);
  std::vector<unsigned char> want(size_t(w) * h * 3);
  for (int p = 0; p < w * h; ++p)
    for (int c = 0; c < 3; ++c) want[size_t(p) * 3 + c] = linearToSrgb8(film.plane(kR + c)[p]);
  expectSrgbPng(dir + "/preview.png", w, h, &want);

  // And the CLI's --preview.
  const CliResult r = runCli({"render", sourcePath("scenes/default.gltf"), "-o", dir + "/pass.exr", "--preview",
                              dir + "/cli.png", "--res", "24x16", "--spp", "1", "-q"},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  expectSrgbPng(dir + "/cli.png", 24, 16, nullptr);
}

}  // namespace
}  // namespace obscura::test
