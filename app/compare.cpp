// `obscura compare`: every CONFIG x spp cell rendered (with `--seeds`
// seeds), its error measured against a full-GI reference, and the trade
// reported: results.csv / results.json, an error-versus-time plot with the
// Pareto front, a heat map per config and a contact sheet.
//
// Cells are independent and keyed by a hash of everything that determines
// their image (reference, scene, camera, resolution, config with every
// parameter value, spp, seed, seeds): a finished cell's row in results.csv
// is kept and not recomputed, so an interrupted run resumes where it
// stopped. Time is the render loop's wall time plus the denoiser's for a
// config with denoise=on (what it costs to get that pass; scene loading and
// the BVH build are the same for every cell and left out); with several
// seeds it is the median. A config may carry render settings beside its
// parameters (target=E, min-spp=N, denoise=on; parseCompareConfig).
#include "app/compare.h"
#include "core/util/input_file.h"
#include "core/util/memory_budget.h"

#include "core/util/hash.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "app/exr_header.h"
#include "app/options.h"
#include "app/interrupt.h"
#include "app/render_setup.h"
#include "app/report.h"
#include <obscura/error.h>
#include "core/load/gltf_document.h"
#include "core/load/gltf_loader.h"
#include "core/image/metrics.h"
#include "core/render/plugin_loader.h"
#include "core/render/render.h"

namespace obscura {
namespace fs = std::filesystem;

namespace {

// compare's keys: file names and resumption (core/util/hash.h).
using Hash64 = Fnv1a64;

std::string fileHash(const std::string& path) {
  checkInputFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot read");
  Hash64 h;
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof buf);
    h.add(buf, size_t(in.gcount()));
  }
  return h.hex();
}

std::vector<int> parseSppList(const std::string& s) {
  std::vector<int> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const long n = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || n < 1 || n > (1 << 24))
      throw Error("--spp: expected a comma-separated list of sample counts in [1, 16777216], got '" + s + "'");
    v.push_back(int(n));
  }
  if (v.empty()) throw Error("--spp: expected a comma-separated list of sample counts, got '" + s + "'");
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// A comma-separated list of error targets, sorted largest first. `option`
// and `what` name them in the message; FLIP targets are at most 1 (FLIP's
// range).
std::vector<double> parseTargets(const std::string& s, const char* option, const char* what, double most) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double t = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !(t > 0) || !(t <= most))
      throw Error(std::string(option) + ": expected a comma-separated list of " + what + " values" +
                  (std::isfinite(most) ? " in (0, " + formatFloat(most) + "]" : "") + ", got '" + s + "'");
    v.push_back(t);
  }
  std::sort(v.rbegin(), v.rend());
  return v;
}

using Cell = ReportCell;

// results.csv: the columns up to `pass` are those of the files written
// before configs carried render settings; those files are still read (their
// cells are plain: no target, no denoiser, mean spp = spp).
const char* kCsvHeaderV1 = "key,config,integrator,params,spp,seeds,time_s,rays,rmse,rel_mse,mae,p99,bias2,variance,pass";
const char* kCsvHeaderV2 =
    "key,config,integrator,params,spp,seeds,time_s,rays,rmse,rel_mse,mae,p99,bias2,variance,pass,target,min_spp,denoise,"
    "mean_spp,denoise_s";
// The FLIP columns (docs/compare.md "FLIP") after those: the files written
// before the per-seed values (cells of the older files have no FLIP yet,
// flipPpd 0).
const char* kCsvHeaderV3 =
    "key,config,integrator,params,spp,seeds,time_s,rays,rmse,rel_mse,mae,p99,bias2,variance,pass,target,min_spp,denoise,"
    "mean_spp,denoise_s,flip,flip_hdr,flip_ppd";
// The current columns: V3's, then each seed's MSE and time (';'-separated:
// the intervals of docs/compare.md "Uncertainty" are computed from them),
// then the intervals themselves (empty with one seed).
const char* kCsvHeader =
    "key,config,integrator,params,spp,seeds,time_s,rays,rmse,rel_mse,mae,p99,bias2,variance,pass,target,min_spp,denoise,"
    "mean_spp,denoise_s,flip,flip_hdr,flip_ppd,seed_mse,seed_time_s,rmse_lo,rmse_hi,time_lo,time_hi";

std::string joinSeeds(const std::vector<double>& v) {
  std::string s;
  for (const double x : v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", x);  // round-trips: a resumed cell's intervals are the same
    s += (s.empty() ? "" : ";") + std::string(buf);
  }
  return s;
}

std::vector<double> splitSeeds(const std::string& s) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ';')) v.push_back(std::stod(item));
  return v;
}

