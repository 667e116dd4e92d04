// What the screen-space integrators (`vo`, `ssat`, `gtao`) share: the per-pixel
// rotation of their sample sets (random, or the 4x4 interleaved pattern of
// AT §4.2), and the one lookup both estimators are built on - the depth z*
// of the first surface on the camera ray through a view-space point q - read
// from the layer's z-buffer (depth=gbuffer) or traced exactly (depth=traced,
// the twin that removes the z-buffer's discretization and keeps the model).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <obscura/screen_space.h>
#include <obscura/params.h>
#include <obscura/sampler.h>

namespace obscura::screen_space {

// None: the integrator reads depth otherwise (vo's area samples: moments).
enum class DepthSource { GBuffer, Traced, None };

// A point q is behind the surface seen through it when depth(q) exceeds z*
// by more than this fraction of z*: a point on the plane a z-buffer read
// reconstructs (zBufferDepth) and the read agree only to float rounding, a
// few ulps (2^-24 each) of the depth; the paper's shader has a bias too.
// Kept this small because every point within it of the surface reads as
// empty: a fraction ~1.5 kDepthBias z / R of a ball's points at depth z.
constexpr float kDepthBias = 2e-6f;

// Parameters shared by the integrators: count, interleave, filter-depth,
// depth, guard-band.
std::vector<ParamSpec> sharedParams(const std::string& countDoc, int countDefault, const std::string& interleaveDefault);
DepthSource depthSourceFromParams(const ParamSet& p);

// Where pixel (x, y)'s samples may read the layer (GBufferLayer: the guard
// band): layer film positions [x0, x1) x [y0, y1) - within g.band pixels of
// the pixel, or with no band (guard-band=0) the whole layer, the image.
// A read outside it knows nothing: no occluder, as off the image.
struct ReadWindow {
  float x0, y0, x1, y1;
  bool contains(float fx, float fy) const { return fx >= x0 && fy >= y0 && fx < x1 && fy < y1; }
};
inline ReadWindow readWindow(const GBufferLayer& g, int x, int y) {
  if (g.band <= 0) return {0.0f, 0.0f, float(g.width), float(g.height)};
  if (g.readsImage)
    return {float(std::max(0, g.image.x0 - g.band)), float(std::max(0, g.image.y0 - g.band)),
            float(std::min(g.width, g.image.x1 + g.band)), float(std::min(g.height, g.image.y1 + g.band))};
  return {float(std::max(0, x - g.band)), float(std::max(0, y - g.band)), float(std::min(g.width, x + g.band + 1)),
          float(std::min(g.height, y + g.band + 1))};
}

// The random numbers that rotate pixel (x, y)'s sample set in layer g.
// With interleaving (AT §4.2) they depend only on (x mod 4, y mod 4) and the
// layer: any 4x4 window holds all 16 rotations, and u.x - the angle of a
// rotation about an axis - is stratified over the 16 (one per sixteenth,
// shifted per layer). Without, they are random per pixel and sample. Each is
// uniform on [0,1)^3 over the layers, so a uniformly random rotation built
// from them keeps the estimators' expectation.
inline Vec3 rotationSample(const GBufferLayer& g, size_t i, int x, int y, bool interleave) {
  if (interleave) {
    // A 4x4 pattern with neighbours far apart in angle (bit-reversed order).
    static constexpr uint8_t kPattern[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};
    const uint32_t k = kPattern[(y & 3) * 4 + (x & 3)];
    const float shift = Sampler::get1D(g.imageKey, g.sampleIndex, kFirstIntegratorDim);
    const Sample2 s = Sampler::get2D(g.imageKey, g.sampleIndex * 16U + k, kFirstIntegratorDim + 1);
    return {(float(k) + shift) / 16.0f, s.u, s.v};
  }
  const Sample2 s = Sampler::get2D(g.pixelKey[i], g.sampleIndex, kFirstIntegratorDim + 1);
  return {Sampler::get1D(g.pixelKey[i], g.sampleIndex, kFirstIntegratorDim), s.u, s.v};
}

// A frame rotated about f.n by the angle with cosine c and sine s.
inline Frame rotateAboutNormal(Frame f, float c, float s) {
  const Vec3 t0 = f.s * c + f.t * s, t1 = f.t * c - f.s * s;
  f.s = t0, f.t = t1;
  return f;
}

// A frame rotated about f.n by the angle 2 pi a.
inline Frame rotateAboutNormal(Frame f, float a) {
  const float phi = 6.2831853071795864f * a;
  return rotateAboutNormal(f, std::cos(phi), std::sin(phi));
}

// The rotations about the normal of a tile's pixels in layer g: with
// interleaving the 16 of the 4x4 pattern, their cosines and sines computed
// once per tile instead of once per pixel; without, per pixel.
class NormalRotations {
 public:
  NormalRotations(const GBufferLayer& g, bool interleave) : interleave_(interleave) {
    if (!interleave) return;
    for (int k = 0; k < 16; ++k) {
      const float phi = 6.2831853071795864f * rotationSample(g, 0, k & 3, k >> 2, true).x;
      cos_[k] = std::cos(phi), sin_[k] = std::sin(phi);
    }
  }
  Frame rotate(const GBufferLayer& g, size_t i, int x, int y, const Frame& f) const {
    if (!interleave_) return rotateAboutNormal(f, rotationSample(g, i, x, y, false).x);
    const int k = (y & 3) * 4 + (x & 3);
    return rotateAboutNormal(f, cos_[k], sin_[k]);
  }

