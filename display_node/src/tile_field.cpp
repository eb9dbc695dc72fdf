#include <afr/display/tile_field.h>

#include <afr/common/check.h>
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

// The grid pixels whose centers map into [a, b) of the sampling image at `scale` output
// pixels per sampling pixel, the grid starting at output pixel `origin`: i with
// a <= (origin + i + 0.5) / scale < b.
void pixel_span(int32_t a, int32_t b, double scale, double origin, int limit, int* lo, int* hi) {
  *lo = int(std::clamp(std::ceil(double(a) * scale - origin - 0.5), 0.0, double(limit)));
  *hi = int(std::clamp(std::ceil(double(b) * scale - origin - 0.5), 0.0, double(limit)));
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
  return update(PixelGrid{width, height, 0.0, 0.0, double(width) / double(image_width_),
                          double(height) / double(image_height_)});
}

bool TileField::update(const PixelGrid& grid) {
  std::vector<const TilingSnapshot*> order;
  std::vector<TilingSnapshot> copies;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (version_ == built_version_ && grid == grid_) return false;
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

  grid_ = grid;
  const int width = grid.width, height = grid.height;
  tiles_.assign(1, FieldTile{});
  index_map_.assign(size_t(width) * size_t(height), 0u);
  const double sx = grid.scale_x, sy = grid.scale_y;
  // The part of the sampling image the grid covers, rounded out to whole pixels: tiles
  // outside it reach no pixel and are not kept.
  const PixelRect covered{int32_t(std::floor(grid.origin_x / sx)),
                          int32_t(std::floor(grid.origin_y / sy)),
                          int32_t(std::ceil((grid.origin_x + width) / sx)),
                          int32_t(std::ceil((grid.origin_y + height) / sy))};
  for (const TilingSnapshot* snap : order) {
    for (const TileInfo& t : snap->tiles) {
      if (intersect(t.rect, covered).empty()) continue;
      const uint32_t index = uint32_t(tiles_.size());
      tiles_.push_back(FieldTile{t.G_x, t.G_y, t.G_t, t.rate, snap->sampler_id, t.rect});
      int i0, i1, j0, j1;
      pixel_span(t.rect.x0, t.rect.x1, sx, grid.origin_x, width, &i0, &i1);
      pixel_span(t.rect.y0, t.rect.y1, sy, grid.origin_y, height, &j0, &j1);
      for (int j = j0; j < j1; ++j) {
        uint32_t* row = index_map_.data() + size_t(j) * size_t(width);
        std::fill(row + i0, row + i1, index);
      }
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// TileSampleCounts

TileSampleCounts::TileSampleCounts(const PixelRect& region, size_t capacity) : region_(region) {
  AFR_CHECK(!region.empty() && region.x0 >= 0 && region.y0 >= 0 && region.width() <= 32768 &&
            region.height() <= 32768 && capacity > 0 && capacity < kNone);
  const uint64_t budget = std::max<uint64_t>(uint64_t(1) << 16, capacity);
  const auto blocks_at = [&](int shift) {
    return uint64_t(((region.width() - 1) >> shift) + 1) *
           uint64_t(((region.height() - 1) >> shift) + 1);
  };
  while (blocks_at(shift_) > budget) ++shift_;
  grid_width_ = ((region.width() - 1) >> shift_) + 1;
  grid_height_ = ((region.height() - 1) >> shift_) + 1;
  blocks_.assign(size_t(grid_width_) * size_t(grid_height_), Block{});
  block_first_.assign(blocks_.size() + 1, 0u);
  slot_pixel_.assign(capacity, kNone);
  slot_next_.assign(capacity, kNone);
  rects_.assign(1, PixelRect{});
  counts_.assign(1, 0u);
}

void TileSampleCounts::set_tiles(const std::vector<FieldTile>& tiles) {
  const size_t n = tiles.size();
  const PixelRect local{0, 0, region_.width(), region_.height()};
  rects_.resize(n);
  counts_.assign(n, 0u);
  // The blocks tile i overlaps: [bx0, bx1] x [by0, by1] (empty rects: none).
  const auto blocks_of = [&](const PixelRect& r, int* bx0, int* bx1, int* by0, int* by1) {
    *bx0 = r.x0 >> shift_;
    *bx1 = (r.x1 - 1) >> shift_;
    *by0 = r.y0 >> shift_;
    *by1 = (r.y1 - 1) >> shift_;
  };
  // Pass 1: how many tiles each block lists (in block_first_[b + 1]).
  std::fill(block_first_.begin(), block_first_.end(), 0u);
  for (size_t i = 0; i < n; ++i) {
    const PixelRect& t = tiles[i].rect;
    PixelRect r = intersect(
        PixelRect{t.x0 - region_.x0, t.y0 - region_.y0, t.x1 - region_.x0, t.y1 - region_.y0},
        local);
    if (i == 0 || r.empty()) r = PixelRect{};  // entry 0 is "no tile"
    rects_[i] = r;
    if (r.empty()) continue;
    int bx0, bx1, by0, by1;
    blocks_of(r, &bx0, &bx1, &by0, &by1);
    for (int by = by0; by <= by1; ++by) {
      for (int bx = bx0; bx <= bx1; ++bx) ++block_first_[size_t(by) * grid_width_ + bx + 1];
    }
  }
  for (size_t b = 1; b < block_first_.size(); ++b) block_first_[b] += block_first_[b - 1];
  block_tiles_.resize(block_first_.back());
  // Pass 2: list the tiles (block_first_[b] runs ahead as a cursor) and count each tile's
  // samples: whole blocks by their count, blocks the tile's edge cuts sample by sample.
  const int side = 1 << shift_;
  for (size_t i = 1; i < n; ++i) {
    const PixelRect& r = rects_[i];
    if (r.empty()) continue;
    int bx0, bx1, by0, by1;
    blocks_of(r, &bx0, &bx1, &by0, &by1);
    uint64_t count = 0;
    for (int by = by0; by <= by1; ++by) {
      const int y0 = by * side, y1 = std::min(y0 + side, local.y1);
      for (int bx = bx0; bx <= bx1; ++bx) {
        const size_t b = size_t(by) * grid_width_ + bx;
        block_tiles_[block_first_[b]++] = uint32_t(i);
        const int x0 = bx * side, x1 = std::min(x0 + side, local.x1);
        if (r.x0 <= x0 && x1 <= r.x1 && r.y0 <= y0 && y1 <= r.y1) {
          count += blocks_[b].count;
          continue;
        }
        for (uint32_t s = blocks_[b].head; s != kNone; s = slot_next_[s]) {
          const uint32_t v = slot_pixel_[s];
          count += r.contains(unpack_x(v), unpack_y(v)) ? 1 : 0;
        }
      }
    }
    counts_[i] = count;
  }
  // The cursors ended at the next block's start: shift them back.
  for (size_t b = block_first_.size() - 1; b > 0; --b) block_first_[b] = block_first_[b - 1];
  block_first_[0] = 0;
}

void TileSampleCounts::clear_samples() {
  std::fill(blocks_.begin(), blocks_.end(), Block{});
  std::fill(slot_pixel_.begin(), slot_pixel_.end(), kNone);
  std::fill(counts_.begin(), counts_.end(), 0u);
  total_ = 0;
}

void TileSampleCounts::remove(size_t slot) {
  const uint32_t v = slot_pixel_[slot];
  if (v == kNone) return;
  slot_pixel_[slot] = kNone;
  const size_t b = block_of(v);
  Block& block = blocks_[b];
  // The ring overwrites its oldest sample: the first of its block's queue.
  AFR_CHECK(block.head == uint32_t(slot));
  block.head = slot_next_[slot];
  if (block.head == kNone) block.tail = kNone;
  --block.count;
  --total_;
  const int x = unpack_x(v), y = unpack_y(v);
  for (uint32_t k = block_first_[b]; k < block_first_[b + 1]; ++k) {
    const uint32_t t = block_tiles_[k];
    if (rects_[t].contains(x, y)) --counts_[t];
  }
}

void TileSampleCounts::insert(size_t slot, const StoredSample& s) {
  // (NaN and far-away positions were rejected at the door; the comparisons keep the casts in
  // range anyway.)
  if (!(s.x >= float(region_.x0) && s.x < float(region_.x1) && s.y >= float(region_.y0) &&
        s.y < float(region_.y1))) {
    slot_pixel_[slot] = kNone;
    return;
  }
  const int x = std::min(int(s.x), region_.x1 - 1) - region_.x0;
  const int y = std::min(int(s.y), region_.y1 - 1) - region_.y0;
  const uint32_t v = pack(x, y);
  slot_pixel_[slot] = v;
  slot_next_[slot] = kNone;
  const size_t b = block_of(v);
  Block& block = blocks_[b];
  if (block.tail != kNone) {
    slot_next_[block.tail] = uint32_t(slot);
  } else {
    block.head = uint32_t(slot);
  }
  block.tail = uint32_t(slot);
  ++block.count;
  ++total_;
  for (uint32_t k = block_first_[b]; k < block_first_[b + 1]; ++k) {
    const uint32_t t = block_tiles_[k];
    if (rects_[t].contains(x, y)) ++counts_[t];
  }
}

void TileSampleCounts::update(const SampleStore::Delta& delta,
                              const std::vector<StoredSample>& fresh) {
  const size_t capacity = slot_pixel_.size();
  RingRun runs[2];
  const int k = ring_runs(delta.first, delta.end, capacity, runs);
  // A whole ring's worth replaces every sample, including ones never seen (more than N
  // arrived since the last update): start from empty rather than evict out of order.
  if (delta.end - delta.first >= capacity) clear_samples();
  for (int r = 0; r < k; ++r) {
    for (size_t j = 0; j < runs[r].count; ++j) {
      const size_t slot = runs[r].slot + j;
      remove(slot);
      insert(slot, fresh[runs[r].offset + j]);
    }
  }
}

}  // namespace afr
