// Which messages of the sample channel come from the members they name (docs/service.md,
// "Identity"). A PULL socket does not say which connection a message came on, so each member's
// sample batches and tiling snapshots carry the token of its welcome, which only the display
// and that member know; with CurveZMQ the message also carries its connection's authenticated
// key, which must be the key the member joined with. A message that names a member without
// both, or names no member, is not that member's: the ingest drops it before the store.
//
// Thread-safety: the control thread admits and revokes members and takes the counts; the
// ingest thread checks every message. One mutex, held for a map lookup.
#pragma once

#include <afr/common/samples.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace afr::service {

class MemberGate {
 public:
  enum class Verdict {
    kMember,     // from the member it names
    kNonMember,  // names an id that is no member
    kSpoofed,    // names a member, without its token or from another CurveZMQ key
  };

  // Control thread. `public_key` empty: the member joined without CurveZMQ.
  void admit(uint32_t id, uint64_t token, const std::string& public_key);
  void revoke(uint32_t id);
  // The region the coordinator gave member `id` (a wall's lead and a single display). A member
  // has none (an empty one) from its admission until then.
  void set_region(uint32_t id, const PixelRect& region);
  // A wall follower: the lead's members with their regions, all at once (member_list). Members
  // that stay keep their accepted counts.
  struct Member {
    uint32_t id = 0;
    uint64_t token = 0;
    std::string public_key;
    PixelRect region;
  };
  void replace(const std::vector<Member>& members);
  size_t size();
  // Ingest thread: is a message that names member `id`, carries `token` and came with CurveZMQ
  // key `key` (empty: none) that member's? A member's accepted samples are counted for
  // take_accepted() (pass 0 for a tiling snapshot).
  Verdict check(uint32_t id, uint64_t token, std::string_view key, uint64_t samples);
  // Ingest thread: whether `id` is a member; its region (empty before it has one), or nothing
  // when it is no member.
  bool has(uint32_t id);
  std::optional<PixelRect> region(uint32_t id);
  // Control thread: samples accepted per member since the last call (members with none left
  // out).
  std::vector<std::pair<uint32_t, uint64_t>> take_accepted();

 private:
  struct Entry {
    uint64_t token = 0;
    std::string public_key;
    uint64_t accepted = 0;  // samples since the last take_accepted()
    PixelRect region;       // empty until it has one
  };
  std::mutex mutex_;
  std::map<uint32_t, Entry> members_;
};

const char* verdict_name(MemberGate::Verdict v);

}  // namespace afr::service
