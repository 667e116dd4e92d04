#include "core/subdivision.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <cmath>
#include <memory>

#include "core/error.h"

namespace obscura {
namespace {

using namespace OpenSubdiv;

// The primvar OpenSubdiv interpolates: a point (Clear / AddWithWeight).
struct OsdPoint {
  double p[3];
  void Clear(void* = nullptr) { p[0] = p[1] = p[2] = 0.0; }
  void AddWithWeight(const OsdPoint& s, float w) {
    p[0] += double(w) * s.p[0], p[1] += double(w) * s.p[1], p[2] += double(w) * s.p[2];
  }
};

void validate(const SubdivisionCage& c, SubdivisionScheme scheme, const std::string& what) {
  const size_t nv = c.positions.size();
  for (size_t i = 0; i < nv; ++i) {
    const Vec3& p = c.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw Error(what + ": vertex " + std::to_string(i) + " is not finite");
  }
  size_t k = 0;
  for (size_t f = 0; f < c.faceSizes.size(); ++f) {
    const int n = c.faceSizes[f];
    if (n < 3) throw Error(what + ": face " + std::to_string(f) + " has " + std::to_string(n) + " vertices (at least 3)");
    if (scheme == SubdivisionScheme::Loop && n != 3)
      throw Error(what + ": face " + std::to_string(f) + " has " + std::to_string(n) +
                  " vertices; Loop subdivision needs triangles (use catmull-clark)");
    if (k + size_t(n) > c.faceIndices.size()) throw Error(what + ": face " + std::to_string(f) + " runs past the index list");
    for (int a = 0; a < n; ++a) {
      const int i = c.faceIndices[k + size_t(a)];
      if (i < 0 || size_t(i) >= nv)
        throw Error(what + ": face " + std::to_string(f) + " refers to vertex " + std::to_string(i) + " of " +
                    std::to_string(nv));
      for (int b = 0; b < a; ++b)
        if (c.faceIndices[k + size_t(b)] == i)
          throw Error(what + ": face " + std::to_string(f) + " repeats vertex " + std::to_string(i) + " (degenerate face)");
    }
    k += size_t(n);
  }
  if (c.faceSizes.empty()) throw Error(what + ": the cage has no faces");
  if (c.creaseEdges.size() != 2 * c.creaseWeights.size()) throw Error(what + ": crease edges and weights do not match");
  for (const int i : c.creaseEdges)
    if (i < 0 || size_t(i) >= nv) throw Error(what + ": a crease refers to vertex " + std::to_string(i));
}

}  // namespace

size_t subdividedBytes(const SubdivisionCage& cage, int level) {
  // Each face becomes n quads at level 1 (Catmull-Clark) or 4 triangles
  // (Loop), then x4 per level; per refined face about one vertex (position +
  // normal, 24 bytes) and two triangles (24 bytes), plus OpenSubdiv's
  // topology (~100 bytes a face, measured order of magnitude).
  double faces = 0;
  for (const int n : cage.faceSizes) faces += n == 3 ? 4.0 : double(n);
  faces *= std::pow(4.0, std::max(level - 1, 0));
  if (level == 0) faces = double(cage.faceSizes.size());
  return size_t(std::min(faces * 150.0, 1e18));
}

SubdividedMesh subdivide(const SubdivisionCage& cage, SubdivisionScheme scheme, int level, size_t maxBytes,
                         const std::string& what) {
  if (level < 0 || level > 10) throw Error(what + ": subdivision level " + std::to_string(level) + " is outside [0, 10]");
  validate(cage, scheme, what);
  const size_t bytes = subdividedBytes(cage, level);
  if (bytes > maxBytes)
    throw Error(what + ": subdivision level " + std::to_string(level) + " needs about " +
                std::to_string(bytes >> 20) + " MiB, over the --max-memory budget of " + std::to_string(maxBytes >> 20) +
                " MiB");

  using Descriptor = Far::TopologyDescriptor;
  Descriptor desc;
  desc.numVertices = int(cage.positions.size());
  desc.numFaces = int(cage.faceSizes.size());
  desc.numVertsPerFace = cage.faceSizes.data();
  desc.vertIndicesPerFace = cage.faceIndices.data();
  desc.numCreases = int(cage.creaseWeights.size());
  desc.creaseVertexIndexPairs = cage.creaseEdges.empty() ? nullptr : cage.creaseEdges.data();
  desc.creaseWeights = cage.creaseWeights.empty() ? nullptr : cage.creaseWeights.data();
  Sdc::Options sdc;
  // Open boundaries are interpolated (the cage's boundary edges stay sharp),
  // as modelling packages do.
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  const Sdc::SchemeType type = scheme == SubdivisionScheme::Loop ? Sdc::SCHEME_LOOP : Sdc::SCHEME_CATMARK;
  std::unique_ptr<Far::TopologyRefiner> refiner(
      Far::TopologyRefinerFactory<Descriptor>::Create(desc, Far::TopologyRefinerFactory<Descriptor>::Options(type, sdc)));
  if (!refiner) throw Error(what + ": OpenSubdiv rejected the cage topology");
  Far::TopologyRefiner::UniformOptions uniform(level);
  uniform.fullTopologyInLastLevel = true;  // the limit stencils need it
  refiner->RefineUniform(uniform);

  // Interpolate positions level by level, then push the last level to the limit.
  const int total = refiner->GetNumVerticesTotal();
  std::vector<OsdPoint> buffer(static_cast<size_t>(total));
  for (size_t i = 0; i < cage.positions.size(); ++i)
    buffer[i] = {{double(cage.positions[i].x), double(cage.positions[i].y), double(cage.positions[i].z)}};
  const Far::PrimvarRefiner primvar(*refiner);
  OsdPoint* src = buffer.data();
  for (int l = 1; l <= level; ++l) {
    OsdPoint* dst = src + refiner->GetLevel(l - 1).GetNumVertices();
    primvar.Interpolate(l, src, dst);
    src = dst;
  }
  const Far::TopologyLevel& last = refiner->GetLevel(level);
  const int nv = last.GetNumVertices();
  std::vector<OsdPoint> limit(static_cast<size_t>(nv)), du(static_cast<size_t>(nv)), dv(static_cast<size_t>(nv));
  primvar.Limit(src, limit, du, dv);

  SubdividedMesh out;
  out.positions.resize(size_t(nv));
  out.normals.resize(size_t(nv));
  for (int i = 0; i < nv; ++i) {
    const OsdPoint &p = limit[size_t(i)], &a = du[size_t(i)], &b = dv[size_t(i)];
    out.positions[size_t(i)] = Vec3(float(p.p[0]), float(p.p[1]), float(p.p[2]));
    const double n[3] = {a.p[1] * b.p[2] - a.p[2] * b.p[1], a.p[2] * b.p[0] - a.p[0] * b.p[2],
                         a.p[0] * b.p[1] - a.p[1] * b.p[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    // A vanishing tangent cross product (extraordinary corners of sharp
    // creases) leaves the normal 0: the renderer then uses the geometric one.
    out.normals[size_t(i)] = len > 0 && std::isfinite(len) ? Vec3(float(n[0] / len), float(n[1] / len), float(n[2] / len))
                                                           : Vec3(0, 0, 0);
  }
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const Far::ConstIndexArray v = last.GetFaceVertices(f);
    for (int k = 1; k + 1 < v.size(); ++k)
      out.triangles.insert(out.triangles.end(), {uint32_t(v[0]), uint32_t(v[k]), uint32_t(v[k + 1])});
  }
  return out;
}

}  // namespace obscura
