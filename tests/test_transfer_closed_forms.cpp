// `gi` and `transfer` against closed forms that a wrong implementation would
// miss: the ambient medium (sigma > 0) with grey albedo < 1, where the
// membership mu matters (a white furnace passes for any mu), and coloured
// occluders whose albedo differs from the receiver's and from depth to depth.
//
// Tolerances, as in test_transfer.cpp: 4 standard errors of the image mean
// (pixels are independent estimates: PixelStats), plus
// - tessellation: the 256 x 512 chord mesh lies within Rs D^2/4 of the
//   sphere (D = the largest angular step, the quads' diagonals), which moves
//   a visibility boundary (the hole's edge, a band's edge) by at most D^2 in
//   probability (test_ao_analytic.cpp), and a chord length by E|dd| <= Rs D^2
//   on average over cosine directions (an endpoint depth delta changes the
//   chord at cos(theta) = c by ~ delta / c, and Int (delta / c) 2c dc = 2 delta
//   per end); mu = 1 - e^(-sigma d) is sigma-Lipschitz, so O moves by at most
//   sigma Rs D^2 = k D^2 / 2: we allow the change of the closed form when O
//   moves by k D^2;
// - the ratio estimator's bias (transfer, docs/math.md §4), bounded below
//   where it is used.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>

#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr int kRings = 256, kSegments = 512;
const double kStep = std::max(2.0 * M_PI / kSegments, M_PI / kRings);
const double kTess = kStep * kStep;  // D^2

std::string num(double x) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", x);
  return b;
}

// J(k, c) = 2 Int_0^c e^(-k x) x dx = 2 (1 - e^(-t)(1 + t)) / k^2, t = k c:
// the cosine-weighted mean of e^(-sigma d) over directions whose chord
// d = 2 Rs cos(theta) (k = 2 sigma Rs) has cos(theta) < c. The closed form
// cancels for small t; there the series 1 - e^(-t)(1 + t) =
// Sum_{n>=2} (-1)^n (n - 1) t^n / n! is used (terms fall by t/n).
double J(double k, double c) {
  const double t = k * c;
  if (t < 1.0) {
    double sum = 0, term = 1.0;  // term = (-t)^(n-2) / n!, from n = 2
    for (int n = 2; n < 30; ++n) {
      term = n == 2 ? 0.5 : term * -t / n;
      sum += (n - 1) * term;
    }
    return 2.0 * c * c * sum;
  }
  return 2.0 * (1.0 - std::exp(-t) * (1.0 + t)) / (k * k);
}

// Obscurance of the exponential membership at a wall point of a sphere whose
// directions with cos(theta) > c0 escape (c0 = 1: closed sphere; the
// antipode of a hole of half-angle alpha: c0 = cos(alpha/2)):
//   O = 1 - 2 Int_0^c0 e^(-k c) c dc = 1 - J(k, c0)      (docs/math.md §7)
// and the variance of one sample of mu, for the ratio bias:
//   E[mu^2] = 1 - Int_0^c0 (1 - mu^2) 2c dc, 1 - mu^2 = 2e - e^2, so
//   Var(mu) = J(2k, c0) - J(k, c0)^2.
double mediumO(double k, double c0) { return 1.0 - J(k, c0); }
double mediumVar(double k, double c0) { return J(2 * k, c0) - J(k, c0) * J(k, c0); }

// The medium model in a closed sphere (docs/math.md §5): W(x) = O(x) +
// (1/pi) Int (1 - mu) a W(y) cos dw. Every wall point is alike (the chord
// distribution seen from any wall point is the same), so W(y) = W(x) = W and
// W = O + a (1 - O) W, i.e. W = O / (1 - a (1 - O)). The closed form of §4
// at depth 0 (and every depth with the closed tail) has the same limit, and
// so has transfer depth 0 at any point whose occluders all have albedo a.
double mediumW(double O, double a) { return O / (1.0 - a * (1.0 - O)); }

