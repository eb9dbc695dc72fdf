#include <afr/sampler/deep_buffer.h>

#include <afr/common/check.h>

namespace afr {

DeepBuffer::DeepBuffer(PixelRect region, int depth) : region_(region), depth_(depth) {
  AFR_CHECK(!region.empty() && depth >= 1 && depth <= 255);
  const size_t pixels = size_t(region.area());
  stats_.resize(pixels * size_t(depth));
  rest_.resize(pixels * size_t(depth));
  queues_.resize(pixels);
}

void DeepBuffer::store(size_t i, const Crosshair& c) {
  stats_[i] = stats_of(c);
  Rest& r = rest_[i];
  r.old_time = c.old_time;
  r.position = c.position;
  r.velocity = c.velocity;
  for (int k = 0; k < 4; ++k) {
    r.neighbor_position[k] = c.neighbor_position[k];
    r.neighbor_luminance[k] = c.neighbor_luminance[k];
  }
  r.x = c.x;
  r.y = c.y;
  r.old_luminance = c.old_luminance;
}

Crosshair DeepBuffer::at(int32_t x, int32_t y, int k) const {
  const size_t i = slot(index(x, y), k);
  const CrosshairStats& s = stats_[i];
  const Rest& r = rest_[i];
  Crosshair c;
  c.time = s.time;
  c.old_time = r.old_time;
  c.position = r.position;
  c.velocity = r.velocity;
  for (int n = 0; n < 4; ++n) {
    c.neighbor_position[n] = r.neighbor_position[n];
    c.neighbor_luminance[n] = r.neighbor_luminance[n];
  }
  c.x = r.x;
  c.y = r.y;
  c.luminance = s.luminance;
  c.old_luminance = r.old_luminance;
  c.G_x = s.G_x;
  c.G_y = s.G_y;
  c.G_t = s.G_t;
  c.flags = s.flags;
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
    ++q.count;
    ++size_;
  }
  store(i, c);
  q.head = uint8_t(head);
  return full;
}

bool DeepBuffer::push_back(int32_t x, int32_t y, const Crosshair& c, CrosshairStats* evicted) {
  const size_t p = index(x, y);
  Queue& q = queues_[p];
  const bool full = q.count == depth_;
  if (full) {
    const size_t i = slot(p, depth_ - 1);
    if (evicted) *evicted = stats_[i];
    store(i, c);
  } else {
    store(slot(p, q.count), c);
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
  return c;
}

}  // namespace afr
