// The render loop: image tiles in parallel (TBB); inside a tile, camera
// samples in chunks traced as one ray stream, handed to the integrator as a batch
// of surface hits, and accumulated per pixel in sample order.
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <string>

#include "core/scene/camera.h"
#include "core/scene/environment.h"
#include "core/render/checkpoint.h"
#include "core/render/cryptomatte.h"
#include "core/image/film.h"
#include <obscura/integrator.h>
#include "core/scene/scene.h"
#include <obscura/warp.h>

namespace obscura {

struct RenderSettings {
  int width = 960, height = 540;
  int spp = 16;            // camera samples per pixel
  uint32_t seed = 0;
  int threads = 0;         // 0 = all hardware threads
  int tileSize = 16;       // pixels per tile side; does not change the image
  PixelFilter filter = PixelFilter::Box;
  Vec3 sky{1, 1, 1};       // La of docs/math.md §1, when environment is null
  // The light (docs/math.md §14): an environment map, or null for the
  // uniform sky `sky` (render() makes it the constant environment).
  std::shared_ptr<const Environment> environment;
  bool aovs = true;        // write albedo/N/Z/shaded channels
  // With aovs: the albedo.* and shaded.* channels too. false (--no-albedo)
  // drops them and, unless a pass reads albedo, the texture lookup at every
  // camera hit that they cost (docs/performance.md "Where the render loop's time goes").
  bool albedoAov = true;
  bool progress = false;   // progress bar on stderr
  CryptomatteSettings cryptomatte;  // ID matte layers (core/render/cryptomatte.h); off by default
  // --region: the window of the frame rendered, [x0, x1) x [y0, y1) in
  // pixels; empty (the default) = the whole frame. Its pixels equal the same
  // pixels of the full render bit for bit (samples are keyed by the pixel's
  // image coordinates). Ray-traced passes only (docs/production.md "Regions and merging").
  PixelRect region;
  // Motion blur (--shutter): each camera sample gets a time in [0, 1)
  // across the shutter from its own sample dimension, which every ray of the
  // sample carries; moving instances (Scene::hasMotion) and a moving camera
  // (Camera::motion) are placed at it. Off: every ray at time 0. A still
  // scene renders bit-identically either way. Ray-traced passes only.
  bool motionBlur = false;
  // Adaptive sampling (core/render/adaptive.h; docs/sampling.md "Adaptive sampling"): with
  // a target error or a time limit, pixels are sampled in rounds and each
  // stops once the standard error of its composited pass (its own and
  // pooled over its 3 x 3 neighbours) is at most targetError, or at spp
  // samples. Absolute, in units of W.
  float targetError = 0;  // 0: off
  int minSpp = 0;         // the first round's samples; 0: min(16, spp)
  // With a target error: the survey's samples (core/render/adaptive.h), after which
  // a pixel with no surface within two pixels stops; 0: no survey, every
  // pixel takes the first round's.
  int backgroundSpp = 4;
  double timeLimit = 0;   // seconds; 0: none. No round starts that is predicted to end past it
  // --denoise (core/image/denoise.h; docs/sampling.md "Denoising"): the primary pass's R,G,B
  // (and its layer, shaded.*) replaced by the edge-aware filter's output,
  // guided by N, Z, W_error, the pixels' objects and (for passes that read
  // it) albedo; the raw pass kept as noisy.R/G/B. Needs the AOVs.
  bool denoise = false;
  RayRecorder* recorder = nullptr;  // benchmarks only: sees every traced batch (core/scene/tracer.h)
  // --checkpoint: finished tiles saved to a file between tiles, and saved
  // tiles skipped (core/render/checkpoint.h; docs/production.md "Checkpoints"). Ray-traced
  // passes only. When set, stats.rays count the rays of every finished
  // tile, saved ones included, and stats.seconds adds the earlier runs'.
  Checkpoint* checkpoint = nullptr;
};

// The window a render fills: s.region, or the whole frame when it is empty.
inline bool hasRegion(const RenderSettings& s) { return s.region.x0 || s.region.y0 || s.region.x1 || s.region.y1; }
inline PixelRect renderWindow(const RenderSettings& s) { return hasRegion(s) ? s.region : PixelRect{0, 0, s.width, s.height}; }
// Throws obscura::Error naming --region unless `r` is a non-empty window
// inside a width x height frame.
void checkRegion(const PixelRect& r, int width, int height);
// Throws naming --shutter if s has motion blur and a pass is screen-space
// (a G-buffer holds one instant). (--region works with screen-space passes:
// their guard band, core/render/gbuffer.h layerGeometry.)
void checkRegionPasses(const RenderSettings& s, bool anyScreenSpace);
// Throws naming --no-albedo if s denoises a primary pass whose W depends on
// the pixel's albedo (multibounce) without the albedo AOV: the filter is
// guided by the albedo planes.
void checkAlbedoPasses(const RenderSettings& s, const IntegratorNeeds& primary);
// Throws naming --checkpoint if s has one and a pass is screen-space: its
// G-buffer loop has no tiles that finish one by one.
void checkCheckpointPasses(const RenderSettings& s, bool anyScreenSpace);

struct RenderStats {
  double seconds = 0;  // wall time of the render loop
  RayCounters rays;
  // Screen-space integrators only (core/render/gbuffer.h): the split of `seconds`
  // into rendering the G-buffer layers, the integrator's pass over them, and
  // the interleaving filter.
  double gbufferSeconds = 0, screenSpaceSeconds = 0, filterSeconds = 0;
  // Camera samples taken per pixel, on average over the window (spp unless
  // adaptive), and the rounds they were taken in.
  double meanSpp = 0;
  int rounds = 1;  // the survey (core/render/adaptive.h) counts as one
  int backgroundSpp = 0;  // the survey's samples a pixel; 0: no survey ran
  double denoiseSeconds = 0;  // --denoise: the filter's wall time (not in `seconds`)
};

// One pass of a render: an integrator, what it needs, and the EXR layer its
// W is written to ("" = none: R,G,B only).
struct RenderPass {
  const Integrator* integrator = nullptr;
  IntegratorNeeds needs;
  std::string layer;
};

// Renders and returns the film. Throws obscura::Error on bad settings.
// If `cancel` becomes true the render stops early and returns an
// incomplete film with `stats.seconds` < 0.
Film render(const Scene& scene, const Camera& camera, const Integrator& integrator,
            const IntegratorNeeds& needs, const RenderSettings& settings, RenderStats& stats,
            const std::atomic<bool>* cancel = nullptr);

// Several passes from one render (docs/production.md "Several passes in one render").
// passes[0] is the primary pass: R,G,B and shaded.* are its W. Every pass
// with a layer name also writes `<layer>.R/G/B` (premultiplied like R,G,B).
// The ray-traced passes share one walk over the camera samples - camera
// rays, surface hits, albedo and AOVs - each integrator estimating the same
// batch of hits in turn; the screen-space passes share one G-buffer layer
// per camera sample (renderScreenSpace).
// Each pass's values are bit-identical to the same pass rendered alone: the
// integrators draw their samples from the sampler by pixel, sample and
// dimension, never from a shared stream, and each pass's sums resolve with
// the arithmetic of a solo render.
Film render(const Scene& scene, const Camera& camera, std::span<const RenderPass> passes,
            const RenderSettings& settings, RenderStats& stats, const std::atomic<bool>* cancel = nullptr);

// The lighting.R/G/B planes of a film lit by a non-constant environment
// with albedo (added once; the render loops fill them).
void addLightingPlanes(Film& film, const RenderSettings& s);
// s with its environment set: the constant sky when it has none.
RenderSettings withEnvironment(const RenderSettings& s);

// The layer loop render() runs for its screen-space passes
// (core/render/gbuffer.h): one G-buffer layer per camera sample, shared by
// every job (each reads it within its own guard band, so each film equals
// the job's solo render bit for bit). One film per job, in order; the
// first job's samples per pixel are stats'.
class ScreenSpaceIntegrator;
// Adds part's times and rays to total; the first part's samples per pixel
// are total's.
void addStats(RenderStats& total, const RenderStats& part);
struct ScreenSpaceJob {
  const ScreenSpaceIntegrator* integrator;
  IntegratorNeeds needs;
  RenderSettings settings;
};
std::vector<Film> renderScreenSpace(const Scene& scene, const Camera& camera, std::span<const ScreenSpaceJob> jobs,
                                    RenderStats& stats, const std::atomic<bool>* cancel = nullptr);

}  // namespace obscura
