#include <afr/display/service/display_service.h>

#include <afr/common/log.h>

#include <afr/common/builtin_scene.h>
#include <afr/common/camera_path.h>

#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/gltf_pack.h>
#include <afr/protocol/scene_hash.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <string_view>
#include <utility>

namespace afr::service {

using namespace afr::protocol;

// ---------------------------------------------------------------------------------------------
// Scene payload

ScenePayload read_scene_payload(const std::string& path, const std::string& variant,
                                const std::string& camera, std::optional<int> ray_depth) {
  ScenePayload p;
  if (path.empty()) {
    if (!variant.empty()) {
      throw Error("a material variant needs a scene file (the built-in scene has none)");
    }
    if (!camera.empty()) throw Error("choosing a camera needs a scene file");
    // The built-in scene travels as a short text the samplers build it from, with the ray depth.
    p.name = "builtin";
    const std::string text = builtin_scene_payload(ray_depth);
    p.bytes.assign(text.begin(), text.end());
    if (ray_depth)
      spdlog::info("built-in scene: ray depth {} (secondary rays in a row)", *ray_depth);
  } else {
    p.bytes = read_scene_file(path);
    p.name = std::filesystem::path(path).filename().string();
    if (p.name.size() > kMaxNameBytes) p.name = p.name.substr(p.name.size() - kMaxNameBytes);
    // Only this one payload travels: a glTF that names other files (buffers, images) goes out
    // packed with them into one .glb, which loads on the samplers as the file loads here.
    const std::vector<std::string> external = gltf_external_files(p.bytes, path);
    if (!external.empty()) {
      PackedGltf packed = pack_gltf(p.bytes, path);
      spdlog::info("{}: {} external file(s) ({}{}) packed with it into one .glb of {} bytes", path,
                   packed.packed_files.size(), packed.packed_files.front(),
                   packed.packed_files.size() > 1 ? ", ..." : "", packed.glb.size());
      p.bytes = std::move(packed.glb);
      p.name = std::filesystem::path(path).stem().string() + ".glb";
      if (p.name.size() > kMaxNameBytes) p.name = p.name.substr(p.name.size() - kMaxNameBytes);
    }
    // KHR_materials_variants: the samplers receive the file with the variant's materials in
    // place (and its hash is the variant's, so a cached scene of another variant is not used).
    if (!variant.empty()) {
      p.bytes = select_material_variant(p.bytes, path, variant);
      spdlog::info("{}: material variant \"{}\" chosen", path, variant);
    }
    if (!camera.empty()) p.bytes = select_camera(p.bytes, path, camera);
    if (ray_depth) {
      p.bytes = set_ray_depth(p.bytes, path, *ray_depth);
      spdlog::info("{}: ray depth {} (secondary rays in a row)", path, *ray_depth);
    }
  }
  if (p.bytes.size() > kMaxSceneBytes) {
    throw Error(
        fmt::format("{}: {} bytes is over the protocol's limit of 4 GiB", path, p.bytes.size()));
  }
  p.hash = scene_hash(p.bytes);
  return p;
}

// ---------------------------------------------------------------------------------------------
// The control thread: membership, the wall, scene transfer, regions, heartbeats and views.
// run() loops over passes; each pass reads every queued message, then does the timed work,
// one member per concern, in the order below.
class DisplayService::Control {
 public:
  Control(DisplayService& service, const Security& sec)
      : service_(service),
        options_(service.options_),
        server_(service.context_, service.endpoints_.control, sec),
        views_(service.context_, service.endpoints_.views, sec),
        coordinator_(options_.image.width, options_.image.height, options_.coordinator) {}

  void run();

 private:
  // Messages.
  void receive_pending(double wait);
  void on_message(const ControlServer::Incoming& in, double t);
  bool on_wall_message(const ControlServer::Incoming& in, const Message& msg, double t);
  std::string admit_display(const ControlServer::Incoming& in, const DisplayJoin& j, double t);
  void on_join(const ControlServer::Incoming& in, const Join& j, double t);
  void on_member_message(Member& m, const std::string& peer, const Message& msg, double t);
  // Timed work of a pass.
  void send_scene_chunks();
  void expire_silent(double t);
  void publish_layout();
  void update_error(double t);
  void send_regions();
  void send_heartbeats(double t);
  void publish_view(double t);
  void say_goodbye();
  void measure(double t);
  void send_snapshot_requests();
  void publish_members();
  // Helpers.
  bool send(const std::string& peer, const Message& m);
  void welcome(const std::string& peer, uint32_t id, uint64_t token);
  uint64_t new_token();
  void send_layout(const std::string& peer);
  MassDensity error_density();

  DisplayService& service_;
  const DisplayServiceOptions& options_;
  ControlServer server_;
  ViewPublisher views_;
  Coordinator coordinator_;
  struct Transfer {
    uint32_t next_chunk = 0;
  };
  std::map<std::string, Transfer> transfers_;   // by peer
  std::map<std::string, double> told_unknown_;  // peers told to join again, when
  LogLimiter log_;  // what peers can repeat at will: a line per cause a second
  // Samplers' joins, leaves, losses and regions: a line each, up to 32 a second (a peer that
  // joins and leaves in a loop must not flood the log), the rest summed up once a second.
  LogBudget membership_log_;
  // The members' ids, tokens and keys go to the wall's followers on every change, so that they
  // drop batches that are not from the member they name (member_list).
  bool members_changed_ = false;
  uint64_t members_epoch_ = 0;
  // The wall's follower displays, by peer (docs/wall.md); the lead is node 1.
  struct WallMember {
    uint32_t id = 0;
    uint64_t token = 0;
    std::string name;
    int column = 0, row = 0;
    std::string endpoint;
    FailureDetector liveness;
  };
  std::map<std::string, WallMember> wall_nodes_;
  uint32_t next_node_id_ = 2;
  bool wall_changed_ = false;
  uint64_t view_sequence_ = 0;
  uint64_t heartbeat_sequence_ = 0;
  double last_heartbeat_ = 0.0, last_expire_ = 0.0, last_error_ = 0.0, next_view_ = 0.0;
  std::optional<MassDensity> error_;  // smoothed
  double last_measured_metrics_ = 0.0;
  std::random_device random_;  // members' tokens
};

namespace {

// Every cell of a wall's grid, row by row, and the node of `layout` that shows it (0: none, as
// for a node that was lost), for the lead's /stats and dashboard.
std::vector<DisplayMetrics::WallCell> grid_cells(const WallGrid& grid, const WallLayout& layout) {
  std::vector<DisplayMetrics::WallCell> cells;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.columns; ++c) {
      DisplayMetrics::WallCell cell;
      cell.cell = grid.cell(c, r, layout.image.width, layout.image.height);
      for (const WallNode& n : layout.nodes) {
        if (n.cell == cell.cell) cell.node = n.node_id;
      }
      cells.push_back(cell);
    }
  }
  return cells;
}

