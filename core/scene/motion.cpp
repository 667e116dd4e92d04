#include "core/scene/motion.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <obscura/error.h>

namespace obscura {
namespace {

Vec3 corner(const Bounds3& b, int c) {
  return {c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z};
}

// The corner placed by `a`, in double (the error measured is the blend's,
// not float rounding's).
void placeCorner(const Affine& a, const Vec3& p, double out[3]) {
  for (int r = 0; r < 3; ++r)
    out[r] = double(a.m[r][0]) * p.x + double(a.m[r][1]) * p.y + double(a.m[r][2]) * p.z + double(a.m[r][3]);
}

// Do n segments follow the grid within `tolerance`? The blend at grid time j
// of segment [a, b] is (1 - f) X_a + f X_b with f = (j - a) / (b - a): Embree
// blends the matrices, and a corner's position is linear in the matrix.
bool follows(std::span<const Affine> grid, const Bounds3& box, double tolerance, int n) {
  const int step = kMotionGrid / n;
  for (int s = 0; s < n; ++s) {
    const Affine &A = grid[size_t(s * step)], &B = grid[size_t((s + 1) * step)];
    for (int c = 0; c < 8; ++c) {
      const Vec3 p = corner(box, c);
      double a[3], b[3], x[3];
      placeCorner(A, p, a);
      placeCorner(B, p, b);
      for (int j = 1; j < step; ++j) {
        const double f = double(j) / double(step);
        placeCorner(grid[size_t(s * step + j)], p, x);
        double d2 = 0;
        for (int r = 0; r < 3; ++r) {
          const double d = (1 - f) * a[r] + f * b[r] - x[r];
          d2 += d * d;
        }
        if (!(d2 <= tolerance * tolerance)) return false;
      }
    }
  }
  return true;
}

}  // namespace

double placedDiagonal(std::span<const Affine> grid, const Bounds3& box) {
  double best = 0;
  for (const Affine& a : grid) {
    Bounds3 placed;
    for (int c = 0; c < 8; ++c) placed.extend(a.point(corner(box, c)));
    best = std::max(best, double(length(placed.hi - placed.lo)));
  }
  return best;
}

std::vector<Affine> motionSteps(std::span<const Affine> grid, const Bounds3& box, double tolerance) {
  if (grid.size() != size_t(kMotionGrid) + 1) throw Error("internal: motionSteps needs kMotionGrid + 1 transforms");
  const bool still = std::all_of(grid.begin(), grid.end(),
                                 [&](const Affine& a) { return std::memcmp(&a, &grid[0], sizeof a) == 0; });
  if (still) return {grid[0]};
  int n = 1;
  while (n < kMaxMotionSegments && !follows(grid, box, tolerance, n)) n *= 2;
  std::vector<Affine> steps;
  const int step = kMotionGrid / n;
  for (int s = 0; s <= n; ++s) steps.push_back(grid[size_t(s * step)]);
  return steps;
}

}  // namespace obscura
