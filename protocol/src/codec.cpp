#include <afr/protocol/codec.h>

#include "validate.h"
#include "wire.h"

#include <string>
#include <type_traits>
#include <variant>

namespace afr::protocol {

using wire::field_error;
using wire::Reader;
using wire::Writer;

// ---------------------------------------------------------------------------------------------
// Names and the wire helpers

const char* message_type_name(MessageType type) {
  switch (type) {
    case MessageType::kJoin:
      return "join";
    case MessageType::kWelcome:
      return "welcome";
    case MessageType::kSceneRequest:
      return "scene_request";
    case MessageType::kSceneChunk:
      return "scene_chunk";
    case MessageType::kRegionAssignment:
      return "region_assignment";
    case MessageType::kView:
      return "view";
    case MessageType::kSampleBatch:
      return "sample_batch";
    case MessageType::kTilingSnapshot:
      return "tiling_snapshot";
    case MessageType::kStats:
      return "stats";
    case MessageType::kHeartbeat:
      return "heartbeat";
    case MessageType::kLeave:
      return "leave";
    case MessageType::kDisplayJoin:
      return "display_join";
    case MessageType::kWallLayout:
      return "wall_layout";
    case MessageType::kWallCoverage:
      return "wall_coverage";
    case MessageType::kSnapshotRequest:
      return "snapshot_request";
    case MessageType::kMemberList:
      return "member_list";
  }
  return "unknown";
}

// The variant lists the types in the order of their numbers.
template <MessageType kType, class T>
constexpr bool kAlternativeIs =
    std::is_same_v<std::variant_alternative_t<size_t(kType) - kFirstMessageType, Message>, T>;
static_assert(kAlternativeIs<MessageType::kJoin, Join> &&
              kAlternativeIs<MessageType::kWelcome, Welcome> &&
              kAlternativeIs<MessageType::kSceneRequest, SceneRequest> &&
              kAlternativeIs<MessageType::kSceneChunk, SceneChunk> &&
              kAlternativeIs<MessageType::kRegionAssignment, RegionAssignment> &&
              kAlternativeIs<MessageType::kView, View> &&
              kAlternativeIs<MessageType::kSampleBatch, SampleBatch> &&
              kAlternativeIs<MessageType::kTilingSnapshot, TilingSnapshot> &&
              kAlternativeIs<MessageType::kStats, SamplerStats> &&
              kAlternativeIs<MessageType::kHeartbeat, Heartbeat> &&
              kAlternativeIs<MessageType::kLeave, Leave> &&
              kAlternativeIs<MessageType::kDisplayJoin, DisplayJoin> &&
              kAlternativeIs<MessageType::kWallLayout, WallLayout> &&
              kAlternativeIs<MessageType::kWallCoverage, WallCoverage> &&
              kAlternativeIs<MessageType::kSnapshotRequest, SnapshotRequest> &&
              kAlternativeIs<MessageType::kMemberList, MemberList> &&
              std::variant_size_v<Message> == kLastMessageType);

MessageType message_type(const Message& message) {
  return MessageType(uint16_t(message.index() + kFirstMessageType));
}

namespace wire {

Writer begin_message(MessageType type, size_t payload_bytes, std::vector<uint8_t>* out) {
  AFR_CHECK(payload_bytes <= UINT32_MAX);
  out->resize(kHeaderBytes + payload_bytes);
  uint8_t* p = out->data();
  store_u32(p, kMagic);
  store_u16(p + 4, kProtocolVersion);
  store_u16(p + 6, uint16_t(type));
  store_u32(p + 8, uint32_t(payload_bytes));
  return Writer(p + kHeaderBytes, p + out->size());
}

Status field_error(const char* message, const std::string& field, const std::string& problem) {
  return Status::error(std::string(message) + "." + field + ": " + problem);
}

bool Reader::string(std::string* s, const char* field, size_t max_bytes) {
  uint16_t n = 0;
  if (!u16(&n, field)) return false;
  if (n > max_bytes) {
    fail(field, std::to_string(n) + " bytes, over the limit of " + std::to_string(max_bytes));
    return false;
  }
  const uint8_t* p = take(n, field);
  if (!p) return false;
  s->assign(reinterpret_cast<const char*>(p), n);
  return true;
}

void Reader::fail(const char* field, const std::string& problem) {
  if (status_.ok()) status_ = field_error(message_, field, problem);
}

Status Reader::finish() {
  if (status_.ok() && p_ != end_) {
    status_ = Status::error(std::string(message_) + ": " + std::to_string(end_ - p_) +
                            " bytes left over after the last field");
  }
  return status_;
}

}  // namespace wire

// ---------------------------------------------------------------------------------------------
// Header

Result<Header> peek_header(Bytes message) {
  if (message.size() < kHeaderBytes) {
    return Status::error("message: " + std::to_string(message.size()) +
                         " bytes, shorter than the 12-byte header");
  }
  const uint8_t* p = message.data();
  if (wire::load_u32(p) != kMagic) return Status::error("message: wrong magic (not afr)");
  Header h;
  h.version = wire::load_u16(p + 4);
  const uint16_t type = wire::load_u16(p + 6);
  if (type < kFirstMessageType || type > kLastMessageType) {
    return Status::error("message: unknown type " + std::to_string(type));
  }
  h.type = MessageType(type);
  h.payload_bytes = wire::load_u32(p + 8);
  if (h.payload_bytes != message.size() - kHeaderBytes) {
    return Status::error(std::string(message_type_name(h.type)) + ": header says " +
                         std::to_string(h.payload_bytes) + " payload bytes, " +
                         std::to_string(message.size() - kHeaderBytes) + " are there");
  }
  return h;
}

namespace detail {

// The payload of a message of `type` in the current version.
Result<Bytes> open_message(Bytes message, MessageType type) {
  Result<Header> h = peek_header(message);
  if (!h) return h.status();
  if (h->version != kProtocolVersion) {
    return Status::error(std::string(message_type_name(h->type)) +
                         ": unsupported protocol version " + std::to_string(h->version) +
                         " (this build speaks " + std::to_string(kProtocolVersion) + ")");
  }
  if (h->type != type) {
    return Status::error(std::string("message: expected ") + message_type_name(type) + ", got " +
                         message_type_name(h->type));
  }
  return message.subspan(kHeaderBytes);
}

}  // namespace detail

using detail::open_message;

namespace {

// Decodes a fixed-layout message: opens it, reads fields with `read`, checks that nothing is
// left over, then validates the values.
template <class T, class ReadFields>
Status decode_with(Bytes message, MessageType type, T* out, ReadFields read) {
  Result<Bytes> payload = open_message(message, type);
  if (!payload) return payload.status();
  Reader r(*payload, message_type_name(type));
  read(r);
  if (Status s = r.finish(); !s) return s;
  return validate(*out);
}

void write_hash(Writer& w, const SceneHash& h) { w.bytes(h.data(), h.size()); }
bool read_hash(Reader& r, SceneHash* h, const char* field) {
  const uint8_t* p = r.take(h->size(), field);
  if (p) std::copy(p, p + h->size(), h->begin());
  return p;
}

void write_dvec3(Writer& w, const glm::dvec3& v) {
  w.f64(v.x);
  w.f64(v.y);
  w.f64(v.z);
}
void read_dvec3(Reader& r, glm::dvec3* v, const char* field) {
  r.f64(&v->x, field) && r.f64(&v->y, field) && r.f64(&v->z, field);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Join: u32 sampler_id, u16 protocol_version, u16 threads, u32 capabilities, string name

Status encode(const Join& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kJoin, 12 + wire::string_bytes(m.name), out);
  w.u32(m.sampler_id);
  w.u16(m.protocol_version);
  w.u16(m.threads);
  w.u32(m.capabilities);
  w.string(m.name);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, Join* out) {
  return decode_with(message, MessageType::kJoin, out, [&](Reader& r) {
    r.u32(&out->sampler_id, "sampler_id") && r.u16(&out->protocol_version, "protocol_version") &&
        r.u16(&out->threads, "threads") && r.u32(&out->capabilities, "capabilities") &&
        r.string(&out->name, "name", kMaxNameBytes);
  });
}

// ---------------------------------------------------------------------------------------------
// Welcome: u32 sampler_id, u64 session, u32 width, u32 height, f64 display_time,
// f64 refresh_interval, u8[32] scene_hash, u64 scene_size, u64 token, string scene_name,
// string presets

Status encode(const Welcome& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(
      MessageType::kWelcome, 84 + wire::string_bytes(m.scene_name) + wire::string_bytes(m.presets),
      out);
  w.u32(m.sampler_id);
  w.u64(m.session);
  w.u32(uint32_t(m.image.width));
  w.u32(uint32_t(m.image.height));
  w.f64(m.display_time);
  w.f64(m.refresh_interval);
  write_hash(w, m.scene_hash);
  w.u64(m.scene_size);
  w.u64(m.token);
  w.string(m.scene_name);
  w.string(m.presets);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, Welcome* out) {
  return decode_with(message, MessageType::kWelcome, out, [&](Reader& r) {
    r.u32(&out->sampler_id, "sampler_id") && r.u64(&out->session, "session") &&
        r.i32(&out->image.width, "width") && r.i32(&out->image.height, "height") &&
        r.f64(&out->display_time, "display_time") &&
        r.f64(&out->refresh_interval, "refresh_interval") &&
        read_hash(r, &out->scene_hash, "scene_hash") && r.u64(&out->scene_size, "scene_size") &&
        r.u64(&out->token, "token") && r.string(&out->scene_name, "scene_name", kMaxNameBytes) &&
        r.string(&out->presets, "presets", kMaxNameBytes);
  });
}

// ---------------------------------------------------------------------------------------------
// SceneRequest: u32 sampler_id, u8[32] scene_hash, u32 first_chunk

Status encode(const SceneRequest& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kSceneRequest, 40, out);
  w.u32(m.sampler_id);
  write_hash(w, m.scene_hash);
  w.u32(m.first_chunk);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, SceneRequest* out) {
  return decode_with(message, MessageType::kSceneRequest, out, [&](Reader& r) {
    r.u32(&out->sampler_id, "sampler_id") && read_hash(r, &out->scene_hash, "scene_hash") &&
        r.u32(&out->first_chunk, "first_chunk");
  });
}

// ---------------------------------------------------------------------------------------------
// SceneChunk: u8[32] scene_hash, u64 scene_size, u64 offset, u32 index, u32 count,
// u32 byte_count, u8[byte_count] bytes

Status encode(const SceneChunk& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kSceneChunk, 60 + m.bytes.size(), out);
  write_hash(w, m.scene_hash);
  w.u64(m.scene_size);
  w.u64(m.offset);
  w.u32(m.index);
  w.u32(m.count);
  w.u32(uint32_t(m.bytes.size()));
  w.bytes(m.bytes.data(), m.bytes.size());
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, SceneChunk* out) {
  return decode_with(message, MessageType::kSceneChunk, out, [&](Reader& r) {
    uint32_t n = 0;
    if (!(read_hash(r, &out->scene_hash, "scene_hash") && r.u64(&out->scene_size, "scene_size") &&
          r.u64(&out->offset, "offset") && r.u32(&out->index, "index") &&
          r.u32(&out->count, "count") && r.u32(&n, "byte_count"))) {
      return;
    }
    // Checked against the limit and against what is there before anything is allocated.
    if (n < 1 || n > kMaxChunkBytes) {
      r.fail("byte_count", std::to_string(n) + " is outside 1.." + std::to_string(kMaxChunkBytes));
      return;
    }
    const uint8_t* p = r.take(n, "bytes");
    if (p) out->bytes.assign(p, p + n);
  });
}

