// Checks shared by validation, encoding and decoding (private to afr_protocol).
#pragma once

#include <afr/protocol/codec.h>

#include <cmath>
#include <string>

namespace afr::protocol::detail {

// Names and texts: at most kMaxNameBytes bytes, no control characters (they end up in logs).
Status check_text(const char* message, const char* field, const std::string& s);
// A ZeroMQ endpoint: tcp://, ipc:// or inproc://, then something; a text by check_text's rules.
Status check_endpoint(const char* message, const char* field, const std::string& s);
// Finite, and >= 0: an absolute display-clock time.
Status check_time(const char* message, const char* field, double t);
// 1..kMaxImageSize on both sides.
Status check_image_size(const char* message, int32_t width, int32_t height);
// Non-empty, inside [0, width) x [0, height).
Status check_rect(const char* message, const char* field, const PixelRect& r, int32_t width,
                  int32_t height);
Status check_bounds(const char* message, const ImageExtent& bounds);

}  // namespace afr::protocol::detail
