// The screen-space seam: G-buffer layers and the integrators that read them
// instead of tracing rays (volumetric obscurance, z-buffer ambient transfer;
// docs/math.md §8, §9).
//
// For each camera sample index s = 0..spp-1 the core renders layer s - every
// pixel's camera sample s, through the same camera ray, pixel filter and
// samples as the ray-traced loop - hands it to the integrator, which returns
// W per pixel as a ratio (num, den) exactly like Integrator::estimate, and
// accumulates the layer's estimates per pixel. A pixel's W is Sum num / Sum
// den over the layers whose sample hit, so --spp, coverage, the AOVs,
// resolvePixel and the EXR header mean what they mean for every integrator.
// Only one layer exists at a time. The core's side (rendering a layer, the
// depth moments, the interleave filter): core/render/gbuffer.h.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <obscura/integrator.h>
#include <obscura/large_vector.h>
#include <obscura/math.h>
#include <obscura/pixel_rect.h>

namespace obscura {

// The camera's view space: camera at the origin looking down -z, +y up, +x
// right (glTF); depth = -z. Maps world points there and view points onto the
// film, the inverse of RasterCamera's rays.
struct ViewTransform {
  Affine toWorld;          // camera-to-world (rigid)
  Vec3 origin;             // camera position (world)
  Vec3 row0, row1, row2;   // rows of the world-to-view rotation
  float tanHalfX, tanHalfY;
  float width, height;           // the image's size (the whole frame, pixels)
  float filmScaleX, filmScaleY;  // film pixels per unit of x/-z and y/-z
  // Where the optical axis meets the layer: the image's centre in layer
  // pixels (GBufferLayer::originX, originY shift the layer off the image).
  float centreX, centreY;
  // (Made by the core from the camera: viewTransform, core/render/gbuffer.h.)
  Vec3 pointToView(Vec3 p) const {
    const Vec3 d = p - origin;
    return {dot(row0, d), dot(row1, d), dot(row2, d)};
  }
  Vec3 vectorToView(Vec3 v) const { return {dot(row0, v), dot(row1, v), dot(row2, v)}; }
  Vec3 pointToWorld(Vec3 v) const { return toWorld.point(v); }
  Vec3 vectorToWorld(Vec3 v) const { return toWorld.vector(v); }
  // Layer position (film pixels) of a view-space point in front of the
  // camera (z < 0).
  void project(Vec3 v, float& fx, float& fy) const {
    const float inv = 1.0f / -v.z;
    fx = centreX + v.x * inv * filmScaleX;
    fy = centreY - v.y * inv * filmScaleY;
  }
};

// One level of a layer's mip-mapped depth moments (VO §4.2): per texel, over
// the covered pixels of the 2^level x 2^level block it spans, the mean view
// depth, the depth variance, and the covered fraction of the block's pixels
// (background pixels are no occluder, so they are kept apart as coverage
// instead of entering the moments). Variances are merged with the parallel
// formula (sum of the parts' variances and of their means' spread), never as
// E[z^2] - E[z]^2, which cancels in float.
//
// Level 0 holds each pixel's depth at the pixel's centre (its surface's
// plane there, not the jittered camera sample's depth), so that a texel's
// depths sit at known film positions. With the pre-blur (VO §4.2;
// ScreenSpaceIntegrator::prefilterDepthMoments) level 0 is first blurred
// with the separable Gaussian kMomentBlurWeights, merged the same way.
struct DepthMoments {
  int width = 0, height = 0;
  LargeVector<float> mean, variance, coverage;
};

// The pre-blur's taps at offsets -2..2 pixels: exp(-i^2 / 2), a Gaussian of
// sigma 1 pixel truncated at 2 sigma (unnormalised: the merge divides by
// the weights of the taps it reads).
inline constexpr int kMomentBlurRadius = 2;
inline constexpr float kMomentBlurWeights[2 * kMomentBlurRadius + 1] = {0.135335283f, 0.606530660f, 1.0f,
                                                                         0.606530660f, 0.135335283f};
// The pre-blur's variance per axis (pixels^2): Sum w_i i^2 / Sum w_i = 0.924.
constexpr float momentBlurVariance() {
  float w = 0.0f, wii = 0.0f;
  for (int i = -kMomentBlurRadius; i <= kMomentBlurRadius; ++i) {
    w += kMomentBlurWeights[i + kMomentBlurRadius];
    wii += kMomentBlurWeights[i + kMomentBlurRadius] * float(i * i);
  }
  return wii / w;
}

// One G-buffer layer: camera sample `sampleIndex` of every pixel, in view
// space, structure of arrays (the screen-space loops read `depth` at
// scattered pixels; keeping it alone keeps those reads in cache).
//
// The guard band (docs/screen_space.md "Guard band"): the layer holds the
// pixels the pass shades (`shaded`: the frame, or the render's --region)
// and a margin around them - beyond the image's edges too, where the
// camera's film extends - so that sample points that project just off the
// frame read real depth. A pixel's samples read the layer only within
// `band` pixels of it (screen_space::ReadWindow), so a region's pixels read
// exactly what the full frame's read and regions merge bit for bit.
// Layer pixel (x, y) is image pixel (x + originX, y + originY); originX and
// originY are multiples of 4 (the interleaving pattern's period: x & 3 in
// layer and image coordinates agree) and, with depth moments, of the
// coarsest moment level's block.
struct GBufferLayer {
  int width = 0, height = 0;  // the layer's size: shaded pixels and margins
  int originX = 0, originY = 0;
  int band = 0;               // reads within this many pixels of the shaded pixel (Chebyshev)
  // Reads anywhere within `band` pixels of the image instead (the
  // automatic band when R projects wider than its cap: a pixel's reach
  // is then not bounded by the band, and a region's layer is the whole
  // image's; docs/screen_space.md "Guard band").
  bool readsImage = false;
  PixelRect shaded;           // the pixels estimated, layer coordinates
  PixelRect image;            // the whole image, layer coordinates (may reach beyond the layer)
  uint32_t sampleIndex = 0;
  ViewTransform view;
  LargeVector<float> depth;        // view depth -z of the visible point; +inf where nothing was hit
  LargeVector<Vec3> position;      // view-space position of the visible point
  LargeVector<Vec3> normal;        // view-space unit shading normal, facing the camera
  // The visible triangle's plane, view space: (n, n.p) with n its unit
  // geometric normal and p the visible point; all zero where nothing is an
  // occluder (background, and objects whose `occluder` role is off). A depth-buffer read at film
  // position (fx, fy) within the pixel intersects its camera ray with this
  // plane (zBufferDepth) instead of returning the depth of the pixel's own,
  // jittered, sample: exact for planar surfaces, first order for curved
  // ones; the stored depth stays the fallback for rays along the plane.
  LargeVector<std::array<float, 4>> plane;
  // (depth, slack) per pixel, packed for the z-buffer read - the depth an
  // occluder query reads: +inf (slack 0) where nothing occludes, over the
  // background and over objects that occlude nothing. Slack bounds how
  // far the plane's depth strays from `depth` over the pixel, so a point
  // farther than that from `depth` is decided without reading `plane`
  // (half the memory traffic of the screen-space loops). +inf slack where
  // the plane is seen edge-on within the pixel.
  LargeVector<std::array<float, 2>> depthSlack;
  LargeVector<Vec3> albedo;        // diffuse albedo (only with IntegratorNeeds::albedo; else empty)
  LargeVector<uint32_t> object;    // geomID ^ (instID << 20): which object (background: ~0u)
  LargeVector<uint32_t> pixelKey;  // the pixel's Sampler key (as SurfaceHit::pixelKey)
  // A Sampler key for randomness shared by the whole image (the same in
  // every layer; index the draws by sampleIndex): hashed from the seed, so
  // --seed changes it like every pixel's stream.
  uint32_t imageKey = 0;
  // Level 0 = the pixels; built only for integrators that ask
  // (ScreenSpaceIntegrator::needsDepthMoments).
  std::vector<DepthMoments> moments;
  bool covered(size_t i) const { return depth[i] < kInfinity; }
  bool inImage(int x, int y) const { return x >= image.x0 && y >= image.y0 && x < image.x1 && y < image.y1; }
  size_t index(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
};

// An integrator that reads G-buffer layers. The core never calls estimate()
// on it; render() sees screenSpace() != nullptr and runs the layer loop.
class ScreenSpaceIntegrator : public Integrator {
 public:
  void estimate(std::span<const SurfaceHit>, IntegratorContext&, SampleEstimate*) const final {}
  const ScreenSpaceIntegrator* screenSpace() const final { return this; }
  // Writes out[tile.offset(x, y)] for the pixels of `tile` in layer g: the
  // estimate at each covered pixel (the core has set num = 0, den = 1;
  // uncovered pixels are ignored). Called from many threads at once on
  // disjoint tiles of at most kScreenSpaceTile^2 pixels: square tiles keep
  // the scattered depth reads of a tile's pixels, all within the sample
  // radius of the tile, in the core's cache (bands of full-width rows did
  // not: the pass took 1.6x the CPU time on the generated scene of
  // bench/bench_screen_space.cpp; 64 beat 32 and 16 there). Samples from Sampler keyed
  // by g.pixelKey[i] and an index derived from g.sampleIndex, dimensions
  // from kFirstIntegratorDim up; rays (the traced twins) through ctx.
  virtual void estimateTile(const GBufferLayer& g, const PixelRect& tile, IntegratorContext& ctx,
                            SampleEstimate* out) const = 0;
  // > 0: after estimating a layer the core applies the depth-aware 4x4 box
  // filter of interleaved sampling (AT §4.2) to its estimates, with this
  // relative depth tolerance (depthAwareBoxFilter).
  virtual float interleaveFilterTolerance() const { return 0.0f; }
  // radius > 0: after estimating a layer (and after the interleave filter),
  // the core blurs its estimates with the depth-aware bilateral blur of
  // this radius in pixels (VO §2, §5; bilateralBlur, core/render/gbuffer.h):
  // Gaussian weights in image distance (sigma = radius / 2), neighbours only
  // on the pixel's own surface - normals within ~25 degrees, and within
  // `tolerance` x its depth of its tangent plane. The guard band's layer
  // grows by the radius, so regions stay exact.
  struct Blur {
    int radius = 0;
    float tolerance = 0.02f;
  };
  virtual Blur blur() const { return {}; }
  // true: the core builds each layer's depth moments (GBufferLayer::moments).
  virtual bool needsDepthMoments() const { return false; }
  // true (with needsDepthMoments): level 0 of the moments is pre-blurred
  // with the Gaussian kMomentBlurWeights before the mip chain is built
  // (VO §4.2); the layer's margin grows by kMomentBlurRadius.
  virtual bool prefilterDepthMoments() const { return false; }
  // The guard band's size (GBufferLayer): `pixels` >= 0 as given, or -1 for
  // the core's default from `reach`, the farthest distance from a shaded
  // point (scene units) at which the pass reads the depth buffer - R
  // projected from the scene's nearest point, capped (docs/screen_space.md
  // "Guard band"). reach 0: the pass reads no neighbour; -1 (the default):
  // unknown - no band, and no --region.
  struct GuardBand {
    double reach = -1.0;
    int pixels = -1;
  };
  virtual GuardBand guardBand() const { return {}; }
};

// The side of the core's screen-space tiles (pixels).
constexpr int kScreenSpaceTile = 64;

}  // namespace obscura
