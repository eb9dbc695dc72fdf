#include <afr/display/service/wall_follower.h>

#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/display/service/display_service.h>
#include <afr/protocol/display_link.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <thread>

namespace afr::service {

using namespace afr::protocol;

namespace {

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

WallFollower::WallFollower(WallFollowerOptions options, SampleSink& sink)
    : options_(std::move(options)), sink_(sink) {
  (void)service_endpoints(options_.lead);  // throws for a malformed endpoint
  if (options_.column < 0 || options_.row < 0 || options_.column > 65535 || options_.row > 65535) {
    throw Error(fmt::format("--cell {},{}: out of range", options_.column, options_.row));
  }
  const bool curve = !options_.keys.secret_key.empty();
  if (curve) {
    context_.allow_curve_clients(options_.allowed_keys, [](const ZapDecision& d) {
      if (!d.accepted) {
        spdlog::warn("CurveZMQ: REFUSED {} key {} from {}: not on the allow-list", d.mechanism,
                     d.public_key.empty() ? "(none)" : d.public_key, d.address);
      }
    });
  }
  try {
    samples_ = std::make_unique<SampleReceiver>(
        context_, options_.bind, curve ? Security::server(options_.keys) : Security::none());
  } catch (const Error& e) {
    throw Error(fmt::format("the sample channel: {}", e.what()));
  }
  if (options_.advertise.empty()) options_.advertise = samples_->endpoint();
  if (options_.name.empty()) {
    options_.name = fmt::format("wall-{}-{}", options_.column, options_.row);
  }
  if (options_.metrics_port > 0) {
    http_ =
        std::make_unique<MetricsServer>(metrics_, options_.metrics_address, options_.metrics_port);
  }
}

WallFollower::~WallFollower() { stop(); }

void WallFollower::start() {
  if (running_.exchange(true)) return;
  spdlog::info("wall follower {}: cell {},{} of the lead {}, samples at {}", options_.name,
               options_.column, options_.row, options_.lead, options_.advertise);
  control_thread_ = std::thread([this] { control_loop(); });
  ingest_thread_ = std::thread([this] {
    const WallPeers wall{&wall_coverage_, options_.keys.public_key};
    run_ingest(*samples_, sink_, metrics_, &gate_, running_, {}, &wall);
  });
  if (http_) http_->start();
}

void WallFollower::stop() {
  if (!running_.exchange(false)) return;
  if (control_thread_.joinable()) control_thread_.join();
  if (ingest_thread_.joinable()) ingest_thread_.join();
  if (http_) http_->stop();
}

std::string WallFollower::lead_samples_endpoint() const {
  return service_endpoints(options_.lead).samples;
}

std::optional<Camera> WallFollower::camera() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return camera_;
}

std::optional<WallLayout> WallFollower::layout() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return layout_;
}

uint32_t WallFollower::node_id() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return node_id_;
}

PixelRect WallFollower::cell() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (layout_) {
    for (const WallNode& n : layout_->nodes) {
      if (n.node_id == node_id_) return n.cell;
    }
  }
  return {};
}

Camera WallFollower::camera_at(double t) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (views_.empty()) {
    throw Error("wall follower: no view from the lead yet (wait_until_admitted first)");
  }
  const protocol::View* nearest = &views_.back();
  for (const protocol::View& v : views_) {
    if (std::abs(v.time - t) < std::abs(nearest->time - t)) nearest = &v;
  }
  return nearest->camera;
}

std::optional<WallPosition> WallFollower::wall_position() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!layout_) return std::nullopt;
  return WallPosition{*layout_, node_id_};
}

bool WallFollower::wait_until_admitted(const std::atomic<bool>& stop) {
  const double started = steady_seconds();
  double next_note = 5.0;
  while (!stop.load() && !failed()) {
    if (layout() && !cell().empty() && camera()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const double waited = steady_seconds() - started;
    if (waited > next_note) {
      spdlog::info("waiting for the lead display {} to admit cell {},{} ({:.0f} s)", options_.lead,
                   options_.column, options_.row, waited);
      next_note += 5.0;
    }
  }
  return false;
}

std::string WallFollower::preset() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return preset_;
}

std::string WallFollower::endpoint() const { return samples_->endpoint(); }

