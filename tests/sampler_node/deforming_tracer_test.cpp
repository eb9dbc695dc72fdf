// The tracer on skinned and morphed meshes (issue 18): a ray hits the surface where the test
// computes it is at time t (tests/support/deforming_content.h, in closed form) and not where
// the bind pose or base shape is; the sample's velocity is the difference quotient of the
// test's own positions (one-sided at the ends of the animation); shading takes the deformed
// normals; a deformed mesh that does not move is traced in its pose with no velocity.
#include <afr/common/gltf_loader.h>
#include <afr/sampler/tracer.h>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "support/deforming_content.h"
#include "support/gltf_content.h"

namespace afr {
namespace {

using json = nlohmann::json;
using testing::GltfContent;
using testing::MorphedQuad;
using testing::SkinnedStrip;
using testing::TempFolder;

// The step of the tracer's difference quotient (tracer_build.cpp, kVelocityDt), and of the test's.
constexpr double kH = 1e-3;

const json kLambert = {{"pbrMetallicRoughness",
                        {{"baseColorFactor", {0.8, 0.8, 0.8, 1.0}},
                         {"metallicFactor", 0.0},
                         {"roughnessFactor", 1.0}}},
                       {"doubleSided", true}};

Scene load(GltfContent g, const TempFolder& dir) {
  g.doc()["materials"] = json::array({kLambert});
  g.doc()["meshes"][0]["primitives"][0]["material"] = 0;
  g.write(dir / "scene.gltf");
  return load_gltf(dir / "scene.gltf");
}

ShadedSample trace(const Tracer& tracer, const glm::dvec3& origin, const glm::dvec3& direction) {
  TraceStats stats;
  return tracer.trace(Ray{glm::vec3(origin), glm::vec3(glm::normalize(direction))}, &stats);
}

void expect_near(const glm::vec3& got, const glm::dvec3& want, double tolerance,
                 const std::string& what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], tolerance) << what << ", axis " << c;
}

// A point of a triangle given by the world positions of its corners at any time.
template <typename PositionAt>
struct MaterialPoint {
  std::array<glm::vec3, 3> corners;  // in the pose the position function starts from
  glm::dvec3 barycentric;
  PositionAt position_at;  // (corner, t) -> world position

  glm::dvec3 at(double t) const {
    glm::dvec3 p(0.0);
    for (int i = 0; i < 3; ++i) p += barycentric[i] * position_at(corners[size_t(i)], t);
    return p;
  }
  glm::dvec3 normal(double t) const {
    const glm::dvec3 a = position_at(corners[0], t), b = position_at(corners[1], t),
                     c = position_at(corners[2], t);
    return glm::normalize(glm::cross(b - a, c - a));
  }
};

TEST(DeformingTracerTest, RaysHitAMorphedSurfaceWhereItIsAtTimeTWithItsVelocity) {
  TempFolder dir;
  const Scene scene = load(MorphedQuad::make(Interpolation::kLinear), dir);
  ASSERT_TRUE(scene.has_moving_geometry());
  Tracer tracer(scene);
  const std::vector<glm::vec3> base = MorphedQuad::base_positions();
  auto position_at = [](const glm::vec3& corner, double t) {
    return MorphedQuad::position(corner, MorphedQuad::weights(Interpolation::kLinear, t));
  };
  const std::vector<glm::dvec3> barycentrics = {
      {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.6, 0.3, 0.1}, {0.1, 0.2, 0.7}};
  for (double t : {0.0, 0.4, 1.5, 2.9, 3.0}) {
    tracer.set_time(t);
    // The difference quotient: central, one-sided at the ends of [0, 3].
    const double before = std::max(t - kH, 0.0), after = std::min(t + kH, 3.0);
    for (const std::array<int, 3>& tri : {std::array<int, 3>{0, 1, 2}, {0, 2, 3}}) {
      for (const glm::dvec3& b : barycentrics) {
        const MaterialPoint<decltype(position_at)> point{
            {base[size_t(tri[0])], base[size_t(tri[1])], base[size_t(tri[2])]}, b, position_at};
        const glm::dvec3 p = point.at(t);
        // The surface is a graph over x and y: a vertical ray through p meets it at p.
        const ShadedSample s = trace(tracer, p + glm::dvec3(0, 0, 10), {0, 0, -1});
        const std::string what = "t = " + std::to_string(t);
        ASSERT_TRUE(s.hit) << what;
        expect_near(s.position, p, 1e-4, what + " position");
        const glm::dvec3 velocity = (point.at(after) - point.at(before)) / (after - before);
        expect_near(s.velocity, velocity, 2e-3, what + " velocity");
        EXPECT_EQ(s.object_id, uint32_t(MorphedQuad::kMeshNode));
        if (t > 0.0) {
          // Not where the base shape is: that lies in the plane z = 0.
          EXPECT_GT(std::abs(s.position.z), 0.3f) << what;
        }
      }
    }
  }
}

