#include "app/report.h"

#include "app/bitmap_font.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include <obscura/error.h>
#include "app/report_html.h"
#include "core/image/image_io.h"

namespace obscura {
namespace fs = std::filesystem;

void writeTextAtomically(const fs::path& path, const std::string& text) { writeTextFile(path.string(), text); }

std::string safeFileName(const std::string& s) {
  std::string out;
  for (const char c : s)
    out += (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '=' || c == '-') ? c : '_';
  return out;
}

std::vector<size_t> paretoFront(const std::vector<ReportCell>& cells) {
  std::vector<size_t> order(cells.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t x, size_t y) {
    if (cells[x].seconds != cells[y].seconds) return cells[x].seconds < cells[y].seconds;
    return cells[x].error.rmse < cells[y].error.rmse;
  });
  std::vector<size_t> front;
  double best = INFINITY;
  for (const size_t i : order)
    if (cells[i].error.rmse < best) {
      front.push_back(i);
      best = cells[i].error.rmse;
    }
  return front;
}

std::optional<size_t> fastestReaching(const std::vector<ReportCell>& cells, double target, TargetMeasure measure) {
  std::optional<size_t> best;
  for (size_t i = 0; i < cells.size(); ++i) {
    const double e = measure == TargetMeasure::Rmse ? cells[i].error.rmse : cells[i].flip;
    if (e <= target && (!best || cells[i].seconds < cells[*best].seconds)) best = i;
  }
  return best;
}

