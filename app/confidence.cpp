#include "app/confidence.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace obscura {
namespace {

// The continued fraction of the regularized incomplete beta function
// (DLMF 8.17.22): I_x(a,b) = x^a (1-x)^b / (a B(a,b)) * 1/(1+ d1/(1+ d2/(1+ ...))),
//   d_{2m+1} = -(a+m)(a+b+m) x / ((a+2m)(a+2m+1)),  d_{2m} = m(b-m) x / ((a+2m-1)(a+2m)),
// evaluated with the modified Lentz method. It converges fast for
// x < (a+1)/(a+b+2); the caller uses I_x(a,b) = 1 - I_{1-x}(b,a) otherwise.
double betaFraction(double a, double b, double x) {
  constexpr double tiny = 1e-300, eps = 1e-15;
  double f = tiny, c = f, d = 0;
  for (int n = 0; n < 2000; ++n) {
    double dn;  // the n-th partial numerator; d_0 = 1
    if (n == 0) {
      dn = 1;
    } else if (n % 2 == 1) {
      const double m = (n - 1) / 2;
      dn = -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1));
    } else {
      const double m = n / 2;
      dn = m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m));
    }
    d = 1 + dn * d;
    d = std::abs(d) < tiny ? tiny : d;
    c = 1 + dn / c;
    c = std::abs(c) < tiny ? tiny : c;
    d = 1 / d;
    const double delta = c * d;
    f *= delta;
    if (n > 0 && std::abs(delta - 1) < eps) break;
  }
  // f approximates 1/(1 + d1/(1 + ...)) up to the leading d_0 = 1 term.
  return f;
}

double regularizedBeta(double a, double b, double x) {
  if (x <= 0) return 0;
  if (x >= 1) return 1;
  const double lnFront = a * std::log(x) + b * std::log1p(-x) - (std::lgamma(a) + std::lgamma(b) - std::lgamma(a + b));
  if (x < (a + 1) / (a + b + 2)) return std::exp(lnFront) / a * betaFraction(a, b, x);
  return 1 - std::exp(lnFront) / b * betaFraction(b, a, 1 - x);
}

double mean(const std::vector<double>& x) {
  double s = 0;
  for (const double v : x) s += v;
  return s / double(x.size());
}

// The unbiased sample variance (n - 1 in the denominator).
double sampleVariance(const std::vector<double>& x) {
  const double m = mean(x);
  double s = 0;
  for (const double v : x) s += (v - m) * (v - m);
  return s / double(x.size() - 1);
}

void needTwo(const std::vector<double>& x, const char* what) {
  if (x.size() < 2) throw std::invalid_argument(std::string(what) + ": needs at least two values");
}

}  // namespace

double studentTCdf(double t, double dof) {
  if (!(dof > 0)) throw std::invalid_argument("studentTCdf: dof must be positive");
  if (std::isinf(t)) return t > 0 ? 1 : 0;
  // P(|T| > |t|) = I_{dof/(dof+t^2)}(dof/2, 1/2).
  const double tail = 0.5 * regularizedBeta(dof / 2, 0.5, dof / (dof + t * t));
  return t > 0 ? 1 - tail : tail;
}

double studentTQuantile(double p, double dof) {
  if (!(dof > 0)) throw std::invalid_argument("studentTQuantile: dof must be positive");
  if (!(p > 0 && p < 1)) throw std::invalid_argument("studentTQuantile: p must be in (0, 1)");
  if (p < 0.5) return -studentTQuantile(1 - p, dof);
  if (p == 0.5) return 0;
  // The CDF is increasing: bracket, then bisect to the last bit.
  double lo = 0, hi = 1;
  while (studentTCdf(hi, dof) < p) hi *= 2;
  for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (studentTCdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Interval meanInterval(const std::vector<double>& x, double confidence) {
  needTwo(x, "meanInterval");
  const double n = double(x.size()), m = mean(x);
  const double half = studentTQuantile(0.5 + confidence / 2, n - 1) * std::sqrt(sampleVariance(x) / n);
  return {m - half, m + half};
}

Interval rmseInterval(const std::vector<double>& seedMse, double confidence) {
  const Interval mse = meanInterval(seedMse, confidence);
  return {std::sqrt(std::max(mse.lo, 0.0)), std::sqrt(std::max(mse.hi, 0.0))};
}

Interval timeRange(const std::vector<double>& seconds) {
  needTwo(seconds, "timeRange");
  const auto [lo, hi] = std::minmax_element(seconds.begin(), seconds.end());
  return {*lo, *hi};
}

double medianRangeConfidence(int n) { return n < 2 ? 0 : 1 - std::ldexp(1.0, 1 - n); }

WelchResult welchTest(const std::vector<double>& a, const std::vector<double>& b, double confidence) {
  needTwo(a, "welchTest");
  needTwo(b, "welchTest");
  WelchResult r;
  const double na = double(a.size()), nb = double(b.size());
  const double va = sampleVariance(a) / na, vb = sampleVariance(b) / nb;
  r.difference = mean(b) - mean(a);
  const double se2 = va + vb;
  if (!(se2 > 0)) {  // both samples constant: the difference is exact
    r.dof = std::numeric_limits<double>::infinity();
    r.interval = {r.difference, r.difference};
    r.distinguishable = r.difference != 0;
    return r;
  }
  // Welch-Satterthwaite: (va + vb)^2 / (va^2/(na-1) + vb^2/(nb-1)).
  r.dof = se2 * se2 / (va * va / (na - 1) + vb * vb / (nb - 1));
  const double half = studentTQuantile(0.5 + confidence / 2, r.dof) * std::sqrt(se2);
  r.interval = {r.difference - half, r.difference + half};
  r.distinguishable = r.interval.lo > 0 || r.interval.hi < 0;
  return r;
}

}  // namespace obscura