 private:
  bool interleave_;
  float cos_[16] = {}, sin_[16] = {};
};

// A uniformly distributed rotation (as the images of the x, y, z axes) from
// u in [0,1)^3: Shoemake's uniform unit quaternion.
inline Frame uniformRotation(Vec3 u) {
  constexpr float kTwoPi = 6.2831853071795864f;
  const float a = std::sqrt(std::max(0.0f, 1.0f - u.x)), b = std::sqrt(u.x);
  const float qx = a * std::sin(kTwoPi * u.y), qy = a * std::cos(kTwoPi * u.y);
  const float qz = b * std::sin(kTwoPi * u.z), qw = b * std::cos(kTwoPi * u.z);
  Frame f;
  f.s = Vec3(1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy + qz * qw), 2 * (qx * qz - qy * qw));
  f.t = Vec3(2 * (qx * qy - qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz + qx * qw));
  f.n = Vec3(2 * (qx * qz + qy * qw), 2 * (qy * qz - qx * qw), 1 - 2 * (qx * qx + qy * qy));
  return f;
}

// The layer pixel (x, y) a view-space point projects to; false when the
// point is behind the camera or outside the read window.
inline bool pixelOf(const GBufferLayer& g, Vec3 q, const ReadWindow& w, int& x, int& y) {
  if (!(q.z < 0.0f)) return false;
  float fx, fy;
  g.view.project(q, fx, fy);
  if (!w.contains(fx, fy)) return false;
  x = int(fx), y = int(fy);
  return true;
}

// The depth at which the camera ray depth x (a, b, -1) meets the plane
// stored at pixel j, or its stored occluder depth (depthSlack: the depth,
// +inf for background and for objects that occlude nothing) when the ray
// runs along the plane.
inline float planeDepth(const GBufferLayer& g, size_t j, float a, float b) {
  const std::array<float, 4>& p = g.plane[j];
  const float den = p[0] * a + p[1] * b - p[2];
  // A plane seen nearly edge-on (|cos| below 1e-3 of the ray's length) or a
  // background or non-occluding pixel (all zero): the stored depth.
  if (!(std::abs(den) > 1e-3f * std::sqrt(a * a + b * b + 1.0f))) return g.depthSlack[j][0];
  const float z = p[3] / den;
  return z > 0.0f ? z : g.depthSlack[j][0];
}

// Far from pixel j's surface (beyond its depth range over the pixel, with
// the bias's margin) the answer does not depend on where exactly in the
// pixel a point at view depth `depthQ` lies: the stored depth serves, and
// `plane` is not read.
inline bool decidedByStoredDepth(const std::array<float, 2>& ds, float depthQ) {
  return std::abs(depthQ - ds[0]) > ds[1] + 4.0f * kDepthBias * ds[0];
}

