#include <afr/protocol/packing.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace afr::protocol {
namespace {

// ---------------------------------------------------------------------------------------------
// References written from the format definitions, in double precision, without bit tricks.

double half_value(uint16_t h) {
  const int sign = (h & 0x8000) ? -1 : 1;
  const int exp = (h >> 10) & 0x1f;
  const int mant = h & 0x3ff;
  if (exp == 0) return sign * std::ldexp(double(mant), -24);
  return sign * std::ldexp(double(1024 + mant), exp - 25);
}

// Positive finite halves in increasing order of value (and of bits).
std::vector<double> positive_halves() {
  std::vector<double> v;
  for (uint32_t h = 0; h <= 0x7bff; ++h) v.push_back(half_value(uint16_t(h)));
  return v;
}

// The nearest half to f, ties to the even mantissa, saturating at 65504: the definition of
// IEEE round-to-nearest-even (with afr's saturation instead of Inf).
uint16_t nearest_half(float f, const std::vector<double>& table) {
  const double a = std::min(std::abs(double(f)), 65504.0);
  const uint16_t sign = std::signbit(f) ? 0x8000 : 0;
  const auto it = std::lower_bound(table.begin(), table.end(), a);
  uint32_t hi = uint32_t(it - table.begin());
  if (hi == table.size()) hi = uint32_t(table.size() - 1);
  const uint32_t lo = hi > 0 ? hi - 1 : 0;
  const double dlo = a - table[lo], dhi = table[hi] - a;
  uint32_t best;
  if (dlo < dhi) {
    best = lo;
  } else if (dhi < dlo) {
    best = hi;
  } else {
    best = (lo % 2 == 0) ? lo : hi;
  }
  return uint16_t(sign | best);
}

// EXT_texture_shared_exponent, "Encoding", transcribed with double math.
uint32_t reference_rgb9e5(float r, float g, float b) {
  const auto clamp = [](float c) {
    return std::isnan(c) ? 0.0 : std::clamp(double(c), 0.0, 65408.0);
  };
  const double rc = clamp(r), gc = clamp(g), bc = clamp(b);
  const double maxrgb = std::max({rc, gc, bc});
  const int floor_log2 = maxrgb > 0.0 ? int(std::floor(std::log2(maxrgb))) : -1000;
  int exp_p = std::max(-16, floor_log2) + 1 + 15;
  int max_s = int(std::floor(maxrgb / std::pow(2.0, exp_p - 24) + 0.5));
  const int exp = max_s == 512 ? exp_p + 1 : exp_p;
  const double step = std::pow(2.0, exp - 24);
  const uint32_t rs = uint32_t(std::floor(rc / step + 0.5));
  const uint32_t gs = uint32_t(std::floor(gc / step + 0.5));
  const uint32_t bs = uint32_t(std::floor(bc / step + 0.5));
  return rs | (gs << 9) | (bs << 18) | (uint32_t(exp) << 27);
}

// A float of random magnitude: 2^[-30, 18) times a uniform mantissa, random sign.
float random_float(Pcg32& rng) {
  const float m = 1.0f + rng.next_float();
  const int e = int(rng.next_below(48)) - 30;
  return (rng.next_below(2) ? -1.0f : 1.0f) * std::ldexp(m, e);
}

// ---------------------------------------------------------------------------------------------
// Half floats

TEST(PackingTest, HalfDecodesEveryFinitePatternLikeTheDefinition) {
  for (uint32_t h = 0; h < 65536; ++h) {
    if (half_is_special(uint16_t(h))) continue;
    ASSERT_EQ(double(decode_half(uint16_t(h))), half_value(uint16_t(h))) << std::hex << h;
  }
}

TEST(PackingTest, HalfSpecialPatternsAreExactlyInfAndNaN) {
  int special = 0;
  for (uint32_t h = 0; h < 65536; ++h) {
    const bool s = half_is_special(uint16_t(h));
    special += s;
    if (s) {
      EXPECT_FALSE(std::isfinite(decode_half(uint16_t(h))));
    }
  }
  EXPECT_EQ(special, 2 * 1024);  // exponent 31, either sign, any mantissa
}

TEST(PackingTest, HalfEncodeRoundTripsEveryFiniteHalf) {
  for (uint32_t h = 0; h < 65536; ++h) {
    if (half_is_special(uint16_t(h))) continue;
    ASSERT_EQ(encode_half(decode_half(uint16_t(h))), h) << std::hex << h;
  }
}

TEST(PackingTest, HalfEncodeIsNearestWithTiesToEven) {
  const std::vector<double> table = positive_halves();
  // Every midpoint between neighbouring halves (the ties) and points just beside them.
  for (size_t i = 0; i + 1 < table.size(); ++i) {
    const float mid = float((table[i] + table[i + 1]) / 2);  // exact in float
    ASSERT_EQ(double(mid), (table[i] + table[i + 1]) / 2);
    for (float f : {mid, std::nextafter(mid, 0.0f), std::nextafter(mid, 1e9f), -mid}) {
      ASSERT_EQ(encode_half(f), nearest_half(f, table)) << f;
    }
  }
  Pcg32 rng(7);
  for (int i = 0; i < 200000; ++i) {
    const float f = random_float(rng);
    ASSERT_EQ(encode_half(f), nearest_half(f, table)) << f;
  }
}

TEST(PackingTest, HalfSaturatesAndNeverMakesInfOrNaN) {
  EXPECT_EQ(decode_half(encode_half(1e9f)), 65504.0f);
  EXPECT_EQ(decode_half(encode_half(-1e9f)), -65504.0f);
  EXPECT_EQ(decode_half(encode_half(INFINITY)), 65504.0f);
  EXPECT_EQ(decode_half(encode_half(-INFINITY)), -65504.0f);
  EXPECT_EQ(decode_half(encode_half(NAN)), 0.0f);
  EXPECT_EQ(decode_half(encode_half(65519.0f)), 65504.0f);  // would round to Inf unclamped
}

TEST(PackingTest, HalfRelativeErrorIsAtMostTwoToTheMinusEleven) {
  Pcg32 rng(8);
  for (int i = 0; i < 100000; ++i) {
    const float f = random_float(rng);
    if (std::abs(f) < 6.2e-5f || std::abs(f) > 65504.0f) continue;  // normal range only
    const float d = decode_half(encode_half(f));
    ASSERT_LE(std::abs(double(d) - f), std::abs(double(f)) * std::ldexp(1.0, -11)) << f;
  }
}

// ---------------------------------------------------------------------------------------------
// RGB9E5

TEST(PackingTest, Rgb9e5MatchesTheSpecificationBitForBit) {
  Pcg32 rng(9);
  for (int i = 0; i < 300000; ++i) {
    float c[3];
    for (float& v : c) v = std::abs(random_float(rng));
    // Also shades of one color (the common case) and colors with a zero channel.
    if (i % 3 == 1) c[1] = c[0] * 0.5f, c[2] = c[0] * 0.25f;
    if (i % 5 == 2) c[2] = 0.0f;
    ASSERT_EQ(encode_rgb9e5(c[0], c[1], c[2]), reference_rgb9e5(c[0], c[1], c[2]))
        << c[0] << " " << c[1] << " " << c[2];
  }
  for (float v : {0.0f, 1.0f, 0.5f, 65408.0f, 65407.0f, 1e-7f, 1.5258789e-05f}) {
    EXPECT_EQ(encode_rgb9e5(v, v, v), reference_rgb9e5(v, v, v)) << v;
  }
}

TEST(PackingTest, Rgb9e5ErrorsAreWithinHalfAStepOfTheLargestChannel) {
  Pcg32 rng(10);
  for (int i = 0; i < 100000; ++i) {
    const float r = std::ldexp(rng.next_float(), int(rng.next_below(20)) - 10);
    const float g = r * rng.next_float(), b = std::ldexp(rng.next_float(), -12);
    const uint32_t code = encode_rgb9e5(r, g, b);
    const Rgb d = decode_rgb9e5(code);
    const double step = std::ldexp(1.0, int(code >> 27) - 24);
    ASSERT_LE(std::abs(double(d.r) - r), step / 2) << r;
    ASSERT_LE(std::abs(double(d.g) - g), step / 2) << g;
    ASSERT_LE(std::abs(double(d.b) - b), step / 2) << b;
    const double max_c = std::max({r, g, b});
    if (max_c > 1e-4) {
      ASSERT_LE(std::abs(double(std::max({d.r, d.g, d.b})) - max_c), max_c * std::ldexp(1.0, -9));
    }
  }
}

TEST(PackingTest, Rgb9e5ClampsWhatItCannotHold) {
  const auto rt = [](float r, float g, float b) { return decode_rgb9e5(encode_rgb9e5(r, g, b)); };
  Rgb d = rt(-1.0f, NAN, 2.0f);
  EXPECT_EQ(d.r, 0.0f);
  EXPECT_EQ(d.g, 0.0f);
  EXPECT_EQ(d.b, 2.0f);
  d = rt(INFINITY, 1e30f, 0.0f);
  EXPECT_EQ(d.r, kRgb9e5Max);
  EXPECT_EQ(d.g, kRgb9e5Max);
  d = rt(0.0f, 0.0f, 0.0f);
  EXPECT_EQ(d.r + d.g + d.b, 0.0f);
  // Every code decodes to finite values.
  for (uint32_t e = 0; e < 32; ++e) {
    const Rgb m = decode_rgb9e5((e << 27) | 0x7ffffff);
    EXPECT_TRUE(std::isfinite(m.r) && m.r <= kRgb9e5Max);
  }
}

// ---------------------------------------------------------------------------------------------
// Image positions

TEST(PackingTest, PositionsStayInTheirBinAndPixel) {
  Pcg32 rng(11);
  for (int i = 0; i < 300000; ++i) {
    // Uniform over the image, and values next to pixel edges and the top of the range.
    float x = rng.next_float() * 32768.0f;
    if (i % 4 == 1) x = std::nextafter(float(rng.next_below(32768) + 1), 0.0f);
    if (i % 4 == 2) x = float(rng.next_below(32768));
    const uint32_t code = encode_position(x);
    ASSERT_EQ(code, uint32_t(std::floor(double(x) * 512.0))) << x;
    const float d = decode_position(code);
    ASSERT_EQ(std::floor(double(d) * 512.0), double(code)) << x;  // same 1/512 bin
    ASSERT_EQ(std::floor(d), std::floor(x)) << x;                 // same pixel
    const double error = std::abs(double(d) - x);
    if (x < 16384.0f) {
      ASSERT_LE(error, 1.0 / 1024.0) << x;
    } else {
      ASSERT_EQ(error, 0.0) << x;  // floats there are multiples of 1/512 already
    }
  }
  EXPECT_LT(decode_position(encode_position(std::nextafter(32768.0f, 0.0f))), 32768.0f);
  EXPECT_EQ(encode_position(-1.0f), 0u);
  EXPECT_EQ(encode_position(NAN), 0u);
  EXPECT_EQ(encode_position(1e9f), kMaxPositionCode);
}

}  // namespace
}  // namespace afr::protocol