// Control messages handled in one pass of the control loop before its timed work (expiry,
// recuts, heartbeats, views): enough to drain what a few hundred peers send in a pass.
constexpr int kMaxMessagesPerPass = 1024;

// A routing id (binary) for logs.
std::string to_hex_peer(const std::string& peer) {
  std::string out;
  for (unsigned char ch : peer) out += fmt::format("{:02x}", ch);
  return out;
}

Security server_security(const DisplayServiceOptions& o) {
  return o.keys.secret_key.empty() ? Security::none() : Security::server(o.keys);
}

}  // namespace

// The view camera at display time t: a replayed path (looping), or the scene's animation
// (looping over its keyframe range, as the samplers' tracers do).
std::function<Camera(double)> view_camera_function(const Scene& scene, const CameraPath* path) {
  if (path) {
    return [path](double t) {
      const double span = path->end_time() - path->start_time();
      const double u = span > 0.0 ? path->start_time() + std::fmod(t, span) : path->start_time();
      return path->camera(u);
    };
  }
  return [&scene](double t) {
    const double d = scene.duration();
    return scene.camera_at(scene.evaluate(d > 0.0 ? std::fmod(t, d) : t));
  };
}

// CurveZMQ from --keys DIR (display.key and samplers.allow in it) or --key and --allow. Without
// keys loopback may go plain; any other address needs --insecure.
void configure_security(const std::string& keys_dir, std::string key_file, std::string allow_file,
                        bool insecure, DisplayServiceOptions* o) {
  namespace fs = std::filesystem;
  if (!keys_dir.empty()) {
    if (key_file.empty()) key_file = (fs::path(keys_dir) / "display.key").string();
    if (allow_file.empty()) allow_file = (fs::path(keys_dir) / "samplers.allow").string();
  }
  if (key_file.empty() != allow_file.empty()) {
    throw Error(
        "CurveZMQ needs both the display's key pair (--key) and the samplers' "
        "allow-list (--allow), or --keys DIR with both");
  }
  if (!key_file.empty()) {
    o->keys = load_curve_keypair(key_file);
    o->allowed_keys = load_allowed_keys(allow_file);
    spdlog::info("CurveZMQ on: display key {}, {} sampler key(s) allowed from {}",
                 o->keys.public_key, o->allowed_keys.size(), allow_file);
    return;
  }
  if (is_local_endpoint(service_endpoints(o->bind).control)) return;
  if (!insecure) {
    throw Error(fmt::format(
        "--bind {} is reachable from other machines: give CurveZMQ keys (--keys DIR, made by "
        "`display_node keygen DIR --samplers N`) or pass --insecure",
        o->bind));
  }
  spdlog::warn("--insecure: {} accepts any sampler, unencrypted", o->bind);
}

DisplayService::DisplayService(DisplayServiceOptions options, SampleSink& sink)
    : options_(std::move(options)), sink_(sink), start_(std::chrono::steady_clock::now()) {
  if (!options_.camera_at) throw Error("display service: no camera function");
  std::random_device rd;
  while (session_ == 0) session_ = (uint64_t(rd()) << 32) ^ rd();
  endpoints_ = service_endpoints(options_.bind);
  if (!options_.keys.secret_key.empty()) {
    context_.allow_curve_clients(options_.allowed_keys, [this](const ZapDecision& d) {
      if (d.accepted) {
        spdlog::info("CurveZMQ: admitted key {} from {}", d.public_key, d.address);
      } else if (const uint64_t n = zap_log_.due(d.mechanism)) {
        spdlog::warn(
            "CurveZMQ: REFUSED {} key {} from {}: not on the allow-list ({} refusal(s) since the "
            "last line)",
            d.mechanism, d.public_key.empty() ? "(none)" : d.public_key, d.address, n);
      }
    });
  }
  const Security sec = server_security(options_);
  try {
    control_ = std::make_unique<Control>(*this, sec);
    samples_ = std::make_unique<SampleReceiver>(context_, endpoints_.samples, sec);
  } catch (const Error& e) {
    throw Error(fmt::format("--bind {} (three ports from {}): {}", options_.bind,
                            endpoints_.control, e.what()));
  }
  samples_->set_image_bounds(options_.image);
  if (options_.metrics_port > 0) {
    http_ =
        std::make_unique<MetricsServer>(metrics_, options_.metrics_address, options_.metrics_port);
    http_->on_snapshot([this](double delay) {
      const SnapshotTicket ticket = request_snapshot(delay);
      nlohmann::json j = {{"id", ticket.id}, {"time", ticket.time}};
      j["cells"] = nlohmann::json::array();
      for (const WallNode& n : ticket.layout.nodes) {
        j["cells"].push_back(
            {{"node", n.node_id}, {"cell", {n.cell.x0, n.cell.y0, n.cell.x1, n.cell.y1}}});
      }
      j["image"] = {ticket.layout.image.width, ticket.layout.image.height};
      return j.dump();
    });
  }
  check_wall_grid(options_.wall, options_.image.width, options_.image.height);
  check_wall_cell(options_.wall, options_.wall_column, options_.wall_row);
  layout_.image = options_.image;
  layout_.margin = options_.wall.margin;
  layout_.nodes = {WallNode{1, cell(), ""}};
  metrics_.set_wall(1, cell(), 1, 0);
  metrics_.set_wall_cells(grid_cells(options_.wall, layout_));
}

