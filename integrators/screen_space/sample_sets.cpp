#include "integrators/screen_space/sample_sets.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

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

// ---------------------------------------------------------------------------
// The VO §4.5 optimiser (docs/vo_sample_sets.md).
//
// A discrete Voronoi diagram on the paper's grids - 512^2 cells over the
// disk's square, 128^3 over the ball's cube - computed exactly per row of
// cells: along a row (y, z fixed) the squared distance to point i is
// x^2 + (-2 p_i.x) x + (p_i.x^2 + (y - p_i.y)^2 + (z - p_i.z)^2), so the
// nearest point is the lower envelope of n lines in x (slopes -2 p_i.x, the
// same order on every row). Each row costs O(n) plus its runs, not
// O(cells * n): a 128^3 diagram of 16 points is ~13k rows * 16 lines.
struct VoronoiGrid {
  Shape shape;
  int g;
  double h;
  struct Row {
    double y, z;
    int i0, i1;     // cells i0..i1-1 lie inside the domain
    size_t prefix;  // offset of the row's prefix sums (disk only)
  };
  std::vector<Row> rows;
  // Disk cells carry the ball's chord above them, 2 sqrt(1 - x^2 - y^2)
  // (VO footnote 5): per row, prefix sums of the weight and weight * x.
  std::vector<double> sumW, sumWX;

  VoronoiGrid(Shape s, int cells) : shape(s), g(cells), h(2.0 / g) {
    const auto centreOf = [&](int i) { return -1.0 + (i + 0.5) * h; };
    const int layers = shape == Shape::Ball ? g : 1;
    for (int k = 0; k < layers; ++k)
      for (int j = 0; j < g; ++j) {
        const double y = centreOf(j), z = shape == Shape::Ball ? centreOf(k) : 0.0;
        const double rest = 1.0 - y * y - z * z;
        int i0 = g, i1 = 0;
        for (int i = 0; i < g; ++i)
          if (centreOf(i) * centreOf(i) < rest) i0 = std::min(i0, i), i1 = i + 1;
        if (i0 >= i1) continue;
        Row row{y, z, i0, i1, sumW.size()};
        if (shape == Shape::Disk) {
          double w = 0.0, wx = 0.0;
          sumW.push_back(0.0), sumWX.push_back(0.0);
          for (int i = i0; i < i1; ++i) {
            const double x = centreOf(i), c = 2.0 * std::sqrt(std::max(0.0, rest - x * x));
            w += c, wx += c * x;
            sumW.push_back(w), sumWX.push_back(wx);
          }
        }
        rows.push_back(row);
      }
  }

  // The weight of cells [a, b) of a row and its first moment in x.
  void run(const Row& row, int a, int b, double& w, double& wx) const {
    if (shape == Shape::Disk) {
      w = sumW[row.prefix + (b - row.i0)] - sumW[row.prefix + (a - row.i0)];
      wx = sumWX[row.prefix + (b - row.i0)] - sumWX[row.prefix + (a - row.i0)];
    } else {  // unit weight per cell; sum of cell centres -1 + (i + 1/2) h over [a, b)
      w = double(b - a);
      wx = w * (-1.0 + h * 0.5 * double(a + b));
    }
  }