// The largest change of g(O) when O moves by dO.
double moved(const std::function<double(double)>& g, double O, double dO) {
  return std::max(std::abs(g(std::min(1.0, O + dO)) - g(O)), std::abs(g(std::max(0.0, O - dO)) - g(O)));
}

// Ratio bias of transfer depth 0 with grey occluders of albedo a (b = 1 - a):
// a pixel's estimate is g(m) = m / (b + a m) of the mean m of its n samples
// of mu (den = mu + (1 - mu)(1 - a) = b + a mu per sample). With E[m] = O,
// Taylor's theorem with the Lagrange remainder gives
// |E g(m) - g(O)| <= sup|g''| Var(m) / 2, and |g''| = 2ab / (b + am)^3 <= 2a / b^2
// on [0, 1]. Var(m) = Var(mu) / n for independent samples; a pixel's n = 2^10
// directions are a scrambled (0,10,2)-net (test_sampler_nets.cpp), for which
// Owen (1997) bounds the variance by (b/(b-1))^(s-1) = 2 times that (the
// integrand is the same for every sample of a pixel: each hit sees the same
// chord distribution about its normal).
double ratioBiasBound(double a, double varMu, int n) { return a / ((1 - a) * (1 - a)) * 2.0 * varMu / n; }

// The recursive transfer with the closed tail (integrators/ambient_paths.h)
// in the closed grey sphere: a path of depth N has N + 1 segments whose
// transmittances e_j = 1 - mu_j are independent and identically distributed
// (every wall point sees the same chord distribution), and its estimate is
// the pair (S, 1 - T) with S = Sum_j a^(j-1) e_1..e_(j-1) (1 - e_j) and
// T = a^(N+1) e_1..e_(N+1). From the suffix recursion S_j = (1 - e_j) +
// a e_j S_(j+1), T_j = a e_j T_(j+1) and E[e] = m1, E[e^2] = m2 follow the
// moments below; E[S] / (1 - E[T]) = (1 - m1) / (1 - a m1) = O / (1 - a (1 - O))
// at every depth (the closure is exact here). The ratio of sums has the
// first-order (delta method) bias (E[N] Var(D) - E[D] Cov(N, D)) / (E[D]^3 n)
// with N = S, D = 1 - T; we allow twice it (the next term is O(1/n^2), and
// the stratified samples only shrink the (co)variances). Distance
// estimator: m1 = J(k, 1), m2 = J(2k, 1); occlusion: e is 0/1, m1 = m2 = 1 - O.
struct ClosedTail {
  double W, bias;
};
ClosedTail closedTail(double m1, double m2, double a, int depth, int n) {
  double s = 0, t = 1, ss = 0, tt = 1, st = 0;  // beyond the last segment: S = 0, T = 1
  for (int j = 0; j <= depth; ++j) {
    const double s1 = 1 - m1 + a * m1 * s, t1 = a * m1 * t;
    const double ss1 = (1 - 2 * m1 + m2) + 2 * a * (m1 - m2) * s + a * a * m2 * ss;
    const double tt1 = a * a * m2 * tt, st1 = a * (m1 - m2) * t + a * a * m2 * st;
    s = s1, t = t1, ss = ss1, tt = tt1, st = st1;
  }
  const double d = 1 - t, varD = tt - t * t, covND = -(st - s * t);
  return {s / d, 2 * std::abs((s * varD - d * covND) / (d * d * d * n))};
}

// A sphere of radius rs seen from inside, with a hole of half-angle alpha
// (0: closed), every wall of grey albedo a.
std::unique_ptr<Scene> greySphere(float rs, double alpha, float a) {
  auto scene = std::make_unique<Scene>();
  addSphereCavity(*scene, rs, alpha, kRings, kSegments, addGreyMaterial(*scene, a));
  scene->setRobust(true);  // the 512-valent poles (test_ao_analytic.cpp)
  scene->commit();
  return scene;
}

Camera insideCamera() { return makeLookAtCamera(Vec3(0, 0, 0), Vec3(0.3f, 0.2f, -1), Vec3(0, 1, 0), 1.2f, "inside"); }

