// Motion blur: the step rule (core/scene/motion.h), and renders whose time
// average has a closed form.
//
// The closed form: a point x on the ground plane z = 0 (normal +z) at
// distance d from an infinite vertical wall (the plane x = d). A
// cosine-distributed direction projects to a point uniform on the unit disk;
// it meets the wall within R exactly when that point's x-coordinate exceeds
// a = d / R, so classical AO with radius R is
//   V(d) = 1 - (acos(a) - a sqrt(1 - a^2)) / pi,  a = min(d / R, 1)
// (one minus the area of the circular segment x > a, over pi). When the wall
// slides (or the camera does, so the point seen moves) at constant speed
// across the shutter, d = d0 + (d1 - d0) u for the sample's time u uniform in
// [0, 1), and the pass is the time average of V, integrated here by Simpson's
// rule - independently of the renderer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <cstring>

#include <obscura/error.h>
#include "core/scene/motion.h"
#include <obscura/params.h>
#include "core/render/render.h"
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include "gltf_builder.h"
#include "support.h"

namespace obscura {
namespace {

using namespace obscura::test;

double wallVisibility(double d, double R) {
  const double a = std::min(d / R, 1.0);
  return 1.0 - (std::acos(a) - a * std::sqrt(1.0 - a * a)) / kPi;
}

// (1/(d1 - d0)) Int_{d0}^{d1} V, Simpson's rule on 20000 intervals.
double averageVisibility(double d0, double d1, double R) {
  const int n = 20000;
  double s = wallVisibility(d0, R) + wallVisibility(d1, R);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4.0 : 2.0) * wallVisibility(d0 + (d1 - d0) * i / n, R);
  return s / (3.0 * n);
}

Affine translation(float x) {
  Affine a;
  a.m[0][3] = x;
  return a;
}

// The ground, and a wall (the plane x = 0 in its own space, 10 high, 100
// long: beyond any AO ray of R = 1) placed by `wallSteps` (one: still).
std::unique_ptr<Scene> wallScene(std::span<const Affine> wallSteps) {
  auto scene = std::make_unique<Scene>();
  addPlane(*scene, 50.0f);
  const int wall = scene->addInstancedMesh("wall");
  scene->addPrimitiveToMesh(wall, {{0, -50, 0}, {0, 50, 0}, {0, 50, 10}, {0, -50, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene->addMovingInstance(wall, wallSteps, "wall");
  scene->commit();
  return scene;
}

// Looking straight down at (x, 0, 0) from 3 above, with a field of view so
// narrow that every pixel sees that point (to 1.5e-3).
Camera downAt(float x) { return makeLookAtCamera(Vec3(x, 0, 3), Vec3(x, 0, 0), Vec3(0, 1, 0), 1e-3f, "down"); }

RenderSettings blurSettings(bool motionBlur) {
  RenderSettings s = passSettings(16, 16, 64);
  s.motionBlur = motionBlur;
  return s;
}

constexpr double kRadius = 1.0, kD0 = 0.05, kD1 = 1.5;

// Every pixel is its own estimate of the same time average (own scrambles).
void expectAverage(const Film& film, double expected) {
  const PixelStats st = pixelStats(film, kR);
  EXPECT_NEAR(st.mean, expected, 4.0 * st.se + 1e-6) << "se " << st.se;
}

TEST(MotionBlur, SlidingWallAveragesTheClosedForm) {
  const Affine steps[2] = {translation(float(kD0)), translation(float(kD1))};
  const auto scene = wallScene(steps);
  ASSERT_TRUE(scene->hasMotion());
  const Film blurred = renderWith(*scene, downAt(0), "ao", {"distance=1"}, blurSettings(true));
  const double expected = averageVisibility(kD0, kD1, kRadius);
  expectAverage(blurred, expected);
  // Without a shutter every ray is at time 0: the wall stands at d0.
  const Film still = renderWith(*scene, downAt(0), "ao", {"distance=1"}, blurSettings(false));
  expectAverage(still, wallVisibility(kD0, kRadius));
  // The two differ by far more than the noise: the test tells them apart.
  ASSERT_GT(std::abs(expected - wallVisibility(kD0, kRadius)), 0.2);
}

TEST(MotionBlur, MovingCameraAveragesTheClosedForm) {
  // The wall stands at x = d0; the camera slides away from it, so the point
  // it sees is at distance d0 .. d1 from the wall.
  const Affine still[1] = {translation(float(kD0))};
  const auto scene = wallScene(still);
  ASSERT_FALSE(scene->hasMotion());
  Camera cam = downAt(0);
  cam.motion = {downAt(0).toWorld, downAt(float(kD0 - kD1)).toWorld};
  const Film blurred = renderWith(*scene, cam, "ao", {"distance=1"}, blurSettings(true));
  expectAverage(blurred, averageVisibility(kD0, kD1, kRadius));
}

TEST(MotionBlur, EverythingMovingTogetherIsTheStill) {
  // Ground, wall and camera all slide 3 along x across the shutter: nothing
  // moves relative to anything else, so the pass is V(d0) - but only if the
  // camera, the hits it finds on the moving ground (rebuilt by
  // Instance::toWorldAt) and the AO rays all agree on each sample's time.
  auto scene = std::make_unique<Scene>();
  const int ground = scene->addInstancedMesh("ground");
  scene->addPrimitiveToMesh(ground, {{-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  const Affine groundSteps[2] = {translation(0.0f), translation(3.0f)};
  scene->addMovingInstance(ground, groundSteps, "ground");
  const int wall = scene->addInstancedMesh("wall");
  scene->addPrimitiveToMesh(wall, {{0, -50, 0}, {0, 50, 0}, {0, 50, 10}, {0, -50, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  const Affine wallSteps[2] = {translation(float(kD0)), translation(float(kD0) + 3.0f)};
  scene->addMovingInstance(wall, wallSteps, "wall");
  scene->commit();
  Camera cam = downAt(0);
  cam.motion = {downAt(0).toWorld, downAt(3).toWorld};
  RenderSettings s = blurSettings(true);
  s.aovs = true;
  const Film film = renderWith(*scene, cam, "ao", {"distance=1"}, s);
  expectAverage(film, wallVisibility(kD0, kRadius));
  // The depth seen is 3 (camera-plane depth, camera and ground co-moving).
  EXPECT_NEAR(meanCovered(film, kZ), 3.0, 1e-4);
}

TEST(MotionBlur, HitsOnARotatingInstanceLieOnTheRay) {
  // A wall at distance 1 from the z axis turns a quarter turn about it over
  // the shutter, keyed by the step rule; a ray from the axis along the
  // wall's normal at time u meets it at ~1, and the hit rebuilt from
  // barycentrics at that time (Instance::toWorldAt) lies on the ray.
  auto scene = std::make_unique<Scene>();
  const int wall = scene->addInstancedMesh("wall");
  scene->addPrimitiveToMesh(wall, {{1, -2, -2}, {1, 2, -2}, {1, 2, 2}, {1, -2, 2}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  std::vector<Affine> grid;
  for (int j = 0; j <= kMotionGrid; ++j) {
    const double a = kPi / 2 * j / kMotionGrid;
    Affine r;
    r.m[0][0] = float(std::cos(a)), r.m[0][1] = float(-std::sin(a));
    r.m[1][0] = float(std::sin(a)), r.m[1][1] = float(std::cos(a));
    grid.push_back(r);
  }
  Bounds3 box;
  box.extend(Vec3(1, -2, -2));
  box.extend(Vec3(1, 2, 2));
  const std::vector<Affine> steps = motionSteps(grid, box, 1e-4 * placedDiagonal(grid, box));
  ASSERT_GT(steps.size(), 2u);
  scene->addMovingInstance(wall, steps, "wall");
  scene->commit();
  for (const float u : {0.0f, 0.1f, 0.37f, 0.5f, 0.83f, 1.0f}) {
    const Vec3 d(std::cos(kPi / 2 * u), std::sin(kPi / 2 * u), 0.0f);
    RayHit rh = {};
    rh.ray.dir_x = d.x, rh.ray.dir_y = d.y, rh.ray.dir_z = d.z;
    rh.ray.tfar = kInfinity, rh.ray.mask = ~0u, rh.ray.time = u;
    rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(scene->rtcScene(), &ctx, Tracer::embree(&rh));
    ASSERT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID) << "u " << u;
    SurfaceHit h;
    computeSurfaceHit(*scene, rh, false, h);
    EXPECT_EQ(h.time, u);
    EXPECT_NEAR(rh.ray.tfar, 1.0, 1e-3) << "u " << u;  // the blend follows the turn to ~1e-4 of its size
    EXPECT_LT(length(h.p - d * rh.ray.tfar), 1e-5f) << "u " << u;
    EXPECT_GT(dot(h.ng, -d), 0.9999f) << "u " << u;
  }
}

TEST(MotionBlur, StillSceneWithShutterEqualsTheStill) {
  // Nothing moves: the samples' times change nothing, and the time's own
  // sample dimension leaves every other dimension as it was.
  const Affine still[1] = {translation(0.4f)};
  const auto scene = wallScene(still);
  for (const char* integrator : {"ao", "transfer", "reflocc"}) {
    RenderSettings on = blurSettings(true), off = blurSettings(false);
    on.aovs = off.aovs = true;
    const Film a = renderWith(*scene, downAt(0.1f), integrator, {}, on);
    const Film b = renderWith(*scene, downAt(0.1f), integrator, {}, off);
    const size_t n = size_t(a.width()) * size_t(a.height());
    ASSERT_EQ(a.channels(), b.channels());
    for (const int c : a.channels())
      EXPECT_EQ(std::memcmp(a.plane(c), b.plane(c), n * sizeof(float)), 0) << integrator << " " << a.name(c);
  }
}

TEST(MotionBlur, ScreenSpacePassesRefuseAShutter) {
  const Affine still[1] = {translation(0.4f)};
  const auto scene = wallScene(still);
  EXPECT_THROW(renderWith(*scene, downAt(0), "vo", {}, blurSettings(true)), Error);
}

// --- through the CLI: a glTF shot --------------------------------------------

// The wall scene as a glTF file: the ground, the wall node animated from x =
// d0 at t = 0 to x = d1 at t = 1 (`interpolation`), and a camera 3 above the
// origin looking down (-Z, glTF's view axis). With `movingCamera` the wall
// stands at d0 and the camera slides from x = 0 to x = d0 - d1 instead.
std::string writeWallShot(const std::string& dir, const std::string& name, const std::string& interpolation,
                          bool movingCamera = false) {
  GltfBuilder b;
  const int ground = b.quadMesh(50.0f);
  const int wallPos = b.positions({{0, -50, 0}, {0, 50, 0}, {0, 50, 10}, {0, -50, 10}});
  const int wallIdx = b.indices(std::vector<uint32_t>{0, 1, 2, 0, 2, 3});
  const int wall = b.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", wallPos}}}, {"indices", wallIdx}}})}});
  b.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 1e-3}, {"znear", 0.01}}}});
  const int groundNode = b.node({{"mesh", ground}, {"name", "ground"}});
  const int wallNode = b.node({{"mesh", wall}, {"name", "wall"}, {"translation", {kD0, 0, 0}}});
  const int camNode = b.node({{"camera", 0}, {"name", "camera"}, {"translation", {0, 0, 3}}});
  b.scene({groundNode, wallNode, camNode});
  const float end = interpolation == "STEP" ? 10.0f : 1.0f;
  if (movingCamera)
    b.animation("pan", {{camNode, "translation", {0.0f, end}, {0, 0, 3, float(kD0 - kD1), 0, 3}, interpolation}});
  else
    b.animation("slide", {{wallNode, "translation", {0.0f, end}, {float(kD0), 0, 0, float(kD1), 0, 0}, interpolation}});
  return b.writeGltf(dir, name);
}

// Mean and standard error of R over the pixels of an EXR (each pixel its
// own estimate).
std::pair<double, double> meanSe(const std::string& exr) {
  const ReadBack r = readExr(exr);
  EXPECT_TRUE(r.ok) << exr;
  if (!r.ok) return {0, 1};
  const std::vector<float>& R = r.planes.at("R");
  double s = 0, s2 = 0;
  for (const float v : R) s += v, s2 += double(v) * v;
  const double n = double(R.size()), mean = s / n;
  return {mean, std::sqrt(std::max(s2 / n - mean * mean, 0.0) / (n - 1))};
}

TEST(MotionBlurCli, AnimatedWallBlursToTheClosedForm) {
  const std::string dir = tempDir("motion_cli");
  const std::string shot = writeWallShot(dir, "shot", "LINEAR");
  const std::vector<std::string> base = {"render", shot, "-q", "-i", "ao", "-p", "distance=1", "--res", "16x16",
                                         "--spp", "64", "--no-aovs", "--fps", "1", "--frame", "0"};
  auto with = [&](std::vector<std::string> extra, const std::string& out) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    a.insert(a.end(), {"-o", dir + "/" + out});
    return a;
  };
  const std::vector<CliResult> runs =
      runClis({with({"--shutter", "0,1"}, "blur.exr"), with({}, "still.exr")}, dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const auto [blur, blurSe] = meanSe(dir + "/blur.exr");
  EXPECT_NEAR(blur, averageVisibility(kD0, kD1, kRadius), 4 * blurSe + 1e-6);
  const auto [still, stillSe] = meanSe(dir + "/still.exr");
  EXPECT_NEAR(still, wallVisibility(kD0, kRadius), 4 * stillSe + 1e-6);
  const ReadBack h = readExr(dir + "/blur.exr");
  EXPECT_EQ(h.spec.get_string_attribute("obscura:shutter"), "0,1");
  EXPECT_EQ(h.spec.get_int_attribute("obscura:movingObjects", -1), 1);
}

TEST(MotionBlurCli, AnimatedCameraBlursToTheClosedForm) {
  const std::string dir = tempDir("motion_cli_camera");
  const std::string shot = writeWallShot(dir, "shot", "LINEAR", true);
  const CliResult r = runCli({"render", shot, "-q", "-i", "ao", "-p", "distance=1", "--res", "16x16", "--spp", "64",
                              "--no-aovs", "--fps", "1", "--frame", "0", "--shutter", "0,1", "-o", dir + "/blur.exr"},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const auto [blur, blurSe] = meanSe(dir + "/blur.exr");
  EXPECT_NEAR(blur, averageVisibility(kD0, kD1, kRadius), 4 * blurSe + 1e-6);
  EXPECT_EQ(readExr(dir + "/blur.exr").spec.get_int_attribute("obscura:movingObjects", -1), 0);
}

TEST(MotionBlurCli, ANodeThatHoldsStillInTheShutterRendersAsTheStill) {
  // STEP keys at 0 and 10 s: the wall is animated but does not move within
  // [0, 1]; the shutter changes nothing, bit for bit, AOVs included.
  const std::string dir = tempDir("motion_cli_still");
  const std::string shot = writeWallShot(dir, "shot", "STEP");
  const std::vector<std::string> base = {"render", shot, "-q", "--res", "12x8", "--spp", "8", "--fps", "1", "--frame", "0"};
  std::vector<std::string> blur = base, still = base;
  blur.insert(blur.end(), {"--shutter", "0,1", "-o", dir + "/blur.exr"});
  still.insert(still.end(), {"-o", dir + "/still.exr"});
  const std::vector<CliResult> runs = runClis({blur, still}, dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack a = readExr(dir + "/blur.exr"), b = readExr(dir + "/still.exr");
  ASSERT_TRUE(a.ok && b.ok);
  for (const auto& [name, plane] : a.planes) EXPECT_EQ(plane, b.planes.at(name)) << name;
  EXPECT_EQ(a.spec.get_int_attribute("obscura:movingObjects", -1), 0);
}

TEST(MotionBlurCli, BadShuttersAreOneLine) {
  const std::string dir = tempDir("motion_cli_bad");
  const std::string shot = writeWallShot(dir, "shot", "LINEAR");
  for (const auto& [args, why] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"--frame", "0", "--shutter", "0.5,0.5"}, "OPEN < CLOSE"},
           {{"--frame", "0", "--shutter", "0.5"}, "OPEN,CLOSE"},
           {{"--frame", "0", "--shutter", "a,1"}, "OPEN,CLOSE"},
           {{"--frame", "0", "--shutter", "0,inf"}, "OPEN,CLOSE"},
           {{"--shutter", "0,1"}, "give --frame"},
           {{"--frame", "0", "--shutter", "0,1", "-i", "vo"}, "screen-space"},
       }) {
    std::vector<std::string> a = {"render", shot, "-q", "--res", "8x8", "--spp", "1"};
    a.insert(a.end(), args.begin(), args.end());
    a.insert(a.end(), {"-o", dir + "/bad.exr"});
    const CliResult r = runCli(a, dir + "/err.txt");
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.stderrText.find(why), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
    EXPECT_FALSE(std::filesystem::exists(dir + "/bad.exr"));
  }
}

// --- the step rule -----------------------------------------------------------

Affine rotationZ(double angle) {
  Affine a;
  a.m[0][0] = float(std::cos(angle)), a.m[0][1] = float(-std::sin(angle));
  a.m[1][0] = float(std::sin(angle)), a.m[1][1] = float(std::cos(angle));
  return a;
}

Bounds3 unitBox() {
  Bounds3 b;
  b.extend(Vec3(-1, -1, -1));
  b.extend(Vec3(1, 1, 1));
  return b;
}

TEST(MotionSteps, StillAndLinearPathsNeedNoMoreThanOneSegment) {
  std::vector<Affine> still(kMotionGrid + 1, translation(2.0f));
  EXPECT_EQ(motionSteps(still, unitBox(), 1e-6).size(), 1u);
  std::vector<Affine> slide;
  for (int j = 0; j <= kMotionGrid; ++j) slide.push_back(translation(float(j) / kMotionGrid * 8.0f));
  const auto steps = motionSteps(slide, unitBox(), 1e-5);
  ASSERT_EQ(steps.size(), 2u);
  EXPECT_EQ(steps[1].m[0][3], 8.0f);
}

TEST(MotionSteps, ARotationGetsTheSegmentsItsChordErrorNeeds) {
  // A quarter turn about z across the shutter. Blending the ends of a
  // segment of angle theta misses the arc by at most r (1 - cos(theta / 2))
  // (at its middle), r = sqrt(2) for the unit box's corners: the rule must
  // pick the fewest power-of-two segments meeting the tolerance.
  const double turn = kPi / 2;
  std::vector<Affine> grid;
  for (int j = 0; j <= kMotionGrid; ++j) grid.push_back(rotationZ(turn * j / kMotionGrid));
  for (const double tol : {1e-2, 1e-3, 1e-4}) {
    int expected = 1;
    while (std::sqrt(2.0) * (1 - std::cos(turn / expected / 2)) > tol) expected *= 2;
    const auto steps = motionSteps(grid, unitBox(), tol * (1 + 1e-6));
    EXPECT_EQ(int(steps.size()) - 1, expected) << "tolerance " << tol;
    // And the blend of the chosen steps follows the turn within tol at
    // times off the grid.
    const int n = int(steps.size()) - 1;
    for (double u : {0.013, 0.377, 0.5001, 0.93}) {
      Instance inst;
      inst.motion = steps;
      const Affine blended = inst.toWorldAt(float(u));
      const Affine exact = rotationZ(turn * u);
      const Vec3 c(1, 1, 1);
      EXPECT_LE(length(blended.point(c) - exact.point(c)), tol * 1.01 + 1e-6) << "u " << u << " n " << n;
    }
  }
}

}  // namespace
}  // namespace obscura
