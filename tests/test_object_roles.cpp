// Objects' roles (occluder, camera, matte, occlusion scope) and alpha
// cut-outs (MASK, BLEND) against the closed form of a square slab over a
// floor (docs/production.md "Objects and roles").
//
// The scene: an open floor z = 0 (object "floor") and a square slab of
// half-size a at height h (object "slab"). At the floor point under the
// slab's centre, AO with R = inf is 1 - F, F the form factor of the slab
// from that point: for a rectangle parallel to the floor, a signed sum of
// the corner-rectangle form factors (rectFormFactor below).
//
// Tolerances: a pixel's W averages spp Bernoulli draws (one AO ray a
// sample), so the image mean over N = pixels x spp draws has standard
// error sqrt(p (1 - p) / N) (scrambled Sobol' only lowers it); we allow 4
// of them. The camera sees a small patch about the centre, not the point:
// we add the largest change of the closed form over that patch, evaluated.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "core/scene/alpha.h"
#include <obscura/error.h>
#include "tests/support.h"

namespace obscura::test {
namespace {

// cornerFormFactor and rectFormFactor: tests/support.h.
constexpr float kHalf = 1.0f, kHeight = 1.0f;  // slab half-size a and height h
constexpr uint32_t kFloor = 0, kSlab = 1;

// Floor and slab as objects 0 and 1 (roles set by the caller before commit).
// The slab has uvs (u, v) = ((x + a) / 2a, (y + a) / 2a) and `material`.
void addFloorAndSlab(Scene& scene, int slabMaterial = -1, bool floor = true) {
  scene.objects = {{"floor", {}}, {"slab", {}}};
  if (floor) {
    scene.setCurrentObject(kFloor);
    addPlane(scene, 100 * kHalf, 0.0f);
  }
  scene.setCurrentObject(kSlab);
  scene.addWorldPrimitive({{-kHalf, -kHalf, kHeight}, {kHalf, -kHalf, kHeight}, {kHalf, kHalf, kHeight}, {-kHalf, kHalf, kHeight}}, {0, 1, 2, 0, 2, 3}, {},
                          {0, 0, 1, 0, 1, 1, 0, 1}, slabMaterial);
  scene.setCurrentObject(kNoObject);
}

// Narrow views: between floor and slab looking down at the floor's centre,
// above the slab looking down, and from the floor's centre looking up.
constexpr float kFov = 0.02f;
Camera underSlab() { return makeLookAtCamera(Vec3(0, 0, 0.5f * kHeight), Vec3(0, 0, 0), Vec3(0, 1, 0), kFov, "under"); }
Camera aboveSlab() { return makeLookAtCamera(Vec3(0, 0, 3 * kHeight), Vec3(0, 0, 0), Vec3(0, 1, 0), kFov, "above"); }
Camera upFromFloor() { return makeLookAtCamera(Vec3(0, 0, 0.01f * kHeight), Vec3(0, 0, kHeight), Vec3(0, 1, 0), kFov, "up"); }

constexpr int kRes = 16, kSpp = 256;
RenderSettings settings() { return passSettings(kRes, kRes, kSpp); }

// The floor's AO with R = inf at the centre under a slab whose occluding
// part has form factor `F` (a function of the floor point), with the
// tolerance of the comment at the top.
struct Expected {
  double w, tol;
};
Expected floorExpectation(const std::function<double(double px, double py)>& F, double distanceToFloor) {
  const double w = 1.0 - F(0, 0);
  // The patch seen: half-width d tan(fov / 2) (corners sqrt(2) farther).
  const double half = distanceToFloor * std::tan(kFov / 2) * std::sqrt(2.0);
  const double patch = std::max(std::abs(F(half, 0) - F(0, 0)), std::abs(F(half / std::sqrt(2.0), half / std::sqrt(2.0)) - F(0, 0)));
  return {w, 4 * bernoulliStdErr(w, double(kRes) * kRes * kSpp) + patch};
}
double solidSlab(double px, double py) { return rectFormFactor(-kHalf, kHalf, -kHalf, kHalf, kHeight, px, py); }

void expectFloorW(const Film& f, const Expected& e, const char* what) {
  size_t n = 0;
  const double mean = meanCovered(f, kR, &n);
  EXPECT_EQ(n, size_t(kRes) * kRes) << what;
  EXPECT_NEAR(mean, e.w, e.tol) << what;
}
void expectExactly(const Film& f, int channel, float value, const char* what) {
  for (int y = 0; y < kRes; ++y)
    for (int x = 0; x < kRes; ++x) ASSERT_EQ(f.at(channel, x, y), value) << what << " pixel " << x << "," << y;
}
void expectSameImage(const Film& a, const Film& b, const char* what) {
  for (const int c : {int(kR), int(kA)})
    for (int y = 0; y < kRes; ++y)
      for (int x = 0; x < kRes; ++x) ASSERT_EQ(a.at(c, x, y), b.at(c, x, y)) << what << " pixel " << x << "," << y;
}

Film renderFloorSlab(const std::function<void(Scene&)>& roles, const Camera& cam, int slabMaterial = -1,
                     const std::function<void(Scene&)>& materials = {}) {
  Scene scene;
  if (materials) materials(scene);
  addFloorAndSlab(scene, slabMaterial);
  if (roles) roles(scene);
  scene.commit();
  return renderWith(scene, cam, "ao", {}, settings());
}

TEST(ObjectRoles, SlabOccludesAsItsFormFactorSays) {
  const Film f = renderFloorSlab({}, underSlab());
  expectFloorW(f, floorExpectation(solidSlab, 0.5 * kHeight), "default roles");
  // Sanity of the closed form itself: the square of half-size 1 at height 1.
  EXPECT_NEAR(solidSlab(0, 0), 4 * cornerFormFactor(1, 1, 1), 1e-15);
}

TEST(ObjectRoles, ExcludedOccluderLeavesTheFloorOpen) {
  const Film f = renderFloorSlab([](Scene& s) { s.objects[kSlab].roles.occluder = false; }, underSlab());
  expectExactly(f, kR, 1.0f, "slab occluder=false");
}

TEST(ObjectRoles, OcclusionScopes) {
  const Film base = renderFloorSlab({}, underSlab());
  // The floor occluded only by itself: a plane never occludes itself.
  expectExactly(renderFloorSlab([](Scene& s) { s.objects[kFloor].roles.occlusion = OcclusionScope::Self; }, underSlab()),
                kR, 1.0f, "floor occlusion=self");
  // A scope applies to rays leaving the object: the slab's own scope, or the
  // floor ignoring itself, leaves the floor's rays exactly as they were.
  expectSameImage(renderFloorSlab([](Scene& s) { s.objects[kSlab].roles.occlusion = OcclusionScope::Self; }, underSlab()),
                  base, "slab occlusion=self");
  expectSameImage(renderFloorSlab([](Scene& s) { s.objects[kFloor].roles.occlusion = OcclusionScope::Others; }, underSlab()),
                  base, "floor occlusion=others");
}

// A closed cube seen from inside (one object): every AO ray hits it, so
// W = 0; with occlusion=others nothing else is there, so W = 1; with self, 0.
TEST(ObjectRoles, SelfOcclusionInsideAClosedBox) {
  const auto render = [](OcclusionScope scope) {
    Scene scene;
    scene.setRobust(true);  // watertight: no ray slips through the cube's edges
    scene.objects = {{"box", {}}};
    scene.objects[0].roles.occlusion = scope;
    scene.setCurrentObject(0);
    std::vector<Vec3> p;
    for (int c = 0; c < 8; ++c) p.emplace_back(c & 1 ? 1.0f : -1.0f, c & 2 ? 1.0f : -1.0f, c & 4 ? 1.0f : -1.0f);
    scene.addWorldPrimitive(p, {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4,
                                1, 5, 7, 1, 7, 3},
                            {}, {}, -1);
    scene.commit();
    return renderWith(scene, makeLookAtCamera(Vec3(0.1f, 0.2f, 0), Vec3(0.3f, 0.1f, -1), Vec3(0, 1, 0), 1.0f, "in"), "ao",
                      {"rays=4"}, settings());
  };
  expectExactly(render(OcclusionScope::All), kR, 0.0f, "box occlusion=all");
  expectExactly(render(OcclusionScope::Self), kR, 0.0f, "box occlusion=self");
  expectExactly(render(OcclusionScope::Others), kR, 1.0f, "box occlusion=others");
}

TEST(ObjectRoles, HiddenFromTheCameraStillOccludes) {
  const auto hide = [](Scene& s) { s.objects[kSlab].roles.camera = false; };
  // From above: the floor's centre is seen through the hidden slab, which
  // still shades it.
  const Film through = renderFloorSlab(hide, aboveSlab());
  expectExactly(through, kA, 1.0f, "coverage through the hidden slab");
  expectFloorW(through, floorExpectation(solidSlab, 3 * kHeight), "floor under a hidden slab");
  // From the floor looking up: the slab covers every pixel, unless hidden.
  expectExactly(renderFloorSlab({}, upFromFloor()), kA, 1.0f, "slab seen");
  expectExactly(renderFloorSlab(hide, upFromFloor()), kA, 0.0f, "slab hidden");
  // And the floor's rays are what they were.
  expectSameImage(renderFloorSlab(hide, underSlab()), renderFloorSlab({}, underSlab()), "floor W, slab hidden");
}

TEST(ObjectRoles, MatteHoldsOutAndStillOccludes) {
  const auto matte = [](Scene& s) { s.objects[kSlab].roles.matte = true; };
  const Film held = renderFloorSlab(matte, aboveSlab());
  expectExactly(held, kA, 0.0f, "matte coverage");
  expectExactly(held, kR, 0.0f, "matte pass");
  expectSameImage(renderFloorSlab(matte, underSlab()), renderFloorSlab({}, underSlab()), "floor W, slab matte");
  // A wider view: the floor around the slab is covered as before.
  const Camera wide = makeLookAtCamera(Vec3(0, 0, 3 * kHeight), Vec3(0, 0, 0), Vec3(0, 1, 0), 1.2f, "wide");
  Scene scene;
  addFloorAndSlab(scene);
  matte(scene);
  scene.commit();
  const Film f = renderWith(scene, wide, "ao", {}, settings());
  EXPECT_EQ(f.at(kA, 0, 0), 1.0f);  // a corner: floor beyond the slab
  EXPECT_GT(f.at(kR, 0, 0), 0.0f);
  EXPECT_EQ(f.at(kA, kRes / 2, kRes / 2), 0.0f);  // the centre: the slab
}

// The slab as a MASK cut-out: an 8 x 8 texel alpha texture whose columns
// are opaque or not by an irregular pattern (open fraction 4/8). The
// floor's AO is 1 minus the form factors of the opaque strips, summed
// independently here. Stripes, not a checkerboard: alpha is interpolated
// bilinearly, so the cutoff's contour follows texel edges exactly only
// where alpha varies along one axis; at a corner shared by differing
// diagonal texels it is a hyperbola, and the cells' closed form would not
// hold (measured: 0.776 against 0.762 for an 8 x 8 checker-like pattern).
TEST(ObjectRoles, MaskCutOutOccludesByItsOpaqueTexels) {
  constexpr int n = 8;
  const auto opaque = [](int x) { return (3 * x) % 7 < 3; };
  const std::string png = writeAlphaTexture(tempDir("roles") + "/mask.png", n, n, [&](int x, int) { return opaque(x) ? 1.0 : 0.0; });
  const auto cells = [&](double px, double py) {
    double F = 0;
    // Texel column x covers u in [x/n, (x+1)/n]: x in [-a + 2a x/n, -a + 2a (x+1)/n] on the slab.
    for (int x = 0; x < n; ++x)
      if (opaque(x)) F += rectFormFactor(-kHalf + 2 * kHalf * x / n, -kHalf + 2 * kHalf * (x + 1) / n, -kHalf, kHalf, kHeight, px, py);
    return F;
  };
  const auto material = [&](Scene& s) {
    const int m = addTexturedMaterial(s, png);
    s.materials[size_t(m)].alphaMode = AlphaMode::Mask;
    s.materials[size_t(m)].wrapS = s.materials[size_t(m)].wrapT = WrapMode::ClampToEdge;
  };
  const Film f = renderFloorSlab({}, underSlab(), 0, material);
  const Expected e = floorExpectation(cells, 0.5 * kHeight);
  // Between the solid slab and no slab, and at the open cells' value.
  EXPECT_GT(e.w, 1 - solidSlab(0, 0) + 0.05);
  EXPECT_LT(e.w, 1 - 0.05);
  expectFloorW(f, e, "MASK stripes");
}

// BLEND with alpha 0.3: each crossing is blocked with probability 0.3, so
// the floor's occlusion is 0.3 of the solid slab's.
TEST(ObjectRoles, BlendOccludesInProportionToAlpha) {
  const auto blend = [](Scene& s) {
    Material m;
    m.alphaMode = AlphaMode::Blend;
    m.alpha = 0.3f;
    s.materials.push_back(m);
  };
  const Film f = renderFloorSlab({}, underSlab(), 0, blend);
  expectFloorW(f, floorExpectation([](double x, double y) { return 0.3 * solidSlab(x, y); }, 0.5 * kHeight), "BLEND 0.3");

  // Seen from above without a floor, the slab covers 0.3 of the camera samples.
  Scene scene;
  blend(scene);
  addFloorAndSlab(scene, 0, false);
  scene.commit();
  const Film c = renderWith(scene, aboveSlab(), "ao", {}, settings());
  double coverage = 0;
  for (int y = 0; y < kRes; ++y)
    for (int x = 0; x < kRes; ++x) coverage += c.at(kA, x, y);
  coverage /= kRes * kRes;
  EXPECT_NEAR(coverage, 0.3, 4 * bernoulliStdErr(0.3, double(kRes) * kRes * kSpp));
}

// The stochastic alpha is a hash of the ray: the image is independent of
// threads and tiles, bit for bit.
TEST(ObjectRoles, BlendIsDeterministic) {
  Scene scene;
  Material m;
  m.alphaMode = AlphaMode::Blend;
  m.alpha = 0.5f;
  scene.materials.push_back(m);
  addFloorAndSlab(scene, 0);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(2, -3, 2.5f), Vec3(0, 0, 0.5f), Vec3(0, 0, 1), 0.9f, "side");
  Film ref;
  bool first = true;
  for (const int threads : {1, 2})
    for (const int tile : {8, 64}) {
      RenderSettings s = settings();
      s.threads = threads;
      s.tileSize = tile;
      Film f = renderWith(scene, cam, "gi", {}, s);
      if (first) {
        ref = std::move(f);
        first = false;
        continue;
      }
      expectSameImage(f, ref, ("threads " + std::to_string(threads) + " tile " + std::to_string(tile)).c_str());
    }
}

TEST(ObjectRoles, BlendSampleIsUniform) {
  // The hash's numbers over a sweep of rays: mean 1/2, variance 1/12 to
  // within 4 standard errors of n draws.
  constexpr int n = 100000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const float org[3] = {float(i) * 1e-3f, 0.5f, -float(i % 97)};
    const float dir[3] = {0.0f, std::sin(float(i)), std::cos(float(i))};
    const double u = blendSample(org, dir, 0, uint32_t(i % 13), RTC_INVALID_GEOMETRY_ID);
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u, sum2 += u * u;
  }
  EXPECT_NEAR(sum / n, 0.5, 4 * std::sqrt(1.0 / 12 / n));
  EXPECT_NEAR(sum2 / n - (sum / n) * (sum / n), 1.0 / 12, 4 * std::sqrt(1.0 / 180 / n));
}

