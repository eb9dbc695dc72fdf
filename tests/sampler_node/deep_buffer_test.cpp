#include <afr/sampler/deep_buffer.h>

#include <gtest/gtest.h>

#include <deque>
#include <vector>

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
    CrosshairStats evicted;
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

TEST(DeepBufferTest, KeepsEveryFieldOfACrosshair) {
  // The buffer stores a crosshair in two parts; each field must come back as it went in.
  DeepBuffer buffer(PixelRect{0, 0, 2, 1}, 2);
  Crosshair c;
  c.time = 12.5;
  c.old_time = 11.25;
  c.position = {1, 2, 3};
  c.velocity = {4, 5, 6};
  for (int k = 0; k < 4; ++k) {
    c.neighbor_position[k] = glm::vec3(7 + k, 8 + k, 9 + k);
    c.neighbor_luminance[k] = 0.1f * float(k + 1);
  }
  c.x = 1.25f;
  c.y = 0.75f;
  c.luminance = 0.5f;
  c.old_luminance = 0.25f;
  c.G_x = 1.5f;
  c.G_y = 2.5f;
  c.G_t = 3.5f;
  c.flags = Crosshair::kCenterHit | Crosshair::kOccluded;
  const auto same = [&](const Crosshair& d) {
    EXPECT_EQ(d.time, c.time);
    EXPECT_EQ(d.old_time, c.old_time);
    EXPECT_EQ(d.position, c.position);
    EXPECT_EQ(d.velocity, c.velocity);
    for (int k = 0; k < 4; ++k) {
      EXPECT_EQ(d.neighbor_position[k], c.neighbor_position[k]);
      EXPECT_EQ(d.neighbor_luminance[k], c.neighbor_luminance[k]);
    }
    EXPECT_EQ(d.x, c.x);
    EXPECT_EQ(d.y, c.y);
    EXPECT_EQ(d.luminance, c.luminance);
    EXPECT_EQ(d.old_luminance, c.old_luminance);
    EXPECT_EQ(d.G_x, c.G_x);
    EXPECT_EQ(d.G_y, c.G_y);
    EXPECT_EQ(d.G_t, c.G_t);
    EXPECT_EQ(d.flags, c.flags);
  };
  buffer.push_back(1, 0, tagged(1.0), nullptr);
  buffer.push_front(1, 0, c, nullptr);
  same(buffer.at(1, 0, 0));
  EXPECT_EQ(buffer.stats(1, 0, 0).G_t, c.G_t);
  EXPECT_EQ(buffer.image_position(1, 0, 0), glm::vec2(c.x, c.y));
  same(buffer.pop_front(1, 0));
  buffer.push_back(1, 0, c, nullptr);
  same(buffer.at(1, 0, 1));
  // Visiting a block's statistics sees every crosshair once, newest first in a pixel.
  std::vector<double> times;
  buffer.for_each_stats(buffer.region(), [&](const CrosshairStats& s) { times.push_back(s.time); });
  EXPECT_EQ(times, (std::vector<double>{1.0, 12.5}));
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
