// The ZeroMQ context of a process and, for CurveZMQ servers, its ZAP handler: the thread that
// answers libzmq's authentication requests on inproc://zeromq.zap.01 and admits only clients
// whose public key is on the allow-list. Without a handler libzmq accepts ANY client key, so
// the channels refuse to make a Curve server socket on a context that has none.
//
// Ownership: sockets (the channels of channels.h) hold a reference to the Context and must be
// destroyed before it; the Context's destructor stops the handler, then terminates ZeroMQ.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace afr::protocol {

// One authentication decision, as the handler saw it.
struct ZapDecision {
  bool accepted = false;
  std::string mechanism;   // "CURVE", "NULL", ...
  std::string public_key;  // Z85, CURVE only
  std::string address;     // the peer's IP address
  std::string domain;      // the socket's ZAP domain
};

// The ZAP handler's decisions so far.
struct ZapCounts {
  uint64_t accepted = 0;
  uint64_t refused = 0;
};

namespace detail {
struct ContextState;  // ZeroMQ's context and the ZAP handler (afr_protocol's own)
}

class Context {
 public:
  using ZapCallback = std::function<void(const ZapDecision&)>;

  explicit Context(int io_threads = 1);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  // Admits CurveZMQ clients with these public keys (Z85) to every Curve server socket made on
  // this context from now on, starting the ZAP handler on first use. `on_decision` runs on the
  // handler's thread for every request (for logging refused keys); it may be empty. Throws
  // afr::Error for a malformed key.
  void allow_curve_clients(std::vector<std::string> public_keys, ZapCallback on_decision = {});
  // The handler's counts, or nothing when allow_curve_clients was never called.
  std::optional<ZapCounts> zap() const;

  // The channels' access to ZeroMQ (the type is complete only inside afr_protocol).
  detail::ContextState& state() { return *state_; }
  const detail::ContextState& state() const { return *state_; }

 private:
  std::unique_ptr<detail::ContextState> state_;
};

}  // namespace afr::protocol
