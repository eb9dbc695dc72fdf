// The binding of sample-channel messages to members (member_gate.h), alone and in the display's
// ingest (run_ingest over a real sample channel, plain and with CurveZMQ): batches and
// snapshots that name another member or no member are dropped and counted, and every real
// sample still reaches the sink.
#include <afr/display/service/display_service.h>
#include <afr/display/service/member_gate.h>
#include <afr/display/service/metrics.h>
#include <afr/protocol/channels.h>

#include "process.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace afr::service {
namespace {

using protocol::Context;
using protocol::SampleReceiver;
using protocol::SampleSender;
using protocol::Security;

TEST(MemberGateTest, OnlyTheNamedMembersTokenAndKeyPass) {
  MemberGate gate;
  gate.admit(1, 111, "");
  gate.admit(2, 222, "KEY-OF-TWO");
  EXPECT_EQ(gate.check(1, 111, "", 10), MemberGate::Verdict::kMember);
  EXPECT_EQ(gate.check(1, 222, "", 10), MemberGate::Verdict::kSpoofed);  // another's token
  EXPECT_EQ(gate.check(1, 0, "", 10), MemberGate::Verdict::kSpoofed);
  EXPECT_EQ(gate.check(2, 222, "KEY-OF-TWO", 5), MemberGate::Verdict::kMember);
  EXPECT_EQ(gate.check(2, 222, "KEY-OF-ONE", 5),
            MemberGate::Verdict::kSpoofed);  // its token, another key
  EXPECT_EQ(gate.check(2, 222, "", 5), MemberGate::Verdict::kSpoofed);
  EXPECT_EQ(gate.check(3, 333, "", 5), MemberGate::Verdict::kNonMember);
  EXPECT_EQ(gate.check(0, 0, "", 5), MemberGate::Verdict::kNonMember);
  // Only accepted samples count; taking them resets.
  const auto taken = gate.take_accepted();
  EXPECT_EQ(taken, (std::vector<std::pair<uint32_t, uint64_t>>{{1, 10}, {2, 5}}));
  EXPECT_TRUE(gate.take_accepted().empty());
  gate.revoke(1);
  EXPECT_EQ(gate.check(1, 111, "", 10), MemberGate::Verdict::kNonMember);
}

// Regions: none (empty) from a member's admission until the coordinator gives it one; a wall
// follower takes them with the lead's member list, where members that stay keep their counts.
TEST(MemberGateTest, AMembersRegionIsEmptyUntilGivenAndAFollowerTakesThemFromTheList) {
  MemberGate gate;
  gate.admit(1, 111, "");
  EXPECT_EQ(gate.region(1), PixelRect{});
  EXPECT_EQ(gate.region(2), std::nullopt);  // no member
  gate.set_region(1, PixelRect{0, 0, 32, 64});
  EXPECT_EQ(gate.region(1), (PixelRect{0, 0, 32, 64}));
  EXPECT_EQ(gate.check(1, 111, "", 7), MemberGate::Verdict::kMember);
  gate.replace({{1, 111, "", PixelRect{0, 0, 16, 64}}, {2, 222, "", PixelRect{16, 0, 64, 64}}});
  EXPECT_EQ(gate.region(1), (PixelRect{0, 0, 16, 64}));
  EXPECT_EQ(gate.region(2), (PixelRect{16, 0, 64, 64}));
  EXPECT_EQ(gate.take_accepted(), (std::vector<std::pair<uint32_t, uint64_t>>{{1, 7}}));
  gate.replace({{2, 222, "", PixelRect{}}});  // 1 left; 2 listed while it waits for a region
  EXPECT_EQ(gate.region(1), std::nullopt);
  EXPECT_EQ(gate.region(2), PixelRect{});
}

// Counts what reaches the store, by sampler id.
class CountingSink final : public SampleSink {
 public:
  void on_batch(SampleBatch&& b) override {
    std::lock_guard<std::mutex> lock(mutex_);
    samples_[b.sampler_id] += b.samples.size();
  }
  void on_tiling(TilingSnapshot&& t) override {
    std::lock_guard<std::mutex> lock(mutex_);
    ++tilings_[t.sampler_id];
    last_tiling_[t.sampler_id] = std::move(t);
  }
  void on_sampler_gone(uint32_t id) override {
    std::lock_guard<std::mutex> lock(mutex_);
    gone_.push_back(id);
  }
  std::optional<TilingSnapshot> last_tiling(uint32_t id) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = last_tiling_.find(id);
    return it == last_tiling_.end() ? std::nullopt : std::optional<TilingSnapshot>(it->second);
  }
  std::vector<uint32_t> gone() {
    std::lock_guard<std::mutex> lock(mutex_);
    return gone_;
  }
  uint64_t samples(uint32_t id) {
    std::lock_guard<std::mutex> lock(mutex_);
    return samples_[id];
  }
  uint64_t tilings(uint32_t id) {
    std::lock_guard<std::mutex> lock(mutex_);
    return tilings_[id];
  }
  uint64_t total_samples() {
    std::lock_guard<std::mutex> lock(mutex_);
    uint64_t n = 0;
    for (const auto& [id, k] : samples_) n += k;
    return n;
  }

