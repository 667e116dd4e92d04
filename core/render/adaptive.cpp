#include "core/render/adaptive.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include <obscura/error.h>
#include "core/render/render.h"
#include "core/util/option_names.h"

namespace obscura {

namespace {
// The first round's samples when --min-spp is not given: enough for the
// two halves' error estimate to mean something (8 samples each), few enough
// that an open floor converged after a handful wastes little.
constexpr int kDefaultMinSpp = 16;
// The next round aims this factor below the target (docs/math.md §13):
// a pixel stops at the first round whose estimate is below the target, so
// aiming at the target itself left the realized error above it (measured:
// 1.0 E on the viking room, 1.06 E in a simulation of the rule; with 1.1,
// 0.95 E and 1.02 E, for 8 % more samples).
constexpr double kAim = 1.1;
// Pixels per task of the schedule's passes (over the window at set-up, over
// the running list after).
constexpr size_t kChunk = size_t(1) << 15;
}  // namespace

bool adaptiveSampling(const RenderSettings& s) { return s.targetError > 0.0f || s.timeLimit > 0.0; }

int firstRoundSpp(const RenderSettings& s) { return std::min(s.spp, s.minSpp > 0 ? s.minSpp : kDefaultMinSpp); }

// The survey needs a target (without one a pixel without a surface is not
// taken as exact: --time-limit alone renders every pixel towards --spp).
int surveySpp(const RenderSettings& s) {
  return s.targetError > 0.0f && s.backgroundSpp > 0 && s.backgroundSpp < firstRoundSpp(s) ? s.backgroundSpp : 0;
}

void checkAdaptiveSettings(const RenderSettings& s) {
  if (!(s.targetError >= 0.0f) || !std::isfinite(s.targetError))
    throw Error(settingName(Setting::TargetError) + " must be a finite standard error >= 0 (0: off)");
  if (!(s.timeLimit >= 0.0) || !std::isfinite(s.timeLimit))
    throw Error(settingName(Setting::TimeLimit) + " must be a finite number of seconds >= 0 (0: none)");
  if (s.minSpp < 0) throw Error(settingName(Setting::MinSpp) + " must be at least 1");
  if (s.backgroundSpp < 0)
    throw Error(settingName(Setting::BackgroundSpp) + " must be >= 0 (0: every pixel takes " +
                settingName(Setting::MinSpp) + ")");
  if (s.minSpp > s.spp)
    throw Error(settingName(Setting::MinSpp) + " (" + std::to_string(s.minSpp) + ") exceeds " +
                settingName(Setting::Spp) + " (" + std::to_string(s.spp) + "), the most samples a pixel takes");
  if (s.minSpp > 0 && !adaptiveSampling(s))
    throw Error(settingName(Setting::MinSpp) + " needs " + settingName(Setting::TargetError) + " or " +
                settingName(Setting::TimeLimit) + " (without them every pixel takes " + settingName(Setting::Spp) +
                " samples)");
}

SampleSchedule::SampleSchedule(const PixelRect& window, const RenderSettings& s, bool uniformRounds)
    : window_(window), spp_(uint32_t(s.spp)), targetError_(s.targetError), uniform_(uniformRounds),
      firstSpp_(uint32_t(firstRoundSpp(s))), surveySpp_(uint32_t(surveySpp(s))) {
  // The running list holds 32-bit pixel indices, 0 ... 2^32 - 1 (--res
  // allows 65536 x 65536, exactly 2^32 pixels; the index arithmetic of
  // next() stays below that too).
  if (window.size() > (size_t(1) << 32))
    throw Error("adaptive sampling: a window of " + std::to_string(window.size()) + " pixels (at most 2^32)");
  // The survey needs per-pixel rounds too (a screen-space round is whole
  // layers).
  if (uniform_) surveySpp_ = 0;
  if (surveySpp_ > 0) phase_ = Phase::Survey;
  const uint32_t first = phase_ == Phase::Survey ? surveySpp_ : firstSpp_;
  parallelFill(taken_, window.size(), 0U);
  parallelFill(target_, window.size(), first);
  running_.resize(window.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, running_.size(), kChunk), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) running_[i] = uint32_t(i);
  });
  planned_ = uint64_t(window.size()) * uint64_t(first);
  expected_ = uint64_t(window.size()) * uint64_t(spp_);  // nothing known yet
  expectedMax_ = spp_;
  maxTarget_ = first;
}

