// CurveZMQ on the afr channels: an allowed sampler key connects and is identified, an unknown
// key is refused by the ZAP handler (and reported), and a server without an allow-list is
// refused outright, because libzmq would admit any key.
#include <afr/protocol/channels.h>

#include <afr/common/error.h>

#include "test_messages.h"

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <thread>

namespace afr::protocol {
namespace {

using namespace testing;

class CurveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(curve_available());
    display_ = generate_curve_keypair();
    allowed_ = generate_curve_keypair();
    stranger_ = generate_curve_keypair();
    context_.allow_curve_clients({allowed_.public_key}, [this](const ZapDecision& d) {
      std::lock_guard<std::mutex> lock(mutex_);
      decisions_.push_back(d);
    });
  }

  std::vector<ZapDecision> decisions() {
    std::lock_guard<std::mutex> lock(mutex_);
    return decisions_;
  }

  CurveKeyPair display_, allowed_, stranger_;
  // Declared before the context, so destroyed after it: its authentication thread calls back
  // into them until the context is gone.
  std::mutex mutex_;
  std::vector<ZapDecision> decisions_;
  Context context_;
};

TEST_F(CurveTest, AllowedKeyConnectsAndIsIdentified) {
  ControlServer server(context_, "tcp://127.0.0.1:*", Security::server(display_));
  Context sampler_context;  // a different process, as far as ZeroMQ can tell
  ControlClient client(sampler_context, server.endpoint(),
                       Security::client(allowed_, display_.public_key));
  Pcg32 rng(1);
  const Join join = random_join(rng);
  ASSERT_TRUE(client.send(join).ok());
  std::optional<ControlServer::Incoming> in = server.receive(3000);
  ASSERT_TRUE(in.has_value());
  ASSERT_TRUE(in->message.ok()) << in->message.error();
  EXPECT_EQ(std::get<Join>(*in->message), join);
  EXPECT_EQ(in->public_key, allowed_.public_key);  // the ZAP user id
  EXPECT_GE(context_.zap()->accepted, 1u);
  EXPECT_EQ(context_.zap()->refused, 0u);

  const Welcome welcome = random_welcome(rng);
  ASSERT_TRUE(server.send(in->peer, welcome).ok());
  std::optional<Result<Message>> back = client.receive(3000);
  ASSERT_TRUE(back.has_value() && back->ok());
  EXPECT_EQ(std::get<Welcome>(**back), welcome);
}

// A wildcard bind listens on IPv6 and IPv4 both (docs/service.md); an IPv4 peer is still
// reported by its IPv4 address, not as the IPv4-mapped IPv6 one ("::ffff:127.0.0.1").
TEST_F(CurveTest, AnIpv4PeerOfAWildcardBindIsReportedByItsIpv4Address) {
  ControlServer everywhere(context_, "tcp://*:*", Security::server(display_));
  const std::string port = everywhere.endpoint().substr(everywhere.endpoint().rfind(':') + 1);
  Context sampler_context;
  ControlClient stranger(sampler_context, "tcp://127.0.0.1:" + port,
                         Security::client(stranger_, display_.public_key));
  Pcg32 rng(3);
  ASSERT_TRUE(stranger.send(random_join(rng)).ok());
  EXPECT_FALSE(everywhere.receive(1000).has_value());
  const std::vector<ZapDecision> d = decisions();
  ASSERT_FALSE(d.empty());
  EXPECT_FALSE(d[0].accepted);
  EXPECT_EQ(d[0].address, "127.0.0.1");
}

