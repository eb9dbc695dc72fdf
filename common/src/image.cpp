#include <afr/common/image.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>

namespace afr {
namespace {

double linear_to_srgb_exact(double v) {
  return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
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
// at least k (k = 1..255), found once by bisection over the ordered float bit patterns, so that
// a lookup gives the formula's code for every float without a pow. Positive floats order like
// their bit patterns; bucket_code[b] is the code of the first float whose bits >> kBucketShift
// are b. No bucket holds two thresholds (checked here), so a float's code is its bucket's code,
// plus one where it is at or past the next threshold: one table read and one comparison.
struct Srgb8Table {
  static constexpr int kBucketShift = 16;
  static constexpr uint32_t kOne = 0x3f800000u;  // 1.0f
  std::array<float, 257> thresholds{};           // [256]: +inf, never reached
  std::array<uint8_t, (kOne >> kBucketShift)> bucket_code{};

  Srgb8Table() {
    std::array<uint32_t, 256> bits{};
    for (int k = 1; k < 256; ++k) {
      uint32_t lo = 0, hi = kOne;  // code(lo) < k <= code(hi) (0 and 1.0f)
      while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        float v;
        std::memcpy(&v, &mid, sizeof v);
        (srgb8_by_formula(v) >= k ? hi : lo) = mid;
      }
      bits[size_t(k)] = hi;
      std::memcpy(&thresholds[size_t(k)], &hi, sizeof(float));
      if (k > 1 && (bits[size_t(k - 1)] >> kBucketShift) == (hi >> kBucketShift)) {
        throw Error(fmt::format("sRGB table: codes {} and {} share a bucket", k - 1, k));
      }
    }
    thresholds[256] = std::numeric_limits<float>::infinity();
    int code = 0;
    for (uint32_t b = 0; b < bucket_code.size(); ++b) {
      while (code < 255 && bits[size_t(code) + 1] <= (b << kBucketShift)) ++code;
      bucket_code[b] = uint8_t(code);
    }
  }
};

const Srgb8Table& srgb8_table() {
  static const Srgb8Table table;
  return table;
}

inline uint8_t srgb8_code(const Srgb8Table& table, float c) {
  if (!(c > 0.0f)) return 0;  // also NaN
  if (c >= 1.0f) return 255;
  uint32_t bits;
  std::memcpy(&bits, &c, sizeof bits);
  const int code = table.bucket_code[bits >> Srgb8Table::kBucketShift];
  return uint8_t(code + (c >= table.thresholds[size_t(code) + 1]));
}

}  // namespace

uint8_t linear_to_srgb8(float c) { return srgb8_code(srgb8_table(), c); }

Srgb8Image to_srgb8(const Image& image) {
  const Srgb8Table& table = srgb8_table();
  Srgb8Image out;
  out.width = image.width;
  out.height = image.height;
  out.codes.resize(3 * image.pixels.size());
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c)
      out.codes[3 * i + size_t(c)] = srgb8_code(table, image.pixels[i][c]);
  }
  return out;
}

// ---- Error metric ----

namespace {

// a and b: width, height and channel values (3 per pixel).
void check_comparable(int aw, int ah, size_t a_values, int bw, int bh, size_t b_values) {
  if (aw != bw || ah != bh || a_values != b_values) {
    throw Error(fmt::format("cannot compare images of different sizes: {} x {} and {} x {}", aw, ah,
                            bw, bh));
  }
}

}  // namespace

double rms_error_255(const Image& a, const Image& b) {
  check_comparable(a.width, a.height, a.pixels.size(), b.width, b.height, b.pixels.size());
  return rms_error_255(a, to_srgb8(b));
}

double rms_error_255(const Image& a, const Srgb8Image& b) {
  check_comparable(a.width, a.height, 3 * a.pixels.size(), b.width, b.height, b.codes.size());
  if (a.pixels.empty()) return 0.0;
  const Srgb8Table& table = srgb8_table();
  // Integer sums: exact, so the result does not depend on the order of the pixels.
  uint64_t sum = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const int d = int(srgb8_code(table, a.pixels[i][c])) - int(b.codes[3 * i + size_t(c)]);
      sum += uint64_t(d * d);
    }
  }
  return std::sqrt(double(sum) / (3.0 * double(a.pixels.size())));
}

}  // namespace afr
