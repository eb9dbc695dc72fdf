// What the public headers of afr_protocol keep opaque: ZeroMQ's context with the ZAP handler
// (Context), and a channel's socket (the channels of channels.h). Private to afr_protocol, so
// that no other part of afr depends on ZeroMQ: they send, receive and wait through the channels.
#pragma once

#include <afr/protocol/context.h>

#include <zmq.hpp>

#include <atomic>
#include <mutex>
#include <thread>

namespace afr::protocol::detail {

// The ZAP handler (RFC 27): the thread that answers libzmq's authentication requests on
// inproc://zeromq.zap.01 and admits only clients whose public key is on the allow-list. Without
// a handler libzmq accepts ANY client key, so the channels refuse to make a Curve server socket
// on a context that has none.
class ZapHandler {
 public:
  // Binds inproc://zeromq.zap.01 on `context` and starts the thread.
  ZapHandler(zmq::context_t& context, std::vector<std::string> allowed_keys,
             Context::ZapCallback on_decision = {});
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
  Context::ZapCallback on_decision_;
  std::atomic<uint64_t> accepted_{0};
  std::atomic<uint64_t> refused_{0};
  std::thread thread_;
};

struct ContextState {
  explicit ContextState(int io_threads) : context(io_threads) {}
  zmq::context_t context;
  std::unique_ptr<ZapHandler> zap;  // destroyed first: the context's end waits for its sockets
};

// One channel's socket, and the message a receiver decodes from.
struct Socket {
  Socket(Context& context, zmq::socket_type type) : socket(context.state().context, type) {}
  zmq::socket_t socket;
  zmq::message_t message;
};

// The socket behind a channel, for afr_protocol's own code (the channels befriend it).
struct SocketAccess {
  template <class Channel>
  static zmq::socket_t& socket(Channel& channel) {
    return channel.socket_->socket;
  }
};

}  // namespace afr::protocol::detail
