// `ssat`'s variants from the ambient-transfer paper beyond [AT 9]: the
// occluding pixel's radiance in place of its albedo (end of AT §4.1,
// occluder=radiance; docs/math.md §9, the pixel's radiance), and the
// combination of the depth buffer for other objects with a height field for
// the surface's own detail (AT §6, map=; docs/math.md §9).
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
#include "core/subd/subdivision.h"
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

// The floor pixels of the crease near the wall (x < xMax, |y| < 1.5) whose
// whole footprint sees the floor (its four corners do, and the floor's
// image is convex).
std::vector<std::pair<int, int>> floorPixels(const RasterCamera& rc, int w, int h, double xMax = 1.2) {
  std::vector<std::pair<int, int>> out;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool floor = true;
      double p[3];
      for (int k = 0; k < 4 && floor; ++k)
        floor = surfaceAtFilm(rc, x + (k & 1), y + (k >> 1), p) == 0 && p[0] < xMax && std::abs(p[1]) < 1.5;
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
  // Nor is it combined with a height field (map=).
  const std::string ripples = writeRipples(tempDir("ssat_radiance_map"));
  EXPECT_THROW(renderWith(c.scene, c.cam, "ssat", {"albedo=true", "occluder=radiance", "map=" + ripples},
                          passSettings(4, 4, 1)),
               Error);
}

// --- the depth buffer with a height field (map=, AT §6) ---------------------------

