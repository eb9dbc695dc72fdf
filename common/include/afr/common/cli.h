// Flag parsing shared by every afr program: image sizes, log levels and the common flags,
// on top of CLI11.
#pragma once

#include <string>
#include <string_view>

namespace afr {

struct ImageSize {
  int width = 0;
  int height = 0;
};

// Parses "WxH" (e.g. "256x256"); both in [1, kMaxImageDimension]. Throws afr::Error naming
// the text and the problem.
inline constexpr int kMaxImageDimension = 32768;
ImageSize parse_image_size(std::string_view text);

}  // namespace afr
