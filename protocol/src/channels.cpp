#include <afr/protocol/channels.h>

#include <afr/common/check.h>
#include <afr/common/error.h>

#include "zmq_state.h"
#include "zmq_util.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>
#include <zmq.h>

#include <charconv>
#include <chrono>

namespace afr::protocol {

using detail::recv_retry;
using detail::send_retry;
using detail::set_int;
using detail::set_int64;
using detail::set_string;
using detail::wait_readable;

// ---------------------------------------------------------------------------------------------
// Endpoints

namespace {

// MAXMSGSIZE bounds every frame libzmq decodes, which includes the CurveZMQ handshake commands
// (WELCOME is 168 bytes, INITIATE about 300 with metadata) and encrypted messages (33 bytes
// more than the plaintext): a limit of exactly the largest message breaks CurveZMQ on the view
// channel, whose messages are 140 bytes. Every limit gets this headroom.
constexpr int64_t kFrameHeadroom = 4096;

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

ServiceEndpoints service_endpoints(const std::string& base) {
  if (starts_with(base, "inproc://") || starts_with(base, "ipc://")) {
    if (base.size() <= std::string(starts_with(base, "ipc://") ? "ipc://" : "inproc://").size()) {
      throw Error("endpoint '" + base + "': no name");
    }
    return {base + "-control", base + "-views", base + "-samples"};
  }
  if (!starts_with(base, "tcp://")) {
    throw Error("endpoint '" + base + "': expected tcp://HOST:PORT, inproc://NAME or ipc://PATH");
  }
  const size_t colon = base.rfind(':');
  if (colon == std::string::npos || colon < 6) {
    throw Error("endpoint '" + base + "': no port (tcp://HOST:PORT)");
  }
  const std::string host = base.substr(0, colon);
  const std::string port_text = base.substr(colon + 1);
  int port = 0;
  const auto [end, ec] =
      std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (ec != std::errc() || end != port_text.data() + port_text.size() || port < 1 || port > 65533) {
    throw Error("endpoint '" + base +
                "': port must be a number in 1..65533 (three ports are used)");
  }
  return {host + ":" + std::to_string(port), host + ":" + std::to_string(port + 1),
          host + ":" + std::to_string(port + 2)};
}

bool is_local_endpoint(const std::string& endpoint) {
  if (starts_with(endpoint, "inproc://") || starts_with(endpoint, "ipc://")) return true;
  if (!starts_with(endpoint, "tcp://")) return false;
  std::string host = endpoint.substr(6);
  // A connect endpoint may name a source address first ("tcp://SRC;HOST:PORT").
  if (const size_t semi = host.find(';'); semi != std::string::npos) host = host.substr(semi + 1);
  if (const size_t colon = host.rfind(':'); colon != std::string::npos) host.resize(colon);
  return starts_with(host, "127.") || host == "localhost" || host == "[::1]" || host == "::1";
}

HostFamilies resolve_host_families(const std::string& host) {
  HostFamilies f;
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host.c_str(), nullptr, &hints, &found) != 0) return f;
  for (const addrinfo* a = found; a; a = a->ai_next) {
    f.ipv4 |= a->ai_family == AF_INET;
    f.ipv6 |= a->ai_family == AF_INET6;
  }
  freeaddrinfo(found);
  return f;
}

bool wants_ipv6(const std::string& endpoint, bool connect, const HostResolver& resolve) {
  if (!starts_with(endpoint, "tcp://")) return false;
  std::string host = endpoint.substr(6);
  if (host.find('[') != std::string::npos) return true;
  if (!connect) return starts_with(host, "*:");
  if (const size_t semi = host.find(';'); semi != std::string::npos) host = host.substr(semi + 1);
  if (const size_t colon = host.rfind(':'); colon != std::string::npos) host.resize(colon);
  in_addr v4{};
  if (host.empty() || inet_pton(AF_INET, host.c_str(), &v4) == 1) return false;
  // A name. One that does not resolve (yet) keeps IPv4: libzmq resolves it again on every
  // reconnect, as it always has.
  const HostFamilies f = resolve(host);
  return f.ipv6 && !f.ipv4;
}

