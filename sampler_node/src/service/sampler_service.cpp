#include <afr/sampler/service/sampler_service.h>

#include <afr/common/clock.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/protocol/display_link.h>
#include <afr/protocol/scene_hash.h>
#include <afr/sampler/sampler_pool.h>
#include <afr/sampler/service/scene_cache.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

namespace afr::service {

using namespace afr::protocol;

namespace {

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// ---------------------------------------------------------------------------------------------
// The camera of the display's views

// The camera of the display's latest view, which the samplers trace from — unless that view
// is the scene's own animated camera at the view's time, as it is when nobody steers: then
// the samplers trace the scene's camera at the exact time of every sample instead of holding
// a view that is up to a refresh old. observe() from the service thread; camera_at() from
// the pool's threads.
class ViewCamera final : public CameraSource {
 public:
  void observe(const View& v, const Scene* scene) {
    bool scene_own = false;
    if (scene) {
      const double d = scene->duration();
      const double t = d > 0.0 ? std::fmod(v.time, d) : v.time;
      const Camera own = scene->camera_at(scene->evaluate(t));
      const double tolerance = 1e-6 * (1.0 + glm::length(own.eye));
      scene_own = glm::length(own.eye - v.camera.eye) <= tolerance &&
                  glm::dot(own.forward, v.camera.forward) >= 1.0 - 1e-9 &&
                  glm::dot(own.up, v.camera.up) >= 1.0 - 1e-9 &&
                  std::abs(own.yfov - v.camera.yfov) <= 1e-9 &&
                  std::abs(own.ymag - v.camera.ymag) <= 1e-9 * (1.0 + own.ymag);
    }
    std::lock_guard<std::mutex> lock(mutex_);
    latest_ = scene_own ? std::nullopt : std::optional<Camera>(v.camera);
  }
  std::optional<Camera> camera_at(double) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return latest_;
  }

 private:
  mutable std::mutex mutex_;
  std::optional<Camera> latest_;
};

// ---------------------------------------------------------------------------------------------
// The pool's sink: the sample channels, shared by the pool's worker threads

// Where samples go. Without a wall, one route: the display's sample channel, everything. On a
// display wall (docs/wall.md), one route per display node, with the part of the image whose
// samples and tiles that node needs; a sample inside several (the margins overlap) goes to each.
struct SampleRoute {
  SampleSender* sender = nullptr;
  PixelRect rect;          // empty: everything (no wall)
  uint64_t sequence = 0;   // batches sent on this route: each node sees its own sequence
  bool had_tiles = false;  // the last snapshot sent on this route had tiles
};

class NetworkSink final : public SampleSink {
 public:
  // `token`: the welcome's, which the display checks on every batch and snapshot.
  void attach(SampleSender* sender, uint32_t sampler_id, uint64_t token, ImageExtent bounds) {
    std::lock_guard<std::mutex> lock(mutex_);
    retire_locked();
    routes_.push_back(SampleRoute{sender, PixelRect{}, 0});
    sampler_id_ = sampler_id;
    token_ = token;
    bounds_ = bounds;
  }
  // A display wall's routes (each sender outlives its route). Keeps the ids and bounds of
  // attach(); counters of senders no longer routed to are kept.
  void route(const std::vector<SampleRoute>& routes) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<SampleRoute> next = routes;
    for (SampleRoute& r : next) {
      for (const SampleRoute& old : routes_) {
        if (old.sender == r.sender) r.sequence = old.sequence;
      }
    }
    for (const SampleRoute& old : routes_) {
      const bool kept = std::any_of(next.begin(), next.end(),
                                    [&](const SampleRoute& r) { return r.sender == old.sender; });
      if (!kept) add(&retired_, old.sender->counters());
    }
    routes_ = std::move(next);
  }
  void detach() {
    std::lock_guard<std::mutex> lock(mutex_);
    retire_locked();
  }

