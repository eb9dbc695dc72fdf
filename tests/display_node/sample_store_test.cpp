#include "support/numbers.h"

#include <afr/display/sample_store.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <limits>
#include <thread>

namespace afr {
namespace {

using afr::testing::kInf;
using afr::testing::kNaN;

// Batch of n samples whose x counts up from `first` (an identity to check order with).
SampleBatch numbered(int first, int n, uint32_t sampler = 0) {
  SampleBatch b;
  b.sampler_id = sampler;
  for (int i = 0; i < n; ++i) {
    Sample s;
    s.x = float(first + i);
    s.time = 0.001 * (first + i);
    s.color = glm::vec3(0.5f);
    b.samples.push_back(s);
  }
  return b;
}

TEST(SampleStoreTest, AStoredSampleRestoresToWhatWasSent) {
  // A hit with a velocity, a hit without, a miss and one without a world position: what a
  // display wall forwards as strays is what the sampler sent, with the same fields.
  const uint32_t field_sets[] = {kFieldPosition | kFieldVelocity, kFieldPosition, kFieldPosition,
                                 0u};
  for (int k = 0; k < 4; ++k) {
    Sample in;
    in.time = 12.5;
    in.x = 3.25f;
    in.y = 700.5f;
    in.color = glm::vec3(0.1f, 2.0f, 30.0f);
    if (field_sets[k] & kFieldPosition) {
      in.miss = k == 2;
      in.position = in.miss ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(1.0f, -2.0f, 3.0f);
    }
    if (field_sets[k] & kFieldVelocity) in.velocity = glm::vec3(0.5f, 0.0f, -0.25f);
    StoredSample stored;
    IngestStats stats;
    ASSERT_TRUE(sanitize_sample(in, field_sets[k], 7, &stored, &stats)) << k;
    EXPECT_EQ(stored_fields(stored), field_sets[k]) << k;
    const Sample out = restored_sample(stored);
    EXPECT_EQ(out.time, in.time);
    EXPECT_EQ(out.x, in.x);
    EXPECT_EQ(out.y, in.y);
    EXPECT_EQ(out.color, in.color);
    EXPECT_EQ(out.position, in.position) << k;
    EXPECT_EQ(out.velocity, in.velocity) << k;
    EXPECT_EQ(out.miss, in.miss) << k;
  }
}

TEST(SampleStoreTest, KeepsTheNewestNInAppendOrder) {
  SampleStore store(10);
  store.append(numbered(0, 3));
  store.append(numbered(3, 4));
  store.append(numbered(7, 7));
  std::vector<StoredSample> out;
  const SampleStore::Delta d = store.copy_since(0, &out);
  EXPECT_EQ(d.end, 14u);
  EXPECT_EQ(d.first, 4u);
  EXPECT_EQ(d.stored, 10u);
  ASSERT_EQ(out.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(out[size_t(i)].x, float(4 + i));
  EXPECT_DOUBLE_EQ(d.oldest_time, 0.004);
  EXPECT_DOUBLE_EQ(d.newest_time, 0.013);
}

TEST(SampleStoreTest, CopySinceGivesOnlyWhatIsNew) {
  SampleStore store(10);
  store.append(numbered(0, 6));
  std::vector<StoredSample> out;
  SampleStore::Delta d = store.copy_since(0, &out);
  EXPECT_EQ(out.size(), 6u);
  store.append(numbered(6, 2));
  d = store.copy_since(d.end, &out);
  EXPECT_EQ(d.first, 6u);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].x, 6.0f);
  d = store.copy_since(d.end, &out);
  EXPECT_TRUE(out.empty());
}

TEST(SampleStoreTest, ABatchLargerThanTheStoreKeepsItsNewest) {
  SampleStore store(5);
  store.append(numbered(0, 12));
  std::vector<StoredSample> out;
  const SampleStore::Delta d = store.copy_since(0, &out);
  ASSERT_EQ(out.size(), 5u);
  EXPECT_EQ(out.front().x, 7.0f);
  EXPECT_EQ(out.back().x, 11.0f);
  EXPECT_EQ(d.stored, 5u);
  EXPECT_EQ(d.first, 7u);  // the older seven were accepted and overwritten at once
  EXPECT_EQ(store.stats().accepted, 12u);
}

TEST(SampleStoreTest, RingRunsSplitAtTheEnd) {
  RingRun runs[2];
  ASSERT_EQ(ring_runs(8, 13, 10, runs), 2);
  EXPECT_EQ(runs[0].slot, 8u);
  EXPECT_EQ(runs[0].count, 2u);
  EXPECT_EQ(runs[1].slot, 0u);
  EXPECT_EQ(runs[1].offset, 2u);
  EXPECT_EQ(runs[1].count, 3u);
  ASSERT_EQ(ring_runs(20, 25, 10, runs), 1);
  EXPECT_EQ(runs[0].slot, 0u);
  EXPECT_EQ(ring_runs(4, 4, 10, runs), 0);
}

TEST(SampleStoreTest, AMirrorKeptWithRingRunsEqualsTheNewestSamples) {
  // Brute force: every accepted sample in a list; the mirror must hold the newest `capacity`
  // of them at slot sequence % capacity, after any pattern of appends and copies.
  const size_t capacity = 37;
  SampleStore store(capacity);
  std::vector<StoredSample> mirror(capacity), staging;
  std::vector<float> all;
  uint64_t seen = 0;
  Pcg32 rng(11);
  int next = 0;
  for (int round = 0; round < 300; ++round) {
    const int n = int(rng.next_below(60));
    store.append(numbered(next, n));
    for (int i = 0; i < n; ++i) all.push_back(float(next + i));
    next += n;
    if (rng.next_below(3) == 0) continue;  // sometimes several batches between copies
    const SampleStore::Delta d = store.copy_since(seen, &staging);
    RingRun runs[2];
    const int k = ring_runs(d.first, d.end, capacity, runs);
    for (int r = 0; r < k; ++r) {
      for (size_t i = 0; i < runs[r].count; ++i) {
        mirror[runs[r].slot + i] = staging[runs[r].offset + i];
      }
    }
    seen = d.end;
    ASSERT_EQ(d.end, all.size());
    for (uint64_t s = d.end - d.stored; s < d.end; ++s) {
      ASSERT_EQ(mirror[s % capacity].x, all[s]) << "sequence " << s;
    }
  }
}

TEST(SampleStoreTest, BadSamplesAreDroppedAndCountedByReason) {
  SampleStore store(100);
  SampleBatch b;
  b.fields = kFieldPosition | kFieldVelocity;
  auto add = [&](auto edit) {
    Sample s;
    s.color = glm::vec3(0.5f);
    s.position = glm::vec3(1.0f, 2.0f, 3.0f);
    edit(s);
    b.samples.push_back(s);
  };
  add([](Sample&) {});                                                  // good
  add([](Sample& s) { s.time = kNaN; });                                // bad time
  add([](Sample& s) { s.time = -double(kInf); });                       // bad time
  add([](Sample& s) { s.x = kInf; });                                   // bad image position
  add([](Sample& s) { s.y = 2e9f; });                                   // bad image position
  add([](Sample& s) { s.color.g = kNaN; });                             // bad color
  add([](Sample& s) { s.color.b = kInf; });                             // bad color
  add([](Sample& s) { s.position.x = kNaN; });                          // bad world
  add([](Sample& s) { s.velocity.z = kInf; });                          // bad world
  add([](Sample& s) { s.miss = true, s.position = glm::vec3(0.0f); });  // bad world
  add([](Sample& s) { s.color = glm::vec3(-1.0f, 1e6f, 0.5f); });       // clamped, kept
  add([](Sample& s) {                                                   // miss: normalised
    s.miss = true, s.position = glm::vec3(0.0f, 3.0f, 4.0f), s.velocity = glm::vec3(9.0f);
  });
  EXPECT_EQ(store.append(b), 3u);
  const IngestStats st = store.stats();
  EXPECT_EQ(st.accepted, 3u);
  EXPECT_EQ(st.bad_time, 2u);
  EXPECT_EQ(st.bad_image_position, 2u);
  EXPECT_EQ(st.bad_color, 2u);
  EXPECT_EQ(st.bad_world, 3u);
  EXPECT_EQ(st.clamped_color, 1u);
  EXPECT_EQ(st.rejected(), 9u);
  std::vector<StoredSample> out;
  store.copy_since(0, &out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].flags, uint32_t(kStoredHasPosition | kStoredHasVelocity));
  EXPECT_EQ(out[1].color, glm::vec3(0.0f, kMaxColor, 0.5f));
  EXPECT_EQ(out[2].flags, uint32_t(kStoredHasPosition | kStoredMiss));
  EXPECT_NEAR(out[2].position.y, 0.6f, 1e-6f);
  EXPECT_NEAR(out[2].position.z, 0.8f, 1e-6f);
  EXPECT_EQ(out[2].velocity, glm::vec3(0.0f));
}

