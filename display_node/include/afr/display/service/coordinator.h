// The display's coordinator (DESIGN.md, "The closed loop", "Network"): who the samplers are
// (membership by join, heartbeats and leave; ids assigned here), and which part of the image
// each one samples. The image is cut into one region per sampler with split_region, each
// region's share of the image's error proportional to that sampler's throughput as the display
// measured it: the samples it accepted from that member per second (add_samples), never what a
// join or a stats message claims (docs/service.md, "Shares"). The error is what the samplers'
// tiling snapshots say, set with set_error(); before any, the area. The cut is redone at once
// when a member leaves, dies, stops delivering (starves) or first delivers after starving; when
// samplers join, at most once per join_interval, once the first join has waited join_gather for
// others (the joins meanwhile wait and are cut in together; without the interval when no member
// has a region); and at most once per recut_interval when a member's part of the error grows
// beyond its throughput share by more than the hysteresis. Plain logic, no I/O: the display service
// feeds it and sends what it decides.
//
// Order of calls, on one thread: join / heard / add_samples / remove / expire as messages and
// samples come; then, once per pass, measure() (rates and starvation) and maybe_recut().
#pragma once

#include <afr/common/failure_detector.h>
#include <afr/common/rect.h>
#include <afr/common/region_split.h>
#include <afr/protocol/messages.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace afr::service {

// A tile's part of the image's error, for the cut: its luminance variance times its area. The
// display shows luminance clamped to [0, 1], whose variance is at most 1/4; a sampler's
// variance comes from unclamped radiance, and one bright specular pixel's could be 1e5 times
// the rest of the image's together (measured on the built-in scene: a 1-pixel tile held 83-97%
// of a sampler's sum, and each cut moved the border by a pixel around it). So the variance is
// capped at what the display can show; a non-finite or negative one counts as none.
inline double shown_error_mass(float variance, const PixelRect& rect) {
  constexpr double kMaxShownVariance = 0.25;
  const double v = variance > 0.0f ? std::min(double(variance), kMaxShownVariance) : 0.0;
  return v * double(rect.area());
}

struct CoordinatorOptions {
  // When a silent sampler is dead (failure_detector.h): never before liveness.floor seconds
  // of silence, later when its messages have come irregularly, always after liveness.ceiling.
  FailureDetectorOptions liveness;
  // The samplers' and wall followers' heartbeat interval: the detector's first guess.
  double heartbeat_interval = protocol::kMemberHeartbeatInterval;
  // Seconds at least between recuts that follow throughput and error. A recut costs every
  // sampler whose region changed a handover (its tiling rebuilt, the pixels it gained filled),
  // which cost more image error than a better balance gains when pools still restarted: on the
  // built-in scene with two samplers the live error (bench/live.py) was 26.3 (25.5-27.2, 3 runs)
  // with recuts at most once a second and 21.0 (17.7-24.3) at most once in 10 s
  // (docs/benchmarks.md, "Live accuracy").
  double recut_interval = 10.0;
  // Seconds at least between recuts that joins make. A join waits for its region until then
  // (at once when no member has one);
  // the joins meanwhile come in with one cut, and a peer that leaves before its cut costs no
  // cut at all (a member that never had a region leaves none to cover). Without it, a peer that
  // joined and left in a loop recut every member twice a round trip, each recut a handover for
  // every sampler whose region moved. Samplers started together still join within one
  // interval's wait.
  double join_interval = 1.0;
  // A join also waits this long for others (samplers started together, or coming back after a
  // display restart, join within a few tens of milliseconds of each other): they come in with
  // one cut, instead of the first at once and the rest an interval later.
  double join_gather = 0.2;
  // Samplers admitted at once (display_node --max-samplers). A join beyond it is refused with
  // the reason: membership is state a peer could otherwise grow without end, and each member
  // costs a region, a heartbeat and per-sampler metrics.
  size_t max_members = 256;
  // A recut happens when a member's part of the error exceeds (1 + hysteresis) times its
  // share of the throughput ...
  double hysteresis = 0.5;
  // ... and the new cut lowers the largest such ratio by at least this fraction. Error that no
  // cut can share out (most of it in one narrow column) would otherwise move a border by a
  // pixel every recut_interval for no gain, each move a handover for both samplers
  // (CoordinatorTest.ErrorThatNoCutCanShareOutMovesNoBorder).
  double min_gain = 0.2;
  // For this long after a member's region changes its pool hands over: its rate is not measured
  // then, and no drift recut happens until every member's region is this old.
  double settle_seconds = 2.0;
  // The measured rate: samples accepted per second, smoothed exponentially with this time
  // constant (seconds).
  double rate_time_constant = 0.5;
  // A member's rate decides its share once measured for this long (settling excluded); until
  // then it gets the provisional share: the mean measured rate, or an equal share.
  double measure_seconds = 1.0;
  // A member from which nothing was accepted for this long while others delivered is starved:
  // the next cut leaves it a strip of the image (kStarvedWeight), which it keeps until it
  // delivers again. A member that has delivered before also gets settle_seconds after each
  // region change (its pool hands over); one that never delivered counts from its first region
  // (a join waits for its cut, join_interval, with nothing to sample). A member
  // whose deliveries came with long gaps (a loaded machine) gets kPatienceFactor times the
  // longest recent gap, up to starve_ceiling.
  double starve_seconds = 0.75;
  double starve_ceiling = 3.0;
  // measure() calls further apart than this are the display's own stall (its control thread
  // held up), not the members' silence: the starvation clocks restart and the interval is not
  // measured.
  double max_measure_gap = 0.25;
  // The first sampler id given; ids count up from it, wrap past the largest u32 to 1 and skip
  // any a member holds. (Tests start near the top to see the wrap.)
  uint32_t first_id = 1;
};

