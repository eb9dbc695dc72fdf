// Framed rendering with temporal accumulation: the modern alternative to frameless rendering
// that the evaluation adds to the paper's methods. Each frame traces one jittered sample per
// cell of a reduced w' x h' grid (the same R/60 samples as framed 60 Hz) and accumulates them
// into a full-resolution history (temporal upsampling, as TAAU/FSR 2/DLSS do):
//   - jitter: the Halton (2, 3) sequence over 16 frames, in grid cells;
//   - motion: every sample's world point is moved back by its velocity over one frame period
//     and projected with the previous frame's camera; each output pixel takes the motion of
//     the nearest sample of this frame (misses move with the camera's rotation only);
//   - history: fetched with a Catmull-Rom filter where the motion says the pixel was, then
//     clamped to the box of this frame's samples in the 3 x 3 cells around the pixel (mean
//     +- gamma standard deviations, inside their min/max: neighbourhood clamping with variance
//     clipping), and blended with this frame's samples by accumulated weight:
//       out = (w_h clamp(h) + sum_i g_i c_i) / (w_h + sum_i g_i),
//     g_i = exp(-d_i^2 / (2 sigma^2)) for the samples within the 3 x 3 cells at distance d_i,
//     w_h = min(weight history, max_history_weight);
//   - where there is no history (the first frame, or the pixel came from outside the image)
//     the pixel is the Gaussian-weighted mean of those samples with sigma one grid cell.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/image.h>
#include <afr/sampler/tracer.h>

#include <cstdint>
#include <vector>

namespace afr::eval {

struct TaaOptions {
  // Caps the history's weight: a sample at a pixel's center then gets at least
  // 1 / (1 + max_history_weight) of the pixel (0.1 for 9, the usual TAA blend factor; 2 was
  // better on the built-in scene at 128 x 128, 100K and 400K: docs/evaluation.md).
  double max_history_weight = 2.0;
  // Standard deviation of a sample's weight g_i in output pixels.
  double sample_sigma = 0.5;
  // Weight of the spatially upsampled value where there is no history.
  double fallback_weight = 0.1;
  bool clamp = true;  // neighbourhood clamping (off: plain exponential accumulation)
  // The clamp box: mean +- clamp_gamma standard deviations of the neighbourhood's samples,
  // inside their min/max box (variance clipping).
  double clamp_gamma = 1.25;
};

class TemporalAccumulator {
 public:
  // Output width x height, grid grid_width x grid_height.
  TemporalAccumulator(int width, int height, int grid_width, int grid_height,
                      const TaaOptions& options);

  // Frame k: traces the grid at scene time `time` (the tracer is moved there) with jitter k,
  // reprojects the history of the previous call (whose time was that call's) and returns the
  // accumulated image. Calls must come in increasing k and time. Adds rays to *stats.
  const Image& render(Tracer& tracer, int64_t k, double time, int threads, TraceStats* stats);

  // The jitter of frame k, in grid cells, in [0, 1)^2.
  static glm::dvec2 jitter(int64_t k);

  // Wall seconds spent tracing and resolving, over all calls.
  double trace_seconds() const { return trace_seconds_; }
  double resolve_seconds() const { return resolve_seconds_; }

 private:
  struct GridSample {
    glm::vec3 color{0.0f};
    glm::vec2 position{0.0f};  // output pixels
    glm::vec2 motion{0.0f};    // output pixels: where it was in the previous frame, minus here
    bool has_motion = false;
  };

  int width_, height_, grid_width_, grid_height_;
  TaaOptions options_;
  std::vector<GridSample> grid_;
  Image history_, next_;
  std::vector<float> weight_, next_weight_;
  bool has_history_ = false;
  Camera previous_camera_;
  double previous_time_ = 0.0;
  double trace_seconds_ = 0.0;
  double resolve_seconds_ = 0.0;
};

}  // namespace afr::eval