// ---------------------------------------------------------------------------------------------
// Socket set-up

ChannelOptions ChannelOptions::samples() {
  ChannelOptions o;
  o.linger_ms = 0;  // unsent samples are stale by the time anyone would get them
  // About 3 kB per batch of 128 samples with world positions: a handful of milliseconds of
  // samples in each queue instead of the defaults' seconds.
  o.send_hwm = 16;
  o.receive_hwm = 64;
  // The kernel holds up to twice this of a sender's data (Linux doubles it) unsent or in
  // flight: 4 ms of a saturated gigabit, a LAN's round trips many times over, and room for a
  // sender descheduled for a moment; 41 ms of 100 Mbit, where sampler_node --send-buffer 32768
  // keeps samples fresh (bench/results/flow.md, goodput.md).
  o.send_buffer = 256 << 10;
  o.receive_buffer = 256 << 10;
  o.max_message_bytes = int64_t(kMaxSampleChannelMessage) + kFrameHeadroom;
  o.sender_queue = 16;
  return o;
}

ChannelOptions ChannelOptions::control() {
  ChannelOptions o;
  o.linger_ms = 500;  // a leave or a last chunk gets out; a dead peer cannot hold close()
  o.send_hwm = 64;    // scene chunks are up to 1 MiB: at most 64 MiB queued per peer
  o.receive_hwm = 256;
  o.max_message_bytes = int64_t(kMaxControlChannelMessage) + kFrameHeadroom;
  return o;
}

ChannelOptions ChannelOptions::views() {
  ChannelOptions o;
  o.linger_ms = 0;
  o.send_hwm = 16;
  o.receive_hwm = 16;
  o.max_message_bytes = int64_t(kMaxViewChannelMessage) + kFrameHeadroom;
  return o;
}

