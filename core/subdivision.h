// Subdivision surfaces through OpenSubdiv (Far): a polygon cage refined
// uniformly to a level and evaluated at the limit surface - positions and
// normals of the limit at every vertex of the refined mesh - then
// triangulated for Embree. Used only for meshes flagged for subdivision;
// everything else stays a plain triangle mesh.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"

namespace obscura {

enum class SubdivisionScheme { CatmullClark, Loop };

// A polygon cage: faceSizes[f] vertices per face, their indices
// concatenated in faceIndices. Creases: sharpness per edge (pairs of vertex
// indices), 0 = smooth, >= 10 = infinitely sharp.
struct SubdivisionCage {
  std::vector<Vec3> positions;
  std::vector<int> faceSizes;
  std::vector<int> faceIndices;
  std::vector<int> creaseEdges;      // 2 per crease
  std::vector<float> creaseWeights;  // 1 per crease
};

// The refined surface, on the limit: one position and one unit normal per
// vertex; triangles (quads split along a diagonal).
struct SubdividedMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  std::vector<uint32_t> triangles;
};

// Bytes the result of refining `cage` to `level` would take (an estimate
// from the face count: each level multiplies faces by 4).
size_t subdividedBytes(const SubdivisionCage& cage, int level);

// Refines uniformly to `level` (0..10) and evaluates the limit. Throws
// obscura::Error, naming `what` (a file or mesh name), for a malformed cage
// (a face with fewer than 3 vertices or a repeated vertex, an index out of
// range, a non-triangle under Loop, a non-finite position) or when the
// result would exceed maxBytes.
SubdividedMesh subdivide(const SubdivisionCage& cage, SubdivisionScheme scheme, int level, size_t maxBytes,
                         const std::string& what);

}  // namespace obscura
