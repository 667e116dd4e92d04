// Multi-bounce AO mappings (docs/math.md §6): W = G(v, rho), the
// normalized ambient irradiance predicted from an AO value v and the albedo
// rho, one RGB channel at a time. Header-only so the tests can sweep them.
//
// Both are finite and within [0, 1] on the whole unit square and
// non-decreasing in v (tests/test_multibounce.cpp proves it on a dense grid
// that includes the edges).
#pragma once

#include <algorithm>
#include <cmath>

namespace obscura {

// Jimenez et al. 2016 (GTAO), fitted to the cosine-weighted visibility v:
//   a = 2.0404 rho - 0.3324, b = -4.7951 rho + 0.6417, c = 2.7552 rho + 0.6903
//   W = max(v, ((v a + b) v + c) v)
// The cubic's derivative 3a v^2 + 2b v + c is affine in rho and positive on
// [0,1] at rho = 0 and rho = 1, so W is increasing in v. At v = 1 the fit
// gives a + b + c = 0.9996 + 0.0005 rho, slightly above 1 for rho near 1:
// clamped to 1.
inline double gtaoMultiBounce(double v, double rho) {
  v = std::clamp(v, 0.0, 1.0);
  rho = std::clamp(rho, 0.0, 1.0);
  const double a = 2.0404 * rho - 0.3324, b = -4.7951 * rho + 0.6417, c = 2.7552 * rho + 0.6903;
  return std::min(1.0, std::max(v, ((v * a + b) * v + c) * v));
}

// Improved AO [IAO 7, 9, 11, 12], fitted to the uniform solid-angle
// visibility alpha = Int V dw / 2 pi [IAO 4]:
//   F0 = alpha (1 + s (1 - alpha)^e)            (zero-bounce irradiance / pi)
//   F1 = A alpha (1 - alpha)^1.5 e^(-B alpha^(1/4))   (one bounce, rho = 1)
//   tau = 1 - F1 / (1 - F0),   W = F0 + rho / (1 - rho tau) F1.
// The paper publishes s = 1/2, e = 0.75 [IAO 7] and A, B [IAO 11]; its
// functional forms fix F1's exponents 1.5 and 1/4, so the four free
// coefficients are s, e, A, B (ImprovedFit; `obscura fit` fits them,
// docs/math.md §6 "Fitting F0 and F1").
// As published this is 0/0 at alpha = 0 and alpha = 1; F0 exceeds 1 for
// alpha > 0.9493 (so 1 - F0 changes sign there and tau leaves [0, 1]); F1 >
// 1 - F0 for alpha in (0.76, 0.95) (tau < 0); and with 1 - F0 < 0 the
// denominator 1 - rho tau crosses zero (a pole near alpha = 0.99, rho = 0.85).
//
// With g = 1 - F0 the same function reads, wherever g > 0,
//   W = F0 + g h,   h = rho F1 / (g (1 - rho) + rho F1),
// a form with no cancellation: both terms of h's denominator are >= 0 (F1
// >= 0 needs A >= 0, which readImprovedFit demands), so h is in [0, 1] and
// W in [F0, 1] (W = 1 at rho = 1: the white furnace the fit was built to
// satisfy). Where F0 >= 1 the geometry leaves no room for bounced light and
// W = 1: F0 clamped to 1, which also keeps W non-decreasing in alpha for the
// published coefficients. h's denominator is 0 only at alpha = 0, rho = 1
// (nothing open, every surface white): h = 1 there, the white-furnace
// limit, as for the ratio estimators (include/obscura/integrator.h).
// Every coefficient set gets this same evaluation (fittedMultiBounce); only the published one is
// proven monotone in alpha (tests/test_multibounce.cpp).
struct ImprovedFit {
  double f0Scale = 0.5;                  // s of F0 [IAO 7]
  double f0Exponent = 0.75;              // e of F0 [IAO 7]
  double f1A = 27.576937094210385;       // A of F1 [IAO 11]
  double f1B = 3.3364392003423804;       // B of F1 [IAO 11]
};

// F0(alpha) and F1(alpha) for alpha in [0, 1] (the fit evaluates them too).
inline double improvedF0(double alpha, const ImprovedFit& c) {
  return alpha * (1.0 + c.f0Scale * std::pow(1.0 - alpha, c.f0Exponent));
}
inline double improvedF1(double alpha, const ImprovedFit& c) {
  return c.f1A * alpha * std::pow(1.0 - alpha, 1.5) * std::exp(-c.f1B * std::sqrt(std::sqrt(alpha)));
}

inline double fittedMultiBounce(double alpha, double rho, const ImprovedFit& c) {
  alpha = std::clamp(alpha, 0.0, 1.0);
  rho = std::clamp(rho, 0.0, 1.0);
  const double F0 = improvedF0(alpha, c);
  if (!(F0 < 1.0)) return 1.0;
  const double g = 1.0 - F0;
  const double F1 = improvedF1(alpha, c);
  const double D = g * (1.0 - rho) + rho * F1;
  const double h = D > 0.0 ? rho * F1 / D : (rho >= 1.0 ? 1.0 : 0.0);
  return std::min(1.0, F0 + g * h);
}

// The published coefficients (`mapping=improved`): the same code, so
// `mapping=fitted` with them is `improved` bit for bit.
inline double improvedMultiBounce(double alpha, double rho) { return fittedMultiBounce(alpha, rho, ImprovedFit{}); }

}  // namespace obscura
