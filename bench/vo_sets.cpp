// obscura_bench_vo_sets: VO's sample sets (integrators/screen_space/
// sample_sets.h) - the reproduction of the paper's Figure 4 (VO §4.5: "certain
// generated sample sets produce much less noise than those around them") and
// the optimiser's cost. docs/vo_sample_sets.md shows the output.
//
// Figure 4 (--figure4): the noise of the VO estimate against the number of
// samples, for line samples (disk sets, with and without the centre) and
// point samples (ball sets), for both generators (`relaxed`, the default,
// and `optimised`, the paper's optimiser). The noise is what the paper's
// per-pixel randomization leaves: the variance, over random rotations of the
// set (lines: about the view axis; points: uniform in SO(3)), of the
// estimate at a fixed configuration of matter in the unit ball, averaged
// over configurations. The configurations are depth-buffer-like (the
// matter is everything behind a surface z = d(x, y), z along the view):
//   plane:  d = (s - n_x x - n_y y) / n_z, n uniform on the hemisphere
//           facing the camera, s uniform in [-1, 1];
//   crease: two such planes, the matter behind either (concave) or behind
//           both (convex), each with probability 1/2.
// Estimates (docs/math.md §8, the unit-ball frame):
//   lines:  V = Sum_k w_k clamp((d(x_k, y_k) + z_k) / (2 z_k), 0, 1),
//           z_k = sqrt(1 - x_k^2 - y_k^2), w_k the set's weights (each
//           chord's share of the ball's volume);
//   points: V = Sum_k w_k [z_k <= d(x_k, y_k)].
// The same configurations and rotations serve every count and generator
// (common random numbers), so differences between neighbouring counts are
// measured far more precisely than each value's standard error (printed:
// the spread of the per-configuration variances over sqrt(configs)).
// Also printed, the mean squared error against the exact V (a 512^2
// midpoint quadrature of the chords) - variance plus the rotation-averaged
// set's bias, which the integrator removes for points by shifting radii per
// layer but not here.
//
// --time: the optimiser's time per count (the median of --runs) against the
// relaxed sets'; every run is a fresh optimisation (not the memoised one).
//
// Run:   build/bench/obscura_bench_vo_sets --figure4 > fig4.csv    (~6 min on 2 busy cores)
//        python3 bench/vo_sets_plot.py fig4.csv docs/vo_sample_sets.svg
//        build/bench/obscura_bench_vo_sets --figure4 --seed 2 --max-lines 12 --max-points 14
//                                     (other seeds of the sets, same configurations)
//        build/bench/obscura_bench_vo_sets --time --runs 3 --threads 2
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench/common.h"
#include "integrators/screen_space/sample_sets.h"

using namespace obscura;
using namespace obscura::screen_space;

