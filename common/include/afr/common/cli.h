// Flag parsing shared by every afr program: image sizes, log levels and the common flags,
// on top of CLI11.
#pragma once

#include <afr/common/rect.h>

#include <string>
#include <string_view>

namespace afr {

// Parses "WxH" (e.g. "256x256"); both in [1, kMaxImageDimension]. Throws afr::Error naming
// the text and the problem.
inline constexpr int kMaxImageDimension = 32768;
ImageExtent parse_image_size(std::string_view text);

}  // namespace afr
