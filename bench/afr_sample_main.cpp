// afr-sample: runs the adaptive sampler on a scene under a virtual clock and draws pictures of
// its loop: the tiling over the newest samples (the paper's Figure 3), the tile gradients
// (Figure 4: G_x, G_y, G_t as red, green, blue), the occlusion map and the sample density
// (Figure 7).
//   afr-sample --time 4 --size 256x256 --rate 400000 --seconds 1 --dump out/loop
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>
#include <afr/common/log.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/sampler_flags.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <filesystem>

namespace {

// Keeps the newest sample of every pixel and counts samples per pixel.
class PictureSink final : public afr::SampleSink {
 public:
  PictureSink(int w, int h) : newest(w, h), count(size_t(w) * h, 0), width_(w), height_(h) {}
  void on_batch(afr::SampleBatch&& batch) override {
    for (const afr::Sample& s : batch.samples) {
      const int x = std::clamp(int(s.x), 0, width_ - 1), y = std::clamp(int(s.y), 0, height_ - 1);
      newest.at(x, y) = s.color;
      ++count[size_t(y) * width_ + x];
    }
  }
  void on_tiling(afr::TilingSnapshot&& s) override { last = std::move(s); }

  afr::Image newest;
  std::vector<uint32_t> count;
  afr::TilingSnapshot last;

 private:
  int width_, height_;
};

void draw_tiles(const afr::TilingSnapshot& snap, glm::vec3 color, afr::Image* image) {
  for (const afr::TileInfo& t : snap.tiles) {
    for (int32_t x = t.rect.x0; x < t.rect.x1; ++x) {
      image->at(x, t.rect.y0) = color;
      image->at(x, t.rect.y1 - 1) = color;
    }
    for (int32_t y = t.rect.y0; y < t.rect.y1; ++y) {
      image->at(t.rect.x0, y) = color;
      image->at(t.rect.x1 - 1, y) = color;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-sample: run the adaptive sampler and draw its tiling, gradients and maps"};
  std::string scene_path, size_text = "256x256", dump = "out/sampler", log_level = "info";
  double time = 4.0, rate = 400000.0, seconds = 1.0;
  afr::SamplerConfig config;
  app.add_option("scene", scene_path, "glTF scene; the built-in scene if omitted")
      ->check(CLI::ExistingFile);
  app.add_option("-t,--time", time, "scene time at which the pictures are taken")
      ->capture_default_str();
  app.add_option("-s,--size", size_text, "image size WxH")->capture_default_str();
  app.add_option("--rate", rate, "simulated primary rays per second (virtual clock)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1e10));
  app.add_option("--seconds", seconds, "virtual seconds of sampling before --time")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 1e5));
  app.add_option("--dump", dump, "folder for the PNG pictures")->capture_default_str();
  app.add_option("--log", log_level, "log level")->capture_default_str();
  afr::add_sampler_flags(app, &config);
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    const afr::ImageExtent size = afr::parse_image_size(size_text);
    config.image = size;
    config.validate();
    const afr::Scene scene = afr::load_scene(scene_path);
    afr::Tracer tracer(scene);
    afr::VirtualClock clock(rate, time - seconds);
    PictureSink sink(size.width, size.height);
    afr::Sampler sampler(scene, tracer, clock, config, sink);
    sampler.fill();
    std::fill(sink.count.begin(), sink.count.end(), 0u);
    while (clock.now() < time) sampler.step();
    sampler.flush();
    const afr::TilingSnapshot snap = sampler.snapshot();

    std::filesystem::create_directories(dump);
    afr::Image tiling = sink.newest;
    draw_tiles(snap, glm::vec3(1.0f, 0.1f, 0.1f), &tiling);
    afr::write_image(tiling, std::filesystem::path(dump) / "tiling.png");

    // Gradients, each channel scaled by its 99th-percentile tile value.
    afr::Image gradients(size.width, size.height);
    auto scale_of = [&](auto field) {
      std::vector<float> v;
      for (const afr::TileInfo& t : snap.tiles) v.push_back(field(t));
      std::sort(v.begin(), v.end());
      const float p = v.empty() ? 0.0f : v[size_t(0.99 * (v.size() - 1))];
      return p > 0.0f ? 1.0f / p : 0.0f;
    };
    const float sx = scale_of([](const afr::TileInfo& t) { return t.G_x; });
    const float sy = scale_of([](const afr::TileInfo& t) { return t.G_y; });
    const float st = scale_of([](const afr::TileInfo& t) { return t.G_t; });
    for (const afr::TileInfo& t : snap.tiles) {
      const glm::vec3 c(std::min(1.0f, t.G_x * sx), std::min(1.0f, t.G_y * sy),
                        std::min(1.0f, t.G_t * st));
      for (int32_t y = t.rect.y0; y < t.rect.y1; ++y) {
        for (int32_t x = t.rect.x0; x < t.rect.x1; ++x) gradients.at(x, y) = c;
      }
    }
    afr::write_image(gradients, std::filesystem::path(dump) / "gradients.png");

    // Occlusion: pixels holding a crosshair made to replace an occluded one, in white.
    afr::Image occlusion(size.width, size.height);
    const afr::DeepBuffer& buffer = sampler.buffer();
    for (int32_t y = 0; y < size.height; ++y) {
      for (int32_t x = 0; x < size.width; ++x) {
        occlusion.at(x, y) = 0.15f * sink.newest.at(x, y);
        for (int k = 0; k < buffer.count(x, y); ++k) {
          if (buffer.at(x, y, k).has(afr::Crosshair::kOccluded)) occlusion.at(x, y) = glm::vec3(1);
        }
      }
    }
    afr::write_image(occlusion, std::filesystem::path(dump) / "occlusion.png");

    // Sample density over the run, normalised to the densest 1% of pixels.
    afr::Image density(size.width, size.height);
    std::vector<uint32_t> sorted = sink.count;
    std::sort(sorted.begin(), sorted.end());
    const float top = std::max(1.0f, float(sorted[size_t(0.99 * (sorted.size() - 1))]));
    for (int32_t y = 0; y < size.height; ++y) {
      for (int32_t x = 0; x < size.width; ++x) {
        density.at(x, y) = glm::vec3(std::min(1.0f, sink.count[size_t(y) * size.width + x] / top));
      }
    }
    afr::write_image(density, std::filesystem::path(dump) / "density.png");

    const afr::SamplerCounters& c = sampler.counters();
    spdlog::info(
        "{} tiles (target {}), {} samples, {} crosshairs, {} reprojections ({} dropped), {} of "
        "{} occlusion rays hit, {} splits, {} merges, {} sanitised; pictures in {}",
        sampler.tiling().tile_count(), sampler.target_tiles(), c.samples, c.crosshairs,
        c.reprojections, c.reprojections_dropped, c.occlusion_hits, c.occlusion_rays, c.splits,
        c.merges, c.sanitized, dump);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