TEST(SampleStoreTest, ConcurrentWritersAndAReaderLoseNothingAndKeepOrder) {
  // Two samplers append while a reconstructor copies; run under ThreadSanitizer this is the
  // store's race test. Every sample of each writer must be in the ring, in its own order.
  const size_t capacity = 50000;
  SampleStore store(capacity);
  const int batches = 400, per_batch = 50;
  auto writer = [&](uint32_t id) {
    for (int b = 0; b < batches; ++b) store.append(numbered(b * per_batch, per_batch, id));
  };
  std::thread a(writer, 1u), b(writer, 2u);
  std::vector<StoredSample> mirror(capacity), staging;
  uint64_t seen = 0;
  uint64_t copied = 0;
  auto copy = [&] {
    const SampleStore::Delta d = store.copy_since(seen, &staging);
    RingRun runs[2];
    const int k = ring_runs(d.first, d.end, capacity, runs);
    for (int r = 0; r < k; ++r) {
      std::copy_n(staging.begin() + ptrdiff_t(runs[r].offset), runs[r].count,
                  mirror.begin() + ptrdiff_t(runs[r].slot));
    }
    copied += staging.size();
    seen = d.end;
    return d;
  };
  while (store.appended() < uint64_t(2 * batches * per_batch)) copy();
  a.join();
  b.join();
  const SampleStore::Delta d = copy();
  EXPECT_EQ(d.end, uint64_t(2 * batches * per_batch));
  EXPECT_EQ(store.stats().accepted, d.end);
  EXPECT_EQ(store.stats().batches, uint64_t(2 * batches));
  EXPECT_EQ(copied, d.end);  // each sample copied exactly once
  float next[3] = {0.0f, 0.0f, 0.0f};
  for (uint64_t s = 0; s < d.end; ++s) {
    const StoredSample& x = mirror[s % capacity];
    ASSERT_TRUE(x.sampler_id == 1 || x.sampler_id == 2);
    ASSERT_EQ(x.x, next[x.sampler_id]);
    next[x.sampler_id] += 1.0f;
  }
  EXPECT_EQ(next[1], float(batches * per_batch));
  EXPECT_EQ(next[2], float(batches * per_batch));
}

}  // namespace
}  // namespace afr
