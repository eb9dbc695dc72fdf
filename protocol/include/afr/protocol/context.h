// The ZeroMQ context of a process and, for CurveZMQ servers, its ZAP handler: the thread that
// answers libzmq's authentication requests on inproc://zeromq.zap.01 and admits only clients
// whose public key is on the allow-list. Without a handler libzmq accepts ANY client key, so
// the channels refuse to make a Curve server socket on a context that has none.
//
// Ownership: sockets (the channels of channels.h) hold a reference to the Context and must be
// destroyed before it; the Context's destructor stops the handler, then terminates ZeroMQ.
#pragma once

#include <zmq.hpp>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
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

class ZapHandler {
 public:
  using Callback = std::function<void(const ZapDecision&)>;

  // Binds inproc://zeromq.zap.01 on `context` and starts the thread. `on_decision` runs on
  // the handler's thread for every request (for logging refused keys); it may be empty.
  ZapHandler(zmq::context_t& context, std::vector<std::string> allowed_keys,
             Callback on_decision = {});
  ~ZapHandler();
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;

  // Replaces the allow-list; later handshakes see the new one.
  void set_allowed_keys(std::vector<std::string> keys);

  uint64_t accepted() const { return accepted_.load(); }
  uint64_t refused() const { return refused_.load(); }

 private:
  void run();
  bool allowed(const std::string& key) const;
  void handle_request();

  zmq::socket_t handler_;     // REP on the ZAP endpoint; used by the thread only
  zmq::socket_t stop_rx_;     // PAIR: the destructor's wake-up, thread side
  zmq::socket_t stop_tx_;     // PAIR: destructor side
  mutable std::mutex mutex_;  // guards allowed_
  std::vector<std::string> allowed_;
  Callback on_decision_;
  std::atomic<uint64_t> accepted_{0};
  std::atomic<uint64_t> refused_{0};
  std::thread thread_;
};

class Context {
 public:
  explicit Context(int io_threads = 1);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  // Admits CurveZMQ clients with these public keys (Z85) to every Curve server socket made on
  // this context from now on, starting the ZAP handler on first use. Throws afr::Error for a
  // malformed key.
  void allow_curve_clients(std::vector<std::string> public_keys,
                           ZapHandler::Callback on_decision = {});
  // The handler, or nullptr when allow_curve_clients was never called.
  const ZapHandler* zap() const { return zap_.get(); }

  zmq::context_t& zmq() { return context_; }

 private:
  zmq::context_t context_;
  std::unique_ptr<ZapHandler> zap_;
};

}  // namespace afr::protocol
