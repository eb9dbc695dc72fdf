// The tile field: for every output pixel, the G_x, G_y, G_t and local rate R_l that the
// filter reads (section 5.2's tile texture). It is made from the latest tiling snapshot of
// every sampler, each covering that sampler's region; snapshots arrive on any thread and the
// reconstructor rebuilds the per-pixel map when one has arrived since its last image.
#pragma once

#include <afr/common/samples.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <vector>

namespace afr {

// One tile as the filter reads it, sanitised.
struct FieldTile {
  float G_x = 0.0f;  // luminance per pixel, finite, >= 0
  float G_y = 0.0f;
  float G_t = 0.0f;   // luminance per second, finite, >= 0
  float rate = 0.0f;  // samples per pixel per second; 0 = unknown (the store's rate is used)
  uint32_t sampler_id = 0;
  PixelRect rect;  // in pixels of the sampling image, clipped to its snapshot's region
};

struct TileFieldStats {
  uint64_t snapshots = 0;
  uint64_t stale_snapshots = 0;  // older than the one already held for that sampler: ignored
  uint64_t bad_values = 0;       // gradients or rates NaN, infinite or negative (set to 0)
  uint64_t dropped_tiles = 0;    // empty after clipping, or beyond kMaxTilesPerSnapshot
};

class TileField {
 public:
  static constexpr size_t kMaxTilesPerSnapshot = size_t(1) << 20;

  // The size of the sampling image, in whose pixels tile rectangles are given.
  TileField(int image_width, int image_height);

  // ---- Any thread.
  // Keeps `snapshot` as its sampler's latest (unless an newer one is held). Tiles are clipped
  // to the snapshot's region and the image; bad values are zeroed and counted.
  void set_tiling(const TilingSnapshot& snapshot);
  TileFieldStats stats() const;

  // ---- The reconstructing thread only.
  // Brings the per-pixel map up to date for an output of width x height pixels (the sampling
  // image scaled by width / image_width, height / image_height). Returns true when the map or
  // the tile list changed since the last call.
  bool update(int width, int height);
  int width() const { return width_; }
  int height() const { return height_; }
  // Index 0 is the "no tile" entry (zero gradients, unknown rate) of pixels no tile covers.
  const std::vector<FieldTile>& tiles() const { return tiles_; }
  // width x height tile indices, row 0 at the top. Where tiles of several snapshots overlap
  // (regions being reassigned), the newest snapshot wins.
  const std::vector<uint32_t>& index_map() const { return index_map_; }
  const FieldTile& at(int x, int y) const {
    return tiles_[index_map_[size_t(y) * size_t(width_) + size_t(x)]];
  }

 private:
  const int image_width_;
  const int image_height_;

  mutable std::mutex mutex_;
  std::map<uint32_t, TilingSnapshot> latest_;  // by sampler id; guarded by mutex_
  uint64_t version_ = 0;                       // guarded by mutex_
  TileFieldStats stats_;                       // guarded by mutex_

  // Reconstructing thread only.
  uint64_t built_version_ = ~uint64_t(0);
  int width_ = 0;
  int height_ = 0;
  std::vector<FieldTile> tiles_;
  std::vector<uint32_t> index_map_;
};

}  // namespace afr
