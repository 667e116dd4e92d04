#include "core/film.h"

namespace obscura {

const char* channelName(int c) {
  static const char* names[kChannelCount] = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B",
                                             "N.X", "N.Y", "N.Z", "Z", "shaded.R", "shaded.G", "shaded.B"};
  return names[c];
}

Film::Film(int width, int height, bool aovs) : width_(width), height_(height), aovs_(aovs) {
  planes_.resize(kChannelCount);
  const int n = aovs ? int(kChannelCount) : 4;
  for (int c = 0; c < n; ++c) {
    channels_.push_back(c);
    planes_[c].assign(size_t(width) * size_t(height), 0.0f);
  }
}

}  // namespace obscura
