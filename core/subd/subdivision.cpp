#include "core/subd/subdivision.h"
#include "core/image/png_check.h"
#include "core/util/input_file.h"

#include <opensubdiv/far/error.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/sdc/catmarkScheme.h>
#include <opensubdiv/sdc/loopScheme.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <tuple>
#include <memory>
#include <mutex>
#include <string>

#include <obscura/error.h>
#include "core/image/oiio_module.h"
#include "core/util/option_names.h"

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

// The vertex neighbourhood Sdc's limit masks read (its VERTEX interface).
struct LimitHood {
  const Far::TopologyLevel& level;
  int v;
  int GetNumEdges() const { return level.GetVertexEdges(v).size(); }
  int GetNumFaces() const { return level.GetVertexFaces(v).size(); }
  float GetSharpness() const { return level.GetVertexSharpness(v); }
  float* GetSharpnessPerEdge(float* s) const {
    const Far::ConstIndexArray e = level.GetVertexEdges(v);
    for (int i = 0; i < e.size(); ++i) s[i] = level.GetEdgeSharpness(e[i]);
    return s;
  }
};

// Sdc's MASK interface over caller-owned weights.
struct LimitMask {
  using Weight = double;
  double *vw, *ew, *fw;
  int nv = 0, ne = 0, nf = 0;
  bool centres = false;
  int GetNumVertexWeights() const { return nv; }
  int GetNumEdgeWeights() const { return ne; }
  int GetNumFaceWeights() const { return nf; }
  void SetNumVertexWeights(int n) { nv = n; }
  void SetNumEdgeWeights(int n) { ne = n; }
  void SetNumFaceWeights(int n) { nf = n; }
  double& VertexWeight(int i) { return vw[i]; }
  double& EdgeWeight(int i) { return ew[i]; }
  double& FaceWeight(int i) { return fw[i]; }
  double VertexWeight(int i) const { return vw[i]; }
  double EdgeWeight(int i) const { return ew[i]; }
  double FaceWeight(int i) const { return fw[i]; }
  bool AreFaceWeightsForFaceCenters() const { return centres; }
  void SetFaceWeightsForFaceCenters(bool on) { centres = on; }
};

// Limit positions and tangents of every vertex of the last level - what
// Far::PrimvarRefiner::Limit computes, with the same Sdc masks, but with each
// mask's edge and face weights sized by the vertex's own edge and face counts.
// OpenSubdiv 3.5's Limit sizes each mask's face-weight slot (and its index
// buffer) by the level's largest valence (edge count), assuming no vertex
// has more faces than edges - true of manifold vertices, false at a
// non-manifold one. Catmull-Clark refinement of an edge shared by N faces
// puts on it a vertex with N + 2 edges and 2N faces: from N = 3 the face
// weights of one mask spill into the next (wrong tangents, silently), and
// from N = 11 the 3N + 2 neighbour indices overrun the 33-entry stack buffer
// (heap or stack corruption; measured under ASan: N = 10 clean, N = 11
// corrupts). Loop's refined edge vertex has 2N + 2 edges and 2N faces, so
// Loop never overflowed; the same code serves both schemes.
template <class Scheme>
void limitLevel(const Scheme& scheme, const Far::TopologyLevel& level, const OsdPoint* src, std::vector<OsdPoint>& pos,
                std::vector<OsdPoint>& tan1, std::vector<OsdPoint>& tan2) {
  std::vector<double> w;
  std::vector<int> opposite;
  for (int v = 0; v < level.GetNumVertices(); ++v) {
    const Far::ConstIndexArray edges = level.GetVertexEdges(v), faces = level.GetVertexFaces(v);
    OsdPoint &p = pos[size_t(v)], &t1 = tan1[size_t(v)], &t2 = tan2[size_t(v)];
    p.Clear(), t1.Clear(), t2.Clear();
    if (edges.size() == 0) {  // an isolated vertex stays where it is
      p.AddWithWeight(src[v], 1.0f);
      continue;
    }
    const size_t ne = size_t(edges.size()), nf = size_t(faces.size()), per = 1 + ne + nf;
    w.assign(3 * per, 0.0);
    LimitMask m[3];
    for (size_t k = 0; k < 3; ++k) m[k].vw = &w[k * per], m[k].ew = &w[k * per + 1], m[k].fw = &w[k * per + 1 + ne];
    scheme.ComputeVertexLimitMask(LimitHood{level, v}, m[0], m[1], m[2], level.GetVertexRule(v));
    // Neighbours: the far end of each edge, the vertex two along each face.
    opposite.resize(ne + nf);
    for (size_t i = 0; i < ne; ++i) {
      const Far::ConstIndexArray ev = level.GetEdgeVertices(edges[int(i)]);
      opposite[i] = ev[0] == v ? ev[1] : ev[0];
    }
    const Far::ConstLocalIndexArray inFace = level.GetVertexFaceLocalIndices(v);
    for (size_t i = 0; i < nf; ++i) {
      const Far::ConstIndexArray fv = level.GetFaceVertices(faces[int(i)]);
      opposite[ne + i] = fv[(inFace[int(i)] + 2) % fv.size()];
    }
    OsdPoint* dst[3] = {&p, &t1, &t2};
    for (size_t k = 0; k < 3; ++k) {
      // Smallest weights first (faces, edges, the vertex), as OpenSubdiv does.
      for (int i = 0; i < m[k].nf; ++i) dst[k]->AddWithWeight(src[opposite[ne + size_t(i)]], float(m[k].fw[i]));
      for (int i = 0; i < m[k].ne; ++i) dst[k]->AddWithWeight(src[opposite[size_t(i)]], float(m[k].ew[i]));
      if (m[k].nv > 0) dst[k]->AddWithWeight(src[v], float(m[k].vw[0]));
    }
  }
}

