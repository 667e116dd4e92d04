// DIR/report.html of `obscura compare` in a real browser (docs/compare.md
// "The report page"): headless Chromium loads the page of a small compare
// from disk; its scripts must run without a console message, build a table
// row for every cell of results.json and a clickable point for each, decode
// the float data into the viewer, show every cell's FLIP heat maps and a
// verdict row per RMSE and FLIP target, and a screenshot is taken. Skipped (with
// the reason) where chromium is absent, except in CI (.ci/run sets
// OBSCURA_REQUIRE_SCENES; CI=true as well), where its absence fails.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "app/report_html.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

std::string chromiumBinary() {
  if (const char* env = std::getenv("OBSCURA_CHROMIUM"); env && *env)
    return std::filesystem::exists(env) ? std::string(env) : std::string();
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (std::filesystem::exists(p)) return p;
  return "";
}

std::string readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The attribute value as Chromium serializes it in the DOM dump.
std::string attributeEscape(const std::string& s) {
  std::string o;
  for (const char c : s) o += c == '&' ? std::string("&amp;") : c == '"' ? std::string("&quot;") : std::string(1, c);
  return o;
}

// Chromium's flags for a headless run as root in a container: no sandbox
// (it refuses root otherwise), no GPU, console messages on stderr.
std::string chromiumCommand(const std::string& chromium, const std::string& dir, const std::string& what,
                            const std::string& page) {
  return "timeout 120 '" + chromium + "' --headless=new --disable-gpu --no-sandbox --no-first-run " +
         "--user-data-dir='" + dir + "/profile' --enable-logging=stderr --v=0 " + what + " 'file://" + page + "'";
}

TEST(CompareReportPage, Base64MatchesTheRfcVectors) {
  // RFC 4648 section 10.
  const std::pair<const char*, const char*> vectors[] = {{"", ""},         {"f", "Zg=="},         {"fo", "Zm8="},
                                                         {"foo", "Zm9v"},  {"foob", "Zm9vYg=="},  {"fooba", "Zm9vYmE="},
                                                         {"foobar", "Zm9vYmFy"}};
  for (const auto& [in, out] : vectors)
    EXPECT_EQ(base64(reinterpret_cast<const unsigned char*>(in), std::strlen(in)), out) << in;
}

TEST(CompareReportPage, FloatDataIsUnpremultipliedLittleEndianFloat32) {
  // Two pixels: the first covered half (A = 0.5, R,G,B premultiplied: W =
  // 1, 2, 0.5), the second not at all. The page reads W and the mask.
  PassImage p;
  p.width = 2, p.height = 1;
  p.r = {0.5f, 0}, p.g = {1.0f, 0}, p.b = {0.25f, 0}, p.a = {0.5f, 0};
  PassImage ref = p;
  ref.a = {1.0f, 1.0f};
  // 1.0f is 00 00 80 3F, 2.0f 00 00 00 40, 0.5f 00 00 00 3F, 0.0f 00 00 00 00.
  const unsigned char expect[] = {0, 0, 0x80, 0x3f, 0, 0, 0, 0x40, 0, 0, 0, 0x3f, 0, 0, 0x80, 0x3f,
                                  0, 0, 0,    0,    0, 0, 0, 0,    0, 0, 0, 0,    0, 0, 0,    0};
  EXPECT_EQ(reportImageBase64(p, ref, false, 1), base64(expect, sizeof expect));
  // Averaged 2x1 -> 1x0 is empty; a factor of 1 over the reference marks both compared.
  EXPECT_EQ(reportImageBase64(p, ref, false, 2), "");
}

