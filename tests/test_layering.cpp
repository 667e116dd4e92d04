// The shape of the code, checked (docs/architecture.md "Layers"):
// - core/ is six subsystems, each a folder, ranked util < image < subd <
//   scene < load < render; a file may include its own folder and the ones
//   below it, never one above (the CMake OBJECT libraries link in the same
//   order, but they share one include root, so only this test sees an
//   include against the grain);
// - the core names no integrator and no front end: nothing in core/ or
//   include/ includes integrators/, app/, python/, oiio/, plugins/, bench/
//   or tests/;
// - include/obscura/, the plugin SDK and the only installed headers,
//   includes only itself and the standard library (no Embree, TBB or core
//   header), and so do the plugins built against it (plugins/);
// - the ABI version has one definition (include/obscura/plugin.h), which
//   docs/plugins.md's ABI history reaches.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <obscura/plugin.h>
#include "tests/support.h"

namespace obscura::test {
namespace {

namespace fs = std::filesystem;

const fs::path kRoot(sourceDir());

// The subsystems of core/ from the bottom up.
const std::map<std::string, int> kRank = {{"util", 0}, {"subd", 2},  {"image", 1},
                                          {"scene", 3}, {"load", 4}, {"render", 5}};

struct Include {
  int line;
  bool angle;        // <...> rather than "..."
  std::string path;  // as written
};

std::vector<Include> includesOf(const fs::path& file) {
  std::ifstream in(file);
  std::vector<Include> out;
  const std::regex inc(R"(^\s*#\s*include\s*([<"])([^>"]+)[>"])");
  int n = 0;
  for (std::string line; std::getline(in, line);) {
    ++n;
    std::smatch m;
    if (std::regex_search(line, m, inc)) out.push_back({n, m[1] == "<", m[2]});
  }
  return out;
}

std::vector<fs::path> sourcesUnder(const fs::path& dir) {
  std::vector<fs::path> files;
  if (!fs::exists(dir)) return files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".h" || ext == ".cpp")) files.push_back(e.path());
  }
  return files;
}

std::string rel(const fs::path& p) { return fs::relative(p, kRoot).string(); }

// A header of the standard library or the compiler's intrinsics.
bool standardHeader(const Include& i) {
  static const std::regex std_(R"([a-z_]+)"), intrin(R"([a-z]*mmintrin\.h)");
  return i.angle && (std::regex_match(i.path, std_) || std::regex_match(i.path, intrin));
}

bool sdkHeader(const Include& i) {
  static const std::regex sdk(R"(obscura/[a-z_]+\.h)");
  return std::regex_match(i.path, sdk);
}

// What `i` may not include from anywhere in core/ or include/.
bool frontEndOrIntegrator(const std::string& path) {
  for (const char* dir : {"integrators/", "app/", "python/", "oiio/", "plugins/", "bench/", "tests/", "fuzz/"})
    if (path.rfind(dir, 0) == 0) return true;
  return false;
}

TEST(Layering, CoreIncludesOnlyItsOwnLayerAndTheOnesBelow) {
  size_t checked = 0;
  for (const auto& [layer, rank] : kRank) {
    for (const fs::path& file : sourcesUnder(kRoot / "core" / layer)) {
      for (const Include& i : includesOf(file)) {
        ++checked;
        EXPECT_FALSE(frontEndOrIntegrator(i.path)) << rel(file) << ":" << i.line << " includes " << i.path;
        if (i.path.rfind("core/", 0) != 0) continue;
        const std::string other = i.path.substr(5, i.path.find('/', 5) - 5);
        const auto it = kRank.find(other);
        if (it == kRank.end()) {
          ADD_FAILURE() << rel(file) << ":" << i.line << " includes " << i.path << ", in no subsystem of core/";
          continue;
        }
        EXPECT_LE(it->second, rank) << rel(file) << ":" << i.line << " (" << layer << ") includes " << i.path
                                    << ": " << other << " is above " << layer << " (util < image < subd < "
                                    << "scene < load < render)";
      }
    }
  }
  EXPECT_GT(checked, 100u) << "the walk found almost no includes: is OBSCURA_SOURCE_DIR right?";
  // Nothing but the six folders in core/.
  for (const auto& e : fs::directory_iterator(kRoot / "core"))
    EXPECT_TRUE(e.is_directory() && kRank.count(e.path().filename().string()))
        << rel(e.path()) << ": core/ holds only the subsystem folders";
}

