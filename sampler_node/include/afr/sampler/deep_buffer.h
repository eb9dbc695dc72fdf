// The sampler's temporally deep buffer (section 4): for every pixel of the owned region a
// queue of up to b crosshairs, newest at the front. Memory is proportional to the owned
// region, never to the whole image; a crosshair takes only the fields its run reads, and the
// larger part of it takes memory only in pixels that hold crosshairs.
#pragma once

#include <afr/common/math.h>
#include <afr/sampler/tiling.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace afr {

// A crosshair (Figure 4): a center sample and its four neighbours one pixel away, traced at
// the same time, plus the old sample traced earlier at the center's position (x, y, t0).
struct Crosshair {
  enum Flags : uint8_t {
    kCenterHit = 1u << 0,
    kHasTemporalGradient = 1u << 1,
    kOccluded = 1u << 2,      // replaced a crosshair that an occlusion ray found hidden
    kNeighborHit0 = 1u << 3,  // neighbour k hit something: bit kNeighborHit0 << k
  };
  // Neighbour order: x-1, x+1, y-1, y+1.
  static constexpr int kLeft = 0, kRight = 1, kUp = 2, kDown = 3;

  double time = 0.0;         // when the center was traced
  double old_time = 0.0;     // t0
  glm::vec3 position{0.0f};  // center world hit point (direction on a miss)
  glm::vec3 velocity{0.0f};
  glm::vec3 neighbor_position[4] = {};
  float x = 0.0f, y = 0.0f;  // image position of the center
  float luminance = 0.0f;
  float old_luminance = 0.0f;
  float neighbor_luminance[4] = {};
  float G_x = 0.0f, G_y = 0.0f, G_t = 0.0f;  // this crosshair's gradients
  uint8_t flags = 0;
  // The scene node in whose space each traced point (the center's, then the neighbours') is
  // kept: a point on a rigidly moving object is kept in the object's space, and reprojection
  // puts it where the object's transform at the new time does (extrapolating a velocity would
  // carry the points of a turning or stopping object off it). kWorld for a world point: static
  // or deforming geometry (moved by `velocity`), or a miss's direction.
  static constexpr uint32_t kWorld = 0xffffffffu;
  uint32_t space[5] = {kWorld, kWorld, kWorld, kWorld, kWorld};

  bool has(uint8_t flag) const { return (flags & flag) != 0; }
  bool neighbor_hit(int k) const { return (flags & (kNeighborHit0 << k)) != 0; }
};

// The part of a crosshair that tile statistics read. The deep buffer keeps it apart from the
// rest, so that a pass over a block reads 32 bytes per crosshair, never across a cache line.
struct alignas(32) CrosshairStats {
  double time = 0.0;
  float luminance = 0.0f;
  float G_x = 0.0f, G_y = 0.0f, G_t = 0.0f;
  uint8_t flags = 0;  // Crosshair::Flags

  bool has(uint8_t flag) const { return (flags & flag) != 0; }
};

inline CrosshairStats stats_of(const Crosshair& c) {
  return CrosshairStats{c.time, c.luminance, c.G_x, c.G_y, c.G_t, c.flags};
}

// What a deep buffer keeps of a crosshair besides its statistics part. A field it does not keep
// reads back as its default (zero).
enum DeepBufferFields : uint32_t {
  // What reprojection reads: the image position, the center's and the neighbours' world
  // points and the neighbours' luminances (84 bytes).
  kKeepReprojection = 1u << 0,
  kKeepVelocity = 1u << 1,   // 12 bytes; zero in a scene where nothing moves
  kKeepOldSample = 1u << 2,  // old_time and old_luminance, 12 bytes; the sampler never reads them
  kKeepSpaces = 1u << 3,     // space, 20 bytes; kWorld in a scene where nothing moves rigidly
  kKeepAll = kKeepReprojection | kKeepVelocity | kKeepOldSample | kKeepSpaces,
};

class DeepBuffer {
 public:
  DeepBuffer(PixelRect region, int depth, uint32_t fields = kKeepAll);

  const PixelRect& region() const { return region_; }
  int depth() const { return depth_; }
  uint32_t fields() const { return fields_; }
  int64_t size() const { return size_; }  // crosshairs held
  int64_t capacity() const { return region_.area() * depth_; }
  // Bytes of the rest of a slot (what `fields` keeps), which pixels holding crosshairs take
  // depth times from a pool; every pixel takes depth x 32 + 2 (+ 4 when the rest is kept).
  size_t rest_bytes() const { return rest_stride_; }
  // Blocks of depth rests the pool has handed out: at most the most pixels ever holding
  // crosshairs at once.
  int64_t pooled_pixels() const { return int64_t(blocks_); }
  size_t bytes() const;