// A starved member's weight in the cut, relative to the mean weight of the others: enough for
// split_region to leave it a non-empty strip, so it can show that it samples again.
inline constexpr double kStarvedWeight = 1e-3;
// A member's patience before it starves: this times the longest gap between its deliveries,
// remembered with this time constant (seconds).
inline constexpr double kPatienceFactor = 1.5;
inline constexpr double kGapMemorySeconds = 30.0;

struct Member {
  uint32_t id = 0;
  std::string peer;        // control channel routing id
  std::string name;        // the sampler's name
  std::string public_key;  // CurveZMQ key, or empty
  uint64_t token = 0;      // what its batches and snapshots must carry (protocol Welcome::token)
  int threads = 1;         // as its join claimed: for logs only, never for its share
  double joined_at = 0.0;  // coordinator time (seconds)
  FailureDetector liveness{0.2};  // its messages' arrivals, in coordinator time
  PixelRect region;               // empty until its first cut (a join waits up to join_interval)
  double region_since = 0.0;
  // Measured by the display.
  uint64_t samples = 0;           // accepted since it joined
  double rate = 0.0;              // samples per second, smoothed; meaningful once measured()
  double measured_seconds = 0.0;  // how long the rate has been measured (settling excluded)
  double last_sample_at = 0.0;    // when samples were last accepted (joined_at before any)
  bool delivered = false;         // any sample accepted since it joined
  bool starved = false;

 private:
  friend class Coordinator;
  uint64_t pending_ = 0;          // accepted since the last measure()
  double smoothed_ = 0.0;         // the exponential average before bias correction
  double weight_ = 0.0;           // 1 - exp(-measured_seconds / time constant): its bias
  double longest_gap_ = 0.0;      // between deliveries (the silence that counted), fading
  double came_back_at_ = -1e300;  // its last return from starving that recut at once
  double assigned_at_ = 0.0;      // its first cut, when it got a region
};

class Coordinator {
 public:
  Coordinator(int width, int height, const CoordinatorOptions& options = {});

  // A join from `peer`. A peer that is already a member keeps its id and token (a repeated
  // join); any other gets a fresh id, never one a member holds (a sampler's proposed id is not
  // asked for: the display assigns them all), and `token`. A join never removes a member.
  // *is_new says whether membership changed.
  Member& join(const std::string& peer, const std::string& name, const std::string& public_key,
               int threads, uint64_t token, double now, bool* is_new);
  Member* find(uint32_t id);
  Member* find_peer(const std::string& peer);
  // Any message from a member.
  void heard(uint32_t id, double now);
  // Samples of member `id` that the display accepted (from its connection, with its token).
  void add_samples(uint32_t id, uint64_t samples, double now);
  // The image's error as the samplers' tilings last said it (an empty density: unknown).
  void set_error(MassDensity density);
  // A leave. Returns whether it was a member. A member that never had a region leaves nothing
  // to cover: no cut follows for it.
  bool remove(uint32_t id);
  // Removes and returns the members whose silence the failure detector suspects.
  std::vector<Member> expire(double now);

  // Folds the samples added since the last call into the members' rates and decides who is
  // starved. Returns the members whose starved state changed (id, starved now).
  std::vector<std::pair<uint32_t, bool>> measure(double now);
  // Recomputes the regions when membership or starvation changed since the last cut, or when
  // throughput drifted (see above). Returns true when regions changed: send them (epoch() is
  // new). Measures first.
  bool maybe_recut(double now);
  uint64_t epoch() const { return epoch_; }
  uint64_t recuts() const { return recuts_; }
  // For the last cut, when drift made it: the largest ratio of a member's part of the error
  // to its share of the throughput before and after it (for the log). {0, 0} when membership
  // or starvation made it.
  std::pair<double, double> drift_loads() const { return drift_loads_; }
  // Whether the member's share follows its measured rate (else it is provisional or starved).
  bool measured(const Member& m) const;
  // The silence after which the member starves (starve_seconds, more after long gaps).
  double patience(const Member& m) const;

  const std::map<uint32_t, Member>& members() const { return members_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  std::vector<double> shares() const;
  // The regions a cut by shares() gives, in the order of members_; members waiting for their
  // first region are cut in with_waiting, else they keep their empty one.
  std::vector<PixelRect> parts(bool with_waiting) const;
  bool same_regions(const std::vector<PixelRect>& parts) const;
  // The largest ratio of a member's part of the error under `parts` (in the order of
  // members_) to its share `s` of the throughput; starved members do not count, a member
  // with no share is infinitely loaded.
  double worst_load(const std::vector<PixelRect>& parts, const std::vector<double>& s) const;
  void cut(double now, const std::vector<PixelRect>& parts);
  // What part of the image `r` holds: of the error when it is known, else of the area.
  double fraction(const PixelRect& r) const;
  uint32_t next_free_id();
  double quiet_from(const Member& m) const;

  int width_, height_;
  CoordinatorOptions options_;
  std::map<uint32_t, Member> members_;  // by id: the order of the cut
  std::optional<MassDensity> error_;
  uint32_t next_id_ = 1;
  bool dirty_ = false;  // a cut is due at once
  double last_cut_ = -1e9;
  double last_join_cut_ = -1e300;  // the last cut that gave a member its first region
  double last_measure_ = 0.0;
  bool measured_once_ = false;
  double watching_since_ = 0.0;  // the end of the display's last own stall
  uint64_t epoch_ = 0;
  std::pair<double, double> drift_loads_{0.0, 0.0};
  uint64_t recuts_ = 0;
};

}  // namespace afr::service