constexpr float kGrey = 0.6f;
const double kKs[] = {0.5, 2.0, 8.0};  // k = 2 sigma Rs

// 1a. The closed sphere (radius 1.25, albedo 0.6) filled with the medium:
//     gi sigma = s, and transfer falloff=exponential at depth 0 (closed form,
//     both estimators) give W = O / (1 - a (1 - O)); tail=zero at depth 1
//     truncates the series W = O Sum (a (1 - O))^j after two terms; the
//     closed tail at depth 2 (both estimators) is exact again.
//     A wrong membership would fail by far: with the step membership (or
//     vacuum, gi sigma ignored) nothing escapes a closed sphere, W = 0; with
//     sigma ignored (the default sigma = 1, k = 2.5) W moves to the closed form
//     at k = 2.5. Both are asserted to lie more than 10 tolerances away.
TEST(MediumClosedForms, ClosedSphereWithGreyAlbedo) {
  const float rs = 1.25f;
  const auto scene = greySphere(rs, 0.0, kGrey);
  const int w = 16, h = 16;
  for (const double k : kKs) {
    const double sigma = k / (2.0 * rs);
    const double O = mediumO(k, 1.0), W = mediumW(O, kGrey);
    const auto Wof = [](double o) { return mediumW(o, kGrey); };
    const double tess = moved(Wof, O, k * kTess);
    struct Case {
      std::string name;
      std::string integrator;
      std::vector<std::string> params;
      int spp;
      double expected, bias, tess;
    };
    const int n = 64 * 16;
    const std::vector<Case> cases = {
        {"gi", "gi", {"sigma=" + num(sigma), "rays=4"}, 64, W, 0.0, tess},
        {"transfer depth 0 distance", "transfer",
         {"falloff=exponential", "sigma=" + num(sigma), "rays=16"}, 64, W,
         ratioBiasBound(kGrey, mediumVar(k, 1.0), n), tess},
        {"transfer depth 0 occlusion", "transfer",
         {"falloff=exponential", "sigma=" + num(sigma), "rays=16", "estimator=occlusion"}, 64, W,
         ratioBiasBound(kGrey, O * (1 - O), n), tess},
        {"transfer depth 1 tail zero", "transfer",
         {"falloff=exponential", "sigma=" + num(sigma), "rays=4", "depth=1", "tail=zero"}, 64,
         O * (1 + kGrey * (1 - O)), 0.0, moved([](double o) { return o * (1 + kGrey * (1 - o)); }, O, k * kTess)},
        {"transfer depth 2 distance", "transfer",
         {"falloff=exponential", "sigma=" + num(sigma), "rays=8", "depth=2"}, 64,
         closedTail(J(k, 1), J(2 * k, 1), kGrey, 2, 512).W, closedTail(J(k, 1), J(2 * k, 1), kGrey, 2, 512).bias, tess},
        {"transfer depth 2 occlusion", "transfer",
         {"falloff=exponential", "sigma=" + num(sigma), "rays=8", "depth=2", "estimator=occlusion"}, 64,
         closedTail(1 - O, 1 - O, kGrey, 2, 512).W, closedTail(1 - O, 1 - O, kGrey, 2, 512).bias, tess},
    };
    for (const Case& c : cases) {
      const Film film = renderWith(*scene, insideCamera(), c.integrator, c.params, passSettings(w, h, c.spp));
      const PixelStats s = pixelStats(film, kR);
      ASSERT_EQ(s.n, size_t(w * h));
      const double tol = 4 * s.se + c.bias + c.tess;
      std::printf("closed sphere k %.1f %-27s: %.5f expected %.5f (O %.5f) SE %.2g bias<=%.2g tess %.2g tol %.2g\n", k,
                  c.name.c_str(), s.mean, c.expected, O, s.se, c.bias, c.tess, tol);
      EXPECT_NEAR(s.mean, c.expected, tol) << c.name << " k " << k;
      EXPECT_EQ(pixelStats(film, kG).mean, s.mean) << "grey albedo, grey W";
      if (c.name == "gi" || c.name == "transfer depth 0 distance") {
        // What a wrong mu would give is far outside the tolerance.
        const double sigmaIgnored = mediumW(mediumO(2.0 * rs, 1.0), kGrey);  // sigma = 1
        EXPECT_GT(W - 0.0, 10 * tol) << "step membership / vacuum: W = 0";
        EXPECT_GT(std::abs(sigmaIgnored - W), 10 * tol) << "sigma ignored";
        std::printf("  wrong mu would be off by: step %.0f SE, sigma ignored %.0f SE\n", W / s.se,
                    std::abs(sigmaIgnored - W) / s.se);
      }
    }
  }
}

