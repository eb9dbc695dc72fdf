// The sampler's knobs as command-line flags, shared by every program that runs a sampler.
#pragma once

#include <afr/sampler/sampler_config.h>

#include <CLI/CLI.hpp>

namespace afr {

// Adds --b, --r, --chunk, --kappa, --lambda, --m, --i, --min-tiles, --max-tiles, --refresh,
// --seed, --fill-step, --crosshair-motion and --mode to `app`, writing into *config (defaults shown
// from it). Ranges are checked by SamplerConfig::validate() after parsing, which names the flag's
// field.
inline void add_sampler_flags(CLI::App& app, SamplerConfig* config) {
  app.add_option("--b", config->b, "deep buffer depth")->capture_default_str();
  app.add_option("--r", config->r, "reprojections per tile visit (0 = none)")
      ->capture_default_str();
  app.add_option("--chunk", config->chunk, "crosshairs between tiling adjustments")
      ->capture_default_str();
  app.add_option("--kappa", config->kappa, "error weight of variance")->capture_default_str();
  app.add_option("--lambda", config->lambda, "error weight of undersampling")
      ->capture_default_str();
  app.add_option("--m", config->m, "undersampling threshold")->capture_default_str();
  app.add_option("--i", config->i, "temporal importance in gain control")->capture_default_str();
  app.add_option("--min-tiles", config->min_tiles, "fewest tiles")->capture_default_str();
  app.add_option("--max-tiles", config->max_tiles, "most tiles")->capture_default_str();
  app.add_option("--refresh", config->refresh_interval, "seconds between tiling snapshots")
      ->capture_default_str();
  app.add_option("--seed", config->seed, "random seed")->capture_default_str();
  app.add_option("--fill-step", config->fill_step,
                 "initial fill: one crosshair every this many pixels (large images: larger)")
      ->capture_default_str();
  app.add_option("--crosshair-motion", config->crosshair_motion,
                 "how reprojection moves crosshairs on rigidly moving objects: velocity (as the "
                 "display moves samples) or transform (exact)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, CrosshairMotion>{{"velocity", CrosshairMotion::kVelocity},
                                                 {"transform", CrosshairMotion::kTransform}},
          CLI::ignore_case));
  app.add_option("--mode", config->mode, "adaptive, uniform (traditional frameless) or framed")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, SamplerMode>{{"adaptive", SamplerMode::kAdaptive},
                                             {"uniform", SamplerMode::kUniformRandom},
                                             {"framed", SamplerMode::kFramedSweep}},
          CLI::ignore_case));
}

}  // namespace afr