TEST_F(CurveTest, UnknownKeyIsRefusedAndReported) {
  ControlServer server(context_, "tcp://127.0.0.1:*", Security::server(display_));
  Context sampler_context;
  ControlClient stranger(sampler_context, server.endpoint(),
                         Security::client(stranger_, display_.public_key));
  Pcg32 rng(2);
  ASSERT_TRUE(stranger.send(random_join(rng)).ok());
  EXPECT_FALSE(server.receive(1000).has_value());
  ASSERT_GE(context_.zap()->refused, 1u);
  EXPECT_EQ(context_.zap()->accepted, 0u);
  const std::vector<ZapDecision> d = decisions();
  ASSERT_FALSE(d.empty());
  EXPECT_FALSE(d[0].accepted);
  EXPECT_EQ(d[0].mechanism, "CURVE");
  EXPECT_EQ(d[0].public_key, stranger_.public_key);
  EXPECT_EQ(d[0].address, "127.0.0.1");

  // libzmq ends a session refused by ZAP for good (no reconnection), so the decision is made
  // once per socket.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(context_.zap()->refused, 1u);

  // The allow-list can change while running: a new socket with the same key is admitted.
  context_.allow_curve_clients({allowed_.public_key, stranger_.public_key});
  ControlClient again(sampler_context, server.endpoint(),
                      Security::client(stranger_, display_.public_key));
  ASSERT_TRUE(again.send(random_join(rng)).ok());
  std::optional<ControlServer::Incoming> in = server.receive(3000);
  ASSERT_TRUE(in.has_value());
  EXPECT_EQ(in->public_key, stranger_.public_key);
}

TEST_F(CurveTest, ClientWithTheWrongServerKeyGetsNowhere) {
  ControlServer server(context_, "tcp://127.0.0.1:*", Security::server(display_));
  Context sampler_context;
  ControlClient client(sampler_context, server.endpoint(),
                       Security::client(allowed_, stranger_.public_key));  // not the display's
  Pcg32 rng(3);
  ASSERT_TRUE(client.send(random_join(rng)).ok());
  EXPECT_FALSE(server.receive(1000).has_value());
  EXPECT_EQ(context_.zap()->accepted, 0u);
}

TEST_F(CurveTest, InsecureClientCannotTalkToACurveServer) {
  SampleReceiver receiver(context_, "tcp://127.0.0.1:*", Security::server(display_));
  Context sampler_context;
  SampleSender sender(sampler_context, receiver.endpoint());  // no keys
  Pcg32 rng(4);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(sender.send(random_batch(rng, 0, 4)).ok());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(receiver.receive(200), SampleReceiver::Got::kNothing);
}

TEST_F(CurveTest, SampleAndViewChannelsWorkWithCurve) {
  SampleReceiver receiver(context_, "tcp://127.0.0.1:*", Security::server(display_));
  ViewPublisher publisher(context_, "tcp://127.0.0.1:*", Security::server(display_));
  Context sampler_context;
  const Security client = Security::client(allowed_, display_.public_key);
  SampleSender sender(sampler_context, receiver.endpoint(), client);
  ViewSubscriber subscriber(sampler_context, publisher.endpoint(), client);
  Pcg32 rng(5);
  const SampleBatch batch = random_batch(rng, kFieldPosition | kFieldVelocity, 256);
  bool got_batch = false, got_view = false;
  const auto start = std::chrono::steady_clock::now();
  while (!(got_batch && got_view) &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(5)) {
    ASSERT_TRUE(sender.send(batch).ok());
    ASSERT_TRUE(publisher.publish(random_view(rng)).ok());
    if (receiver.receive(10) == SampleReceiver::Got::kBatch) {
      got_batch = true;
      // The connection's authenticated key travels with each message: the display binds a
      // member's batches to the key it joined with.
      EXPECT_EQ(receiver.peer_key(), allowed_.public_key);
    }
    got_view |= subscriber.receive(10).has_value();
  }
  EXPECT_TRUE(got_batch);
  EXPECT_TRUE(got_view);
  EXPECT_EQ(receiver.batch().samples.size(), 256u);
}

TEST(CurveSetupTest, CurveServerWithoutAnAllowListIsRefused) {
  Context context;  // no allow_curve_clients: libzmq would admit any client key
  EXPECT_THROW(
      ControlServer(context, "tcp://127.0.0.1:*", Security::server(generate_curve_keypair())),
      Error);
  EXPECT_THROW(context.allow_curve_clients({"not a key"}), Error);
}

}  // namespace
}  // namespace afr::protocol
