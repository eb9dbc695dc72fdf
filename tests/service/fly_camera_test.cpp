#include <afr/display/service/fly_camera.h>

#include <gtest/gtest.h>

#include <cmath>

namespace afr::service {
namespace {

void expect_orthonormal(const Camera& c) {
  EXPECT_NEAR(glm::length(c.forward), 1.0, 1e-12);
  EXPECT_NEAR(glm::length(c.right), 1.0, 1e-12);
  EXPECT_NEAR(glm::length(c.up), 1.0, 1e-12);
  EXPECT_NEAR(glm::dot(c.forward, c.right), 0.0, 1e-12);
  EXPECT_NEAR(glm::dot(c.forward, c.up), 0.0, 1e-12);
}

TEST(FlyCameraTest, StartsWhereTheGivenCameraLooks) {
  const Camera start = Camera::look_at({1, 2, 3}, {4, 1, -2}, {0, 1, 0}, 0.9, 0.05);
  const Camera c = FlyCamera(start, 1.0).camera();
  EXPECT_NEAR(glm::length(c.forward - start.forward), 0.0, 1e-9);
  EXPECT_EQ(c.eye, start.eye);
  EXPECT_EQ(c.yfov, start.yfov);
  EXPECT_EQ(c.znear, start.znear);
  expect_orthonormal(c);
}

TEST(FlyCameraTest, DraggingRightTurnsRightByTheAngleAndUpLooksUp) {
  const Camera start = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 0.8, 0.01);
  FlyCamera fly(start, 1.0);
  fly.look(100.0, 0.0, 0.003);  // 0.3 rad to the right
  Camera c = fly.camera();
  EXPECT_NEAR(std::acos(glm::dot(c.forward, start.forward)), 0.3, 1e-9);
  EXPECT_GT(glm::dot(c.forward, start.right), 0.0);
  EXPECT_NEAR(c.forward.y, 0.0, 1e-12);  // yaw only
  fly.look(0.0, -100.0, 0.003);          // dragging up
  c = fly.camera();
  EXPECT_NEAR(std::asin(c.forward.y), 0.3, 1e-9);
  expect_orthonormal(c);
  // Pitch stops short of straight up however far the drag goes, and never flips over.
  fly.look(0.0, -1e7, 0.003);
  c = fly.camera();
  EXPECT_NEAR(std::asin(c.forward.y), 1.55, 1e-9);
  EXPECT_GT(c.up.y, 0.0);
  expect_orthonormal(c);
  // Input that is not finite is ignored.
  fly.look(NAN, 1.0);
  fly.move({0, 0, 1}, INFINITY);
  EXPECT_EQ(fly.camera().forward, c.forward);
  EXPECT_EQ(fly.camera().eye, c.eye);
}

// + and - in the window: each step narrows or widens a perspective view's yfov by the zoom
// step, within its bounds, and an orthographic view's height (ymag) likewise, with no bound but
// a positive one; the position and direction stay.
TEST(FlyCameraTest, ZoomNarrowsThePerspectiveFieldOrTheOrthographicHeight) {
  const Camera start = Camera::look_at({0, 1, 5}, {0, 1, 0}, {0, 1, 0}, 0.8, 0.01);
  FlyCamera fly(start, 1.0);
  fly.zoom(2.0);
  EXPECT_NEAR(fly.camera().yfov, 0.8 * FlyCamera::kZoomStep * FlyCamera::kZoomStep, 1e-12);
  fly.zoom(-2.0);
  EXPECT_NEAR(fly.camera().yfov, 0.8, 1e-12);
  EXPECT_EQ(fly.camera().eye, start.eye);
  EXPECT_NEAR(glm::length(fly.camera().forward - start.forward), 0.0, 1e-12);
  fly.zoom(1e6);  // as far as it goes
  EXPECT_NEAR(fly.camera().yfov, FlyCamera::kMinYfov, 1e-12);
  fly.zoom(-1e6);
  EXPECT_NEAR(fly.camera().yfov, FlyCamera::kMaxYfov, 1e-12);
  fly.zoom(NAN);
  EXPECT_NEAR(fly.camera().yfov, FlyCamera::kMaxYfov, 1e-12);

  Camera ortho = start;
  ortho.ymag = 2.0;
  FlyCamera flat(ortho, 1.0);
  flat.zoom(1.0);
  EXPECT_NEAR(flat.camera().ymag, 2.0 * FlyCamera::kZoomStep, 1e-12);
  EXPECT_EQ(flat.camera().yfov, ortho.yfov);
  flat.zoom(-3.0);
  EXPECT_NEAR(flat.camera().ymag, 2.0 / std::pow(FlyCamera::kZoomStep, 2.0), 1e-12);
  flat.look(10.0, 0.0);  // turning keeps it orthographic and its height
  EXPECT_NEAR(flat.camera().ymag, 2.0 / std::pow(FlyCamera::kZoomStep, 2.0), 1e-12);
}

TEST(FlyCameraTest, MovesAlongItsOwnAxesAtItsSpeed) {
  const Camera start = Camera::look_at({0, 1, 0}, {1, 1, 0}, {0, 1, 0}, 0.8, 0.01);
  FlyCamera fly(start, 2.0);
  fly.move({0, 0, 1}, 0.5);  // forward, 2 units/s for 0.5 s
  EXPECT_NEAR(glm::length(fly.camera().eye - glm::dvec3(1, 1, 0)), 0.0, 1e-12);
  fly.move({1, 0, 0}, 1.0);  // right: +z when looking along +x
  EXPECT_NEAR(glm::length(fly.camera().eye - glm::dvec3(1, 1, 2)), 0.0, 1e-12);
  fly.move({0, 5, 0}, 1.0);  // clamped to 1: up by 2
  EXPECT_NEAR(fly.camera().eye.y, 3.0, 1e-12);
}

}  // namespace
}  // namespace afr::service
