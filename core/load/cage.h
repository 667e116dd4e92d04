// A polygon cage into scene geometry, as the load options ask: refined by
// OpenSubdiv into triangles, or handed to Embree as a subdivision surface;
// to a uniform level or adaptively to an edge length in pixels; displaced
// or not. The one path OBJ cages and subdivided glTF meshes take.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/load/load_options.h"
#include "core/scene/scene.h"
#include "core/subd/subdivision.h"

namespace obscura {

struct CageDisplacement {
  std::shared_ptr<const HeightMap> map;  // null: none
  double scale = 0, midlevel = 0;
  bool flipV = false;  // look up (u, 1 - v): glTF's v runs down the image
  // Where the scale came from, for messages: "" = the displacementScale
  // setting (core/util/option_names.h), or "FILE: meshes[i].extras.obscura.displacement.scale".
  std::string scaleField;
};

// Displaced coordinates must stay within this magnitude (scene units); see
// addCage.
constexpr double kMaxDisplacedCoordinate = 1e12;

// Length in pixels of each cage edge (the edge from face corner k to the
// next corner, parallel to cage.faceIndices) seen from `camera` on a
// width x height image: |b - a| over the size of a pixel at the nearer end's
// distance. Both half-edges of an edge get the same value bit for bit, so
// per-edge tessellation rates derived from it leave no crack.
std::vector<float> edgePixelLengths(const SubdivisionCage& cage, const Camera& camera, int width, int height);

// The uniform level (0..10) at which no refined edge is longer than
// maxPixels: each level halves the cage's edges.
int levelForEdgeLength(const std::vector<float>& edgePixels, double maxPixels);

// Bytes Embree's tessellation of the cage at these edge rates takes (grids
// of (rate + 1)^2 points per quad, a quarter of the rate per sub-quad of
// other faces, with their BVH; measured per point, see the benchmark).
size_t embreeSubdivisionBytes(const SubdivisionCage& cage, const std::vector<float>& edgeRates);

// Adds the cage (world space) to the scene; `what` names it in errors.
// Throws obscura::Error for a malformed cage, a scheme the backend lacks, or
// a refinement over options.maxMemoryBytes.
void addCage(Scene& scene, const SubdivisionCage& cage, const LoadOptions& options, const CageDisplacement& displacement,
             int material, const std::string& what);

}  // namespace obscura