// The floor of the crease with texture coordinates uv = (x, y) (dP/du = +x,
// dP/dv = +y, N = +z: the field's frame is the world's), a ripple map along
// u - h = 0.5 + 0.5 cos(2 pi P u), P = 4 periods a unit, so d = scale (h -
// 1/2) has wavelength 1/4 - and the wall x = 0 (or none).
struct RippledCrease {
  Crease c;  // (its camera)
  Scene scene;
  std::string map;
  static constexpr double kPeriods = 4.0;
  explicit RippledCrease(bool wall) {
    // 1024 float texels a unit of u: bilinear interpolation errs by at most
    // (1/1024)^2/8 (2 pi 4)^2 0.5 = 3.8e-5 of the unit height.
    map = writeHeightMap(tempDir("ssat_field") + "/ripples.exr", 1024, 4,
                         [](double u, double) { return 0.5 + 0.5 * std::cos(2 * kPiD * kPeriods * u); });
    scene.addWorldPrimitive({{0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 1, 2, 0, 2, 3}, {},
                            {0, -10, 10, -10, 10, 10, 0, 10}, -1);
    if (wall) scene.addWorldPrimitive({{0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.commit();
  }
};

// The combination's expectation at the floor pixels, without the renderer:
// the rule of AT §6 as docs/math.md §9 states it, for the step membership
// (every sample's r = R) and the traced containment (exact here). A floor
// point P (the pixel's camera sample, uniform over the pixel) is shaded at
// x = P + N d(uv), the lobe cosine about the displaced normal
// n_d = normalize(-dd/du, -dd/dv, 1) (central differences one texel apart,
// the map's own bilinear samples), and a sample w is open iff at each
// t = R j/m (j = 1..m)
//   - x + w t is above the field: d0 + t w_z >= d(u + t w_x, v + t w_y), and
//   - w points below the macro plane (w_z <= 0: no depth test), or P + w t
//     is not behind the wall (its x >= 0; such a point has z > 0, so the
//     camera ray meets the wall first iff x < 0).
// `wall` false: the field alone; `field` false: the depth buffer alone
// (d = 0, n_d = N). Returns the mean over pixels and its Monte Carlo
// standard error (K draws a pixel; pixels independent).
// flip, if not null: the bound on the z-buffer's departure from the traced
// twin - the probability that a sample has a depth-tested point behind the
// wall projecting into a pixel the crease crosses whose sample (another
// draw) lies on the floor: that point meets the floor's plane beyond
// itself and reads open (RadianceReference::straddleOuter's argument; the
// field reads no depth, and open points stay open), moving the sample by
// <= 1.
MeanSe fieldReference(const RippledCrease& rc0, int w, int h, const std::vector<std::pair<int, int>>& pixels,
                      double R, int m, double scale, bool field, bool wall, int K, double* flip = nullptr) {
  const RasterCamera rc(rc0.c.cam, w, h);
  const HeightMap map(rc0.map);
  const bool flipOut = flip != nullptr;
  const auto d = [&](double u, double v) { return field ? scale * (map.sample(u, v) - 0.5) : 0.0; };
  const double du = 1.0 / map.width(), dv = 1.0 / map.height();
  std::mt19937_64 rng(777);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const ViewTransform view = viewTransform(rc0.c.cam, w, h);
  const auto flips = [&](const double q[3]) {
    float fx, fy;
    view.project(view.pointToView(Vec3(float(q[0]), float(q[1]), float(q[2]))), fx, fy);
    const double x0 = std::floor(fx), y0 = std::floor(fy);
    double c[3];
    const int s0 = surfaceAtFilm(rc, x0, y0, c);
    bool straddles = false;
    for (int k = 1; k < 4; ++k) straddles |= surfaceAtFilm(rc, x0 + (k & 1), y0 + (k >> 1), c) != s0;
    return straddles && surfaceAtFilm(rc, x0 + u01(rng), y0 + u01(rng), c) == 0;
  };
  double sum = 0.0, var = 0.0, flipped = 0.0;
  for (auto [px, py] : pixels) {
    double s = 0.0, s2 = 0.0;
    for (int k = 0; k < K; ++k) {
      double P[3];
      surfaceAtFilm(rc, px + u01(rng), py + u01(rng), P);
      const double u = P[0], v = P[1], d0 = d(u, v);
      const double gu = (d(u + du, v) - d(u - du, v)) / (2 * du), gv = (d(u, v + dv) - d(u, v - dv)) / (2 * dv);
      double n[3] = {-gu, -gv, 1.0};
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (double& c : n) c /= len;
      // A frame about n and a cosine-distributed direction in it.
      double a[3] = {1.0, 0.0, 0.0};
      const double an = a[0] * n[0];
      for (int i = 0; i < 3; ++i) a[i] -= an * n[i];
      const double al = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
      for (double& c : a) c /= al;
      const double b[3] = {n[1] * a[2] - n[2] * a[1], n[2] * a[0] - n[0] * a[2], n[0] * a[1] - n[1] * a[0]};
      const double phi = 2.0 * kPiD * u01(rng), q = u01(rng);
      const double cx = std::sqrt(q) * std::cos(phi), cy = std::sqrt(q) * std::sin(phi), cz = std::sqrt(1.0 - q);
      double wv[3];
      for (int i = 0; i < 3; ++i) wv[i] = a[i] * cx + b[i] * cy + n[i] * cz;
      bool open = true, flipsHere = false;
      for (int j = 1; j <= m && open; ++j) {
        const double t = R * j / m;
        if (d0 + t * wv[2] < d(u + t * wv[0], v + t * wv[1])) open = false;
        if (wall && wv[2] > 0.0 && P[0] + t * wv[0] < 0.0) {
          open = false;
          const double q[3] = {P[0] + t * wv[0], P[1] + t * wv[1], P[2] + t * wv[2]};
          if (flipOut && !flipsHere) flipsHere = flips(q);
        }
      }
      flipped += flipsHere;
      s += open, s2 += open;
    }
    const double mean = s / K;
    sum += mean;
    var += (s2 / K - mean * mean) / K;
  }
  const double N = double(pixels.size());
  if (flip) *flip = flipped / (double(K) * N);
  return {sum / N, std::sqrt(var) / N, pixels.size()};
}

// AT §6 in screen space: on the rippled floor beside the wall (R = 0.2,
// scale 0.04: amplitude 0.02, max slope 2 pi 4 0.02 = 0.5; steps 2), the
// traced twin of `ssat map=` equals the rule's expectation
// (fieldReference) within 4 standard errors of the replicate renders and
// the reference combined. The test tells the rule from the alternatives:
// the field alone, the wall alone and the product of the two parts' means
// (the pass values multiplied, which would count a direction both close
// twice) each lie more than 2 tolerances from it. The z-buffer pass agrees
// with its twin within 4 standard errors of the paired difference plus the
// crease pixels' bound (fieldReference's flip).
TEST(SsatField, CombinationIsTheProductOfTheCharacteristicFunctions) {
  const RippledCrease rc0(true);
  const int w = 96, h = 72;
  const double R = 0.2, scale = 0.04;
  // Within 2R of the wall, where both parts shadow.
  const auto pixels = floorPixels(RasterCamera(rc0.c.cam, w, h), w, h, 2 * R);
  ASSERT_GT(pixels.size(), 60u);
  double flip = 0.0;
  const MeanSe both = fieldReference(rc0, w, h, pixels, R, 2, scale, true, true, 4096, &flip);
  const MeanSe fieldOnly = fieldReference(rc0, w, h, pixels, R, 2, scale, true, false, 4096);
  const MeanSe wallOnly = fieldReference(rc0, w, h, pixels, R, 2, scale, false, true, 4096);
  const std::vector<std::string> p = {"map=" + rc0.map, "scale=0.04", "falloff=step", "distance=0.2", "steps=2",
                                      "silhouette=false", "interleave=off", "depth=traced"};
  // The wall has no texture coordinates: plain ssat there, said once a render.
  const WarningCapture warnings;
  // Per seed, the traced twin's mean and the z-buffer pass's paired
  // difference from it (the same camera samples and sets).
  std::vector<double> traced, paired;
  for (uint32_t seed = 1; seed <= 16; ++seed) {
    std::vector<std::string> z = p;
    z.back() = "depth=gbuffer";
    const Film t = renderWith(rc0.scene, rc0.c.cam, "ssat", p, passSettings(w, h, 16, seed));
    const Film g = renderWith(rc0.scene, rc0.c.cam, "ssat", z, passSettings(w, h, 16, seed));
    double st = 0.0, sd = 0.0;
    for (auto [x, y] : pixels) st += t.at(kR, x, y), sd += double(g.at(kR, x, y)) - double(t.at(kR, x, y));
    traced.push_back(st / double(pixels.size()));
    paired.push_back(sd / double(pixels.size()));
  }
  const MeanSe m = meanSe(traced), d = meanSe(paired);
  EXPECT_NEAR(d.mean, 0.0, 4.0 * d.se + flip) << "z-buffer minus traced, se " << d.se << " crease bound " << flip;
  RecordProperty("ssat_field_gbuffer_minus_traced",
                 std::to_string(d.mean) + " se " + std::to_string(d.se) + " crease bound " + std::to_string(flip));
  const double tol = 4.0 * std::sqrt(m.se * m.se + both.se * both.se);
  EXPECT_NEAR(m.mean, both.mean, tol) << "field alone " << fieldOnly.mean << " wall alone " << wallOnly.mean;
  EXPECT_EQ(warnings.count("ssat: an unnamed mesh has no usable texture coordinates"), 32u) << warnings.all();
  for (double alternative : {fieldOnly.mean, wallOnly.mean, fieldOnly.mean * wallOnly.mean})
    EXPECT_GT(std::abs(alternative - both.mean), 2.0 * tol) << alternative;
  RecordProperty("ssat_field_traced", std::to_string(m.mean) + " se " + std::to_string(m.se) + " expected " +
                                          std::to_string(both.mean) + " se " + std::to_string(both.se) +
                                          " field alone " + std::to_string(fieldOnly.mean) + " wall alone " +
                                          std::to_string(wallOnly.mean));
}

// Each part alone is the existing pass. The field without another object:
// `ssat map=` (the depth buffer's points start on the macro plane, above
// it: never inside) against `containment` with the same map, mu and steps,
// over the rippled floor's pixels - the same expectation (both sample
// mu' cos/pi about n_d and test the same points), independent noise, so
// within 4 standard errors of the difference (16 replicates each). The
// depth buffer without a field: a flat map (scale=0: no gradient, n_d = N,
// the plain frame) is plain `ssat`, bit for bit with the traced twin
// (the same stream of lookups), and with the z-buffer within 4 standard
// errors of the paired difference.
TEST(SsatField, EachPartAloneIsTheExistingPass) {
  const int w = 64, h = 48;
  {
    const RippledCrease rc0(false);
    const auto pixels = floorPixels(RasterCamera(rc0.c.cam, w, h), w, h);
    ASSERT_GT(pixels.size(), 150u);
    const std::vector<std::string> mu = {"map=" + rc0.map, "scale=0.1", "falloff=linear", "distance=0.15", "steps=2"};
    std::vector<std::string> ss = mu, ct = mu;
    ss.push_back("interleave=off");
    ct.push_back("rays=4");
    const auto meanOf = [&](const std::string& integ, const std::vector<std::string>& params) {
      return replicateMean(16, [&](uint32_t seed) {
        const Film f = renderWith(rc0.scene, rc0.c.cam, integ, params, passSettings(w, h, 4, seed));
        double sum = 0.0;
        for (auto [x, y] : pixels) sum += f.at(kR, x, y);
        return sum / double(pixels.size());
      });
    };
    const MeanSe a = meanOf("ssat", ss), b = meanOf("containment", ct);
    EXPECT_NEAR(a.mean, b.mean, 4.0 * std::sqrt(a.se * a.se + b.se * b.se)) << a.se << " " << b.se;
    EXPECT_LT(a.mean, 0.97);  // the field shadows
    RecordProperty("ssat_field_alone_vs_containment",
                   std::to_string(a.mean) + " se " + std::to_string(a.se) + " vs " + std::to_string(b.mean) + " se " +
                       std::to_string(b.se));
  }
  {
    const RippledCrease rc0(true);
    const WarningCapture warnings;  // the wall's (no texture coordinates)
    const auto pixels = floorPixels(RasterCamera(rc0.c.cam, w, h), w, h);
    const std::vector<std::string> mu = {"distance=0.6", "falloff=sqrt", "steps=2", "interleave=off"};
    std::vector<std::string> flat = mu;
    flat.insert(flat.end(), {"map=" + rc0.map, "scale=0"});
    {
      std::vector<std::string> t = mu, tf = flat;
      t.push_back("depth=traced"), tf.push_back("depth=traced");
      const RenderSettings s = passSettings(w, h, 2, 3);
      const Film a = renderWith(rc0.scene, rc0.c.cam, "ssat", t, s);
      const Film b = renderWith(rc0.scene, rc0.c.cam, "ssat", tf, s);
      size_t differ = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int ch : {kR, kG, kB, kA}) differ += !sameBits(a.at(ch, x, y), b.at(ch, x, y));
      EXPECT_EQ(differ, 0u);
    }
    const MeanSe d = replicateMean(16, [&](uint32_t seed) {
      const Film a = renderWith(rc0.scene, rc0.c.cam, "ssat", mu, passSettings(w, h, 4, seed));
      const Film b = renderWith(rc0.scene, rc0.c.cam, "ssat", flat, passSettings(w, h, 4, seed));
      double sum = 0.0;
      for (auto [x, y] : pixels) sum += double(a.at(kR, x, y)) - double(b.at(kR, x, y));
      return sum / double(pixels.size());
    });
    EXPECT_NEAR(d.mean, 0.0, 4.0 * d.se) << d.se;
    RecordProperty("ssat_flat_map_minus_plain", std::to_string(d.mean) + " se " + std::to_string(d.se));
  }
}

}  // namespace
}  // namespace obscura::test
