// Per-vertex tangents for normal maps whose mesh has no TANGENT attribute.
//
// glTF asks for MikkTSpace tangents; its code cannot be vendored (and is no
// Debian package), so this is a simpler generator of our own, from each
// triangle's uv derivatives (docs/math.md §16.2):
// - a triangle's tangent is dP/du, its bitangent dP/dv with v up the image
//   (a normal map's +Y), both from the linear map taking uv differences to
//   edge vectors (as surfaceUvFrame solves it);
// - a vertex sums the unit tangents and bitangents of its triangles, each
//   weighted by the triangle's angle at that corner, and Gram-Schmidts the
//   sum against its normal (the vertex normal, or the angle-weighted face
//   normals where the mesh has none); w = the sign of the bitangent sum
//   along cross(N, T).
// Where it differs from MikkTSpace: vertices are never split (a vertex shared
// by triangles with mirrored uvs averages their tangents, which MikkTSpace
// would split by handedness), and a vertex whose triangles all have
// degenerate uvs gets an arbitrary tangent perpendicular to its normal
// (MikkTSpace does the same in effect; its maps bake nothing readable
// there). On meshes whose uv charts are not mirrored the two agree up to
// the weighting of smooth-shaded corners, which changes tangents only
// where the uv map is not affine across a vertex's triangles.
#pragma once

#include <cstdint>
#include <vector>

#include <obscura/math.h>

namespace obscura {

// 4 floats per vertex (xyz unit, w = +-1) for the triangle list `indices`.
// uvs: 2 per vertex; `vRunsDown`: v = 0 at the top row of an image (glTF),
// so +Y of the map is -v. normals: per vertex, or empty.
std::vector<float> generateTangents(const std::vector<Vec3>& positions, const std::vector<Vec3>& normals,
                                    const std::vector<float>& uvs, const std::vector<uint32_t>& indices,
                                    bool vRunsDown);

}  // namespace obscura
