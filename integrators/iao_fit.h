// Fitting the improved-AO mapping's F0 and F1 [IAO 7, 11] to rendered data,
// and the file that carries the coefficients (docs/math.md §6 "Fitting F0
// and F1"; `obscura fit` makes it, `multibounce mapping=fitted fit=FILE`
// reads it).
//
// The data (docs/math.md §6): per covered pixel the uniform AO alpha
// [IAO 4], the zero-bounce irradiance over pi y0 = (1/pi) Int V cos dw (unit
// sky radiance) and the one-bounce irradiance over pi y1 with every surface
// white [IAO 5, "WE USE ALBEDO=1"]. The paper histograms y0 and y1 against
// alpha [IAO "Collecting Data", step 4] and fits
//   F0(alpha) = alpha + s phi_e(alpha),   phi_e = alpha (1 - alpha)^e       [IAO 7]
//   F1(alpha) = A psi_B(alpha),           psi_B = alpha (1 - alpha)^1.5 e^(-B alpha^(1/4))  [IAO 11]
// Each model is linear in one coefficient (s, A) given the other (e, B), so
// the least squares is separable (variable projection, Golub and Pereyra
// 1973): for a fixed e the best s is the weighted linear regression
//   s*(e) = Sum n_b phi_b r_b / Sum n_b phi_b^2,   r_b = y0_b - alpha_b,
// and the remaining sum of squares
//   S(e) = Sum n_b r_b^2 - (Sum n_b phi_b r_b)^2 / Sum n_b phi_b^2
// is a function of e alone, minimised by a scan of the range followed by a
// golden-section search in the best bracket (likewise A*(B) and S(B)). The
// sums run over the histogram's bins b with n_b pixels, mean alpha_b and
// mean y_b: the per-pixel least squares, with each pixel's alpha replaced
// by its bin's mean (bins of width h = 1/bins). That replaces a bin's mean
// of f by f at its mean alpha, an error of about f'' h^2 / 24 - not small
// everywhere: F1's e^(-B alpha^(1/4)) makes f'' grow as alpha^(-3/4) towards
// alpha = 0 (f'' ~ 200 at alpha = 0.01 for the published curve), so at 64
// bins the bias of A and B is several standard errors of a 400000-pixel
// fit. Hence the default of 1000 bins (`obscura fit --bins`), where it is
// below a tenth of one; empty and thin bins cost nothing (weights n_b).
//
// Standard errors: the Gauss-Newton covariance sigma^2 (J^T N J)^-1 at the
// optimum, J the model's derivatives in its two coefficients at the bins'
// alpha, N = diag(n_b), sigma^2 the per-pixel residual variance (a bin
// mean of n_b pixels has variance sigma^2 / n_b). They measure the noise of
// the data only, not whether the model's form is right: the residuals do.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "integrators/multibounce_mapping.h"

namespace obscura {

// Per-bin sums of the pixels' (alpha, y0, y1), alpha in [0, 1] cut into
// `bins` equal bins (alpha = 1 in the last).
class IaoHistogram {
 public:
  struct Bin {
    double n = 0, alpha = 0, y0 = 0, y0sq = 0, y1 = 0, y1sq = 0;  // count and sums
  };
  explicit IaoHistogram(int bins = 1000);
  void add(double alpha, double y0, double y1);
  // Pools another histogram of the same bin count (another scene's pixels).
  void merge(const IaoHistogram& other);
  const std::vector<Bin>& bins() const { return bins_; }
  double pixels() const;

 private:
  std::vector<Bin> bins_;
};

// One curve's fit: its two coefficients (linear, nonlinear), their standard
// errors, and the residuals.
struct CurveFit {
  double linear = 0, nonlinear = 0;        // (s, e) of F0, (A, B) of F1
  double seLinear = 0, seNonlinear = 0;    // standard errors
  double rmsMeans = 0;   // sqrt(Sum n_b (y_b - f(alpha_b))^2 / N): the curve against the bin means
  double rmsPixels = 0;  // sqrt(Sum over pixels (y - f(alpha_b))^2 / N): the pixels' scatter about it
  // The nonlinear coefficient ended at an end of its searched range (e in
  // [0.01, 8], B in [-20, 40]): the form does not describe the data there.
  bool atBound = false;
};

struct IaoFit {
  ImprovedFit coefficients;
  CurveFit f0, f1;
  double pixels = 0;
  int bins = 0, filledBins = 0;
};

// The least-squares fit of F0 and F1 to the histogram (see above). Throws
// obscura::Error when fewer than 3 bins hold pixels (two coefficients per
// curve need at least one more point).
IaoFit fitImprovedAo(const IaoHistogram& h);

// The residuals (CurveFit::rmsMeans, rmsPixels) of given coefficients on the
// histogram, standard errors 0: the published fit measured on the same data.
IaoFit improvedFitResiduals(const IaoHistogram& h, const ImprovedFit& c);

// The standard errors of the four coefficients at `c` for per-pixel noise of
// standard deviation sigma0 (y0) and sigma1 (y1): {s, e, A, B}. What a fit of
// data with that noise should scatter by (the tests' tolerances).
void improvedFitStdErrors(const IaoHistogram& h, const ImprovedFit& c, double sigma0, double sigma1, double se[4]);

// The coefficients file (JSON, docs/math.md §6): {"format": "obscura-iao-fit",
// "version": 1, "F0": {"scale", "exponent"}, "F1": {"A", "B"}, "fit": {...}}.
// "fit" (how the coefficients were made: scenes, pixels, residuals) is
// informative and not read back.
std::string improvedFitJson(const IaoFit& fit, const std::vector<std::string>& scenes, const std::string& settings);
// Reads F0.scale, F0.exponent, F1.A and F1.B. Throws obscura::Error naming
// the file and the field on a missing or unreadable file, bad JSON, a
// missing or non-numeric field, or a value out of range: scale >= -1 (F0 >=
// 0), exponent in (0, 100] (F0(1) = 1), A >= 0 (F1 >= 0), |B| <= 1000, all
// finite.
ImprovedFit readImprovedFit(const std::string& path);

}  // namespace obscura
