#include "validate.h"

#include "wire.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace afr::protocol {

using wire::field_error;

namespace detail {

Status check_text(const char* message, const char* field, const std::string& s) {
  if (s.size() > kMaxNameBytes) {
    return field_error(
        message, field,
        std::to_string(s.size()) + " bytes, over the limit of " + std::to_string(kMaxNameBytes));
  }
  for (size_t i = 0; i < s.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f) {
      return field_error(
          message, field,
          "control character " + std::to_string(int(c)) + " at byte " + std::to_string(i));
    }
  }
  return {};
}

Status check_endpoint(const char* message, const char* field, const std::string& s) {
  if (Status st = check_text(message, field, s); !st) return st;
  for (const char* scheme : {"tcp://", "ipc://", "inproc://"}) {
    if (s.rfind(scheme, 0) == 0 && s.size() > std::string(scheme).size()) return {};
  }
  return field_error(message, field, "'" + s + "' is not a tcp://, ipc:// or inproc:// endpoint");
}

Status check_time(const char* message, const char* field, double t) {
  if (!std::isfinite(t)) return field_error(message, field, "not finite");
  if (t < 0.0) return field_error(message, field, "negative (" + std::to_string(t) + ")");
  return {};
}

Status check_image_size(const char* message, int32_t width, int32_t height) {
  if (width < 1 || width > kMaxImageSize) {
    return field_error(message, "width",
                       std::to_string(width) + " is outside 1.." + std::to_string(kMaxImageSize));
  }
  if (height < 1 || height > kMaxImageSize) {
    return field_error(message, "height",
                       std::to_string(height) + " is outside 1.." + std::to_string(kMaxImageSize));
  }
  return {};
}

Status check_rect(const char* message, const char* field, const PixelRect& r, int32_t width,
                  int32_t height) {
  const auto text = [&] {
    return "[" + std::to_string(r.x0) + ", " + std::to_string(r.x1) + ") x [" +
           std::to_string(r.y0) + ", " + std::to_string(r.y1) + ")";
  };
  if (r.empty()) return field_error(message, field, text() + " is empty");
  if (r.x0 < 0 || r.y0 < 0 || r.x1 > width || r.y1 > height) {
    return field_error(
        message, field,
        text() + " is not inside " + std::to_string(width) + " x " + std::to_string(height));
  }
  return {};
}

Status check_bounds(const char* message, const ImageExtent& bounds) {
  if (bounds.width < 1 || bounds.width > kMaxImageSize || bounds.height < 1 ||
      bounds.height > kMaxImageSize) {
    return field_error(message, "(image bounds)",
                       std::to_string(bounds.width) + " x " + std::to_string(bounds.height) +
                           " is outside 1.." + std::to_string(kMaxImageSize));
  }
  return {};
}

}  // namespace detail

using namespace detail;

// ---------------------------------------------------------------------------------------------
// Control messages

Status validate(const Join& m) {
  if (m.protocol_version != kProtocolVersion) {
    return field_error("join", "protocol_version",
                       std::to_string(m.protocol_version) + " (this build speaks " +
                           std::to_string(kProtocolVersion) + ")");
  }
  if (m.threads < 1 || m.threads > kMaxThreads) {
    return field_error("join", "threads",
                       std::to_string(m.threads) + " is outside 1.." + std::to_string(kMaxThreads));
  }
  if (m.capabilities & ~kKnownCapabilities) {
    return field_error("join", "capabilities",
                       "unknown bits " + std::to_string(m.capabilities & ~kKnownCapabilities));
  }
  return check_text("join", "name", m.name);
}

Status validate(const Welcome& m) {
  if (m.sampler_id == 0) return field_error("welcome", "sampler_id", "0 is not an assigned id");
  if (m.session == 0) return field_error("welcome", "session", "0 is not a session id");
  if (m.token == 0) return field_error("welcome", "token", "0 is not a member token");
  if (Status s = check_image_size("welcome", m.image.width, m.image.height); !s) return s;
  if (Status s = check_time("welcome", "display_time", m.display_time); !s) return s;
  if (!std::isfinite(m.refresh_interval) || !(m.refresh_interval > 0.0) ||
      m.refresh_interval > kMaxRefreshInterval) {
    return field_error("welcome", "refresh_interval",
                       std::to_string(m.refresh_interval) + " is outside (0, " +
                           std::to_string(kMaxRefreshInterval) + "]");
  }
  if (m.scene_size < 1 || m.scene_size > kMaxSceneBytes) {
    return field_error(
        "welcome", "scene_size",
        std::to_string(m.scene_size) + " is outside 1.." + std::to_string(kMaxSceneBytes));
  }
  if (Status s = check_text("welcome", "scene_name", m.scene_name); !s) return s;
  return check_text("welcome", "presets", m.presets);
}

