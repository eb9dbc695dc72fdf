// Every malformed variant is rejected with a reason that names the field, without reading out
// of bounds (run under ASan in the sanitizer build) and without allocating for counts that the
// bytes do not back.
#include <afr/protocol/codec.h>

#include "test_messages.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>

namespace afr::protocol {
namespace {

using namespace testing;

// Little-endian patches at payload offsets (after the 12-byte header).
void put_u8(std::vector<uint8_t>& b, size_t off, uint8_t v) { b.at(kHeaderBytes + off) = v; }
void put_u16(std::vector<uint8_t>& b, size_t off, uint16_t v) {
  for (int i = 0; i < 2; ++i) b.at(kHeaderBytes + off + i) = uint8_t(v >> (8 * i));
}
void put_u32(std::vector<uint8_t>& b, size_t off, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.at(kHeaderBytes + off + i) = uint8_t(v >> (8 * i));
}
void put_u64(std::vector<uint8_t>& b, size_t off, uint64_t v) {
  for (int i = 0; i < 8; ++i) b.at(kHeaderBytes + off + i) = uint8_t(v >> (8 * i));
}
void put_f32(std::vector<uint8_t>& b, size_t off, float v) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  put_u32(b, off, u);
}
void put_f64(std::vector<uint8_t>& b, size_t off, double v) {
  uint64_t u;
  std::memcpy(&u, &v, 8);
  put_u64(b, off, u);
}
// Makes the header's payload length agree with the bytes, so checks past the header run.
void fix_length(std::vector<uint8_t>& b) {
  const uint32_t n = uint32_t(b.size() - kHeaderBytes);
  for (int i = 0; i < 4; ++i) b[8 + i] = uint8_t(n >> (8 * i));
}

// Decodes as the type in the header and returns the error ("" when accepted).
std::string error_of(const std::vector<uint8_t>& b, const ImageExtent& bounds = kMaxImageExtent) {
  Result<Message> m = decode_message(b, bounds);
  return m.ok() ? "" : m.error();
}

#define EXPECT_REJECTED(bytes, text)                                                      \
  do {                                                                                    \
    const std::string error_ = error_of(bytes);                                           \
    EXPECT_FALSE(error_.empty()) << "accepted; expected an error about '" << text << "'"; \
    EXPECT_NE(error_.find(text), std::string::npos) << error_;                            \
  } while (false)

// ---------------------------------------------------------------------------------------------
// Framing

TEST(CodecRejectTest, EveryTruncationOfEveryMessageIsRejected) {
  Pcg32 rng(1);
  for (int round = 0; round < 5; ++round) {
    for (const Message& m : random_messages(rng)) {
      const std::vector<uint8_t> full = encoded(m);
      for (size_t n = 0; n < full.size(); ++n) {
        std::vector<uint8_t> cut(full.begin(), full.begin() + n);
        ASSERT_FALSE(error_of(cut).empty()) << message_type_name(message_type(m)) << " at " << n;
        // And with a header that agrees, so the payload's own checks must catch it.
        if (n >= kHeaderBytes) {
          fix_length(cut);
          ASSERT_FALSE(error_of(cut).empty())
              << message_type_name(message_type(m)) << " at " << n << " (length fixed)";
        }
      }
    }
  }
}

TEST(CodecRejectTest, TrailingBytesAreRejected) {
  Pcg32 rng(2);
  for (const Message& m : random_messages(rng)) {
    std::vector<uint8_t> b = encoded(m);
    b.push_back(0);
    EXPECT_FALSE(error_of(b).empty()) << message_type_name(message_type(m));  // length mismatch
    fix_length(b);
    EXPECT_FALSE(error_of(b).empty()) << message_type_name(message_type(m));  // extra byte
  }
}

TEST(CodecRejectTest, WrongMagicVersionAndTypeAreRejected) {
  Pcg32 rng(3);
  const std::vector<uint8_t> good = encoded(random_heartbeat(rng));
  ASSERT_EQ(error_of(good), "");
  std::vector<uint8_t> b = good;
  b[0] = 'X';
  EXPECT_REJECTED(b, "magic");
  for (uint16_t version : {uint16_t(0), uint16_t(kProtocolVersion - 1),
                           uint16_t(kProtocolVersion + 1), uint16_t(0xffff)}) {
    b = good;
    b[4] = uint8_t(version);
    b[5] = uint8_t(version >> 8);
    EXPECT_REJECTED(b, "version");
    // The header alone still reads, so the peer can be told why.
    Result<Header> h = peek_header(b);
    ASSERT_TRUE(h.ok()) << h.error();
    EXPECT_EQ(h->version, version);
  }
  for (uint16_t type : {uint16_t(0), uint16_t(kLastMessageType + 1), uint16_t(0xffff)}) {
    b = good;
    b[6] = uint8_t(type);
    b[7] = uint8_t(type >> 8);
    EXPECT_REJECTED(b, "unknown type");
  }
  // A decoder of one type refuses another.
  Join join;
  EXPECT_FALSE(decode(Bytes(good), &join).ok());
}

TEST(CodecRejectTest, HeaderLengthMustMatchTheBytes) {
  Pcg32 rng(4);
  std::vector<uint8_t> b = encoded(random_view(rng));
  for (uint32_t len : {0u, 127u, 129u, 0xffffffffu}) {
    for (int i = 0; i < 4; ++i) b[8 + i] = uint8_t(len >> (8 * i));
    EXPECT_REJECTED(b, "payload bytes");
  }
}

// ---------------------------------------------------------------------------------------------
// Counts and lengths

TEST(CodecRejectTest, BatchCountsBeyondTheLimitOrTheBytesAreRejectedBeforeAllocating) {
  Pcg32 rng(5);
  const std::vector<uint8_t> good = encoded(random_batch(rng, kFieldPosition, 10));
  for (uint32_t count : {11u, 9u, kMaxSamplesPerBatch + 1, 0x80000000u, 0xffffffffu,
                         uint32_t(0x100000000ull / 24)}) {  // count * 24 wraps 32 bits
    std::vector<uint8_t> b = good;
    put_u32(b, 24, count);
    SampleBatch out;
    const Status s = decode(Bytes(b), &out);
    EXPECT_FALSE(s.ok()) << count;
    EXPECT_NE(s.message().find("sample_batch.count"), std::string::npos) << s.message();
    EXPECT_EQ(out.samples.capacity(), 0u) << count;  // nothing allocated for the claim
  }
  // A count at the limit with the bytes missing.
  std::vector<uint8_t> b = good;
  put_u32(b, 24, kMaxSamplesPerBatch);
  EXPECT_REJECTED(b, "count");
}

TEST(CodecRejectTest, TileCountsBeyondTheLimitTheRegionOrTheBytesAreRejected) {
  Pcg32 rng(6);
  TilingSnapshot t = random_tiling(rng, 3);
  t.region = PixelRect{0, 0, 4, 4};
  t.tiles[0].rect = PixelRect{0, 0, 2, 2};
  t.tiles[1].rect = PixelRect{2, 0, 4, 2};
  t.tiles[2].rect = PixelRect{0, 2, 2, 4};
  const std::vector<uint8_t> good = encoded(t);
  for (uint32_t count : {4u, 2u, 17u, kMaxTilesPerSnapshot + 1, 0xffffffffu}) {
    std::vector<uint8_t> b = good;
    put_u32(b, 20, count);
    TilingSnapshot out;
    EXPECT_FALSE(decode(Bytes(b), &out).ok()) << count;
    EXPECT_EQ(out.tiles.capacity(), 0u);
    EXPECT_REJECTED(b, "tile_count");
  }
}

TEST(CodecRejectTest, OversizedChunksAndStringsAreRejected) {
  Pcg32 rng(7);
  SceneChunk chunk = random_scene_chunk(rng, 16);
  const std::vector<uint8_t> good = encoded(chunk);
  std::vector<uint8_t> b = good;
  put_u32(b, 56, kMaxChunkBytes + 1);  // byte_count over the limit
  EXPECT_REJECTED(b, "byte_count");
  b = good;
  put_u32(b, 56, uint32_t(chunk.bytes.size() + 1));  // more than is there
  EXPECT_REJECTED(b, "truncated");
  b = good;
  put_u32(b, 56, 0);
  EXPECT_REJECTED(b, "byte_count");

  Join join = random_join(rng);
  join.name = "abc";
  const std::vector<uint8_t> j = encoded(join);
  b = j;
  put_u16(b, 12, uint16_t(kMaxNameBytes + 1));
  EXPECT_REJECTED(b, "join.name");
  b = j;
  put_u16(b, 12, 4);  // longer than the bytes
  EXPECT_REJECTED(b, "join.name: truncated");
  b = j;
  put_u8(b, 15, 0x07);  // a control character (BEL) in the name
  EXPECT_REJECTED(b, "join.name: control character");

  // Strings too long for encoding are refused too.
  join.name.assign(kMaxNameBytes + 1, 'x');
  std::vector<uint8_t> out;
  EXPECT_FALSE(encode(join, &out).ok());
}

TEST(CodecRejectTest, ChunkPlacementIsChecked) {
  Pcg32 rng(8);
  SceneChunk chunk = random_scene_chunk(rng, 16);
  const auto error = [&](SceneChunk c) {
    std::vector<uint8_t> out;
    return encode(c, &out).message();
  };
  SceneChunk c = chunk;
  c.offset = c.scene_size - c.bytes.size() + 1;  // runs past the end
  EXPECT_NE(error(c).find("scene_chunk.offset"), std::string::npos);
  c = chunk;
  c.offset = std::numeric_limits<uint64_t>::max();  // would wrap a naive offset + size
  EXPECT_NE(error(c).find("scene_chunk.offset"), std::string::npos);
  c = chunk;
  c.index = c.count;
  EXPECT_NE(error(c).find("scene_chunk.index"), std::string::npos);
  c = chunk;
  c.scene_size = kMaxSceneBytes + 1;
  EXPECT_NE(error(c).find("scene_chunk.scene_size"), std::string::npos);

  // The same, arriving as bytes.
  std::vector<uint8_t> b = encoded(chunk);
  put_u64(b, 40, std::numeric_limits<uint64_t>::max());
  EXPECT_REJECTED(b, "scene_chunk.offset");
}

// ---------------------------------------------------------------------------------------------
// Enums and reserved bits

TEST(CodecRejectTest, UnknownEnumValuesAndBitsAreRejected) {
  Pcg32 rng(9);
  std::vector<uint8_t> b = encoded(random_leave(rng));
  put_u16(b, 4, kLastLeaveReason + 1);
  EXPECT_REJECTED(b, "leave.reason");

  b = encoded(random_join(rng));
  put_u32(b, 8, kKnownCapabilities + 1);
  EXPECT_REJECTED(b, "join.capabilities");
  b = encoded(random_join(rng));
  put_u16(b, 4, kProtocolVersion + 1);
  EXPECT_REJECTED(b, "join.protocol_version");
  b = encoded(random_join(rng));
  put_u16(b, 6, 0);
  EXPECT_REJECTED(b, "join.threads");

  const std::vector<uint8_t> batch = encoded(random_batch(rng, 0, 4));
  b = batch;
  put_u32(b, 4, 4);  // field bit 2: unknown
  EXPECT_REJECTED(b, "sample_batch.fields");
  for (int tick : {kMinTickExp - 1, kMaxTickExp + 1, -128, 127}) {
    b = batch;
    put_u8(b, 28, uint8_t(int8_t(tick)));
    EXPECT_REJECTED(b, "sample_batch.tick_exp");
  }
  b = batch;
  put_u8(b, 30, 1);
  EXPECT_REJECTED(b, "sample_batch.reserved");
  // The miss bit without positions.
  b = batch;
  put_u8(b, 40 + 12 + 7, 0x80);
  EXPECT_REJECTED(b, "miss");

  b = encoded(random_stats(rng));
  put_u16(b, 114, 1);
  EXPECT_REJECTED(b, "stats.reserved");
}

// ---------------------------------------------------------------------------------------------
// Floats and ranges

TEST(CodecRejectTest, NonFiniteValuesAreRejectedWhereForbidden) {
  Pcg32 rng(10);
  const double bad[] = {NAN, INFINITY, -INFINITY};
  for (double x : bad) {
    std::vector<uint8_t> b = encoded(random_view(rng));
    put_f64(b, 8, x);
    EXPECT_REJECTED(b, "view.time");
    for (size_t off = 16; off < 112; off += 8) {  // every component of eye, right, up, forward
      b = encoded(random_view(rng));
      put_f64(b, off, x);
      EXPECT_REJECTED(b, "view.camera");
    }
    b = encoded(random_view(rng));
    put_f64(b, 112, x);
    EXPECT_REJECTED(b, "view.camera.yfov");
    b = encoded(random_view(rng));
    put_f64(b, 120, x);
    EXPECT_REJECTED(b, "view.camera.znear");
    b = encoded(random_view(rng));
    put_f64(b, 128, x);
    EXPECT_REJECTED(b, "view.camera.ymag");

    b = encoded(random_welcome(rng));
    put_f64(b, 20, x);
    EXPECT_REJECTED(b, "welcome.display_time");
    b = encoded(random_welcome(rng));
    put_f64(b, 28, x);
    EXPECT_REJECTED(b, "welcome.refresh_interval");

    b = encoded(random_heartbeat(rng));
    put_f64(b, 20, x);
    EXPECT_REJECTED(b, "heartbeat.time");

    b = encoded(random_stats(rng));
    put_f64(b, 92, x);
    EXPECT_REJECTED(b, "stats.samples_per_second");

    b = encoded(random_batch(rng, kFieldPosition, 3));
    put_f64(b, 16, x);
    EXPECT_REJECTED(b, "sample_batch.base_time");
    for (size_t c = 0; c < 3; ++c) {
      b = encoded(random_batch(rng, kFieldPosition, 3));
      put_f32(b, 40 + 24 * 2 + 12 + 4 * c, float(x));  // sample 2's world position
      EXPECT_REJECTED(b, "sample_batch.samples[2].position");
    }

    b = encoded(random_tiling(rng, 2));
    for (size_t field = 0; field < 6; ++field) {
      std::vector<uint8_t> t = b;
      const size_t off = field < 5 ? 8 + 4 * field : 32;  // G_x, G_y, G_t, v, E; rate
      put_f32(t, 32 + kTileBytes + off, float(x));
      EXPECT_REJECTED(t, "tiling_snapshot.tiles[1]");
    }
  }
  // Half-float Inf and NaN in velocities.
  for (uint16_t h : {uint16_t(0x7c00), uint16_t(0xfc00), uint16_t(0x7e00), uint16_t(0x7c01)}) {
    std::vector<uint8_t> b = encoded(random_batch(rng, kFieldVelocity, 3));
    put_u16(b, 40 + 18 + 12 + 2, h);
    EXPECT_REJECTED(b, "sample_batch.samples[1].velocity");
  }
}

TEST(CodecRejectTest, NegativeValuesAreRejectedWhereForbidden) {
  Pcg32 rng(11);
  std::vector<uint8_t> b = encoded(random_view(rng));
  put_f64(b, 8, -1.0);
  EXPECT_REJECTED(b, "view.time");
  b = encoded(random_view(rng));
  put_f64(b, 120, 0.0);
  EXPECT_REJECTED(b, "znear");
  b = encoded(random_view(rng));
  put_f64(b, 112, 3.2);
  EXPECT_REJECTED(b, "yfov");
  b = encoded(random_view(rng));
  put_f64(b, 128, -0.5);
  EXPECT_REJECTED(b, "view.camera.ymag");
  b = encoded(random_tiling(rng, 1));
  put_f32(b, 32 + 20, -0.5f);  // v
  EXPECT_REJECTED(b, "tiles[0].v: negative");
  b = encoded(random_welcome(rng));
  put_f64(b, 28, 0.0);
  EXPECT_REJECTED(b, "refresh_interval");
  // A welcome without a member token: the member's batches could not be told from others'.
  b = encoded(random_welcome(rng));
  put_u64(b, 76, 0);
  EXPECT_REJECTED(b, "welcome.token: 0 is not a member token");
}

// What the decoder accepts the encoder accepts too, at any finite base: base + 32767 one-second
// ticks rounds to the nearest double, and at a base of 2^60 (an ulp of 256 s) the decoded span
// came out 32768 s, which the encoder once refused (the fuzzer's find,
// tests/fuzz/regressions/protocol).
TEST(CodecRejectTest, ABatchDecodedAtAHugeBaseTimeEncodesAgain) {
  for (const double base : {std::ldexp(1.0, 60), std::ldexp(1.0, 60) + 384.0, 1e300}) {
    SampleBatch batch;
    batch.fields = 0;
    Sample first, last;
    first.time = 0.0;
    last.time = 32767.0;  // 1 s ticks: 0 and 32767
    batch.samples = {first, last};
    std::vector<uint8_t> b;
    ASSERT_TRUE(encode(batch, &b).ok());
    put_f64(b, 16, base);
    SampleBatch decoded;
    ASSERT_TRUE(decode(Bytes(b), &decoded).ok()) << base;
    std::vector<uint8_t> again;
    EXPECT_TRUE(encode(decoded, &again).ok()) << base;
  }
}

TEST(CodecRejectTest, ViewsWithoutAnOrthonormalBasisAreRejected) {
  Pcg32 rng(12);
  View v = random_view(rng);
  std::vector<uint8_t> out;
  v.camera.forward *= 2.0;
  EXPECT_NE(encode(v, &out).message().find("camera.forward"), std::string::npos);
  v = random_view(rng);
  v.camera.up = v.camera.forward;
  EXPECT_NE(encode(v, &out).message().find("orthogonal"), std::string::npos);
}

TEST(CodecRejectTest, SizesAndRectanglesOutsideTheImageAreRejected) {
  Pcg32 rng(13);
  std::vector<uint8_t> b = encoded(random_welcome(rng));
  put_u32(b, 12, kMaxImageSize + 1);
  EXPECT_REJECTED(b, "welcome.width");
  b = encoded(random_welcome(rng));
  put_u32(b, 16, 0);
  EXPECT_REJECTED(b, "welcome.height");
  b = encoded(random_welcome(rng));
  put_u32(b, 12, 0xffffffffu);
  EXPECT_REJECTED(b, "welcome.width");

  RegionAssignment r;
  r.image.width = 100;
  r.image.height = 50;
  r.region = PixelRect{10, 10, 20, 20};
  const std::vector<uint8_t> good = encoded(r);
  for (PixelRect bad : {PixelRect{10, 10, 10, 20}, PixelRect{-1, 0, 5, 5}, PixelRect{0, 0, 101, 5},
                        PixelRect{0, 0, 5, 51}, PixelRect{20, 10, 10, 20}}) {
    b = good;
    put_u32(b, 20, uint32_t(bad.x0));
    put_u32(b, 24, uint32_t(bad.y0));
    put_u32(b, 28, uint32_t(bad.x1));
    put_u32(b, 32, uint32_t(bad.y1));
    EXPECT_REJECTED(b, "region_assignment.region");
  }

  // Sample positions beyond the image.
  SampleBatch batch = random_batch(rng, 0, 4, 0.01, ImageExtent{100, 100});
  b = encoded(batch);
  EXPECT_EQ(error_of(b, ImageExtent{100, 100}), "");
  b[kHeaderBytes + 40 + 12 * 3 + 2] = 0x01;  // sample 3: x code + 65536 (x + 128 px)
  EXPECT_NE(error_of(b, ImageExtent{100, 100}).find("samples[3].x: outside"), std::string::npos);
  EXPECT_EQ(error_of(b), "");  // inside the protocol's 32768 x 32768 still

  // A tile outside its region, and a region outside the bounds.
  TilingSnapshot t = random_tiling(rng, 2);
  b = encoded(t);
  put_u16(b, 32 + kTileBytes + 4, uint16_t(t.region.x1 + 1));  // tile 1's x1
  EXPECT_REJECTED(b, "tiles[1].rect");
  b = encoded(t);
  EXPECT_NE(error_of(b, ImageExtent{t.region.x1 - 1, 32768}).find("tiling_snapshot.region"),
            std::string::npos);

  // Tiles that overlap: copies of one tile (each would count its error again in the recuts),
  // decoded and encoded alike.
  TilingSnapshot copies = random_tiling(rng, 1);
  copies.tiles.push_back(copies.tiles[0]);
  std::vector<uint8_t> refused = {1, 2, 3};
  const Status s = encode(copies, &refused);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("tiling_snapshot.tiles: cover"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("tiles overlap"), std::string::npos) << s.message();
  EXPECT_TRUE(refused.empty());
  // One tile's bytes repeated, with the tile count and the header's length to agree.
  b = encoded(random_tiling(rng, 1));  // its one tile is the whole region
  const std::vector<uint8_t> tile(b.end() - kTileBytes, b.end());
  b.insert(b.end(), tile.begin(), tile.end());
  put_u32(b, 20, 2);
  fix_length(b);
  EXPECT_REJECTED(b, "tiles overlap");
}

// ---------------------------------------------------------------------------------------------
// Encoding refuses what decoding would refuse

TEST(CodecRejectTest, EncoderRefusesInvalidSamplesAndWritesNothing) {
  Pcg32 rng(14);
  std::vector<uint8_t> out = {1, 2, 3};
  const auto refused = [&](SampleBatch b, const char* text) {
    const Status s = encode(b, &out);
    EXPECT_FALSE(s.ok()) << text;
    EXPECT_NE(s.message().find(text), std::string::npos) << s.message();
    EXPECT_TRUE(out.empty());
  };
  SampleBatch b = random_batch(rng, kFieldPosition | kFieldVelocity, 5);
  b.samples[3].time = NAN;
  refused(b, "samples[3].time");
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[1].time = -0.5;
  refused(b, "samples[1].time");
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[0].time = 0.0;
  b.samples[1].time = 40000.0;  // a span of more than 32767 s
  refused(b, "span");
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[2].x = 32768.0f;
  refused(b, "samples[2].x");
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[2].y = -0.001f;
  refused(b, "samples[2].y");
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[4].position.z = INFINITY;
  refused(b, "samples[4].position");
  b = random_batch(rng, kFieldVelocity, 5);
  b.samples[0].velocity.x = NAN;
  refused(b, "samples[0].velocity");
  b = random_batch(rng, 0, 5);
  b.fields = 8;
  refused(b, "fields");
  // Fields that are not sent are not checked: a NaN velocity without kFieldVelocity is fine.
  b = random_batch(rng, kFieldPosition, 5);
  b.samples[0].velocity.x = NAN;
  EXPECT_TRUE(encode(b, &out).ok());
}

// ---------------------------------------------------------------------------------------------
// Display wall

TEST(CodecRejectTest, MalformedWallLayoutsAreRejected) {
  Pcg32 rng(41);
  std::vector<uint8_t> out;
  const auto refused = [&](const WallLayout& m, const char* text) {
    const Status s = encode(m, &out);
    EXPECT_FALSE(s.ok()) << "accepted; expected an error about '" << text << "'";
    EXPECT_NE(s.message().find(text), std::string::npos) << s.message();
    EXPECT_TRUE(out.empty());
  };
  WallLayout base;
  base.epoch = 3;
  base.image.width = 200;
  base.image.height = 100;
  base.margin = 8;
  base.nodes = {WallNode{1, PixelRect{0, 0, 100, 100}, ""},
                WallNode{2, PixelRect{100, 0, 200, 100}, "tcp://10.0.0.2:7202"}};
  ASSERT_TRUE(encode(base, &out).ok());

  WallLayout m = base;
  m.nodes[1].cell.x0 = 99;  // overlaps node 1
  refused(m, "overlaps the cell of node 1");
  m = base;
  m.nodes[1].node_id = 1;
  refused(m, "appears twice");
  m = base;
  m.nodes[0].node_id = 0;
  refused(m, "node_id");
  m = base;
  m.nodes[1].cell.x1 = 201;
  refused(m, "cell");
  m = base;
  m.margin = kMaxWallMargin + 1;
  refused(m, "margin");
  m = base;
  m.margin = -1;
  refused(m, "margin");
  m = base;
  m.nodes.clear();
  refused(m, "count");
  m = base;
  m.nodes[1].samples_endpoint = "http://10.0.0.2:7202";
  refused(m, "samples_endpoint");
  m = base;
  m.image.width = kMaxImageSize + 1;
  refused(m, "width");

  // A count beyond the limit, or beyond what the bytes hold, is refused before allocating.
  ASSERT_TRUE(encode(base, &out).ok());
  std::vector<uint8_t> b = out;
  put_u32(b, 20, kMaxWallNodes + 1);
  EXPECT_REJECTED(b, "count");
  b = out;
  put_u32(b, 20, 1000);
  EXPECT_REJECTED(b, "do not fit");
  b = out;
  put_u32(b, 20, 0xffffffffu);
  EXPECT_REJECTED(b, "count");
}

// A 3 x 2 map at (10, 20) from node 4, for the tests below. Payload offsets: node_id 0,
// time 4, rect 12 (u16 x0, y0, x1, y1), cell_count 20, cells from 24 (8 bytes per pixel).
WallCoverage small_coverage() {
  WallCoverage m;
  m.node_id = 4;
  m.time = 12.5;
  m.rect = PixelRect{10, 20, 13, 22};
  m.cells = {1, 0.5f, 0, 0, 2, 3, 1, 1, 0, 0, 4, 0.25f};
  return m;
}

TEST(CodecRejectTest, EncoderRefusesMalformedWallCoverageAndWritesNothing) {
  std::vector<uint8_t> out = {1, 2, 3};
  const auto refused = [&](const WallCoverage& m, const char* text,
                           const ImageExtent& bounds = kMaxImageExtent) {
    const Status s = encode(m, &out, bounds);
    EXPECT_FALSE(s.ok()) << "accepted; expected an error about '" << text << "'";
    EXPECT_NE(s.message().find(text), std::string::npos) << s.message();
    EXPECT_TRUE(out.empty());
  };
  const WallCoverage base = small_coverage();
  ASSERT_TRUE(encode(base, &out).ok());
  ASSERT_TRUE(encode(base, &out, ImageExtent{13, 22}).ok());

  WallCoverage m = base;
  m.node_id = 0;
  refused(m, "wall_coverage.node_id");
  for (double t : {double(NAN), double(INFINITY), -double(INFINITY), -1.0}) {
    m = base;
    m.time = t;
    refused(m, "wall_coverage.time");
  }
  for (PixelRect r :
       {PixelRect{10, 20, 10, 22}, PixelRect{10, 20, 13, 20}, PixelRect{13, 20, 10, 22}}) {
    m = base;
    m.rect = r;
    m.cells.clear();
    refused(m, "wall_coverage.rect");  // empty
  }
  m = base;
  m.rect = PixelRect{-1, 20, 2, 22};
  refused(m, "wall_coverage.rect");
  m = base;
  m.rect = PixelRect{kMaxImageSize - 2, 20, kMaxImageSize + 1, 22};
  refused(m, "wall_coverage.rect");
  refused(base, "wall_coverage.rect", ImageExtent{12, 100});  // outside the receiver's image
  refused(base, "wall_coverage.rect", ImageExtent{100, 21});
  // One pixel over the limit of a message.
  m = base;
  m.rect = PixelRect{0, 0, 512, 513};
  m.cells.assign(2 * 512 * 513, 0.0f);
  refused(m, "wall_coverage.rect: 262656 pixels, over the limit of 262144");
  m.rect = PixelRect{0, 0, 512, 512};
  m.cells.resize(2 * 512 * 512);
  EXPECT_TRUE(encode(m, &out).ok());
  // Two floats per pixel, exactly.
  m = base;
  m.cells.pop_back();
  refused(m, "wall_coverage.cells: 11 floats");
  m = base;
  m.cells.push_back(0.0f);
  m.cells.push_back(0.0f);
  refused(m, "wall_coverage.cells: 14 floats");
  for (float bad : {NAN, INFINITY, -INFINITY}) {
    m = base;
    m.cells[4] = bad;
    refused(m, "wall_coverage.cells[2].count: not finite");
    m = base;
    m.cells[11] = bad;
    refused(m, "wall_coverage.cells[5].growth_sum: not finite");
  }
  m = base;
  m.cells[6] = -1.0f;
  refused(m, "wall_coverage.cells[3].count: negative");
  m = base;
  m.cells[1] = -1e-30f;
  refused(m, "wall_coverage.cells[0].growth_sum: negative");
}

TEST(CodecRejectTest, MalformedWallCoverageBytesAreRejected) {
  const std::vector<uint8_t> good = encoded(small_coverage());
  ASSERT_EQ(good.size(), kHeaderBytes + 24 + 6 * 8);
  ASSERT_EQ(error_of(good), "");
  std::vector<uint8_t> b = good;
  put_u32(b, 0, 0);
  EXPECT_REJECTED(b, "wall_coverage.node_id");
  for (double t : {double(NAN), double(INFINITY), -double(INFINITY), -2.0}) {
    b = good;
    put_f64(b, 4, t);
    EXPECT_REJECTED(b, "wall_coverage.time");
  }
  // Rects: empty, reversed, beyond the protocol's image (a u16 holds up to 65535).
  const auto put_rect = [](std::vector<uint8_t>& b, uint16_t x0, uint16_t y0, uint16_t x1,
                           uint16_t y1) {
    put_u16(b, 12, x0);
    put_u16(b, 14, y0);
    put_u16(b, 16, x1);
    put_u16(b, 18, y1);
  };
  for (const auto& [x0, y0, x1, y1] :
       {std::array<uint16_t, 4>{10, 20, 10, 26}, std::array<uint16_t, 4>{10, 20, 16, 20},
        std::array<uint16_t, 4>{16, 20, 10, 21}, std::array<uint16_t, 4>{65530, 0, 65535, 1}}) {
    b = good;
    put_rect(b, x0, y0, x1, y1);
    EXPECT_REJECTED(b, "wall_coverage.rect");
  }
  // Outside the receiver's image, which the receiver passes in.
  EXPECT_EQ(error_of(good, ImageExtent{13, 22}), "");
  EXPECT_NE(error_of(good, ImageExtent{12, 22}).find("wall_coverage.rect"), std::string::npos);
  EXPECT_NE(error_of(good, ImageExtent{13, 21}).find("wall_coverage.rect"), std::string::npos);
  // A rect over the limit is refused for its area, before the count or the bytes are looked
  // at, whatever the count says.
  for (uint32_t count : {6u, 1024u * 1024u, 0xffffffffu}) {
    b = good;
    put_rect(b, 0, 0, 1024, 1024);
    put_u32(b, 20, count);
    EXPECT_REJECTED(b, "wall_coverage.rect: 1048576 pixels, over the limit");
  }
  // A count that is not the rect's area, or that the bytes do not back, is refused without
  // allocating for it.
  for (uint32_t count : {0u, 5u, 7u, kMaxWallCoverageCells, kMaxWallCoverageCells + 1,
                         0x20000000u,  // count * 8 wraps 32 bits
                         0xffffffffu}) {
    b = good;
    put_u32(b, 20, count);
    WallCoverage out;
    const Status st = decode(Bytes(b), &out);
    EXPECT_FALSE(st.ok()) << count;
    EXPECT_NE(st.message().find("wall_coverage.cell_count"), std::string::npos) << st.message();
    EXPECT_EQ(out.cells.capacity(), 0u) << count;
  }
  // The largest rect with its count, but the cells of the small one.
  b = good;
  put_rect(b, 0, 0, 512, 512);
  put_u32(b, 20, kMaxWallCoverageCells);
  {
    WallCoverage out;
    const Status st = decode(Bytes(b), &out);
    EXPECT_NE(st.message().find("wall_coverage.cell_count: 262144 cells need 2097152 bytes, 48 "
                                "are there"),
              std::string::npos)
        << st.message();
    EXPECT_EQ(out.cells.capacity(), 0u);
  }
  // Cells cut short (the header's length agreeing), or one byte too many.
  b = good;
  b.resize(b.size() - 4);
  fix_length(b);
  EXPECT_REJECTED(b, "wall_coverage.cell_count: 6 cells need 48 bytes, 44 are there");
  b = good;
  b.push_back(0);
  fix_length(b);
  EXPECT_REJECTED(b, "wall_coverage.cell_count: 6 cells need 48 bytes, 49 are there");
  // Truncated inside the fixed fields.
  b = good;
  b.resize(kHeaderBytes + 22);
  fix_length(b);
  EXPECT_REJECTED(b, "wall_coverage.cell_count: truncated");
  b.resize(kHeaderBytes + 6);
  fix_length(b);
  EXPECT_REJECTED(b, "wall_coverage.time: truncated");
  // Cell values: not finite or negative, each named with its pixel and field.
  for (float bad : {NAN, INFINITY, -INFINITY}) {
    b = good;
    put_f32(b, 24 + 8 * 2, bad);
    EXPECT_REJECTED(b, "wall_coverage.cells[2].count: not finite");
    b = good;
    put_f32(b, 24 + 8 * 5 + 4, bad);
    EXPECT_REJECTED(b, "wall_coverage.cells[5].growth_sum: not finite");
  }
  b = good;
  put_f32(b, 24 + 8 * 3, -0.5f);
  EXPECT_REJECTED(b, "wall_coverage.cells[3].count: negative");
  b = good;
  put_f32(b, 24 + 4, -1.0f);
  EXPECT_REJECTED(b, "wall_coverage.cells[0].growth_sum: negative");
}

TEST(CodecRejectTest, MalformedDisplayJoinsAreRejected) {
  std::vector<uint8_t> out;
  DisplayJoin j;
  j.samples_endpoint = "tcp://10.0.0.3:7202";
  j.name = "wall-1-0";
  ASSERT_TRUE(encode(j, &out).ok());
  DisplayJoin m = j;
  m.samples_endpoint.clear();
  EXPECT_FALSE(encode(m, &out).ok());
  m = j;
  m.samples_endpoint = "10.0.0.3:7202";
  EXPECT_FALSE(encode(m, &out).ok());
  m = j;
  m.name = "bell\a";
  EXPECT_FALSE(encode(m, &out).ok());
  // Another version is refused with a reason that says so.
  ASSERT_TRUE(encode(j, &out).ok());
  std::vector<uint8_t> b = out;
  put_u16(b, 4, kProtocolVersion + 1);
  EXPECT_REJECTED(b, "protocol_version");
}

}  // namespace
}  // namespace afr::protocol
