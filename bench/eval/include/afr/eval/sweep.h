// The speed/accuracy trade (docs/tradeoffs.md): runs of the adaptive renderer with one knob
// changed at a time from the defaults (R, b, r, chunk, the reconstructor's N, the tile count
// bounds and the filter clamps), plus the framed, frameless and TAA baselines over R, each
// scored by mean RMS against the ideal frames and by wall-clock cost, with the Pareto front
// (no other point both cheaper and more accurate) marked per animation. control_sweep() does
// the same for the sampler's control weights (kappa, lambda, m, i), which docs/sampler.md
// chose with it.
#pragma once

#include <afr/eval/evaluation.h>

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
  double mean_rms = 0.0;
  // Wall seconds per second of animation: sampling wall time over the virtual seconds sampled
  // plus reconstruction wall time over the seconds of frames shown. 1 is real time on this
  // machine.
  double cost = 0.0;
  double sample_seconds = 0.0;
  double reconstruct_seconds = 0.0;
  bool pareto = false;
};

// The default sweep around `base` (knob values in docs/tradeoffs.md).
std::vector<SweepPoint> default_sweep();

// The sampler's control weights one at a time around `base`, adaptive at R = 400K: kappa
// (variance) 0.2, 0.4, 0.8 and 1 (lambda lowered to 1 - kappa where the sum would pass 1),
// lambda (undersampling) 0, 0.1, 0.4, m (undersampling threshold) 0.5, 1, 2, 4, 8, i (temporal
// importance in gain control) 0.01, 0.03, 0.3, 1, and the defaults point.
std::vector<SweepPoint> control_sweep();

// The knob names of default_sweep() then control_sweep(), each once, "default" first.
std::vector<std::string> sweep_knobs();

// The defaults point, then the points of default_sweep() and control_sweep() whose knob is
// one of `knobs` (afr-eval --sweep --knobs kappa,lambda,m,i). Throws afr::Error naming an
// unknown knob and the known ones.
std::vector<SweepPoint> select_sweep(const std::vector<std::string>& knobs);

// Runs every point on every animation of `config` (config.methods and config.rates are not
// used) and marks the Pareto fronts.
std::vector<SweepResult> run_sweep(const EvalConfig& config, const std::vector<SweepPoint>& points);

// Sets `pareto` on the points no other point of the same animation dominates (cost <= and
// RMS <=, one of them strictly).
void mark_pareto(std::vector<SweepResult>* results);

void write_sweep_csv(const std::vector<SweepResult>& results, const std::filesystem::path& file);
std::string sweep_markdown(const std::vector<SweepResult>& results);
// tradeoff-<animation>.png per animation (gnuplot): RMS against cost, one series per knob,
// the Pareto front as a line. Returns the PNGs made.
std::vector<std::filesystem::path> write_sweep_plots(const std::vector<SweepResult>& results,
                                                     const std::filesystem::path& folder);

}  // namespace afr::eval
