// The improved-AO fit and its file (integrators/iao_fit.h, docs/math.md §6).
#include "integrators/iao_fit.h"
#include "core/util/input_file.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include <obscura/error.h>
#include <obscura/params.h>

namespace obscura {
namespace {

// One curve's model f = base(alpha) + linear * basis(alpha, p): F0 has
// base = alpha, F1 none. dBasis is d basis / dp (for the standard errors).
struct Model {
  bool hasBase;
  double (*basis)(double alpha, double p);
  double (*dBasis)(double alpha, double p);
  double pLo, pHi;  // the range searched for p
};

double f0Basis(double a, double e) { return a * std::pow(1.0 - a, e); }
double f0dBasis(double a, double e) { return a < 1.0 ? f0Basis(a, e) * std::log1p(-a) : 0.0; }
double f1Basis(double a, double B) { return improvedF1(a, ImprovedFit{.f1A = 1.0, .f1B = B}); }
double f1dBasis(double a, double B) { return -f1Basis(a, B) * std::sqrt(std::sqrt(a)); }

// e in [0.01, 8]: below, F0 is alpha(1 + s) almost everywhere (no longer a
// correction that vanishes at alpha = 1); above, it is alpha but within a
// sliver at alpha = 0. B in [-20, 40]: e^(-B alpha^(1/4)) from e^20 to e^-40
// covers every peak position the form can take.
const Model kF0{true, f0Basis, f0dBasis, 0.01, 8.0};
const Model kF1{false, f1Basis, f1dBasis, -20.0, 40.0};

// y_b and the sum of y^2 of bin b for curve `which` (0: y0, 1: y1).
double meanY(const IaoHistogram::Bin& b, int which) { return (which == 0 ? b.y0 : b.y1) / b.n; }
double sumYsq(const IaoHistogram::Bin& b, int which) { return which == 0 ? b.y0sq : b.y1sq; }

// The best linear coefficient for p and the sum of squares of the bin
// means about the curve (the variable-projection functional S(p)).
struct Projection {
  double linear = 0, ss = std::numeric_limits<double>::infinity();
};
Projection project(const IaoHistogram& h, int which, const Model& m, double p) {
  double sxx = 0, sxr = 0, srr = 0;
  for (const IaoHistogram::Bin& b : h.bins()) {
    if (b.n <= 0) continue;
    const double a = b.alpha / b.n;
    const double r = meanY(b, which) - (m.hasBase ? a : 0.0);
    const double x = m.basis(a, p);
    sxx += b.n * x * x, sxr += b.n * x * r, srr += b.n * r * r;
  }
  Projection out;
  if (!(sxx > 0.0) || !std::isfinite(sxx)) return out;
  out.linear = sxr / sxx;
  out.ss = std::max(0.0, srr - sxr * out.linear);
  return out;
}

// Minimises S(p) over [pLo, pHi]: a scan of kScan points, then golden
// section in the bracket about the best one (S is smooth; the scan guards
// against the local minima a bare golden section could settle in).
double minimise(const std::function<double(double)>& S, double lo, double hi) {
  constexpr int kScan = 240;
  int best = 0;
  double bestS = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= kScan; ++i) {
    const double s = S(lo + (hi - lo) * i / kScan);
    if (s < bestS) bestS = s, best = i;
  }
  double a = lo + (hi - lo) * std::max(0, best - 1) / kScan, b = lo + (hi - lo) * std::min(kScan, best + 1) / kScan;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double c = b - g * (b - a), d = a + g * (b - a);
  double Sc = S(c), Sd = S(d);
  for (int it = 0; it < 200 && b - a > 1e-13 * std::max(1.0, std::abs(a)); ++it) {
    if (Sc < Sd) {
      b = d, d = c, Sd = Sc, c = b - g * (b - a), Sc = S(c);
    } else {
      a = c, c = d, Sc = Sd, d = a + g * (b - a), Sd = S(d);
    }
  }
  const double p = (a + b) / 2.0;
  return S(p) <= bestS ? p : lo + (hi - lo) * best / kScan;
}

// sigma^2 (J^T N J)^-1's diagonal square roots for the model at (linear, p).
void stdErrors(const IaoHistogram& h, const Model& m, double linear, double p, double sigma, double& seLin,
               double& seP) {
  double a11 = 0, a12 = 0, a22 = 0;
  for (const IaoHistogram::Bin& b : h.bins()) {
    if (b.n <= 0) continue;
    const double a = b.alpha / b.n;
    const double j1 = m.basis(a, p), j2 = linear * m.dBasis(a, p);
    a11 += b.n * j1 * j1, a12 += b.n * j1 * j2, a22 += b.n * j2 * j2;
  }
  const double det = a11 * a22 - a12 * a12;
  const double inf = std::numeric_limits<double>::infinity();
  seLin = det > 0.0 ? sigma * std::sqrt(a22 / det) : inf;
  seP = det > 0.0 ? sigma * std::sqrt(a11 / det) : inf;
}

// c.rmsMeans and c.rmsPixels for the curve at (c.linear, c.nonlinear): the
// residuals of the bin means (what the fit minimises) and of the pixels,
// Sum_b [Sum y^2 - 2 f Sum y + n f^2] (each pixel at its bin's f). Returns N.
double residuals(const IaoHistogram& h, int which, const Model& m, CurveFit& c) {
  double ssMeans = 0, ssPixels = 0, n = 0;
  for (const IaoHistogram::Bin& b : h.bins()) {
    if (b.n <= 0) continue;
    const double a = b.alpha / b.n;
    const double f = (m.hasBase ? a : 0.0) + c.linear * m.basis(a, c.nonlinear);
    const double y = meanY(b, which);
    ssMeans += b.n * (y - f) * (y - f);
    ssPixels += std::max(0.0, sumYsq(b, which) - 2.0 * f * y * b.n + b.n * f * f);
    n += b.n;
  }
  c.rmsMeans = n > 0 ? std::sqrt(ssMeans / n) : 0.0;
  c.rmsPixels = n > 0 ? std::sqrt(ssPixels / n) : 0.0;
  return n;
}

CurveFit fitCurve(const IaoHistogram& h, int which, const Model& m) {
  const double p = minimise([&](double q) { return project(h, which, m, q).ss; }, m.pLo, m.pHi);
  CurveFit c;
  c.nonlinear = p;
  c.linear = project(h, which, m, p).linear;
  c.atBound = p <= m.pLo + 1e-9 * (m.pHi - m.pLo) || p >= m.pHi - 1e-9 * (m.pHi - m.pLo);
  const double n = residuals(h, which, m, c);
  const double sigma = n > 2.0 ? c.rmsPixels * std::sqrt(n / (n - 2.0)) : std::numeric_limits<double>::infinity();
  stdErrors(h, m, c.linear, p, sigma, c.seLinear, c.seNonlinear);
  return c;
}

[[noreturn]] void fail(const std::string& path, const std::string& field, const std::string& why) {
  throw Error(path + ": " + (field.empty() ? "" : "field '" + field + "': ") + why);
}

}  // namespace