std::string csvQuote(const std::string& s) {
  std::string q = "\"";
  for (const char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// rmse_lo,rmse_hi,time_lo,time_hi, or four empty fields without intervals.
std::string intervalColumns(const Cell& c) {
  if (!c.hasIntervals()) return ",,,";
  const CellIntervals ci = cellIntervals(c);
  return fmt(ci.rmse.lo) + "," + fmt(ci.rmse.hi) + "," + fmt(ci.seconds.lo) + "," + fmt(ci.seconds.hi);
}

std::string csvRow(const Cell& c) {
  return c.key + "," + csvQuote(c.config) + "," + c.integrator + "," + csvQuote(c.params) + "," + std::to_string(c.spp) +
         "," + std::to_string(c.seeds) + "," + fmt(c.seconds) + "," + std::to_string(c.rays) + "," + fmt(c.error.rmse) +
         "," + fmt(c.error.relMse) + "," + fmt(c.error.mae) + "," + fmt(c.error.p99) + "," +
         (c.bv ? fmt(c.bv->bias2) : "") + "," + (c.bv ? fmt(c.bv->variance) : "") + "," + csvQuote(c.pass) + "," +
         (c.targetError > 0 ? fmt(c.targetError) : "") + "," + (c.minSpp > 0 ? std::to_string(c.minSpp) : "") + "," +
         (c.denoise ? "on" : "off") + "," + fmt(c.meanSpp) + "," + fmt(c.denoiseSeconds) + "," + fmt(c.flip) + "," +
         fmt(c.flipHdr) + "," + fmt(c.flipPpd) + "," + joinSeeds(c.seedMse) + "," + joinSeeds(c.seedSeconds) + "," +
         intervalColumns(c);
}

// Splits one CSV line (quoted fields with "" escapes).
std::vector<std::string> csvFields(const std::string& line) {
  std::vector<std::string> f(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') f.back() += '"', ++i;
      else if (c == '"') quoted = false;
      else f.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      f.emplace_back();
    } else {
      f.back() += c;
    }
  }
  return f;
}

// Rows of an earlier run's results.csv (empty if none or unreadable: the
// run then recomputes; a file from another version is ignored whole).
std::map<std::string, Cell> readPreviousCells(const std::string& path) {
  std::map<std::string, Cell> cells;
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line) ||
      (line != kCsvHeader && line != kCsvHeaderV3 && line != kCsvHeaderV2 && line != kCsvHeaderV1))
    return cells;
  const size_t fields = line == kCsvHeader ? 29 : line == kCsvHeaderV3 ? 23 : line == kCsvHeaderV2 ? 20 : 15;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = csvFields(line);
    if (f.size() != fields) continue;
    try {
      Cell c;
      c.key = f[0], c.config = f[1], c.integrator = f[2], c.params = f[3];
      c.spp = std::stoi(f[4]), c.seeds = std::stoi(f[5]);
      c.seconds = std::stod(f[6]), c.rays = std::stoull(f[7]);
      c.error.rmse = std::stod(f[8]), c.error.relMse = std::stod(f[9]), c.error.mae = std::stod(f[10]);
      c.error.p99 = std::stod(f[11]);
      if (!f[12].empty()) c.bv = BiasVariance{std::stod(f[12]), std::stod(f[13])};
      c.pass = f[14];
      c.meanSpp = c.spp;
      if (fields >= 20) {
        if (!f[15].empty()) c.targetError = std::stod(f[15]);
        if (!f[16].empty()) c.minSpp = std::stoi(f[16]);
        c.denoise = f[17] == "on";
        c.meanSpp = std::stod(f[18]), c.denoiseSeconds = std::stod(f[19]);
      }
      if (fields >= 23) c.flip = std::stod(f[20]), c.flipHdr = std::stod(f[21]), c.flipPpd = std::stod(f[22]);
      if (fields >= 29) c.seedMse = splitSeeds(f[23]), c.seedSeconds = splitSeeds(f[24]);
      cells[c.key] = c;
    } catch (const std::exception&) {
      // a damaged row is recomputed
    }
  }
  return cells;
}


// A pass image as a film (for the EXR writer): RGBA only.
Film filmFromPass(const PassImage& p) {
  Film f(p.width, p.height, false);
  std::copy(p.r.begin(), p.r.end(), f.plane(kR));
  std::copy(p.g.begin(), p.g.end(), f.plane(kG));
  std::copy(p.b.begin(), p.b.end(), f.plane(kB));
  std::copy(p.a.begin(), p.a.end(), f.plane(kA));
  return f;
}


}  // namespace

