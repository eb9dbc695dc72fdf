#include <afr/eval/sweep.h>

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/eval/report.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>

namespace afr::eval {
namespace {

const char* comparison_word(Comparison c) {
  return c == Comparison::kLower ? "lower" : c == Comparison::kHigher ? "higher" : "within spread";
}

}  // namespace

std::vector<SweepPoint> default_sweep() {
  std::vector<SweepPoint> p;
  const auto add = [&](std::string knob, std::string value, Method m, double rate,
                       std::function<void(RunSettings*)> apply) {
    p.push_back(SweepPoint{std::move(knob), std::move(value), m, rate, std::move(apply)});
  };
  const Method A = Method::kAdaptive;
  add("default", "defaults", A, 4e5, nullptr);
  for (double r : {1e5, 2e5, 8e5, 1.6e6}) add("R", rate_label(r), A, r, nullptr);
  for (int b : {1, 2, 8}) {
    add("b", fmt::format("b={}", b), A, 4e5, [b](RunSettings* s) { s->sampler.b = b; });
  }
  for (int r : {0, 1, 2, 10}) {
    add("r", fmt::format("r={}", r), A, 4e5, [r](RunSettings* s) { s->sampler.r = r; });
  }
  for (int c : {5, 100}) {
    add("chunk", fmt::format("chunk={}", c), A, 4e5, [c](RunSettings* s) { s->sampler.chunk = c; });
  }
  for (int n : {1, 2, 8}) {
    add("N", fmt::format("N={}WH", n), A, 4e5, [n](RunSettings* s) {
      s->reconstructor.capacity = size_t(n) * size_t(s->width) * size_t(s->height);
    });
  }
  for (const auto& range : {std::pair{4, 256}, std::pair{64, 4096}, std::pair{16, 4096}}) {
    const int lo = range.first, hi = range.second;  // named for the capture (clang 14)
    add("tiles", fmt::format("tiles {}..{}", lo, hi), A, 4e5, [lo, hi](RunSettings* s) {
      s->sampler.min_tiles = lo;
      s->sampler.max_tiles = hi;
    });
  }
  add("filter", "max e_xy 8", A, 4e5,
      [](RunSettings* s) { s->reconstructor.filter.max_spatial_extent = 8.0f; });
  add("filter", "max e_xy 16", A, 4e5,
      [](RunSettings* s) { s->reconstructor.filter.max_spatial_extent = 16.0f; });
  add("filter", "min e_xy 0.6", A, 4e5,
      [](RunSettings* s) { s->reconstructor.filter.min_spatial_extent = 0.6f; });
  add("filter", "max e_t 0.25", A, 4e5,
      [](RunSettings* s) { s->reconstructor.filter.max_temporal_extent = 0.25f; });
  for (Method m : {Method::kFramed60, Method::kFrameless, Method::kFramedTaa}) {
    for (double r : {1e5, 2e5, 4e5, 8e5, 1.6e6}) add(method_name(m), rate_label(r), m, r, nullptr);
  }
  return p;
}

std::vector<SweepPoint> control_sweep() {
  std::vector<SweepPoint> p;
  const auto add = [&](std::string knob, std::string value,
                       std::function<void(RunSettings*)> apply) {
    p.push_back(
        SweepPoint{std::move(knob), std::move(value), Method::kAdaptive, 4e5, std::move(apply)});
  };
  add("default", "defaults", nullptr);
  for (double kappa : {0.2, 0.4, 0.8, 1.0}) {
    add("kappa", fmt::format("kappa={}", kappa), [kappa](RunSettings* s) {
      s->sampler.kappa = kappa;
      s->sampler.lambda = std::min(s->sampler.lambda, 1.0 - kappa);
    });
  }
  for (double lambda : {0.0, 0.1, 0.2}) {
    add("lambda", fmt::format("lambda={}", lambda), [lambda](RunSettings* s) {
      s->sampler.lambda = lambda;
      s->sampler.kappa = std::min(s->sampler.kappa, 1.0 - lambda);
    });
  }
  // m's list holds the default (1) and the former default (2), so that a sweep around either
  // (afr-eval --m 2) has both neighbours; the point equal to the base repeats the defaults.
  for (double m : {0.5, 1.0, 2.0, 4.0, 8.0}) {
    add("m", fmt::format("m={}", m), [m](RunSettings* s) { s->sampler.m = m; });
  }
  for (double i : {0.01, 0.03, 0.3, 1.0}) {
    add("i", fmt::format("i={}", i), [i](RunSettings* s) { s->sampler.i = i; });
  }
  return p;
}

std::vector<std::string> sweep_knobs() {
  std::vector<std::string> knobs;
  for (const auto& points : {default_sweep(), control_sweep()}) {
    for (const SweepPoint& point : points) {
      if (std::find(knobs.begin(), knobs.end(), point.knob) == knobs.end()) {
        knobs.push_back(point.knob);
      }
    }
  }
  return knobs;
}

std::vector<SweepPoint> select_sweep(const std::vector<std::string>& knobs) {
  const std::vector<std::string> known = sweep_knobs();
  for (const std::string& knob : knobs) {
    if (std::find(known.begin(), known.end(), knob) == known.end()) {
      std::string names;
      for (const std::string& k : known) names += (names.empty() ? "" : ", ") + k;
      throw Error(fmt::format("unknown sweep knob '{}' (expected one of {})", knob, names));
    }
  }
  std::vector<SweepPoint> out;
  for (const auto& points : {default_sweep(), control_sweep()}) {
    for (const SweepPoint& point : points) {
      const bool is_default = point.knob == "default";
      if (is_default && !out.empty()) continue;
      if (is_default || std::find(knobs.begin(), knobs.end(), point.knob) != knobs.end()) {
        out.push_back(point);
      }
    }
  }
  return out;
}

void mark_pareto(std::vector<SweepResult>* results) {
  for (SweepResult& a : *results) {
    a.pareto = true;
    for (const SweepResult& b : *results) {
      if (&a == &b || a.animation != b.animation) continue;
      const bool no_worse = b.cost <= a.cost && b.mean_rms <= a.mean_rms;
      const bool better = b.cost < a.cost || b.mean_rms < a.mean_rms;
      if (no_worse && better) {
        a.pareto = false;
        break;
      }
    }
  }
}

void compare_with_defaults(std::vector<SweepResult>* results) {
  std::map<std::string, const SweepResult*> defaults;
  for (const SweepResult& r : *results) {
    if (r.point.knob == "default") defaults.emplace(r.animation, &r);
  }
  const auto cell = [](const SweepResult& r) {
    Cell c;
    c.runs = r.runs;
    c.mean = r.mean_rms;
    c.min = r.min_rms;
    c.max = r.max_rms;
    return c;
  };
  for (SweepResult& r : *results) {
    const auto d = defaults.find(r.animation);
    r.vs_default = d == defaults.end() || d->second == &r ? Comparison::kWithinSpread
                                                          : compare(cell(r), cell(*d->second));
  }
}

SweepResult sweep_result(const SweepPoint& point, const std::vector<RunResult>& runs,
                         double seconds_shown) {
  AFR_CHECK(!runs.empty());
  SweepResult sr;
  sr.animation = runs.front().animation;
  sr.point = point;
  sr.runs = int(runs.size());
  sr.min_rms = runs.front().mean_rms;
  sr.max_rms = runs.front().mean_rms;
  for (const RunResult& r : runs) {
    sr.mean_rms += r.mean_rms;
    sr.min_rms = std::min(sr.min_rms, r.mean_rms);
    sr.max_rms = std::max(sr.max_rms, r.mean_rms);
    sr.sample_seconds += r.stats.sample_seconds;
    sr.reconstruct_seconds += r.stats.reconstruct_seconds;
    sr.cost +=
        (r.stats.virtual_seconds > 0.0 ? r.stats.sample_seconds / r.stats.virtual_seconds : 0.0) +
        r.stats.reconstruct_seconds / seconds_shown;
  }
  const double n = double(runs.size());
  sr.mean_rms /= n;
  sr.sample_seconds /= n;
  sr.reconstruct_seconds /= n;
  sr.cost /= n;
  return sr;
}

std::vector<SweepResult> run_sweep(const EvalConfig& config,
                                   const std::vector<SweepPoint>& points) {
  const int frames = std::max(1, int(std::lround(config.seconds * config.base.fps)));
  const int seeds = std::max(1, config.seeds);
  const JobSplit split = job_split(config);
  uint64_t runs_per_animation = 0;
  for (const SweepPoint& point : points) {
    runs_per_animation += method_uses_seed(point.method) ? uint64_t(seeds) : 1;
  }
  Progress progress(config.animations.size() * uint64_t(frames) * (1 + runs_per_animation),
                    config.progress);
  std::vector<SweepResult> out;
  for (const AnimationSpec& spec : config.animations) {
    progress.set_task(fmt::format("{}: loading", spec.name));
    const Scene scene = load_animation_scene(spec);
    Tracer tracer(scene, tracer_options(split));
    progress.set_task(fmt::format("{}: ideal frames", spec.name));
    const std::vector<Image> ideal =
        ideal_frames(scene, tracer, config, spec.start, frames, &progress, nullptr);
    // Every (point, seed) run, the seeds of a point after each other.
    std::vector<RunSettings> runs;
    std::vector<size_t> point_of;
    for (size_t p = 0; p < points.size(); ++p) {
      const SweepPoint& point = points[p];
      for (int k = 0; k < (method_uses_seed(point.method) ? seeds : 1); ++k) {
        RunSettings s = config.base;
        s.method = point.method;
        s.rate = point.rate;
        s.seed = config.base.seed + uint64_t(k);
        s.first_time = spec.start;
        s.frames = frames;
        s.threads = split.threads_per_run;
        if (point.apply) point.apply(&s);
        runs.push_back(s);
        point_of.push_back(p);
      }
    }
    const std::vector<RunResult> done =
        run_all(scene, tracer, runs, ideal, split.jobs, spec.name, {}, 0, &progress);
    const double shown = double(frames) / config.base.fps;
    for (size_t p = 0; p < points.size(); ++p) {
      std::vector<RunResult> of_point;
      for (size_t k = 0; k < done.size(); ++k) {
        if (point_of[k] == p) of_point.push_back(done[k]);
      }
      out.push_back(sweep_result(points[p], of_point, shown));
    }
  }
  progress.finish();
  mark_pareto(&out);
  compare_with_defaults(&out);
  return out;
}

void write_sweep_csv(const std::vector<SweepResult>& results, const std::filesystem::path& file) {
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
  std::ofstream out(file);
  out << "animation,knob,value,method,rate,runs,mean_rms,min_rms,max_rms,cost,sample_wall_s,"
         "reconstruct_wall_s,pareto,vs_default\n";
  for (const SweepResult& r : results) {
    out << fmt::format("{},{},{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.3f},{:.3f},{},{}\n",
                       r.animation, r.point.knob, r.point.value, method_name(r.point.method),
                       r.point.rate, r.runs, r.mean_rms, r.min_rms, r.max_rms, r.cost,
                       r.sample_seconds, r.reconstruct_seconds, r.pareto ? 1 : 0,
                       comparison_word(r.vs_default));
  }
}

std::string sweep_markdown(const std::vector<SweepResult>& results) {
  std::string out;
  std::set<std::string> done;
  for (const SweepResult& first : results) {
    if (!done.insert(first.animation).second) continue;
    out += fmt::format(
        "\n**{}**\n\n| knob | value | method | R | mean RMS (range) | against the defaults | "
        "cost (wall s per s) | Pareto |\n|---|---|---|---:|---:|:-:|---:|:-:|\n",
        first.animation);
    for (const SweepResult& r : results) {
      if (r.animation != first.animation) continue;
      const std::string rms =
          r.runs > 1 ? fmt::format("{:.1f} ({:.1f}-{:.1f})", r.mean_rms, r.min_rms, r.max_rms)
                     : fmt::format("{:.1f}", r.mean_rms);
      const std::string word = comparison_word(r.vs_default);
      const std::string vs = r.point.knob == "default"                   ? ""
                             : r.vs_default == Comparison::kWithinSpread ? word
                                                                         : "**" + word + "**";
      out += fmt::format("| {} | {} | {} | {} | {} | {} | {:.2f} | {} |\n", r.point.knob,
                         r.point.value, method_name(r.point.method), rate_label(r.point.rate), rms,
                         vs, r.cost, r.pareto ? "*" : "");
    }
  }
  return out;
}

std::vector<std::filesystem::path> write_sweep_plots(const std::vector<SweepResult>& results,
                                                     const std::filesystem::path& out_folder) {
  // Scripts name their files absolutely, so they run from anywhere.
  const std::filesystem::path folder = std::filesystem::absolute(out_folder);
  std::filesystem::create_directories(folder);
  std::vector<std::filesystem::path> pngs;
  std::set<std::string> animations;
  for (const SweepResult& r : results) animations.insert(r.animation);
  for (const std::string& anim : animations) {
    // One data block per knob (gnuplot's index), then the Pareto front sorted by cost.
    std::vector<std::string> knobs;
    for (const SweepResult& r : results) {
      if (r.animation == anim &&
          std::find(knobs.begin(), knobs.end(), r.point.knob) == knobs.end()) {
        knobs.push_back(r.point.knob);
      }
    }
    const std::filesystem::path dat = folder / fmt::format("tradeoff-{}.dat", anim);
    const std::filesystem::path png = folder / fmt::format("tradeoff-{}.png", anim);
    const std::filesystem::path gp = folder / fmt::format("tradeoff-{}.gp", anim);
    {
      std::ofstream out(dat);
      for (const std::string& knob : knobs) {
        out << "# " << knob << "\n";
        for (const SweepResult& r : results) {
          if (r.animation == anim && r.point.knob == knob) {
            out << fmt::format("{:.5f} {:.4f} {:.4f} {:.4f} \"{}\"\n", r.cost, r.mean_rms,
                               r.min_rms, r.max_rms, r.point.value);
          }
        }
        out << "\n\n";
      }
      std::vector<const SweepResult*> front;
      for (const SweepResult& r : results) {
        if (r.animation == anim && r.pareto) front.push_back(&r);
      }
      std::sort(front.begin(), front.end(),
                [](const SweepResult* a, const SweepResult* b) { return a->cost < b->cost; });
      out << "# pareto\n";
      for (const SweepResult* r : front) {
        out << fmt::format("{:.5f} {:.4f} {:.4f} {:.4f} \"{} {}\"\n", r->cost, r->mean_rms,
                           r->min_rms, r->max_rms, r->point.knob, r->point.value);
      }
      out << "\n\n";
    }
    {
      std::ofstream out(gp);
      out << "set terminal pngcairo noenhanced size 1000,560 font 'DejaVu Sans,10'\n"
          << fmt::format("set output '{}'\n", png.string())
          << fmt::format(
                 "set title '{}: mean RMS error (range over the seeds) against wall-clock "
                 "cost'\n",
                 anim)
          << "set xlabel 'wall seconds per second of animation (this machine)'\n"
          << "set ylabel 'mean RMS error (0-255)'\nset logscale x\nset grid\n"
          << "set key outside right top\nplot";
      for (size_t k = 0; k < knobs.size(); ++k) {
        out << fmt::format("{} '{}' index {} using 1:2:3:4 with yerrorbars pt {} ps 1.3 title '{}'",
                           k ? "," : "", dat.string(), k, int(k % 12) + 1, knobs[k]);
      }
      out << fmt::format(
          ", '{}' index {} using 1:2 with lines lw 2 lc rgb 'black' title 'Pareto front', "
          "'{}' index {} using 1:2:5 with labels font ',8' offset 0.5,0.6 left notitle\n",
          dat.string(), knobs.size(), dat.string(), knobs.size());
    }
    if (run_gnuplot(gp)) pngs.push_back(png);
  }
  return pngs;
}

}  // namespace afr::eval
