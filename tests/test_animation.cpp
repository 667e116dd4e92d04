// glTF animation (docs/production.md "Animation and frames"; core/load/animation.h): the
// samplers against closed forms computed here (lerp, the rotation angle a
// slerp must reach, the Hermite polynomial in its power form), held values
// before and after the keys, poses (which nodes move, the static pose), a
// rendered frame against a static file with the nodes placed where the test
// computes them (bit for bit), frame sequences (`--frames`), and bad input.
#include <gtest/gtest.h>
#include <signal.h>

#include <cfloat>
#include <chrono>
#include <fstream>
#include <thread>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "app/options.h"
#include <obscura/error.h>
#include "core/load/gltf_document.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// The keys are floats in the file: a value the test writes and the value
// the file holds differ by the float rounding, |x| * FLT_EPSILON / 2, and
// the double arithmetic after it adds nothing comparable. A few of those
// bound every comparison against a closed form of the written values.
constexpr double kKeyTolerance = 8 * FLT_EPSILON;

// A node with a quad mesh and the animation `channels` on node 0.
std::string writeAnimated(const std::string& dir, const std::string& name, const std::vector<GltfBuilder::Channel>& channels,
                          json node = json::object()) {
  GltfBuilder b;
  const int mesh = b.quadMesh(1.0f);
  node["mesh"] = mesh;
  node["name"] = "moving";
  const int n = b.node(node);
  b.scene({n});
  if (!channels.empty()) b.animation("move", channels);
  return b.writeGltf(dir, name);
}

std::array<double, 3> translationAt(const GltfDocument& doc, double t) {
  const Matrix4d m = doc.pose(t, {}).uses.at(0).world;
  return {m[12], m[13], m[14]};
}

TEST(Animation, LinearMidpointIsTheLerpAndKeysHoldOutside) {
  const std::string dir = tempDir("anim_linear");
  const std::array<double, 3> a = {1.0, -2.0, 0.5}, b = {5.0, 2.0, -3.5};
  const double t0 = 0.5, t1 = 2.5;
  const GltfDocument doc(writeAnimated(
      dir, "linear", {{0, "translation", {float(t0), float(t1)}, {float(a[0]), float(a[1]), float(a[2]), float(b[0]), float(b[1]), float(b[2])}}}));
  for (const double u : {0.25, 0.5, 0.75}) {
    const std::array<double, 3> p = translationAt(doc, t0 + u * (t1 - t0));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(p[size_t(c)], (1 - u) * a[size_t(c)] + u * b[size_t(c)], kKeyTolerance * 8) << "u " << u;
  }
  // Before the first key the first value holds, after the last the last.
  for (const double t : {-10.0, 0.0, t0}) EXPECT_EQ(translationAt(doc, t), a) << t;
  for (const double t : {t1, 3.0, 1e6}) EXPECT_EQ(translationAt(doc, t), b) << t;
  ASSERT_EQ(doc.animations().size(), 1u);
  EXPECT_EQ(doc.animations()[0].name, "move");
  EXPECT_EQ(doc.animations()[0].start, t0);
  EXPECT_EQ(doc.animations()[0].end, t1);
  EXPECT_EQ(doc.animations()[0].channels, 1u);
}

TEST(Animation, SlerpOfAQuarterTurnAboutZ) {
  const std::string dir = tempDir("anim_slerp");
  // 0 -> 90 degrees about +Z over [0, 1]: at t = 0.25 a slerp has turned a
  // quarter of the angle, 22.5 degrees (a normalised lerp would not: it
  // runs ahead of the angle at the ends and behind it mid-way).
  const double half = 0.25 * M_PI;  // half the 90 degree angle, as a quaternion holds it
  const GltfDocument doc(writeAnimated(
      dir, "slerp", {{0, "rotation", {0.0f, 1.0f}, {0, 0, 0, 1, 0, 0, float(std::sin(half)), float(std::cos(half))}}}));
  for (const double u : {0.25, 0.5, 0.8}) {
    const double angle = u * 0.5 * M_PI;
    const Matrix4d m = doc.pose(u, {}).uses.at(0).world;
    // Column 0 is the image of +X: (cos, sin, 0); column 1 of +Y: (-sin, cos, 0).
    EXPECT_NEAR(m[0], std::cos(angle), kKeyTolerance) << u;
    EXPECT_NEAR(m[1], std::sin(angle), kKeyTolerance) << u;
    EXPECT_NEAR(m[4], -std::sin(angle), kKeyTolerance) << u;
    EXPECT_NEAR(m[5], std::cos(angle), kKeyTolerance) << u;
    EXPECT_NEAR(m[10], 1.0, kKeyTolerance) << u;
  }
}