  // Each point's share (its cells' weight, normalized to sum 1) and
  // weighted centroid.
  void diagram(const std::vector<P3>& pts, std::vector<double>& share, std::vector<P3>& centroid) const {
    const size_t n = pts.size();
    share.assign(n, 0.0);
    std::vector<P3> moment(n, P3{0, 0, 0});
    std::vector<int> order(n);
    for (size_t i = 0; i < n; ++i) order[i] = int(i);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return pts[a][0] < pts[b][0]; });
    struct Line {
      double m, b;
      int id;
    };
    std::vector<Line> hull;
    hull.reserve(n);
    for (const Row& row : rows) {
      // Lines by decreasing slope (increasing x of the point); of equal
      // slopes the lower one.
      hull.clear();
      for (int id : order) {
        const P3& p = pts[id];
        const Line l{-2.0 * p[0], p[0] * p[0] + (row.y - p[1]) * (row.y - p[1]) + (row.z - p[2]) * (row.z - p[2]), id};
        if (!hull.empty() && hull.back().m == l.m) {
          if (l.b >= hull.back().b) continue;
          hull.pop_back();
        }
        while (hull.size() >= 2) {
          const Line& a = hull[hull.size() - 2];
          const Line& c = hull.back();
          // c is never lowest once l undercuts a no later than c does.
          if ((l.b - a.b) * (a.m - c.m) <= (c.b - a.b) * (a.m - l.m))
            hull.pop_back();
          else
            break;
        }
        hull.push_back(l);
      }
      int a = row.i0;
      for (size_t t = 0; t < hull.size() && a < row.i1; ++t) {
        int b = row.i1;
        if (t + 1 < hull.size()) {
          // Cells up to the breakpoint with the next line (cell centres
          // -1 + (i + 1/2) h <= x belong to this one).
          const double x = (hull[t + 1].b - hull[t].b) / (hull[t].m - hull[t + 1].m);
          const double last = std::floor((x + 1.0) / h - 0.5);
          b = last < double(a) ? a : last + 1.0 >= double(row.i1) ? row.i1 : int(last) + 1;
        }
        if (b > a) {
          double w, wx;
          run(row, a, b, w, wx);
          const int id = hull[t].id;
          share[id] += w;
          moment[id][0] += wx, moment[id][1] += w * row.y, moment[id][2] += w * row.z;
        }
        a = b;
      }
    }
    double total = 0.0;
    for (double w : share) total += w;
    centroid.resize(n);
    for (size_t i = 0; i < n; ++i) {
      for (int d = 0; d < 3; ++d) centroid[i][d] = share[i] > 0.0 ? moment[i][d] / share[i] : pts[i][d];
      share[i] /= total;
    }
  }
};

// The paper's grids (512^2, 128^3) and half-resolution ones (256^2, 64^3)
// for the charge's tuning between rounds, 4x / 8x cheaper: the tuning needs
// only the sign of the points' radial offset from their centroids, which a
// half-resolution diagram gets right (a cell's centroid moves by under half
// a fine cell). The shares that pick the round, the start and the weights
// are the paper's grids'.
const VoronoiGrid& voronoiGrid(Shape s, bool fine) {
  static const VoronoiGrid disk(Shape::Disk, 512), ball(Shape::Ball, 128);
  static const VoronoiGrid diskCoarse(Shape::Disk, 256), ballCoarse(Shape::Ball, 64);
  return s == Shape::Disk ? (fine ? disk : diskCoarse) : (fine ? ball : ballCoarse);
}

// The paper's error: the goal is equal integrals over the Voronoi regions
// (VO §4.5), so the spread of the shares about 1/n, relative:
// (1/n) Sum (n w_i - 1)^2.
double shareError(const std::vector<double>& share) {
  const double n = double(share.size());
  double e = 0.0;
  for (double w : share) e += (n * w - 1.0) * (n * w - 1.0);
  return e / n;
}

// The boundary charge's potential per unit charge at radius r (VO §4.5): a
// uniform charge on the boundary with the points' own 1/d^4 force, whose
// potential is 1/(3 d^3). Unlike 1/d^2 (Gauss: no net force inside), this
// pushes inward, the harder the nearer the boundary. Up to a constant factor
// (absorbed in the charge):
// - ball: Int_sphere |p - s|^-3 dS = 2 pi Int_-1^1 (1 + r^2 - 2 r u)^(-3/2) du
//   = 4 pi / (1 - r^2), so phi = 1 / (1 - r^2);
// - disk: (1/2 pi) Int_0^2pi (1 + r^2 - 2 r cos t)^(-3/2) dt
//   = (2/pi) E(k) / ((1 - r)^2 (1 + r)), k = 2 sqrt(r) / (1 + r) (E the
//   complete elliptic integral of the second kind; 1 at r = 0).
// Complete elliptic integrals K(k) and E(k) by the arithmetic-geometric mean
// (a few iterations to double precision; std::comp_ellint_* cost ~20x more,
// and the disk's charge is evaluated for every point at every step).
void ellipticKE(double k, double& K, double& E) {
  double a = 1.0, b = std::sqrt(std::max(0.0, 1.0 - k * k)), sum = 0.5 * k * k, pow2 = 0.5;
  for (int it = 0; it < 40 && std::abs(a - b) > 1e-16 * a; ++it) {
    const double an = 0.5 * (a + b), c = 0.5 * (a - b);
    b = std::sqrt(a * b);
    a = an;
    pow2 *= 2.0;
    sum += pow2 * c * c;
  }
  K = M_PI / (2.0 * a);
  E = K * (1.0 - sum);
}

