// Lossless WebP bytes of an 8-bit RGB or RGBA image, for the tests of EXT_texture_webp (libwebp's
// encoder: lossless, so the decoded texels are the ones given).
#pragma once

#include <afr/common/image.h>

#include <webp/encode.h>

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace afr::testing {

inline std::vector<uint8_t> lossless_webp(const DecodedImage& image) {
  if (image.channels != 3 && image.channels != 4) {
    throw std::invalid_argument("lossless_webp: 3 or 4 channels");
  }
  uint8_t* out = nullptr;
  const int stride = image.width * image.channels;
  const size_t size =
      image.channels == 4
          ? WebPEncodeLosslessRGBA(image.data.data(), image.width, image.height, stride, &out)
          : WebPEncodeLosslessRGB(image.data.data(), image.width, image.height, stride, &out);
  if (size == 0 || out == nullptr) throw std::runtime_error("lossless_webp: encoding failed");
  std::vector<uint8_t> bytes(out, out + size);
  WebPFree(out);
  return bytes;
}

}  // namespace afr::testing
