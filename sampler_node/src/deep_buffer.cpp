#include <afr/sampler/deep_buffer.h>

#include <afr/common/check.h>

#include <cstring>

namespace afr {

namespace {

// Byte offsets of the reprojection fields in a slot's rest.
constexpr size_t kImageAt = 0;               // float x, y
constexpr size_t kPositionAt = 8;            // vec3
constexpr size_t kNeighborLuminanceAt = 20;  // float[4]
constexpr size_t kNeighborPositionAt = 36;   // vec3[4]
constexpr size_t kReprojectionBytes = 84;
constexpr size_t kVelocityBytes = 12;
constexpr size_t kOldSampleBytes = 12;  // double old_time, float old_luminance

static_assert(sizeof(glm::vec3) == 12 && sizeof(glm::vec2) == 8);

template <typename T>
void put(std::byte* at, const T& v) {
  std::memcpy(at, &v, sizeof(T));
}
template <typename T>
void get(const std::byte* at, T* v) {
  std::memcpy(v, at, sizeof(T));
}

}  // namespace

DeepBuffer::DeepBuffer(PixelRect region, int depth, uint32_t fields)
    : region_(region), depth_(depth), fields_(fields & kKeepAll) {
  AFR_CHECK(!region.empty() && depth >= 1 && depth <= 255);
  if (fields_ & kKeepReprojection) rest_stride_ += kReprojectionBytes;
  if (fields_ & kKeepVelocity) {
    velocity_at_ = int(rest_stride_);
    rest_stride_ += kVelocityBytes;
  }
  if (fields_ & kKeepOldSample) {
    old_sample_at_ = int(rest_stride_);
    rest_stride_ += kOldSampleBytes;
  }
  if (fields_ & kKeepSpaces) {
    spaces_at_ = int(rest_stride_);
    rest_stride_ += sizeof(Crosshair::space);
  }
  const size_t pixels = size_t(region.area());
  AFR_CHECK(pixels < size_t(UINT32_MAX));
  stats_.resize(pixels * size_t(depth));
  queues_.resize(pixels);
  if (rest_stride_ > 0) block_.resize(pixels);
}

size_t DeepBuffer::bytes() const {
  return stats_.size() * sizeof(CrosshairStats) + queues_.size() * sizeof(Queue) +
         block_.size() * sizeof(uint32_t) + free_blocks_.capacity() * sizeof(uint32_t) +
         chunks_.size() * kBlocksPerChunk * size_t(depth_) * rest_stride_;
}

void DeepBuffer::acquire_block(size_t p) {
  if (rest_stride_ == 0 || block_[p] != 0) return;
  uint32_t b;
  if (!free_blocks_.empty()) {
    b = free_blocks_.back();
    free_blocks_.pop_back();
  } else {
    if ((blocks_ & kChunkMask) == 0) {
      // Not value-initialized: a slot is written before it is read.
      chunks_.emplace_back(new std::byte[kBlocksPerChunk * size_t(depth_) * rest_stride_]);
    }
    b = blocks_++;
  }
  block_[p] = b + 1;
}

void DeepBuffer::release_block(size_t p) {
  if (rest_stride_ == 0) return;
  free_blocks_.push_back(block_[p] - 1);
  block_[p] = 0;
}

void DeepBuffer::store(size_t p, int s, const Crosshair& c) {
  stats_[p * size_t(depth_) + size_t(s)] = stats_of(c);
  if (rest_stride_ == 0) return;
  std::byte* r = rest(p, s);
  if (fields_ & kKeepReprojection) {
    put(r + kImageAt, glm::vec2(c.x, c.y));
    put(r + kPositionAt, c.position);
    put(r + kNeighborLuminanceAt, c.neighbor_luminance);
    put(r + kNeighborPositionAt, c.neighbor_position);
  }
  if (velocity_at_ >= 0) put(r + velocity_at_, c.velocity);
  if (old_sample_at_ >= 0) {
    put(r + old_sample_at_, c.old_time);
    put(r + old_sample_at_ + sizeof(double), c.old_luminance);
  }
  if (spaces_at_ >= 0) put(r + spaces_at_, c.space);
}

glm::vec2 DeepBuffer::image_position(int32_t x, int32_t y, int k) const {
  glm::vec2 xy(0.0f);
  const size_t p = index(x, y);
  if (fields_ & kKeepReprojection) get(rest(p, slot_of(p, k)) + kImageAt, &xy);
  return xy;
}

Crosshair DeepBuffer::at(int32_t x, int32_t y, int k) const {
  const size_t p = index(x, y);
  const int slot_k = slot_of(p, k);
  const CrosshairStats& s = stats_[p * size_t(depth_) + size_t(slot_k)];
  Crosshair c;
  c.time = s.time;
  c.luminance = s.luminance;
  c.G_x = s.G_x;
  c.G_y = s.G_y;
  c.G_t = s.G_t;
  c.flags = s.flags;
  if (rest_stride_ == 0) return c;
  const std::byte* r = rest(p, slot_k);
  if (fields_ & kKeepReprojection) {
    glm::vec2 xy;
    get(r + kImageAt, &xy);
    c.x = xy.x;
    c.y = xy.y;
    get(r + kPositionAt, &c.position);
    get(r + kNeighborLuminanceAt, &c.neighbor_luminance);
    get(r + kNeighborPositionAt, &c.neighbor_position);
  }
  if (velocity_at_ >= 0) get(r + velocity_at_, &c.velocity);
  if (old_sample_at_ >= 0) {
    get(r + old_sample_at_, &c.old_time);
    get(r + old_sample_at_ + sizeof(double), &c.old_luminance);
  }
  if (spaces_at_ >= 0) get(r + spaces_at_, &c.space);
  return c;
}

bool DeepBuffer::push_front(int32_t x, int32_t y, const Crosshair& c, CrosshairStats* evicted) {
  const size_t p = index(x, y);
  Queue& q = queues_[p];
  const int head = q.head == 0 ? depth_ - 1 : q.head - 1;
  const size_t i = p * size_t(depth_) + size_t(head);
  const bool full = q.count == depth_;
  // When full, the new front slot is the old back: the oldest is evicted.
  if (full) {
    if (evicted) *evicted = stats_[i];
  } else {
    if (q.count == 0) acquire_block(p);
    ++q.count;
    ++size_;
  }
  store(p, head, c);
  q.head = uint8_t(head);
  return full;
}

bool DeepBuffer::push_back(int32_t x, int32_t y, const Crosshair& c, CrosshairStats* evicted) {
  const size_t p = index(x, y);
  Queue& q = queues_[p];
  const bool full = q.count == depth_;
  if (full) {
    const int back = slot_of(p, depth_ - 1);
    if (evicted) *evicted = stats_[p * size_t(depth_) + size_t(back)];
    store(p, back, c);
  } else {
    if (q.count == 0) acquire_block(p);
    store(p, slot_of(p, q.count), c);
    ++q.count;
    ++size_;
  }
  return full;
}

Crosshair DeepBuffer::pop_front(int32_t x, int32_t y) {
  const size_t p = index(x, y);
  Queue& q = queues_[p];
  AFR_CHECK(q.count > 0);
  const Crosshair c = at(x, y, 0);
  q.head = uint8_t(q.head + 1 == depth_ ? 0 : q.head + 1);
  --q.count;
  --size_;
  if (q.count == 0) release_block(p);
  return c;
}

void DeepBuffer::copy_pixels(const DeepBuffer& from, const PixelRect& rect) {
  if (rect.empty()) return;
  AFR_CHECK(from.depth_ == depth_ && from.fields_ == fields_);
  AFR_CHECK(intersect(rect, region_) == rect && intersect(rect, from.region_) == rect);
  for (int32_t y = rect.y0; y < rect.y1; ++y) {
    for (int32_t x = rect.x0; x < rect.x1; ++x) {
      AFR_CHECK(count(x, y) == 0);
      // Oldest first, each to the front: the newest ends up at the front again.
      for (int k = from.count(x, y) - 1; k >= 0; --k) push_front(x, y, from.at(x, y, k), nullptr);
    }
  }
}

}  // namespace afr