namespace {

constexpr const char* kZapDomain = "afr";

void apply_options(zmq::socket_t& s, const ChannelOptions& o) {
  set_int(s, ZMQ_LINGER, o.linger_ms);
  set_int(s, ZMQ_SNDHWM, o.send_hwm);
  set_int(s, ZMQ_RCVHWM, o.receive_hwm);
  if (o.send_buffer > 0) set_int(s, ZMQ_SNDBUF, o.send_buffer);
  if (o.receive_buffer > 0) set_int(s, ZMQ_RCVBUF, o.receive_buffer);
  set_int64(s, ZMQ_MAXMSGSIZE, o.max_message_bytes);
  set_int(s, ZMQ_RECONNECT_IVL, o.reconnect_ms);
  set_int(s, ZMQ_RECONNECT_IVL_MAX, o.reconnect_max_ms);
  // Set on every socket, bound or connecting: accepted connections inherit them.
  if (o.keepalive_idle_s > 0) {
    set_int(s, ZMQ_TCP_KEEPALIVE, 1);
    set_int(s, ZMQ_TCP_KEEPALIVE_IDLE, o.keepalive_idle_s);
    set_int(s, ZMQ_TCP_KEEPALIVE_INTVL, o.keepalive_interval_s);
    set_int(s, ZMQ_TCP_KEEPALIVE_CNT, o.keepalive_count);
  }
  if (o.max_retransmit_ms > 0) set_int(s, ZMQ_TCP_MAXRT, o.max_retransmit_ms);
}

void apply_security(zmq::socket_t& s, const Security& security, const Context& context,
                    const std::string& endpoint) {
  if (!security.enabled()) return;
  if (!is_curve_key(security.own.secret_key) || !is_curve_key(security.own.public_key)) {
    throw Error(endpoint + ": malformed CurveZMQ key pair");
  }
  if (security.is_server()) {
    // Without a ZAP handler libzmq admits every client key: refuse to run like that.
    if (!context.state().zap) {
      throw Error(endpoint +
                  ": a CurveZMQ server needs an allow-list of client keys "
                  "(Context::allow_curve_clients)");
    }
    set_int(s, ZMQ_CURVE_SERVER, 1);
    set_string(s, ZMQ_CURVE_SECRETKEY, security.own.secret_key);
    set_string(s, ZMQ_ZAP_DOMAIN, kZapDomain);
    return;
  }
  if (!is_curve_key(security.server_public_key)) {
    throw Error(endpoint + ": malformed CurveZMQ server public key");
  }
  set_string(s, ZMQ_CURVE_SERVERKEY, security.server_public_key);
  set_string(s, ZMQ_CURVE_PUBLICKEY, security.own.public_key);
  set_string(s, ZMQ_CURVE_SECRETKEY, security.own.secret_key);
}

void enable_ipv6_for(zmq::socket_t& s, const std::string& endpoint, bool connect) {
  // With the option an IPv4 address becomes an IPv4-mapped IPv6 one ("[::ffff:127.0.0.1]") in
  // the socket's endpoint and its peers' addresses: only where IPv6 is needed.
  if (wants_ipv6(endpoint, connect)) set_int(s, ZMQ_IPV6, 1);
}

void bind(zmq::socket_t& s, const std::string& endpoint) {
  enable_ipv6_for(s, endpoint, false);
  try {
    s.bind(endpoint);
  } catch (const zmq::error_t& e) {
    if (starts_with(endpoint, "tcp://*:")) {
      set_int(s, ZMQ_IPV6, 0);
      try {
        s.bind(endpoint);
        return;
      } catch (const zmq::error_t&) {
      }
    }
    throw Error("cannot bind " + endpoint + ": " + e.what());
  }
}

void connect(zmq::socket_t& s, const std::string& endpoint) {
  enable_ipv6_for(s, endpoint, true);
  try {
    s.connect(endpoint);
  } catch (const zmq::error_t& e) {
    throw Error("cannot connect to " + endpoint + ": " + e.what());
  }
}

std::string last_endpoint(const zmq::socket_t& s) { return s.get(zmq::sockopt::last_endpoint); }

// Receives one single-frame message; a multi-frame one is drained and reported as such.
enum class Frame { kNone, kOne, kMultipart };
Frame receive_one(zmq::socket_t& s, zmq::message_t& m) {
  if (!recv_retry(s, m, zmq::recv_flags::dontwait)) return Frame::kNone;
  if (!m.more()) return Frame::kOne;
  zmq::message_t rest;
  while (recv_retry(s, rest, zmq::recv_flags::dontwait) && rest.more()) {
  }
  return Frame::kMultipart;
}

Bytes bytes_of(const zmq::message_t& m) {
  return Bytes(static_cast<const uint8_t*>(m.data()), m.size());
}

Status type_error(MessageType type, const char* channel) {
  return Status::error(std::string(message_type_name(type)) + ": not allowed on the " + channel +
                       " channel");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// SampleSender

SampleSender::SampleSender(Context& context, const std::string& endpoint, const Security& security,
                           const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::push)),
      slots_(size_t(std::max(1, options.sender_queue)) + 1) {
  apply_options(socket_->socket, options);
  // Queue only to completed connections: with no display, messages wait in our queue (which
  // drops the oldest) instead of in a pipe that would deliver them stale after a reconnect.
  set_int(socket_->socket, ZMQ_IMMEDIATE, 1);
  apply_security(socket_->socket, security, context, endpoint);
  connect(socket_->socket, endpoint);
}

SampleSender::~SampleSender() = default;

SampleSender::Slot& SampleSender::push_slot() {
  // One physical slot more than the queue holds: the tail is always free to encode into.
  return slots_[(head_ + size_) % slots_.size()];
}

void SampleSender::pop_slot() {
  head_ = (head_ + 1) % slots_.size();
  --size_;
}

uint64_t& SampleSender::sent_counter(Kind kind) {
  if (kind == Kind::kBatch) return counters_.batches_sent;
  if (kind == Kind::kTiling) return counters_.tilings_sent;
  return counters_.coverage_sent;
}

uint64_t& SampleSender::dropped_counter(Kind kind) {
  if (kind == Kind::kBatch) return counters_.batches_dropped;
  if (kind == Kind::kTiling) return counters_.tilings_dropped;
  return counters_.coverage_dropped;
}

void SampleSender::commit_slot(Kind kind) {
  push_slot().kind = kind;
  if (size_ == slots_.size() - 1) {
    // Popping the head leaves the tail, the slot just encoded, where it is.
    ++dropped_counter(slots_[head_].kind);
    pop_slot();
  }
  ++size_;
  pump();
}

Status SampleSender::send(const SampleBatch& batch, const ImageExtent& bounds) {
  if (Status s = encode(batch, &push_slot().bytes, bounds); !s) return s;
  commit_slot(Kind::kBatch);
  return {};
}

Status SampleSender::send(const TilingSnapshot& snapshot, const ImageExtent& bounds) {
  if (Status s = encode(snapshot, &push_slot().bytes, bounds); !s) return s;
  commit_slot(Kind::kTiling);
  return {};
}

Status SampleSender::send(const WallCoverage& coverage, const ImageExtent& bounds) {
  if (Status s = encode(coverage, &push_slot().bytes, bounds); !s) return s;
  commit_slot(Kind::kCoverage);
  return {};
}

size_t SampleSender::pump() {
  while (size_ > 0) {
    Slot& slot = slots_[head_];
    zmq::message_t m(slot.bytes.data(), slot.bytes.size());
    if (!send_retry(socket_->socket, m, zmq::send_flags::dontwait)) break;
    ++sent_counter(slot.kind);
    counters_.bytes_sent += slot.bytes.size();
    pop_slot();
  }
  return size_;
}

bool SampleSender::flush(int timeout_ms) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  while (pump() > 0) {
    int wait = -1;
    if (timeout_ms >= 0) {
      wait = int(
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count());
      if (wait <= 0) return false;
    }
    detail::wait_writable(socket_->socket, wait);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// SampleReceiver

SampleReceiver::SampleReceiver(Context& context, const std::string& endpoint,
                               const Security& security, const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::pull)) {
  apply_options(socket_->socket, options);
  apply_security(socket_->socket, security, context, endpoint);
  bind(socket_->socket, endpoint);
}

SampleReceiver::~SampleReceiver() = default;

std::string SampleReceiver::endpoint() const { return last_endpoint(socket_->socket); }

std::string_view SampleReceiver::peer_key() const {
  // The ZAP handler's user id, which afr's handler sets to the client's Z85 key; libzmq keeps it
  // in the metadata of every message of that connection.
  const char* user = zmq_msg_gets(socket_->message.handle(), "User-Id");
  return user ? std::string_view(user) : std::string_view();
}

SampleReceiver::Got SampleReceiver::receive(int timeout_ms) {
  if (timeout_ms != 0 && !wait_readable(socket_->socket, timeout_ms)) return Got::kNothing;
  const Frame frame = receive_one(socket_->socket, socket_->message);
  if (frame == Frame::kNone) return Got::kNothing;
  counters_.bytes += socket_->message.size();
  const auto reject = [&](Status s) {
    rejection_ = std::move(s);
    ++counters_.rejected;
    return Got::kRejected;
  };
  if (frame == Frame::kMultipart) {
    return reject(Status::error("message: multipart messages are not part of the protocol"));
  }
  const Bytes bytes = bytes_of(socket_->message);
  Result<Header> header = peek_header(bytes);
  if (!header) return reject(header.status());
  if (header->type == MessageType::kSampleBatch) {
    if (Status s = decode(bytes, &batch_, image_bounds()); !s) return reject(std::move(s));
    ++counters_.batches;
    counters_.samples += batch_.samples.size();
    return Got::kBatch;
  }
  if (header->type == MessageType::kTilingSnapshot) {
    if (Status s = decode(bytes, &tiling_, image_bounds()); !s) return reject(std::move(s));
    ++counters_.tilings;
    return Got::kTiling;
  }
  if (header->type == MessageType::kWallCoverage) {
    if (Status s = decode(bytes, &coverage_, image_bounds()); !s) return reject(std::move(s));
    ++counters_.coverage;
    return Got::kCoverage;
  }
  return reject(type_error(header->type, "sample"));
}

// ---------------------------------------------------------------------------------------------
// Views

ViewPublisher::ViewPublisher(Context& context, const std::string& endpoint,
                             const Security& security, const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::pub)) {
  apply_options(socket_->socket, options);
  // A PUB socket drops the NEWEST message when a subscriber's queue is full; conflating keeps
  // one message per subscriber instead, and it is always the latest view.
  set_int(socket_->socket, ZMQ_CONFLATE, 1);
  apply_security(socket_->socket, security, context, endpoint);
  bind(socket_->socket, endpoint);
}

