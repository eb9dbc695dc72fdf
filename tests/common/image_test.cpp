#include "support/files.h"
#include "support/srgb.h"
#include "support/webp.h"

#include <afr/common/image.h>

#include <afr/common/error.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace afr {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class ImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("afr_image_test_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

using afr::testing::read_bytes;

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// The sRGB transfer functions written out independently of image.cpp.
using afr::testing::reference_linear_to_srgb;
using afr::testing::reference_srgb_to_linear;

// An image with distinct, non-trivial values in every channel, some above 1 (EXR keeps them).
Image test_pattern(int w, int h) {
  Image image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      image.at(x, y) = {0.013f * float(x + 1), 0.37f * float(y) / float(h),
                        float(x * 7 + y * 3) / 11.0f};
    }
  }
  return image;
}

Image quantized_like_png(const Image& image) {
  // What an 8-bit sRGB file can hold: every channel quantised to its display value.
  Image out = image;
  for (auto& p : out.pixels) {
    for (int c = 0; c < 3; ++c)
      p[c] = float(reference_srgb_to_linear(linear_to_srgb8(p[c]) / 255.0));
  }
  return out;
}

TEST(SrgbTest, ConversionsFollowTheFormulas) {
  for (double c : {0.0, 0.001, 0.04045, 0.05, 0.2, 0.5, 0.9, 1.0}) {
    EXPECT_NEAR(srgb_to_linear(float(c)), reference_srgb_to_linear(c), 1e-7) << c;
  }
  for (double c : {0.0, 0.0001, 0.0031308, 0.01, 0.18, 0.5, 1.0}) {
    EXPECT_NEAR(linear_to_srgb(float(c)), reference_linear_to_srgb(c), 1e-7) << c;
  }
  EXPECT_NEAR(linear_to_srgb(srgb_to_linear(0.3f)), 0.3f, 1e-6);
}

TEST(SrgbTest, EightBitValuesSurviveALinearRoundTrip) {
  for (int v = 0; v < 256; ++v) {
    EXPECT_EQ(linear_to_srgb8(srgb_to_linear(float(v) / 255.0f)), v);
  }
}

TEST(SrgbTest, EightBitEncodingClampsAndRejectsNaN) {
  EXPECT_EQ(linear_to_srgb8(-1.0f), 0);
  EXPECT_EQ(linear_to_srgb8(0.0f), 0);
  EXPECT_EQ(linear_to_srgb8(1.0f), 255);
  EXPECT_EQ(linear_to_srgb8(7.0f), 255);
  EXPECT_EQ(linear_to_srgb8(std::nanf("")), 0);
  // 18% grey is 117.6 on the display scale.
  EXPECT_EQ(linear_to_srgb8(0.18f), 118);
}

