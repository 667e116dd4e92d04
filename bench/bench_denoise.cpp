// obscura_bench_denoise: the denoiser's cost against the render it cleans
// (docs/sampling.md "Denoising", docs/denoise.md).
//
// Renders the pass as two independent halves of spp/2 samples (seeds s and
// s + 1) with the AOVs on, combines them into the spp pass and its
// per-pixel variance ((W_a - W_b) / 2)^2 (max over channels: what the
// film's W_error holds, squared), then times core/denoise on it. Prints the
// render loop's time (both halves), the denoiser's (median over runs) and
// their ratio; the issue's goal is a denoiser under 10 % of the render at
// 1920x1080. With --reference-spp N it also renders an N-spp reference and
// prints the RMSE of W (fully covered pixels) noisy and denoised.
//
// --error-table (docs/denoise.md "Measured against a converged reference"):
// instead of timing, renders a reference (cached with --reference-cache) and
// each --sweep spp over --seeds seeds through the render's own --denoise
// path, denoises the noisy pass again with the settings on the command line
// (object guide: the Cryptomatte rank-0 id), and prints per spp the RMSE of
// W noisy and denoised against the reference (its own variance subtracted),
// bias^2 and variance over seeds, near edges and away from them, W_error's
// calibration, and the equal-RMSE sample ratio (the spp a fixed render needs
// to reach the denoised MSE, interpolated log-log on the noisy rows, over the
// denoised render's spp).
//
// Run:   build/bench/obscura_bench_denoise                 viking room, 1920x1080, ao, 16 spp, 3 runs
//        build/bench/obscura_bench_denoise --error-table --res 1920x1080 --crop 480x270
//            --param distance=0.5 --reference-cache /tmp/viking_ao.ref   (one line) the table of docs/denoise.md
//        build/bench/obscura_bench_denoise --quick         smoke run (320x180, 2 spp, 1 run)
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench/common.h"
#include "core/image/denoise.h"
#include "core/render/cryptomatte.h"
#include <obscura/error.h>
#include "core/image/film.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

// The spp pass made from two half renders, with its variance estimate, as
// planes the denoiser reads.
struct Combined {
  int w = 0, h = 0;
  std::vector<float> c[3], alpha, var;
};

Combined combine(const Film& a, const Film& b) {
  Combined m;
  m.w = a.width(), m.h = a.height();
  const size_t n = size_t(m.w) * size_t(m.h);
  for (auto& p : m.c) p.assign(n, 0.0f);
  m.alpha.assign(n, 0.0f), m.var.assign(n, 0.0f);
  for (size_t p = 0; p < n; ++p) {
    const float aa = a.plane(kA)[p], ab = b.plane(kA)[p];
    m.alpha[p] = 0.5f * (aa + ab);
    float v = 0.0f;
    for (int c = 0; c < 3; ++c) {
      const float ra = a.plane(kR + c)[p], rb = b.plane(kR + c)[p];
      m.c[c][p] = 0.5f * (ra + rb);
      // Both halves must have hit for two W's to compare; where one half
      // missed the pixel the estimate has nothing to go on, and the other
      // half's W stands with variance 0 (rare: silhouette pixels).
      if (aa > 0.0f && ab > 0.0f) v = std::max(v, 0.5f * std::abs(ra / aa - rb / ab));
    }
    m.var[p] = v * v;
  }
  return m;
}

double rmse(const float* const c[3], const std::vector<float>& alpha, const Film& ref) {
  double s = 0;
  size_t n = 0;
  for (size_t p = 0; p < alpha.size(); ++p) {
    if (alpha[p] < 1.0f || ref.plane(kA)[p] < 1.0f) continue;
    for (int k = 0; k < 3; ++k) {
      const double e = double(c[k][p]) - double(ref.plane(kR + k)[p]);
      s += e * e, ++n;
    }
  }
  return std::sqrt(s / double(std::max<size_t>(n, 1)));
}

// --- --error-table: RMSE against a converged reference ---------------------

// The planes of a reference render the table reads (a crop of the frame):
// W (premultiplied), A, W_error, N, Z. Cached to a raw file so a sweep of
// denoiser settings renders it once.
struct Reference {
  int w = 0, h = 0, spp = 0;
  std::vector<float> c[3], alpha, error, n[3], z;
};