TEST(Animation, SlerpTakesTheShorterArc) {
  // q and -q are one rotation: slerp towards -b is slerp towards b.
  const double h = 0.3;
  const std::array<double, 4> a = {0, 0, 0, 1}, b = {0, std::sin(h), 0, std::cos(h)}, nb = {-b[0], -b[1], -b[2], -b[3]};
  for (const double u : {0.1, 0.5, 0.9}) {
    const std::array<double, 4> p = slerp(a, b, u), q = slerp(a, nb, u);
    // The rotation by u * 2h about +Y: (0, sin(u h), 0, cos(u h)).
    EXPECT_NEAR(q[1], std::sin(u * h), 1e-15);
    EXPECT_NEAR(q[3], std::cos(u * h), 1e-15);
    for (size_t i = 0; i < 4; ++i) EXPECT_NEAR(p[i], q[i], 1e-15);
  }
}

TEST(Animation, StepHoldsEachKeyUntilTheNext) {
  const std::string dir = tempDir("anim_step");
  const GltfDocument doc(writeAnimated(dir, "step", {{0, "scale", {1.0f, 2.0f, 4.0f}, {1, 1, 1, 2, 3, 4, 5, 6, 7}, "STEP"}}));
  const auto scaleAt = [&](double t) {
    const Matrix4d m = doc.pose(t, {}).uses.at(0).world;
    return std::array<double, 3>{m[0], m[5], m[10]};
  };
  using V = std::array<double, 3>;
  EXPECT_EQ(scaleAt(0.0), (V{1, 1, 1}));
  EXPECT_EQ(scaleAt(1.999), (V{1, 1, 1}));
  EXPECT_EQ(scaleAt(2.0), (V{2, 3, 4}));
  EXPECT_EQ(scaleAt(3.999), (V{2, 3, 4}));
  EXPECT_EQ(scaleAt(4.0), (V{5, 6, 7}));
  EXPECT_EQ(scaleAt(100.0), (V{5, 6, 7}));
}

TEST(Animation, CubicSplineIsTheHermitePolynomial) {
  const std::string dir = tempDir("anim_cubic");
  // Two keys at t = 1 and t = 3 (interval d = 2) with values v0, v1, the
  // out-tangent b0 of the first and the in-tangent a1 of the second (the
  // first's in- and the last's out-tangent are not used between the keys).
  const double d = 2.0;
  const std::array<double, 3> v0 = {1, -1, 2}, v1 = {4, 3, -2}, b0 = {0.5, -3, 1}, a1 = {-2, 0.25, 4};
  std::vector<float> values;
  for (const auto* k : {&b0 /* in-tangent of key 0, unused */, &v0, &b0, &a1, &v1, &a1 /* out-tangent of key 1, unused */})
    for (double x : *k) values.push_back(float(x));
  const GltfDocument doc(writeAnimated(dir, "cubic", {{0, "translation", {1.0f, 3.0f}, values, "CUBICSPLINE"}}));
  for (const double s : {0.1, 0.5, 0.7}) {
    const std::array<double, 3> p = translationAt(doc, 1.0 + s * d);
    for (size_t c = 0; c < 3; ++c) {
      // The same cubic in power form: p(0) = v0, p(1) = v1, p'(0) = d b0,
      // p'(1) = d a1 give c0 = v0, c1 = d b0, c2 = 3 (v1 - v0) - 2 d b0 - d a1,
      // c3 = 2 (v0 - v1) + d b0 + d a1.
      const double c0 = v0[c], c1 = d * b0[c], c2 = 3 * (v1[c] - v0[c]) - 2 * d * b0[c] - d * a1[c],
                   c3 = 2 * (v0[c] - v1[c]) + d * b0[c] + d * a1[c];
      EXPECT_NEAR(p[c], c0 + s * (c1 + s * (c2 + s * c3)), kKeyTolerance * 16) << "s " << s << " c " << c;
    }
  }
  // Held outside: the values, not the tangents.
  EXPECT_EQ(translationAt(doc, 0.0), v0);
  EXPECT_EQ(translationAt(doc, 5.0), v1);
}