TEST(DeformingTracerTest, RaysHitASkinnedSurfaceWhereItIsAtTimeTWithItsVelocity) {
  TempFolder dir;
  const Scene scene = load(SkinnedStrip::make(), dir);
  Tracer tracer(scene);
  const std::vector<glm::vec3> bind = SkinnedStrip::bind_positions();
  auto position_at = [](const glm::vec3& corner, double t) {
    return SkinnedStrip::position(corner, t);
  };
  for (double t : {0.0, 0.3, 0.5, 1.0, 1.2}) {
    tracer.set_time(t);
    // (Beyond 1.2 s the arm folds back over the strip and hides it from these rays.)
    const double before = std::max(t - kH, 0.0), after = t + kH;
    for (int row = 0; row < 4; ++row) {
      const size_t a = size_t(2 * row);
      for (const std::array<size_t, 3>& tri :
           {std::array<size_t, 3>{a, a + 1, a + 3}, std::array<size_t, 3>{a, a + 3, a + 2}}) {
        const MaterialPoint<decltype(position_at)> point{
            {bind[tri[0]], bind[tri[1]], bind[tri[2]]}, {0.25, 0.35, 0.4}, position_at};
        const glm::dvec3 p = point.at(t);
        const glm::dvec3 n = point.normal(t);
        const std::string what = "t = " + std::to_string(t) + ", row " + std::to_string(row);
        const ShadedSample s = trace(tracer, p + 0.25 * n, -n);
        ASSERT_TRUE(s.hit) << what;
        expect_near(s.position, p, 1e-4, what + " position");
        const glm::dvec3 velocity = (point.at(after) - point.at(before)) / (after - before);
        expect_near(s.velocity, velocity, 2e-3, what + " velocity");
        // The bind pose is elsewhere: a ray at the bind-pose point finds no surface there.
        if (t > 0.0) {
          const glm::dvec3 rest = point.at(0.0);
          const ShadedSample r = trace(tracer, rest + glm::dvec3(0, 0, 0.25), {0, 0, -1});
          if (r.hit) {
            EXPECT_GT(glm::length(glm::dvec3(r.position) - rest), 0.1) << what;
          }
        }
      }
    }
  }
}

TEST(DeformingTracerTest, ShadingTakesTheMorphedNormals) {
  // A morph target of normals alone: the quad stays flat (geometric normal +Z) while its
  // shading normals tilt to (-w0, 0, 1). Lit by the default headlight, which comes from
  // (0.35, 0.5, 1) in the frame of the default camera (the world's axes: it looks down -Z),
  // the Lambert law with the tilted normal gives the color (docs/scene-model.md).
  TempFolder dir;
  GltfContent g = MorphedQuad::make(Interpolation::kLinear);
  g.doc()["meshes"][0]["primitives"][0]["targets"][0]["POSITION"] =
      g.add_floats(std::vector<float>(12, 0.0f), 3);
  const Scene scene = load(g, dir);
  Tracer tracer(scene);
  const glm::dvec3 from = glm::normalize(glm::dvec3(0.35, 0.5, 1.0));
  for (double t : {0.0, 0.5, 1.0}) {
    tracer.set_time(t);
    const glm::dvec2 w = MorphedQuad::weights(Interpolation::kLinear, t);
    const glm::dvec3 p = MorphedQuad::position({0.3f, 0.6f, 0.0f}, {0.0, w.y});
    const Camera& camera = tracer.camera();
    TraceStats stats;
    glm::dvec2 pixel;
    ASSERT_TRUE(camera.project(p, 64, 64, &pixel, nullptr));
    const ShadedSample s = tracer.trace(camera.ray(pixel.x, pixel.y, 64, 64), &stats);
    ASSERT_TRUE(s.hit);
    const glm::dvec3 n = MorphedQuad::normal(w);
    const double want = 0.8 * (0.2 + 2.5 / std::numbers::pi * std::max(glm::dot(n, from), 0.0));
    EXPECT_NEAR(s.color.g, want, 1e-4) << "t = " << t;
  }
}

TEST(DeformingTracerTest, APosedSkinThatDoesNotMoveIsStaticInItsPose) {
  // No animation: the strip is bent by its file's joint rotation once, and has no velocity.
  TempFolder dir;
  GltfContent g = SkinnedStrip::make(false);
  const double a = std::numbers::pi / 4.0;
  g.doc()["nodes"][2]["rotation"] = {std::sin(a / 2.0), 0.0, 0.0, std::cos(a / 2.0)};
  const Scene scene = load(g, dir);
  EXPECT_FALSE(scene.has_moving_geometry());
  Tracer tracer(scene);
  tracer.set_time(0.0);
  // Vertex (1.5, 2, 0), all on joint 1, is turned by 45 degrees about (1, 1, 0) along X; the
  // point a little inside the strip from it is where the ray meets the strip.
  const glm::dvec3 corner(1.5, 1.0 + std::cos(a), std::sin(a));
  const glm::dvec3 normal(0.0, -std::sin(a), std::cos(a));
  const glm::dvec3 inside = corner + glm::dvec3(-0.1, -0.1 * std::cos(a), -0.1 * std::sin(a));
  const ShadedSample s = trace(tracer, inside + normal, -normal);
  ASSERT_TRUE(s.hit);
  expect_near(s.position, inside, 1e-4, "position");
  EXPECT_EQ(s.velocity, glm::vec3(0.0f));
}

}  // namespace
}  // namespace afr
