// The three channels of the afr service over ZeroMQ (DESIGN.md, "Network"). The display
// binds all three; samplers connect.
//
//   control  ROUTER (display) <-> DEALER (sampler)  join, welcome, scene, regions, stats,
//                                                   heartbeat, leave: reliable and addressed
//   views    PUB (display) -> SUB (sampler)         views, conflated: a sampler sees the latest
//   samples  PUSH (sampler) -> PULL (display)       sample batches and tiling snapshots
//
// Every socket is set up with the facts measured for afr (docs/protocol.md, "Transport"):
// LINGER (or closing hangs on unsent messages), MAXMSGSIZE (or a peer that announces a 1 GiB
// frame holds the connection), small high-water marks and kernel buffers on the sample channel
// (marks count messages, not bytes: the defaults queue seconds of stale samples), CONFLATE on
// the view subscriber (PUB drops silently for a slow subscriber; conflation makes "the latest
// view" the only thing to lose), and retries on EINTR. A PULL socket cannot tell which
// connection sent a message: sampler ids and member tokens travel in the message headers, and
// with CurveZMQ each message carries its connection's authenticated key (peer_key()); the
// control channel knows its peers.
//
// None of the classes is thread-safe: each belongs to one thread (ZeroMQ sockets may move
// between threads, but not be shared). All hold a reference to their Context, which must
// outlive them. They expose sending, receiving and waiting, never the socket: ZeroMQ stays
// inside afr_protocol (display_link.h waits on a client's two channels at once). A channel
// that cannot bind or connect throws afr::Error naming the endpoint.
#pragma once

#include <afr/protocol/codec.h>
#include <afr/protocol/context.h>
#include <afr/protocol/keys.h>
#include <afr/protocol/messages.h>
#include <afr/protocol/result.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace afr::protocol {

namespace detail {
struct Socket;        // the ZeroMQ socket of a channel (zmq_state.h)
struct SocketAccess;  // afr_protocol's own way to it
}  // namespace detail

// ---------------------------------------------------------------------------------------------
// Endpoints and security

// The three endpoints of one display. From a base "tcp://HOST:PORT": ports PORT, PORT + 1 and
// PORT + 2; from "inproc://NAME" or "ipc://PATH": NAME-control, NAME-views, NAME-samples.
struct ServiceEndpoints {
  std::string control;
  std::string views;
  std::string samples;
};
// Throws afr::Error for a malformed base (no port, port out of range, unknown transport).
ServiceEndpoints service_endpoints(const std::string& base);

// True for endpoints no other machine can reach: tcp on 127.0.0.0/8, localhost or [::1],
// inproc and ipc. The display requires CurveZMQ on every other address unless told otherwise.
bool is_local_endpoint(const std::string& endpoint);

// The address families a host name has (getaddrinfo, any family): what a connect to it needs.
struct HostFamilies {
  bool ipv4 = false;
  bool ipv6 = false;
};
using HostResolver = std::function<HostFamilies(const std::string& host)>;
HostFamilies resolve_host_families(const std::string& host);
// Whether a socket that binds or connects `endpoint` needs libzmq's IPv6 option: an IPv6
// address in brackets ("tcp://[::1]:7100", either side of a connect's "SRC;HOST"); a wildcard
// bind ("tcp://*:7100", which then listens on IPv6 and IPv4 both); and a connect to a host
// name that has IPv6 addresses only (`resolve` says: libzmq without the option resolves a name
// for IPv4 alone, with it for IPv6, so a name with both families keeps IPv4, as before).
bool wants_ipv6(const std::string& endpoint, bool connect,
                const HostResolver& resolve = resolve_host_families);

// CurveZMQ settings of one socket; the default (no keys) is an unencrypted socket.
struct Security {
  CurveKeyPair own;               // this side's key pair
  std::string server_public_key;  // clients: the display's public key; empty on servers

  static Security none() { return {}; }
  static Security server(const CurveKeyPair& own) { return {own, ""}; }
  static Security client(const CurveKeyPair& own, const std::string& server_public_key) {
    return {own, server_public_key};
  }
  bool enabled() const { return !own.secret_key.empty(); }
  bool is_server() const { return enabled() && server_public_key.empty(); }
};

