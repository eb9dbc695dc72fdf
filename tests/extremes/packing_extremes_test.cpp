// Numerical extremes of the wire's compact number formats (protocol/packing.h and the batch
// codec's time ticks): the largest, smallest, denormal, infinite and NaN inputs of each,
// packed and unpacked. The result is always finite and what docs/protocol.md documents.
#include <afr/protocol/codec.h>
#include <afr/protocol/packing.h>

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace afr::protocol {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kFloatMax = std::numeric_limits<float>::max();
constexpr float kFloatDenormMin = std::numeric_limits<float>::denorm_min();

float half_round_trip(float f) { return decode_half(encode_half(f)); }

TEST(ExtremesTest, HalfFloatsAtTheirRangeLimitsStayFiniteAndDocumented) {
  const float kHalfMinNormal = std::ldexp(1.0f, -14);
  const float kHalfMinDenormal = std::ldexp(1.0f, -24);
  const float kHalfMaxDenormal = 1023.0f * kHalfMinDenormal;
  // Exactly representable limits come back exactly, with their sign.
  for (float f : {kHalfMax, kHalfMinNormal, kHalfMaxDenormal, kHalfMinDenormal, 0.0f}) {
    EXPECT_EQ(half_round_trip(f), f);
    EXPECT_EQ(half_round_trip(-f), -f);
  }
  EXPECT_TRUE(std::signbit(half_round_trip(-0.0f)));
  // Beyond the range and infinities saturate; NaN becomes 0.
  for (float f : {65519.0f, 65520.0f, 1e30f, kFloatMax, kInf}) {
    EXPECT_EQ(half_round_trip(f), kHalfMax) << f;
    EXPECT_EQ(half_round_trip(-f), -kHalfMax) << f;
  }
  EXPECT_EQ(half_round_trip(kNaN), 0.0f);
  EXPECT_EQ(half_round_trip(-kNaN), 0.0f);
  // Below the smallest denormal: half of it is a tie (to even: 0), more than half rounds up,
  // float denormals vanish (keeping the sign).
  EXPECT_EQ(half_round_trip(0.5f * kHalfMinDenormal), 0.0f);
  EXPECT_EQ(half_round_trip(0.75f * kHalfMinDenormal), kHalfMinDenormal);
  EXPECT_EQ(half_round_trip(1.5f * kHalfMinDenormal), 2.0f * kHalfMinDenormal);  // tie to even
  EXPECT_EQ(half_round_trip(kFloatDenormMin), 0.0f);
  EXPECT_TRUE(std::signbit(half_round_trip(-kFloatDenormMin)));
  // Between the largest denormal and the smallest normal, and at the top of the range.
  EXPECT_EQ(half_round_trip(0.5f * (kHalfMaxDenormal + kHalfMinNormal)), kHalfMinNormal);
  EXPECT_EQ(half_round_trip(65503.0f), 65504.0f);
  // Every float bit pattern whose exponent is at a limit of the half range: the encoder never
  // writes an Inf or NaN pattern, and the error is within the documented bound.
  for (uint32_t exp : {0u, 1u, 102u, 103u, 112u, 113u, 142u, 143u, 254u, 255u}) {
    for (uint32_t m = 0; m < (1u << 23); m += 4099) {
      for (uint32_t sign : {0u, 0x80000000u}) {
        const float f = std::bit_cast<float>(sign | (exp << 23) | m);
        const uint16_t h = encode_half(f);
        ASSERT_FALSE(half_is_special(h)) << f;
        const float back = decode_half(h);
        ASSERT_TRUE(std::isfinite(back)) << f;
        if (std::isnan(f)) continue;
        const float clamped = std::clamp(f, -kHalfMax, kHalfMax);
        const float bound =
            std::max(std::abs(clamped) * std::ldexp(1.0f, -11), 0.5f * kHalfMinDenormal);
        ASSERT_LE(std::abs(back - clamped), bound) << f;
      }
    }
  }
}

Rgb rgb9e5_round_trip(float r, float g, float b) { return decode_rgb9e5(encode_rgb9e5(r, g, b)); }

TEST(ExtremesTest, Rgb9e5AtItsRangeLimitsStaysFiniteAndDocumented) {
  const float kSmallest = std::ldexp(1.0f, -24);  // mantissa 1 at the lowest exponent
  Rgb c = rgb9e5_round_trip(kRgb9e5Max, kRgb9e5Max, kRgb9e5Max);
  EXPECT_EQ(c.r, kRgb9e5Max);
  EXPECT_EQ(c.b, kRgb9e5Max);
  // Above the range, and +Inf, clamp to the largest value; NaN, negatives and -Inf to 0.
  c = rgb9e5_round_trip(65409.0f, kFloatMax, kInf);
  EXPECT_EQ(c.r, kRgb9e5Max);
  EXPECT_EQ(c.g, kRgb9e5Max);
  EXPECT_EQ(c.b, kRgb9e5Max);
  c = rgb9e5_round_trip(kNaN, -kInf, -1.0f);
  EXPECT_EQ(c.r, 0.0f);
  EXPECT_EQ(c.g, 0.0f);
  EXPECT_EQ(c.b, 0.0f);
  // The smallest non-zero value, and what rounds to it or to 0.
  c = rgb9e5_round_trip(kSmallest, 0.5f * kSmallest, 0.49f * kSmallest);
  EXPECT_EQ(c.r, kSmallest);
  EXPECT_EQ(c.g, kSmallest);  // the specification's floor(x + 0.5)
  EXPECT_EQ(c.b, 0.0f);
  c = rgb9e5_round_trip(kFloatDenormMin, 1e-40f, 0.0f);
  EXPECT_EQ(c.r, 0.0f);
  EXPECT_EQ(c.g, 0.0f);
  // A channel far below the largest one shares its step and vanishes.
  c = rgb9e5_round_trip(kRgb9e5Max, 1.0f, kSmallest);
  EXPECT_EQ(c.r, kRgb9e5Max);
  EXPECT_EQ(c.g, 0.0f);
  EXPECT_EQ(c.b, 0.0f);
  // Every power of two from below the range to above it, alone and with dimmer neighbours:
  // finite, in [0, 65408], the largest channel within 2^-9 relative (or half the smallest step).
  for (int e = -30; e <= 20; ++e) {
    for (float f : {1.0f, 1.5f, 1.999f}) {
      const float v = std::ldexp(f, e);
      const Rgb d = rgb9e5_round_trip(v, 0.3f * v, 1e-3f * v);
      for (float x : {d.r, d.g, d.b}) {
        ASSERT_TRUE(std::isfinite(x) && x >= 0.0f && x <= kRgb9e5Max) << v;
      }
      const float expected = std::min(v, kRgb9e5Max);
      ASSERT_LE(std::abs(d.r - expected),
                std::max(expected * std::ldexp(1.0f, -9), 0.5f * kSmallest))
          << v;
    }
  }
  // Every code decodes to finite values in range: all exponents with extreme mantissas.
  for (uint32_t e = 0; e < 32; ++e) {
    for (uint32_t m : {0u, 1u, 256u, 511u}) {
      const Rgb d = decode_rgb9e5(m | (m << 9) | (m << 18) | (e << 27));
      ASSERT_TRUE(std::isfinite(d.r) && d.r >= 0.0f && d.r <= kRgb9e5Max) << e << " " << m;
    }
  }
}

TEST(ExtremesTest, PackedImagePositionsAddressEveryPixelOf32768) {
  // Every pixel of a 32768-pixel side: its first position, its center and the last float
  // inside it come back inside the same pixel.
  for (uint32_t k = 0; k < 32768; ++k) {
    const float lo = float(k), hi = std::nextafter(float(k + 1), 0.0f);
    for (float x : {lo, lo + 0.5f, hi}) {
      const uint32_t code = encode_position(x);
      ASSERT_LE(code, kMaxPositionCode);
      const float back = decode_position(code);
      ASSERT_EQ(uint32_t(back), k) << x;
      ASSERT_LE(std::abs(back - x), 1.0f / 512.0f) << x;
    }
  }
  // The last float below 32768 round-trips exactly; everything at or beyond the edge, and
  // +Inf, clamps to the last code, which stays inside the image.
  const float last = std::nextafter(32768.0f, 0.0f);
  EXPECT_EQ(decode_position(encode_position(last)), last);
  for (float x : {32768.0f, 1e9f, kFloatMax, kInf}) {
    EXPECT_EQ(encode_position(x), kMaxPositionCode) << x;
  }
  EXPECT_LT(decode_position(kMaxPositionCode), 32768.0f);
  // Negative, NaN and -Inf clamp to the first code.
  for (float x : {-0.0f, -kFloatDenormMin, -1.0f, -kInf, kNaN}) {
    EXPECT_EQ(encode_position(x), 0u) << x;
  }
  EXPECT_EQ(encode_position(kFloatDenormMin), 0u);
}

// Encodes and decodes a batch of samples at `times`; returns false if the encoder refused.
bool time_round_trip(const std::vector<double>& times, std::vector<double>* out, int* tick_exp) {
  SampleBatch b;
  for (double t : times) {
    Sample s;
    s.time = t;
    s.x = 1.5f;
    s.y = 2.5f;
    b.samples.push_back(s);
  }
  std::vector<uint8_t> bytes;
  if (!encode(b, &bytes)) return false;
  *tick_exp = int(int8_t(bytes[kHeaderBytes + 28]));
  SampleBatch decoded;
  const Status st = decode(bytes, &decoded);
  EXPECT_TRUE(st.ok()) << st.message();
  out->clear();
  for (const Sample& s : decoded.samples) out->push_back(s.time);
  return true;
}

TEST(ExtremesTest, PackedSampleTimesAtTheirLimitsStayWithinHalfATick) {
  const double kDoubleMax = std::numeric_limits<double>::max();
  struct Case {
    double base, span;
    int expected_tick_exp;
  };
  const Case cases[] = {
      {0.0, 0.0, kMinTickExp},      // one instant at the session start
      {1e6, 1e-7, kMinTickExp},     // a week-long session, 100 ns apart
      {1e9, 3e-5, kMinTickExp},     // 30 years, 1 ns ticks
      {1e9, 1e-3, -24},             // 1 ms span
      {1e9, 32767.0, kMaxTickExp},  // the longest span: 1 s ticks
      {1e15, 1.0, -14},             // far beyond any session; double spacing 0.125 s
      {kDoubleMax / 2, 0.0, kMinTickExp},
      {std::ldexp(1.0, -1060), 0.0, kMinTickExp},  // a denormal time
  };
  for (const Case& c : cases) {
    std::vector<double> times;
    for (int k = 0; k <= 64; ++k) times.push_back(c.base + c.span * (k * k) / 4096.0);
    std::vector<double> back;
    int tick_exp = 0;
    ASSERT_TRUE(time_round_trip(times, &back, &tick_exp)) << c.base << " + " << c.span;
    EXPECT_EQ(tick_exp, c.expected_tick_exp) << c.base << " + " << c.span;
    const double tick = std::ldexp(1.0, tick_exp);
    ASSERT_EQ(back.size(), times.size());
    for (size_t i = 0; i < times.size(); ++i) {
      ASSERT_TRUE(std::isfinite(back[i]));
      // Half a tick, or the spacing of doubles where that is coarser.
      const double ulp = std::nextafter(times[i], INFINITY) - times[i];
      EXPECT_LE(std::abs(back[i] - times[i]), std::max(0.5 * tick, ulp))
          << c.base << " + " << c.span << " sample " << i;
    }
  }
  // Longer spans (beyond the last 1 s tick and half a tick of rounding), non-finite and
  // negative times are refused by the encoder.
  std::vector<double> back;
  int tick_exp;
  EXPECT_TRUE(time_round_trip({1e9, 1e9 + 32767.5}, &back, &tick_exp));
  EXPECT_FALSE(time_round_trip({1e9, 1e9 + 32768.0}, &back, &tick_exp));
  EXPECT_FALSE(time_round_trip({0.0, kDoubleMax}, &back, &tick_exp));
  EXPECT_FALSE(time_round_trip({1.0, std::numeric_limits<double>::infinity()}, &back, &tick_exp));
  EXPECT_FALSE(time_round_trip({1.0, std::nan("")}, &back, &tick_exp));
  EXPECT_FALSE(time_round_trip({-1e-300, 0.0}, &back, &tick_exp));
}

}  // namespace
}  // namespace afr::protocol