  // Flow control: a batch waits (up to kMaxWait, without the lock) until ZeroMQ has taken
  // everything queued before it on its routes, so a worker traces no faster than the link and
  // the display absorb, and what is traced is sent rather than dropped. The wait adds no
  // latency beyond ZeroMQ's own small queue (ChannelOptions::samples). A display that stays
  // away is not waited for longer: then the sender drops the oldest, as before.
  void on_batch(SampleBatch&& batch) override {
    const auto deadline = std::chrono::steady_clock::now() + kMaxWait;
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        bool clear = true;
        for (SampleRoute& r : routes_) clear = r.sender->pump() == 0 && clear;
        if (clear || std::chrono::steady_clock::now() >= deadline) break;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (routes_.empty()) {
      ++unsent_;
      return;
    }
    batch.sampler_id = sampler_id_;
    batch.token = token_;
    if (routes_.size() == 1 && routes_[0].rect.empty()) {
      // One sequence per node: the pool's threads each count their own batches.
      batch.sequence = routes_[0].sequence++;
      if (Status s = routes_[0].sender->send(batch, bounds_); !s.ok()) report(s);
      return;
    }
    for (SampleRoute& r : routes_) {
      select_samples(batch, r.rect, &part_);
      if (part_.samples.empty()) continue;
      part_.sequence = r.sequence++;
      if (Status s = r.sender->send(part_, bounds_); !s.ok()) report(s);
    }
  }
  void on_tiling(TilingSnapshot&& snapshot) override {
    std::lock_guard<std::mutex> lock(mutex_);
    snapshot.sampler_id = sampler_id_;
    snapshot.token = token_;
    for (SampleRoute& r : routes_) {
      if (r.rect.empty()) {
        if (Status s = r.sender->send(snapshot, bounds_); !s.ok()) report(s);
        continue;
      }
      // Only the tiles that reach the node's part of the image. When none do any more (the
      // sampler's region moved away), one empty snapshot tells the node to drop this sampler's
      // tiles; after that the node hears nothing from it.
      select_tiles(snapshot, r.rect, &tiles_);
      if (tiles_.tiles.empty() && !r.had_tiles) continue;
      r.had_tiles = !tiles_.tiles.empty();
      if (Status s = r.sender->send(tiles_, bounds_); !s.ok()) report(s);
    }
  }
  void pump() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (SampleRoute& r : routes_) r.sender->pump();
  }
  // Over every sender this sink has had.
  SampleSender::Counters counters() const {
    std::lock_guard<std::mutex> lock(mutex_);
    SampleSender::Counters c = retired_;
    for (const SampleRoute& r : routes_) add(&c, r.sender->counters());
    c.batches_dropped += unsent_;
    return c;
  }

 private:
  static void add(SampleSender::Counters* a, const SampleSender::Counters& b) {
    a->batches_sent += b.batches_sent;
    a->tilings_sent += b.tilings_sent;
    a->bytes_sent += b.bytes_sent;
    a->batches_dropped += b.batches_dropped;
    a->tilings_dropped += b.tilings_dropped;
  }
  void retire_locked() {
    for (const SampleRoute& r : routes_) add(&retired_, r.sender->counters());
    routes_.clear();
  }
  void report(const Status& s) {
    // Only a bug upstream makes a batch the codec refuses; say it once in a while.
    if (encode_errors_++ % 1000 == 0) {
      spdlog::error("sample channel: could not encode ({} so far): {}", encode_errors_,
                    s.message());
    }
  }

  static constexpr std::chrono::milliseconds kMaxWait{50};
  mutable std::mutex mutex_;
  std::vector<SampleRoute> routes_;
  uint32_t sampler_id_ = 0;
  uint64_t token_ = 0;
  ImageExtent bounds_ = kMaxImageExtent;
  SampleBatch part_;      // the samples of one route (reused: no allocation per batch)
  TilingSnapshot tiles_;  // the tiles of one route
  uint64_t unsent_ = 0;
  uint64_t encode_errors_ = 0;
  SampleSender::Counters retired_;
};

enum class SessionEnd { kStopped, kRetry, kFatal, kFailed };

// What the scene loader thread hands back: the scene, or why there is none yet.
struct SceneLoad {
  enum class Outcome { kLoaded, kNotCached, kCorrupt } outcome = Outcome::kLoaded;
  std::unique_ptr<Scene> scene;
  std::string detail;       // kCorrupt: the hash the bytes had
  bool from_cache = false;  // kLoaded: found in the cache, not received
};

