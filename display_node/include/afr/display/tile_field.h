// The tile field: for every output pixel, the G_x, G_y, G_t and local rate R_l that the
// filter reads (section 5.2's tile texture). It is made from the latest tiling snapshot of
// every sampler, each covering that sampler's region; snapshots arrive on any thread and the
// reconstructor rebuilds the per-pixel map when one has arrived since its last image. R_l is
// measured from the store: TileSampleCounts keeps how many stored samples lie in each tile.
#pragma once

#include <afr/common/samples.h>
#include <afr/display/sample_store.h>

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

// The pixels a reconstructor computes, placed in the sampling image: pixel (i, j) of this
// width x height grid is pixel (origin_x + i, origin_y + j) of the whole sampling image scaled
// by scale_x, scale_y (output pixels per sampling pixel), so its center lies at
// ((origin_x + i + 0.5) / scale_x, (origin_y + j + 0.5) / scale_y) in sampling pixels. The whole
// image at the output size is {width, height, 0, 0, width / image_width, height / image_height};
// a viewport with its margin has its origin where it starts.
struct PixelGrid {
  int width = 0;
  int height = 0;
  double origin_x = 0.0;  // output pixels
  double origin_y = 0.0;
  double scale_x = 1.0;
  double scale_y = 1.0;
  bool operator==(const PixelGrid&) const = default;
};

// Tiles wider or taller than this many sampling-image pixels enter the field cut along the
// lattice of cells [k L, (k + 1) L) (L = kRateLattice) on the axes where they are: each piece
// gets its own R_l, measured over the piece. Every piece is then at most L a side and lies in
// one cell of a lattice that is the same for every reconstructor, so a viewport's
// reconstructor whose margin reaches L past what its viewport's pixels read holds every
// sample of the pieces they read, and measures their R_l as the whole image's reconstruction
// does (docs/reconstruction.md, "Viewports"). The sampler draws a tile's samples uniformly,
// so its pieces' rates are its own up to counting noise (1.6% at 4 samples per pixel over a
// 32 x 32 piece).
// An image drawn smaller than its sampling size (output scale s < 1) cuts on a coarser
// lattice, kRateLattice x 2^k with k the least for which a cell is at least kRateLattice
// output pixels: the pieces stay at least as large on screen, so a whole 32768² image drawn at
// 512² holds 16² pieces of a tile, not 1024² (nodes of a wall share one scale, hence one
// lattice). rate_lattice gives the side for a grid's scale.
inline constexpr int32_t kRateLattice = 32;
int32_t rate_lattice(double scale_x, double scale_y);

class TileField {
 public:
  static constexpr size_t kMaxTilesPerSnapshot = size_t(1) << 20;

  // The size of the sampling image, in whose pixels tile rectangles are given.
  TileField(int image_width, int image_height);

  // ---- Any thread.
  // Keeps `snapshot` as its sampler's latest (unless an newer one is held). Tiles are clipped
  // to the snapshot's region and the image; bad values are zeroed and counted.
  void set_tiling(const TilingSnapshot& snapshot);
  // Drops sampler `sampler_id`'s snapshot (a sampler that left): its tiles no longer shape the
  // filter, and the field holds snapshots of present samplers only.
  void forget(uint32_t sampler_id);
  TileFieldStats stats() const;

