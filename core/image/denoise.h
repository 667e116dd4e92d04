// The edge-aware denoiser of a pass W (docs/sampling.md "Denoising", docs/denoise.md):
// an a-trous wavelet filter (3 x 3 binomial or 5 x 5 B3-spline taps, the
// step doubling each iteration) whose taps are weighted by the AOVs (normal, depth, object,
// albedo) and by W's own differences measured against its per-pixel
// standard error, with that variance carried through the iterations.
//
// It works on W un-premultiplied (colour / alpha): a pixel's coverage is not
// part of the signal, and a silhouette pixel's W is the mean over its hits
// like any other. The output is premultiplied again by the pixel's own alpha.
#pragma once

#include <cstdint>
#include <memory>

namespace obscura {

struct DenoiseInput {
  int width = 0, height = 0;
  // The pass W, premultiplied by coverage (the film's R, G, B planes).
  const float* color[3] = {nullptr, nullptr, nullptr};
  // Coverage (the film's A). Pixels with alpha <= 0 hold no W: they are
  // neither filtered nor read by their neighbours, and are copied through.
  const float* alpha = nullptr;
  // Per-pixel variance of the un-premultiplied W (the square of the W_error
  // plane: the standard error of the pixel's W, the max over channels).
  const float* variance = nullptr;
  // World-space unit normal (N.X/Y/Z; 0 where nothing was hit).
  const float* normal[3] = {nullptr, nullptr, nullptr};
  // Camera-plane depth (Z; kBackgroundDepth where nothing was hit).
  const float* depth = nullptr;
  // Albedo as the film stores it (premultiplied by coverage), or all nullptr
  // when the pass does not depend on albedo (ao, obscurance, ...): then
  // albedo edges are no edges of W and must not stop the filter.
  const float* albedo[3] = {nullptr, nullptr, nullptr};
  // The object of each pixel's first hit (~0u where nothing was hit), or
  // nullptr: then object boundaries are found by normal and depth alone.
  const uint32_t* object = nullptr;
  // Samples per pixel (the film's spp plane), or nullptr (all equal). The
  // filter's taps are weighted by their pixel's count over the largest: for
  // a per-sample variance shared by the neighbours that is inverse-variance
  // weighting, so a pixel that took more samples (adaptive sampling) is not
  // averaged down to its noisier neighbours. Equal counts weigh 1 exactly:
  // a fixed-spp pass is filtered as without them.
  const float* samples = nullptr;
};

// Every weight is exp(-E) with E a sum of the terms below (docs/denoise.md
// gives the equations and the measurements behind each default).
struct DenoiseSettings {
  // A-trous iterations; iteration i reads taps 2^i pixels apart.
  int iterations = 5;
  // Taps per iteration and axis: 3 (the binomial 1 2 1 / 4: footprint
  // 2 (2^iterations - 1) + 1 = 63 pixels across at 5 iterations) or 5 (the
  // B3 spline 1 4 6 4 1 / 16: 125 pixels, 25 taps instead of 9). 3 is the
  // default by measurement (docs/denoise.md "Why this filter"): the same
  // error as 5 on the viking room and the crease at under half the time.
  int kernel = 3;
  // Normal term sigmaNormal * (1 - n_p . n_q): 10 degrees apart weigh 0.14,
  // a 90 degree crease exp(-128).
  float sigmaNormal = 128.0f;
  // Depth term ((d_q - d_p - g_p . (q - p)) / (sigmaDepth * |g_p . (q - p)|_1
  // + depthTolerance * d_p))^2 on inverse depth d = 1 / Z, which is affine
  // in the image on any plane; g_p is its one-sided gradient at p.
  float sigmaDepth = 1.0f;
  float depthTolerance = 0.01f;
  // Luminance term (|W_p - W_q|_max / (sigmaLuminance sqrt(V_p + V_q)))^2,
  // V the variance (propagated through the iterations), with
  // luminanceTolerance^2 added to the denominator: differences within a few
  // standard errors of the difference weigh ~1, a feature of W the AOVs do
  // not show stops the filter. 0 turns the term off (a linear, guide-only
  // filter).
  float sigmaLuminance = 4.0f;
  float luminanceTolerance = 1e-4f;
  // Albedo term |a_p - a_q|_max / sigmaAlbedo (only with albedo planes).
  float sigmaAlbedo = 0.05f;
  // Mirrored taps (docs/denoise.md "Symmetric taps"): the taps at p + o and
  // p - o share the smaller of their two weights, so a linear change of W
  // across p's taps cancels and a pixel next to an edge is not pulled
  // towards the side away from it. false: each tap its own weight.
  bool symmetric = true;
  // Worker threads; 0 = all hardware threads. The result does not depend on
  // it (each pixel is computed by one thread from the previous iteration).
  int threads = 0;
};

// Throws obscura::Error naming the field unless the input is usable (sizes
// positive, every required plane present; settings in range).
void checkDenoise(const DenoiseInput& in, const DenoiseSettings& s);

// Writes the denoised pass, premultiplied by in.alpha, to out[0..2] (width x
// height floats each; may not alias the input). Pixels with alpha <= 0 are
// copied from in.color. Allocates its working planes once per call.
void denoise(const DenoiseInput& in, const DenoiseSettings& s, float* out[3]);

// As above, and writes to gain (width x height, or nullptr: not asked) each
// pixel's variance reduction: the variance the iterations carry to the
// output over the prefiltered input variance (sum w^2 V / (sum w)^2 per
// iteration, pixels taken as independent), at most 1 and at least the
// linear filter's own factor (in a flat region the iterations reuse the same
// pixels, and the product of their factors falls below what any weights
// achieve); 1 where the pixel holds no W or its variance is 0. Adaptive sampling for a denoised pass reads it
// (docs/sampling.md "Adaptive sampling", docs/denoise.md "Adaptive sampling for the
// filter"). With a gain, out may be nullptr: the gain alone is wanted (the
// adaptive rounds' gain pass), and the pass is not written.
// The working planes (guides, two iterations' states: 18-21 floats a pixel)
// of a caller that filters more than once - adaptive rounds filter the first
// round's film for the gain, then the final one: the second call reuses the
// first's pages instead of faulting in new ones, which the kernel clears
// first (a fifth of an adaptive + denoise render's CPU time on the
// development machine's VM, perf: clear_page).
class DenoiseWorkspace {
 public:
  DenoiseWorkspace();
  ~DenoiseWorkspace();
  struct Planes;
  std::unique_ptr<Planes> planes;  // made by the first call
};

void denoise(const DenoiseInput& in, const DenoiseSettings& s, float* out[3], float* gain,
             DenoiseWorkspace* workspace = nullptr);

}  // namespace obscura