// Socket options of one channel. The defaults of each channel are its named constructor.
struct ChannelOptions {
  int linger_ms = 0;    // how long close() may wait for unsent messages
  int send_hwm = 1000;  // messages (not bytes) queued per peer
  int receive_hwm = 1000;
  int send_buffer = 0;  // kernel socket buffers in bytes; 0: the OS default
  int receive_buffer = 0;
  int64_t max_message_bytes = -1;  // larger incoming messages drop the connection
  int reconnect_ms = 100;          // first reconnection attempt after a lost connection
  int reconnect_max_ms = 1000;     // back-off limit: a restarted display is found within 1 s
  // A dead TCP peer (no FIN) is noticed by the kernel, not by ZMTP heartbeats: keepalive
  // probes an idle connection after `keepalive_idle_s` seconds, every `keepalive_interval_s`,
  // and TCP_USER_TIMEOUT (ZMQ_TCP_MAXRT) drops a connection whose data has gone unacknowledged
  // for `max_retransmit_ms`. keepalive_idle_s 0: no keepalive; max_retransmit_ms 0: the
  // kernel's own retransmission limit. ZMTP heartbeats are never set: libzmq 4.3.4
  // aborts the process when a heartbeat falls due on a connection whose peer closed while
  // the reader's queue was full (docs/protocol.md, "Socket options").
  int keepalive_idle_s = 2;
  int keepalive_interval_s = 1;
  int keepalive_count = 3;
  int max_retransmit_ms = 10000;
  int sender_queue = 0;  // SampleSender: encoded messages kept while ZeroMQ's queue is full

  // Samples: drop rather than queue; a few ms of batches in flight at most.
  static ChannelOptions samples();
  // Control: reliable, small in count (scene chunks are 1 MiB), a short linger so a leave
  // gets out.
  static ChannelOptions control();
  // Views: only the latest matters.
  static ChannelOptions views();
};

// ---------------------------------------------------------------------------------------------
// Samples: sampler -> display

// PUSH, connects to the display. send() never blocks: when ZeroMQ's queue is full (the display
// is slow or away) messages wait in a small queue of its own, whose oldest entry is dropped
// and counted when a new one arrives, so what finally goes out is the freshest.
class SampleSender {
 public:
  struct Counters {
    uint64_t batches_sent = 0;
    uint64_t tilings_sent = 0;
    uint64_t bytes_sent = 0;
    uint64_t batches_dropped = 0;
    uint64_t tilings_dropped = 0;
    uint64_t coverage_sent = 0;  // wall_coverage messages (a display wall's nodes)
    uint64_t coverage_dropped = 0;
  };

  SampleSender(Context& context, const std::string& endpoint, const Security& security = {},
               const ChannelOptions& options = ChannelOptions::samples());
  ~SampleSender();
  SampleSender(const SampleSender&) = delete;
  SampleSender& operator=(const SampleSender&) = delete;

  // Encode (an error means the contents break the protocol's rules: nothing is queued), queue
  // and hand as much of the queue to ZeroMQ as it takes.
  Status send(const SampleBatch& batch, const ImageExtent& bounds = kMaxImageExtent);
  Status send(const TilingSnapshot& snapshot, const ImageExtent& bounds = kMaxImageExtent);
  Status send(const WallCoverage& coverage, const ImageExtent& bounds = kMaxImageExtent);
  // Hands queued messages to ZeroMQ; call when idle. Returns the number still queued.
  size_t pump();
  // Waits (up to timeout_ms; -1: forever) until ZeroMQ has taken the whole queue: for a last
  // batch before leaving, or to send without loss where waiting is acceptable (benchmarks).
  // Returns whether the queue is empty.
  bool flush(int timeout_ms);

  const Counters& counters() const { return counters_; }

 private:
  // What a queued message is, so that sends and drops are counted per kind.
  enum class Kind : uint8_t { kBatch, kTiling, kCoverage };
  struct Slot {
    std::vector<uint8_t> bytes;
    Kind kind = Kind::kBatch;
  };
  Slot& push_slot();
  void pop_slot();
  // Queues the message just encoded into push_slot() (dropping the oldest when the queue is
  // full) and pumps.
  void commit_slot(Kind kind);
  uint64_t& sent_counter(Kind kind);
  uint64_t& dropped_counter(Kind kind);

  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  std::vector<Slot> slots_;  // ring buffer of encoded messages
  size_t head_ = 0, size_ = 0;
  Counters counters_;
};

// PULL, bound by the display. Decodes into objects it keeps, so steady state allocates only
// ZeroMQ's message.
class SampleReceiver {
 public:
  enum class Got { kNothing, kBatch, kTiling, kCoverage, kRejected };
  struct Counters {
    uint64_t batches = 0;
    uint64_t tilings = 0;
    uint64_t coverage = 0;
    uint64_t samples = 0;
    uint64_t bytes = 0;
    uint64_t rejected = 0;
  };

  SampleReceiver(Context& context, const std::string& endpoint, const Security& security = {},
                 const ChannelOptions& options = ChannelOptions::samples());
  ~SampleReceiver();
  SampleReceiver(const SampleReceiver&) = delete;
  SampleReceiver& operator=(const SampleReceiver&) = delete;

  // Waits up to timeout_ms (0: only what is there; -1: forever) for one message and decodes
  // it. After kBatch read batch(), after kTiling tiling(), after kCoverage coverage(), after
  // kRejected rejection(); each stays valid until the next receive().
  Got receive(int timeout_ms);
  const SampleBatch& batch() const { return batch_; }
  SampleBatch& batch() { return batch_; }
  const TilingSnapshot& tiling() const { return tiling_; }
  TilingSnapshot& tiling() { return tiling_; }
  const WallCoverage& coverage() const { return coverage_; }
  WallCoverage& coverage() { return coverage_; }
  const Status& rejection() const { return rejection_; }
  // The CurveZMQ public key (Z85) of the connection the last message came on, as the ZAP
  // handler authenticated it; empty without CurveZMQ. Valid until the next receive().
  std::string_view peer_key() const;

