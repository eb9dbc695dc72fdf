// Telling a dead peer from a busy one: a phi-accrual failure detector (Hayashibara, Defago,
// Yared and Katayama, SRDS 2004), as Cassandra and Akka use it. Every message from the peer is
// a sign of life; the detector remembers the intervals between them and says how unlikely the
// current silence would be for a live peer with that history:
//
//   phi(silence) = -log10 P(interval > silence),  intervals ~ Normal(mean, deviation)
//
// A peer is suspected once phi passes a threshold (8: one live peer in 10^8 would be that
// silent), but never before `floor` seconds of silence (a node stopped for a moment, or a
// steady history whose spread is tiny) and always after `ceiling` (a history made of long
// gaps must not keep a dead peer a member for ever). On an idle machine, with heartbeats every
// 0.2 s, that is about 0.76 s of silence; on a loaded one the intervals spread and the
// detector waits longer, up to the ceiling. Plain arithmetic on the times it is given: the
// caller owns the clock.
#pragma once

#include <cstddef>
#include <vector>

namespace afr {

struct FailureDetectorOptions {
  double floor = 0.75;         // seconds of silence never suspected
  double ceiling = 5.0;        // seconds of silence always suspected
  double threshold = 8.0;      // phi at which a peer is suspected
  double min_deviation = 0.1;  // seconds: the spread assumed at least
  size_t window = 64;          // intervals remembered (bounded per peer)

  // These defaults with the floor at `seconds` (a user's timeout flag) and the ceiling at
  // least as high.
  static FailureDetectorOptions with_floor(double seconds) {
    FailureDetectorOptions o;
    o.floor = seconds;
    o.ceiling = o.ceiling > seconds ? o.ceiling : seconds;
    return o;
  }
};

class FailureDetector {
 public:
  // `expected_interval`: the seconds between the peer's heartbeats, the history's first guess.
  explicit FailureDetector(double expected_interval, FailureDetectorOptions options = {});

  // A message from the peer arrived at `now` (seconds; any monotonic clock, never earlier
  // than the previous call's).
  void heard(double now);
  // The first arrival: starts the history's clock without adding an interval.
  void reset(double now);

  double last_heard() const { return last_; }
  double silence(double now) const { return now - last_; }
  // How suspicious the silence at `now` is (0: not at all; grows without bound).
  double phi(double now) const;
  // The silence after which the peer is suspected, given its history: clamped to
  // [floor, ceiling].
  double suspect_after() const;
  bool suspect(double now) const { return silence(now) > suspect_after(); }

  double mean() const { return sum_ / double(intervals_.size()); }
  double deviation() const;
  size_t intervals() const { return intervals_.size(); }
  const FailureDetectorOptions& options() const { return options_; }

 private:
  void add(double interval);

  FailureDetectorOptions options_;
  std::vector<double> intervals_;  // a ring of at most options_.window
  size_t next_ = 0;
  double sum_ = 0.0, sum_sq_ = 0.0;
  double last_ = 0.0;
  double z_ = 0.0;  // the standard normal's z at which phi reaches the threshold
};

}  // namespace afr
