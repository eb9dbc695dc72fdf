// decode_image: encoded texture bytes (a glTF's PNG or JPEG, or WebP with EXT_texture_webp, from
// a file or from inside a .glb) to 8-bit pixels, through stb_image (libwebp for WebP). Kept apart
// from image_io.cpp so that a program that loads scenes but never writes an image file
// (sampler_node, most tests) does not load OpenImageIO and the 260 shared libraries it brings,
// which cost each process about 0.2 s and 130 MB at start (0.5 s under AddressSanitizer). tinygltf
// already links stb_image.
#include "image_formats.h"

#include <afr/common/error.h>
#include <afr/common/image.h>

#include <fmt/format.h>
#include <stb/stb_image.h>
#include <webp/decode.h>

#include <algorithm>
#include <climits>
#include <cstring>
#include <initializer_list>
#include <memory>

namespace afr {
namespace image_formats {

std::string sniff(std::span<const uint8_t> b) {
  auto starts_with = [&](std::initializer_list<uint8_t> magic) {
    return b.size() >= magic.size() && std::equal(magic.begin(), magic.end(), b.begin());
  };
  if (starts_with({0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A})) return "png";
  if (starts_with({0xFF, 0xD8, 0xFF})) return "jpeg";
  if (starts_with({'B', 'M'})) return "bmp";
  if (starts_with({'G', 'I', 'F', '8'})) return "gif";
  if (starts_with({0x76, 0x2F, 0x31, 0x01})) return "openexr";
  if (starts_with({'I', 'I', '*', 0}) || starts_with({'M', 'M', 0, '*'})) return "tiff";
  if (starts_with({'#', '?'})) return "hdr";
  if (b.size() >= 12 && starts_with({'R', 'I', 'F', 'F'}) && std::memcmp(&b[8], "WEBP", 4) == 0) {
    return "webp";
  }
  if (b.size() >= 2 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6') {
    // P5 and P6 are binary gray and color; P1-P4 are ASCII or 1-bit.
    return b[1] == '5' || b[1] == '6' ? "pnm" : "pnm-ascii";
  }
  return {};
}

bool decoded_in_memory(const std::string& format) {
  return format == "png" || format == "jpeg" || format == "bmp" || format == "gif" ||
         format == "pnm" || format == "webp";
}

}  // namespace image_formats

namespace {

void check_size(int width, int height, int channels, const std::string& name) {
  if (width <= 0 || height <= 0 || channels < 1 || channels > 4) {
    throw Error(fmt::format("{}: image has no pixels ({} x {}, {} channels)", name, width, height,
                            channels));
  }
  if (width > image_formats::kMaxImageSide || height > image_formats::kMaxImageSide ||
      uint64_t(width) * uint64_t(height) > image_formats::kMaxImagePixels) {
    throw Error(
        fmt::format("{}: image of {} x {} pixels is larger than afr accepts", name, width, height));
  }
}

// WebP (EXT_texture_webp) through libwebp: RGB, or RGBA where the image has alpha; the header
// first, as for the other formats, since decoding allocates what it claims.
DecodedImage decode_webp(std::span<const uint8_t> bytes, const std::string& name) {
  WebPBitstreamFeatures features;
  if (WebPGetFeatures(bytes.data(), bytes.size(), &features) != VP8_STATUS_OK) {
    throw Error(fmt::format("{}: cannot decode webp image: its header is not valid", name));
  }
  const int channels = features.has_alpha ? 4 : 3;
  check_size(features.width, features.height, channels, name);
  DecodedImage image;
  image.width = features.width;
  image.height = features.height;
  image.channels = channels;
  image.data.resize(size_t(image.width) * size_t(image.height) * size_t(channels));
  const int stride = image.width * channels;
  const uint8_t* done = channels == 4
                            ? WebPDecodeRGBAInto(bytes.data(), bytes.size(), image.data.data(),
                                                 image.data.size(), stride)
                            : WebPDecodeRGBInto(bytes.data(), bytes.size(), image.data.data(),
                                                image.data.size(), stride);
  if (done == nullptr) throw Error(fmt::format("{}: cannot decode webp image", name));
  return image;
}

}  // namespace

DecodedImage decode_image(std::span<const uint8_t> bytes, const std::string& name) {
  using namespace image_formats;
  if (bytes.empty()) throw Error(fmt::format("{}: image data is empty", name));
  const std::string format = sniff(bytes);
  if (format.empty()) {
    throw Error(
        fmt::format("{}: not an image format afr can decode (expected PNG, JPEG or WebP)", name));
  }
  if (!decoded_in_memory(format)) {
    throw Error(
        fmt::format("{}: {} images are not decoded as textures (expected PNG, JPEG or WebP)", name,
                    format == "pnm-ascii" ? "ASCII PNM" : format));
  }
  if (bytes.size() > size_t(INT_MAX)) {
    throw Error(
        fmt::format("{}: {} bytes of image data are more than afr accepts", name, bytes.size()));
  }
  if (format == "webp") return decode_webp(bytes, name);
  const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
  const int size = static_cast<int>(bytes.size());
  // The header first: its size is untrusted, and decoding allocates what it claims.
  int width = 0, height = 0, channels = 0;
  if (stbi_info_from_memory(data, size, &width, &height, &channels) == 0) {
    throw Error(fmt::format("{}: cannot decode {} image: {}", name, format, stbi_failure_reason()));
  }
  check_size(width, height, channels, name);
  // Values as stored: stb_image neither premultiplies alpha nor converts color, and takes
  // 16-bit channels to their high byte.
  int w = 0, h = 0, n = 0;
  std::unique_ptr<stbi_uc, decltype(&stbi_image_free)> pixels(
      stbi_load_from_memory(data, size, &w, &h, &n, channels), &stbi_image_free);
  if (!pixels || w != width || h != height) {
    throw Error(fmt::format("{}: cannot decode {} image: {}", name, format,
                            pixels ? "its size changed while decoding" : stbi_failure_reason()));
  }
  DecodedImage image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.data.assign(pixels.get(), pixels.get() + size_t(width) * size_t(height) * size_t(channels));
  return image;
}

}  // namespace afr