ViewPublisher::~ViewPublisher() = default;

std::string ViewPublisher::endpoint() const { return last_endpoint(socket_->socket); }

Status ViewPublisher::publish(const View& view) {
  if (Status s = encode(view, &buffer_); !s) return s;
  zmq::message_t m(buffer_.data(), buffer_.size());
  send_retry(socket_->socket, m, zmq::send_flags::dontwait);  // PUB never blocks; it drops
  return {};
}

ViewSubscriber::ViewSubscriber(Context& context, const std::string& endpoint,
                               const Security& security, const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::sub)) {
  apply_options(socket_->socket, options);
  set_int(socket_->socket, ZMQ_CONFLATE, 1);  // keep only the latest view
  set_string(socket_->socket, ZMQ_SUBSCRIBE, "");
  apply_security(socket_->socket, security, context, endpoint);
  connect(socket_->socket, endpoint);
}

ViewSubscriber::~ViewSubscriber() = default;

std::optional<View> ViewSubscriber::receive(int timeout_ms) {
  if (timeout_ms != 0 && !wait_readable(socket_->socket, timeout_ms)) return std::nullopt;
  zmq::message_t m;
  const Frame frame = receive_one(socket_->socket, m);
  if (frame == Frame::kNone) return std::nullopt;
  View view;
  Status s = frame == Frame::kMultipart
                 ? Status::error("message: multipart messages are not part of the protocol")
                 : decode(bytes_of(m), &view);
  if (!s) {
    rejection_ = std::move(s);
    ++rejected_;
    return std::nullopt;
  }
  return view;
}

