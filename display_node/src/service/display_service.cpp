#include <afr/display/service/display_service.h>

#include <afr/common/error.h>
#include <afr/protocol/scene_hash.h>

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>

namespace afr::service {

using namespace afr::protocol;

// ---------------------------------------------------------------------------------------------
// Scene payload

ScenePayload read_scene_payload(const std::string& path) {
  ScenePayload p;
  if (path.empty()) {
    p.name = "builtin";
    p.bytes.assign(kBuiltinSceneBytes.begin(), kBuiltinSceneBytes.end());
  } else {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("{}: cannot open the scene file", path));
    p.bytes.assign(std::istreambuf_iterator<char>(in), {});
    if (p.bytes.empty()) throw Error(fmt::format("{}: the scene file is empty", path));
    if (p.bytes.size() > kMaxSceneBytes) {
      throw Error(
          fmt::format("{}: {} bytes is over the protocol's limit of 4 GiB", path, p.bytes.size()));
    }
    p.name = std::filesystem::path(path).filename().string();
    if (p.name.size() > kMaxNameBytes) p.name = p.name.substr(p.name.size() - kMaxNameBytes);
    // Only this one file travels: external buffers or images would be missing on the samplers.
    const std::string ext = std::filesystem::path(path).extension().string();
    if (ext == ".gltf") {
      const std::string text(p.bytes.begin(), p.bytes.end());
      if (text.find("\"uri\"") != std::string::npos) {
        size_t pos = 0;
        while ((pos = text.find("\"uri\"", pos)) != std::string::npos) {
          const size_t q = text.find('"', text.find(':', pos) + 1);
          if (q == std::string::npos || text.compare(q + 1, 5, "data:") != 0) {
            throw Error(fmt::format(
                "{}: refers to external files (a \"uri\" that is not a data: URI); samplers "
                "receive only this file: convert it to .glb or embed its buffers",
                path));
          }
          pos = q;
        }
      }
    }
  }
  p.hash = scene_hash(p.bytes);
  return p;
}

// ---------------------------------------------------------------------------------------------
// The control thread's state

struct DisplayService::Control {
  Control(Context& ctx, const ServiceEndpoints& ep, const Security& sec, int w, int h,
          const CoordinatorOptions& co)
      : server(ctx, ep.control, sec), views(ctx, ep.views, sec), coordinator(w, h, co) {}
  ControlServer server;
  ViewPublisher views;
  Coordinator coordinator;
  struct Transfer {
    uint32_t next_chunk = 0;
  };
  std::map<std::string, Transfer> transfers;   // by peer
  std::map<std::string, double> told_unknown;  // peers told to join again, when
  uint64_t view_sequence = 0;
  uint64_t heartbeat_sequence = 0;
};

struct DisplayService::Http {
  httplib::Server server;
};

namespace {

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
      } else {
        spdlog::warn("CurveZMQ: REFUSED {} key {} from {}: not on the allow-list", d.mechanism,
                     d.public_key.empty() ? "(none)" : d.public_key, d.address);
      }
    });
  }
  const Security sec = server_security(options_);
  try {
    control_ = std::make_unique<Control>(context_, endpoints_, sec, options_.width, options_.height,
                                         options_.coordinator);
    samples_ = std::make_unique<SampleReceiver>(context_, endpoints_.samples, sec);
  } catch (const zmq::error_t& e) {
    throw Error(fmt::format("cannot bind {} (ports {}, +1, +2): {}", options_.bind,
                            endpoints_.control, e.what()));
  }
  samples_->set_image_bounds({options_.width, options_.height});
  if (options_.metrics_port > 0) {
    http_ = std::make_unique<Http>();
    http_->server.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
      res.set_content(metrics_.prometheus(), "text/plain; version=0.0.4");
    });
    http_->server.Get("/stats", [this](const httplib::Request&, httplib::Response& res) {
      res.set_content(metrics_.json(), "application/json");
    });
    if (!http_->server.bind_to_port(options_.metrics_address.c_str(), options_.metrics_port)) {
      throw Error(fmt::format("cannot serve metrics on {}:{} (port in use?)",
                              options_.metrics_address, options_.metrics_port));
    }
  }
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
  if (http_) {
    http_thread_ = std::thread([this] { http_->server.listen_after_bind(); });
    spdlog::info("metrics on http://{}:{}/metrics and /stats", options_.metrics_address,
                 options_.metrics_port);
  }
}

