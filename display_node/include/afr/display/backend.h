// Choosing a reconstruction backend: --backend gl|cpu|auto. "auto" takes OpenGL on a hardware
// driver and the CPU backend on a software rasteriser (on llvmpipe the CPU backend is several
// times faster); every choice falls back to the CPU when no OpenGL context can be made.
#pragma once

#include <afr/display/gl_reconstructor.h>
#include <afr/display/reconstructor.h>

#include <memory>
#include <string>
#include <string_view>

namespace afr {

enum class Backend { kAuto, kGl, kCpu };

// "auto", "gl", "cpu"; throws afr::Error naming the text otherwise.
Backend parse_backend(std::string_view text);
const char* backend_name(Backend backend);

struct BackendChoice {
  std::unique_ptr<Reconstructor> reconstructor;
  Backend chosen = Backend::kCpu;
  std::string reason;  // one line for the log: what was chosen and why
};

// How a GL backend is made: which EGL device (--gpu) and which splat pass (--gl-splat).
struct GlBackendOptions {
  int gpu = -1;  // HeadlessGlOptions::gpu
  GlReconstructorOptions reconstructor;
};

// Makes the reconstructor; a GL one gets its own headless EGL context, current on the calling
// thread (which must then be the reconstructing thread). Logs the reason at info level (warn
// when a requested GL backend fell back), naming the EGL device and renderer.
BackendChoice make_reconstructor(Backend backend, const ReconstructorConfig& config,
                                 const GlBackendOptions& gl = {});

}  // namespace afr
