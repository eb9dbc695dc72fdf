#include <afr/common/region_split.h>

#include <afr/common/check.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace afr {

namespace {

// The mass of the part [r.x0, r.x0 + cut) (or the rows) of r.
double part_mass(const PixelRect& r, bool across_x, int32_t cut, const MassDensity& d) {
  PixelRect a = r;
  if (across_x) {
    a.x1 = r.x0 + cut;
  } else {
    a.y1 = r.y0 + cut;
  }
  return d.mass(a);
}

void split(const PixelRect& r, std::span<const double> shares, size_t first,
           std::vector<PixelRect>* out, const MassDensity* density) {
  if (shares.size() == 1) {
    (*out)[first] = r;
    return;
  }
  const size_t half = shares.size() / 2;
  const double left = std::accumulate(shares.begin(), shares.begin() + half, 0.0);
  const double total = std::accumulate(shares.begin(), shares.end(), 0.0);
  const bool across_x = r.width() >= r.height();
  const int32_t extent = across_x ? r.width() : r.height();
  // Each side keeps at least as many pixel columns (rows) as it has parts, when it can.
  const int32_t lo = std::min<int32_t>(int32_t(half), extent);
  const int32_t hi = std::max<int32_t>(lo, extent - int32_t(shares.size() - half));
  int32_t cut = std::clamp(int32_t(std::lround(extent * left / total)), lo, hi);
  const double whole = density ? density->mass(r) : 0.0;
  if (whole > 0.0) {
    // The smallest cut whose part holds at least its share of the mass (the mass grows with
    // the cut), then the nearer of it and the cut before.
    const double want = whole * left / total;
    int32_t a_cut = lo, b_cut = hi;
    while (a_cut < b_cut) {
      const int32_t mid = a_cut + (b_cut - a_cut) / 2;
      if (part_mass(r, across_x, mid, *density) < want) {
        a_cut = mid + 1;
      } else {
        b_cut = mid;
      }
    }
    cut = a_cut;
    if (cut > lo && std::abs(part_mass(r, across_x, cut - 1, *density) - want) <
                        std::abs(part_mass(r, across_x, cut, *density) - want)) {
      --cut;
    }
  }
  PixelRect a = r, b = r;
  if (across_x) {
    a.x1 = b.x0 = r.x0 + cut;
  } else {
    a.y1 = b.y0 = r.y0 + cut;
  }
  split(a, shares.subspan(0, half), first, out, density);
  split(b, shares.subspan(half), first + half, out, density);
}

}  // namespace

std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares) {
  AFR_CHECK(!shares.empty());
  for (double s : shares) AFR_CHECK(s > 0.0 && std::isfinite(s));
  std::vector<PixelRect> out(shares.size());
  split(region, shares, 0, &out, nullptr);
  return out;
}

std::vector<PixelRect> split_region(const PixelRect& region, std::span<const double> shares,
                                    const MassDensity& density) {
  AFR_CHECK(!shares.empty());
  for (double s : shares) AFR_CHECK(s > 0.0 && std::isfinite(s));
  std::vector<PixelRect> out(shares.size());
  split(region, shares, 0, &out, &density);
  return out;
}

// ---------------------------------------------------------------------------------------------
// MassDensity

MassDensity::MassDensity(int width, int height, int cells_x, int cells_y)
    : width_(width),
      height_(height),
      cells_x_(std::clamp(cells_x, 1, std::max(1, width))),
      cells_y_(std::clamp(cells_y, 1, std::max(1, height))),
      cell_w_(double(width) / double(cells_x_)),
      cell_h_(double(height) / double(cells_y_)),
      density_(size_t(cells_x_) * size_t(cells_y_), 0.0) {
  AFR_CHECK(width >= 1 && height >= 1);
}

