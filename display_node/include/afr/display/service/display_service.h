// The display node's network side (DESIGN.md, "Network"; docs/service.md): it binds the three
// channels, runs the coordinator (membership, regions), owns the display clock (seconds since
// the session start), broadcasts views at the refresh rate, serves the scene to samplers in
// chunks, and feeds every received batch and tiling to a SampleSink (the reconstructor) on an
// ingest thread, asynchronous from reconstruction. Optionally serves /metrics and /stats.
//
// Threads: start() launches the control thread, the ingest thread and the HTTP thread; stop()
// (or the destructor) joins them. now(), metrics() and the accessors are safe from any thread.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/camera_path.h>
#include <afr/common/log.h>
#include <afr/common/samples.h>
#include <afr/common/scene.h>
#include <afr/display/service/coordinator.h>
#include <afr/display/service/display_role.h>
#include <afr/display/service/member_gate.h>
#include <afr/display/service/metrics.h>
#include <afr/display/service/metrics_server.h>
#include <afr/display/service/snapshots.h>
#include <afr/display/service/wall.h>
#include <afr/display/service/wall_exchange.h>
#include <afr/protocol/channels.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace afr::service {

// The scene as the display serves it: the file's bytes and their hash.
struct ScenePayload {
  std::string name;  // file name (without folders), or "builtin"
  std::vector<uint8_t> bytes;
  protocol::SceneHash hash{};
};
// Reads a scene file (empty path: the built-in scene, as builtin_scene_payload). A glTF that refers
// to other files (buffers, images) is packed with them into one .glb (afr/common/gltf_pack.h),
// since only this one payload travels; `name` then ends in .glb. A `variant`
// (KHR_materials_variants) and a `camera` are chosen in the payload (select_material_variant,
// select_camera), and a `ray_depth` is written into it (set_ray_depth; the built-in scene's payload
// carries it), so that the samplers load the scene as the display shows it. Throws afr::Error
// naming the file.
ScenePayload read_scene_payload(const std::string& path, const std::string& variant = "",
                                const std::string& camera = "",
                                std::optional<int> ray_depth = std::nullopt);

struct DisplayServiceOptions {
  std::string bind = "tcp://127.0.0.1:7100";  // base endpoint; ports P, P+1, P+2
  ImageExtent image{256, 256};
  double refresh_interval = 1.0 / 60.0;  // views and samplers' tiling snapshots
  std::string preset = "balanced";       // named to samplers in the welcome
  ScenePayload scene;
  // CurveZMQ: the display's key pair and the samplers allowed; empty own key = no CurveZMQ.
  protocol::CurveKeyPair keys;
  std::vector<std::string> allowed_keys;
  CoordinatorOptions coordinator;
  size_t chunk_bytes = 256 << 10;
  // The camera of the views at a display time (the scene's animation, or a replayed path).
  std::function<Camera(double)> camera_at;
  // HTTP /metrics and /stats; port 0: off.
  std::string metrics_address = "127.0.0.1";
  int metrics_port = 0;
  // Display wall (docs/wall.md): the grid over the image and this lead node's cell. Follower
  // displays (WallFollower) join for the other cells. 1 x 1: no wall.
  WallGrid wall;
  int wall_column = 0;
  int wall_row = 0;
};

// The views' camera at display time t: a replayed path (looping), or the scene's animation
// (looping over its keyframe range, as the samplers' tracers do). `scene` and `path` must
// outlive the function.
std::function<Camera(double)> view_camera_function(const Scene& scene, const CameraPath* path);

// CurveZMQ from --keys DIR (display.key and samplers.allow in it) or --key and --allow, into
// o->keys and o->allowed_keys. Without keys, loopback may go plain; any other address needs
// `insecure` (then a warning). Throws afr::Error saying what is missing.
void configure_security(const std::string& keys_dir, std::string key_file, std::string allow_file,
                        bool insecure, DisplayServiceOptions* o);

// What a display wall's node takes from the wall's other nodes (docs/wall.md, "Seams"): their
// coverage, into `coverage`, and their strays (batches with sampler_id kWallPeerSamplerId).
// With CurveZMQ every node of a wall holds the display's key pair, so only a connection
// authenticated with `key`, that pair's public key, speaks for a node; a sampler's key cannot.
// `key` empty: no CurveZMQ, and nothing tells a node from any other peer.
struct WallPeers {
  WallCoverageInbox* coverage = nullptr;
  std::string key;
};