// OpenSubdiv prints its errors and warnings to stdout unless given callbacks
// (which are process-wide). They are collected per thread while a cage is
// refined, then thrown (errors) or warned about (warnings) on one line each
// naming the cage, so stdout stays the command's own.
thread_local std::vector<std::string>* tOsdMessages = nullptr;

void collectOsdMessage(const std::string& message) {
  std::string m = message;
  for (char& c : m)
    if (c == '\n' || c == '\r') c = ' ';
  while (!m.empty() && m.back() == ' ') m.pop_back();
  if (tOsdMessages)
    tOsdMessages->push_back(m);
  else
    Log::warn("OpenSubdiv: " + m);
}

class OsdMessages {
 public:
  explicit OsdMessages(const std::string& what) : what_(what) {
    static std::once_flag once;
    std::call_once(once, [] {
      Far::SetErrorCallback([](Far::ErrorType, const char* m) { collectOsdMessage(m ? m : "error"); });
      Far::SetWarningCallback([](const char* m) { collectOsdMessage(m ? m : "warning"); });
    });
    tOsdMessages = &messages_;
  }
  ~OsdMessages() { tOsdMessages = nullptr; }
  OsdMessages(const OsdMessages&) = delete;
  OsdMessages& operator=(const OsdMessages&) = delete;
  // The messages so far joined into one clause ("" when none).
  std::string joined() const {
    std::string r;
    for (const std::string& m : messages_) r += (r.empty() ? "" : "; ") + m;
    return r;
  }
  void warnAll() {
    for (const std::string& m : messages_) Log::warn(what_ + ": OpenSubdiv: " + m);
    messages_.clear();
  }

 private:
  std::string what_;
  std::vector<std::string> messages_;
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
  // (Loop), then x4 per level. Per refined face the process's peak grows by
  // about 520 bytes: OpenSubdiv's refinement tables, the triangles'
  // positions, normals and uvs, and Embree's BVH build at its peak
  // (measured: `obscura render` of the Spot cage at level 7, 3.0M quads,
  // peak RSS 1.49 GiB above level 0; obscura_bench_subdiv shows Embree's
  // own share, 256 bytes a quad at the build's peak).
  constexpr double kBytesPerFace = 520.0;
  double faces = 0;
  for (const int n : cage.faceSizes) faces += n == 3 ? 4.0 : double(n);
  faces *= std::pow(4.0, std::max(level - 1, 0));
  if (level == 0) faces = double(cage.faceSizes.size());
  return size_t(std::min(faces * kBytesPerFace, 1e18));
}

