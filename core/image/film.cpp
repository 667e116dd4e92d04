#include "core/image/film.h"

#include <obscura/error.h>

namespace obscura {

const char* channelName(int c) {
  static const char* names[kChannelCount] = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B",
                                             "N.X", "N.Y", "N.Z", "Z", "shaded.R", "shaded.G", "shaded.B"};
  return names[c];
}

Film::Film(int width, int height, bool aovs, bool albedo)
    : Film(PixelRect{0, 0, width, height}, width, height, aovs, albedo) {}

Film::Film(const PixelRect& window, int fullWidth, int fullHeight, bool aovs, bool albedo)
    : width_(window.width()), height_(window.height()), x0_(window.x0), y0_(window.y0), fullWidth_(fullWidth),
      fullHeight_(fullHeight), aovs_(aovs), albedo_(albedo) {
  planes_.resize(kChannelCount);
  for (int c = 0; c < kChannelCount; ++c) names_.emplace_back(channelName(c));
  const int n = aovs ? int(kChannelCount) : 4;
  for (int c = 0; c < n; ++c) {
    const bool albedoPlane = (c >= kAlbedoR && c <= kAlbedoB) || (c >= kShadedR && c <= kShadedB);
    if (albedoPlane && !albedo) continue;  // empty, never written
    channels_.push_back(c);
    planes_[c].assign(size_t(width_) * size_t(height_), 0.0f);
  }
}

int Film::addPlane(const std::string& name) {
  if (find(name) >= 0) throw Error("two output channels are named '" + name + "'");
  const int c = int(planes_.size());
  names_.push_back(name);
  planes_.emplace_back(size_t(width_) * size_t(height_), 0.0f);
  channels_.push_back(c);
  return c;
}

int Film::find(const std::string& name) const {
  for (int c : channels_)
    if (names_[size_t(c)] == name) return c;
  return -1;
}

}  // namespace obscura
