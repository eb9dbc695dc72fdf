#include <afr/display/tile_field.h>

#include <afr/common/error.h>

#include <algorithm>
#include <cmath>

namespace afr {

namespace {

// A gradient or rate as the field keeps it: finite and >= 0, else 0 (counted).
float sanitized(float v, uint64_t* bad) {
  if (std::isfinite(v) && v >= 0.0f) return v;
  ++*bad;
  return 0.0f;
}

PixelRect intersect(const PixelRect& a, const PixelRect& b) {
  return PixelRect{std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1),
                   std::min(a.y1, b.y1)};
}

// The output pixels whose centers map into [a, b) of the sampling image at `scale` output
// pixels per sampling pixel: i with a <= (i + 0.5) / scale < b.
void pixel_span(int32_t a, int32_t b, double scale, int limit, int* lo, int* hi) {
  *lo = std::clamp(int(std::ceil(double(a) * scale - 0.5)), 0, limit);
  *hi = std::clamp(int(std::ceil(double(b) * scale - 0.5)), 0, limit);
}

}  // namespace

TileField::TileField(int image_width, int image_height)
    : image_width_(image_width), image_height_(image_height) {
  if (image_width <= 0 || image_height <= 0) {
    throw Error("tile field: the sampling image size must be positive");
  }
}

void TileField::set_tiling(const TilingSnapshot& snapshot) {
  // Sanitise a copy outside the lock.
  TilingSnapshot clean;
  clean.sampler_id = snapshot.sampler_id;
  clean.time = snapshot.time;
  clean.region = intersect(snapshot.region, PixelRect{0, 0, image_width_, image_height_});
  TileFieldStats counted;
  const size_t n = std::min(snapshot.tiles.size(), kMaxTilesPerSnapshot);
  counted.dropped_tiles = snapshot.tiles.size() - n;
  clean.tiles.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    TileInfo t = snapshot.tiles[i];
    t.rect = intersect(t.rect, clean.region);
    if (t.rect.empty()) {
      ++counted.dropped_tiles;
      continue;
    }
    t.G_x = sanitized(t.G_x, &counted.bad_values);
    t.G_y = sanitized(t.G_y, &counted.bad_values);
    t.G_t = sanitized(t.G_t, &counted.bad_values);
    t.rate = sanitized(t.rate, &counted.bad_values);
    clean.tiles.push_back(t);
  }

  std::lock_guard<std::mutex> lock(mutex_);
  stats_.snapshots += 1;
  stats_.bad_values += counted.bad_values;
  stats_.dropped_tiles += counted.dropped_tiles;
  auto it = latest_.find(clean.sampler_id);
  // A NaN time never replaces anything and is never replaced by ordering mistakes.
  const bool stale =
      !std::isfinite(clean.time) || (it != latest_.end() && clean.time < it->second.time);
  if (stale) {
    ++stats_.stale_snapshots;
    return;
  }
  latest_[clean.sampler_id] = std::move(clean);
  ++version_;
}

TileFieldStats TileField::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

bool TileField::update(int width, int height) {
  std::vector<const TilingSnapshot*> order;
  std::vector<TilingSnapshot> copies;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (version_ == built_version_ && width == width_ && height == height_) return false;
    built_version_ = version_;
    // Copy under the lock (tile lists are small next to the samples), rasterise outside it.
    copies.reserve(latest_.size());
    for (const auto& [id, snap] : latest_) copies.push_back(snap);
  }
  for (const TilingSnapshot& s : copies) order.push_back(&s);
  // Older snapshots first, so the newest wins where regions overlap.
  std::stable_sort(
      order.begin(), order.end(),
      [](const TilingSnapshot* a, const TilingSnapshot* b) { return a->time < b->time; });

  width_ = width;
  height_ = height;
  tiles_.assign(1, FieldTile{});
  index_map_.assign(size_t(width) * size_t(height), 0u);
  const double sx = double(width) / double(image_width_);
  const double sy = double(height) / double(image_height_);
  for (const TilingSnapshot* snap : order) {
    for (const TileInfo& t : snap->tiles) {
      const uint32_t index = uint32_t(tiles_.size());
      tiles_.push_back(FieldTile{t.G_x, t.G_y, t.G_t, t.rate, snap->sampler_id, t.rect});
      int i0, i1, j0, j1;
      pixel_span(t.rect.x0, t.rect.x1, sx, width, &i0, &i1);
      pixel_span(t.rect.y0, t.rect.y1, sy, height, &j0, &j1);
      for (int j = j0; j < j1; ++j) {
        uint32_t* row = index_map_.data() + size_t(j) * size_t(width);
        std::fill(row + i0, row + i1, index);
      }
    }
  }
  return true;
}

}  // namespace afr