void MassDensity::add(const PixelRect& rect, double mass) {
  const PixelRect r{std::max(rect.x0, 0), std::max(rect.y0, 0), std::min(rect.x1, width_),
                    std::min(rect.y1, height_)};
  if (r.empty() || !(mass > 0.0) || !std::isfinite(mass)) return;
  const double per_pixel = mass / double(r.area());
  // Each cell the rectangle overlaps gets the overlap's share, as a density over the cell.
  const int i0 = std::min(cells_x_ - 1, int(r.x0 / cell_w_));
  const int i1 = std::min(cells_x_ - 1, int((r.x1 - 1) / cell_w_));
  const int j0 = std::min(cells_y_ - 1, int(r.y0 / cell_h_));
  const int j1 = std::min(cells_y_ - 1, int((r.y1 - 1) / cell_h_));
  for (int j = j0; j <= j1; ++j) {
    const double oy =
        std::min(double(r.y1), (j + 1) * cell_h_) - std::max(double(r.y0), j * cell_h_);
    for (int i = i0; i <= i1; ++i) {
      const double ox =
          std::min(double(r.x1), (i + 1) * cell_w_) - std::max(double(r.x0), i * cell_w_);
      if (ox > 0.0 && oy > 0.0) {
        density_[size_t(j) * size_t(cells_x_) + size_t(i)] +=
            per_pixel * ox * oy / (cell_w_ * cell_h_);
      }
    }
  }
  built_ = false;
}

void MassDensity::blend(const MassDensity& other, double w) {
  if (other.cells_x_ != cells_x_ || other.cells_y_ != cells_y_ || other.width_ != width_ ||
      other.height_ != height_) {
    *this = other;
    return;
  }
  w = std::clamp(w, 0.0, 1.0);
  for (size_t i = 0; i < density_.size(); ++i) {
    density_[i] = (1.0 - w) * density_[i] + w * other.density_[i];
  }
  built_ = false;
}

void MassDensity::add_uniform(double density) {
  if (!(density > 0.0) || !std::isfinite(density)) return;
  for (double& d : density_) d += density;
  built_ = false;
}

void MassDensity::build() const {
  const size_t stride = size_t(cells_x_) + 1;
  table_.assign(stride * (size_t(cells_y_) + 1), 0.0);
  const double cell_area = cell_w_ * cell_h_;
  for (int j = 0; j < cells_y_; ++j) {
    double row = 0.0;
    for (int i = 0; i < cells_x_; ++i) {
      row += density_[size_t(j) * size_t(cells_x_) + size_t(i)] * cell_area;
      table_[size_t(j + 1) * stride + size_t(i + 1)] =
          table_[size_t(j) * stride + size_t(i + 1)] + row;
    }
  }
  built_ = true;
}

double MassDensity::integral(double x, double y) const {
  const size_t stride = size_t(cells_x_) + 1;
  const int i = std::min(cells_x_ - 1, int(x / cell_w_));
  const int j = std::min(cells_y_ - 1, int(y / cell_h_));
  const double fx = x - i * cell_w_, fy = y - j * cell_h_;
  const auto T = [&](int ii, int jj) { return table_[size_t(jj) * stride + size_t(ii)]; };
  // Whole cells before (i, j), the partial column i above row j, the partial row j left of
  // column i, and the partial cell (i, j).
  return T(i, j) + fx * (T(i + 1, j) - T(i, j)) / cell_w_ + fy * (T(i, j + 1) - T(i, j)) / cell_h_ +
         fx * fy * density_[size_t(j) * size_t(cells_x_) + size_t(i)];
}

double MassDensity::total() const { return mass(PixelRect{0, 0, width_, height_}); }

double MassDensity::mass(const PixelRect& rect) const {
  if (!built_) build();
  const double x0 = std::clamp(double(rect.x0), 0.0, double(width_));
  const double x1 = std::clamp(double(rect.x1), 0.0, double(width_));
  const double y0 = std::clamp(double(rect.y0), 0.0, double(height_));
  const double y1 = std::clamp(double(rect.y1), 0.0, double(height_));
  if (x1 <= x0 || y1 <= y0) return 0.0;
  const double m = integral(x1, y1) - integral(x0, y1) - integral(x1, y0) + integral(x0, y0);
  return std::max(0.0, m);
}

}  // namespace afr
