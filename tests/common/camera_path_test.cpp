#include <afr/common/camera_path.h>

#include <afr/common/error.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>

namespace afr {
namespace {

// A rotation by `degrees` about a unit axis, written out from the half-angle formula (not
// through glm's helpers, which the code under test uses).
glm::dquat axis_angle(glm::dvec3 axis, double degrees) {
  const double h = 0.5 * degrees * std::numbers::pi / 180.0;
  return glm::dquat(std::cos(h), axis.x * std::sin(h), axis.y * std::sin(h), axis.z * std::sin(h));
}

// The message of the afr::Error that parsing `text` throws ("" when it does not throw).
std::string parse_error(const std::string& text) {
  try {
    parse_camera_path(text, "paths/test.path");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(CameraPathTest, WrittenPathReadsBackBitForBit) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::vector<CameraKey> keys;
  double t = -1.0 / 3.0;
  for (int i = 0; i < 200; ++i) {
    CameraKey k;
    t += 1.0 / 60.0 + 1e-3 * std::abs(u(rng));
    k.time = t;
    k.eye = glm::dvec3(u(rng), u(rng), u(rng) * 1e-7);
    k.rotation = glm::normalize(glm::dquat(u(rng), u(rng), u(rng), u(rng)));
    k.yfov = 0.1 + 0.25 * std::abs(u(rng));
    keys.push_back(k);
  }
  const CameraPath path(keys);
  const CameraPath back = parse_camera_path(format_camera_path(path), "round trip");
  ASSERT_EQ(back.keys().size(), path.keys().size());
  for (size_t i = 0; i < keys.size(); ++i) {
    const CameraKey &a = path.keys()[i], &b = back.keys()[i];
    EXPECT_EQ(a.time, b.time);
    EXPECT_EQ(a.eye, b.eye);
    EXPECT_EQ(a.rotation.x, b.rotation.x);
    EXPECT_EQ(a.rotation.y, b.rotation.y);
    EXPECT_EQ(a.rotation.z, b.rotation.z);
    EXPECT_EQ(a.rotation.w, b.rotation.w);
    EXPECT_EQ(a.yfov, b.yfov);
  }
}

TEST(CameraPathTest, FileRoundTripAndCommentsBlankLinesAndCrlf) {
  const std::string text =
      "# afr camera path v1\r\n"
      "# t ex ey ez qx qy qz qw yfov\r\n"
      "\r\n"
      "0 1 2 3 0 0 0 1 0.5\r\n"
      "  # an indented comment\r\n"
      "0.5\t4 5 6   0 0 0 2 0.7\r\n";  // an unnormalised quaternion is normalised
  const CameraPath path = parse_camera_path(text, "crlf");
  ASSERT_EQ(path.keys().size(), 2u);
  EXPECT_EQ(path.keys()[1].eye, glm::dvec3(4, 5, 6));
  EXPECT_DOUBLE_EQ(path.keys()[1].rotation.w, 1.0);
  EXPECT_DOUBLE_EQ(path.keys()[1].yfov, 0.7);

  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / "afr_camera_path_test.path";
  write_camera_path(path, file);
  const CameraPath back = read_camera_path(file);
  std::filesystem::remove(file);
  ASSERT_EQ(back.keys().size(), 2u);
  EXPECT_EQ(back.keys()[0].eye, glm::dvec3(1, 2, 3));
  EXPECT_EQ(back.keys()[1].time, 0.5);
}

TEST(CameraPathTest, PoseInterpolatesEyeLinearlyAndRotationAlongTheShortArc) {
  CameraKey a, b;
  a.time = 1.0;
  a.eye = glm::dvec3(0, 0, 0);
  a.rotation = axis_angle(glm::dvec3(0, 1, 0), 10.0);
  a.yfov = 0.5;
  b.time = 3.0;
  b.eye = glm::dvec3(4, -2, 8);
  // 70 degrees, written as the negated quaternion: the same rotation, the long way round if
  // slerped naively.
  b.rotation = -axis_angle(glm::dvec3(0, 1, 0), 70.0);
  b.yfov = 1.0;
  const CameraPath path({a, b});

  const CameraKey mid = path.pose(1.5);  // a quarter of the way
  EXPECT_NEAR(mid.eye.x, 1.0, 1e-12);
  EXPECT_NEAR(mid.eye.y, -0.5, 1e-12);
  EXPECT_NEAR(mid.eye.z, 2.0, 1e-12);
  EXPECT_NEAR(mid.yfov, 0.625, 1e-12);
  const glm::dquat expected = axis_angle(glm::dvec3(0, 1, 0), 25.0);
  EXPECT_NEAR(std::abs(glm::dot(mid.rotation, expected)), 1.0, 1e-12);

  // Held still outside the keys.
  EXPECT_EQ(path.pose(-5.0).eye, a.eye);
  EXPECT_EQ(path.pose(100.0).eye, b.eye);
  EXPECT_EQ(path.pose(std::nan("")).eye, a.eye);
}

TEST(CameraPathTest, KeyOfACameraGivesTheSameCameraBack) {
  const Camera cam = Camera::look_at({1, 2, 3}, {-4, 0.5, -2}, {0, 1, 0}, glm::radians(50.0), 0.01);
  const CameraPath path({camera_key(0.0, cam)});
  const Camera back = path.camera(0.0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(back.eye[i], cam.eye[i], 1e-12);
    EXPECT_NEAR(back.forward[i], cam.forward[i], 1e-12);
    EXPECT_NEAR(back.up[i], cam.up[i], 1e-12);
    EXPECT_NEAR(back.right[i], cam.right[i], 1e-12);
  }
  EXPECT_DOUBLE_EQ(back.yfov, cam.yfov);
  // A rotation about +Y by 90 degrees looks down -X (glTF's camera convention).
  CameraKey k;
  k.rotation = axis_angle(glm::dvec3(0, 1, 0), 90.0);
  const Camera turned = CameraPath({k}).camera(0.0);
  EXPECT_NEAR(turned.forward.x, -1.0, 1e-12);
  EXPECT_NEAR(turned.up.y, 1.0, 1e-12);
}

TEST(CameraPathTest, MalformedFilesNameTheFileAndLine) {
  const std::string h = "# afr camera path v1\n";
  EXPECT_EQ(parse_error(""), "paths/test.path:1: expected the header '# afr camera path v1'");
  EXPECT_EQ(parse_error("# afr camera path v2\n0 0 0 0 0 0 0 1 1\n"),
            "paths/test.path:1: expected the header '# afr camera path v1'");
  EXPECT_EQ(parse_error(h), "paths/test.path:1: no keys after the header");
  EXPECT_EQ(parse_error(h + "# only comments\n\n"), "paths/test.path:3: no keys after the header");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 1\n1 0 0 0 0 0 1\n"),
            "paths/test.path:3: expected 9 or 10 numbers (t ex ey ez qx qy qz qw yfov [ymag]), "
            "found 7");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 1 5 6\n"),
            "paths/test.path:2: expected 9 or 10 numbers (t ex ey ez qx qy qz qw yfov [ymag]), "
            "found 11");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 1 -2\n"),
            "paths/test.path:2: ymag -2 is not finite and >= 0");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 1 2\n1 0 0 0 0 0 0 1 1\n"),
            "paths/test.path:3: ymag 0 after the previous key's 2: a path is perspective (0) or "
            "orthographic (> 0) throughout");
  EXPECT_EQ(parse_error(h + "0 0 0 x 0 0 0 1 1\n"), "paths/test.path:2: 'x' is not a number");
  EXPECT_EQ(parse_error(h + "0 0 0 1.5e 0 0 0 1 1\n"), "paths/test.path:2: '1.5e' is not a number");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 1\n\n0 0 0 0 0 0 0 1 1\n"),
            "paths/test.path:4: time 0 is not after the previous key's 0");
  EXPECT_EQ(parse_error(h + "nan 0 0 0 0 0 0 1 1\n"), "paths/test.path:2: the time is not finite");
  EXPECT_EQ(parse_error(h + "0 inf 0 0 0 0 0 1 1\n"), "paths/test.path:2: the eye is not finite");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 0 1\n"),
            "paths/test.path:2: the rotation quaternion has (nearly) zero length");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 0\n"),
            "paths/test.path:2: yfov 0 is outside (0, pi) radians");
  EXPECT_EQ(parse_error(h + "0 0 0 0 0 0 0 1 3.5\n"),
            "paths/test.path:2: yfov 3.5 is outside (0, pi) radians");
  EXPECT_THROW(read_camera_path("/nonexistent/afr/none.path"), Error);
  EXPECT_THROW(CameraPath(std::vector<CameraKey>{}), Error);
}

