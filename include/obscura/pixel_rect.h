// Rectangles of pixels: the render loops' tiles.
#pragma once

#include <algorithm>
#include <cstddef>

namespace obscura {

// A rectangle of pixels [x0, x1) x [y0, y1): the render loops' tiles (the
// ray-traced loop's and the screen-space loop's).
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  size_t size() const { return size_t(x1 - x0) * size_t(y1 - y0); }
  // Row-major index of pixel (x, y) within the rectangle.
  size_t offset(int x, int y) const { return size_t(y - y0) * size_t(x1 - x0) + size_t(x - x0); }
  // The size x size tiles covering a w x h image, row-major: how many, and
  // tile `index` (clipped at the image's right and bottom edges).
  static int tileCount(int size, int w, int h) { return ((w + size - 1) / size) * ((h + size - 1) / size); }
  static PixelRect tile(int index, int size, int w, int h) {
    const int across = (w + size - 1) / size;
    PixelRect r;
    r.x0 = (index % across) * size, r.y0 = (index / across) * size;
    r.x1 = std::min(w, r.x0 + size), r.y1 = std::min(h, r.y0 + size);
    return r;
  }
};

}  // namespace obscura
