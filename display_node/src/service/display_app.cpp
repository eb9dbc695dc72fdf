#include <afr/display/service/display_app.h>

#include <afr/common/camera_path.h>
#include <afr/common/error.h>
#include <afr/common/image.h>
#include <afr/display/backend.h>
#include <afr/display/coverage_map.h>
#include <afr/display/gl_reconstructor.h>
#include <afr/display/glfw_window.h>
#include <afr/display/service/fly_camera.h>
#include <afr/display/service/metrics.h>
#include <afr/display/service/metrics_exposition.h>
#include <afr/display/service/overlays.h>
#include <afr/display/service/snapshots.h>
#include <afr/display/service/wall.h>
#include <afr/display/service/wall_exchange.h>

#include <GLFW/glfw3.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>
#include <vector>

namespace afr::service {

namespace fs = std::filesystem;

void SwitchSink::set(SampleSink* target) {
  std::lock_guard<std::mutex> lock(mutex_);
  target_ = target;
}

void SwitchSink::on_batch(SampleBatch&& batch) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (target_) target_->on_batch(std::move(batch));
}

void SwitchSink::on_tiling(TilingSnapshot&& snapshot) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (target_) target_->on_tiling(std::move(snapshot));
}

void SwitchSink::on_sampler_gone(uint32_t sampler_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (target_) target_->on_sampler_gone(sampler_id);
}

ReconstructorConfig display_reconstructor_config(const Preset& preset, ReconstructionMode mode,
                                                 int width, int height, PixelRect cell, int margin,
                                                 size_t capacity) {
  ReconstructorConfig rc;
  rc.mode = mode;
  rc.image.width = width;
  rc.image.height = height;
  rc.viewport = cell;
  rc.viewport_margin = margin;
  rc.filter.min_spatial_extent = preset.reconstruction.min_spatial_extent;
  rc.filter.max_spatial_extent = preset.reconstruction.max_spatial_extent;
  rc.filter.max_temporal_extent = preset.reconstruction.max_temporal_extent;
  protocol::WallLayout shape;
  shape.image.width = width;
  shape.image.height = height;
  shape.margin = margin;
  protocol::WallNode self;
  self.cell = cell;
  const PixelRect received = protocol::wall_receive_rect(shape, self);
  rc.capacity = capacity > 0 ? capacity
                             : size_t(std::max(1.0, preset.reconstruction.samples_per_pixel *
                                                        double(received.area())));
  rc.capacity = std::min(rc.capacity, kMaxCapacity);
  return rc;
}

// display_memory_estimate's model: peak resident size of display_node --headless --backend cpu
// at 256x256 and 1024x1024 with 1, 4 and 8 samples a pixel stored (RSS = 133 MB + 132 B a slot
// + 119 B a pixel), rounded up.
constexpr uint64_t kMemoryFixed = uint64_t(160) << 20;
constexpr uint64_t kMemoryPerSample = 136;
constexpr uint64_t kMemoryPerPixel = 128;

uint64_t display_memory_estimate(const ReconstructorConfig& config) {
  const PixelRect& v = config.viewport.empty() ? config.image.rect() : config.viewport;
  const uint64_t m = uint64_t(std::max(0, config.viewport_margin));
  const uint64_t pixels = (uint64_t(v.width()) + 2 * m) * (uint64_t(v.height()) + 2 * m);
  return kMemoryFixed + kMemoryPerSample * uint64_t(config.capacity) + kMemoryPerPixel * pixels;
}

uint64_t default_memory_limit() {
  uint64_t available = 0;
  if (std::ifstream meminfo("/proc/meminfo"); meminfo) {
    std::string key, unit;
    uint64_t kb = 0;
    while (meminfo >> key >> kb >> unit) {
      if (key == "MemAvailable:") {
        available = kb * 1024;
        break;
      }
    }
  }
  if (available == 0) {
    available = uint64_t(sysconf(_SC_PHYS_PAGES)) * uint64_t(sysconf(_SC_PAGE_SIZE));
  }
  return available / 10 * 8;
}