PixelRect DisplayService::cell() const {
  return options_.wall.cell(options_.wall_column, options_.wall_row, options_.image.width,
                            options_.image.height);
}

DisplayService::SnapshotTicket DisplayService::request_snapshot(double delay) {
  if (!std::isfinite(delay) || delay < 0.0 || delay > 10.0) {
    throw Error(fmt::format("snapshot delay {} s is outside 0..10", delay));
  }
  SnapshotTicket ticket;
  ticket.layout = wall_layout();
  std::lock_guard<std::mutex> lock(snapshot_mutex_);
  const double t = now();
  if (t - last_snapshot_request_ < 0.2) {
    throw Error("a snapshot was asked less than 0.2 s ago: ask again shortly");
  }
  last_snapshot_request_ = t;
  ticket.id = next_snapshot_id_++;
  ticket.time = t + delay;
  if (!snapshots_.request({ticket.id, ticket.time})) {
    throw Error(fmt::format("{} snapshots are pending already", SnapshotQueue::kMaxPending));
  }
  snapshot_outbox_.push_back(protocol::SnapshotRequest{ticket.id, ticket.time});
  spdlog::info("snapshot {}: every cell's image of t={:.3f}s ({} node(s))", ticket.id, ticket.time,
               ticket.layout.nodes.size());
  return ticket;
}

WallLayout DisplayService::wall_layout() const {
  std::lock_guard<std::mutex> lock(regions_mutex_);
  return layout_;
}

DisplayService::~DisplayService() { stop(); }

double DisplayService::now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

std::vector<std::pair<uint32_t, PixelRect>> DisplayService::regions() const {
  std::lock_guard<std::mutex> lock(regions_mutex_);
  return regions_;
}

void DisplayService::start() {
  if (running_.exchange(true)) return;
  spdlog::info("display session {:x}: control {}, views {}, samples {}{}", session_,
               endpoints_.control, endpoints_.views, endpoints_.samples,
               options_.keys.secret_key.empty() ? ""
                                                : fmt::format(", CurveZMQ with {} allowed key(s)",
                                                              options_.allowed_keys.size()));
  control_thread_ = std::thread([this] { control_loop(); });
  ingest_thread_ = std::thread([this] { ingest_loop(); });
  if (http_) http_->start();
}

void DisplayService::stop() {
  if (!running_.exchange(false)) return;
  if (control_thread_.joinable()) control_thread_.join();
  if (ingest_thread_.joinable()) ingest_thread_.join();
  if (http_) http_->stop();
}

// ---------------------------------------------------------------------------------------------
// Ingest: the sample channel into the sink

namespace {

// A CurveZMQ key for a log line: enough of it to tell keys apart.
std::string short_key(std::string_view key) {
  return key.empty() ? std::string("none") : std::string(key.substr(0, 8)) + "...";
}

// A member's snapshot cut to the region the coordinator gave it: a member describes its own
// pixels only, whatever region its message claims (one that names the whole image would
// otherwise shape the filter and weigh in the recuts over the others' regions). A snapshot of
// the region before a recut keeps the part still its own; one from a member that has no region
// yet (its join waits for its cut) keeps nothing. A wall's followers cut by the regions of the
// lead's member list.
void keep_to_region(const PixelRect& mine, TilingSnapshot* t) {
  t->region = intersect(t->region, mine);
  std::erase_if(t->tiles, [&](TileInfo& tile) {
    tile.rect = intersect(tile.rect, t->region);
    return tile.rect.empty();
  });
}

}  // namespace