// z* from the z-buffer: the depth, along the camera ray through q, of the
// surface stored at the pixel q projects to - that pixel's plane met by the
// ray (GBufferLayer::plane), or its stored depth when the ray runs along the
// plane; +inf when q is behind the camera, outside the read window, or over
// the background (no occluder known there).
// Without `exact` (enough to classify q as in front or behind, and for the
// thresholds of the silhouette rule and the thickness model, which move by
// at most the pixel's depth range) a q far from the pixel's surface gets the
// stored depth; line samples, which place the surface on their chord, ask
// for the plane always.
// `normal`, if not null, receives the stored plane's normal there (view
// space; zero where nothing is known), for gtao's same-plane test.
inline float zBufferDepth(const GBufferLayer& g, Vec3 q, bool exact, const ReadWindow& w, Vec3* normal = nullptr) {
  if (normal) *normal = Vec3(0, 0, 0);
  if (!(q.z < 0.0f)) return kInfinity;
  // The ray through q is depth x (a, b, -1).
  const float inv = 1.0f / -q.z;
  const float a = q.x * inv, b = q.y * inv;
  const float fx = g.view.centreX + a * g.view.filmScaleX;
  const float fy = g.view.centreY - b * g.view.filmScaleY;
  if (!w.contains(fx, fy)) return kInfinity;
  const size_t j = g.index(int(fx), int(fy));
  if (normal) *normal = Vec3(g.plane[j][0], g.plane[j][1], g.plane[j][2]);
  const std::array<float, 2> ds = g.depthSlack[j];
  if (!exact && decidedByStoredDepth(ds, -q.z)) return ds[0];
  return planeDepth(g, j, a, b);
}

// The projection of many points P + o_k, o_k = s ox[k] + t oy[k] + n oz[k]
// (view space; a pixel's point and frame, a sample set's offsets), each
// offset reflected into the half-space c . o >= 0 first (c = 0: no
// reflection; vo's normal clamp, VO §4.4), onto the layer:
// depth[k] = their view depth, or -1 where the point is behind the camera or
// outside the read window; pixel[k] = the index of the pixel it falls in
// (valid where depth[k] > 0). The screen-space loops' arithmetic, written branch-free over
// arrays so that it vectorizes (compiled for AVX2 and baseline, picked at
// load time); the depth-buffer reads that follow are scattered and stay
// scalar.
struct PointProjection {
  float cx, cy, sx, sy;  // the optical axis on the layer, film pixels per unit x/-z and y/-z
  ReadWindow window;     // the pixel's (set per pixel)
  uint32_t width;
  explicit PointProjection(const GBufferLayer& g)
      : cx(g.view.centreX), cy(g.view.centreY), sx(g.view.filmScaleX), sy(g.view.filmScaleY),
        window{0.0f, 0.0f, float(g.width), float(g.height)}, width(uint32_t(g.width)) {}
};
void projectOffsets(const PointProjection& pr, Vec3 P, const Frame& f, Vec3 c, const float* ox, const float* oy,
                    const float* oz, int count, float* depth, uint32_t* pixel);

// z* for a point of view depth depthQ > 0 that projectOffsets placed in
// pixel j: zBufferDepth without the projection. point() rebuilds the point
// (view space), only when the plane must be read.
template <class Point>
inline float zStarAt(const GBufferLayer& g, uint32_t j, float depthQ, bool exact, Point&& point) {
  const std::array<float, 2> ds = g.depthSlack[j];
  if (!exact && decidedByStoredDepth(ds, depthQ)) return ds[0];
  const Vec3 q = point();
  return planeDepth(g, j, q.x / depthQ, q.y / depthQ);
}

// Pixels in flight in forEachPixelPipelined: the slots a caller's buffers
// hold.
constexpr int kPipelineSlots = 4;

// Prefetches layer array `a` at the pixels of n points.
template <class T>
inline void prefetchAt(const LargeVector<T>& a, const uint32_t* pixels, size_t n) {
  for (size_t m = 0; m < n; ++m) __builtin_prefetch(&a[pixels[m]]);
}

