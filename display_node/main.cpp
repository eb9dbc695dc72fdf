// display_node: the display of the afr service. It binds the channels, coordinates the
// samplers that join, and reconstructs images from their samples at its refresh rate.
//   display_node --headless --size 256x256 --seconds 10 --output out     (built-in scene)
//   display_node kitchen.glb --bind tcp://0.0.0.0:7100 --keys keys/ --metrics-port 9100
//   display_node keygen keys/ --samplers 4     (CurveZMQ keys for a LAN; docs/service.md)
//   display_node --wall 2x2 --headless                        (lead of a wall: cell 0,0)
//   display_node --follow tcp://LEAD:7100 --cell 1,0 --bind tcp://127.0.0.1:7110 --headless
//                                                             (a follower; docs/wall.md)
#include <afr/common/builtin_scene.h>
#include <afr/common/camera_path.h>
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/display/backend.h>
#include <afr/display/gl_reconstructor.h>
#include <afr/display/glfw_window.h>
#include <afr/display/service/display_service.h>
#include <afr/display/service/fly_camera.h>
#include <afr/display/service/metrics_exposition.h>
#include <afr/display/service/overlays.h>
#include <afr/display/service/wall_follower.h>
#include <afr/protocol/keys.h>
#include <afr/protocol/messages.h>

#include <GLFW/glfw3.h>
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <mutex>
#include <thread>

namespace {

std::atomic<bool> g_stop{false};  // set by SIGINT / SIGTERM
extern "C" void on_signal(int) { g_stop.store(true); }

namespace fs = std::filesystem;
using afr::service::DisplayServiceOptions;

int keygen(const std::string& dir, int samplers) {
  fs::create_directories(dir);
  const afr::protocol::CurveKeyPair display = afr::protocol::generate_curve_keypair();
  afr::protocol::save_curve_keypair((fs::path(dir) / "display.key").string(), display);
  afr::protocol::save_curve_public_key((fs::path(dir) / "display.pub").string(),
                                       display.public_key);
  std::string allow = "# afr: sampler public keys the display admits (one per line)\n";
  // The display's own key: the follower displays of a wall use the display's key pair.
  allow += fmt::format("{} display (wall followers)\n", display.public_key);
  for (int i = 1; i <= samplers; ++i) {
    const afr::protocol::CurveKeyPair s = afr::protocol::generate_curve_keypair();
    const std::string name = fmt::format("sampler-{}", i);
    afr::protocol::save_curve_keypair((fs::path(dir) / (name + ".key")).string(), s);
    afr::protocol::save_curve_public_key((fs::path(dir) / (name + ".pub")).string(), s.public_key);
    allow += fmt::format("{} {}\n", s.public_key, name);
  }
  const fs::path allow_file = fs::path(dir) / "samplers.allow";
  FILE* f = std::fopen(allow_file.c_str(), "w");
  if (!f || std::fputs(allow.c_str(), f) < 0 || std::fclose(f) != 0) {
    throw afr::Error(fmt::format("{}: cannot write", allow_file.string()));
  }
  fmt::print(
      "wrote {0}/display.key, {0}/display.pub, {1} sampler key pair(s) and {0}/samplers.allow\n"
      "display: display_node --keys {0} ...   sampler i: sampler_node --key {0}/sampler-i.key "
      "--server-key {0}/display.pub ...\n",
      dir, samplers);
  return 0;
}

// The view camera at display time t: a replayed path (looping), or the scene's animation
// (looping over its keyframe range, as the samplers' tracers do).
std::function<afr::Camera(double)> camera_function(const afr::Scene& scene,
                                                   const afr::CameraPath* path) {
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

// The ingest side of a wall follower: samples arrive as soon as the lead admits the node, before
// the reconstructor (sized from the lead's layout) exists; until then they are dropped.
class SwitchSink final : public afr::SampleSink {
 public:
  void set(afr::SampleSink* target) {
    std::lock_guard<std::mutex> lock(mutex_);
    target_ = target;
  }
  void on_batch(afr::SampleBatch&& batch) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (target_) target_->on_batch(std::move(batch));
  }
  void on_tiling(afr::TilingSnapshot&& snapshot) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (target_) target_->on_tiling(std::move(snapshot));
  }