CompareConfig parseCompareConfig(const std::string& text) {
  // The render settings a config may carry are taken out first; the rest is
  // the integrator's and checked by parseIntegratorSpec ("ao:" goes to it
  // whole, for its own message).
  const std::string where = "-c '" + text + "': ";
  const size_t colon = text.find(':');
  const std::string rest = colon == std::string::npos ? "" : text.substr(colon + 1);
  const bool wellFormed = colon == std::string::npos ||
                          (!rest.empty() && rest.front() != ',' && rest.back() != ',' && rest.find(",,") == std::string::npos);
  if (!wellFormed && !rest.empty()) throw Error(where + "expected integrator:key=value,... without empty items");
  CompareConfig c;
  c.text = text;
  std::string kept;
  std::vector<std::string> seen;
  bool stripped = false;
  if (wellFormed && colon != std::string::npos) {
    std::stringstream ss(rest);
    std::string item;
    while (std::getline(ss, item, ',')) {
      const size_t eq = item.find('=');
      const std::string key = eq == std::string::npos ? "" : item.substr(0, eq), value = item.substr(eq + 1);
      if (key != "target" && key != "min-spp" && key != "denoise") {
        kept += (kept.empty() ? "" : ",") + item;
        continue;
      }
      stripped = true;
      if (std::find(seen.begin(), seen.end(), key) != seen.end()) throw Error(where + key + " is given twice");
      seen.push_back(key);
      char* end = nullptr;
      if (key == "target") {
        // A standard error of W, absolute (docs/sampling.md "Adaptive sampling"); the
        // renderer keeps it as a float.
        c.targetError = std::strtod(value.c_str(), &end);
        if (value.empty() || *end != '\0' || !(c.targetError > 0) || !(c.targetError <= 1e30))
          throw Error(where + "target must be a positive standard error of W (absolute, e.g. target=0.01), got '" + value + "'");
      } else if (key == "min-spp") {
        const long n = std::strtol(value.c_str(), &end, 10);
        if (value.empty() || *end != '\0' || n < 1 || n > (1 << 24))
          throw Error(where + "min-spp must be a sample count in [1, 16777216], got '" + value + "'");
        c.minSpp = int(n);
      } else if (value == "on" || value == "off") {
        c.denoise = value == "on";
      } else {
        throw Error(where + "denoise must be on or off, got '" + value + "'");
      }
    }
    if (c.minSpp > 0 && c.targetError == 0)
      throw Error(where + "min-spp needs target=E (without it every pixel takes the cell's spp)");
  }
  const std::string integratorText = !stripped ? text : kept.empty() ? text.substr(0, colon) : text.substr(0, colon) + ":" + kept;
  IntegratorSpec spec;
  try {
    spec = parseIntegratorSpec("-c", integratorText);
  } catch (const Error& e) {
    // Name the config as typed, not the part left after the settings.
    const std::string msg = e.what(), prefix = "-c '" + integratorText + "': ";
    throw Error(msg.rfind(prefix, 0) == 0 ? where + msg.substr(prefix.size()) : msg);
  }
  c.integrator = std::move(spec.integrator);
  c.assignments = std::move(spec.assignments);
  c.canonical = std::move(spec.canonical);
  if (c.targetError > 0) c.canonical += ":target=" + formatFloat(c.targetError);
  if (c.minSpp > 0) c.canonical += ":min-spp=" + std::to_string(c.minSpp);
  if (c.denoise) c.canonical += ":denoise=on";
  return c;
}

