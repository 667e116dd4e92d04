// Motion blur's time steps: how finely a moving placement (an instance's
// object-to-world transform, or a camera's) is keyed across the shutter.
//
// Embree interpolates a motion-blurred instance's transform linearly between
// uniformly spaced time steps, so a path that is not linear in the matrix - a
// rotation, a cubic spline, a curve from a parent's motion - is followed only
// as closely as the steps are dense. The rule (docs/architecture.md, "Motion
// blur"): the placement is evaluated exactly at kMotionGrid + 1 evenly spaced
// times of the shutter; the steps are the fewest segments n in 1, 2, 4, ...,
// kMaxMotionSegments whose linear blend reproduces every one of those
// evaluations within `tolerance` at every corner of the object's bounds (the
// largest error over a box of an affine difference is at a corner). A
// placement that never changes gets one step: it is still, and costs nothing.
#pragma once

#include <span>
#include <vector>

#include <obscura/math.h>

namespace obscura {

// Exact evaluations per shutter (the grid the steps are chosen from) and
// Embree's limit on time steps (129 = 128 segments).
constexpr int kMotionGrid = 512;
constexpr int kMaxMotionSegments = 128;
// The default tolerance, relative to the size of the moving object's box:
// 1e-4 of it, well under a pixel for any object that fits in the frame.
constexpr double kMotionTolerance = 1e-4;

// `grid`: the placement at times j / kMotionGrid, j = 0..kMotionGrid.
// `box`: the object's bounds in its own space (the corners tested).
// `tolerance`: the largest distance allowed between the blended and the
// exact corner positions, in world units.
// Returns the steps (the grid's transforms at the chosen segment ends): one
// if every grid transform equals the first, else n + 1 with n <= 128 (the
// finest n if even it misses the tolerance: the best Embree can take).
std::vector<Affine> motionSteps(std::span<const Affine> grid, const Bounds3& box, double tolerance);

// The world-space size used to scale the tolerance: the largest diagonal of
// the box placed by any grid transform.
double placedDiagonal(std::span<const Affine> grid, const Bounds3& box);

}  // namespace obscura
