// Error of a pass against a reference pass: the numbers `obscura compare`
// reports (docs/compare.md "Compare"). Pure functions on plain images, so tests can
// check them on tiny synthetic images with known answers.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/image/film.h"

namespace obscura {

// The pass of a render: R, G, B premultiplied by coverage A (the EXR
// convention), one plane each, row-major.
struct PassImage {
  int width = 0, height = 0;
  std::vector<float> r, g, b, a;
  size_t pixels() const { return size_t(width) * size_t(height); }
  // Un-premultiplied W of channel c (0 = R, 1 = G, 2 = B) at pixel i; 0 where A = 0.
  float W(int c, size_t i) const;
};

PassImage passFromFilm(const Film& film);
// The film's shaded.R/G/B (the radiance under the render's light) with A:
// what `compare` measures under an environment map.
PassImage shadedFromFilm(const Film& film);
// Multiplies R, G, B (not A) by s.
void scaleRgb(PassImage& p, double s);
// The mean of the un-premultiplied R, G, B over pixels with A = 1.
double meanCoveredRgb(const PassImage& p);
// Reads R, G, B, A of an EXR written by obscura (its data window; through
// OpenEXR), or of another format through OpenImageIO's module
// (core/image/oiio_module.h); throws obscura::Error naming the file.
PassImage readPass(const std::string& path);
// An EXR's `prefix`R, `prefix`G, `prefix`B and A (e.g. "shaded."): EXR only.
PassImage readPass(const std::string& path, const std::string& prefix);

// Which pixels count: those the reference covers fully (A = 1: every
// reference sample hit geometry) and the test covers at all. Edge pixels,
// whose coverage itself is noisy, are left out.
std::vector<size_t> comparedPixels(const PassImage& test, const PassImage& ref);

// Errors e = W_test - W_ref over the compared pixels and all three channels.
struct ErrorMetrics {
  double rmse = 0;    // sqrt(mean e^2)
  double relMse = 0;  // mean e^2 / (W_ref^2 + kRelMseEpsilon)
  double mae = 0;     // mean |e|
  double p99 = 0;     // 99th percentile of |e| (nearest rank)
  size_t values = 0;  // pixels x 3
};
constexpr double kRelMseEpsilon = 1e-2;

// Throws obscura::Error if the sizes differ or no pixel is compared.
ErrorMetrics errorMetrics(const PassImage& test, const PassImage& ref);

// FLIP of a pass against the reference (core/image/flip.h; docs/compare.md
// "FLIP"), each the mean over comparedPixels of the per-pixel map:
//  - ldr: LDR-FLIP of the passes as their preview PNGs show them: R, G, B as
//    stored (premultiplied, so over black), clamped to [0, 1]; the PNG's sRGB
//    encoding is what LDR-FLIP decodes first, so the clamped linear values are
//    its input (not quantised to 8 bits);
//  - hdr: HDR-FLIP of the linear passes (premultiplied, unclamped), its
//    exposure range from the reference's luminance over the compared pixels.
// With `maps`, the per-pixel maps are kept (0 outside the compared pixels).
struct FlipError {
  double ldr = 0, hdr = 0;
  std::vector<float> ldrMap, hdrMap;
};
FlipError flipError(const PassImage& test, const PassImage& ref, double ppd, bool maps = false);

// Bias and variance from K >= 2 renders that differ only in seed, per pixel
// value x_k (MATH: MSE of one render = bias^2 + variance):
//   variance = mean over values of  Sum_k (x_k - m)^2 / (K - 1),  m = mean_k x_k
//   bias2    = mean over values of (m - ref)^2  -  variance / K  -  refNoise^2
// (m's own variance and the reference's noise, an RMSE, removed, so bias2 is
// unbiased; it can come out slightly negative when the true bias is ~0, and
// is reported as computed).
struct BiasVariance {
  double bias2 = 0, variance = 0;
};
BiasVariance biasVariance(const std::vector<PassImage>& renders, const PassImage& ref, double refNoise = 0);

// The reference's own noise from two independent halves a, b (each of half
// the samples) whose mean is the reference: per value Var(mean) ~ (a - b)^2 / 4,
// averaged; returns its square root (an RMSE).
double referenceNoise(const PassImage& a, const PassImage& b);

// The per-value mean of two passes of the same size (a reference from two
// halves).
PassImage averagePasses(const PassImage& a, const PassImage& b);

}  // namespace obscura
