#include <afr/sampler/deep_buffer.h>

#include <gtest/gtest.h>

#include <deque>

namespace afr {
namespace {

Crosshair tagged(double time) {
  Crosshair c;
  c.time = time;
  return c;
}

TEST(DeepBufferTest, BehavesLikeBoundedDequesPerPixel) {
  const PixelRect region{4, 4, 7, 6};
  DeepBuffer buffer(region, 3);
  std::deque<double> model[6];
  int64_t size = 0;
  double next = 0.0;
  for (int op = 0; op < 2000; ++op) {
    const int32_t x = 4 + op % 3, y = 4 + (op / 3) % 2;
    std::deque<double>& q = model[(y - 4) * 3 + (x - 4)];
    const int kind = (op * 7919) % 5;
    Crosshair evicted;
    if (kind < 2) {
      const bool full = q.size() == 3;
      const double back = full ? q.back() : -1.0;
      EXPECT_EQ(buffer.push_front(x, y, tagged(next), &evicted), full);
      if (full) {
        EXPECT_EQ(evicted.time, back);
        q.pop_back();
      } else {
        ++size;
      }
      q.push_front(next);
    } else if (kind < 4) {
      const bool full = q.size() == 3;
      const double back = full ? q.back() : -1.0;
      EXPECT_EQ(buffer.push_back(x, y, tagged(next), &evicted), full);
      if (full) {
        EXPECT_EQ(evicted.time, back);
        q.pop_back();
      } else {
        ++size;
      }
      q.push_back(next);
    } else if (!q.empty()) {
      EXPECT_EQ(buffer.pop_front(x, y).time, q.front());
      q.pop_front();
      --size;
    }
    next += 1.0;
    ASSERT_EQ(buffer.count(x, y), int(q.size()));
    for (int k = 0; k < int(q.size()); ++k) ASSERT_EQ(buffer.at(x, y, k).time, q[k]);
    ASSERT_EQ(buffer.size(), size);
  }
}

TEST(DeepBufferTest, MemoryFollowsTheOwnedRegion) {
  // A small region of a huge image: capacity is the region's, addresses are absolute.
  DeepBuffer buffer(PixelRect{32000, 32000, 32010, 32004}, 4);
  EXPECT_EQ(buffer.capacity(), 160);
  buffer.push_front(32009, 32003, tagged(1.0), nullptr);
  EXPECT_EQ(buffer.count(32009, 32003), 1);
}

}  // namespace
}  // namespace afr
