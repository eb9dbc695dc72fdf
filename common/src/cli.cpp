#include <afr/common/cli.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <charconv>

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

}  // namespace afr
