// obscura_bench_denoise: the denoiser's cost against the render it cleans
// (README "Denoising", docs/denoise.md).
//
// Renders the pass as two independent halves of spp/2 samples (seeds s and
// s + 1) with the AOVs on, combines them into the spp pass and its
// per-pixel variance ((W_a - W_b) / 2)^2 (max over channels: what the
// film's W.error holds, squared), then times core/denoise on it. Prints the
// render loop's time (both halves), the denoiser's (median over runs) and
// their ratio; the goal is a denoiser under 10 % of the render at
// 1920x1080. With --reference-spp N it also renders an N-spp reference and
// prints the RMSE of W (fully covered pixels) noisy and denoised.
//
// Run:   build/bench/obscura_bench_denoise                 viking room, 1920x1080, ao, 16 spp, 3 runs
//        build/bench/obscura_bench_denoise --quick         smoke run (320x180, 2 spp, 1 run)
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>

#include "bench/common.h"
#include "core/denoise.h"
#include "core/error.h"

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
  app.add_option("--reference-spp", referenceSpp, "Also render an N-spp reference and print RMSE noisy vs denoised (0: off)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (common.quick) common.res = "320x180", common.spp = 2, common.runs = 1;
    if (common.scenes.empty()) common.scenes = {"viking"};
    const BenchSize size = checkCommonOptions(common);
    if (common.spp < 2 || common.spp % 2) throw Error("--spp: must be even and at least 2 (two halves)");
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());
    const BenchIntegrator integ(integrator, {});
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