void run_ingest(SampleReceiver& receiver, SampleSink& sink, ServiceMetrics& metrics,
                MemberGate* gate, const std::atomic<bool>& running,
                const std::function<void(const TilingSnapshot&)>& on_tiling,
                const WallPeers* wall) {
  uint64_t rejected = 0;
  LogLimiter log;
  // The members whose tilings the sink holds, checked against the gate every 0.1 s: the sink
  // forgets the tiling of one that is no longer a member, so that what it keeps is bounded by
  // the members, not by every sampler that ever joined.
  std::set<uint32_t> tiled;
  auto next_check = std::chrono::steady_clock::now();
  // On a wall's node: whether a stray or a coverage message comes from a node of the wall; logs
  // (rate-limited) when not.
  const auto from_wall_node = [&](const char* what, uint32_t id) {
    if (wall->key.empty() || receiver.peer_key() == wall->key) return true;
    if (const uint64_t n = log.due("wall message from no node")) {
      spdlog::warn(
          "sample channel: dropped {} wall message(s) from a key that is not the wall's (the last "
          "a {} naming node {}, key {}): not stored",
          n, what, id, short_key(receiver.peer_key()));
    }
    return false;
  };
  // Whether a batch or snapshot comes from the member it names; logs (rate-limited) when not.
  const auto from_member = [&](const char* what, uint32_t id, uint64_t token, uint64_t samples) {
    const MemberGate::Verdict v =
        gate ? gate->check(id, token, receiver.peer_key(), samples) : MemberGate::Verdict::kMember;
    if (v == MemberGate::Verdict::kNonMember) {
      if (const uint64_t n = log.due("non-member")) {
        spdlog::warn(
            "sample channel: dropped {} message(s) from no member (the last a {} naming sampler "
            "{}, key {}): not stored",
            n, what, id, short_key(receiver.peer_key()));
      }
    } else if (v == MemberGate::Verdict::kSpoofed) {
      if (const uint64_t n = log.due("spoofed")) {
        spdlog::warn(
            "sample channel: dropped {} message(s) naming a member without its token or key (the "
            "last a {} naming sampler {}, key {}): not stored",
            n, what, id, short_key(receiver.peer_key()));
      }
    }
    return v;
  };
  while (running.load(std::memory_order_relaxed)) {
    log.flush([](const std::string& cause, uint64_t n) {
      spdlog::warn("sample channel: {} more like this since its last line: {}", n, cause);
    });
    if (gate != nullptr && std::chrono::steady_clock::now() >= next_check) {
      next_check = std::chrono::steady_clock::now() + std::chrono::milliseconds(100);
      for (auto it = tiled.begin(); it != tiled.end();) {
        if (gate->has(*it)) {
          ++it;
        } else {
          sink.on_sampler_gone(*it);
          it = tiled.erase(it);
        }
      }
    }
    switch (receiver.receive(50)) {
      case SampleReceiver::Got::kNothing:
        break;
      case SampleReceiver::Got::kBatch: {
        const SampleBatch& b = receiver.batch();
        const size_t bytes = batch_message_bytes(b.fields, b.samples.size());
        if (b.sampler_id == kWallPeerSamplerId && wall != nullptr) {
          if (from_wall_node("stray batch", b.sampler_id)) {
            metrics.on_wall_strays_in(b.samples.size(), bytes);
            sink.on_batch(std::move(receiver.batch()));
          } else {
            metrics.on_spoofed_batch(b.samples.size());
          }
          break;
        }
        const MemberGate::Verdict v = from_member("batch", b.sampler_id, b.token, b.samples.size());
        if (v == MemberGate::Verdict::kSpoofed) {
          metrics.on_spoofed_batch(b.samples.size());
          break;
        }
        metrics.on_batch(b, bytes, v == MemberGate::Verdict::kMember);
        if (v == MemberGate::Verdict::kMember) sink.on_batch(std::move(receiver.batch()));
        break;
      }
      case SampleReceiver::Got::kCoverage: {
        WallCoverage& c = receiver.coverage();
        if (wall == nullptr) {
          metrics.on_rejected_sample_message();
          if (const uint64_t n = log.due("coverage outside a wall")) {
            spdlog::warn(
                "sample channel: rejected {} wall_coverage message(s), the last from node {}: "
                "this display is not part of a wall",
                n, c.node_id);
          }
          break;
        }
        if (!from_wall_node("wall_coverage", c.node_id)) {
          metrics.on_rejected_sample_message();
          break;
        }
        metrics.on_wall_coverage_in(uint64_t(c.rect.area()),
                                    wall_coverage_message_bytes(c.cells.size() / 2));
        wall->coverage->put(std::move(c));
        break;
      }
      case SampleReceiver::Got::kTiling: {
        TilingSnapshot& t = receiver.tiling();
        const MemberGate::Verdict v = from_member("tiling snapshot", t.sampler_id, t.token, 0);
        if (v == MemberGate::Verdict::kSpoofed) {
          metrics.on_spoofed_tiling();
          break;
        }
        metrics.on_tiling(t.sampler_id, snapshot_message_bytes(t.tiles.size()),
                          v == MemberGate::Verdict::kMember);
        if (v != MemberGate::Verdict::kMember) break;
        if (gate != nullptr) {
          if (const std::optional<PixelRect> mine = gate->region(t.sampler_id)) {
            keep_to_region(*mine, &t);
          }
          tiled.insert(t.sampler_id);
          int64_t pixels = 0;
          for (const TileInfo& tile : t.tiles) pixels += tile.rect.area();
          metrics.set_tiled_pixels(t.sampler_id, pixels);
        }
        if (on_tiling) on_tiling(t);
        sink.on_tiling(std::move(receiver.tiling()));
        break;
      }
      case SampleReceiver::Got::kRejected:
        metrics.on_rejected_sample_message();
        ++rejected;
        if (const uint64_t n = log.due(LogLimiter::cause_of(receiver.rejection().message()))) {
          spdlog::warn("sample channel: rejected {} message(s) like this one ({} in all): {}", n,
                       rejected, receiver.rejection().message());
        }
        break;
    }
  }
}

void DisplayService::ingest_loop() {
  // Only a wall's lead takes coverage and strays from peers; a single display refuses them.
  const WallPeers wall{&wall_coverage_, options_.keys.public_key};
  run_ingest(
      *samples_, sink_, metrics_, &gate_, running_,
      [this](const TilingSnapshot& t) {
        // The tile's luminance variance over its pixels: comparable between samplers (their
        // E_tile is normalised by each sampler's own sums, section 6.1), capped at what the
        // display can show (shown_error_mass).
        std::vector<std::pair<PixelRect, double>> tiles;
        tiles.reserve(t.tiles.size());
        for (const TileInfo& tile : t.tiles) {
          tiles.emplace_back(tile.rect, shown_error_mass(tile.v, tile.rect));
        }
        std::lock_guard<std::mutex> lock(errors_mutex_);
        tile_errors_[t.sampler_id] = std::move(tiles);
      },
      options_.wall.is_wall() ? &wall : nullptr);
}

// ---------------------------------------------------------------------------------------------
// Control: membership, regions, scene, heartbeats, views

void DisplayService::control_loop() { control_->run(); }