TEST(CompareReportPage, EveryCellIsOnThePageInHeadlessChromium) {
  const std::string chromium = chromiumBinary();
  if (chromium.empty()) {
    const std::string why =
        "skipped: needs Debian's chromium at /usr/bin/chromium or $OBSCURA_CHROMIUM (apt-get install chromium; "
        "scripts/setup.sh test installs it)";
    if (clientsRequired()) FAIL() << why;
    GTEST_SKIP() << why;
  }
  const std::string dir = tempDir("compare_report_page");
  // Tiny: two configs, two spp, two seeds (the intervals and bars appear),
  // RMSE and FLIP targets.
  const CliResult r = runCli({"compare", sourcePath("scenes/default.gltf"), "-o", dir + "/out", "--res", "48x27",
                              "--reference-spp", "16", "--spp", "2,8", "--seeds", "2", "--targets", "0.5,0.2", "--targets-flip", "0.5,0.2", "-q",
                              "-c", "ao", "-c", "obscurance:falloff=sqrt,distance=0.5"},
                             dir + "/compare.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const std::string page = std::filesystem::absolute(dir + "/out/report.html").string();
  ASSERT_TRUE(std::filesystem::exists(page));

  // Self-contained: nothing the page loads is on the network (the SVG's
  // xmlns names a namespace, not a request).
  const std::string source = readAll(page);
  for (const char* remote : {"src=\"http", "href=\"http", "url(http", "fetch("})
    EXPECT_EQ(source.find(remote), std::string::npos) << remote;

  const std::string dom = dir + "/dom.html", log = dir + "/chromium.txt";
  const int rc = std::system((chromiumCommand(chromium, dir, "--dump-dom", page) + " >'" + dom + "' 2>'" + log + "'").c_str());
  ASSERT_EQ(rc, 0) << readAll(log);
  const std::string html = readAll(dom), messages = readAll(log);
  // No console message at all: the page logs nothing when it works, and an
  // uncaught exception is logged as "CONSOLE ... Uncaught ...".
  EXPECT_EQ(messages.find("CONSOLE"), std::string::npos) << messages;
  EXPECT_NE(html.find("data-status=\"ready\""), std::string::npos) << "the page's script did not finish";
  EXPECT_NE(html.find("data-drawn=\"cell-"), std::string::npos) << "the viewer did not decode the float data";
  EXPECT_NE(html.find("<svg"), std::string::npos) << "no plot";

  const nlohmann::json results = nlohmann::json::parse(readAll(dir + "/out/results.json"));
  ASSERT_EQ(results["cells"].size(), 4u);
  for (size_t i = 0; i < results["cells"].size(); ++i) {
    const auto& c = results["cells"][i];
    const std::string row = "<tr data-cell=\"" + std::to_string(i) + "\" data-config=\"" +
                            attributeEscape(c["config"].get<std::string>()) + "\" data-spp=\"" +
                            std::to_string(c["spp"].get<int>()) + "\"";
    EXPECT_NE(html.find(row), std::string::npos) << "no table row for cell " << i << ": " << c.dump();
    // The chosen point's class is "pt sel".
    EXPECT_TRUE(std::regex_search(html, std::regex("<circle class=\"pt( sel)?\" data-cell=\"" + std::to_string(i) + "\"")))
        << "no plot point for cell " << i;
    EXPECT_TRUE(c.contains("rmseInterval") && c.contains("secondsInterval")) << c.dump();
    // FLIP's two heat maps of every cell are images on the page.
    for (const char* map : {"flipHeatmap", "flipHdrHeatmap"}) {
      ASSERT_TRUE(c.contains(map)) << c.dump();
      EXPECT_NE(html.find("src=\"" + attributeEscape(c[map].get<std::string>()) + "\""), std::string::npos)
          << "no " << map << " image for cell " << i;
    }
  }
  EXPECT_EQ(html.find("id=\"flipsection\" hidden"), std::string::npos) << "the FLIP heat maps are hidden";
  // Each target's verdict (RMSE and FLIP) is a row of its verdict table.
  for (const auto& [list, measure] : {std::pair{"targets", "rmse"}, std::pair{"flipTargets", "flip"}}) {
    EXPECT_EQ(results[list].size(), 2u) << list;
    for (const auto& t : results[list]) {
      std::ostringstream row;
      row << "<tr data-measure=\"" << measure << "\" data-target=\"" << t[measure].get<double>() << "\"";
      EXPECT_NE(html.find(row.str()), std::string::npos) << "no verdict row " << row.str();
      EXPECT_TRUE(t.contains("verdict")) << t.dump();
    }
  }

  const std::string shot = dir + "/page.png";
  ASSERT_EQ(std::system((chromiumCommand(chromium, dir, "--hide-scrollbars --window-size=1300,2200 --screenshot='" +
                                                            shot + "'", page) + " >/dev/null 2>'" + log + "'").c_str()),
            0)
      << readAll(log);
  const std::string png = readAll(shot);
  ASSERT_GT(png.size(), 1000u) << "no screenshot";
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

}  // namespace
}  // namespace obscura::test