// The points of the pixels in flight in forEachPixelPipelined, one slot
// each: the pixel's point P, frame f and clamp normal c, and its points'
// projection (projectOffsets: view depth or -1, pixel index). On the heap,
// once per tile (up to kPipelineSlots x 4096 points).
class PixelPoints {
 public:
  PixelPoints(const GBufferLayer& g, size_t perPixel)
      : g_(g), pr_(g), n_(perPixel), depth_(size_t(kPipelineSlots) * perPixel), pixel_(size_t(kPipelineSlots) * perPixel) {}
  // Slot b: P + o_k for the offsets (ox, oy, oz) in frame f, reflected by
  // c, read from layer pixel (x, y) (its read window).
  void project(int b, int x, int y, Vec3 P, const Frame& f, Vec3 c, const float* ox, const float* oy, const float* oz) {
    this->P[b] = P, this->f[b] = f, this->c[b] = c;
    pr_.window = readWindow(g_, x, y);
    projectOffsets(pr_, P, f, c, ox, oy, oz, int(n_), depth(b), pixels(b));
  }
  float* depth(int b) { return depth_.data() + size_t(b) * n_; }
  uint32_t* pixels(int b) { return pixel_.data() + size_t(b) * n_; }
  size_t size() const { return n_; }
  Vec3 P[kPipelineSlots], c[kPipelineSlots];
  Frame f[kPipelineSlots];

 private:
  const GBufferLayer& g_;
  PointProjection pr_;
  size_t n_;
  std::vector<float> depth_;
  std::vector<uint32_t> pixel_;
};

// The covered pixels of `tile` in two stages kPipelineSlots - 1 pixels
// apart, so that the cache misses of a pixel's scattered depth reads
// overlap the work on the pixels before it: project(i, x, y, slot) places
// the pixel's points in buffer `slot` (0..kPipelineSlots-1) and prefetches
// what finish(i, x, y, slot) will read of the layer for them, later. (Measured on the generated scene
// of bench/bench_screen_space.cpp, where a ball spans ~100 pixels and its
// reads miss the L2.)
// `byClass`: the pixels one 4x4 interleaving class after the other
// ((x, y) mod 4; tiles start at multiples of 4), so that consecutive pixels
// share their rotation and read the depth buffer 4 pixels apart - mostly in
// the cache lines the previous pixel loaded (deinterleaved order).
template <class Project, class Finish>
void forEachPixelPipelined(const GBufferLayer& g, const PixelRect& tile, bool byClass, Project&& project,
                           Finish&& finish) {
  struct Pending {
    size_t i;
    int x, y;
  };
  Pending pending[kPipelineSlots] = {};
  int issued = 0, finished = 0;
  const auto visit = [&](int x, int y) {
    const size_t i = g.index(x, y);
    if (!g.covered(i)) return;
    const int slot = issued % kPipelineSlots;
    if (issued - finished == kPipelineSlots) {  // the ring is full: finish the oldest (this slot's)
      finish(pending[slot].i, pending[slot].x, pending[slot].y, slot);
      ++finished;
    }
    project(i, x, y, slot);
    pending[slot] = {i, x, y};
    ++issued;
  };
  const int step = byClass ? 4 : 1;
  for (int cy = 0; cy < step; ++cy)
    for (int cx = 0; cx < step; ++cx)
      for (int y = tile.y0 + cy; y < tile.y1; y += step)
        for (int x = tile.x0 + cx; x < tile.x1; x += step) visit(x, y);
  for (; finished < issued; ++finished) {
    const int slot = finished % kPipelineSlots;
    finish(pending[slot].i, pending[slot].x, pending[slot].y, slot);
  }
}

// Pixels per run of forEachPixelRun.
constexpr int kPixelRun = 64;

