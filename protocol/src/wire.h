// Little-endian byte writing and bounds-checked reading for the codec (private to
// afr_protocol). The reader turns every shortfall into a Status that names the field.
#pragma once

#include <afr/common/check.h>
#include <afr/protocol/codec.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace afr::protocol::wire {

// ---------------------------------------------------------------------------------------------
// Unchecked little-endian stores and loads (callers have checked the room)

inline void store_u8(uint8_t* p, uint8_t v) { p[0] = v; }
inline void store_u16(uint8_t* p, uint16_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
}
inline void store_u24(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
  p[2] = uint8_t(v >> 16);
}
inline void store_u32(uint8_t* p, uint32_t v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(p, &v, 4);
  } else {
    for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
  }
}
inline void store_u64(uint8_t* p, uint64_t v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(p, &v, 8);
  } else {
    for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
  }
}
inline void store_f32(uint8_t* p, float v) { store_u32(p, std::bit_cast<uint32_t>(v)); }
inline void store_f64(uint8_t* p, double v) { store_u64(p, std::bit_cast<uint64_t>(v)); }

inline uint16_t load_u16(const uint8_t* p) { return uint16_t(p[0] | (p[1] << 8)); }
inline uint32_t load_u24(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16);
}
inline uint32_t load_u32(const uint8_t* p) {
  uint32_t v;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&v, p, 4);
  } else {
    v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(p[i]) << (8 * i);
  }
  return v;
}
inline uint64_t load_u64(const uint8_t* p) {
  uint64_t v;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&v, p, 8);
  } else {
    v = 0;
    for (int i = 0; i < 8; ++i) v |= uint64_t(p[i]) << (8 * i);
  }
  return v;
}
inline float load_f32(const uint8_t* p) { return std::bit_cast<float>(load_u32(p)); }
inline double load_f64(const uint8_t* p) { return std::bit_cast<double>(load_u64(p)); }

// ---------------------------------------------------------------------------------------------
// Writer: fills a buffer sized in advance by begin_message()

class Writer {
 public:
  Writer(uint8_t* begin, uint8_t* end) : p_(begin), end_(end) {}

  void u8(uint8_t v) { store_u8(take(1), v); }
  void u16(uint16_t v) { store_u16(take(2), v); }
  void u32(uint32_t v) { store_u32(take(4), v); }
  void i32(int32_t v) { store_u32(take(4), uint32_t(v)); }
  void u64(uint64_t v) { store_u64(take(8), v); }
  void f32(float v) { store_f32(take(4), v); }
  void f64(double v) { store_f64(take(8), v); }
  void bytes(const uint8_t* data, size_t n) {
    if (n) std::memcpy(take(n), data, n);
  }
  // u16 length, then the bytes.
  void string(const std::string& s) {
    u16(uint16_t(s.size()));
    bytes(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  }
  uint8_t* take(size_t n) {
    AFR_CHECK(size_t(end_ - p_) >= n);
    uint8_t* p = p_;
    p_ += n;
    return p;
  }
  bool done() const { return p_ == end_; }

 private:
  uint8_t* p_;
  uint8_t* end_;
};

// Sizes *out to the header plus `payload_bytes`, writes the header and returns a writer for
// the payload.
Writer begin_message(MessageType type, size_t payload_bytes, std::vector<uint8_t>* out);

inline size_t string_bytes(const std::string& s) { return 2 + s.size(); }

// ---------------------------------------------------------------------------------------------
// Reader: every read checks the room left and, on a shortfall, records which field it was

class Reader {
 public:
  // `payload` is what follows the header; `message` names the message in errors.
  Reader(Bytes payload, const char* message)
      : p_(payload.data()), end_(payload.data() + payload.size()), message_(message) {}

  bool u8(uint8_t* v, const char* field) {
    const uint8_t* p = take(1, field);
    if (p) *v = p[0];
    return p;
  }
  bool u16(uint16_t* v, const char* field) {
    const uint8_t* p = take(2, field);
    if (p) *v = load_u16(p);
    return p;
  }
  bool u32(uint32_t* v, const char* field) {
    const uint8_t* p = take(4, field);
    if (p) *v = load_u32(p);
    return p;
  }
  bool i32(int32_t* v, const char* field) {
    const uint8_t* p = take(4, field);
    if (p) *v = int32_t(load_u32(p));
    return p;
  }
  bool u64(uint64_t* v, const char* field) {
    const uint8_t* p = take(8, field);
    if (p) *v = load_u64(p);
    return p;
  }
  bool f32(float* v, const char* field) {
    const uint8_t* p = take(4, field);
    if (p) *v = load_f32(p);
    return p;
  }
  bool f64(double* v, const char* field) {
    const uint8_t* p = take(8, field);
    if (p) *v = load_f64(p);
    return p;
  }
  // u16 length (checked against max_bytes before the bytes are looked at), then the bytes.
  bool string(std::string* s, const char* field, size_t max_bytes);
  // The next n bytes, or nullptr (with the error recorded) when fewer are left.
  const uint8_t* take(size_t n, const char* field) {
    if (!status_.ok()) return nullptr;
    if (size_t(end_ - p_) < n) {
      fail(field, "truncated: needs " + std::to_string(n) + " bytes, " + std::to_string(end_ - p_) +
                      " left");
      return nullptr;
    }
    const uint8_t* p = p_;
    p_ += n;
    return p;
  }
  size_t remaining() const { return size_t(end_ - p_); }

  // Records the first error only.
  void fail(const char* field, const std::string& problem);
  // The recorded error, or an error for bytes left over after the last field.
  Status finish();
  bool ok() const { return status_.ok(); }
  Status status() const { return status_; }

 private:
  const uint8_t* p_;
  const uint8_t* end_;
  const char* message_;
  Status status_;
};

// "<message>.<field>: <problem>"
Status field_error(const char* message, const std::string& field, const std::string& problem);

}  // namespace afr::protocol::wire