void DisplayService::Control::run() {
  next_view_ = service_.now();
  while (service_.running_.load(std::memory_order_relaxed)) {
    receive_pending(std::max(0.0, std::min(next_view_ - service_.now(), 0.005)));
    const double t = service_.now();
    send_scene_chunks();
    expire_silent(t);
    membership_log_.flush([](uint64_t n) {
      spdlog::warn(
          "{} more sampler joins, leaves and regions than the log shows since its last such "
          "line (/stats counts joins, leaves and deaths)",
          n);
    });
    if (wall_changed_) {
      wall_changed_ = false;
      publish_layout();
      members_changed_ = true;  // a new node needs the members too
    }
    if (members_changed_) {
      members_changed_ = false;
      publish_members();
    }
    measure(t);
    update_error(t);
    if (coordinator_.maybe_recut(t)) send_regions();
    send_heartbeats(t);
    publish_view(t);
    log_.flush([](const std::string& cause, uint64_t n) {
      spdlog::warn("control: {} more like this since its last line: {}", n, cause);
    });
    send_snapshot_requests();
  }
  say_goodbye();
}

// ---------------------------------------------------------------------------------------------
// Messages

// Every message already queued is read before anyone is declared dead: when this thread
// itself was held up (a loaded machine), the heartbeats that arrived meanwhile count.
void DisplayService::Control::receive_pending(double wait) {
  for (int k = 0; k < kMaxMessagesPerPass; ++k) {
    std::optional<ControlServer::Incoming> in = server_.receive(k == 0 ? int(wait * 1000.0) : 0);
    if (!in) break;
    on_message(*in, service_.now());
  }
}

void DisplayService::Control::on_message(const ControlServer::Incoming& in, double t) {
  if (!in.message.ok()) {
    service_.metrics_.on_rejected_control();
    if (const uint64_t n = log_.due(LogLimiter::cause_of(in.message.error()))) {
      spdlog::warn("control: rejected {} message(s) like this one from peer {} key {}: {}", n,
                   to_hex_peer(in.peer), short_key(in.public_key), in.message.error());
    }
    if (in.message.error().find("version") != std::string::npos) {
      send(in.peer,
           Leave{0, LeaveReason::kVersionMismatch,
                 fmt::format("this display speaks protocol version {}", kProtocolVersion)});
    }
    return;
  }
  const Message& msg = in.message.value();
  if (on_wall_message(in, msg, t)) return;  // a follower display of the wall
  if (const auto* j = std::get_if<Join>(&msg)) {
    on_join(in, *j, t);
  } else if (Member* m = coordinator_.find_peer(in.peer)) {
    on_member_message(*m, in.peer, msg, t);
  } else if (!std::holds_alternative<Leave>(msg)) {
    // Not a member: a sampler of a previous session (this display restarted) or one declared
    // dead. Tell it to join (at most twice a second per peer).
    double& told = told_unknown_[in.peer];
    if (t - told > 0.5) {
      told = t;
      send(in.peer, Leave{0, LeaveReason::kTimeout, "not a member of this session: join"});
    }
  }
}

// Messages of a wall follower (or a follower's join). Returns whether it was one.
bool DisplayService::Control::on_wall_message(const ControlServer::Incoming& in, const Message& msg,
                                              double t) {
  const std::string& peer = in.peer;
  if (const auto* j = std::get_if<DisplayJoin>(&msg)) {
    if (std::string refusal = admit_display(in, *j, t); !refusal.empty()) {
      if (const uint64_t n = log_.due(LogLimiter::cause_of(refusal))) {
        spdlog::warn("display {} refused ({} like this): {}", j->name, n, refusal);
      }
      send(peer, Leave{0, LeaveReason::kRefused, refusal});
    }
    return true;
  }
  auto it = wall_nodes_.find(peer);
  if (it == wall_nodes_.end()) return false;
  it->second.liveness.heard(t);
  if (const auto* l = std::get_if<Leave>(&msg)) {
    spdlog::info("display node {} ({}) left the wall: {}", it->second.id, it->second.name, l->text);
    wall_nodes_.erase(it);
    wall_changed_ = true;
  }
  return true;
}

// A follower display asks for a cell. Returns the refusal, or "" when admitted.
std::string DisplayService::Control::admit_display(const ControlServer::Incoming& in,
                                                   const DisplayJoin& j, double t) {
  const std::string& peer = in.peer;
  const WallGrid& wall = options_.wall;
  if (!wall.is_wall()) return "this display is not a wall: start it with --wall COLUMNSxROWS";
  // With CurveZMQ a wall's nodes hold the display's key pair (docs/wall.md): a node is what
  // connects with it. Any other allowed key is a sampler's, and a sampler that took a cell
  // would get the members' list and keep the cell from its node.
  if (!options_.keys.public_key.empty() && in.public_key != options_.keys.public_key) {
    return fmt::format(
        "key {} is not the display's: a wall's display nodes join with the display's key pair",
        in.public_key);
  }
  if (j.column >= wall.columns || j.row >= wall.rows) {
    return fmt::format("cell {},{} is outside the {}x{} wall", j.column, j.row, wall.columns,
                       wall.rows);
  }
  if (j.column == options_.wall_column && j.row == options_.wall_row) {
    return fmt::format("cell {},{} is the lead display's own", j.column, j.row);
  }
  for (const auto& [other, n] : wall_nodes_) {
    if (other != peer && n.column == j.column && n.row == j.row) {
      return fmt::format("cell {},{} is shown by node {} ({})", j.column, j.row, n.id, n.name);
    }
  }
  auto it = wall_nodes_.find(peer);
  if (it == wall_nodes_.end()) {
    // The lead assigns node ids as it does sampler ids: the proposed one is not followed
    // (asking for 0xFFFFFFFF once made every later node the same id), the counter wraps past
    // the top to 2 (the lead is 1) and skips every live id.
    uint32_t id = 0;
    for (bool taken = true; taken;) {
      id = next_node_id_;
      next_node_id_ = next_node_id_ == std::numeric_limits<uint32_t>::max() ? 2 : next_node_id_ + 1;
      taken = std::any_of(wall_nodes_.begin(), wall_nodes_.end(),
                          [&](const auto& e) { return e.second.id == id; });
    }
    FailureDetector liveness(options_.coordinator.heartbeat_interval,
                             options_.coordinator.liveness);
    liveness.reset(t);
    it = wall_nodes_
             .emplace(peer, WallMember{id, new_token(), j.name, j.column, j.row, j.samples_endpoint,
                                       liveness})
             .first;
    spdlog::info("display node {} joined the wall: {} shows cell {},{}, samples at {}", id, j.name,
                 j.column, j.row, j.samples_endpoint);
    wall_changed_ = true;
  } else if (it->second.column != j.column || it->second.row != j.row ||
             it->second.endpoint != j.samples_endpoint) {
    it->second.column = j.column;
    it->second.row = j.row;
    it->second.endpoint = j.samples_endpoint;
    wall_changed_ = true;
  }
  it->second.liveness.heard(t);
  welcome(peer, it->second.id, it->second.token);
  if (!wall_changed_) send_layout(peer);  // a repeated join; a change is sent to everyone
  return "";
}