// ---------------------------------------------------------------------------------------------
// RegionAssignment: u32 sampler_id, u64 epoch, u32 width, u32 height, i32 x0, y0, x1, y1

Status encode(const RegionAssignment& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kRegionAssignment, 36, out);
  w.u32(m.sampler_id);
  w.u64(m.epoch);
  w.u32(uint32_t(m.image.width));
  w.u32(uint32_t(m.image.height));
  w.i32(m.region.x0);
  w.i32(m.region.y0);
  w.i32(m.region.x1);
  w.i32(m.region.y1);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, RegionAssignment* out) {
  return decode_with(message, MessageType::kRegionAssignment, out, [&](Reader& r) {
    r.u32(&out->sampler_id, "sampler_id") && r.u64(&out->epoch, "epoch") &&
        r.i32(&out->image.width, "width") && r.i32(&out->image.height, "height") &&
        r.i32(&out->region.x0, "region.x0") && r.i32(&out->region.y0, "region.y0") &&
        r.i32(&out->region.x1, "region.x1") && r.i32(&out->region.y1, "region.y1");
  });
}

// ---------------------------------------------------------------------------------------------
// View: u64 sequence, f64 time, f64[3] eye, right, up, forward, f64 yfov, f64 znear, f64 ymag

Status encode(const View& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kView, 136, out);
  w.u64(m.sequence);
  w.f64(m.time);
  write_dvec3(w, m.camera.eye);
  write_dvec3(w, m.camera.right);
  write_dvec3(w, m.camera.up);
  write_dvec3(w, m.camera.forward);
  w.f64(m.camera.yfov);
  w.f64(m.camera.znear);
  w.f64(m.camera.ymag);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, View* out) {
  return decode_with(message, MessageType::kView, out, [&](Reader& r) {
    r.u64(&out->sequence, "sequence") && r.f64(&out->time, "time");
    read_dvec3(r, &out->camera.eye, "camera.eye");
    read_dvec3(r, &out->camera.right, "camera.right");
    read_dvec3(r, &out->camera.up, "camera.up");
    read_dvec3(r, &out->camera.forward, "camera.forward");
    r.f64(&out->camera.yfov, "camera.yfov") && r.f64(&out->camera.znear, "camera.znear") &&
        r.f64(&out->camera.ymag, "camera.ymag");
  });
}

