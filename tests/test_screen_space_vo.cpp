// `vo`'s line and area samples (docs/math.md §8) against closed forms, an
// independent ray-traced Monte Carlo of the ball's empty volume, and point
// samples; with bounds on the biases the estimators carry by construction.
//
// Statistics: vo shares randomness across an image (per-layer shifts), so
// standard errors come from replicate renders with seeds 1..16 (replicateMean);
// the Monte Carlo in the test has its own standard error from its draws.
// Tolerances are 4 standard errors of the compared difference plus the
// deterministic bound named at each test.
//
// Perspective: line samples run their chords along the camera rays through
// the disk points Q0 (integrators/screen_space/vo.cpp), a fan that diverges
// by up to R / d over the ball (d: the camera's distance). The fan's volume
// element is ((|Q0| + s) / |Q0|)^2 cos(theta) dA ds at s along a chord
// (theta: the ray's angle with the disk's normal), and vo weighs the
// lengths by it, so the estimator measures the ball's empty volume up to
// the disk set's quadrature. Weighing lengths uniformly instead (as vo did
// before) shifts a frontal plane without the clamp by the chords' offset
// along themselves: the ray through Q0 at disk radius rho R is tilted
// outwards by rho R / d, its sphere chord centred b = rho^2 R^2 / d before
// the plane, so V - 1/2 = Sum a_k b_k / Sum a_k chord_k
//   = (R / d) Sum_k w_k rho_k^2 / (2 z_k)       (z_k = sqrt(1 - rho_k^2)),
// (3/8) R / d for the continuous disk - `perspectiveShift` below, which the
// tests use as the scale of what the weighting removes; with it the shift is
// gone to within the second-order quadrature terms, (R / (d - R))^2.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "integrators/screen_space/sample_sets.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Double-precision vectors for the models in this file.
struct D3 {
  double x = 0, y = 0, z = 0;
};
D3 d3(Vec3 v) { return {v.x, v.y, v.z}; }
D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 operator-(D3 a, D3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
D3 operator*(D3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(D3 a, D3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross(D3 a, D3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
D3 unit(D3 a) { return a * (1.0 / std::sqrt(dot(a, a))); }

// The line weights of the disk set, a_k = w_k / (2 z_k), as vo computes them
// from the set's published points and shares (docs/math.md §8).
struct LineSet {
  screen_space::DiskSet d;
  std::vector<double> a;
  explicit LineSet(int count, bool centre = true) : d(screen_space::diskSet(count, centre)) {
    for (int k = 0; k < count; ++k) {
      const double zs = std::sqrt(std::max(0.0, 1.0 - double(d.x[k]) * d.x[k] - double(d.y[k]) * d.y[k]));
      a.push_back(zs > 0 ? d.w[k] / (2 * zs) : 0.0);
    }
  }
  // (R / d) x this = the first-order perspective shift of a frontal plane
  // without the clamp (header comment).
  double perspectiveShift() const {
    double s = 0;
    for (size_t k = 0; k < a.size(); ++k) s += a[k] * (double(d.x[k]) * d.x[k] + double(d.y[k]) * d.y[k]);
    return s;
  }
};

// A uniformly distributed unit vector (hemisphere z >= 0 when `half`).
D3 uniformDirection(std::mt19937_64& rng, bool half) {
  std::uniform_real_distribution<double> U(0, 1);
  const double z = half ? U(rng) : 2 * U(rng) - 1, phi = 2 * kPi * U(rng), r = std::sqrt(std::max(0.0, 1 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// The empty fraction of the ball of radius R about p (the half-ball above the
// tangent plane of normal n when `half`), by Monte Carlo over the ray-traced
// distance d(w) to the first surface: when the empty part is star-shaped
// from p, it is Int min(d, R)^3 / 3 dw over the directions, against the
// (half-)ball's R^3 / 3 x 4 pi (2 pi): the mean of (min(d, R) / R)^3 over
// uniform directions of the sphere (hemisphere) - docs/math.md §8, "Relation
// to obscurance". Directions below n see matter at once (d = 0).
double emptyFractionDraw(const Scene& scene, Vec3 p, D3 n, double R, bool half, std::mt19937_64& rng) {
  D3 w = uniformDirection(rng, half);
  const D3 t = unit(cross(n, std::abs(n.z) < 0.9 ? D3{0, 0, 1} : D3{1, 0, 0})), b = cross(n, t);
  w = t * w.x + b * w.y + n * w.z;  // the draw in n's frame
  if (dot(w, n) <= 0) return 0.0;
  const Vec3 nf(float(n.x), float(n.y), float(n.z));
  const RayHit hit = traceClosest(scene, p + nf * 1e-5f, Vec3(float(w.x), float(w.y), float(w.z)));
  const double d = hit.hit.geomID == RTC_INVALID_GEOMETRY_ID ? R : std::min<double>(hit.ray.tfar, R);
  return std::pow(d / R, 3.0);
}

// The mean over `pixels` of each pixel's Monte Carlo mean of M draws of
// draw(x, y) (each at its own uniformly random film position: the box
// filter's pixel), with its standard error from the draws' spread per pixel.
MeanSe pixelMonteCarlo(const std::vector<std::pair<int, int>>& pixels, int M,
                       const std::function<double(int x, int y)>& draw) {
  double sum = 0, var = 0;
  for (auto [x, y] : pixels) {
    double s1 = 0, s2 = 0;
    for (int j = 0; j < M; ++j) {
      const double f = draw(x, y);
      s1 += f, s2 += f * f;
    }
    const double m = s1 / M;
    sum += m;
    var += std::max(0.0, s2 / M - m * m) / (M - 1);
  }
  MeanSe r;
  r.n = pixels.size();
  r.mean = sum / double(pixels.size());
  r.se = std::sqrt(var) / double(pixels.size());
  return r;
}

// The mean over `pixels` of W, over 16 replicate renders.
MeanSe renderMean(const Scene& scene, const Camera& cam, const std::vector<std::string>& params, int w, int h,
                  const std::vector<std::pair<int, int>>& pixels, const std::vector<double>& minus = {}) {
  return replicateMean(16, [&](uint32_t seed) {
    const Film f = renderWith(scene, cam, "vo", params, passSettings(w, h, 2, seed));
    double sum = 0;
    for (size_t k = 0; k < pixels.size(); ++k)
      sum += f.at(kR, pixels[k].first, pixels[k].second) - (minus.empty() ? 0.0 : minus[k]);
    return sum / double(pixels.size());
  });
}

// --- the crease -------------------------------------------------------------------

// Pixels whose whole area sees the crease's floor within 1.5 R of the wall
// (|y| < 1): every camera sample of them is a floor point, so their
// expected value is the average over the pixel of the quantity at the
// floor point seen.
std::vector<std::pair<int, int>> creaseFloorPixels(const Crease& c, int w, int h, double R) {
  std::vector<std::pair<int, int>> out;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool all = true;
      Vec3 p;
      for (int k = 0; k < 4 && all; ++k) all = c.floorAtFilm(w, h, float(x + (k & 1)), float(y + (k >> 1)), p);
      if (all && c.floorAt(w, h, x, y, p) && p.x < 1.5 * R && std::abs(p.y) < 1.0f) out.emplace_back(x, y);
    }
  return out;
}

// The line estimator's value at a floor point P (z = 0, normal +z) for the
// disk rotated by phi, on exact geometry: chords of the sphere |X - P| = R
// along the camera rays through Q0 = P + R (x e1 + y e2), weighed as vo
// weighs them (header), cut at the floor
// (the tangent plane, normal clamp), free up to `occluder`(Q0, u), the
// distance along the ray from Q0 to the first surface other than the floor
// (+inf: none) - docs/math.md §8's line samples with exact depths, as vo
// computes them with depth=traced (everything behind the first surface
// counts as matter).
double floorLineModel(D3 O, D3 P, double R, const LineSet& s, double phi,
                      const std::function<double(D3 Q0, D3 u)>& occluder) {
  const D3 v = unit(P - O);
  const D3 e1 = unit(cross(v, D3{0, 0, 1})), e2 = cross(v, e1);
  const double c = std::cos(phi), sn = std::sin(phi);
  double freeSum = 0, chordSum = 0;
  for (size_t k = 0; k < s.a.size(); ++k) {
    const double x = c * s.d.x[k] - sn * s.d.y[k], y = sn * s.d.x[k] + c * s.d.y[k];
    const D3 Q0 = P + (e1 * x + e2 * y) * R;
    const D3 u = unit(Q0 - O), o = Q0 - P;
    const double b = dot(u, o), disc = b * b - (dot(o, o) - R * R);
    if (!(disc > 0)) continue;
    double s0 = -b - std::sqrt(disc), s1 = -b + std::sqrt(disc);
    if (u.z < 0) s1 = std::min(s1, -o.z / u.z);
    else if (u.z > 0) s0 = std::max(s0, -o.z / u.z);
    if (!(s1 > s0)) continue;
    // vo's weights (header): the fan's volume element along the chord,
    // ((dQ + s) / dQ)^2, integrated in closed form, and cos(theta).
    const double dQ = std::sqrt(dot(Q0 - O, Q0 - O)), cosTheta = dot(u, v);
    const auto weighted = [&](double a, double b) {
      const double A = (dQ + a) / dQ, B = (dQ + b) / dQ;
      return (b - a) * (A * A + A * B + B * B) / 3;
    };
    const double end = std::clamp(occluder(Q0, u), s0, s1);
    freeSum += s.a[k] * cosTheta * weighted(s0, end);
    chordSum += s.a[k] * cosTheta * weighted(s0, s1);
  }
  return chordSum > 0 ? freeSum / chordSum : 1.0;
}

// The crease's wall x = 0 along a ray from the open quadrant (u.x < 0 for
// the crease's camera); above the floor the ray meets it first.
double creaseWall(D3 Q0, D3 u) { return -Q0.x / u.x; }

// The mean over `pixels` of floorLineModel - V, each pixel averaged over
// the G x G midpoint grid of film positions `grid` (its floor points) and
// 64 rotations per position (4096 angles per pixel).
double floorLineBias(D3 O, double R, const LineSet& set, const std::vector<std::vector<Vec3>>& grid,
                     const std::vector<double>& V, const std::function<double(D3 Q0, D3 u)>& occluder) {
  constexpr int A = 64;
  double B = 0;
  for (size_t i = 0; i < grid.size(); ++i) {
    const double n = double(grid[i].size());
    double sm = 0;
    for (size_t j = 0; j < grid[i].size(); ++j)
      for (int t = 0; t < A; ++t) sm += floorLineModel(O, d3(grid[i][j]), R, set, 2 * kPi * (t + (j + 0.5) / n) / A, occluder);
    B += sm / (n * A) - V[i];
  }
  return B / double(grid.size());
}

// VO with line samples on the 90 degree crease (normal clamp, R = 0.5):
// every chord crosses one surface (the wall), so the estimator measures the
// half-ball's empty volume, whose closed form is creaseVo (VO §3).
// (a) Against the closed form at the pixel centre, as the point samples are
//     (test_screen_space.cpp, VoPointsMatchTheClosedForm): 4 SE plus the
//     pixel-footprint bound of creaseCentres, for both depth sources and
//     disk sets with and without the centre.
// (b) The line bias, sharply: the closed form averaged over each pixel (an
//     8 x 8 midpoint grid of film positions; V'' <= 3 / (2 R^2), so the
//     grid's error is below 3 / (2 R^2) x (pixel's h-range / 8)^2 / 24,
//     < 1e-5 here) and the estimator's own expectation on the exact geometry
//     (floorLineModel over the same grid x 64 rotations) give the line
//     bias B = model - V. The traced render must reproduce B within 4 SE
//     (depth=traced reads the exact depths the model uses), for 16 and 256
//     chords; B, the disk set's quadrature error, stays below
//     (R / d) x perspectiveShift, the scale of the perspective term the
//     weighting removes (header).
TEST(ScreenSpaceVoLines, CreaseMatchesTheClosedForm) {
  const Crease c;
  const int w = 64, h = 48;
  const double R = 0.5;
  // (a)
  const CreaseCentres cc = creaseCentres(c, w, h, R);
  ASSERT_GT(cc.pixels.size(), 100u);
  RecordProperty("vo_line_crease_footprint_bound", std::to_string(cc.footprint));
  for (const char* centre : {"centre=true", "centre=false"})
    for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
      // renderMean counts every listed pixel: all of them are fully covered.
      const MeanSe m = renderMean(c.scene, c.cam, {"samples=line", "radius=0.5", depth, centre}, w, h, cc.pixels, cc.V);
      EXPECT_NEAR(m.mean, 0.0, 4 * m.se + cc.footprint) << depth << centre << " se " << m.se;
      RecordProperty(std::string("vo_line_crease_bias_") + (depth[6] == 'g' ? "gbuffer_" : "traced_") + (centre + 7),
                     std::to_string(m.mean));
    }
  // The same with VO §4.5's optimised sets (sets=optimised): the closed form
  // holds for any weighted disk set, so the same bound.
  for (const char* centre : {"centre=true", "centre=false"}) {
    const MeanSe m =
        renderMean(c.scene, c.cam, {"samples=line", "radius=0.5", "depth=gbuffer", centre, "sets=optimised"}, w, h, cc.pixels, cc.V);
    EXPECT_NEAR(m.mean, 0.0, 4 * m.se + cc.footprint) << "sets=optimised " << centre << " se " << m.se;
    RecordProperty(std::string("vo_line_crease_bias_optimised_") + (centre + 7), std::to_string(m.mean));
  }
  // (b)
  const auto pixels = creaseFloorPixels(c, w, h, R);
  ASSERT_GT(pixels.size(), 100u);
  const D3 O = d3(c.cam.position());
  double dMin = 1e30;
  constexpr int G = 8;
  std::vector<std::vector<Vec3>> grid(pixels.size());
  std::vector<double> Vpix(pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) {
    double sv = 0;
    for (int j = 0; j < G * G; ++j) {
      Vec3 p;
      ASSERT_TRUE(c.floorAtFilm(w, h, float(pixels[i].first) + (float(j % G) + 0.5f) / G,
                                float(pixels[i].second) + (float(j / G) + 0.5f) / G, p));
      grid[i].push_back(p);
      sv += creaseVo(p.x, R);
      dMin = std::min(dMin, std::sqrt(dot(d3(p) - O, d3(p) - O)));
    }
    Vpix[i] = sv / (G * G);
  }
  for (int count : {16, 256}) {
    const LineSet set(count);
    const double B = floorLineBias(O, R, set, grid, Vpix, creaseWall);
    const MeanSe m =
        renderMean(c.scene, c.cam, {"samples=line", "radius=0.5", "depth=traced", "count=" + std::to_string(count)}, w, h,
                   pixels, Vpix);
    EXPECT_NEAR(m.mean, B, 4 * m.se) << count << " se " << m.se;
    EXPECT_LE(std::abs(B), R / dMin * set.perspectiveShift()) << count;
    RecordProperty("vo_line_crease_perspective_bound_" + std::to_string(count), std::to_string(R / dMin * set.perspectiveShift()));
    RecordProperty("vo_line_crease_model_bias_" + std::to_string(count), std::to_string(B));
    RecordProperty("vo_line_crease_traced_bias_" + std::to_string(count), std::to_string(m.mean));
  }
}

// --- the quadratic kernel and the tangent sphere (VO §4, §4.4; docs/math.md §8) ---
//
// The closed forms (docs/math.md §8), eta = h / R at a floor point h from
// the wall:
// - kernel=quadratic, rho = 1 - (r/R)^2, half-ball:
//     V = 1/2 + (15 eta - 10 eta^3 + 3 eta^5) / 16,        |dV/dh| <= (15/16) / R;
// - normal=tangent-sphere, constant: the ball of radius R/2 tangent at the
//   point is cut by the wall as the half-ball of radius R/2 is, so
//     V = creaseVo(h, R/2),                                 |dV/dh| <= (3/2) / R;
// - normal=tangent-sphere, kernel=quadratic (rho from the point, radius R):
//     V = 1/2 + (25 e - 10 e^3 + e^5) / 32,  e = min(2h/R, 1), |dV/dh| <= (25/16) / R.
// Each is checked first against an independent quadrature of the "relation
// to obscurance" (docs/math.md §8): V = Int mu-weighted over the hemisphere's
// directions, the inner radial integral of rho r^2 analytic, the outer a
// midpoint grid in (cos theta, phi) - a different route from the slices the
// closed forms were derived with.
//
// Tolerances: 4 SE (renderMean's replicates) plus the pixel-footprint bound
// of creaseCentres with the slopes above.

double creaseQuadratic(double h, double R) {
  const double e = std::min(h / R, 1.0);
  return 0.5 + (15 * e - 10 * e * e * e + 3 * std::pow(e, 5)) / 16;
}
double creaseTangent(double h, double R) { return creaseVo(h, 0.5 * R); }
double creaseTangentQuadratic(double h, double R) {
  const double e = std::min(2 * h / R, 1.0);
  return 0.5 + (25 * e - 10 * e * e * e + std::pow(e, 5)) / 32;
}

// The crease's V by quadrature over directions w of the floor's hemisphere
// (z = cos theta uniform in [0, 1] and phi: dw = dz dphi, N x N midpoints):
// along w the domain reaches L(w) (R for the half-ball, R cos theta for the
// tangent sphere) and the wall at d = h / (-w_x) (w_x < 0), and the empty
// part is [0, min(d, L)]: V = Int F(min(d, L)) dw / Int F(L) dw with F(t) =
// Int_0^t rho r^2 dr (t^3/3, or t^3/3 - t^5/(5 R^2) for the quadratic).
double creaseByDirections(double h, double R, bool quadratic, bool tangent, int N) {
  const auto F = [&](double t) { return t * t * t / 3 - (quadratic ? std::pow(t, 5) / (5 * R * R) : 0.0); };
  double num = 0, den = 0;
  for (int i = 0; i < N; ++i) {
    const double z = (i + 0.5) / N, s = std::sqrt(1 - z * z), L = tangent ? R * z : R;
    for (int j = 0; j < N; ++j) {
      const double wx = s * std::cos(2 * kPi * (j + 0.5) / N);
      const double d = wx < 0 ? h / -wx : 1e300;
      num += F(std::min(d, L)), den += F(L);
    }
  }
  return num / den;
}

// The closed forms against the quadrature. The integrand is continuous with
// a kink where d = L, so the midpoint grid converges at least as 1/N; the
// tolerance is twice the change from N/2 to N (the error of the N grid is
// below the change when the convergence is at least first order), plus 1e-12.
TEST(ScreenSpaceVoKernel, CreaseClosedFormsMatchAQuadratureOverDirections) {
  const double R = 1.0;
  struct Form {
    bool quadratic, tangent;
    double (*V)(double, double);
  };
  for (const Form f : {Form{true, false, creaseQuadratic}, Form{false, true, creaseTangent},
                       Form{true, true, creaseTangentQuadratic}, Form{false, false, creaseVo}})
    for (double h : {0.0, 0.1, 0.3, 0.45, 0.7, 1.2}) {
      const double fine = creaseByDirections(h, R, f.quadratic, f.tangent, 800);
      const double coarse = creaseByDirections(h, R, f.quadratic, f.tangent, 400);
      EXPECT_NEAR(f.V(h, R), fine, 2 * std::abs(fine - coarse) + 1e-12)
          << "quadratic " << f.quadratic << " tangent " << f.tangent << " h " << h;
    }
}

// Point samples are unbiased for V (each point distributed as the kernel's
// weight over the domain, weights summing to 1), so against the closed form
// averaged over each pixel (the box filter's pixel; pixels wholly on the
// floor) they need no footprint bound. The average is a G x G midpoint grid
// of film positions; the midpoint rule errs by at most max|V''| x (the
// pixel's h-range / G)^2 / 24 per film axis (h is linear over a pixel to
// first order), so 2 x that, from each pixel's own h-range, bounds it, with
// max|V''| = 1.44 / R^2 for the quadratic ((15/4) eta (1 - eta^2) / R^2)
// and 6 / R^2 for the tangent sphere (creaseVo's 3/2 at R/2).
struct PixelAverages {
  std::vector<std::pair<int, int>> pixels;
  std::vector<double> V;
  double gridBound = 0;
};
PixelAverages pixelAverages(const Crease& c, int w, int h, double R, double (*closedForm)(double, double),
                            double maxSecond) {
  constexpr int G = 8;
  PixelAverages out;
  out.pixels = creaseFloorPixels(c, w, h, R);
  for (auto [x, y] : out.pixels) {
    double sum = 0, lo = 1e30, hi = -1e30;
    for (int j = 0; j < G * G; ++j) {
      Vec3 p;
      if (!c.floorAtFilm(w, h, float(x) + (float(j % G) + 0.5f) / G, float(y) + (float(j / G) + 0.5f) / G, p)) continue;
      sum += closedForm(p.x, R), lo = std::min<double>(lo, p.x), hi = std::max<double>(hi, p.x);
    }
    out.V.push_back(sum / (G * G));
    out.gridBound = std::max(out.gridBound, 2 * maxSecond * std::pow((hi - lo) / G, 2) / 24);
  }
  return out;
}

// The quadratic kernel at the crease (normal clamp, R = 0.5): lines from the
// G-buffer and traced, 4 SE + footprint (slope 15/16); points against the
// pixel averages, 4 SE + the grid's bound.
TEST(ScreenSpaceVoKernel, QuadraticCreaseMatchesTheClosedForm) {
  const Crease c;
  const int w = 64, h = 48;
  const double R = 0.5;
  const CreaseCentres cc = creaseCentres(c, w, h, R, creaseQuadratic, 15.0 / 16.0);
  ASSERT_GT(cc.pixels.size(), 100u);
  for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
    const MeanSe m = renderMean(c.scene, c.cam, {"samples=line", "kernel=quadratic", "radius=0.5", depth}, w, h, cc.pixels, cc.V);
    EXPECT_NEAR(m.mean, 0.0, 4 * m.se + cc.footprint) << depth << " se " << m.se << " footprint " << cc.footprint;
    RecordProperty(std::string("vo_quadratic_line_crease_tolerance_") + (depth + 6), std::to_string(4 * m.se + cc.footprint));
    RecordProperty(std::string("vo_quadratic_line_crease_bias_") + (depth + 6), std::to_string(m.mean));
  }
  const PixelAverages pa = pixelAverages(c, w, h, R, creaseQuadratic, 1.44 / (R * R));
  ASSERT_GT(pa.pixels.size(), 100u);
  const MeanSe m = renderMean(c.scene, c.cam, {"samples=point", "kernel=quadratic", "radius=0.5"}, w, h, pa.pixels, pa.V);
  EXPECT_NEAR(m.mean, 0.0, 4 * m.se + pa.gridBound) << " se " << m.se << " grid " << pa.gridBound;
  RecordProperty("vo_quadratic_point_crease_bias", std::to_string(m.mean));
  RecordProperty("vo_quadratic_point_crease_tolerance", std::to_string(4 * m.se + pa.gridBound));
}

// The tangent sphere at the crease (R = 0.5): lines with either kernel
// (4 SE + footprint with slopes 3/2 and 25/16) and points with the constant
// kernel against the pixel averages (4 SE + the grid's bound). Points with
// the quadratic kernel are a ratio there (vo.cpp), biased by O(1/count):
// measured (vo_tangent_point_quadratic_ratio_bias), not bounded.
TEST(ScreenSpaceVoKernel, TangentSphereCreaseMatchesTheClosedForm) {
  const Crease c;
  const int w = 64, h = 48;
  const double R = 0.5;
  const CreaseCentres constant = creaseCentres(c, w, h, R, creaseTangent, 1.5);
  const CreaseCentres quadratic = creaseCentres(c, w, h, R, creaseTangentQuadratic, 25.0 / 16.0);
  ASSERT_GT(constant.pixels.size(), 100u);
  for (const char* kind : {"samples=line", "samples=point"})
    for (const char* kernel : {"kernel=constant", "kernel=quadratic"}) {
      const bool q = std::string(kernel) == "kernel=quadratic";
      if (std::string(kind) == "samples=point") continue;  // below
      const CreaseCentres& cc = q ? quadratic : constant;
      const MeanSe m = renderMean(c.scene, c.cam, {kind, kernel, "normal=tangent-sphere", "radius=0.5"}, w, h, cc.pixels, cc.V);
      EXPECT_NEAR(m.mean, 0.0, 4 * m.se + cc.footprint) << kind << kernel << " se " << m.se << " footprint " << cc.footprint;
      RecordProperty(std::string("vo_tangent_crease_bias_") + (kind + 8) + "_" + (kernel + 7), std::to_string(m.mean));
    }
  const PixelAverages pa = pixelAverages(c, w, h, R, creaseTangent, 6.0 / (R * R));
  const MeanSe m = renderMean(c.scene, c.cam, {"samples=point", "normal=tangent-sphere", "radius=0.5"}, w, h, pa.pixels, pa.V);
  EXPECT_NEAR(m.mean, 0.0, 4 * m.se + pa.gridBound) << " se " << m.se << " grid " << pa.gridBound;
  RecordProperty("vo_tangent_point_constant_bias", std::to_string(m.mean));
  RecordProperty("vo_tangent_point_constant_tolerance", std::to_string(4 * m.se + pa.gridBound));
  const PixelAverages pq = pixelAverages(c, w, h, R, creaseTangentQuadratic, 0.0);
  const MeanSe r = renderMean(c.scene, c.cam, {"samples=point", "normal=tangent-sphere", "kernel=quadratic", "radius=0.5"},
                              w, h, pq.pixels, pq.V);
  RecordProperty("vo_tangent_point_quadratic_ratio_bias", std::to_string(r.mean) + " se " + std::to_string(r.se));
}

// VO with line samples against an independent ray-traced obscurance-type
// integral (docs/math.md §8: V = mean over uniform directions of
// (min(d, R) / R)^3 when the empty part is star-shaped from the point and
// every chord crosses one surface), Monte Carlo in the test over the same
// pixels' areas (256 draws per pixel, each at its own film position):
// - the crease with the normal clamp (half-ball, hemisphere of the floor's
//   normal): the line bias there is floorLineModel's B, bounded in
//   CreaseMatchesTheClosedForm by (R / d) x perspectiveShift, which this
//   test allows on top of 4 SE;
// - the spherical cavity of docs/math.md §7 (Rs = 1, R = 0.5) seen through
//   its opening, bottom pixels, without the clamp (whole ball, directions
//   into the wall's facet have d = 0 - the cavity is convex): the empty part
//   is the ball's lens inside the sphere, (8 Rs - 3 R) / (16 Rs) = 0.40625
//   for the exact sphere. The chords start inside the cavity, cross the wall
//   once and end in matter. The line value equals the Monte Carlo within
//   the second-order quadrature terms of the weighting (header), (R / (d -
//   R))^2, on top of 4 SE; unweighted lengths were (R / d) x
//   perspectiveShift = 0.035 (16 chords) above it.
TEST(ScreenSpaceVoLines, EqualTracedObscuranceUpToPerspective) {
  std::mt19937_64 rng(20261201);
  std::uniform_real_distribution<double> U(0, 1);
  const double R = 0.5;
  {
    const Crease c;
    const int w = 64, h = 48;
    const auto pixels = creaseFloorPixels(c, w, h, R);
    ASSERT_GT(pixels.size(), 100u);
    const MeanSe mc = pixelMonteCarlo(pixels, 256, [&](int x, int y) {
      Vec3 p;
      c.floorAtFilm(w, h, float(x + U(rng)), float(y + U(rng)), p);
      return emptyFractionDraw(c.scene, p, {0, 0, 1}, R, true, rng);
    });
    double dMin = 1e30;
    for (auto [x, y] : pixels) {
      Vec3 p;
      c.floorAt(w, h, x, y, p);
      dMin = std::min<double>(dMin, length(p - c.cam.position()));
    }
    const double bound = R / (dMin - R) * LineSet(16).perspectiveShift();
    for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
      const MeanSe m = renderMean(c.scene, c.cam, {"samples=line", "radius=0.5", depth}, w, h, pixels);
      const double se = std::hypot(m.se, mc.se);
      EXPECT_NEAR(m.mean - mc.mean, 0.0, 4 * se + bound) << depth << " mc " << mc.mean << " se " << se;
      RecordProperty(std::string("vo_line_minus_traced_crease_") + (depth[6] == 'g' ? "gbuffer" : "traced"),
                     std::to_string(m.mean - mc.mean));
    }
  }
  {
    Scene scene;
    addSphereCavity(scene, 1.0f, 1.2, 24, 48);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(0, 0, 4), Vec3(0, 0, -1), Vec3(0, 1, 0), 0.45f, "hole");
    const int w = 40, h = 40;
    const RasterCamera rc(cam, w, h);
    auto bottom = [&](float fx, float fy, Vec3& p, Vec3& ng) {
      const Vec3 d = rc.direction(fx, fy);
      const RayHit hit = traceClosest(scene, rc.org, d);
      if (hit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
      p = rc.org + d * hit.ray.tfar;
      ng = normalize(Vec3(hit.hit.Ng_x, hit.hit.Ng_y, hit.hit.Ng_z));
      if (dot(ng, d) > 0.0f) ng = -ng;  // towards the camera: the cavity's side
      return p.z < -0.92f;
    };
    std::vector<std::pair<int, int>> pixels;
    double dMin = 1e30;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        bool all = true;
        Vec3 p, ng;
        for (int k = 0; k < 4 && all; ++k) all = bottom(float(x + (k & 1)), float(y + (k >> 1)), p, ng);
        if (all) pixels.emplace_back(x, y), dMin = std::min<double>(dMin, length(p - rc.org));
      }
    ASSERT_GT(pixels.size(), 100u);
    const MeanSe mc = pixelMonteCarlo(pixels, 256, [&](int x, int y) {
      Vec3 p, ng;
      bottom(float(x + U(rng)), float(y + U(rng)), p, ng);
      return emptyFractionDraw(scene, p, d3(ng), R, false, rng);
    });
    // The Monte Carlo against the exact sphere's lens: the 24 x 48 facets
    // lie inside the sphere by at most Rs (1 - cos(pi / 48)) ~ 2e-3, which
    // moves the lens by at most that depth over the ball's radius x its
    // cross-section share, well under 4 SE; the facets are what vo sees too.
    EXPECT_NEAR(mc.mean, 0.40625, 4 * mc.se + 2e-3 / R) << "se " << mc.se;
    const double rd = R / (dMin - R);
    for (int count : {16, 256})
      for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
        const MeanSe m = renderMean(scene, cam, {"samples=line", "normal=false", "radius=0.5", depth, "count=" + std::to_string(count)},
                                    w, h, pixels);
        const double se = std::hypot(m.se, mc.se);
        EXPECT_NEAR(m.mean - mc.mean, 0.0, 4 * se + rd * rd) << depth << " " << count << " mc " << mc.mean << " se " << se;
        RecordProperty("vo_line_minus_traced_cavity_" + std::string(depth + 6) + "_" + std::to_string(count),
                       std::to_string(m.mean - mc.mean));
        RecordProperty("vo_line_cavity_unweighted_shift_" + std::to_string(count),
                       std::to_string(R / dMin * LineSet(count).perspectiveShift()));
      }
    RecordProperty("vo_cavity_traced_empty_fraction", std::to_string(mc.mean));
  }
}

// Chords crossing two surfaces: a thin square slab (half-size 0.5, no
// thickness) 0.25 above a floor, R = 0.5 with the normal clamp, floor
// pixels beside the slab (0.5 < x < 1). The slab holds no volume, so the
// true empty fraction is 1; the depth buffer - and vo's model - count all
// behind the slab as matter. To first order in R / d the line estimate is
// 1 - S, S the share of the half-ball that the camera sees behind the slab
// (Monte Carlo in the test: 64 uniform points of the half-ball per film
// position of an 8 x 8 grid per pixel, the segment from the camera to each
// point tested against the square). Asserted: the traced render equals
// the estimator's expectation on the exact geometry (floorLineModel with
// the slab as first surface, 4 SE); that expectation minus 1, the line
// bias B, is -S within the perspective bound (R / d) x perspectiveShift
// plus 4 SE of S - so |B| <= S + that bound.
TEST(ScreenSpaceVoLines, TwoSurfacesThinSlab) {
  Scene scene;
  addPlane(scene, 50.0f);
  addPlane(scene, 0.5f, 0.25f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.3f, -3, 4), Vec3(0.7f, 0, 0), Vec3(0, 0, 1), 0.5f, "slab");
  const int w = 64, h = 48, G = 8;
  const double R = 0.5;
  const RasterCamera rc(cam, w, h);
  auto floorAt = [&](float fx, float fy, Vec3& p) {
    const Vec3 d = rc.direction(fx, fy);
    const RayHit hit = traceClosest(scene, rc.org, d);
    p = rc.org + d * hit.ray.tfar;
    return hit.hit.geomID == 0;
  };
  std::vector<std::pair<int, int>> pixels;
  std::vector<std::vector<Vec3>> grid;
  double dMin = 1e30;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::vector<Vec3> g;
      Vec3 p;
      for (int j = 0; j < G * G; ++j)
        if (floorAt(float(x) + (float(j % G) + 0.5f) / G, float(y) + (float(j / G) + 0.5f) / G, p)) g.push_back(p);
      bool all = g.size() == size_t(G * G);
      for (int k = 0; k < 4 && all; ++k) all = floorAt(float(x + (k & 1)), float(y + (k >> 1)), p);
      for (const Vec3& q : g) all = all && q.x > 0.5f && q.x < 1.0f && std::abs(q.y) < 0.5f;
      if (!all) continue;
      pixels.emplace_back(x, y), grid.push_back(g);
      for (const Vec3& q : g) dMin = std::min<double>(dMin, length(q - rc.org));
    }
  ASSERT_GT(pixels.size(), 50u);
  const D3 O = d3(rc.org);
  // The first surface along a ray besides the floor: the slab, if the ray
  // crosses z = 0.25 inside the square.
  auto slab = [](D3 Q0, D3 u) {
    if (u.z == 0) return 1e30;
    const double t = (0.25 - Q0.z) / u.z;
    const D3 X = Q0 + u * t;
    return std::abs(X.x) <= 0.5 && std::abs(X.y) <= 0.5 ? t : 1e30;
  };
  // S by Monte Carlo, per pixel over its grid.
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> U(0, 1);
  double S = 0, varS = 0;
  for (const auto& g : grid) {
    double s1 = 0;
    int n = 0;
    for (const Vec3& p : g)
      for (int j = 0; j < 64; ++j, ++n) {
        const D3 X = d3(p) + uniformDirection(rng, true) * (R * std::cbrt(U(rng)));
        const double lam = (0.25 - O.z) / (X.z - O.z);
        const D3 C = O + (X - O) * lam;
        s1 += lam > 0 && lam < 1 && std::abs(C.x) <= 0.5 && std::abs(C.y) <= 0.5;
      }
    const double m = s1 / n;
    S += m, varS += m * (1 - m) / (n - 1);
  }
  S /= double(grid.size());
  const double seS = std::sqrt(varS) / double(grid.size());
  const std::vector<double> one(pixels.size(), 1.0);
  const LineSet set(16);
  const double B = floorLineBias(O, R, set, grid, one, slab);
  const MeanSe traced = renderMean(scene, cam, {"samples=line", "radius=0.5", "depth=traced"}, w, h, pixels, one);
  EXPECT_NEAR(traced.mean, B, 4 * traced.se) << "se " << traced.se;
  const double perspective = R / dMin * set.perspectiveShift();
  EXPECT_NEAR(B, -S, perspective + 4 * seS) << "S " << S << " se " << seS;
  EXPECT_GT(S, 0.05);  // the case is not empty: the slab hides a real share of the balls
  const MeanSe gbuffer = renderMean(scene, cam, {"samples=line", "radius=0.5", "depth=gbuffer"}, w, h, pixels, one);
  RecordProperty("vo_line_slab_pixels", std::to_string(pixels.size()));
  RecordProperty("vo_line_slab_shadow_share", std::to_string(S));
  RecordProperty("vo_line_slab_model_bias", std::to_string(B));
  RecordProperty("vo_line_slab_traced_bias", std::to_string(traced.mean));
  RecordProperty("vo_line_slab_gbuffer_bias", std::to_string(gbuffer.mean));
  RecordProperty("vo_line_slab_perspective_bound", std::to_string(perspective));
}

