// Cutting an image region into parts for several workers (sampler threads, sampler nodes):
// the top of the K-D tree above every worker's own tiling (DESIGN.md, "The closed loop").
#pragma once

#include <afr/common/rect.h>

#include <span>
#include <vector>

namespace afr {

// Cuts `region` into shares.size() rectangles by recursive halving across the longer side,
// each part's area proportional to its share (shares > 0). The parts partition the region
// exactly and come back in the order of `shares`. A part is never empty as long as the region
// has at least shares.size() pixels; when it has fewer, the extra parts are empty.
std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares);

// A non-negative mass (error) over an image, as a density per cell of a coarse grid: enough to
// cut an image by error rather than by area. mass() integrates it exactly over any rectangle
// (the density is constant in each cell, so the integral is piecewise bilinear).
class MassDensity {
 public:
  // width x height pixels, cells_x x cells_y cells (each at least 1, at most the pixels).
  MassDensity(int width, int height, int cells_x, int cells_y);
  // Spreads `mass` (finite, >= 0; anything else is ignored) evenly over `rect` (clipped).
  void add(const PixelRect& rect, double mass);
  // Adds `density` per pixel everywhere (a floor, so no part of the image is weightless).
  void add_uniform(double density);
  // This = (1 - w) x this + w x other, cell by cell (same grid; a different grid: other).
  void blend(const MassDensity& other, double w);
  double total() const;
  double mass(const PixelRect& rect) const;  // builds the integral table on first use

 private:
  double integral(double x, double y) const;  // over [0, x) x [0, y)
  void build() const;

  int width_, height_, cells_x_, cells_y_;
  double cell_w_, cell_h_;
  std::vector<double> density_;        // per cell, mass per pixel
  mutable std::vector<double> table_;  // (cells_x + 1) x (cells_y + 1): mass of whole cells
  mutable bool built_ = false;
};

// As split_region, but each part's share of `density`'s mass (not its area) is proportional
// to its share. Falls back to areas where the region holds no mass.
std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares,
                                    const MassDensity& density);

}  // namespace afr
