// The image files of image.h, through OpenImageIO. Kept apart from image.cpp (pixels, sRGB,
// the error metric) and image_decode.cpp (textures in memory, stb_image) so that a program that
// never reads or writes an image file links without OpenImageIO and its hundreds of megabytes
// of dependencies (every program links with --as-needed).
#include "image_formats.h"

#include <afr/common/image.h>

#include <afr/common/error.h>

// fmt before OpenImageIO: OpenImageIO's headers carry a header-only copy of fmt that would
// otherwise define fmt's functions in this file, where the linker takes them for libfmt's and
// pulls this file, and OpenImageIO with it, into every program that formats a string.
#include <fmt/format.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>

namespace afr {
namespace {

using image_formats::kMaxImagePixels;
using image_formats::kMaxImageSide;

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

// OIIO reports errors on the object and, when no object could be made, globally.
template <typename ImageIO>
std::string oiio_error(const ImageIO* io) {
  std::string message = io != nullptr ? io->geterror() : std::string();
  if (message.empty()) message = OIIO::geterror();
  message = trimmed(std::move(message));
  return message.empty() ? std::string("unknown OpenImageIO error") : message;
}

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// Asks readers for the values as stored: without it, OIIO premultiplies color by alpha (PNG),
// which would darken every partly transparent texel of a glTF base color texture.
OIIO::ImageSpec as_stored_config() {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  return config;
}

void check_spec(const OIIO::ImageSpec& spec, const std::string& name) {
  if (spec.deep) throw Error(fmt::format("{}: deep images are not supported", name));
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) {
    throw Error(fmt::format("{}: image has no pixels ({} x {}, {} channels)", name, spec.width,
                            spec.height, spec.nchannels));
  }
  if (spec.width > kMaxImageSide || spec.height > kMaxImageSide ||
      uint64_t(spec.width) * uint64_t(spec.height) > kMaxImagePixels) {
    throw Error(fmt::format("{}: image of {} x {} pixels is larger than afr accepts", name,
                            spec.width, spec.height));
  }
}

// Reads the first subimage of an opened input as 8-bit values of up to four channels.
DecodedImage read_8bit(OIIO::ImageInput* in, const std::string& name) {
  const OIIO::ImageSpec& spec = in->spec();
  check_spec(spec, name);
  DecodedImage image;
  image.width = spec.width;
  image.height = spec.height;
  image.channels = std::min(spec.nchannels, 4);
  image.data.resize(size_t(image.width) * size_t(image.height) * size_t(image.channels));
  if (!in->read_image(0, 0, 0, image.channels, OIIO::TypeDesc::UINT8, image.data.data())) {
    throw Error(fmt::format("{}: cannot decode image: {}", name, oiio_error(in)));
  }
  return image;
}

void check_image(const Image& image, const std::filesystem::path& path) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != size_t(image.width) * size_t(image.height)) {
    throw Error(fmt::format("{}: cannot write an image of {} x {} with {} pixels", path.string(),
                            image.width, image.height, image.pixels.size()));
  }
}

// Opens, writes and closes one image; `data` holds `spec.nchannels` values of `type` per pixel.
void write_pixels(const std::filesystem::path& path, const OIIO::ImageSpec& spec,
                  OIIO::TypeDesc type, const void* data) {
  const std::string name = path.string();
  auto out = OIIO::ImageOutput::create(name);
  if (!out) {
    throw Error(
        fmt::format("{}: cannot write images of this type: {}", name, oiio_error(out.get())));
  }
  if (!out->open(name, spec)) {
    throw Error(fmt::format("{}: cannot open for writing: {}", name, oiio_error(out.get())));
  }
  if (!out->write_image(type, data) || !out->close()) {
    throw Error(fmt::format("{}: cannot write image: {}", name, oiio_error(out.get())));
  }
}

}  // namespace

// ---- Float images ----

void write_image(const Image& image, const std::filesystem::path& path) {
  check_image(image, path);
  if (lower_extension(path) == ".exr") {
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT);
    write_pixels(path, spec, OIIO::TypeDesc::FLOAT, image.pixels.data());
    return;
  }
  std::vector<uint8_t> bytes(image.pixels.size() * 3);
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) bytes[3 * i + size_t(c)] = linear_to_srgb8(image.pixels[i][c]);
  }
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  write_pixels(path, spec, OIIO::TypeDesc::UINT8, bytes.data());
}

Image read_image(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(fmt::format("{}: no such image file", name));
  }
  const OIIO::ImageSpec config = as_stored_config();
  auto in = OIIO::ImageInput::open(name, &config);
  if (!in) throw Error(fmt::format("{}: cannot open image: {}", name, oiio_error(in.get())));
  const OIIO::ImageSpec& spec = in->spec();
  check_spec(spec, name);
  const int channels = std::min(spec.nchannels, 3);
  std::vector<float> values(size_t(spec.width) * size_t(spec.height) * size_t(channels));
  if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, values.data())) {
    throw Error(fmt::format("{}: cannot read image: {}", name, oiio_error(in.get())));
  }
  // Integer formats hold display (sRGB) values; float formats (EXR, HDR) hold linear ones.
  const bool is_srgb = !spec.format.is_floating_point();
  Image image(spec.width, spec.height);
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    const float* v = &values[i * size_t(channels)];
    // One channel is gray; two are gray and alpha.
    glm::vec3 rgb = channels >= 3 ? glm::vec3(v[0], v[1], v[2]) : glm::vec3(v[0]);
    if (is_srgb) rgb = {srgb_to_linear(rgb.r), srgb_to_linear(rgb.g), srgb_to_linear(rgb.b)};
    image.pixels[i] = rgb;
  }
  return image;
}

// ---- 8-bit images ----

DecodedImage decode_image_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(fmt::format("{}: no such image file", name));
  }
  // The formats decode_image reads go through it, so that a texture decodes to the same values
  // from a file and from inside a .glb; OpenImageIO reads the rest (ASCII PNM, TIFF, ...).
  std::ifstream file(path, std::ios::binary);
  std::array<uint8_t, 16> head{};
  file.read(reinterpret_cast<char*>(head.data()), std::streamsize(head.size()));
  const auto got = size_t(file.gcount());
  if (image_formats::decoded_in_memory(image_formats::sniff({head.data(), got}))) {
    file.clear();
    file.seekg(0);
    const std::vector<uint8_t> bytes{std::istreambuf_iterator<char>(file),
                                     std::istreambuf_iterator<char>()};
    return decode_image(bytes, name);
  }
  const OIIO::ImageSpec config = as_stored_config();
  auto in = OIIO::ImageInput::open(name, &config);
  if (!in) throw Error(fmt::format("{}: cannot decode image: {}", name, oiio_error(in.get())));
  return read_8bit(in.get(), name);
}

void write_image8(const DecodedImage& image, const std::filesystem::path& path) {
  if (image.width <= 0 || image.height <= 0 || image.channels < 1 || image.channels > 4 ||
      image.data.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) {
    throw Error(fmt::format("{}: cannot write an 8-bit image of {} x {} x {} with {} bytes",
                            path.string(), image.width, image.height, image.channels,
                            image.data.size()));
  }
  OIIO::ImageSpec spec(image.width, image.height, image.channels, OIIO::TypeDesc::UINT8);
  if (image.channels == 2 || image.channels == 4) spec.alpha_channel = image.channels - 1;
  spec.attribute("oiio:UnassociatedAlpha", 1);  // the values are written as they are
  write_pixels(path, spec, OIIO::TypeDesc::UINT8, image.data.data());
}

}  // namespace afr
