// Flag parsing shared by every afr program: image sizes, log levels and the common flags,
// on top of CLI11.
#pragma once

#include <afr/common/rect.h>

#include <optional>
#include <string>
#include <string_view>

namespace CLI {
class App;
class Validator;
}  // namespace CLI

namespace afr {

// Parses "WxH" (e.g. "256x256"); both in [1, kMaxImageDimension]. Throws afr::Error naming
// the text and the problem.
inline constexpr int kMaxImageDimension = 32768;
ImageExtent parse_image_size(std::string_view text);

// The image size of `pixels`' pixel count whose width over height is `aspect` (a camera's
// CameraModel::aspect_ratio; taken within [1/16, 16]), each side rounded, at least 1: how a
// program sizes its image by the scene's camera where no size is given.
ImageExtent image_size_for_aspect(ImageExtent pixels, double aspect);

// Gives every floating-point option of `app` and of its subcommands a check that refuses NaN
// and infinities, naming the option and the value (CLI::Range lets NaN through: every
// comparison with it is false). Call once the options are added, before parsing.
void refuse_non_finite(CLI::App& app);

// That check, for an option of another type that takes numbers too (a word or a number).
CLI::Validator finite_number();

// --ray-depth N (0 to kMaxRayDepth, Scene::ray_depth) into *depth, its help saying `where` the
// depth goes: the programs that set a scene's ray depth all describe it so.
void add_ray_depth_option(CLI::App& app, std::optional<int>* depth, std::string_view where);

}  // namespace afr
