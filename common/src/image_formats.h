// What image.cpp's decoders share (private to afr_common): the format of encoded bytes, from
// their first bytes, and the size limit for untrusted image headers.
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace afr::image_formats {

// Images larger than this are refused before any pixel memory is allocated: a file header is
// untrusted input, and 2^28 pixels (16384 x 16384) is far beyond any texture or reference image
// afr uses.
inline constexpr uint64_t kMaxImagePixels = uint64_t(1) << 28;
inline constexpr int kMaxImageSide = 1 << 16;

// The OpenImageIO name of an encoded image's format, from its first bytes; empty when none
// matches. A name such as "image 3 of scene.glb" carries no extension, so the bytes decide.
std::string sniff(std::span<const uint8_t> bytes);

// Whether decode_image (stb_image or libwebp, in memory) decodes this format: PNG and JPEG (the
// image formats of glTF), WebP (EXT_texture_webp), BMP, GIF and binary PNM. The others (EXR, TIFF,
// ASCII PNM, ...) are read from files only, through OpenImageIO.
bool decoded_in_memory(const std::string& format);

}  // namespace afr::image_formats
