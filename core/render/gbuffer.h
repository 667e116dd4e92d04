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

// The view transform of camera c for a w x h image.
ViewTransform viewTransform(const Camera& c, int w, int h);

// Builds g.moments from g.depth (parallel over rows; the caller's TBB arena).
void buildDepthMoments(GBufferLayer& g);

// An upper bound of the bytes renderScreenSpace keeps for a w x h image
// besides the film: one layer with every optional array (albedo, moments),
// the per-pixel sums and the estimates (kept whole for the filter).
uint64_t screenSpaceWorkingBytes(int w, int h);

// Renders layer s of an image into g (parallel over rows; the caller's TBB
// arena). Counts camera rays into `cameraRays`.
struct RenderSettings;
void renderGBufferLayer(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                        uint32_t sampleIndex, bool albedo, GBufferLayer& g, uint64_t& cameraRays);

// The depth-aware 4x4 box filter of interleaved sampling (AT §4.2): each
// covered pixel's (num, den) becomes the mean over the covered pixels of the
// 4x4 window x-1..x+2, y-1..y+2 (clipped to the image) whose depth differs
// from its own by at most `tolerance` x its depth. A 4x4 window holds every
// one of the 16 interleaved sample sets once, so inside a surface the
// filtered value uses 16x the samples; across a depth edge nothing is mixed.
// Rows [y0, y1) of `out` from the whole of `in`.
void depthAwareBoxFilter(const GBufferLayer& g, const SampleEstimate* in, float tolerance, int y0, int y1,
                         SampleEstimate* out);

}  // namespace obscura