double boundaryPotential(Shape s, double r) {
  if (s == Shape::Ball) return 1.0 / (1.0 - r * r);
  const double k = 2.0 * std::sqrt(r) / (1.0 + r);
  double K, E;
  ellipticKE(std::min(k, 1.0), K, E);
  return (2.0 / M_PI) * E / ((1.0 - r) * (1.0 - r) * (1.0 + r));
}

// d phi / dr. Disk: with D = (1 - r)^2 (1 + r), D' = -(1 - r)(1 + 3r),
// k' = (1 - r) / (sqrt(r) (1 + r)^2) and dE/dk = (E - K) / k.
double boundarySlope(Shape s, double r) {
  if (s == Shape::Ball) return 2.0 * r / ((1.0 - r * r) * (1.0 - r * r));
  if (r <= 0.0) return 0.0;
  const double sr = std::sqrt(r), k = 2.0 * sr / (1.0 + r);
  double K, E;
  ellipticKE(std::min(k, 1.0), K, E);
  const double D = (1.0 - r) * (1.0 - r) * (1.0 + r), dD = -(1.0 - r) * (1.0 + 3.0 * r);
  const double dk = (1.0 - r) / (sr * (1.0 + r) * (1.0 + r));
  return (2.0 / M_PI) * (((E - K) / k) * dk / D - E * dD / (D * D));
}

struct Candidate {
  std::vector<P3> pts;
  std::vector<double> share;
  double error = std::numeric_limits<double>::infinity();
  double charge = 0.0;
};

