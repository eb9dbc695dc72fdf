#include <afr/display/backend.h>

#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/display/cpu_reconstructor.h>
#include <afr/display/gl_context.h>
#include <afr/display/gl_reconstructor.h>

#include <fmt/format.h>

namespace afr {

Backend parse_backend(std::string_view text) {
  if (text == "auto") return Backend::kAuto;
  if (text == "gl") return Backend::kGl;
  if (text == "cpu") return Backend::kCpu;
  throw Error("--backend '" + std::string(text) + "': expected gl, cpu or auto");
}

const char* backend_name(Backend backend) {
  switch (backend) {
    case Backend::kAuto:
      return "auto";
    case Backend::kGl:
      return "gl";
    case Backend::kCpu:
      return "cpu";
  }
  return "?";
}

BackendChoice make_reconstructor(Backend backend, const ReconstructorConfig& config,
                                 const GlBackendOptions& gl) {
  BackendChoice choice;
  bool fell_back = false;
  if (backend == Backend::kCpu) {
    choice.reason = "reconstruction backend: cpu (requested)";
  } else {
    std::string error;
    std::shared_ptr<EglContext> context =
        EglContext::create_headless(HeadlessGlOptions{gl.gpu}, &error);
    if (context == nullptr) {
      choice.reason = fmt::format("reconstruction backend: cpu ({}: no OpenGL context: {})",
                                  backend == Backend::kGl ? "gl requested but" : "auto", error);
      fell_back = backend == Backend::kGl;
    } else if (backend == Backend::kAuto && context->software()) {
      choice.reason = fmt::format(
          "reconstruction backend: cpu (auto: OpenGL renderer '{}' on {} is a software "
          "rasteriser)",
          context->renderer(), context->device());
    } else {
      try {
        auto reconstructor = std::make_unique<GlReconstructor>(config, context, gl.reconstructor);
        choice.reason = fmt::format(
            "reconstruction backend: gl ({}: renderer '{}' on {}, {}, {} splats)",
            backend == Backend::kGl ? "requested" : "auto", context->renderer(), context->device(),
            context->version(), gl_splat_name(reconstructor->splat_method()));
        choice.reconstructor = std::move(reconstructor);
        choice.chosen = Backend::kGl;
      } catch (const Error& e) {
        choice.reason =
            fmt::format("reconstruction backend: cpu (the OpenGL backend failed: {})", e.what());
        fell_back = true;
      }
    }
  }
  if (choice.reconstructor == nullptr) {
    choice.reconstructor = std::make_unique<CpuReconstructor>(config);
    choice.chosen = Backend::kCpu;
  }
  if (fell_back) {
    spdlog::warn("{}", choice.reason);
  } else {
    spdlog::info("{}", choice.reason);
  }
  return choice;
}

}  // namespace afr