Status validate(const SceneRequest& m) { return {}; }

Status validate(const SceneChunk& m) {
  if (m.scene_size < 1 || m.scene_size > kMaxSceneBytes) {
    return field_error(
        "scene_chunk", "scene_size",
        std::to_string(m.scene_size) + " is outside 1.." + std::to_string(kMaxSceneBytes));
  }
  if (m.count < 1 || m.count > m.scene_size) {
    return field_error("scene_chunk", "count",
                       std::to_string(m.count) + " is outside 1..scene_size (" +
                           std::to_string(m.scene_size) + ")");
  }
  if (m.index >= m.count) {
    return field_error("scene_chunk", "index",
                       std::to_string(m.index) + " is not below count " + std::to_string(m.count));
  }
  if (m.bytes.empty() || m.bytes.size() > kMaxChunkBytes) {
    return field_error(
        "scene_chunk", "bytes",
        std::to_string(m.bytes.size()) + " bytes, outside 1.." + std::to_string(kMaxChunkBytes));
  }
  if (m.offset > m.scene_size || m.bytes.size() > m.scene_size - m.offset) {
    return field_error("scene_chunk", "offset",
                       std::to_string(m.offset) + " + " + std::to_string(m.bytes.size()) +
                           " bytes runs past scene_size " + std::to_string(m.scene_size));
  }
  return {};
}

Status validate(const RegionAssignment& m) {
  if (Status s = check_image_size("region_assignment", m.image.width, m.image.height); !s) return s;
  return check_rect("region_assignment", "region", m.region, m.image.width, m.image.height);
}

Status validate(const SamplerStats& m) {
  if (Status s = check_time("stats", "time", m.time); !s) return s;
  if (!std::isfinite(m.samples_per_second) || m.samples_per_second < 0.0) {
    return field_error("stats", "samples_per_second", "not finite and >= 0");
  }
  if (!std::isfinite(m.rays_per_second) || m.rays_per_second < 0.0) {
    return field_error("stats", "rays_per_second", "not finite and >= 0");
  }
  if (m.threads < 1 || m.threads > kMaxThreads) {
    return field_error("stats", "threads",
                       std::to_string(m.threads) + " is outside 1.." + std::to_string(kMaxThreads));
  }
  return {};
}

Status validate(const Heartbeat& m) { return check_time("heartbeat", "time", m.time); }

Status validate(const MemberList& m) {
  if (m.members.size() > kMaxMembers) {
    return field_error(
        "member_list", "count",
        std::to_string(m.members.size()) + " is outside 0.." + std::to_string(kMaxMembers));
  }
  std::vector<uint32_t> ids;
  ids.reserve(m.members.size());
  for (size_t i = 0; i < m.members.size(); ++i) {
    const MemberEntry& e = m.members[i];
    const std::string at = "members[" + std::to_string(i) + "]";
    if (e.sampler_id == 0) return field_error("member_list", at + ".sampler_id", "0 is not an id");
    if (!e.public_key.empty() && e.public_key.size() != 40) {
      return field_error(
          "member_list", at + ".public_key",
          std::to_string(e.public_key.size()) + " characters: a Z85 CurveZMQ key has 40");
    }
    if (Status s = check_text("member_list", (at + ".public_key").c_str(), e.public_key); !s) {
      return s;
    }
    // A member waiting for its first region has none: all zero.
    if (!(e.region == PixelRect{})) {
      if (Status s = check_rect("member_list", (at + ".region").c_str(), e.region, kMaxImageSize,
                                kMaxImageSize);
          !s) {
        return s;
      }
    }
    ids.push_back(e.sampler_id);
  }
  std::sort(ids.begin(), ids.end());
  if (const auto dup = std::adjacent_find(ids.begin(), ids.end()); dup != ids.end()) {
    return field_error("member_list", "sampler_id", std::to_string(*dup) + " appears twice");
  }
  return {};
}

Status validate(const SnapshotRequest& m) {
  if (m.id == 0) return field_error("snapshot_request", "id", "0 (ids start at 1)");
  return check_time("snapshot_request", "time", m.time);
}