IaoHistogram::IaoHistogram(int bins) : bins_(size_t(std::max(1, bins))) {}

void IaoHistogram::add(double alpha, double y0, double y1) {
  const double a = std::clamp(alpha, 0.0, 1.0);
  const size_t k = std::min(bins_.size() - 1, size_t(a * double(bins_.size())));
  Bin& b = bins_[k];
  b.n += 1, b.alpha += a, b.y0 += y0, b.y0sq += y0 * y0, b.y1 += y1, b.y1sq += y1 * y1;
}

void IaoHistogram::merge(const IaoHistogram& o) {
  if (o.bins_.size() != bins_.size()) throw Error("internal: merging histograms of different bin counts");
  for (size_t k = 0; k < bins_.size(); ++k) {
    Bin& b = bins_[k];
    const Bin& c = o.bins_[k];
    b.n += c.n, b.alpha += c.alpha, b.y0 += c.y0, b.y0sq += c.y0sq, b.y1 += c.y1, b.y1sq += c.y1sq;
  }
}

double IaoHistogram::pixels() const {
  double n = 0;
  for (const Bin& b : bins_) n += b.n;
  return n;
}

IaoFit fitImprovedAo(const IaoHistogram& h) {
  IaoFit fit;
  fit.bins = int(h.bins().size());
  for (const IaoHistogram::Bin& b : h.bins()) fit.filledBins += b.n > 0 ? 1 : 0;
  fit.pixels = h.pixels();
  if (fit.filledBins < 3)
    throw Error("fit: the pixels fill " + std::to_string(fit.filledBins) + " of " + std::to_string(fit.bins) +
                " AO bins; at least 3 are needed to fit two coefficients per curve (a scene with more varied occlusion, "
                "a higher --res, or fewer --bins)");
  fit.f0 = fitCurve(h, 0, kF0);
  fit.f1 = fitCurve(h, 1, kF1);
  fit.coefficients = ImprovedFit{.f0Scale = fit.f0.linear, .f0Exponent = fit.f0.nonlinear, .f1A = fit.f1.linear,
                                 .f1B = fit.f1.nonlinear};
  return fit;
}

