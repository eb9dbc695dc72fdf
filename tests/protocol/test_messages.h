// Random, valid messages of every type for the protocol tests, the fuzz corpus and the
// benchmarks: built from a seeded generator, so every run sees the same ones.
#pragma once

#include <afr/common/random.h>
#include <afr/protocol/codec.h>
#include <afr/protocol/messages.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace afr::protocol::testing {

inline std::string random_name(Pcg32& rng, size_t max_len = kMaxNameBytes) {
  std::string s(rng.next_below(uint32_t(max_len) + 1), ' ');
  for (char& c : s) c = char(0x20 + rng.next_below(0x7f - 0x20));  // printable ASCII
  return s;
}

inline SceneHash random_hash(Pcg32& rng) {
  SceneHash h;
  for (uint8_t& b : h) b = uint8_t(rng.next_u32());
  return h;
}

inline uint64_t random_u64(Pcg32& rng) { return (uint64_t(rng.next_u32()) << 32) | rng.next_u32(); }

inline double random_time(Pcg32& rng) { return rng.next_double() * 1e6; }

inline Join random_join(Pcg32& rng) {
  Join m;
  m.sampler_id = rng.next_u32();
  m.threads = uint16_t(1 + rng.next_below(kMaxThreads));
  m.capabilities = rng.next_u32() & kKnownCapabilities;
  m.name = random_name(rng);
  return m;
}

inline Welcome random_welcome(Pcg32& rng) {
  Welcome m;
  m.sampler_id = 1 + rng.next_below(1000);
  m.session = random_u64(rng) | 1;
  m.token = random_u64(rng) | 1;
  m.image.width = int32_t(1 + rng.next_below(kMaxImageSize));
  m.image.height = int32_t(1 + rng.next_below(kMaxImageSize));
  m.display_time = random_time(rng);
  m.refresh_interval = 1e-3 + rng.next_double() * 0.1;
  m.scene_hash = random_hash(rng);
  m.scene_size = 1 + random_u64(rng) % kMaxSceneBytes;
  m.scene_name = random_name(rng);
  m.presets = random_name(rng, 16);
  return m;
}

inline SceneRequest random_scene_request(Pcg32& rng) {
  return SceneRequest{rng.next_u32(), random_hash(rng), rng.next_u32()};
}

inline SceneChunk random_scene_chunk(Pcg32& rng, uint32_t max_bytes = 4096) {
  SceneChunk m;
  m.scene_hash = random_hash(rng);
  m.bytes.resize(1 + rng.next_below(max_bytes));
  for (uint8_t& b : m.bytes) b = uint8_t(rng.next_u32());
  m.scene_size = m.bytes.size() + rng.next_below(1u << 30);
  m.offset = rng.next_below(uint32_t(m.scene_size - m.bytes.size() + 1));
  m.count = 1 + rng.next_below(uint32_t(std::min<uint64_t>(m.scene_size, 1u << 20)));
  m.index = rng.next_below(m.count);
  return m;
}

inline PixelRect random_rect_in(Pcg32& rng, const PixelRect& outer) {
  const int32_t x0 = outer.x0 + int32_t(rng.next_below(uint32_t(outer.width())));
  const int32_t y0 = outer.y0 + int32_t(rng.next_below(uint32_t(outer.height())));
  const int32_t x1 = x0 + 1 + int32_t(rng.next_below(uint32_t(outer.x1 - x0)));
  const int32_t y1 = y0 + 1 + int32_t(rng.next_below(uint32_t(outer.y1 - y0)));
  return {x0, y0, x1, y1};
}

inline RegionAssignment random_region(Pcg32& rng) {
  RegionAssignment m;
  m.sampler_id = rng.next_u32();
  m.epoch = random_u64(rng);
  m.image.width = int32_t(1 + rng.next_below(kMaxImageSize));
  m.image.height = int32_t(1 + rng.next_below(kMaxImageSize));
  m.region = random_rect_in(rng, m.image.rect());
  return m;
}

inline glm::dvec3 random_unit(Pcg32& rng) {
  for (;;) {
    const glm::dvec3 v(2 * rng.next_double() - 1, 2 * rng.next_double() - 1,
                       2 * rng.next_double() - 1);
    const double l = glm::length(v);
    if (l > 0.1 && l <= 1.0) return v / l;
  }
}

inline View random_view(Pcg32& rng) {
  View m;
  m.sequence = random_u64(rng);
  m.time = random_time(rng);
  const glm::dvec3 eye(rng.next_double() * 100 - 50, rng.next_double() * 100 - 50,
                       rng.next_double() * 100 - 50);
  m.camera = Camera::look_at(eye, eye + random_unit(rng), glm::dvec3(0, 1, 0),
                             0.1 + rng.next_double() * 2.5, 1e-3 + rng.next_double());
  if (rng.next_below(2) == 0) m.camera.ymag = 1e-3 + rng.next_double() * 10.0;  // orthographic
  return m;
}

