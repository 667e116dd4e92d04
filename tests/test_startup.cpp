// Start-up and the EXR writer (docs/performance.md "Start-up and file speed"): the
// program does not load OpenImageIO (its module is dlopen'ed when a format
// needs it, and its absence is one error line), and every --compression
// writes the same pixels, named in the header's standard attribute.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include <obscura/error.h>
#include "core/image/image_io.h"
#include "core/image/metrics.h"
#include "tests/support.h"

namespace obscura::test {
namespace {
namespace fs = std::filesystem;

// Runs a shell command; its stdout and stderr, and its exit status.
std::pair<std::string, int> shell(const std::string& command) {
  std::FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return {"popen failed", -1};
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int status = pclose(p);
  return {out, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
}

// The libraries the dynamic loader maps for the program (what ldd lists).
TEST(Startup, ProgramDoesNotLoadOpenImageIO) {
  const auto [libs, code] = shell(std::string("LD_TRACE_LOADED_OBJECTS=1 '") + obscuraBinary() + "'");
  ASSERT_EQ(code, 0) << libs;
  EXPECT_NE(libs.find("libobscura.so"), std::string::npos) << libs;
  EXPECT_NE(libs.find("libOpenEXR"), std::string::npos) << libs;
  EXPECT_EQ(libs.find("OpenImageIO"), std::string::npos) << libs;
}

// libobscura looks for the module beside itself: a copy of the library in a
// folder without the module makes `merge` (which needs OpenImageIO) fail
// with one line naming the tile and the module, and exit 1.
TEST(Startup, MissingOiioModuleIsOneErrorLine) {
  const std::string dir = tempDir("startup_no_module");
  // Every name of the library (the soname the program needs among them).
  for (const auto& e : fs::directory_iterator(fs::path(obscuraBinary()).parent_path()))
    if (e.path().filename().string().rfind("libobscura.so", 0) == 0)
      fs::copy_file(fs::canonical(e.path()), fs::path(dir) / e.path().filename(), fs::copy_options::overwrite_existing);
  Film film(4, 4, false);
  writeExr(dir + "/tile.exr", film, {});
  const auto [text, code] = shell("LD_LIBRARY_PATH='" + dir + "' '" + std::string(obscuraBinary()) + "' merge '" + dir + "/out.exr' '" + dir +
                                  "/tile.exr'");
  EXPECT_EQ(code, 1) << text;
  EXPECT_EQ(text.rfind("obscura: error: " + dir + "/tile.exr: reading this file needs OpenImageIO", 0), 0u) << text;
  EXPECT_NE(text.find("libobscura_oiio.so"), std::string::npos) << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
  EXPECT_FALSE(fs::exists(dir + "/out.exr"));
}

// Every compression is lossless: the same render written with each holds
// the same bits in every channel (float and, with --half, half), and the
// header names the compression.
TEST(ExrWrite, EveryCompressionWritesTheSamePixels) {
  const std::string dir = tempDir("exr_compression");
  const char* names[] = {"none", "rle", "zips", "zip", "piz"};
  for (const bool half : {false, true}) {
    std::vector<std::vector<std::string>> runs;
    for (const char* n : names) {
      std::vector<std::string> args = {"render", sourcePath("scenes/default.gltf"), "-o",
                                       dir + "/" + n + (half ? "_half" : "") + ".exr", "--res", "48x27", "--spp", "2",
                                       "--quiet", "--compression", n == std::string("piz") ? "PIZ" : n};
      if (half) args.push_back("--half");
      runs.push_back(args);
    }
    const std::vector<CliResult> results = runClis(runs, dir);
    for (size_t i = 0; i < results.size(); ++i) ASSERT_EQ(results[i].exitCode, 0) << names[i] << results[i].stderrText;
    const ReadBack zip = readExr(dir + "/zip" + (half ? "_half" : "") + ".exr");
    ASSERT_TRUE(zip.ok);
    EXPECT_EQ(zip.planes.size(), size_t(kChannelCount) + 2);  // the fixed channels, W_error and spp
    // Under --half, spp stays float: half holds integers exactly only to 2048.
    const int sppIndex = zip.spec.channelindex(kSppPlane);
    ASSERT_GE(sppIndex, 0);
    EXPECT_EQ(zip.spec.channelformat(sppIndex), OIIO::TypeDesc(OIIO::TypeDesc::FLOAT));
    for (const char* n : names) {
      SCOPED_TRACE(std::string(n) + (half ? " half" : ""));
      const ReadBack r = readExr(dir + "/" + n + (half ? "_half" : "") + ".exr");
      ASSERT_TRUE(r.ok);
      EXPECT_EQ(r.spec.get_string_attribute("compression"), n);
      for (const auto& [name, plane] : zip.planes) {
        ASSERT_TRUE(r.planes.count(name)) << name;
        EXPECT_TRUE(r.planes.at(name) == plane) << name;
      }
    }
  }
}

TEST(ExrWrite, UnknownCompressionIsACommandLineError) {
  const std::string dir = tempDir("exr_compression_bad");
  const CliResult r = runCli({"render", "-o", dir + "/x.exr", "--compression", "dwaa", "--quiet"}, dir + "/stderr.txt");
  EXPECT_EQ(r.exitCode, 2) << r.stderrText;
  EXPECT_NE(r.stderrText.find("--compression"), std::string::npos) << r.stderrText;
  EXPECT_THROW(exrCompressionFromName("b44", "--compression"), Error);
  for (const auto c : {ExrCompression::None, ExrCompression::Rle, ExrCompression::Zips, ExrCompression::Zip, ExrCompression::Piz})
    EXPECT_EQ(exrCompressionFromName(exrCompressionName(c), "x"), c);
}

// readPass reads a region render's data window (through OpenEXR) and an
// image in another format (through the module) alike.
TEST(ExrWrite, ReadPassFromExrWindowAndFromPng) {
  const std::string dir = tempDir("read_pass");
  Film film(PixelRect{3, 2, 10, 7}, 16, 9, false);
  for (int c : film.channels())
    for (int y = 2; y < 7; ++y)
      for (int x = 3; x < 10; ++x) film.at(c, x, y) = float(c) + 0.125f * float(x) + 0.0625f * float(y);
  writeExr(dir + "/w.exr", film, {});
  const PassImage p = readPass(dir + "/w.exr");
  ASSERT_EQ(p.width, 7);
  ASSERT_EQ(p.height, 5);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) {
      const size_t i = size_t(y) * 7 + size_t(x);
      EXPECT_EQ(p.r[i], film.at(kR, x + 3, y + 2));
      EXPECT_EQ(p.a[i], film.at(kA, x + 3, y + 2));
    }
  EXPECT_EQ(readExrAttribute(dir + "/w.exr", "obscura:nothing"), "");
  // A PNG: OpenImageIO reads it (8-bit values v / 255).
  std::vector<unsigned char> rgb(4 * 3 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = (unsigned char)(i * 7);
  writePngRgb8(dir + "/p.png", 4, 3, rgb.data());
  try {
    readPass(dir + "/p.png");
    ADD_FAILURE() << "a PNG has no A channel";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("channel A is missing"), std::string::npos) << e.what();
  }
  const ReadBack png = readExr(dir + "/p.png");
  ASSERT_TRUE(png.ok);
  for (size_t i = 0; i < 12; ++i) EXPECT_FLOAT_EQ(png.planes.at("G")[i], float(rgb[3 * i + 1]) / 255.0f);
}

}  // namespace
}  // namespace obscura::test