uint64_t SampleSchedule::planned(const PixelRect& r) const {
  uint64_t n = 0;
  for (int y = r.y0; y < r.y1; ++y) {
    const size_t row = window_.offset(r.x0, y);
    for (int x = 0; x < r.width(); ++x) n += target_[row + size_t(x)] - taken_[row + size_t(x)];
  }
  return n;
}

void SampleSchedule::dropPlan() {
  if (planned_) --rounds_;
  for (const uint32_t i : running_) target_[i] = taken_[i];
  running_.clear();
  planned_ = expected_ = 0;
  maxTarget_ = expectedMax_ = 0;
}

void SampleSchedule::dropStopped() {
  running_.resize(size_t(
      std::remove_if(running_.begin(), running_.end(), [&](uint32_t i) { return target_[i] == taken_[i]; }) -
      running_.begin()));
}

uint64_t SampleSchedule::next(const float* error) {
  // The round just taken: its samples into the total, and every running
  // pixel's target becomes its samples taken (the others' already are). In
  // parallel over the running list (a 1080p window is 2 M pixels in the
  // first round, a few thousand in the last); integer sums, so the same
  // total whatever the split.
  total_ += tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, running_.size(), kChunk), uint64_t(0),
      [&](const tbb::blocked_range<size_t>& r, uint64_t sum) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
          const uint32_t i = running_[k];
          sum += target_[i] - taken_[i], taken_[i] = target_[i];
        }
        return sum;
      },
      std::plus<uint64_t>());
  const int w = window_.width(), h = window_.height();
  if (phase_ == Phase::Survey) {
    // The survey's decision: background where no sample of the 5 x 5
    // neighbourhood hit a surface (docs/sampling.md "Adaptive sampling": a thin
    // feature all 25 m samples missed - 100 at the default m = 4 - is missed
    // by this render); every other pixel takes the rest of its first round.
    phase_ = Phase::FirstRound;
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        bool surface = false;
        for (int v = std::max(0, y - 2); v <= std::min(h - 1, y + 2) && !surface; ++v)
          for (int u = std::max(0, x - 2); u <= std::min(w - 1, x + 2); ++u)
            if (error[size_t(v) * size_t(w) + size_t(u)] != kNoSurface) {
              surface = true;
              break;
            }
        if (surface) target_[size_t(y) * size_t(w) + size_t(x)] = firstSpp_;
      }
    });
    // Every pixel ran the survey: the running list is the window in order,
    // and keeps the pixels that go on, in order.
    dropStopped();
    planned_ = uint64_t(running_.size()) * uint64_t(firstSpp_ - surveySpp_);
    expected_ = uint64_t(running_.size()) * uint64_t(spp_ - surveySpp_);  // no estimate yet
    maxTarget_ = planned_ ? firstSpp_ : 0;
    expectedMax_ = planned_ ? spp_ : 0;
    if (planned_) ++rounds_;
    return planned_;
  }
  phase_ = Phase::Rounds;
  // The pixel's decision error (docs/math.md §13). The per-pixel rule: the
  // larger of its own estimate and the RMS of the estimates over its 3 x 3
  // neighbourhood's surface pixels. One estimate has one degree of freedom
  // (it is near 0 a few times in a hundred); the neighbours share the
  // pixel's variance, and their pooled mean square has about nine, so a
  // lucky pixel does not stop while its neighbourhood is noisy. The pixel's
  // own estimate keeps a noisy pixel among quiet ones going. The largest of
  // the nine (the rule before) stopped pixels at 0.6 of the target: the
  // maximum of nine noisy estimates sits well above their typical value.
  //
  // The marginal rule (a denoised pass): the RMS over the 5 x 5
  // neighbourhood, without the own term. The filter averages each pixel
  // with its neighbours, so what its samples buy is the neighbourhood's;
  // and a stop decided on the pixel's own estimate favours pixels whose
  // halves agree by chance, which correlates with the value itself (for
  // AO, visibility near 0 or 1): the filter spreads that shift instead of
  // averaging it away. Measured (generated scene, ao, 1080p, E = 0.005): the
  // per-pixel decision gave RMSE 0.01044 at 25.84 mean spp with a mean
  // signed error of +0.00063 against the reference; this one 0.00838 at
  // 24.74 spp, +0.00010 (without the own term, 3 x 3: 0.00860 at 23.76;
  // 7 x 7: 0.00833 at 25.43; 11 x 11: 0.00831 at 26.50 - the same trade;
  // 7 x 7 with it: 0.00968 at 27.76).
  const int radius = marginal_ ? 2 : 1;
  const bool ownTerm = !marginal_;
  const auto decisionError = [&](uint32_t i) {
    const int y = int(i / uint32_t(w)), x = int(i - uint32_t(y) * uint32_t(w));
    double sq = 0;
    int k = 0;
    for (int v = std::max(0, y - radius); v <= std::min(h - 1, y + radius); ++v)
      for (int u = std::max(0, x - radius); u <= std::min(w - 1, x + radius); ++u)
        if (const double e = error[size_t(v) * size_t(w) + size_t(u)]; e != double(kNoSurface)) sq += e * e, ++k;
    // A pixel without a surface (yet) goes by its surface neighbours: a
    // sliver of coverage it has not hit may be there.
    const float own = ownTerm ? std::max(0.0f, error[i]) : 0.0f;
    return std::max(own, k ? float(std::sqrt(sq / k)) : 0.0f);
  };
  // Each running pixel either stops (its target stays its samples taken)
  // or takes the samples its estimate says it needs - the error falls as
  // 1/sqrt(n), so n (d/E)^2, aimed at E / kAim so that a pixel whose
  // estimate was low is usually done after the next round - but at least
  // one and at most half again what it has: the estimate is noisy, and a
  // round that overshoots cannot be taken back. Stopped pixels are never
  // read again. Per pixel, independent of the others (the errors are the
  // round's, read only): in parallel, with the planned samples summed and
  // the largest target found (exact, any split).
  struct Plan {
    uint64_t planned = 0, expected = 0;
    uint32_t maxTarget = 0, maxExpected = 0;
  };
  const Plan plan = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, running_.size(), kChunk / 8), Plan{},
      [&](const tbb::blocked_range<size_t>& r, Plan acc) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
          const uint32_t i = running_[k];
          const uint32_t n = taken_[i];
          if (n >= spp_) continue;
          const float d = decisionError(i);
          // The marginal rule's threshold grows with the samples taken: the
          // error a sample more removes, d^2 / n, is what every pixel is stopped at.
          const double threshold =
              marginal_ ? double(targetError_) * std::sqrt(double(n) / double(firstSpp_)) : double(targetError_);
          if (targetError_ > 0.0f && double(d) <= threshold) continue;
          const double grow = std::max(1.0, std::floor(double(n) * 0.5));
          // What the estimate asks for (the most there is without one).
          double need = double(spp_);
          if (targetError_ > 0.0f && std::isfinite(d)) {
            if (marginal_) {
              // n' = d sqrt(n) sqrt(n0) / E: the deviation over the threshold's
              // scale, aimed kAim beyond it.
              need = std::ceil(double(d) * std::sqrt(double(n) * double(firstSpp_)) / double(targetError_) * kAim);
            } else {
              const double ratio = double(d) / double(targetError_) * kAim;
              need = std::ceil(double(n) * ratio * ratio);
            }
          }
          need = std::max(need, double(n) + 1.0);
          const double want = std::min(double(n) + grow, need);
          target_[i] = uint32_t(std::min(double(spp_), want));
          acc.planned += target_[i] - n;
          const uint32_t expected = uint32_t(std::min(double(spp_), need));
          acc.expected += expected - n;
          acc.maxExpected = std::max(acc.maxExpected, expected);
          acc.maxTarget = std::max(acc.maxTarget, target_[i]);
        }
        return acc;
      },
      [](Plan a, Plan b) {
        return Plan{a.planned + b.planned, a.expected + b.expected, std::max(a.maxTarget, b.maxTarget),
                    std::max(a.maxExpected, b.maxExpected)};
      });
  // The pixels that go on, in order.
  dropStopped();
  uint64_t planned = plan.planned;
  maxTarget_ = plan.maxTarget;
  expectedMax_ = std::max(plan.maxExpected, maxTarget_);
  expected_ = plan.expected;
  if (uniform_) {
    // Every running pixel takes the round's largest target, and is
    // expected to go on to the largest forecast.
    planned = expected_ = 0;
    for (const uint32_t i : running_)
      target_[i] = maxTarget_, planned += maxTarget_ - taken_[i], expected_ += expectedMax_ - taken_[i];
  }
  planned_ = planned;
  if (planned) ++rounds_;
  return planned;
}

}  // namespace obscura