  // ---- The reconstructing thread only.
  // Brings the per-pixel map up to date for `grid`. Returns true when the map or the tile
  // list changed since the last call. Only tiles that overlap the grid's part of the sampling
  // image are kept (the map and the filters are bounded by what is drawn).
  bool update(const PixelGrid& grid);
  // The whole sampling image at width x height pixels.
  bool update(int width, int height);
  int width() const { return grid_.width; }
  int height() const { return grid_.height; }
  const PixelGrid& grid() const { return grid_; }
  // Index 0 is the "no tile" entry (zero gradients, unknown rate) of pixels no tile covers;
  // tiles larger than kRateLattice are here as their pieces.
  const std::vector<FieldTile>& tiles() const { return tiles_; }
  // width x height tile indices, row 0 at the top. Where tiles of several snapshots overlap
  // (regions being reassigned), the newest snapshot wins: the highest index. Empty when the
  // map is not built (set_index_map(false): a GPU backend builds it from spans()).
  const std::vector<uint32_t>& index_map() const { return index_map_; }
  // Per tile, the grid pixels its rectangle covers, [x0, x1) x [y0, y1) (entry 0 empty):
  // pixel p of the map holds the highest i whose span contains p, or 0.
  const std::vector<PixelRect>& spans() const { return spans_; }
  // Whether update() fills index_map() (default true). A backend that builds the map itself
  // turns it off and saves a pass over every pixel of the grid whenever the tiling changes.
  void set_index_map(bool build) { build_index_map_ = build; }
  const FieldTile& at(int x, int y) const {
    return tiles_[index_map_[size_t(y) * size_t(grid_.width) + size_t(x)]];
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
  PixelGrid grid_;
  std::vector<FieldTile> tiles_;
  std::vector<PixelRect> spans_;
  std::vector<uint32_t> index_map_;
  bool build_index_map_ = true;
};

// Section 5.1's local rate R_l, measured: how many samples of the store lie in each tile of
// the field, counted over `region` of the sampling image (the part this reconstructor receives
// samples for). The region is cut into square blocks of 2^k pixels, as few powers of two as
// keep the blocks at most max(2^16, capacity): one block per pixel with the default N = 4 x
// pixels, and on average at most 4 samples per block otherwise. Each block keeps how many
// stored samples it holds, moved by update() with the samples entering and leaving the ring;
// blocks of more than one pixel also keep their samples as a queue in ring order (the ring
// overwrites oldest first, so a sample leaving it is always the first of its block's queue).
// count_tiles() then sums, per tile, the blocks wholly inside it and walks the samples of the
// blocks its edges cut (none with one-pixel blocks). The counts are exact: count(i) is the
// number of stored samples whose position lies in tile i's rectangle inside the region
// (samples in overlapping tiles count in each).
// Cost per image: O(1) per sample entering or leaving, O(blocks the tiles cover + samples in
// cut blocks) for the sums. (Keeping per-tile counts incrementally instead, through per-block
// tile lists, cost ~40 ns per entering/leaving pair in cache misses, ~5x the sums at N = 4 x
// pixels turned over once a second, and samplers send a new tiling every 1/60 s anyway.)
// Memory: 4 bytes per ring slot and per block (16 and 12 with blocks of several pixels), 24
// bytes per tile; nothing per pixel of the sampling image outside the region.
class TileSampleCounts {
 public:
  // region: non-empty, inside the sampling image, sides <= 32768. capacity: the ring's N.
  TileSampleCounts(const PixelRect& region, size_t capacity);

  // The samples the store copied (SampleStore::copy_since), oldest first, into ring slots
  // [delta.first, delta.end) mod N, replacing the samples there. With one-pixel blocks (no
  // queues: the moves commute) a large delta is spread over up to `threads` threads, each
  // moving its part's counts atomically: the update is a cache miss per sample at N = 4 x
  // pixels (33 MB of counts at 3840x2160), which threads overlap.
  void update(const SampleStore::Delta& delta, const std::vector<StoredSample>& fresh,
              int threads = 1);
  // Counts the stored samples in each of `tiles` (entry 0, "no tile", gets none), the tiles
  // spread over up to `threads` threads when they cover millions of pixels.
  void count_tiles(const std::vector<FieldTile>& tiles, int threads = 1);

  const PixelRect& region() const { return region_; }
  // After count_tiles(): stored samples in tile i's rectangle inside the region, and that
  // part's area in pixels.
  uint64_t count(size_t tile) const { return counts_[tile]; }
  int64_t area(size_t tile) const { return rects_[tile].area(); }
  // Stored samples inside the region.
  uint64_t total() const { return total_; }
  int block_side() const { return 1 << shift_; }
  size_t blocks() const { return block_count_.size(); }

 private:
  static constexpr uint32_t kNone = ~uint32_t(0);
  struct Queue {
    uint32_t head = kNone;  // oldest sample's ring slot
    uint32_t tail = kNone;  // newest
  };
  // A sample's pixel, relative to the region: x in the low 16 bits, y in the high ones.
  static uint32_t pack(int x, int y) { return uint32_t(x) | (uint32_t(y) << 16); }
  static int unpack_x(uint32_t v) { return int(v & 0xffffu); }
  static int unpack_y(uint32_t v) { return int(v >> 16); }
  size_t block_of(uint32_t v) const {
    return size_t(unpack_y(v) >> shift_) * size_t(grid_width_) + size_t(unpack_x(v) >> shift_);
  }
  void remove(size_t slot);
  void insert(size_t slot, const StoredSample& s);
  void count_tile(size_t i);  // counts_[i] from rects_[i]
  // The pixel of a sample relative to the region, or kNone outside it.
  uint32_t pixel_of(const StoredSample& s) const;
  // update()'s pairs [lo, hi) of the delta, with one-pixel blocks and atomic counts; returns
  // the change of total_.
  int64_t update_part(const SampleStore::Delta& delta, const std::vector<StoredSample>& fresh,
                      size_t lo, size_t hi);
  void clear_samples();

  PixelRect region_;
  int shift_ = 0;  // block side = 2^shift_
  int grid_width_ = 0, grid_height_ = 0;
  uint64_t total_ = 0;
  std::vector<uint32_t> slot_pixel_;   // per ring slot: packed pixel, kNone if outside/empty
  std::vector<uint32_t> block_count_;  // per block
  // Blocks of several pixels only: per block its queue, per ring slot the next (newer) slot
  // of its block.
  std::vector<Queue> queues_;
  std::vector<uint32_t> slot_next_;
  std::vector<PixelRect> rects_;  // per tile: its rectangle inside the region, relative to it
  std::vector<uint64_t> counts_;  // per tile
};

}  // namespace afr