// One loop over links to the lead: fresh sockets, join until welcomed, then heartbeats, views
// and layouts until the lead falls silent, restarts or asks this node to go.
void WallFollower::control_loop() {
  DisplayLinkOptions lo;
  lo.display = options_.lead;
  lo.security = options_.keys.secret_key.empty()
                    ? Security::none()
                    : Security::client(options_.keys, options_.lead_public_key.empty()
                                                          ? options_.keys.public_key
                                                          : options_.lead_public_key);
  lo.silence_floor = options_.lead_timeout;
  lo.heartbeat_interval = options_.heartbeat_interval;
  uint64_t heartbeat_sequence = 0;
  LogLimiter log;              // what the lead (or whoever holds its address) can repeat at will
  uint64_t members_epoch = 0;  // of the last member_list (a new session numbers them anew)
  while (running_.load() && !failed_.load()) {
    DisplayLink link(context_, lo);
    bool over = false;
    uint64_t session = 0;
    while (running_.load() && !over) {
      const DisplayLink::State state = link.state();
      if (state == DisplayLink::State::kGiveUp) break;  // fresh sockets now and then
      if (state == DisplayLink::State::kSilent) {
        spdlog::warn("lead display silent for {:.1f} s: joining again", link.silence());
        break;
      }
      if (state == DisplayLink::State::kUnanswered) {
        spdlog::warn("no answer from the lead display at {} after 5 s (is it running?)",
                     options_.lead);
      }
      if (link.join_due()) {
        DisplayJoin j;
        j.node_id = node_id();
        j.column = uint16_t(options_.column);
        j.row = uint16_t(options_.row);
        j.samples_endpoint = options_.advertise;
        j.name = options_.name;
        if (Status s = link.send(j); !s.ok()) {
          spdlog::debug("cannot ask the lead to join: {}", s.message());
        }
      }
      link.wait(10);
      log.flush([](const std::string& cause, uint64_t n) {
        spdlog::warn("control channel: {} more like this since its last line: {}", n, cause);
      });
      while (std::optional<Result<Message>> m = link.receive_control()) {
        if (!m->ok()) {
          if (const uint64_t n = log.due(LogLimiter::cause_of(m->error()))) {
            spdlog::warn("control channel: rejected {} message(s) like this one from the lead: {}",
                         n, m->error());
          }
          continue;
        }
        const Message& msg = m->value();
        if (const auto* w = std::get_if<Welcome>(&msg)) {
          if (!link.joined() || w->session != session) {
            spdlog::info("joined the wall as display node {} (session {:x}): {}x{} virtual display",
                         w->sampler_id, w->session, w->image.width, w->image.height);
          }
          std::lock_guard<std::mutex> lock(mutex_);
          if (w->session != session) {  // a new session numbers layouts and member lists anew
            layout_.reset();
            members_epoch = 0;
            gate_.replace({});
          }
          link.welcomed();
          session = w->session;
          clock_.reset_to(w->display_time);
          node_id_ = w->sampler_id;
          preset_ = w->presets;
        } else if (const auto* l = std::get_if<WallLayout>(&msg)) {
          std::lock_guard<std::mutex> lock(mutex_);
          if (layout_ && l->epoch < layout_->epoch) continue;  // an older one, overtaken
          layout_ = *l;
          samples_->set_image_bounds({l->image.width, l->image.height});
          for (const WallNode& n : l->nodes) {
            if (n.node_id == node_id_) {
              metrics_.set_wall(n.node_id, n.cell, l->nodes.size(), l->epoch);
            }
          }
        } else if (const auto* ml = std::get_if<MemberList>(&msg)) {
          // The lead's members: only their batches, with their tokens (and keys), are stored, and
          // their tiling snapshots cut to their regions.
          if (ml->epoch > members_epoch) {
            members_epoch = ml->epoch;
            std::vector<MemberGate::Member> members;
            for (const MemberEntry& e : ml->members) {
              members.push_back({e.sampler_id, e.token, e.public_key, e.region});
            }
            gate_.replace(members);
          }
        } else if (const auto* sr = std::get_if<SnapshotRequest>(&msg)) {
          if (!snapshots_.request({sr->id, sr->time})) {
            spdlog::warn("snapshot {} of t={:.3f}s refused: {} snapshots are pending already",
                         sr->id, sr->time, SnapshotQueue::kMaxPending);
          }
        } else if (const auto* hb = std::get_if<Heartbeat>(&msg)) {
          if (link.joined() && hb->session != session) {
            spdlog::info("the lead display restarted: joining again");
            over = true;
          }
        } else if (const auto* l = std::get_if<Leave>(&msg)) {
          if (l->reason == LeaveReason::kVersionMismatch) {
            spdlog::error("the lead display refused this node: {} (protocol version {})", l->text,
                          kProtocolVersion);
            failed_.store(true);
          } else {
            spdlog::warn("the lead display asked this node to leave: {}", l->text);
          }
          over = true;
        }
      }
      while (std::optional<View> v = link.receive_view()) {
        if (!link.joined()) continue;
        clock_.observe(v->time);  // views carry no session: only control messages are life
        std::lock_guard<std::mutex> lock(mutex_);
        camera_ = v->camera;
        // A restarted lead's clock starts again: its views replace the old session's.
        if (!views_.empty() && v->time < views_.back().time) views_.clear();
        views_.push_back(*v);
        if (views_.size() > kViewHistory) views_.pop_front();
      }
      if (link.heartbeat_due()) {
        (void)link.send(Heartbeat{node_id(), session, heartbeat_sequence++, clock_.now()});
      }
    }
    if (link.joined() && !running_.load() && !failed_.load()) {
      (void)link.send(Leave{node_id(), LeaveReason::kShutdown, "display node stopped"});
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (!running_.load() || failed_.load()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace afr::service
