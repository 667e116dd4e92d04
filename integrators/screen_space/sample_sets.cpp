#include "integrators/screen_space/sample_sets.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <obscura/error.h>

namespace obscura::screen_space {
namespace {

using P3 = std::array<double, 3>;

// splitmix64: a fixed, platform-independent stream (std:: distributions are
// not specified bit for bit).
struct Rng {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1p-53; }
};

double dist2(const P3& a, const P3& b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}

enum class Shape { Ball, Disk, Cube };

// The domain, its uniform sampling, its projection, and a discrete Voronoi
// grid: cell centres with the weight each carries in the integral.
struct Domain {
  Shape shape;
  int dims;
  std::vector<P3> cells;
  std::vector<double> cellWeight;

  explicit Domain(Shape s) : shape(s), dims(s == Shape::Disk ? 2 : 3) {
    // Grid resolutions: ~33k cells in each domain, enough that a cell is a
    // small fraction of a Voronoi region for n up to a few hundred.
    if (shape == Shape::Disk) {
      const int g = 200;
      for (int j = 0; j < g; ++j)
        for (int i = 0; i < g; ++i) {
          const double x = -1.0 + (i + 0.5) * 2.0 / g, y = -1.0 + (j + 0.5) * 2.0 / g;
          const double r2 = x * x + y * y;
          if (r2 >= 1.0) continue;
          cells.push_back({x, y, 0.0});
          cellWeight.push_back(2.0 * std::sqrt(1.0 - r2));  // the ball's chord above the cell
        }
    } else if (shape == Shape::Ball) {
      const int g = 40;
      for (int k = 0; k < g; ++k)
        for (int j = 0; j < g; ++j)
          for (int i = 0; i < g; ++i) {
            const P3 c{-1.0 + (i + 0.5) * 2.0 / g, -1.0 + (j + 0.5) * 2.0 / g, -1.0 + (k + 0.5) * 2.0 / g};
            if (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] >= 1.0) continue;
            cells.push_back(c);
            cellWeight.push_back(1.0);
          }
    } else {
      const int g = 32;
      for (int k = 0; k < g; ++k)
        for (int j = 0; j < g; ++j)
          for (int i = 0; i < g; ++i) {
            cells.push_back({(i + 0.5) / g, (j + 0.5) / g, (k + 0.5) / g});
            cellWeight.push_back(1.0);
          }
    }
  }

  double volume() const { return shape == Shape::Ball ? 4.0 / 3.0 * M_PI : shape == Shape::Disk ? M_PI : 1.0; }

  P3 sample(Rng& r) const {
    for (;;) {
      P3 p{r.uniform(), r.uniform(), dims == 3 ? r.uniform() : 0.0};
      if (shape == Shape::Cube) return p;
      for (int d = 0; d < dims; ++d) p[d] = 2.0 * p[d] - 1.0;
      if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] < 1.0) return p;
    }
  }

  void project(P3& p) const {
    if (shape == Shape::Cube) {
      for (double& c : p) c = std::clamp(c, 0.0, std::nextafter(1.0, 0.0));
      return;
    }
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    if (r > 1.0)
      for (double& c : p) c /= r;
  }

  // The nearest point of every cell: the cells' weight (into `weight`) and
  // weighted centroid (into `centroid`) per point.
  void voronoi(const std::vector<P3>& pts, std::vector<double>& weight, std::vector<P3>& centroid) const {
    weight.assign(pts.size(), 0.0);
    centroid.assign(pts.size(), P3{0, 0, 0});
    for (size_t c = 0; c < cells.size(); ++c) {
      size_t best = 0;
      double bd = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < pts.size(); ++i) {
        const double d = dist2(cells[c], pts[i]);
        if (d < bd) bd = d, best = i;
      }
      weight[best] += cellWeight[c];
      for (int d = 0; d < 3; ++d) centroid[best][d] += cellWeight[c] * cells[c][d];
    }
    for (size_t i = 0; i < pts.size(); ++i)
      if (weight[i] > 0)
        for (int d = 0; d < 3; ++d) centroid[i][d] /= weight[i];
      else
        centroid[i] = pts[i];
  }
};

// Dart throwing: a candidate is kept when it is at least r from every kept
// point; r shrinks whenever many candidates in a row fail, so n points always
// arrive. `fixed` points (the disk's centre) are placed first.
std::vector<P3> poissonDisk(const Domain& dom, int n, const std::vector<P3>& fixed, Rng& rng) {
  std::vector<P3> pts = fixed;
  // Start near the packing radius of n points in the domain.
  double r = 0.9 * std::pow(dom.volume() / n, 1.0 / dom.dims);
  int failures = 0;
  while (int(pts.size()) < n) {
    const P3 c = dom.sample(rng);
    bool ok = true;
    for (const P3& q : pts)
      if (dist2(c, q) < r * r) {
        ok = false;
        break;
      }
    if (ok) {
      pts.push_back(c);
      failures = 0;
    } else if (++failures > 200) {
      r *= 0.95;
      failures = 0;
    }
  }
  return pts;
}

double repulsionEnergy(const std::vector<P3>& p) {
  double e = 0.0;
  for (size_t i = 0; i < p.size(); ++i)
    for (size_t j = i + 1; j < p.size(); ++j) {
      const double d2 = std::max(dist2(p[i], p[j]), 1e-24);
      e += 1.0 / (d2 * std::sqrt(d2));
    }
  return e;
}