TEST(Animation, CubicSplineRotationIsNormalised) {
  const std::string dir = tempDir("anim_cubic_rot");
  const double h = 0.5;  // key 1: a rotation by 1 radian about +X
  const std::vector<float> values = {0, 0, 0, 0, /**/ 0, 0, 0, 1, /**/ 1, 0, 0, 0,
                                     1, 0, 0, 0, /**/ float(std::sin(h)), 0, 0, float(std::cos(h)), /**/ 0, 0, 0, 0};
  const GltfDocument doc(writeAnimated(dir, "cubic_rot", {{0, "rotation", {0.0f, 1.0f}, values, "CUBICSPLINE"}}));
  for (const double t : {0.3, 0.6}) {
    const Matrix4d m = doc.pose(t, {}).uses.at(0).world;
    // A unit quaternion gives a rotation matrix: its columns are unit vectors.
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(std::hypot(m[size_t(4 * c)], m[size_t(4 * c + 1)], m[size_t(4 * c + 2)]), 1.0, 1e-12) << t;
  }
}

TEST(Animation, PoseMarksAnimatedNodesAndTheirChildren) {
  const std::string dir = tempDir("anim_pose");
  GltfBuilder b;
  const int mesh = b.quadMesh(1.0f);
  const int child = b.node({{"mesh", mesh}, {"name", "child"}, {"translation", {0, 0, 1}}});
  const int parent = b.node({{"mesh", mesh}, {"name", "parent"}, {"children", {child}}});
  const int other = b.node({{"mesh", mesh}, {"name", "other"}, {"translation", {3, 0, 0}}});
  b.doc["cameras"] = json::array({perspective("cam", 0.8, 0.01)});
  const int cam = b.node({{"camera", 0}, {"name", "camnode"}, {"translation", {0, 0, 5}}});
  b.scene({parent, other, cam});
  b.animation("lift", {{parent, "translation", {0.0f, 1.0f}, {0, 0, 0, 0, 2, 0}}});
  b.animation("dolly", {{cam, "translation", {0.0f, 2.0f}, {0, 0, 5, 0, 0, 9}}});
  const GltfDocument doc(b.writeGltf(dir, "pose"));

  // The static pose: nothing animated, the file's transforms.
  const GltfDocument::Pose still = doc.pose(std::nullopt, {});
  ASSERT_EQ(still.uses.size(), 3u);
  for (const auto& u : still.uses) EXPECT_FALSE(u.animated) << u.node;
  EXPECT_FALSE(still.cameras.at(0).animated);
  EXPECT_EQ(still.uses[1].world, doc.meshUses()[1].world);

  const GltfDocument::Pose p = doc.pose(0.5, {});
  ASSERT_EQ(p.uses.size(), 3u);  // the same order at every time
  EXPECT_EQ(p.uses[0].node, "parent");
  EXPECT_EQ(p.uses[1].node, "child");
  EXPECT_EQ(p.uses[2].node, "other");
  EXPECT_TRUE(p.uses[0].animated);
  EXPECT_TRUE(p.uses[1].animated);  // its parent moves
  EXPECT_FALSE(p.uses[2].animated);
  EXPECT_EQ(p.uses[1].world[13], 0.5 * 2.0);  // the parent's lerp
  EXPECT_EQ(p.uses[1].world[14], 1.0);        // plus the child's own offset
  ASSERT_EQ(p.cameras.size(), 1u);
  EXPECT_TRUE(p.cameras[0].animated);
  EXPECT_FLOAT_EQ(p.cameras[0].position().z, float(5.0 + 0.25 * 4.0));

  // A selection plays only what it names, by name or by index.
  const GltfDocument::Pose onlyDolly = doc.pose(0.5, {"dolly"});
  EXPECT_FALSE(onlyDolly.uses[0].animated);
  EXPECT_EQ(onlyDolly.uses[1].world, still.uses[1].world);
  EXPECT_TRUE(onlyDolly.cameras[0].animated);
  const GltfDocument::Pose onlyLift = doc.pose(0.5, {"0"});
  EXPECT_TRUE(onlyLift.uses[0].animated);
  EXPECT_FALSE(onlyLift.cameras[0].animated);
  EXPECT_EQ(onlyLift.cameras[0].position().z, 5.0f);

  // An unknown one lists what there is.
  try {
    doc.pose(0.5, {"run"});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("'run'"), std::string::npos) << m;
    EXPECT_NE(m.find("0 'lift', 1 'dolly'"), std::string::npos) << m;
  }
  EXPECT_THROW(doc.pose(0.5, {"2"}), Error);

  ASSERT_EQ(doc.animations().size(), 2u);
  EXPECT_EQ(doc.animations()[1].start, 0.0);
  EXPECT_EQ(doc.animations()[1].end, 2.0);
  EXPECT_EQ(doc.animations()[1].nodes, std::vector<int>{cam});
}

