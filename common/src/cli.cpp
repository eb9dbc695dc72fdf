#include <afr/common/cli.h>

#include <afr/common/error.h>
#include <afr/common/scene.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace afr {

ImageExtent parse_image_size(std::string_view text) {
  const size_t x = text.find_first_of("xX");
  const auto bad = [&](std::string_view why) {
    return Error(fmt::format("image size '{}': {} (expected WxH, e.g. 256x256)", text, why));
  };
  if (x == std::string_view::npos) throw bad("no 'x' between width and height");
  ImageExtent size;
  const auto parse = [&](std::string_view part, int32_t* out) {
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), *out);
    if (ec != std::errc() || end != part.data() + part.size() || part.empty()) {
      throw bad(fmt::format("'{}' is not a whole number", part));
    }
    if (*out < 1 || *out > kMaxImageDimension) {
      throw bad(fmt::format("{} is outside 1..{}", *out, kMaxImageDimension));
    }
  };
  parse(text.substr(0, x), &size.width);
  parse(text.substr(x + 1), &size.height);
  return size;
}

ImageExtent image_size_for_aspect(ImageExtent pixels, double aspect) {
  if (!(aspect > 0.0) || !std::isfinite(aspect)) return pixels;
  aspect = std::clamp(aspect, 1.0 / 16.0, 16.0);
  const double area = double(pixels.width) * double(pixels.height);
  const auto side = [](double v) {
    return int32_t(std::clamp(std::lround(v), 1L, long(kMaxImageDimension)));
  };
  return {side(std::sqrt(area * aspect)), side(std::sqrt(area / aspect))};
}

CLI::Validator finite_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end != text.c_str() && !std::isfinite(v)) {
          return fmt::format("{} is not a finite number", text);
        }
        return {};
      },
      "FINITE");
}

void refuse_non_finite(CLI::App& app) {
  const CLI::Validator finite = finite_number();
  for (CLI::Option* option : app.get_options()) {
    if (option->get_type_name().find("FLOAT") != std::string::npos) option->check(finite);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
    refuse_non_finite(*sub);
  }
}

void add_ray_depth_option(CLI::App& app, std::optional<int>* depth, std::string_view where) {
  app.add_option("--ray-depth", *depth,
                 fmt::format("secondary rays in a row (mirror reflections, glass's reflections "
                             "and refractions), {} (default: the file's extras.afr_ray_depth, "
                             "else 3)",
                             where))
      ->check(CLI::Range(0, kMaxRayDepth));
}

}  // namespace afr