Status validate(const DisplayJoin& m) {
  if (m.protocol_version != kProtocolVersion) {
    return field_error("display_join", "protocol_version",
                       std::to_string(m.protocol_version) + " (this build speaks " +
                           std::to_string(kProtocolVersion) + ")");
  }
  if (m.samples_endpoint.empty()) {
    return field_error("display_join", "samples_endpoint", "empty");
  }
  if (Status s = check_endpoint("display_join", "samples_endpoint", m.samples_endpoint); !s) {
    return s;
  }
  return check_text("display_join", "name", m.name);
}

Status validate(const WallLayout& m) {
  if (Status s = check_image_size("wall_layout", m.image.width, m.image.height); !s) return s;
  if (m.margin < 0 || m.margin > kMaxWallMargin) {
    return field_error(
        "wall_layout", "margin",
        std::to_string(m.margin) + " is outside 0.." + std::to_string(kMaxWallMargin));
  }
  if (m.nodes.empty() || m.nodes.size() > kMaxWallNodes) {
    return field_error(
        "wall_layout", "count",
        std::to_string(m.nodes.size()) + " is outside 1.." + std::to_string(kMaxWallNodes));
  }
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    const WallNode& n = m.nodes[i];
    const std::string at = "nodes[" + std::to_string(i) + "]";
    if (n.node_id == 0) return field_error("wall_layout", at + ".node_id", "0 is not an id");
    if (Status s = check_rect("wall_layout", "cell", n.cell, m.image.width, m.image.height); !s)
      return s;
    if (!n.samples_endpoint.empty()) {
      if (Status s = check_endpoint("wall_layout", "samples_endpoint", n.samples_endpoint); !s) {
        return s;
      }
    }
    // At most kMaxWallNodes^2 / 2 comparisons (half a million): cheap for a rare message.
    for (size_t j = 0; j < i; ++j) {
      const WallNode& o = m.nodes[j];
      if (o.node_id == n.node_id) {
        return field_error("wall_layout", at + ".node_id",
                           std::to_string(n.node_id) + " appears twice");
      }
      const bool overlap = n.cell.x0 < o.cell.x1 && o.cell.x0 < n.cell.x1 &&
                           n.cell.y0 < o.cell.y1 && o.cell.y0 < n.cell.y1;
      if (overlap) {
        return field_error("wall_layout", at + ".cell",
                           "overlaps the cell of node " + std::to_string(o.node_id));
      }
    }
  }
  return {};
}

Status validate(const Leave& m) {
  if (uint16_t(m.reason) > kLastLeaveReason) {
    return field_error("leave", "reason", "unknown value " + std::to_string(uint16_t(m.reason)));
  }
  return check_text("leave", "text", m.text);
}

// ---------------------------------------------------------------------------------------------
// View

Status validate(const View& m) {
  if (Status s = check_time("view", "time", m.time); !s) return s;
  const Camera& c = m.camera;
  const struct {
    const char* name;
    const glm::dvec3& v;
  } vectors[] = {{"camera.eye", c.eye},
                 {"camera.right", c.right},
                 {"camera.up", c.up},
                 {"camera.forward", c.forward}};
  for (const auto& [name, v] : vectors) {
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
      return field_error("view", name, "not finite");
    }
  }
  for (int i = 1; i < 4; ++i) {
    const double len = glm::length(vectors[i].v);
    if (std::abs(len - 1.0) > kBasisTolerance) {
      return field_error("view", vectors[i].name,
                         "length " + std::to_string(len) + " is not 1 (the basis is orthonormal)");
    }
  }
  if (std::abs(glm::dot(c.right, c.up)) > kBasisTolerance ||
      std::abs(glm::dot(c.right, c.forward)) > kBasisTolerance ||
      std::abs(glm::dot(c.up, c.forward)) > kBasisTolerance) {
    return field_error("view", "camera", "right, up and forward are not orthogonal");
  }
  if (!std::isfinite(c.yfov) || !(c.yfov > 0.0) || !(c.yfov < std::numbers::pi)) {
    return field_error("view", "camera.yfov", std::to_string(c.yfov) + " is outside (0, pi)");
  }
  if (!std::isfinite(c.znear) || !(c.znear > 0.0)) {
    return field_error("view", "camera.znear", std::to_string(c.znear) + " is not finite and > 0");
  }
  if (!std::isfinite(c.ymag) || !(c.ymag >= 0.0)) {
    return field_error("view", "camera.ymag",
                       std::to_string(c.ymag) + " is not finite and >= 0 (0: perspective)");
  }
  return {};
}

}  // namespace afr::protocol