TEST(CameraPathTest, AnOrthographicPathKeepsItsYmagAndReadsBack) {
  CameraKey a, b;
  a.ymag = 2.0;
  b.time = 1.0;
  b.eye = glm::dvec3(4.0, 0.0, 0.0);
  b.ymag = 3.0;
  const CameraPath path({a, b});
  EXPECT_DOUBLE_EQ(path.pose(0.5).ymag, 2.5);
  const Camera middle = path.camera(0.5);
  EXPECT_TRUE(middle.orthographic());
  EXPECT_DOUBLE_EQ(middle.ymag, 2.5);
  EXPECT_EQ(camera_key(0.5, middle).ymag, 2.5);
  const std::string text = format_camera_path(path);
  EXPECT_NE(text.find("yfov ymag\n"), std::string::npos) << text;
  const CameraPath again = parse_camera_path(text, "again");
  EXPECT_EQ(again.keys()[1].ymag, 3.0);
  // A perspective path is written in the nine columns it always had.
  const std::string perspective = format_camera_path(CameraPath({CameraKey{}}));
  EXPECT_EQ(perspective.find("ymag"), std::string::npos) << perspective;
  EXPECT_FALSE(parse_camera_path(perspective, "p").camera(0.0).orthographic());
}

// Fuzzing found this (docs/robustness.md): a quaternion with a component near 1e308 has a
// length that overflows, and was normalised to zero, so its written path could not be read.
TEST(CameraPathTest, HugeRotationComponentsNormaliseWithoutOverflow) {
  const CameraPath path = parse_camera_path(
      "# afr camera path v1\n0 1 2 3 0 1e308 0 1e308 0.8\n1 1 2 3 0 0 -1.7e308 0 0.8\n", "huge");
  const double h = std::sqrt(0.5);
  EXPECT_NEAR(path.keys()[0].rotation.y, h, 1e-15);
  EXPECT_NEAR(path.keys()[0].rotation.w, h, 1e-15);
  EXPECT_EQ(path.keys()[1].rotation, glm::dquat(0.0, 0.0, 0.0, -1.0));
  const CameraPath again = parse_camera_path(format_camera_path(path), "again");
  EXPECT_EQ(again.keys()[0].rotation, path.keys()[0].rotation);
  EXPECT_EQ(parse_error("# afr camera path v1\n0 0 0 0 1e-7 0 0 0 1\n"),
            "paths/test.path:2: the rotation quaternion has (nearly) zero length");
}

}  // namespace
}  // namespace afr