// --- planes and slopes ---------------------------------------------------------------

// A plane whose normal makes the angle theta with the view direction of
// the image centre, at distance D, a 0.3 rad field of view (incidence varies
// by +-0.25 rad over the image).
struct Slope {
  Scene scene;
  Camera cam;
  explicit Slope(double theta, double D = 6.0)
      : cam(makeLookAtCamera(Vec3(0, -float(D * std::sin(theta)), float(D * std::cos(theta))), Vec3(0, 0, 0),
                             Vec3(0, 1, 0), 0.3f, "slope")) {
    addPlane(scene, 50.0f);
    scene.commit();
  }
};

// Line and area samples against point samples on a plane seen frontally
// and at 30 and 60 degrees (R = 0.3, D = 6; pixels within 10 of the edges,
// where the ball may reach off the image, left out: R spans ~6 pixels).
// - With the normal clamp, point and line samples give exactly 1 on every
//   pixel (the chords end at the tangent plane, which is the surface).
//   So do area samples, to float rounding: vo reads the footprint's depths
//   relative to the tangent plane where it ends the chord (docs/math.md §8
//   "The plane-relative spread"), and on the plane the texels' offsets from
//   it are its own convex curvature, behind the clamp, with a spread of the
//   next order: every chord is free to its end. (The box about the absolute
//   depth darkened slopes by up to ~9 %.) What is left: the clamp and the
//   box's lower end are floats computed from lengths <= 1.04 z + R (z the
//   point's depth) in a few roundings each, so they may cross by 16 ulps,
//   lost_k <= 16 x 2^-24 (1.04 z + R), counted at most ((z + R) / (z - R))^2
//   times a chord length (vo's perspective weights, header). The bias is
//   Sum a_k lost_k / Sum a_k chord_k <= (Sum a_k) lost / min over rotations
//   of Sum a_k chord_k, the latter >= R x minClampedChord (the set's clamped
//   chords at the plane's incidence, parallel chords). The bound is the
//   mean over pixels of each pixel's bound; the test asserts
//   |1 - W_area| <= bound + 4 SE.
// - Without the clamp, points give 1/2 within 4 SE (unbiased: uniform
//   rotation). Lines and areas give 1/2 within the weighting's second-order
//   quadrature terms on the frontal plane (tolerance 4 SE + (R / (D - R))^2;
//   unweighted lengths gave (R / D) x perspectiveShift more); on the slopes within the bound of
//   test_screen_space.cpp WithoutTheNormalIsHalf, 0.75 R / (D cos theta_max),
//   theta_max the largest incidence in the image.
double minClampedChord(const LineSet& s, double theta) {
  // Unit ball, view along +z, plane through the centre with normal
  // (0, sin theta, -cos theta) facing the camera; a chord at disk point q is
  // [-z_s, z_s] cut above the plane: z <= z_p = q.y tan(theta).
  double lo = 1e30;
  for (int t = 0; t < 720; ++t) {
    const double phi = 2 * kPi * t / 720, c = std::cos(phi), sn = std::sin(phi);
    double sum = 0;
    for (size_t k = 0; k < s.a.size(); ++k) {
      const double y = sn * s.d.x[k] + c * s.d.y[k];
      const double zs = std::sqrt(std::max(0.0, 1.0 - double(s.d.x[k]) * s.d.x[k] - double(s.d.y[k]) * s.d.y[k]));
      sum += s.a[k] * std::clamp(y * std::tan(theta) + zs, 0.0, 2 * zs);
    }
    lo = std::min(lo, sum);
  }
  return lo;
}