// linear_to_srgb8 looks the code up in a table of thresholds; it must give the formula's
// lround(255 srgb(c)) for every float: checked on every 16th float of (0, 1) (66 M values),
// which includes each threshold's neighbourhood within 16 ulps, and on 64 ulps around each
// code's boundary.
TEST(SrgbTest, EightBitEncodingEqualsTheFormulaForEveryFloatChecked) {
  const auto formula = [](float c) {
    return int(std::lround(reference_linear_to_srgb(c) * 255.0));
  };
  const auto from_bits = [](uint32_t bits) {
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  };
  int mismatches = 0;
  for (uint32_t bits = 1; bits < 0x3f800000u && mismatches < 10; bits += 16) {
    const float c = from_bits(bits);
    if (linear_to_srgb8(c) != formula(c)) {
      ++mismatches;
      ADD_FAILURE() << c << ": " << int(linear_to_srgb8(c)) << " vs " << formula(c);
    }
  }
  for (int k = 1; k < 256; ++k) {
    // The boundary between codes k - 1 and k: where 255 srgb(c) = k - 0.5.
    const float edge = float(reference_srgb_to_linear((k - 0.5) / 255.0));
    uint32_t bits;
    std::memcpy(&bits, &edge, sizeof bits);
    for (uint32_t b = bits - 64; b <= bits + 64; ++b) {
      const float c = from_bits(b);
      if (c >= 1.0f) break;
      ASSERT_EQ(linear_to_srgb8(c), formula(c)) << c << " near code " << k;
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST_F(ImageTest, PngRoundTripKeepsEveryEightBitValue) {
  const Image image = test_pattern(7, 5);
  const fs::path path = dir_ / "pattern.png";
  write_image(image, path);
  const Image back = read_image(path);
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  const Image expected = quantized_like_png(image);
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(linear_to_srgb8(back.pixels[i][c]), linear_to_srgb8(image.pixels[i][c]));
      EXPECT_NEAR(back.pixels[i][c], expected.pixels[i][c], 1e-6);
    }
  }
  EXPECT_EQ(rms_error_255(image, back), 0.0);
}

TEST_F(ImageTest, ExrRoundTripIsExact) {
  Image image = test_pattern(6, 4);
  image.at(0, 0) = {1e-6f, 1234.5f, 0.0f};
  const fs::path path = dir_ / "pattern.exr";
  write_image(image, path);
  const Image back = read_image(path);
  ASSERT_EQ(back.width, 6);
  ASSERT_EQ(back.height, 4);
  for (size_t i = 0; i < image.pixels.size(); ++i) EXPECT_EQ(back.pixels[i], image.pixels[i]);
}

TEST_F(ImageTest, RowZeroIsTheTopRowOfTheFile) {
  DecodedImage raw{2, 2, 3, {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255}};
  const fs::path path = dir_ / "rows.png";
  write_image8(raw, path);
  const Image image = read_image(path);
  EXPECT_EQ(image.at(0, 0), glm::vec3(1, 0, 0));
  EXPECT_EQ(image.at(1, 0), glm::vec3(0, 1, 0));
  EXPECT_EQ(image.at(0, 1), glm::vec3(0, 0, 1));
  EXPECT_EQ(image.at(1, 1), glm::vec3(1, 1, 1));
}

TEST_F(ImageTest, DecodeFromMemoryEqualsDecodeFromFile) {
  DecodedImage raw{3, 2, 4, {}};
  for (int i = 0; i < 3 * 2 * 4; ++i) raw.data.push_back(uint8_t(i * 11 + 3));
  const fs::path png = dir_ / "rgba.png";
  write_image8(raw, png);
  const DecodedImage from_file = decode_image_file(png);
  const DecodedImage from_memory = decode_image(read_bytes(png), "rgba in memory");
  EXPECT_EQ(from_file.width, 3);
  EXPECT_EQ(from_file.height, 2);
  EXPECT_EQ(from_file.channels, 4);
  EXPECT_EQ(from_file.data, raw.data);
  EXPECT_EQ(from_memory.width, from_file.width);
  EXPECT_EQ(from_memory.height, from_file.height);
  EXPECT_EQ(from_memory.channels, from_file.channels);
  EXPECT_EQ(from_memory.data, from_file.data);

  // JPEG is lossy, but the same bytes must decode the same way on both paths.
  DecodedImage gray{16, 8, 3, std::vector<uint8_t>(16 * 8 * 3)};
  for (size_t i = 0; i < gray.data.size(); ++i) gray.data[i] = uint8_t((i * 37) % 256);
  const fs::path jpg = dir_ / "noise.jpg";
  write_image8(gray, jpg);
  const DecodedImage jpg_file = decode_image_file(jpg);
  const DecodedImage jpg_memory = decode_image(read_bytes(jpg), "jpeg in memory");
  EXPECT_EQ(jpg_memory.width, 16);
  EXPECT_EQ(jpg_memory.height, 8);
  EXPECT_EQ(jpg_memory.channels, 3);
  EXPECT_EQ(jpg_memory.data, jpg_file.data);
}

TEST_F(ImageTest, DecodesBinaryAndAsciiPpmFilesAndBinaryPpmBytes) {
  const fs::path p6 = dir_ / "binary.ppm";
  write_bytes(p6, std::string("P6\n2 1\n255\n") + std::string("\x0a\x14\x1e\xff\x00\x80", 6));
  const fs::path p3 = dir_ / "ascii.ppm";
  write_bytes(p3, "P3\n# a comment\n2 1\n255\n10 20 30\n255 0 128\n");
  const std::vector<uint8_t> expected = {10, 20, 30, 255, 0, 128};
  for (const fs::path& path : {p6, p3}) {
    const DecodedImage image = decode_image_file(path);
    EXPECT_EQ(image.width, 2) << path;
    EXPECT_EQ(image.height, 1) << path;
    EXPECT_EQ(image.channels, 3) << path;
    EXPECT_EQ(image.data, expected) << path;
  }
  // In memory (a texture inside a .glb) only the binary form decodes; the ASCII one is refused
  // by name, not misread.
  EXPECT_EQ(decode_image(read_bytes(p6), p6.string()).data, expected);
  try {
    decode_image(read_bytes(p3), "ascii in memory");
    FAIL() << "ASCII PNM bytes decoded";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("ascii in memory: ASCII PNM"));
  }
}

TEST(RmsErrorTest, IdenticalImagesHaveNoError) {
  const Image a = test_pattern(5, 5);
  EXPECT_EQ(rms_error_255(a, a), 0.0);
}

TEST(RmsErrorTest, OneDifferingPixelMatchesHandComputedValue) {
  const Image black(4, 4);
  Image one_channel = black;
  one_channel.at(2, 1) = {1.0f, 0.0f, 0.0f};  // 255 in one of 4 * 4 * 3 values
  EXPECT_DOUBLE_EQ(rms_error_255(black, one_channel), std::sqrt(255.0 * 255.0 / 48.0));

  Image white_pixel = black;
  white_pixel.at(3, 3) = glm::vec3(1.0f);  // 255 in 3 of 48 values: sqrt(3 * 255^2 / 48)
  EXPECT_DOUBLE_EQ(rms_error_255(black, white_pixel), 63.75);
  EXPECT_DOUBLE_EQ(rms_error_255(white_pixel, black), 63.75);

  // Linear 0.18 shows as 118: one channel off by 118 in a 2 x 1 image.
  Image a(2, 1), b(2, 1);
  b.at(1, 0).g = 0.18f;
  EXPECT_DOUBLE_EQ(rms_error_255(a, b), std::sqrt(118.0 * 118.0 / 6.0));
}

