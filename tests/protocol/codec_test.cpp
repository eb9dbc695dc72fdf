#include <afr/protocol/codec.h>

#include <afr/protocol/packing.h>

#include "test_messages.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

namespace afr::protocol {
namespace {

using namespace testing;

// Decodes what was encoded and returns it (failing the test on any error).
template <class T, class... Bounds>
T round_trip(const T& in, std::vector<uint8_t>* bytes, const Bounds&... bounds) {
  const Status e = encode(in, bytes, bounds...);
  EXPECT_TRUE(e.ok()) << e.message();
  T out;
  const Status d = decode(Bytes(*bytes), &out, bounds...);
  EXPECT_TRUE(d.ok()) << d.message();
  return out;
}

// Bytes of a wall_coverage message over `pixels` pixels, from docs/protocol.md: the header,
// 24 bytes of node_id, time, rect and cell_count, and two f32 per pixel.
constexpr size_t coverage_bytes(size_t pixels) { return kHeaderBytes + 24 + 8 * pixels; }

// ---------------------------------------------------------------------------------------------
// Control and view messages travel exactly

TEST(CodecTest, ControlMessagesRoundTripExactly) {
  Pcg32 rng(1);
  std::vector<uint8_t> bytes;
  for (int i = 0; i < 300; ++i) {
    const Join join = random_join(rng);
    EXPECT_EQ(round_trip(join, &bytes), join);
    EXPECT_EQ(bytes.size(), kHeaderBytes + 14 + join.name.size());
    const Welcome welcome = random_welcome(rng);
    EXPECT_EQ(round_trip(welcome, &bytes), welcome);
    const SceneRequest request = random_scene_request(rng);
    EXPECT_EQ(round_trip(request, &bytes), request);
    const SceneChunk chunk = random_scene_chunk(rng);
    EXPECT_EQ(round_trip(chunk, &bytes), chunk);
    EXPECT_EQ(bytes.size(), kHeaderBytes + 60 + chunk.bytes.size());
    const RegionAssignment region = random_region(rng);
    EXPECT_EQ(round_trip(region, &bytes), region);
    const SamplerStats stats = random_stats(rng);
    EXPECT_EQ(round_trip(stats, &bytes), stats);
    const Heartbeat heartbeat = random_heartbeat(rng);
    EXPECT_EQ(round_trip(heartbeat, &bytes), heartbeat);
    const Leave leave = random_leave(rng);
    EXPECT_EQ(round_trip(leave, &bytes), leave);
    const View view = random_view(rng);
    EXPECT_EQ(round_trip(view, &bytes), view);
    EXPECT_EQ(bytes.size(), kMaxViewChannelMessage);
    const DisplayJoin display_join = random_display_join(rng);
    EXPECT_EQ(round_trip(display_join, &bytes), display_join);
    EXPECT_EQ(bytes.size(),
              kHeaderBytes + 14 + display_join.samples_endpoint.size() + display_join.name.size());
    const WallLayout layout = random_wall_layout(rng);
    EXPECT_EQ(round_trip(layout, &bytes), layout);
    const SnapshotRequest snapshot = random_snapshot_request(rng);
    EXPECT_EQ(round_trip(snapshot, &bytes), snapshot);
    EXPECT_EQ(bytes.size(), kHeaderBytes + 16);
    const MemberList members = random_member_list(rng);
    EXPECT_EQ(round_trip(members, &bytes), members);
  }
}

TEST(CodecTest, LargestMemberListFitsTheControlChannelLimitAndBadListsAreRefused) {
  MemberList m;
  for (uint32_t i = 0; i < kMaxMembers; ++i) {
    m.members.push_back(MemberEntry{i + 1, uint64_t(i) * 977, std::string(40, 'k'),
                                    PixelRect{0, 0, kMaxImageSize, kMaxImageSize}});
  }
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode(m, &bytes).ok());
  EXPECT_LE(bytes.size(), kMaxControlChannelMessage);
  MemberList back;
  ASSERT_TRUE(decode(bytes, &back).ok());
  EXPECT_EQ(back, m);
  // One more, a repeated id, an id 0, a key that is no CurveZMQ key: refused by name.
  MemberList bad = m;
  bad.members.push_back(MemberEntry{kMaxMembers + 1, 1, "", PixelRect{}});
  EXPECT_NE(encode(bad, &bytes).message().find("member_list.count"), std::string::npos);
  bad = MemberList{1, {{3, 1, "", PixelRect{}}, {3, 2, "", PixelRect{}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("3 appears twice"), std::string::npos);
  bad = MemberList{1, {{0, 1, "", PixelRect{}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("sampler_id: 0 is not an id"), std::string::npos);
  bad = MemberList{1, {{5, 1, "short", PixelRect{}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("a Z85 CurveZMQ key has 40"), std::string::npos);
  // A region: none yet (all zero), or a non-empty rectangle inside the largest image.
  bad = MemberList{1, {{5, 1, "", PixelRect{0, 0, 0, 9}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("members[0].region"), std::string::npos);
  bad = MemberList{1, {{5, 1, "", PixelRect{-1, 0, 8, 8}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("members[0].region"), std::string::npos);
  bad = MemberList{1, {{5, 1, "", PixelRect{0, 0, kMaxImageSize + 1, 8}}}};
  EXPECT_NE(encode(bad, &bytes).message().find("is not inside"), std::string::npos);
  EXPECT_TRUE(encode(MemberList{1, {{5, 1, "", PixelRect{}}}}, &bytes).ok());
  // The decoder refuses what the encoder would not write: a region out of range patched in.
  ASSERT_TRUE(encode(MemberList{1, {{5, 1, "", PixelRect{0, 0, 8, 8}}}}, &bytes).ok());
  const size_t x1 = bytes.size() - 8;  // i32 x1, y1 last
  bytes[x1] = 0xff;
  bytes[x1 + 1] = 0xff;
  bytes[x1 + 2] = 0xff;
  bytes[x1 + 3] = 0x7f;
  MemberList decoded;
  const Status s = decode(bytes, &decoded);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("members[0].region"), std::string::npos) << s.message();
}

TEST(CodecTest, LargestWallLayoutFitsTheControlChannelLimit) {
  // 32 x 32 cells, every endpoint as long as the protocol allows.
  WallLayout m;
  m.image.width = m.image.height = kMaxImageSize;
  m.margin = kMaxWallMargin;
  for (int32_t r = 0; r < 32; ++r) {
    for (int32_t c = 0; c < 32; ++c) {
      WallNode n;
      n.node_id = uint32_t(1 + r * 32 + c);
      n.cell = PixelRect{c * 1024, r * 1024, (c + 1) * 1024, (r + 1) * 1024};
      n.samples_endpoint = "tcp://" + std::string(kMaxNameBytes - 6, 'h');
      m.nodes.push_back(n);
    }
  }
  ASSERT_EQ(m.nodes.size(), kMaxWallNodes);
  std::vector<uint8_t> bytes;
  EXPECT_EQ(round_trip(m, &bytes), m);
  EXPECT_LE(bytes.size(), kMaxControlChannelMessage);
}

TEST(CodecTest, WallReceiveRectIsTheCellGrownByTheMarginInsideTheImage) {
  WallLayout m;
  m.image.width = 100;
  m.image.height = 80;
  m.margin = 8;
  m.nodes = {WallNode{1, PixelRect{0, 0, 50, 40}, ""}, WallNode{2, PixelRect{50, 40, 100, 80}, ""}};
  EXPECT_EQ(wall_receive_rect(m, m.nodes[0]), (PixelRect{0, 0, 58, 48}));
  EXPECT_EQ(wall_receive_rect(m, m.nodes[1]), (PixelRect{42, 32, 100, 80}));
  m.margin = 0;
  EXPECT_EQ(wall_receive_rect(m, m.nodes[1]), m.nodes[1].cell);
}

TEST(CodecTest, LargestChunkFitsTheControlChannelLimit) {
  SceneChunk chunk;
  chunk.bytes.assign(kMaxChunkBytes, 0xab);
  chunk.scene_size = kMaxSceneBytes;
  chunk.offset = kMaxSceneBytes - kMaxChunkBytes;
  chunk.count = 4096;
  chunk.index = 4095;
  std::vector<uint8_t> bytes;
  EXPECT_EQ(round_trip(chunk, &bytes), chunk);
  EXPECT_LE(bytes.size(), kMaxControlChannelMessage);
}

TEST(CodecTest, AnyMessageDecodesToItsType) {
  Pcg32 rng(2);
  for (int round = 0; round < 20; ++round) {
    for (const Message& m : random_messages(rng)) {
      const std::vector<uint8_t> bytes = encoded(m);
      Result<Header> h = peek_header(bytes);
      ASSERT_TRUE(h.ok()) << h.error();
      EXPECT_EQ(h->type, message_type(m));
      EXPECT_EQ(h->version, kProtocolVersion);
      EXPECT_EQ(h->payload_bytes, bytes.size() - kHeaderBytes);
      Result<Message> d = decode_message(bytes);
      ASSERT_TRUE(d.ok()) << d.error();
      EXPECT_EQ(d->index(), m.index());
      EXPECT_EQ(encoded(*d), bytes) << message_type_name(message_type(m));  // a fixed point
    }
  }
}

// The header and a join, byte by byte as docs/protocol.md writes them.
TEST(CodecTest, JoinBytesAreTheDocumentedLayout) {
  Join join;
  join.sampler_id = 0x01020304;
  join.threads = 8;
  join.capabilities = kCapWorldPosition | kCapTilings;
  join.name = "ab";
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode(join, &bytes).ok());
  const std::vector<uint8_t> expected = {'A',  'F',  'R',  'P',   // magic
                                         6,    0,                 // version
                                         1,    0,                 // type: join
                                         16,   0,    0,    0,     // payload bytes
                                         0x04, 0x03, 0x02, 0x01,  // sampler_id
                                         6,    0,                 // protocol_version
                                         8,    0,                 // threads
                                         5,    0,    0,    0,     // capabilities
                                         2,    0,    'a',  'b'};  // name
  EXPECT_EQ(bytes, expected);
}

// ---------------------------------------------------------------------------------------------
// Sample batches: sizes and quantisation

TEST(CodecTest, BytesPerSampleAreTheDocumentedFigures) {
  EXPECT_EQ(packed_sample_bytes(0), 12u);
  EXPECT_EQ(packed_sample_bytes(kFieldPosition), 24u);  // the goal: <= 24 with world position
  EXPECT_EQ(packed_sample_bytes(kFieldVelocity), 18u);
  EXPECT_EQ(packed_sample_bytes(kFieldPosition | kFieldVelocity), 30u);
  Pcg32 rng(3);
  std::vector<uint8_t> bytes;
  for (uint32_t fields = 0; fields < 4; ++fields) {
    for (size_t n : {size_t(0), size_t(1), size_t(128), size_t(4096)}) {
      ASSERT_TRUE(encode(random_batch(rng, fields, n), &bytes).ok());
      EXPECT_EQ(bytes.size(), 52 + n * packed_sample_bytes(fields));
      EXPECT_EQ(bytes.size(), batch_message_bytes(fields, n));
    }
  }
  // The default batch of the sampler (128 samples) with world positions, per sample, with
  // the headers shared out: 24 + 52 / 128.
  EXPECT_NEAR(double(batch_message_bytes(kFieldPosition, 128)) / 128, 24.40625, 1e-12);
}

// The tick of a batch: the finest power of two that spans it in 32767 ticks (from the
// definition, by search from fine to coarse).
double expected_tick(double span) {
  for (int e = kMinTickExp; e <= kMaxTickExp; ++e) {
    if (span <= 32767.0 * std::ldexp(1.0, e)) return std::ldexp(1.0, e);
  }
  return NAN;
}

void expect_batch_close(const SampleBatch& in, const SampleBatch& out, double tick) {
  ASSERT_EQ(out.samples.size(), in.samples.size());
  EXPECT_EQ(out.sampler_id, in.sampler_id);
  EXPECT_EQ(out.token, in.token);
  EXPECT_EQ(out.sequence, in.sequence);
  EXPECT_EQ(out.fields, in.fields);
  for (size_t i = 0; i < in.samples.size(); ++i) {
    const Sample& a = in.samples[i];
    const Sample& b = out.samples[i];
    // Time: half a tick, plus the rounding of base + ticks * tick in double.
    ASSERT_LE(std::abs(b.time - a.time), tick / 2 + 1e-15 * std::abs(a.time)) << i;
    // Position in the image: same 1/512 bin.
    ASSERT_EQ(std::floor(double(b.x) * 512), std::floor(double(a.x) * 512)) << i;
    ASSERT_EQ(std::floor(double(b.y) * 512), std::floor(double(a.y) * 512)) << i;
    // Color: RGB9E5, half a step of the largest channel.
    const double max_c = std::max({a.color.r, a.color.g, a.color.b});
    const double step = max_c > 0 ? std::ldexp(1.0, int(std::floor(std::log2(max_c))) - 8) : 0;
    for (int c = 0; c < 3; ++c) ASSERT_LE(std::abs(double(b.color[c]) - a.color[c]), step) << i;
    if (in.fields & kFieldPosition) {
      ASSERT_EQ(b.position, a.position) << i;  // floats, exactly
      ASSERT_EQ(b.miss, a.miss) << i;
    } else {
      ASSERT_EQ(b.position, glm::vec3(0.0f));
      ASSERT_FALSE(b.miss);
    }
    if (in.fields & kFieldVelocity) {
      for (int c = 0; c < 3; ++c) {
        // Half precision: 2^-11 relative, 2^-25 absolute near zero.
        ASSERT_LE(std::abs(double(b.velocity[c]) - a.velocity[c]),
                  std::abs(double(a.velocity[c])) * std::ldexp(1.0, -11) + std::ldexp(1.0, -25))
            << i;
      }
    } else {
      ASSERT_EQ(b.velocity, glm::vec3(0.0f));
    }
  }
}

TEST(CodecTest, BatchesRoundTripWithinTheDocumentedQuantisation) {
  Pcg32 rng(4);
  std::vector<uint8_t> bytes;
  SampleBatch out;  // reused, as a receiver does
  for (int i = 0; i < 400; ++i) {
    const uint32_t fields = uint32_t(i % 4);
    const double span = std::ldexp(rng.next_double(), int(rng.next_below(40)) - 30);  // to 512 s
    const SampleBatch in = random_batch(rng, fields, 1 + rng.next_below(300), span);
    ASSERT_TRUE(encode(in, &bytes).ok());
    ASSERT_TRUE(decode(Bytes(bytes), &out).ok());
    double t_min = INFINITY, t_max = -INFINITY;
    for (const Sample& s : in.samples)
      t_min = std::min(t_min, s.time), t_max = std::max(t_max, s.time);
    expect_batch_close(in, out, expected_tick(t_max - t_min));
  }
}

TEST(CodecTest, BatchTimesAreExactWhenTheyFallOnTicks) {
  SampleBatch in;
  in.fields = kFieldPosition;
  const double base = 604800.0;  // a week into the session: absolute times stay exact
  for (int k = 0; k < 100; ++k) {
    Sample s;
    s.time = base + k * std::ldexp(1.0, -20);
    s.x = float(k);
    s.y = 1.5f;
    in.samples.push_back(s);
  }
  std::vector<uint8_t> bytes;
  SampleBatch out = round_trip(in, &bytes);
  for (int k = 0; k < 100; ++k) EXPECT_EQ(out.samples[k].time, in.samples[k].time) << k;
  // The tick byte: 99 * 2^-20 s needs 2^-28 s ticks (32767 * 2^-29 < 99 * 2^-20).
  EXPECT_EQ(int8_t(bytes[12 + 28]), -28);
}

// Found by afr_fuzz_protocol: a batch decoded with 1 s ticks, one sample at the base time and
// one 32767 ticks later, has absolute times whose difference rounds to a few ulps over 32767 s.
// The encoder must take it back (clamping into the last tick) rather than refuse the span.
TEST(CodecTest, BatchesAtTheLongestSpanEncodeAgainAfterDecoding) {
  SampleBatch in;
  in.fields = 0;
  const double base = 63144.367073921712;
  for (double offset : {0.0, 32767.0, 38.0}) {
    Sample s;
    s.time = base + offset;
    s.x = s.y = 1.5f;
    in.samples.push_back(s);
  }
  ASSERT_GT(in.samples[1].time - in.samples[0].time, 32767.0);  // rounded up: the case
  std::vector<uint8_t> bytes;
  const SampleBatch once = round_trip(in, &bytes);
  const SampleBatch twice = round_trip(once, &bytes);
  for (size_t i = 0; i < in.samples.size(); ++i) {
    EXPECT_LE(std::abs(twice.samples[i].time - in.samples[i].time), 0.5) << i;
  }
  // Half a tick more is still refused.
  in.samples[1].time = base + 32767.6;
  EXPECT_FALSE(encode(in, &bytes).ok());
}

TEST(CodecTest, OneSampleBatchIsTheDocumentedLayout) {
  SampleBatch in;
  in.sampler_id = 7;
  in.token = 0x1122334455667788;
  in.sequence = 9;
  in.fields = kFieldPosition | kFieldVelocity;
  Sample s;
  s.time = 2.0;
  s.x = 3.25f;                   // 3.25 * 512 = 1664 = 0x000680
  s.y = 32767.5f;                // 16776960 = 0xffff00
  s.color = {1.0f, 0.5f, 0.0f};  // exponent 16, step 2^-8: mantissas 256, 128, 0
  s.position = {1.0f, -2.0f, 0.5f};
  s.velocity = {1.0f, -2.0f, 0.0f};  // halves 0x3c00, 0xc000, 0x0000
  s.miss = true;
  in.samples.push_back(s);
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode(in, &bytes).ok());
  ASSERT_EQ(bytes.size(), 12u + 40 + 30);
  const uint8_t* p = bytes.data() + 12;
  uint32_t u32;
  double f64;
  std::memcpy(&u32, p, 4);
  EXPECT_EQ(u32, 7u);  // sampler_id
  std::memcpy(&u32, p + 4, 4);
  EXPECT_EQ(u32, 3u);  // fields
  std::memcpy(&f64, p + 16, 8);
  EXPECT_EQ(f64, 2.0);  // base_time
  std::memcpy(&u32, p + 24, 4);
  EXPECT_EQ(u32, 1u);                     // count
  EXPECT_EQ(int8_t(p[28]), kMinTickExp);  // a zero span takes the finest tick
  uint64_t u64;
  std::memcpy(&u64, p + 32, 8);
  EXPECT_EQ(u64, 0x1122334455667788u);  // token
  const uint8_t* q = p + 40;
  const std::vector<uint8_t> sample(q, q + 12);
  const uint32_t color = 256u | (128u << 9) | (0u << 18) | (16u << 27);
  const std::vector<uint8_t> expected = {0x80,
                                         0x06,
                                         0x00,  // x
                                         0x00,
                                         0xff,
                                         0xff,  // y
                                         0x00,
                                         0x80,  // time 0, miss
                                         uint8_t(color),
                                         uint8_t(color >> 8),
                                         uint8_t(color >> 16),
                                         uint8_t(color >> 24)};
  EXPECT_EQ(sample, expected);
  float pos[3];
  std::memcpy(pos, q + 12, 12);
  EXPECT_EQ(pos[0], 1.0f);
  EXPECT_EQ(pos[1], -2.0f);
  EXPECT_EQ(pos[2], 0.5f);
  EXPECT_EQ(std::vector<uint8_t>(q + 24, q + 30),
            (std::vector<uint8_t>{0x00, 0x3c, 0x00, 0xc0, 0x00, 0x00}));
}

TEST(CodecTest, DecodingReusesTheBatchWithoutReallocating) {
  Pcg32 rng(5);
  std::vector<uint8_t> big, small;
  ASSERT_TRUE(encode(random_batch(rng, kFieldPosition, 512), &big).ok());
  ASSERT_TRUE(encode(random_batch(rng, kFieldPosition, 100), &small).ok());
  SampleBatch out;
  ASSERT_TRUE(decode(Bytes(big), &out).ok());
  const Sample* data = out.samples.data();
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(decode(Bytes(i % 2 ? big : small), &out).ok());
    EXPECT_EQ(out.samples.data(), data);
  }
  // Encoding reuses the output's capacity too.
  const uint8_t* before = big.data();
  ASSERT_TRUE(encode(random_batch(rng, kFieldPosition, 400), &big).ok());
  EXPECT_EQ(big.data(), before);
}

TEST(CodecTest, MissTravelsOnlyWithPositions) {
  SampleBatch in;
  in.fields = 0;
  Sample s;
  s.miss = true;  // meaningless without a position: not sent
  in.samples.push_back(s);
  std::vector<uint8_t> bytes;
  const SampleBatch out = round_trip(in, &bytes);
  EXPECT_FALSE(out.samples[0].miss);
}

TEST(CodecTest, SamplesAreCheckedAgainstTheImageBounds) {
  Pcg32 rng(6);
  const ImageExtent bounds{640, 480};
  SampleBatch in = random_batch(rng, kFieldPosition, 200, 0.01, bounds);
  std::vector<uint8_t> bytes;
  const SampleBatch out = round_trip(in, &bytes, bounds);
  for (const Sample& s : out.samples) {
    EXPECT_LT(s.x, 640.0f);
    EXPECT_LT(s.y, 480.0f);
  }
  SampleBatch decoded;
  EXPECT_FALSE(decode(Bytes(bytes), &decoded, ImageExtent{64, 48}).ok());
}

// ---------------------------------------------------------------------------------------------
// Tiling snapshots

TEST(CodecTest, TilingsRoundTripExactly) {
  Pcg32 rng(7);
  std::vector<uint8_t> bytes;
  for (int i = 0; i < 100; ++i) {
    const TilingSnapshot in = random_tiling(rng, rng.next_below(200));
    const TilingSnapshot out = round_trip(in, &bytes);
    EXPECT_EQ(bytes.size(), snapshot_message_bytes(in.tiles.size()));
    EXPECT_EQ(out.sampler_id, in.sampler_id);
    EXPECT_EQ(out.token, in.token);
    EXPECT_EQ(out.time, in.time);
    EXPECT_EQ(out.region, in.region);
    ASSERT_EQ(out.tiles.size(), in.tiles.size());
    for (size_t t = 0; t < in.tiles.size(); ++t) {
      const TileInfo& a = in.tiles[t];
      const TileInfo& b = out.tiles[t];
      EXPECT_EQ(b.rect, a.rect);
      EXPECT_EQ(b.G_x, a.G_x);
      EXPECT_EQ(b.G_y, a.G_y);
      EXPECT_EQ(b.G_t, a.G_t);
      EXPECT_EQ(b.v, a.v);
      EXPECT_EQ(b.E, a.E);
      EXPECT_EQ(b.count, a.count);
      EXPECT_EQ(b.rate, a.rate);
    }
  }
}

TEST(CodecTest, ChannelLimitsHoldTheLargestMessages) {
  EXPECT_EQ(kMaxSampleChannelMessage, snapshot_message_bytes(kMaxTilesPerSnapshot));
  EXPECT_GE(kMaxSampleChannelMessage,
            batch_message_bytes(kFieldPosition | kFieldVelocity, kMaxSamplesPerBatch));
  EXPECT_GE(kMaxSampleChannelMessage, coverage_bytes(kMaxWallCoverageCells));
  Pcg32 rng(8);
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode(random_batch(rng, 3, kMaxSamplesPerBatch), &bytes).ok());
  EXPECT_LE(bytes.size(), kMaxSampleChannelMessage);
  SampleBatch too_big = random_batch(rng, 0, kMaxSamplesPerBatch + 1);
  EXPECT_FALSE(encode(too_big, &bytes).ok());
  EXPECT_TRUE(bytes.empty());
}

// ---------------------------------------------------------------------------------------------
// Display wall: coverage maps and strays between display nodes

TEST(CodecTest, WallCoverageRoundTripsExactly) {
  Pcg32 rng(9);
  std::vector<uint8_t> bytes;
  WallCoverage out;  // reused, as a receiver does
  for (int i = 0; i < 200; ++i) {
    const WallCoverage in = random_wall_coverage(rng, 1 + rng.next_below(64));
    ASSERT_TRUE(encode(in, &bytes).ok());
    EXPECT_EQ(bytes.size(), coverage_bytes(size_t(in.rect.area())));
    EXPECT_EQ(bytes.size(), wall_coverage_message_bytes(size_t(in.rect.area())));
    const Status s = decode(Bytes(bytes), &out);
    ASSERT_TRUE(s.ok()) << s.message();
    EXPECT_EQ(out, in);
  }
  // Inside a receiver's own image, its right and bottom edges included.
  WallCoverage in = random_wall_coverage(rng);
  const ImageExtent bounds{in.rect.x1, in.rect.y1};
  EXPECT_EQ(round_trip(in, &bytes, bounds), in);
}

TEST(CodecTest, WallCoverageBytesAreTheDocumentedLayout) {
  WallCoverage m;
  m.node_id = 0x01020304;
  m.time = 2.0;
  m.rect = PixelRect{3, 4, 5, 5};  // two pixels
  m.cells = {1.0f, 0.5f, 0.0f, 0.0f};
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode(m, &bytes).ok());
  const std::vector<uint8_t> expected = {
      'A',  'F',  'R',  'P',  6,    0,    14,   0,    40, 0, 0, 0,  // header: version 6, type 14
      0x04, 0x03, 0x02, 0x01,                                       // node_id
      0,    0,    0,    0,    0,    0,    0x00, 0x40,               // time: 2.0
      3,    0,    4,    0,    5,    0,    5,    0,                  // rect x0, y0, x1, y1
      2,    0,    0,    0,                                          // cell_count
      0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x3f,  // (3, 4): count 1, growth_sum 0.5
      0,    0,    0,    0,    0,    0,    0,    0};    // (4, 4): nothing reached it
  EXPECT_EQ(bytes, expected);
}

TEST(CodecTest, LargestWallCoverageFitsTheSampleChannelLimit) {
  WallCoverage m;
  m.node_id = kMaxWallNodes;
  m.time = 1e6;
  m.rect = PixelRect{kMaxImageSize - 512, kMaxImageSize - 512, kMaxImageSize, kMaxImageSize};
  ASSERT_EQ(m.rect.area(), int64_t(kMaxWallCoverageCells));
  m.cells.assign(2 * size_t(kMaxWallCoverageCells), 0.25f);
  std::vector<uint8_t> bytes;
  EXPECT_EQ(round_trip(m, &bytes), m);
  EXPECT_EQ(bytes.size(), 12u + 24 + 8 * size_t(kMaxWallCoverageCells));  // 2 MiB + 36
  EXPECT_LE(bytes.size(), kMaxSampleChannelMessage);
}

TEST(CodecTest, WallCoverageDecodesAsAnyMessage) {
  Pcg32 rng(10);
  const WallCoverage in = random_wall_coverage(rng);
  const std::vector<uint8_t> bytes = encoded(in);
  Result<Message> m = decode_message(bytes);
  ASSERT_TRUE(m.ok()) << m.error();
  ASSERT_TRUE(std::holds_alternative<WallCoverage>(*m));
  EXPECT_EQ(std::get<WallCoverage>(*m), in);
  EXPECT_EQ(message_type(*m), MessageType::kWallCoverage);
  EXPECT_STREQ(message_type_name(MessageType::kWallCoverage), "wall_coverage");
  // The bounds reach the coverage decoder, as they reach those of batches and snapshots.
  const ImageExtent inside{in.rect.x1, in.rect.y1};
  EXPECT_TRUE(decode_message(bytes, inside).ok());
  const ImageExtent outside{in.rect.x1 - 1, in.rect.y1};
  const Result<Message> refused = decode_message(bytes, outside);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().find("wall_coverage.rect"), std::string::npos) << refused.error();
}

TEST(CodecTest, DecodingReusesTheCoverageWithoutReallocating) {
  Pcg32 rng(11);
  WallCoverage big = random_wall_coverage(rng), small = random_wall_coverage(rng);
  big.rect = PixelRect{0, 0, 16, 16};
  big.cells.assign(2 * 256, 1.0f);
  small.rect = PixelRect{8, 8, 10, 9};
  small.cells.assign(4, 2.0f);
  const std::vector<uint8_t> big_bytes = encoded(big), small_bytes = encoded(small);
  WallCoverage out;
  ASSERT_TRUE(decode(Bytes(big_bytes), &out).ok());
  const float* data = out.cells.data();
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(decode(Bytes(i % 2 ? big_bytes : small_bytes), &out).ok());
    EXPECT_EQ(out.cells.data(), data);
    EXPECT_EQ(out, i % 2 ? big : small);
  }
}

// Strays one wall node forwards to another are ordinary batches with sampler_id 0, an id the
// coordinator never assigns: the sample channel takes them like any other batch.
TEST(CodecTest, SampleBatchesFromAWallPeerAreValid) {
  Pcg32 rng(12);
  SampleBatch in = random_batch(rng, kFieldPosition, 20);
  in.sampler_id = kWallPeerSamplerId;
  EXPECT_TRUE(validate(in).ok());
  std::vector<uint8_t> bytes;
  const SampleBatch out = round_trip(in, &bytes);
  EXPECT_EQ(out.sampler_id, 0u);
  EXPECT_EQ(out.samples.size(), in.samples.size());
  Result<Message> m = decode_message(bytes);
  ASSERT_TRUE(m.ok()) << m.error();
  EXPECT_EQ(std::get<SampleBatch>(*m).sampler_id, kWallPeerSamplerId);
}

}  // namespace
}  // namespace afr::protocol