namespace {

// --- stage 1: the plan --------------------------------------------------------
// Everything the arguments say, validated before any work.
struct ComparePlan {
  std::vector<CompareConfig> configs;
  std::vector<int> spps;
  std::vector<double> targets, flipTargets;
  RenderSettings base;  // resolution, sky, threads, motion blur; spp and seed per render
  fs::path dir;
  std::optional<PassImage> givenReference;
  bool lit = false;  // --environment: shaded.* relative to the reference's mean radiance
  MemoryHold films;  // the films below, held against --max-memory while the plan lives (beside the scene)
};

ComparePlan planCompare(const CompareArgs& a) {
  ComparePlan p;
  loadPlugins(a.plugins);
  if (a.configs.empty()) throw Error("-c: at least one CONFIG is required, e.g. -c ao -c transfer:depth=1");
  for (const auto& t : a.configs) p.configs.push_back(parseCompareConfig(t));
  p.spps = parseSppList(a.sppList);
  p.targets = a.targets.empty() ? std::vector<double>{0.1, 0.05, 0.02, 0.01}
                                : parseTargets(a.targets, "--targets", "positive RMSE", INFINITY);
  p.flipTargets = parseTargets(a.targetsFlip, "--targets-flip", "FLIP", 1.0);
  if (!(a.flipPpd >= 1 && a.flipPpd <= 1000))
    throw Error("--flip-ppd: pixels per degree must be in [1, 1000], got " + formatFloat(a.flipPpd));
  if (a.seeds < 1 || a.seeds > 64) throw Error("--seeds: must be in [1, 64], got " + std::to_string(a.seeds));
  if (a.referenceSpp < 2) throw Error("--reference-spp: must be at least 2, got " + std::to_string(a.referenceSpp));
  if (a.seed < 0 || a.seed > 0xffffffffLL - 64) throw Error("--seed: must be in [0, 4294967231]");
  checkThreads(a.threads);
  parseResolution(a.res, p.base.width, p.base.height);
  sceneOptions(a);  // --max-memory, before the first allocation it bounds
  p.base.sky = parseSky(a.sky);
  // Under a map the cells are measured by their shaded.* (the radiance),
  // which needs the albedo AOV.
  p.base.environment = loadEnvironment(a.env, a.sky);
  p.lit = p.base.environment != nullptr;
  p.base.threads = a.threads;
  p.base.motionBlur = !a.shutter.empty();
  p.base.aovs = p.lit;
  p.base.progress = !a.quiet;
  // What compare holds at once besides the scene: a render's film, the
  // reference, and a cell's pass with the film made of it (RGBA planes
  // each): refused up front and held, as render's holdFilmMemory does.
  {
    const uint64_t pixels = uint64_t(p.base.width) * uint64_t(p.base.height);
    const uint64_t need = filmBytes(p.base.width, p.base.height, p.base.aovs) + 3 * pixels * 4 * sizeof(float);
    p.films = MemoryHold(need, "--res " + a.res + ": the films");
    if (const uint64_t avail = availableMemoryBytes(); avail > 0 && need > avail)
      throw Error("--res " + a.res + ": the films need " + formatBytes(need) + ", but only " + formatBytes(avail) +
                  " of memory is available");
  }
  if (a.output.empty()) throw Error("-o: an output directory is required");
  p.dir = fs::path(a.output);
  if (fs::exists(p.dir) && !fs::is_directory(p.dir)) throw Error(a.output + ": exists and is not a directory");
  if (!p.dir.parent_path().empty() && !fs::is_directory(p.dir.parent_path()))
    throw Error(a.output + ": cannot create: directory '" + p.dir.parent_path().string() + "' does not exist");
  // The files compare writes in DIR may not be files the renders read (the
  // scene, the files it names, the maps): checked before any work, as
  // render's -o (docs/compare.md).
  {
    std::vector<std::pair<std::string, std::string>> inputs = {{"the scene", a.scene}, {"--displace", a.displace},
                                                               {"--environment", a.env.environment}};
    if (!hasExtension(a.scene, ".obj"))
      for (auto& [field, path] : gltfExternalFiles(a.scene)) inputs.push_back({a.scene + " " + field, std::move(path)});
    std::error_code ec;
    const fs::path dir = fs::weakly_canonical(p.dir, ec);
    for (const auto& [what, path] : inputs) {
      if (path.empty()) continue;
      const fs::path file = fs::weakly_canonical(path, ec);
      const fs::path rel = file.lexically_relative(dir);
      if (rel.empty() || *rel.begin() == "..") continue;
      const std::string top = rel.begin()->string();
      const bool written = std::distance(rel.begin(), rel.end()) > 1
                               ? (top == "passes" || top == "cache" || top == "heatmaps" || top == "previews" ||
                                  top == "report_data")
                               : (top == "results.csv" || top == "results.json" || top == "summary.md" ||
                                  top == "error_vs_time.svg" || top == "contact_sheet.svg" || top == "contact_sheet.png" ||
                                  top == "report.html");
      if (written)
        throw Error("-o " + a.output + ": compare writes " + (p.dir / rel).string() + ", which is " + what + " " + path +
                    "; refusing to overwrite an input");
    }
  }
  if (!a.reference.empty()) p.givenReference = p.lit ? readPass(a.reference, "shaded.") : readPass(a.reference);
  return p;
}

// The image every cell is measured against.
struct Reference {
  PassImage image;
  std::string path, key;
  double noiseRmse = -1;  // RMSE of the reference itself; < 0: unknown (a given reference)
  // Under a map: 1 / the reference's mean radiance. Cells and reference are
  // measured after multiplying by it, so every error is relative to the
  // reference's mean (docs/compare.md "Under an environment map"); 1 otherwise.
  double scale = 1.0;
  // Scales the image (and the noise, which is in its units) by `scale`.
  void normalise(bool lit) {
    if (!lit) return;
    const double m = meanCoveredRgb(image);
    if (!(m > 0.0)) throw Error(path + ": the reference's mean radiance is 0: nothing to measure errors against");
    scale = 1.0 / m;
    scaleRgb(image, scale);
    if (noiseRmse >= 0) noiseRmse *= scale;
  }
};

// The stages that render (reference, cells) and the report, over one loaded
// scene and view.
class CompareRun {
 public:
  CompareRun(const CompareArgs& a, const ComparePlan& plan, const Scene& scene, const Camera& camera,
             const std::atomic<bool>* cancel)
      : a_(a), plan_(plan), scene_(scene), camera_(camera), cancel_(cancel) {
    // What makes two images comparable: scene, view, resolution, sky.
    viewHash_.add(fileHash(a.scene)).add(camera.name).add(&camera.toWorld, sizeof camera.toWorld);
    viewHash_.add(&camera.yfov, sizeof camera.yfov).add(a.res);
    viewHash_.add(formatFloat(plan.base.sky.x) + "," + formatFloat(plan.base.sky.y) + "," + formatFloat(plan.base.sky.z));
    viewHash_.add(a.robust ? "robust" : "fast");
    // The map: its content, turn, strength and E0 method (added only with a
    // map, so the keys of uniform-sky runs stay as they were).
    if (const Environment* e = plan.base.environment.get()) {
      const EnvironmentOptions& o = e->options();
      viewHash_.add("environment/" + e->contentHash() + "/" + formatFloat(o.rotationDegrees) + "/" +
                    formatFloat(o.strength) + "/" + irradianceMethodName(o.irradiance));
    }
    // What the scene is made of beyond its file: the geometry options and
    // the objects' roles (a reference with other roles is another image).
    viewHash_.add(a.subdiv + "/" + a.subdivBackend + "/" + std::to_string(a.subdivLevel) + "/" + formatFloat(a.subdivEdge));
    viewHash_.add(a.displace + "/" + formatFloat(a.displaceScale) + "/" + formatFloat(a.displaceMidlevel));
    viewHash_.add(nonDefaultRoles(scene.objects));
    if (a.normalMaps != "on") viewHash_.add("normal-maps/" + a.normalMaps);  // only off: keys stay as they were
    // The pose: another frame (or other animations) is another image. Added
    // only with a frame, so the keys of still renders stay as they were.
    if (!a.frame.empty()) {
      std::string anims;
      for (const std::string& n : a.animations) anims += "," + n;
      viewHash_.add("frame/" + formatFloat(parseFrame(a.frame) / a.fps) + anims);
      if (!a.shutter.empty()) {  // by value: "-.25,.25" and "-0.25,0.25" are one shutter
        const std::array<double, 2> sh = parseShutter(a.shutter);
        viewHash_.add("shutter/" + formatFloat(sh[0]) + "," + formatFloat(sh[1]));
      }
    }
  }