void check_memory(const ReconstructorConfig& config, uint64_t limit) {
  const uint64_t need = display_memory_estimate(config);
  if (need <= limit) return;
  const auto gib = [](uint64_t b) { return double(b) / double(uint64_t(1) << 30); };
  throw Error(fmt::format(
      "--size {}x{}{} with N = {} stored samples needs about {:.1f} GiB ({} B a stored sample, "
      "{} B a pixel, {} MiB besides), more than the limit of {:.1f} GiB (--memory-limit; by "
      "default 80% of the memory available): use a smaller --size or --capacity, or a wall "
      "(--wall) to spread the image over display nodes",
      config.image.width, config.image.height,
      config.viewport == config.image.rect() || config.viewport.empty()
          ? std::string()
          : fmt::format(" (a cell of {}x{})", config.viewport.width(), config.viewport.height()),
      config.capacity, gib(need), kMemoryPerSample, kMemoryPerPixel, kMemoryFixed >> 20,
      gib(limit)));
}

// What the window's keyboard and mouse did since the last frame.
struct WindowInput {
  bool dragging = false;
  double drag_x = 0.0, drag_y = 0.0;
  int overlay = 0;                // 0 the image, 1 tiling, 2 gradients, 3 density
  bool hud = true;                // the heads-up text over the image (H toggles it)
  std::string stats;              // the latest stats line, for the HUD
  glm::vec3 gradient_full{0.0f};  // the gradient overlay's full-scale values
};

// `text` as lines of at most `width` characters, broken after ", " or at spaces where it can.
void wrap(const std::string& text, size_t width, std::vector<std::string>* lines) {
  std::string rest = text;
  while (rest.size() > width) {
    size_t cut = rest.rfind(", ", width - 1);
    if (cut != std::string::npos && cut > 0) {
      cut += 1;  // keep the comma
    } else {
      cut = rest.rfind(' ', width);
      if (cut == std::string::npos || cut == 0) cut = width;
    }
    lines->push_back(rest.substr(0, cut));
    rest = rest.substr(std::min(rest.size(), cut + (rest[cut] == ' ' ? 1 : 0)));
  }
  if (!rest.empty()) lines->push_back(rest);
}

// The HUD's lines, at most `width` characters each: the latest stats line cut at its
// separators, the overlay's legend, the keys.
std::vector<std::string> hud_lines(const WindowInput& input, const std::string& mode,
                                   size_t width) {
  std::vector<std::string> parts;
  std::string rest =
      input.stats.empty() ? std::string("waiting for the first stats period") : input.stats;
  for (size_t at; (at = rest.find(" | ")) != std::string::npos; rest = rest.substr(at + 3)) {
    parts.push_back(rest.substr(0, at));
  }
  parts.push_back(rest);
  switch (input.overlay) {
    case 1:
      parts.push_back("overlay 1: tiling (each sampler's region tinted, tiles outlined)");
      break;
    case 2:
      parts.push_back(fmt::format(
          "overlay 2: gradients, red |G_x| full at {:.3g}, green |G_y| at {:.3g}, blue |G_t| at "
          "{:.3g}",
          input.gradient_full.x, input.gradient_full.y, input.gradient_full.z));
      break;
    case 3:
      parts.push_back("overlay 3: sample density (filter weight, log scale, white = densest)");
      break;
    default:
      parts.push_back("reconstruction: " + mode);
  }
  parts.push_back(
      "keys: 0 image, 1 tiling, 2 gradients, 3 density, M mode, S screenshot, H HUD, Q quit");
  std::vector<std::string> lines;
  for (const std::string& part : parts) wrap(part, std::max<size_t>(width, 16), &lines);
  return lines;
}

