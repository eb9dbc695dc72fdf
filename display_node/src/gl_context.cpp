#include <afr/display/gl_context.h>

#include <afr/common/log.h>

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

namespace {

bool has_extension(const char* list, std::string_view name) {
  if (list == nullptr) return false;
  std::string_view rest(list);
  while (!rest.empty()) {
    const size_t space = rest.find(' ');
    if (rest.substr(0, space) == name) return true;
    if (space == std::string_view::npos) break;
    rest.remove_prefix(space + 1);
  }
  return false;
}

const char* client_extensions() { return eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS); }

// An OpenGL 4.3 core context on an initialised display, current with no surface; EGL_NO_CONTEXT
// with the reason in *error otherwise.
// `debug`: a debug context whose driver messages (errors, performance and memory notes) go to
// the log at debug level.
EGLContext make_context(EGLDisplay display, bool debug, std::string* error) {
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    *error = fmt::format("no EGL display (EGL error 0x{:x})", eglGetError());
    return EGL_NO_CONTEXT;
  }
  // The display is never terminated: EGL hands every caller the same display for the same
  // platform and device, so terminating it would pull it from under other contexts.
  if (!eglBindAPI(EGL_OPENGL_API)) {
    *error = "EGL cannot bind the OpenGL API";
    return EGL_NO_CONTEXT;
  }
  // The newest core profile the driver gives, 4.3 at least: a driver may answer a request
  // for 4.3 with exactly 4.3, without 4.4's persistent mappings or 4.5's direct access.
  EGLContext context = EGL_NO_CONTEXT;
  for (const EGLint minor : {6, 5, 3}) {
    const std::array<EGLint, 9> attributes = {EGL_CONTEXT_MAJOR_VERSION,
                                              4,
                                              EGL_CONTEXT_MINOR_VERSION,
                                              minor,
                                              EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                              EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                              debug ? EGL_CONTEXT_OPENGL_DEBUG : EGL_NONE,
                                              EGL_TRUE,
                                              EGL_NONE};
    // EGL_KHR_no_config_context: a context for FBO rendering needs no config.
    context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attributes.data());
    if (context != EGL_NO_CONTEXT) break;
  }
  if (context == EGL_NO_CONTEXT) {
    *error = fmt::format("no OpenGL 4.3 core context (EGL error 0x{:x})", eglGetError());
    return EGL_NO_CONTEXT;
  }
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    *error = fmt::format("cannot make the context current without a surface (EGL error 0x{:x})",
                         eglGetError());
    eglDestroyContext(display, context);
    return EGL_NO_CONTEXT;
  }
  if (debug) {
    glEnable(GL_DEBUG_OUTPUT);
    glDebugMessageCallback(
        [](GLenum, GLenum type, GLuint id, GLenum severity, GLsizei, const GLchar* message,
           const void*) {
          spdlog::debug("OpenGL debug message {} (type 0x{:x}, severity 0x{:x}): {}", id, type,
                        severity, message);
        },
        nullptr);
  }
  return context;
}

std::vector<EGLDeviceEXT> device_handles(std::string* why) {
  const char* client = client_extensions();
  if (!has_extension(client, "EGL_EXT_device_enumeration") &&
      !has_extension(client, "EGL_EXT_device_base")) {
    *why = "EGL has no EGL_EXT_device_enumeration";
    return {};
  }
  EGLint count = 0;
  if (!eglQueryDevicesEXT(0, nullptr, &count) || count <= 0) {
    *why = fmt::format("EGL lists no devices (EGL error 0x{:x})", eglGetError());
    return {};
  }
  std::vector<EGLDeviceEXT> handles(size_t(std::min(count, 64)));
  if (!eglQueryDevicesEXT(EGLint(handles.size()), handles.data(), &count)) {
    *why = fmt::format("EGL cannot list its devices (EGL error 0x{:x})", eglGetError());
    return {};
  }
  handles.resize(size_t(std::max(count, 0)));
  return handles;
}

}  // namespace

std::string EglDevice::describe() const {
  std::string d = fmt::format("EGL device {} ({}", index, software ? "software" : "hardware");
  if (!drm_file.empty()) d += ", " + drm_file;
  return d + ")";
}

