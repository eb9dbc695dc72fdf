// The ZeroMQ channels, each checked for the behaviour docs/protocol.md promises, against raw
// libzmq sockets and raw TCP where the point is what a foreign peer can do.
#include <afr/protocol/channels.h>

#include <afr/common/error.h>

#include "support/timing.h"
#include "test_messages.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>
#include <zmq.hpp>

#include <atomic>
#include <chrono>
#include <cstring>
#include <thread>

namespace afr::protocol {
namespace {

using namespace testing;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Polls `f` until it returns true or `ms` pass.
template <class F>
bool eventually(F f, int ms = 3000) {
  const auto start = Clock::now();
  while (seconds_since(start) * 1000 < ms) {
    if (f()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return f();
}

int port_of(const std::string& endpoint) {
  return std::stoi(endpoint.substr(endpoint.rfind(':') + 1));
}

// A TCP port that was free a moment ago.
int free_port() {
  zmq::context_t ctx;
  zmq::socket_t s(ctx, zmq::socket_type::pull);
  s.set(zmq::sockopt::linger, 0);
  s.bind("tcp://127.0.0.1:*");
  return port_of(s.get(zmq::sockopt::last_endpoint));
}

std::string tcp(int port) { return "tcp://127.0.0.1:" + std::to_string(port); }

// Whether this machine can bind a TCP socket on the IPv6 loopback (a container may have no
// IPv6 at all).
bool has_ipv6_loopback() {
  const int fd = socket(AF_INET6, SOCK_STREAM, 0);
  if (fd < 0) return false;
  sockaddr_in6 a{};
  a.sin6_family = AF_INET6;
  a.sin6_addr = in6addr_loopback;
  const bool ok = bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0;
  close(fd);
  return ok;
}

// ---------------------------------------------------------------------------------------------
// Endpoints

TEST(TransportTest, ServiceEndpointsFollowTheBase) {
  const ServiceEndpoints t = service_endpoints("tcp://10.0.0.5:7000");
  EXPECT_EQ(t.control, "tcp://10.0.0.5:7000");
  EXPECT_EQ(t.views, "tcp://10.0.0.5:7001");
  EXPECT_EQ(t.samples, "tcp://10.0.0.5:7002");
  EXPECT_EQ(service_endpoints("tcp://[::1]:9").samples, "tcp://[::1]:11");
  EXPECT_EQ(service_endpoints("inproc://afr").views, "inproc://afr-views");
  EXPECT_THROW(service_endpoints("tcp://host"), Error);
  EXPECT_THROW(service_endpoints("tcp://host:65534"), Error);
  EXPECT_THROW(service_endpoints("tcp://host:x1"), Error);
  EXPECT_THROW(service_endpoints("udp://host:1"), Error);
}

TEST(TransportTest, LocalEndpointsAreRecognised) {
  for (const char* e : {"tcp://127.0.0.1:5000", "tcp://127.3.2.1:1", "tcp://localhost:5",
                        "tcp://[::1]:5", "inproc://x", "ipc:///tmp/x"}) {
    EXPECT_TRUE(is_local_endpoint(e)) << e;
  }
  for (const char* e : {"tcp://*:5000", "tcp://0.0.0.0:5000", "tcp://192.168.1.2:5", "tcp://eth0:5",
                        "tcp://1270.0.0.1:5"}) {
    EXPECT_FALSE(is_local_endpoint(e)) << e;
  }
}

// ---------------------------------------------------------------------------------------------
// Samples

TEST(TransportTest, PushPullCarriesBatchesAndTilings) {
  for (const char* where : {"inproc://samples-test", "tcp://127.0.0.1:*"}) {
    Context context;
    SampleReceiver receiver(context, where);
    SampleSender sender(context, receiver.endpoint());
    Pcg32 rng(1);
    const SampleBatch batch = random_batch(rng, kFieldPosition, 128);
    const TilingSnapshot tiling = random_tiling(rng, 20);
    ASSERT_TRUE(eventually([&] {
      // Until connected the sender queues; pump() hands the queue over once it is.
      return sender.send(batch).ok() && sender.counters().batches_sent > 0;
    }));
    ASSERT_TRUE(sender.send(tiling).ok());
    EXPECT_EQ(sender.pump(), 0u);

    SampleReceiver::Got got = receiver.receive(2000);
    ASSERT_EQ(got, SampleReceiver::Got::kBatch) << where << " " << receiver.rejection().message();
    EXPECT_EQ(receiver.batch().sampler_id, batch.sampler_id);
    EXPECT_EQ(receiver.batch().token, batch.token);
    EXPECT_EQ(receiver.peer_key(), "");  // no CurveZMQ: no authenticated key
    EXPECT_EQ(receiver.batch().samples.size(), 128u);
    EXPECT_EQ(receiver.batch().samples[5].position, batch.samples[5].position);
    // Any further batches the retry loop sent, then the tiling.
    while ((got = receiver.receive(2000)) == SampleReceiver::Got::kBatch) {
    }
    ASSERT_EQ(got, SampleReceiver::Got::kTiling);
    EXPECT_EQ(receiver.tiling().tiles.size(), 20u);
    EXPECT_EQ(receiver.tiling().region, tiling.region);
    EXPECT_EQ(receiver.receive(0), SampleReceiver::Got::kNothing);
    EXPECT_EQ(receiver.counters().rejected, 0u);
  }
}

// What display nodes of a wall send each other on the receiver's sample channel: coverage maps,
// and strays as batches with sampler_id 0 (docs/wall.md, "Seams").
TEST(TransportTest, PushPullCarriesWallCoverageAndPeerStrays) {
  for (const char* where : {"inproc://coverage-test", "tcp://127.0.0.1:*"}) {
    Context context;
    SampleReceiver receiver(context, where);
    const ImageExtent image{1920, 1080};
    receiver.set_image_bounds(image);
    SampleSender sender(context, receiver.endpoint());
    Pcg32 rng(12);
    SampleBatch stray = random_batch(rng, kFieldPosition, 16, 0.01, image);
    stray.sampler_id = kWallPeerSamplerId;
    WallCoverage coverage = random_wall_coverage(rng, 32);
    coverage.rect = PixelRect{900, 500, 932, 520};
    coverage.cells.assign(2 * 32 * 20, 0.0f);
    for (size_t i = 0; i < coverage.cells.size(); i += 2) {
      coverage.cells[i] = float(i % 5);
      coverage.cells[i + 1] = 0.75f * coverage.cells[i];
    }
    ASSERT_TRUE(eventually(
        [&] { return sender.send(stray, image).ok() && sender.counters().batches_sent > 0; }));
    ASSERT_TRUE(sender.send(coverage, image).ok());
    EXPECT_EQ(sender.pump(), 0u);
    EXPECT_EQ(sender.counters().coverage_sent, 1u);
    EXPECT_EQ(sender.counters().coverage_dropped, 0u);

    SampleReceiver::Got got = receiver.receive(2000);
    ASSERT_EQ(got, SampleReceiver::Got::kBatch) << where << " " << receiver.rejection().message();
    EXPECT_EQ(receiver.batch().sampler_id, kWallPeerSamplerId);
    EXPECT_EQ(receiver.batch().samples.size(), 16u);
    while ((got = receiver.receive(2000)) == SampleReceiver::Got::kBatch) {
      EXPECT_EQ(receiver.batch().sampler_id, kWallPeerSamplerId);
    }
    ASSERT_EQ(got, SampleReceiver::Got::kCoverage)
        << where << " " << receiver.rejection().message();
    EXPECT_EQ(receiver.coverage(), coverage);
    EXPECT_EQ(receiver.counters().coverage, 1u);
    EXPECT_EQ(receiver.counters().batches, sender.counters().batches_sent);
    EXPECT_EQ(receiver.counters().rejected, 0u);

    // A map outside the receiver's image is refused like a sample outside it.
    receiver.set_image_bounds(ImageExtent{640, 480});
    ASSERT_TRUE(sender.send(coverage).ok());
    ASSERT_EQ(receiver.receive(2000), SampleReceiver::Got::kRejected);
    EXPECT_NE(receiver.rejection().message().find("wall_coverage.rect"), std::string::npos)
        << receiver.rejection().message();
    EXPECT_EQ(receiver.counters().coverage, 1u);
    EXPECT_EQ(receiver.receive(0), SampleReceiver::Got::kNothing);
  }
}

TEST(TransportTest, SampleIdsTellSendersApartOnOnePullSocket) {
  Context context;
  SampleReceiver receiver(context, "tcp://127.0.0.1:*");
  SampleSender a(context, receiver.endpoint()), b(context, receiver.endpoint());
  Pcg32 rng(2);
  SampleBatch ba = random_batch(rng, 0, 10), bb = random_batch(rng, 0, 10);
  ba.sampler_id = 1;
  bb.sampler_id = 2;
  int seen[3] = {0, 0, 0};
  ASSERT_TRUE(eventually([&] {
    (void)a.send(ba);
    (void)b.send(bb);
    while (receiver.receive(0) == SampleReceiver::Got::kBatch) ++seen[receiver.batch().sampler_id];
    return seen[1] > 0 && seen[2] > 0;
  }));
}

TEST(TransportTest, SenderKeepsTheFreshestWhenTheDisplayIsAway) {
  const int port = free_port();
  Context context;
  SampleSender sender(context, tcp(port));
  const int queue = ChannelOptions::samples().sender_queue;
  Pcg32 rng(3);
  SampleBatch batch = random_batch(rng, kFieldPosition, 16);
  for (uint64_t i = 0; i < 100; ++i) {
    batch.sequence = i;
    ASSERT_TRUE(sender.send(batch).ok());
  }
  EXPECT_EQ(sender.counters().batches_sent, 0u);  // nothing queued into an absent connection
  EXPECT_EQ(sender.counters().batches_dropped, uint64_t(100 - queue));

  // The display comes up: the queue (the last `queue` batches) goes out, oldest first.
  SampleReceiver receiver(context, tcp(port));
  ASSERT_TRUE(eventually([&] { return sender.pump() == 0; }));
  for (int i = 0; i < queue; ++i) {
    ASSERT_EQ(receiver.receive(2000), SampleReceiver::Got::kBatch);
    EXPECT_EQ(receiver.batch().sequence, uint64_t(100 - queue + i));
  }
  EXPECT_EQ(receiver.receive(100), SampleReceiver::Got::kNothing);
}

TEST(TransportTest, SenderCountsSendsAndDropsPerKind) {
  const int port = free_port();
  Context context;
  SampleSender sender(context, tcp(port));
  const size_t queue = size_t(ChannelOptions::samples().sender_queue);
  ASSERT_GE(queue, 8u);
  Pcg32 rng(13);
  const SampleBatch batch = random_batch(rng, 0, 4);
  const TilingSnapshot tiling = random_tiling(rng, 3);
  const WallCoverage coverage = random_wall_coverage(rng);
  // No display: 5 maps, 3 snapshots and queue - 8 batches fill the queue; one more map pushes
  // out the oldest map, 6 more batches the other 4 maps and 2 snapshots.
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(sender.send(coverage).ok());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(sender.send(tiling).ok());
  for (size_t i = 0; i < queue - 8; ++i) ASSERT_TRUE(sender.send(batch).ok());
  ASSERT_TRUE(sender.send(coverage).ok());
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(sender.send(batch).ok());
  const SampleSender::Counters& c = sender.counters();
  EXPECT_EQ(c.coverage_dropped, 5u);
  EXPECT_EQ(c.tilings_dropped, 2u);
  EXPECT_EQ(c.batches_dropped, 0u);
  EXPECT_EQ(c.batches_sent + c.tilings_sent + c.coverage_sent, 0u);
  // A map that breaks the rules is refused and changes nothing.
  WallCoverage bad = coverage;
  bad.node_id = 0;
  EXPECT_FALSE(sender.send(bad).ok());
  EXPECT_EQ(c.coverage_dropped, 5u);

  // The display comes up: what is left goes out oldest first, each counted as its kind.
  SampleReceiver receiver(context, tcp(port));
  ASSERT_TRUE(eventually([&] { return sender.pump() == 0; }));
  EXPECT_EQ(c.tilings_sent, 1u);
  EXPECT_EQ(c.batches_sent, queue - 2);
  EXPECT_EQ(c.coverage_sent, 1u);
  using Got = SampleReceiver::Got;
  std::vector<Got> expected = {Got::kTiling};
  expected.insert(expected.end(), queue - 8, Got::kBatch);
  expected.push_back(Got::kCoverage);
  expected.insert(expected.end(), 6, Got::kBatch);
  std::vector<Got> got;
  for (size_t i = 0; i < expected.size(); ++i) got.push_back(receiver.receive(2000));
  EXPECT_EQ(got, expected);
  EXPECT_EQ(receiver.coverage(), coverage);
  EXPECT_EQ(receiver.receive(100), Got::kNothing);
}

TEST(TransportTest, SenderMemoryStaysBoundedWhenTheDisplayStalls) {
  Context context;
  SampleReceiver receiver(context, "tcp://127.0.0.1:*");  // never reads
  SampleSender sender(context, receiver.endpoint());
  Pcg32 rng(4);
  const SampleBatch batch = random_batch(rng, kFieldPosition, 128);
  uint64_t total = 0;
  ASSERT_TRUE(eventually([&] {
    ++total;
    return sender.send(batch).ok() && sender.counters().batches_sent > 0;
  }));
  for (int i = 0; i < 20000; ++i, ++total) ASSERT_TRUE(sender.send(batch).ok());
  const size_t queued = sender.pump();
  const auto& c = sender.counters();
  // What got out is bounded by the high-water marks and socket buffers (a few hundred kB of
  // 3 kB batches); the rest was dropped and counted.
  EXPECT_EQ(c.batches_sent + c.batches_dropped + queued, total);
  EXPECT_LE(queued, size_t(ChannelOptions::samples().sender_queue));
  EXPECT_GT(c.batches_dropped, 15000u);
  EXPECT_LT(c.batches_sent * batch_message_bytes(kFieldPosition, 128), 2u << 20);
}

TEST(TransportTest, ReceiverRejectsWhatIsNotASampleMessage) {
  Context context;
  SampleReceiver receiver(context, "tcp://127.0.0.1:*");
  zmq::context_t raw_context;  // a peer that speaks ZeroMQ, not afr
  zmq::socket_t raw(raw_context, zmq::socket_type::push);
  raw.set(zmq::sockopt::linger, 0);
  raw.connect(receiver.endpoint());
  raw.send(zmq::str_buffer("garbage"), zmq::send_flags::none);
  Pcg32 rng(5);
  const std::vector<uint8_t> view = encoded(random_view(rng));
  raw.send(zmq::buffer(view), zmq::send_flags::none);
  raw.send(zmq::str_buffer("a"), zmq::send_flags::sndmore);
  raw.send(zmq::str_buffer("b"), zmq::send_flags::none);
  const std::vector<uint8_t> batch = encoded(random_batch(rng, 0, 3));
  raw.send(zmq::buffer(batch), zmq::send_flags::none);

  ASSERT_EQ(receiver.receive(1000), SampleReceiver::Got::kRejected);
  EXPECT_NE(receiver.rejection().message().find("header"), std::string::npos);
  ASSERT_EQ(receiver.receive(1000), SampleReceiver::Got::kRejected);
  EXPECT_NE(receiver.rejection().message().find("view: not allowed"), std::string::npos);
  ASSERT_EQ(receiver.receive(1000), SampleReceiver::Got::kRejected);
  EXPECT_NE(receiver.rejection().message().find("multipart"), std::string::npos);
  ASSERT_EQ(receiver.receive(1000), SampleReceiver::Got::kBatch);
  EXPECT_EQ(receiver.counters().rejected, 3u);
}

// ---------------------------------------------------------------------------------------------
// Views

TEST(TransportTest, ViewSubscriberKeepsOnlyTheLatestView) {
  Context context;
  ViewPublisher publisher(context, "tcp://127.0.0.1:*");
  ViewSubscriber subscriber(context, publisher.endpoint());
  Pcg32 rng(6);
  View view = random_view(rng);
  // Subscriptions travel asynchronously: publish until one arrives.
  ASSERT_TRUE(eventually([&] {
    EXPECT_TRUE(publisher.publish(view).ok());
    return subscriber.receive(10).has_value();
  }));
  while (subscriber.receive(50)) {
  }
  for (uint64_t s = 1; s <= 200; ++s) {
    view.sequence = s;
    ASSERT_TRUE(publisher.publish(view).ok());
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // Only the newest view is kept: reading after the burst gives at most the few views still in
  // flight when it ended (none on a fast machine), newer and newer, never the 200. The very
  // last write of a burst into a conflating pipe can wait for the next one (seen once under
  // ThreadSanitizer: 199 arrived, 200 not within 5 s); a display publishes every refresh, so
  // the next view, 201 here, follows after 100 ms without a newer one.
  std::optional<View> got;
  int received = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  auto next_nudge = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  while (std::chrono::steady_clock::now() < deadline && !(got && got->sequence >= 200u)) {
    if (std::optional<View> v = subscriber.receive(100)) {
      if (got) {
        EXPECT_GT(v->sequence, got->sequence);
      }
      got = v;
      ++received;
    } else if (std::chrono::steady_clock::now() > next_nudge) {
      view.sequence = 201;
      ASSERT_TRUE(publisher.publish(view).ok());
      next_nudge = std::chrono::steady_clock::now() + std::chrono::milliseconds(100);
    }
  }
  ASSERT_TRUE(got.has_value());
  EXPECT_GE(got->sequence, 200u);
  EXPECT_EQ(got->camera.forward, view.camera.forward);
  EXPECT_LE(received, 10);
  if (got->sequence == 200u) {
    EXPECT_FALSE(subscriber.receive(100).has_value());
  }
}

// ---------------------------------------------------------------------------------------------
// Control

TEST(TransportTest, ControlChannelAddressesPeers) {
  Context context;
  ControlServer server(context, "tcp://127.0.0.1:*");
  ControlClient client(context, server.endpoint());
  Pcg32 rng(7);
  const Join join = random_join(rng);
  ASSERT_TRUE(client.send(join).ok());  // queued until connected
  std::optional<ControlServer::Incoming> in = server.receive(2000);
  ASSERT_TRUE(in.has_value());
  ASSERT_TRUE(in->message.ok()) << in->message.error();
  EXPECT_EQ(std::get<Join>(*in->message), join);
  EXPECT_TRUE(in->public_key.empty());  // no CurveZMQ here

  const Welcome welcome = random_welcome(rng);
  ASSERT_TRUE(server.send(in->peer, welcome).ok());
  std::optional<Result<Message>> back = client.receive(2000);
  ASSERT_TRUE(back.has_value() && back->ok());
  EXPECT_EQ(std::get<Welcome>(**back), welcome);

  // Directions are enforced on both ends, and unknown peers are an error, not a silent loss.
  EXPECT_FALSE(client.send(welcome).ok());
  EXPECT_FALSE(server.send(in->peer, join).ok());
  EXPECT_NE(server.send("nobody", welcome).message().find("not connected"), std::string::npos);
}

TEST(TransportTest, ControlServerRejectsMessagesMeantForSamplers) {
  Context context;
  ControlServer server(context, "tcp://127.0.0.1:*");
  zmq::context_t raw_context;  // a peer that speaks ZeroMQ, not afr
  zmq::socket_t raw(raw_context, zmq::socket_type::dealer);
  raw.set(zmq::sockopt::linger, 0);
  raw.connect(server.endpoint());
  Pcg32 rng(8);
  const std::vector<uint8_t> welcome = encoded(random_welcome(rng));
  raw.send(zmq::buffer(welcome), zmq::send_flags::none);
  std::optional<ControlServer::Incoming> in = server.receive(1000);
  ASSERT_TRUE(in.has_value());
  ASSERT_FALSE(in->message.ok());
  EXPECT_NE(in->message.error().find("welcome: not allowed"), std::string::npos);
  EXPECT_FALSE(in->peer.empty());
}

// ---------------------------------------------------------------------------------------------
// IPv6

// Every channel takes IPv6 endpoints as docs/service.md says: the samples and the control
// channel bound on the IPv6 loopback, reached by address, and a wildcard bind reached over
// IPv6 and IPv4 both; an IPv4 bind keeps its IPv4 endpoint.
TEST(TransportTest, ChannelsBindAndConnectOverIpv6) {
  if (!has_ipv6_loopback()) GTEST_SKIP() << "no IPv6 loopback on this machine";
  struct Case {
    const char* bind;
    const char* connect_host;
  };
  for (const Case& c : {Case{"tcp://[::1]:*", "[::1]"}, Case{"tcp://*:*", "[::1]"},
                        Case{"tcp://*:*", "127.0.0.1"}}) {
    Context context;
    SampleReceiver receiver(context, c.bind);
    const int port = port_of(receiver.endpoint());
    SampleSender sender(context,
                        "tcp://" + std::string(c.connect_host) + ":" + std::to_string(port));
    Pcg32 rng(21);
    const SampleBatch batch = random_batch(rng, kFieldPosition, 64);
    ASSERT_TRUE(eventually([&] {
      return sender.send(batch).ok() && sender.counters().batches_sent > 0;
    })) << c.bind
        << " from " << c.connect_host;
    ASSERT_EQ(receiver.receive(2000), SampleReceiver::Got::kBatch) << c.bind;
    EXPECT_EQ(receiver.batch().samples.size(), 64u);
  }
  {
    Context context;
    SampleReceiver receiver(context, "tcp://127.0.0.1:*");
    EXPECT_EQ(receiver.endpoint().rfind("tcp://127.0.0.1:", 0), 0u) << receiver.endpoint();
  }
  Context context;
  ControlServer server(context, "tcp://[::1]:*");
  EXPECT_EQ(server.endpoint().rfind("tcp://[::1]:", 0), 0u) << server.endpoint();
  ControlClient client(context, server.endpoint());
  Pcg32 rng(22);
  const Join join = random_join(rng);
  ASSERT_TRUE(client.send(join).ok());
  std::optional<ControlServer::Incoming> in = server.receive(2000);
  ASSERT_TRUE(in.has_value() && in->message.ok());
  EXPECT_EQ(std::get<Join>(*in->message), join);
}

// Which sockets get libzmq's IPv6 option: IPv6 addresses and wildcard binds, and connects to a
// name that has IPv6 addresses only (a display on an IPv6-only network, named in DNS or
// /etc/hosts). A name with both families, or none yet, keeps IPv4 as before, and an address
// is never looked up. (deploy/lan/lan.sh --ipv6, the service_netns_ipv6 test, runs the service
// across namespaces that have IPv6 alone, reached by such a name.)
TEST(TransportTest, IpvSixIsAskedForWhereTheEndpointNeedsIt) {
  std::vector<std::string> asked;
  const HostResolver resolve = [&](const std::string& host) {
    asked.push_back(host);
    if (host == "v6only.example") return HostFamilies{false, true};
    if (host == "both.example") return HostFamilies{true, true};
    if (host == "v4only.example") return HostFamilies{true, false};
    return HostFamilies{};
  };
  for (const char* e : {"tcp://[::1]:5", "tcp://[fd77::1]:7100", "tcp://v6only.example:7100",
                        "tcp://10.0.0.2;v6only.example:7100", "tcp://[fd77::2];[fd77::1]:9"}) {
    EXPECT_TRUE(wants_ipv6(e, /*connect=*/true, resolve)) << e;
  }
  for (const char* e : {"tcp://127.0.0.1:5", "tcp://both.example:7100", "tcp://v4only.example:1",
                        "tcp://unknown.example:1", "inproc://x", "ipc:///tmp/x"}) {
    EXPECT_FALSE(wants_ipv6(e, /*connect=*/true, resolve)) << e;
  }
  EXPECT_TRUE(wants_ipv6("tcp://*:7100", /*connect=*/false, resolve));
  EXPECT_TRUE(wants_ipv6("tcp://[::]:7100", /*connect=*/false, resolve));
  EXPECT_FALSE(wants_ipv6("tcp://0.0.0.0:7100", /*connect=*/false, resolve));
  EXPECT_FALSE(wants_ipv6("tcp://eth0:7100", /*connect=*/false, resolve));  // an interface
  // Only connects to names were looked up, each once.
  EXPECT_EQ(asked, (std::vector<std::string>{"v6only.example", "v6only.example", "both.example",
                                             "v4only.example", "unknown.example"}));
  // The real resolver: this machine's own names.
  EXPECT_TRUE(resolve_host_families("localhost").ipv4);
  EXPECT_FALSE(resolve_host_families("127.0.0.1").ipv6);
}

// ---------------------------------------------------------------------------------------------
// LINGER, MAXMSGSIZE, EINTR

// A PUSH socket with messages it cannot deliver (the PULL peer does not read), then closed.
double close_seconds(int linger_ms) {
  zmq::context_t sink_ctx;
  zmq::socket_t sink(sink_ctx, zmq::socket_type::pull);
  sink.set(zmq::sockopt::linger, 0);
  sink.set(zmq::sockopt::rcvhwm, 1);
  sink.set(zmq::sockopt::rcvbuf, 4096);
  sink.bind("tcp://127.0.0.1:*");
  const std::string endpoint = sink.get(zmq::sockopt::last_endpoint);

  auto* ctx = new Context;
  ChannelOptions options = ChannelOptions::samples();
  options.linger_ms = linger_ms;
  options.send_buffer = 4096;
  auto* sender = new SampleSender(*ctx, endpoint, {}, options);
  Pcg32 rng(9);
  const SampleBatch batch = random_batch(rng, kFieldPosition, 4000);  // ~96 kB each
  eventually([&] { return sender->send(batch).ok() && sender->counters().batches_sent > 3; });
  const auto start = Clock::now();
  delete sender;
  delete ctx;  // zmq_ctx_term waits for unsent messages up to LINGER
  return seconds_since(start);
}

// A busy machine (or a sanitizer) makes every close slower, never faster, so the tight bound is
// the lower one; the upper one has seconds of slack. The sample channel's LINGER of 0 is judged
// against a close that must wait, measured side by side, not against an absolute time.
TEST(TransportTest, LingerBoundsHowLongClosingWaits) {
  const double lingering = close_seconds(1000);
  EXPECT_GE(lingering, 0.95);  // unsent messages really do hold close() for LINGER
  EXPECT_LT(lingering, afr::testing::scaled(1.0 + 5.0));  // ... and no longer than that, plus slack
  const double immediate = close_seconds(0);              // the sample channel's setting
  EXPECT_LT(immediate, 0.5 * lingering);
}

TEST(TransportTest, MaxMessageSizeDropsOversizedMessages) {
  Context context;
  ChannelOptions options = ChannelOptions::samples();
  options.max_message_bytes = 1000;
  SampleReceiver receiver(context, "tcp://127.0.0.1:*", {}, options);
  zmq::context_t peer_ctx;  // a peer without the limit
  zmq::socket_t raw(peer_ctx, zmq::socket_type::push);
  raw.set(zmq::sockopt::linger, 0);
  raw.set(zmq::sockopt::reconnect_ivl, 20);
  raw.connect(receiver.endpoint());
  Pcg32 rng(10);
  const std::vector<uint8_t> big = encoded(random_batch(rng, kFieldPosition, 100));   // 2444 B
  const std::vector<uint8_t> small = encoded(random_batch(rng, kFieldPosition, 10));  // 284 B
  ASSERT_GT(big.size(), 1000u);
  raw.send(zmq::buffer(big), zmq::send_flags::none);
  // The connection that carried it is dropped; the peer reconnects by itself and later
  // messages arrive. The big one never reaches the decoder.
  ASSERT_TRUE(eventually([&] {
    raw.send(zmq::buffer(small), zmq::send_flags::dontwait);
    return receiver.receive(20) == SampleReceiver::Got::kBatch;
  }));
  EXPECT_EQ(receiver.batch().samples.size(), 10u);
  EXPECT_EQ(receiver.counters().rejected, 0u);
  EXPECT_EQ(receiver.counters().batches * small.size(), receiver.counters().bytes);
}

// A peer floods a receiver that does not read, so the receiver's queue fills and libzmq stops
// reading that connection; then the peer closes. With a ZMTP heartbeat set, libzmq 4.3.4
// aborts the receiving process ("Assertion failed: !_io_error", stream_engine_base.cpp): a
// ping into the closed connection draws a reset, which marks the connection failed, and the
// next ping asserts that it is not. A display stalled for 3 s while its sampler reconnected
// died of it. The channels set no heartbeats, so the receiver outlives this and reads what
// was queued, counted in `received`. `kind` is a socket type a peer of the channel uses.
template <typename Receive>
void flood_close_and_wait(const std::string& endpoint, zmq::socket_type kind, int receive_hwm,
                          int& received, Receive receive) {
  const std::vector<uint8_t> payload(2400, 0x5a);
  for (int round = 0; round < 2; ++round) {
    zmq::context_t peer_ctx;
    {
      zmq::socket_t peer(peer_ctx, kind);
      // More messages than the receiver's queue holds, all taken by the peer's own queue
      // (1000), so no send waits. They fit the receiver's queue and the two kernels' buffers,
      // so closing returns as soon as they are written, which takes milliseconds; the 10 s
      // bound only keeps a broken connection from holding the test, and a loaded machine's
      // slow handshake does not drop them: the queue fills before the peer leaves.
      peer.set(zmq::sockopt::linger, 10000);
      peer.set(zmq::sockopt::sndtimeo, 5000);
      peer.connect(endpoint);
      for (int i = 0; i < receive_hwm + 64; ++i) {
        ASSERT_TRUE(peer.send(zmq::buffer(payload), zmq::send_flags::none).has_value());
      }
    }
    // Two and a half of the 1 s heartbeats the sample channel had: two pings fall due.
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));
    while (receive()) ++received;
  }
}

TEST(TransportTest, AReceiverThatStoppedReadingOutlivesAFloodingPeerThatCloses) {
  Context context;
  SampleReceiver samples(context, "tcp://127.0.0.1:*", {}, ChannelOptions::samples());
  const int hwm = ChannelOptions::samples().receive_hwm;
  int batches = 0;
  flood_close_and_wait(samples.endpoint(), zmq::socket_type::push, hwm, batches,
                       [&] { return samples.receive(10) != SampleReceiver::Got::kNothing; });
  // Each round's queue (its high-water mark and more) reaches the reader after the peer left.
  EXPECT_GE(batches, 2 * hwm);

  ControlServer control(context, "tcp://127.0.0.1:*");
  const int control_hwm = ChannelOptions::control().receive_hwm;
  int messages = 0;
  flood_close_and_wait(control.endpoint(), zmq::socket_type::dealer, control_hwm, messages,
                       [&] { return control.receive(10).has_value(); });
  EXPECT_GE(messages, 2 * control_hwm);
}

// Speaks ZMTP 3.0 by hand: greeting (NULL mechanism), READY as a PUSH socket, then the header
// of a 1 GiB frame. Returns the seconds until the peer closes the connection, or -1 if it is
// still open after `wait_s`.
double seconds_until_closed_after_huge_frame(int port, double wait_s) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(uint16_t(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) return -2;
  std::vector<uint8_t> out(64, 0);
  out[0] = 0xff;
  out[8] = 0x01;
  out[9] = 0x7f;
  out[10] = 3;  // ZMTP 3.0
  out[11] = 0;
  std::memcpy(&out[12], "NULL", 4);
  const uint8_t ready[] = {0x04, 26,  5,   'R', 'E', 'A', 'D', 'Y', 11, 'S', 'o', 'c', 'k', 'e',
                           't',  '-', 'T', 'y', 'p', 'e', 0,   0,   0,  4,   'P', 'U', 'S', 'H'};
  out.insert(out.end(), ready, ready + sizeof(ready));
  const uint8_t huge[] = {0x02, 0, 0, 0, 0, 0x40, 0, 0, 0};  // long frame of 2^30 bytes
  out.insert(out.end(), huge, huge + sizeof(huge));
  out.insert(out.end(), 1000, 0xaa);  // the start of the "payload"
  if (send(fd, out.data(), out.size(), 0) != ssize_t(out.size())) return -3;
  const auto start = Clock::now();
  uint8_t buf[4096];
  for (;;) {
    pollfd p = {fd, POLLIN, 0};
    const double left = wait_s - seconds_since(start);
    if (left <= 0) break;
    if (poll(&p, 1, int(left * 1000) + 1) > 0) {
      const ssize_t n = recv(fd, buf, sizeof(buf), 0);
      if (n <= 0) {  // EOF or reset: the peer dropped us
        close(fd);
        return seconds_since(start);
      }
    }
  }
  close(fd);
  return -1;
}

TEST(TransportTest, APeerAnnouncingAHugeFrameIsDisconnected) {
  Context context;
  SampleReceiver receiver(context, "tcp://127.0.0.1:*");
  const double t = seconds_until_closed_after_huge_frame(port_of(receiver.endpoint()), 2.0);
  EXPECT_GE(t, 0.0);
  EXPECT_LT(t, 1.0);

  // The fact behind the option: without MAXMSGSIZE, libzmq waits for the gigabyte.
  zmq::context_t raw_ctx;
  zmq::socket_t raw(raw_ctx, zmq::socket_type::pull);
  raw.set(zmq::sockopt::linger, 0);
  raw.bind("tcp://127.0.0.1:*");
  EXPECT_EQ(
      seconds_until_closed_after_huge_frame(port_of(raw.get(zmq::sockopt::last_endpoint)), 0.5),
      -1.0);
}

std::atomic<int> g_signals{0};
void on_signal(int) { g_signals.fetch_add(1); }

TEST(TransportTest, ReceivingSurvivesSignals) {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sa.sa_flags = 0;  // no SA_RESTART: blocking calls return EINTR
  sigemptyset(&sa.sa_mask);
  struct sigaction old {};
  ASSERT_EQ(sigaction(SIGUSR1, &sa, &old), 0);

  Context context;
  SampleReceiver receiver(context, "inproc://eintr-test");
  SampleSender sender(context, "inproc://eintr-test");
  std::atomic<bool> started{false};
  SampleReceiver::Got got = SampleReceiver::Got::kNothing;
  std::thread t([&] {
    started = true;
    got = receiver.receive(3000);  // interrupted, then retried
  });
  while (!started) std::this_thread::yield();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const int before = g_signals.load();
  pthread_kill(t.native_handle(), SIGUSR1);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_GT(g_signals.load(), before);
  Pcg32 rng(11);
  ASSERT_TRUE(sender.send(random_batch(rng, 0, 5)).ok());
  t.join();
  EXPECT_EQ(got, SampleReceiver::Got::kBatch);
  sigaction(SIGUSR1, &old, nullptr);
}

}  // namespace
}  // namespace afr::protocol