// One start (VO §4.5): a Poisson-disk set, spread by the 1/d^4 repulsion
// between the points plus the boundary charge's push. The step along the
// force is kept only when it lowers the energy (then it grows by 1.2),
// otherwise it is not applied and halves: "the net force is reduced until
// the error decreases (not applying the force until there is a reduction)
// and increased otherwise". After each round of steps the discrete Voronoi
// diagram gives every point its weighted centroid, and the charge is tuned
// so the push moves points toward their centroids: points lying outside
// their centroids on average (radially) need more charge, inside less - a
// search in log q that doubles until the sign flips, then bisects. The
// start's result is its round with the least share error (on the
// half-resolution grid), measured again on the paper's grid.
Candidate optimiseStart(Shape shape, const Domain& dom, int n, const std::vector<P3>& fixed, uint64_t seed) {
  const VoronoiGrid &coarse = voronoiGrid(shape, false), &fine = voronoiGrid(shape, true);
  constexpr int kRounds = 12, kSteps = 40;
  Rng rng{seed};
  std::vector<P3> pts = poissonDisk(dom, n, fixed, rng);
  const size_t firstFree = fixed.size();
  const double spacing = std::pow(dom.volume() / double(n), 1.0 / dom.dims);
  // The charge that balances a neighbour's push at one spacing from the
  // rim: 1/a^4 against q dphi/dr there (~q/(2 a^2) in the ball,
  // ~q/(pi a^3) in the disk); the search corrects it.
  double q = shape == Shape::Ball ? 2.0 / (spacing * spacing) : M_PI / spacing;
  double logStep = std::log(2.0);
  int lastSign = 0;
  double h = 0.1 * spacing;

  const auto energy = [&](const std::vector<P3>& p) {
    double e = 0.0;
    for (size_t i = 0; i < p.size(); ++i) {
      for (size_t j = i + 1; j < p.size(); ++j) {
        const double d2 = std::max(dist2(p[i], p[j]), 1e-24);
        e += 1.0 / (3.0 * d2 * std::sqrt(d2));
      }
      if (i >= firstFree) {
        const double r = std::sqrt(p[i][0] * p[i][0] + p[i][1] * p[i][1] + p[i][2] * p[i][2]);
        if (!(r < 1.0)) return std::numeric_limits<double>::infinity();
        e += q * boundaryPotential(shape, r);
      }
    }
    return e;
  };

  Candidate best;
  std::vector<P3> force(static_cast<size_t>(n)), trial, centroid;
  std::vector<double> share;
  for (int round = 0; round < kRounds && firstFree < size_t(n); ++round) {
    double e = energy(pts);
    for (int step = 0; step < kSteps; ++step) {
      double fmax = 0.0;
      for (size_t i = firstFree; i < size_t(n); ++i) {
        P3 f{0, 0, 0};
        for (size_t j = 0; j < size_t(n); ++j) {
          if (i == j) continue;
          const double d2 = std::max(dist2(pts[i], pts[j]), 1e-24);
          const double s = 1.0 / (d2 * d2 * std::sqrt(d2));  // 1/d^4 along (p_i - p_j)/d
          for (int d = 0; d < 3; ++d) f[d] += s * (pts[i][d] - pts[j][d]);
        }
        const double r = std::sqrt(pts[i][0] * pts[i][0] + pts[i][1] * pts[i][1] + pts[i][2] * pts[i][2]);
        if (r > 0.0) {
          const double s = q * boundarySlope(shape, r) / r;
          for (int d = 0; d < 3; ++d) f[d] -= s * pts[i][d];
        }
        force[i] = f;
        fmax = std::max(fmax, std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
      }
      if (!(fmax > 0.0)) break;
      trial = pts;
      for (size_t i = firstFree; i < size_t(n); ++i)
        for (int d = 0; d < dom.dims; ++d) trial[i][d] += h * force[i][d] / fmax;
      const double et = energy(trial);
      if (et < e) {
        pts.swap(trial);
        e = et;
        h *= 1.2;
      } else {
        h *= 0.5;
      }
    }
    coarse.diagram(pts, share, centroid);
    const double error = shareError(share);
    if (error < best.error) best = Candidate{pts, {}, error, q};
    // Radial offset of the points from their centroids.
    double outward = 0.0;
    for (size_t i = firstFree; i < size_t(n); ++i) {
      const double r = std::sqrt(pts[i][0] * pts[i][0] + pts[i][1] * pts[i][1] + pts[i][2] * pts[i][2]);
      if (r > 0.0)
        outward += ((pts[i][0] - centroid[i][0]) * pts[i][0] + (pts[i][1] - centroid[i][1]) * pts[i][1] +
                    (pts[i][2] - centroid[i][2]) * pts[i][2]) / r;
    }
    const int sign = outward > 0.0 ? 1 : -1;
    if (lastSign != 0 && sign != lastSign) logStep *= 0.5;
    lastSign = sign;
    q *= std::exp(sign * logStep);
  }
  if (firstFree >= size_t(n)) best = Candidate{pts, {}, 0.0, 0.0};  // nothing to move (the disk's centre alone)
  // The chosen round's shares and error on the paper's grid.
  fine.diagram(best.pts, best.share, centroid);
  best.error = shareError(best.share);
  return best;
}

// Tens of starts (VO §4.5), each from its own Poisson-disk set, run in
// parallel; the start with the least share error wins (the lowest index
// among equals), so the set does not depend on the threads or their order.
Candidate optimise(Shape shape, int n, const std::vector<P3>& fixed, uint64_t seed, int starts, int threads,
                   std::vector<double>* startErrors, int* chosen) {
  checkCount(n);
  if (starts < 1) throw Error("sample set: need at least one start");
  const Domain dom(shape);
  std::vector<Candidate> result(static_cast<size_t>(starts));
  const auto run = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, starts, 1), [&](const tbb::blocked_range<int>& r) {
      for (int s = r.begin(); s < r.end(); ++s)
        result[size_t(s)] = optimiseStart(shape, dom, n, fixed, seed + 0x632be59bd9b4e019ULL * uint64_t(s + 1));
    });
  };
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(run);
  } else {
    run();
  }
  int best = 0;
  for (int s = 1; s < starts; ++s)
    if (result[size_t(s)].error < result[size_t(best)].error) best = s;
  if (startErrors) {
    startErrors->clear();
    for (const Candidate& c : result) startErrors->push_back(c.error);
  }
  if (chosen) *chosen = best;
  return std::move(result[size_t(best)]);
}