// ---------------------------------------------------------------------------------------------
// SamplerStats: u32 sampler_id, f64 time, u64 samples, batches, batches_dropped, tilings,
// bytes_sent, crosshairs, reprojections, reprojections_dropped, occlusion_rays, sanitized,
// f64 samples_per_second, f64 rays_per_second, u32 tiles, u16 threads, u16 reserved (0)

Status encode(const SamplerStats& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kStats, 116, out);
  w.u32(m.sampler_id);
  w.f64(m.time);
  for (uint64_t v : {m.samples, m.batches, m.batches_dropped, m.tilings, m.bytes_sent, m.crosshairs,
                     m.reprojections, m.reprojections_dropped, m.occlusion_rays, m.sanitized}) {
    w.u64(v);
  }
  w.f64(m.samples_per_second);
  w.f64(m.rays_per_second);
  w.u32(m.tiles);
  w.u16(m.threads);
  w.u16(0);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, SamplerStats* out) {
  return decode_with(message, MessageType::kStats, out, [&](Reader& r) {
    uint16_t reserved = 0;
    if (!(r.u32(&out->sampler_id, "sampler_id") && r.f64(&out->time, "time") &&
          r.u64(&out->samples, "samples") && r.u64(&out->batches, "batches") &&
          r.u64(&out->batches_dropped, "batches_dropped") && r.u64(&out->tilings, "tilings") &&
          r.u64(&out->bytes_sent, "bytes_sent") && r.u64(&out->crosshairs, "crosshairs") &&
          r.u64(&out->reprojections, "reprojections") &&
          r.u64(&out->reprojections_dropped, "reprojections_dropped") &&
          r.u64(&out->occlusion_rays, "occlusion_rays") && r.u64(&out->sanitized, "sanitized") &&
          r.f64(&out->samples_per_second, "samples_per_second") &&
          r.f64(&out->rays_per_second, "rays_per_second") && r.u32(&out->tiles, "tiles") &&
          r.u16(&out->threads, "threads") && r.u16(&reserved, "reserved"))) {
      return;
    }
    if (reserved != 0) r.fail("reserved", "not zero");
  });
}