SubdividedMesh subdivide(const SubdivisionCage& cage, SubdivisionScheme scheme, int level, size_t maxBytes,
                         const std::string& what) {
  if (level < 0 || level > 10) throw Error(what + ": subdivision level " + std::to_string(level) + " is outside [0, 10]");
  validateCage(cage, scheme, what);
  const size_t bytes = subdividedBytes(cage, level);
  if (bytes > maxBytes)
    throw Error(what + ": subdivision level " + std::to_string(level) + " needs about " +
                std::to_string(bytes >> 20) + " MiB, over the " + settingName(Setting::MaxMemory) + " budget of " + std::to_string(maxBytes >> 20) +
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
  // uvs: bilinear over each cage face (CageUvs), the parametrization the
  // Embree backend displaces with too, so both backends move a point alike.
  sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
  // Open boundaries are interpolated - boundary edges and corner vertices
  // stay where the cage puts them ("edge and corner", the usual modelling
  // default), so a flat cage's limit is the cage itself.
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
  const Sdc::SchemeType type = scheme == SubdivisionScheme::Loop ? Sdc::SCHEME_LOOP : Sdc::SCHEME_CATMARK;
  OsdMessages messages(what);
  std::unique_ptr<Far::TopologyRefiner> refiner(
      Far::TopologyRefinerFactory<Descriptor>::Create(desc, Far::TopologyRefinerFactory<Descriptor>::Options(type, sdc)));
  if (!refiner) {
    const std::string why = messages.joined();
    throw Error(what + ": OpenSubdiv rejected the cage topology" + (why.empty() ? "" : ": " + why));
  }
  Far::TopologyRefiner::UniformOptions uniform(level);
  uniform.fullTopologyInLastLevel = true;  // the limit masks need it
  refiner->RefineUniform(uniform);
  messages.warnAll();

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
  if (type == Sdc::SCHEME_LOOP)
    limitLevel(Sdc::Scheme<Sdc::SCHEME_LOOP>(sdc), last, src, limit, du, dv);
  else
    limitLevel(Sdc::Scheme<Sdc::SCHEME_CATMARK>(sdc), last, src, limit, du, dv);

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
    // A non-manifold vertex (three or more sheets meet there) has no single
    // tangent plane: normal 0, so each sheet shades with its own facets.
    out.normals[size_t(i)] = len > 0 && std::isfinite(len) && !last.IsVertexNonManifold(i) ? Vec3(float(n[0] / len), float(n[1] / len), float(n[2] / len))
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
    // One vertex per (vertex, uv) pair: a vertex on a uv seam is split into
    // copies at the same position, one per side, so every triangle
    // interpolates its own chart's uvs (textures and texture-space
    // integrators stay clean along seams) while the copies' identical
    // coordinates keep the surface watertight. The first copy is canonical
    // (weld): displacement moves all copies by its uv, so none separates.
    out.uvs.assign(size_t(nv) * 2, 0.0f);
    out.weld.resize(size_t(nv));
    for (int i = 0; i < nv; ++i) out.weld[size_t(i)] = uint32_t(i);
    // Copies are keyed by the uv's value: corners with equal uvs (welded
    // glTF vertices have several fvar values of one uv) share a vertex.
    std::vector<char> seen(static_cast<size_t>(nv), 0);
    std::map<std::tuple<int, float, float>, uint32_t> copies;  // (vertex, uv) -> split copy
    const auto cornerIndex = [&](int v, int t) -> uint32_t {
      const float su = float(uvLimit[size_t(t)].uv[0]), sv = float(uvLimit[size_t(t)].uv[1]);
      float* own = &out.uvs[size_t(v) * 2];
      if (!seen[size_t(v)]) {
        seen[size_t(v)] = 1;
        own[0] = su, own[1] = sv;
        return uint32_t(v);
      }
      if (own[0] == su && own[1] == sv) return uint32_t(v);
      const auto [it, fresh] = copies.emplace(std::tuple{v, su, sv}, uint32_t(out.positions.size()));
      if (fresh) {
        out.positions.push_back(out.positions[size_t(v)]);
        out.normals.push_back(out.normals[size_t(v)]);
        out.uvs.insert(out.uvs.end(), {su, sv});
        out.weld.push_back(uint32_t(v));
      }
      return it->second;
    };
    for (int f = 0; f < last.GetNumFaces(); ++f) {
      const Far::ConstIndexArray v = last.GetFaceVertices(f), t = last.GetFaceFVarValues(f, 0);
      const uint32_t c0 = cornerIndex(v[0], t[0]);
      for (int k = 1; k + 1 < v.size(); ++k)
        out.triangles.insert(out.triangles.end(), {c0, cornerIndex(v[k], t[k]), cornerIndex(v[k + 1], t[k + 1])});
    }
    return out;
  }
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const Far::ConstIndexArray v = last.GetFaceVertices(f);
    for (int k = 1; k + 1 < v.size(); ++k)
      out.triangles.insert(out.triangles.end(), {uint32_t(v[0]), uint32_t(v[k]), uint32_t(v[k + 1])});
  }
  return out;
}

