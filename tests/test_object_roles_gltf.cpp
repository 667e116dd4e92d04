// Objects' roles and alpha from glTF files and the command line: node
// extras inherited by children, --object overrides, the EXR header's
// record, glTF alphaMode, and bad input refused with one line.
#include <gtest/gtest.h>

#include <algorithm>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A floor (half-size 50) and a slab (half-size 1) at height 1 under a group
// node "set"; a camera between them looking down at the floor's centre.
// `setRoles` / `slabRoles`: the extras.obscura of "set" and "slab";
// `slabMaterial`: a material for the slab (json null: none).
std::string writeSlabScene(const std::string& dir, const std::string& name, const json& setRoles, const json& slabRoles,
                           const json& slabMaterial = nullptr) {
  GltfBuilder g;
  const int floorMesh = g.quadMesh(50.0f);
  int mat = -1;
  if (!slabMaterial.is_null()) mat = g.push("materials", slabMaterial);
  const int slabMesh = g.quadMesh(1.0f, mat, true);
  json floor = {{"name", "floor"}, {"mesh", floorMesh}};
  json slab = {{"name", "slab"}, {"mesh", slabMesh}, {"translation", {0, 0, 1}}};
  if (!slabRoles.is_null()) slab["extras"] = {{"obscura", slabRoles}};
  const int f = g.node(floor), s = g.node(slab);
  json set = {{"name", "set"}, {"children", {f, s}}};
  if (!setRoles.is_null()) set["extras"] = {{"obscura", setRoles}};
  const int root = g.node(set);
  g.push("cameras", perspective("under", 0.02, 0.01));
  const int cam = g.node({{"name", "cam"}, {"camera", 0}, {"translation", {0, 0, 0.5}}});
  g.scene({root, cam});
  return g.writeGltf(dir, name);
}

TEST(ObjectRolesGltf, NodeRolesAreInheritedAndOverridden) {
  const std::string dir = tempDir("roles_gltf");
  const std::string path = writeSlabScene(dir, "inherit", {{"occluder", false}, {"occlusion", "self"}}, {{"occluder", true}});
  const auto scene = loadGltf(path);
  ASSERT_EQ(scene->objects.size(), 2u);  // "set" has no mesh: not an object
  EXPECT_EQ(scene->objects[0].name, "floor");
  EXPECT_FALSE(scene->objects[0].roles.occluder);  // from "set"
  EXPECT_EQ(scene->objects[0].roles.occlusion, OcclusionScope::Self);
  EXPECT_EQ(scene->objects[1].name, "slab");
  EXPECT_TRUE(scene->objects[1].roles.occluder);  // its own
  EXPECT_EQ(scene->objects[1].roles.occlusion, OcclusionScope::Self);
  LoadOptions o;
  o.objectOverrides = {parseObjectOverride("fl*:occluder=true,camera=false")};
  const auto over = loadGltf(path, o);
  EXPECT_TRUE(over->objects[0].roles.occluder);
  EXPECT_FALSE(over->objects[0].roles.camera);
}

// Every pixel of a pass's R channel, read back.
std::vector<float> passR(const std::string& exr) { return readExr(exr).planes["R"]; }