void improvedFitStdErrors(const IaoHistogram& h, const ImprovedFit& c, double sigma0, double sigma1, double se[4]) {
  stdErrors(h, kF0, c.f0Scale, c.f0Exponent, sigma0, se[0], se[1]);
  stdErrors(h, kF1, c.f1A, c.f1B, sigma1, se[2], se[3]);
}

IaoFit improvedFitResiduals(const IaoHistogram& h, const ImprovedFit& c) {
  IaoFit fit;
  fit.coefficients = c;
  fit.bins = int(h.bins().size());
  for (const IaoHistogram::Bin& b : h.bins()) fit.filledBins += b.n > 0 ? 1 : 0;
  fit.pixels = h.pixels();
  fit.f0.linear = c.f0Scale, fit.f0.nonlinear = c.f0Exponent;
  fit.f1.linear = c.f1A, fit.f1.nonlinear = c.f1B;
  residuals(h, 0, kF0, fit.f0);
  residuals(h, 1, kF1, fit.f1);
  return fit;
}

std::string improvedFitJson(const IaoFit& fit, const std::vector<std::string>& scenes, const std::string& settings) {
  // %.17g: the coefficients read back to the same doubles.
  const auto num = [](double v) {
    char t[40];
    std::snprintf(t, sizeof t, "%.17g", v);
    return std::string(t);
  };
  const auto curve = [&](const CurveFit& c, const char* lin, const char* nonlin) {
    return std::string("{\"") + lin + "\": " + num(c.seLinear) + ", \"" + nonlin + "\": " + num(c.seNonlinear) + "}";
  };
  std::ostringstream o;
  o << "{\n  \"format\": \"obscura-iao-fit\",\n  \"version\": 1,\n";
  o << "  \"F0\": {\"scale\": " << num(fit.coefficients.f0Scale) << ", \"exponent\": " << num(fit.coefficients.f0Exponent)
    << "},\n";
  o << "  \"F1\": {\"A\": " << num(fit.coefficients.f1A) << ", \"B\": " << num(fit.coefficients.f1B) << "},\n";
  o << "  \"fit\": {\n    \"scenes\": " << nlohmann::json(scenes).dump() << ",\n";
  o << "    \"settings\": " << nlohmann::json(settings).dump() << ",\n";
  o << "    \"pixels\": " << num(fit.pixels) << ", \"bins\": " << fit.bins << ", \"filled_bins\": " << fit.filledBins << ",\n";
  o << "    \"stderr\": {\"F0\": " << curve(fit.f0, "scale", "exponent") << ", \"F1\": " << curve(fit.f1, "A", "B") << "},\n";
  o << "    \"rms_of_bin_means\": {\"F0\": " << num(fit.f0.rmsMeans) << ", \"F1\": " << num(fit.f1.rmsMeans) << "},\n";
  o << "    \"rms_of_pixels\": {\"F0\": " << num(fit.f0.rmsPixels) << ", \"F1\": " << num(fit.f1.rmsPixels) << "}\n";
  o << "  }\n}\n";
  return o.str();
}

ImprovedFit readImprovedFit(const std::string& path) {
  const std::string kind = nonRegularKind(path);
  if (!kind.empty()) fail(path, "", "is " + kind + ", not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "", "cannot open the fit file (write one with 'obscura fit')");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    fail(path, "", std::string("not valid JSON (") + e.what() + ")");
  }
  if (!j.is_object()) fail(path, "", "expected a JSON object with fields F0 and F1");
  const auto number = [&](const char* curve, const char* key, double lo, double hi, bool openLo) {
    const std::string field = std::string(curve) + "." + key;
    if (!j.contains(curve) || !j[curve].is_object()) fail(path, curve, "missing (an object with the curve's coefficients)");
    const nlohmann::json& c = j[curve];
    if (!c.contains(key)) fail(path, field, "missing");
    if (!c[key].is_number()) fail(path, field, "must be a number, got " + c[key].dump());
    const double v = c[key].get<double>();
    if (!std::isfinite(v) || v < lo || v > hi || (openLo && v == lo)) {
      char t[40];
      std::snprintf(t, sizeof t, "%.17g", v);
      fail(path, field, std::string("must be ") + (openLo ? "in (" : "in [") + formatFloat(lo) + ", " + formatFloat(hi) +
                            "], got " + t);
    }
    return v;
  };
  ImprovedFit c;
  c.f0Scale = number("F0", "scale", -1.0, 1e6, false);
  c.f0Exponent = number("F0", "exponent", 0.0, 100.0, true);
  c.f1A = number("F1", "A", 0.0, 1e6, false);
  c.f1B = number("F1", "B", -1000.0, 1000.0, false);
  return c;
}

}  // namespace obscura