  // --- stage 2: the reference (given, cached or rendered); nullopt when interrupted.
  std::optional<Reference> reference() const;
  // --- stage 3: every cell, each saved to results.csv as it finishes. Returns
  // false when interrupted; `cells` then holds the finished ones.
  // `kept`: the rows of an earlier run's results.csv that are no cell of
  // this run (another config, or an spp not in --spp), written back with
  // this run's rows.
  bool measureCells(const Reference& ref, std::vector<Cell>& cells, std::vector<Cell>& kept) const;
  // --- stage 4: the report files and the summary on stdout.
  void report(const Reference& ref, const std::vector<Cell>& cells, const std::vector<Cell>& kept) const;

 private:
  // The settings of one render: the plan's, the cell's spp and seed, and the
  // config's own (target error, min-spp, denoiser). A min-spp above the
  // cell's spp is cut to it, so one config runs at every spp of the list.
  RenderSettings settingsFor(const CompareConfig* cfg, int spp, uint32_t seed) const {
    RenderSettings s = plan_.base;
    s.spp = spp;
    s.seed = seed;
    if (cfg) {
      s.targetError = float(cfg->targetError);
      s.minSpp = std::min(cfg->minSpp, spp);
      s.denoise = cfg->denoise;
      s.aovs = s.aovs || cfg->denoise;  // the denoiser is guided by N, Z and W_error
    }
    return s;
  }
  std::optional<PassImage> renderPass(const IntegratorDescriptor& d, const ParamSet& p, const RenderSettings& s,
                                      RenderStats& stats) const {
    auto integ = d.create(p);
    const IntegratorNeeds needs = passNeeds(d, p);
    // AOVs that are on for the denoiser alone (settingsFor) skip the albedo
    // lookups unless the filter reads albedo: the timings are the pass's.
    RenderSettings rs = s;
    if (!plan_.base.aovs && rs.denoise) rs.albedoAov = needs.pixelAlbedo;
    Film film = render(scene_, camera_, *integ, needs, rs, stats, cancel_);
    if (cancel_ && cancel_->load()) return std::nullopt;
    return plan_.lit ? shadedFromFilm(film) : passFromFilm(film);
  }
  ExrOptions header(const IntegratorDescriptor& d, const ParamSet& p, const RenderSettings& s,
                    const RenderStats& stats) const {
    return passHeader(PassInfo{.scenePath = a_.scene, .camera = camera_, .integrator = d, .params = p, .settings = s,
                               .stats = stats, .filterName = "box", .robust = a_.robust, .sceneArgs = &a_,
                               .scene = &scene_, .bvhSeconds = scene_.buildSeconds()});
  }
  // Whether a kept cell's FLIP is at this run's --flip-ppd (the CSV keeps 9
  // digits).
  bool sameFlipPpd(double ppd) const { return std::abs(ppd - a_.flipPpd) <= 1e-7 * a_.flipPpd; }
  // Whether a cell of an earlier run can be kept as far as FLIP goes: it has
  // FLIP at this ppd, or one seed, whose pass (passes/) then gives it
  // exactly; with more seeds FLIP is their mean and the cell is rendered
  // again.
  bool keepFlip(const Cell& c) const { return sameFlipPpd(c.flipPpd) || c.seeds == 1; }
  // Whether it can be kept as far as the intervals go: a row without one
  // value per seed (an older file) cannot give them, and the cell is
  // measured again (a row of another config is still written back as it
  // is: measureCells' `kept`).
  static bool keepSeeds(const Cell& c) {
    return c.seeds < 2 || (c.seedMse.size() == size_t(c.seeds) && c.seedSeconds.size() == size_t(c.seeds));
  }
  // One cell: renders its seeds and measures them; nullopt when interrupted.
  std::optional<Cell> measureCell(const CompareConfig& cfg, const IntegratorDescriptor& d, const ParamSet& params,
                                  int spp, const Reference& ref, Cell c) const;