TEST(RmsErrorTest, DifferentSizesThrow) {
  EXPECT_THROW(rms_error_255(Image(2, 3), Image(3, 2)), Error);
  EXPECT_THROW(rms_error_255(Image(2, 3), to_srgb8(Image(3, 2))), Error);
  Srgb8Image short_codes = to_srgb8(Image(2, 3));
  short_codes.codes.pop_back();
  EXPECT_THROW(rms_error_255(Image(2, 3), short_codes), Error);
}

// An image compared through its display codes (what afr-eval does with its ideal frames) gives
// what comparing the images gives, and the codes are linear_to_srgb8 of each channel in order.
TEST(RmsErrorTest, ComparingWithDisplayCodesEqualsComparingImages) {
  const Image a = test_pattern(7, 5);
  Image b(7, 5);
  for (size_t i = 0; i < b.pixels.size(); ++i) {
    const float f = float(i) / float(b.pixels.size());
    b.pixels[i] = {f * f, 1.2f - f, i % 3 == 0 ? -0.5f : 0.5f * f};
  }
  const Srgb8Image codes = to_srgb8(b);
  ASSERT_EQ(codes.width, 7);
  ASSERT_EQ(codes.height, 5);
  ASSERT_EQ(codes.codes.size(), 3 * b.pixels.size());
  for (size_t i = 0; i < b.pixels.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(codes.codes[3 * i + size_t(c)], linear_to_srgb8(b.pixels[i][c])) << i << " " << c;
    }
  }
  EXPECT_GT(rms_error_255(a, codes), 10.0);
  EXPECT_EQ(rms_error_255(a, codes), rms_error_255(a, b));
  EXPECT_EQ(rms_error_255(b, to_srgb8(b)), 0.0);
}

TEST_F(ImageTest, CorruptFileFailsNamingIt) {
  const fs::path path = dir_ / "broken.png";
  write_bytes(path, "this is not a picture at all");
  for (auto read : {+[](const fs::path& p) { read_image(p); },
                    +[](const fs::path& p) { decode_image_file(p); }}) {
    try {
      read(path);
      ADD_FAILURE() << "no error for a corrupt file";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("broken.png"), std::string::npos) << e.what();
    }
  }
}

// WebP (EXT_texture_webp) decodes in memory: lossless bytes give back the pixels, RGB as 3
// channels and RGBA as 4; from a file the same; cut short, the error names the image.
TEST_F(ImageTest, WebpDecodesInMemoryAndFromAFile) {
  for (int channels : {3, 4}) {
    SCOPED_TRACE(channels);
    DecodedImage raw{5, 3, channels, {}};
    for (int i = 0; i < 5 * 3 * channels; ++i) raw.data.push_back(uint8_t(i * 13 + 7));
    // A nearly transparent pixel keeps its color (the encoder may change a fully transparent
    // one's: its color does not show).
    if (channels == 4) raw.data[3] = 1;
    const std::vector<uint8_t> bytes = testing::lossless_webp(raw);
    const DecodedImage decoded = decode_image(bytes, "webp in memory");
    EXPECT_EQ(decoded.width, 5);
    EXPECT_EQ(decoded.height, 3);
    EXPECT_EQ(decoded.channels, channels);
    EXPECT_EQ(decoded.data, raw.data);
    const fs::path file = dir_ / "image.webp";
    std::ofstream(file, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    EXPECT_EQ(decode_image_file(file).data, raw.data);

    std::vector<uint8_t> truncated = bytes;
    truncated.resize(truncated.size() / 2);
    try {
      decode_image(truncated, "half a webp");
      ADD_FAILURE() << "no error for a truncated WebP";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("half a webp"), std::string::npos) << e.what();
    }
  }
}

TEST_F(ImageTest, CorruptBytesFailNamingTheImage) {
  const std::vector<uint8_t> garbage = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  try {
    decode_image(garbage, "image 3 of scene.glb");
    ADD_FAILURE() << "no error for garbage bytes";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image 3 of scene.glb"), std::string::npos) << e.what();
  }

  // A PNG cut off after its header.
  const fs::path png = dir_ / "whole.png";
  write_image(test_pattern(8, 8), png);
  std::vector<uint8_t> truncated = read_bytes(png);
  truncated.resize(truncated.size() / 2);
  try {
    decode_image(truncated, "half a png");
    ADD_FAILURE() << "no error for a truncated PNG";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("half a png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(decode_image({}, "nothing"), Error);
}

TEST_F(ImageTest, MissingAndUnwritableFilesFailNamingThem) {
  const fs::path missing = dir_ / "missing.exr";
  try {
    read_image(missing);
    ADD_FAILURE() << "no error for a missing file";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.exr"), std::string::npos) << e.what();
  }
  const fs::path unwritable = dir_ / "no" / "such" / "folder" / "out.png";
  try {
    write_image(Image(2, 2), unwritable);
    ADD_FAILURE() << "no error for an unwritable path";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out.png"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace afr
