// The reconstructor's deep buffer (section 5.2): one temporally ordered ring of the N most
// recent samples from every sampler. Samplers' batches are appended on network or sampler
// threads while the reconstructor copies out what is new on its own thread; each side holds
// the lock only for a copy of the new samples.
#pragma once

#include <afr/common/samples.h>

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

namespace afr {

enum StoredSampleFlag : uint32_t {
  kStoredHasPosition = 1u << 0,  // `position` is valid (the batch carried kFieldPosition)
  kStoredMiss = 1u << 1,         // `position` is the ray direction (unit length)
  kStoredHasVelocity = 1u << 2,  // `velocity` is valid (never set for a miss)
};

// One sample as stored: sanitised, 64 bytes, and laid out as the OpenGL backend's vertex
// buffer reads it (the byte offsets are part of that contract).
struct StoredSample {
  double time = 0.0;  // display-clock seconds
  float x = 0.0f;     // sampling-image position, pixels
  float y = 0.0f;
  glm::vec3 color{0.0f};  // linear RGB, finite, in [0, kMaxColor]
  uint32_t flags = 0;     // StoredSampleFlag bits
  glm::vec3 position{0.0f};
  glm::vec3 velocity{0.0f};
  uint32_t sampler_id = 0;
  uint32_t reserved = 0;
};
static_assert(sizeof(StoredSample) == 64);

// Colors above this are clamped (it is the largest half float, the precision of the paper's
// GPU buffers); it keeps weighted sums of colors far from float overflow.
inline constexpr float kMaxColor = 65504.0f;
// Image positions beyond this magnitude are rejected as garbage.
inline constexpr float kMaxImageCoordinate = 1e9f;

// Samples rejected at the door, by reason, and colors clamped.
struct IngestStats {
  uint64_t batches = 0;
  uint64_t accepted = 0;
  uint64_t bad_time = 0;            // time NaN or infinite
  uint64_t bad_image_position = 0;  // x or y NaN, infinite or beyond kMaxImageCoordinate
  uint64_t bad_color = 0;           // a channel NaN or infinite
  uint64_t bad_world = 0;           // position, direction or velocity NaN or infinite
  uint64_t clamped_color = 0;       // a channel negative or above kMaxColor (kept, clamped)
  uint64_t rejected() const { return bad_time + bad_image_position + bad_color + bad_world; }
};

// Checks and converts one sample (what append() does to each). Returns false, counting the
// reason in `stats`, when the sample must be dropped.
bool sanitize_sample(const Sample& in, uint32_t fields, uint32_t sampler_id, StoredSample* out,
                     IngestStats* stats);
// The other way: a stored sample as a batch carries it (a display wall forwards strays so),
// and the batch fields it has (kFieldPosition, kFieldVelocity; 0 without a world position).
Sample restored_sample(const StoredSample& s);
uint32_t stored_fields(const StoredSample& s);

// A contiguous run of ring slots, for copying new samples to where they live in the ring.
struct RingRun {
  size_t slot = 0;    // first ring slot
  size_t offset = 0;  // index of its first sample in the copied range
  size_t count = 0;
};
// The sample with sequence number s lives in slot s % capacity. Splits [first, end) into at
// most two runs; returns how many.
int ring_runs(uint64_t first, uint64_t end, size_t capacity, RingRun runs[2]);

class SampleStore {
 public:
  // capacity: N, the number of samples kept (> 0).
  explicit SampleStore(size_t capacity);
  SampleStore(const SampleStore&) = delete;
  SampleStore& operator=(const SampleStore&) = delete;

  size_t capacity() const { return capacity_; }

  // Any thread. Sanitises the batch's samples (outside the lock), then copies the accepted
  // ones into the ring, overwriting the oldest. Returns how many were accepted.
  size_t append(const SampleBatch& batch);

  // What copy_since() copied.
  struct Delta {
    uint64_t first = 0;        // sequence number of the first copied sample
    uint64_t end = 0;          // sequence number after the last one: every sample ever accepted
    size_t stored = 0;         // samples in the ring now: min(end, capacity)
    double oldest_time = 0.0;  // time of the oldest-appended sample in the ring (if stored)
    double newest_time = 0.0;  // time of the newest-appended one
  };
  // Any thread (the reconstructor's). Replaces *out with the samples appended after sequence
  // number `since`, oldest first; when more than `capacity` arrived, only the newest
  // `capacity` (the older ones are gone). Copy them to slots with ring_runs(first, end).
  Delta copy_since(uint64_t since, std::vector<StoredSample>* out) const;

  // Every sample ever accepted.
  uint64_t appended() const;
  IngestStats stats() const;

 private:
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::vector<StoredSample> ring_;  // guarded by mutex_
  uint64_t end_ = 0;                // guarded by mutex_
  IngestStats stats_;               // guarded by mutex_
};

}  // namespace afr