CageUvs::CageUvs(const SubdivisionCage& c) {
  faceStart_.reserve(c.faceSizes.size() + 1);
  uint32_t k = 0;
  for (const int n : c.faceSizes) faceStart_.push_back(k), k += uint32_t(n);
  faceStart_.push_back(k);
  const auto uvOf = [&](uint32_t corner, int a) { return c.uvs[size_t(c.uvIndices[corner]) * 2 + size_t(a)]; };
  cornerUv_.resize(size_t(k) * 2);
  for (uint32_t i = 0; i < k; ++i) cornerUv_[2 * i] = uvOf(i, 0), cornerUv_[2 * i + 1] = uvOf(i, 1);
  // Canonical uvs: the first face (in order) to use a vertex or an edge.
  std::vector<int64_t> vertexCorner(c.positions.size(), -1);
  std::map<std::pair<int, int>, uint32_t> edgeCorner;  // (lo, hi) -> first corner whose edge it is
  vertexUv_.resize(size_t(k) * 2);
  edgeUv_.resize(size_t(k) * 4);
  for (size_t f = 0; f < c.faceSizes.size(); ++f) {
    const uint32_t first = faceStart_[f], n = faceStart_[f + 1] - first;
    for (uint32_t j = 0; j < n; ++j) {
      const uint32_t corner = first + j, next = first + (j + 1) % n;
      const int a = c.faceIndices[corner], b = c.faceIndices[next];
      if (vertexCorner[size_t(a)] < 0) vertexCorner[size_t(a)] = corner;
      edgeCorner.emplace(std::minmax(a, b), corner);
    }
  }
  for (size_t f = 0; f < c.faceSizes.size(); ++f) {
    const uint32_t first = faceStart_[f], n = faceStart_[f + 1] - first;
    for (uint32_t j = 0; j < n; ++j) {
      const uint32_t corner = first + j, next = first + (j + 1) % n;
      const int a = c.faceIndices[corner], b = c.faceIndices[next];
      const uint32_t vc = uint32_t(vertexCorner[size_t(a)]);
      vertexUv_[2 * corner] = cornerUv_[2 * vc], vertexUv_[2 * corner + 1] = cornerUv_[2 * vc + 1];
      // The canonical corner ca runs either a -> b or b -> a.
      const uint32_t ca = edgeCorner.at(std::minmax(a, b));
      const uint32_t cf = uint32_t(std::upper_bound(faceStart_.begin(), faceStart_.end(), ca) - faceStart_.begin()) - 1;
      const uint32_t cn = faceStart_[cf] + (ca - faceStart_[cf] + 1) % (faceStart_[cf + 1] - faceStart_[cf]);
      const bool same = c.faceIndices[ca] == a;
      const uint32_t atA = same ? ca : cn, atB = same ? cn : ca;
      float* e = &edgeUv_[size_t(corner) * 4];
      e[0] = cornerUv_[2 * atA], e[1] = cornerUv_[2 * atA + 1], e[2] = cornerUv_[2 * atB], e[3] = cornerUv_[2 * atB + 1];
    }
  }
}