// Lookups of z* for a list of view-space points: from the z-buffer (at
// push, no second pass), or by tracing the camera ray through each point
// (closest hit; z* = the hit's depth, +inf on a miss) in one stream at
// run(). Fixed capacity, allocated once per use: nothing allocates per point.
// With `normals`, also the unit normal (view space) of the surface found:
// the stored plane's, or the traced hit's geometric normal; zero where
// nothing was found.
class DepthLookup {
 public:
  // `exact`: see zBufferDepth.
  DepthLookup(DepthSource src, size_t capacity, bool exact, bool normals = false)
      : src_(src), exact_(exact), q_(capacity), z_(capacity), n_(normals ? capacity : 0) {}
  void clear() { size_ = 0; }
  // The read window of the pixel whose points come next (forEachPixelRun
  // sets it); the traced twin traces every point, wherever it projects.
  void setWindow(const ReadWindow& w) { window_ = w; }
  void push(const GBufferLayer& g, Vec3 q) {
    q_[size_] = q;
    if (src_ == DepthSource::GBuffer)
      z_[size_] = zBufferDepth(g, q, exact_, window_, n_.empty() ? nullptr : &n_[size_]);
    ++size_;
  }
  size_t size() const { return size_; }
  // Traced: fills z(i) for every pushed point (the z-buffer's are filled).
  void run(const GBufferLayer& g, IntegratorContext& ctx) {
    if (src_ != DepthSource::Traced) return;
    IntersectBatch& b = ctx.intersectBatch(size_);
    const Vec3 org = g.view.origin;
    for (size_t i = 0; i < size_; ++i) {
      const Vec3 d = g.view.vectorToWorld(q_[i]);
      const float len = length(d);
      if (q_[i].z < 0.0f && len > 0.0f)
        b.push(org, d * (1.0f / len), 0.0f, kInfinity);  // an occluder query: occluders' mask
      else  // behind the camera: nothing known (inactive ray)
        b.push(org, Vec3(0, 0, -1), kInfinity, 0.0f);
    }
    ctx.trace(b);
    SurfaceHit h;
    for (size_t i = 0; i < size_; ++i) {
      const float len = length(q_[i]);
      z_[i] = b.hit(i) && len > 0.0f ? b.t(i) * (-q_[i].z / len) : kInfinity;
      if (n_.empty()) continue;
      n_[i] = Vec3(0, 0, 0);
      if (z_[i] < kInfinity) {
        ctx.surfaceAt(b, i, false, 0, 0, h);
        n_[i] = g.view.vectorToView(h.ng);
      }
    }
  }
  float z(size_t i) const { return z_[i]; }
  const Vec3& q(size_t i) const { return q_[i]; }
  const Vec3& normal(size_t i) const { return n_[i]; }

 private:
  DepthSource src_;
  bool exact_;
  ReadWindow window_{0.0f, 0.0f, 0.0f, 0.0f};
  std::vector<Vec3> q_;
  std::vector<float> z_;
  std::vector<Vec3> n_;
  size_t size_ = 0;
};

// The pixels of `tile` in runs along its rows, so that the lookups of a
// whole run are made at once (one ray stream for the traced twin): for each
// covered pixel i at (x, y), push(i, x, y) queues exactly `perPixel` points
// on `look`; after the lookup, evaluate(i, x, y, at, out[tile.offset(x, y)]) reads them
// from index `at` and writes the pixel's estimate.
template <class Push, class Evaluate>
void forEachPixelRun(const GBufferLayer& g, const PixelRect& tile, size_t perPixel, IntegratorContext& ctx,
                     DepthLookup& look, SampleEstimate* out, Push&& push, Evaluate&& evaluate) {
  constexpr int kRun = kPixelRun;
  for (int y = tile.y0; y < tile.y1; ++y) {
    for (int xr = tile.x0; xr < tile.x1; xr += kRun) {
      const int xe = std::min(tile.x1, xr + kRun);
      look.clear();
      for (int x = xr; x < xe; ++x)
        if (g.covered(g.index(x, y))) {
          look.setWindow(readWindow(g, x, y));
          push(g.index(x, y), x, y);
        }
      if (look.size() == 0) continue;
      look.run(g, ctx);
      size_t at = 0;
      for (int x = xr; x < xe; ++x) {
        const size_t i = g.index(x, y);
        if (!g.covered(i)) continue;
        evaluate(i, x, y, at, out[tile.offset(x, y)]);
        at += perPixel;
      }
    }
  }
}

}  // namespace obscura::screen_space
