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
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/display/backend.h>
#include <afr/display/service/display_app.h>
#include <afr/display/service/display_service.h>
#include <afr/display/service/fly_camera.h>
#include <afr/display/service/wall_follower.h>
#include <afr/protocol/keys.h>
#include <afr/protocol/messages.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <filesystem>
#include <optional>

namespace {

std::atomic<bool> g_stop{false};  // set by SIGINT / SIGTERM
extern "C" void on_signal(int) { g_stop.store(true); }

namespace fs = std::filesystem;
using afr::service::DisplayServiceOptions;

int keygen(const std::string& dir, int samplers) {
  afr::protocol::write_key_folder(dir, samplers);
  fmt::print(
      "wrote {0}/display.key, {0}/display.pub, {1} sampler key pair(s) and {0}/samplers.allow\n"
      "display: display_node --keys {0} ...   sampler i: sampler_node --key {0}/sampler-i.key "
      "--server-key {0}/display.pub ...\n",
      dir, samplers);
  return 0;
}

// The metrics server's port must not be one of the three the service binds: its bind would
// fail with no better reason than "port in use", the service's own use.
void check_metrics_port(const std::string& bind, int metrics_port) {
  if (metrics_port <= 0 || bind.rfind("tcp://", 0) != 0) return;
  const std::string samples = afr::protocol::service_endpoints(bind).samples;
  const int last = std::stoi(samples.substr(samples.rfind(':') + 1));
  if (metrics_port >= last - 2 && metrics_port <= last) {
    throw afr::Error(fmt::format(
        "--metrics-port {} is one of the ports --bind {} takes ({} to {}): choose another",
        metrics_port, bind, last - 2, last));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"display_node: the afr display: coordinates sampler nodes and reconstructs"};
  std::string gl_splat_text = "auto";
  int gpu = -1;
  std::string scene_path, size_text = "256x256", backend_text = "auto", preset = "balanced",
                          mode_text = "adaptive", keys_dir, key_file, allow_file, record, replay,
                          output = "out", log_level = "info", wall_text = "1x1", cell_text = "0,0",
                          follow, advertise, variant, camera;
  DisplayServiceOptions o;
  bool headless = false, insecure = false, interactive = false;
  double fps = 30.0, seconds = 0.0, stats_interval = 2.0;
  int screenshot_every = 0, margin = -1;
  size_t capacity = 0;
  uint64_t memory_limit = 0;
  double lead_timeout = 1.5;
  bool no_exchange = false;
  app.add_option("scene", scene_path,
                 "glTF scene (.glb or .gltf; the files a .gltf names are packed with it "
                 "for the samplers); the built-in scene if omitted")
      ->check(CLI::ExistingFile);
  app.add_option("--variant", variant,
                 "KHR_materials_variants: serve and show the scene with this material variant");
  app.add_option("--camera", camera,
                 "the scene's camera to view from: a camera's or its node's name, or an index "
                 "into the glTF's cameras (default: the first camera node of the scene)");
  std::optional<int> ray_depth;
  afr::add_ray_depth_option(app, &ray_depth,
                            "for the samplers: written into the scene they are served");
  app.add_option("--bind", o.bind, "base endpoint tcp://HOST:PORT (uses PORT..PORT+2)")
      ->capture_default_str();
  app.add_option("-s,--size", size_text,
                 "image size WxH (a wall's whole virtual display); without it a single display "
                 "takes the scene camera's aspect ratio, where the file gives one, at as many "
                 "pixels")
      ->capture_default_str();
  app.add_flag("--headless", headless, "no window: reconstruct at --fps and write images");
  app.add_option("--gpu", gpu, "EGL device for a headless GL backend (-1: hardware first)")
      ->check(CLI::Range(-1, 63));
  app.add_option("--gl-splat", gl_splat_text,
                 "GL splat pass: gather (compute), raster (points) or auto (gather on a GPU)")
      ->check(CLI::IsMember({"auto", "gather", "raster"}))
      ->capture_default_str();
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
               "arrow keys to move, Page Up/Down to rise and sink, + and - to zoom (record it with "
               "--record)");
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
  app.add_option("--recut-interval", o.coordinator.recut_interval,
                 "seconds at least between recuts of the samplers' regions that follow their "
                 "throughput and error (leaves and deaths recut at once, joins after "
                 "--join-interval)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  app.add_option("--join-interval", o.coordinator.join_interval,
                 "seconds at least between recuts that joins make: a join waits for its region "
                 "until then, and the joins meanwhile are cut in together")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--max-samplers", o.coordinator.max_members,
                 "samplers admitted at once; a join beyond them is refused with the reason")
      ->capture_default_str()
      ->check(CLI::Range(1u, afr::protocol::kMaxMembers));
  app.add_option("--recut-hysteresis", o.coordinator.hysteresis,
                 "recut when a sampler's part of the image's error exceeds (1 + this) times its "
                 "share of the throughput")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--recut-min-gain", o.coordinator.min_gain,
                 "recut only when the new cut lowers the largest such ratio by this fraction")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
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
  app.add_option("--memory-limit", memory_limit,
                 "the most memory the reconstructor may plan for, e.g. 8G (0: 80% of the memory "
                 "available at start); a --size and --capacity that need more are refused before "
                 "anything is allocated")
      ->transform(CLI::AsSizeValue(false));
  app.add_option("--log", log_level, "log level")->capture_default_str();
  std::string keygen_dir;
  int keygen_samplers = 1;
  CLI::App* kg = app.add_subcommand("keygen", "write CurveZMQ keys for a display and samplers");
  kg->add_option("dir", keygen_dir, "folder to write the keys to")->required();
  kg->add_option("--samplers", keygen_samplers, "sampler key pairs to make")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    if (*kg) return keygen(keygen_dir, keygen_samplers);

    // Before anything waits (a follower waits for the lead), so a stop is always clean.
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::signal(SIGPIPE, SIG_IGN);
    const bool follower = !follow.empty();
    const afr::ImageExtent size = afr::parse_image_size(size_text);
    if (wall_text == "1x1" && !follower &&
        (size.width > afr::kMaxOutputSide || size.height > afr::kMaxOutputSide)) {
      throw afr::Error(fmt::format(
          "--size {}x{}: one display node reconstructs at most {} pixels a side; a larger "
          "image (up to {} a side) needs a wall (--wall COLUMNSxROWS) whose cells are within it",
          size.width, size.height, afr::kMaxOutputSide, afr::kMaxImageDimension));
    }
    check_metrics_port(o.bind, o.metrics_port);
    o.image = size;
    o.refresh_interval = 1.0 / fps;
    o.coordinator.liveness.ceiling =
        std::max(o.coordinator.liveness.ceiling, o.coordinator.liveness.floor);  // as documented
    o.preset = preset;
    const afr::Preset* p = &afr::find_preset(preset);
    const afr::ReconstructionMode mode = afr::parse_mode(mode_text);
    o.wall = afr::service::parse_wall_grid(wall_text);
    afr::service::parse_wall_cell(cell_text, &o.wall_column, &o.wall_row);
    // The wall's margin is what the reconstructor's splats reach unless told otherwise; the
    // lead sends it to every node in the layout.
    o.wall.margin =
        margin >= 0 ? margin : afr::auto_viewport_margin(afr::ReconstructorConfig{}.splat);
    if (follower && (wall_text != "1x1" || margin != -1 || !scene_path.empty() ||
                     !variant.empty() || !camera.empty() || ray_depth)) {
      throw afr::Error(
          "--follow: the wall's grid, margin and scene are the lead's; give only --cell");
    }
    afr::service::configure_security(keys_dir, key_file, allow_file, insecure, &o);

    // The role: the lead (or only) display, with its scene and coordinator; or a follower of a
    // lead, which learns the virtual display, its cell and the camera from the lead.
    afr::service::SwitchSink ingest;
    std::unique_ptr<afr::Scene> scene;
    std::unique_ptr<afr::CameraPath> path;
    std::unique_ptr<afr::service::FlyCamera> fly;  // --interactive
    std::unique_ptr<afr::service::DisplayService> service;
    std::unique_ptr<afr::service::WallFollower> wall_follower;
    afr::service::DisplayRole* role = nullptr;
    if (follower) {
      afr::service::WallFollowerOptions fo;
      fo.lead = follow;
      fo.bind = afr::protocol::service_endpoints(o.bind).samples;
      fo.advertise = advertise;
      fo.column = o.wall_column;
      fo.row = o.wall_row;
      fo.keys = o.keys;
      fo.allowed_keys = o.allowed_keys;
      fo.metrics_address = o.metrics_address;
      fo.metrics_port = o.metrics_port;
      fo.lead_timeout = lead_timeout;
      wall_follower = std::make_unique<afr::service::WallFollower>(fo, ingest);
      wall_follower->start();
      // The layout that names this node gives the virtual display and the cell.
      if (!wall_follower->wait_until_admitted(g_stop)) return wall_follower->failed() ? 2 : 0;
      const afr::protocol::WallLayout layout = *wall_follower->layout();
      o.image = layout.image;
      o.wall.margin = layout.margin;
      // The lead's preset, unless this node was given one.
      if (app.count("--preset") == 0 && !wall_follower->preset().empty()) {
        p = &afr::find_preset(wall_follower->preset());
      }
      role = wall_follower.get();
    } else {
      // The display reconstructs and never shades: its scene (cameras, animation, bounds) needs
      // no textures; each image is still checked (GltfLoadOptions::textures).
      afr::GltfLoadOptions no_textures;
      no_textures.textures = false;
      if (variant.empty() && camera.empty() && !ray_depth) {
        scene = std::make_unique<afr::Scene>(
            scene_path.empty() ? afr::make_builtin_scene()
                               : afr::load_gltf(scene_path, nullptr, no_textures));
        o.scene = afr::service::read_scene_payload(scene_path);
      } else {
        // The chosen variant's, camera's or ray depth's scene, as the samplers will load it.
        o.scene = afr::service::read_scene_payload(scene_path, variant, camera, ray_depth);
        scene = std::make_unique<afr::Scene>(
            scene_path.empty()
                ? afr::builtin_scene_from_payload(o.scene.bytes)
                : afr::load_gltf_bytes(o.scene.bytes, scene_path, nullptr, no_textures));
        if (!camera.empty()) afr::check_chosen_camera(*scene, camera);
      }
      if (g_stop.load()) return 0;  // a signal while the scene loaded
      // Without --size, a single display takes its camera's aspect ratio (glTF's aspectRatio,
      // or an orthographic camera's xmag / ymag) at the default size's pixel count.
      if (app.count("--size") == 0 && !o.wall.is_wall() && scene->camera_aspect_ratio() > 0.0) {
        o.image = afr::image_size_for_aspect(o.image, scene->camera_aspect_ratio());
        spdlog::info("image {}x{}: the camera's aspect ratio {:.3f} (--size sets another)",
                     o.image.width, o.image.height, scene->camera_aspect_ratio());
      }
      if (!replay.empty()) {
        path = std::make_unique<afr::CameraPath>(afr::read_camera_path(replay));
        spdlog::warn(
            "--replay {}: the display reprojects with the path's camera; samplers "
            "trace the scene's own camera (docs/service.md, \"Camera paths\")",
            replay);
      }
      o.camera_at = afr::service::view_camera_function(*scene, path.get());
      if (interactive) {
        if (headless) throw afr::Error("--interactive needs a window (drop --headless)");
        fly = afr::service::FlyCamera::framing(*scene, o.camera_at(0.0));
        o.camera_at = [f = fly.get()](double) { return f->camera(); };
      }
      spdlog::info("scene {}: {} triangles, {:.2f} s of animation, {} bytes to serve", o.scene.name,
                   scene->triangle_count(), scene->duration(), o.scene.bytes.size());
      service = std::make_unique<afr::service::DisplayService>(o, ingest);
      role = service.get();
    }

    afr::service::DisplayAppOptions ao;
    ao.headless = headless;
    ao.backend = afr::parse_backend(backend_text);
    ao.gl.gpu = gpu;
    ao.gl.reconstructor.splat = afr::parse_gl_splat(gl_splat_text);
    ao.fps = fps;
    ao.seconds = seconds;
    ao.stats_interval = stats_interval;
    ao.screenshot_every = screenshot_every;
    ao.output = output;
    ao.record = record;
    // A wall's nodes exchange coverage and strays after every image (docs/wall.md, "Seams"):
    // as clients of each other's sample channels, with the display key pair they share.
    ao.exchange = !no_exchange && (follower || o.wall.is_wall());
    ao.peer_security = o.keys.secret_key.empty()
                           ? afr::protocol::Security::none()
                           : afr::protocol::Security::client(o.keys, o.keys.public_key);
    const afr::ReconstructorConfig rc = afr::service::display_reconstructor_config(
        *p, mode, o.image.width, o.image.height, role->cell(), o.wall.margin, capacity);
    // Before the reconstructor allocates anything.
    afr::service::check_memory(
        rc, memory_limit > 0 ? memory_limit : afr::service::default_memory_limit());
    if (g_stop.load()) return 0;  // a signal during setup
    afr::service::DisplayApp display(ao, *role, rc, ingest, fly.get());
    if (g_stop.load()) return 0;
    if (service) service->start();
    const int status = display.run(g_stop);
    role->stop();
    return status;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
