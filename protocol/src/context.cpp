#include <afr/protocol/context.h>

#include <afr/common/error.h>
#include <afr/protocol/keys.h>

#include "zmq_state.h"
#include "zmq_util.h"

#include <zmq.h>

#include <algorithm>
#include <array>
#include <cstdio>

namespace afr::protocol {

using detail::ZapHandler;

namespace {

constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";

std::string frame_text(const zmq::message_t& m) { return std::string(m.to_string_view()); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// ZapHandler

namespace detail {

ZapHandler::ZapHandler(zmq::context_t& context, std::vector<std::string> allowed_keys,
                       Context::ZapCallback on_decision)
    : handler_(context, zmq::socket_type::rep),
      stop_rx_(context, zmq::socket_type::pair),
      stop_tx_(context, zmq::socket_type::pair),
      allowed_(std::move(allowed_keys)),
      on_decision_(std::move(on_decision)) {
  handler_.set(zmq::sockopt::linger, 0);
  stop_rx_.set(zmq::sockopt::linger, 0);
  stop_tx_.set(zmq::sockopt::linger, 0);
  try {
    handler_.bind(kZapEndpoint);
  } catch (const zmq::error_t& e) {
    throw Error(std::string("cannot start the ZAP handler (") + kZapEndpoint + "): " + e.what());
  }
  char name[64];
  std::snprintf(name, sizeof(name), "inproc://afr-zap-stop-%p", static_cast<void*>(this));
  stop_rx_.bind(name);
  stop_tx_.connect(name);
  // Bound before the thread starts, so no handshake can happen without a handler.
  thread_ = std::thread([this] { run(); });
}

ZapHandler::~ZapHandler() {
  zmq::message_t stop;
  (void)stop_tx_.send(stop, zmq::send_flags::none);
  thread_.join();
}

void ZapHandler::set_allowed_keys(std::vector<std::string> keys) {
  std::lock_guard<std::mutex> lock(mutex_);
  allowed_ = std::move(keys);
}

bool ZapHandler::allowed(const std::string& key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::find(allowed_.begin(), allowed_.end(), key) != allowed_.end();
}

void ZapHandler::run() {
  zmq_pollitem_t items[] = {{handler_.handle(), 0, ZMQ_POLLIN, 0},
                            {stop_rx_.handle(), 0, ZMQ_POLLIN, 0}};
  for (;;) {
    if (zmq_poll(items, 2, -1) < 0) {
      if (zmq_errno() == EINTR) continue;
      return;  // context terminated
    }
    if (items[1].revents & ZMQ_POLLIN) return;
    if (items[0].revents & ZMQ_POLLIN) handle_request();
  }
}

// RFC 27 (ZAP): request = version, request id, domain, address, identity, mechanism,
// credentials...; reply = version, request id, status code, status text, user id, metadata.
void ZapHandler::handle_request() {
  std::vector<zmq::message_t> frames;
  for (;;) {
    zmq::message_t frame;
    if (!detail::recv_retry(handler_, frame, zmq::recv_flags::dontwait)) break;
    const bool more = frame.more();
    frames.push_back(std::move(frame));
    if (!more) break;
  }
  if (frames.empty()) return;

  ZapDecision d;
  std::string status = "400", text = "malformed ZAP request";
  if (frames.size() >= 6 && frame_text(frames[0]) == "1.0") {
    d.domain = frame_text(frames[2]);
    d.address = frame_text(frames[3]);
    // An IPv4 peer of a dual-stack (wildcard) socket comes as "::ffff:a.b.c.d".
    if (d.address.rfind("::ffff:", 0) == 0 && d.address.find('.') != std::string::npos) {
      d.address.erase(0, 7);
    }
    d.mechanism = frame_text(frames[5]);
    if (d.mechanism == "CURVE" && frames.size() == 7 && frames[6].size() == 32) {
      std::array<char, 41> z85{};
      zmq_z85_encode(z85.data(), static_cast<const uint8_t*>(frames[6].data()), 32);
      d.public_key = z85.data();
      d.accepted = allowed(d.public_key);
      text = d.accepted ? "OK" : "public key not on the allow-list";
    } else if (d.mechanism == "NULL") {
      // Only reached for NULL sockets that set a ZAP domain; afr's insecure sockets do not.
      // They are insecure by configuration, so the handler does not stand in their way.
      d.accepted = true;
      text = "OK";
    } else {
      text = "mechanism " + d.mechanism + " is not accepted";
    }
    if (d.accepted) status = "200";
  }
  (d.accepted ? accepted_ : refused_).fetch_add(1);
  if (on_decision_) on_decision_(d);

  const std::string request_id = frames.size() > 1 ? frame_text(frames[1]) : "";
  const std::string reply[] = {"1.0", request_id, status, text, d.accepted ? d.public_key : "", ""};
  for (size_t i = 0; i < 6; ++i) {
    zmq::message_t m(reply[i].data(), reply[i].size());
    detail::send_retry(handler_, m, i < 5 ? zmq::send_flags::sndmore : zmq::send_flags::none);
  }
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------
// Context

Context::Context(int io_threads) : state_(std::make_unique<detail::ContextState>(io_threads)) {}

Context::~Context() {
  state_->zap.reset();  // before the context, whose termination waits for the handler's sockets
}

void Context::allow_curve_clients(std::vector<std::string> public_keys, ZapCallback on_decision) {
  for (const std::string& key : public_keys) {
    if (!is_curve_key(key)) throw Error("allow-list: malformed CurveZMQ public key '" + key + "'");
  }
  if (!curve_available()) throw Error("this libzmq was built without CurveZMQ");
  if (state_->zap) {
    state_->zap->set_allowed_keys(std::move(public_keys));
    return;
  }
  state_->zap =
      std::make_unique<ZapHandler>(state_->context, std::move(public_keys), std::move(on_decision));
}

std::optional<ZapCounts> Context::zap() const {
  if (!state_->zap) return std::nullopt;
  return ZapCounts{state_->zap->accepted(), state_->zap->refused()};
}

}  // namespace afr::protocol