// 1b. The cavity with a hole (radius 1.25, alpha = 60 degrees, albedo 0.6)
//     at the wall point opposite the hole, seen through a 1e-4 lens:
//     O = 1 - J(k, c0), c0 = cos(alpha/2) (docs/math.md §7). Directions
//     escaping through the hole have mu = 1 and add nothing to the
//     denominator, every other one meets the wall of albedo a, so transfer
//     depth 0 gives O / (1 - a (1 - O)) there (W is not uniform over the
//     wall, so gi has no closed form here). The step membership at R = inf
//     would give f / (1 - a (1 - f)), f = 1/4; sigma = 1 would be k = 2.5.
TEST(MediumClosedForms, CavityAntipodeTransfer) {
  const float rs = 1.25f;
  const double alpha = M_PI / 3, c0 = std::cos(alpha / 2), f = (1 - std::cos(alpha)) / 2;
  const auto scene = greySphere(rs, alpha, kGrey);
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1e-4f, "antipode");
  const int w = 16, h = 16, spp = 64, rays = 16, n = spp * rays;
  for (const double k : kKs) {
    const double sigma = k / (2.0 * rs);
    const double O = mediumO(k, c0), W = mediumW(O, kGrey);
    // The hole's edge (D^2 in probability) and the chords (k D^2).
    const double tess = moved([](double o) { return mediumW(o, kGrey); }, O, (k + 1) * kTess);
    for (const char* estimator : {"estimator=distance", "estimator=occlusion"}) {
      const bool occlusion = std::string(estimator) == "estimator=occlusion";
      const double bias = ratioBiasBound(kGrey, occlusion ? O * (1 - O) : mediumVar(k, c0), n);
      const Film film = renderWith(*scene, cam, "transfer",
                                   {"falloff=exponential", "sigma=" + num(sigma), "rays=" + std::to_string(rays), estimator},
                                   passSettings(w, h, spp));
      const PixelStats s = pixelStats(film, kR);
      ASSERT_EQ(s.n, size_t(w * h));
      const double tol = 4 * s.se + bias + tess;
      const double step = mediumW(f, kGrey), sigmaIgnored = mediumW(mediumO(2.0 * rs, c0), kGrey);
      std::printf("antipode k %.1f %s: %.5f expected %.5f (O %.5f) SE %.2g bias<=%.2g tess %.2g; step off by %.0f SE, "
                  "sigma=1 by %.0f SE\n",
                  k, estimator, s.mean, W, O, s.se, bias, tess, std::abs(step - W) / s.se,
                  std::abs(sigmaIgnored - W) / s.se);
      EXPECT_NEAR(s.mean, W, tol) << estimator << " k " << k;
      EXPECT_GT(std::abs(step - W), 10 * tol) << "the step membership would pass";
      EXPECT_GT(std::abs(sigmaIgnored - W), 10 * tol) << "ignoring sigma would pass";
    }
  }
}


// --- 2. coloured occluders, a receiver of another albedo, depths that differ --

