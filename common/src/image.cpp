#include <afr/common/image.h>

#include <afr/common/error.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <string_view>
#include <system_error>

namespace afr {
namespace {

// Images larger than this are refused before any pixel memory is allocated: a file header is
// untrusted input, and 2^28 pixels (16384 x 16384) is far beyond any texture or reference image
// afr uses.
constexpr uint64_t kMaxImagePixels = uint64_t(1) << 28;
constexpr int kMaxImageSide = 1 << 16;

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

double linear_to_srgb_exact(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// The OIIO format of an encoded image, from its first bytes; empty when none matches. A name
// such as "image 3 of scene.glb" carries no extension, so the bytes decide.
std::string sniff_format(std::span<const uint8_t> b) {
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
  if (b.size() >= 2 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6') return "pnm";
  return {};
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

// ---- sRGB transfer function (IEC 61966-2-1) ----

float srgb_to_linear(float c) {
  const double v = c;
  return float(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
}

float linear_to_srgb(float c) { return float(linear_to_srgb_exact(c)); }

namespace {

// The 8-bit code of a linear value in (0, 1) by the formula: one pow per call.
uint8_t srgb8_by_formula(float c) { return uint8_t(std::lround(linear_to_srgb_exact(c) * 255.0)); }

// The code is a step function of c: thresholds[k] is the smallest positive float whose code is
// at least k (k = 1..255), found once by bisection over the ordered float bit patterns, so
// that a lookup gives the formula's code for every float, with 8 comparisons instead of a pow.
struct Srgb8Thresholds {
  std::array<float, 256> thresholds{};
  Srgb8Thresholds() {
    for (int k = 1; k < 256; ++k) {
      // Positive floats order like their bit patterns; the code of 1.0f's predecessor is 255.
      uint32_t lo = 0, hi = 0x3f800000u;  // code(lo) < k <= code(hi) (0 and 1.0f)
      while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        float v;
        std::memcpy(&v, &mid, sizeof v);
        (srgb8_by_formula(v) >= k ? hi : lo) = mid;
      }
      std::memcpy(&thresholds[size_t(k)], &hi, sizeof(float));
    }
  }
};

}  // namespace

uint8_t linear_to_srgb8(float c) {
  if (!(c > 0.0f)) return 0;  // also NaN
  if (c >= 1.0f) return 255;
  static const Srgb8Thresholds table;
  const float* t = table.thresholds.data();
  int code = 0;  // the largest k with t[k] <= c: binary search over 1..255
  for (int step = 128; step > 0; step /= 2) {
    if (code + step <= 255 && t[code + step] <= c) code += step;
  }
  return uint8_t(code);
}

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

DecodedImage decode_image(std::span<const uint8_t> bytes, const std::string& name) {
  if (bytes.empty()) throw Error(fmt::format("{}: image data is empty", name));
  const std::string format = sniff_format(bytes);
  if (format.empty()) {
    throw Error(fmt::format("{}: not an image format afr can decode (expected PNG or JPEG)", name));
  }
  auto in = OIIO::ImageInput::create(format);
  if (!in || !in->supports("ioproxy")) {
    throw Error(fmt::format("{}: {} images cannot be decoded from memory: {}", name, format,
                            oiio_error(in.get())));
  }
  OIIO::Filesystem::IOMemReader proxy(bytes.data(), bytes.size());
  in->set_ioproxy(&proxy);
  OIIO::ImageSpec spec;
  if (!in->open(name, spec, as_stored_config())) {
    throw Error(fmt::format("{}: cannot decode {} image: {}", name, format, oiio_error(in.get())));
  }
  return read_8bit(in.get(), name);
}

DecodedImage decode_image_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(fmt::format("{}: no such image file", name));
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

// ---- Error metric ----

double rms_error_255(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.pixels.size() != b.pixels.size()) {
    throw Error(fmt::format("cannot compare images of different sizes: {} x {} and {} x {}",
                            a.width, a.height, b.width, b.height));
  }
  if (a.pixels.empty()) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double d = double(linear_to_srgb8(a.pixels[i][c])) - linear_to_srgb8(b.pixels[i][c]);
      sum += d * d;
    }
  }
  return std::sqrt(sum / (3.0 * double(a.pixels.size())));
}

}  // namespace afr