// A join: the display assigns the id (the one the join proposes is not asked for) and the token
// that binds the member's sample batches to it (docs/service.md, "Identity").
void DisplayService::Control::on_join(const ControlServer::Incoming& in, const Join& j, double t) {
  if (!coordinator_.find_peer(in.peer) &&
      coordinator_.members().size() >= options_.coordinator.max_members) {
    const std::string refusal =
        fmt::format("the display admits at most {} samplers (--max-samplers)",
                    options_.coordinator.max_members);
    if (const uint64_t n = log_.due("join refused: full")) {
      spdlog::warn("sampler join(s) refused ({} like this, the last from {}): {}", n, j.name,
                   refusal);
    }
    send(in.peer, Leave{0, LeaveReason::kRefused, refusal});
    return;
  }
  bool is_new = false;
  const uint64_t token = coordinator_.find_peer(in.peer) ? 0 : new_token();
  Member& m = coordinator_.join(in.peer, j.name, in.public_key, j.threads, token, t, &is_new);
  if (is_new) {
    service_.gate_.admit(m.id, m.token, m.public_key);
    members_changed_ = true;
    if (membership_log_.take()) {
      spdlog::info("sampler {} joined: {} ({} thread(s) claimed{})", m.id, j.name, j.threads,
                   in.public_key.empty() ? "" : ", key " + in.public_key);
    }
    service_.metrics_.on_member(j.name, m.id, in.public_key, j.threads);
  }
  welcome(m.peer, m.id, m.token);
  send_layout(m.peer);
  if (!is_new && !m.region.empty()) {  // a repeated join: the region it may have missed
    send(m.peer, RegionAssignment{m.id, coordinator_.epoch(), options_.image.width,
                                  options_.image.height, m.region});
  }
}

void DisplayService::Control::on_member_message(Member& m, const std::string& peer,
                                                const Message& msg, double t) {
  coordinator_.heard(m.id, t);
  if (const auto* r = std::get_if<SceneRequest>(&msg)) {
    if (r->scene_hash != options_.scene.hash) {
      if (const uint64_t n = log_.due("scene request: another scene")) {
        spdlog::warn(
            "sampler {} asked for scene {}, not this session's ({} such request(s)): "
            "ignored",
            m.id, to_hex(r->scene_hash).substr(0, 16), n);
      }
    } else {
      transfers_[peer].next_chunk = r->first_chunk;
    }
  } else if (const auto* s = std::get_if<SamplerStats>(&msg)) {
    // Shown in /stats and /metrics; the share follows what the display measures instead.
    service_.metrics_.on_reported(m.id, *s);
  } else if (const auto* l = std::get_if<Leave>(&msg)) {
    if (membership_log_.take()) {
      if (l->reason == LeaveReason::kError) {
        // The sampler cannot serve this session (its scene did not load, say): it said why.
        spdlog::error("sampler {} ({}) failed and left: {}", m.id, m.name, l->text);
      } else {
        spdlog::info("sampler {} ({}) left: {}", m.id, m.name, l->text);
      }
    }
    service_.metrics_.on_member_gone(m.id, false);
    service_.gate_.revoke(m.id);
    members_changed_ = true;
    transfers_.erase(m.peer);
    coordinator_.remove(m.id);  // m is gone from here on
  }
}

// ---------------------------------------------------------------------------------------------
// Timed work of a pass

// Scene transfers: a few chunks per pass, resumed when the peer's queue has room.
void DisplayService::Control::send_scene_chunks() {
  const ScenePayload& scene = options_.scene;
  const uint64_t size = scene.bytes.size();
  const uint32_t count = uint32_t((size + options_.chunk_bytes - 1) / options_.chunk_bytes);
  for (auto it = transfers_.begin(); it != transfers_.end();) {
    uint64_t sent = 0;
    bool stalled = false;
    for (int k = 0; k < 4 && it->second.next_chunk < count; ++k) {
      SceneChunk ch;
      ch.scene_hash = scene.hash;
      ch.scene_size = size;
      ch.index = it->second.next_chunk;
      ch.count = count;
      ch.offset = uint64_t(ch.index) * options_.chunk_bytes;
      const uint64_t n = std::min<uint64_t>(options_.chunk_bytes, size - ch.offset);
      ch.bytes.assign(scene.bytes.begin() + ch.offset, scene.bytes.begin() + ch.offset + n);
      if (!send(it->first, ch)) {
        stalled = true;
        break;
      }
      ++it->second.next_chunk;
      ++sent;
    }
    service_.metrics_.on_chunks_sent(sent);
    if (const Member* m = coordinator_.find_peer(it->first)) {
      service_.metrics_.on_scene_progress(m->id, it->second.next_chunk, count);
    }
    if (!stalled && it->second.next_chunk >= count) {
      it = transfers_.erase(it);
    } else {
      ++it;
    }
  }
}

