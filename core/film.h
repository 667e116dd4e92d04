// The film: one float plane per output channel.
//
// Channel layout (README "Channels"): R,G,B = the pass W, premultiplied by
// coverage; A = coverage; albedo.R/G/B (premultiplied); N.X/Y/Z = world
// normal (mean over the pixel's hits, renormalized; 0 where nothing was hit);
// Z = camera distance (mean over hits; +inf where nothing was hit);
// shaded.R/G/B = albedo * W * sky, from the pixel's albedo and W
// (premultiplied).
#pragma once

#include <string>
#include <vector>

namespace obscura {

enum Channel : int {
  kR, kG, kB, kA,
  kAlbedoR, kAlbedoG, kAlbedoB,
  kNX, kNY, kNZ,
  kZ,
  kShadedR, kShadedG, kShadedB,
  kChannelCount
};

const char* channelName(int c);

class Film {
 public:
  Film() = default;
  Film(int width, int height, bool aovs);
  int width() const { return width_; }
  int height() const { return height_; }
  bool hasAovs() const { return aovs_; }
  // The channels stored, in file order (RGBA, then AOVs if enabled).
  const std::vector<int>& channels() const { return channels_; }
  float* plane(int c) { return planes_[c].data(); }
  const float* plane(int c) const { return planes_[c].data(); }
  float at(int c, int x, int y) const { return planes_[c][size_t(y) * width_ + x]; }
  float& at(int c, int x, int y) { return planes_[c][size_t(y) * width_ + x]; }

 private:
  int width_ = 0, height_ = 0;
  bool aovs_ = true;
  std::vector<int> channels_;
  std::vector<std::vector<float>> planes_;
};

}  // namespace obscura