// Samples within bounds, times within `span` seconds of a random base.
inline SampleBatch random_batch(Pcg32& rng, uint32_t fields, size_t n, double span = 0.01,
                                const ImageExtent& bounds = kMaxImageExtent) {
  SampleBatch m;
  m.sampler_id = rng.next_u32();
  m.token = random_u64(rng);
  m.sequence = random_u64(rng);
  m.fields = fields;
  const double base = random_time(rng);
  m.samples.resize(n);
  for (Sample& s : m.samples) {
    s.time = base + rng.next_double() * span;
    s.x =
        std::min(rng.next_float() * float(bounds.width), std::nextafter(float(bounds.width), 0.f));
    s.y = std::min(rng.next_float() * float(bounds.height),
                   std::nextafter(float(bounds.height), 0.f));
    s.color = glm::vec3(rng.next_float() * 4, rng.next_float(), rng.next_float() * 0.25f);
    if (fields & kFieldPosition) {
      s.position = glm::vec3(rng.next_float() * 200 - 100, rng.next_float() * 200 - 100,
                             rng.next_float() * 200 - 100);
      s.miss = rng.next_below(8) == 0;
    }
    if (fields & kFieldVelocity) {
      s.velocity = glm::vec3(rng.next_float() * 20 - 10, rng.next_float() * 2 - 1, 0.0f);
    }
  }
  return m;
}

inline TilingSnapshot random_tiling(Pcg32& rng, size_t n) {
  TilingSnapshot m;
  m.sampler_id = rng.next_u32();
  m.token = random_u64(rng);
  m.time = random_time(rng);
  const int32_t w = 64 + int32_t(rng.next_below(4000)), h = 64 + int32_t(rng.next_below(4000));
  m.region = random_rect_in(rng, PixelRect{0, 0, w, h});
  while (m.region.area() < int64_t(n)) m.region = random_rect_in(rng, PixelRect{0, 0, w, h});
  // n tiles that do not overlap, as a tiling's: the largest piece of the region cut across its
  // longer side at a random place, until there are n pieces.
  std::vector<PixelRect> pieces;
  if (n > 0) pieces.push_back(m.region);
  while (pieces.size() < n) {
    const auto largest = std::max_element(
        pieces.begin(), pieces.end(),
        [](const PixelRect& a, const PixelRect& b) { return a.area() < b.area(); });
    PixelRect a = *largest, b = *largest;
    if (a.width() >= a.height()) {
      a.x1 = b.x0 = a.x0 + 1 + int32_t(rng.next_below(uint32_t(a.width() - 1)));
    } else {
      a.y1 = b.y0 = a.y0 + 1 + int32_t(rng.next_below(uint32_t(a.height() - 1)));
    }
    *largest = a;
    pieces.push_back(b);
  }
  m.tiles.resize(n);
  for (size_t i = 0; i < n; ++i) {
    TileInfo& t = m.tiles[i];
    t.rect = pieces[i];
    t.G_x = rng.next_float() * 2 - 1;
    t.G_y = rng.next_float() * 2 - 1;
    t.G_t = rng.next_float() * 10 - 5;
    t.v = rng.next_float();
    t.E = rng.next_float() * 100;
    t.count = rng.next_u32();
    t.rate = rng.next_float() * 1000;
  }
  return m;
}

inline SamplerStats random_stats(Pcg32& rng) {
  SamplerStats m;
  m.sampler_id = rng.next_u32();
  m.time = random_time(rng);
  for (uint64_t* v :
       {&m.samples, &m.batches, &m.batches_dropped, &m.tilings, &m.bytes_sent, &m.crosshairs,
        &m.reprojections, &m.reprojections_dropped, &m.occlusion_rays, &m.sanitized}) {
    *v = random_u64(rng);
  }
  m.samples_per_second = rng.next_double() * 1e8;
  m.rays_per_second = rng.next_double() * 1e8;
  m.tiles = rng.next_u32();
  m.threads = uint16_t(1 + rng.next_below(kMaxThreads));
  return m;
}

inline Heartbeat random_heartbeat(Pcg32& rng) {
  return Heartbeat{rng.next_u32(), random_u64(rng), random_u64(rng), random_time(rng)};
}

inline MemberList random_member_list(Pcg32& rng) {
  MemberList m;
  m.epoch = random_u64(rng);
  const uint32_t n = rng.next_below(6);
  for (uint32_t i = 0; i < n; ++i) {
    MemberEntry e;
    e.sampler_id = 1 + i * 7 + rng.next_below(7);
    e.token = random_u64(rng);
    if (rng.next_below(2)) e.public_key = std::string(40, char('A' + rng.next_below(26)));
    if (rng.next_below(4)) {  // else none yet
      const int32_t x0 = int32_t(rng.next_below(1000)), y0 = int32_t(rng.next_below(1000));
      e.region = PixelRect{x0, y0, x0 + 1 + int32_t(rng.next_below(2000)),
                           y0 + 1 + int32_t(rng.next_below(2000))};
    }
    m.members.push_back(e);
  }
  return m;
}

