// `ssat`'s variants from the ambient-transfer paper beyond [AT 9]: the
// occluding pixel's radiance in place of its albedo (end of AT §4.1,
// occluder=radiance; docs/math.md §9, the pixel's radiance).
//
// Tolerances: replicate renders (seeds 1..16) are independent, so the mean
// over them of an image statistic has the standard error of their spread
// (support.h replicateMean); tests allow 4 of them, combined with the
// standard error of any Monte Carlo reference (independent of the renders).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kPiD = 3.14159265358979323846;

// The crease of support.h (floor z = 0, x in [0, 10]; wall x = 0, z in
// [0, 10]; |y| <= 10; its camera) with a black floor and a coloured wall:
// a floor point's occluders are wall points, whose own occluder is the
// black floor - so a wall point reflects a_w O(z) under the sky, O(z) =
// creaseCosine(z, R) its obscurance at height z (the floor is a half-plane
// at distance z), and receives no light from the floor.
struct ColouredCrease {
  Crease c;  // (its camera)
  Scene scene;
  Vec3 wallAlbedo{0.9f, 0.6f, 0.3f};
  ColouredCrease() {
    const int black = addGreyMaterial(scene, 0.0f);
    Material m;
    m.name = "wall";
    m.baseColorFactor = wallAlbedo;
    scene.materials.push_back(m);
    const int wall = int(scene.materials.size()) - 1;
    scene.addWorldPrimitive({{0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, black);
    scene.addWorldPrimitive({{0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, wall);
    scene.commit();
  }
};

// The first surface on the camera ray through film position (fx, fy): 0
// floor, 1 wall, -1 nothing, with the point (both planes analytic).
int surfaceAtFilm(const RasterCamera& rc, double fx, double fy, double p[3]) {
  const Vec3 d = rc.direction(float(fx), float(fy));
  const double o[3] = {rc.org.x, rc.org.y, rc.org.z}, v[3] = {d.x, d.y, d.z};
  double best = INFINITY;
  int which = -1;
  const auto tryPlane = [&](int axis, int id, int u, double uMax) {
    if (!(v[axis] < 0.0)) return;
    const double t = -o[axis] / v[axis];
    const double pu = o[u] + t * v[u], py = o[1] + t * v[1];
    if (t > 0.0 && t < best && pu >= 0.0 && pu <= uMax && std::abs(py) <= 10.0) best = t, which = id;
  };
  tryPlane(2, 0, 0, 10.0);  // the floor z = 0, x in [0, 10]
  tryPlane(0, 1, 2, 10.0);  // the wall x = 0, z in [0, 10]
  if (which >= 0)
    for (int k = 0; k < 3; ++k) p[k] = o[k] + best * v[k];
  return which;
}

// The floor pixels of the crease near the wall (x < 1.2, |y| < 1.5) whose
// whole footprint sees the floor (its four corners do, and the floor's
// image is convex).
std::vector<std::pair<int, int>> floorPixels(const RasterCamera& rc, int w, int h) {
  std::vector<std::pair<int, int>> out;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool floor = true;
      double p[3];
      for (int k = 0; k < 4 && floor; ++k)
        floor = surfaceAtFilm(rc, x + (k & 1), y + (k >> 1), p) == 0 && p[0] < 1.2 && std::abs(p[1]) < 1.5;
      if (floor) out.emplace_back(x, y);
    }
  return out;
}

// --- the pixel's radiance (occluder=radiance) ------------------------------------

// The expected value of `ssat albedo=true occluder=radiance depth=traced`
// (step membership, R, one test point per sample, silhouette rule off) at
// a floor pixel of the coloured crease, per unit of wall albedo, computed
// without the renderer: with the step membership every test point lies at
// p = X + R w, w cosine distributed about +z, X the pixel's camera sample
// (uniform over the pixel: the box filter). The traced twin's containment
// is exact here: p is inside iff it is behind the wall (p.x < 0; the camera
// ray to p then meets the wall first, the floor never, as p.z >= 0), so
//   E[W] = E[O(X)] + a_w E[[p.x < 0] [q's sample is on the wall] O(z_q)],
// O = creaseCosine the obscurance (floor point: distance to the wall X.x;
// wall point: height z), q the pixel p projects to, z_q the height of
// pixel q's own camera sample, uniform over q (independent of X's: another
// pixel's stream), where the pass estimates q's obscurance (with a shift
// and rotation of its own, so unbiased given q; a floor sample there is
// black). Monte Carlo over (film position, w, q's film position), K draws
// per pixel: per pixel E[O] and the bounce per unit albedo, and the
// (co)variances of the pixel means for the reference's own standard error.
struct RadianceReference {
  std::vector<double> obscurance, bounce;
  double varO = 0.0, varB = 0.0, covOB = 0.0;  // of the mean over pixels
  // The z-buffer's one departure from the traced containment here: a test
  // point is tested against the plane of the sample of the pixel it
  // projects to, exact unless that sample lies on the other plane, in a
  // pixel the crease crosses. A closed point behind the wall whose pixel's
  // sample is on the floor meets the floor's plane beyond itself: open; a
  // closed point under the floor whose pixel's sample is on the wall
  // likewise; an open point is open against either plane. Each such flip
  // moves a shaded pixel's sample by <= 1 (from a~ O~ to 1) and an
  // occluder's test by <= 1 (a~ O~ by <= a/n per test of n), so
  // |E[z-buffer] - E[traced]| <= straddleOuter + a straddleOccluder, the
  // probabilities of a flip among the shaded pixels' test points and among
  // the occluders' (weighted by the closed, wall-lit samples).
  double straddleOuter = 0.0, straddleOccluder = 0.0;
  // The Monte Carlo variance of the mean over pixels of O + a bounce.
  double variance(double a) const { return varO + a * a * varB + 2.0 * a * covOB; }
};
RadianceReference radianceReference(const Camera& cam, int w, int h, const std::vector<std::pair<int, int>>& pixels,
                                    double R, int K) {
  const RasterCamera rc(cam, w, h);
  const ViewTransform view = viewTransform(cam, w, h);
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  RadianceReference ref;
  const double n2 = double(pixels.size()) * double(pixels.size());
  // A pixel the crease crosses: its corners see different planes.
  const auto straddles = [&](double fx, double fy) {
    const int qx = int(std::floor(fx)), qy = int(std::floor(fy));
    double c[3];
    const int s0 = surfaceAtFilm(rc, qx, qy, c);
    for (int k = 1; k < 4; ++k)
      if (surfaceAtFilm(rc, qx + (k & 1), qy + (k >> 1), c) != s0) return true;
    return false;
  };
  const auto filmOf = [&](const double p[3], float& fx, float& fy) {
    view.project(view.pointToView(Vec3(float(p[0]), float(p[1]), float(p[2]))), fx, fy);
  };
  double straddleOuter = 0.0, straddleOccluder = 0.0;
  for (auto [px, py] : pixels) {
    double so = 0.0, sb = 0.0, soo = 0.0, sbb = 0.0, sob = 0.0;
    for (int k = 0; k < K; ++k) {
      double X[3];
      surfaceAtFilm(rc, px + u01(rng), py + u01(rng), X);  // the whole footprint sees the floor
      const double o = creaseCosine(X[0], R);
      const double phi = 2.0 * kPiD * u01(rng), u = u01(rng);
      const double sr = std::sqrt(u), wz = std::sqrt(1.0 - u);
      const double p[3] = {X[0] + R * sr * std::cos(phi), X[1] + R * sr * std::sin(phi), X[2] + R * wz};
      double b = 0.0;
      float fx, fy;
      filmOf(p, fx, fy);
      if (p[0] < 0.0) {
        const int qx = int(std::floor(fx)), qy = int(std::floor(fy));
        double Y[3], F[3];
        // The flip: pixel q's sample (another draw of it) on the floor.
        straddleOuter += straddles(fx, fy) && surfaceAtFilm(rc, qx + u01(rng), qy + u01(rng), F) == 0;
        if (qx >= 0 && qy >= 0 && qx < w && qy < h && surfaceAtFilm(rc, qx + u01(rng), qy + u01(rng), Y) == 1) {
          b = creaseCosine(Y[2], R);
          // One of the occluder's test points, cosine about the wall's +x.
          const double phi2 = 2.0 * kPiD * u01(rng), u2 = u01(rng);
          const double s2 = std::sqrt(u2);
          const double p2[3] = {Y[0] + R * std::sqrt(1.0 - u2), Y[1] + R * s2 * std::cos(phi2),
                                Y[2] + R * s2 * std::sin(phi2)};
          float gx, gy;
          filmOf(p2, gx, gy);
          if (p2[2] < 0.0 && straddles(gx, gy))
            straddleOccluder += surfaceAtFilm(rc, std::floor(gx) + u01(rng), std::floor(gy) + u01(rng), F) == 1;
        }
      }
      so += o, sb += b, soo += o * o, sbb += b * b, sob += o * b;
    }
    const double mo = so / K, mb = sb / K;
    ref.obscurance.push_back(mo);
    ref.bounce.push_back(mb);
    ref.varO += (soo / K - mo * mo) / K / n2;
    ref.varB += (sbb / K - mb * mb) / K / n2;
    ref.covOB += (sob / K - mo * mb) / K / n2;
  }
  ref.straddleOuter = straddleOuter / (double(K) * double(pixels.size()));
  ref.straddleOccluder = straddleOccluder / (double(K) * double(pixels.size()));
  return ref;
}

// The closed form of the radiance variant on the coloured crease, per RGB
// channel: the traced twin's mean over the floor pixels near the wall
// equals E[O] + a_w,c E[bounce] (radianceReference) within 4 standard
// errors (16 replicate renders; the reference's Monte Carlo error, ~10^-4,
// added in quadrature). The bounce is no rounding error: it raises the
// red channel by >= 20 of those standard errors over the obscurance.
// The z-buffer pass agrees with its twin within 4 standard errors of the
// paired difference (same seeds: same camera samples and sets) plus the
// bound on what the crease's pixels can change (RadianceReference::
// straddleOuter, straddleOccluder: the only place the two containments
// differ here; both planes are stored exactly).
TEST(SsatRadiance, CreaseMatchesTheOneBounceClosedForm) {
  const ColouredCrease cc;
  const int w = 64, h = 48;
  const double R = 0.6;
  const RasterCamera rc(cc.c.cam, w, h);
  const auto pixels = floorPixels(rc, w, h);
  ASSERT_GT(pixels.size(), 150u);
  const RadianceReference ref = radianceReference(cc.c.cam, w, h, pixels, R, 4096);
  double meanO = 0.0, meanB = 0.0;
  for (size_t i = 0; i < pixels.size(); ++i) meanO += ref.obscurance[i], meanB += ref.bounce[i];
  meanO /= double(pixels.size()), meanB /= double(pixels.size());
  const std::vector<std::string> base = {"falloff=step", "distance=0.6", "albedo=true", "occluder=radiance",
                                         "silhouette=false", "interleave=off"};
  const float albedo[3] = {cc.wallAlbedo.x, cc.wallAlbedo.y, cc.wallAlbedo.z};
  const int channel[3] = {kR, kG, kB};
  for (int c = 0; c < 3; ++c) {
    std::vector<std::string> traced = base;
    traced.push_back("depth=traced");
    const MeanSe m = replicateMean(16, [&](uint32_t seed) {
      const Film f = renderWith(cc.scene, cc.c.cam, "ssat", traced, passSettings(w, h, 4, seed));
      double sum = 0.0;
      for (auto [x, y] : pixels) sum += f.at(channel[c], x, y);
      return sum / double(pixels.size());
    });
    const double expected = meanO + albedo[c] * meanB;
    const double tol = 4.0 * std::sqrt(m.se * m.se + ref.variance(albedo[c]));
    EXPECT_NEAR(m.mean, expected, tol) << "channel " << c << " obscurance " << meanO << " bounce " << meanB;
    if (c == 0) {
      EXPECT_GT(albedo[c] * meanB, 20.0 * tol) << "the bounce is too small to test";
    }
    RecordProperty("ssat_radiance_traced_" + std::to_string(c),
                   std::to_string(m.mean) + " expected " + std::to_string(expected) + " tol " + std::to_string(tol));
  }
  // The twin: z-buffer minus traced, paired by seed.
  for (int c = 0; c < 3; ++c) {
    const MeanSe d = replicateMean(16, [&](uint32_t seed) {
      std::vector<std::string> traced = base;
      traced.push_back("depth=traced");
      const Film a = renderWith(cc.scene, cc.c.cam, "ssat", base, passSettings(w, h, 4, seed));
      const Film b = renderWith(cc.scene, cc.c.cam, "ssat", traced, passSettings(w, h, 4, seed));
      double sum = 0.0;
      for (auto [x, y] : pixels) sum += double(a.at(channel[c], x, y)) - double(b.at(channel[c], x, y));
      return sum / double(pixels.size());
    });
    const double bound = ref.straddleOuter + albedo[c] * ref.straddleOccluder;
    EXPECT_NEAR(d.mean, 0.0, 4.0 * d.se + bound) << "channel " << c;
    RecordProperty("ssat_radiance_gbuffer_minus_traced_" + std::to_string(c),
                   std::to_string(d.mean) + " se " + std::to_string(d.se) + " crease bound " + std::to_string(bound));
  }
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Invariants of occluder=radiance: with every albedo 0 nothing is
// reflected, and the pass is the obscurance (albedo=false) bit for bit -
// the same samples, the same sum, an added zero; the default,
// occluder=albedo, is [AT 9] unchanged. It needs albedo=true.
TEST(SsatRadiance, BlackOccludersGiveTheObscuranceBitForBit) {
  const Crease c;
  Scene scene;
  const int black = addGreyMaterial(scene, 0.0f);
  scene.addWorldPrimitive({{0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, black);
  scene.addWorldPrimitive({{0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, black);
  scene.commit();
  for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
    const RenderSettings s = passSettings(32, 24, 3, 9);
    const Film o = renderWith(scene, c.cam, "ssat", {"distance=0.7", depth, "steps=2"}, s);
    const Film r =
        renderWith(scene, c.cam, "ssat", {"distance=0.7", depth, "steps=2", "albedo=true", "occluder=radiance"}, s);
    size_t differ = 0, darker = 0;
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 32; ++x) {
        for (int ch : {kR, kG, kB, kA}) differ += !sameBits(o.at(ch, x, y), r.at(ch, x, y));
        darker += o.at(kR, x, y) < 0.9f;
      }
    EXPECT_EQ(differ, 0u) << depth;
    EXPECT_GT(darker, 20u) << depth;  // the comparison covered occluded pixels
  }
  EXPECT_THROW(renderWith(c.scene, c.cam, "ssat", {"occluder=radiance"}, passSettings(4, 4, 1)), Error);
}

}  // namespace
}  // namespace obscura::test