// Reads the sample channel into `sink` until `running` turns false (waking every 50 ms to
// check), counting in `metrics`. The ingest thread of a display or of a wall's follower.
// `gate` says whether a batch or snapshot comes from the member it names (member_gate.h): those
// that do not are dropped before the sink, counted, and logged at most once a second per cause.
// Without a gate every id counts as a member. on_tiling, when set, sees every accepted snapshot
// before the sink does. `wall`, set on a node of a display wall, admits the wall's strays (to
// the sink, counted apart) and coverage from the connections it names; from any other peer they
// are dropped and counted (a stray as a spoofed batch). A display that is no wall (`wall` null)
// drops strays as from no member (through `gate`) and rejects coverage.
void run_ingest(protocol::SampleReceiver& receiver, SampleSink& sink, ServiceMetrics& metrics,
                MemberGate* gate, const std::atomic<bool>& running,
                const std::function<void(const TilingSnapshot&)>& on_tiling = {},
                const WallPeers* wall = nullptr);

class DisplayService final : public DisplayRole {
 public:
  // Binds everything (throws afr::Error naming the endpoint on failure, e.g. a port in use).
  DisplayService(DisplayServiceOptions options, SampleSink& sink);
  ~DisplayService() override;
  DisplayService(const DisplayService&) = delete;
  DisplayService& operator=(const DisplayService&) = delete;

  void start();
  // Tells the samplers (leave: shutdown) and joins the threads.
  void stop() override;

  // The display clock: seconds since the session started.
  double now() const override;
  // The views' camera: the options' camera function.
  Camera camera_at(double t) const override { return options_.camera_at(t); }
  uint64_t session() const override { return session_; }
  ServiceMetrics& metrics() override { return metrics_; }
  // The current regions by sampler id (for overlays).
  std::vector<std::pair<uint32_t, PixelRect>> regions() const override;
  // This node's cell of the wall (the whole image without a wall), and the current layout.
  PixelRect cell() const override;
  protocol::WallLayout wall_layout() const;
  // The lead is node 1 of every layout it makes.
  std::optional<WallPosition> wall_position() const override {
    return WallPosition{wall_layout(), 1};
  }
  // The coverage the wall's other nodes sent this one (WallPeerLinks::apply takes it).
  WallCoverageInbox& wall_coverage() override { return wall_coverage_; }
  std::string lead_samples_endpoint() const override { return ""; }
  bool failed() const override { return false; }
  SnapshotQueue& snapshots() override { return snapshots_; }

  // A snapshot of one moment (docs/wall.md, "Snapshots"): this node and every follower write
  // their image of display time now() + delay as snapshot_<id>. Throws afr::Error when the
  // delay is out of 0..10 s or one was asked less than 0.2 s ago (the HTTP answer says why).
  struct SnapshotTicket {
    uint64_t id = 0;
    double time = 0.0;
    protocol::WallLayout layout;  // the cells that are asked (the lead's own included)
  };
  SnapshotTicket request_snapshot(double delay);

 private:
  void control_loop();
  void ingest_loop();

  class Control;  // the control thread (display_service.cpp)
  DisplayServiceOptions options_;
  SampleSink& sink_;
  WallCoverageInbox wall_coverage_;
  ServiceMetrics metrics_;
  uint64_t session_ = 0;
  std::chrono::steady_clock::time_point start_;
  protocol::Context context_;
  protocol::ServiceEndpoints endpoints_;
  std::unique_ptr<Control> control_;  // the control thread's sockets and coordinator
  std::unique_ptr<protocol::SampleReceiver> samples_;
  // The members' tokens and keys: the control thread admits, the ingest thread checks.
  MemberGate gate_;
  mutable std::mutex regions_mutex_;
  std::vector<std::pair<uint32_t, PixelRect>> regions_;
  protocol::WallLayout layout_;  // under regions_mutex_
  // Each sampler's tiles as its last snapshot gave them: (tile, error mass = v x area), for
  // the coordinator's cut by error. Ingest thread writes, control thread reads.
  std::mutex errors_mutex_;
  std::map<uint32_t, std::vector<std::pair<PixelRect, double>>> tile_errors_;
  std::atomic<bool> running_{false};
  std::thread control_thread_, ingest_thread_;
  std::unique_ptr<MetricsServer> http_;
  SnapshotQueue snapshots_;
  // Snapshot requests for the followers: the HTTP thread adds, the control thread sends.
  std::mutex snapshot_mutex_;
  std::vector<protocol::SnapshotRequest> snapshot_outbox_;
  uint64_t next_snapshot_id_ = 1;        // under snapshot_mutex_
  double last_snapshot_request_ = -1e9;  // under snapshot_mutex_
  LogLimiter zap_log_;                   // refused CurveZMQ clients (the ZAP thread's only)
};

}  // namespace afr::service