 private:
  std::mutex mutex_;
  std::map<uint32_t, uint64_t> samples_, tilings_;
  std::map<uint32_t, TilingSnapshot> last_tiling_;
  std::vector<uint32_t> gone_;
};

SampleBatch batch(uint32_t id, uint64_t token, uint64_t sequence, size_t n) {
  SampleBatch b;
  b.sampler_id = id;
  b.token = token;
  b.sequence = sequence;
  b.samples.resize(n);
  for (size_t i = 0; i < n; ++i) {
    b.samples[i].time = 1.0 + 1e-6 * double(i);
    b.samples[i].x = float(i % 64) + 0.5f;
    b.samples[i].y = 3.5f;
  }
  return b;
}

TilingSnapshot tiling(uint32_t id, uint64_t token) {
  TilingSnapshot t;
  t.sampler_id = id;
  t.token = token;
  t.time = 1.0;
  t.region = PixelRect{0, 0, 64, 64};
  TileInfo tile;
  tile.rect = t.region;
  t.tiles.push_back(tile);
  return t;
}

// The ingest thread of a display with the given gate, on a sample channel bound at `endpoint`.
class Ingest {
 public:
  // `wall`: the ingest of a wall's node (its coverage inbox and key), else of a single display.
  Ingest(Context& context, const std::string& endpoint, const Security& security, MemberGate& gate,
         std::optional<WallPeers> wall = std::nullopt)
      : receiver_(context, endpoint, security), wall_(std::move(wall)) {
    receiver_.set_image_bounds({64, 64});
    thread_ = std::thread([this, &gate] {
      run_ingest(receiver_, sink_, metrics_, &gate, running_, {}, wall_ ? &*wall_ : nullptr);
    });
  }
  ~Ingest() {
    running_ = false;
    thread_.join();
  }
  std::string endpoint() const { return receiver_.endpoint(); }
  CountingSink& sink() { return sink_; }
  ServiceMetrics& metrics() { return metrics_; }

