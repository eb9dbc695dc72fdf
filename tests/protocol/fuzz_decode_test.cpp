// Runs the libFuzzer entry point (tests/fuzz/protocol_fuzz.cpp) with any compiler: over the
// round-trip corpus, every truncation and single-byte mutation of it, and random bytes. The entry
// point aborts on a broken invariant; this test checks the verdicts it can know in advance.
//
// With AFR_FUZZ_CORPUS_DIR set, it also writes the seeds of the clang fuzzer there.
#include "test_messages.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace afr::protocol::fuzz {
bool check_one(const uint8_t* data, size_t size);
}  // namespace afr::protocol::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace afr::protocol {
namespace {

using namespace testing;

std::vector<std::vector<uint8_t>> corpus(int rounds) {
  Pcg32 rng(99);
  std::vector<std::vector<uint8_t>> all;
  for (int r = 0; r < rounds; ++r) {
    for (const Message& m : random_messages(rng)) all.push_back(encoded(m));
  }
  return all;
}

TEST(FuzzDecodeTest, CorpusIsAccepted) {
  for (const auto& bytes : corpus(40)) {
    EXPECT_TRUE(fuzz::check_one(bytes.data(), bytes.size()));
    EXPECT_EQ(LLVMFuzzerTestOneInput(bytes.data(), bytes.size()), 0);
  }
}

// The seeds of tests/fuzz/corpus/protocol: two messages of every type (every batch field
// combination), written to $AFR_FUZZ_CORPUS_DIR when it is set.
TEST(FuzzDecodeTest, SeedsAreAccepted) {
  const auto seeds = corpus(2);
  const char* dir = std::getenv("AFR_FUZZ_CORPUS_DIR");
  for (size_t i = 0; i < seeds.size(); ++i) {
    EXPECT_TRUE(fuzz::check_one(seeds[i].data(), seeds[i].size()));
    if (dir == nullptr) continue;
    const std::string name = fmt::format("/seed-{:02}-type-{}", i, unsigned(seeds[i][6]));
    std::ofstream out(std::string(dir) + name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(seeds[i].data()), std::streamsize(seeds[i].size()));
  }
}

// The fuzzer's protocol findings (tests/fuzz/regressions/protocol) replay the path they broke
// only while they speak this protocol's version: any other is refused at the header. A version
// bump rewrites their version field (bytes 4-5; the layouts they exercise did not change), and
// this test says when one was missed; the fuzzer's dictionary must name the version too.
TEST(FuzzDecodeTest, RegressionInputsSpeakTheCurrentVersion) {
  size_t n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(AFR_PROTOCOL_REGRESSIONS)) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
    const Result<Header> h = peek_header(bytes);
    ASSERT_TRUE(h.ok()) << entry.path() << ": " << h.status().message();
    EXPECT_EQ(h->version, kProtocolVersion) << entry.path();
    ++n;
  }
  EXPECT_GE(n, 1u);
  std::ifstream dict(AFR_PROTOCOL_DICT);
  const std::string text((std::istreambuf_iterator<char>(dict)), std::istreambuf_iterator<char>());
  const std::string entry =
      fmt::format("\"AFRP\\x{:02x}\\x{:02x}\"", kProtocolVersion & 0xff, kProtocolVersion >> 8);
  EXPECT_NE(text.find(entry), std::string::npos) << entry << " is not in " << AFR_PROTOCOL_DICT;
}

TEST(FuzzDecodeTest, TruncationsAreRejected) {
  for (const auto& bytes : corpus(3)) {
    for (size_t n = 0; n < bytes.size(); ++n) EXPECT_FALSE(fuzz::check_one(bytes.data(), n));
  }
}

TEST(FuzzDecodeTest, SingleByteMutationsKeepTheInvariants) {
  Pcg32 rng(100);
  size_t accepted = 0, total = 0;
  for (auto bytes : corpus(3)) {
    for (size_t at = 0; at < bytes.size(); ++at) {
      const uint8_t original = bytes[at];
      for (uint8_t v : {uint8_t(original ^ 0x01), uint8_t(original ^ 0x80), uint8_t(0x00),
                        uint8_t(0xff), uint8_t(rng.next_u32())}) {
        bytes[at] = v;
        accepted += fuzz::check_one(bytes.data(), bytes.size());
        ++total;
      }
      bytes[at] = original;
    }
  }
  // Many mutations land in free-valued fields (ids, names, colors) and stay valid; many do not.
  EXPECT_GT(accepted, 0u);
  EXPECT_LT(accepted, total);
}

TEST(FuzzDecodeTest, RandomBytesKeepTheInvariants) {
  Pcg32 rng(101);
  std::vector<uint8_t> bytes;
  for (int i = 0; i < 20000; ++i) {
    bytes.resize(rng.next_below(400));
    for (uint8_t& b : bytes) b = uint8_t(rng.next_u32());
    // Half of them with a valid header, so the payload checks are what is exercised.
    if (i % 2 && bytes.size() >= kHeaderBytes) {
      const uint32_t n = uint32_t(bytes.size() - kHeaderBytes);
      const uint16_t type = uint16_t(1 + rng.next_below(kLastMessageType));
      const uint8_t header[12] = {
          'A', 'F', 'R', 'P', 0, 0, uint8_t(type), 0, uint8_t(n), uint8_t(n >> 8), 0, 0};
      std::copy(header, header + 12, bytes.begin());
      // The version this build speaks, so that the payloads reach their decoders (a literal
      // version here went stale with the first version bump and stopped them all at the header).
      bytes[4] = uint8_t(kProtocolVersion);
      bytes[5] = uint8_t(kProtocolVersion >> 8);
      const Result<Message> m = decode_message(bytes);
      EXPECT_TRUE(m.ok() || m.error().find("unsupported protocol version") == std::string::npos)
          << m.error();
    }
    fuzz::check_one(bytes.data(), bytes.size());
  }
}

}  // namespace
}  // namespace afr::protocol
