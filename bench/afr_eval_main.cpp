// afr-eval: the gold-standard evaluation of the paper's section 7 and the speed/accuracy
// sweeps, with the real sampler and reconstructor libraries joined in one process under a
// virtual clock. See docs/evaluation.md and docs/tradeoffs.md.
//   afr-eval --size 256x256 --seconds 3 --spp 16                 (Table 1, Figure 8, strips)
//   afr-eval --sweep --animations bart,toycar --seconds 2         (the trade, Pareto fronts)
//   afr-eval --sweep --knobs kappa,lambda,m,i --animations builtin (the control weights)
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/eval/evaluation.h>
#include <afr/eval/report.h>
#include <afr/eval/sweep.h>
#include <afr/sampler/sampler_flags.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <charconv>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include <sys/resource.h>

namespace {

namespace fs = std::filesystem;

// "100K" -> 1e5, "1.6M" -> 1.6e6, "250000" -> 2.5e5.
double parse_rate(std::string text) {
  double scale = 1.0;
  if (!text.empty() && (text.back() == 'K' || text.back() == 'k')) scale = 1e3;
  if (!text.empty() && (text.back() == 'M' || text.back() == 'm')) scale = 1e6;
  if (scale != 1.0) text.pop_back();
  double v = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !(v > 0.0)) {
    throw afr::Error(fmt::format("rate '{}': expected a positive number, e.g. 400K or 1.6M", text));
  }
  return v * scale;
}

