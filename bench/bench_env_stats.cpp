// obscura_bench_env_stats: the image statistics of bench/env_bench.sh
// (docs/performance.md "Environment lighting"), read from EXR files written
// by `obscura render` and by Blender (bench/cycles/render_env.py). No
// rendering here: the renders are whole `obscura render` processes, timed
// by the script.
//
//   rmse --target T REF1 REF2 -- TEST...
//       shaded.R/G/B of each TEST against the mean of two references of
//       the same settings and different seeds, over the pixels both
//       references cover fully (A = 1): all three channels pooled,
//       RMSE = sqrt(mean e^2). The references' own noise is subtracted:
//       the tests and references are independent, so per value
//           E[(x - r)^2] = MSE(x) + Var(r),  r = (r1 + r2) / 2,
//       and Var(r) = E[(r1 - r2)^2] / 4 is measured from the pair (no
//       W_error exists for shaded.*). Prints per test its spp and
//       obscura:renderTime (render-loop wall seconds), the raw and the
//       corrected RMSE, and RMSE / mean(r); then, for the tests in the
//       order given (increasing spp), where the corrected RMSE first
//       crosses T, interpolated linearly in log spp - log RMSE, with the
//       render time interpolated in log spp - log time. A sweep that never
//       reaches T is extrapolated from its last point by RMSE ~ spp^-1/2
//       (said so).
//   mean MASK IMAGE CHANNELS
//       the mean of each of IMAGE's channels CHANNELS (comma-separated,
//       e.g. shaded.R,shaded.G,shaded.B or R,G,B) over the pixels where
//       MASK's A = 1 (an Obscura render of the same camera and resolution:
//       its fully covered pixels), and over all pixels.
//   header FILE NAME...
//       header attributes of an Obscura EXR, one per line (NAME value).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "core/image/image_io.h"

namespace {

using obscura::ExrImage;

const std::vector<float>& plane(const ExrImage& im, const std::string& name, const std::string& path) {
  for (size_t i = 0; i < im.names.size(); ++i)
    if (im.names[i] == name) return im.planes[i];
  throw std::runtime_error(path + ": no channel " + name);
}

std::string attribute(const ExrImage& im, const std::string& name) {
  for (const auto& a : im.attributes) {
    if (a.name != name) continue;
    std::ostringstream s;
    s.precision(9);
    if (auto p = std::get_if<std::string>(&a.value)) return *p;
    if (auto p = std::get_if<int>(&a.value)) s << *p;
    if (auto p = std::get_if<float>(&a.value)) s << *p;
    return s.str();
  }
  return "";
}

const char* kShaded[3] = {"shaded.R", "shaded.G", "shaded.B"};

struct Point {
  double spp, seconds, rmse;
};

int rmseMode(double target, const std::string& ref1Path, const std::string& ref2Path,
             const std::vector<std::string>& tests) {
  const ExrImage r1 = obscura::readExrImage(ref1Path), r2 = obscura::readExrImage(ref2Path);
  if (r1.width != r2.width || r1.height != r2.height) throw std::runtime_error("references differ in size");
  const size_t n = size_t(r1.width) * r1.height;
  const auto& a1 = plane(r1, "A", ref1Path);
  const auto& a2 = plane(r2, "A", ref2Path);
  std::vector<size_t> pixels;
  for (size_t p = 0; p < n; ++p)
    if (a1[p] == 1.0f && a2[p] == 1.0f) pixels.push_back(p);
  std::vector<float> ref(3 * pixels.size());
  double mean = 0, refVar = 0;
  for (int c = 0; c < 3; ++c) {
    const auto& p1 = plane(r1, kShaded[c], ref1Path);
    const auto& p2 = plane(r2, kShaded[c], ref2Path);
    for (size_t k = 0; k < pixels.size(); ++k) {
      const double x1 = p1[pixels[k]], x2 = p2[pixels[k]];
      ref[3 * k + c] = float(0.5 * (x1 + x2));
      mean += 0.5 * (x1 + x2);
      refVar += 0.25 * (x1 - x2) * (x1 - x2);
    }
  }
  const double values = 3.0 * pixels.size();
  mean /= values;
  refVar /= values;
  std::printf("reference: %s + %s, %zu fully covered pixels, mean shaded %.5f, reference noise RMSE %.5f\n",
              ref1Path.c_str(), ref2Path.c_str(), pixels.size(), mean, std::sqrt(refVar));
  std::printf("%-40s %8s %10s %10s %10s %9s\n", "test", "spp", "render s", "raw RMSE", "RMSE", "RMSE/mean");
  std::vector<Point> points;
  for (const auto& t : tests) {
    const ExrImage im = obscura::readExrImage(t);
    if (im.width != r1.width || im.height != r1.height) throw std::runtime_error(t + ": size differs");
    double se = 0;
    for (int c = 0; c < 3; ++c) {
      const auto& x = plane(im, kShaded[c], t);
      for (size_t k = 0; k < pixels.size(); ++k) {
        const double e = double(x[pixels[k]]) - ref[3 * k + c];
        se += e * e;
      }
    }
    const double mse = se / values;
    const double rmse = std::sqrt(std::max(0.0, mse - refVar));
    const double spp = std::atof(attribute(im, "obscura:spp").c_str());
    const double seconds = std::atof(attribute(im, "obscura:renderTime").c_str());
    std::printf("%-40s %8.0f %10.3f %10.5f %10.5f %9.5f\n", t.c_str(), spp, seconds, std::sqrt(mse), rmse,
                rmse / mean);
    points.push_back({spp, seconds, rmse});
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].rmse > target) continue;
    if (i == 0) {
      std::printf("crossing: already below %g at %g spp (%.3f s)\n", target, points[0].spp, points[0].seconds);
      return 0;
    }
    const Point& a = points[i - 1];
    const Point& b = points[i];
    const double f = (std::log(target) - std::log(a.rmse)) / (std::log(b.rmse) - std::log(a.rmse));
    const double spp = std::exp(std::log(a.spp) + f * (std::log(b.spp) - std::log(a.spp)));
    const double sec = std::exp(std::log(a.seconds) + f * (std::log(b.seconds) - std::log(a.seconds)));
    std::printf("crossing: RMSE %g at %.1f spp, %.3f s render (interpolated between %g and %g spp)\n", target, spp,
                sec, a.spp, b.spp);
    return 0;
  }
  if (!points.empty()) {
    const Point& l = points.back();
    const double spp = l.spp * (l.rmse / target) * (l.rmse / target);
    std::printf("crossing: not reached; extrapolated by RMSE ~ spp^-1/2 from %g spp: %.3g spp, %.3g s render\n",
                l.spp, spp, l.seconds * spp / l.spp);
  }
  return 0;
}

