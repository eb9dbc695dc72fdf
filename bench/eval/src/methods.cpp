#include <afr/eval/methods.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <array>
#include <string>

namespace afr::eval {

namespace {

constexpr std::array<Method, 7> kMethods = {
    Method::kFramed60,  Method::kFramedFullRes,          Method::kFrameless,
    Method::kFramedTaa, Method::kAdaptiveNoReprojection, Method::kAdaptive,
    Method::kFullRes60,
};

}  // namespace

std::span<const Method> all_methods() { return kMethods; }

const char* method_name(Method method) {
  switch (method) {
    case Method::kFramed60:
      return "framed-60hz";
    case Method::kFramedFullRes:
      return "framed-full-res";
    case Method::kFrameless:
      return "frameless";
    case Method::kAdaptive:
      return "adaptive";
    case Method::kAdaptiveNoReprojection:
      return "adaptive-no-reproj";
    case Method::kFullRes60:
      return "full-res-60hz";
    case Method::kFramedTaa:
      return "framed-taa";
  }
  return "?";
}

const char* method_label(Method method) {
  switch (method) {
    case Method::kFramed60:
      return "Framed 60 Hz";
    case Method::kFramedFullRes:
      return "Framed full res";
    case Method::kFrameless:
      return "Traditional frameless";
    case Method::kAdaptive:
      return "Adaptive";
    case Method::kAdaptiveNoReprojection:
      return "Adaptive, no reprojection";
    case Method::kFullRes60:
      return "Full res 60 Hz (W x H x 60 /s)";
    case Method::kFramedTaa:
      return "Framed 60 Hz + TAA";
  }
  return "?";
}

Method parse_method(std::string_view name) {
  std::string names;
  for (Method m : kMethods) {
    if (name == method_name(m)) return m;
    names += names.empty() ? "" : ", ";
    names += method_name(m);
  }
  throw Error(fmt::format("unknown method '{}' (expected one of {})", name, names));
}

bool method_uses_rate(Method method) { return method != Method::kFullRes60; }

bool method_is_frameless(Method method) {
  return method == Method::kFrameless || method == Method::kAdaptive ||
         method == Method::kAdaptiveNoReprojection;
}

bool method_uses_seed(Method method) {
  return method != Method::kFramed60 && method != Method::kFullRes60;
}

}  // namespace afr::eval
