// Core messages name a setting the way the caller set it (core/util/option_names.h):
// the library's field name by default, the flag the user typed on the CLI.
#include <string>

#include <obscura/error.h>
#include "core/util/option_names.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// Called as a library (no front end registered names): the setting's field,
// no flag.
TEST(SettingNames, CoreNamesTheSetting) {
  Scene scene;
  addPlane(scene, 1.0f);
  scene.commit();
  Camera camera;
  RenderSettings s = passSettings(4, 4, 0);
  try {
    renderWith(scene, camera, "ao", {}, s);
    ADD_FAILURE() << "rendered at spp 0";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), settingName(Setting::Spp) + " must be at least 1");
    EXPECT_EQ(settingName(Setting::Spp), "spp");
  }
}

// Through the CLI: the same checks name the flags.
TEST(SettingNames, CliNamesTheFlag) {
  const std::string dir = tempDir("setting_names");
  writeText(dir + "/quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n");
  // Level 10 of one quad is ~1M quads: over a budget of about 1 MiB.
  const CliResult budget = runCli({"render", dir + "/quad.obj", "--subdiv", "catmull-clark", "--subdiv-level", "10",
                                   "--max-memory", "0.001", "-o", dir + "/a.exr", "-q", "--camera", "auto"},
                                  dir + "/budget.txt");
  EXPECT_EQ(budget.exitCode, 1);
  EXPECT_NE(budget.stderrText.find("over the --max-memory budget of"), std::string::npos) << budget.stderrText;
  writeRipples(dir);
  const CliResult displace = runCli({"render", dir + "/quad.obj", "--displace", dir + "/ripples.exr", "-o",
                                     dir + "/b.exr", "-q", "--camera", "auto"},
                                    dir + "/displace.txt");
  EXPECT_EQ(displace.exitCode, 1);
  EXPECT_NE(displace.stderrText.find("quad.obj: displacement (--displace) needs --subdiv"), std::string::npos)
      << displace.stderrText;
}

}  // namespace
}  // namespace obscura::test
