#include <afr/display/service/coordinator.h>

#include <afr/common/region_split.h>

#include <algorithm>
#include <cmath>

namespace afr::service {

Coordinator::Coordinator(int width, int height, const CoordinatorOptions& options)
    : width_(width), height_(height), options_(options) {
  (void)FailureDetector(options_.heartbeat_interval, options_.liveness);  // throws when invalid
}

Member& Coordinator::join(const std::string& peer, uint32_t requested_id, const std::string& name,
                          const std::string& public_key, int threads, double now, bool* is_new) {
  if (Member* m = find_peer(peer)) {
    m->liveness.heard(now);
    *is_new = false;
    return *m;
  }
  uint32_t id = requested_id;
  if (id == 0 || members_.count(id)) id = next_id_;
  next_id_ = std::max(next_id_, id + 1);
  Member m;
  m.id = id;
  m.peer = peer;
  m.name = name;
  m.public_key = public_key;
  m.threads = std::max(1, threads);
  m.joined_at = now;
  m.liveness = FailureDetector(options_.heartbeat_interval, options_.liveness);
  m.liveness.reset(now);
  dirty_ = true;
  *is_new = true;
  return members_[id] = m;
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

void Coordinator::report_throughput(uint32_t id, double samples_per_second, double now) {
  Member* m = find(id);
  if (!m || !std::isfinite(samples_per_second) || samples_per_second <= 0.0) return;
  if (now - m->region_since < options_.settle_seconds) return;
  m->throughput =
      m->throughput == 0.0 ? samples_per_second : 0.5 * m->throughput + 0.5 * samples_per_second;
}

bool Coordinator::remove(uint32_t id) {
  if (!members_.erase(id)) return false;
  dirty_ = true;
  return true;
}

std::vector<Member> Coordinator::expire(double now) {
  std::vector<Member> dead;
  for (auto it = members_.begin(); it != members_.end();) {
    if (it->second.liveness.suspect(now)) {
      dead.push_back(it->second);
      it = members_.erase(it);
      dirty_ = true;
    } else {
      ++it;
    }
  }
  return dead;
}

// Shares of the image: measured throughput; a member not yet measured counts as the mean
// measured throughput per thread times its threads (or all equal when nothing is measured).
std::vector<double> Coordinator::shares() const {
  double measured = 0.0;
  int measured_threads = 0;
  for (const auto& [id, m] : members_) {
    if (m.throughput > 0.0) {
      measured += m.throughput;
      measured_threads += m.threads;
    }
  }
  const double per_thread = measured_threads > 0 ? measured / measured_threads : 1.0;
  std::vector<double> s;
  for (const auto& [id, m] : members_) {
    s.push_back(m.throughput > 0.0 ? m.throughput : per_thread * m.threads);
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

void Coordinator::cut(double now) {
  const std::vector<double> s = shares();
  const PixelRect image{0, 0, width_, height_};
  const std::vector<PixelRect> parts =
      error_ ? split_region(image, s, *error_) : split_region(image, s);
  size_t i = 0;
  for (auto& [id, m] : members_) {
    if (!(m.region == parts[i])) m.region_since = now;
    m.region = parts[i++];
  }
  ++epoch_;
  ++recuts_;
  last_cut_ = now;
  dirty_ = false;
}

bool Coordinator::maybe_recut(double now) {
  if (members_.empty()) {
    dirty_ = false;
    return false;
  }
  if (dirty_) {
    cut(now);
    return true;
  }
  if (now - last_cut_ < options_.recut_interval) return false;
  // A sampler that just got a new region restarts its pool: its throughput and its tiles'
  // error say little until it settles. Recutting on them would chase the restart (measured:
  // regions swinging between 17% and 73% every second).
  for (const auto& [id, m] : members_) {
    if (now - m.region_since < options_.settle_seconds) return false;
  }
  // The gain a recut would bring: the image's error is covered when the most loaded member
  // is done, so what counts is the largest ratio of a member's part to its share of the
  // throughput. A recut costs every member whose region changes a pool restart; it is worth
  // that only when that member carries more than (1 + hysteresis) times its share. An
  // underloaded member alone is no reason (with two members at 9% against 20% wanted, the
  // other carries 91% against 80%: 14% slower than balanced).
  const std::vector<double> s = shares();
  double total = 0.0;
  for (double x : s) total += x;
  size_t i = 0;
  bool drift = false;
  for (const auto& [id, m] : members_) {
    const double want = s[i++] / total;
    const double have = fraction(m.region);
    if (!(want > 0.0) || have / want > 1.0 + options_.hysteresis) drift = true;
  }
  if (!drift) return false;
  cut(now);
  return true;
}

}  // namespace afr::service