uint64_t ballSeed(uint32_t seed) { return 0xba11ULL * 0x100000001ULL + seed; }
uint64_t diskSeed(uint32_t seed, bool centre) { return 0xd15cULL * 0x100000001ULL + seed + (centre ? 0x51ULL : 0ULL); }

OptimisedSet toSet(const Candidate& c, std::vector<double> errors, int chosen) {
  OptimisedSet s;
  for (size_t i = 0; i < c.pts.size(); ++i) {
    s.p.emplace_back(float(c.pts[i][0]), float(c.pts[i][1]), float(c.pts[i][2]));
    s.w.push_back(float(c.share[i]));
  }
  s.startError = std::move(errors);
  s.chosen = chosen;
  s.charge = c.charge;
  return s;
}

// The optimised sets, memoised per process: every integrator created with
// the same count (a multi-pass render, a sweep) reuses them.
const OptimisedSet& memoised(Shape shape, int n, bool centre, uint32_t seed) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, bool, uint32_t>, std::unique_ptr<OptimisedSet>> cache;
  const auto key = std::make_tuple(int(shape), n, centre, seed);
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto it = cache.find(key);
    if (it != cache.end()) return *it->second;
  }
  auto set = std::make_unique<OptimisedSet>(shape == Shape::Ball ? optimiseBall(n, seed) : optimiseDisk(n, centre, seed));
  std::lock_guard<std::mutex> lock(mutex);
  return *cache.try_emplace(key, std::move(set)).first->second;  // a racing twin computed the same set
}

}  // namespace

OptimisedSet optimiseBall(int n, uint32_t seed, int starts, int threads) {
  std::vector<double> errors;
  int chosen = 0;
  const Candidate c = optimise(Shape::Ball, n, {}, ballSeed(seed), starts, threads, &errors, &chosen);
  return toSet(c, std::move(errors), chosen);
}

OptimisedSet optimiseDisk(int n, bool centre, uint32_t seed, int starts, int threads) {
  std::vector<P3> fixed;
  if (centre) fixed.push_back({0, 0, 0});
  std::vector<double> errors;
  int chosen = 0;
  const Candidate c = optimise(Shape::Disk, n, fixed, diskSeed(seed, centre), starts, threads, &errors, &chosen);
  return toSet(c, std::move(errors), chosen);
}

BallSet optimisedBallSet(int n, uint32_t seed) {
  checkCount(n);
  const OptimisedSet& o = memoised(Shape::Ball, n, false, seed);
  return BallSet{o.p, o.w};
}

DiskSet optimisedDiskSet(int n, bool centre, uint32_t seed) {
  checkCount(n);
  const OptimisedSet& o = memoised(Shape::Disk, n, centre, seed);
  DiskSet s;
  for (const Vec3& p : o.p) s.x.push_back(p.x), s.y.push_back(p.y);
  s.w = o.w;
  return s;
}

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
  relaxedSet(Shape::Ball, n, ballSeed(seed), {}, pts, share);
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
  relaxedSet(Shape::Disk, n, diskSeed(seed, centre), fixed, pts, share);
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
