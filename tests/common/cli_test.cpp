#include <afr/common/cli.h>
#include <afr/common/error.h>

#include <gtest/gtest.h>
#include <CLI/CLI.hpp>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace afr {
namespace {

// Parses `args` (after a program name) with the options of a small program; returns the
// error's text, empty when the arguments were taken.
std::string parse(std::vector<std::string> args, double* fps = nullptr) {
  CLI::App app{"test"};
  double rate = 60.0;
  std::vector<double> starts;
  int count = 1;
  std::string name;
  app.add_option("--fps", rate)->check(CLI::Range(1.0, 1000.0));
  app.add_option("--start", starts)->delimiter(',');
  app.add_option("--count", count);
  app.add_option("--name", name);
  CLI::App* sub = app.add_subcommand("sub");
  double limit = 1.0;
  sub->add_option("--limit", limit);
  refuse_non_finite(app);
  std::vector<std::string> reversed(args.rbegin(), args.rend());
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    return e.what();
  }
  if (fps) *fps = rate;
  return {};
}

TEST(CliTest, FloatingOptionsRefuseNanAndInfinityByName) {
  double fps = 0.0;
  EXPECT_EQ(parse({"--fps", "30"}, &fps), "");
  EXPECT_EQ(fps, 30.0);
  // CLI::Range alone would take NaN: every comparison with it is false.
  const std::string nan = parse({"--fps", "nan"});
  EXPECT_NE(nan.find("--fps"), std::string::npos) << nan;
  EXPECT_NE(nan.find("nan is not a finite number"), std::string::npos) << nan;
  EXPECT_NE(parse({"--start", "1,inf"}).find("inf is not a finite number"), std::string::npos);
  EXPECT_NE(parse({"--start", "-infinity"}), "");
  EXPECT_NE(parse({"sub", "--limit", "NaN"}).find("--limit"), std::string::npos);
  // Text and whole-number options are left alone.
  EXPECT_EQ(parse({"--name", "nan"}), "");
  EXPECT_EQ(parse({"--start", "0.5,2", "--count", "3"}), "");
}

// --ray-depth takes a whole number from 0 to kMaxRayDepth, absent by default, and its help
// says where the depth goes.
TEST(CliTest, RayDepthOptionTakesAWholeNumberInRange) {
  const auto parse_depth = [](std::vector<std::string> args, std::optional<int>* depth) {
    CLI::App app{"test"};
    add_ray_depth_option(app, depth, "into the scene");
    std::vector<std::string> reversed(args.rbegin(), args.rend());
    try {
      app.parse(reversed);
    } catch (const CLI::ParseError& e) {
      return std::string(e.what());
    }
    EXPECT_NE(app.help().find("into the scene (default: the file's extras.afr_ray_depth"),
              std::string::npos)
        << app.help();
    return std::string();
  };
  std::optional<int> depth;
  EXPECT_EQ(parse_depth({}, &depth), "");
  EXPECT_EQ(depth, std::nullopt);
  EXPECT_EQ(parse_depth({"--ray-depth", "6"}, &depth), "");
  EXPECT_EQ(depth, std::optional<int>(6));
  for (const std::string bad : {"11", "-1", "2.5", "deep"}) {
    std::optional<int> refused;
    const std::string error = parse_depth({"--ray-depth", bad}, &refused);
    EXPECT_NE(error.find("--ray-depth"), std::string::npos) << bad << ": " << error;
    EXPECT_EQ(refused, std::nullopt) << bad;
  }
}

TEST(CliTest, ImageSizesAreCheckedWithTheirReason) {
  EXPECT_EQ(parse_image_size("256x128").width, 256);
  EXPECT_THROW(parse_image_size("256"), Error);
  EXPECT_THROW(parse_image_size("0x5"), Error);
  EXPECT_THROW(parse_image_size("40000x5"), Error);
}

// A camera's aspect ratio at a size's pixel count, each side rounded.
TEST(CliTest, ImageSizeForAnAspectRatioKeepsThePixelCount) {
  const auto size = [](ImageExtent pixels, double aspect) {
    const ImageExtent e = image_size_for_aspect(pixels, aspect);
    return std::to_string(e.width) + "x" + std::to_string(e.height);
  };
  EXPECT_EQ(size({256, 256}, 16.0 / 9.0), "341x192");
  EXPECT_EQ(size({256, 256}, 2.0), "362x181");
  EXPECT_EQ(size({256, 256}, 0.5), "181x362");
  EXPECT_EQ(size({320, 240}, 1.0), "277x277");
  // None, or one that is not a number > 0: the size as it is; extremes within [1/16, 16].
  EXPECT_EQ(size({256, 256}, 0.0), "256x256");
  EXPECT_EQ(size({256, 256}, -1.0), "256x256");
  EXPECT_EQ(size({256, 256}, std::nan("")), "256x256");
  EXPECT_EQ(size({256, 256}, 1e9), "1024x64");
  EXPECT_EQ(size({1, 1}, 1e-9), "1x4");
}

}  // namespace
}  // namespace afr
