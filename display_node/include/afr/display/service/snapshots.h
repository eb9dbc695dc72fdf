// Snapshots of one moment (docs/wall.md, "Snapshots"): requests to write this node's image of a
// given display time, taken by the frame loop once the clock has reached that time. The lead
// display makes them (POST /snapshot) and sends them to its followers (snapshot_request); each
// node holds its own pending ones here.
//
// Thread-safe: the control thread (or the HTTP thread) adds, the frame loop takes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>

namespace afr::service {

struct Snapshot {
  uint64_t id = 0;
  double time = 0.0;  // display time of the image
};

class SnapshotQueue {
 public:
  // Requests beyond this many pending are refused (request returns false): a peer cannot grow
  // the queue, and a display that cannot keep up says so.
  static constexpr size_t kMaxPending = 16;

  // Adds a request; a repeated id is ignored (true: it is pending already).
  bool request(const Snapshot& s) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Snapshot& p : pending_) {
      if (p.id == s.id) return true;
    }
    if (pending_.size() >= kMaxPending) return false;
    pending_.push_back(s);
    return true;
  }

  // The earliest pending snapshot whose time has come (time <= now), removed; nullopt if none.
  std::optional<Snapshot> take_due(double now) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto best = pending_.end();
    for (auto it = pending_.begin(); it != pending_.end(); ++it) {
      if (it->time <= now && (best == pending_.end() || it->time < best->time)) best = it;
    }
    if (best == pending_.end()) return std::nullopt;
    const Snapshot s = *best;
    pending_.erase(best);
    return s;
  }

  size_t pending() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return pending_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::deque<Snapshot> pending_;
};

}  // namespace afr::service
