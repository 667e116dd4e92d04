// The render's outputs as a unit: a pass and its preview land together or not
// at all, outputs are checked before the render (writable, not the scene, not
// each other), a film larger than the available memory is refused up front,
// and the EXR is written in bands (large images round-trip).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "core/util/large_vector.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

std::string fileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
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

}  // namespace
}  // namespace obscura::test
