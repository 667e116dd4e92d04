// Confidence intervals over the seeds of a `compare` cell, and the test that
// says whether a verdict's runner-up is distinguishable from its winner
// (docs/compare.md "Uncertainty"). Pure functions on plain numbers, so tests
// check them against tables, closed forms and synthetic samples.
#pragma once

#include <vector>

namespace obscura {

// The confidence level of every interval `compare` reports.
constexpr double kConfidence = 0.95;

// The Student-t distribution with `dof` > 0 degrees of freedom: its CDF
// (through the regularized incomplete beta function) and its quantile
// (the CDF inverted by bisection). Throws std::invalid_argument on dof <= 0
// or p outside (0, 1).
double studentTCdf(double t, double dof);
double studentTQuantile(double p, double dof);

struct Interval {
  double lo = 0, hi = 0;
};

// The two-sided Student-t interval of the mean of `x` (size >= 2) at level
// `confidence`: mean +- t_{(1+c)/2, n-1} * s / sqrt(n).
Interval meanInterval(const std::vector<double>& x, double confidence = kConfidence);

// The interval of a cell's RMSE from the per-seed MSEs (one per render): the
// t-interval of the mean MSE, its ends square-rooted (the square root is
// increasing, so the coverage of sqrt(E[MSE]) is that of E[MSE]); the lower
// end is clamped at 0.
Interval rmseInterval(const std::vector<double>& seedMse, double confidence = kConfidence);

// The time interval: the fastest and slowest run. For n runs with a
// continuous distribution it holds the median with probability
// 1 - 2^(1-n) (both ends on one side of the median has probability 2 * 2^-n),
// whatever the distribution: medianRangeConfidence(n).
Interval timeRange(const std::vector<double>& seconds);
double medianRangeConfidence(int n);

// Welch's two-sample t-test of mean(b) - mean(a) (unequal variances,
// Welch-Satterthwaite degrees of freedom): the interval of the difference
// at `confidence`, and whether it excludes 0. Each sample needs size >= 2.
struct WelchResult {
  double difference = 0, dof = 0;
  Interval interval;
  bool distinguishable = false;
};
WelchResult welchTest(const std::vector<double>& a, const std::vector<double>& b, double confidence = kConfidence);

}  // namespace obscura