struct DisplayApp::State {
  DisplayAppOptions options;
  DisplayRole& role;
  SwitchSink& ingest;
  FlyCamera* fly;
  std::shared_ptr<GlfwWindow> window;
  std::unique_ptr<Reconstructor> recon;
  GlReconstructor* gl = nullptr;  // recon, when it draws into the window
  std::unique_ptr<OverlaySink> tee;
  PixelRect cell;
  int out_w = 0, out_h = 0;
  bool whole = true;  // the cell is the whole image (no wall)
  protocol::Context links_context;
  std::unique_ptr<WallPeerLinks> links;
  WindowInput input;
  std::vector<CameraKey> recorded;
  Image image;
  std::set<uint32_t> dashboard_members;  // the members at the last stats period
  std::set<uint32_t> dashboard_scenes;   // members whose scene transfer the events told of
  uint64_t dashboard_recuts = 0, dashboard_deaths = 0;
  uint64_t frame = 0;
  double last_input = 0.0, last_stats = 0.0, next_stats = 0.0;

  State(DisplayAppOptions o, DisplayRole& r, SwitchSink& s, FlyCamera* f)
      : options(std::move(o)), role(r), ingest(s), fly(f) {}

  void make_reconstructor(const ReconstructorConfig& rc);
  // One image: the peers' coverage in, reconstruct (and show), the own coverage out.
  void frame_at(double now, std::atomic<bool>& stop);
  // The window's frame: the image (or an overlay) drawn and shown, then the input read.
  // Returns whether the image is the cell at its own size (the wall exchange's scale).
  // `want_image`: `image` should hold this frame's image at the cell's size (the dashboard);
  // *read_back says whether it does.
  bool show_in_window(const Camera& camera, double t, bool want_image, bool* read_back);
  void read_input(const Camera& camera, double t, std::atomic<bool>& stop);
  void save(const std::string& stem, double t);
  void report_stats(double t);
  // The stats period and what changed in the membership into the dashboard's history.
  void feed_dashboard(double t);
};

void DisplayApp::State::make_reconstructor(const ReconstructorConfig& rc) {
  cell = rc.viewport;
  out_w = cell.width();
  out_h = cell.height();
  whole = cell == rc.image.rect();
  if (!options.headless) {
    std::string error;
    window = GlfwWindow::create(out_w, out_h, "afr display", &error);
    if (window) {
      auto g = std::make_unique<GlReconstructor>(rc, window, options.gl.reconstructor);
      gl = g.get();
      recon = std::move(g);
    } else {
      spdlog::warn("no window ({}): running headless", error);
      options.headless = true;
    }
  }
  if (!recon) recon = afr::make_reconstructor(options.backend, rc, options.gl).reconstructor;
  tee = std::make_unique<OverlaySink>(*recon);
  ingest.set(tee.get());
  if (options.exchange) {
    links =
        std::make_unique<WallPeerLinks>(links_context, options.peer_security,
                                        role.lead_samples_endpoint(), splat_guard_band(rc.splat));
  }
}

DisplayApp::DisplayApp(DisplayAppOptions options, DisplayRole& role,
                       const ReconstructorConfig& config, SwitchSink& ingest, FlyCamera* fly)
    : state_(std::make_unique<State>(std::move(options), role, ingest, fly)) {
  State& s = *state_;
  s.make_reconstructor(config);
  s.role.metrics().set_display(s.role.session(), s.out_w, s.out_h, s.recon->backend_name(),
                               mode_name(s.recon->mode()));
  if (!s.whole) {
    spdlog::info("wall cell [{}, {}) x [{}, {}) of the {}x{} display, margin {} px, N = {}",
                 s.cell.x0, s.cell.x1, s.cell.y0, s.cell.y1, config.image.width,
                 config.image.height, config.viewport_margin, s.recon->capacity());
  }
  if (!s.options.output.empty()) fs::create_directories(s.options.output);
}

DisplayApp::~DisplayApp() { state_->ingest.set(nullptr); }

Reconstructor& DisplayApp::reconstructor() { return *state_->recon; }

