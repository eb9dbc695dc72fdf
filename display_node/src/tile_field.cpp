#include <afr/display/tile_field.h>

#include <afr/common/check.h>
#include <afr/common/error.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <future>

namespace afr {

namespace {

// A gradient or rate as the field keeps it: finite and >= 0, else 0 (counted).
float sanitized(float v, uint64_t* bad) {
  if (std::isfinite(v) && v >= 0.0f) return v;
  ++*bad;
  return 0.0f;
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

void TileField::forget(uint32_t sampler_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (latest_.erase(sampler_id) > 0) ++version_;
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
  spans_.assign(1, PixelRect{});
  if (build_index_map_) {
    index_map_.assign(size_t(width) * size_t(height), 0u);
  } else {
    index_map_.clear();
  }
  const double sx = grid.scale_x, sy = grid.scale_y;
  // The part of the sampling image the grid covers, rounded out to whole pixels: tiles
  // outside it reach no pixel and are not kept.
  const PixelRect covered{int32_t(std::floor(grid.origin_x / sx)),
                          int32_t(std::floor(grid.origin_y / sy)),
                          int32_t(std::ceil((grid.origin_x + width) / sx)),
                          int32_t(std::ceil((grid.origin_y + height) / sy))};
  const auto add = [&](const TileInfo& t, const PixelRect& rect, uint32_t sampler_id) {
    const uint32_t index = uint32_t(tiles_.size());
    tiles_.push_back(FieldTile{t.G_x, t.G_y, t.G_t, t.rate, sampler_id, rect});
    int i0, i1, j0, j1;
    pixel_span(rect.x0, rect.x1, sx, grid.origin_x, width, &i0, &i1);
    pixel_span(rect.y0, rect.y1, sy, grid.origin_y, height, &j0, &j1);
    spans_.push_back(PixelRect{i0, j0, i1, j1});
    if (!build_index_map_) return;
    for (int j = j0; j < j1; ++j) {
      uint32_t* row = index_map_.data() + size_t(j) * size_t(width);
      std::fill(row + i0, row + i1, index);
    }
  };
  // The lattice cells [k L, (k + 1) L) that the span [a, b) reaches, one axis.
  const int32_t lattice = rate_lattice(sx, sy);
  const auto cells = [lattice](int32_t a, int32_t b, int32_t* k0, int32_t* k1) {
    *k0 = a / lattice;
    *k1 = (b - 1) / lattice + 1;
  };
  for (const TilingSnapshot* snap : order) {
    for (const TileInfo& t : snap->tiles) {
      const PixelRect seen = intersect(t.rect, covered);
      if (seen.empty()) continue;
      if (t.rect.width() <= lattice && t.rect.height() <= lattice) {
        add(t, t.rect, snap->sampler_id);
        continue;
      }
      // A larger tile: its pieces in the lattice's cells (an axis the tile spans at most one
      // cell's width of is not cut), those that reach the grid.
      const bool cut_x = t.rect.width() > lattice, cut_y = t.rect.height() > lattice;
      int32_t kx0 = 0, kx1 = 1, ky0 = 0, ky1 = 1;
      if (cut_x) cells(seen.x0, seen.x1, &kx0, &kx1);
      if (cut_y) cells(seen.y0, seen.y1, &ky0, &ky1);
      for (int32_t ky = ky0; ky < ky1; ++ky) {
        for (int32_t kx = kx0; kx < kx1; ++kx) {
          PixelRect piece = t.rect;
          if (cut_x) {
            piece.x0 = std::max(piece.x0, kx * lattice);
            piece.x1 = std::min(piece.x1, (kx + 1) * lattice);
          }
          if (cut_y) {
            piece.y0 = std::max(piece.y0, ky * lattice);
            piece.y1 = std::min(piece.y1, (ky + 1) * lattice);
          }
          add(t, piece, snap->sampler_id);
        }
      }
    }
  }
  return true;
}

int32_t rate_lattice(double scale_x, double scale_y) {
  const double s = std::min(scale_x, scale_y);
  int32_t lattice = kRateLattice;
  // (32768 is the largest image side: one cell then holds a whole axis.)
  while (s * double(lattice) < double(kRateLattice) && lattice < 32768) lattice *= 2;
  return lattice;
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
  block_count_.assign(size_t(grid_width_) * size_t(grid_height_), 0u);
  slot_pixel_.assign(capacity, kNone);
  if (shift_ > 0) {
    queues_.assign(block_count_.size(), Queue{});
    slot_next_.assign(capacity, kNone);
  }
  rects_.assign(1, PixelRect{});
  counts_.assign(1, 0u);
}

void TileSampleCounts::count_tiles(const std::vector<FieldTile>& tiles, int threads) {
  const size_t n = tiles.size();
  const PixelRect local{0, 0, region_.width(), region_.height()};
  rects_.resize(n);
  counts_.assign(n, 0u);
  rects_[0] = PixelRect{};  // "no tile"
  int64_t area = 0;
  for (size_t i = 1; i < n; ++i) {
    const PixelRect& t = tiles[i].rect;
    rects_[i] = intersect(
        PixelRect{t.x0 - region_.x0, t.y0 - region_.y0, t.x1 - region_.x0, t.y1 - region_.y0},
        local);
    area += rects_[i].area();
  }
  // Tiles i = p, p + parts, ... on part p's thread: each reads the counts and writes its own
  // tiles' (parts of at least 2^20 pixels to sum).
  const int parts = int(std::clamp<int64_t>(area >> 20, 1, std::max(threads, 1)));
  const auto count_part = [&](int p) {
    for (size_t i = 1 + size_t(p); i < n; i += size_t(parts)) count_tile(i);
  };
  std::vector<std::future<void>> others;
  for (int p = 1; p < parts; ++p) others.push_back(std::async(std::launch::async, count_part, p));
  count_part(0);
  for (std::future<void>& f : others) f.get();
}

void TileSampleCounts::count_tile(size_t i) {
  const PixelRect local{0, 0, region_.width(), region_.height()};
  const size_t gw = size_t(grid_width_);
  const int side = 1 << shift_;
  const auto walk = [&](size_t b, const PixelRect& r) {
    uint64_t c = 0;
    for (uint32_t s = queues_[b].head; s != kNone; s = slot_next_[s]) {
      const uint32_t v = slot_pixel_[s];
      c += r.contains(unpack_x(v), unpack_y(v)) ? 1 : 0;
    }
    return c;
  };
  const PixelRect r = rects_[i];
  if (r.empty()) return;
  uint64_t count = 0;
  if (shift_ == 0) {
    // One block per pixel: the sum of the rectangle's counts, row by row.
    for (int y = r.y0; y < r.y1; ++y) {
      const uint32_t* row = block_count_.data() + size_t(y) * gw;
      uint32_t sum = 0;  // < N < 2^32
      for (int x = r.x0; x < r.x1; ++x) sum += row[x];
      count += sum;
    }
    counts_[i] = count;
    return;
  }
  // The blocks it overlaps, [bx0, bx1] x [by0, by1], and those wholly inside it,
  // [ix0, ix1) x [iy0, iy1) (the region's last blocks may be narrower).
  const int bx0 = r.x0 >> shift_, bx1 = (r.x1 - 1) >> shift_;
  const int by0 = r.y0 >> shift_, by1 = (r.y1 - 1) >> shift_;
  const int ix0 = std::min((r.x0 + side - 1) >> shift_, bx1 + 1);
  const int ix1 = std::max(r.x1 == local.x1 ? grid_width_ : r.x1 >> shift_, ix0);
  const int iy0 = (r.y0 + side - 1) >> shift_;
  const int iy1 = r.y1 == local.y1 ? grid_height_ : r.y1 >> shift_;
  for (int by = by0; by <= by1; ++by) {
    const size_t row = size_t(by) * gw;
    if (by < iy0 || by >= iy1) {
      for (int bx = bx0; bx <= bx1; ++bx) count += walk(row + size_t(bx), r);
      continue;
    }
    for (int bx = bx0; bx < ix0; ++bx) count += walk(row + size_t(bx), r);
    for (int bx = ix0; bx < ix1; ++bx) count += block_count_[row + size_t(bx)];
    for (int bx = ix1; bx <= bx1; ++bx) count += walk(row + size_t(bx), r);
  }
  counts_[i] = count;
}

void TileSampleCounts::clear_samples() {
  std::fill(block_count_.begin(), block_count_.end(), 0u);
  std::fill(queues_.begin(), queues_.end(), Queue{});
  std::fill(slot_pixel_.begin(), slot_pixel_.end(), kNone);
  total_ = 0;
}

void TileSampleCounts::remove(size_t slot) {
  const uint32_t v = slot_pixel_[slot];
  if (v == kNone) return;
  slot_pixel_[slot] = kNone;
  const size_t b = block_of(v);
  --block_count_[b];
  --total_;
  if (shift_ > 0) {
    // The ring overwrites its oldest sample: the first of its block's queue.
    Queue& q = queues_[b];
    AFR_CHECK(q.head == uint32_t(slot));
    q.head = slot_next_[slot];
    if (q.head == kNone) q.tail = kNone;
  }
}

uint32_t TileSampleCounts::pixel_of(const StoredSample& s) const {
  // (NaN and far-away positions were rejected at the door; the comparisons keep the casts in
  // range anyway.)
  if (!(s.x >= float(region_.x0) && s.x < float(region_.x1) && s.y >= float(region_.y0) &&
        s.y < float(region_.y1))) {
    return kNone;
  }
  const int x = std::min(int(s.x), region_.x1 - 1) - region_.x0;
  const int y = std::min(int(s.y), region_.y1 - 1) - region_.y0;
  return pack(x, y);
}

void TileSampleCounts::insert(size_t slot, const StoredSample& s) {
  const uint32_t v = pixel_of(s);
  slot_pixel_[slot] = v;
  if (v == kNone) return;
  const size_t b = block_of(v);
  ++block_count_[b];
  ++total_;
  if (shift_ > 0) {
    Queue& q = queues_[b];
    slot_next_[slot] = kNone;
    if (q.tail != kNone) {
      slot_next_[q.tail] = uint32_t(slot);
    } else {
      q.head = uint32_t(slot);
    }
    q.tail = uint32_t(slot);
  }
}

int64_t TileSampleCounts::update_part(const SampleStore::Delta& delta,
                                      const std::vector<StoredSample>& fresh, size_t lo,
                                      size_t hi) {
  const size_t capacity = slot_pixel_.size();
  int64_t change = 0;
  for (size_t i = lo; i < hi; ++i) {
    const size_t slot = size_t((delta.first + i) % capacity);
    if (const uint32_t old = slot_pixel_[slot]; old != kNone) {
      std::atomic_ref<uint32_t>(block_count_[block_of(old)])
          .fetch_sub(1, std::memory_order_relaxed);
      --change;
    }
    const uint32_t v = pixel_of(fresh[i]);
    slot_pixel_[slot] = v;
    if (v != kNone) {
      std::atomic_ref<uint32_t>(block_count_[block_of(v)]).fetch_add(1, std::memory_order_relaxed);
      ++change;
    }
  }
  return change;
}

void TileSampleCounts::update(const SampleStore::Delta& delta,
                              const std::vector<StoredSample>& fresh, int threads) {
  const size_t capacity = slot_pixel_.size();
  RingRun runs[2];
  const int k = ring_runs(delta.first, delta.end, capacity, runs);
  // A whole ring's worth replaces every sample, including ones never seen (more than N
  // arrived since the last update): start from empty rather than evict out of order.
  if (delta.end - delta.first >= capacity) clear_samples();
  // Parts of at least this many pairs (a thread start costs tens of microseconds).
  constexpr size_t kPairsPerThread = size_t(1) << 16;
  const size_t pairs = size_t(delta.end - delta.first);
  const int parts =
      shift_ == 0 ? int(std::min<size_t>(size_t(std::max(threads, 1)), pairs / kPairsPerThread))
                  : 1;
  if (parts > 1) {
    // The parts' slots are disjoint and their block counts move by atomic adds and subtracts,
    // which commute (a count may pass below zero while the parts run; unsigned arithmetic
    // wraps it back).
    std::vector<std::future<int64_t>> others;
    const auto bound = [&](int p) { return pairs * size_t(p) / size_t(parts); };
    for (int p = 1; p < parts; ++p) {
      others.push_back(std::async(std::launch::async, [this, &delta, &fresh, &bound, p] {
        return update_part(delta, fresh, bound(p), bound(p + 1));
      }));
    }
    int64_t change = update_part(delta, fresh, 0, bound(1));
    for (std::future<int64_t>& f : others) change += f.get();
    total_ = uint64_t(int64_t(total_) + change);
    return;
  }
  for (int r = 0; r < k; ++r) {
    for (size_t j = 0; j < runs[r].count; ++j) {
      const size_t slot = runs[r].slot + j;
      remove(slot);
      insert(slot, fresh[runs[r].offset + j]);
    }
  }
}

}  // namespace afr
