// The environment: the radiance L(w) arriving from infinitely far away in
// each direction w (docs/math.md §14). A uniform sky (--sky R,G,B) is the
// constant environment; --environment FILE is an equirectangular
// (latitude-longitude) map. This is the view integrators read: plain data
// and inline lookups, no call into the core per ray. The core builds it
// (core/scene/environment.h) and hands it out through
// IntegratorContext::environment().
//
// The mapping (docs/math.md §14.1) is Blender's equirectangular mapping for
// a glTF imported into Blender (glTF +Y up is Blender +Z up, glTF -Z is
// Blender +Y), so a map lights a scene here as Blender's World Environment
// Texture lights it there. In glTF coordinates, for a unit direction d
// (towards the sky) in the map's frame:
//
//   u = 1/2 + atan2(d.z, d.x) / (2 pi)   (0 at the left column, 1 at the right)
//   v = acos(d.y) / pi                   (0 at the top row, 1 at the bottom)
//
// so +X looks at the middle column, +Z at three quarters across, -X at the
// left and right edges, +Y (up) along the top row. Texel (i, j) (column i,
// row j from the top) covers u in [i, i + 1) / W and v in [j, j + 1) / H.
// Radiance is piecewise constant over texels (Blender's "Closest"
// interpolation): what makes the sampling density below exactly
// proportional to it.
//
// Rotation by phi about the up axis (--environment-rotation, right-handed
// about +Y: +X turns towards -Z): L(w) = L_map(R(-phi) w).
//
// Sampling (docs/math.md §14.3): a texel is drawn with probability
// proportional to lum(L_ij) Omega_ij, its luminance times its solid angle
// Omega_ij = (2 pi / W) (cos theta_j - cos theta_(j+1)) (the sin theta
// factor of a lat-long map, exactly), then a direction uniformly in solid
// angle within it. The density is pdf(w) = P(texel) / Omega_texel, computed
// from the same float CDFs the sampler searches, so pdf() is exactly the
// probability the sampler realises: a texel whose CDF step rounds to zero
// has pdf 0 and is left to the other technique of a MIS estimator, which
// keeps it unbiased.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <obscura/math.h>
#include <obscura/sampler.h>