int DisplayApp::run(std::atomic<bool>& stop) {
  State& s = *state_;
  const double period = 1.0 / s.options.fps;
  const double started = s.role.now();
  double next_frame = started;
  s.last_input = s.last_stats = started;
  s.next_stats = started + s.options.stats_interval;
  while (!stop.load()) {
    const double t = s.role.now();
    if (s.options.seconds > 0.0 && t - started >= s.options.seconds) break;
    if (s.window && s.window->should_close()) break;
    if (s.role.failed()) break;
    if (!s.window && t < next_frame) {  // headless: at the refresh rate; a window: at vsync
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(next_frame - t, 0.05)));
      continue;
    }
    next_frame += period;
    if (next_frame < t) next_frame = t + period;
    s.frame_at(t, stop);
  }

  const double t = s.role.now();
  s.recon->reconstruct(s.role.camera_at(t), t, s.out_w, s.out_h, &s.image);
  s.role.metrics().set_uptime(t);
  if (!s.options.output.empty()) s.save("final", t);
  if (!s.options.record.empty() && !s.recorded.empty()) {
    write_camera_path(CameraPath(std::move(s.recorded)), s.options.record);
    spdlog::info("recorded the camera path to {}", s.options.record);
  }
  spdlog::info("stopping: {}", stats_line(s.role.metrics()));
  return s.role.failed() ? 2 : 0;
}

void DisplayApp::State::frame_at(double now, std::atomic<bool>& stop) {
  // A snapshot whose moment has come (snapshots.h): this image is of that moment, a frame
  // period ago at most, with that moment's camera, and is written out.
  const std::optional<Snapshot> snapshot = role.snapshots().take_due(now);
  const double t = snapshot ? snapshot->time : now;
  const Camera camera = role.camera_at(t);
  if (!options.record.empty()) recorded.push_back(camera_key(t, camera));
  // Before the image: the current layout, and the peers' coverage into the reconstructor.
  uint64_t coverage_applied = 0;
  if (links) {
    if (const std::optional<WallPosition> w = role.wall_position()) {
      links->set_layout(w->layout, w->node_id);
    }
    coverage_applied = links->apply(role.wall_coverage(), *recon);
  }
  bool cell_sized = true;  // headless: the image is the cell at its own size
  ServiceMetrics& metrics = role.metrics();
  // A dashboard page watching: a few images a second leave the reconstructor for it.
  const bool dashboard = metrics.dashboard().wants_image();
  bool read_back = false;  // `image` holds this frame's image at the cell's size
  if (window) {
    cell_sized = show_in_window(camera, t, dashboard, &read_back);
    read_input(camera, t, stop);
  } else {
    // The image leaves the reconstructor (a GPU's memory) only when it is written out.
    const bool saving = options.screenshot_every > 0 && frame > 0 &&
                        frame % uint64_t(options.screenshot_every) == 0;
    read_back = saving || dashboard || snapshot.has_value();
    recon->reconstruct(camera, t, out_w, out_h, read_back ? &image : nullptr);
  }
  if (snapshot && !read_back) {  // a window of another size, or an overlay drawn
    recon->reconstruct(camera, t, out_w, out_h, &image);
    read_back = true;
  }
  if (dashboard) {
    // (A window larger than the cell drew another size: one more image, at the cell's.)
    if (!read_back) recon->reconstruct(camera, t, out_w, out_h, &image);
    // (A wall node's overlays would be in whole-image pixels: its cell alone.)
    metrics.dashboard().publish(
        image, whole ? tiling_overlay(image, tee->tilings(), role.regions()) : image);
  }
  if (links) links->send(*recon, camera, t, cell_sized, coverage_applied, metrics);
  const double done = role.now();
  metrics.on_frame(done, recon->frame_stats().milliseconds, recon->frame_stats().stored,
                   recon->capacity());
  metrics.set_gpu(recon->frame_stats().gpu);
  metrics.add_call(recon->frame_stats().call);
  metrics.set_image_counts(recon->frame_stats().hole_pixels, recon->frame_stats().empty_pixels);
  if (!window && options.screenshot_every > 0 && frame > 0 &&
      frame % uint64_t(options.screenshot_every) == 0) {
    save(fmt::format("frame_{:06d}", frame), t);
  }
  if (snapshot) {
    if (options.output.empty()) {
      spdlog::warn("snapshot {} of t={:.3f}s: no --output folder, nothing written", snapshot->id,
                   snapshot->time);
    } else {
      save(fmt::format("snapshot_{:06d}", snapshot->id), t);
      spdlog::info("snapshot {}: the image of t={:.3f}s, made at t={:.3f}s", snapshot->id,
                   snapshot->time, now);
    }
  }
  ++frame;
  if (done >= next_stats) report_stats(done);
}

