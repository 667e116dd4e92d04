// The report of `obscura compare`: results.json, the error-versus-time plot
// with the Pareto front (SVG), a heat map of each config's error (PNG), a
// contact sheet of the passes (SVG over PNG previews, and one PNG), and the
// summary table on stdout.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "app/confidence.h"
#include "core/image/flip.h"
#include "core/image/metrics.h"

namespace obscura {

// One cell of a comparison (CONFIG x spp, over the seeds): what
// results.csv stores per row and what the report draws.
struct ReportCell {
  std::string key;  // hash of everything that determines the cell's images (results.csv; resumption)
  std::string config, integrator, params;
  int spp = 0, seeds = 0;  // spp: the most a pixel takes when targetError > 0
  // The config's render settings (docs/compare.md "Compare"): adaptive sampling to
  // targetError (0: fixed spp) and the denoiser; meanSpp is the samples a
  // pixel took on average (mean over seeds), denoiseSeconds the filter's
  // time (median over seeds), already inside `seconds`.
  double targetError = 0;
  int minSpp = 0;
  bool denoise = false;
  double meanSpp = 0, denoiseSeconds = 0;
  double seconds = 0;  // render loop + denoiser, median over seeds
  uint64_t rays = 0;
  ErrorMetrics error;
  // FLIP (docs/compare.md "FLIP"): LDR-FLIP of the displayed pass and
  // HDR-FLIP of the linear one, means over seeds, at flipPpd pixels per
  // degree; flipPpd 0: not measured (a row from before the FLIP columns).
  double flip = 0, flipHdr = 0, flipPpd = 0;
  std::optional<BiasVariance> bv;
  std::string pass;  // EXR relative to the report directory
  // One value per seed (empty for a cell of a results.csv from before they
  // were kept): the MSE of each render and its time. With two or more they
  // give the intervals (app/confidence.h, docs/compare.md "Uncertainty").
  std::vector<double> seedMse, seedSeconds;
  bool hasIntervals() const { return seedMse.size() >= 2 && seedSeconds.size() >= 2; }
};

// The interval of a cell's RMSE and time (hasIntervals() must hold).
struct CellIntervals {
  Interval rmse, seconds;
  double secondsConfidence = 0;  // medianRangeConfidence(seeds)
};
CellIntervals cellIntervals(const ReportCell& c);

// The error a target is of: RMSE or (LDR-)FLIP.
enum class TargetMeasure { Rmse, Flip };

// The verdict for one RMSE or FLIP target: the fastest cell reaching it
// (point estimates), the fastest cell of another config reaching it (the
// runner-up), and with intervals on both, Welch's test of their times
// (docs/compare.md "Uncertainty"): distinguishable, or a tie. Only an RMSE
// target says whether the winner's interval is below it.
struct TargetVerdict {
  double target = 0;
  std::optional<size_t> winner, runnerUp;
  std::optional<WelchResult> time;      // runner-up minus winner, seconds
  std::optional<bool> winnerSurely;     // the winner's RMSE interval is below the target
  // "distinguishable", "tie", "no runner-up", "one seed" or "not reached".
  std::string status() const;
};
TargetVerdict targetVerdict(const std::vector<ReportCell>& cells, double target,
                            TargetMeasure measure = TargetMeasure::Rmse);

struct CompareReport {
  std::string dir, scene, camera, resolution, referencePath;
  std::string lighting;  // the light and what the errors measure, one line
  // What a pass is multiplied by before it is compared (1 under a uniform
  // sky; 1 / the reference's mean radiance under an environment map).
  double passScale = 1;
  double referenceNoise = -1;  // RMSE of the reference itself; < 0: unknown
  const PassImage* reference = nullptr;
  std::vector<double> targets;  // RMSE targets, largest first
  std::vector<double> flipTargets;  // FLIP targets, largest first (may be empty)
  double flipPpd = kFlipDefaultPpd;
  std::vector<ReportCell> cells;
  // Rows results.csv keeps from earlier runs that are no cell of this one
  // (other configs or spps): listed in results.json's "keptRows" and in a
  // note line, not drawn or ranked (they may be measured against another
  // reference or view).
  std::vector<ReportCell> kept;
};

// Indices of the cells on the Pareto front of (time, RMSE): no other cell is
// both faster and at least as accurate. Sorted by time.
std::vector<size_t> paretoFront(const std::vector<ReportCell>& cells);
// For a target, the fastest cell whose error is at most it, if any.
std::optional<size_t> fastestReaching(const std::vector<ReportCell>& cells, double target,
                                      TargetMeasure measure = TargetMeasure::Rmse);

// Writes text to a temporary sibling, then renames it over path: readers
// never see half a file. Throws obscura::Error naming the path.
void writeTextAtomically(const std::filesystem::path& path, const std::string& text);

// Text with < > & " escaped for XML and HTML (text and attribute values).
std::string xmlEscape(const std::string& s);

// A name safe in a file name: [A-Za-z0-9.=-] kept, the rest '_'.
std::string safeFileName(const std::string& s);

// The heat maps' colour map: six RGB (0-255) control points evenly spaced
// over [0, 1], linearly interpolated (heatmaps/*.png and report.html).
extern const double kHeatStops[6][3];

// Writes every file of the report into report.dir; throws obscura::Error.
void writeCompareReport(const CompareReport& report);

// contact_sheet.png's grid: tiles (the reference, then each config's finest
// pass) of the pass's size, 4 pixels apart, 4 from the edges, at most 4 to
// a row; below each, after kContactSheetLabelGap blank rows, its label's two
// parts (what it is; its time and error), each wrapped to `columns`
// glyphs (app/bitmap_font.h), one line every kLineAdvance rows.
inline constexpr int kContactSheetLabelGap = 3;
struct ContactSheetLayout {
  int columns = 1;      // glyphs per label line
  int labelHeight = 0;  // rows from a tile's bottom to the next tile's gap
};
ContactSheetLayout contactSheetLayout(int tileWidth, const std::vector<std::pair<std::string, std::string>>& labels);
void printCompareSummary(const CompareReport& report, FILE* out);

}  // namespace obscura
