#include "zmq_util.h"

#include <afr/common/error.h>

#include <zmq.h>

#include <cerrno>
#include <string>

namespace afr::protocol::detail {

bool recv_retry(zmq::socket_t& socket, zmq::message_t& message, zmq::recv_flags flags) {
  for (;;) {
    try {
      return socket.recv(message, flags).has_value();
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;
      if (e.num() == ETERM) return false;
      throw;
    }
  }
}

bool send_retry(zmq::socket_t& socket, zmq::message_t& message, zmq::send_flags flags, int* error) {
  bool rechecked = false;
  for (;;) {
    try {
      if (socket.send(message, flags).has_value()) return true;
      // A non-blocking send reads the socket's command mailbox at most about once a
      // millisecond (libzmq throttles it), so a pipe that has room again can still look full:
      // sends top out near one high-water mark per millisecond. Reading ZMQ_EVENTS processes
      // the commands unthrottled; then one more try.
      if (!rechecked && (socket.get(zmq::sockopt::events) & ZMQ_POLLOUT)) {
        rechecked = true;
        continue;
      }
      if (error) *error = EAGAIN;
      return false;
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;
      if (e.num() == EHOSTUNREACH || e.num() == ETERM) {
        if (error) *error = e.num();
        return false;
      }
      throw;
    }
  }
}

namespace {

bool wait_for(zmq::socket_t& socket, short events, int timeout_ms) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  zmq_pollitem_t item = {socket.handle(), 0, events, 0};
  int wait = timeout_ms;
  for (;;) {
    const int rc = zmq_poll(&item, 1, wait);
    if (rc > 0) return true;
    if (rc == 0) return false;
    if (zmq_errno() != EINTR) return false;  // ETERM: shutting down
    if (timeout_ms >= 0) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return false;
      wait = int(left);
    }
  }
}

}  // namespace

bool wait_readable(zmq::socket_t& socket, int timeout_ms) {
  return wait_for(socket, ZMQ_POLLIN, timeout_ms);
}

bool wait_writable(zmq::socket_t& socket, int timeout_ms) {
  return wait_for(socket, ZMQ_POLLOUT, timeout_ms);
}

void set_int(zmq::socket_t& socket, int option, int value) {
  if (zmq_setsockopt(socket.handle(), option, &value, sizeof(value)) != 0) {
    throw Error("zmq_setsockopt(" + std::to_string(option) + ", " + std::to_string(value) +
                "): " + zmq_strerror(zmq_errno()));
  }
}

void set_int64(zmq::socket_t& socket, int option, int64_t value) {
  if (zmq_setsockopt(socket.handle(), option, &value, sizeof(value)) != 0) {
    throw Error("zmq_setsockopt(" + std::to_string(option) + ", " + std::to_string(value) +
                "): " + zmq_strerror(zmq_errno()));
  }
}

void set_string(zmq::socket_t& socket, int option, const std::string& value) {
  if (zmq_setsockopt(socket.handle(), option, value.data(), value.size()) != 0) {
    throw Error("zmq_setsockopt(" + std::to_string(option) + "): " + zmq_strerror(zmq_errno()));
  }
}

}  // namespace afr::protocol::detail
