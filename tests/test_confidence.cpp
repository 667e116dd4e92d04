// The intervals and the verdict test of `obscura compare` (app/confidence.h,
// docs/compare.md "Uncertainty"): t quantiles against printed tables and
// closed forms, coverage of every interval on synthetic samples, and the
// per-target verdicts on cells with known times.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "app/confidence.h"
#include "app/report.h"

namespace obscura::test {
namespace {

TEST(Confidence, StudentTMatchesTheClosedForms) {
  // dof 1 is the Cauchy distribution: F(t) = 1/2 + atan(t)/pi, Q(p) = tan(pi (p - 1/2)).
  // dof 2: F(t) = 1/2 + t / (2 sqrt(2 + t^2)), Q(p) = (2p - 1) / sqrt(2 p (1 - p)).
  for (const double t : {-7.0, -1.5, -0.2, 0.0, 0.3, 1.0, 4.0, 30.0}) {
    EXPECT_NEAR(studentTCdf(t, 1), 0.5 + std::atan(t) / std::numbers::pi, 1e-12) << t;
    EXPECT_NEAR(studentTCdf(t, 2), 0.5 + t / (2 * std::sqrt(2 + t * t)), 1e-12) << t;
  }
  for (const double p : {0.01, 0.1, 0.5, 0.8, 0.975, 0.995}) {
    EXPECT_NEAR(studentTQuantile(p, 1), std::tan(std::numbers::pi * (p - 0.5)), 1e-9) << p;
    EXPECT_NEAR(studentTQuantile(p, 2), (2 * p - 1) / std::sqrt(2 * p * (1 - p)), 1e-9) << p;
  }
}

TEST(Confidence, StudentTQuantilesMatchThePrintedTable) {
  // The two-sided 95% points t_{0.975, dof} as statistics tables print them
  // (to the digits given), and the normal's 1.959964 for a large dof.
  const std::pair<double, double> table[] = {{1, 12.7062}, {2, 4.3027}, {3, 3.1824}, {4, 2.7764}, {5, 2.5706},
                                             {9, 2.2622},  {10, 2.2281}, {20, 2.0860}, {30, 2.0423}, {1e7, 1.95996}};
  for (const auto& [dof, t] : table) EXPECT_NEAR(studentTQuantile(0.975, dof), t, 6e-5) << "dof " << dof;
  // A non-integer dof (Welch's) lies between its integer neighbours.
  const double q = studentTQuantile(0.975, 5.5);
  EXPECT_LT(q, studentTQuantile(0.975, 5));
  EXPECT_GT(q, studentTQuantile(0.975, 6));
  EXPECT_THROW(studentTQuantile(0.975, 0), std::invalid_argument);
  EXPECT_THROW(studentTQuantile(1.0, 3), std::invalid_argument);
}

// The share of `trials` intervals that hold the true value is binomial:
// its standard error is sqrt(c (1 - c) / trials); 4 of them is the
// tolerance (a false failure about once in 16000 runs).
double coverageTolerance(double c, int trials) { return 4 * std::sqrt(c * (1 - c) / trials); }

TEST(Confidence, MeanIntervalCoversAtItsLevelOnNormalSamples) {
  std::mt19937_64 rng(12345);
  std::normal_distribution<double> normal(3.0, 0.7);
  const int trials = 6000;
  for (const int n : {2, 4, 8}) {
    int hits = 0;
    for (int k = 0; k < trials; ++k) {
      std::vector<double> x(static_cast<size_t>(n));
      for (double& v : x) v = normal(rng);
      const Interval i = meanInterval(x);
      hits += i.lo <= 3.0 && 3.0 <= i.hi;
    }
    EXPECT_NEAR(double(hits) / trials, kConfidence, coverageTolerance(kConfidence, trials)) << "n " << n;
  }
}

TEST(Confidence, RmseIntervalIsTheMseIntervalSquareRooted) {
  const std::vector<double> mse = {0.04, 0.05, 0.03, 0.045};
  const Interval m = meanInterval(mse), r = rmseInterval(mse);
  EXPECT_DOUBLE_EQ(r.lo, std::sqrt(m.lo));
  EXPECT_DOUBLE_EQ(r.hi, std::sqrt(m.hi));
  // A lower end below 0 (two far-apart seeds) is clamped, not NaN.
  const Interval wide = rmseInterval({0.001, 0.2});
  EXPECT_EQ(wide.lo, 0.0);
  EXPECT_GT(wide.hi, std::sqrt(0.2));
}

TEST(Confidence, TimeRangeHoldsTheMedianAtItsStatedLevel) {
  // Skewed times (exponential, median ln 2): the min-max range of n runs
  // holds the median with probability 1 - 2^(1-n) whatever the distribution.
  std::mt19937_64 rng(777);
  std::exponential_distribution<double> expo(1.0);
  const int trials = 6000;
  for (const int n : {2, 3, 5}) {
    const double c = medianRangeConfidence(n);
    EXPECT_DOUBLE_EQ(c, 1 - std::pow(0.5, n - 1));
    int hits = 0;
    for (int k = 0; k < trials; ++k) {
      std::vector<double> x(static_cast<size_t>(n));
      for (double& v : x) v = expo(rng);
      const Interval i = timeRange(x);
      hits += i.lo <= std::log(2.0) && std::log(2.0) <= i.hi;
    }
    EXPECT_NEAR(double(hits) / trials, c, coverageTolerance(c, trials)) << "n " << n;
  }
}

TEST(Confidence, WelchDegreesOfFreedomByHand) {
  // a = 1,2,3,4: mean 2.5, s^2 = 5/3, s^2/n = 5/12; b = 2,4,...,10: mean 6,
  // s^2 = 10, s^2/n = 2. dof = (5/12 + 2)^2 / ((5/12)^2/3 + 2^2/4)
  //   = (29/12)^2 / (25/432 + 1) = (841/144) / (457/432) = 2523/457.
  const WelchResult w = welchTest({1, 2, 3, 4}, {2, 4, 6, 8, 10});
  EXPECT_DOUBLE_EQ(w.difference, 3.5);
  EXPECT_NEAR(w.dof, 2523.0 / 457.0, 1e-12);
  const double half = studentTQuantile(0.975, 2523.0 / 457.0) * std::sqrt(29.0 / 12.0);
  EXPECT_NEAR(w.interval.lo, 3.5 - half, 1e-12);
  EXPECT_NEAR(w.interval.hi, 3.5 + half, 1e-12);
  EXPECT_EQ(w.distinguishable, w.interval.lo > 0);
  // Constant samples: the difference is exact.
  const WelchResult c = welchTest({1, 1}, {2, 2});
  EXPECT_TRUE(c.distinguishable);
  EXPECT_FALSE(welchTest({1, 1}, {1, 1}).distinguishable);
}

TEST(Confidence, WelchFalseAlarmRateIsOneMinusTheLevel) {
  // Equal means, unequal variances and sizes: Welch's test calls them
  // distinguishable in about 5% of trials (exact for normal samples up to
  // the Satterthwaite approximation, which is good to well under a point).
  std::mt19937_64 rng(4242);
  std::normal_distribution<double> narrow(1.0, 0.2), wide(1.0, 0.6);
  const int trials = 6000;
  int alarms = 0;
  for (int k = 0; k < trials; ++k) {
    std::vector<double> a(4), b(6);
    for (double& v : a) v = narrow(rng);
    for (double& v : b) v = wide(rng);
    alarms += welchTest(a, b).distinguishable;
  }
  EXPECT_NEAR(double(alarms) / trials, 1 - kConfidence, coverageTolerance(1 - kConfidence, trials));
}

ReportCell timedCell(const std::string& config, int spp, double rmse, std::vector<double> seconds) {
  ReportCell c;
  c.config = config, c.spp = spp, c.error.rmse = rmse, c.seeds = int(seconds.size());
  c.seedSeconds = seconds;
  c.seedMse.assign(seconds.size(), rmse * rmse);
  std::vector<double> s = seconds;
  std::sort(s.begin(), s.end());
  c.seconds = s[s.size() / 2];
  return c;
}

TEST(CompareVerdict, RunnerUpIsAnotherConfigAndTiesAreCalled) {
  std::vector<ReportCell> cells = {timedCell("ao", 4, 0.05, {1.00, 1.01, 0.99}),
                                   timedCell("ao", 16, 0.04, {1.50, 1.52, 1.49}),
                                   timedCell("transfer", 4, 0.03, {2.00, 2.02, 1.98})};
  TargetVerdict v = targetVerdict(cells, 0.06);
  ASSERT_TRUE(v.winner && v.runnerUp);
  EXPECT_EQ(*v.winner, 0u);
  EXPECT_EQ(*v.runnerUp, 2u);  // not ao@16: the same config
  EXPECT_EQ(v.status(), "distinguishable");
  EXPECT_EQ(v.winnerSurely, std::optional<bool>(true));
  // A runner-up whose runs overlap the winner's: a tie.
  cells[2] = timedCell("transfer", 4, 0.03, {0.9, 1.3, 1.05});
  EXPECT_EQ(targetVerdict(cells, 0.06).status(), "tie");
  // One seed: no confidence; nobody else reaching it: no runner-up.
  EXPECT_EQ(targetVerdict({timedCell("ao", 4, 0.05, {1.0}), timedCell("gi", 4, 0.01, {3.0})}, 0.06).status(),
            "one seed");
  EXPECT_EQ(targetVerdict(cells, 0.035).status(), "no runner-up");
  EXPECT_EQ(targetVerdict(cells, 0.001).status(), "not reached");
}

}  // namespace
}  // namespace obscura::test