TEST(ObjectRolesGltf, CliRendersRolesAndRecordsThem) {
  const std::string dir = tempDir("roles_cli");
  const std::string plain = writeSlabScene(dir, "plain", nullptr, nullptr);
  const std::string excluded = writeSlabScene(dir, "excluded", nullptr, {{"occluder", false}});
  const std::string masked = writeSlabScene(dir, "masked", nullptr, nullptr,
                                            {{"alphaMode", "MASK"}, {"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 0.2}}}}});
  const std::string opaqueBlend = writeSlabScene(dir, "blend1", nullptr, nullptr, {{"alphaMode", "BLEND"}});
  const std::vector<std::string> common = {"--res", "8x8", "--spp", "16", "-q"};
  const auto args = [&](const std::string& scene, const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> a = {"render", scene, "-o", dir + "/" + out};
    a.insert(a.end(), common.begin(), common.end());
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const auto results = runClis({args(plain, "plain.exr", {}), args(excluded, "excluded.exr", {}),
                                args(excluded, "restored.exr", {"--object", "slab:occluder=true"}),
                                args(masked, "masked.exr", {}), args(opaqueBlend, "blend1.exr", {}),
                                args(plain, "cli_excluded.exr", {"--object", "s?ab:occluder=false"})},
                               dir);
  for (const CliResult& r : results) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const std::vector<float> base = passR(dir + "/plain.exr");
  ASSERT_EQ(base.size(), 64u);
  for (const float w : base) EXPECT_LT(w, 0.75f);  // the slab occludes (1 - F = 0.446)
  // Excluded in the file or on the command line, or cut out entirely by a
  // MASK with alpha 0.2 < 0.5: nothing occludes the floor.
  for (const char* f : {"excluded.exr", "cli_excluded.exr", "masked.exr"})
    for (const float w : passR(dir + "/" + f)) ASSERT_EQ(w, 1.0f) << f;
  // An override restoring the default, and BLEND at alpha 1: the plain image, bit for bit.
  EXPECT_EQ(passR(dir + "/restored.exr"), base);
  EXPECT_EQ(passR(dir + "/blend1.exr"), base);
  // The header: overrides as given, and the roles that differ from the default.
  const ReadBack ex = readExr(dir + "/excluded.exr");
  EXPECT_EQ(ex.spec.get_string_attribute("obscura:objectRoles"), "slab: occluder=false,camera=true,matte=false,occlusion=all");
  EXPECT_EQ(ex.spec.get_string_attribute("obscura:objectOverrides"), "");
  const ReadBack re = readExr(dir + "/restored.exr");
  EXPECT_EQ(re.spec.get_string_attribute("obscura:objectOverrides"), "--object 'slab:occluder=true'");
  EXPECT_EQ(re.spec.get_string_attribute("obscura:objectRoles"), "");
}

TEST(ObjectRolesGltf, CompareTakesObjectOverrides) {
  const std::string dir = tempDir("roles_compare");
  const std::string scene = writeSlabScene(dir, "s", nullptr, nullptr);
  const CliResult r = runCli({"compare", scene, "-o", dir + "/out", "--res", "8x8", "--spp", "2", "--reference-spp", "4",
                              "-c", "ao", "--object", "slab:matte=true", "-q"},
                             dir + "/stderr.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const std::vector<unsigned char> bytes = readBytes(dir + "/out/results.csv");
  const std::string csv(bytes.begin(), bytes.end());
  EXPECT_NE(csv.find("ao"), std::string::npos) << csv;
}

TEST(ObjectRolesGltf, BadRolesAndAlphaAreRefusedWithOneLine) {
  const std::string dir = tempDir("roles_bad");
  struct Case {
    std::string scene;
    std::vector<std::string> extra;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {writeSlabScene(dir, "b1", nullptr, {{"occluder", "no"}}), {}, "nodes[1].extras.obscura.occluder: expected true or false"},
      {writeSlabScene(dir, "b2", {{"occlusion", 3}}, nullptr), {}, "nodes[2].extras.obscura.occlusion"},
      {writeSlabScene(dir, "b3", nullptr, {{"occlusion", "mine"}}), {}, "occlusion: expected all, self or others, got 'mine'"},
      {writeSlabScene(dir, "b4", nullptr, nullptr, {{"alphaMode", "CUTOUT"}}), {}, "materials[0].alphaMode: expected OPAQUE, MASK or BLEND"},
      {writeSlabScene(dir, "b5", nullptr, nullptr, {{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1.5}}}}}), {},
       "materials[0].pbrMetallicRoughness.baseColorFactor: alpha"},
      {writeSlabScene(dir, "b6", nullptr, nullptr, {{"alphaMode", "MASK"}, {"alphaCutoff", -1}}), {}, "materials[0].alphaCutoff"},
      {writeSlabScene(dir, "b7", nullptr, nullptr), {"--object", "tree*:matte=true"}, "no object is named 'tree*' (objects: 'floor', 'slab')"},
      {writeSlabScene(dir, "b8", nullptr, nullptr), {"--object", "slab:matte"}, "--object 'slab:matte': expected role=value"},
  };
  std::vector<std::vector<std::string>> argLists;
  for (size_t i = 0; i < cases.size(); ++i) {
    std::vector<std::string> a = {"render", cases[i].scene, "-o", dir + "/bad" + std::to_string(i) + ".exr", "--res", "4x4", "-q"};
    a.insert(a.end(), cases[i].extra.begin(), cases[i].extra.end());
    argLists.push_back(a);
  }
  const auto results = runClis(argLists, dir);
  for (size_t i = 0; i < cases.size(); ++i) {
    EXPECT_EQ(results[i].exitCode, 1) << cases[i].needle;
    EXPECT_NE(results[i].stderrText.find(cases[i].needle), std::string::npos) << results[i].stderrText;
    EXPECT_EQ(std::count(results[i].stderrText.begin(), results[i].stderrText.end(), '\n'), 1) << results[i].stderrText;
  }
}

}  // namespace
}  // namespace obscura::test