// The scene: a sphere cavity of radius 1 with a hole of half-angle
// alpha = pi/4 about +Z (f = (1 - cos alpha)/2), its wall split at the
// equator into an upper band (alpha <= theta < pi/2) of albedo aHi and a lower
// hemisphere of albedo aLo, and at the centre a tiny receiver square (half
// side 1e-3, normal +Z) of albedo aRecv, seen from above through a 1e-4 lens.
//
// Form factors inside a sphere are uniform: from any wall point, the hit
// point of a cosine-distributed direction is uniform over the sphere's area.
// So from every wall point a direction escapes with probability f, meets the
// upper band with 1/2 - f and the lower half with 1/2, whatever the point.
// From the centre facing +Z, the direction at angle theta from +Z meets the
// sphere at polar angle theta: it escapes with probability
// p0 = sin^2(alpha) (cosine-weighted cone) and otherwise meets the upper band.
// A path is then a Markov chain on {receiver, upper, lower}, and the
// expectation of each path's (num, den) at any depth (docs/math.md §5,
// integrators/ambient_paths.h: num = S, den = S + A with tail=closed, 1 with
// tail=zero) is a finite sum over its state sequences, per channel.
// The receiver's albedo enters no W: only shaded = aRecv W.
// The receiver itself is an occluder for wall points with probability at
// most its area / (pi Rs^2) = 1.3e-6 per bounce (bounded below).
struct Chain {
  double p0, f, qLo;  // qLo = 1/2
  Vec3 albedo[3];     // receiver, upper band, lower half
  bool sourceAlbedo = false;  // a wrong implementation: the albedo of the vertex left, not of the occluder

  double escape(int s) const { return s == 0 ? p0 : f; }
  double to(int s, int t) const {  // t = 1 (upper) or 2 (lower)
    if (s == 0) return t == 1 ? 1 - p0 : 0.0;
    return t == 1 ? 1 - f - qLo : qLo;
  }
};

// Moments of one path's (N, D) for channel c, depth `depth`, tail closed or
// zero: E[N], E[D], E[N^2], E[D^2], E[N D].
struct Moments {
  double n = 0, d = 0, nn = 0, dd = 0, nd = 0;
};
void enumeratePaths(const Chain& ch, int c, int depth, bool closed, int s, int bounce, double prob, double T, double S,
                    double A, Moments& m) {
  const auto add = [&](double p, double N, double D) {
    m.n += p * N, m.d += p * D, m.nn += p * N * N, m.dd += p * D * D, m.nd += p * N * D;
  };
  const double S1 = S + T;  // escape
  add(prob * ch.escape(s), S1, closed ? S1 + A : 1.0);
  for (int t = 1; t <= 2; ++t) {
    const double pt = prob * ch.to(s, t);
    if (pt == 0) continue;
    const double a = ch.albedo[ch.sourceAlbedo ? s : t][c];
    const double A1 = A + T * (1 - a);
    if (bounce >= depth)
      add(pt, S, closed ? S + A1 : 1.0);
    else
      enumeratePaths(ch, c, depth, closed, t, bounce + 1, pt, T * a, S, A1, m);
  }
}
Moments pathMoments(const Chain& ch, int c, int depth, bool closed) {
  Moments m;
  enumeratePaths(ch, c, depth, closed, 0, 0, 1.0, 1.0, 0.0, 0.0, m);
  return m;
}
// The pixel's expectation: E[N]/E[D] (the ratio of sums converges to it).
double chainW(const Chain& ch, int c, int depth, bool closed) {
  const Moments m = pathMoments(ch, c, depth, closed);
  return m.n / m.d;
}
// Full GI: the series of the escapes, no tail (paths die out geometrically).
double chainGi(const Chain& ch, int c) {
  std::array<double, 3> mass = {1, 0, 0};
  double W = 0;
  for (int b = 0; b < 2000; ++b) {
    std::array<double, 3> next = {0, 0, 0};
    for (int s = 0; s < 3; ++s) {
      W += mass[size_t(s)] * ch.escape(s);
      for (int t = 1; t <= 2; ++t)
        next[size_t(t)] += mass[size_t(s)] * ch.to(s, t) * ch.albedo[ch.sourceAlbedo ? s : t][c];
    }
    mass = next;
  }
  return W;
}
// First-order (delta method) bias of the ratio of sums of n independent
// (N, D) pairs: (E[N] Var(D) - E[D] Cov(N, D)) / (E[D]^3 n). We allow twice
// its size: the next term is O(1/n^2) and the stratified Sobol' samples only
// shrink the (co)variances it is made of.
double chainRatioBias(const Chain& ch, int c, int depth, int n) {
  const Moments m = pathMoments(ch, c, depth, true);
  const double varD = m.dd - m.d * m.d, cov = m.nd - m.n * m.d;
  return 2.0 * std::abs((m.n * varD - m.d * cov) / (m.d * m.d * m.d * n));
}
// The tessellation: p0, f and the band split each move by at most D^2.
double chainTess(const Chain& ch, const std::function<double(const Chain&)>& W) {
  const double w0 = W(ch);
  double t = 0;
  for (double Chain::*p : {&Chain::p0, &Chain::f, &Chain::qLo}) {
    double worst = 0;
    for (const double sgn : {-1.0, 1.0}) {
      Chain moved = ch;
      moved.*p += sgn * kTess;
      worst = std::max(worst, std::abs(W(moved) - w0));
    }
    t += worst;
  }
  return t;
}

