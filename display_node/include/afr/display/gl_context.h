// OpenGL contexts for the GL reconstructor: a headless one through EGL (tests, benchmarks,
// servers without a display), and the GLFW window's (glfw_window.h). Both give an OpenGL 4.3+
// core profile. The headless context takes an EGL device (EGL_EXT_platform_device: NVIDIA's
// driver on a GPU server, Mesa's drivers), hardware first, or Mesa's surfaceless platform.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace afr {

class GlContext {
 public:
  virtual ~GlContext() = default;
  // Makes the context current on the calling thread.
  virtual void make_current() = 0;

  // GL_RENDERER and GL_VERSION, read when the context was made.
  const std::string& renderer() const { return renderer_; }
  const std::string& version() const { return version_; }
  // True for software rasterisers (llvmpipe, softpipe, swrast, SwiftShader, ...).
  bool software() const;

 protected:
  // Reads the strings; the context must be current.
  void query_strings();

  std::string renderer_;
  std::string version_;
};

// By GL_RENDERER: a driver that rasterises on the CPU.
bool is_software_renderer(std::string_view renderer);

// One device that EGL lists (EGL_EXT_device_enumeration), in EGL's order.
struct EglDevice {
  int index = 0;
  bool software = false;         // EGL_MESA_device_software: a CPU rasteriser
  std::string drm_file;          // EGL_DRM_DEVICE_FILE_EXT, when the driver names one
  std::string extensions;        // the device's own extension string
  std::string describe() const;  // "device 0 (hardware, /dev/dri/card0)"
};

// The devices EGL lists; empty, with the reason in *why, when EGL cannot enumerate devices.
std::vector<EglDevice> egl_devices(std::string* why);

struct HeadlessGlOptions {
  // -1: the first hardware device that gives a context, else Mesa's surfaceless platform,
  // else a software device. N >= 0: EGL device N alone (--gpu N).
  int gpu = -1;
  // A debug context: the driver's messages (where buffers live, stalls, errors) are logged at
  // debug level (afr-bench-reconstruct --gl-debug).
  bool debug = false;
};

// A context without any surface, OpenGL 4.3 core, made current with no draw surface (it
// renders to FBOs), through libepoxy's EGL.
class EglContext final : public GlContext {
 public:
  // nullptr, with the reason in *error, when no such context can be made: the reason names
  // every device and platform tried and what each answered. Leaves the context current.
  static std::unique_ptr<EglContext> create_headless(const HeadlessGlOptions& options,
                                                     std::string* error);
  static std::unique_ptr<EglContext> create_headless(std::string* error) {
    return create_headless(HeadlessGlOptions{}, error);
  }
  ~EglContext() override;
  void make_current() override;

  // Where the context runs: "EGL device 0 (hardware, /dev/dri/card0)" or "Mesa surfaceless
  // platform".
  const std::string& device() const { return device_; }

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  std::string device_;
};

}  // namespace afr
