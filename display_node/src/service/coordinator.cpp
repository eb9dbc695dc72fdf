#include <afr/display/service/coordinator.h>

#include <afr/common/check.h>
#include <afr/common/region_split.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace afr::service {

Coordinator::Coordinator(int width, int height, const CoordinatorOptions& options)
    : width_(width), height_(height), options_(options), next_id_(std::max(1u, options.first_id)) {
  (void)FailureDetector(options_.heartbeat_interval, options_.liveness);  // throws when invalid
}

Member& Coordinator::join(const std::string& peer, const std::string& name,
                          const std::string& public_key, int threads, uint64_t token, double now,
                          bool* is_new) {
  if (Member* m = find_peer(peer)) {
    m->liveness.heard(now);
    *is_new = false;
    return *m;
  }
  Member m;
  m.id = next_free_id();
  m.peer = peer;
  m.name = name;
  m.public_key = public_key;
  m.token = token;
  m.threads = std::max(1, threads);
  m.joined_at = now;
  m.region_since = now;
  m.last_sample_at = now;
  m.liveness = FailureDetector(options_.heartbeat_interval, options_.liveness);
  m.liveness.reset(now);
  *is_new = true;
  const uint32_t id = m.id;
  auto placed = members_.emplace(id, std::move(m));
  AFR_CHECK(placed.second);  // next_free_id() never gives a member's id
  return placed.first->second;
}

// Ids count up from 1 and wrap past the largest u32 to 1 (0 is kWallPeerSamplerId), skipping
// every id a member holds: a live id is never given twice, and no claim can push the counter.
uint32_t Coordinator::next_free_id() {
  AFR_CHECK(members_.size() < size_t(std::numeric_limits<uint32_t>::max()) - 1);
  for (;;) {
    const uint32_t id = next_id_;
    next_id_ = next_id_ == std::numeric_limits<uint32_t>::max() ? 1 : next_id_ + 1;
    if (id != protocol::kWallPeerSamplerId && !members_.count(id)) return id;
  }
}

Member* Coordinator::find(uint32_t id) {
  auto it = members_.find(id);
  return it == members_.end() ? nullptr : &it->second;
}

Member* Coordinator::find_peer(const std::string& peer) {
  for (auto& [id, m] : members_) {
    if (m.peer == peer) return &m;
  }
  return nullptr;
}

void Coordinator::heard(uint32_t id, double now) {
  if (Member* m = find(id)) m->liveness.heard(now);
}

void Coordinator::add_samples(uint32_t id, uint64_t samples, double now) {
  (void)now;  // measure() dates them: the service calls it in the same pass
  Member* m = find(id);
  if (!m || samples == 0) return;
  m->pending_ += samples;
  m->samples += samples;
}

bool Coordinator::remove(uint32_t id) {
  auto it = members_.find(id);
  if (it == members_.end()) return false;
  if (!it->second.region.empty()) dirty_ = true;
  members_.erase(it);
  return true;
}

std::vector<Member> Coordinator::expire(double now) {
  std::vector<Member> dead;
  for (auto it = members_.begin(); it != members_.end();) {
    if (it->second.liveness.suspect(now)) {
      dead.push_back(it->second);
      if (!it->second.region.empty()) dirty_ = true;
      it = members_.erase(it);
    } else {
      ++it;
    }
  }
  return dead;
}

// When a member's silence started to count: its last batch, or its first region when it never
// delivered;
// for one that delivered, not before its pool has had settle_seconds on its current region; and
// never before this display's last own stall ended.
double Coordinator::quiet_from(const Member& m) const {
  const double from = m.delivered
                          ? std::max(m.last_sample_at, m.region_since + options_.settle_seconds)
                          : m.assigned_at_;
  return std::max(from, watching_since_);
}

double Coordinator::patience(const Member& m) const {
  return std::clamp(kPatienceFactor * m.longest_gap_, options_.starve_seconds,
                    std::max(options_.starve_seconds, options_.starve_ceiling));
}

