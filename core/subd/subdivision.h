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

#include <obscura/math.h>

namespace obscura {

enum class SubdivisionScheme { CatmullClark, Loop };

// Who refines the surface: OpenSubdiv into a triangle mesh at load time
// (core/subd/subdivision.cpp), or Embree's own subdivision geometry, tessellated
// into grids while the BVH is built, displaced through a callback
// (Scene::addSubdivisionSurface). Embree implements Catmull-Clark only.
enum class SubdivisionBackend { OpenSubdiv, Embree };

// A polygon cage: faceSizes[f] vertices per face, their indices
// concatenated in faceIndices. Creases: sharpness per edge (pairs of vertex
// indices), 0 = smooth, >= 10 = infinitely sharp.
struct SubdivisionCage {
  std::vector<Vec3> positions;
  std::vector<int> faceSizes;
  std::vector<int> faceIndices;
  std::vector<int> creaseEdges;      // 2 per crease
  std::vector<float> creaseWeights;  // 1 per crease
  // Texture coordinates, optional: uv values (2 floats each) and, parallel
  // to faceIndices, the value of each face corner (face-varying).
  std::vector<float> uvs;
  std::vector<int> uvIndices;
};

// The refined surface, on the limit: one position and one unit normal per
// vertex; triangles (quads split along a diagonal).
struct SubdividedMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  std::vector<uint32_t> triangles;
  // 2 per vertex when the cage has uvs. A vertex on a uv seam is split into
  // copies at the same position, one per side's uv; weld[i] is the first
  // (canonical) copy of vertex i (i itself for most), whose uv a
  // displacement uses for all copies, so none separates.
  std::vector<float> uvs;
  std::vector<uint32_t> weld;
};

// A scalar height map read through OpenImageIO (its module, loaded by the
// first map: core/image/oiio_module.h) (PNG, EXR, TIFF, ...; 8/16-bit
// or float; the first channel), sampled bilinearly with repeat wrapping,
// v = 0 at the bottom row (OpenGL / OBJ convention).
class HeightMap {
 public:
  explicit HeightMap(const std::string& path);  // throws obscura::Error naming the file
  double sample(double u, double v) const;  // any u, v (a non-finite one reads as 0)
  int width() const { return w_; }
  int height() const { return h_; }
  // The range of the texels, which bounds every sample (bilinear, repeat).
  float minTexel() const { return min_; }
  float maxTexel() const { return max_; }

 private:
  int w_ = 0, h_ = 0;
  float min_ = 0, max_ = 0;
  std::vector<float> texels_;
};

// The texture coordinates of a cage, bilinear over each face: the
// parametrization both backends displace with (OpenSubdiv interpolates
// face-varying uvs linearly, FVAR_LINEAR_ALL; Embree hands the displacement
// callback patch coordinates, mapped here). Quads use Embree's patch
// coordinates (p0 base, u towards p1, v towards p3); other faces are split
// into the n quads one subdivision step makes - corner i, the midpoint of
// edge (i, i+1), the face centre, the midpoint of edge (i-1, i) - and Embree
// encodes the sub-quad and the position in it in (u, v) (see
// RTC_GEOMETRY_TYPE_SUBDIVISION, "Parametrization").
//
// Where a uv seam runs along an edge, the two faces map the edge to
// different texels, and a displacement taken from each face's own uvs would
// move the edge's points apart: a crack. Points on a cage edge therefore take
// the uvs of one canonical face of that edge (the lowest-numbered), and cage
// vertices those of their lowest-numbered face, so every face agrees on the
// displaced boundary; the seam's jump happens inside the first tessellation
// step (as the OpenSubdiv backend, whose seam vertices keep one side's uv).
class CageUvs {
 public:
  CageUvs() = default;
  explicit CageUvs(const SubdivisionCage& cage);  // cage.uvIndices must cover every corner
  bool empty() const { return faceStart_.empty(); }
  uint32_t faceSize(uint32_t face) const { return faceStart_[face + 1] - faceStart_[face]; }
  size_t bytes() const {
    return (faceStart_.size() + cornerUv_.size() + edgeUv_.size() + vertexUv_.size()) * sizeof(float);
  }
  // uv of face f at Embree patch coordinates (u, v).
  void at(uint32_t face, float u, float v, float& s, float& t) const;

 private:
  // uv at parameter x along face corner k's outgoing edge, from the
  // canonical face's uvs (x = 0 and 1: the canonical vertex uvs).
  void onEdge(uint32_t k, float x, float& s, float& t) const;
  std::vector<uint32_t> faceStart_;  // first corner of each face, plus one past the end
  std::vector<float> cornerUv_;      // 2 per face corner
  std::vector<float> edgeUv_;        // 4 per face corner: canonical uv at its edge's two ends
  std::vector<float> vertexUv_;      // 2 per face corner: canonical uv of its vertex
};

// Moves every vertex along its limit normal by scale * (h(uv) - midlevel),
// then recomputes the normals from the displaced triangles (area-weighted),
// so shading follows the displaced surface. Needs mesh.uvs.
// flipV: the map is looked up at (u, 1 - v) (glTF's uv convention).
void displace(SubdividedMesh& mesh, const HeightMap& height, double scale, double midlevel, bool flipV = false);

// Throws obscura::Error, naming `what`, for a malformed cage (see subdivide).
void validateCage(const SubdivisionCage& cage, SubdivisionScheme scheme, const std::string& what);

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