namespace {

// splitmix64: a fixed stream on every platform.
struct Rng {
  uint64_t s;
  double uniform() {
    uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return double((z ^ (z >> 31)) >> 11) * 0x1p-53;
  }
};

struct Plane {
  double a, b, c;  // d(x, y) = a + b x + c y
  double depth(double x, double y) const { return a + b * x + c * y; }
};

struct Config {
  Plane p, q;
  int kind;  // 0 plane, 1 concave crease (min depth), 2 convex (max depth)
  double exact;
  double depth(double x, double y) const {
    const double d = p.depth(x, y);
    return kind == 0 ? d : kind == 1 ? std::min(d, q.depth(x, y)) : std::max(d, q.depth(x, y));
  }
};

Plane randomPlane(Rng& r) {
  // n uniform on the hemisphere n_z > 0 (the surface faces the camera).
  const double nz = std::max(r.uniform(), 1e-6), phi = 2.0 * M_PI * r.uniform();
  const double st = std::sqrt(1.0 - nz * nz), nx = st * std::cos(phi), ny = st * std::sin(phi);
  const double s = 2.0 * r.uniform() - 1.0;
  return Plane{s / nz, -nx / nz, -ny / nz};
}

// V = (1 / (4 pi / 3)) Int_disk clamp(d + z_s, 0, 2 z_s) dA, 512^2 midpoints
// (error ~1e-5, its square far below the MSEs it is subtracted from).
double exactV(const Config& c) {
  const int g = 512;
  const double h = 2.0 / g;
  double sum = 0.0;
  for (int j = 0; j < g; ++j)
    for (int i = 0; i < g; ++i) {
      const double x = -1 + (i + 0.5) * h, y = -1 + (j + 0.5) * h, r2 = x * x + y * y;
      if (r2 >= 1.0) continue;
      const double zs = std::sqrt(1.0 - r2);
      sum += std::clamp(c.depth(x, y) + zs, 0.0, 2.0 * zs);
    }
  return sum * h * h / (4.0 * M_PI / 3.0);
}

// Shoemake's uniform random rotation (as a 3x3 matrix) from three uniforms.
std::array<double, 9> randomRotation(Rng& r) {
  const double u1 = r.uniform(), u2 = 2.0 * M_PI * r.uniform(), u3 = 2.0 * M_PI * r.uniform();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const double w = a * std::sin(u2), x = a * std::cos(u2), y = b * std::sin(u3), z = b * std::cos(u3);
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

struct Stats {
  double variance[2] = {0, 0}, varianceSE[2] = {0, 0}, mse[2] = {0, 0};  // per family: planes, creases
  std::vector<double> perConfig;  // the variance over rotations at each configuration
};

// The mean over configurations of the variance over rotations, per family.
Stats measure(const std::vector<Vec3>& pts, const std::vector<float>& w, bool lines, const std::vector<Config>& configs,
              int rotations, uint64_t seed) {
  Stats st;
  double sumV[2] = {0, 0}, sumV2[2] = {0, 0};
  int count[2] = {0, 0};
  Rng rng{seed};
  std::vector<double> est(static_cast<size_t>(rotations));
  for (const Config& c : configs) {
    for (int t = 0; t < rotations; ++t) {
      double v = 0.0;
      if (lines) {
        const double phi = 2.0 * M_PI * rng.uniform(), cs = std::cos(phi), sn = std::sin(phi);
        for (size_t k = 0; k < pts.size(); ++k) {
          const double x = cs * pts[k].x - sn * pts[k].y, y = sn * pts[k].x + cs * pts[k].y;
          const double zs = std::sqrt(std::max(0.0, 1.0 - x * x - y * y));
          if (zs > 0.0) v += w[k] * std::clamp((c.depth(x, y) + zs) / (2.0 * zs), 0.0, 1.0);
        }
      } else {
        const std::array<double, 9> R = randomRotation(rng);
        for (size_t k = 0; k < pts.size(); ++k) {
          const double x = R[0] * pts[k].x + R[1] * pts[k].y + R[2] * pts[k].z;
          const double y = R[3] * pts[k].x + R[4] * pts[k].y + R[5] * pts[k].z;
          const double z = R[6] * pts[k].x + R[7] * pts[k].y + R[8] * pts[k].z;
          if (z <= c.depth(x, y)) v += w[k];
        }
      }
      est[size_t(t)] = v;
    }
    double mean = 0.0, var = 0.0, mse = 0.0;
    for (double v : est) mean += v;
    mean /= rotations;
    for (double v : est) var += (v - mean) * (v - mean), mse += (v - c.exact) * (v - c.exact);
    var /= rotations - 1;
    mse /= rotations;
    const int f = c.kind == 0 ? 0 : 1;
    sumV[f] += var, sumV2[f] += var * var, st.mse[f] += mse, ++count[f];
    st.perConfig.push_back(var);
  }
  for (int f = 0; f < 2; ++f) {
    st.variance[f] = sumV[f] / count[f];
    st.varianceSE[f] = std::sqrt(std::max(0.0, sumV2[f] / count[f] - st.variance[f] * st.variance[f]) / count[f]);
    st.mse[f] /= count[f];
  }
  return st;
}

int figure4(int configsPerFamily, int rotations, int maxLines, int maxPoints, uint32_t seed) {
  Rng rng{0xf164ULL};
  std::vector<Config> configs;
  for (int f = 0; f < 2; ++f)
    for (int i = 0; i < configsPerFamily; ++i) {
      Config c{randomPlane(rng), randomPlane(rng), f == 0 ? 0 : (rng.uniform() < 0.5 ? 1 : 2), 0.0};
      configs.push_back(c);
    }
  for (Config& c : configs) c.exact = exactV(c);
  std::printf("# configs %d planes + %d creases, %d rotations each\n", configsPerFamily, configsPerFamily, rotations);
  std::printf("samples,n,generator,var_plane,se_plane,var_crease,se_crease,mse_plane,mse_crease,"
              "diff_prev,se_diff_prev\n");
  // diff_prev: the mean over all configurations of variance(n) - variance(n
  // - 1), same samples and generator, with its standard error from the
  // paired differences (common configurations and rotations).
  std::vector<double> previous[2];
  const auto row = [&](const char* samples, int n, const char* gen, const Stats& s, std::vector<double>& prev) {
    double diff = 0.0, diff2 = 0.0;
    const bool paired = prev.size() == s.perConfig.size();
    for (size_t i = 0; paired && i < prev.size(); ++i) {
      const double d = s.perConfig[i] - prev[i];
      diff += d, diff2 += d * d;
    }
    const double m = double(s.perConfig.size());
    diff /= m;
    const double se = std::sqrt(std::max(0.0, diff2 / m - diff * diff) / m);
    std::printf("%s,%d,%s,%.6g,%.3g,%.6g,%.3g,%.6g,%.6g,", samples, n, gen, s.variance[0], s.varianceSE[0],
                s.variance[1], s.varianceSE[1], s.mse[0], s.mse[1]);
    if (paired)
      std::printf("%.6g,%.3g\n", diff, se);
    else
      std::printf(",\n");
    prev = s.perConfig;
    std::fflush(stdout);
  };
  for (bool centre : {true, false}) {
    previous[0].clear(), previous[1].clear();
    for (int n = 2; n <= maxLines; ++n)
      for (bool opt : {false, true}) {
        const DiskSet d = opt ? optimisedDiskSet(n, centre, seed) : diskSet(n, centre, seed);
        std::vector<Vec3> p;
        for (int k = 0; k < n; ++k) p.emplace_back(d.x[k], d.y[k], 0.0f);
        row(centre ? "lines+centre" : "lines", n, opt ? "optimised" : "relaxed",
            measure(p, d.w, true, configs, rotations, 0x11e5ULL), previous[opt]);
      }
  }
  previous[0].clear(), previous[1].clear();
  for (int n = 2; n <= maxPoints; ++n)
    for (bool opt : {false, true}) {
      const BallSet b = opt ? optimisedBallSet(n, seed) : ballSet(n, seed);
      row("points", n, opt ? "optimised" : "relaxed", measure(b.p, b.w, false, configs, rotations, 0x9017ULL),
          previous[opt]);
    }
  return 0;
}

int timing(int runs, int threads) {
  std::printf("# median of %d runs, %d threads (0: all); ms\n", runs, threads);
  std::printf("%5s %12s %12s %12s %12s %12s\n", "n", "ball relax", "disk relax", "ball opt", "disk+c opt", "disk opt");
  for (int n : {1, 5, 9, 12, 16, 33, 64}) {
    std::vector<double> t[5];
    for (int r = 0; r < runs; ++r) {
      const auto ms = [](auto f) {
        const auto t0 = std::chrono::steady_clock::now();
        f();
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      };
      t[0].push_back(ms([&] { ballSet(n); }));
      t[1].push_back(ms([&] { diskSet(n, true); }));
      t[2].push_back(ms([&] { optimiseBall(n, 1, kVoStarts, threads); }));
      t[3].push_back(ms([&] { optimiseDisk(n, true, 1, kVoStarts, threads); }));
      t[4].push_back(ms([&] { optimiseDisk(n, false, 1, kVoStarts, threads); }));
    }
    using bench::median;
    std::printf("%5d %12.1f %12.1f %12.1f %12.1f %12.1f\n", n, median(t[0]), median(t[1]), median(t[2]), median(t[3]),
                median(t[4]));
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"VO's sample sets: Figure 4 (variance against count) and the optimiser's cost"};
  bool fig4 = false, time = false;
  int configs = 2000, rotations = 128, maxLines = 20, maxPoints = 36, runs = 3, threads = 0;
  uint32_t seed = 1;
  app.add_flag("--figure4", fig4, "print the variance against count (CSV)");
  app.add_flag("--time", time, "time the generators");
  app.add_option("--configs", configs, "configurations per family (planes, creases)");
  app.add_option("--rotations", rotations, "random rotations per configuration");
  app.add_option("--max-lines", maxLines, "largest line count");
  app.add_option("--max-points", maxPoints, "largest point count");
  app.add_option("--seed", seed, "the sets' seed (vo uses 1)");
  app.add_option("--runs", runs, "timing runs (median)");
  app.add_option("--threads", threads, "optimiser threads (0: all)");
  CLI11_PARSE(app, argc, argv);
  if (fig4) return figure4(configs, rotations, maxLines, maxPoints, seed);
  if (time) return timing(runs, threads);
  std::printf("%s", app.help().c_str());
  return 1;
}
