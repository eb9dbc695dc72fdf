#include <afr/common/camera.h>

#include <gtest/gtest.h>

#include <random>

namespace afr {
namespace {

TEST(CameraTest, CenterRayLooksForwardAndCornersSpanTheFieldOfView) {
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, glm::radians(90.0), 0.01);
  const Ray center = cam.ray(50, 25, 100, 50);
  EXPECT_NEAR(center.direction.z, -1.0f, 1e-6f);
  // With a 90 degree vertical field of view the top edge is at 45 degrees; the right edge at
  // atan(aspect = 2).
  const Ray top = cam.ray(50, 0, 100, 50);
  EXPECT_NEAR(top.direction.y, std::sqrt(0.5f), 1e-6f);
  const Ray right = cam.ray(100, 25, 100, 50);
  EXPECT_NEAR(right.direction.x / -right.direction.z, 2.0f, 1e-5f);
}

TEST(CameraTest, ProjectInvertsRay) {
  const Camera cam =
      Camera::look_at({1, 2, 3}, {-1, 0.5, -2}, {0, 1, 0.2}, glm::radians(40.0), 0.01);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const double x = 640 * u(rng), y = 480 * u(rng), dist = 0.1 + 10 * u(rng);
    const Ray r = cam.ray(x, y, 640, 480);
    const glm::dvec3 p = glm::dvec3(r.origin) + dist * glm::dvec3(r.direction);
    glm::dvec2 xy;
    double depth;
    ASSERT_TRUE(cam.project(p, 640, 480, &xy, &depth));
    EXPECT_NEAR(xy.x, x, 1e-3);
    EXPECT_NEAR(xy.y, y, 1e-3);
  }
}

TEST(CameraTest, PointsBehindTheCameraDoNotProject) {
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.1);
  glm::dvec2 xy;
  EXPECT_FALSE(cam.project({0, 0, 1}, 10, 10, &xy, nullptr));
  EXPECT_FALSE(cam.project({0, 0, -0.05}, 10, 10, &xy, nullptr));  // nearer than znear
  EXPECT_TRUE(cam.project({0, 0, -0.2}, 10, 10, &xy, nullptr));
}

TEST(CameraTest, FromTransformUsesLocalMinusZAndIgnoresScale) {
  // A node rotated 90 degrees about +Y looks down -X; scaled by 3 it must look the same.
  glm::dmat4 m = glm::rotate(glm::dmat4(1.0), glm::radians(90.0), glm::dvec3(0, 1, 0));
  m = glm::scale(m, glm::dvec3(3.0));
  m[3] = glm::dvec4(5, 6, 7, 1);
  const Camera cam = Camera::from_transform(m, 1.0, 0.1);
  EXPECT_NEAR(cam.forward.x, -1.0, 1e-12);
  EXPECT_NEAR(cam.up.y, 1.0, 1e-12);
  EXPECT_NEAR(cam.right.z, -1.0, 1e-12);
  EXPECT_EQ(cam.eye, glm::dvec3(5, 6, 7));
}

TEST(CameraTest, LookAtStraightUpStillGivesAnOrthonormalBasis) {
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 5, 0}, {0, 1, 0}, 1.0, 0.1);
  EXPECT_NEAR(glm::length(cam.right), 1.0, 1e-12);
  EXPECT_NEAR(glm::dot(cam.right, cam.forward), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(cam.up, cam.forward), 0.0, 1e-12);
  const Ray r = cam.ray(3, 3, 7, 7);
  EXPECT_TRUE(std::isfinite(r.direction.x));
}

TEST(CameraTest, AnOrthographicCameraProjectsAlongItsAxisAndInvertsItsRays) {
  Camera cam = Camera::look_at({1, 2, 3}, {-1, 0.5, -2}, {0, 1, 0.2}, glm::radians(40.0), 0.01);
  cam.ymag = 1.5;
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const double x = 640 * u(rng), y = 480 * u(rng), dist = 0.1 + 10 * u(rng);
    const Ray r = cam.ray(x, y, 640, 480);
    // Every ray runs along the view, from the eye's plane.
    EXPECT_NEAR(glm::dot(glm::dvec3(r.direction), cam.forward), 1.0, 1e-6);
    EXPECT_NEAR(glm::dot(glm::dvec3(r.origin) - cam.eye, cam.forward), 0.0, 1e-5);
    const glm::dvec3 p = glm::dvec3(r.origin) + dist * glm::dvec3(r.direction);
    glm::dvec2 xy;
    double depth;
    ASSERT_TRUE(cam.project(p, 640, 480, &xy, &depth));
    EXPECT_NEAR(xy.x, x, 1e-3);
    EXPECT_NEAR(xy.y, y, 1e-3);
    EXPECT_NEAR(depth, dist, 1e-5);
  }
  // The view is 2 ymag high and as wide as the image's aspect ratio makes it, at any depth.
  const Ray top_left = cam.ray(0, 0, 640, 480), bottom_right = cam.ray(640, 480, 640, 480);
  const glm::dvec3 across = glm::dvec3(bottom_right.origin) - glm::dvec3(top_left.origin);
  EXPECT_NEAR(glm::dot(across, cam.right), 4.0, 1e-5);
  EXPECT_NEAR(glm::dot(across, cam.up), -3.0, 1e-5);
  // A ray is a pixel wide from its start and does not spread.
  EXPECT_EQ(top_left.spread, 0.0f);
  EXPECT_NEAR(top_left.cone, 3.0f / 480.0f, 1e-7f);
  // Nearer than znear or behind the eye's plane it sees nothing, as a perspective camera.
  glm::dvec2 xy;
  EXPECT_FALSE(cam.project(cam.eye - cam.forward, 640, 480, &xy, nullptr));
  EXPECT_FALSE(cam.project(cam.eye + 0.005 * cam.forward, 640, 480, &xy, nullptr));
}

}  // namespace
}  // namespace afr