bool DisplayApp::State::show_in_window(const Camera& camera, double t, bool want_image,
                                       bool* read_back) {
  bool cell_sized = false;
  if (input.overlay == 0 || !whole) {
    int fw = 0, fh = 0;
    window->framebuffer_size(&fw, &fh);
    cell_sized = fw == out_w && fh == out_h;
    *read_back = want_image && cell_sized;
    recon->reconstruct(camera, t, std::max(1, fw), std::max(1, fh), *read_back ? &image : nullptr);
    window->draw(*gl);
  } else {
    *read_back = true;
    // An overlay: the image read back at the sampling size, drawn over, scaled up.
    recon->reconstruct(camera, t, out_w, out_h, &image);
    const auto tilings = tee->tilings();
    if (input.overlay == 1) {
      window->draw_image(tiling_overlay(image, tilings, role.regions()));
    } else if (input.overlay == 2) {
      window->draw_image(gradient_overlay(tilings, out_w, out_h, &input.gradient_full));
    } else {
      std::vector<float> weights;
      recon->read_weights(&weights);
      window->draw_image(density_overlay(weights, out_w, out_h));
    }
  }
  if (input.hud) {
    // Font pixels twice the size in a window wide enough for it; lines wrapped to its width
    // (the font is 6 pixels a character, with 4 of margin on each side).
    int fw = 0, fh = 0;
    window->framebuffer_size(&fw, &fh);
    const int scale = fw >= 640 ? 2 : 1;
    window->draw_text(
        hud_lines(input, mode_name(recon->mode()), size_t(std::max(0, fw / scale - 8) / 6)), scale);
  }
  window->swap();
  window->poll_events();
  return cell_sized;
}

// Keys (taps, from the window's key events): M cycles the reconstruction mode, S writes a
// screenshot, H shows or hides the HUD, Q/Esc quits; 1, 2, 3 show the tiling (the paper's
// Figure 3), the gradients (Figure 4) and the sample density (Figure 7) over the image, 0 the
// image alone. With --interactive a left-button drag looks around, the arrows and Page Up/Down
// move (held, polled each frame).
void DisplayApp::State::read_input(const Camera& camera, double t, std::atomic<bool>& stop) {
  for (const int key : window->take_key_presses()) {
    if (key >= GLFW_KEY_0 && key <= GLFW_KEY_3) {
      input.overlay = key - GLFW_KEY_0;
    } else if (key == GLFW_KEY_M) {
      const ReconstructionMode next = ReconstructionMode((int(recon->mode()) + 1) % 3);
      recon->set_mode(next);
      spdlog::info("reconstruction mode: {}", mode_name(next));
    } else if (key == GLFW_KEY_S) {
      recon->reconstruct(camera, t, out_w, out_h, &image);
      save(fmt::format("screenshot_{:06d}", frame), t);
    } else if (key == GLFW_KEY_H) {
      input.hud = !input.hud;
    } else if (fly && (key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD)) {
      fly->zoom(1.0);
    } else if (fly && (key == GLFW_KEY_MINUS || key == GLFW_KEY_KP_SUBTRACT)) {
      fly->zoom(-1.0);
    } else if (key == GLFW_KEY_Q || key == GLFW_KEY_ESCAPE) {
      stop.store(true);
    }
  }
  GLFWwindow* w = glfwGetCurrentContext();
  if (!w) return;
  const auto pressed = [w](int key) { return glfwGetKey(w, key) == GLFW_PRESS; };
  if (fly) {
    double cx = 0.0, cy = 0.0;
    glfwGetCursorPos(w, &cx, &cy);
    const bool button = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    if (button && input.dragging) fly->look(cx - input.drag_x, cy - input.drag_y);
    input.dragging = button;
    input.drag_x = cx;
    input.drag_y = cy;
    const auto axis = [&](int plus, int minus) {
      return (pressed(plus) ? 1.0 : 0.0) - (pressed(minus) ? 1.0 : 0.0);
    };
    const glm::dvec3 move(axis(GLFW_KEY_RIGHT, GLFW_KEY_LEFT),
                          axis(GLFW_KEY_PAGE_UP, GLFW_KEY_PAGE_DOWN),
                          axis(GLFW_KEY_UP, GLFW_KEY_DOWN));
    fly->move(move, std::min(t - last_input, 0.1));
  }
  last_input = t;
}

