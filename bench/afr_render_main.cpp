// afr-render: the ideal renderer (the evaluation's gold standard) as a command.
//   afr-render kitchen.gltf --time 6 --size 256x256 --spp 16 -o kitchen_t6.png
//   afr-render --frames 600 --fps 60 -o frames/builtin_%04d.png     (the built-in scene)
//   afr-render --time 4.25 --compare out/frame_000255.png   (RMS error of a display's image)
#include <afr/bench/ideal_renderer.h>
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/gltf_pack.h>
#include <afr/common/log.h>

#include <fmt/format.h>
#include <fmt/printf.h>
#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <optional>

int main(int argc, char** argv) {
  CLI::App app{"afr-render: zero-delay, antialiased reference images of a scene at exact times"};
  std::string scene_path, size_text = "256x256", output = "render.png", log_level = "info";
  double time = 0.0, fps = 60.0;
  int spp = 16, frames = 1, threads = 0, light_samples = 0;
  uint64_t seed = 1;
  std::vector<std::string> compare;
  std::string variant, camera;
  bool loop = false;
  app.add_option("scene", scene_path, "glTF 2.0 scene (.gltf/.glb); the built-in scene if omitted")
      ->check(CLI::ExistingFile);
  app.add_option("--variant", variant,
                 "KHR_materials_variants: draw the scene with this material variant (by name)");
  app.add_option("--camera", camera,
                 "the scene's camera to draw from: a camera's or its node's name, or an index "
                 "into the glTF's cameras (default: the first camera node of the scene)");
  std::optional<int> ray_depth;
  afr::add_ray_depth_option(app, &ray_depth,
                            "as display_node --ray-depth sets them for the samplers");
  app.add_option("-t,--time", time, "scene time in seconds (first frame's time with --frames)");
  app.add_option("-s,--size", size_text,
                 "image size WxH; without it the scene camera's aspect ratio, where the file "
                 "gives one, at as many pixels")
      ->capture_default_str();
  app.add_option("--spp", spp, "samples per pixel, a square S*S (stratified S x S)")
      ->capture_default_str()
      ->check(CLI::Range(1, 4096));
  app.add_option("--frames", frames, "number of frames to render")->check(CLI::Range(1, 1000000));
  app.add_option("--fps", fps, "frames per second of scene time")->check(CLI::Range(0.001, 1e6));
  app.add_option("-o,--output", output,
                 "output image (.png/.exr/...); with --frames, a pattern such as out_%04d.png")
      ->capture_default_str();
  app.add_option("-j,--threads", threads, "worker threads (0 = all cores)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--seed", seed, "seed of the sample jitter");
  app.add_option("--light-samples", light_samples,
                 "shadow rays of a surface's direct light (TracerOptions::light_samples): 0 = one "
                 "toward every light; K = K toward picked lights (--compare's ideal keeps 0)")
      ->capture_default_str()
      ->check(CLI::Range(0, afr::kMaxLightSamples));
  app.add_option("--log", log_level, "log level")->capture_default_str();
  app.add_flag("--loop", loop,
               "times wrap over the scene's animation, as the service's nodes wrap display time");
  app.add_option("--compare", compare,
                 "instead of writing, print the RMS error (0-255 sRGB, afr-eval's metric) of "
                 "these images against the ideal image of --time (their size)");
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging(log_level);
    afr::ImageExtent size = afr::parse_image_size(size_text);
    const int strata = int(std::lround(std::sqrt(double(spp))));
    if (strata * strata != spp) {
      throw afr::Error(fmt::format("--spp {} is not a square (use 1, 4, 9, 16, 25, ...)", spp));
    }
    if (frames > 1 && output.find('%') == std::string::npos) {
      throw afr::Error(fmt::format(
          "--frames {} needs an output pattern with a frame number, e.g. out_%04d.png", frames));
    }
    if (!variant.empty() && scene_path.empty()) {
      throw afr::Error("--variant needs a scene file (the built-in scene has no variants)");
    }
    if (!camera.empty() && scene_path.empty()) throw afr::Error("--camera needs a scene file");
    afr::Scene scene = [&] {
      if (variant.empty() && camera.empty()) return afr::load_scene(scene_path);
      std::vector<uint8_t> bytes = afr::read_scene_file(scene_path);
      if (!variant.empty()) bytes = afr::select_material_variant(bytes, scene_path, variant);
      if (!camera.empty()) bytes = afr::select_camera(bytes, scene_path, camera);
      afr::Scene chosen = afr::load_gltf_bytes(bytes, scene_path);
      if (!camera.empty()) afr::check_chosen_camera(chosen, camera);
      return chosen;
    }();
    if (ray_depth) scene.ray_depth = *ray_depth;
    if (!variant.empty()) spdlog::info("material variant \"{}\" chosen", variant);
    spdlog::info("scene {}: {} triangles, {} lights, {:.2f} s of animation", scene.source,
                 scene.triangle_count(), scene.lights.size(), scene.duration());
    afr::TracerOptions tracer_options;
    if (compare.empty()) tracer_options.light_samples = light_samples;
    afr::Tracer tracer(scene, tracer_options);
    // --loop: display time to scene time, as the service's nodes map it.
    const auto scene_time = [&](double t) {
      const double d = scene.duration();
      return loop && d > 0.0 ? std::fmod(t, d) : t;
    };
    if (!compare.empty()) {
      // One ideal image per size among the images, at --time; a line per image.
      afr::IdealRenderOptions options;
      options.strata = strata;
      options.threads = threads;
      options.seed = seed;
      options.time = scene_time(time);
      afr::Image ideal;
      for (const std::string& path : compare) {
        const afr::Image shot = afr::read_image(path);
        if (ideal.width != shot.width || ideal.height != shot.height) {
          options.width = shot.width;
          options.height = shot.height;
          ideal = afr::render_ideal(tracer, options, nullptr);
        }
        fmt::print("{} t={:.4f} scene_time={:.4f} rms={:.3f}\n", path, time, options.time,
                   afr::rms_error_255(ideal, shot));
      }
      return 0;
    }

    // Without --size, the camera's aspect ratio at the default size's pixel count (as
    // display_node sizes its image).
    if (app.count("--size") == 0 && scene.camera_aspect_ratio() > 0.0) {
      size = afr::image_size_for_aspect(size, scene.camera_aspect_ratio());
      spdlog::info("image {}x{}: the camera's aspect ratio {:.3f} (--size sets another)",
                   size.width, size.height, scene.camera_aspect_ratio());
    }
    afr::IdealRenderOptions options;
    options.width = size.width;
    options.height = size.height;
    options.strata = strata;
    options.threads = threads;
    options.seed = seed;
    for (int f = 0; f < frames; ++f) {
      options.time = scene_time(time + f / fps);
      afr::IdealRenderStats stats;
      const afr::Image image = afr::render_ideal(tracer, options, &stats);
      const std::string path = frames > 1 ? fmt::sprintf(output, f) : output;
      const std::filesystem::path parent = std::filesystem::path(path).parent_path();
      if (!parent.empty()) std::filesystem::create_directories(parent);
      afr::write_image(image, path);
      const uint64_t rays =
          stats.trace.primary_rays + stats.trace.shadow_rays + stats.trace.reflection_rays;
      spdlog::info(
          "{} t={:.4f}s {}x{} {} spp: {:.3f} s, {:.2f} M rays/s{}", path, options.time, size.width,
          size.height, spp, stats.seconds, rays / stats.seconds * 1e-6,
          stats.trace.sanitized ? fmt::format(", {} values sanitised", stats.trace.sanitized) : "");
    }
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