std::string xmlEscape(const std::string& s) {
  std::string o;
  for (const char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

// A perceptually ordered dark-to-bright map (magma-like control points),
// evenly spaced over [0, 1].
const double kHeatStops[6][3] = {{0, 0, 4}, {59, 15, 112}, {140, 41, 129}, {222, 73, 104}, {254, 159, 109}, {252, 253, 191}};

CellIntervals cellIntervals(const ReportCell& c) {
  return {rmseInterval(c.seedMse), timeRange(c.seedSeconds), medianRangeConfidence(int(c.seedSeconds.size()))};
}

TargetVerdict targetVerdict(const std::vector<ReportCell>& cells, double target, TargetMeasure measure) {
  TargetVerdict v;
  v.target = target;
  v.winner = fastestReaching(cells, target, measure);
  if (!v.winner) return v;
  const ReportCell& w = cells[*v.winner];
  const auto error = [&](const ReportCell& c) { return measure == TargetMeasure::Rmse ? c.error.rmse : c.flip; };
  // The runner-up is another config: the same config at another spp is the
  // same choice, only at another sample count.
  for (size_t i = 0; i < cells.size(); ++i)
    if (cells[i].config != w.config && error(cells[i]) <= target &&
        (!v.runnerUp || cells[i].seconds < cells[*v.runnerUp].seconds))
      v.runnerUp = i;
  // Only RMSE has an interval (FLIP keeps no per-seed values).
  if (measure == TargetMeasure::Rmse && w.hasIntervals()) v.winnerSurely = cellIntervals(w).rmse.hi <= target;
  if (v.runnerUp && w.hasIntervals() && cells[*v.runnerUp].hasIntervals())
    v.time = welchTest(w.seedSeconds, cells[*v.runnerUp].seedSeconds);
  return v;
}

std::string TargetVerdict::status() const {
  if (!winner) return "not reached";
  if (!runnerUp) return "no runner-up";
  if (!time) return "one seed";
  return time->distinguishable ? "distinguishable" : "tie";
}

namespace {



std::string num(double v, int digits = 3) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// Distinguishable line colours (Okabe-Ito, then a few more).
const char* kPalette[] = {"#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9",
                          "#F0E442", "#8C564B", "#7F3C8D", "#11A579", "#3969AC", "#F2B701"};

// Cells grouped by config, in first-appearance order, each by spp.
std::vector<std::pair<std::string, std::vector<size_t>>> byConfig(const std::vector<ReportCell>& cells) {
  std::vector<std::pair<std::string, std::vector<size_t>>> groups;
  for (size_t i = 0; i < cells.size(); ++i) {
    auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == cells[i].config; });
    if (it == groups.end()) {
      groups.push_back({cells[i].config, {}});
      it = groups.end() - 1;
    }
    it->second.push_back(i);
  }
  for (auto& g : groups)
    std::sort(g.second.begin(), g.second.end(), [&](size_t x, size_t y) { return cells[x].spp < cells[y].spp; });
  return groups;
}

// Log-scale axis: the decades (and 2, 5 between them when the range is
// short) inside [lo, hi], as values.
std::vector<double> logTicks(double lo, double hi) {
  std::vector<double> t;
  const bool fine = std::log10(hi / lo) < 2.5;
  for (int e = int(std::floor(std::log10(lo))); e <= int(std::ceil(std::log10(hi))); ++e)
    for (const double m : {1.0, 2.0, 5.0}) {
      if (!fine && m != 1.0) continue;
      const double v = m * std::pow(10.0, e);
      if (v >= lo * 0.999 && v <= hi * 1.001) t.push_back(v);
    }
  return t;
}

std::string errorVersusTimeSvg(const CompareReport& r) {
  const std::vector<ReportCell>& cells = r.cells;
  double tLo = INFINITY, tHi = 0, eLo = INFINITY, eHi = 0;
  for (const ReportCell& c : cells) {
    const double t = std::max(c.seconds, 1e-6), e = std::max(c.error.rmse, 1e-9);
    tLo = std::min(tLo, t), tHi = std::max(tHi, t), eLo = std::min(eLo, e), eHi = std::max(eHi, e);
    if (c.hasIntervals()) {  // the error bars fit too
      const CellIntervals ci = cellIntervals(c);
      tLo = std::min(tLo, std::max(ci.seconds.lo, 1e-6)), tHi = std::max(tHi, ci.seconds.hi);
      eLo = std::min(eLo, std::max(ci.rmse.lo, e / 10)), eHi = std::max(eHi, ci.rmse.hi);
    }
  }
  if (r.referenceNoise > 0) eLo = std::min(eLo, r.referenceNoise), eHi = std::max(eHi, r.referenceNoise);
  // Pad to at least a factor of 2 and by 15% (in log) on each side.
  const auto pad = [](double& lo, double& hi) {
    if (hi / lo < 2.0) {
      const double m = std::sqrt(lo * hi);
      lo = m / std::sqrt(2.0), hi = m * std::sqrt(2.0);
    }
    const double k = std::pow(hi / lo, 0.15);
    lo /= k, hi *= k;
  };
  pad(tLo, tHi);
  pad(eLo, eHi);
  const double W = 900, H = 560, L = 80, R = 280, T = 40, B = 60;
  const auto X = [&](double t) { return L + (W - L - R) * std::log(t / tLo) / std::log(tHi / tLo); };
  const auto Y = [&](double e) { return H - B - (H - T - B) * std::log(e / eLo) / std::log(eHi / eLo); };
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s << "<text x=\"" << L << "\" y=\"24\" font-size=\"15\">Error against the GI reference vs render time ("
    << xmlEscape(fs::path(r.scene).filename().string()) << ", " << xmlEscape(r.resolution) << ")</text>\n";
  // Axes and grid.
  for (const double t : logTicks(tLo, tHi))
    s << "<line x1=\"" << X(t) << "\" y1=\"" << T << "\" x2=\"" << X(t) << "\" y2=\"" << H - B
      << "\" stroke=\"#ddd\"/><text x=\"" << X(t) << "\" y=\"" << H - B + 16 << "\" text-anchor=\"middle\">" << num(t)
      << "</text>\n";
  for (const double e : logTicks(eLo, eHi))
    s << "<line x1=\"" << L << "\" y1=\"" << Y(e) << "\" x2=\"" << W - R << "\" y2=\"" << Y(e)
      << "\" stroke=\"#ddd\"/><text x=\"" << L - 6 << "\" y=\"" << Y(e) + 4 << "\" text-anchor=\"end\">" << num(e)
      << "</text>\n";
  s << "<rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W - L - R << "\" height=\"" << H - T - B
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  s << "<text x=\"" << (L + W - R) / 2 << "\" y=\"" << H - 18 << "\" text-anchor=\"middle\">render time, s (log)</text>\n";
  s << "<text transform=\"translate(18," << (T + H - B) / 2 << ") rotate(-90)\" text-anchor=\"middle\">RMSE of W (log)</text>\n";
  if (r.referenceNoise > 0)
    s << "<line x1=\"" << L << "\" y1=\"" << Y(r.referenceNoise) << "\" x2=\"" << W - R << "\" y2=\"" << Y(r.referenceNoise)
      << "\" stroke=\"#888\" stroke-dasharray=\"2,3\"/><text x=\"" << W - R - 4 << "\" y=\"" << Y(r.referenceNoise) - 4
      << "\" text-anchor=\"end\" fill=\"#666\">reference noise " << num(r.referenceNoise) << "</text>\n";
  // One curve per config, points labelled with spp.
  const auto groups = byConfig(cells);
  for (size_t g = 0; g < groups.size(); ++g) {
    const char* colour = kPalette[g % (sizeof kPalette / sizeof *kPalette)];
    std::string pts;
    for (const size_t i : groups[g].second)
      pts += num(X(std::max(cells[i].seconds, 1e-6)), 6) + "," + num(Y(std::max(cells[i].error.rmse, 1e-9)), 6) + " ";
    s << "<polyline points=\"" << pts << "\" fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"2\"/>\n";
    for (const size_t i : groups[g].second) {
      const ReportCell& c = cells[i];
      const double x = X(std::max(c.seconds, 1e-6)), y = Y(std::max(c.error.rmse, 1e-9));
      std::string ci;
      if (c.hasIntervals()) {
        // Error bars: the RMSE's t-interval (vertical; a lower end of 0 is
        // drawn at a tenth of the point: the axis is logarithmic) and the
        // time's range over the seeds (horizontal).
        const CellIntervals iv = cellIntervals(c);
        const double y0 = Y(std::max(iv.rmse.lo, std::max(c.error.rmse, 1e-9) / 10)), y1 = Y(std::max(iv.rmse.hi, 1e-9));
        const double x0 = X(std::max(iv.seconds.lo, 1e-6)), x1 = X(std::max(iv.seconds.hi, 1e-6));
        s << "<path class=\"errbar\" d=\"M" << x << "," << y0 << "V" << y1 << "M" << x - 3 << "," << y0 << "h6M" << x - 3
          << "," << y1 << "h6M" << x0 << "," << y << "H" << x1 << "M" << x0 << "," << y - 3 << "v6M" << x1 << "," << y - 3
          << "v6\" stroke=\"" << colour << "\" stroke-width=\"1\" fill=\"none\" opacity=\"0.7\"/>\n";
        ci = " (95% CI " + num(iv.rmse.lo) + "-" + num(iv.rmse.hi) + "), time range " + num(iv.seconds.lo) + "-" +
             num(iv.seconds.hi) + " s";
      }
      s << "<circle class=\"pt\" data-cell=\"" << i << "\" cx=\"" << x << "\" cy=\"" << y << "\" r=\"3.5\" fill=\"" << colour
        << "\"><title>" << xmlEscape(c.config) << " @ " << c.spp << " spp: " << num(c.seconds) << " s, RMSE "
        << num(c.error.rmse) << xmlEscape(ci) << "</title></circle><text x=\"" << x + 5 << "\" y=\"" << y - 5
        << "\" font-size=\"9\" fill=\"" << colour << "\">" << cells[i].spp << "</text>\n";
    }
    const double ly = T + 10 + 18 * double(g);
    s << "<line x1=\"" << W - R + 14 << "\" y1=\"" << ly << "\" x2=\"" << W - R + 38 << "\" y2=\"" << ly << "\" stroke=\""
      << colour << "\" stroke-width=\"2\"/><text x=\"" << W - R + 44 << "\" y=\"" << ly + 4 << "\">"
      << xmlEscape(groups[g].first) << "</text>\n";
  }
  // The Pareto front.
  std::string front;
  for (const size_t i : paretoFront(cells))
    front += num(X(std::max(cells[i].seconds, 1e-6)), 6) + "," + num(Y(std::max(cells[i].error.rmse, 1e-9)), 6) + " ";
  s << "<polyline points=\"" << front << "\" fill=\"none\" stroke=\"black\" stroke-width=\"1.2\" stroke-dasharray=\"6,4\"/>\n";
  const double ly = T + 10 + 18 * double(groups.size());
  s << "<line x1=\"" << W - R + 14 << "\" y1=\"" << ly << "\" x2=\"" << W - R + 38 << "\" y2=\"" << ly
    << "\" stroke=\"black\" stroke-dasharray=\"6,4\"/><text x=\"" << W - R + 44 << "\" y=\"" << ly + 4
    << "\">Pareto front</text>\n";
  s << "<text x=\"" << W - R + 14 << "\" y=\"" << ly + 22 << "\" font-size=\"10\" fill=\"#555\">numbers at points: spp</text>\n";
  bool bars = false;
  for (const ReportCell& c : cells) bars = bars || c.hasIntervals();
  if (bars)
    s << "<text x=\"" << W - R + 14 << "\" y=\"" << ly + 36 << "\" font-size=\"10\" fill=\"#555\">bars: RMSE 95% t-interval,</text>"
      << "<text x=\"" << W - R + 14 << "\" y=\"" << ly + 48 << "\" font-size=\"10\" fill=\"#555\">time min-max over seeds</text>\n";
  s << "</svg>\n";
  return s.str();
}

void heatColour(double x, unsigned char* rgb) {
  const auto& stops = kHeatStops;
  x = std::clamp(std::isfinite(x) ? x : 1.0, 0.0, 1.0) * 5.0;
  const int i = std::min(int(x), 4);
  const double f = x - i;
  for (int c = 0; c < 3; ++c) rgb[c] = (unsigned char)std::lround(stops[i][c] * (1 - f) + stops[i + 1][c] * f);
}

void writePassPreview(const fs::path& path, const PassImage& p) {
  std::vector<unsigned char> px(p.pixels() * 3);
  for (size_t i = 0; i < p.pixels(); ++i) {
    px[i * 3 + 0] = linearToSrgb8(p.r[i]);
    px[i * 3 + 1] = linearToSrgb8(p.g[i]);
    px[i * 3 + 2] = linearToSrgb8(p.b[i]);
  }
  writePngRgb8(path.string(), p.width, p.height, px.data());
}

// "N spp", and for an adaptive cell "N spp (mean M)": N is then the most a
// pixel took.
std::string cellSpp(const ReportCell& c) {
  std::string t = std::to_string(c.spp) + " spp";
  if (c.targetError > 0) t += " (mean " + num(c.meanSpp) + ")";
  return t;
}

// The verdict's confidence in words (summary.md, stdout, results.json;
// docs/compare.md "Uncertainty"). `quote` wraps config names (` in Markdown).
std::string verdictText(const TargetVerdict& v, const std::vector<ReportCell>& cells, const char* quote) {
  if (!v.winner) return "";
  const auto name = [&](size_t i) { return quote + cells[i].config + quote + " @ " + std::to_string(cells[i].spp); };
  std::string t;
  if (!v.runnerUp) {
    t = "no runner-up: no other config reaches it";
  } else if (!v.time) {
    t = "runner-up " + name(*v.runnerUp) + " (" + num(cells[*v.runnerUp].seconds) +
        " s); one seed: no confidence (--seeds 2 or more)";
  } else {
    const WelchResult& w = *v.time;
    t = std::string(w.distinguishable ? "distinguishable" : "tie") + ": runner-up " + name(*v.runnerUp) + " is " +
        num(w.difference) + " s slower on average (95% CI " + num(w.interval.lo) + " to " + num(w.interval.hi) +
        " s, Welch t-test over seeds)";
  }
  if (v.winnerSurely)
    t += *v.winnerSurely ? "; the winner's RMSE 95% CI is below the target"
                         : "; the winner's RMSE 95% CI reaches above the target";
  return t;
}

// "0.012 [0.010, 0.014]": a value and its interval.
std::string withInterval(double v, const Interval& i) { return num(v) + " [" + num(i.lo) + ", " + num(i.hi) + "]"; }

// The summary as Markdown (for docs/trade.md and reports): the table, the
// targets and the Pareto front.
std::string summaryMarkdown(const CompareReport& r) {
  const std::vector<ReportCell>& cells = r.cells;
  bool bv = false, ci = false;
  for (const ReportCell& c : cells) bv = bv || c.bv.has_value(), ci = ci || c.hasIntervals();
  std::ostringstream s;
  s << "| config | spp | mean spp | time s" << (ci ? " [min, max]" : "") << " | denoise s | Mrays | RMSE"
    << (ci ? " [95% CI]" : "") << " | relMSE | MAE | p99 | FLIP | HDR-FLIP |" << (bv ? " bias² | variance |" : "") << "\n";
  s << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|" << (bv ? "---:|---:|" : "") << "\n";
  for (const ReportCell& c : cells) {
    const std::optional<CellIntervals> iv = c.hasIntervals() ? std::optional(cellIntervals(c)) : std::nullopt;
    s << "| `" << c.config << "` | " << c.spp << " | " << num(c.meanSpp) << " | "
      << (iv ? withInterval(c.seconds, iv->seconds) : num(c.seconds)) << " | "
      << (c.denoise ? num(c.denoiseSeconds) : "") << " | " << num(double(c.rays) * 1e-6) << " | "
      << (iv ? withInterval(c.error.rmse, iv->rmse) : num(c.error.rmse)) << " | " << num(c.error.relMse) << " | "
      << num(c.error.mae) << " | " << num(c.error.p99) << " | " << num(c.flip) << " | " << num(c.flipHdr) << " |";
    if (bv) s << " " << (c.bv ? num(c.bv->bias2) : "") << " | " << (c.bv ? num(c.bv->variance) : "") << " |";
    s << "\n";
  }
  s << "\n";
  if (!r.lighting.empty()) s << "Lighting: " << r.lighting << ".\n\n";
  if (r.referenceNoise >= 0) s << "Reference noise (RMSE of the gi reference itself): " << num(r.referenceNoise) << ".\n\n";
  s << "Time includes the denoiser for `denoise=on` configs; spp is a `target=` config's most per pixel.\n\n";
  if (ci)
    s << "Intervals over the seeds: RMSE a 95% Student-t interval of the per-seed MSE (ends square-rooted), time the "
         "fastest and slowest run (docs/compare.md \"Uncertainty\").\n\n";
  const auto verdicts = [&](const std::vector<double>& targets, TargetMeasure measure, const char* what) {
    s << "| " << what << " target | fastest config reaching it | confidence |\n|---:|---|---|\n";
    for (const double t : targets) {
      const TargetVerdict v = targetVerdict(cells, t, measure);
      const auto best = v.winner;
      s << "| " << num(t) << " | " << (best ? "`" + cells[*best].config + "` @ " + cellSpp(cells[*best]) + ", " +
                                                  num(cells[*best].seconds) + " s"
                                            : std::string("not reached"))
        << " | " << verdictText(v, cells, "`") << " |\n";
    }
  };
  verdicts(r.targets, TargetMeasure::Rmse, "RMSE");
  if (!r.flipTargets.empty()) {
    s << "\n";
    verdicts(r.flipTargets, TargetMeasure::Flip, "FLIP");
  }
  s << "\nFLIP at " << num(r.flipPpd, 4) << " pixels per degree (docs/compare.md \"FLIP\").\n";
  s << "\nPareto front:";
  for (const size_t i : paretoFront(cells)) s << " `" << cells[i].config << "`@" << cells[i].spp;
  s << "\n";
  return s.str();
}

}  // namespace

