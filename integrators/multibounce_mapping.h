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
//   F0 = alpha (1 + (1 - alpha)^0.75 / 2)      (zero-bounce irradiance)
//   F1 = A alpha (1 - alpha)^1.5 e^(-B alpha^(1/4))
//   tau = 1 - F1 / (1 - F0),   W = F0 + rho / (1 - rho tau) F1.
// As published this is 0/0 at alpha = 0 and alpha = 1; F0 exceeds 1 for
// alpha > 0.9493 (so 1 - F0 changes sign there and tau leaves [0, 1]); F1 >
// 1 - F0 for alpha in (0.76, 0.95) (tau < 0); and with 1 - F0 < 0 the
// denominator 1 - rho tau crosses zero (a pole near alpha = 0.99, rho = 0.85).
//
// With g = 1 - F0 the same function reads, wherever g > 0,
//   W = F0 + g h,   h = rho F1 / (g (1 - rho) + rho F1),
// a form with no cancellation: both terms of h's denominator are >= 0, so
// h is in [0, 1] and W in [F0, 1] (W = 1 at rho = 1: the white furnace the
// fit was built to satisfy). Where F0 >= 1 the geometry leaves no room for
// bounced light and W = 1: F0 clamped to 1, which also keeps W
// non-decreasing in alpha. h's denominator is 0 only at alpha = 0, rho = 1
// (nothing open, every surface white): h = 1 there, the white-furnace
// limit, as for the ratio estimators (include/obscura/integrator.h).
inline double improvedMultiBounce(double alpha, double rho) {
  constexpr double A = 27.576937094210385, B = 3.3364392003423804;
  alpha = std::clamp(alpha, 0.0, 1.0);
  rho = std::clamp(rho, 0.0, 1.0);
  const double F0 = alpha * (1.0 + 0.5 * std::pow(1.0 - alpha, 0.75));
  if (!(F0 < 1.0)) return 1.0;
  const double g = 1.0 - F0;
  const double F1 = A * alpha * std::pow(1.0 - alpha, 1.5) * std::exp(-B * std::sqrt(std::sqrt(alpha)));
  const double D = g * (1.0 - rho) + rho * F1;
  const double h = D > 0.0 ? rho * F1 / D : (rho >= 1.0 ? 1.0 : 0.0);
  return std::min(1.0, F0 + g * h);
}

}  // namespace obscura