const Vec3 kHi(0.9f, 0.5f, 0.1f), kLo(0.3f, 0.8f, 0.6f), kRecv(0.2f, 0.7f, 0.4f);
constexpr double kBandAlpha = M_PI / 4;
constexpr int kBandRings = 192;  // theta steps of (pi - alpha)/192 = pi/256: the equator is ring 64
constexpr float kPatch = 1e-3f;

Chain bandChain(Vec3 hi, Vec3 lo, Vec3 recv) {
  Chain ch;
  ch.p0 = std::sin(kBandAlpha) * std::sin(kBandAlpha);
  ch.f = (1 - std::cos(kBandAlpha)) / 2;
  ch.qLo = 0.5;
  ch.albedo[0] = recv, ch.albedo[1] = hi, ch.albedo[2] = lo;
  return ch;
}

std::unique_ptr<Scene> bandScene() {
  auto scene = std::make_unique<Scene>();
  const auto material = [&](Vec3 a) {
    Material m;
    m.name = "colour";
    m.baseColorFactor = a;
    scene->materials.push_back(m);
    return int(scene->materials.size()) - 1;
  };
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx, hi, lo;
  sphereCavityMesh(1.0f, kBandAlpha, kBandRings, kSegments, pos, nrm, idx);
  // Split the triangles at the equator (a ring of shared vertices).
  for (size_t t = 0; t < idx.size(); t += 3) {
    const float z = pos[idx[t]].z + pos[idx[t + 1]].z + pos[idx[t + 2]].z;
    (z > 0 ? hi : lo).insert((z > 0 ? hi : lo).end(), {idx[t], idx[t + 1], idx[t + 2]});
  }
  scene->addWorldPrimitive(pos, hi, nrm, {}, material(kHi));
  scene->addWorldPrimitive(pos, lo, nrm, {}, material(kLo));
  const float e = kPatch;
  scene->addWorldPrimitive({{-e, -e, 0}, {e, -e, 0}, {e, e, 0}, {-e, e, 0}}, {0, 1, 2, 0, 2, 3}, {}, {},
                           material(kRecv));
  scene->setRobust(true);
  scene->commit();
  return scene;
}
Camera patchCamera() { return makeLookAtCamera(Vec3(0, 0, 0.5f), Vec3(0, 0, 0), Vec3(0, 1, 0), 1e-4f, "patch"); }

