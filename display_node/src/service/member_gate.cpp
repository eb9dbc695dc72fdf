#include <afr/display/service/member_gate.h>

namespace afr::service {

void MemberGate::admit(uint32_t id, uint64_t token, const std::string& public_key) {
  std::lock_guard<std::mutex> lock(mutex_);
  Entry& e = members_[id];
  e.token = token;
  e.public_key = public_key;
  e.accepted = 0;
  e.region = PixelRect{};
}

void MemberGate::revoke(uint32_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  members_.erase(id);
}

void MemberGate::replace(const std::vector<Member>& members) {
  std::map<uint32_t, Entry> next;
  std::lock_guard<std::mutex> lock(mutex_);
  for (const Member& m : members) {
    Entry e;
    e.token = m.token;
    e.public_key = m.public_key;
    e.region = m.region;
    if (const auto it = members_.find(m.id); it != members_.end()) e.accepted = it->second.accepted;
    next[m.id] = std::move(e);
  }
  members_.swap(next);
}

void MemberGate::set_region(uint32_t id, const PixelRect& region) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto it = members_.find(id); it != members_.end()) it->second.region = region;
}

bool MemberGate::has(uint32_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  return members_.count(id) > 0;
}

std::optional<PixelRect> MemberGate::region(uint32_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = members_.find(id);
  if (it == members_.end()) return std::nullopt;
  return it->second.region;
}

size_t MemberGate::size() {
  std::lock_guard<std::mutex> lock(mutex_);
  return members_.size();
}

MemberGate::Verdict MemberGate::check(uint32_t id, uint64_t token, std::string_view key,
                                      uint64_t samples) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = members_.find(id);
  if (it == members_.end()) return Verdict::kNonMember;
  Entry& e = it->second;
  // The key is compared whenever the member has one: a message without CurveZMQ cannot reach
  // a display that uses it, and one from another allowed key is another sampler's.
  if (token != e.token || (!e.public_key.empty() && key != e.public_key)) return Verdict::kSpoofed;
  e.accepted += samples;
  return Verdict::kMember;
}

std::vector<std::pair<uint32_t, uint64_t>> MemberGate::take_accepted() {
  std::vector<std::pair<uint32_t, uint64_t>> out;
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [id, e] : members_) {
    if (e.accepted == 0) continue;
    out.emplace_back(id, e.accepted);
    e.accepted = 0;
  }
  return out;
}

const char* verdict_name(MemberGate::Verdict v) {
  switch (v) {
    case MemberGate::Verdict::kMember:
      return "member";
    case MemberGate::Verdict::kNonMember:
      return "non-member";
    case MemberGate::Verdict::kSpoofed:
      return "spoofed";
  }
  return "unknown";
}

}  // namespace afr::service