double megabytes(uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

// A leave's text within the protocol's limit, cut at a character boundary.
std::string leave_text(std::string text) {
  if (text.size() <= kMaxNameBytes) return text;
  size_t n = kMaxNameBytes - 3;
  while (n > 0 && (uint8_t(text[n]) & 0xC0) == 0x80) --n;
  return text.substr(0, n) + "...";
}

// The sample channel's options: the protocol's, with the send buffer the options name.
protocol::ChannelOptions sample_channel(const SamplerServiceOptions& options) {
  protocol::ChannelOptions o = protocol::ChannelOptions::samples();
  if (options.send_buffer > 0) o.send_buffer = options.send_buffer;
  return o;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

struct SamplerService::Impl {
  explicit Impl(SamplerServiceOptions o)
      : options(std::move(o)), cache(options.cache_dir, options.cache_max_bytes) {}

  // What a display (or whoever holds its address) can repeat at will: a line per cause a
  // second. The control thread's only.
  LogLimiter log;

  SessionEnd run_session(const std::atomic<bool>& stop);
  void handle(const Message& m, DisplayLink& control, SampleSender& sender, double now,
              SessionEnd* end);
  void on_welcome(const Welcome& w, DisplayLink& control, SampleSender& sender);
  void on_chunk(const SceneChunk& c);
  void on_region(const RegionAssignment& r);
  void on_wall(const WallLayout& w, SampleSender& sender);
  void load_scene(std::function<SceneLoad()> job, const SceneHash& hash);
  void update_pool();
  void stop_pool();
  void finish_background_work(DisplayLink& control);
  void send_stats(DisplayLink& control);
  SamplerCounters pool_counters() const;

  SamplerServiceOptions options;
  Context context;
  RemoteClock clock;  // the display's (DESIGN.md, "Time"), learned from views
  ViewCamera view_camera;
  NetworkSink sink;
  SceneCache cache;
  SceneAssembler assembler;

  // Session state.
  bool joined = false;
  bool session_over = false;  // a leave or a restarted display ended the session
  uint32_t sampler_id = 0;    // kept across sessions: asked for again on a rejoin
  uint64_t session = 0;
  Welcome welcome;
  bool fetching = false;
  double last_chunk_time = 0.0;
  double last_progress_time = 0.0;  // of the last progress line of a transfer or a load
  std::optional<RegionAssignment> region;
  uint64_t epoch = 0;
  // A display wall's sample channels (the lead display's is the session's own sender), by
  // endpoint; they live as long as the session or until the wall drops their node.
  std::map<std::string, std::unique_ptr<SampleSender>> wall_senders;
  uint64_t wall_epoch = 0;
  // The layout in force: the display sends it again with every answer to a repeated join.
  std::optional<WallLayout> wall;

  // Scene and pool.
  std::unique_ptr<Scene> scene;
  SceneHash scene_hash{};
  std::unique_ptr<SamplerPool> pool;
  PixelRect pool_region;
  ImageExtent pool_image;  // what the pool was built for, besides the session's scene
  SceneHash pool_scene{};
  // The scene's BVHs, built with the first pool and shared by every pool of the scene
  // (SamplerPoolOptions::geometry); it holds `scene` (no copy), so it goes before the scene.
  std::shared_ptr<const Tracer> geometry;
  struct BuiltPool {
    std::unique_ptr<SamplerPool> pool;
    std::shared_ptr<const Tracer> geometry;  // the one it shares
  };
  std::future<BuiltPool> building;  // a pool being constructed
  PixelRect building_region;
  ImageExtent building_image;
  SceneHash building_scene{};
  // The control thread never waits for a scene or a pool (its heartbeats would stop): a scene
  // loads on a helper thread, and a pool whose construction is abandoned (a recut, a new
  // session) finishes on its own and is dropped here once built. Such pools read `scene`, so
  // a loaded scene replaces it only when none is left.
  std::future<SceneLoad> loading;
  SceneHash loading_hash{};
  double loading_since = 0.0;
  std::vector<std::future<BuiltPool>> abandoned_pools;
  std::vector<std::future<SceneLoad>> abandoned_scenes;
  // Why this sampler cannot serve the session (the scene does not load, the pool cannot be
  // built): told to the display in a leave, then run() returns 3.
  std::optional<std::string> failure;
  SamplerCounters retired;  // counters of pools already stopped

  // Stats.
  uint64_t last_stats_samples = 0;
  double last_stats_time = 0.0;
  double samples_per_second = 0.0;
  uint64_t heartbeat_sequence = 0;

  mutable std::mutex counters_mutex;
  SamplerServiceCounters counters;
};

SamplerService::SamplerService(SamplerServiceOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {
  const SamplerServiceOptions& o = impl_->options;
  (void)service_endpoints(o.display);  // throws for a malformed endpoint, before any socket
  if (o.threads < 1 || o.threads > 256) {
    throw Error(fmt::format("--threads {}: must be in 1..256", o.threads));
  }
  if (!(o.max_samples_per_second >= 0.0)) {
    throw Error(fmt::format("--max-samples-per-second {}: must be >= 0", o.max_samples_per_second));
  }
  if (!o.preset.empty()) (void)find_preset(o.preset);
}

SamplerService::~SamplerService() { impl_->stop_pool(); }

SamplerServiceCounters SamplerService::counters() const {
  std::lock_guard<std::mutex> lock(impl_->counters_mutex);
  return impl_->counters;
}

int SamplerService::run(const std::atomic<bool>& stop) {
  while (!stop.load()) {
    const SessionEnd end = impl_->run_session(stop);
    if (end == SessionEnd::kFatal) return 2;
    if (end == SessionEnd::kFailed) {
      impl_->stop_pool();
      return 3;
    }
    if (end == SessionEnd::kStopped) break;
    // A short pause, so a display that refuses at once is not hammered.
    for (int i = 0; i < 5 && !stop.load(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  impl_->stop_pool();
  return 0;
}

// ---------------------------------------------------------------------------------------------
// One session: from fresh sockets to the loss of the display (or a stop)

SessionEnd SamplerService::Impl::run_session(const std::atomic<bool>& stop) {
  DisplayLinkOptions lo;
  lo.display = options.display;
  lo.security = options.security;
  lo.silence_floor = options.display_timeout;
  lo.heartbeat_interval = options.heartbeat_interval;
  DisplayLink control(context, lo);
  SampleSender sender(context, service_endpoints(options.display).samples, options.security,
                      sample_channel(options));

  joined = false;
  session_over = false;
  fetching = false;
  SessionEnd end = SessionEnd::kRetry;
  bool done = false;
  uint64_t views_rejected = 0;

  while (!done) {
    if (stop.load()) {
      end = SessionEnd::kStopped;
      break;
    }
    const DisplayLink::State state = control.state();
    if (state == DisplayLink::State::kGiveUp) return SessionEnd::kRetry;
    if (state == DisplayLink::State::kSilent) {
      spdlog::warn("display silent for {:.1f} s: reconnecting", control.silence());
      break;
    }
    if (state == DisplayLink::State::kUnanswered) {
      spdlog::warn(
          "no answer from the display at {} after 5 s (is it running? with CurveZMQ: is this "
          "sampler's public key on its allow-list, and --server-key its public key?)",
          options.display);
    }
    if (control.join_due()) {
      Join j;
      j.sampler_id = sampler_id;
      j.threads = uint16_t(options.threads);
      j.capabilities = kCapWorldPosition | kCapVelocity | kCapTilings | kCapSceneCache;
      j.name = options.name;
      (void)control.send(j);  // queued until connected; resent until welcomed
      std::lock_guard<std::mutex> lock(counters_mutex);
      ++counters.joins_sent;
    }

    control.wait(5);
    log.flush([](const std::string& cause, uint64_t n) {
      spdlog::warn("{} more like this since its last line: {}", n, cause);
    });
    while (std::optional<Result<Message>> m = control.receive_control()) {
      if (!m->ok()) {
        std::lock_guard<std::mutex> lock(counters_mutex);
        ++counters.rejected_messages;
        if (const uint64_t n = log.due(LogLimiter::cause_of(m->error()))) {
          spdlog::warn("control channel: rejected {} message(s) like this one from the display: {}",
                       n, m->error());
        }
        continue;
      }
      handle(m->value(), control, sender, steady_seconds(), &end);
      if (session_over) {
        done = true;
        break;
      }
    }
    if (done) break;
    while (std::optional<View> v = control.receive_view()) {
      if (!joined) continue;
      clock.observe(v->time);
      view_camera.observe(*v, scene.get());
    }
    if (control.views().rejected() > views_rejected) {
      views_rejected = control.views().rejected();
      const std::string& why = control.views().rejection().message();
      if (const uint64_t n = log.due("view: " + LogLimiter::cause_of(why))) {
        spdlog::warn("view channel: rejected views ({} in all; {} since the last line): {}",
                     views_rejected, n, why);
      }
    }

    if (joined) {
      const double now = steady_seconds();
      if (control.heartbeat_due()) {
        (void)control.send(Heartbeat{sampler_id, session, heartbeat_sequence++, clock.now()});
      }
      if (now - last_stats_time >= options.stats_interval) send_stats(control);
      if (fetching && now - last_chunk_time > 3.0) {
        spdlog::warn("scene transfer stalled: asking again from chunk {}", assembler.next_chunk());
        (void)control.send(SceneRequest{sampler_id, assembler.hash(), assembler.next_chunk()});
        last_chunk_time = now;
      }
      if (loading.valid() && now - loading_since >= 2.0 && now - last_progress_time >= 2.0) {
        spdlog::info("still loading scene {}: {:.0f} s so far", welcome.scene_name,
                     now - loading_since);
        last_progress_time = now;
      }
    }
    finish_background_work(control);
    update_pool();
    if (failure) {
      // The display hears why and gives the region to the others; joining again would only
      // fail the same way on the same scene.
      spdlog::error("{}: leaving the display", *failure);
      if (joined) (void)control.send(Leave{sampler_id, LeaveReason::kError, leave_text(*failure)});
      end = SessionEnd::kFailed;
      break;
    }
    sink.pump();
  }

  // The pool first: its threads send through the senders, which flush() then uses alone.
  stop_pool();
  if (end == SessionEnd::kStopped && joined) {
    (void)control.send(Leave{sampler_id, LeaveReason::kShutdown, "sampler stopped"});
    sender.flush(200);
    for (auto& [endpoint, s] : wall_senders) s->flush(200);
  }
  sink.detach();  // before the senders it routes to go away
  wall_senders.clear();
  wall_epoch = 0;
  wall.reset();
  joined = false;
  return end;
}

void SamplerService::Impl::handle(const Message& m, DisplayLink& control, SampleSender& sender,
                                  double now, SessionEnd* end) {
  if (const auto* w = std::get_if<Welcome>(&m)) {
    on_welcome(*w, control, sender);
  } else if (const auto* c = std::get_if<SceneChunk>(&m)) {
    last_chunk_time = now;
    on_chunk(*c);
  } else if (const auto* r = std::get_if<RegionAssignment>(&m)) {
    on_region(*r);
  } else if (const auto* wl = std::get_if<WallLayout>(&m)) {
    on_wall(*wl, sender);
  } else if (const auto* hb = std::get_if<Heartbeat>(&m)) {
    if (joined && hb->session != session) {
      spdlog::info("the display restarted (session {:x} -> {:x}): joining again", session,
                   hb->session);
      session_over = true;
    }
  } else if (const auto* l = std::get_if<Leave>(&m)) {
    switch (l->reason) {
      case LeaveReason::kVersionMismatch:
        spdlog::error("the display refused this sampler: {} (protocol version {})", l->text,
                      kProtocolVersion);
        *end = SessionEnd::kFatal;
        break;
      case LeaveReason::kShutdown:
        spdlog::info("the display is shutting down: {}", l->text);
        break;
      default:
        spdlog::warn("the display asked this sampler to leave ({}): joining again", l->text);
        break;
    }
    session_over = true;
  }
}

void SamplerService::Impl::on_welcome(const Welcome& w, DisplayLink& control,
                                      SampleSender& sender) {
  const bool same_session = joined && w.session == session && w.sampler_id == sampler_id;
  clock.reset_to(w.display_time);
  if (same_session) return;  // an answer to a repeated join
  if (w.session != session) {
    stop_pool();
    region.reset();
    epoch = 0;
  }
  joined = true;
  control.welcomed();
  session = w.session;
  sampler_id = w.sampler_id;
  welcome = w;
  sink.attach(&sender, sampler_id, w.token, w.image);
  {
    std::lock_guard<std::mutex> lock(counters_mutex);
    ++counters.sessions;
  }
  spdlog::info("joined the display as sampler {} (session {:x}): {}x{}, scene {} ({} bytes)",
               sampler_id, session, w.image.width, w.image.height, w.scene_name, w.scene_size);
  if (loading.valid() ? loading_hash == w.scene_hash : scene && scene_hash == w.scene_hash) {
    return;
  }
  fetching = false;
  // The cache is looked up on the loader thread (a hit is read and hashed whole, then loaded);
  // a miss comes back as kNotCached and the transfer starts then (finish_background_work).
  load_scene(
      [cache = cache, hash = w.scene_hash, name = w.scene_name] {
        SceneLoad out;
        const std::optional<std::filesystem::path> file = cache.find(hash);
        if (!file) {
          out.outcome = SceneLoad::Outcome::kNotCached;
          return out;
        }
        spdlog::info("scene {} found in the cache: {}", to_hex(hash).substr(0, 16), file->string());
        out.scene = std::make_unique<Scene>(load_scene_payload(*file));
        out.from_cache = true;
        return out;
      },
      w.scene_hash);
}

void SamplerService::Impl::on_chunk(const SceneChunk& c) {
  if (!fetching) return;  // a late chunk of a transfer already done
  if (std::string err = assembler.add(c); !err.empty()) {
    spdlog::warn("scene transfer: {}", err);
    return;
  }
  const double now = steady_seconds();
  if (!assembler.complete()) {
    if (now - last_progress_time >= 2.0) {
      spdlog::info("scene transfer: {:.1f} of {:.1f} MB ({:.0f}%)", megabytes(assembler.received()),
                   megabytes(assembler.size()),
                   100.0 * double(assembler.received()) / double(assembler.size()));
      last_progress_time = now;
    }
    return;
  }
  fetching = false;
  {
    std::lock_guard<std::mutex> lock(counters_mutex);
    ++counters.scenes_received;
  }
  // Hash, cache and load on the loader thread: tens of MB take a while, and this thread sends
  // the heartbeats that keep this sampler a member.
  const SceneHash hash = assembler.hash();
  auto bytes = std::make_shared<std::vector<uint8_t>>(assembler.take_bytes());
  load_scene(
      [cache = cache, hash, bytes, name = welcome.scene_name] {
        SceneLoad out;
        const SceneHash got = protocol::scene_hash(*bytes);
        if (got != hash) {
          out.outcome = SceneLoad::Outcome::kCorrupt;
          out.detail = to_hex(got);
          return out;
        }
        std::filesystem::path file;
        try {
          file = cache.store(hash, name, *bytes);
          spdlog::info("scene received: {} bytes, cached as {}", bytes->size(), file.string());
        } catch (const Error& e) {
          // Not fatal: the scene is in memory; only a later session fetches it again.
          spdlog::warn("scene received: {} bytes, not cached ({}): loading it from memory",
                       bytes->size(), e.what());
        }
        if (!file.empty()) {
          out.scene = std::make_unique<Scene>(load_scene_payload(file));
        } else {
          // Named as the cached file would be: the loader looks for nothing outside the
          // cache's folder, as for a cached file.
          const std::string as = (cache.dir() / to_hex(hash)).string() +
                                 std::filesystem::path(name).extension().string();
          out.scene = std::make_unique<Scene>(load_scene_payload(*bytes, as));
        }
        return out;
      },
      hash);
}

// Starts loading a scene on the loader thread; the pool stops (it reads the old scene).
void SamplerService::Impl::load_scene(std::function<SceneLoad()> job, const SceneHash& hash) {
  stop_pool();
  if (loading.valid()) abandoned_scenes.push_back(std::move(loading));
  loading_hash = hash;
  loading_since = steady_seconds();
  loading = std::async(std::launch::async, std::move(job));
}

// Drops what background threads finished and no one waits for; takes a finished scene load:
// installs the scene, or starts the transfer the cache could not spare, or fails.
void SamplerService::Impl::finish_background_work(DisplayLink& control) {
  const auto ready = [](const auto& f) {
    return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  };
  const auto drop_ready = [&](auto* futures) {
    for (auto it = futures->begin(); it != futures->end();) {
      if (!ready(*it)) {
        ++it;
        continue;
      }
      try {
        it->get();
      } catch (const std::exception&) {
      }
      it = futures->erase(it);
    }
  };
  drop_ready(&abandoned_pools);
  drop_ready(&abandoned_scenes);
  if (!loading.valid() || !ready(loading) || !abandoned_pools.empty()) return;
  const double seconds = steady_seconds() - loading_since;
  SceneLoad got;
  try {
    got = loading.get();
  } catch (const std::exception& e) {
    failure = fmt::format("cannot load the display's scene {}: {}", welcome.scene_name, e.what());
    return;
  }
  switch (got.outcome) {
    case SceneLoad::Outcome::kNotCached:
    case SceneLoad::Outcome::kCorrupt:
      if (got.outcome == SceneLoad::Outcome::kCorrupt) {
        spdlog::error("scene transfer: the bytes hash to {}, not {}: asking again", got.detail,
                      to_hex(loading_hash));
      } else {
        spdlog::info("asking the display for scene {} ({:.1f} MB)", welcome.scene_name,
                     megabytes(welcome.scene_size));
      }
      if (!joined || loading_hash != welcome.scene_hash) return;  // a session since
      assembler.reset(welcome.scene_hash, welcome.scene_size);
      fetching = true;
      last_chunk_time = last_progress_time = steady_seconds();
      (void)control.send(SceneRequest{sampler_id, welcome.scene_hash, 0});
      return;
    case SceneLoad::Outcome::kLoaded:
      break;
  }
  if (got.from_cache) {
    std::lock_guard<std::mutex> lock(counters_mutex);
    ++counters.scene_cache_hits;
  }
  geometry.reset();  // built on the scene it replaces (no pool shares it any more)
  scene = std::move(got.scene);
  scene_hash = loading_hash;
  spdlog::info("scene {}: {} triangles, {:.2f} s of animation{} (loaded in {:.2f} s)",
               welcome.scene_name, scene->triangle_count(), scene->duration(),
               scene->ray_depth ? fmt::format(", ray depth {}", *scene->ray_depth) : "", seconds);
}

void SamplerService::Impl::on_region(const RegionAssignment& r) {
  if (r.sampler_id != sampler_id) {
    if (const uint64_t n = log.due("region for another sampler")) {
      spdlog::warn("region assignment for sampler {} reached sampler {} ({} such): ignored",
                   r.sampler_id, sampler_id, n);
    }
    return;
  }
  if (r.epoch < epoch) return;
  epoch = r.epoch;
  region = r;
  std::lock_guard<std::mutex> lock(counters_mutex);
  ++counters.regions;
}

// A display wall's layout: one sample route per display node, to the part of the image it
// needs (docs/wall.md). The lead display's own node has no endpoint: the session's sender.
void SamplerService::Impl::on_wall(const WallLayout& w, SampleSender& sender) {
  if (!joined || w.epoch < wall_epoch || w == wall) return;
  if (w.image != welcome.image) {
    if (const uint64_t n = log.due("wall layout of another image")) {
      spdlog::warn("wall layout {}x{} does not match the display's image {}x{} ({} such): ignored",
                   w.image.width, w.image.height, welcome.image.width, welcome.image.height, n);
    }
    return;
  }
  wall_epoch = w.epoch;
  wall = w;
  std::vector<SampleRoute> routes;
  std::map<std::string, std::unique_ptr<SampleSender>> kept;
  for (const WallNode& n : w.nodes) {
    SampleSender* to = &sender;
    if (!n.samples_endpoint.empty()) {
      auto it = wall_senders.find(n.samples_endpoint);
      if (it != wall_senders.end()) {
        kept[n.samples_endpoint] = std::move(it->second);
        wall_senders.erase(it);
      } else if (!kept.count(n.samples_endpoint)) {
        try {
          kept[n.samples_endpoint] = std::make_unique<SampleSender>(
              context, n.samples_endpoint, options.security, sample_channel(options));
        } catch (const Error& e) {
          spdlog::error("wall node {}: {}", n.node_id, e.what());
          continue;
        }
      }
      to = kept[n.samples_endpoint].get();
    }
    const bool whole = n.cell == w.image.rect();
    routes.push_back(SampleRoute{to, whole ? PixelRect{} : wall_receive_rect(w, n), 0});
  }
  sink.route(routes);  // no longer routes to the senders left in wall_senders
  wall_senders = std::move(kept);
  spdlog::info("wall layout {}: {} display node(s), margin {} px", w.epoch, w.nodes.size(),
               w.margin);
  std::lock_guard<std::mutex> lock(counters_mutex);
  ++counters.wall_layouts;
}

// Starts, replaces or keeps the pool so that it runs on the current region. Pools are built on
// a helper thread (the first of a scene builds its BVHs, `geometry`, which later pools of the
// scene share), so heartbeats go on meanwhile.
void SamplerService::Impl::update_pool() {
  if (building.valid()) {
    if (building.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return;
    std::unique_ptr<SamplerPool> built;
    try {
      BuiltPool b = building.get();
      built = std::move(b.pool);
      if (scene_hash == building_scene) geometry = std::move(b.geometry);
    } catch (const std::exception& e) {
      failure =
          fmt::format("cannot start sampling region [{}, {}) x [{}, {}): {}", building_region.x0,
                      building_region.x1, building_region.y0, building_region.y1, e.what());
      return;
    }
    // A pool built for a region that has been recut meanwhile (its sampler starved while the
    // BVHs of a large scene were built, say) is kept and handed over to the new region below,
    // as a running pool is, rather than built again; a new image or scene needs a new pool.
    if (joined && region && region->image == building_image && scene_hash == building_scene &&
        region->region.area() >= int64_t(built->regions().size())) {
      pool = std::move(built);
      pool_region = building_region;
      pool_image = building_image;
      pool_scene = building_scene;
      pool->set_camera_source(&view_camera);
      pool->start();
      spdlog::info("sampling region [{}, {}) x [{}, {}) with {} thread(s)", pool_region.x0,
                   pool_region.x1, pool_region.y0, pool_region.y1, pool->regions().size());
    }
  }
  if (!joined || !scene || scene_hash != welcome.scene_hash || loading.valid() || !region) return;
  if (pool && pool_region == region->region) return;
  // A recut within the same image and scene: the running pool moves to the new region and keeps
  // what its samplers hold of it (Sampler::set_region), instead of a new pool filling the whole
  // region at once.
  if (pool && pool_image == region->image && pool_scene == scene_hash &&
      region->region.area() >= int64_t(pool->regions().size())) {
    try {
      pool->set_region(region->region);
      spdlog::info("region [{}, {}) x [{}, {}) handed over to [{}, {}) x [{}, {})", pool_region.x0,
                   pool_region.x1, pool_region.y0, pool_region.y1, region->region.x0,
                   region->region.x1, region->region.y0, region->region.y1);
      pool_region = region->region;
      return;
    } catch (const Error& e) {
      spdlog::warn("region handover: {}; starting a new pool", e.what());
    }
  }
  stop_pool();

  SamplerConfig config = options.config;
  const std::string preset_name = options.preset.empty() ? welcome.presets : options.preset;
  if (!preset_name.empty()) {
    try {
      apply_preset(find_preset(preset_name), &config);
      options.overrides.apply(&config);
    } catch (const Error& e) {
      spdlog::warn("display's preset: {}; using the sampler's flags", e.what());
    }
  }
  config.image = ImageExtent{region->image.width, region->image.height};
  config.region = region->region;
  config.sampler_id = sampler_id;
  config.seed = options.config.seed + uint64_t(sampler_id) * 0x9e3779b97f4a7c15ULL;
  config.refresh_interval = welcome.refresh_interval;
  spdlog::info("sampler knobs: preset {}, b = {}, r = {}, chunk = {}, tiles {}..{}",
               preset_name.empty() ? "(none)" : preset_name, config.b, config.r, config.chunk,
               config.min_tiles, config.max_tiles);
  SamplerPoolOptions po;
  po.threads = int(std::min<int64_t>(options.threads, region->region.area()));
  po.max_samples_per_second = options.max_samples_per_second;
  po.worker_nice = options.worker_nice;
  po.worker_idle = options.worker_idle;
  building_region = region->region;
  building_image = region->image;
  building_scene = scene_hash;
  const Scene* s = scene.get();
  po.tracer.light_samples = options.light_samples;
  building = std::async(
      std::launch::async, [this, s, config, po, g = geometry, name = welcome.scene_name]() mutable {
        if (!g) {
          const double start = steady_seconds();
          g = std::make_shared<const Tracer>(
              std::shared_ptr<const Scene>(std::shared_ptr<void>(), s), po.tracer);
          spdlog::info("scene {}: BVHs built in {:.2f} s", name, steady_seconds() - start);
        }
        po.geometry = g.get();
        return BuiltPool{std::make_unique<SamplerPool>(*s, config, po, clock, sink), std::move(g)};
      });
}

void SamplerService::Impl::stop_pool() {
  if (building.valid()) abandoned_pools.push_back(std::move(building));
  if (!pool) return;
  pool->stop();
  const SamplerCounters c = pool->counters();
  retired.samples += c.samples;
  retired.crosshairs += c.crosshairs;
  retired.reprojections += c.reprojections;
  retired.reprojections_dropped += c.reprojections_dropped;
  retired.occlusion_rays += c.occlusion_rays;
  retired.sanitized += c.sanitized;
  retired.batches += c.batches;
  retired.snapshots += c.snapshots;
  pool.reset();
}

SamplerCounters SamplerService::Impl::pool_counters() const {
  SamplerCounters c = retired;
  if (pool) {
    const SamplerCounters p = pool->counters();
    c.samples += p.samples;
    c.crosshairs += p.crosshairs;
    c.reprojections += p.reprojections;
    c.reprojections_dropped += p.reprojections_dropped;
    c.occlusion_rays += p.occlusion_rays;
    c.sanitized += p.sanitized;
    c.batches += p.batches;
    c.snapshots += p.snapshots;
  }
  return c;
}

void SamplerService::Impl::send_stats(DisplayLink& control) {
  const double now = steady_seconds();
  const SamplerCounters c = pool_counters();
  const SampleSender::Counters net = sink.counters();
  if (last_stats_time > 0.0 && now > last_stats_time) {
    samples_per_second = double(c.samples - last_stats_samples) / (now - last_stats_time);
  }
  last_stats_samples = c.samples;
  last_stats_time = now;
  SamplerStats s;
  s.sampler_id = sampler_id;
  s.time = std::max(0.0, clock.now());
  s.samples = c.samples;
  s.batches = net.batches_sent;
  s.batches_dropped = net.batches_dropped;
  s.tilings = net.tilings_sent;
  s.bytes_sent = net.bytes_sent;
  s.crosshairs = c.crosshairs;
  s.reprojections = c.reprojections;
  s.reprojections_dropped = c.reprojections_dropped;
  s.occlusion_rays = c.occlusion_rays;
  s.sanitized = c.sanitized;
  s.samples_per_second = std::max(0.0, samples_per_second);
  s.rays_per_second = s.samples_per_second;
  s.tiles = 0;
  s.threads = uint16_t(pool ? pool->regions().size() : size_t(options.threads));
  (void)control.send(s);
}

}  // namespace afr::service