 private:
  std::mutex mutex_;
  afr::SampleSink* target_ = nullptr;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"display_node: the afr display: coordinates sampler nodes and reconstructs"};
  std::string scene_path, size_text = "256x256", backend_text = "auto", preset = "balanced",
                          mode_text = "adaptive", keys_dir, key_file, allow_file, record, replay,
                          output = "out", log_level = "info", wall_text = "1x1", cell_text = "0,0",
                          follow, advertise;
  DisplayServiceOptions o;
  bool headless = false, insecure = false, interactive = false;
  double fps = 30.0, seconds = 0.0, stats_interval = 2.0;
  int screenshot_every = 0, margin = -1;
  size_t capacity = 0;
  double lead_timeout = 1.5;
  bool no_exchange = false;
  app.add_option("scene", scene_path,
                 "glTF scene (.glb, or .gltf with embedded buffers); "
                 "the built-in scene if omitted")
      ->check(CLI::ExistingFile);
  app.add_option("--bind", o.bind, "base endpoint tcp://HOST:PORT (uses PORT..PORT+2)")
      ->capture_default_str();
  app.add_option("-s,--size", size_text, "image size WxH (a wall's whole virtual display)")
      ->capture_default_str();
  app.add_flag("--headless", headless, "no window: reconstruct at --fps and write images");
  app.add_option("--backend", backend_text, "reconstruction backend gl, cpu or auto")
      ->capture_default_str();
  app.add_option("--preset", preset, "fast, balanced or accurate (samplers follow it)")
      ->capture_default_str();
  app.add_option("--mode", mode_text, "adaptive, frameless or adaptive-no-reprojection")
      ->capture_default_str();
  app.add_option("--fps", fps, "refresh rate: views, tiling snapshots and (headless) images")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 1000.0));
  app.add_option("--metrics-port", o.metrics_port, "HTTP port of /metrics and /stats (0 = off)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--metrics-address", o.metrics_address, "address the metrics server binds")
      ->capture_default_str();
  app.add_option("--keys", keys_dir, "folder with display.key and samplers.allow (CurveZMQ)");
  app.add_option("--key", key_file, "the display's CurveZMQ key pair file");
  app.add_option("--allow", allow_file, "allow-list of sampler public keys");
  app.add_flag("--insecure", insecure, "allow a non-loopback bind without CurveZMQ");
  app.add_option("--record", record, "write the views' camera path to this file at exit");
  app.add_option("--replay", replay, "views follow this camera path (looping)")
      ->check(CLI::ExistingFile);
  app.add_flag("--interactive", interactive,
               "steer the camera in the window: drag with the left mouse button to look, "
               "arrow keys to move, Page Up/Down to rise and sink (record it with --record)");
  app.add_option("--screenshot-every", screenshot_every,
                 "write an image every K frames to --output (0 = only at exit)")
      ->check(CLI::Range(0, 1000000000));
  app.add_option("-o,--output", output, "folder for images")->capture_default_str();
  app.add_option("--seconds", seconds, "stop after this many seconds (0 = run until a signal)")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--stats-interval", stats_interval, "seconds between stats log lines")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  app.add_option("--member-timeout", o.coordinator.liveness.floor,
                 "seconds of silence before a sampler or wall node may be declared dead; the "
                 "failure detector waits longer when its messages came irregularly, up to "
                 "--member-timeout-max")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 600.0));
  app.add_option("--member-timeout-max", o.coordinator.liveness.ceiling,
                 "seconds of silence after which a sampler or wall node is always dead (raised "
                 "to --member-timeout when below it)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 600.0));
  app.add_option(
         "--wall", wall_text,
         "display wall: COLUMNSxROWS cells over --size, this display leading (docs/wall.md)")
      ->capture_default_str();
  app.add_option("--cell", cell_text, "this display's cell COLUMN,ROW of the wall")
      ->capture_default_str();
  app.add_option("--margin", margin,
                 "pixels of samples each wall node receives around its cell "
                 "(-1: what the reconstructor's splats reach)")
      ->capture_default_str()
      ->check(CLI::Range(-1, int(afr::protocol::kMaxWallMargin)));
  app.add_option("--follow", follow,
                 "follow the lead display at tcp://HOST:PORT as one cell of its wall; --bind "
                 "then gives this node's endpoints (samples on PORT+2)");
  app.add_option("--lead-timeout", lead_timeout,
                 "follower: seconds without a word from the lead before joining it again")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 600.0));
  app.add_flag("--no-exchange", no_exchange,
               "wall: do not exchange coverage and strays with the other display nodes (they "
               "then drift apart from a single display's image; docs/wall.md, \"Seams\")");
  app.add_option("--advertise", advertise,
                 "follower: the sample endpoint samplers should use (default: the bound one)");
  app.add_option("--capacity", capacity,
                 "samples the reconstructor keeps (0: the preset's samples per pixel x the "
                 "pixels this node receives samples for)")
      ->capture_default_str()
      ->check(CLI::Range(size_t(0), afr::kMaxCapacity));
  app.add_option("--log", log_level, "log level")->capture_default_str();
  std::string keygen_dir;
  int keygen_samplers = 1;
  CLI::App* kg = app.add_subcommand("keygen", "write CurveZMQ keys for a display and samplers");
  kg->add_option("dir", keygen_dir, "folder to write the keys to")->required();
  kg->add_option("--samplers", keygen_samplers, "sampler key pairs to make")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    if (*kg) return keygen(keygen_dir, keygen_samplers);

    // Before anything waits (a follower waits for the lead), so a stop is always clean.
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::signal(SIGPIPE, SIG_IGN);
    const bool follower = !follow.empty();
    const afr::ImageSize size = afr::parse_image_size(size_text);
    o.width = size.width;
    o.height = size.height;
    o.refresh_interval = 1.0 / fps;
    o.coordinator.liveness.ceiling =
        std::max(o.coordinator.liveness.ceiling, o.coordinator.liveness.floor);  // as documented
    o.preset = preset;
    const afr::Preset* p = &afr::find_preset(preset);
    const afr::Backend backend = afr::parse_backend(backend_text);
    o.wall = afr::service::parse_wall_grid(wall_text);
    afr::service::parse_wall_cell(cell_text, &o.wall_column, &o.wall_row);
    if (follower && (wall_text != "1x1" || margin != -1 || !scene_path.empty())) {
      throw afr::Error(
          "--follow: the wall's grid, margin and scene are the lead's; give only --cell");
    }

    // Security: loopback may go plain; anything else needs CurveZMQ or --insecure.
    const afr::protocol::ServiceEndpoints ep = afr::protocol::service_endpoints(o.bind);
    if (!keys_dir.empty()) {
      if (key_file.empty()) key_file = (fs::path(keys_dir) / "display.key").string();
      if (allow_file.empty()) allow_file = (fs::path(keys_dir) / "samplers.allow").string();
    }
    if (key_file.empty() != allow_file.empty()) {
      throw afr::Error(
          "CurveZMQ needs both the display's key pair (--key) and the samplers' "
          "allow-list (--allow), or --keys DIR with both");
    }
    if (!key_file.empty()) {
      o.keys = afr::protocol::load_curve_keypair(key_file);
      o.allowed_keys = afr::protocol::load_allowed_keys(allow_file);
      spdlog::info("CurveZMQ on: display key {}, {} sampler key(s) allowed from {}",
                   o.keys.public_key, o.allowed_keys.size(), allow_file);
    } else if (!afr::protocol::is_local_endpoint(ep.control)) {
      if (!insecure) {
        throw afr::Error(fmt::format(
            "--bind {} is reachable from other machines: give CurveZMQ keys (--keys DIR, made "
            "by `display_node keygen DIR --samplers N`) or pass --insecure",
            o.bind));
      }
      spdlog::warn("--insecure: {} accepts any sampler, unencrypted", o.bind);
    }

    afr::ReconstructorConfig rc;
    rc.mode = afr::parse_mode(mode_text);
    // The wall's margin is what the reconstructor's splats reach unless told otherwise; the
    // lead sends it to every node in the layout.
    o.wall.margin = margin >= 0 ? margin : afr::auto_viewport_margin(rc.splat);

    // The role: the lead (or only) display, with its scene and coordinator; or a follower of a
    // lead, which learns the virtual display, its cell and the camera from the lead.
    std::unique_ptr<afr::Scene> scene;
    std::unique_ptr<afr::CameraPath> path;
    SwitchSink switch_sink;
    std::unique_ptr<afr::service::DisplayService> service;
    std::unique_ptr<afr::service::WallFollower> wall_follower;
    std::unique_ptr<afr::service::FlyCamera> fly;  // --interactive
    afr::PixelRect cell;
    if (follower) {
      afr::service::WallFollowerOptions fo;
      fo.lead = follow;
      fo.bind = ep.samples;
      fo.advertise = advertise;
      fo.column = o.wall_column;
      fo.row = o.wall_row;
      fo.keys = o.keys;
      fo.allowed_keys = o.allowed_keys;
      fo.metrics_address = o.metrics_address;
      fo.metrics_port = o.metrics_port;
      fo.lead_timeout = lead_timeout;
      wall_follower = std::make_unique<afr::service::WallFollower>(fo, switch_sink);
      wall_follower->start();
      double next_note = 5.0;
      const auto waiting = std::chrono::steady_clock::now();
      // The layout that names this node gives the virtual display and the cell.
      while (!g_stop.load() && !wall_follower->failed()) {
        if (wall_follower->layout() && !wall_follower->cell().empty() && wall_follower->camera()) {
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        const double waited =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - waiting).count();
        if (waited > next_note) {
          spdlog::info("waiting for the lead display {} to admit cell {},{} ({:.0f} s)", follow,
                       o.wall_column, o.wall_row, waited);
          next_note += 5.0;
        }
      }
      if (wall_follower->failed()) return 2;
      if (g_stop.load()) return 0;
      const afr::protocol::WallLayout layout = *wall_follower->layout();
      o.width = layout.width;
      o.height = layout.height;
      cell = wall_follower->cell();
      rc.viewport_margin = layout.margin;
      // The lead's preset, unless this node was given one.
      if (app.count("--preset") == 0 && !wall_follower->preset().empty()) {
        p = &afr::find_preset(wall_follower->preset());
      }
    } else {
      scene = std::make_unique<afr::Scene>(afr::load_scene(scene_path));
      o.scene = afr::service::read_scene_payload(scene_path);
      if (!replay.empty()) {
        path = std::make_unique<afr::CameraPath>(afr::read_camera_path(replay));
        spdlog::warn(
            "--replay {}: the display reprojects with the path's camera; samplers "
            "trace the scene's own camera (docs/service.md, \"Camera paths\")",
            replay);
      }
      o.camera_at = camera_function(*scene, path.get());
      if (interactive) {
        if (headless) throw afr::Error("--interactive needs a window (drop --headless)");
        // From where the animation (or path) starts, a tenth of the scene's size per second.
        glm::dvec3 lo, hi;
        scene->bounds(scene->evaluate(0.0), &lo, &hi);
        const double size = glm::length(hi - lo);
        fly = std::make_unique<afr::service::FlyCamera>(
            o.camera_at(0.0), std::isfinite(size) && size > 0.0 ? 0.1 * size : 1.0);
        o.camera_at = [f = fly.get()](double) { return f->camera(); };
      }
      spdlog::info("scene {}: {} triangles, {:.2f} s of animation, {} bytes to serve", o.scene.name,
                   scene->triangle_count(), scene->duration(), o.scene.bytes.size());
      service = std::make_unique<afr::service::DisplayService>(o, switch_sink);
      cell = service->cell();
      rc.viewport_margin = o.wall.margin;
    }
    rc.image_width = o.width;
    rc.image_height = o.height;
    rc.viewport = cell;
    rc.filter.min_spatial_extent = p->reconstruction.min_spatial_extent;
    rc.filter.max_spatial_extent = p->reconstruction.max_spatial_extent;
    rc.filter.max_temporal_extent = p->reconstruction.max_temporal_extent;
    // N: the preset's samples per pixel of the pixels this node receives samples for.
    // (The samplers' routing rule: this node's cell grown by the margin, clipped to the image.)
    afr::protocol::WallLayout shape;
    shape.width = o.width;
    shape.height = o.height;
    shape.margin = rc.viewport_margin;
    afr::protocol::WallNode self;
    self.cell = cell;
    const afr::PixelRect received = afr::protocol::wall_receive_rect(shape, self);
    rc.capacity =
        capacity > 0
            ? capacity
            : size_t(std::max(1.0, p->reconstruction.samples_per_pixel * double(received.area())));
    rc.capacity = std::min(rc.capacity, afr::kMaxCapacity);
    const int out_w = cell.width(), out_h = cell.height();
    const bool whole = cell == afr::PixelRect{0, 0, o.width, o.height};

    // Window (GL in the window's context) or headless (make_reconstructor picks).
    std::shared_ptr<afr::GlfwWindow> window;
    std::unique_ptr<afr::Reconstructor> recon;
    afr::GlReconstructor* gl = nullptr;
    if (!headless) {
      std::string error;
      window = afr::GlfwWindow::create(out_w, out_h, "afr display", &error);
      if (window) {
        auto g = std::make_unique<afr::GlReconstructor>(rc, window);
        gl = g.get();
        recon = std::move(g);
      } else {
        spdlog::warn("no window ({}): running headless", error);
        headless = true;
      }
    }
    if (!recon) recon = afr::make_reconstructor(backend, rc).reconstructor;

    afr::service::OverlaySink tee(*recon);
    switch_sink.set(&tee);
    afr::service::ServiceMetrics& metrics = service ? service->metrics() : wall_follower->metrics();
    const auto now = [&] { return service ? service->now() : wall_follower->now(); };
    // The camera of the image at display time t: the lead's own; a follower's, the lead's
    // latest view.
    const auto camera_at = [&](double t) {
      return service ? o.camera_at(t) : *wall_follower->camera();
    };
    const auto regions = [&] {
      return service ? service->regions() : std::vector<std::pair<uint32_t, afr::PixelRect>>{};
    };
    metrics.set_display(service ? service->session() : 0, out_w, out_h, recon->backend_name(),
                        afr::mode_name(recon->mode()));
    if (!whole) {
      spdlog::info("wall cell [{}, {}) x [{}, {}) of the {}x{} display, margin {} px, N = {}",
                   cell.x0, cell.x1, cell.y0, cell.y1, o.width, o.height, rc.viewport_margin,
                   recon->capacity());
    }
    if (service) service->start();
    if (!output.empty()) fs::create_directories(output);

    // A wall's nodes exchange coverage and strays after every image (docs/wall.md, "Seams"):
    // as clients of each other's sample channels, with the display key pair they share.
    afr::protocol::Context links_context;
    std::unique_ptr<afr::service::WallPeerLinks> links;
    if (!no_exchange && (wall_follower || o.wall.is_wall())) {
      const afr::protocol::Security client =
          o.keys.secret_key.empty() ? afr::protocol::Security::none()
                                    : afr::protocol::Security::client(o.keys, o.keys.public_key);
      links = std::make_unique<afr::service::WallPeerLinks>(
          links_context, client, wall_follower ? wall_follower->lead_samples_endpoint() : "",
          afr::splat_guard_band(rc.splat));
    }
    afr::service::WallCoverageInbox& wall_inbox =
        service ? service->wall_coverage() : wall_follower->wall_coverage();
    // Before an image: the current layout, and the peers' coverage into the reconstructor.
    const auto exchange_before = [&]() -> uint64_t {
      if (!links) return 0;
      if (service) {
        links->set_layout(service->wall_layout(), 1);
      } else if (const auto layout = wall_follower->layout()) {
        links->set_layout(*layout, wall_follower->node_id());
      }
      return links->apply(wall_inbox, *recon);
    };

    std::vector<afr::CameraKey> recorded;
    afr::Image image;
    uint64_t frame = 0;
    double next_frame = now(), next_stats = now() + stats_interval, last_stats = now();
    const double started = now();
    bool key_down[3] = {false, false, false};
    bool dragging = false;
    int overlay = 0;  // window: 0 the image, 1 tiling, 2 gradients, 3 density
    double drag_x = 0.0, drag_y = 0.0, last_input = now();
    auto save = [&](const std::string& stem, double t) {
      if (whole) {
        afr::service::write_images(*recon, image, tee, regions(), fs::path(output) / stem);
        spdlog::info("wrote {}/{}.png (t={:.2f}s) with _tiling and _density overlays", output, stem,
                     t);
      } else {  // the overlays draw whole-image coordinates: the cell's image alone
        afr::write_image(image, fs::path(output) / (stem + ".png"));
        afr::write_image(image, fs::path(output) / (stem + ".exr"));
        spdlog::info("wrote {}/{}.png and .exr (t={:.2f}s)", output, stem, t);
      }
    };
    while (!g_stop.load()) {
      const double t = now();
      if (seconds > 0.0 && t - started >= seconds) break;
      if (window && window->should_close()) break;
      if (wall_follower && wall_follower->failed()) break;
      if (headless && t < next_frame) {
        std::this_thread::sleep_for(std::chrono::duration<double>(std::min(next_frame - t, 0.05)));
        continue;
      }
      next_frame += 1.0 / fps;
      if (next_frame < t) next_frame = t + 1.0 / fps;
      const afr::Camera camera = camera_at(t);
      if (!record.empty()) recorded.push_back(afr::camera_key(t, camera));
      const uint64_t coverage_applied = exchange_before();
      bool cell_sized = !window;  // the image is the cell at its own size
      const bool write =
          headless && screenshot_every > 0 && frame > 0 && frame % uint64_t(screenshot_every) == 0;
      if (window) {
        int fw = 0, fh = 0;
        window->framebuffer_size(&fw, &fh);
        if (overlay == 0 || !whole) {
          recon->reconstruct(camera, t, std::max(1, fw), std::max(1, fh), nullptr);
          cell_sized = fw == out_w && fh == out_h;
          window->draw(*gl);
        } else {
          // An overlay: the image read back at the sampling size, drawn over, scaled up.
          recon->reconstruct(camera, t, out_w, out_h, &image);
          const auto tilings = tee.tilings();
          if (overlay == 1) {
            window->draw_image(afr::service::tiling_overlay(image, tilings, regions()));
          } else if (overlay == 2) {
            window->draw_image(afr::service::gradient_overlay(tilings, out_w, out_h));
          } else {
            std::vector<float> weights;
            recon->read_weights(&weights);
            window->draw_image(afr::service::density_overlay(weights, out_w, out_h));
          }
        }
        window->swap();
        window->poll_events();
        // Keys: M cycles the reconstruction mode, S writes a screenshot, Q/Esc quits; 1, 2, 3
        // show the tiling (the paper's Figure 3), the gradients (Figure 4) and the sample
        // density (Figure 7) over the image, 0 the image alone.
        GLFWwindow* w = glfwGetCurrentContext();
        for (int k = 0; k < 4 && w; ++k) {
          if (glfwGetKey(w, GLFW_KEY_0 + k) == GLFW_PRESS) overlay = k;
        }
        if (fly && w) {
          // --interactive: a left-button drag looks around, arrows and Page Up/Down move.
          double cx = 0.0, cy = 0.0;
          glfwGetCursorPos(w, &cx, &cy);
          if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS && dragging) {
            fly->look(cx - drag_x, cy - drag_y);
          }
          dragging = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
          drag_x = cx;
          drag_y = cy;
          const auto key = [&](int k) { return glfwGetKey(w, k) == GLFW_PRESS ? 1.0 : 0.0; };
          const glm::dvec3 move(key(GLFW_KEY_RIGHT) - key(GLFW_KEY_LEFT),
                                key(GLFW_KEY_PAGE_UP) - key(GLFW_KEY_PAGE_DOWN),
                                key(GLFW_KEY_UP) - key(GLFW_KEY_DOWN));
          fly->move(move, std::min(t - last_input, 0.1));
        }
        last_input = t;
        const int keys[3] = {GLFW_KEY_M, GLFW_KEY_S, GLFW_KEY_Q};
        for (int k = 0; k < 3 && w; ++k) {
          const bool down = glfwGetKey(w, keys[k]) == GLFW_PRESS;
          if (down && !key_down[k]) {
            if (k == 0) {
              const afr::ReconstructionMode next =
                  afr::ReconstructionMode((int(recon->mode()) + 1) % 3);
              recon->set_mode(next);
              spdlog::info("reconstruction mode: {}", afr::mode_name(next));
            } else if (k == 1) {
              recon->reconstruct(camera, t, out_w, out_h, &image);
              save(fmt::format("screenshot_{:06d}", frame), t);
            } else {
              g_stop.store(true);
            }
          }
          key_down[k] = down;
        }
        if (w && glfwGetKey(w, GLFW_KEY_ESCAPE) == GLFW_PRESS) g_stop.store(true);
      } else {
        recon->reconstruct(camera, t, out_w, out_h, &image);
      }
      if (links) links->send(*recon, camera, t, cell_sized, coverage_applied, metrics);
      const double done = now();
      metrics.on_frame(done, recon->frame_stats().milliseconds, recon->frame_stats().stored,
                       recon->capacity());
      if (write) save(fmt::format("frame_{:06d}", frame), t);
      ++frame;
      if (done >= next_stats) {
        metrics.set_uptime(done);
        metrics.end_period(done - last_stats);
        last_stats = done;
        next_stats = done + stats_interval;
        spdlog::info("{}", afr::service::stats_line(metrics));
        // The window's heads-up line: the same figures in its title.
        if (window) window->set_title("afr display | " + afr::service::stats_line(metrics));
      }
    }

    const double t = now();
    recon->reconstruct(camera_at(t), t, out_w, out_h, &image);
    metrics.set_uptime(t);
    if (!output.empty()) save("final", t);
    if (!record.empty() && !recorded.empty()) {
      afr::write_camera_path(afr::CameraPath(std::move(recorded)), record);
      spdlog::info("recorded the camera path to {}", record);
    }
    spdlog::info("stopping: {}", afr::service::stats_line(metrics));
    if (service) service->stop();
    if (wall_follower) wall_follower->stop();
    switch_sink.set(nullptr);
    return wall_follower && wall_follower->failed() ? 2 : 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
