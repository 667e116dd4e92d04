// Adaptive sampling: how many camera samples each pixel takes, decided in
// rounds from the pixels' error estimates (docs/sampling.md "Adaptive sampling",
// docs/math.md §13).
//
// Every pixel takes the first --min-spp samples (but a background pixel,
// SampleSchedule::Phase::Survey); after each round, a pixel
// whose error estimate and the pooled (RMS) estimate of its 3 x 3
// neighbourhood are both at most the target stops (the marginal rule of a
// denoised pass: the RMS over its 5 x 5 neighbourhood, see setMarginal),
// and every other pixel is given its next samples, up to --spp. A pixel's samples are always its first n samples in sample order,
// the very samples of a fixed-spp render, so a pixel that never stops equals
// the fixed-spp render bit for bit; and the decisions read only the sums at
// round boundaries, so the image does not depend on threads or tile size.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/film.h"
#include "core/util/large_vector.h"

namespace obscura {

struct RenderSettings;

// True when s asks for rounds: a target error or a time limit.
bool adaptiveSampling(const RenderSettings& s);
// The samples of the first round: --min-spp (default min(16, spp)).
int firstRoundSpp(const RenderSettings& s);
// Throws obscura::Error naming the setting if s's adaptive settings are out
// of range.
void checkAdaptiveSettings(const RenderSettings& s);

// The survey's samples a pixel (SampleSchedule::Phase; --background-spp,
// default 4: one in each quadrant of the pixel's stratified sequence, so a
// 5 x 5 neighbourhood shows no surface only when its 25 m camera samples -
// 100 at the default - all miss); 0 when s takes no survey (no target, or not fewer
// than the first round's).
int surveySpp(const RenderSettings& s);

// SampleSchedule::next's error for a pixel without a surface (no hit yet:
// the background, exact): its neighbours do not pool it, and it goes by
// theirs.
inline constexpr float kNoSurface = -1.0f;

// The pixels' sample counts over a window (row-major within it).
class SampleSchedule {
 public:
  // With `uniformRounds` every pixel that goes on takes the round's
  // largest target: the screen-space loop's samples are whole-image
  // G-buffer layers, taken by every running pixel at once.
  SampleSchedule(const PixelRect& window, const RenderSettings& s, bool uniformRounds = false);
  size_t pixels() const { return taken_.size(); }
  // Pixel i's samples so far (before this round) and the end of this
  // round's: it takes samples [taken(i), target(i)).
  uint32_t taken(size_t i) const { return taken_[i]; }
  uint32_t target(size_t i) const { return target_[i]; }
  // The samples this round takes, in all and in rect r (image coordinates,
  // inside the window).
  uint64_t planned() const { return planned_; }
  // The largest target: the samples the round runs up to.
  uint32_t maxTarget() const { return maxTarget_; }
  // The samples the render is expected to take from this round on, this
  // round's included (for the progress bar's total and ETA, not for any
  // decision): each running pixel's own forecast, the samples its estimate
  // says it needs to reach the target (the error falling as 1/sqrt(n), as
  // next() plans, without the round's growth cap), at least this round's
  // and at most --spp; where no estimate exists yet (the survey, no target,
  // an unknown error) the most it may take, --spp.
  uint64_t expectedRemaining() const { return expected_; }
  // The most samples a pixel is expected to end with, by the same forecast
  // (a screen-space render's layers run up to it); 0 once none runs.
  uint32_t expectedMaxTarget() const { return expectedMax_; }
  uint64_t planned(const PixelRect& r) const;
  // The pixels that take samples this round (window row-major indices,
  // ascending); every other pixel's target is its samples taken.
  const LargeVector<uint32_t>& running() const { return running_; }
  // The round is done: every pixel's samples so far become its target.
  // Then, from each pixel's error (window row-major: the composited pass's
  // standard error, compositedError in core/render/pixel_sums.h; kNoSurface
  // without a surface; +inf where unknown), plans the next round and
  // returns its samples (0: finished).
  uint64_t next(const float* error);
  // What the round planned now (being taken) is. With a target error a
  // ray-traced render starts with a survey of surveySpp(s) samples a pixel:
  // a pixel with no surface within two pixels of it (every error of its
  // 5 x 5 neighbourhood kNoSurface: none of its 25 m camera samples hit)
  // is background, exact, and stops there; every other pixel then takes
  // the rest of --min-spp (FirstRound) before the rounds decide.
  enum class Phase { Survey, FirstRound, Rounds };
  Phase phase() const { return phase_; }
  // The survey's samples a pixel; 0 when this schedule takes none.
  uint32_t backgroundSpp() const { return surveySpp_; }
  // The marginal rule (a denoised pass; docs/sampling.md "Adaptive sampling"): a
  // pixel stops when error <= E sqrt(n / n0), n its samples, n0 the first
  // round's, and plans n proportional to its per-sample deviation
  // error sqrt(n): the allocation that minimizes the image's mean squared
  // error for the samples spent (docs/math.md §13), where the default rule
  // (every pixel to E) spends as a fixed-spp render would. The error it
  // decides on is the RMS over the pixel's 5 x 5 neighbourhood, with no
  // term of its own (the filter averages neighbourhoods; an own term was a
  // stopping bias): the allocation is optimal per neighbourhood, and a
  // lone pixel the filter cannot average among quiet ones (a thin
  // silhouette) may stop above the threshold.
  void setMarginal(bool on) { marginal_ = on; }
  // Drops the round just planned (the time limit): the render ends with
  // the samples taken.
  void dropPlan();
  // Samples taken over the window, and their mean per pixel.
  uint64_t total() const { return total_; }
  double meanSpp() const { return double(total_) / double(pixels()); }
  int rounds() const { return rounds_; }

 private:
  PixelRect window_;
  uint32_t spp_;
  float targetError_;
  bool uniform_;
  bool marginal_ = false;
  uint32_t firstSpp_, surveySpp_;
  Phase phase_ = Phase::FirstRound;
  // Whole-window arrays on huge pages (core/util/large_vector.h).
  LargeVector<uint32_t> taken_, target_;
  // The pixels that take samples this round (target > taken), ascending:
  // the rounds' passes are over these, not the window (late rounds run a
  // few thousand pixels of millions).
  LargeVector<uint32_t> running_;
  // Drops the pixels that reached their target from running_ (a stable
  // compaction, so the list stays ascending).
  void dropStopped();
  uint64_t planned_ = 0, total_ = 0, expected_ = 0;
  uint32_t maxTarget_ = 0, expectedMax_ = 0;
  int rounds_ = 1;
};

}  // namespace obscura
