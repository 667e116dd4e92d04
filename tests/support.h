// Shared helpers for the test suite: scenes built in code, renders in
// process, and statistics for tolerances derived from sample counts.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/film.h"
#include "core/integrator.h"
#include "core/render.h"
#include "core/scene.h"

namespace obscura::test {

// A fresh, empty directory under the build tree's temp area for one test.
std::string tempDir(const std::string& name);

// Triangle list of a sphere of radius rs about the origin, normals facing the
// centre (seen from inside), with the polar cap of half-angle alpha about +Z
// removed (MATH.md section 7). `rings` latitude bands from the hole edge to
// the -Z pole, `segments` around; vertex normals are exact (-p/rs).
void addSphereCavity(Scene& scene, float rs, double alpha, int rings, int segments);

// A square in the plane z = 0, side 2*halfSize, normal +Z.
void addPlane(Scene& scene, float halfSize, float z = 0.0f);

// Renders with `integrator` configured by "key=value" strings.
Film renderWith(const Scene& scene, const Camera& camera, const std::string& integrator,
                const std::vector<std::string>& params, const RenderSettings& settings,
                RenderStats* stats = nullptr);

// Mean of channel c over pixels whose coverage A is 1 (fully covered).
double meanCovered(const Film& film, int channel, size_t* count = nullptr);

// Standard error of the mean of n Bernoulli(p) draws.
inline double bernoulliStdErr(double p, double n) { return std::sqrt(std::max(p * (1 - p), 1e-12) / n); }

}  // namespace obscura::test