std::vector<std::pair<uint32_t, bool>> Coordinator::measure(double now) {
  std::vector<std::pair<uint32_t, bool>> changes;
  if (!measured_once_) {
    measured_once_ = true;
    last_measure_ = now;
    watching_since_ = now;
  }
  const double dt = now - last_measure_;
  if (dt < 0.0) return changes;
  last_measure_ = now;
  // A long gap is this display's own stall: what arrived meanwhile is no rate, and the members'
  // silence was not theirs. Their starvation clocks start again.
  const bool stalled = dt > options_.max_measure_gap;
  if (stalled) watching_since_ = now;
  const double alpha = 1.0 - std::exp(-dt / options_.rate_time_constant);
  const double forget = std::exp(-dt / kGapMemorySeconds);
  for (auto& [id, m] : members_) {
    const uint64_t n = m.pending_;
    m.pending_ = 0;
    m.longest_gap_ *= forget;
    if (n > 0) {
      // The silence this delivery ends, as far as it counted: the member's patience follows the
      // longest of the recent ones (a loaded machine's samplers deliver in bursts).
      if (m.delivered) m.longest_gap_ = std::max(m.longest_gap_, now - quiet_from(m));
      m.last_sample_at = now;
      m.delivered = true;
    }
    if (n > 0 && m.starved) {
      m.starved = false;
      changes.emplace_back(id, false);
      // A return recuts at once (a sampler that starved while it loaded the scene and built its
      // pool, or while its machine was busy) at most once per recut_interval; others wait for
      // the drift check, so that a member cannot buy recuts (every changed sampler's
      // handover) with a batch now and then.
      if (now - m.came_back_at_ >= options_.recut_interval) {
        dirty_ = true;
        m.came_back_at_ = now;
      }
    }
    // Not measured: across this display's stall, while the member waits for its first region,
    // while its pool hands over, and while it is starved (measured afresh from its return).
    if (stalled || dt <= 0.0 || m.region.empty() || m.starved ||
        now - m.region_since < options_.settle_seconds) {
      continue;
    }
    // Exponential smoothing of the arrival rate over time steps of any length, and its bias
    // (the weight the average has gathered, which is less than 1 while it is young).
    m.smoothed_ += alpha * (double(n) / dt - m.smoothed_);
    m.weight_ += alpha * (1.0 - m.weight_);
    m.measured_seconds += dt;
    m.rate = m.weight_ > 0.0 ? m.smoothed_ / m.weight_ : 0.0;
  }
  // Starvation: silence while others' batches flow, so that it is not the display's, the
  // network's or everyone's (all loading a scene).
  const auto flowing = [&](const Member& m) {
    return m.delivered && now - m.last_sample_at <= options_.max_measure_gap;
  };
  for (auto& [id, m] : members_) {
    // A member still waiting for its region has nothing to deliver yet.
    if (m.starved || m.region.empty() || now - quiet_from(m) < patience(m)) continue;
    const uint32_t self = id;
    const bool others = std::any_of(members_.begin(), members_.end(), [&](const auto& e) {
      return e.first != self && flowing(e.second);
    });
    if (!others) continue;
    m.starved = true;
    // What it delivered before says nothing about it now: measured afresh when it returns (until
    // then, and for measure_seconds after, the provisional share).
    m.smoothed_ = m.weight_ = m.rate = m.measured_seconds = 0.0;
    dirty_ = true;
    changes.emplace_back(id, true);
  }
  return changes;
}

bool Coordinator::measured(const Member& m) const {
  return !m.starved && m.measured_seconds >= options_.measure_seconds;
}

// Weights of the cut, by member: the measured rate; before a member is measured, the mean
// measured rate (an equal share when nobody is measured yet); a starved member kStarvedWeight
// of the others' mean. Nothing a sampler says about itself enters.
std::vector<double> Coordinator::shares() const {
  double measured_sum = 0.0;
  int measured_count = 0;
  for (const auto& [id, m] : members_) {
    if (measured(m) && m.rate > 0.0) {
      measured_sum += m.rate;
      ++measured_count;
    }
  }
  const bool any = measured_count > 0;
  const double provisional = any ? measured_sum / measured_count : 1.0;
  std::vector<double> s;
  double live_sum = 0.0;
  int live = 0;
  for (const auto& [id, m] : members_) {
    double w = 0.0;
    if (!m.starved) {
      w = any && measured(m) ? std::max(m.rate, kStarvedWeight * provisional) : provisional;
      live_sum += w;
      ++live;
    }
    s.push_back(w);
  }
  const double starved = live > 0 ? kStarvedWeight * live_sum / live : 1.0;
  for (double& w : s) {
    if (w == 0.0) w = starved;
  }
  return s;
}

void Coordinator::set_error(MassDensity density) {
  if (density.total() > 0.0) {
    error_ = std::move(density);
  } else {
    error_.reset();
  }
}

double Coordinator::fraction(const PixelRect& r) const {
  if (error_) return error_->mass(r) / error_->total();
  return double(r.area()) / (double(width_) * double(height_));
}

std::vector<PixelRect> Coordinator::parts(bool with_waiting) const {
  const std::vector<double> all = shares();
  std::vector<double> s;
  size_t i = 0;
  for (const auto& [id, m] : members_) {
    if (with_waiting || !m.region.empty()) s.push_back(all[i]);
    ++i;
  }
  if (s.empty()) return std::vector<PixelRect>(members_.size());
  const PixelRect image{0, 0, width_, height_};
  const std::vector<PixelRect> cut =
      error_ ? split_region(image, s, *error_) : split_region(image, s);
  if (s.size() == all.size()) return cut;
  std::vector<PixelRect> out;  // a waiting member keeps its empty region
  size_t k = 0;
  for (const auto& [id, m] : members_) out.push_back(m.region.empty() ? PixelRect{} : cut[k++]);
  return out;
}