 private:
  SampleReceiver receiver_;
  std::optional<WallPeers> wall_;
  CountingSink sink_;
  ServiceMetrics metrics_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

void send_all(SampleSender& s, const SampleBatch& b) {
  ASSERT_TRUE(s.send(b, {64, 64}).ok());
  ASSERT_TRUE(s.flush(10000));
}

// The attack of issue 19 on plaintext channels: a peer that sends batches naming member 1 (the
// id is in the batch header for anyone to write) and batches under an id nobody holds. Neither
// reaches the store; each is counted by cause; every batch of the real member arrives.
TEST(DisplayIngestTest, SpoofedAndNonMemberBatchesAreDroppedAndCountedAndNoRealSampleIsLost) {
  Context context;
  MemberGate gate;
  const uint64_t token = 0x5eed5eed5eed5eedull;
  gate.admit(1, token, "");
  Ingest ingest(context, "tcp://127.0.0.1:*", Security::none(), gate);
  Context peer_context;
  SampleSender real(peer_context, ingest.endpoint());
  SampleSender hostile(peer_context, ingest.endpoint());
  for (uint64_t k = 0; k < 50; ++k) {
    send_all(real, batch(1, token, k, 100));
    send_all(hostile, batch(1, token + 1, k, 70));  // member 1's id, a guessed token
    send_all(hostile, batch(1, 0, k, 70));          // member 1's id, no token
    send_all(hostile, batch(9, token, k, 30));      // no member, even with a real token
  }
  ASSERT_TRUE(real.send(tiling(1, token), {64, 64}).ok());
  ASSERT_TRUE(hostile.send(tiling(1, 77), {64, 64}).ok());
  ASSERT_TRUE(hostile.send(tiling(9, 77), {64, 64}).ok());
  ASSERT_TRUE(real.flush(10000) && hostile.flush(10000));
  ASSERT_TRUE(afr::testing::wait_until(
      [&] {
        const DisplayMetrics d = ingest.metrics().display();
        return ingest.sink().samples(1) == 5000 && d.spoofed_batches == 100 &&
               d.unknown_sampler_batches == 50 && d.spoofed_tilings == 1 &&
               d.unknown_sampler_tilings == 1 && ingest.sink().tilings(1) == 1;
      },
      20.0));
  const DisplayMetrics d = ingest.metrics().display();
  EXPECT_EQ(d.spoofed_samples, 100u * 70u);
  EXPECT_EQ(d.unknown_sampler_samples, 50u * 30u);
  EXPECT_EQ(ingest.sink().total_samples(), 5000u);  // nothing but the member's own
  EXPECT_EQ(gate.take_accepted(), (std::vector<std::pair<uint32_t, uint64_t>>{{1, 5000}}));
  const std::vector<SamplerMetrics> ss = ingest.metrics().samplers();
  ASSERT_EQ(ss.size(), 1u);
  EXPECT_EQ(ss[0].samples, 5000u);
  EXPECT_EQ(ss[0].sequence_gaps, 0u);  // the spoofed sequences did not touch the member's
}

// A member describes its own region only: a snapshot that claims the whole image reaches the
// sink cut to the region the coordinator gave the member, and with nothing in it while the
// member has no region yet. And a member that is gone is forgotten by the sink, while the
// members that stay are not.
TEST(DisplayIngestTest, AMembersTilingIsCutToItsRegionAndForgottenOnceItIsGone) {
  Context context;
  MemberGate gate;
  gate.admit(1, 111, "");
  gate.admit(2, 222, "");
  gate.set_region(1, PixelRect{0, 0, 32, 64});
  Ingest ingest(context, "tcp://127.0.0.1:*", Security::none(), gate);
  Context peer_context;
  SampleSender one(peer_context, ingest.endpoint());
  SampleSender two(peer_context, ingest.endpoint());
  TilingSnapshot whole = tiling(1, 111);  // region: the whole 64 x 64 image
  whole.tiles.clear();
  for (const PixelRect& r :
       {PixelRect{0, 0, 16, 64}, PixelRect{16, 0, 48, 64}, PixelRect{48, 0, 64, 64}}) {
    TileInfo tile;
    tile.rect = r;
    tile.v = 1.0f;
    whole.tiles.push_back(tile);
  }
  ASSERT_TRUE(one.send(whole, {64, 64}).ok());
  ASSERT_TRUE(two.send(tiling(2, 222), {64, 64}).ok());
  ASSERT_TRUE(one.flush(10000) && two.flush(10000));
  ASSERT_TRUE(afr::testing::wait_until(
      [&] { return ingest.sink().tilings(1) == 1 && ingest.sink().tilings(2) == 1; }, 20.0));
  const TilingSnapshot cut = *ingest.sink().last_tiling(1);
  EXPECT_EQ(cut.region, (PixelRect{0, 0, 32, 64}));
  ASSERT_EQ(cut.tiles.size(), 2u);  // the third lay outside the region
  EXPECT_EQ(cut.tiles[0].rect, (PixelRect{0, 0, 16, 64}));
  EXPECT_EQ(cut.tiles[1].rect, (PixelRect{16, 0, 32, 64}));
  // Member 2 has no region yet (its join waits for its cut): nothing of its snapshot is kept.
  EXPECT_TRUE(ingest.sink().last_tiling(2)->region.empty());
  EXPECT_TRUE(ingest.sink().last_tiling(2)->tiles.empty());

  EXPECT_TRUE(ingest.sink().gone().empty());
  gate.revoke(1);
  ASSERT_TRUE(afr::testing::wait_until([&] { return !ingest.sink().gone().empty(); }, 20.0));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // a few more checks
  EXPECT_EQ(ingest.sink().gone(), std::vector<uint32_t>{1});
}

// With CurveZMQ the batch is bound to its connection's authenticated key as well: another
// allowed sampler that learned member 1's id and token (say, from a packet capture before keys
// were used) still cannot send as member 1.
TEST(DisplayIngestTest, WithCurveABatchFromAnotherAllowedKeyIsDroppedEvenWithTheToken) {
  ASSERT_TRUE(protocol::curve_available());
  const protocol::CurveKeyPair display = protocol::generate_curve_keypair();
  const protocol::CurveKeyPair one = protocol::generate_curve_keypair();
  const protocol::CurveKeyPair other = protocol::generate_curve_keypair();
  Context context;
  context.allow_curve_clients({one.public_key, other.public_key});
  MemberGate gate;
  const uint64_t token = 42;
  gate.admit(1, token, one.public_key);
  Ingest ingest(context, "tcp://127.0.0.1:*", Security::server(display), gate);
  Context peer_context;
  SampleSender real(peer_context, ingest.endpoint(), Security::client(one, display.public_key));
  SampleSender thief(peer_context, ingest.endpoint(), Security::client(other, display.public_key));
  for (uint64_t k = 0; k < 20; ++k) {
    send_all(real, batch(1, token, k, 50));
    send_all(thief, batch(1, token, k, 40));
  }
  ASSERT_TRUE(afr::testing::wait_until(
      [&] {
        return ingest.sink().samples(1) == 1000 && ingest.metrics().display().spoofed_batches == 20;
      },
      20.0));
  EXPECT_EQ(ingest.sink().total_samples(), 1000u);
  EXPECT_EQ(ingest.metrics().display().spoofed_samples, 800u);
}

protocol::WallCoverage coverage(uint32_t node) {
  protocol::WallCoverage c;
  c.node_id = node;
  c.time = 1.0;
  c.rect = PixelRect{0, 0, 4, 4};
  c.cells.assign(2 * 16, 1.0f);
  return c;
}

// A wall's strays (sampler id 0) and coverage name no member and carry no token: with CurveZMQ
// what speaks for a node of the wall is the display's key pair, which every node holds. A
// sampler whose own key is allowed cannot pass batches off as strays (stored outside any
// member's accounting) nor push coverage into a node's image; the wall's key can, and the
// sampler's own batches still arrive. A display that is no wall takes neither from anyone:
// strays are from no member there.
TEST(DisplayIngestTest, WithCurveOnlyTheWallsKeySendsStraysAndCoverage) {
  ASSERT_TRUE(protocol::curve_available());
  const protocol::CurveKeyPair display = protocol::generate_curve_keypair();
  const protocol::CurveKeyPair one = protocol::generate_curve_keypair();
  Context context;
  context.allow_curve_clients({display.public_key, one.public_key});
  MemberGate gate;
  const uint64_t token = 42;
  gate.admit(1, token, one.public_key);
  WallCoverageInbox inbox;
  Ingest node(context, "tcp://127.0.0.1:*", Security::server(display), gate,
              WallPeers{&inbox, display.public_key});
  Ingest single(context, "tcp://127.0.0.1:*", Security::server(display), gate);
  Context peer_context;
  // The senders live to the end: a sender's socket closed early could drop what it still holds.
  std::vector<std::unique_ptr<SampleSender>> senders;
  for (Ingest* ingest : {&node, &single}) {
    SampleSender& peer = *senders.emplace_back(std::make_unique<SampleSender>(
        peer_context, ingest->endpoint(), Security::client(display, display.public_key)));
    SampleSender& sampler = *senders.emplace_back(std::make_unique<SampleSender>(
        peer_context, ingest->endpoint(), Security::client(one, display.public_key)));
    for (uint64_t k = 0; k < 20; ++k) {
      send_all(peer, batch(protocol::kWallPeerSamplerId, 0, k, 30));
      send_all(sampler, batch(protocol::kWallPeerSamplerId, 0, k, 40));
      send_all(sampler, batch(1, token, k, 50));
    }
    ASSERT_TRUE(peer.send(coverage(2), {64, 64}).ok());
    ASSERT_TRUE(sampler.send(coverage(3), {64, 64}).ok());
    ASSERT_TRUE(peer.flush(10000) && sampler.flush(10000));
  }
  ASSERT_TRUE(afr::testing::wait_until(
      [&] {
        const DisplayMetrics d = node.metrics().display();
        return node.sink().samples(1) == 1000 && d.spoofed_batches == 20 &&
               d.rejected_samples_channel == 1 && d.wall_exchange.strays_in == 600 &&
               d.wall_exchange.coverage_in == 1;
      },
      20.0))
      << node.metrics().display().spoofed_batches << " spoofed, "
      << node.metrics().display().wall_exchange.strays_in << " strays in, "
      << node.sink().samples(protocol::kWallPeerSamplerId) << " stored, "
      << node.metrics().display().rejected_samples_channel << " rejected";
  ASSERT_TRUE(afr::testing::wait_until(
      [&] {
        const DisplayMetrics d = single.metrics().display();
        return single.sink().samples(1) == 1000 && d.unknown_sampler_batches == 40 &&
               d.rejected_samples_channel == 2;
      },
      20.0))
      << single.metrics().display().unknown_sampler_batches;
  EXPECT_EQ(node.sink().samples(protocol::kWallPeerSamplerId), 600u);  // the wall's own strays only
  EXPECT_EQ(node.metrics().display().spoofed_samples, 20u * 40u);
  std::vector<protocol::WallCoverage> got;
  inbox.take(&got);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].node_id, 2u);
  EXPECT_EQ(single.sink().samples(protocol::kWallPeerSamplerId), 0u);
  EXPECT_EQ(single.metrics().display().wall_exchange.strays_in, 0u);
}

}  // namespace
}  // namespace afr::service
