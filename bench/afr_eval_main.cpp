// afr-eval: the gold-standard evaluation of the paper's section 7 and the speed/accuracy
// sweeps, with the real sampler and reconstructor libraries joined in one process under a
// virtual clock. See docs/evaluation.md and docs/tradeoffs.md.
//   afr-eval --size 256x256 --seconds 3 --spp 16                 (Table 1, Figure 8, strips)
//   afr-eval --scene city.glb --camera own --start 4 --rates 400K  (any glTF scene)
//   afr-eval --sweep --animations bart,toycar --seconds 2         (the trade, Pareto fronts)
//   afr-eval --sweep --knobs kappa,lambda,m,i --animations builtin (the control weights)
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/eval/animations.h>
#include <afr/eval/evaluation.h>
#include <afr/eval/report.h>
#include <afr/eval/sweep.h>
#include <afr/sampler/sampler_flags.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
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

// The first line of a command's output ("" when it fails).
std::string first_line_of(const std::string& command) {
  std::string out;
  if (FILE* pipe = popen((command + " 2>/dev/null").c_str(), "r")) {
    char buffer[256];
    if (fgets(buffer, sizeof buffer, pipe) != nullptr) out = buffer;
    pclose(pipe);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

// The source tree's commit, "+" when tracked files have uncommitted changes; "unknown" outside
// a git checkout.
std::string source_commit(const std::string& source) {
  const std::string git = "git -C '" + source + "' ";
  const std::string commit = first_line_of(git + "rev-parse --short HEAD");
  if (commit.empty()) return "unknown";
  const bool dirty = !first_line_of(git + "status --porcelain --untracked-files=no").empty();
  return dirty ? commit + "+" : commit;
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\u{:04x}", int(c));
      continue;
    }
    out += c;
  }
  return out + "\"";
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
  std::vector<std::string> animation_names;
  std::string scene_file, camera = "own";
  std::vector<std::string> rate_texts{"100K", "400K", "800K"}, method_names, starts, knobs;
  std::vector<int> strip_frames;
  double seconds = 3.0, warmup = 1.0, capacity_per_pixel = 4.0;
  std::string coverage_rule = "continuous";
  double latency_frames = 1.0, occlusion_ray_cost = 1.0;
  int spp = 16, threads = 0, jobs = 0, seeds = 3;
  bool sweep = false, no_progress = false, no_plots = false, no_cache = false, ideal_only = false;
  afr::SamplerConfig sampler;
  afr::ReconstructorConfig recon;
  afr::eval::TaaOptions taa;

  app.add_option("--scene", scene_file,
                 "evaluate this glTF scene (.gltf or .glb), named after the file; without "
                 "--animations, only it");
  app.add_option("--camera", camera,
                 "with --scene: 'own' (the scene's camera) or a camera path file")
      ->capture_default_str();
  app.add_option("--animations", animation_names,
                 "presets: bart, toycar, interactive, builtin (default: all four, or none with "
                 "--scene)")
      ->delimiter(',');
  app.add_option("--start", starts,
                 "first frame's display time: SECONDS (the --scene animation, or every preset "
                 "without --scene) or NAME=SECONDS")
      ->delimiter(',');
  app.add_option("--kitchen", kitchen, "the presets' BART kitchen as glTF (made by aff2gltf)")
      ->capture_default_str();
  app.add_option("--paths", paths, "the presets' camera paths (toycar.path, interactive.path)")
      ->capture_default_str();
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
  app.add_option("--latency", latency_frames,
                 "refreshes between the input an image is made from and its display, for every "
                 "method (0: the former zero-latency accounting of the frameless methods)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 600.0));
  app.add_option("--occlusion-ray-cost", occlusion_ray_cost,
                 "rays charged to the budget per occlusion ray of the sampler (0: free)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--seeds", seeds,
                 "runs per method and rate, seeds --seed, --seed + 1, ...; tables give the mean "
                 "and range")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--spp", spp, "ideal frames' samples per pixel (a square)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  app.add_option("--cache", cache, "folder of cached ideal frames")->capture_default_str();
  CLI::Option* no_cache_flag = app.add_flag(
      "--no-cache", no_cache, "render ideal frames without reading or writing the cache");
  app.add_flag("--ideal-only", ideal_only,
               "only render the ideal frames into the cache (warm it for a timed run)")
      ->excludes(no_cache_flag);
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
  app.add_option("--coverage-rule", coverage_rule,
                 "continuous (afr's), or thresholds: the former x4 / x0.7 rule, for comparison "
                 "(docs/reconstruction.md, \"Why continuous\")")
      ->capture_default_str()
      ->check(CLI::IsMember({"continuous", "thresholds"}));
  app.add_option("--grow-below", recon.splat.grow_below,
                 "coverage map: splats grow where fewer splats than this reached a pixel "
                 "(the lower end of the band)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1024.0));
  app.add_option("--shrink-above", recon.splat.shrink_above,
                 "coverage map: splats shrink where more splats than this reached a pixel "
                 "(the upper end of the band; above --grow-below)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1024.0));
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
  afr::refuse_non_finite(app);
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
    const afr::ImageExtent size = afr::parse_image_size(size_text);
    if (!(recon.splat.grow_below < recon.splat.shrink_above)) {
      throw afr::Error(fmt::format("--grow-below ({}) must be below --shrink-above ({})",
                                   recon.splat.grow_below, recon.splat.shrink_above));
    }

    EvalConfig config;
    config.seconds = seconds;
    config.ideal_spp = spp;
    if (!no_cache) config.cache = cache;
    config.progress = !no_progress;
    config.base.width = size.width;
    config.base.height = size.height;
    config.base.warmup = warmup;
    config.base.sampler = sampler;
    config.base.sampler.image = size;
    config.base.sampler.validate();
    if (coverage_rule == "thresholds") {
      recon.splat.thresholds = true;
      recon.splat.shrink = 0.7f;  // the former rule's factor
    }
    config.base.reconstructor = recon;
    config.base.reconstructor.capacity =
        size_t(capacity_per_pixel * double(size.width) * double(size.height));
    config.base.taa = taa;
    config.base.seed = sampler.seed;
    config.base.latency = latency_frames / config.base.fps;
    config.base.occlusion_ray_cost = occlusion_ray_cost;
    config.seeds = seeds;
    config.base.threads = threads;
    config.jobs = jobs;
    config.rates.clear();
    for (const std::string& r : rate_texts) config.rates.push_back(parse_rate(r));
    for (const std::string& m : method_names) config.methods.push_back(parse_method(m));
    const int frames = std::max(1, int(std::lround(seconds * config.base.fps)));
    if (strip_frames.empty()) strip_frames = {frames / 3, 2 * frames / 3, frames - 1};
    config.strip_frames = strip_frames;

    // The animations: the presets named, and the --scene one.
    const PresetFiles files{kitchen, paths};
    if (animation_names.empty() && scene_file.empty()) animation_names = animation_preset_names();
    if (scene_file.empty() && camera != "own") {
      throw afr::Error("--camera needs --scene (the presets have their own cameras)");
    }
    for (const std::string& name : animation_names) {
      config.animations.push_back(animation_preset(name, files));
    }
    if (!scene_file.empty()) config.animations.push_back(scene_animation(scene_file, camera, 0.0));
    for (const std::string& s : starts) {
      const size_t eq = s.find('=');
      const std::string name = eq == std::string::npos ? "" : s.substr(0, eq);
      const std::string value = eq == std::string::npos ? s : s.substr(eq + 1);
      double start_time = 0.0;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), start_time);
      if (ec != std::errc() || end != value.data() + value.size() || !std::isfinite(start_time)) {
        throw afr::Error(fmt::format("--start '{}': expected SECONDS or NAME=SECONDS", s));
      }
      bool found = false;
      for (AnimationSpec& a : config.animations) {
        // SECONDS alone: the --scene animation, or every animation when there is none.
        const bool plain_match =
            name.empty() && (scene_file.empty() || &a == &config.animations.back());
        if (a.name == name || plain_match) {
          a.start = start_time;
          found = true;
        }
      }
      if (!found) {
        throw afr::Error(
            fmt::format("--start '{}': no animation named '{}' is evaluated", s, name));
      }
    }

    const fs::path out = fs::path(out_dir);
    fs::create_directories(out);
    const auto start = std::chrono::steady_clock::now();
    const afr::eval::JobSplit split = afr::eval::job_split(config);
    std::string seed_text = fmt::format("seed {}", sampler.seed);
    if (seeds > 1) {
      seed_text = fmt::format(
          "seeds {}-{} (mean and range of {} runs per cell; framed 60 Hz and "
          "full res 60 Hz do not depend on the seed and run once)",
          sampler.seed, sampler.seed + uint64_t(seeds) - 1, seeds);
    }
    const std::string setup = fmt::format(
        "{}x{}, {} s ({} frames at 60 Hz) per animation, ideal {} spp, warm-up {} s, {}; latency "
        "{} refresh(es) for every method{}, occlusion rays charged as {} ray(s) each; {} runs at "
        "a time, {} threads each",
        size.width, size.height, seconds, frames, spp, warmup, seed_text, latency_frames,
        latency_frames < 1.0 ? " (a framed method's at least the refresh its frame takes)" : "",
        occlusion_ray_cost, split.jobs, split.threads_per_run);
    const std::string commit = source_commit(source);

    if (ideal_only) {
      render_ideal_only(config);
      const double minutes =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;
      fmt::print("ideal frames in {} ({:.1f} minutes)\n", cache, minutes);
      return 0;
    }

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
    uint64_t ideal_rendered = 0, ideal_cached = 0;
    for (const AnimationResult& a : results) {
      ideal_rendered += a.ideal_rendered;
      ideal_cached += a.ideal_cached;
    }
    write_cells_csv(results, out / "cells.csv");
    const std::string rms = rms_table_markdown(results), wall = wall_table_markdown(results);
    const std::string versus = comparison_markdown(results, Method::kAdaptive);
    std::ofstream md(out / "table.md");
    md << fmt::format(
        "# afr-eval\n\n    {}\n\nCommit {}. {}; {:.1f} minutes in all, {:.1f} of them rendering "
        "ideal frames ({} rendered, {} from the cache); {:.1f} CPU minutes.\n\n",
        command, commit, setup, minutes, ideal_minutes, ideal_rendered, ideal_cached, cpu_minutes);
    md << "## Mean RMS error (0-255)\n\n"
       << (seeds > 1 ? "Mean over the seeds (lowest-highest run).\n\n" : "") << rms;
    if (!versus.empty() && versus.find('|') != std::string::npos) {
      md << "\n## Adaptive against every other method\n\n"
         << "Lower or higher only where the ranges over the seeds do not overlap"
         << (seeds > 1 ? "" : " (one seed: no spread, every difference counts)") << ".\n\n"
         << versus;
    }
    md << "\n## Wall seconds per run\n\n" << wall;
    md << "\n## Ideal frames\n\n";
    for (const AnimationResult& a : results) {
      md << fmt::format("- {}: {} rendered ({:.0f} s), {} from the cache\n", a.spec.name,
                        a.ideal_rendered, a.ideal_seconds, a.ideal_cached);
    }
    for (const AnimationResult& a : results) {
      if (a.still_frames == 0) continue;
      md << fmt::format(
          "\n**{}: {} of its {} frames show a still scene** (its animation ends at {:.3f} s; "
          "the window starts at {:.3f} s): every method converges there, and its cells mix "
          "motion with stillness.\n",
          a.spec.name, a.still_frames, a.frame_times.size(), a.duration, a.spec.start);
    }
    {
      // What eval_tables.py (docs/results.md) needs besides cells.csv.
      std::ofstream json(out / "run.json");
      json << fmt::format(
          "{{\n  \"command\": {},\n  \"commit\": {},\n  \"setup\": {},\n  \"size\": [{}, {}],\n"
          "  \"seconds\": {},\n  \"ideal_spp\": {},\n  \"seeds\": {},\n  \"first_seed\": {},\n"
          "  \"latency_refreshes\": {},\n  \"occlusion_ray_cost\": {},\n  \"minutes\": {:.3f},\n"
          "  \"ideal_minutes\": {:.3f},\n  \"ideal_rendered\": {},\n  \"ideal_cached\": {},\n"
          "  \"cpu_minutes\": {:.3f},",
          json_string(command), json_string(commit), json_string(setup), size.width, size.height,
          seconds, spp, seeds, sampler.seed, latency_frames, occlusion_ray_cost, minutes,
          ideal_minutes, ideal_rendered, ideal_cached, cpu_minutes);
      std::string rates_json, methods_json;
      for (double r : config.rates)
        rates_json += fmt::format("{}{}", rates_json.empty() ? "" : ", ", r);
      const std::vector<Method> methods =
          config.methods.empty() ? std::vector<Method>(all_methods().begin(), all_methods().end())
                                 : config.methods;
      for (Method m : methods) {
        methods_json += (methods_json.empty() ? "" : ", ") + json_string(method_name(m));
      }
      json << fmt::format("\n  \"rates\": [{}],\n  \"methods\": [{}],\n  \"animations\": [",
                          rates_json, methods_json);
      for (size_t i = 0; i < results.size(); ++i) {
        const AnimationSpec& a = results[i].spec;
        json << fmt::format(
            "{}\n    {{\"name\": {}, \"scene\": {}, \"camera\": {}, \"start\": {}, "
            "\"duration\": {}, \"still_frames\": {}}}",
            i ? "," : "", json_string(a.name),
            json_string(a.scene.empty() ? "builtin" : a.scene.string()),
            json_string(a.camera_path.empty() ? "own" : a.camera_path.string()), a.start,
            results[i].duration, results[i].still_frames);
      }
      json << "\n  ]\n}\n";
    }
    for (const fs::path& p : plots)
      md << fmt::format("\n![{}]({})\n", p.stem().string(), p.filename().string());
    for (const fs::path& p : strips)
      md << fmt::format("\n![{}]({})\n", p.stem().string(), p.filename().string());
    fmt::print(
        "Mean RMS error (0-255), {}\n\n{}\nAdaptive against every other method\n\n{}\n"
        "Wall seconds per run\n\n{}\n",
        setup, rms, versus, wall);
    fmt::print(
        "written to {} in {:.1f} minutes ({:.1f} rendering ideal frames), {:.1f} CPU minutes\n",
        out.string(), minutes, ideal_minutes, cpu_minutes);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