inline SnapshotRequest random_snapshot_request(Pcg32& rng) {
  return SnapshotRequest{1 + random_u64(rng) % (~uint64_t(0)), random_time(rng)};
}

inline Leave random_leave(Pcg32& rng) {
  return Leave{rng.next_u32(), LeaveReason(rng.next_below(kLastLeaveReason + 1)), random_name(rng)};
}

inline std::string random_endpoint(Pcg32& rng) {
  return "tcp://10." + std::to_string(rng.next_below(256)) + "." +
         std::to_string(rng.next_below(256)) + ".7:" + std::to_string(1 + rng.next_below(65535));
}

inline DisplayJoin random_display_join(Pcg32& rng) {
  DisplayJoin m;
  m.node_id = rng.next_u32();
  m.column = uint16_t(rng.next_below(64));
  m.row = uint16_t(rng.next_below(64));
  m.samples_endpoint = random_endpoint(rng);
  m.name = random_name(rng);
  return m;
}

// A grid of columns x rows cells over a random image (some cells left out), random margin.
inline WallLayout random_wall_layout(Pcg32& rng, uint32_t max_side = 8) {
  WallLayout m;
  m.epoch = random_u64(rng);
  m.image.width = int32_t(max_side + rng.next_below(kMaxImageSize - max_side));
  m.image.height = int32_t(max_side + rng.next_below(kMaxImageSize - max_side));
  m.margin = int32_t(rng.next_below(kMaxWallMargin + 1));
  const int32_t columns = int32_t(1 + rng.next_below(max_side));
  const int32_t rows = int32_t(1 + rng.next_below(max_side));
  for (int32_t r = 0; r < rows; ++r) {
    for (int32_t c = 0; c < columns; ++c) {
      if (!m.nodes.empty() && rng.next_below(4) == 0) continue;
      WallNode n;
      n.node_id = uint32_t(1 + r * columns + c);
      n.cell = PixelRect{c * m.image.width / columns, r * m.image.height / rows,
                         (c + 1) * m.image.width / columns, (r + 1) * m.image.height / rows};
      if (rng.next_below(3) != 0) n.samples_endpoint = random_endpoint(rng);
      m.nodes.push_back(n);
    }
  }
  return m;
}

// A coverage map of a random rectangle of at most max_side x max_side pixels somewhere in the
// protocol's image, with whole splat counts (some zero) and growth sums to match.
inline WallCoverage random_wall_coverage(Pcg32& rng, uint32_t max_side = 8) {
  WallCoverage m;
  m.node_id = 1 + rng.next_below(kMaxWallNodes);
  m.time = random_time(rng);
  const int32_t w = int32_t(1 + rng.next_below(max_side));
  const int32_t h = int32_t(1 + rng.next_below(max_side));
  const int32_t x0 = int32_t(rng.next_below(uint32_t(kMaxImageSize - w + 1)));
  const int32_t y0 = int32_t(rng.next_below(uint32_t(kMaxImageSize - h + 1)));
  m.rect = PixelRect{x0, y0, x0 + w, y0 + h};
  m.cells.resize(2 * size_t(m.rect.area()));
  for (size_t i = 0; i < m.cells.size(); i += 2) {
    m.cells[i] = float(rng.next_below(6));
    m.cells[i + 1] = m.cells[i] * rng.next_float() * 3.0f;
  }
  return m;
}

// One random message of every type (batches in every field combination).
inline std::vector<Message> random_messages(Pcg32& rng) {
  std::vector<Message> all;
  all.push_back(random_join(rng));
  all.push_back(random_welcome(rng));
  all.push_back(random_scene_request(rng));
  all.push_back(random_scene_chunk(rng, 300));
  all.push_back(random_region(rng));
  all.push_back(random_view(rng));
  for (uint32_t fields = 0; fields < 4; ++fields) {
    all.push_back(random_batch(rng, fields, 1 + rng.next_below(20)));
  }
  all.push_back(random_tiling(rng, 1 + rng.next_below(10)));
  all.push_back(random_stats(rng));
  all.push_back(random_heartbeat(rng));
  all.push_back(random_leave(rng));
  all.push_back(random_display_join(rng));
  all.push_back(random_wall_layout(rng));
  all.push_back(random_wall_coverage(rng));
  all.push_back(random_snapshot_request(rng));
  all.push_back(random_member_list(rng));
  return all;
}

inline std::vector<uint8_t> encoded(const Message& m) {
  std::vector<uint8_t> bytes;
  const Status s = encode(m, &bytes);
  if (!s) throw std::runtime_error(s.message());
  return bytes;
}

}  // namespace afr::protocol::testing
