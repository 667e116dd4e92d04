// The film: one float plane per output channel.
//
// Channel layout (docs/exr.md "Channels"): R,G,B = the pass W, premultiplied by
// coverage; A = coverage; albedo.R/G/B (premultiplied); N.X/Y/Z = world
// normal (mean over the pixel's hits, renormalized; 0 where nothing was hit);
// Z = camera distance (mean over hits; +inf where nothing was hit);
// shaded.R/G/B = albedo * W * sky, from the pixel's albedo and W
// (premultiplied). A film without the albedo AOV (--no-albedo) holds
// neither albedo.* nor shaded.*: those planes are empty and not among
// channels().
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "core/util/large_vector.h"
#include <obscura/pixel_rect.h>

namespace obscura {

enum Channel : int {
  kR, kG, kB, kA,
  kAlbedoR, kAlbedoG, kAlbedoB,
  kNX, kNY, kNZ,
  kZ,
  kShadedR, kShadedG, kShadedB,
  kChannelCount
};

// Z where nothing was hit: large and finite, so a compositor's filters
// (negative lobes times +inf give NaN) and range nodes stay finite. 1e10 is
// what Cycles writes for its Depth pass's background, and above the range
// Blender's Normalize node takes into account (|v| <= 10000). docs/exr.md "Depth
// and camera conventions".
constexpr float kBackgroundDepth = 1e10f;

// The planes the render loops add with the AOVs (docs/sampling.md "Adaptive
// sampling"): the standard error of the pass W per pixel (un-premultiplied)
// and the camera samples the pixel took. Each is a one-channel layer named
// LAYER.Y (docs/exr.md "Channels"): Blender's multilayer reader takes only a
// one-letter last token (or R/G/B/A, X/Y/Z, U/V after a pass letter) as a
// channel and drops the rest with "unknown channel token" ("W.error", "spp"
// were dropped), and Y is OpenEXR's name for the one channel of a grey
// image, so OpenImageIO and Nuke show a layer W_error with one channel.
inline constexpr const char* kErrorPlane = "W_error.Y";
inline constexpr const char* kSppPlane = "spp.Y";
// lighting.R/G/B: what shaded.* = albedo x W x lighting multiplies, under a
// non-constant environment (docs/exr.md "Channels").
inline constexpr const char* kLightingPlane = "lighting.R";

// The name of a fixed channel (Channel); extra planes are named by the Film.
const char* channelName(int c);

// A film holds the planes of a window of the image (docs/production.md "Regions and
// merging"): the whole frame, or a region [x0, x1) x [y0, y1) of a
// fullWidth x fullHeight frame. Pixels are addressed by their image
// coordinates (at(c, x, y) with x in [x0, x1)), so the render loops write a
// region's pixels where a full render writes them; plane(c) is the window's
// pixels row-major from (x0, y0).
class Film {
 public:
  Film() = default;
  // aovs: the channels after R,G,B,A; albedo (with aovs): albedo.* and
  // shaded.* among them.
  Film(int width, int height, bool aovs, bool albedo = true);
  // A film of `window` inside a fullWidth x fullHeight frame.
  Film(const PixelRect& window, int fullWidth, int fullHeight, bool aovs, bool albedo = true);
  int width() const { return width_; }
  int height() const { return height_; }
  // The window's origin in the frame, and the frame (the EXR's data and
  // display windows).
  int originX() const { return x0_; }
  int originY() const { return y0_; }
  int fullWidth() const { return fullWidth_; }
  int fullHeight() const { return fullHeight_; }
  PixelRect window() const { return {x0_, y0_, x0_ + width_, y0_ + height_}; }
  bool hasAovs() const { return aovs_; }
  // The albedo.* and shaded.* planes are there (the AOVs without --no-albedo).
  bool hasAlbedo() const { return aovs_ && albedo_; }
  // The channels stored, in file order (RGBA, then AOVs if enabled, then
  // extra planes in the order they were added).
  const std::vector<int>& channels() const { return channels_; }
  // Adds a zero-filled plane named `name` (e.g. "ao.R" of a pass's layer,
  // "CryptoObject00.R"), written after the fixed channels; returns its
  // channel index (>= kChannelCount). Throws obscura::Error if the name is
  // taken.
  int addPlane(const std::string& name);
  // The index of the plane called `name`, or -1.
  int find(const std::string& name) const;
  // The file name of channel c (a Channel or an added plane).
  const std::string& name(int c) const { return names_[size_t(c)]; }
  float* plane(int c) { return planes_[c].data(); }
  const float* plane(int c) const { return planes_[c].data(); }
  float at(int c, int x, int y) const { return planes_[c][size_t(y - y0_) * width_ + size_t(x - x0_)]; }
  float& at(int c, int x, int y) { return planes_[c][size_t(y - y0_) * width_ + size_t(x - x0_)]; }

 private:
  int width_ = 0, height_ = 0;
  int x0_ = 0, y0_ = 0, fullWidth_ = 0, fullHeight_ = 0;
  bool aovs_ = true, albedo_ = true;
  std::vector<int> channels_;
  std::vector<std::string> names_;
  // Whole-image planes on huge pages (core/util/large_vector.h): zeroing a 1080p
  // film with every AOV faulted ~20k 4 KiB pages in, a few hundred here.
  std::vector<LargeVector<float>> planes_;
};

}  // namespace obscura
