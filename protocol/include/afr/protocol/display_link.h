// The client side of a display's control and view channels: what a sampler (sampler_service)
// and a wall's follower display (wall_follower) both do to stay joined to a display. One
// DisplayLink is one connection, a fresh pair of sockets; its owner makes a new one to start
// over. It
//   - says when to (re)send the join, until the owner reports a welcome;
//   - gives up on a handshake that never answers (libzmq does not retry one that the display's
//     ZAP handler refused, so only fresh sockets recover from a key added later);
//   - tells a display that fell silent from a busy one (failure_detector.h): every control
//     message is a sign of life, views are not (a view carries no session, so a restarted
//     display's views would keep a link alive whose control connection never came back);
//   - waits on both channels at once, a signal ending the wait early (EINTR is not an error);
//   - says when a heartbeat is due.
// Times are seconds of the steady clock. Not thread-safe: one thread owns a link.
#pragma once

#include <afr/common/failure_detector.h>
#include <afr/protocol/channels.h>

#include <optional>
#include <string>

namespace afr::protocol {

struct DisplayLinkOptions {
  std::string display;  // the display's base endpoint, tcp://HOST:PORT (service_endpoints)
  Security security;
  double join_interval = 0.5;         // the join is resent this often until a welcome
  double unanswered_after = 5.0;      // then state() reports kUnanswered, once
  double fresh_sockets_after = 10.0;  // then kGiveUp: make a new link
  double silence_floor = 1.5;         // the failure detector's floor (a user's timeout flag)
  double expected_interval = kDisplayHeartbeatInterval;  // how often the display speaks
  double heartbeat_interval = kMemberHeartbeatInterval;  // how often this side speaks
};

class DisplayLink {
 public:
  enum class State {
    kJoining,     // no welcome yet
    kUnanswered,  // no welcome after unanswered_after (reported once, then kJoining again)
    kGiveUp,      // no welcome after fresh_sockets_after: this link is done
    kJoined,      // welcomed, and the display speaks
    kSilent,      // welcomed, and the display's silence is beyond a busy display's
  };

  // Connects both channels (throws afr::Error naming the endpoint when it cannot).
  DisplayLink(Context& context, const DisplayLinkOptions& options);

  State state();
  // True when a join should go out now (not welcomed, join_interval since the last one).
  bool join_due();
  // The owner got a welcome; from now on silence counts.
  void welcomed();
  bool joined() const { return joined_; }
  // True when a heartbeat should go out now (welcomed, heartbeat_interval since the last).
  bool heartbeat_due();
  // Seconds since the display last spoke on the control channel.
  double silence() const;

  // Waits up to timeout_ms for a message on either channel.
  void wait(int timeout_ms);
  // The next queued control message (a sign of the display's life), or why it was rejected, or
  // nothing when none is queued.
  std::optional<Result<Message>> receive_control();
  // The next queued view; nothing when none is queued or it was rejected (see views()).
  std::optional<View> receive_view();
  Status send(const Message& message) { return control_.send(message); }
  const ViewSubscriber& views() const { return views_; }

 private:
  DisplayLinkOptions options_;
  ControlClient control_;
  ViewSubscriber views_;
  FailureDetector display_;
  double started_ = 0.0, last_join_ = -1e300, last_heartbeat_ = -1e300;
  bool joined_ = false, reported_unanswered_ = false;
};

}  // namespace afr::protocol