TEST(Animation, MorphTargetChannelsAreWarnedAboutOnce) {
  const std::string dir = tempDir("anim_weights");
  WarningCapture w;
  const std::string path = writeAnimated(dir, "weights", {{0, "weights", {0.0f, 1.0f}, {0, 1}}, {0, "translation", {0.0f, 1.0f}, {0, 0, 0, 1, 0, 0}}});
  const GltfDocument doc(path);
  const GltfDocument doc2(path);
  EXPECT_EQ(w.count("morph target animation is not supported (ignored)"), 1u) << w.all();
  EXPECT_TRUE(doc.pose(0.5, {}).uses[0].animated);
}

// Each malformed animation throws naming the file and the field.
void expectDocumentError(const std::string& path, const std::string& field, const std::string& why) {
  try {
    const GltfDocument doc(path);
    ADD_FAILURE() << path << ": no error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(path + ": " + field, 0), 0u) << m;
    EXPECT_NE(m.find(why), std::string::npos) << m;
  }
}

TEST(Animation, BadAnimationsNameTheField) {
  const std::string dir = tempDir("anim_bad");
  const std::vector<float> xyz2 = {0, 0, 0, 1, 1, 1};
  expectDocumentError(writeAnimated(dir, "decreasing", {{0, "translation", {0.0f, 1.0f, 1.0f}, {0, 0, 0, 1, 1, 1, 2, 2, 2}}}),
                      "animations[0].samplers[0].input", "strictly increasing");
  expectDocumentError(writeAnimated(dir, "count", {{0, "translation", {0.0f, 1.0f, 2.0f}, xyz2}}),
                      "animations[0].samplers[0].output", "does not match");
  expectDocumentError(writeAnimated(dir, "cubic_count", {{0, "translation", {0.0f, 1.0f}, xyz2, "CUBICSPLINE"}}),
                      "animations[0].samplers[0].output", "3 x 2");
  expectDocumentError(writeAnimated(dir, "matrix", {{0, "translation", {0.0f, 1.0f}, xyz2}},
                                    {{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}}),
                      "animations[0].channels[0].target.node", "matrix");
  expectDocumentError(writeAnimated(dir, "interp", {{0, "translation", {0.0f, 1.0f}, xyz2, "SMOOTH"}}),
                      "animations[0].samplers[0].interpolation", "LINEAR, STEP or CUBICSPLINE");
  expectDocumentError(writeAnimated(dir, "nan", {{0, "translation", {0.0f, NAN}, xyz2}}), "animations[0].samplers[0].input",
                      "NaN");
  expectDocumentError(writeAnimated(dir, "quat", {{0, "rotation", {0.0f}, {0, 0, 0, 0}}}), "animations[0].samplers[0].output",
                      "quaternion");
  // Two channels on one target of one animation; a sampler that does not exist.
  expectDocumentError(writeAnimated(dir, "twice", {{0, "translation", {0.0f, 1.0f}, xyz2}, {0, "translation", {0.0f, 1.0f}, xyz2}}),
                      "animations[0].channels[1].target", "already");
  GltfBuilder b;
  b.node({{"mesh", b.quadMesh(1.0f)}});
  b.scene({0});
  b.animation("", {{0, "translation", {0.0f, 1.0f}, xyz2}});
  b.doc["animations"][0]["channels"][0]["sampler"] = 3;
  expectDocumentError(b.writeGltf(dir, "sampler"), "animations[0].channels[0].sampler", "does not exist");
  b.doc["animations"][0]["channels"][0]["sampler"] = "0";
  expectDocumentError(b.writeGltf(dir, "sampler_type"), "animations[0].channels[0].sampler", "expected a non-negative integer");
}

