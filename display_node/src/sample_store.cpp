#include <afr/display/sample_store.h>

#include <afr/common/check.h>
#include <afr/common/error.h>

#include "parallel_copy.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace afr {

namespace {

bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

Sample restored_sample(const StoredSample& s) {
  Sample out;
  out.time = s.time;
  out.x = s.x;
  out.y = s.y;
  out.color = s.color;
  out.position = s.position;
  out.velocity = s.velocity;
  out.miss = (s.flags & kStoredMiss) != 0;
  return out;
}

uint32_t stored_fields(const StoredSample& s) {
  if (!(s.flags & kStoredHasPosition)) return 0;
  return kFieldPosition | ((s.flags & kStoredHasVelocity) ? kFieldVelocity : 0u);
}

bool sanitize_sample(const Sample& in, uint32_t fields, uint32_t sampler_id, StoredSample* out,
                     IngestStats* stats) {
  if (!std::isfinite(in.time)) {
    ++stats->bad_time;
    return false;
  }
  if (!(std::abs(in.x) <= kMaxImageCoordinate) || !(std::abs(in.y) <= kMaxImageCoordinate)) {
    ++stats->bad_image_position;
    return false;
  }
  if (!finite3(in.color)) {
    ++stats->bad_color;
    return false;
  }
  StoredSample s;
  s.time = in.time;
  s.x = in.x;
  s.y = in.y;
  s.sampler_id = sampler_id;
  s.color = glm::clamp(in.color, glm::vec3(0.0f), glm::vec3(kMaxColor));
  if (s.color != in.color) ++stats->clamped_color;
  if (fields & kFieldPosition) {
    if (!finite3(in.position)) {
      ++stats->bad_world;
      return false;
    }
    s.position = in.position;
    s.flags |= kStoredHasPosition;
    if (in.miss) {
      const float len = glm::length(in.position);
      if (!(len > 0.0f) || !std::isfinite(len)) {
        ++stats->bad_world;
        return false;
      }
      s.position = in.position / len;
      s.flags |= kStoredMiss;
    } else if (fields & kFieldVelocity) {
      if (!finite3(in.velocity)) {
        ++stats->bad_world;
        return false;
      }
      s.velocity = in.velocity;
      s.flags |= kStoredHasVelocity;
    }
  }
  *out = s;
  return true;
}

int ring_runs(uint64_t first, uint64_t end, size_t capacity, RingRun runs[2]) {
  if (end <= first) return 0;
  const uint64_t count = end - first;
  AFR_CHECK(count <= capacity);
  const size_t slot = size_t(first % capacity);
  const size_t head = std::min<size_t>(size_t(count), capacity - slot);
  runs[0] = RingRun{slot, 0, head};
  if (head == count) return 1;
  runs[1] = RingRun{0, head, size_t(count) - head};
  return 2;
}

SampleStore::SampleStore(size_t capacity) : capacity_(capacity) {
  if (capacity == 0) throw Error("sample store: capacity must be at least 1");
  ring_.resize(capacity);
}

size_t SampleStore::append(const SampleBatch& batch) {
  // Sanitise outside the lock into a per-thread buffer (reused: no allocation per batch once
  // it has grown), then hold the lock only for the copy.
  thread_local std::vector<StoredSample> staging;
  staging.clear();
  staging.reserve(batch.samples.size());
  IngestStats counted;
  for (const Sample& in : batch.samples) {
    StoredSample s;
    if (sanitize_sample(in, batch.fields, batch.sampler_id, &s, &counted)) staging.push_back(s);
  }
  counted.accepted = staging.size();
  // Of a batch larger than the ring only the newest `capacity` samples are written; the
  // others still take their sequence numbers (accepted, then overwritten at once).
  const size_t skip = staging.size() > capacity_ ? staging.size() - capacity_ : 0;

  std::lock_guard<std::mutex> lock(mutex_);
  RingRun runs[2];
  const int k = ring_runs(end_ + skip, end_ + staging.size(), capacity_, runs);
  for (int r = 0; r < k; ++r) {
    std::memcpy(&ring_[runs[r].slot], &staging[skip + runs[r].offset],
                runs[r].count * sizeof(StoredSample));
  }
  end_ += staging.size();
  stats_.batches += 1;
  stats_.accepted += counted.accepted;
  stats_.bad_time += counted.bad_time;
  stats_.bad_image_position += counted.bad_image_position;
  stats_.bad_color += counted.bad_color;
  stats_.bad_world += counted.bad_world;
  stats_.clamped_color += counted.clamped_color;
  return staging.size();
}

SampleStore::Delta SampleStore::copy_since(uint64_t since, std::vector<StoredSample>* out) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Delta d;
  d.end = end_;
  d.stored = size_t(std::min<uint64_t>(end_, capacity_));
  const uint64_t oldest = end_ - d.stored;
  d.first = std::clamp(since, oldest, end_);
  if (d.stored > 0) {
    d.oldest_time = ring_[size_t(oldest % capacity_)].time;
    d.newest_time = ring_[size_t((end_ - 1) % capacity_)].time;
  }
  out->resize(size_t(d.end - d.first));
  RingRun runs[2];
  const int k = ring_runs(d.first, d.end, capacity_, runs);
  for (int r = 0; r < k; ++r) {
    parallel_copy(out->data() + runs[r].offset, &ring_[runs[r].slot],
                  runs[r].count * sizeof(StoredSample));
  }
  return d;
}

uint64_t SampleStore::appended() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return end_;
}

IngestStats SampleStore::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace afr