int meanMode(const std::string& maskPath, const std::string& imagePath, const std::string& channels) {
  const ExrImage mask = obscura::readExrImage(maskPath), im = obscura::readExrImage(imagePath);
  if (mask.width != im.width || mask.height != im.height) throw std::runtime_error("mask and image differ in size");
  const auto& a = plane(mask, "A", maskPath);
  std::vector<std::string> names;
  std::stringstream ss(channels);
  for (std::string c; std::getline(ss, c, ',');) names.push_back(c);
  size_t covered = 0;
  for (float v : a) covered += v == 1.0f;
  std::printf("%s: %zu of %zu pixels covered (A = 1 in %s)\n", imagePath.c_str(), covered, a.size(), maskPath.c_str());
  for (const auto& c : names) {
    const auto& x = plane(im, c, imagePath);
    double masked = 0, all = 0;
    for (size_t p = 0; p < x.size(); ++p) {
      all += x[p];
      if (a[p] == 1.0f) masked += x[p];
    }
    std::printf("  %-10s mean over A = 1: %.6f   over all pixels: %.6f\n", c.c_str(), masked / double(covered),
                all / double(x.size()));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) try {
  const std::vector<std::string> args(argv + 1, argv + argc);
  const char* usage =
      "usage: obscura_bench_env_stats rmse [--target T] REF1 REF2 -- TEST...\n"
      "       obscura_bench_env_stats mean MASK.exr IMAGE.exr CH1,CH2,...\n"
      "       obscura_bench_env_stats header FILE.exr NAME...\n";
  if (args.empty()) {
    std::fputs(usage, stderr);
    return 2;
  }
  if (args[0] == "rmse") {
    double target = 0.01;
    size_t i = 1;
    if (i + 1 < args.size() && args[i] == "--target") {
      target = std::atof(args[i + 1].c_str());
      i += 2;
    }
    if (i + 3 > args.size() || args[i + 2] != "--") {
      std::fputs(usage, stderr);
      return 2;
    }
    return rmseMode(target, args[i], args[i + 1], {args.begin() + long(i) + 3, args.end()});
  }
  if (args[0] == "mean" && args.size() == 4) return meanMode(args[1], args[2], args[3]);
  if (args[0] == "header" && args.size() >= 3) {
    const ExrImage im = obscura::readExrImage(args[1]);
    for (size_t i = 2; i < args.size(); ++i) std::printf("%s %s\n", args[i].c_str(), attribute(im, args[i]).c_str());
    return 0;
  }
  std::fputs(usage, stderr);
  return 2;
} catch (const std::exception& e) {
  std::fprintf(stderr, "obscura_bench_env_stats: %s\n", e.what());
  return 1;
}
