#include <afr/sampler/deep_buffer.h>

#include <gtest/gtest.h>

#include <algorithm>
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
  for (int k = 0; k < 5; ++k) c.space[k] = k == 2 ? Crosshair::kWorld : uint32_t(40 + k);
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
    for (int k = 0; k < 5; ++k) EXPECT_EQ(d.space[k], c.space[k]);
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

// A crosshair whose every field says which it is: time t, the rest derived from t.
Crosshair full_crosshair(double t) {
  Crosshair c;
  c.time = t;
  c.old_time = t - 0.5;
  const float f = float(t);
  c.position = {f, f + 1, f + 2};
  c.velocity = {-f, f, 2 * f};
  for (int k = 0; k < 4; ++k) {
    c.neighbor_position[k] = glm::vec3(f + k, f - k, f * k);
    c.neighbor_luminance[k] = f + 0.25f * float(k);
  }
  c.x = f + 0.5f;
  c.y = f + 0.75f;
  c.luminance = 2 * f;
  c.old_luminance = 3 * f;
  c.G_x = f + 0.125f;
  for (int k = 0; k < 5; ++k) c.space[k] = uint32_t(t) + uint32_t(k);
  return c;
}

TEST(DeepBufferTest, PixelsTakeTheRestOfCrosshairsOnlyWhileTheyHoldSome) {
  // Crosshairs come and go in a few pixels of a large region. Every field that is kept comes
  // back as it went in, those not kept come back zero, and the pool holds no more blocks than
  // the most pixels that held crosshairs at once (a pixel that empties gives its block back).
  for (uint32_t fields : {uint32_t(kKeepAll), uint32_t(kKeepReprojection), 0u}) {
    SCOPED_TRACE(fields);
    const PixelRect region{0, 0, 1000, 1000};
    DeepBuffer buffer(region, 2, fields);
    std::deque<double> model[8];
    int64_t busy = 0, most_busy = 0;
    double next = 1.0;
    for (int op = 0; op < 4000; ++op) {
      const int pixel = (op * 5) % 8;
      const int32_t x = 100 * pixel + 7, y = 999 - pixel;
      std::deque<double>& q = model[pixel];
      if ((op * 7919) % 3 != 0) {
        if (q.empty()) most_busy = std::max(most_busy, ++busy);
        buffer.push_front(x, y, full_crosshair(next), nullptr);
        if (q.size() == 2) q.pop_back();
        q.push_front(next);
        next += 1.0;
      } else if (!q.empty()) {
        const Crosshair c = buffer.pop_front(x, y);
        const Crosshair want = full_crosshair(q.front());
        q.pop_front();
        if (q.empty()) --busy;
        EXPECT_EQ(c.time, want.time);
        EXPECT_EQ(c.G_x, want.G_x);
        const bool reprojection = (fields & kKeepReprojection) != 0;
        EXPECT_EQ(c.position, reprojection ? want.position : glm::vec3(0.0f));
        EXPECT_EQ(c.neighbor_position[3], reprojection ? want.neighbor_position[3] : glm::vec3(0));
        EXPECT_EQ(c.neighbor_luminance[2], reprojection ? want.neighbor_luminance[2] : 0.0f);
        EXPECT_EQ(c.x, reprojection ? want.x : 0.0f);
        EXPECT_EQ(c.velocity, (fields & kKeepVelocity) ? want.velocity : glm::vec3(0.0f));
        EXPECT_EQ(c.old_time, (fields & kKeepOldSample) ? want.old_time : 0.0);
        EXPECT_EQ(c.old_luminance, (fields & kKeepOldSample) ? want.old_luminance : 0.0f);
        EXPECT_EQ(c.space[4], (fields & kKeepSpaces) ? want.space[4] : Crosshair::kWorld);
      }
      for (int k = 0; k < int(q.size()); ++k) {
        ASSERT_EQ(buffer.at(x, y, k).time, q[size_t(k)]);
      }
    }
    ASSERT_GE(most_busy, 4);
    EXPECT_LE(buffer.pooled_pixels(), fields == 0 ? 0 : most_busy);
    // A million pixels: the statistics part of every slot, the rest for a few pixels only.
    const size_t dense = size_t(region.area()) *
                         (2 * sizeof(CrosshairStats) + 2 + (fields == 0 ? 0 : sizeof(uint32_t)));
    EXPECT_LE(buffer.bytes(), dense + 4096 * 2 * buffer.rest_bytes() + 1024);
  }
}

}  // namespace
}  // namespace afr