// ---------------------------------------------------------------------------------------------
// Heartbeat: u32 sampler_id, u64 session, u64 sequence, f64 time

Status encode(const Heartbeat& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kHeartbeat, 28, out);
  w.u32(m.sampler_id);
  w.u64(m.session);
  w.u64(m.sequence);
  w.f64(m.time);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, Heartbeat* out) {
  return decode_with(message, MessageType::kHeartbeat, out, [&](Reader& r) {
    r.u32(&out->sampler_id, "sampler_id") && r.u64(&out->session, "session") &&
        r.u64(&out->sequence, "sequence") && r.f64(&out->time, "time");
  });
}

// ---------------------------------------------------------------------------------------------
// SnapshotRequest: u64 id, f64 time

Status encode(const SnapshotRequest& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kSnapshotRequest, 16, out);
  w.u64(m.id);
  w.f64(m.time);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, SnapshotRequest* out) {
  return decode_with(message, MessageType::kSnapshotRequest, out,
                     [&](Reader& r) { r.u64(&out->id, "id") && r.f64(&out->time, "time"); });
}

// ---------------------------------------------------------------------------------------------
// MemberList: u64 epoch, u32 count, then per member: u32 sampler_id, u64 token, string
// public_key, i32 x0, y0, x1, y1 (the region)

