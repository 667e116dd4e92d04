// Numerical stability at the extremes (scene scale, R, sigma, grazing
// normals, degenerate triangles, rays starting on edges and vertices):
// every pixel finite and in range, and the closed-form values where there is
// one. Tolerances: 4 standard errors of the Bernoulli/[0,1] mean, as in
// test_ao_analytic.cpp.
#include <gtest/gtest.h>

#include "core/scene/environment.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

void expectFiniteInUnitRange(const Film& f, const std::string& what) {
  for (int c : {int(kR), int(kG), int(kB), int(kA)})
    for (int y = 0; y < f.height(); ++y)
      for (int x = 0; x < f.width(); ++x) {
        const float v = f.at(c, x, y);
        ASSERT_TRUE(std::isfinite(v)) << what << " channel " << c << " pixel " << x << "," << y;
        ASSERT_GE(v, 0.0f) << what;
        ASSERT_LE(v, 1.0f) << what;
      }
}

// A floor z = 0 (a grid of 2x2-unit cells, so there are interior edges and
// vertices) and a wall x = 0 rising above it, both "infinite" (1e3 x the
// region looked at), scaled by s. On either surface every direction into the
// other's half-space hits it: AO = 1/2 exactly, at every point, at any scale.
void addCrease(Scene& scene, float s, int cells = 8) {
  const float big = 1e3f * s, cell = 2.0f * s;
  std::vector<Vec3> p;
  std::vector<uint32_t> idx;
  // Floor: a grid near the crease, framed by large triangles out to `big`.
  for (int j = 0; j <= cells; ++j)
    for (int i = 0; i <= cells; ++i) p.push_back(Vec3(float(i) * cell, float(j - cells / 2) * cell, 0));
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i) {
      const uint32_t a = uint32_t(j * (cells + 1) + i), b = a + 1, c = a + uint32_t(cells + 1), d = c + 1;
      idx.insert(idx.end(), {a, b, d, a, d, c});
    }
  scene.addWorldPrimitive(p, idx, {}, {}, -1);
  const float x1 = float(cells) * cell, y0 = -float(cells / 2) * cell, y1 = float(cells / 2) * cell;
  // Surround of the grid on the floor (x in [0, big], y in [-big, big]).
  scene.addWorldPrimitive({{0, -big, 0}, {big, -big, 0}, {big, y0, 0}, {0, y0, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.addWorldPrimitive({{0, y1, 0}, {big, y1, 0}, {big, big, 0}, {0, big, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.addWorldPrimitive({{x1, y0, 0}, {big, y0, 0}, {big, y1, 0}, {x1, y1, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  // Wall x = 0, z in [0, big].
  scene.addWorldPrimitive({{0, -big, 0}, {0, big, 0}, {0, big, big}, {0, -big, big}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
}

struct Config {
  std::string integrator;
  std::vector<std::string> params;
};

// Integrators whose value in the crease is exactly 1/2 (occluders are black
// and any hit occludes).
std::vector<Config> halfInCrease() {
  return {{"ao", {}},
          {"obscurance", {"falloff=step", "estimator=distance"}},
          {"obscurance", {"falloff=step", "estimator=occlusion"}}};
}

std::string describe(const Config& c) {
  std::string s = c.integrator;
  for (const auto& p : c.params) s += " " + p;
  return s;
}

TEST(Stability, CreaseIsOneHalfAtEveryScale) {
  for (const float s : {1e-4f, 1.0f, 1e5f}) {
    Scene scene;
    addCrease(scene, s);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(6 * s, -5 * s, 4 * s), Vec3(2 * s, 0, 1 * s), Vec3(0, 0, 1), 0.9f, "crease");
    for (const Config& c : halfInCrease()) {
      const int w = 32, h = 24, spp = 32;
      const Film f = renderWith(scene, cam, c.integrator, c.params, passSettings(w, h, spp));
      expectFiniteInUnitRange(f, describe(c));
      size_t n = 0;
      const double mean = meanCovered(f, kR, &n);
      ASSERT_EQ(n, size_t(w * h)) << describe(c);
      EXPECT_NEAR(mean, 0.5, 4.0 * bernoulliStdErr(0.5, double(n) * spp)) << describe(c) << " scale " << s;
    }
  }
}

// Camera rays aimed (to within 1e-7 of the view) at a grid vertex of the
// floor, at a point of an interior edge, and at the crease line itself: the
// AO rays then start on a vertex or an edge shared by several triangles.
TEST(Stability, RaysStartingOnEdgesAndVertices) {
  for (const float s : {1e-4f, 1.0f, 1e5f}) {
    Scene scene;
    addCrease(scene, s);
    scene.setRobust(true);  // camera rays must not slip between the triangles either
    scene.commit();
    const Vec3 targets[] = {{4 * s, 2 * s, 0}, {4 * s, 3 * s, 0}, {5 * s, 3 * s, 0}, {0, 2 * s, 0}, {0, 2 * s, 1 * s}};
    for (const Vec3 t : targets) {
      const Camera cam = makeLookAtCamera(t + Vec3(3 * s, -2 * s, 2.5f * s), t, Vec3(0, 0, 1), 1e-6f, "point");
      for (const Config& c : halfInCrease()) {
        const int w = 4, h = 4, spp = 1024;
        const Film f = renderWith(scene, cam, c.integrator, c.params, passSettings(w, h, spp));
        expectFiniteInUnitRange(f, describe(c));
        size_t n = 0;
        const double mean = meanCovered(f, kR, &n);
        ASSERT_EQ(n, size_t(w * h)) << describe(c) << " scale " << s;
        EXPECT_NEAR(mean, 0.5, 4.0 * bernoulliStdErr(0.5, double(n) * spp))
            << describe(c) << " scale " << s << " target " << t.x / s << "," << t.y / s << "," << t.z / s;
      }
    }
  }
}

// R at the extremes, relative to a scene of size ~16: R = 1e-9 x that is
// below the ray offset, so nothing occludes (value 1 but where geometry is
// closer than R: nowhere at pixel centres); R = 1e12 x is R = inf.
TEST(Stability, ExtremeDistances) {
  Scene scene;
  addCrease(scene, 1.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(6, -5, 4), Vec3(2, 0, 1), Vec3(0, 0, 1), 0.9f, "crease");
  const RenderSettings st = passSettings(24, 16, 8);
  for (const std::string integ : {"ao", "obscurance", "transfer", "multibounce"}) {
    const Film tiny = renderWith(scene, cam, integ, {"distance=1.6e-8"}, st);
    expectFiniteInUnitRange(tiny, integ + " tiny R");
    EXPECT_GT(meanCovered(tiny, kR), 1.0 - 1e-3) << integ;
    const Film huge = renderWith(scene, cam, integ, {"distance=1.6e13"}, st);
    const Film inf = renderWith(scene, cam, integ, {"distance=inf"}, st);
    expectFiniteInUnitRange(huge, integ + " huge R");
    for (int y = 0; y < st.height; ++y)
      for (int x = 0; x < st.width; ++x) EXPECT_EQ(huge.at(kR, x, y), inf.at(kR, x, y)) << integ;
  }
}

// The screen-space passes' radius over its whole accepted range, 1e-30 to
// 1e30 (scene size ~16): every pixel finite and in [0, 1], and shaded.*
// finite with E0 read at the bent normal under a non-uniform map (vo's
// line and area chords once overflowed float for R in 1e14 .. 1e19: NaN in
// every covered pixel). Tiny R: nothing occludes, W = 1.
TEST(Stability, ScreenSpaceRadiusOverItsWholeRange) {
  Scene scene;
  addCrease(scene, 1.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(6, -5, 4), Vec3(2, 0, 1), Vec3(0, 0, 1), 0.9f, "crease");
  std::vector<float> rgb;
  for (int t = 0; t < 8 * 4; ++t) rgb.insert(rgb.end(), {float(t % 8), 1.0f, float(t / 8)});
  RenderSettings st = passSettings(24, 16, 2);
  st.aovs = true;
  st.albedoAov = true;
  st.environment = Environment::fromTexels(std::move(rgb), 8, 4, {}, "ramp");
  for (const char* R : {"1e-30", "1e-20", "1e-10", "1e-3", "1", "1e3", "1e10", "1e14", "1e16", "1e19", "1e20", "1e30"}) {
    const std::string r = R;
    const std::vector<Config> configs = {
        {"vo", {"samples=point", "radius=" + r, "e0=bent"}},
        {"vo", {"samples=line", "radius=" + r, "e0=bent"}},
        {"vo", {"samples=area", "radius=" + r, "e0=bent"}},
        {"vo", {"samples=line", "radius=1", "radius2=" + r, "thickness=" + r}},
        {"vo", {"samples=line", "radius=" + r, "depth=traced"}},
        {"ssat", {"distance=" + r, "e0=bent"}},
        {"ssat", {"distance=" + r, "falloff=linear", "steps=2", "albedo=true"}},
        {"gtao", {"radius=" + r, "e0=bent"}},
        {"gtao", {"radius=" + r, "depth=traced", "multibounce=on"}},
    };
    for (const Config& c : configs) {
      const Film f = renderWith(scene, cam, c.integrator, c.params, st);
      expectFiniteInUnitRange(f, describe(c));
      for (int y = 0; y < f.height(); ++y)
        for (int x = 0; x < f.width(); ++x) ASSERT_TRUE(std::isfinite(f.at(kShadedR, x, y))) << describe(c);
      if (std::stod(r) < 1e-9) {
        EXPECT_EQ(meanCovered(f, kR), 1.0) << describe(c);
      }
    }
  }
}

// The white crease (albedo 1, sky reachable) is a white furnace: transfer is
// exactly 1 and gi converges to 1, at every scale, with the extreme media
// too. gi's pixels are independent estimates: 4 standard errors of their
// mean. sigma = 1e30 makes mu(d) = 1 - e^(-sigma d) = 1 beyond d ~ 1e-28, so
// the medium itself is the sky; sigma = 1e-30 is vacuum to double precision.
TEST(Stability, WhiteCreaseIsAWhiteFurnaceAtEveryScale) {
  for (const float s : {1e-4f, 1.0f, 1e5f}) {
    Scene scene;
    addCrease(scene, s);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(6 * s, -5 * s, 4 * s), Vec3(2 * s, 0, 1 * s), Vec3(0, 0, 1), 0.9f, "crease");
    const int w = 32, h = 24;
    for (const std::vector<std::string>& p : {std::vector<std::string>{"depth=0"}, {"depth=3"},
                                              {"falloff=exponential", "sigma=1e-30"},
                                              {"falloff=exponential", "sigma=1e30", "estimator=occlusion"}}) {
      const Film f = renderWith(scene, cam, "transfer", p, passSettings(w, h, 8));
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) ASSERT_EQ(f.at(kR, x, y), 1.0f) << "transfer " << p[0] << " scale " << s;
    }
    for (const char* sigma : {"sigma=0", "sigma=1e-30", "sigma=1e30"}) {
      const Film f = renderWith(scene, cam, "gi", {sigma}, passSettings(w, h, 16));
      double sum = 0, sum2 = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const double v = f.at(kR, x, y);
          ASSERT_TRUE(std::isfinite(v)) << sigma;
          sum += v, sum2 += v * v;
        }
      const double n = double(w * h), mean = sum / n;
      const double se = std::sqrt(std::max(sum2 / n - mean * mean, 0.0) / (n - 1));
      EXPECT_NEAR(mean, 1.0, 4.0 * se + 1e-6) << "gi " << sigma << " scale " << s;
    }
  }
}

// A plane whose shading normals are nearly (or exactly) perpendicular to the
// geometric normal, or flipped, or degenerate (zero): always finite. With
// the shading normal at elevation beta above the plane, the cosine lobe about
// it leaves through the open side with probability (1 + sin beta)/2 (the
// rest is blocked by the opaque surface itself).
TEST(Stability, GrazingAndDegenerateShadingNormals) {
  for (const double d : {1e-3, 1e-7, 0.0}) {
    Scene scene;
    const float h = 1e3f;
    const Vec3 ns = normalize(Vec3(1, 0, float(d)));
    scene.addWorldPrimitive({{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}}, {0, 1, 2, 0, 2, 3}, {ns, ns, ns, ns}, {}, -1);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(0.3f, -2, 1.5f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "grazing");
    const int w = 24, hgt = 24, spp = 64;
    const Film f = renderWith(scene, cam, "ao", {}, passSettings(w, hgt, spp));
    expectFiniteInUnitRange(f, "grazing");
    size_t n = 0;
    const double mean = meanCovered(f, kR, &n);
    const double expected = (1.0 + double(ns.z)) / 2.0;
    EXPECT_NEAR(mean, expected, 4.0 * bernoulliStdErr(expected, double(n) * spp)) << "d " << d;
  }
  // Flipped and zero normals fall back to facing the camera: an open plane.
  for (const Vec3 ns : {Vec3(0, 0, -1), Vec3(0, 0, 0)}) {
    Scene scene;
    const float h = 1e3f;
    scene.addWorldPrimitive({{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}}, {0, 1, 2, 0, 2, 3}, {ns, ns, ns, ns}, {}, -1);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(0.3f, -2, 1.5f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "flipped");
    const Film f = renderWith(scene, cam, "ao", {}, passSettings(16, 16, 16));
    expectFiniteInUnitRange(f, "flipped/zero normal");
    EXPECT_EQ(meanCovered(f, kR), 1.0);
  }
}

// Zero-area triangles (repeated vertices, collinear vertices) next to an
// ordinary plane: loading, building and rendering stay finite, and the
// plane stays open (AO = 1 exactly).
TEST(Stability, ZeroAreaTriangles) {
  Scene scene;
  const float h = 1e3f;
  std::vector<Vec3> p = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0},
                         {1, 1, 0}, {1, 1, 0}, {2, 2, 0}, {0, 0, 0}};
  std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3, 4, 5, 4, 4, 6, 7, 7, 7, 7};
  scene.addWorldPrimitive(p, idx, {}, {}, -1);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(1.3f, -1, 2), Vec3(1, 1, 0), Vec3(0, 0, 1), 0.8f, "degenerate");
  for (const Config& c : halfInCrease()) {
    const Film f = renderWith(scene, cam, c.integrator, c.params, passSettings(16, 16, 16));
    expectFiniteInUnitRange(f, describe(c));
    EXPECT_EQ(meanCovered(f, kR), 1.0) << describe(c);
  }
}

}  // namespace
}  // namespace obscura::test