// --- frames, rendered ---------------------------------------------------------

// A floor, a small square above it that slides, turns and stretches, and a
// camera on a rig that moves. Animated: the keys below; static: no
// animation, the nodes at the transforms given.
struct Placement {
  std::array<double, 3> boxT, boxS;
  std::array<double, 4> boxR;
  std::array<double, 3> rigT;
};

std::string writeShot(const std::string& dir, const std::string& name, const Placement* still) {
  GltfBuilder b;
  const int floorMesh = b.quadMesh(3.0f);
  const int boxMesh = b.quadMesh(0.6f);
  const int floorNode = b.node({{"mesh", floorMesh}, {"name", "floor"}});
  json box = {{"mesh", boxMesh}, {"name", "box"}, {"translation", {-1, 0, 0.5}}};
  b.doc["cameras"] = json::array({perspective("shot", 0.9, 0.01)});
  const int camNode = b.node({{"camera", 0}, {"name", "camera"}, {"translation", {0, 0, 6}}});
  json rig = {{"name", "rig"}, {"children", {camNode}}};
  if (still) {
    box["translation"] = still->boxT;
    box["scale"] = still->boxS;
    box["rotation"] = still->boxR;
    rig["translation"] = still->rigT;
  }
  const int boxNode = b.node(box);
  const int rigNode = b.node(rig);
  b.scene({floorNode, boxNode, rigNode});
  if (!still) {
    b.animation("slide", {{boxNode, "translation", {0.0f, 1.0f}, {-1, 0, 0.5, 1, 0, 0.5}},
                          {boxNode, "scale", {0.0f, 1.0f}, {1, 1, 1, 3, 1, 1}},
                          // A third of a turn about (1, 1, 1), exactly unit in float.
                          {boxNode, "rotation", {0.0f, 0.2f}, {0, 0, 0, 1, 0.5f, 0.5f, 0.5f, 0.5f}, "STEP"}});
    b.animation("pan", {{rigNode, "translation", {0.0f, 1.0f}, {0, 0, 0, 1, 0.5f, 0}}});
  }
  return b.writeGltf(dir, name);
}

// The placement at time t, from the keys above: lerps, and the STEP rotation's second key.
Placement placementAt(double t) {
  const auto lerp = [&](std::array<double, 3> a, std::array<double, 3> b) {
    std::array<double, 3> r;
    for (size_t i = 0; i < 3; ++i) r[i] = (1 - t) * a[i] + t * b[i];
    return r;
  };
  return {lerp({-1, 0, 0.5}, {1, 0, 0.5}), lerp({1, 1, 1}, {3, 1, 1}), {0.5, 0.5, 0.5, 0.5}, lerp({0, 0, 0}, {1, 0.5, 0})};
}

const std::vector<std::string> kRender = {"-q", "--res", "40x30", "--spp", "4", "-p", "distance=2"};

std::vector<std::string> renderArgs(const std::string& scene, const std::string& out, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> a = {"render", scene};
  a.insert(a.end(), kRender.begin(), kRender.end());
  a.insert(a.end(), extra.begin(), extra.end());
  a.push_back("-o");
  a.push_back(out);
  return a;
}

