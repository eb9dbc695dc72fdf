// afr-bench-stability: how far two reconstructions of the same scene drift apart when nothing
// but the arrival order of the samples differs, or (--compare seeds) how far two sample
// streams leave their images apart (tests/support/order_stability.h). Prints the RMS between
// the two images (0-255, on the displayed 8-bit values: the evaluation's metric) at images 8,
// 16, 32, ... and the last, one row per seed, and with --ideal-every each one's error against
// the ideal image of its display time.
//   afr-bench-stability --images 600 --seeds 3 --ideal-every 100       (arrival order)
//   afr-bench-stability --images 600 --seeds 3 --still --compare seeds (a still scene)
#include <afr/bench/ideal_renderer.h>
#include <afr/common/cli.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "support/order_stability.h"

namespace {

bool reported(int image, int last) {
  return image == last || (image >= 8 && (image & (image - 1)) == 0);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace afr;
  CLI::App app{"afr-bench-stability: image-to-image drift from arrival order or sample streams"};
  testing::StabilitySettings s;
  std::string scene_path, size_text = "256x256", compare = "orders";
  int seeds = 1, ideal_every = 0, spp = 3;
  app.add_option("--scene", scene_path, "glTF scene (default: the built-in scene)")
      ->check(CLI::ExistingFile);
  app.add_option("--size", size_text, "image size WxH")->capture_default_str();
  app.add_option("--rate", s.rate, "primary rays per second (virtual clock)")
      ->capture_default_str()
      ->check(CLI::Range(1e3, 1e9));
  app.add_option("--images", s.images, "images at --fps")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--fps", s.fps, "display refresh rate")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--seeds", seeds, "sampler seeds 1..N, one row each")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_flag("--still", s.still, "freeze the scene past the end of its animation");
  app.add_option("--compare", compare,
                 "orders: one stream, two arrival orders; seeds: streams of seed s and s + 1000")
      ->capture_default_str()
      ->check(CLI::IsMember({"orders", "seeds"}));
  app.add_option("--ideal-every", ideal_every,
                 "also the error against the ideal image every K images (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  app.add_option("--spp", spp, "ideal image: S x S samples per pixel")
      ->capture_default_str()
      ->check(CLI::Range(1, 16));
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  try {
    init_logging("warn");
    s.size = parse_image_size(size_text);
    s.compare_seeds = compare == "seeds";
    const Scene scene = load_scene(scene_path);
    Tracer ideal_tracer(scene);
    fmt::print("# afr-bench-stability {} {}x{}, {:.0f} rays/s, {} images at {:g} Hz, {}{}\n\n",
               scene_path.empty() ? "builtin" : scene_path, s.size.width, s.size.height, s.rate,
               s.images, s.fps, s.compare_seeds ? "two sample streams" : "two arrival orders",
               s.still ? ", still scene" : "");
    std::string header = "| seed |", rule = "|---:|";
    for (int j = 1; j <= s.images; ++j) {
      if (!reported(j, s.images)) continue;
      header += fmt::format(" {} |", j);
      rule += "---:|";
    }
    fmt::print("RMS between the two images (0-255), by image:\n\n{}\n{}\n", header, rule);
    std::vector<std::string> ideal_rows;
    for (int seed = 1; seed <= seeds; ++seed) {
      s.seed = uint64_t(seed);
      std::string row = fmt::format("| {} |", seed), ideal_row = row;
      testing::run_stability(scene, s, [&](int j, double t, const Image& a, const Image& b) {
        if (reported(j, s.images)) row += fmt::format(" {:.2f} |", rms_error_255(a, b));
        if (ideal_every == 0 || j % ideal_every != 0) return;
        IdealRenderOptions io;
        io.width = s.size.width;
        io.height = s.size.height;
        io.strata = spp;
        io.time = testing::stability_scene_time(scene, s, t);
        const Image ideal = render_ideal(ideal_tracer, io);
        ideal_row +=
            fmt::format(" {:.2f} / {:.2f} |", rms_error_255(a, ideal), rms_error_255(b, ideal));
      });
      fmt::print("{}\n", row);
      ideal_rows.push_back(ideal_row);
    }
    if (ideal_every > 0) {
      std::string h = "| seed |", r = "|---:|";
      for (int j = ideal_every; j <= s.images; j += ideal_every) {
        h += fmt::format(" {} |", j);
        r += "---:|";
      }
      fmt::print(
          "\nRMS against the ideal image ({0}x{0} spp), first / second, by image:\n\n{1}\n{2}\n",
          spp, h, r);
      for (const std::string& row : ideal_rows) fmt::print("{}\n", row);
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "afr-bench-stability: {}\n", e.what());
    return 1;
  }
  return 0;
}
