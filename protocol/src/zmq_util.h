// ZeroMQ calls that survive signals: cppzmq throws zmq::error_t on EINTR (a signal arrived
// during a blocking call), which is not an error for afr, so every call retries it; and poll
// with a deadline that the retries respect. Private to afr_protocol.
#pragma once

#include <zmq.hpp>

#include <chrono>
#include <optional>

namespace afr::protocol::detail {

// Returns false when nothing was there (dontwait) or the context is terminating.
bool recv_retry(zmq::socket_t& socket, zmq::message_t& message, zmq::recv_flags flags);
// Returns false when the message was not queued (EAGAIN: high-water mark or no peer;
// EHOSTUNREACH: unknown ROUTER peer); `error` receives errno then.
bool send_retry(zmq::socket_t& socket, zmq::message_t& message, zmq::send_flags flags,
                int* error = nullptr);
// Waits until `socket` is readable or timeout_ms passes (-1: forever). True when readable.
bool wait_readable(zmq::socket_t& socket, int timeout_ms);
// Waits until `socket` takes a message without blocking, or timeout_ms passes.
bool wait_writable(zmq::socket_t& socket, int timeout_ms);

void set_int(zmq::socket_t& socket, int option, int value);
void set_int64(zmq::socket_t& socket, int option, int64_t value);
void set_string(zmq::socket_t& socket, int option, const std::string& value);

}  // namespace afr::protocol::detail
