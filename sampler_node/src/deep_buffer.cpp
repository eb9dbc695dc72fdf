#include <afr/sampler/deep_buffer.h>

#include <afr/common/check.h>

namespace afr {

DeepBuffer::DeepBuffer(PixelRect region, int depth) : region_(region), depth_(depth) {
  AFR_CHECK(!region.empty() && depth >= 1 && depth <= 255);
  const size_t pixels = size_t(region.area());
  slots_.resize(pixels * size_t(depth));
  head_.assign(pixels, 0);
  count_.assign(pixels, 0);
}

bool DeepBuffer::push_front(int32_t x, int32_t y, const Crosshair& c, Crosshair* evicted) {
  const size_t p = index(x, y);
  const uint8_t head = uint8_t((head_[p] + depth_ - 1) % depth_);
  Crosshair& slot = slots_[p * depth_ + head];
  const bool full = count_[p] == depth_;
  // When full, the new front slot is the old back: the oldest is evicted.
  if (full) {
    if (evicted) *evicted = slot;
  } else {
    ++count_[p];
    ++size_;
  }
  slot = c;
  head_[p] = head;
  return full;
}

bool DeepBuffer::push_back(int32_t x, int32_t y, const Crosshair& c, Crosshair* evicted) {
  const size_t p = index(x, y);
  const bool full = count_[p] == depth_;
  if (full) {
    Crosshair& back = slots_[p * depth_ + (head_[p] + depth_ - 1) % depth_];
    if (evicted) *evicted = back;
    back = c;
  } else {
    slots_[p * depth_ + (head_[p] + count_[p]) % depth_] = c;
    ++count_[p];
    ++size_;
  }
  return full;
}

Crosshair DeepBuffer::pop_front(int32_t x, int32_t y) {
  const size_t p = index(x, y);
  AFR_CHECK(count_[p] > 0);
  const Crosshair c = slots_[p * depth_ + head_[p]];
  head_[p] = uint8_t((head_[p] + 1) % depth_);
  --count_[p];
  --size_;
  return c;
}

}  // namespace afr