  const CompareArgs& a_;
  const ComparePlan& plan_;
  const Scene& scene_;
  const Camera& camera_;
  const std::atomic<bool>* cancel_;
  Hash64 viewHash_;
};

std::optional<Reference> CompareRun::reference() const {
  Reference ref;
  if (plan_.givenReference) {
    ref.image = *plan_.givenReference;
    if (ref.image.width != plan_.base.width || ref.image.height != plan_.base.height)
      throw Error(a_.reference + ": is " + std::to_string(ref.image.width) + "x" + std::to_string(ref.image.height) +
                  " but --res is " + a_.res);
    ref.path = fs::absolute(a_.reference).lexically_normal().string();
    ref.key = fileHash(a_.reference);
    // A reference written by an earlier compare records its noise.
    const std::string noise = readExrAttribute(a_.reference, "obscura:referenceNoise");
    if (!noise.empty()) ref.noiseRmse = std::strtod(noise.c_str(), nullptr);
    ref.normalise(plan_.lit);
    return ref;
  }
  Hash64 rk = viewHash_;
  rk.add("gi-reference").add(std::to_string(a_.referenceSpp)).add(std::to_string(a_.seed)).add(OBSCURA_VERSION);
  ref.key = rk.hex();
  const fs::path cached = plan_.dir / "cache" / ("reference-" + ref.key + ".exr");
  ref.path = cached.string();
  bool have = false;
  if (fs::exists(cached)) {
    try {
      ref.image = readPass(cached.string());
      const std::string noise = readExrAttribute(cached.string(), "obscura:referenceNoise");
      ref.noiseRmse = noise.empty() ? -1 : std::stod(noise);
      have = ref.image.width == plan_.base.width && ref.image.height == plan_.base.height;
    } catch (const std::exception&) {
      have = false;  // damaged cache: render again
    }
  }
  if (have) {
    if (!a_.quiet) std::fprintf(stderr, "obscura: reference: cached %s\n", cached.string().c_str());
    ref.normalise(plan_.lit);
    return ref;
  }
  // Two independent halves: their mean is the reference, their difference
  // measures its noise.
  if (!a_.quiet)
    std::fprintf(stderr, "obscura: reference: gi at %d spp (two halves of %d) -> %s\n", a_.referenceSpp,
                 a_.referenceSpp / 2, cached.string().c_str());
  const IntegratorDescriptor& gi = IntegratorRegistry::instance().find("gi");
  const ParamSet giParams(gi.params, gi.name);
  RenderStats s1, s2;
  const uint32_t refSeed = uint32_t(a_.seed) ^ 0x9e3779b9U;  // never a cell's seed
  const auto h1 = renderPass(gi, giParams, settingsFor(nullptr, a_.referenceSpp / 2, refSeed), s1);
  if (!h1) return std::nullopt;
  const auto h2 = renderPass(gi, giParams, settingsFor(nullptr, a_.referenceSpp - a_.referenceSpp / 2, refSeed + 1), s2);
  if (!h2) return std::nullopt;
  ref.image = averagePasses(*h1, *h2);
  ref.noiseRmse = referenceNoise(*h1, *h2);
  RenderStats both = s1;
  both.seconds += s2.seconds;
  both.rays.camera += s2.rays.camera;
  both.rays.occlusion += s2.rays.occlusion;
  both.rays.closest += s2.rays.closest;
  ExrOptions exr = header(gi, giParams, settingsFor(nullptr, a_.referenceSpp, refSeed), both);
  char noise[32];  // round-trips: a cached reference reports the same noise
  std::snprintf(noise, sizeof noise, "%.17g", ref.noiseRmse);
  exr.attributes.push_back({"obscura:referenceNoise", std::string(noise)});
  exr.attributes.push_back({"obscura:referenceKey", ref.key});
  writeExr(cached.string(), filmFromPass(ref.image), exr);
  ref.normalise(plan_.lit);
  return ref;
}

std::optional<Cell> CompareRun::measureCell(const CompareConfig& cfg, const IntegratorDescriptor& d,
                                            const ParamSet& params, int spp, const Reference& ref, Cell c) const {
  std::vector<PassImage> renders;
  std::vector<double> seconds, denoiseSeconds;
  double mse = 0, rel = 0, mae = 0, p99 = 0, meanSpp = 0, flip = 0, flipHdr = 0;
  for (int k = 0; k < a_.seeds; ++k) {
    RenderStats stats;
    const RenderSettings s = settingsFor(&cfg, spp, uint32_t(a_.seed) + uint32_t(k));
    auto img = renderPass(d, params, s, stats);
    if (!img) return std::nullopt;
    if (k == 0) {  // the pass as rendered (shaded.* under a map), before scaling
      c.rays = stats.rays.camera + stats.rays.occlusion + stats.rays.closest;
      c.pass = "passes/" + safeFileName(cfg.text) + "@" + std::to_string(spp) + ".exr";
      writeExr((plan_.dir / c.pass).string(), filmFromPass(*img), header(d, params, s, stats));
    }
    scaleRgb(*img, ref.scale);
    const ErrorMetrics e = errorMetrics(*img, ref.image);
    mse += e.rmse * e.rmse, rel += e.relMse, mae += e.mae, p99 += e.p99;
    c.seedMse.push_back(e.rmse * e.rmse);
    c.error.values = e.values;
    const FlipError f = flipError(*img, ref.image, a_.flipPpd);
    flip += f.ldr, flipHdr += f.hdr;
    // The time to this pass: the render loop and the denoiser after it
    // (RenderStats keeps them apart; a denoised cell pays both).
    seconds.push_back(stats.seconds + stats.denoiseSeconds);
    c.seedSeconds.push_back(seconds.back());
    denoiseSeconds.push_back(stats.denoiseSeconds);
    meanSpp += stats.meanSpp > 0 ? stats.meanSpp : double(spp);
    renders.push_back(std::move(*img));
  }
  const double K = double(a_.seeds);
  c.error.rmse = std::sqrt(mse / K), c.error.relMse = rel / K, c.error.mae = mae / K, c.error.p99 = p99 / K;
  c.flip = flip / K, c.flipHdr = flipHdr / K, c.flipPpd = a_.flipPpd;
  std::sort(seconds.begin(), seconds.end());
  std::sort(denoiseSeconds.begin(), denoiseSeconds.end());
  c.seconds = seconds[seconds.size() / 2];
  c.denoiseSeconds = denoiseSeconds[denoiseSeconds.size() / 2];
  c.meanSpp = meanSpp / K;
  if (a_.seeds >= 2) c.bv = biasVariance(renders, ref.image, std::max(ref.noiseRmse, 0.0));
  return c;
}

bool CompareRun::measureCells(const Reference& ref, std::vector<Cell>& cells, std::vector<Cell>& kept) const {
  const std::string csvPath = (plan_.dir / "results.csv").string();
  const std::map<std::string, Cell> previous = readPreviousCells(csvPath);
  const auto cellKey = [&](const CompareConfig& cfg, int spp) {
    Hash64 ck;
    ck.add(ref.key).add(viewHash_.hex()).add(cfg.canonical).add(std::to_string(spp)).add(std::to_string(a_.seed));
    ck.add(std::to_string(a_.seeds)).add(OBSCURA_VERSION);
    return ck.hex();
  };
  // A run with fewer configs (or spps) keeps the other rows: results.csv
  // gathers every cell measured in DIR, and a later run with those configs
  // finds them done. A row is replaced only by a cell of this run: the same
  // key, or the same config text and spp measured anew (another seed,
  // reference or view). docs/compare.md "Compare".
  std::set<std::string> keys;
  std::set<std::pair<std::string, int>> planned;
  for (const CompareConfig& cfg : plan_.configs)
    for (const int spp : plan_.spps) keys.insert(cellKey(cfg, spp)), planned.insert({cfg.text, spp});
  for (const auto& [key, c] : previous)
    if (!keys.count(key) && !planned.count({c.config, c.spp})) kept.push_back(c);
  const auto save = [&] {
    std::string csv = std::string(kCsvHeader) + "\n";
    for (const Cell& c : cells) csv += csvRow(c) + "\n";
    for (const Cell& c : kept) csv += csvRow(c) + "\n";
    writeTextAtomically(csvPath, csv);
  };
  const size_t total = plan_.configs.size() * plan_.spps.size();
  size_t done = 0;
  for (const CompareConfig& cfg : plan_.configs) {
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find(cfg.integrator);
    ParamSet params(d.params, d.name);
    for (const auto& s : cfg.assignments) params.setAssignment(s);
    std::string paramText;
    for (const auto& [k, v] : params.values()) paramText += (paramText.empty() ? "" : ",") + k + "=" + v;
    for (const int spp : plan_.spps) {
      ++done;
      const std::string key = cellKey(cfg, spp);
      if (auto it = previous.find(key); it != previous.end() && fs::exists(plan_.dir / it->second.pass) &&
                                        keepFlip(it->second) && keepSeeds(it->second)) {
        Cell c = it->second;
        c.config = cfg.text;
        if (!sameFlipPpd(c.flipPpd)) {  // one seed: its pass is all FLIP needs
          PassImage pass = readPass((plan_.dir / c.pass).string());
          scaleRgb(pass, ref.scale);
          const FlipError f = flipError(pass, ref.image, a_.flipPpd);
          c.flip = f.ldr, c.flipHdr = f.hdr, c.flipPpd = a_.flipPpd;
        }
        cells.push_back(c);
        if (!a_.quiet)
          std::fprintf(stderr, "[%zu/%zu] %s @ %d spp: done earlier (kept)\n", done, total, cfg.text.c_str(), spp);
        continue;
      }
      if (!a_.quiet) std::fprintf(stderr, "[%zu/%zu] %s @ %d spp\n", done, total, cfg.text.c_str(), spp);
      Cell c;
      c.key = key, c.config = cfg.text, c.integrator = d.name, c.params = paramText;
      c.spp = spp, c.seeds = a_.seeds;
      c.targetError = cfg.targetError, c.minSpp = cfg.minSpp, c.denoise = cfg.denoise;
      std::optional<Cell> measured = measureCell(cfg, d, params, spp, ref, std::move(c));
      if (!measured) return false;
      if (!a_.quiet)
        std::fprintf(stderr, "        %.3f s  %.3g Mrays  mean spp %.4g  RMSE %.4g  MAE %.4g  p99 %.4g  FLIP %.4g  HDR-FLIP %.4g%s\n",
                     measured->seconds, double(measured->rays) * 1e-6, measured->meanSpp, measured->error.rmse,
                     measured->error.mae, measured->error.p99, measured->flip, measured->flipHdr,
                     measured->bv ? (" bias2 " + fmt(measured->bv->bias2) + " var " + fmt(measured->bv->variance)).c_str()
                                  : "");
      cells.push_back(std::move(*measured));
      save();
    }
  }
  save();
  return true;
}

void CompareRun::report(const Reference& ref, const std::vector<Cell>& cells, const std::vector<Cell>& kept) const {
  CompareReport report;
  report.dir = a_.output;
  report.scene = a_.scene;
  report.camera = camera_.name;
  report.resolution = a_.res;
  report.referencePath = ref.path;
  report.referenceNoise = ref.noiseRmse;
  if (const Environment* e = plan_.base.environment.get()) {
    char m[64];
    std::snprintf(m, sizeof m, "%.6g", 1.0 / ref.scale);
    report.lighting = "environment " + e->options().path + " (content " + e->contentHash() + ", rotation " +
                      formatFloat(e->options().rotationDegrees) + " deg, strength " +
                      formatFloat(e->options().strength) + "); errors are of shaded.* (radiance), relative to the "
                      "reference's mean radiance " + m;
  } else {
    report.lighting = "uniform sky " + a_.sky + "; errors are of W (R,G,B)";
  }
  report.reference = &ref.image;
  report.targets = plan_.targets;
  report.flipTargets = plan_.flipTargets;
  report.flipPpd = a_.flipPpd;
  report.passScale = ref.scale;
  report.cells = cells;
  report.kept = kept;
  writeCompareReport(report);
  printCompareSummary(report, stdout);
}

}  // namespace