TEST(ObjectRoles, OverridesMatchByGlobAndRefuseUnknownNames) {
  std::vector<SceneObject> objects = {{"Tree_01", {}}, {"Tree_02", {}}, {"ground", {}}};
  applyObjectOverrides(objects, {parseObjectOverride("Tree*:occluder=false,occlusion=self")});
  EXPECT_FALSE(objects[0].roles.occluder);
  EXPECT_EQ(objects[1].roles.occlusion, OcclusionScope::Self);
  EXPECT_TRUE(objects[2].roles.isDefault());
  try {
    applyObjectOverrides(objects, {parseObjectOverride("Bush*:matte=true")});
    FAIL() << "an override matching nothing must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no object is named 'Bush*'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'ground'"), std::string::npos) << e.what();
  }
  for (const char* bad : {"Tree", "Tree:", ":matte=true", "Tree:matte", "Tree:matte=maybe", "Tree:occlusion=some", "Tree:colour=red"})
    EXPECT_THROW(parseObjectOverride(bad), Error) << bad;
}

}  // namespace
}  // namespace obscura::test

namespace obscura::test {
namespace {

// Screen-space integrators occlude by the depth buffer: with no object an
// occluder, every tap reads background and every covered pixel is open (W
// = the sum of the taps' weights: 1 up to float rounding of a sum of a few
// dozen weights, within 1e-5; vo with point samples, whose weights sum to 1 -
// line samples weight chords by a perspective Jacobian, normalized only in
// expectation); a matte slab holds out in their G-buffer as in the
// ray-traced loop.
TEST(ObjectRoles, ScreenSpaceHonoursOccluderAndMatte) {
  const Camera side = makeLookAtCamera(Vec3(0.5f, -3, 1.6f), Vec3(0, 0, 0.4f), Vec3(0, 0, 1), 1.0f, "side");
  for (const std::string integrator : {"vo", "ssat"}) {
    const std::vector<std::string> params = integrator == "vo" ? std::vector<std::string>{"samples=point"} : std::vector<std::string>{};
    Scene scene;
    addFloorAndSlab(scene);
    for (SceneObject& o : scene.objects) o.roles.occluder = false;
    scene.commit();
    const Film f = renderWith(scene, side, integrator, params, passSettings(24, 24, 4));
    size_t covered = 0;
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 24; ++x) {
        ASSERT_NEAR(f.at(kR, x, y), f.at(kA, x, y), 1e-5) << integrator << " pixel " << x << "," << y;  // W = 1, premultiplied
        covered += f.at(kA, x, y) > 0 ? 1 : 0;
      }
    EXPECT_GT(covered, 400u) << integrator;
    Scene held;
    addFloorAndSlab(held);
    held.objects[kSlab].roles.matte = true;
    held.commit();
    const Film m = renderWith(held, aboveSlab(), integrator, params, passSettings(kRes, kRes, 4));
    expectExactly(m, kA, 0.0f, integrator.c_str());
    expectExactly(m, kR, 0.0f, integrator.c_str());
  }
}

}  // namespace
}  // namespace obscura::test
