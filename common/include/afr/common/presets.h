// Named speed/accuracy presets: fast, balanced, accurate. Each sets the sampler's knobs and the
// reconstructor's settings that the evaluation's sweeps found on or next to the Pareto front of
// RMS error against wall-clock cost (docs/tradeoffs.md says how, with the commands). Plain
// numbers, so that both nodes stand on them without knowing each other: sampler_node applies
// the knobs with apply_preset (afr/sampler/sampler_config.h); display_node copies
// `reconstruction` into its ReconstructorConfig (capacity = samples_per_pixel x width x
// height, and the FilterLimits fields of the same names). A preset leaves everything it does
// not name at its default.
#pragma once

#include <afr/common/error.h>

#include <array>
#include <span>
#include <string>
#include <string_view>

namespace afr {

// The reconstructor's side of a preset.
struct ReconstructionPreset {
  double samples_per_pixel = 4.0;   // N = this x width x height (section 5.2: at least 4)
  float min_spatial_extent = 0.3f;  // FilterLimits, pixels
  float max_spatial_extent = 4.0f;
  float max_temporal_extent = 60.0f;  // FilterLimits, seconds
};

struct Preset {
  std::string_view name;
  std::string_view summary;
  // The sampler's knobs (SamplerConfig's fields of the same names).
  int b = 4;
  int r = 5;
  int chunk = 25;
  int min_tiles = 16;
  int max_tiles = 1024;
  ReconstructionPreset reconstruction;
};

// From the 256 x 256 sweeps of docs/tradeoffs.md: R is the knob that matters; r = 0 is the
// one bad setting; a smaller store (N) and fewer reprojections and tiling adjustments cost
// less for a few percent of error; a larger store and more reprojections and tiles lower the
// error where it is high (fast motion).
inline constexpr std::array<Preset, 3> kPresets = {{
    {"fast", "less work per sample: r = 2, chunk 100, N = 2 W H", /*b=*/4,
     /*r=*/2, /*chunk=*/100, /*min_tiles=*/16, /*max_tiles=*/1024,
     ReconstructionPreset{2.0, 0.3f, 4.0f, 60.0f}},
    {"balanced", "the paper's settings, afr's defaults: b = 4, r = 5, chunk 25, N = 4 W H", 4, 5,
     25, 16, 1024, ReconstructionPreset{4.0, 0.3f, 4.0f, 60.0f}},
    {"accurate", "lower error under fast motion: r = 10, up to 4096 tiles, N = 8 W H", 4, 10, 25,
     16, 4096, ReconstructionPreset{8.0, 0.3f, 4.0f, 60.0f}},
}};

inline std::span<const Preset> presets() { return kPresets; }

// The preset called `name`; throws afr::Error naming it and the known presets.
inline const Preset& find_preset(std::string_view name) {
  std::string names;
  for (const Preset& p : kPresets) {
    if (p.name == name) return p;
    names += names.empty() ? "" : ", ";
    names += p.name;
  }
  throw Error("unknown preset '" + std::string(name) + "' (expected " + names + ")");
}

}  // namespace afr