int runCompare(const CompareArgs& a, const std::atomic<bool>* cancel) {
  const ComparePlan plan = planCompare(a);
  std::optional<tbb::global_control> limit;
  if (a.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(a.threads));

  Camera camera;
  std::unique_ptr<Scene> scene = loadSceneAndCamera(a, a.scene, a.camera, plan.base.width, plan.base.height, camera);
  interrupt::startPolling();  // from here on the renders poll `cancel` (app/interrupt.h)
  std::error_code ec;
  fs::create_directories(plan.dir / "passes", ec);
  if (ec) throw Error(a.output + ": cannot create: " + ec.message());
  fs::create_directories(plan.dir / "cache", ec);

  const CompareRun run(a, plan, *scene, camera, cancel);
  std::vector<Cell> cells, kept;
  const auto interrupted = [&] {
    std::fprintf(stderr, "obscura: interrupted; %zu finished cell%s kept in %s/results.csv (run again to resume)\n",
                 cells.size(), cells.size() == 1 ? "" : "s", a.output.c_str());
    return 130;
  };
  const std::optional<Reference> ref = run.reference();
  if (!ref) return interrupted();
  if (!a.quiet && ref->noiseRmse >= 0)
    std::fprintf(stderr, "obscura: reference noise (RMSE of the reference itself): %.3g\n", ref->noiseRmse);
  if (!run.measureCells(*ref, cells, kept)) return interrupted();
  run.report(*ref, cells, kept);
  return 0;
}

}  // namespace obscura
