// Pixel rectangles: tiles, regions and display rectangles.
#pragma once

#include <cstdint>

namespace afr {

// A half-open pixel rectangle [x0, x1) x [y0, y1). 32-bit coordinates address images of up to
// 2^31 pixels a side; areas are 64-bit.
struct PixelRect {
  int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  int32_t width() const { return x1 - x0; }
  int32_t height() const { return y1 - y0; }
  int64_t area() const { return int64_t(width()) * int64_t(height()); }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  bool contains(int32_t x, int32_t y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
  bool operator==(const PixelRect&) const = default;
};

// The size of an image in pixels: a sampling image, a display's image, a wall's virtual display.
// Every config and message that carries an image size uses it.
struct ImageExtent {
  int32_t width = 0, height = 0;

  int64_t area() const { return int64_t(width) * int64_t(height); }
  bool empty() const { return width <= 0 || height <= 0; }
  // The whole image as a rectangle, [0, width) x [0, height).
  PixelRect rect() const { return PixelRect{0, 0, width, height}; }
  bool operator==(const ImageExtent&) const = default;
};

// The overlap of two rectangles; the empty rectangle {} when they do not overlap.
inline PixelRect intersect(const PixelRect& a, const PixelRect& b) {
  const PixelRect r{a.x0 > b.x0 ? a.x0 : b.x0, a.y0 > b.y0 ? a.y0 : b.y0, a.x1 < b.x1 ? a.x1 : b.x1,
                    a.y1 < b.y1 ? a.y1 : b.y1};
  return r.empty() ? PixelRect{} : r;
}

}  // namespace afr