  int count(int32_t x, int32_t y) const { return queues_[index(x, y)].count; }
  // The k-th crosshair of pixel (x, y), k = 0 the newest, as a copy. k < count(x, y).
  Crosshair at(int32_t x, int32_t y, int k) const;
  // Its statistics part, and its image position, without assembling the whole crosshair.
  const CrosshairStats& stats(int32_t x, int32_t y, int k) const {
    return stats_[slot(index(x, y), k)];
  }
  glm::vec2 image_position(int32_t x, int32_t y, int k) const;

  // Inserts at the front (newest). When the queue was full, the oldest is evicted (its
  // statistics part into *evicted) and true is returned.
  bool push_front(int32_t x, int32_t y, const Crosshair& c, CrosshairStats* evicted);
  // Inserts at the back (oldest). When the queue was full, the previous oldest is evicted.
  bool push_back(int32_t x, int32_t y, const Crosshair& c, CrosshairStats* evicted);
  // Removes and returns the newest crosshair. count(x, y) > 0.
  Crosshair pop_front(int32_t x, int32_t y);

  // Copies the queues of the pixels of `rect` from `from` (a buffer of another region of the
  // same image, depth and fields) into this one, whose pixels there must be empty: every
  // crosshair stays in its pixel, in its order. `rect` lies inside both regions. What a region
  // handover keeps (Sampler::set_region).
  void copy_pixels(const DeepBuffer& from, const PixelRect& rect);

  // Calls f(const CrosshairStats&) for every crosshair of the pixels of `rect` (inside the
  // region), row by row, newest first within a pixel.
  template <typename F>
  void for_each_stats(const PixelRect& rect, F&& f) const {
    for (int32_t y = rect.y0; y < rect.y1; ++y) {
      size_t p = index(rect.x0, y);
      for (int32_t x = rect.x0; x < rect.x1; ++x, ++p) {
        const Queue q = queues_[p];
        const CrosshairStats* base = &stats_[p * size_t(depth_)];
        int s = q.head;
        for (int k = 0; k < q.count; ++k) {
          f(base[s]);
          if (++s == depth_) s = 0;
        }
      }
    }
  }

 private:
  // Per pixel: slot of the newest crosshair and how many there are.
  struct Queue {
    uint8_t head = 0;
    uint8_t count = 0;
  };

  size_t index(int32_t x, int32_t y) const {
    return size_t(y - region_.y0) * size_t(region_.width()) + size_t(x - region_.x0);
  }
  // The slot of pixel p of its k-th crosshair (k may reach the queue's depth - 1), and its
  // index in stats_.
  int slot_of(size_t p, int k) const {
    const int s = queues_[p].head + k;
    return s >= depth_ ? s - depth_ : s;
  }
  size_t slot(size_t p, int k) const { return p * size_t(depth_) + size_t(slot_of(p, k)); }
  // Writes slot s of pixel p, which has a block when the rest is kept.
  void store(size_t p, int s, const Crosshair& c);
  // The rest of slot s of pixel p, which has a block.
  const std::byte* rest(size_t p, int s) const {
    const uint32_t b = block_[p] - 1;
    return chunks_[b >> kChunkShift].get() +
           (size_t(b & kChunkMask) * size_t(depth_) + size_t(s)) * rest_stride_;
  }
  std::byte* rest(size_t p, int s) {
    return const_cast<std::byte*>(static_cast<const DeepBuffer*>(this)->rest(p, s));
  }
  // Gives pixel p a block (when the rest is kept and it has none), and takes it back.
  void acquire_block(size_t p);
  void release_block(size_t p);

  PixelRect region_;
  int depth_;
  uint32_t fields_;
  int64_t size_ = 0;
  // The rest of a slot, packed without padding: the fields that `fields_` keeps, at these
  // byte offsets (the image position first); -1 for one not kept.
  size_t rest_stride_ = 0;
  int velocity_at_ = -1, old_sample_at_ = -1, spaces_at_ = -1;
  // The statistics part of slot s of pixel p at p * depth + s, for every pixel.
  std::vector<CrosshairStats> stats_;
  std::vector<Queue> queues_;
  // The rest: a block of depth slots per pixel that holds crosshairs, from chunks of
  // kBlocksPerChunk blocks allocated as needed (never written before use, so never resident
  // before it). A pixel whose queue empties gives its block back.
  static constexpr int kChunkShift = 12;
  static constexpr uint32_t kBlocksPerChunk = 1u << kChunkShift, kChunkMask = kBlocksPerChunk - 1;
  std::vector<uint32_t> block_;  // per pixel: its block + 1, or 0 for none
  std::vector<std::unique_ptr<std::byte[]>> chunks_;
  std::vector<uint32_t> free_blocks_;
  uint32_t blocks_ = 0;  // blocks handed out from the chunks
};

}  // namespace afr
