// Float RGB images, their files (through OpenImageIO: PNG and JPEG as 8-bit sRGB, EXR as
// linear float) and the error metric of the evaluation (RMS on the 0-255 display scale).
#pragma once

#include <afr/common/math.h>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace afr {

// Linear RGB, row 0 at the top.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<glm::vec3> pixels;

  Image() = default;
  Image(int w, int h, glm::vec3 fill = glm::vec3(0.0f))
      : width(w), height(h), pixels(size_t(w) * size_t(h), fill) {}
  glm::vec3& at(int x, int y) { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
  const glm::vec3& at(int x, int y) const { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
};

float srgb_to_linear(float c);
float linear_to_srgb(float c);
// A linear value as the 8-bit sRGB value a display shows (clamped, rounded): exactly the
// formula's code for every float, by a table.
uint8_t linear_to_srgb8(float c);

// An image as a display shows it: linear_to_srgb8 of each channel, r, g, b per pixel, rows top
// to bottom. What rms_error_255 compares; made once for an image compared many times.
struct Srgb8Image {
  int width = 0, height = 0;
  std::vector<uint8_t> codes;
};
Srgb8Image to_srgb8(const Image& image);

// Writes by extension: .exr keeps linear floats; .png/.jpg/.ppm/.tif store 8-bit sRGB.
// Throws afr::Error naming the file on failure.
void write_image(const Image& image, const std::filesystem::path& path);
// Reads any format OpenImageIO knows; 8-bit formats are taken as sRGB and linearised.
Image read_image(const std::filesystem::path& path);

// Raw 8-bit pixels as stored in a file: the one decode path of afr for textures, whether
// they come from a file or from bytes inside a .glb.
struct DecodedImage {
  int width = 0;
  int height = 0;
  int channels = 0;           // 1..4
  std::vector<uint8_t> data;  // width * height * channels, row 0 at the top
};
// Decodes PNG, JPEG, BMP, GIF and binary PNM bytes (stb_image; glTF's images are PNG or JPEG);
// other formats are refused by name. `name` is used in error messages (a file name or
// "image 3 of scene.glb").
DecodedImage decode_image(std::span<const uint8_t> bytes, const std::string& name);
// Decodes a file: the formats above as decode_image does, any other OpenImageIO reads (ASCII
// PNM, TIFF, ...) through OpenImageIO.
DecodedImage decode_image_file(const std::filesystem::path& path);
// Writes 8-bit pixels as they are (no color conversion) to PNG or any format by extension.
void write_image8(const DecodedImage& image, const std::filesystem::path& path);

// Root-mean-square difference of two images of the same size, on the 0-255 scale of their
// 8-bit sRGB display values, over all pixels and the three channels (the metric of the
// paper's Table 1). Throws afr::Error if the sizes differ.
double rms_error_255(const Image& a, const Image& b);
// The same against an image already as its display codes.
double rms_error_255(const Image& a, const Srgb8Image& b);

}  // namespace afr