// Every channel equal bit for bit.
void expectSamePixels(const std::string& a, const std::string& b) {
  const ReadBack x = readExr(a), y = readExr(b);
  ASSERT_TRUE(x.ok && y.ok);
  ASSERT_EQ(x.spec.channelnames, y.spec.channelnames);
  for (const auto& [name, plane] : x.planes) {
    const std::vector<float>& q = y.planes.at(name);
    ASSERT_EQ(plane.size(), q.size());
    EXPECT_EQ(std::memcmp(plane.data(), q.data(), q.size() * sizeof(float)), 0) << a << " vs " << b << ": channel " << name;
  }
}

TEST(AnimationRender, FrameEqualsTheStaticFileAtTheComputedTransforms) {
  const std::string dir = tempDir("anim_render");
  const std::string animated = writeShot(dir, "shot", nullptr);
  // Frame 6 at 24 fps is t = 0.25, past the rotation's second key; frame 3
  // at 12 fps is the same time.
  const Placement p = placementAt(6.0 / 24.0);
  const std::string still = writeShot(dir, "still", &p);
  const std::vector<CliResult> runs =
      runClis({renderArgs(animated, dir + "/frame6.exr", {"--frame", "6"}), renderArgs(still, dir + "/still.exr"),
               renderArgs(animated, dir + "/fps12.exr", {"--frame", "3", "--fps", "12"}),
               renderArgs(animated, dir + "/static.exr")},
              dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  expectSamePixels(dir + "/frame6.exr", dir + "/still.exr");
  expectSamePixels(dir + "/frame6.exr", dir + "/fps12.exr");
  // Without --frame the file's own transforms: another image.
  const ReadBack f = readExr(dir + "/frame6.exr"), s = readExr(dir + "/static.exr");
  EXPECT_NE(f.planes.at("R"), s.planes.at("R"));
  EXPECT_EQ(f.spec.get_string_attribute("obscura:frame"), "6");
  EXPECT_EQ(f.spec.get_string_attribute("obscura:fps"), "24");
  EXPECT_EQ(f.spec.get_string_attribute("obscura:time"), formatFloat(6.0 / 24.0));
  EXPECT_EQ(f.spec.get_string_attribute("obscura:animations"), "all");
  EXPECT_EQ(s.spec.find_attribute("obscura:frame"), nullptr);
}

TEST(AnimationRender, OneAnimationOfTwo) {
  const std::string dir = tempDir("anim_select");
  const std::string animated = writeShot(dir, "shot", nullptr);
  // "pan" alone at t = 0.5: the box where the file puts it, the rig moved.
  Placement p = placementAt(0.5);
  p.boxT = {-1, 0, 0.5}, p.boxS = {1, 1, 1}, p.boxR = {0, 0, 0, 1};
  const std::string still = writeShot(dir, "still", &p);
  const std::vector<CliResult> runs = runClis({renderArgs(animated, dir + "/pan.exr", {"--frame", "12", "--animation", "pan"}),
                                               renderArgs(animated, dir + "/pan1.exr", {"--frame", "12", "--animation", "1"}),
                                               renderArgs(still, dir + "/still.exr")},
                                              dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  expectSamePixels(dir + "/pan.exr", dir + "/still.exr");
  expectSamePixels(dir + "/pan1.exr", dir + "/still.exr");
  EXPECT_EQ(readExr(dir + "/pan.exr").spec.get_string_attribute("obscura:animations"), "pan");
}

TEST(AnimationRender, FramesWriteOneFileEachEqualToItsFrame) {
  const std::string dir = tempDir("anim_frames");
  const std::string animated = writeShot(dir, "shot", nullptr);
  std::vector<std::vector<std::string>> runs = {renderArgs(animated, dir + "/seq.####.exr", {"--frames", "1-3"})};
  for (int f = 1; f <= 3; ++f) runs.push_back(renderArgs(animated, dir + "/single" + std::to_string(f) + ".exr", {"--frame", std::to_string(f)}));
  // A farm task's single frame fills the '#' run too; negative frames keep the width.
  runs.push_back(renderArgs(animated, dir + "/task.###.exr", {"--frame", "-2"}));
  for (const CliResult& r : runClis(runs, dir)) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  for (int f = 1; f <= 3; ++f) {
    const std::string seq = dir + "/seq.000" + std::to_string(f) + ".exr";
    ASSERT_TRUE(std::filesystem::exists(seq)) << seq;
    expectSamePixels(seq, dir + "/single" + std::to_string(f) + ".exr");
    EXPECT_EQ(readExr(seq).spec.get_string_attribute("obscura:frame"), std::to_string(f));
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/seq.0000.exr"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/seq.0004.exr"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/task.-02.exr"));
}

TEST(AnimationRender, FramePatterns) {
  const FramePattern p = framePattern("-o", "dir.#/out.####.exr");
  EXPECT_EQ(frameFileName("dir.#/out.####.exr", p, 1), "dir.#/out.0001.exr");
  EXPECT_EQ(frameFileName("dir.#/out.####.exr", p, -1), "dir.#/out.-001.exr");
  EXPECT_EQ(frameFileName("dir.#/out.####.exr", p, 123456), "dir.#/out.123456.exr");
  EXPECT_FALSE(framePattern("-o", "out.exr").any());
  EXPECT_THROW(framePattern("-o", "out.##.#.exr"), Error);
  EXPECT_EQ(parseFrameRange("1-3"), (std::vector<long long>{1, 2, 3}));
  EXPECT_EQ(parseFrameRange("-3--1"), (std::vector<long long>{-3, -2, -1}));
  EXPECT_EQ(parseFrameRange("1-10:4"), (std::vector<long long>{1, 5, 9}));
  for (const char* bad : {"3-1", "1-3:0", "1-3:-1", "1", "a-b", "1-3:", "1.5-3", "-", "1--"})
    EXPECT_THROW(parseFrameRange(bad), Error) << bad;
  EXPECT_EQ(parseFrame("12.5"), 12.5);
  for (const char* bad : {"", "x", "nan", "inf", "0x10", "1e400", "3 "}) EXPECT_THROW(parseFrame(bad), Error) << bad;
}

TEST(AnimationRender, BadInputIsOneLineAndWritesNothing) {
  const std::string dir = tempDir("anim_cli_bad");
  const std::string animated = writeShot(dir, "shot", nullptr);
  const std::string decreasing = writeAnimated(dir, "decreasing", {{0, "translation", {1.0f, 0.5f}, {0, 0, 0, 1, 1, 1}}});
  const std::string matrix = writeAnimated(dir, "matrix", {{0, "translation", {0.0f, 1.0f}, {0, 0, 0, 1, 1, 1}}},
                                           {{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}});
  const std::string count = writeAnimated(dir, "count", {{0, "translation", {0.0f, 1.0f}, {0, 0, 0}}});
  const std::string obj = dir + "/cage.obj";
  writeText(obj, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
  struct Case {
    std::vector<std::string> args;
    std::string out, says;
  };
  const std::vector<Case> cases = {
      {renderArgs(animated, dir + "/a.exr", {"--frame", "1", "--animation", "walk"}), "a.exr", "--animation 'walk': no animation"},
      {renderArgs(animated, dir + "/b.exr", {"--frames", "1-3"}), "b.exr", "--frames needs a '#'"},
      {renderArgs(animated, dir + "/c.####.exr", {"--frames", "1-3", "--frame", "2"}), "c.0001.exr", "--frame: cannot be combined"},
      {renderArgs(animated, dir + "/d.####.exr", {"--frames", "3-1"}), "d.0001.exr", "--frames: expected A-B"},
      {renderArgs(animated, dir + "/e.exr", {"--frame", "1", "--fps", "0"}), "e.exr", "--fps"},
      {renderArgs(animated, dir + "/f.exr", {"--frame", "one"}), "f.exr", "--frame: expected a frame number"},
      {renderArgs(animated, dir + "/g.exr", {"--animation", "slide"}), "g.exr", "give --frame"},
      {renderArgs(obj, dir + "/h.exr", {"--frame", "1"}), "h.exr", "an OBJ file has no animation"},
      {renderArgs(decreasing, dir + "/i.exr", {"--frame", "1"}), "i.exr", "animations[0].samplers[0].input: keyframe times must be strictly increasing"},
      {renderArgs(matrix, dir + "/j.exr"), "j.exr", "animations[0].channels[0].target.node: nodes[0] has a matrix"},
      {renderArgs(count, dir + "/k.exr"), "k.exr", "animations[0].samplers[0].output: count 1 does not match"},
      {renderArgs(animated, dir + "/l.####.exr", {"--frames", "1-2", "--preview", dir + "/l.png"}), "l.0001.exr", "--preview"},
      {renderArgs(animated, dir + "/m.#.exr", {"--frame", "1.5"}), "m.1.exr", "whole frame number"},
  };
  std::vector<std::vector<std::string>> runs;
  for (const Case& c : cases) runs.push_back(c.args);
  const std::vector<CliResult> results = runClis(runs, dir);
  for (size_t i = 0; i < cases.size(); ++i) {
    const CliResult& r = results[i];
    EXPECT_EQ(r.exitCode, 1) << i << ": " << r.stderrText;
    EXPECT_EQ(r.stderrText.rfind("obscura: error: ", 0), 0u) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
    EXPECT_NE(r.stderrText.find(cases[i].says), std::string::npos) << i << ": " << r.stderrText;
    EXPECT_FALSE(std::filesystem::exists(dir + "/" + cases[i].out)) << cases[i].out;
  }
}

// Ctrl-C during a sequence: exit 130, one line naming the frame that was
// not written; the frames before it are complete, none after it is begun.
TEST(AnimationRender, InterruptedSequenceKeepsTheFramesBefore) {
  const std::string dir = tempDir("anim_interrupt");
  const std::string animated = writeShot(dir, "shot", nullptr);
  CliResult r;
  const pid_t pid = startCli({"render", animated, "--res", "400x300", "--spp", "256", "--frames", "1-4", "-o", dir + "/f.#.exr"},
                             dir + "/stderr.txt", r);
  ASSERT_GT(pid, 0) << r.stderrText;
  // Signal only once the handler is in place (SigCgt in /proc), a moment into the renders.
  const auto catches = [&] {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    for (std::string line; std::getline(in, line);)
      if (line.rfind("SigCgt:", 0) == 0) return ((std::stoull(line.substr(7), nullptr, 16) >> (SIGINT - 1)) & 1) != 0;
    return false;
  };
  for (int i = 0; i < 6000 && !catches(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  kill(pid, SIGINT);
  finishCli(pid, dir + "/stderr.txt", r);
  ASSERT_EQ(r.exitCode, 130) << r.stderrText;
  const size_t at = r.stderrText.find("obscura: interrupted; " + dir + "/f.");
  ASSERT_NE(at, std::string::npos) << r.stderrText;
  const int stopped = r.stderrText[at + std::string("obscura: interrupted; " + dir + "/f.").size()] - '0';
  ASSERT_GE(stopped, 1);
  ASSERT_LE(stopped, 4);
  for (int f = 1; f <= 4; ++f) {
    const std::string out = dir + "/f." + std::to_string(f) + ".exr";
    EXPECT_EQ(std::filesystem::exists(out), f < stopped) << out;
    if (f < stopped) EXPECT_TRUE(readExr(out).ok);
  }
}

TEST(AnimationRender, InfoListsAnimations) {
  const std::string dir = tempDir("anim_info");
  const std::string animated = writeShot(dir, "shot", nullptr);
  const std::string out = dir + "/info.txt";
  // runCli sends stdout to /dev/null: the listing is read through a shell redirect.
  const std::string cmd = std::string(obscuraBinary()) + " info " + animated + " --fps 10 > " + out + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::string text;
  for (unsigned char c : readBytes(out)) text += char(c);
  EXPECT_NE(text.find("animations 2"), std::string::npos) << text;
  EXPECT_NE(text.find("[0] slide  0 - 1 s  (frames 0 - 10 at 10 fps)  3 channels  nodes: box"), std::string::npos) << text;
  EXPECT_NE(text.find("[1] pan  0 - 1 s  (frames 0 - 10 at 10 fps)  1 channel  nodes: rig"), std::string::npos) << text;
}

}  // namespace
}  // namespace obscura::test