namespace obscura {

// Rec. 709 luminance: the sampling density's weight. Every channel's
// weight is positive, so a texel with any radiance has a positive density.
inline float luminance(Vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// The power heuristic (Veach 1997, eq. 9.13): the MIS weight of a direction
// drawn by the technique of density pThis, against one of density pOther.
inline double powerHeuristic(double pThis, double pOther) {
  return pThis * pThis / (pThis * pThis + pOther * pOther);
}

// The map coordinates (u, v) in [0, 1]^2 of a unit direction in the map's
// frame (see above).
inline void directionToLatLong(Vec3 d, float& u, float& v) {
  constexpr float kInv2Pi = 0.15915494309189533577f;
  u = 0.5f + std::atan2(d.z, d.x) * kInv2Pi;
  // atan2 of the sine and cosine: accurate at the poles, where acos(d.y)
  // loses half its digits.
  v = std::atan2(std::sqrt(d.x * d.x + d.z * d.z), d.y) * kInvPi;
}

// The unit direction at map coordinates (u, v): the inverse of
// directionToLatLong.
inline Vec3 latLongToDirection(float u, float v) {
  const float phi = (u - 0.5f) * (2.0f * kPi), theta = v * kPi;
  const float st = std::sin(theta);
  return {st * std::cos(phi), std::cos(theta), st * std::sin(phi)};
}

struct EnvironmentView {
  // Radiance, four floats a texel - R, G, B with the strength applied, and
  // the texel's density pdf (per steradian; 0 if the map cannot be
  // sampled) - width x height texels, top row first.
  const float* texels = nullptr;
  uint32_t width = 1, height = 1;
  bool constant = true;  // every texel equal: radiance() is texels[0..2] everywhere
  // R(-phi) as cosine and sine (rotation 0: exactly 1 and 0).
  float cosRotation = 1.0f, sinRotation = 0.0f;
  // Sampling: rowCdf has height + 1 entries (0 ... 1), columnCdf height
  // rows of width + 1 (each 0 ... 1, or all 0 for a black row);
  // rowSolidAngle[j] = Omega of a texel of row j. samplable: some texel has
  // radiance (a black map cannot be sampled and needs no sampling).
  const float* rowCdf = nullptr;
  const float* columnCdf = nullptr;
  // Guide tables (docs/math.md §14.3, "Cost"): rowGuide has rowGuideSize
  // entries, columnGuide height rows of columnGuideSize; entry k of a CDF's
  // guide is the step pick() returns for x = k / size, where the search for
  // any x in [k, k + 1) / size starts. Only a start: the walk from it gives
  // the binary search's answer exactly, wherever it starts.
  const uint32_t* rowGuide = nullptr;
  const uint32_t* columnGuide = nullptr;
  uint32_t rowGuideSize = 1, columnGuideSize = 1;
  const float* rowSolidAngle = nullptr;
  const float* rowCos = nullptr;  // height + 1 entries: cos(pi j / height), the rows' bounds
  bool samplable = false;
  // E0(n) / pi, the unoccluded irradiance over pi (docs/math.md §14.4):
  // irradianceWidth x irradianceHeight RGB nodes on the lat-long, node
  // (i, j) at u = i / irradianceWidth (wrapping), v = j / (irradianceHeight
  // - 1) (both poles are rows), interpolated bilinearly; or, with sh9, the
  // nine spherical-harmonic coefficients per channel (sh[3 k + c]).
  const float* irradiance = nullptr;
  uint32_t irradianceWidth = 0, irradianceHeight = 0;
  bool sh9 = false;
  float sh[27] = {};
  // (1/4pi) Int L dw per channel: the uniform sky of the same power.
  Vec3 meanRadiance{1, 1, 1};

  // A world direction in the map's frame.
  Vec3 toMap(Vec3 w) const {
    return {cosRotation * w.x - sinRotation * w.z, w.y, sinRotation * w.x + cosRotation * w.z};
  }
  Vec3 fromMap(Vec3 m) const {
    return {cosRotation * m.x + sinRotation * m.z, m.y, -sinRotation * m.x + cosRotation * m.z};
  }
  // The texel a world direction falls in, as column and row.
  void texelOf(Vec3 w, uint32_t& i, uint32_t& j) const {
    float u, v;
    directionToLatLong(toMap(w), u, v);
    i = std::min(width - 1, uint32_t(std::max(0.0f, u * float(width))));
    j = std::min(height - 1, uint32_t(std::max(0.0f, v * float(height))));
  }
  Vec3 texel(uint32_t i, uint32_t j) const {
    const float* t = texels + 4 * (size_t(j) * width + i);
    return {t[0], t[1], t[2]};
  }
  float storedPdf(uint32_t i, uint32_t j) const { return texels[4 * (size_t(j) * width + i) + 3]; }
  // L(w) for a unit world direction w.
  Vec3 radiance(Vec3 w) const {
    if (constant) return {texels[0], texels[1], texels[2]};
    uint32_t i, j;
    texelOf(w, i, j);
    return texel(i, j);
  }
  // The probability of texel (i, j) over its solid angle (0 if never drawn).
  float texelPdf(uint32_t i, uint32_t j) const {
    const float* c = columnCdf + size_t(j) * (width + 1);
    return (rowCdf[j + 1] - rowCdf[j]) * (c[i + 1] - c[i]) / rowSolidAngle[j];
  }
  // The density (per steradian) with which sample() draws w.
  float pdf(Vec3 w) const {
    if (!samplable) return 0.0f;
    uint32_t i, j;
    texelOf(w, i, j);
    return storedPdf(i, j);
  }
  // L(w) and pdf(w) with one texel lookup (a cosine direction's escape
  // under MIS needs both).
  Vec3 radianceAndPdf(Vec3 w, float& density) const { return radianceAndPdfAt(texelIndex(w), density); }
  // The same in two steps, for a batch of lookups: texelIndex() of each
  // direction with prefetch() of its texel first, then
  // radianceAndPdfAt() of each - the texel array is far larger than the
  // caches, and the lookups' misses overlap instead of following one
  // another (docs/math.md §14.3, "Cost").
  size_t texelIndex(Vec3 w) const {
    uint32_t i = 0, j = 0;
    if (!constant) texelOf(w, i, j);
    return size_t(j) * width + i;
  }
  void prefetch(size_t texel) const { prefetchLine(texels + 4 * texel); }
  Vec3 radianceAndPdfAt(size_t texel, float& density) const {
    const float* t = texels + 4 * texel;
    density = t[3];
    return {t[0], t[1], t[2]};
  }
  // A direction drawn from the density above (samplable only), with its
  // density and the radiance of the texel it lies in (the one drawn, not a
  // lookup of the direction, which could round into a neighbour).
  Vec3 sample(Sample2 s, float& density, Vec3& L) const {
    Draw d;
    drawRow(s, d);
    drawStart(d);
    drawColumn(s, d);
    return drawDirection(s, d, density, L);
  }
  // sample() in stages, for a batch of draws: each stage of every draw,
  // then the next. A stage prefetches what the next one reads - the column
  // guide's entry, the column CDF where the walk starts, the texel - so
  // the batch's cache misses overlap (docs/math.md §14.3, "Cost"). The
  // same arithmetic as sample(): the same direction, bit for bit.
  struct Draw {
    uint32_t j = 0;  // the row
    uint32_t i = 0;  // the column guide's slot, then the walk's start, then the column
  };
  void drawRow(Sample2 s, Draw& d) const {
    d.j = guidedPick(rowCdf, height, rowGuide, rowGuideSize, s.v);
    d.i = guideSlot(columnGuideSize, s.u);
    prefetchLine(columnGuide + size_t(d.j) * columnGuideSize + d.i);
  }
  void drawStart(Draw& d) const {
    d.i = columnGuide[size_t(d.j) * columnGuideSize + d.i];
    prefetchLine(columnCdf + size_t(d.j) * (width + 1) + d.i);
  }
  void drawColumn(Sample2 s, Draw& d) const {
    d.i = walk(columnCdf + size_t(d.j) * (width + 1), width, d.i, s.u);
    prefetch(size_t(d.j) * width + d.i);
  }
  Vec3 drawDirection(Sample2 s, const Draw& d, float& density, Vec3& L) const {
    const uint32_t i = d.i, j = d.j;
    const float* c = columnCdf + size_t(j) * (width + 1);
    // Uniform in solid angle within the texel: phi uniform, cos theta uniform.
    const float fu = remap(c, i, s.u), fv = remap(rowCdf, j, s.v);
    const float phi = ((float(i) + fu) / float(width) - 0.5f) * (2.0f * kPi);
    const float c0 = rowCos[j], c1 = rowCos[j + 1];
    const float cosTheta = std::clamp(c0 + (c1 - c0) * fv, -1.0f, 1.0f);
    const float sinTheta = std::sqrt(std::max(0.0f, 1.0f - cosTheta * cosTheta));
    const float* t = texels + 4 * (size_t(j) * width + i);
    density = t[3];
    L = Vec3(t[0], t[1], t[2]);
    return fromMap({sinTheta * std::cos(phi), cosTheta, sinTheta * std::sin(phi)});
  }
  // E0(n) / pi for a unit world normal n (docs/math.md §14.4).
  Vec3 irradianceOverPi(Vec3 n) const {
    if (constant) return {texels[0], texels[1], texels[2]};
    const Vec3 m = toMap(n);
    if (sh9) return evalSh9(m);
    float u, v;
    directionToLatLong(m, u, v);
    const float x = u * float(irradianceWidth), y = v * float(irradianceHeight - 1);
    const uint32_t i0 = std::min(irradianceWidth - 1, uint32_t(std::max(0.0f, x)));
    const uint32_t j0 = std::min(irradianceHeight - 2, uint32_t(std::max(0.0f, y)));
    const float fx = std::clamp(x - float(i0), 0.0f, 1.0f), fy = std::clamp(y - float(j0), 0.0f, 1.0f);
    const uint32_t i1 = i0 + 1 == irradianceWidth ? 0 : i0 + 1;
    const auto node = [&](uint32_t i, uint32_t j) {
      const float* t = irradiance + 3 * (size_t(j) * irradianceWidth + i);
      return Vec3(t[0], t[1], t[2]);
    };
    const Vec3 top = node(i0, j0) * (1.0f - fx) + node(i1, j0) * fx;
    const Vec3 bottom = node(i0, j0 + 1) * (1.0f - fx) + node(i1, j0 + 1) * fx;
    return vmax(top * (1.0f - fy) + bottom * fy, Vec3(0, 0, 0));
  }
  // The nine real SH basis functions at a unit direction in the map's frame
  // (Ramamoorthi and Hanrahan 2001, with y up), in the order of sh[].
  static void sh9Basis(Vec3 d, float b[9]) {
    b[0] = 0.282094792f;
    b[1] = 0.488602512f * d.y;
    b[2] = 0.488602512f * d.z;
    b[3] = 0.488602512f * d.x;
    b[4] = 1.092548431f * d.x * d.y;
    b[5] = 1.092548431f * d.y * d.z;
    b[6] = 0.315391565f * (3.0f * d.z * d.z - 1.0f);
    b[7] = 1.092548431f * d.x * d.z;
    b[8] = 0.546274215f * (d.x * d.x - d.y * d.y);
  }
  // E0/pi from the coefficients of L (docs/math.md §14.5): the clamped
  // cosine's SH coefficients A_l = pi, 2pi/3, pi/4 (bands 0, 1, 2) scale
  // each band; over pi, the factors are 1, 2/3 and 1/4.
  Vec3 evalSh9(Vec3 d) const {
    float b[9];
    sh9Basis(d, b);
    const float a[9] = {1.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f, 0.25f, 0.25f, 0.25f, 0.25f, 0.25f};
    float e[3] = {0, 0, 0};
    for (int k = 0; k < 9; ++k)
      for (int c = 0; c < 3; ++c) e[c] += a[k] * sh[3 * k + c] * b[k];
    return vmax(Vec3(e[0], e[1], e[2]), Vec3(0, 0, 0));
  }

 private:
  // The k with cdf[k] <= x < cdf[k + 1] among n steps (cdf[n] == 1 > x).
  static uint32_t pick(const float* cdf, uint32_t n, float x) {
    const float* k = std::upper_bound(cdf, cdf + n + 1, x);
    return uint32_t(std::clamp<ptrdiff_t>(k - cdf - 1, 0, ptrdiff_t(n) - 1));
  }
  // pick(cdf, n, x) from the guide's start (cdf non-decreasing, 0 ... 1):
  // down while cdf[i] > x, then up while cdf[i + 1] <= x - the largest i
  // < n with cdf[i] <= x, as upper_bound finds it. The guide makes the walk
  // n / size + 1 steps on average over x, one or two cache lines of the CDF
  // instead of the binary search's log2(n) scattered ones (docs/math.md
  // §14.3, "Cost").
  static uint32_t guidedPick(const float* cdf, uint32_t n, const uint32_t* guide, uint32_t size, float x) {
    return walk(cdf, n, guide[guideSlot(size, x)], x);
  }
  static uint32_t guideSlot(uint32_t size, float x) {
    return std::min(size - 1, uint32_t(std::max(0.0f, x * float(size))));
  }
  static uint32_t walk(const float* cdf, uint32_t n, uint32_t i, float x) {
    while (i > 0 && cdf[i] > x) --i;
    while (i + 1 < n && cdf[i + 1] <= x) ++i;
    return i;
  }
  template <class T>
  static void prefetchLine(const T* p) {
#if defined(__GNUC__)
    __builtin_prefetch(p);
#else
    (void)p;
#endif
  }

 public:
  // The guide of a CDF of n steps with `size` entries (built with the
  // tables; public for the tests).
  static void buildGuide(const float* cdf, uint32_t n, uint32_t size, uint32_t* guide) {
    for (uint32_t k = 0; k < size; ++k) guide[k] = pick(cdf, n, float(k) / float(size));
  }
  static uint32_t searchStep(const float* cdf, uint32_t n, float x) { return pick(cdf, n, x); }
  static uint32_t guidedStep(const float* cdf, uint32_t n, const uint32_t* guide, uint32_t size, float x) {
    return guidedPick(cdf, n, guide, size, x);
  }

 private:
  static float remap(const float* cdf, uint32_t k, float x) {
    const float w = cdf[k + 1] - cdf[k];
    return w > 0.0f ? std::clamp((x - cdf[k]) / w, 0.0f, 0.99999994f) : 0.5f;
  }
};

}  // namespace obscura