// ---------------------------------------------------------------------------------------------
// Control

bool allowed_to_display(MessageType type) {
  return type == MessageType::kJoin || type == MessageType::kSceneRequest ||
         type == MessageType::kStats || type == MessageType::kHeartbeat ||
         type == MessageType::kLeave || type == MessageType::kDisplayJoin;
}

bool allowed_to_sampler(MessageType type) {
  return type == MessageType::kWelcome || type == MessageType::kSceneChunk ||
         type == MessageType::kRegionAssignment || type == MessageType::kHeartbeat ||
         type == MessageType::kLeave || type == MessageType::kWallLayout ||
         type == MessageType::kSnapshotRequest || type == MessageType::kMemberList;
}

namespace {

// The decoded message if it is allowed in this direction.
Result<Message> decode_control(Bytes bytes, bool (*allowed)(MessageType)) {
  Result<Header> header = peek_header(bytes);
  if (!header) return header.status();
  if (!allowed(header->type)) return type_error(header->type, "control");
  return decode_message(bytes);
}

}  // namespace

ControlServer::ControlServer(Context& context, const std::string& endpoint,
                             const Security& security, const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::router)) {
  apply_options(socket_->socket, options);
  // Sending to an unknown peer fails instead of vanishing.
  set_int(socket_->socket, ZMQ_ROUTER_MANDATORY, 1);
  apply_security(socket_->socket, security, context, endpoint);
  bind(socket_->socket, endpoint);
}

