// The core's side of the screen-space seam (obscura/screen_space.h: the
// layers and the integrators that read them; docs/math.md §8, §9).
// The layers are rendered through the same camera ray, pixel filter and
// samples as the ray-traced loop (cameraSampleFilm below is the one piece of
// code both use).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/scene/camera.h"
#include "core/image/film.h"
#include "core/util/large_vector.h"
#include <obscura/integrator.h>
#include <obscura/screen_space.h>
#include <obscura/sampler.h>
#include <obscura/warp.h>

namespace obscura {

// Film position (pixel coordinates, y down) of camera sample `si` of pixel
// (px, py): the pixel filter's importance-sampled offset from dimension
// kDimPixelFilter of the pixel's stream (`filterSeeds` = Sampler::seeds2D(key,
// kDimPixelFilter)).
// cameraFilmPosition maps the drawn sample f to the film (the render loop
// draws its lanes' samples at once, Sampler::get2DLanes).
inline void cameraFilmPosition(PixelFilter filter, Sample2 f, int px, int py, float& fx, float& fy) {
  if (filter == PixelFilter::Box) {
    fx = float(px) + f.u;
    fy = float(py) + f.v;
  } else {
    const GaussianFilterSampler& gauss = GaussianFilterSampler::instance();
    fx = float(px) + 0.5f + gauss.sample(f.u);
    fy = float(py) + 0.5f + gauss.sample(f.v);
  }
}
inline void cameraSampleFilm(PixelFilter filter, const Sampler::Seeds2& filterSeeds, uint32_t si, int px, int py,
                             float& fx, float& fy) {
  cameraFilmPosition(filter, Sampler::get2D(filterSeeds, si), px, py, fx, fy);
}

// The view transform of camera c for a w x h image, onto a layer whose
// pixel (0, 0) is image pixel (originX, originY).
ViewTransform viewTransform(const Camera& c, int w, int h, int originX = 0, int originY = 0);

// The guard band's default cap for a w x h image: 1/8 of the larger side,
// at least 16 pixels (docs/screen_space.md "Guard band").
int guardBandCap(int w, int h);

// Where a screen-space pass's layers lie (GBufferLayer's band, origin,
// size, shaded and image rectangles) for a render of `window` (the frame or
// the region) of a w x h image: the band from the integrator's guardBand()
// (the default: its reach projected from the point of the scene's bounds
// nearest the camera, capped); around the window the band, plus for depth
// moments half the coarsest block (vo's area samples read a block whose
// centre is in the band), plus 2 pixels for the interleave filter's
// neighbours; the origin rounded down to a multiple of 4 and of the
// coarsest block. Depends on the whole image, never on the window's place,
// so a region's layer holds what the full frame's holds around it.
struct LayerGeometry {
  int band = 0, momentLevels = 0;
  // The automatic band capped: the pass reads anywhere within the band of
  // the image, and the layer is the whole image's and the band's whatever
  // the window (GBufferLayer::readsImage).
  bool readsImage = false;
  int originX = 0, originY = 0, width = 0, height = 0;
  PixelRect shaded, image;
};
LayerGeometry layerGeometry(const ScreenSpaceIntegrator& integrator, const Scene& scene, const Camera& camera,
                            int w, int h, const PixelRect& window);

// Builds g.moments from g.depth: `levels` levels (level 0 = the pixels'
// depths at their centres, from the stored planes; `prefilter`: blurred by
// the Gaussian kMomentBlurWeights, VO §4.2), each block of level l aligned
// to image pixels 2^l apart (parallel over rows; the caller's TBB arena).
void buildDepthMoments(GBufferLayer& g, int levels, bool prefilter);

// An upper bound of the bytes renderScreenSpace keeps besides the output
// film for a render of `window` with a guard band of at most `band` pixels
// and `passes` screen-space passes: one shared layer with every optional
// array (albedo, moments) and, per pass, the per-pixel sums, the estimates
// (kept whole for the filter) and the pass's own film.
uint64_t screenSpaceWorkingBytes(const PixelRect& window, int band, int passes = 1);

// Renders layer s into g, whose geometry (band, origin, size, rectangles)
// is set (parallel over rows; the caller's TBB arena). Counts camera rays
// into `cameraRays`.
struct RenderSettings;
void renderGBufferLayer(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                        uint32_t sampleIndex, bool albedo, GBufferLayer& g, uint64_t& cameraRays);

// The depth-aware 4x4 box filter of interleaved sampling (AT §4.2): each
// covered pixel's (num, den) becomes the mean over the covered pixels of the
// 4x4 window x-1..x+2, y-1..y+2 (clipped to the image) whose depth differs
// from its own by at most `tolerance` x its depth. A 4x4 window holds every
// one of the 16 interleaved sample sets once, so inside a surface the
// filtered value uses 16x the samples; across a depth edge nothing is mixed.
// Layer rows [y0, y1) of g.shaded into `out` (g.shaded's width per row),
// from `in`, the whole layer's estimates (those of g.shaded and its
// neighbours in the image).
void depthAwareBoxFilter(const GBufferLayer& g, const SampleEstimate* in, float tolerance, int y0, int y1,
                         SampleEstimate* out);

// The depth-aware bilateral blur after VO (VO §2, §5;
// ScreenSpaceIntegrator::Blur): each covered pixel's (num, den, bent)
// becomes the weighted mean over the covered pixels j of the (2r+1)^2
// window about it (clipped to the image) with weight exp(-(dx^2 + dy^2) /
// (2 sigma^2)), sigma = r / 2, times the range test - j on the pixel's own
// surface: n.n_j >= kBlurNormalCos and |n.(P_j - P)| <= tolerance x depth
// (the distance from the pixel's tangent plane, so an oblique plane passes
// whole where a depth difference would not). Weights are made once
// (BlurKernel). Layer rows [y0, y1) of g.shaded into `out` (g.shaded's
// width per row), from `in`, the whole layer's estimates (those of
// g.shaded and of its neighbours within r in the image).
constexpr float kBlurNormalCos = 0.9f;
struct BlurKernel {
  int radius = 0;
  float tolerance = 0.02f;
  std::vector<float> weights;  // (2r+1)^2, row-major, the Gaussian factor
  BlurKernel(int radius, float tolerance);
};
void bilateralBlur(const GBufferLayer& g, const SampleEstimate* in, const BlurKernel& k, int y0, int y1,
                   SampleEstimate* out);

}  // namespace obscura
