// libFuzzer target for the protocol decoder: every message type's decode entry on every input.
// Built as afr_fuzz_protocol with clang (tests/fuzz/CMakeLists.txt); the protocol tests
// (tests/protocol/fuzz_decode_test.cpp) run the same entry point over a corpus with any
// compiler. Besides "no crash, no out-of-bounds read", it checks that everything the decoder
// accepts the encoder accepts too, and that it survives a second trip: bytes unchanged for
// exact messages, values unchanged (times within a tick) for batches.
#include <afr/common/check.h>
#include <afr/protocol/codec.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <variant>
#include <vector>

namespace afr::protocol::fuzz {

namespace {

void check_batch_trip(const SampleBatch& a, const ImageExtent& bounds) {
  std::vector<uint8_t> bytes;
  AFR_CHECK(encode(a, &bytes, bounds).ok());
  SampleBatch b;
  AFR_CHECK(decode(Bytes(bytes), &b, bounds).ok());
  AFR_CHECK(a.samples.size() == b.samples.size() && a.fields == b.fields);
  double lo = INFINITY, hi = -INFINITY;
  for (const Sample& s : a.samples) lo = std::min(lo, s.time), hi = std::max(hi, s.time);
  // At least the tick of the second encoding: the finest, or within a factor 2 of span / 32767.
  const double tick = std::max(std::ldexp(1.0, kMinTickExp), (hi - lo) / 32767.0 * 2.0);
  for (size_t i = 0; i < a.samples.size(); ++i) {
    const Sample& s = a.samples[i];
    const Sample& t = b.samples[i];
    // Decoded values are representable, so a second trip keeps them.
    AFR_CHECK(s.x == t.x && s.y == t.y && s.color == t.color && s.position == t.position &&
              s.velocity == t.velocity && s.miss == t.miss);
    AFR_CHECK(std::abs(s.time - t.time) <= tick + 1e-15 * std::abs(s.time) + 1e-300);
  }
}

}  // namespace

// Returns whether the message was accepted.
bool check_one(const uint8_t* data, size_t size) {
  const Bytes bytes(data, size);
  // Every typed decoder must cope with every input.
  {
    Join a;
    Welcome b;
    SceneRequest c;
    SceneChunk d;
    RegionAssignment e;
    View f;
    SampleBatch g;
    TilingSnapshot h;
    SamplerStats i;
    Heartbeat j;
    Leave k;
    DisplayJoin l;
    WallLayout n;
    WallCoverage o;
    (void)decode(bytes, &a);
    (void)decode(bytes, &b);
    (void)decode(bytes, &c);
    (void)decode(bytes, &d);
    (void)decode(bytes, &e);
    (void)decode(bytes, &f);
    (void)decode(bytes, &g, ImageExtent{17, 9});
    (void)decode(bytes, &h, ImageExtent{17, 9});
    (void)decode(bytes, &i);
    (void)decode(bytes, &j);
    (void)decode(bytes, &k);
    (void)decode(bytes, &l);
    (void)decode(bytes, &n);
    (void)decode(bytes, &o, ImageExtent{17, 9});
  }
  const Result<Message> m = decode_message(bytes);
  const Result<Header> h = peek_header(bytes);
  if (!m.ok()) return false;
  AFR_CHECK(h.ok() && h->type == message_type(*m) && h->version == kProtocolVersion);
  std::visit(
      [&](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, SampleBatch>) {
          check_batch_trip(v, kMaxImageExtent);
        } else {
          // Exact messages: the encoding of what was decoded is the input, byte for byte.
          std::vector<uint8_t> again;
          AFR_CHECK(encode(v, &again).ok());
          AFR_CHECK(again.size() == size && std::equal(again.begin(), again.end(), data));
        }
      },
      *m);
  return true;
}

}  // namespace afr::protocol::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  afr::protocol::fuzz::check_one(data, size);
  return 0;
}