constexpr uint32_t kReferenceMagic = 0x4f424446;  // "OBDF"

bool readReference(const std::string& path, int w, int h, int spp, Reference& r) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return false;
  uint32_t head[4] = {};
  bool ok = std::fread(head, sizeof head, 1, f) == 1 && head[0] == kReferenceMagic && int(head[1]) == w &&
            int(head[2]) == h && int(head[3]) == spp;
  r.w = w, r.h = h, r.spp = spp;
  const size_t n = size_t(w) * size_t(h);
  std::vector<float>* planes[] = {&r.c[0], &r.c[1], &r.c[2], &r.alpha, &r.error, &r.n[0], &r.n[1], &r.n[2], &r.z};
  for (auto* p : planes) {
    p->resize(n);
    ok = ok && std::fread(p->data(), sizeof(float), n, f) == n;
  }
  std::fclose(f);
  return ok;
}

void writeReference(const std::string& path, const Reference& r) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw Error("--reference-cache: cannot write " + path);
  const uint32_t head[4] = {kReferenceMagic, uint32_t(r.w), uint32_t(r.h), uint32_t(r.spp)};
  bool ok = std::fwrite(head, sizeof head, 1, f) == 1;
  const std::vector<float>* planes[] = {&r.c[0], &r.c[1], &r.c[2], &r.alpha, &r.error, &r.n[0], &r.n[1], &r.n[2], &r.z};
  for (auto* p : planes) ok = ok && std::fwrite(p->data(), sizeof(float), p->size(), f) == p->size();
  ok = std::fclose(f) == 0 && ok;
  if (!ok) throw Error("--reference-cache: writing " + path + " failed");
}

Reference referenceFromFilm(const Film& f, int spp) {
  Reference r;
  r.w = f.width(), r.h = f.height(), r.spp = spp;
  const size_t n = size_t(f.width()) * size_t(f.height());
  auto copy = [&](std::vector<float>& to, int c) { to.assign(f.plane(c), f.plane(c) + n); };
  for (int c = 0; c < 3; ++c) copy(r.c[c], kR + c), copy(r.n[c], kNX + c);
  copy(r.alpha, kA), copy(r.z, kZ), copy(r.error, f.find(kErrorPlane));
  return r;
}

// Pixels within `radius` of a geometric edge of the reference: a 4-neighbour
// whose normal is more than 25 degrees off, whose depth differs by more than
// 2 %, or that is not fully covered. The bias of an edge-aware filter lives
// there; the table reports it apart.
std::vector<uint8_t> edgeMask(const Reference& r, int radius) {
  const int w = r.w, h = r.h;
  std::vector<uint8_t> edge(size_t(w) * size_t(h), 0), out(edge.size(), 0);
  auto differs = [&](size_t p, size_t q) {
    const float dot = r.n[0][p] * r.n[0][q] + r.n[1][p] * r.n[1][q] + r.n[2][p] * r.n[2][q];
    return r.alpha[q] < 1.0f || dot < 0.9f || std::abs(r.z[q] - r.z[p]) > 0.02f * r.z[p];
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t p = size_t(y) * size_t(w) + size_t(x);
      edge[p] = (x > 0 && differs(p, p - 1)) || (x + 1 < w && differs(p, p + 1)) ||
                (y > 0 && differs(p, p - size_t(w))) || (y + 1 < h && differs(p, p + size_t(w)));
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool e = false;
      for (int j = std::max(0, y - radius); j <= std::min(h - 1, y + radius) && !e; ++j)
        for (int i = std::max(0, x - radius); i <= std::min(w - 1, x + radius) && !e; ++i)
          e = edge[size_t(j) * size_t(w) + size_t(i)];
      out[size_t(y) * size_t(w) + size_t(x)] = e;
    }
  return out;
}

// Per pixel and channel, over seeds: the sums of x and x^2 for the mean and
// variance of a pass, so bias^2 and variance can be told apart.
struct SeedSums {
  std::vector<double> s1, s2;
  int seeds = 0;
  explicit SeedSums(size_t n) : s1(3 * n, 0.0), s2(3 * n, 0.0) {}
  void add(const float* const c[3], size_t n) {
    for (int k = 0; k < 3; ++k)
      for (size_t p = 0; p < n; ++p) {
        const double x = c[k][p];
        s1[3 * p + size_t(k)] += x, s2[3 * p + size_t(k)] += x * x;
      }
    ++seeds;
  }
};