void CageUvs::onEdge(uint32_t k, float x, float& s, float& t) const {
  // Within rounding of a corner (as at() tolerates for edges): the vertex's
  // canonical uv, which every face around it agrees on.
  constexpr float kAtCorner = 1e-6f;
  if (x <= kAtCorner) {
    s = vertexUv_[2 * k], t = vertexUv_[2 * k + 1];
    return;
  }
  const uint32_t face = uint32_t(std::upper_bound(faceStart_.begin(), faceStart_.end(), k) - faceStart_.begin()) - 1;
  const uint32_t n = faceStart_[face + 1] - faceStart_[face], next = faceStart_[face] + (k - faceStart_[face] + 1) % n;
  if (x >= 1.0f - kAtCorner) {
    s = vertexUv_[2 * next], t = vertexUv_[2 * next + 1];
    return;
  }
  const float* e = &edgeUv_[size_t(k) * 4];
  s = (1 - x) * e[0] + x * e[2];
  t = (1 - x) * e[1] + x * e[3];
}

void CageUvs::at(uint32_t face, float u, float v, float& s, float& t) const {
  // Points within this much of a cage edge (in patch coordinates) lie on it;
  // Embree generates boundary points at exactly 0 or 1, up to rounding.
  constexpr float kOnEdge = 1e-6f;
  const uint32_t first = faceStart_[face], n = faceStart_[face + 1] - first;
  const float* c = &cornerUv_[size_t(first) * 2];
  if (n == 4) {
    if (v <= kOnEdge) return onEdge(first, u, s, t);
    if (u >= 1 - kOnEdge) return onEdge(first + 1, v, s, t);
    if (v >= 1 - kOnEdge) return onEdge(first + 2, 1 - u, s, t);
    if (u <= kOnEdge) return onEdge(first + 3, 1 - v, s, t);
    const float a = (1 - u) * (1 - v), b = u * (1 - v), cc = u * v, d = (1 - u) * v;
    s = a * c[0] + b * c[2] + cc * c[4] + d * c[6];
    t = a * c[1] + b * c[3] + cc * c[5] + d * c[7];
    return;
  }
  // Sub-quad i and its local coordinates, decoded as Embree documents.
  const float hu = 0.5f * u, hv = 0.5f * v;
  const uint32_t i = std::min(4 * uint32_t(std::max(std::floor(hv), 0.0f)) + uint32_t(std::max(std::floor(hu), 0.0f)), n - 1);
  const float lu = 2.0f * (hu - std::floor(hu)) - 0.5f, lv = 2.0f * (hv - std::floor(hv)) - 0.5f;
  // The sub-quad's edges on the cage face's boundary: lv = 0 is the first
  // half of edge i, lu = 0 the second half of edge i - 1.
  if (lv <= kOnEdge) return onEdge(first + i, 0.5f * lu, s, t);
  if (lu <= kOnEdge) return onEdge(first + (i + n - 1) % n, 1.0f - 0.5f * lv, s, t);
  float centre[2] = {0, 0};
  for (uint32_t k = 0; k < n; ++k) centre[0] += c[2 * k], centre[1] += c[2 * k + 1];
  centre[0] /= float(n), centre[1] /= float(n);
  const float* p0 = c + 2 * i;
  const float* pn = c + 2 * ((i + 1) % n);
  const float* pp = c + 2 * ((i + n - 1) % n);
  for (int a = 0; a < 2; ++a) {
    const float q0 = p0[a], q1 = 0.5f * (p0[a] + pn[a]), q2 = centre[a], q3 = 0.5f * (p0[a] + pp[a]);
    const float r = (1 - lu) * (1 - lv) * q0 + lu * (1 - lv) * q1 + lu * lv * q2 + (1 - lu) * lv * q3;
    (a == 0 ? s : t) = r;
  }
}