  // Samples and tiles outside this image are rejected (default: the protocol's limit).
  // Safe from any thread while another receives (a wall's follower learns its image from the
  // control thread): the bounds travel as one atomic word, read once per message.
  void set_image_bounds(const ImageExtent& bounds) {
    bounds_.store((uint64_t(uint32_t(bounds.width)) << 32) | uint32_t(bounds.height),
                  std::memory_order_relaxed);
  }
  ImageExtent image_bounds() const {
    const uint64_t b = bounds_.load(std::memory_order_relaxed);
    return ImageExtent{int32_t(b >> 32), int32_t(b & 0xffffffffu)};
  }
  const Counters& counters() const { return counters_; }
  // The endpoint as bound ("tcp://127.0.0.1:41234" for "tcp://127.0.0.1:*").
  std::string endpoint() const;

 private:
  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  SampleBatch batch_;
  TilingSnapshot tiling_;
  WallCoverage coverage_;
  Status rejection_;
  std::atomic<uint64_t> bounds_{(uint64_t(uint32_t(kMaxImageSize)) << 32) |
                                uint32_t(kMaxImageSize)};
  Counters counters_;
};

// ---------------------------------------------------------------------------------------------
// Views: display -> samplers

// PUB, bound by the display.
class ViewPublisher {
 public:
  ViewPublisher(Context& context, const std::string& endpoint, const Security& security = {},
                const ChannelOptions& options = ChannelOptions::views());
  ~ViewPublisher();
  ViewPublisher(const ViewPublisher&) = delete;
  ViewPublisher& operator=(const ViewPublisher&) = delete;
  // Sends to every connected subscriber; a subscriber whose queue is full misses it (it has a
  // newer one by then or will get the next).
  Status publish(const View& view);
  std::string endpoint() const;

 private:
  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  std::vector<uint8_t> buffer_;
};

// SUB with CONFLATE, connects to the display: holds only the latest view.
class ViewSubscriber {
 public:
  ViewSubscriber(Context& context, const std::string& endpoint, const Security& security = {},
                 const ChannelOptions& options = ChannelOptions::views());
  ~ViewSubscriber();
  ViewSubscriber(const ViewSubscriber&) = delete;
  ViewSubscriber& operator=(const ViewSubscriber&) = delete;
  // The latest view, waiting up to timeout_ms; nothing on timeout or when the message was
  // rejected (then rejection() says why and rejected() counts it).
  std::optional<View> receive(int timeout_ms);
  const Status& rejection() const { return rejection_; }
  uint64_t rejected() const { return rejected_; }

 private:
  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  Status rejection_;
  uint64_t rejected_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Control: display <-> samplers

// Which messages may travel on the control channel, by direction.
// join, scene_request, stats, heartbeat, leave, and display_join (from a wall's followers)
bool allowed_to_display(MessageType type);
// welcome, scene_chunk, region, heartbeat, leave, and wall_layout (to samplers and followers)
bool allowed_to_sampler(MessageType type);

// ROUTER, bound by the display. Knows each peer by ZeroMQ's routing id and, with CurveZMQ, by
// its public key (the user id the ZAP handler gave it).
class ControlServer {
 public:
  struct Incoming {
    std::string peer;         // routing id: the address for send()
    std::string public_key;   // Z85 CurveZMQ key of the peer; empty without CurveZMQ
    Result<Message> message;  // or why it was rejected
  };

  ControlServer(Context& context, const std::string& endpoint, const Security& security = {},
                const ChannelOptions& options = ChannelOptions::control());
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;
  std::optional<Incoming> receive(int timeout_ms);
  // Fails for messages not allowed towards a sampler, for an unknown or disconnected peer,
  // and when the peer's queue is full.
  Status send(const std::string& peer, const Message& message);
  std::string endpoint() const;

 private:
  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  std::vector<uint8_t> buffer_;
};

// DEALER, connects to the display.
class ControlClient {
 public:
  ControlClient(Context& context, const std::string& endpoint, const Security& security = {},
                const ChannelOptions& options = ChannelOptions::control());
  ~ControlClient();
  ControlClient(const ControlClient&) = delete;
  ControlClient& operator=(const ControlClient&) = delete;
  std::optional<Result<Message>> receive(int timeout_ms);
  // Fails for messages not allowed towards the display and when the queue is full (no
  // connection yet: ZeroMQ queues until the high-water mark).
  Status send(const Message& message);

 private:
  friend struct detail::SocketAccess;
  std::unique_ptr<detail::Socket> socket_;
  std::vector<uint8_t> buffer_;
};

}  // namespace afr::protocol
