// The framed baselines of section 7. A framed renderer samples the input (camera and scene) at
// the moment it starts a frame, traces every pixel of the frame at that one time, and shows the
// frame only when it is done (double buffering): the frame shown at display time t carries the
// input of the time its rendering began, at least one frame period before t.
#pragma once

#include <afr/common/image.h>
#include <afr/common/scene.h>
#include <afr/sampler/tracer.h>

#include <cstdint>

namespace afr::eval {

// When framed rendering starts and shows frames. Frame k takes the input of
// input_time(k) = origin + k period, is traced during [input_time(k), input_time(k + 1)) and is
// shown from input_time(k + 1) until the next frame is done. The renderer is taken to have
// run for ever, so every display time has a frame (k may be negative). With a display
// latency L (RunSettings::latency) a frame is also shown no earlier than input_time(k) + L:
// the display rule every method follows; for L <= period it changes nothing.
struct FrameSchedule {
  double origin = 0.0;
  double period = 1.0 / 60.0;
  double latency = 0.0;

  double input_time(int64_t k) const { return origin + double(k) * period; }
  // The frame shown at display time t: the largest k with input_time(k + 1) <= t (done) and
  // input_time(k) <= t - latency. A display time within 1e-9 periods of a bound counts as
  // after it (display times and completions of 60 Hz frames coincide, but are computed in
  // floating point).
  int64_t frame_shown_at(double t) const;
};

// The resolution of a framed renderer with `samples_per_frame` samples for a width x height
// display: h' = floor(sqrt(samples_per_frame / aspect)), w' = floor(h' aspect), so that
// w' h' <= samples_per_frame and w' / h' is the display's aspect (clamped to 1 x 1 ..
// width x height). 256 x 256 at 400K/60 samples: 81 x 81.
void framed_resolution(double samples_per_frame, int width, int height, int* w, int* h);

// Traces one sample at every pixel center of a width x height frame (no antialiasing) with the
// tracer moved to scene time `time` and its camera, on `threads` threads. Adds the frame's
// rays to *stats.
Image trace_frame(Tracer& tracer, double time, int width, int height, int threads,
                  TraceStats* stats);

// Bilinear magnification with pixel centers aligned (what a GPU's linear texture filter does
// when a small frame is drawn over the whole window); edges clamp.
Image upsample_bilinear(const Image& source, int width, int height);

}  // namespace afr::eval