void DisplayApp::State::save(const std::string& stem, double t) {
  if (whole) {
    write_images(*recon, image, *tee, role.regions(), fs::path(options.output) / stem);
    spdlog::info("wrote {}/{}.png (t={:.2f}s) with _tiling and _density overlays", options.output,
                 stem, t);
  } else {  // the overlays draw whole-image coordinates: the cell's image alone
    write_image(image, fs::path(options.output) / (stem + ".png"));
    write_image(image, fs::path(options.output) / (stem + ".exr"));
    spdlog::info("wrote {}/{}.png and .exr (t={:.2f}s)", options.output, stem, t);
  }
}

void DisplayApp::State::report_stats(double t) {
  ServiceMetrics& metrics = role.metrics();
  metrics.set_uptime(t);
  metrics.end_period(t - last_stats);
  last_stats = t;
  next_stats = t + options.stats_interval;
  input.stats = stats_line(metrics);
  feed_dashboard(t);
  spdlog::info("{}", input.stats);
  // The window's title and HUD: the same figures.
  if (window) window->set_title("afr display | " + input.stats);
}

void DisplayApp::State::feed_dashboard(double t) {
  ServiceMetrics& metrics = role.metrics();
  const DisplayMetrics d = metrics.display();
  DashboardPeriod p;
  p.time = t;
  p.refresh_hz = d.refresh_hz;
  p.reconstruct_ms_mean = d.period_reconstruct_ms_mean;
  p.reconstruct_ms_p99 = d.period_reconstruct_ms_p99;
  p.latency_ms_p50 = d.window_latency_p50 * 1e3;
  p.latency_ms_p99 = d.window_latency_p99 * 1e3;
  p.store_fill = d.store_capacity > 0 ? double(d.store_stored) / double(d.store_capacity) : 0.0;
  p.members = d.members;
  const double area = double(std::max<int64_t>(1, int64_t(d.width) * int64_t(d.height)));
  std::set<uint32_t> members;
  for (const SamplerMetrics& s : metrics.samplers()) {
    if (!s.member) continue;
    members.insert(s.id);
    p.samplers.push_back({s.id, s.samples_per_second, double(s.region.area()) / area});
    // A member that received the scene from the display (not from its cache): said once.
    if (s.scene_chunks > 0 && s.scene_chunks_sent >= s.scene_chunks &&
        dashboard_scenes.insert(s.id).second) {
      metrics.dashboard().add_event(
          t, fmt::format("sampler #{} received the scene ({} chunk(s))", s.id, s.scene_chunks));
    }
  }
  std::erase_if(dashboard_scenes, [&](uint32_t id) { return !members.count(id); });
  DashboardFeed& feed = metrics.dashboard();
  feed.add_period(p);
  for (const uint32_t id : members) {
    if (!dashboard_members.count(id)) feed.add_event(t, fmt::format("sampler #{} joined", id));
  }
  for (const uint32_t id : dashboard_members) {
    if (!members.count(id)) {
      feed.add_event(t, fmt::format("sampler #{} {}", id,
                                    d.deaths > dashboard_deaths ? "lost (no heartbeat)" : "left"));
    }
  }
  if (d.recuts > dashboard_recuts) {
    feed.add_event(
        t, fmt::format("regions recut (epoch {}, {} recut(s) in all)", d.region_epoch, d.recuts));
  }
  dashboard_members = std::move(members);
  dashboard_recuts = d.recuts;
  dashboard_deaths = d.deaths;
}

}  // namespace afr::service
