// `obscura fit` (app/fit.h, docs/cli.md "Fitting the improved-AO mapping").
#include "app/fit.h"

#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>

#include <obscura/error.h>
#include <obscura/params.h>
#include "app/interrupt.h"
#include "app/render_setup.h"
#include "core/image/image_io.h"
#include "core/render/render.h"
#include "core/scene/scene.h"
#include "integrators/iao_fit.h"

namespace obscura {
namespace {

// The layers of the render (app/fit.h).
// "visibility", not "alpha": Nuke reserves that layer name (docs/exr.md).
constexpr const char* kAlpha = "visibility.R";
constexpr const char* kE0 = "e0.R";
constexpr const char* kE1 = "e1.R";

std::string csvNumber(double v) {
  char t[40];
  std::snprintf(t, sizeof t, "%.9g", v);
  return t;
}

// The histogram as CSV: each bin's count and means, and the fitted and the
// published curves at the bin's mean alpha (what docs/iao_fit.md plots).
std::string histogramCsv(const IaoHistogram& h, const ImprovedFit& fitted) {
  const ImprovedFit published;
  std::ostringstream o;
  o << "alpha_lo,alpha_hi,pixels,alpha,F0_data,F1_data,F0_fitted,F1_fitted,F0_published,F1_published\n";
  const double k = double(h.bins().size());
  for (size_t i = 0; i < h.bins().size(); ++i) {
    const IaoHistogram::Bin& b = h.bins()[i];
    if (b.n <= 0) continue;
    const double a = b.alpha / b.n;
    o << csvNumber(double(i) / k) << "," << csvNumber(double(i + 1) / k) << "," << csvNumber(b.n) << "," << csvNumber(a)
      << "," << csvNumber(b.y0 / b.n) << "," << csvNumber(b.y1 / b.n) << "," << csvNumber(improvedF0(a, fitted)) << ","
      << csvNumber(improvedF1(a, fitted)) << "," << csvNumber(improvedF0(a, published)) << ","
      << csvNumber(improvedF1(a, published)) << "\n";
  }
  return o.str();
}

void printCurve(const char* title, const CurveFit& fit, const CurveFit& published, const char* lin, const char* nonlin,
                double pubLin, double pubNonlin) {
  std::printf("%s\n", title);
  std::printf("  %-8s = %-22.17g +- %.3g   (published %.17g)\n", lin, fit.linear, fit.seLinear, pubLin);
  std::printf("  %-8s = %-22.17g +- %.3g   (published %.17g)%s\n", nonlin, fit.nonlinear, fit.seNonlinear, pubNonlin,
              fit.atBound ? "  at the end of the searched range: the form does not describe this data" : "");
  std::printf("  residual: rms of bin means %.4g, of pixels %.4g   (published coefficients: %.4g, %.4g)\n",
              fit.rmsMeans, fit.rmsPixels, published.rmsMeans, published.rmsPixels);
}

void printFit(const IaoFit& fit, const IaoHistogram& h) {
  const IaoFit pub = improvedFitResiduals(h, ImprovedFit{});
  const ImprovedFit p;
  printCurve("F0(alpha) = alpha (1 + scale (1 - alpha)^exponent)            [IAO 7]", fit.f0, pub.f0, "scale",
             "exponent", p.f0Scale, p.f0Exponent);
  printCurve("F1(alpha) = A alpha (1 - alpha)^1.5 e^(-B alpha^(1/4))         [IAO 11]", fit.f1, pub.f1, "A", "B",
             p.f1A, p.f1B);
}

}  // namespace

int runFit(const FitArgs& a, const std::atomic<bool>* cancel) {
  // Every option is checked before any scene is read.
  if (a.output.empty()) throw Error("-o: an output path for the coefficients (.json) is required");
  if (!hasExtension(a.output, ".json")) throw Error("-o " + a.output + ": must end in .json (the coefficients are written as JSON)");
  checkWritable(a.output);
  if (!a.histogram.empty()) {
    checkWritable(a.histogram);
    if (!hasExtension(a.histogram, ".csv")) throw Error("--histogram " + a.histogram + ": must end in .csv");
  }
  if (a.bins < 3 || a.bins > 100000) throw Error("--bins: must be in [3, 100000], got " + std::to_string(a.bins));
  if (a.rays < 1 || a.rays > 65536) throw Error("--rays: must be in [1, 65536], got " + std::to_string(a.rays));
  if (a.scenes.empty()) throw Error("fit: at least one scene is required");
  interrupt::setMessage("obscura: interrupted; " + a.output + " was not written");
  sceneOptions(a);

  RenderArgs r;
  static_cast<SceneArgs&>(r) = a;
  r.res = a.res, r.spp = a.spp, r.seed = a.seed, r.threads = a.threads, r.camera = a.camera, r.quiet = a.quiet;
  r.noAovs = true;
  const std::string rays = ",rays=" + std::to_string(a.rays);
  r.passes = {"visibility=ao:weighting=uniform" + rays, "e0=gi:max-depth=0" + rays, "e1=gi:max-depth=1" + rays};
  const std::vector<PassSetup> setups = passSetups(r);
  RenderSettings s = renderSettings(r);
  std::vector<RenderPass> passes;
  for (const PassSetup& p : setups) passes.push_back({p.integrator.get(), p.needs, p.layer});
  std::optional<tbb::global_control> limit;
  if (a.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(a.threads));

  IaoHistogram pooled(a.bins);
  for (const std::string& path : a.scenes) {
    if (!a.quiet) std::fprintf(stderr, "obscura: fit: rendering %s\n", path.c_str());
    Camera camera;
    std::unique_ptr<Scene> scene = loadSceneAndCamera(a, path, a.camera, s.width, s.height, camera);
    // F1 is the one-bounce light at albedo 1 [IAO 8]: every surface white.
    // (Cut-outs keep their alpha: the scene's filters hold their own
    // texture pointers, built at load.)
    for (Material& m : scene->materials) {
      m.baseColorFactor = Vec3(1, 1, 1);
      m.texture = -1;
    }
    interrupt::startPolling();
    RenderStats stats;
    const Film film = render(*scene, camera, passes, s, stats, cancel);
    if (cancel && cancel->load()) {
      std::fprintf(stderr, "obscura: interrupted; %s was not written\n", a.output.c_str());
      return 130;
    }
    const float *alpha = film.plane(film.find(kAlpha)), *e0 = film.plane(film.find(kE0)),
                *e1 = film.plane(film.find(kE1)), *cover = film.plane(kA);
    IaoHistogram h(a.bins);
    const size_t n = size_t(film.width()) * size_t(film.height());
    for (size_t i = 0; i < n; ++i)
      if (cover[i] == 1.0f) h.add(alpha[i], e0[i], double(e1[i]) - double(e0[i]));
    pooled.merge(h);
    if (!a.quiet) std::fprintf(stderr, "obscura: fit: %s: %.0f covered pixels (%.2f s)\n", path.c_str(), h.pixels(), stats.seconds);
    if (a.scenes.size() > 1) {
      try {
        const IaoFit one = fitImprovedAo(h);
        std::printf("%s alone: scale %.6g exponent %.6g A %.6g B %.6g (rms of bin means F0 %.3g, F1 %.3g)\n",
                    path.c_str(), one.coefficients.f0Scale, one.coefficients.f0Exponent, one.coefficients.f1A,
                    one.coefficients.f1B, one.f0.rmsMeans, one.f1.rmsMeans);
      } catch (const Error& e) {
        std::printf("%s alone: no fit (%s)\n", path.c_str(), e.what());
      }
    }
  }

  const IaoFit fit = fitImprovedAo(pooled);
  std::printf("obscura fit: %zu scene%s, %.0f pixels in %d of %d AO bins\n", a.scenes.size(),
              a.scenes.size() == 1 ? "" : "s", fit.pixels, fit.filledBins, fit.bins);
  printFit(fit, pooled);

  std::string settings = "res " + a.res + ", spp " + std::to_string(a.spp) + ", rays " + std::to_string(a.rays) +
                         ", seed " + std::to_string(a.seed) + ", bins " + std::to_string(a.bins) +
                         ", camera " + (a.camera.empty() ? "default" : a.camera);
  OutputSet out;
  out.addText(a.output, improvedFitJson(fit, a.scenes, settings));
  if (!a.histogram.empty()) out.addText(a.histogram, histogramCsv(pooled, fit.coefficients));
  out.commit();
  std::printf("wrote %s%s%s (use: -i multibounce -p mapping=fitted -p fit=%s)\n", a.output.c_str(),
              a.histogram.empty() ? "" : " and ", a.histogram.c_str(), a.output.c_str());
  return 0;
}

}  // namespace obscura