bool Coordinator::same_regions(const std::vector<PixelRect>& parts) const {
  size_t i = 0;
  for (const auto& [id, m] : members_) {
    if (!(m.region == parts[i++])) return false;
  }
  return true;
}

void Coordinator::cut(double now, const std::vector<PixelRect>& parts) {
  size_t i = 0;
  for (auto& [id, m] : members_) {
    // A join cut in (a cut for a leave or a starvation leaves waiting members waiting, and does
    // not put their cut off).
    if (m.region.empty() && !parts[i].empty()) {
      m.assigned_at_ = now;
      last_join_cut_ = now;
    }
    if (!(m.region == parts[i])) m.region_since = now;
    m.region = parts[i++];
  }
  ++epoch_;
  ++recuts_;
  last_cut_ = now;
  dirty_ = false;
  drift_loads_ = {0.0, 0.0};
}

bool Coordinator::maybe_recut(double now) {
  (void)measure(now);
  if (members_.empty()) {
    dirty_ = false;
    return false;
  }
  // Joins are cut in once their interval is up, when their peers are still members (a peer that
  // left before its cut leaves nothing to do, not even a cut on shares that drifted meanwhile),
  // and without waiting for it when no member has a region (the image has no sampler); either
  // way once the first of them has waited join_gather for others.
  double first_waiting = std::numeric_limits<double>::infinity();
  bool all_waiting = true;
  for (const auto& [id, m] : members_) {
    if (m.region.empty()) {
      first_waiting = std::min(first_waiting, m.joined_at);
    } else {
      all_waiting = false;
    }
  }
  const bool joins_due = now - first_waiting >= options_.join_gather &&
                         (now - last_join_cut_ >= options_.join_interval || all_waiting);
  if (dirty_ || joins_due) {
    // A cut for anything else leaves the joins waiting (else a peer's leave would cut in its
    // next join at once). A change that moves no region (a member on a strip starving again)
    // sends nothing.
    const std::vector<PixelRect> next = parts(joins_due);
    if (same_regions(next)) {
      dirty_ = false;
      return false;
    }
    cut(now, next);
    return true;
  }
  if (now - last_cut_ < options_.recut_interval) return false;
  // A sampler that just got a new region hands its pool over (tiling rebuilt, gained pixels
  // filled): its rate and its tiles' error say little until it settles. Recutting on them would
  // chase the handover (measured: regions
  // swinging between 17% and 73% every second).
  // Nor while a join waits for its region (it comes with the next join cut).
  for (const auto& [id, m] : members_) {
    if (m.region.empty() || now - m.region_since < options_.settle_seconds) return false;
  }
  // The gain a recut would bring: the image's error is covered when the most loaded member
  // is done, so what counts is the largest ratio of a member's part to its share of the
  // throughput. A recut costs every member whose region changes a handover; it is worth
  // that only when that member carries more than (1 + hysteresis) times its share. An
  // underloaded member alone is no reason (with two members at 9% against 20% wanted, the
  // other carries 91% against 80%: 14% slower than balanced).
  const std::vector<double> s = shares();
  std::vector<PixelRect> current;
  for (const auto& [id, m] : members_) current.push_back(m.region);
  const double before = worst_load(current, s);
  if (!(before > 1.0 + options_.hysteresis)) return false;
  // A member slower than a strip's worth keeps its strip: when the cut would give the regions
  // they have, there is nothing to send (and nothing to look at again for an interval). Nor
  // when the cut would not lower the worst load by min_gain: error it cannot share out.
  const std::vector<PixelRect> next = parts(joins_due);
  const double after = worst_load(next, s);
  if (same_regions(next) || !(after * (1.0 + options_.min_gain) < before)) {
    last_cut_ = now;
    return false;
  }
  cut(now, next);
  drift_loads_ = {before, after};
  return true;
}

double Coordinator::worst_load(const std::vector<PixelRect>& parts,
                               const std::vector<double>& s) const {
  double total = 0.0;
  for (double x : s) total += x;
  double worst = 0.0;
  size_t i = 0;
  for (const auto& [id, m] : members_) {
    const size_t k = i++;
    // A starved member's strip is the least a cut gives, not a share it carries.
    if (m.starved) continue;
    const double want = s[k] / total;
    if (!(want > 0.0)) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, fraction(parts[k]) / want);
  }
  return worst;
}

}  // namespace afr::service
