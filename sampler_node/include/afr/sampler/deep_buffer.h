// The sampler's temporally deep buffer (section 4): for every pixel of the owned region a
// queue of up to b crosshairs, newest at the front. Memory is proportional to the owned
// region, never to the whole image.
#pragma once

#include <afr/common/math.h>
#include <afr/sampler/tiling.h>

#include <cstdint>
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

  bool has(uint8_t flag) const { return (flags & flag) != 0; }
  bool neighbor_hit(int k) const { return (flags & (kNeighborHit0 << k)) != 0; }
};

class DeepBuffer {
 public:
  DeepBuffer(PixelRect region, int depth);

  const PixelRect& region() const { return region_; }
  int depth() const { return depth_; }
  int64_t size() const { return size_; }  // crosshairs held
  int64_t capacity() const { return region_.area() * depth_; }

  int count(int32_t x, int32_t y) const { return count_[index(x, y)]; }
  // The k-th crosshair of pixel (x, y), k = 0 the newest. k < count(x, y).
  const Crosshair& at(int32_t x, int32_t y, int k) const {
    const size_t p = index(x, y);
    return slots_[p * depth_ + (head_[p] + k) % depth_];
  }

  // Inserts at the front (newest). When the queue was full, the oldest is evicted into
  // *evicted and true is returned.
  bool push_front(int32_t x, int32_t y, const Crosshair& c, Crosshair* evicted);
  // Inserts at the back (oldest). When the queue was full, the previous oldest is evicted.
  bool push_back(int32_t x, int32_t y, const Crosshair& c, Crosshair* evicted);
  // Removes and returns the newest crosshair. count(x, y) > 0.
  Crosshair pop_front(int32_t x, int32_t y);

 private:
  size_t index(int32_t x, int32_t y) const {
    return size_t(y - region_.y0) * size_t(region_.width()) + size_t(x - region_.x0);
  }

  PixelRect region_;
  int depth_;
  int64_t size_ = 0;
  std::vector<Crosshair> slots_;  // pixel * depth + slot
  std::vector<uint8_t> head_;     // slot of the newest crosshair
  std::vector<uint8_t> count_;
};

}  // namespace afr