TEST(ScreenSpaceVoSlopes, LinesAndAreasAgainstPoints) {
  const double R = 0.3, D = 6.0;
  const int w = 48, h = 36, border = 10, count = 16;
  const LineSet set(count);
  double sumA = 0;
  for (size_t k = 0; k < set.a.size(); ++k) sumA += set.a[k];
  for (double deg : {0.0, 30.0, 60.0}) {
    const double theta = deg * kPi / 180.0;
    const Slope sl(theta, D);
    auto meanOf = [&](const std::vector<std::string>& p) {
      return replicateMean(16, [&](uint32_t seed) {
        return meanSe(coveredW(renderWith(sl.scene, sl.cam, "vo", p, passSettings(w, h, 2, seed)), border)).mean;
      });
    };
    // The pixels' incidence and the area model's bound (see above).
    const RasterCamera rc(sl.cam, w, h);
    double thetaMax = 0, areaBound = 0;
    int n = 0;
    for (int y = border; y < h - border; ++y)
      for (int x = border; x < w - border; ++x) {
        const Vec3 d = rc.direction(float(x) + 0.5f, float(y) + 0.5f);
        const RayHit hit = traceClosest(sl.scene, rc.org, d);
        ASSERT_NE(hit.hit.geomID, RTC_INVALID_GEOMETRY_ID);
        const double inc = std::acos(std::min(1.0, std::abs(double(d.z))));
        thetaMax = std::max(thetaMax, inc);
        const double depth = hit.ray.tfar * dot(d, sl.cam.toWorld.vector(Vec3(0, 0, -1)));
        const double lost = 16 * 0x1p-24 * (1.04 * depth + R);  // float rounding (above)
        const double jacobian = std::pow((depth + R) / (depth - R), 2.0);
        areaBound += sumA * jacobian * lost / (R * minClampedChord(set, inc)), ++n;
      }
    areaBound /= n;
    for (const char* kind : {"samples=point", "samples=line"})
      for (double v : coveredW(renderWith(sl.scene, sl.cam, "vo", {kind, "radius=0.3"}, passSettings(w, h, 2, 1))))
        ASSERT_EQ(v, 1.0) << kind << " " << deg;
    const MeanSe area = meanOf({"samples=area", "radius=0.3"});
    EXPECT_NEAR(area.mean, 1.0, areaBound + 4 * area.se) << deg << " se " << area.se;
    RecordProperty("vo_area_clamp_bias_" + std::to_string(int(deg)), std::to_string(area.mean - 1.0));
    RecordProperty("vo_area_clamp_bound_" + std::to_string(int(deg)), std::to_string(areaBound));

    const MeanSe point = meanOf({"samples=point", "normal=false", "radius=0.3"});
    EXPECT_NEAR(point.mean, 0.5, 4 * point.se) << deg;
    const double rd = R / (D - R);
    RecordProperty("vo_noclamp_unweighted_shift_" + std::to_string(int(deg)), std::to_string(R / D * set.perspectiveShift()));
    RecordProperty("vo_noclamp_slope_bound_" + std::to_string(int(deg)), std::to_string(0.75 * R / (D * std::cos(thetaMax))));
    for (const char* kind : {"samples=line", "samples=area"}) {
      const MeanSe m = meanOf({kind, "normal=false", "radius=0.3"});
      const double se = std::hypot(m.se, point.se);
      if (deg == 0.0) {
        EXPECT_NEAR(m.mean - point.mean, 0.0, 4 * se + rd * rd) << kind << " se " << se;
      } else {
        EXPECT_NEAR(m.mean - point.mean, 0.0, 4 * se + 0.75 * R / (D * std::cos(thetaMax))) << kind << " " << deg;
      }
      RecordProperty(std::string("vo_") + (kind[8] == 'l' ? "line" : "area") + "_noclamp_minus_point_" +
                         std::to_string(int(deg)),
                     std::to_string(m.mean - point.mean));
    }
  }
}

}  // namespace
}  // namespace obscura::test
