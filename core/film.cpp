#include "core/film.h"

#include <sys/mman.h>

#include "core/error.h"

namespace obscura {

namespace {
// A plane of n zeros. LargeAllocator puts storage of 2 MiB or more at a
// 2 MiB boundary and rounds it up to whole 2 MiB (core/large_vector.h), so
// those pages can be handed back with MADV_DONTNEED: on a private anonymous
// mapping (the heap and glibc's mmapped chunks are) the kernel then maps
// zero-filled pages on first touch (madvise(2)). The plane is zero without
// writing it: the render loop's threads fault in the pages they write, in
// parallel, and a page nothing writes is never allocated. Filling it
// instead had one thread fault in and clear every page (the kernel's
// zeroing) and then write its zeros a second time: 4 % of an `obscura
// render` process's CPU (README "Speed"). Smaller planes, or a refused
// madvise, are filled.
void zeroPlane(LargeVector<float>& plane, size_t n) {
  plane.resize(n);  // uninitialized (LargeAllocator)
  const size_t bytes = n * sizeof(float), huge = LargeAllocator<float>::kHuge;
  if (bytes >= huge && madvise(plane.data(), (bytes + huge - 1) / huge * huge, MADV_DONTNEED) == 0) return;
  std::fill(plane.begin(), plane.end(), 0.0f);
}
}  // namespace

const char* channelName(int c) {
  static const char* names[kChannelCount] = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B",
                                             "N.X", "N.Y", "N.Z", "Z", "shaded.R", "shaded.G", "shaded.B"};
  return names[c];
}

Film::Film(int width, int height, bool aovs) : Film(PixelRect{0, 0, width, height}, width, height, aovs) {}

Film::Film(const PixelRect& window, int fullWidth, int fullHeight, bool aovs)
    : width_(window.width()), height_(window.height()), x0_(window.x0), y0_(window.y0), fullWidth_(fullWidth),
      fullHeight_(fullHeight), aovs_(aovs) {
  planes_.resize(kChannelCount);
  for (int c = 0; c < kChannelCount; ++c) names_.emplace_back(channelName(c));
  const int n = aovs ? int(kChannelCount) : 4;
  for (int c = 0; c < n; ++c) {
    channels_.push_back(c);
    zeroPlane(planes_[c], size_t(width_) * size_t(height_));
  }
}

int Film::addPlane(const std::string& name) {
  if (find(name) >= 0) throw Error("two output channels are named '" + name + "'");
  const int c = int(planes_.size());
  names_.push_back(name);
  planes_.emplace_back();
  zeroPlane(planes_.back(), size_t(width_) * size_t(height_));
  channels_.push_back(c);
  return c;
}

int Film::find(const std::string& name) const {
  for (int c : channels_)
    if (names_[size_t(c)] == name) return c;
  return -1;
}

}  // namespace obscura