// The error of a pass against the reference over the pixels `sel` picks
// (fully covered in the reference). E[(x - r)^2] = MSE(x) + Var(r): the
// reference's own variance (its W_error squared, max over channels, so an
// upper bound for each channel) is subtracted. variance = the spread over
// seeds (unbiased), bias2 = mse - variance.
struct ErrorStats {
  double mse = 0, variance = 0, bias2 = 0;
  size_t pixels = 0;
};
ErrorStats errorStats(const SeedSums& s, const Reference& r, const std::vector<uint8_t>& mask, int want) {
  ErrorStats e;
  const double k = s.seeds;
  double sq = 0, var = 0, refVar = 0;
  for (size_t p = 0; p < r.alpha.size(); ++p) {
    if (r.alpha[p] < 1.0f || (want >= 0 && mask[p] != want)) continue;
    ++e.pixels;
    refVar += 3.0 * double(r.error[p]) * double(r.error[p]);
    for (int c = 0; c < 3; ++c) {
      const double s1 = s.s1[3 * p + size_t(c)], s2 = s.s2[3 * p + size_t(c)], ref = r.c[c][p];
      // sum over seeds of (x - ref)^2
      sq += s2 - 2.0 * ref * s1 + k * ref * ref;
      if (s.seeds > 1) var += (s2 - s1 * s1 / k) / (k - 1.0);
    }
  }
  const double m = 3.0 * double(std::max<size_t>(e.pixels, 1));
  e.mse = (sq / k - refVar) / m;
  e.variance = s.seeds > 1 ? var / m : 0.0;
  e.bias2 = e.mse - e.variance;
  return e;
}

