#include <afr/protocol/display_link.h>

#include "zmq_state.h"

#include <zmq.h>

#include <cerrno>
#include <chrono>

namespace afr::protocol {

namespace {

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

DisplayLink::DisplayLink(Context& context, const DisplayLinkOptions& options)
    : options_(options),
      control_(context, service_endpoints(options.display).control, options.security),
      views_(context, service_endpoints(options.display).views, options.security),
      display_(options.expected_interval,
               FailureDetectorOptions::with_floor(options.silence_floor)),
      started_(steady_seconds()) {
  display_.reset(started_);
}

DisplayLink::State DisplayLink::state() {
  const double now = steady_seconds();
  if (joined_) return display_.suspect(now) ? State::kSilent : State::kJoined;
  if (now - started_ > options_.fresh_sockets_after) return State::kGiveUp;
  if (!reported_unanswered_ && now - started_ > options_.unanswered_after) {
    reported_unanswered_ = true;
    return State::kUnanswered;
  }
  return State::kJoining;
}

bool DisplayLink::join_due() {
  const double now = steady_seconds();
  if (joined_ || now - last_join_ < options_.join_interval) return false;
  last_join_ = now;
  return true;
}

void DisplayLink::welcomed() { joined_ = true; }

bool DisplayLink::heartbeat_due() {
  const double now = steady_seconds();
  if (!joined_ || now - last_heartbeat_ < options_.heartbeat_interval) return false;
  last_heartbeat_ = now;
  return true;
}

double DisplayLink::silence() const { return display_.silence(steady_seconds()); }

void DisplayLink::wait(int timeout_ms) {
  zmq_pollitem_t items[] = {{detail::SocketAccess::socket(control_).handle(), 0, ZMQ_POLLIN, 0},
                            {detail::SocketAccess::socket(views_).handle(), 0, ZMQ_POLLIN, 0}};
  // A signal ends the wait early (EINTR); the owner's loop comes back here anyway.
  (void)zmq_poll(items, 2, timeout_ms);
}

std::optional<Result<Message>> DisplayLink::receive_control() {
  std::optional<Result<Message>> m = control_.receive(0);
  if (m && m->ok()) display_.heard(steady_seconds());
  return m;
}

std::optional<View> DisplayLink::receive_view() { return views_.receive(0); }

}  // namespace afr::protocol