Status encode(const MemberList& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  size_t bytes = 12;
  for (const MemberEntry& e : m.members) bytes += 28 + wire::string_bytes(e.public_key);
  Writer w = wire::begin_message(MessageType::kMemberList, bytes, out);
  w.u64(m.epoch);
  w.u32(uint32_t(m.members.size()));
  for (const MemberEntry& e : m.members) {
    w.u32(e.sampler_id);
    w.u64(e.token);
    w.string(e.public_key);
    w.i32(e.region.x0);
    w.i32(e.region.y0);
    w.i32(e.region.x1);
    w.i32(e.region.y1);
  }
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, MemberList* out) {
  return decode_with(message, MessageType::kMemberList, out, [&](Reader& r) {
    uint32_t count = 0;
    if (!(r.u64(&out->epoch, "epoch") && r.u32(&count, "count"))) return;
    // Each member takes at least 30 bytes: a count the bytes cannot hold is refused before any
    // allocation.
    if (count > kMaxMembers) {
      r.fail("count", std::to_string(count) + " is outside 0.." + std::to_string(kMaxMembers));
      return;
    }
    if (r.remaining() < size_t(count) * 30) {
      r.fail("count", std::to_string(count) + " members do not fit in the message");
      return;
    }
    out->members.resize(count);
    for (MemberEntry& e : out->members) {
      if (!(r.u32(&e.sampler_id, "sampler_id") && r.u64(&e.token, "token") &&
            r.string(&e.public_key, "public_key", kMaxNameBytes) &&
            r.i32(&e.region.x0, "region.x0") && r.i32(&e.region.y0, "region.y0") &&
            r.i32(&e.region.x1, "region.x1") && r.i32(&e.region.y1, "region.y1"))) {
        return;
      }
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Leave: u32 sampler_id, u16 reason, string text

Status encode(const Leave& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(MessageType::kLeave, 6 + wire::string_bytes(m.text), out);
  w.u32(m.sampler_id);
  w.u16(uint16_t(m.reason));
  w.string(m.text);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, Leave* out) {
  return decode_with(message, MessageType::kLeave, out, [&](Reader& r) {
    uint16_t reason = 0;
    if (!(r.u32(&out->sampler_id, "sampler_id") && r.u16(&reason, "reason"))) return;
    out->reason = LeaveReason(reason);  // validate() rejects unknown values
    r.string(&out->text, "text", kMaxNameBytes);
  });
}

// ---------------------------------------------------------------------------------------------
// DisplayJoin: u32 node_id, u16 protocol_version, u16 column, u16 row, string samples_endpoint,
// string name

Status encode(const DisplayJoin& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  Writer w = wire::begin_message(
      MessageType::kDisplayJoin,
      10 + wire::string_bytes(m.samples_endpoint) + wire::string_bytes(m.name), out);
  w.u32(m.node_id);
  w.u16(m.protocol_version);
  w.u16(m.column);
  w.u16(m.row);
  w.string(m.samples_endpoint);
  w.string(m.name);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, DisplayJoin* out) {
  return decode_with(message, MessageType::kDisplayJoin, out, [&](Reader& r) {
    r.u32(&out->node_id, "node_id") && r.u16(&out->protocol_version, "protocol_version") &&
        r.u16(&out->column, "column") && r.u16(&out->row, "row") &&
        r.string(&out->samples_endpoint, "samples_endpoint", kMaxNameBytes) &&
        r.string(&out->name, "name", kMaxNameBytes);
  });
}

// ---------------------------------------------------------------------------------------------
// WallLayout: u64 epoch, u32 width, u32 height, i32 margin, u32 count, then per node: u32 node_id,
// i32 x0, y0, x1, y1, string samples_endpoint

Status encode(const WallLayout& m, std::vector<uint8_t>* out) {
  out->clear();
  if (Status s = validate(m); !s) return s;
  size_t bytes = 24;
  for (const WallNode& n : m.nodes) bytes += 20 + wire::string_bytes(n.samples_endpoint);
  Writer w = wire::begin_message(MessageType::kWallLayout, bytes, out);
  w.u64(m.epoch);
  w.u32(uint32_t(m.image.width));
  w.u32(uint32_t(m.image.height));
  w.i32(m.margin);
  w.u32(uint32_t(m.nodes.size()));
  for (const WallNode& n : m.nodes) {
    w.u32(n.node_id);
    w.i32(n.cell.x0);
    w.i32(n.cell.y0);
    w.i32(n.cell.x1);
    w.i32(n.cell.y1);
    w.string(n.samples_endpoint);
  }
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, WallLayout* out) {
  return decode_with(message, MessageType::kWallLayout, out, [&](Reader& r) {
    uint32_t count = 0;
    if (!(r.u64(&out->epoch, "epoch") && r.i32(&out->image.width, "width") &&
          r.i32(&out->image.height, "height") && r.i32(&out->margin, "margin") &&
          r.u32(&count, "count"))) {
      return;
    }
    // Each node takes at least 22 bytes: a count the bytes cannot hold is refused before any
    // allocation.
    if (count < 1 || count > kMaxWallNodes) {
      r.fail("count", std::to_string(count) + " is outside 1.." + std::to_string(kMaxWallNodes));
      return;
    }
    if (r.remaining() < size_t(count) * 22) {
      r.fail("count", std::to_string(count) + " nodes do not fit in the message");
      return;
    }
    out->nodes.resize(count);
    for (WallNode& n : out->nodes) {
      if (!(r.u32(&n.node_id, "node_id") && r.i32(&n.cell.x0, "cell.x0") &&
            r.i32(&n.cell.y0, "cell.y0") && r.i32(&n.cell.x1, "cell.x1") &&
            r.i32(&n.cell.y1, "cell.y1") &&
            r.string(&n.samples_endpoint, "samples_endpoint", kMaxNameBytes))) {
        return;
      }
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Any message

Status encode(const Message& m, std::vector<uint8_t>* out) {
  return std::visit([&](const auto& v) { return encode(v, out); }, m);
}

Result<Message> decode_message(Bytes message, const ImageExtent& bounds) {
  Result<Header> h = peek_header(message);
  if (!h) return h.status();
  Message m;
  // Construct the alternative of the header's type, then decode into it.
  switch (h->type) {
    case MessageType::kJoin:
      m.emplace<Join>();
      break;
    case MessageType::kWelcome:
      m.emplace<Welcome>();
      break;
    case MessageType::kSceneRequest:
      m.emplace<SceneRequest>();
      break;
    case MessageType::kSceneChunk:
      m.emplace<SceneChunk>();
      break;
    case MessageType::kRegionAssignment:
      m.emplace<RegionAssignment>();
      break;
    case MessageType::kView:
      m.emplace<View>();
      break;
    case MessageType::kSampleBatch:
      m.emplace<SampleBatch>();
      break;
    case MessageType::kTilingSnapshot:
      m.emplace<TilingSnapshot>();
      break;
    case MessageType::kStats:
      m.emplace<SamplerStats>();
      break;
    case MessageType::kHeartbeat:
      m.emplace<Heartbeat>();
      break;
    case MessageType::kLeave:
      m.emplace<Leave>();
      break;
    case MessageType::kDisplayJoin:
      m.emplace<DisplayJoin>();
      break;
    case MessageType::kWallLayout:
      m.emplace<WallLayout>();
      break;
    case MessageType::kWallCoverage:
      m.emplace<WallCoverage>();
      break;
    case MessageType::kSnapshotRequest:
      m.emplace<SnapshotRequest>();
      break;
    case MessageType::kMemberList:
      m.emplace<MemberList>();
      break;
  }
  AFR_CHECK(message_type(m) == h->type);
  Status s = std::visit(
      [&](auto& v) -> Status {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, SampleBatch> || std::is_same_v<T, TilingSnapshot> ||
                      std::is_same_v<T, WallCoverage>) {
          return decode(message, &v, bounds);
        } else {
          return decode(message, &v);
        }
      },
      m);
  if (!s) return s;
  return m;
}

}  // namespace afr::protocol