std::vector<EglDevice> egl_devices(std::string* why) {
  if (!epoxy_has_egl()) {
    *why = "EGL is not available";
    return {};
  }
  std::vector<EglDevice> devices;
  const std::vector<EGLDeviceEXT> handles = device_handles(why);
  for (size_t i = 0; i < handles.size(); ++i) {
    EglDevice d;
    d.index = int(i);
    const char* extensions = eglQueryDeviceStringEXT(handles[i], EGL_EXTENSIONS);
    d.extensions = extensions != nullptr ? extensions : "";
    d.software = has_extension(extensions, "EGL_MESA_device_software");
    if (has_extension(extensions, "EGL_EXT_device_drm")) {
      const char* file = eglQueryDeviceStringEXT(handles[i], EGL_DRM_DEVICE_FILE_EXT);
      if (file != nullptr) d.drm_file = file;
    }
    devices.push_back(std::move(d));
  }
  return devices;
}

std::unique_ptr<EglContext> EglContext::create_headless(const HeadlessGlOptions& options,
                                                        std::string* error) {
  // libepoxy resolves EGL itself; without libEGL there is nothing to ask.
  if (!epoxy_has_egl()) {
    *error = "EGL is not available";
    return nullptr;
  }
  std::string why_no_devices;
  const std::vector<EglDevice> devices = egl_devices(&why_no_devices);
  const std::vector<EGLDeviceEXT> handles =
      devices.empty() ? std::vector<EGLDeviceEXT>{} : device_handles(&why_no_devices);
  const bool device_platform = has_extension(client_extensions(), "EGL_EXT_platform_device");
  const bool surfaceless = has_extension(client_extensions(), "EGL_MESA_platform_surfaceless");

  std::vector<std::string> tried;  // "what: why not", for the error
  const auto on = [&](EGLDisplay display, std::string where) -> std::unique_ptr<EglContext> {
    std::string why;
    EGLContext context = make_context(display, options.debug, &why);
    if (context == EGL_NO_CONTEXT) {
      tried.push_back(where + ": " + why);
      return nullptr;
    }
    std::unique_ptr<EglContext> c(new EglContext());
    c->display_ = display;
    c->context_ = context;
    c->device_ = std::move(where);
    c->query_strings();
    return c;
  };
  const auto on_device = [&](const EglDevice& d) -> std::unique_ptr<EglContext> {
    if (!device_platform) {
      tried.push_back(d.describe() + ": EGL has no EGL_EXT_platform_device");
      return nullptr;
    }
    return on(eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, handles[size_t(d.index)], nullptr),
              d.describe());
  };
  const auto listed = [&] {
    if (devices.empty()) return why_no_devices;
    std::string list;
    for (const EglDevice& d : devices) list += (list.empty() ? "" : ", ") + d.describe();
    return fmt::format("EGL lists {} device{}: {}", devices.size(), devices.size() == 1 ? "" : "s",
                       list);
  };

  if (options.gpu >= 0) {
    if (size_t(options.gpu) >= devices.size() || size_t(options.gpu) >= handles.size()) {
      *error = fmt::format("--gpu {}: no such EGL device ({})", options.gpu, listed());
      return nullptr;
    }
    if (auto c = on_device(devices[size_t(options.gpu)])) return c;
    *error = fmt::format("--gpu {}: {}", options.gpu, tried.back());
    return nullptr;
  }
  for (const EglDevice& d : devices) {
    if (d.software || size_t(d.index) >= handles.size()) continue;
    if (auto c = on_device(d)) return c;
  }
  if (surfaceless) {
    if (auto c = on(
            eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
            "Mesa surfaceless platform")) {
      return c;
    }
  } else {
    tried.push_back("Mesa surfaceless platform: EGL has no EGL_MESA_platform_surfaceless");
  }
  for (const EglDevice& d : devices) {
    if (!d.software || size_t(d.index) >= handles.size()) continue;
    if (auto c = on_device(d)) return c;
  }
  std::string reasons;
  for (const std::string& t : tried) reasons += "; " + t;
  *error = fmt::format("no headless OpenGL context ({}{})", listed(), reasons);
  return nullptr;
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