void DisplayService::stop() {
  if (!running_.exchange(false)) return;
  if (control_thread_.joinable()) control_thread_.join();
  if (ingest_thread_.joinable()) ingest_thread_.join();
  if (http_) {
    http_->server.stop();
    if (http_thread_.joinable()) http_thread_.join();
  }
}

// ---------------------------------------------------------------------------------------------
// Ingest: the sample channel into the sink

void DisplayService::ingest_loop() {
  uint64_t rejected = 0;
  while (running_.load(std::memory_order_relaxed)) {
    switch (samples_->receive(50)) {
      case SampleReceiver::Got::kNothing:
        break;
      case SampleReceiver::Got::kBatch: {
        const SampleBatch& b = samples_->batch();
        bool member;
        {
          std::lock_guard<std::mutex> lock(regions_mutex_);
          member = std::any_of(regions_.begin(), regions_.end(),
                               [&](const auto& r) { return r.first == b.sampler_id; });
        }
        metrics_.on_batch(b, batch_message_bytes(b.fields, b.samples.size()), member);
        sink_.on_batch(std::move(samples_->batch()));
        break;
      }
      case SampleReceiver::Got::kTiling: {
        const TilingSnapshot& t = samples_->tiling();
        metrics_.on_tiling(t.sampler_id, snapshot_message_bytes(t.tiles.size()));
        sink_.on_tiling(std::move(samples_->tiling()));
        break;
      }
      case SampleReceiver::Got::kRejected:
        metrics_.on_rejected_sample_message();
        if (rejected++ % 1000 == 0) {
          spdlog::warn("sample channel: rejected a message ({} so far): {}", rejected,
                       samples_->rejection().message());
        }
        break;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Control: membership, regions, scene, heartbeats, views

void DisplayService::control_loop() {
  Control& c = *control_;
  Coordinator& co = c.coordinator;
  const double heartbeat_interval = 0.15;
  double last_heartbeat = 0.0, last_expire = 0.0, next_view = now();

  auto send = [&](const std::string& peer, const Message& m) {
    Status s = c.server.send(peer, m);
    if (!s.ok())
      spdlog::debug("control: cannot send {}: {}", message_type_name(message_type(m)), s.message());
    return s.ok();
  };
  auto send_regions = [&](double t) {
    std::vector<std::pair<uint32_t, PixelRect>> regions;
    for (const auto& [id, m] : co.members()) {
      RegionAssignment ra{id, co.epoch(), options_.width, options_.height, m.region};
      send(m.peer, ra);
      metrics_.on_region(id, m.region, co.epoch(), co.recuts());
      regions.emplace_back(id, m.region);
      spdlog::info("region epoch {}: sampler {} ({}) gets [{}, {}) x [{}, {}) ({:.0f}%)",
                   co.epoch(), id, m.name, m.region.x0, m.region.x1, m.region.y0, m.region.y1,
                   100.0 * double(m.region.area()) / (double(options_.width) * options_.height));
    }
    std::lock_guard<std::mutex> lock(regions_mutex_);
    regions_ = std::move(regions);
  };
  auto welcome = [&](const Member& m, double t) {
    Welcome w;
    w.sampler_id = m.id;
    w.session = session_;
    w.width = options_.width;
    w.height = options_.height;
    w.display_time = now();
    w.refresh_interval = options_.refresh_interval;
    w.scene_hash = options_.scene.hash;
    w.scene_size = options_.scene.bytes.size();
    w.scene_name = options_.scene.name;
    w.presets = options_.preset;
    send(m.peer, w);
  };

  while (running_.load(std::memory_order_relaxed)) {
    const double wait = std::max(0.0, std::min(next_view - now(), 0.005));
    if (auto in = c.server.receive(int(wait * 1000.0))) {
      const double t = now();
      if (!in->message.ok()) {
        metrics_.on_rejected_control();
        spdlog::warn("control: rejected a message from peer {}{}: {}", to_hex_peer(in->peer),
                     in->public_key.empty() ? "" : " key " + in->public_key, in->message.error());
        if (in->message.error().find("version") != std::string::npos) {
          send(in->peer,
               Leave{0, LeaveReason::kVersionMismatch,
                     fmt::format("this display speaks protocol version {}", kProtocolVersion)});
        }
      } else {
        const Message& msg = in->message.value();
        Member* m = co.find_peer(in->peer);
        if (const auto* j = std::get_if<Join>(&msg)) {
          bool is_new = false;
          Member& mm =
              co.join(in->peer, j->sampler_id, j->name, in->public_key, j->threads, t, &is_new);
          if (is_new) {
            spdlog::info("sampler {} joined: {} ({} thread(s){})", mm.id, j->name, j->threads,
                         in->public_key.empty() ? "" : ", key " + in->public_key);
            metrics_.on_member(j->name, mm.id, in->public_key, j->threads);
          }
          welcome(mm, t);
          if (!is_new) {  // a repeated join: the region it may have missed
            send(mm.peer,
                 RegionAssignment{mm.id, co.epoch(), options_.width, options_.height, mm.region});
          }
        } else if (!m) {
          // Not a member: a sampler of a previous session (this display restarted) or one
          // declared dead. Tell it to join (at most twice a second per peer).
          if (!std::holds_alternative<Leave>(msg)) {
            double& told = c.told_unknown[in->peer];
            if (t - told > 0.5) {
              told = t;
              send(in->peer, Leave{0, LeaveReason::kTimeout, "not a member of this session: join"});
            }
          }
        } else {
          co.heard(m->id, t);
          if (const auto* r = std::get_if<SceneRequest>(&msg)) {
            if (r->scene_hash != options_.scene.hash) {
              spdlog::warn("sampler {} asked for scene {}, not this session's: ignored", m->id,
                           to_hex(r->scene_hash).substr(0, 16));
            } else {
              c.transfers[in->peer].next_chunk = r->first_chunk;
            }
          } else if (const auto* s = std::get_if<SamplerStats>(&msg)) {
            metrics_.on_reported(*s);
            co.report_throughput(m->id, s->samples_per_second, t);
          } else if (const auto* l = std::get_if<Leave>(&msg)) {
            spdlog::info("sampler {} ({}) left: {}", m->id, m->name, l->text);
            metrics_.on_member_gone(m->id, false);
            c.transfers.erase(m->peer);
            co.remove(m->id);
          }
        }
      }
    }

    const double t = now();
    // Scene transfers: a few chunks per pass, resumed when the peer's queue has room.
    const uint64_t size = options_.scene.bytes.size();
    const uint32_t count = uint32_t((size + options_.chunk_bytes - 1) / options_.chunk_bytes);
    for (auto it = c.transfers.begin(); it != c.transfers.end();) {
      uint64_t sent = 0;
      bool stalled = false;
      for (int k = 0; k < 4 && it->second.next_chunk < count; ++k) {
        SceneChunk ch;
        ch.scene_hash = options_.scene.hash;
        ch.scene_size = size;
        ch.index = it->second.next_chunk;
        ch.count = count;
        ch.offset = uint64_t(ch.index) * options_.chunk_bytes;
        const uint64_t n = std::min<uint64_t>(options_.chunk_bytes, size - ch.offset);
        ch.bytes.assign(options_.scene.bytes.begin() + ch.offset,
                        options_.scene.bytes.begin() + ch.offset + n);
        if (!send(it->first, ch)) {
          stalled = true;
          break;
        }
        ++it->second.next_chunk;
        ++sent;
      }
      metrics_.on_chunks_sent(sent);
      if (!stalled && it->second.next_chunk >= count) {
        it = c.transfers.erase(it);
      } else {
        ++it;
      }
    }

    if (t - last_expire >= 0.02) {
      last_expire = t;
      for (const Member& dead : co.expire(t)) {
        spdlog::warn("sampler {} ({}) lost: no word for {:.2f} s; its region goes to the others",
                     dead.id, dead.name, t - dead.last_heard);
        metrics_.on_member_gone(dead.id, true);
        c.transfers.erase(dead.peer);
        send(dead.peer, Leave{dead.id, LeaveReason::kTimeout, "no heartbeat: join again"});
      }
    }
    if (co.maybe_recut(t)) send_regions(t);

    if (t - last_heartbeat >= heartbeat_interval) {
      last_heartbeat = t;
      for (const auto& [id, m] : co.members()) {
        send(m.peer, Heartbeat{id, session_, c.heartbeat_sequence, t});
      }
      ++c.heartbeat_sequence;
      if (context_.zap()) metrics_.set_zap(context_.zap()->accepted(), context_.zap()->refused());
    }
    if (t >= next_view) {
      View v;
      v.sequence = c.view_sequence++;
      v.time = t;
      v.camera = options_.camera_at(t);
      if (Status s = c.views.publish(v); !s.ok()) {
        spdlog::error("view {}: {}", v.sequence, s.message());
      }
      metrics_.on_view();
      next_view += options_.refresh_interval;
      if (next_view < t) next_view = t + options_.refresh_interval;
    }
  }
  for (const auto& [id, m] : co.members()) {
    send(m.peer, Leave{id, LeaveReason::kShutdown, "display shutting down"});
  }
}

}  // namespace afr::service
