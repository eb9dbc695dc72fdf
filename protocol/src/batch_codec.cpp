// Sample batches, tiling snapshots and wall coverage maps: the large messages of the sample
// channel. The per-sample loops are instantiated per field combination so that they branch on
// nothing but the checks, and they allocate nothing.
#include <afr/protocol/codec.h>
#include <afr/protocol/packing.h>

#include "validate.h"
#include "wire.h"

#include <cmath>
#include <string>

namespace afr::protocol {

namespace detail {
Result<Bytes> open_message(Bytes message, MessageType type);
}  // namespace detail

using detail::check_bounds;
using detail::check_rect;
using detail::check_time;
using wire::field_error;
using wire::Reader;
using wire::Writer;

namespace {

constexpr uint32_t kMaxTicks = 0x7fff;  // 15 bits of time offset
constexpr uint16_t kMissBit = 0x8000;   // the 16th bit
constexpr const char* kBatch = "sample_batch";
constexpr const char* kSnapshot = "tiling_snapshot";

bool finite3(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

std::string sample_field(size_t i, const char* field) {
  return "samples[" + std::to_string(i) + "]." + field;
}

// Checks every sample's values (not what packing clamps: colors, velocity magnitudes) and
// finds the time range.
Status check_samples(const SampleBatch& m, const ImageExtent& bounds, double* t_min,
                     double* t_max) {
  if (Status s = check_bounds(kBatch, bounds); !s) return s;
  if (m.fields & ~kKnownSampleFields) {
    return field_error(kBatch, "fields",
                       "unknown bits " + std::to_string(m.fields & ~kKnownSampleFields));
  }
  if (m.samples.size() > kMaxSamplesPerBatch) {
    return field_error(kBatch, "count",
                       std::to_string(m.samples.size()) + " is over the limit of " +
                           std::to_string(kMaxSamplesPerBatch));
  }
  const float w = float(bounds.width), h = float(bounds.height);
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < m.samples.size(); ++i) {
    const Sample& s = m.samples[i];
    if (!std::isfinite(s.time) || s.time < 0.0) {
      return field_error(kBatch, sample_field(i, "time"), "not finite and >= 0");
    }
    lo = std::min(lo, s.time);
    hi = std::max(hi, s.time);
    if (!(s.x >= 0.0f && s.x < w)) {  // also NaN
      return field_error(
          kBatch, sample_field(i, "x"),
          std::to_string(s.x) + " is outside [0, " + std::to_string(bounds.width) + ")");
    }
    if (!(s.y >= 0.0f && s.y < h)) {
      return field_error(
          kBatch, sample_field(i, "y"),
          std::to_string(s.y) + " is outside [0, " + std::to_string(bounds.height) + ")");
    }
    if ((m.fields & kFieldPosition) && !finite3(s.position)) {
      return field_error(kBatch, sample_field(i, "position"), "not finite");
    }
    if ((m.fields & kFieldVelocity) && !finite3(s.velocity)) {
      return field_error(kBatch, sample_field(i, "velocity"), "not finite");
    }
  }
  if (m.samples.empty()) lo = hi = 0.0;
  // 32767 ticks of the coarsest size, and the half tick more that pack_samples clamps into the
  // last tick. Absolute times that a decoder made as base + 32767 ticks round to the nearest
  // double, each by up to half an ulp of hi, so their span can exceed that by an ulp (256 s at a
  // base of 2^60, where the fuzzer found it) and they must encode again: pack_samples clamps
  // them into the last tick.
  const double ulp = hi > 0.0 ? std::ldexp(1.0, std::ilogb(hi) - 52) : 0.0;  // hi's binade
  if (hi - lo > (double(kMaxTicks) + 0.5) * std::ldexp(1.0, kMaxTickExp) + ulp) {
    return field_error(
        kBatch, "samples",
        "times span " + std::to_string(hi - lo) + " s, more than one batch may (32767 s)");
  }
  *t_min = lo;
  *t_max = hi;
  return {};
}

// The finest power-of-two tick that spans `span` seconds in kMaxTicks ticks.
int choose_tick_exp(double span) {
  int e = kMinTickExp;
  while (e < kMaxTickExp && span > double(kMaxTicks) * std::ldexp(1.0, e)) ++e;
  return e;
}

template <uint32_t kFields>
void pack_samples(const SampleBatch& m, double base, double inv_tick, uint8_t* p) {
  constexpr size_t kStride = packed_sample_bytes(kFields);
  for (const Sample& s : m.samples) {
    wire::store_u24(p, encode_position(s.x));
    wire::store_u24(p + 3, encode_position(s.y));
    const uint32_t ticks = std::min(uint32_t((s.time - base) * inv_tick + 0.5), kMaxTicks);
    const bool miss = (kFields & kFieldPosition) && s.miss;
    wire::store_u16(p + 6, uint16_t(ticks | (miss ? kMissBit : 0)));
    wire::store_u32(p + 8, encode_rgb9e5(s.color.r, s.color.g, s.color.b));
    uint8_t* q = p + 12;
    if constexpr ((kFields & kFieldPosition) != 0) {
      wire::store_f32(q, s.position.x);
      wire::store_f32(q + 4, s.position.y);
      wire::store_f32(q + 8, s.position.z);
      q += 12;
    }
    if constexpr ((kFields & kFieldVelocity) != 0) {
      wire::store_u16(q, encode_half(s.velocity.x));
      wire::store_u16(q + 2, encode_half(s.velocity.y));
      wire::store_u16(q + 4, encode_half(s.velocity.z));
    }
    p += kStride;
  }
}

// Returns the index of the first bad sample and what is wrong with it, or -1.
template <uint32_t kFields>
int64_t unpack_samples(const uint8_t* p, double base, double tick, uint32_t max_x_code,
                       uint32_t max_y_code, std::vector<Sample>& samples, const char** problem) {
  constexpr size_t kStride = packed_sample_bytes(kFields);
  const size_t n = samples.size();
  for (size_t i = 0; i < n; ++i, p += kStride) {
    Sample& s = samples[i];
    const uint32_t xc = wire::load_u24(p), yc = wire::load_u24(p + 3);
    const uint16_t t = wire::load_u16(p + 6);
    if (xc > max_x_code || yc > max_y_code) [[unlikely]] {
      *problem = xc > max_x_code ? "x: outside the image" : "y: outside the image";
      return int64_t(i);
    }
    s.x = decode_position(xc);
    s.y = decode_position(yc);
    s.time = base + double(t & kMaxTicks) * tick;
    const Rgb c = decode_rgb9e5(wire::load_u32(p + 8));
    s.color = glm::vec3(c.r, c.g, c.b);
    const uint8_t* q = p + 12;
    if constexpr ((kFields & kFieldPosition) != 0) {
      s.position = glm::vec3(wire::load_f32(q), wire::load_f32(q + 4), wire::load_f32(q + 8));
      if (!finite3(s.position)) [[unlikely]] {
        *problem = "position: not finite";
        return int64_t(i);
      }
      s.miss = (t & kMissBit) != 0;
      q += 12;
    } else {
      if (t & kMissBit) [[unlikely]] {
        *problem = "miss: set without the position field";
        return int64_t(i);
      }
      s.position = glm::vec3(0.0f);
      s.miss = false;
    }
    if constexpr ((kFields & kFieldVelocity) != 0) {
      const uint16_t vx = wire::load_u16(q), vy = wire::load_u16(q + 2), vz = wire::load_u16(q + 4);
      if (half_is_special(vx) || half_is_special(vy) || half_is_special(vz)) [[unlikely]] {
        *problem = "velocity: not finite";
        return int64_t(i);
      }
      s.velocity = glm::vec3(decode_half(vx), decode_half(vy), decode_half(vz));
    } else {
      s.velocity = glm::vec3(0.0f);
    }
  }
  return -1;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// SampleBatch: u32 sampler_id, u32 fields, u64 sequence, f64 base_time, u32 count,
// i8 tick_exp, u8[3] reserved (0), u64 token; then count packed samples (docs/protocol.md)

Status validate(const SampleBatch& m, const ImageExtent& bounds) {
  double lo, hi;
  return check_samples(m, bounds, &lo, &hi);
}

Status encode(const SampleBatch& m, std::vector<uint8_t>* out, const ImageExtent& bounds) {
  out->clear();
  double t_min = 0.0, t_max = 0.0;
  if (Status s = check_samples(m, bounds, &t_min, &t_max); !s) return s;
  const int tick_exp = choose_tick_exp(t_max - t_min);
  const size_t n = m.samples.size();
  Writer w = wire::begin_message(MessageType::kSampleBatch,
                                 kBatchHeaderBytes + n * packed_sample_bytes(m.fields), out);
  w.u32(m.sampler_id);
  w.u32(m.fields);
  w.u64(m.sequence);
  w.f64(t_min);
  w.u32(uint32_t(n));
  w.u8(uint8_t(int8_t(tick_exp)));
  w.u8(0);
  w.u8(0);
  w.u8(0);
  w.u64(m.token);
  uint8_t* p = w.take(n * packed_sample_bytes(m.fields));
  const double inv_tick = std::ldexp(1.0, -tick_exp);
  switch (m.fields) {
    case 0:
      pack_samples<0>(m, t_min, inv_tick, p);
      break;
    case kFieldPosition:
      pack_samples<kFieldPosition>(m, t_min, inv_tick, p);
      break;
    case kFieldVelocity:
      pack_samples<kFieldVelocity>(m, t_min, inv_tick, p);
      break;
    default:
      pack_samples<kFieldPosition | kFieldVelocity>(m, t_min, inv_tick, p);
      break;
  }
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, SampleBatch* out, const ImageExtent& bounds) {
  if (Status s = check_bounds(kBatch, bounds); !s) return s;
  Result<Bytes> payload = detail::open_message(message, MessageType::kSampleBatch);
  if (!payload) return payload.status();
  Reader r(*payload, kBatch);
  uint32_t count = 0;
  double base = 0.0;
  uint8_t tick_byte = 0;
  const uint8_t* reserved = nullptr;
  if (!(r.u32(&out->sampler_id, "sampler_id") && r.u32(&out->fields, "fields") &&
        r.u64(&out->sequence, "sequence") && r.f64(&base, "base_time") && r.u32(&count, "count") &&
        r.u8(&tick_byte, "tick_exp") && (reserved = r.take(3, "reserved")) &&
        r.u64(&out->token, "token"))) {
    return r.status();
  }
  if (out->fields & ~kKnownSampleFields) {
    return field_error(kBatch, "fields",
                       "unknown bits " + std::to_string(out->fields & ~kKnownSampleFields));
  }
  if (Status s = check_time(kBatch, "base_time", base); !s) return s;
  const int tick_exp = int(int8_t(tick_byte));
  if (tick_exp < kMinTickExp || tick_exp > kMaxTickExp) {
    return field_error(kBatch, "tick_exp",
                       std::to_string(tick_exp) + " is outside " + std::to_string(kMinTickExp) +
                           ".." + std::to_string(kMaxTickExp));
  }
  if (reserved[0] | reserved[1] | reserved[2]) return field_error(kBatch, "reserved", "not zero");
  if (count > kMaxSamplesPerBatch) {
    return field_error(
        kBatch, "count",
        std::to_string(count) + " is over the limit of " + std::to_string(kMaxSamplesPerBatch));
  }
  const uint64_t need = uint64_t(count) * packed_sample_bytes(out->fields);
  if (r.remaining() != need) {
    return field_error(kBatch, "count",
                       std::to_string(count) + " samples need " + std::to_string(need) +
                           " bytes, " + std::to_string(r.remaining()) + " are there");
  }
  const uint8_t* p = r.take(need, "samples");
  AFR_CHECK(p != nullptr || need == 0);
  out->samples.resize(count);  // bounded by the limit and by the bytes received
  const double tick = std::ldexp(1.0, tick_exp);
  // Codes of positions that floor into the image: code / 512 < width.
  const uint32_t max_x = uint32_t(bounds.width) * kPositionScale - 1;
  const uint32_t max_y = uint32_t(bounds.height) * kPositionScale - 1;
  const char* problem = nullptr;
  int64_t bad = -1;
  switch (out->fields) {
    case 0:
      bad = unpack_samples<0>(p, base, tick, max_x, max_y, out->samples, &problem);
      break;
    case kFieldPosition:
      bad = unpack_samples<kFieldPosition>(p, base, tick, max_x, max_y, out->samples, &problem);
      break;
    case kFieldVelocity:
      bad = unpack_samples<kFieldVelocity>(p, base, tick, max_x, max_y, out->samples, &problem);
      break;
    default:
      bad = unpack_samples<kFieldPosition | kFieldVelocity>(p, base, tick, max_x, max_y,
                                                            out->samples, &problem);
      break;
  }
  if (bad >= 0) {
    return Status::error(std::string(kBatch) + ".samples[" + std::to_string(bad) + "]." + problem);
  }
  return {};
}

// ---------------------------------------------------------------------------------------------
// TilingSnapshot: u32 sampler_id, f64 time, u16 region x0, y0, x1, y1, u32 tile_count,
// u64 token; then per tile u16 x0, y0, x1, y1, f32 G_x, G_y, G_t, v, E, u32 count, f32 rate

namespace {

Status check_tile(size_t i, const TileInfo& t, const PixelRect& region) {
  // The field name is built only on failure: checking allocates nothing.
  const auto fail = [&](const char* field, const char* problem) {
    return field_error(kSnapshot, "tiles[" + std::to_string(i) + "]." + field, problem);
  };
  const PixelRect& r = t.rect;
  if (r.empty() || r.x0 < region.x0 || r.y0 < region.y0 || r.x1 > region.x1 || r.y1 > region.y1) {
    return fail("rect", "empty or not inside the region");
  }
  const struct {
    const char* field;
    float value;
    bool non_negative;
  } values[] = {{"G_x", t.G_x, false}, {"G_y", t.G_y, false}, {"G_t", t.G_t, false},
                {"v", t.v, true},      {"E", t.E, true},      {"rate", t.rate, true}};
  for (const auto& v : values) {
    if (!std::isfinite(v.value)) return fail(v.field, "not finite");
    if (v.non_negative && v.value < 0.0f) return fail(v.field, "negative");
  }
  return {};
}

// A tiling cuts its region into tiles that do not overlap, so together they cover at most the
// region's pixels. (Overlapping copies of one tile would multiply its error in the display's
// recuts.)
Status check_tiles_fit(const std::vector<TileInfo>& tiles, const PixelRect& region) {
  int64_t covered = 0;
  for (const TileInfo& t : tiles) covered += t.rect.area();
  if (covered <= region.area()) return {};
  return field_error(kSnapshot, "tiles",
                     "cover " + std::to_string(covered) + " pixels, more than the region's " +
                         std::to_string(region.area()) + ": tiles overlap");
}

}  // namespace

Status validate(const TilingSnapshot& m, const ImageExtent& bounds) {
  if (Status s = check_bounds(kSnapshot, bounds); !s) return s;
  if (Status s = check_time(kSnapshot, "time", m.time); !s) return s;
  if (Status s = check_rect(kSnapshot, "region", m.region, bounds.width, bounds.height); !s) {
    return s;
  }
  if (m.tiles.size() > kMaxTilesPerSnapshot || int64_t(m.tiles.size()) > m.region.area()) {
    return field_error(kSnapshot, "tile_count",
                       std::to_string(m.tiles.size()) + " is over the limit of " +
                           std::to_string(kMaxTilesPerSnapshot) + " or the region's pixels");
  }
  for (size_t i = 0; i < m.tiles.size(); ++i) {
    if (Status s = check_tile(i, m.tiles[i], m.region); !s) return s;
  }
  return check_tiles_fit(m.tiles, m.region);
}

Status encode(const TilingSnapshot& m, std::vector<uint8_t>* out, const ImageExtent& bounds) {
  out->clear();
  if (Status s = validate(m, bounds); !s) return s;
  Writer w = wire::begin_message(MessageType::kTilingSnapshot,
                                 kSnapshotHeaderBytes + m.tiles.size() * kTileBytes, out);
  w.u32(m.sampler_id);
  w.f64(m.time);
  // Coordinates are in [0, 32768] after validation: u16 holds them.
  w.u16(uint16_t(m.region.x0));
  w.u16(uint16_t(m.region.y0));
  w.u16(uint16_t(m.region.x1));
  w.u16(uint16_t(m.region.y1));
  w.u32(uint32_t(m.tiles.size()));
  w.u64(m.token);
  for (const TileInfo& t : m.tiles) {
    w.u16(uint16_t(t.rect.x0));
    w.u16(uint16_t(t.rect.y0));
    w.u16(uint16_t(t.rect.x1));
    w.u16(uint16_t(t.rect.y1));
    w.f32(t.G_x);
    w.f32(t.G_y);
    w.f32(t.G_t);
    w.f32(t.v);
    w.f32(t.E);
    w.u32(t.count);
    w.f32(t.rate);
  }
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, TilingSnapshot* out, const ImageExtent& bounds) {
  if (Status s = check_bounds(kSnapshot, bounds); !s) return s;
  Result<Bytes> payload = detail::open_message(message, MessageType::kTilingSnapshot);
  if (!payload) return payload.status();
  Reader r(*payload, kSnapshot);
  uint16_t rc[4] = {};
  uint32_t count = 0;
  if (!(r.u32(&out->sampler_id, "sampler_id") && r.f64(&out->time, "time") &&
        r.u16(&rc[0], "region.x0") && r.u16(&rc[1], "region.y0") && r.u16(&rc[2], "region.x1") &&
        r.u16(&rc[3], "region.y1") && r.u32(&count, "tile_count") && r.u64(&out->token, "token"))) {
    return r.status();
  }
  out->region = PixelRect{rc[0], rc[1], rc[2], rc[3]};
  if (Status s = check_time(kSnapshot, "time", out->time); !s) return s;
  if (Status s = check_rect(kSnapshot, "region", out->region, bounds.width, bounds.height); !s) {
    return s;
  }
  if (count > kMaxTilesPerSnapshot || int64_t(count) > out->region.area()) {
    return field_error(kSnapshot, "tile_count",
                       std::to_string(count) + " is over the limit of " +
                           std::to_string(kMaxTilesPerSnapshot) + " or the region's pixels");
  }
  const uint64_t need = uint64_t(count) * kTileBytes;
  if (r.remaining() != need) {
    return field_error(kSnapshot, "tile_count",
                       std::to_string(count) + " tiles need " + std::to_string(need) + " bytes, " +
                           std::to_string(r.remaining()) + " are there");
  }
  const uint8_t* p = r.take(need, "tiles");
  out->tiles.resize(count);
  for (uint32_t i = 0; i < count; ++i, p += kTileBytes) {
    TileInfo& t = out->tiles[i];
    t.rect = PixelRect{wire::load_u16(p), wire::load_u16(p + 2), wire::load_u16(p + 4),
                       wire::load_u16(p + 6)};
    t.G_x = wire::load_f32(p + 8);
    t.G_y = wire::load_f32(p + 12);
    t.G_t = wire::load_f32(p + 16);
    t.v = wire::load_f32(p + 20);
    t.E = wire::load_f32(p + 24);
    t.count = wire::load_u32(p + 28);
    t.rate = wire::load_f32(p + 32);
    if (Status s = check_tile(i, t, out->region); !s) return s;
  }
  return check_tiles_fit(out->tiles, out->region);
}

// ---------------------------------------------------------------------------------------------
// WallCoverage: u32 node_id, f64 time, u16 rect x0, y0, x1, y1, u32 cell_count; then per pixel
// of rect, row by row, f32 count, f32 growth_sum

namespace {

constexpr const char* kCoverage = "wall_coverage";
constexpr size_t kCoverageCellBytes = 8;  // f32 count, f32 growth_sum
static_assert(wall_coverage_message_bytes(1) - wall_coverage_message_bytes(0) ==
              kCoverageCellBytes);
// The sample channel's MAXMSGSIZE must let the largest map through (2 MiB + 36 bytes; a full
// tiling snapshot is larger still).
static_assert(wall_coverage_message_bytes(kMaxWallCoverageCells) <= kMaxSampleChannelMessage);

// Everything but the cells: the sender, the time, and a rect inside the image that is small
// enough for one message.
Status check_coverage_header(uint32_t node_id, double time, const PixelRect& rect,
                             const ImageExtent& bounds) {
  if (node_id == 0) return field_error(kCoverage, "node_id", "0 is not a node id");
  if (Status s = check_time(kCoverage, "time", time); !s) return s;
  if (Status s = check_rect(kCoverage, "rect", rect, bounds.width, bounds.height); !s) return s;
  if (rect.area() > int64_t(kMaxWallCoverageCells)) {
    return field_error(kCoverage, "rect",
                       std::to_string(rect.area()) + " pixels, over the limit of " +
                           std::to_string(kMaxWallCoverageCells) + " per message");
  }
  return {};
}

// A cell's values are finite and >= 0 (false for NaN too).
bool cell_value_ok(float v) { return std::isfinite(v) && v >= 0.0f; }

// What is wrong with cell i, one of whose values is not ok: built only on failure, so the
// checking loops allocate nothing.
Status cell_error(size_t i, float count, float growth_sum) {
  const bool count_ok = cell_value_ok(count);
  const float v = count_ok ? growth_sum : count;
  return field_error(kCoverage,
                     "cells[" + std::to_string(i) + "]." + (count_ok ? "growth_sum" : "count"),
                     std::isfinite(v) ? "negative" : "not finite");
}

}  // namespace

Status validate(const WallCoverage& m, const ImageExtent& bounds) {
  if (Status s = check_bounds(kCoverage, bounds); !s) return s;
  if (Status s = check_coverage_header(m.node_id, m.time, m.rect, bounds); !s) return s;
  const size_t pixels = size_t(m.rect.area());
  if (m.cells.size() != 2 * pixels) {
    return field_error(kCoverage, "cells",
                       std::to_string(m.cells.size()) + " floats, the rect's " +
                           std::to_string(pixels) + " pixels need " + std::to_string(2 * pixels));
  }
  for (size_t i = 0; i < pixels; ++i) {
    const float c = m.cells[2 * i], g = m.cells[2 * i + 1];
    if (!cell_value_ok(c) || !cell_value_ok(g)) [[unlikely]] {
      return cell_error(i, c, g);
    }
  }
  return {};
}

Status encode(const WallCoverage& m, std::vector<uint8_t>* out, const ImageExtent& bounds) {
  out->clear();
  if (Status s = validate(m, bounds); !s) return s;
  const size_t pixels = size_t(m.rect.area());
  Writer w = wire::begin_message(MessageType::kWallCoverage,
                                 kWallCoverageHeaderBytes + pixels * kCoverageCellBytes, out);
  w.u32(m.node_id);
  w.f64(m.time);
  // Coordinates are in [0, 32768] after validation: u16 holds them.
  w.u16(uint16_t(m.rect.x0));
  w.u16(uint16_t(m.rect.y0));
  w.u16(uint16_t(m.rect.x1));
  w.u16(uint16_t(m.rect.y1));
  w.u32(uint32_t(pixels));
  uint8_t* p = w.take(pixels * kCoverageCellBytes);
  for (size_t i = 0; i < 2 * pixels; ++i, p += 4) wire::store_f32(p, m.cells[i]);
  AFR_CHECK(w.done());
  return {};
}

Status decode(Bytes message, WallCoverage* out, const ImageExtent& bounds) {
  if (Status s = check_bounds(kCoverage, bounds); !s) return s;
  Result<Bytes> payload = detail::open_message(message, MessageType::kWallCoverage);
  if (!payload) return payload.status();
  Reader r(*payload, kCoverage);
  uint16_t rc[4] = {};
  uint32_t count = 0;
  if (!(r.u32(&out->node_id, "node_id") && r.f64(&out->time, "time") && r.u16(&rc[0], "rect.x0") &&
        r.u16(&rc[1], "rect.y0") && r.u16(&rc[2], "rect.x1") && r.u16(&rc[3], "rect.y1") &&
        r.u32(&count, "cell_count"))) {
    return r.status();
  }
  out->rect = PixelRect{rc[0], rc[1], rc[2], rc[3]};
  if (Status s = check_coverage_header(out->node_id, out->time, out->rect, bounds); !s) {
    return s;
  }
  // The count is checked against the limit, the rect and the bytes before anything is
  // allocated for it.
  if (count > kMaxWallCoverageCells || int64_t(count) != out->rect.area()) {
    return field_error(kCoverage, "cell_count",
                       std::to_string(count) + " is not the rect's " +
                           std::to_string(out->rect.area()) + " pixels (at most " +
                           std::to_string(kMaxWallCoverageCells) + ")");
  }
  const uint64_t need = uint64_t(count) * kCoverageCellBytes;
  if (r.remaining() != need) {
    return field_error(kCoverage, "cell_count",
                       std::to_string(count) + " cells need " + std::to_string(need) + " bytes, " +
                           std::to_string(r.remaining()) + " are there");
  }
  const uint8_t* p = r.take(need, "cells");
  out->cells.resize(2 * size_t(count));
  for (uint32_t i = 0; i < count; ++i, p += kCoverageCellBytes) {
    const float c = wire::load_f32(p), g = wire::load_f32(p + 4);
    if (!cell_value_ok(c) || !cell_value_ok(g)) [[unlikely]] {
      return cell_error(i, c, g);
    }
    out->cells[2 * size_t(i)] = c;
    out->cells[2 * size_t(i) + 1] = g;
  }
  return {};
}

}  // namespace afr::protocol
