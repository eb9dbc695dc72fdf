#include <afr/bench/ideal_renderer.h>

#include <gtest/gtest.h>

#include "support/test_scenes.h"

namespace afr {
namespace {

TEST(IdealRendererTest, UniformSceneRendersExactlyItsColor) {
  // Emission only, no lights, no ambient: every sample has the same radiance.
  Scene s = testing::camera_scene();
  s.background = glm::vec3(0.3f, 0.5f, 0.7f);
  testing::add_quad(&s, glm::vec3(0.3f, 0.5f, 0.7f), {-100, -100}, {100, 100});
  s.finalize();
  Tracer tracer(s);
  IdealRenderOptions o;
  o.width = 17;
  o.height = 9;
  o.strata = 3;
  const Image image = render_ideal(tracer, o);
  for (const glm::vec3& p : image.pixels) {
    EXPECT_NEAR(p.r, 0.3f, 1e-6f);
    EXPECT_NEAR(p.g, 0.5f, 1e-6f);
    EXPECT_NEAR(p.b, 0.7f, 1e-6f);
  }
}

TEST(IdealRendererTest, EdgesAreAntialiased) {
  // A white half plane (x < 0 in view) on black: the column at the edge is a blend.
  Scene s = testing::camera_scene();
  testing::add_quad(&s, glm::vec3(1.0f), {-100, -100}, {0.0f, 100});
  s.finalize();
  Tracer tracer(s);
  IdealRenderOptions o;
  o.width = 16;
  o.height = 4;
  o.strata = 8;
  const Image image = render_ideal(tracer, o);
  // The edge falls exactly between columns 7 and 8; the filter reaches one pixel further.
  EXPECT_NEAR(image.at(0, 2).r, 1.0f, 1e-6f);
  EXPECT_NEAR(image.at(15, 2).r, 0.0f, 1e-6f);
  const float left = image.at(7, 2).r, right = image.at(8, 2).r;
  EXPECT_GT(left, 0.5f);
  EXPECT_LT(left, 1.0f);
  EXPECT_GT(right, 0.0f);
  EXPECT_LT(right, 0.5f);
  EXPECT_NEAR(left + right, 1.0f, 0.05f);  // symmetric about the edge
}

TEST(IdealRendererTest, SameSeedGivesTheSameImageWithAnyThreadCount) {
  Scene s = testing::camera_scene();
  s.background = glm::vec3(0.1f);
  testing::add_quad(&s, glm::vec3(0.9f, 0.2f, 0.1f), {-0.3f, -100}, {0.4f, 100});
  s.finalize();
  Tracer tracer(s);
  IdealRenderOptions o;
  o.width = 40;
  o.height = 37;  // not a multiple of the row block
  o.threads = 1;
  const Image one = render_ideal(tracer, o);
  o.threads = 3;
  const Image three = render_ideal(tracer, o);
  ASSERT_EQ(one.pixels.size(), three.pixels.size());
  for (size_t i = 0; i < one.pixels.size(); ++i) EXPECT_EQ(one.pixels[i], three.pixels[i]);
  o.seed = 2;
  const Image other = render_ideal(tracer, o);
  EXPECT_NE(one.pixels, other.pixels);
}

}  // namespace
}  // namespace afr
