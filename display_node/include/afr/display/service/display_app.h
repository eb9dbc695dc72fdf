// The display node as an application: the frame loop that asks its role (display_role.h) for
// the time and camera of each image, has the reconstructor make it, shows it in a window or
// writes it (headless), runs the wall exchange around it, reads the keyboard and mouse, and
// logs the stats. display_node's main() parses the flags, builds the role and hands both here.
//
// One thread: run() on the thread that made the window (GLFW and the GL context are bound to
// it). The role's own threads (control, ingest, HTTP) run beside it.
#pragma once

#include <afr/common/presets.h>
#include <afr/common/samples.h>
#include <afr/display/backend.h>
#include <afr/display/reconstructor.h>
#include <afr/display/service/display_role.h>
#include <afr/protocol/channels.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <string>

namespace afr::service {

// The ingest side of a display: batches and tilings go to the target set last (none: they are
// dropped). A follower's samples arrive once the lead admits it, before the reconstructor
// (sized from the lead's layout) exists.
class SwitchSink final : public SampleSink {
 public:
  void set(SampleSink* target);
  void on_batch(SampleBatch&& batch) override;
  void on_tiling(TilingSnapshot&& snapshot) override;
  void on_sampler_gone(uint32_t sampler_id) override;

 private:
  std::mutex mutex_;
  SampleSink* target_ = nullptr;
};

// The reconstructor of a display node: the preset's filter, the image and this node's cell
// with `margin` pixels of samples around it, and N = `capacity` samples, or (0) the preset's
// samples per pixel times the pixels it receives samples for (the samplers' routing rule: the
// cell grown by the margin, clipped to the image), at most kMaxCapacity.
ReconstructorConfig display_reconstructor_config(const Preset& preset, ReconstructionMode mode,
                                                 int width, int height, PixelRect cell, int margin,
                                                 size_t capacity);

// The display's memory with the reconstructor of `config` (CPU backend; a GPU one keeps less
// here), bytes: a fixed part plus so much a stored sample and a pixel of the reconstructed
// grid, from display_node's measured peak resident size (docs/robustness.md, "Admission").
uint64_t display_memory_estimate(const ReconstructorConfig& config);
// The default of display_node's --memory-limit: 80% of the memory available now (the kernel's
// MemAvailable; the physical memory where it does not say).
uint64_t default_memory_limit();
// Throws afr::Error naming the estimate, its parts and the limit when the estimate exceeds it.
void check_memory(const ReconstructorConfig& config, uint64_t limit);

struct DisplayAppOptions {
  bool headless = false;  // no window: images at `fps` into `output`
  Backend backend = Backend::kAuto;
  GlBackendOptions gl;  // --gpu, --gl-splat (the window's context takes only the splat pass)
  double fps = 30.0;
  double seconds = 0.0;  // stop after this long; 0: until the stop flag
  double stats_interval = 2.0;
  int screenshot_every = 0;  // headless: an image every K frames; 0: only the final one
  std::string output = "out";
  std::string record;     // write the views' camera path here at exit
  bool exchange = false;  // a wall's coverage and strays with the other nodes (docs/wall.md)
  protocol::Security peer_security;  // this node as a client of its peers' sample channels
};

class FlyCamera;

class DisplayApp {
 public:
  // Makes the window (unless headless; without a display it falls back to headless) and the
  // reconstructor, and points `ingest` at it. `fly`: --interactive's camera, steered with the
  // mouse and arrow keys (nullptr: none).
  DisplayApp(DisplayAppOptions options, DisplayRole& role, const ReconstructorConfig& config,
             SwitchSink& ingest, FlyCamera* fly = nullptr);
  ~DisplayApp();
  DisplayApp(const DisplayApp&) = delete;
  DisplayApp& operator=(const DisplayApp&) = delete;

  // Runs the frame loop until `stop` turns true (a signal, or Q / Esc in the window), the
  // window closes, `seconds` pass or the role fails; then writes the final image and the
  // recorded camera path. Returns the process exit status: 2 when the role failed, else 0.
  int run(std::atomic<bool>& stop);

  Reconstructor& reconstructor();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace afr::service
