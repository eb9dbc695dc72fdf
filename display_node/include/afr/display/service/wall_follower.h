// A follower display of a display wall (docs/wall.md). It joins the lead display's control
// channel for one cell of the lead's grid, binds a sample channel of its own (the samplers push
// to it the samples of its cell plus a margin), learns the lead's clock and camera from its
// views, and feeds what arrives to a SampleSink (the reconstructor) on an ingest thread. When
// the lead goes away or restarts it joins again by itself; a refusal (cell taken, no wall,
// another protocol version) is logged and retried, except for a version mismatch.
//
// Threads: start() launches the control, ingest and (optionally) HTTP metrics threads; stop()
// (or the destructor) joins them. The accessors are safe from any thread.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/clock.h>
#include <afr/common/samples.h>
#include <afr/display/service/display_role.h>
#include <afr/display/service/member_gate.h>
#include <afr/display/service/metrics.h>
#include <afr/display/service/metrics_server.h>
#include <afr/display/service/snapshots.h>
#include <afr/display/service/wall_exchange.h>
#include <afr/protocol/channels.h>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace afr::service {

struct WallFollowerOptions {
  std::string lead;  // the lead display's base endpoint, tcp://HOST:PORT
  // This node's sample channel: bound here, and told to samplers as `advertise` (default: the
  // bound endpoint; give the address samplers reach when binding 0.0.0.0).
  std::string bind = "tcp://127.0.0.1:7200";
  std::string advertise;
  int column = 0;
  int row = 0;
  std::string name;
  // CurveZMQ: as a client of the lead (own key pair and the lead's public key), and as the
  // server of its own sample channel (the same key pair, the samplers' allow-list).
  protocol::CurveKeyPair keys;
  std::string lead_public_key;
  std::vector<std::string> allowed_keys;
  double lead_timeout = 1.5;  // seconds without a word from the lead before joining again
  double heartbeat_interval = protocol::kMemberHeartbeatInterval;
  std::string metrics_address = "127.0.0.1";
  int metrics_port = 0;
};

class WallFollower final : public DisplayRole {
 public:
  // Binds the sample channel and the metrics port (throws afr::Error naming what failed).
  WallFollower(WallFollowerOptions options, SampleSink& sink);
  ~WallFollower() override;
  WallFollower(const WallFollower&) = delete;
  WallFollower& operator=(const WallFollower&) = delete;

  void start();
  void stop() override;
  // Waits until the lead has admitted this node (a layout naming it, and a view), logging
  // every 5 s. False when `stop` turned true or the lead refused the node for good first.
  bool wait_until_admitted(const std::atomic<bool>& stop);

  // The lead's clock (display time, seconds) and the camera of its latest view.
  double now() const override { return clock_.now(); }
  std::optional<Camera> camera() const;
  // The camera of the lead's view nearest display time t among the last kViewHistory (the
  // latest one for an image of now; for a snapshot of a moment just past, that moment's).
  Camera camera_at(double t) const override;
  static constexpr size_t kViewHistory = 128;
  // The layout once admitted, and this node's id and cell in it.
  std::optional<protocol::WallLayout> layout() const;
  uint32_t node_id() const;
  PixelRect cell() const override;
  std::optional<WallPosition> wall_position() const override;
  // The preset the lead names (its welcome), "" before joining.
  std::string preset() const;
  // The sample endpoint as bound (the port resolved for "tcp://HOST:*").
  std::string endpoint() const;
  // True once the lead refused this node for good (another protocol version).
  bool failed() const override { return failed_.load(); }
  ServiceMetrics& metrics() override { return metrics_; }
  uint64_t session() const override { return 0; }
  std::vector<std::pair<uint32_t, PixelRect>> regions() const override { return {}; }
  // The coverage the wall's other nodes sent this one (WallPeerLinks::apply takes it).
  WallCoverageInbox& wall_coverage() override { return wall_coverage_; }
  // The lead's sample endpoint (the layout leaves the lead's own entry empty).
  std::string lead_samples_endpoint() const override;
  // Snapshots the lead asked for (snapshot_request).
  SnapshotQueue& snapshots() override { return snapshots_; }

 private:
  void control_loop();

  WallFollowerOptions options_;
  SampleSink& sink_;
  ServiceMetrics metrics_;
  WallCoverageInbox wall_coverage_;
  RemoteClock clock_;
  protocol::Context context_;
  std::unique_ptr<protocol::SampleReceiver> samples_;
  std::unique_ptr<MetricsServer> http_;
  mutable std::mutex mutex_;
  std::optional<Camera> camera_;
  std::deque<protocol::View> views_;  // the latest kViewHistory views, oldest first
  SnapshotQueue snapshots_;
  // The lead's members (member_list): the ingest stores only their batches.
  MemberGate gate_;
  std::optional<protocol::WallLayout> layout_;
  uint32_t node_id_ = 0;
  std::string preset_;
  std::atomic<bool> running_{false};
  std::atomic<bool> failed_{false};
  std::thread control_thread_, ingest_thread_;
};

}  // namespace afr::service
