#include "core/subdivision.h"

#include <OpenImageIO/imagebuf.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <cmath>
#include <memory>

#include "core/error.h"

namespace obscura {
namespace {

using namespace OpenSubdiv;

// The primvar OpenSubdiv interpolates: a point (Clear / AddWithWeight).
struct OsdUv {
  double uv[2];
  void Clear(void* = nullptr) { uv[0] = uv[1] = 0.0; }
  void AddWithWeight(const OsdUv& s, float w) { uv[0] += double(w) * s.uv[0], uv[1] += double(w) * s.uv[1]; }
};

struct OsdPoint {
  double p[3];
  void Clear(void* = nullptr) { p[0] = p[1] = p[2] = 0.0; }
  void AddWithWeight(const OsdPoint& s, float w) {
    p[0] += double(w) * s.p[0], p[1] += double(w) * s.p[1], p[2] += double(w) * s.p[2];
  }
};

}  // namespace

void validateCage(const SubdivisionCage& c, SubdivisionScheme scheme, const std::string& what) {
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
  if (!c.uvIndices.empty()) {
    if (c.uvIndices.size() != c.faceIndices.size()) throw Error(what + ": texture coordinates do not cover every face corner");
    for (const int i : c.uvIndices)
      if (i < 0 || size_t(i) * 2 + 1 >= c.uvs.size()) throw Error(what + ": a face refers to texture coordinate " + std::to_string(i) + " of " + std::to_string(c.uvs.size() / 2));
  }
  if (c.creaseEdges.size() != 2 * c.creaseWeights.size()) throw Error(what + ": crease edges and weights do not match");
  for (const int i : c.creaseEdges)
    if (i < 0 || size_t(i) >= nv) throw Error(what + ": a crease refers to vertex " + std::to_string(i));
}


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
  validateCage(cage, scheme, what);
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
  Descriptor::FVarChannel uvChannel;
  const bool hasUv = !cage.uvIndices.empty();
  if (hasUv) {
    uvChannel.numValues = int(cage.uvs.size() / 2);
    uvChannel.valueIndices = cage.uvIndices.data();
    desc.numFVarChannels = 1;
    desc.fvarChannels = &uvChannel;
  }
  Sdc::Options sdc;
  // uvs: smooth inside, linear along seams and boundaries' corners.
  sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_CORNERS_ONLY);
  // Open boundaries are interpolated - boundary edges and corner vertices
  // stay where the cage puts them ("edge and corner", the usual modelling
  // default), so a flat cage's limit is the cage itself.
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
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
  if (hasUv) {
    std::vector<OsdUv> uvBuffer(static_cast<size_t>(refiner->GetNumFVarValuesTotal(0)));
    for (size_t i = 0; i < cage.uvs.size() / 2; ++i) uvBuffer[i] = {{double(cage.uvs[2 * i]), double(cage.uvs[2 * i + 1])}};
    OsdUv* usrc = uvBuffer.data();
    for (int l = 1; l <= level; ++l) {
      OsdUv* udst = usrc + refiner->GetLevel(l - 1).GetNumFVarValues(0);
      primvar.InterpolateFaceVarying(l, usrc, udst, 0);
      usrc = udst;
    }
    std::vector<OsdUv> uvLimit(static_cast<size_t>(last.GetNumFVarValues(0)));
    primvar.LimitFaceVarying(usrc, uvLimit, 0);
    out.uvs.assign(size_t(nv) * 2, 0.0f);
    std::vector<char> set(static_cast<size_t>(nv), 0);
    for (int f = 0; f < last.GetNumFaces(); ++f) {
      const Far::ConstIndexArray v = last.GetFaceVertices(f), t = last.GetFaceFVarValues(f, 0);
      for (int k = 0; k < v.size(); ++k) {
        if (set[size_t(v[k])]) continue;
        set[size_t(v[k])] = 1;
        out.uvs[size_t(v[k]) * 2] = float(uvLimit[size_t(t[k])].uv[0]);
        out.uvs[size_t(v[k]) * 2 + 1] = float(uvLimit[size_t(t[k])].uv[1]);
      }
    }
  }
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const Far::ConstIndexArray v = last.GetFaceVertices(f);
    for (int k = 1; k + 1 < v.size(); ++k)
      out.triangles.insert(out.triangles.end(), {uint32_t(v[0]), uint32_t(v[k]), uint32_t(v[k + 1])});
  }
  return out;
}

HeightMap::HeightMap(const std::string& path) {
  OIIO::ImageBuf buf(path);
  if (!buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) throw Error(path + ": cannot read the height map: " + buf.geterror());
  const OIIO::ImageSpec& spec = buf.spec();
  w_ = spec.width, h_ = spec.height;
  if (w_ < 1 || h_ < 1) throw Error(path + ": the height map is empty");
  texels_.resize(size_t(w_) * size_t(h_));
  if (!buf.get_pixels(OIIO::ROI(0, w_, 0, h_, 0, 1, 0, 1), OIIO::TypeDesc::FLOAT, texels_.data()))
    throw Error(path + ": cannot read the height map: " + buf.geterror());
  for (const float t : texels_)
    if (!std::isfinite(t)) throw Error(path + ": the height map has a non-finite texel");
}

float HeightMap::sample(float u, float v) const {
  // Texel centres at (i + 0.5) / w; rows stored top first, v = 0 at the bottom.
  const double x = double(u) * w_ - 0.5, y = (1.0 - double(v)) * h_ - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const auto wrap = [](long i, int n) { return size_t(((i % n) + n) % n); };
  const long ix = long(fx), iy = long(fy);
  const double ax = x - fx, ay = y - fy;
  const auto at = [&](long i, long j) { return double(texels_[wrap(j, h_) * size_t(w_) + wrap(i, w_)]); };
  return float((at(ix, iy) * (1 - ax) + at(ix + 1, iy) * ax) * (1 - ay) +
               (at(ix, iy + 1) * (1 - ax) + at(ix + 1, iy + 1) * ax) * ay);
}

void displace(SubdividedMesh& m, const HeightMap& height, double scale, double midlevel) {
  if (m.uvs.size() != m.positions.size() * 2) throw Error("displacement needs texture coordinates on the cage");
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const double d = scale * (double(height.sample(m.uvs[2 * i], m.uvs[2 * i + 1])) - midlevel);
    m.positions[i] = m.positions[i] + m.normals[i] * float(d);
  }
  // Normals of the displaced surface: area-weighted triangle normals,
  // oriented like the limit normals they replace.
  std::vector<Vec3> n(m.positions.size(), Vec3(0, 0, 0));
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    const uint32_t a = m.triangles[t], b = m.triangles[t + 1], c = m.triangles[t + 2];
    const Vec3 fn = cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
    n[a] += fn, n[b] += fn, n[c] += fn;
  }
  for (size_t i = 0; i < n.size(); ++i) {
    const float len = length(n[i]);
    Vec3 v = len > 0 && std::isfinite(len) ? n[i] * (1.0f / len) : m.normals[i];
    if (dot(v, m.normals[i]) < 0) v = -v;
    m.normals[i] = v;
  }
}

}  // namespace obscura