// Members and wall nodes the failure detector suspects are dropped and told so.
void DisplayService::Control::expire_silent(double t) {
  if (t - last_expire_ < 0.02) return;
  last_expire_ = t;
  // Peers told to join again are remembered for the rate limit only: a bounded while.
  std::erase_if(told_unknown_, [&](const auto& e) { return t - e.second > 10.0; });
  for (const Member& dead : coordinator_.expire(t)) {
    if (membership_log_.take()) {
      spdlog::warn(
          "sampler {} ({}) lost: no word for {:.2f} s (suspected after {:.2f} s: its messages "
          "came every {:.3f} s, deviation {:.3f} s); its region goes to the others",
          dead.id, dead.name, dead.liveness.silence(t), dead.liveness.suspect_after(),
          dead.liveness.mean(), dead.liveness.deviation());
    }
    service_.metrics_.on_member_gone(dead.id, true);
    service_.gate_.revoke(dead.id);
    members_changed_ = true;
    transfers_.erase(dead.peer);
    send(dead.peer, Leave{dead.id, LeaveReason::kTimeout, "no heartbeat: join again"});
  }
  for (auto it = wall_nodes_.begin(); it != wall_nodes_.end();) {
    const FailureDetector& d = it->second.liveness;
    if (!d.suspect(t)) {
      ++it;
      continue;
    }
    spdlog::warn(
        "display node {} ({}) lost: no word for {:.2f} s (suspected after {:.2f} s: its "
        "messages came every {:.3f} s, deviation {:.3f} s); its cell goes dark",
        it->second.id, it->second.name, d.silence(t), d.suspect_after(), d.mean(), d.deviation());
    send(it->first, Leave{it->second.id, LeaveReason::kTimeout, "no heartbeat: join again"});
    it = wall_nodes_.erase(it);
    wall_changed_ = true;
  }
}

// The members and their regions, for the followers' gates (docs/wall.md, "Identity on a wall").
void DisplayService::Control::publish_members() {
  if (wall_nodes_.empty()) return;
  MemberList list;
  list.epoch = ++members_epoch_;
  for (const auto& [id, m] : coordinator_.members()) {
    list.members.push_back(MemberEntry{id, m.token, m.public_key, m.region});
  }
  for (const auto& [peer, node] : wall_nodes_) send(peer, list);
}

// Snapshots of one moment: each request goes to every follower of the wall.
void DisplayService::Control::send_snapshot_requests() {
  std::vector<SnapshotRequest> requests;
  {
    std::lock_guard<std::mutex> lock(service_.snapshot_mutex_);
    requests.swap(service_.snapshot_outbox_);
  }
  for (const SnapshotRequest& r : requests) {
    for (const auto& [peer, node] : wall_nodes_) send(peer, r);
  }
}

// The wall: the layout every sampler routes by, sent to everyone on every change.
void DisplayService::Control::publish_layout() {
  WallLayout l;
  l.image = options_.image;
  l.margin = options_.wall.margin;
  l.nodes.push_back(WallNode{1, service_.cell(), ""});
  for (const auto& [peer, n] : wall_nodes_) {
    l.nodes.push_back(WallNode{
        n.id, options_.wall.cell(n.column, n.row, options_.image.width, options_.image.height),
        n.endpoint});
  }
  {
    std::lock_guard<std::mutex> lock(service_.regions_mutex_);
    l.epoch = service_.layout_.epoch + 1;
    service_.layout_ = l;
  }
  service_.metrics_.set_wall(1, service_.cell(), l.nodes.size(), l.epoch);
  service_.metrics_.set_wall_cells(grid_cells(options_.wall, l));
  spdlog::info("wall layout {}: {} display node(s)", l.epoch, l.nodes.size());
  for (const auto& [id, m] : coordinator_.members()) send(m.peer, l);
  for (const auto& [peer, n] : wall_nodes_) send(peer, l);
}

// The error as the tilings say it, once every member has settled in its region (its tiles then
// describe its region, not the one before or its pool's first fill).
void DisplayService::Control::update_error(double t) {
  const CoordinatorOptions& o = options_.coordinator;
  const bool settled =
      std::all_of(coordinator_.members().begin(), coordinator_.members().end(),
                  [&](const auto& e) { return t - e.second.region_since >= o.settle_seconds; });
  if (!settled || t - last_error_ < o.recut_interval) return;
  last_error_ = t;
  // Smoothed over about three readings: one snapshot's variances are noisy, and a cut that
  // follows the noise restarts the samplers for nothing.
  if (error_) {
    error_->blend(error_density(), 0.3);
  } else {
    error_ = error_density();
  }
  coordinator_.set_error(*error_);
}

// The samples the ingest accepted from each member, into the coordinator's rates; who starved
// or came back is logged, and the rates go to the metrics a few times a second.
void DisplayService::Control::measure(double t) {
  for (const auto& [id, n] : service_.gate_.take_accepted()) coordinator_.add_samples(id, n, t);
  const std::vector<std::pair<uint32_t, bool>> changes = coordinator_.measure(t);
  for (const auto& [id, starved] : changes) {
    const Member* m = coordinator_.find(id);
    if (!m) continue;
    if (starved) {
      spdlog::warn(
          "sampler {} ({}) starved: no samples from it for {:.2f} s (its patience {:.2f} s) while "
          "others delivered; its region goes to them until it delivers",
          id, m->name, t - m->last_sample_at, coordinator_.patience(*m));
    } else {
      spdlog::info("sampler {} ({}) delivers samples again", id, m->name);
    }
  }
  if (changes.empty() && t - last_measured_metrics_ < 0.25) return;
  last_measured_metrics_ = t;
  for (const auto& [id, m] : coordinator_.members()) {
    service_.metrics_.set_measured(id, coordinator_.measured(m) ? m.rate : 0.0, m.starved);
  }
}