// 2. transfer (closed form and closed tails at depths 1 and 2, tail=zero) and
//    gi against the chain's expectations, per channel; the albedo AOV is the
//    receiver's and shaded = aRecv W. Every variant a wrong implementation
//    might compute - the receiver's albedo in place of the occluders', the
//    occluder albedo's channels reversed, the upper and lower albedos
//    swapped (which changes depths >= 1 only), the albedo of the vertex left
//    instead of the one hit - is asserted to lie more than 5 tolerances
//    away in some channel.
TEST(TransferColour, ReceiverAndOccludersOfDifferentAlbedo) {
  const auto scene = bandScene();
  const Chain ch = bandChain(kHi, kLo, kRecv);
  struct Case {
    std::string name, integrator;
    std::vector<std::string> params;
    int depth;  // -1: gi
    bool closed;
  };
  const int w = 16, h = 16, spp = 64, rays = 16, n = spp * rays;
  const std::vector<Case> cases = {
      {"transfer depth 0", "transfer", {"rays=16"}, 0, true},
      {"transfer depth 1", "transfer", {"rays=16", "depth=1"}, 1, true},
      {"transfer depth 2", "transfer", {"rays=16", "depth=2"}, 2, true},
      {"transfer depth 1 zero", "transfer", {"rays=16", "depth=1", "tail=zero"}, 1, false},
      {"gi", "gi", {"rays=16"}, -1, false},
  };
  RenderSettings settings = passSettings(w, h, spp);
  settings.aovs = true;
  for (const Case& cs : cases) {
    const Film film = renderWith(*scene, patchCamera(), cs.integrator, cs.params, settings);
    const auto expect = [&](const Chain& c, int channel) {
      return cs.depth < 0 ? chainGi(c, channel) : chainW(c, channel, cs.depth, cs.closed);
    };
    // Wrong variants.
    const auto rev = [](Vec3 v) { return Vec3(v.z, v.y, v.x); };
    Chain recvAsOcc = bandChain(kRecv, kRecv, kRecv), reversed = bandChain(rev(kHi), rev(kLo), kRecv),
          swapped = bandChain(kLo, kHi, kRecv), source = ch;
    source.sourceAlbedo = true;
    const Chain* wrong[] = {&recvAsOcc, &reversed, &swapped, &source};
    const char* wrongName[] = {"receiver albedo", "channels reversed", "bands swapped", "albedo of the vertex left"};
    double worstMiss[4] = {0, 0, 0, 0};
    for (int c = 0; c < 3; ++c) {
      const PixelStats s = pixelStats(film, kR + c);
      ASSERT_EQ(s.n, size_t(w * h));
      const double W = expect(ch, c);
      const double bias = cs.closed ? chainRatioBias(ch, c, cs.depth, n) : 0.0;
      const double tess = chainTess(ch, [&](const Chain& x) { return expect(x, c); });
      const double patch = 4 * (cs.depth < 0 ? 10 : cs.depth + 1) * (4.0 * kPatch * kPatch / M_PI);
      const double tol = 4 * s.se + bias + tess + patch;
      std::printf("%-22s channel %d: %.5f expected %.5f SE %.2g bias %.2g tess %.2g tol %.2g |", cs.name.c_str(), c,
                  s.mean, W, s.se, bias, tess, tol);
      EXPECT_NEAR(s.mean, W, tol) << cs.name << " channel " << c;
      for (int v = 0; v < 4; ++v) {
        const double off = std::abs(expect(*wrong[v], c) - W) / tol;
        worstMiss[v] = std::max(worstMiss[v], off);
        std::printf(" %.0f", off);
      }
      std::printf("\n");
      // The albedo AOV is the receiver's; shaded = albedo W per channel.
      const PixelStats albedo = pixelStats(film, kAlbedoR + c), shaded = pixelStats(film, kShadedR + c);
      EXPECT_NEAR(albedo.mean, kRecv[c], 1e-6) << cs.name;
      EXPECT_NEAR(shaded.mean, kRecv[c] * s.mean, 1e-5) << cs.name;
    }
    for (int v = 0; v < 4; ++v) {
      if (v == 2 && cs.depth == 0) continue;  // depth 0 never reaches the lower half
      EXPECT_GT(worstMiss[v], 5.0) << cs.name << ": the test would not see " << wrongName[v];
    }
  }
}

}  // namespace
}  // namespace obscura::test
