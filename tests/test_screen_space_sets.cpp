// The sample sets of the screen-space integrators (integrators/screen_space/
// sample_sets.h): deterministic, inside their domains, better spread than
// random points, and weighted so the estimators built on them integrate
// what they should.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "integrators/screen_space/sample_sets.h"

namespace obscura::test {
namespace {

using namespace screen_space;

// The mean over `trials` uniform random sets of n points of the smallest
// pairwise distance: what the generated sets must beat.
double randomMinimumDistance(int n, int dims, bool ball, int trials) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  double sum = 0.0;
  for (int t = 0; t < trials; ++t) {
    std::vector<Vec3> p;
    while (int(p.size()) < n) {
      const Vec3 c(u(rng), u(rng), dims == 3 ? u(rng) : 0.0f);
      if (!ball || dot(c, c) < 1.0f) p.push_back(c);
    }
    sum += minimumDistance(p);
  }
  return sum / trials;
}

TEST(ScreenSpaceSets, Deterministic) {
  const BallSet a = ballSet(12), b = ballSet(12);
  for (int k = 0; k < 12; ++k) {
    EXPECT_EQ(a.p[k].x, b.p[k].x);
    EXPECT_EQ(a.p[k].z, b.p[k].z);
    EXPECT_EQ(a.w[k], b.w[k]);
  }
  const DiskSet c = diskSet(9, true), d = diskSet(9, true);
  for (int k = 0; k < 9; ++k) {
    EXPECT_EQ(c.x[k], d.x[k]);
    EXPECT_EQ(c.w[k], d.w[k]);
  }
  const std::vector<Vec3> e = cubeSet(16), f = cubeSet(16);
  for (int k = 0; k < 16; ++k) EXPECT_EQ(e[k].y, f[k].y);
  // A different seed is a different set.
  EXPECT_NE(ballSet(12, 2).p[0].x, a.p[0].x);
}

TEST(ScreenSpaceSets, InDomainWeightsSumToOne) {
  for (int n : {1, 5, 12, 16, 33, 64}) {
    const BallSet b = ballSet(n);
    double sw = 0.0;
    for (int k = 0; k < n; ++k) {
      EXPECT_LE(length(b.p[k]), 1.0f + 1e-6f);
      EXPECT_GT(b.w[k], 0.0f) << "n " << n << " point " << k << " owns no Voronoi cell";
      sw += b.w[k];
    }
    EXPECT_NEAR(sw, 1.0, 1e-5);  // float rounding of n shares
    for (bool centre : {false, true}) {
      const DiskSet d = diskSet(n, centre);
      double dw = 0.0;
      for (int k = 0; k < n; ++k) {
        EXPECT_LE(d.x[k] * d.x[k] + d.y[k] * d.y[k], 1.0f + 1e-6f);
        dw += d.w[k];
      }
      EXPECT_NEAR(dw, 1.0, 1e-5);
      if (centre) {
        EXPECT_EQ(d.x[0], 0.0f);
        EXPECT_EQ(d.y[0], 0.0f);
      }
    }
    for (const Vec3& p : cubeSet(n)) {
      EXPECT_GE(std::min({p.x, p.y, p.z}), 0.0f);
      EXPECT_LT(std::max({p.x, p.y, p.z}), 1.0f);
    }
  }
}

// Blue noise: the smallest distance is well above that of random points
// (for n uniform points it shrinks like n^(-2/d), for a relaxed set like
// n^(-1/d)); 1.5x the random mean over 64 sets is a margin the relaxed sets
// clear by far (they reach 3-10x).
TEST(ScreenSpaceSets, MinimumDistanceBeatsRandom) {
  for (int n : {12, 16, 33}) {
    EXPECT_GT(minimumDistance(ballSet(n).p), 1.5 * randomMinimumDistance(n, 3, true, 64)) << n;
    const DiskSet d = diskSet(n, true);
    std::vector<Vec3> dp;
    for (int k = 0; k < n; ++k) dp.emplace_back(d.x[k], d.y[k], 0.0f);
    EXPECT_GT(minimumDistance(dp), 1.5 * randomMinimumDistance(n, 2, true, 64)) << n;
    std::vector<Vec3> c = cubeSet(n);
    for (Vec3& p : c) p = p * 2.0f - Vec3(1, 1, 1);  // to [-1,1]^3 like the random reference
    EXPECT_GT(minimumDistance(c), 1.5 * randomMinimumDistance(n, 3, false, 64)) << n;
  }
}

// The weighted moments that the estimators rely on. Each weight is the
// share of its Voronoi cell on a discrete grid, and the last relaxation step
// moved each point to its cell's centroid, so the weighted first moment is
// the domain's (0 for ball and disk by symmetry; (1/2,1/2,1/2) for the cube)
// up to how far the points moved since: bounded by one grid cell (0.05 for
// the ball's 40^3 grid over [-1,1]^3, 0.01 for the disk's 200^2, 1/32 for the
// cube) - the tolerance. The disk's weights are its cells' share of the
// ball's volume, so Sum w_k z_s(x_k)^2 ~ E_ball-chord-weighted[1 - r^2]:
// for the density (3/(4 pi)) 2 sqrt(1 - r^2) over the disk,
// E[1 - r^2] = (3/2) Int_0^1 (1 - r^2)^(3/2) r dr = 3/5; within the
// within-cell variation (|grad (1 - r^2)| <= 2 times a cell radius
// (pi/n)^(1/2)) halved for centroid placement - tolerance 2 (pi/n)^(1/2)/2.
TEST(ScreenSpaceSets, WeightedMoments) {
  for (int n : {9, 16, 33}) {
    const BallSet b = ballSet(n);
    Vec3 m(0, 0, 0);
    for (int k = 0; k < n; ++k) m += b.p[k] * b.w[k];
    EXPECT_LT(length(m), 0.05f) << n;
    const DiskSet d = diskSet(n, false);
    double mx = 0.0, my = 0.0, zz = 0.0;
    for (int k = 0; k < n; ++k) {
      mx += d.w[k] * d.x[k];
      my += d.w[k] * d.y[k];
      zz += d.w[k] * (1.0 - d.x[k] * d.x[k] - d.y[k] * d.y[k]);
    }
    EXPECT_LT(std::hypot(mx, my), 0.01 + 0.01) << n;
    EXPECT_NEAR(zz, 0.6, std::sqrt(M_PI / n)) << n;
    Vec3 c(0, 0, 0);
    for (const Vec3& p : cubeSet(n)) c += p * (1.0f / float(n));
    EXPECT_NEAR(c.x, 0.5, 1.0 / 32.0);
    EXPECT_NEAR(c.y, 0.5, 1.0 / 32.0);
    EXPECT_NEAR(c.z, 0.5, 1.0 / 32.0);
  }
}

TEST(ScreenSpaceSets, BadCountIsAnError) {
  EXPECT_THROW(ballSet(0), std::exception);
  EXPECT_THROW(diskSet(2000, false), std::exception);
}

}  // namespace
}  // namespace obscura::test