ContactSheetLayout contactSheetLayout(int tileWidth, const std::vector<std::pair<std::string, std::string>>& labels) {
  ContactSheetLayout L;
  // As many glyphs as fit the tile: the last one needs no blank column after it.
  L.columns = std::max(1, (tileWidth + 1) / kGlyphAdvance);
  int lines = 2;
  for (const auto& [first, second] : labels)
    lines = std::max(lines, int(wrapText(first, L.columns).size() + wrapText(second, L.columns).size()));
  L.labelHeight = kContactSheetLabelGap + lines * kLineAdvance;
  return L;
}

void writeCompareReport(const CompareReport& r) {
  const fs::path dir(r.dir);
  std::error_code ec;
  for (const char* sub : {"heatmaps", "previews"}) fs::create_directories(dir / sub, ec);
  const std::vector<ReportCell>& cells = r.cells;
  const auto groups = byConfig(cells);

  // The highest-spp pass of each config: heat map, preview, contact sheet.
  std::vector<std::pair<size_t, PassImage>> finest;
  double scale = 0;
  for (const auto& g : groups) {
    const size_t i = g.second.back();
    finest.push_back({i, readPass((dir / cells[i].pass).string())});
    // In the units the errors are measured in (the reference is already):
    // under an environment map the passes are divided by its mean radiance.
    scaleRgb(finest.back().second, r.passScale);
    scale = std::max(scale, cells[i].error.p99);
  }
  if (!(scale > 0)) scale = 1e-6;
  const PassImage& ref = *r.reference;
  std::vector<std::string> names;
  for (const auto& [i, img] : finest) names.push_back(safeFileName(cells[i].config));
  for (size_t k = 0; k < finest.size(); ++k) {
    const PassImage& img = finest[k].second;
    std::vector<unsigned char> px(img.pixels() * 3);
    for (size_t i = 0; i < img.pixels(); ++i) {
      if (!(ref.a[i] == 1.0f && img.a[i] > 0.0f)) {  // not compared: grey
        px[i * 3] = px[i * 3 + 1] = px[i * 3 + 2] = 64;
        continue;
      }
      double e = 0;
      for (int c = 0; c < 3; ++c) e += std::abs(double(img.W(c, i)) - ref.W(c, i)) / 3.0;
      heatColour(e / scale, &px[i * 3]);
    }
    writePngRgb8((dir / "heatmaps" / (names[k] + ".png")).string(), img.width, img.height, px.data());
    writePassPreview(dir / "previews" / (names[k] + ".png"), img);
  }
  writePassPreview(dir / "previews" / "reference.png", ref);

  // A FLIP heat map per cell (LDR and HDR), of its first seed's pass, on
  // FLIP's own [0, 1] scale.
  std::vector<std::pair<std::string, std::string>> flipMaps;
  for (const ReportCell& c : cells) {
    PassImage img = readPass((dir / c.pass).string());
    scaleRgb(img, r.passScale);
    const FlipError f = flipError(img, ref, r.flipPpd, true);
    const std::string base = "heatmaps/" + safeFileName(c.config) + "@" + std::to_string(c.spp);
    flipMaps.push_back({base + ".flip.png", base + ".flip-hdr.png"});
    for (const auto& [file, map] : {std::pair{flipMaps.back().first, &f.ldrMap}, std::pair{flipMaps.back().second, &f.hdrMap}}) {
      std::vector<unsigned char> px(img.pixels() * 3);
      for (size_t i = 0; i < img.pixels(); ++i) {
        if (!(ref.a[i] == 1.0f && img.a[i] > 0.0f)) px[i * 3] = px[i * 3 + 1] = px[i * 3 + 2] = 64;  // not compared: grey
        else heatColour((*map)[i], &px[i * 3]);
      }
      writePngRgb8((dir / file).string(), img.width, img.height, px.data());
    }
  }

  // Contact sheet: the reference, then each config's finest pass, in a grid,
  // each labelled with two lines: what it is, and its time and error.
  const int tiles = int(finest.size()) + 1, cols = std::min(tiles, 4), rows = (tiles + cols - 1) / cols;
  const int w = ref.width, h = ref.height, label = 34;
  std::vector<std::pair<std::string, std::string>> labels;
  for (int t = 0; t < tiles; ++t) {
    if (t == 0) {
      labels.push_back({"gi reference", r.referenceNoise >= 0 ? "noise RMSE " + num(r.referenceNoise) : "given"});
      continue;
    }
    const ReportCell& c = cells[finest[size_t(t - 1)].first];
    labels.push_back({c.config + " @ " + std::to_string(c.spp) + " spp",
                      num(c.seconds) + " s, RMSE " + num(c.error.rmse) + ", FLIP " + num(c.flip)});
  }
  {
    std::ostringstream s;
    s << "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" width=\"" << cols * (w + 8)
      << "\" height=\"" << rows * (h + label + 8) << "\" font-family=\"sans-serif\" font-size=\"12\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    for (int t = 0; t < tiles; ++t) {
      const int x = (t % cols) * (w + 8) + 4, y = (t / cols) * (h + label + 8) + 4;
      const std::string file = t == 0 ? "previews/reference.png" : "previews/" + names[size_t(t - 1)] + ".png";
      s << "<image x=\"" << x << "\" y=\"" << y << "\" width=\"" << w << "\" height=\"" << h << "\" href=\"" << file
        << "\" xlink:href=\"" << file << "\"/>\n<text x=\"" << x << "\" y=\"" << y + h + 14 << "\">" << xmlEscape(labels[size_t(t)].first)
        << "</text><text x=\"" << x << "\" y=\"" << y + h + 28 << "\" fill=\"#555\">" << xmlEscape(labels[size_t(t)].second)
        << "</text>\n";
    }
    s << "</svg>\n";
    writeTextAtomically(dir / "contact_sheet.svg", s.str());
    // The same grid as one PNG, with the same labels in the 5 x 7 bitmap
    // font (app/bitmap_font.h), wrapped to the tile's width; the label band
    // is as tall as the longest label needs.
    const ContactSheetLayout L = contactSheetLayout(w, labels);
    const int W = cols * (w + 4) + 4, H = rows * (h + L.labelHeight + 4) + 4;
    std::vector<unsigned char> px(size_t(W) * H * 3, 255);
    const unsigned char ink[3] = {0, 0, 0}, grey[3] = {0x55, 0x55, 0x55};
    for (int t = 0; t < tiles; ++t) {
      const PassImage& img = t == 0 ? ref : finest[size_t(t - 1)].second;
      const int x0 = (t % cols) * (w + 4) + 4, y0 = (t / cols) * (h + L.labelHeight + 4) + 4;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const size_t i = size_t(y) * w + x, o = (size_t(y0 + y) * W + x0 + x) * 3;
          px[o] = linearToSrgb8(img.r[i]), px[o + 1] = linearToSrgb8(img.g[i]), px[o + 2] = linearToSrgb8(img.b[i]);
        }
      int ly = y0 + h + kContactSheetLabelGap;
      for (int part = 0; part < 2; ++part)
        for (const std::string& line : wrapText(part == 0 ? labels[size_t(t)].first : labels[size_t(t)].second, L.columns)) {
          drawText(px.data(), W, H, x0, ly, x0 + w, line, part == 0 ? ink : grey);
          ly += kLineAdvance;
        }
    }
    writePngRgb8((dir / "contact_sheet.png").string(), W, H, px.data());
  }

  writeTextAtomically(dir / "error_vs_time.svg", errorVersusTimeSvg(r));

  nlohmann::json j;
  j["scene"] = r.scene;
  j["camera"] = r.camera;
  j["resolution"] = r.resolution;
  j["reference"] = {{"path", r.referencePath}};
  if (!r.lighting.empty()) j["lighting"] = r.lighting;
  if (r.referenceNoise >= 0) j["reference"]["noiseRmse"] = r.referenceNoise;
  j["metrics"] = {{"rmse", "sqrt(mean e^2), e = W - W_ref over fully covered reference pixels and R,G,B"},
                  {"relMse", "mean e^2 / (W_ref^2 + 0.01)"},
                  {"mae", "mean |e|"},
                  {"p99", "99th percentile of |e|"},
                  {"bias2", "mean (mean over seeds - W_ref)^2 - variance / seeds"},
                  {"variance", "mean per-value variance across seeds (of one render)"},
                  {"time", "render loop wall time plus the denoiser's (denoise=on), median over seeds"},
                  {"meanSpp", "camera samples per pixel on average, mean over seeds (below spp only with a target)"},
                  {"rmseInterval", "95% Student-t interval of the mean per-seed MSE, ends square-rooted (seeds >= 2)"},
                  {"secondsInterval", "fastest and slowest run over the seeds; holds the median with probability "
                                      "secondsIntervalConfidence = 1 - 2^(1 - seeds)"},
                  {"verdict", "distinguishable | tie: Welch's t-test (95%) of the per-seed times of the runner-up "
                              "(the fastest other config reaching the target) minus the winner's"},
                  {"flip", "LDR-FLIP (Andersson et al. 2020) of the pass as displayed (R,G,B over black, clamped to [0,1]), "
                           "mean over compared pixels, mean over seeds"},
                  {"flipHdr", "HDR-FLIP (Andersson et al. 2021) of the linear pass, exposures from the reference, mean over "
                              "compared pixels, mean over seeds"}};
  j["flipPpd"] = r.flipPpd;
  j["cells"] = nlohmann::json::array();
  for (size_t k = 0; k < cells.size(); ++k) {
    const ReportCell& c = cells[k];
    nlohmann::json e = {{"config", c.config}, {"integrator", c.integrator}, {"params", c.params},
                        {"spp", c.spp}, {"seeds", c.seeds}, {"seconds", c.seconds}, {"rays", c.rays},
                        {"rmse", c.error.rmse}, {"relMse", c.error.relMse}, {"mae", c.error.mae},
                        {"p99", c.error.p99}, {"pass", c.pass}, {"meanSpp", c.meanSpp},
                        {"denoise", c.denoise}, {"denoiseSeconds", c.denoiseSeconds}};
    if (c.targetError > 0) e["targetError"] = c.targetError;
    if (c.minSpp > 0) e["minSpp"] = c.minSpp;
    if (c.bv) e["bias2"] = c.bv->bias2, e["variance"] = c.bv->variance;
    if (!c.seedMse.empty()) e["seedMse"] = c.seedMse, e["seedSeconds"] = c.seedSeconds;
    if (c.hasIntervals()) {
      const CellIntervals iv = cellIntervals(c);
      e["rmseInterval"] = {iv.rmse.lo, iv.rmse.hi};
      e["secondsInterval"] = {iv.seconds.lo, iv.seconds.hi};
      e["secondsIntervalConfidence"] = iv.secondsConfidence;
    }
    e["flip"] = c.flip, e["flipHdr"] = c.flipHdr;
    e["flipHeatmap"] = flipMaps[k].first, e["flipHdrHeatmap"] = flipMaps[k].second;
    j["cells"].push_back(e);
  }
  j["paretoFront"] = nlohmann::json::array();
  for (const size_t i : paretoFront(cells)) j["paretoFront"].push_back({{"config", cells[i].config}, {"spp", cells[i].spp}});
  // The verdicts: per target, the fastest cell reaching it (null: none),
  // the runner-up and the confidence (docs/compare.md "Uncertainty").
  const auto verdicts = [&](const std::vector<double>& targets, TargetMeasure measure, const char* key) {
    nlohmann::json list = nlohmann::json::array();
    for (const double t : targets) {
      const TargetVerdict v = targetVerdict(cells, t, measure);
      const auto best = v.winner;
      nlohmann::json e = {{key, t}};
      if (best)
        e["fastest"] = {{"config", cells[*best].config}, {"spp", cells[*best].spp}, {"meanSpp", cells[*best].meanSpp},
                        {"seconds", cells[*best].seconds}};
      else e["fastest"] = nullptr;
      e["verdict"] = v.status();
      if (best) e["verdictText"] = verdictText(v, cells, "");
      if (v.runnerUp)
        e["runnerUp"] = {{"config", cells[*v.runnerUp].config}, {"spp", cells[*v.runnerUp].spp},
                         {"seconds", cells[*v.runnerUp].seconds}};
      if (v.time)
        e["timeDifference"] = {{"seconds", v.time->difference}, {"interval", {v.time->interval.lo, v.time->interval.hi}},
                               {"dof", std::isfinite(v.time->dof) ? nlohmann::json(v.time->dof) : nlohmann::json(nullptr)}};
      if (v.winnerSurely) e["winnerRmseIntervalBelowTarget"] = *v.winnerSurely;
      list.push_back(e);
    }
    return list;
  };
  j["targets"] = verdicts(r.targets, TargetMeasure::Rmse, "rmse");
  j["flipTargets"] = verdicts(r.flipTargets, TargetMeasure::Flip, "flip");
  j["keptRows"] = nlohmann::json::array();
  for (const ReportCell& c : r.kept) j["keptRows"].push_back({{"config", c.config}, {"spp", c.spp}, {"key", c.key}});
  j["heatmapScale"] = scale;
  writeTextAtomically(dir / "summary.md", summaryMarkdown(r));
  j["contactSheet"] = nlohmann::json::array({"reference"});
  for (const auto& [i, img] : finest) j["contactSheet"].push_back({{"config", cells[i].config}, {"spp", cells[i].spp}});
  writeTextAtomically(dir / "results.json", j.dump(2) + "\n");
  writeReportHtml(r, j.dump(), errorVersusTimeSvg(r));
}

