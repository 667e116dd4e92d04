// Low-noise sample sets for the screen-space integrators, generated when an
// integrator is created (never in the render loop) from fixed seeds, so every
// run draws the same sets.
//
// - ballSet / diskSet: the sets of volumetric obscurance (VO §4.5; docs/math.md
//   §8): points in the unit ball (point samples) and in the unit disk (line
//   and area samples), with or without the centre. Two generators:
//   - the default (`vo sets=relaxed`): one Poisson-disk (dart-throwing)
//     start spread by a 1/d^4 repulsion with adaptive step (a step is kept
//     only when it lowers the repulsion energy), kept inside the domain by
//     periodic Lloyd steps towards the centroids of the Voronoi cells
//     (discrete diagrams of 40^3 / 200^2 cells); ~10 ms for 16 points.
//   - optimisedBallSet / optimisedDiskSet (`vo sets=optimised`): the
//     optimiser as VO §4.5 describes it (docs/vo_sample_sets.md): tens of
//     Poisson-disk starts, each spread by the 1/d^4 repulsion and kept
//     inside by a charge on the boundary, the charge tuned so the points
//     move toward the weighted centroids of their Voronoi cells (discrete
//     diagrams on 128^3 cells for the ball, 512^2 for the disk); the start
//     whose cells' shares of the integral are the most nearly equal wins.
//     Seconds of CPU for 16 points, so memoised per process and opt-in.
//   Each point carries its cell's share of the integral: the cell's volume
//   for the ball, the ball's volume above the cell (the integral of the chord
//   2 sqrt(1 - x^2 - y^2) over it, VO footnote 5) for the disk. The weights
//   sum to 1, so a weighted sum integrates constants exactly and smooth
//   functions to within the cells' size (tests/test_screen_space_sets.cpp).
// - cubeSet: the (xi_x, xi_y, xi_z) series of the ambient-transfer paper
//   (AT §4.1; docs/math.md §9): a Poisson-disk set in the unit cube improved
//   by Lloyd relaxation, equal weights (its cells have near-equal volume).
#pragma once

#include <cstdint>
#include <vector>

#include <obscura/math.h>

namespace obscura::screen_space {

struct BallSet {
  std::vector<Vec3> p;   // |p| <= 1
  std::vector<float> w;  // Voronoi volume shares, sum 1
};

struct DiskSet {
  std::vector<float> x, y;  // x^2 + y^2 <= 1
  std::vector<float> w;     // shares of the ball's volume above each cell, sum 1
};

// n in [1, 1024]; `seed` selects among equally good sets (the integrators
// use fixed seeds).
BallSet ballSet(int n, uint32_t seed = 1);
// With `centre` the first point is the disk's centre and stays there.
DiskSet diskSet(int n, bool centre, uint32_t seed = 1);
// The optimiser's result with its diagnostics: every start's share error
// (1/n) Sum (n w_i - 1)^2 and the chosen one (the least; the lowest index
// among equals). `threads` 0 runs in the caller's TBB arena; the result does
// not depend on it. optimised*Set are these with kVoStarts starts, memoised.
struct OptimisedSet {
  std::vector<Vec3> p;  // the disk's in x, y (z = 0)
  std::vector<float> w;
  std::vector<double> startError;
  int chosen = 0;
  double charge = 0.0;  // the boundary charge the chosen start ended with
};
inline constexpr int kVoStarts = 32;
OptimisedSet optimiseBall(int n, uint32_t seed = 1, int starts = kVoStarts, int threads = 0);
OptimisedSet optimiseDisk(int n, bool centre, uint32_t seed = 1, int starts = kVoStarts, int threads = 0);

BallSet optimisedBallSet(int n, uint32_t seed = 1);
DiskSet optimisedDiskSet(int n, bool centre, uint32_t seed = 1);

// Points in [0, 1)^3.
std::vector<Vec3> cubeSet(int n, uint32_t seed = 1);

// The smallest distance between two points of a set (for the tests and for
// the documentation of a set's quality).
float minimumDistance(const std::vector<Vec3>& p);

}  // namespace obscura::screen_space
