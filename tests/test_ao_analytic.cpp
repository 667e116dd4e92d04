// The `ao` integrator against the closed forms of docs/math.md §7.
//
// Tolerances: each covered pixel averages spp camera samples, each one AO ray
// that is a Bernoulli(p) draw, so the mean over N = pixels x spp x rays draws
// has standard error sqrt(p(1-p)/N) (scrambled Sobol' only lowers it). We
// allow 4 standard errors, plus, for the tessellated sphere, a bound on the
// geometric error of replacing the sphere by chords: the surface lies within
// Rs (1 - cos(D/2)) <= Rs D^2 / 8 of the sphere (D = largest angular step),
// which moves a visibility boundary by at most that distance; we bound its
// effect on the estimate by D^2 (a generous multiple of D^2/8).
//
// The cavity scenes are built watertight (Scene::setRobust): the UV sphere's
// pole is a vertex shared by 512 sliver triangles, and Embree's fast
// (non-robust) traversal lets about 3e-4 of the rays aimed within 1e-4 of
// it slip through - a property of the mesh and the traversal mode, not of
// the estimator these tests check.
#include <gtest/gtest.h>

#include <obscura/sampler.h>
#include "tests/support.h"

namespace obscura::test {
namespace {

// A plane with nothing else: every AO ray escapes, so AO = 1 exactly at every
// pixel, at any scene scale and distance from the origin (robust offsets:
// a self-intersection anywhere would make some pixel < 1).
TEST(AoAnalytic, InfinitePlaneIsExactlyOneAtEveryScale) {
  for (const float scale : {1e-3f, 1.0f, 1e5f}) {
    for (const float shift : {0.0f, 1000.0f}) {
      Scene scene;
      const float z = shift * scale;
      addPlane(scene, 1e3f * scale, z);
      scene.commit();
      const Camera cam = makeLookAtCamera(Vec3(0.3f * scale, -2.0f * scale, z + 1.0f * scale),
                                          Vec3(0, 0, z), Vec3(0, 0, 1), 1.0f, "test");
      const Film film = renderWith(scene, cam, "ao", {"rays=4"}, passSettings(32, 32, 16));
      size_t covered = 0;
      for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x) {
          if (film.at(kA, x, y) != 1.0f) continue;
          ++covered;
          ASSERT_EQ(film.at(kR, x, y), 1.0f) << "scale " << scale << " shift " << shift << " pixel " << x << "," << y;
        }
      EXPECT_GT(covered, 900u);
    }
  }
}

struct Cavity {
  double alpha;  // hole half-angle at the centre
  double f() const { return (1.0 - std::cos(alpha)) / 2.0; }
};

constexpr int kRings = 256, kSegments = 512;
// Largest angular step of the tessellation (segments around the equator).
const double kStep = std::max(2.0 * M_PI / kSegments, M_PI / kRings);
const double kTessellationBound = kStep * kStep;

// AO with R = inf equals f at every wall point (uniform form factors inside a
// sphere), seen from several camera positions inside the cavity.
TEST(AoAnalytic, SphericalCavityInfiniteRadiusIsFEverywhere) {
  for (const double alpha : {0.5, 1.0471975511965976, 1.5707963267948966}) {
    Scene scene;
    addSphereCavity(scene, 1.0f, alpha, kRings, kSegments);
    scene.setRobust(true);
    scene.commit();
    const Cavity cav{alpha};
    const struct {
      Vec3 eye, target;
    } views[] = {{{0, 0, 0}, {0, 0, -1}}, {{0.3f, -0.2f, -0.1f}, {1, 0.2f, -0.6f}}, {{-0.2f, 0.1f, -0.3f}, {-0.3f, -1, -0.9f}}};
    for (const auto& v : views) {
      const Camera cam = makeLookAtCamera(v.eye, v.target, Vec3(0, 0, 1), 1.2f, "inside");
      const int w = 48, h = 48, spp = 64;
      const Film film = renderWith(scene, cam, "ao", {}, passSettings(w, h, spp));
      size_t n = 0;
      const double mean = meanCovered(film, kR, &n);
      ASSERT_GT(n, size_t(w * h / 2)) << "eye " << v.eye.x << "," << v.eye.y << "," << v.eye.z << " alpha " << alpha;
      const double se = bernoulliStdErr(cav.f(), double(n) * spp);
      EXPECT_NEAR(mean, cav.f(), 4.0 * se + kTessellationBound)
          << "alpha " << alpha << " eye " << v.eye.x << "," << v.eye.y << "," << v.eye.z;
    }
  }
}

// Step membership with finite R at the wall point opposite the hole:
// O = f + max(0, c0^2 - (R / 2Rs)^2), c0 = cos(alpha/2) (docs/math.md §7).
TEST(AoAnalytic, SphericalCavityFiniteRadiusAtAntipode) {
  const double alpha = 1.0471975511965976;  // 60 degrees: f = 1/4, c0^2 = 3/4
  for (const float rs : {1.0f, 250.0f}) {
    Scene scene;
    addSphereCavity(scene, rs, alpha, kRings, kSegments);
    scene.setRobust(true);
    scene.commit();
    // A very narrow view from the centre: every pixel sees the antipode
    // (0,0,-Rs) to within 1e-4 Rs.
    const Camera cam = makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1e-4f, "antipode");
    const double c0 = std::cos(alpha / 2);
    for (const double rOverRs : {0.5, 1.0, 1.5, 1.8, 2.5}) {
      const double R = rOverRs * rs;
      const double expected = Cavity{alpha}.f() + std::max(0.0, c0 * c0 - (R / (2.0 * rs)) * (R / (2.0 * rs)));
      const int w = 16, h = 16, spp = 256, rays = 4;
      const Film film = renderWith(scene, cam, "ao", {"distance=" + std::to_string(R), "rays=" + std::to_string(rays)},
                                   passSettings(w, h, spp));
      size_t n = 0;
      const double mean = meanCovered(film, kR, &n);
      ASSERT_EQ(n, size_t(w * h)) << "R/Rs " << rOverRs << " Rs " << rs;
      const double se = bernoulliStdErr(expected, double(n) * spp * rays);
      EXPECT_NEAR(mean, expected, 4.0 * se + kTessellationBound) << "Rs " << rs << " R/Rs " << rOverRs;
    }
  }
}

// Scrambled Sobol' samples are uniform: the AO estimate of a half-space test
// (fraction of cosine directions with x > 0 is exactly 1/2) converges.
TEST(AoAnalytic, SamplerIsUniformInTwoDimensions) {
  const uint32_t key = Sampler(7).pixelKey(3, 5);
  const int n = 1 << 14;
  double sx = 0, sy = 0, sxy = 0;
  for (int i = 0; i < n; ++i) {
    const Sample2 s = Sampler::get2D(key, uint32_t(i), kFirstIntegratorDim);
    ASSERT_GE(s.u, 0.0f);
    ASSERT_LT(s.u, 1.0f);
    ASSERT_GE(s.v, 0.0f);
    ASSERT_LT(s.v, 1.0f);
    sx += s.u, sy += s.v, sxy += s.u * s.v;
  }
  // A (0,2)-sequence prefix of 2^14 points: each of the 2^14 elementary
  // intervals holds one point, so means are within 2^-14 of exact.
  EXPECT_NEAR(sx / n, 0.5, 1.0 / n + 1e-6);
  EXPECT_NEAR(sy / n, 0.5, 1.0 / n + 1e-6);
  EXPECT_NEAR(sxy / n, 0.25, 2.0 / n + 1e-6);
}

}  // namespace
}  // namespace obscura::test
