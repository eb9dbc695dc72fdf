// OpenGL contexts for the GL reconstructor: a headless one through EGL on Mesa's surfaceless
// platform (tests, benchmarks, servers without a display), and the GLFW window's
// (glfw_window.h). Both give an OpenGL 4.3+ core profile.
#pragma once

#include <memory>
#include <string>
#include <string_view>

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

// A context without any surface: eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA)
// through libepoxy, OpenGL 4.3 core, made current with no draw surface (render to FBOs).
class EglContext final : public GlContext {
 public:
  // nullptr, with the reason in *error, when no such context can be made (no EGL, no Mesa
  // surfaceless platform, no GL 4.3 core). Leaves the context current.
  static std::unique_ptr<EglContext> create_headless(std::string* error);
  ~EglContext() override;
  void make_current() override;

 private:
  EglContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
};

}  // namespace afr
