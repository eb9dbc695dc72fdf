// PNG files of an 8-bit image, for the tests' glTF textures: written with stb_image_write, an
// encoder independent of afr's image I/O. A test binary that writes no other image file then
// starts without OpenImageIO and its 260 shared libraries, a quarter of a second a test process
// (cmake/check_needed_libraries.cmake); afr's own image files are image_test.cpp's.
#pragma once

#include <afr/common/image.h>

#include <stb_image_write.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace afr::testing {

inline void write_png(const DecodedImage& image, const std::filesystem::path& path) {
  if (image.width <= 0 || image.height <= 0 || image.channels < 1 || image.channels > 4 ||
      image.data.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) {
    throw std::invalid_argument("write_png: not an 8-bit image: " + path.string());
  }
  if (!stbi_write_png(path.c_str(), image.width, image.height, image.channels, image.data.data(),
                      image.width * image.channels)) {
    throw std::runtime_error("write_png: cannot write " + path.string());
  }
}

}  // namespace afr::testing
