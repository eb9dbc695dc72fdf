// The speed/accuracy trade (docs/tradeoffs.md): runs of the adaptive renderer with one knob
// changed at a time from the defaults (R, b, r, chunk, the reconstructor's N, the tile count
// bounds and the filter clamps), plus the framed, frameless and TAA baselines over R, each
// scored by mean RMS against the ideal frames and by wall-clock cost, with the Pareto front
// (no other point both cheaper and more accurate) marked per animation. control_sweep() does
// the same for the sampler's control weights (kappa, lambda, m, i), which docs/sampler.md
// chose with it.
#pragma once

#include <afr/eval/evaluation.h>
#include <afr/eval/report.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace afr::eval {

struct SweepPoint {
  std::string knob;   // "default", "R", "b", "r", "chunk", "N", "tiles", "filter", a
                      // baseline's method, or "kappa", "lambda", "m", "i" (control_sweep())
  std::string value;  // as shown in tables and plots
  Method method = Method::kAdaptive;
  double rate = 4e5;
  std::function<void(RunSettings*)> apply;  // changes from the base settings (may be empty)
};

struct SweepResult {
  std::string animation;
  SweepPoint point;
  // Over the point's runs, one per seed (one for methods no seed changes: method_uses_seed):
  // the mean of their mean RMS, and the lowest and highest.
  int runs = 0;
  double mean_rms = 0.0;
  double min_rms = 0.0;
  double max_rms = 0.0;
  // Wall seconds per second of animation, mean over the runs: sampling wall time over the
  // virtual seconds sampled plus reconstruction wall time over the seconds of frames shown.
  // 1 is real time on this machine.
  double cost = 0.0;
  double sample_seconds = 0.0;  // means over the runs
  double reconstruct_seconds = 0.0;
  bool pareto = false;
  // Against the defaults point of the same animation, beyond the spread over the seeds
  // (compare() of report.h); kWithinSpread for the defaults point itself.
  Comparison vs_default = Comparison::kWithinSpread;
};

// The default sweep around `base` (knob values in docs/tradeoffs.md).
std::vector<SweepPoint> default_sweep();

// The sampler's control weights one at a time around `base`, adaptive at R = 400K: kappa
// (variance) 0.2, 0.4, 0.8 and 1 (lambda lowered to 1 - kappa where the sum would pass 1),
// lambda (undersampling) 0, 0.1, 0.2, m (undersampling threshold) 0.5, 1, 2, 4, 8, i (temporal
// importance in gain control) 0.01, 0.03, 0.3, 1, and the defaults point.
std::vector<SweepPoint> control_sweep();

// The knob names of default_sweep() then control_sweep(), each once, "default" first.
std::vector<std::string> sweep_knobs();

// The defaults point, then the points of default_sweep() and control_sweep() whose knob is
// one of `knobs` (afr-eval --sweep --knobs kappa,lambda,m,i). Throws afr::Error naming an
// unknown knob and the known ones.
std::vector<SweepPoint> select_sweep(const std::vector<std::string>& knobs);

// Runs every point on every animation of `config` with config.seeds seeds (config.methods and
// config.rates are not used), config.jobs runs at a time (job_split), marks the Pareto fronts
// and compares every point with the defaults point.
std::vector<SweepResult> run_sweep(const EvalConfig& config, const std::vector<SweepPoint>& points);

// Sets `pareto` on the points no other point of the same animation dominates (mean cost <= and
// mean RMS <=, one of them strictly).
void mark_pareto(std::vector<SweepResult>* results);

// Sets `vs_default` of every point against the first point of its animation whose knob is
// "default" (none: every point stays kWithinSpread).
void compare_with_defaults(std::vector<SweepResult>* results);

// A point's result from its runs (one per seed, all of one animation).
SweepResult sweep_result(const SweepPoint& point, const std::vector<RunResult>& runs,
                         double seconds_shown);

void write_sweep_csv(const std::vector<SweepResult>& results, const std::filesystem::path& file);
std::string sweep_markdown(const std::vector<SweepResult>& results);
// tradeoff-<animation>.png per animation (gnuplot): RMS against cost, one series per knob,
// each point with its range over the seeds, the Pareto front as a line. Returns the PNGs made.
std::vector<std::filesystem::path> write_sweep_plots(const std::vector<SweepResult>& results,
                                                     const std::filesystem::path& folder);

}  // namespace afr::eval