std::string quoted_command(int argc, char** argv) {
  std::string out;
  for (int i = 0; i < argc; ++i) {
    std::string a = i == 0 ? fs::path(argv[0]).filename().string() : std::string(argv[i]);
    if (a.find_first_of(" ;'\"") != std::string::npos) a = "'" + a + "'";
    out += (i ? " " : "") + a;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace afr::eval;
  CLI::App app{"afr-eval: gold-standard evaluation (paper section 7) and speed/accuracy sweeps"};
  std::string size_text = "256x256", log_level = "warn", preset_name;
  std::string source = AFR_SOURCE_DIR;
  std::string kitchen = source + "/out/kitchen/kitchen.gltf";
  std::string paths = source + "/bench/paths";
  std::string out_dir = source + "/out/eval", cache = source + "/out/ideal-cache";
  std::vector<std::string> animation_names{"bart", "toycar", "interactive", "builtin"};
  std::vector<std::string> rate_texts{"100K", "400K", "800K"}, method_names, starts, knobs;
  std::vector<int> strip_frames;
  double seconds = 3.0, warmup = 1.0, capacity_per_pixel = 4.0;
  int spp = 16, threads = 0, jobs = 0;
  bool sweep = false, no_progress = false, no_plots = false, no_cache = false;
  afr::SamplerConfig sampler;
  afr::ReconstructorConfig recon;
  afr::eval::TaaOptions taa;

  app.add_option("--kitchen", kitchen, "the BART kitchen as glTF (made by aff2gltf)")
      ->capture_default_str();
  app.add_option("--paths", paths, "folder of the camera paths (toycar.path, interactive.path)")
      ->capture_default_str();
  app.add_option("--animations", animation_names, "bart, toycar, interactive, builtin")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--start", starts, "first frame's time of an animation, NAME=SECONDS")
      ->delimiter(',');
  app.add_option("--rates", rate_texts, "primary rays per second, e.g. 100K,400K,800K")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--methods", method_names,
                 "framed-60hz, framed-full-res, frameless, framed-taa, adaptive-no-reproj, "
                 "adaptive, full-res-60hz (default: all)")
      ->delimiter(',');
  app.add_option("-s,--size", size_text, "image size WxH")->capture_default_str();
  app.add_option("--seconds", seconds, "seconds of animation evaluated (60 frames each)")
      ->capture_default_str()
      ->check(CLI::Range(1.0 / 60.0, 3600.0));
  app.add_option("--warmup", warmup, "virtual seconds of sampling before the first frame")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--spp", spp, "ideal frames' samples per pixel (a square)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  app.add_option("--cache", cache, "folder of cached ideal frames")->capture_default_str();
  app.add_flag("--no-cache", no_cache, "render ideal frames without reading or writing the cache");
  app.add_option("-o,--out", out_dir, "output folder")->capture_default_str();
  app.add_option("--strip-frames", strip_frames, "frame indices shown in image strips")
      ->delimiter(',');
  app.add_option("-j,--threads", threads, "threads (0 = all cores)")->check(CLI::Range(0, 256));
  app.add_option("--jobs", jobs,
                 "runs at the same time, each with threads / jobs threads (0 = one per thread)")
      ->check(CLI::Range(0, 256));
  CLI::Option* sweep_flag =
      app.add_flag("--sweep", sweep, "run the speed/accuracy sweeps instead of the table");
  app.add_option("--knobs", knobs,
                 "with --sweep: only these knobs' points, plus the defaults (R, b, r, chunk, N, "
                 "tiles, filter, framed-60hz, frameless, framed-taa, kappa, lambda, m, i; "
                 "default: the speed/accuracy sweep, without kappa, lambda, m, i)")
      ->delimiter(',')
      ->needs(sweep_flag);
  app.add_option("--preset", preset_name, "fast, balanced or accurate (sampler_node presets)");
  app.add_flag("--no-progress", no_progress, "no progress bar");
  app.add_flag("--no-plots", no_plots, "do not run gnuplot");
  app.add_option("--log", log_level, "log level")->capture_default_str();
  // The sampler's knobs (--mode is set per method and ignored).
  afr::add_sampler_flags(app, &sampler);
  app.add_option("--capacity", capacity_per_pixel, "reconstructor N in samples per pixel")
      ->capture_default_str()
      ->check(CLI::Range(0.25, 64.0));
  app.add_option("--min-extent", recon.filter.min_spatial_extent, "filter: smallest e_x, e_y")
      ->capture_default_str();
  app.add_option("--max-extent", recon.filter.max_spatial_extent, "filter: largest e_x, e_y")
      ->capture_default_str();
  app.add_option("--max-temporal-extent", recon.filter.max_temporal_extent,
                 "filter: largest e_t (seconds)")
      ->capture_default_str();
  app.add_option("--taa-history", taa.max_history_weight, "TAA: cap of the history weight")
      ->capture_default_str();
  app.add_option("--taa-gamma", taa.clamp_gamma, "TAA: clamp box half-width in std devs")
      ->capture_default_str();
  app.add_flag("!--taa-no-clamp", taa.clamp, "TAA: no neighbourhood clamping");
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    const std::string command = quoted_command(argc, argv);
    if (!preset_name.empty()) {
      const afr::Preset& p = afr::find_preset(preset_name);
      afr::apply_preset(p, &sampler);
      capacity_per_pixel = p.reconstruction.samples_per_pixel;
      recon.filter.min_spatial_extent = p.reconstruction.min_spatial_extent;
      recon.filter.max_spatial_extent = p.reconstruction.max_spatial_extent;
      recon.filter.max_temporal_extent = p.reconstruction.max_temporal_extent;
    }
    const afr::ImageSize size = afr::parse_image_size(size_text);

    EvalConfig config;
    config.seconds = seconds;
    config.ideal_spp = spp;
    if (!no_cache) config.cache = cache;
    config.progress = !no_progress;
    config.base.width = size.width;
    config.base.height = size.height;
    config.base.warmup = warmup;
    config.base.sampler = sampler;
    config.base.sampler.width = size.width;
    config.base.sampler.height = size.height;
    config.base.sampler.validate();
    config.base.reconstructor = recon;
    config.base.reconstructor.capacity =
        size_t(capacity_per_pixel * double(size.width) * double(size.height));
    config.base.taa = taa;
    config.base.seed = sampler.seed;
    config.base.threads = threads;
    config.jobs = jobs;
    config.rates.clear();
    for (const std::string& r : rate_texts) config.rates.push_back(parse_rate(r));
    for (const std::string& m : method_names) config.methods.push_back(parse_method(m));
    const int frames = std::max(1, int(std::lround(seconds * config.base.fps)));
    if (strip_frames.empty()) strip_frames = {frames / 3, 2 * frames / 3, frames - 1};
    config.strip_frames = strip_frames;

    // The animations (docs/evaluation.md says why these views and windows).
    std::map<std::string, AnimationSpec> known = {
        {"bart", {"bart", kitchen, "", 8.5}},
        {"toycar", {"toycar", kitchen, fs::path(paths) / "toycar.path", 11.0}},
        {"interactive", {"interactive", kitchen, fs::path(paths) / "interactive.path", 1.0}},
        {"builtin", {"builtin", "", "", 2.0}},
    };
    for (const std::string& s : starts) {
      const size_t eq = s.find('=');
      if (eq == std::string::npos || !known.count(s.substr(0, eq))) {
        throw afr::Error(
            fmt::format("--start '{}': expected NAME=SECONDS with a known animation", s));
      }
      known[s.substr(0, eq)].start = std::stod(s.substr(eq + 1));
    }
    for (const std::string& name : animation_names) {
      if (!known.count(name)) {
        throw afr::Error(fmt::format(
            "unknown animation '{}' (expected bart, toycar, interactive, builtin)", name));
      }
      config.animations.push_back(known[name]);
    }

    const fs::path out = fs::path(out_dir);
    fs::create_directories(out);
    const auto start = std::chrono::steady_clock::now();
    const afr::eval::JobSplit split = afr::eval::job_split(config);
    const std::string setup = fmt::format(
        "{}x{}, {} s ({} frames at 60 Hz) per animation, ideal {} spp, warm-up {} s, seed {}; "
        "{} runs at a time, {} threads each",
        size.width, size.height, seconds, frames, spp, warmup, sampler.seed, split.jobs,
        split.threads_per_run);

    if (sweep) {
      const std::vector<SweepResult> results =
          run_sweep(config, knobs.empty() ? default_sweep() : select_sweep(knobs));
      write_sweep_csv(results, out / "sweep.csv");
      std::vector<fs::path> plots;
      if (!no_plots) plots = write_sweep_plots(results, out);
      const double minutes =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;
      std::ofstream md(out / "sweep.md");
      md << fmt::format("# afr-eval sweep\n\n    {}\n\n{}; {:.1f} minutes.\n{}\n", command, setup,
                        minutes, sweep_markdown(results));
      for (const fs::path& p : plots)
        md << fmt::format("\n![{}]({})\n", p.stem().string(), p.filename().string());
      fmt::print("{}\n", sweep_markdown(results));
      fmt::print("written to {} in {:.1f} minutes\n", out.string(), minutes);
      return 0;
    }

    const std::vector<AnimationResult> results = evaluate(config);
    write_summary_csv(results, out / "table.csv");
    write_frames_csv(results, out / "frames.csv");
    std::vector<fs::path> plots, strips = write_strips(results, out);
    if (!no_plots) plots = write_frame_plots(results, out);
    const double minutes =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;
    double ideal_minutes = 0.0;
    for (const AnimationResult& a : results) ideal_minutes += a.ideal_seconds / 60;
    // CPU time of the whole process: what the run costs whatever else the machine was doing.
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const double cpu_minutes = (double(usage.ru_utime.tv_sec) + double(usage.ru_stime.tv_sec) +
                                1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec)) /
                               60;
    const std::string rms = rms_table_markdown(results), wall = wall_table_markdown(results);
    std::ofstream md(out / "table.md");
    md << fmt::format(
        "# afr-eval\n\n    {}\n\n{}; {:.1f} minutes in all, {:.1f} of them rendering ideal "
        "frames; {:.1f} CPU minutes.\n\n",
        command, setup, minutes, ideal_minutes, cpu_minutes);
    md << "## Mean RMS error (0-255)\n\n" << rms << "\n## Wall seconds per run\n\n" << wall;
    md << "\n## Ideal frames\n\n";
    for (const AnimationResult& a : results) {
      md << fmt::format("- {}: {} rendered ({:.0f} s), {} from the cache\n", a.spec.name,
                        a.ideal_rendered, a.ideal_seconds, a.ideal_cached);
    }
    for (const fs::path& p : plots)
      md << fmt::format("\n![{}]({})\n", p.stem().string(), p.filename().string());
    for (const fs::path& p : strips)
      md << fmt::format("\n![{}]({})\n", p.stem().string(), p.filename().string());
    fmt::print("Mean RMS error (0-255), {}\n\n{}\nWall seconds per run\n\n{}\n", setup, rms, wall);
    fmt::print(
        "written to {} in {:.1f} minutes ({:.1f} rendering ideal frames), {:.1f} CPU minutes\n",
        out.string(), minutes, ideal_minutes, cpu_minutes);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
