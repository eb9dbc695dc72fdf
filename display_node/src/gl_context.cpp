#include <afr/display/gl_context.h>

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>

namespace afr {

bool is_software_renderer(std::string_view renderer) {
  std::string lower(renderer);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  for (const char* name : {"llvmpipe", "softpipe", "swrast", "software rasterizer", "swiftshader",
                           "lavapipe", "microsoft basic render"}) {
    if (lower.find(name) != std::string::npos) return true;
  }
  return false;
}

bool GlContext::software() const { return is_software_renderer(renderer_); }

void GlContext::query_strings() {
  const auto str = [](GLenum name) {
    const GLubyte* s = glGetString(name);
    return s != nullptr ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  renderer_ = str(GL_RENDERER);
  version_ = str(GL_VERSION);
}

std::unique_ptr<EglContext> EglContext::create_headless(std::string* error) {
  // libepoxy resolves EGL itself; without libEGL there is nothing to ask.
  if (!epoxy_has_egl()) {
    *error = "EGL is not available";
    return nullptr;
  }
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (client_extensions == nullptr ||
      std::string_view(client_extensions).find("EGL_MESA_platform_surfaceless") ==
          std::string_view::npos) {
    *error = "EGL has no EGL_MESA_platform_surfaceless";
    return nullptr;
  }
  EGLDisplay display =
      eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    *error = fmt::format("no surfaceless EGL display (EGL error 0x{:x})", eglGetError());
    return nullptr;
  }
  // The display is never terminated: EGL hands every caller the same display for the same
  // platform, so terminating it would pull it from under other contexts of this process.
  if (!eglBindAPI(EGL_OPENGL_API)) {
    *error = "EGL cannot bind the OpenGL API";
    return nullptr;
  }
  const std::array<EGLint, 7> attributes = {EGL_CONTEXT_MAJOR_VERSION,
                                            4,
                                            EGL_CONTEXT_MINOR_VERSION,
                                            3,
                                            EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                            EGL_NONE};
  // EGL_KHR_no_config_context: a context for FBO rendering needs no config.
  EGLContext context =
      eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes.data());
  if (context == EGL_NO_CONTEXT) {
    *error = fmt::format("no OpenGL 4.3 core context (EGL error 0x{:x})", eglGetError());
    return nullptr;
  }
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    *error = fmt::format("cannot make the context current without a surface (EGL error 0x{:x})",
                         eglGetError());
    eglDestroyContext(display, context);
    return nullptr;
  }
  std::unique_ptr<EglContext> c(new EglContext());
  c->display_ = display;
  c->context_ = context;
  c->query_strings();
  return c;
}

EglContext::~EglContext() {
  EGLDisplay display = static_cast<EGLDisplay>(display_);
  if (eglGetCurrentContext() == static_cast<EGLContext>(context_)) {
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }
  eglDestroyContext(display, static_cast<EGLContext>(context_));
}

void EglContext::make_current() {
  EGLDisplay display = static_cast<EGLDisplay>(display_);
  EGLContext context = static_cast<EGLContext>(context_);
  if (eglGetCurrentContext() != context) {
    eglBindAPI(EGL_OPENGL_API);
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context);
  }
}

}  // namespace afr