ControlServer::~ControlServer() = default;

std::string ControlServer::endpoint() const { return last_endpoint(socket_->socket); }

std::optional<ControlServer::Incoming> ControlServer::receive(int timeout_ms) {
  if (timeout_ms != 0 && !wait_readable(socket_->socket, timeout_ms)) return std::nullopt;
  zmq::message_t id;
  if (!recv_retry(socket_->socket, id, zmq::recv_flags::dontwait)) return std::nullopt;
  std::string peer(static_cast<const char*>(id.data()), id.size());
  if (!id.more()) {  // a ROUTER always prefixes the routing id; nothing follows: malformed
    return Incoming{peer, "", Status::error("message: empty")};
  }
  zmq::message_t m;
  const Frame frame = receive_one(socket_->socket, m);
  if (frame == Frame::kNone) return std::nullopt;
  const char* user = zmq_msg_gets(m.handle(), "User-Id");
  std::string key = user ? user : "";
  if (frame == Frame::kMultipart) {
    return Incoming{std::move(peer), std::move(key),
                    Status::error("message: multipart messages are not part of the protocol")};
  }
  return Incoming{std::move(peer), std::move(key), decode_control(bytes_of(m), allowed_to_display)};
}

Status ControlServer::send(const std::string& peer, const Message& message) {
  if (!allowed_to_sampler(message_type(message))) {
    return type_error(message_type(message), "control (display -> sampler)");
  }
  if (Status s = encode(message, &buffer_); !s) return s;
  zmq::message_t id(peer.data(), peer.size());
  zmq::message_t m(buffer_.data(), buffer_.size());
  int error = 0;
  if (!send_retry(socket_->socket, id, zmq::send_flags::sndmore | zmq::send_flags::dontwait,
                  &error) ||
      !send_retry(socket_->socket, m, zmq::send_flags::dontwait, &error)) {
    return Status::error(
        std::string(message_type_name(message_type(message))) + ": " +
        (error == EHOSTUNREACH ? "peer is not connected" : "peer's queue is full"));
  }
  return {};
}

ControlClient::ControlClient(Context& context, const std::string& endpoint,
                             const Security& security, const ChannelOptions& options)
    : socket_(std::make_unique<detail::Socket>(context, zmq::socket_type::dealer)) {
  apply_options(socket_->socket, options);
  apply_security(socket_->socket, security, context, endpoint);
  connect(socket_->socket, endpoint);
}

ControlClient::~ControlClient() = default;

std::optional<Result<Message>> ControlClient::receive(int timeout_ms) {
  if (timeout_ms != 0 && !wait_readable(socket_->socket, timeout_ms)) return std::nullopt;
  zmq::message_t m;
  const Frame frame = receive_one(socket_->socket, m);
  if (frame == Frame::kNone) return std::nullopt;
  if (frame == Frame::kMultipart) {
    return Result<Message>(
        Status::error("message: multipart messages are not part of the protocol"));
  }
  return decode_control(bytes_of(m), allowed_to_sampler);
}

Status ControlClient::send(const Message& message) {
  if (!allowed_to_display(message_type(message))) {
    return type_error(message_type(message), "control (sampler -> display)");
  }
  if (Status s = encode(message, &buffer_); !s) return s;
  zmq::message_t m(buffer_.data(), buffer_.size());
  if (!send_retry(socket_->socket, m, zmq::send_flags::dontwait)) {
    return Status::error(std::string(message_type_name(message_type(message))) + ": queue is full");
  }
  return {};
}

}  // namespace afr::protocol