// Points spread by a 1/d^4 repulsion (energy sum 1/d^3) with adaptive step:
// a step that lowers the energy is kept and the next one is longer; one that
// does not is undone and the step halves (VO §4.5). Points pushed out of the
// domain are projected back onto it; every `lloydEvery` iterations a Lloyd
// step moves each point to its Voronoi cell's centroid, which pulls the
// points the repulsion piles onto the boundary back inside.
void relax(const Domain& dom, std::vector<P3>& pts, size_t firstFree, int rounds, int itersPerRound) {
  const size_t n = pts.size();
  if (n - firstFree == 0) return;
  std::vector<P3> force(n), trial(n), centroid;
  std::vector<double> weight;
  double h = 0.1 * std::pow(dom.volume() / double(n), 1.0 / dom.dims);
  for (int round = 0; round < rounds; ++round) {
    double energy = repulsionEnergy(pts);
    for (int it = 0; it < itersPerRound && n > 1; ++it) {
      double fmax = 0.0;
      for (size_t i = 0; i < n; ++i) {
        P3 f{0, 0, 0};
        for (size_t j = 0; j < n; ++j) {
          if (i == j) continue;
          const double d2 = std::max(dist2(pts[i], pts[j]), 1e-24);
          const double s = 1.0 / (d2 * d2 * std::sqrt(d2));  // |f| = 1/d^4 along (pi - pj)/d
          for (int d = 0; d < 3; ++d) f[d] += s * (pts[i][d] - pts[j][d]);
        }
        force[i] = f;
        if (i >= firstFree) fmax = std::max(fmax, std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
      }
      if (!(fmax > 0.0)) break;
      for (size_t i = 0; i < n; ++i) {
        trial[i] = pts[i];
        if (i < firstFree) continue;
        for (int d = 0; d < 3; ++d) trial[i][d] += h * force[i][d] / fmax;
        dom.project(trial[i]);
      }
      const double e = repulsionEnergy(trial);
      if (e < energy) {
        pts.swap(trial);
        energy = e;
        h *= 1.2;
      } else {
        h *= 0.5;
      }
    }
    dom.voronoi(pts, weight, centroid);
    for (size_t i = firstFree; i < n; ++i) pts[i] = centroid[i];
  }
}

void checkCount(int n) {
  if (n < 1 || n > 1024) throw Error("sample set: count " + std::to_string(n) + " outside [1, 1024]");
}

}  // namespace

// The relaxed set of n points in `shape` (the `fixed` ones first, never
// moved) and the shares of their Voronoi cells, normalized to sum 1.
static void relaxedSet(Shape shape, int n, uint64_t seed, const std::vector<P3>& fixed, std::vector<P3>& pts,
                std::vector<double>& share) {
  checkCount(n);
  const Domain dom(shape);
  Rng rng{seed};
  pts = poissonDisk(dom, n, fixed, rng);
  relax(dom, pts, fixed.size(), 6, 25);
  std::vector<P3> centroid;
  dom.voronoi(pts, share, centroid);
  double total = 0.0;
  for (double w : share) total += w;
  for (double& w : share) w /= total;
}

BallSet ballSet(int n, uint32_t seed) {
  std::vector<P3> pts;
  std::vector<double> share;
  relaxedSet(Shape::Ball, n, 0xba11ULL * 0x100000001ULL + seed, {}, pts, share);
  BallSet s;
  for (int i = 0; i < n; ++i) {
    s.p.emplace_back(float(pts[i][0]), float(pts[i][1]), float(pts[i][2]));
    s.w.push_back(float(share[i]));
  }
  return s;
}

DiskSet diskSet(int n, bool centre, uint32_t seed) {
  std::vector<P3> pts, fixed;
  if (centre) fixed.push_back({0, 0, 0});
  std::vector<double> share;
  relaxedSet(Shape::Disk, n, 0xd15cULL * 0x100000001ULL + seed + (centre ? 0x51ULL : 0ULL), fixed, pts, share);
  DiskSet s;
  for (int i = 0; i < n; ++i) {
    s.x.push_back(float(pts[i][0]));
    s.y.push_back(float(pts[i][1]));
    s.w.push_back(float(share[i]));
  }
  return s;
}

std::vector<Vec3> cubeSet(int n, uint32_t seed) {
  checkCount(n);
  const Domain dom(Shape::Cube);
  Rng rng{0xc0beULL * 0x100000001ULL + seed};
  std::vector<P3> pts = poissonDisk(dom, n, {}, rng);
  // Lloyd relaxation alone (AT §4.1): no repulsion.
  std::vector<double> weight;
  std::vector<P3> centroid;
  for (int it = 0; it < 20; ++it) {
    dom.voronoi(pts, weight, centroid);
    pts = centroid;
  }
  std::vector<Vec3> out;
  for (const P3& p : pts) out.emplace_back(float(p[0]), float(p[1]), float(p[2]));
  return out;
}

float minimumDistance(const std::vector<Vec3>& p) {
  float best = kInfinity;
  for (size_t i = 0; i < p.size(); ++i)
    for (size_t j = i + 1; j < p.size(); ++j) best = std::min(best, length(p[i] - p[j]));
  return best;
}

}  // namespace obscura::screen_space