TEST(Layering, SdkHeadersIncludeOnlyTheSdkAndTheStandardLibrary) {
  const std::vector<fs::path> headers = sourcesUnder(kRoot / "include" / "obscura");
  ASSERT_GE(headers.size(), 10u);
  for (const fs::path& file : headers) {
    EXPECT_EQ(file.extension(), ".h") << rel(file) << ": only headers in include/obscura/";
    for (const Include& i : includesOf(file))
      EXPECT_TRUE(standardHeader(i) || (i.angle && sdkHeader(i)))
          << rel(file) << ":" << i.line << " includes " << (i.angle ? "<" : "\"") << i.path
          << (i.angle ? ">" : "\"") << ": the SDK may include only <obscura/...> and the standard library";
  }
}

TEST(Layering, PluginsBuildAgainstTheSdkAlone) {
  const std::vector<fs::path> files = sourcesUnder(kRoot / "plugins");
  ASSERT_FALSE(files.empty());
  for (const fs::path& file : files)
    for (const Include& i : includesOf(file))
      EXPECT_TRUE(standardHeader(i) || (i.angle && sdkHeader(i)))
          << rel(file) << ":" << i.line << " includes " << i.path;
}

TEST(Layering, IntegratorsUseNoFrontEnd) {
  for (const fs::path& file : sourcesUnder(kRoot / "integrators"))
    for (const Include& i : includesOf(file))
      for (const char* dir : {"app/", "python/", "bench/", "tests/"})
        EXPECT_NE(i.path.rfind(dir, 0), 0u) << rel(file) << ":" << i.line << " includes " << i.path;
}

// The check above sees every kind of offence (a rule that can never fail
// checks nothing).
TEST(Layering, TheChecksSeeEachKindOfOffence) {
  EXPECT_FALSE(standardHeader({1, true, "embree3/rtcore.h"}));
  EXPECT_FALSE(standardHeader({1, true, "tbb/parallel_for.h"}));
  EXPECT_FALSE(standardHeader({1, false, "vector"}));
  EXPECT_TRUE(standardHeader({1, true, "vector"}));
  EXPECT_TRUE(standardHeader({1, true, "emmintrin.h"}));
  EXPECT_FALSE(sdkHeader({1, true, "core/scene/scene.h"}));
  EXPECT_FALSE(sdkHeader({1, true, "obscura/../core/x.h"}));
  EXPECT_TRUE(sdkHeader({1, true, "obscura/math.h"}));
  EXPECT_TRUE(frontEndOrIntegrator("integrators/falloff.h"));
  EXPECT_TRUE(frontEndOrIntegrator("app/exr_header.h"));
  EXPECT_FALSE(frontEndOrIntegrator("core/render/render.h"));
}

TEST(Layering, AbiVersionIsDefinedOnceAndDocumented) {
  // One definition: no other file defines the macro.
  for (const char* dir : {"include", "core", "app", "integrators", "python", "plugins", "cmake"}) {
    for (const auto& e : fs::recursive_directory_iterator(kRoot / dir)) {
      if (!e.is_regular_file() || e.path() == kRoot / "include" / "obscura" / "plugin.h") continue;
      std::ifstream in(e.path());
      std::stringstream text;
      text << in.rdbuf();
      EXPECT_EQ(text.str().find("#define OBSCURA_PLUGIN_ABI_VERSION"), std::string::npos)
          << rel(e.path()) << " defines the ABI version again";
    }
  }
  // docs/plugins.md's history has an entry for this version ("- **N**").
  std::ifstream in(kRoot / "docs" / "plugins.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string entry = "- **" + std::to_string(OBSCURA_PLUGIN_ABI_VERSION) + "**";
  EXPECT_NE(text.str().find(entry), std::string::npos)
      << "docs/plugins.md \"ABI history\" has no entry \"" << entry << "\" for the current version";
}

}  // namespace
}  // namespace obscura::test
