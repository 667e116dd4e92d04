// Low-noise sample sets for the screen-space integrators, generated once
// when an integrator is created (never in the render loop) from fixed seeds,
// so every run draws the same sets.
//
// - ballSet / diskSet: the sets of volumetric obscurance (VO §4.5; docs/math.md
//   §8): points in the unit ball (point samples) and in the unit disk (line
//   and area samples), with or without the centre, spread by a 1/d^4
//   repulsion between the points with adaptive step size (a step is kept
//   only when it lowers the repulsion energy), the points kept inside the
//   domain by periodic Lloyd steps towards the centroids of their Voronoi
//   cells, started from a Poisson-disk (dart-throwing) set.
//   Each point carries a weight: the share of the integral its Voronoi cell
//   covers, measured on a discrete Voronoi diagram - the cell's volume for
//   the ball, the ball's volume above the cell (the integral of the chord
//   2 sqrt(1 - x^2 - y^2) over it) for the disk. The weights sum to 1, so a
//   weighted sum is exact for an integrand that is constant on each cell and
//   the sets integrate constants, and nearly every smooth moment, as the
//   domain does (tests/test_screen_space_sets.cpp measures them).
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
// Points in [0, 1)^3.
std::vector<Vec3> cubeSet(int n, uint32_t seed = 1);

// The smallest distance between two points of a set (for the tests and for
// the documentation of a set's quality).
float minimumDistance(const std::vector<Vec3>& p);

}  // namespace obscura::screen_space
