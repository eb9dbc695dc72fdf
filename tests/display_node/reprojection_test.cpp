#include <afr/display/reprojection.h>

#include <afr/common/random.h>

#include <gtest/gtest.h>

namespace afr {
namespace {

// Projects random points with `cam`'s Projector (float) and with Camera::project (double) and
// expects the same answer; returns how many projected.
int expect_projector_agrees_with(const Camera& cam, uint64_t seed) {
  const Projector proj(cam, 320, 200);
  Pcg32 rng(seed);
  int in_front = 0;
  for (int i = 0; i < 2000; ++i) {
    const glm::dvec3 p(20 * rng.next_double() - 10, 20 * rng.next_double() - 10,
                       20 * rng.next_double() - 10);
    glm::dvec2 want;
    const bool ok = cam.project(p, 320, 200, &want, nullptr);
    float x, y;
    const bool got = proj.project_point(glm::vec3(p), &x, &y);
    // Points within a hair of znear may go either way in float.
    if (std::abs(glm::dot(p - cam.eye, cam.forward) - cam.znear) < 1e-4) continue;
    EXPECT_EQ(ok && std::abs(want.x) < 1e7 && std::abs(want.y) < 1e7, got) << i;
    if (!got) continue;
    ++in_front;
    const double tol = 1e-5 * std::max(1.0, std::abs(want.x) + std::abs(want.y));
    EXPECT_NEAR(x, want.x, std::max(tol, 2e-3));
    EXPECT_NEAR(y, want.y, std::max(tol, 2e-3));
  }
  return in_front;
}

TEST(ReprojectionTest, ProjectorAgreesWithTheCamerasDoubleProjection) {
  const Camera cam = Camera::look_at({1, 2, 3}, {-1, 0.5, -2}, {0, 1, 0.2}, 0.9, 0.05);
  EXPECT_GT(expect_projector_agrees_with(cam, 5), 500);
}

TEST(ReprojectionTest, AnOrthographicProjectorAgreesWithTheCameraAndPlacesNoDirection) {
  Camera cam = Camera::look_at({1, 2, 3}, {-1, 0.5, -2}, {0, 1, 0.2}, 0.9, 0.05);
  cam.ymag = 2.5;
  EXPECT_GT(expect_projector_agrees_with(cam, 6), 500);
  // Its rays share one direction, so a direction says nothing of where a miss is seen.
  const Projector proj(cam, 320, 200);
  float x, y;
  EXPECT_FALSE(proj.project_direction(glm::vec3(cam.forward), &x, &y));
  StoredSample miss;
  miss.position = glm::vec3(cam.forward);
  miss.flags = kStoredHasPosition | kStoredMiss;
  EXPECT_FALSE(proj.project(miss, 0.0f, &x, &y));
}

TEST(ReprojectionTest, DirectionsProjectLikePointsAtInfinityAndIgnoreTheEye) {
  const Camera a = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  Camera b = a;
  b.eye = glm::dvec3(5, -3, 2);  // translation does not move directions
  const Projector pa(a, 64, 48), pb(b, 64, 48);
  const glm::vec3 d = glm::normalize(glm::vec3(0.2f, -0.1f, -1.0f));
  float xa, ya, xb, yb;
  ASSERT_TRUE(pa.project_direction(d, &xa, &ya));
  ASSERT_TRUE(pb.project_direction(d, &xb, &yb));
  EXPECT_FLOAT_EQ(xa, xb);
  EXPECT_FLOAT_EQ(ya, yb);
  glm::dvec2 far;
  ASSERT_TRUE(a.project(glm::dvec3(d) * 1e6, 64, 48, &far, nullptr));
  // Positions are rounded to kPositionStep.
  EXPECT_NEAR(xa, far.x, 1e-3 + 0.5 * kPositionStep);
  EXPECT_NEAR(ya, far.y, 1e-3 + 0.5 * kPositionStep);
  EXPECT_FALSE(pa.project_direction(-d, &xa, &ya));  // pointing backwards
}

TEST(ReprojectionTest, VelocityMovesTheHitPointOverTheSamplesAge) {
  const Camera cam = Camera::look_at({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 1.0, 0.01);
  const Projector proj(cam, 100, 100);
  StoredSample s;
  s.position = glm::vec3(0.0f, 0.0f, -5.0f);
  s.velocity = glm::vec3(1.0f, 0.5f, 0.0f);
  s.flags = kStoredHasPosition | kStoredHasVelocity;
  float x, y, wx, wy;
  ASSERT_TRUE(proj.project(s, 0.4f, &x, &y));
  ASSERT_TRUE(proj.project_point(glm::vec3(0.4f, 0.2f, -5.0f), &wx, &wy));
  EXPECT_FLOAT_EQ(x, wx);
  EXPECT_FLOAT_EQ(y, wy);
  EXPECT_GT(x, 50.0f);           // moved right
  EXPECT_LT(y, 50.0f);           // and up (y down)
  s.flags = kStoredHasPosition;  // without the velocity field it stays
  ASSERT_TRUE(proj.project(s, 0.4f, &x, &y));
  EXPECT_FLOAT_EQ(x, 50.0f);
  EXPECT_FLOAT_EQ(y, 50.0f);
  s.position = glm::vec3(0.0f, 0.0f, 1.0f);  // behind
  EXPECT_FALSE(proj.project(s, 0.0f, &x, &y));
}

}  // namespace
}  // namespace afr