void DisplayService::Control::send_regions() {
  std::vector<std::pair<uint32_t, PixelRect>> regions;
  if (const auto [before, after] = coordinator_.drift_loads(); before > 0.0) {
    spdlog::info(
        "regions recut for drift: the most loaded sampler's part of the error over its "
        "share of the throughput {:.2f} before, {:.2f} after",
        before, after);
  }
  for (const auto& [id, m] : coordinator_.members()) {
    // The gate first: the member's snapshots of its new region must not meet the old one.
    service_.gate_.set_region(id, m.region);
    if (m.region.empty()) continue;  // a join still waiting for its cut
    send(m.peer, RegionAssignment{id, coordinator_.epoch(), options_.image.width,
                                  options_.image.height, m.region});
    service_.metrics_.on_region(id, m.region, coordinator_.epoch(), coordinator_.recuts());
    regions.emplace_back(id, m.region);
    if (!membership_log_.take()) continue;
    spdlog::info(
        "region epoch {}: sampler {} ({}) gets [{}, {}) x [{}, {}) ({:.0f}%)", coordinator_.epoch(),
        id, m.name, m.region.x0, m.region.x1, m.region.y0, m.region.y1,
        100.0 * double(m.region.area()) / (double(options_.image.width) * options_.image.height));
  }
  {
    std::lock_guard<std::mutex> lock(service_.regions_mutex_);
    service_.regions_ = std::move(regions);
  }
  publish_members();  // the followers cut the members' snapshots by the new regions
}

void DisplayService::Control::send_heartbeats(double t) {
  if (t - last_heartbeat_ < kDisplayHeartbeatInterval) return;
  last_heartbeat_ = t;
  const uint64_t session = service_.session_;
  for (const auto& [id, m] : coordinator_.members()) {
    send(m.peer, Heartbeat{id, session, heartbeat_sequence_, t});
  }
  for (const auto& [peer, n] : wall_nodes_) {
    send(peer, Heartbeat{n.id, session, heartbeat_sequence_, t});
  }
  ++heartbeat_sequence_;
  if (const std::optional<ZapCounts> zap = service_.context_.zap()) {
    service_.metrics_.set_zap(zap->accepted, zap->refused);
  }
}

// A view at every refresh tick: the camera at display time t.
void DisplayService::Control::publish_view(double t) {
  if (t < next_view_) return;
  View v;
  v.sequence = view_sequence_++;
  v.time = t;
  v.camera = options_.camera_at(t);
  if (Status s = views_.publish(v); !s.ok()) spdlog::error("view {}: {}", v.sequence, s.message());
  service_.metrics_.on_view();
  next_view_ += options_.refresh_interval;
  if (next_view_ < t) next_view_ = t + options_.refresh_interval;
}

void DisplayService::Control::say_goodbye() {
  for (const auto& [id, m] : coordinator_.members()) {
    send(m.peer, Leave{id, LeaveReason::kShutdown, "display shutting down"});
  }
  for (const auto& [peer, n] : wall_nodes_) {
    send(peer, Leave{n.id, LeaveReason::kShutdown, "display shutting down"});
  }
}

// ---------------------------------------------------------------------------------------------
// Helpers

bool DisplayService::Control::send(const std::string& peer, const Message& m) {
  Status s = server_.send(peer, m);
  if (!s.ok()) {
    spdlog::debug("control: cannot send {}: {}", message_type_name(message_type(m)), s.message());
  }
  return s.ok();
}

// The answer to a sampler's join, and to a follower display's (id: its node id).
void DisplayService::Control::welcome(const std::string& peer, uint32_t id, uint64_t token) {
  Welcome w;
  w.sampler_id = id;
  w.session = service_.session_;
  w.token = token;
  w.image = options_.image;
  w.display_time = service_.now();
  w.refresh_interval = options_.refresh_interval;
  w.scene_hash = options_.scene.hash;
  w.scene_size = options_.scene.bytes.size();
  w.scene_name = options_.scene.name;
  w.presets = options_.preset;
  send(peer, w);
}

// A member's token: random (the system's entropy source), never 0.
uint64_t DisplayService::Control::new_token() {
  uint64_t token = 0;
  while (token == 0) token = (uint64_t(random_()) << 32) ^ uint64_t(random_());
  return token;
}

void DisplayService::Control::send_layout(const std::string& peer) {
  WallLayout l;
  {
    std::lock_guard<std::mutex> lock(service_.regions_mutex_);
    l = service_.layout_;
  }
  send(peer, l);
}

// The image's error from the members' latest tilings, on a grid of at most 64 x 64 cells, with
// a floor of 1% of the mean so that no part of the image weighs nothing.
MassDensity DisplayService::Control::error_density() {
  const int w = options_.image.width, h = options_.image.height;
  MassDensity d(w, h, std::min(64, w), std::min(64, h));
  std::lock_guard<std::mutex> lock(service_.errors_mutex_);
  auto& errors = service_.tile_errors_;
  for (auto it = errors.begin(); it != errors.end();) {
    if (!coordinator_.members().count(it->first)) {
      it = errors.erase(it);
      continue;
    }
    for (const auto& [rect, mass] : it->second) d.add(rect, mass);
    ++it;
  }
  d.add_uniform(0.01 * d.total() / (double(w) * double(h)));
  return d;
}

}  // namespace afr::service
