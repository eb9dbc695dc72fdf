// The display's coordinator (DESIGN.md, "The closed loop", "Network"): who the samplers are
// (membership by join, heartbeats and leave), and which part of the image each one samples.
// The image is cut into one region per sampler with split_region, each region's share of the
// image's error proportional to that sampler's measured throughput (DESIGN.md: the error is
// what the samplers' tiling snapshots say, set with set_error(); before any, the area); the
// cut is redone at once when a sampler joins, leaves or dies, and at most once per
// recut_interval when a member's part of the error grows beyond its throughput share by more
// than the hysteresis. Plain logic, no I/O: the display service feeds it and sends what it
// decides.
#pragma once

#include <afr/common/failure_detector.h>
#include <afr/common/rect.h>
#include <afr/common/region_split.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace afr::service {

struct CoordinatorOptions {
  // When a silent sampler is dead (failure_detector.h): never before liveness.floor seconds
  // of silence, later when its messages have come irregularly, always after liveness.ceiling.
  FailureDetectorOptions liveness;
  // The samplers' and wall followers' heartbeat interval: the detector's first guess.
  double heartbeat_interval = protocol::kMemberHeartbeatInterval;
  // Seconds at least between recuts that follow throughput and error. A recut restarts the
  // pool of every sampler whose region changed (its deep buffer and tiling refill), which costs
  // more image error than a better balance gains: on the built-in scene with two samplers the
  // live error (bench/live.py) was 26.3 (25.5-27.2, 3 runs) with recuts at most once a second
  // and 21.0 (17.7-24.3) at most once in 10 s (docs/benchmarks.md, "Live accuracy").
  double recut_interval = 10.0;
  // A recut happens when a member's part of the error exceeds (1 + hysteresis) times its
  // share of the throughput.
  double hysteresis = 0.5;
  // Throughput reports this soon after a region change are ignored (the pool restarts).
  double settle_seconds = 2.0;
};

struct Member {
  uint32_t id = 0;
  std::string peer;        // control channel routing id
  std::string name;        // the sampler's name
  std::string public_key;  // CurveZMQ key, or empty
  int threads = 1;
  double joined_at = 0.0;         // coordinator time (seconds)
  FailureDetector liveness{0.2};  // its messages' arrivals, in coordinator time
  double throughput = 0.0;        // samples per second, 0 until measured
  PixelRect region;
  double region_since = 0.0;
};

class Coordinator {
 public:
  Coordinator(int width, int height, const CoordinatorOptions& options = {});

  // A join from `peer`. A peer that is already a member keeps its id (a repeated join); a
  // requested id (a sampler that had one before a display restart) is honoured when free.
  // *is_new says whether membership changed.
  Member& join(const std::string& peer, uint32_t requested_id, const std::string& name,
               const std::string& public_key, int threads, double now, bool* is_new);
  Member* find(uint32_t id);
  Member* find_peer(const std::string& peer);
  // Any message from a member.
  void heard(uint32_t id, double now);
  void report_throughput(uint32_t id, double samples_per_second, double now);
  // The image's error as the samplers' tilings last said it (an empty density: unknown).
  void set_error(MassDensity density);
  // A leave. Returns whether it was a member.
  bool remove(uint32_t id);
  // Removes and returns the members whose silence the failure detector suspects.
  std::vector<Member> expire(double now);

  // Recomputes the regions when membership changed since the last cut, or when throughput
  // drifted (see above). Returns true when regions changed: send them (epoch() is new).
  bool maybe_recut(double now);
  uint64_t epoch() const { return epoch_; }
  uint64_t recuts() const { return recuts_; }

  const std::map<uint32_t, Member>& members() const { return members_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  std::vector<double> shares() const;
  void cut(double now);
  // What part of the image `r` holds: of the error when it is known, else of the area.
  double fraction(const PixelRect& r) const;

  int width_, height_;
  CoordinatorOptions options_;
  std::map<uint32_t, Member> members_;  // by id: the order of the cut
  std::optional<MassDensity> error_;
  uint32_t next_id_ = 1;
  bool dirty_ = false;
  double last_cut_ = -1e9;
  uint64_t epoch_ = 0;
  uint64_t recuts_ = 0;
};

}  // namespace afr::service