void printCompareSummary(const CompareReport& r, FILE* out) {
  const std::vector<ReportCell>& cells = r.cells;
  bool bv = false;
  size_t width = 6;
  for (const ReportCell& c : cells) bv = bv || c.bv.has_value(), width = std::max(width, c.config.size());
  if (!r.lighting.empty()) std::fprintf(out, "lighting: %s\n", r.lighting.c_str());
  bool ci = false;
  for (const ReportCell& c : cells) ci = ci || c.hasIntervals();
  std::fprintf(out, "%-*s %7s %8s %9s %8s %9s %9s %9s %9s %9s %9s", int(width), "config", "spp", "mean spp", "time s",
               "Mrays", "RMSE", "relMSE", "MAE", "p99", "FLIP", "HDR-FLIP");
  if (bv) std::fprintf(out, " %9s %9s", "bias^2", "variance");
  if (ci) std::fprintf(out, "  %-21s %-21s", "RMSE 95% CI", "time min-max s");
  std::fprintf(out, "\n");
  for (const ReportCell& c : cells) {
    std::fprintf(out, "%-*s %7d %8.4g %9.3f %8.2f %9.3g %9.3g %9.3g %9.3g %9.3g %9.3g", int(width), c.config.c_str(), c.spp,
                 c.meanSpp, c.seconds, double(c.rays) * 1e-6, c.error.rmse, c.error.relMse, c.error.mae, c.error.p99, c.flip,
                 c.flipHdr);
    if (c.bv) std::fprintf(out, " %9.3g %9.3g", c.bv->bias2, c.bv->variance);
    else if (bv) std::fprintf(out, " %9s %9s", "", "");
    if (c.hasIntervals()) {
      const CellIntervals iv = cellIntervals(c);
      std::fprintf(out, "  %-21s %-21s", (num(iv.rmse.lo) + " - " + num(iv.rmse.hi)).c_str(),
                   (num(iv.seconds.lo) + " - " + num(iv.seconds.hi)).c_str());
    }
    std::fprintf(out, "\n");
  }
  if (r.referenceNoise >= 0)
    std::fprintf(out, "\nreference noise (RMSE of the gi reference itself): %.3g — errors near it are not resolved\n",
                 r.referenceNoise);
  const auto verdicts = [&](const std::vector<double>& targets, TargetMeasure measure, const char* what) {
    for (const double t : targets) {
      const TargetVerdict v = targetVerdict(cells, t, measure);
      const auto best = v.winner;
      if (best)
        std::fprintf(out, "  %s <= %-8.3g %s @ %s (%.3f s)\n             %s\n", what, t, cells[*best].config.c_str(),
                     cellSpp(cells[*best]).c_str(), cells[*best].seconds, verdictText(v, cells, "").c_str());
      else
        std::fprintf(out, "  %s <= %-8.3g not reached by any config\n", what, t);
    }
  };
  std::fprintf(out, "\nfastest config reaching each RMSE target (time includes the denoiser):\n");
  verdicts(r.targets, TargetMeasure::Rmse, "RMSE");
  if (!r.flipTargets.empty()) {
    std::fprintf(out, "\nfastest config reaching each FLIP target (%.4g pixels per degree):\n", r.flipPpd);
    verdicts(r.flipTargets, TargetMeasure::Flip, "FLIP");
  }
  std::fprintf(out, "\nPareto front (faster and more accurate than every other):");
  for (const size_t i : paretoFront(cells)) std::fprintf(out, "  %s@%d", cells[i].config.c_str(), cells[i].spp);
  std::fprintf(out, "\nreport: %s/report.html (and results.csv, results.json, error_vs_time.svg, contact_sheet.svg, heatmaps/)\n",
               r.dir.c_str());
  if (!r.kept.empty()) {
    std::string which;
    for (const ReportCell& c : r.kept) {
      const std::string one = c.config + "@" + std::to_string(c.spp);
      if (which.size() + one.size() > 120) {
        which += ", ...";
        break;
      }
      which += (which.empty() ? "" : ", ") + one;
    }
    std::fprintf(out, "note: results.csv also keeps %zu row%s of earlier runs that are not in this one (%s); "
                 "results.json lists them under keptRows, the report above leaves them out\n",
                 r.kept.size(), r.kept.size() == 1 ? "" : "s", which.c_str());
  }
}

}  // namespace obscura