std::vector<int> parseList(const std::string& text, const char* option) {
  std::vector<int> v;
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, comma - at);
    char* end = nullptr;
    const long x = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end || x < 2 || x % 2)
      throw Error(std::string(option) + ": expected even sample counts >= 2 separated by commas, got '" + text + "'");
    v.push_back(int(x));
    at = comma + 1;
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The denoiser's cost against the render it cleans"};
  CommonOptions common;
  common.res = "1920x1080";
  common.spp = 16;
  common.runs = 3;
  addCommonOptions(app, common, "smoke run: 320x180, 2 spp, 1 run");
  std::string integrator = "ao";
  int referenceSpp = 0;
  DenoiseSettings ds;
  app.add_option("--kernel", ds.kernel, "Denoiser taps per axis: 3 or 5");
  app.add_option("--iterations", ds.iterations, "Denoiser a-trous iterations");
  app.add_option("--sigma-luminance", ds.sigmaLuminance, "Denoiser luminance term (0: off)");
  app.add_option("--integrator", integrator, "Integrator of the pass (default parameters)");
  app.add_option("--sigma-normal", ds.sigmaNormal, "Denoiser normal term");
  app.add_option("--sigma-depth", ds.sigmaDepth, "Denoiser depth term");
  app.add_option("--depth-tolerance", ds.depthTolerance, "Denoiser depth tolerance");
  app.add_option("--sigma-albedo", ds.sigmaAlbedo, "Denoiser albedo term");
  bool ownWeights = false;
  app.add_flag("--no-symmetric", ownWeights, "Denoiser: each tap its own weight (not the mirrored pair's smaller one)");
  std::vector<std::string> paramText;
  app.add_option("--param", paramText, "Integrator parameter key=value (repeatable)");
  app.add_option("--reference-spp", referenceSpp,
                 "Also render an N-spp reference and print RMSE noisy vs denoised (0: off; --error-table: default 2048)");
  bool errorTable = false;
  std::string crop, referenceCache, sweepText = "16,32,64,128";
  int seeds = 4;
  app.add_flag("--error-table", errorTable,
               "Instead of timing: RMSE against a reference for each --sweep spp over --seeds seeds, noisy and denoised, "
               "bias^2 and variance, near edges and away from them, and the equal-RMSE sample ratio");
  app.add_option("--crop", crop, "--error-table: render only a centred WIDTHxHEIGHT window of --res");
  app.add_option("--reference-cache", referenceCache, "--error-table: read the reference from FILE, or render and write it there");
  app.add_option("--sweep", sweepText, "--error-table: sample counts, comma-separated (default 16,32,64,128)");
  app.add_option("--seeds", seeds, "--error-table: seeds per sample count (default 4)");
  CLI11_PARSE(app, argc, argv);
  ds.symmetric = !ownWeights;
  try {
    if (common.quick) common.res = "320x180", common.spp = 2, common.runs = 1;
    if (common.scenes.empty()) common.scenes = {"viking"};
    const BenchSize size = checkCommonOptions(common);
    if (common.spp < 2 || common.spp % 2) throw Error("--spp: must be even and at least 2 (two halves)");
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());
    std::vector<std::pair<std::string, std::string>> params;
    for (const std::string& kv : paramText) {
      const size_t eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) throw Error("--param: expected key=value, got '" + kv + "'");
      params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    }
    const BenchIntegrator integ(integrator, params);
    if (errorTable) {
      if (seeds < 1) throw Error("--seeds: must be at least 1");
      const std::vector<int> sweep = parseList(sweepText, "--sweep");
      PixelRect window{0, 0, size.width, size.height};
      if (!crop.empty()) {
        const size_t x = crop.find('x');
        const int cw = x == std::string::npos ? -1 : std::atoi(crop.substr(0, x).c_str());
        const int ch = x == std::string::npos ? -1 : std::atoi(crop.substr(x + 1).c_str());
        if (cw <= 0 || ch <= 0 || cw > size.width || ch > size.height)
          throw Error("--crop: expected WIDTHxHEIGHT inside --res, got '" + crop + "'");
        window = {(size.width - cw) / 2, (size.height - ch) / 2, (size.width - cw) / 2 + cw, (size.height - ch) / 2 + ch};
      }
      if (referenceSpp <= 0) referenceSpp = 2048;
      for (const std::string& which : common.scenes) {
        const BenchScene scene = loadScene(which, float(size.width) / float(size.height));
        std::printf("\n%s: %dx%d, window %d,%d-%d,%d, %s", scene.label.c_str(), size.width, size.height, window.x0,
                    window.y0, window.x1, window.y1, integrator.c_str());
        for (const auto& [k, v] : params) std::printf(" %s=%s", k.c_str(), v.c_str());
        std::printf("; denoiser kernel %d, %d iterations, %s taps, sigma n %g z %g (tol %g) l %g a %g\n", ds.kernel,
                    ds.iterations, ds.symmetric ? "symmetric" : "own-weight", ds.sigmaNormal, ds.sigmaDepth,
                    ds.depthTolerance, ds.sigmaLuminance, ds.sigmaAlbedo);
        RenderSettings base = benchRenderSettings(size.width, size.height, 1, threads.threads(), 0);
        base.aovs = true;
        base.region = window;
        Reference ref;
        const int rw = window.x1 - window.x0, rh = window.y1 - window.y0;
        if (referenceCache.empty() || !readReference(referenceCache, rw, rh, referenceSpp, ref)) {
          RenderSettings rs = base;
          rs.spp = referenceSpp, rs.seed = 1000;
          RenderStats st;
          ref = referenceFromFilm(integ.render(*scene.scene, scene.camera, rs, st), referenceSpp);
          std::printf("  reference: %d spp rendered in %.1f s\n", referenceSpp, st.seconds);
          if (!referenceCache.empty()) writeReference(referenceCache, ref);
        } else {
          std::printf("  reference: %d spp read from %s\n", referenceSpp, referenceCache.c_str());
        }
        const size_t n = ref.alpha.size();
        const std::vector<uint8_t> mask = edgeMask(ref, 2);
        double refVar = 0;
        size_t covered = 0, edges = 0;
        for (size_t p = 0; p < n; ++p)
          if (ref.alpha[p] >= 1.0f) refVar += double(ref.error[p]) * ref.error[p], ++covered, edges += mask[p];
        std::printf("  %zu fully covered pixels, %zu within 2 px of an edge; the reference's own RMSE %.5f (subtracted)\n",
                    covered, edges, std::sqrt(refVar / double(std::max<size_t>(covered, 1))));
        struct Row {
          int spp;
          ErrorStats noisy, denoised, renderPath, noisyEdge, denoisedEdge, noisyFlat, denoisedFlat;
          double renderSeconds, denoiseSeconds, meanV;
        };
        std::vector<Row> rows;
        for (int spp : sweep) {
          SeedSums sn(n), sd(n), sr(n);
          std::vector<double> tr, td;
          double sumV = 0;
          for (int k = 0; k < seeds; ++k) {
            RenderSettings s = base;
            s.spp = spp, s.seed = uint32_t(2 * k), s.denoise = true;
            s.cryptomatte.object = true, s.cryptomatte.ranks = 1;
            RenderStats st;
            const Film f = integ.render(*scene.scene, scene.camera, s, st);
            tr.push_back(st.seconds);
            const int noisyPlane = f.find("noisy.R"), cryptoPlane = f.find("CryptoObject00.R");
            if (noisyPlane < 0 || cryptoPlane < 0) throw Error("the render has no noisy.R or CryptoObject00.R plane");
            std::vector<float> var(n);
            std::vector<uint32_t> object(n);
            for (size_t p = 0; p < n; ++p) {
              const float e = f.plane(f.find(kErrorPlane))[p];
              var[p] = e * e;
              if (ref.alpha[p] >= 1.0f) sumV += double(var[p]);
              object[p] = floatToBits(f.plane(cryptoPlane)[p]);
            }
            DenoiseInput in;
            in.width = f.width(), in.height = f.height();
            for (int c = 0; c < 3; ++c) {
              in.color[c] = f.plane(noisyPlane + c);
              in.normal[c] = f.plane(kNX + c);
              in.albedo[c] = integ.needs.albedo ? f.plane(kAlbedoR + c) : nullptr;
            }
            in.alpha = f.plane(kA), in.variance = var.data(), in.depth = f.plane(kZ), in.object = object.data();
            ds.threads = threads.threads();
            std::vector<float> out[3];
            for (auto& p : out) p.assign(n, 0.0f);
            float* outp[3] = {out[0].data(), out[1].data(), out[2].data()};
            const auto t0 = std::chrono::steady_clock::now();
            denoise(in, ds, outp);
            td.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
            const float* noisy[3] = {in.color[0], in.color[1], in.color[2]};
            const float* clean[3] = {out[0].data(), out[1].data(), out[2].data()};
            const float* path[3] = {f.plane(kR), f.plane(kG), f.plane(kB)};
            sn.add(noisy, n), sd.add(clean, n), sr.add(path, n);
          }
          rows.push_back({spp, errorStats(sn, ref, mask, -1), errorStats(sd, ref, mask, -1), errorStats(sr, ref, mask, -1),
                          errorStats(sn, ref, mask, 1), errorStats(sd, ref, mask, 1), errorStats(sn, ref, mask, 0),
                          errorStats(sd, ref, mask, 0), median(tr), median(td), sumV / double(seeds) / double(covered)});
        }
        // The fixed render's MSE falls as a power of spp, faster than 1/spp
        // with the renderer's low-discrepancy samples (measured: the noisy
        // rows' local exponent). The spp a fixed render needs to reach a
        // denoised MSE: log-log interpolation between the noisy rows,
        // extrapolated with the nearest segment's exponent.
        auto fixedSpp = [&](double mse) {
          if (rows.size() < 2) return double(rows[0].spp) * rows[0].noisy.mse / mse;
          size_t i = 0;
          while (i + 2 < rows.size() && rows[i + 1].noisy.mse > mse) ++i;
          const double l0 = std::log(rows[i].noisy.mse), l1 = std::log(rows[i + 1].noisy.mse);
          const double s0 = std::log(double(rows[i].spp)), s1 = std::log(double(rows[i + 1].spp));
          return std::exp(s0 + (std::log(mse) - l0) * (s1 - s0) / (l1 - l0));
        };
        std::printf("  fixed render: MSE x spp =");
        for (const Row& r : rows) std::printf(" %.4g", r.noisy.mse * r.spp);
        for (size_t i = 0; i + 1 < rows.size(); ++i)
          std::printf("%s%.2f", i ? " " : "; MSE ~ spp^-a, a = ",
                      std::log(rows[i].noisy.mse / rows[i + 1].noisy.mse) / std::log(double(rows[i + 1].spp) / rows[i].spp));
        std::printf("\n");
        for (const Row& r : rows)
          std::printf("  %d spp: W_error^2 mean %.3g, noisy variance over seeds %.3g (ratio %.2f)\n", r.spp, r.meanV,
                      r.noisy.variance, r.meanV / r.noisy.variance);
        std::printf("  %4s | %8s %8s %6s %7s | %9s %9s | %9s %9s | %9s %9s | %8s | %6s %6s\n", "spp", "RMSE n", "RMSE d",
                    "MSE/", "eq.spp", "bias2 d", "var d", "edge b2 n", "edge b2 d", "flat b2 d", "flat var d",
                    "RMSE rp", "rend s", "dn s");
        for (const Row& r : rows) {
          auto rm = [](const ErrorStats& e) { return std::sqrt(std::max(0.0, e.mse)); };
          std::printf("  %4d | %8.5f %8.5f %6.2f %6.2fx | %9.2e %9.2e | %9.2e %9.2e | %9.2e %9.2e | %8.5f | %6.2f %6.3f\n",
                      r.spp, rm(r.noisy), rm(r.denoised), r.noisy.mse / r.denoised.mse, fixedSpp(r.denoised.mse) / r.spp,
                      r.denoised.bias2, r.denoised.variance, r.noisyEdge.bias2, r.denoisedEdge.bias2,
                      r.denoisedFlat.bias2, r.denoisedFlat.variance, rm(r.renderPath), r.renderSeconds,
                      r.denoiseSeconds);
        }
      }
      return 0;
    }
    for (const std::string& which : common.scenes) {
      const BenchScene scene = loadScene(which, float(size.width) / float(size.height));
      std::printf("\n%s: %zu triangles, %dx%d, %s, %d spp (two halves of %d), AOVs on\n", scene.label.c_str(),
                  scene.triangles, size.width, size.height, integrator.c_str(), common.spp, common.spp / 2);
      RenderSettings s = benchRenderSettings(size.width, size.height, common.spp / 2, threads.threads(), 0);
      s.aovs = true;
      RenderStats sa, sb;
      const Film fa = integ.render(*scene.scene, scene.camera, s, sa);
      s.seed = 1;
      const Film fb = integ.render(*scene.scene, scene.camera, s, sb);
      const Combined m = combine(fa, fb);

      DenoiseInput in;
      in.width = m.w, in.height = m.h;
      for (int c = 0; c < 3; ++c) {
        in.color[c] = m.c[c].data();
        in.normal[c] = fa.plane(kNX + c);
        in.albedo[c] = integ.needs.albedo ? fa.plane(kAlbedoR + c) : nullptr;
      }
      in.alpha = m.alpha.data(), in.variance = m.var.data(), in.depth = fa.plane(kZ);
      ds.threads = threads.threads();
      std::vector<float> out[3];
      for (auto& p : out) p.assign(m.alpha.size(), 0.0f);
      float* outp[3] = {out[0].data(), out[1].data(), out[2].data()};
      std::vector<double> times;
      for (int run = 0; run < common.runs; ++run) {
        const auto t0 = std::chrono::steady_clock::now();
        denoise(in, ds, outp);
        times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      }
      const double tr = sa.seconds + sb.seconds, td = median(times);
      std::printf("  render loop (both halves) %8.3f s\n", tr);
      std::printf("  denoiser: kernel %d, %d iterations, sigmaLuminance %g\n", ds.kernel, ds.iterations, ds.sigmaLuminance);
      std::printf("  denoise (median of %d)     %8.3f s   %.1f %% of the render   (%.1f ns per pixel and iteration)\n",
                  common.runs, td, 100.0 * td / tr, td * 1e9 / double(m.alpha.size()) / ds.iterations);
      if (referenceSpp > 0) {
        RenderSettings rs = benchRenderSettings(size.width, size.height, referenceSpp, threads.threads(), 1000);
        RenderStats st;
        const Film ref = integ.render(*scene.scene, scene.camera, rs, st);
        const float* noisy[3] = {m.c[0].data(), m.c[1].data(), m.c[2].data()};
        const float* clean[3] = {out[0].data(), out[1].data(), out[2].data()};
        const double en = rmse(noisy, m.alpha, ref), ed = rmse(clean, m.alpha, ref);
        std::printf("  RMSE against %d spp: noisy %.4f, denoised %.4f (MSE / %.1f)\n", referenceSpp, en, ed,
                    en * en / (ed * ed));
      }
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "obscura_bench_denoise: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