HeightMap::HeightMap(const std::string& path) {
  checkInputFile(path);
  checkPngFitsItsFile(path);
  // Any format OpenImageIO reads, so through its module (core/image/oiio_module.h).
  oiioModule(path).readFirstChannel(path, w_, h_, texels_);
  for (const float t : texels_)
    if (!std::isfinite(t)) throw Error(path + ": the height map has a non-finite texel");
  const auto [lo, hi] = std::minmax_element(texels_.begin(), texels_.end());
  min_ = *lo, max_ = *hi;
}

double HeightMap::sample(double u, double v) const {
  // Texel centres at (i + 0.5) / w; rows stored top first, v = 0 at the
  // bottom. Repeat: the fractional parts of u and v put x in [-0.5, w - 0.5],
  // so the lower texel index is in [-1, w - 1] - one wrap each way at most,
  // without a modulo per lookup (this sits in renders' hot loops: the
  // containment integrator, Embree's displacement and shading normals).
  if (!std::isfinite(u)) u = 0;
  if (!std::isfinite(v)) v = 0;
  const double x = (u - std::floor(u)) * w_ - 0.5, y = (1.0 - (v - std::floor(v))) * h_ - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const double ax = x - fx, ay = y - fy;
  int i0 = int(fx), j0 = int(fy);
  if (i0 < 0) i0 += w_;
  if (j0 < 0) j0 += h_;
  if (i0 >= w_) i0 -= w_;
  if (j0 >= h_) j0 -= h_;
  const int i1 = i0 + 1 == w_ ? 0 : i0 + 1, j1 = j0 + 1 == h_ ? 0 : j0 + 1;
  const float* r0 = &texels_[size_t(j0) * size_t(w_)];
  const float* r1 = &texels_[size_t(j1) * size_t(w_)];
  return (double(r0[i0]) * (1 - ax) + double(r0[i1]) * ax) * (1 - ay) +
         (double(r1[i0]) * (1 - ax) + double(r1[i1]) * ax) * ay;
}

void displace(SubdividedMesh& m, const HeightMap& height, double scale, double midlevel, bool flipV) {
  if (m.uvs.size() != m.positions.size() * 2) throw Error("displacement needs texture coordinates on the cage");
  const auto canonical = [&](size_t i) { return m.weld.empty() ? i : size_t(m.weld[i]); };
  // Canonical vertices first (a copy's canonical vertex has a lower index),
  // then each seam copy takes its canonical vertex's displaced position.
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const size_t c = canonical(i);
    if (c != i) {
      m.positions[i] = m.positions[c];
      continue;
    }
    const float v = flipV ? 1.0f - m.uvs[2 * i + 1] : m.uvs[2 * i + 1];
    const double d = scale * (height.sample(m.uvs[2 * i], v) - midlevel);
    m.positions[i] = m.positions[i] + m.normals[i] * float(d);
  }
  // Normals of the displaced surface: area-weighted triangle normals,
  // gathered on the canonical vertex (so seam copies shade alike), oriented
  // like the limit normals they replace.
  std::vector<Vec3> n(m.positions.size(), Vec3(0, 0, 0));
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    const uint32_t a = m.triangles[t], b = m.triangles[t + 1], c = m.triangles[t + 2];
    const Vec3 fn = cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
    n[canonical(a)] += fn, n[canonical(b)] += fn, n[canonical(c)] += fn;
  }
  for (size_t i = 0; i < n.size(); ++i) {
    const size_t c = canonical(i);
    const float len = length(n[c]);
    Vec3 v = len > 0 && std::isfinite(len) ? n[c] * (1.0f / len) : m.normals[i];
    if (dot(v, m.normals[i]) < 0) v = -v;
    m.normals[i] = v;
  }
}

}  // namespace obscura
