// FLIP, the perceptual difference of a test image from a reference, as the
// two papers define it: LDR-FLIP (Andersson, Nilsson, Akenine-Möller,
// Oskarsson, Åström, Fairchild, "FLIP: A Difference Evaluator for Alternating
// Images", Proc. ACM CGIT 3(2), 2020; HPG 2020) and HDR-FLIP (Andersson,
// Nilsson, Shirley, Akenine-Möller, "Visualizing Errors in Rendered High
// Dynamic Range Images", Eurographics 2021 short paper). Implemented from the
// papers' equations; the derivation is at the head of flip.cpp and in
// docs/compare.md "FLIP". Pure functions on plain images, so tests can check
// them on tiny synthetic images with closed-form answers.
#pragma once

#include <cstddef>
#include <vector>

namespace obscura {

// The papers' observer: a 0.7 m wide 3840-pixel monitor seen from 0.7 m,
// ppd = d * (pixels / width) * pi / 180 = 67.02 pixels per degree.
constexpr double kFlipDefaultPpd = 0.7 * (3840.0 / 0.7) * 3.14159265358979323846 / 180.0;

// Linear RGB planes, row-major (the image as it reaches the eye: for LDR-FLIP
// in [0, 1], values outside are clamped).
struct FlipImage {
  int width = 0, height = 0;
  std::vector<float> r, g, b;
  size_t pixels() const { return size_t(width) * size_t(height); }
};

// LDR-FLIP per pixel, each in [0, 1] (the LDR paper's colour pipeline,
// feature pipeline and their combination; flip.cpp's head). Inputs are linear RGB: the paper's sRGB input after its
// transfer function is decoded, clamped to [0, 1]. Throws obscura::Error when
// sizes differ or ppd is not in [1, 1000].
std::vector<float> ldrFlip(const FlipImage& reference, const FlipImage& test, double ppd = kFlipDefaultPpd);

// The exposure range of HDR-FLIP (HDR paper Sec. 3): exposures
// start + i (stop - start) / (count - 1), i = 0..count-1.
struct FlipExposures {
  double start = 0, stop = 0;
  int count = 1;
};
// From the reference's luminance Y = 0.2126 R + 0.7152 G + 0.0722 B over
// `pixels` (all pixels when null): start = log2(t^-1(0.85) / max Y), stop =
// log2(t^-1(0.85) / median Y), count = max(2, ceil(stop - start)). A black
// reference gives the single exposure 0; a median of 0 is replaced by the
// smallest positive Y (the paper's stop would be infinite).
FlipExposures flipExposures(const FlipImage& reference, const std::vector<size_t>* pixels = nullptr);

// HDR-FLIP per pixel: the maximum over the exposures of LDR-FLIP on the two
// images scaled by 2^c and tone mapped by flipAces, each in [0, 1].
std::vector<float> hdrFlip(const FlipImage& reference, const FlipImage& test, const FlipExposures& exposures,
                           double ppd = kFlipDefaultPpd);

// The HDR paper's tone mapper: Narkowicz's fit of the ACES curve with its 0.6
// pre-exposure folded in, t(x) = (k0 x^2 + k1 x) / (k3 x^2 + k4 x + k5),
// clamped to [0, 1]; and its inverse on (0, 1) (the positive root of the
// quadratic).
double flipAces(double x);
double flipAcesInverse(double t);

// Building blocks, exposed for the closed-form tests.
// The feature pipeline's detectors (LDR paper, feature pipeline) on a plane of luminance
// normalised to [0, 1]: per pixel the length of the (x, y) response of the
// edge (first Gaussian derivative) and point (second derivative) filters.
struct FlipFeatures {
  std::vector<float> edge, point;
};
FlipFeatures flipFeatures(const std::vector<float>& luminance, int width, int height, double ppd);
// The features' standard deviation in pixels: 0.5 * 0.082 degrees * ppd.
double flipFeatureSigma(double ppd);
// The colour difference of two linear RGB colours in [0, 1] with no spatial
// filtering (the LDR paper's colour pipeline on constant images):
// HyAB of the Hunt-adjusted L*a*b*, to the power 0.7, remapped to [0, 1].
double flipColourDifference(const float reference[3], const float test[3]);

}  // namespace obscura
