// What samplers emit and reconstructors consume: frameless samples in batches and tiling
// snapshots at the refresh rate, and the sink interface that receives them (the network in
// sampler_node, the reconstructor directly in evaluations and tests).
#pragma once

#include <afr/common/math.h>
#include <afr/common/rect.h>

#include <cstdint>
#include <vector>

namespace afr {

// Which optional fields a batch's samples carry (DESIGN.md, "Samples and what they carry").
enum SampleField : uint32_t {
  kFieldPosition = 1u << 0,  // world hit point, or the ray direction for a miss
  kFieldVelocity = 1u << 1,  // world velocity of the hit point (scenes with moving objects)
};

// One primary ray's result. Fields not named in the batch's `fields` are left zero.
struct Sample {
  double time = 0.0;  // display-clock seconds at which the ray was traced
  float x = 0.0f;     // image position in pixels (sub-pixel), y down
  float y = 0.0f;
  glm::vec3 color{0.0f};  // linear RGB
  glm::vec3 position{0.0f};
  glm::vec3 velocity{0.0f};
  bool miss = false;  // position is a direction (the ray hit nothing)
};

struct SampleBatch {
  uint32_t sampler_id = 0;
  uint64_t sequence = 0;  // per sampler, +1 per batch
  uint32_t fields = 0;    // SampleField bits
  std::vector<Sample> samples;
  // The display's proof that the batch comes from the member `sampler_id` names: the token of
  // that member's welcome (docs/protocol.md). 0 where samples stay in one process.
  uint64_t token = 0;
};

// One tile of a tiling snapshot: what the reconstructor's tile field reads (section 4.2).
struct TileInfo {
  PixelRect rect;
  float G_x = 0.0f;  // luminance per pixel
  float G_y = 0.0f;
  float G_t = 0.0f;    // luminance per second
  float v = 0.0f;      // age-weighted luminance variance
  float E = 0.0f;      // error that drives split and merge
  uint32_t count = 0;  // crosshairs in the tile's block
  float rate = 0.0f;   // local sampling rate, samples per pixel per second
};

struct TilingSnapshot {
  uint32_t sampler_id = 0;
  double time = 0.0;  // display-clock seconds
  PixelRect region;   // the part of the image this sampler owns
  std::vector<TileInfo> tiles;
  uint64_t token = 0;  // as SampleBatch::token
};

// Receives the sampler's output, on the sampler's thread. Batches are handed over by value
// and may be kept.
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void on_batch(SampleBatch&& batch) = 0;
  virtual void on_tiling(TilingSnapshot&& snapshot) = 0;
  // The sampler is no longer a member of the display (it left, was declared dead, or a wall's
  // lead dropped it): forget what is kept of it besides its samples (its tiling). Ingest
  // thread.
  virtual void on_sampler_gone(uint32_t /*sampler_id*/) {}
};

}  // namespace afr
