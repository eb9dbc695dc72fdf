#include "tessellate.h"

#include <gtest/gtest.h>

#include <map>
#include <utility>

namespace afr::aff {
namespace {

glm::dvec3 corner(const TriangleSet& s, size_t tri, int k) {
  return glm::dvec3(s.positions[s.indices[3 * tri + size_t(k)]]);
}
glm::dvec3 face_normal(const TriangleSet& s, size_t tri) {
  return glm::cross(corner(s, tri, 1) - corner(s, tri, 0), corner(s, tri, 2) - corner(s, tri, 0));
}

// Every directed edge appears once and its reverse once: a closed, consistently wound surface.
bool closed_and_consistent(const TriangleSet& s) {
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t t = 0; t < s.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) {
      ++edges[{s.indices[3 * t + size_t(k)], s.indices[3 * t + size_t((k + 1) % 3)]}];
    }
  }
  for (const auto& [edge, count] : edges) {
    if (count != 1 || edges.count({edge.second, edge.first}) != 1) return false;
  }
  return true;
}

TEST(TessellateTest, SphereIsClosedOnTheSurfaceAndFacesOutward) {
  const TessellationOptions options;
  const glm::dvec3 center(1, -2, 3);
  const double r = 0.75;
  TriangleSet s;
  append_sphere(center, r, options, &s);
  // 32 slices x 16 stacks: 32 triangles at each pole, 2 x 32 in each of the 14 inner bands.
  EXPECT_EQ(s.triangle_count(), 32u + 32u + 14u * 64u);
  EXPECT_EQ(s.triangle_count(), sphere_triangle_count(options));
  ASSERT_EQ(s.normals.size(), s.positions.size());
  for (size_t i = 0; i < s.positions.size(); ++i) {
    const glm::dvec3 d = glm::dvec3(s.positions[i]) - center;
    EXPECT_NEAR(glm::length(d), r, 1e-6);
    EXPECT_NEAR(glm::dot(glm::dvec3(s.normals[i]), d / r), 1.0, 1e-6);
  }
  for (size_t t = 0; t < s.triangle_count(); ++t) {
    const glm::dvec3 centroid = (corner(s, t, 0) + corner(s, t, 1) + corner(s, t, 2)) / 3.0;
    EXPECT_GT(glm::dot(face_normal(s, t), centroid - center), 0.0) << "triangle " << t;
  }
  EXPECT_TRUE(closed_and_consistent(s));
}

TEST(TessellateTest, NegativeRadiusSphereFacesInward) {
  TriangleSet s;
  append_sphere({0, 0, 0}, -2.0, {}, &s);
  for (size_t i = 0; i < s.positions.size(); ++i) {
    EXPECT_NEAR(glm::length(s.positions[i]), 2.0, 1e-6);
    EXPECT_LT(glm::dot(s.normals[i], s.positions[i]), 0.0f);
  }
  for (size_t t = 0; t < s.triangle_count(); ++t) {
    const glm::dvec3 centroid = corner(s, t, 0) + corner(s, t, 1) + corner(s, t, 2);
    EXPECT_LT(glm::dot(face_normal(s, t), centroid), 0.0);
  }
}

TEST(TessellateTest, ConeLiesOnItsSurfaceAndFacesAwayFromTheAxis) {
  TessellationOptions options;
  options.cone_slices = 24;
  const glm::dvec3 base(0, 1, 0), apex(2, 1, 0);  // axis along +X, length 2
  const double r0 = 1.0, r1 = 0.5;
  TriangleSet s;
  append_cone(base, r0, apex, r1, options, &s);
  EXPECT_EQ(s.triangle_count(), 48u);
  EXPECT_EQ(s.triangle_count(), cone_triangle_count(options, r0, r1));
  for (size_t i = 0; i < s.positions.size(); ++i) {
    const glm::dvec3 p(s.positions[i]);
    const double x = p.x;  // distance along the axis from the base
    const double radius = glm::length(glm::dvec2(p.y - 1, p.z));
    EXPECT_TRUE(std::abs(x) < 1e-6 || std::abs(x - 2) < 1e-6);
    EXPECT_NEAR(radius, x < 1 ? r0 : r1, 1e-6);
    // The normal is perpendicular to the slant line (direction (2, -0.5 * radial)).
    const glm::dvec3 radial = glm::normalize(glm::dvec3(0, p.y - 1, p.z));
    const glm::dvec3 slant = glm::dvec3(2, 0, 0) + (r1 - r0) * radial;
    EXPECT_NEAR(glm::dot(glm::dvec3(s.normals[i]), slant), 0.0, 1e-6);
    EXPECT_GT(glm::dot(glm::dvec3(s.normals[i]), radial), 0.0);
  }
  for (size_t t = 0; t < s.triangle_count(); ++t) {
    const glm::dvec3 c = (corner(s, t, 0) + corner(s, t, 1) + corner(s, t, 2)) / 3.0;
    EXPECT_GT(glm::dot(face_normal(s, t), glm::dvec3(0, c.y - 1, c.z)), 0.0);
  }
}

TEST(TessellateTest, ConeWithNegativeRadiiFacesInwardAndPointedConeHasNoDegenerateTriangles) {
  TriangleSet inside;
  append_cone({0, 0, 0}, -1.0, {0, 0, 3}, -1.0, {}, &inside);
  for (size_t t = 0; t < inside.triangle_count(); ++t) {
    const glm::dvec3 c = corner(inside, t, 0) + corner(inside, t, 1) + corner(inside, t, 2);
    EXPECT_LT(glm::dot(face_normal(inside, t), glm::dvec3(c.x, c.y, 0)), 0.0);
  }
  TriangleSet pointed;
  append_cone({0, 0, 0}, 1.0, {0, 0, 3}, 0.0, {}, &pointed);
  EXPECT_EQ(pointed.triangle_count(), 32u);
  for (size_t t = 0; t < pointed.triangle_count(); ++t) {
    EXPECT_GT(glm::length(face_normal(pointed, t)), 1e-6);
  }
}

TEST(TessellateTest, PolygonIsAFanFromTheFirstVertex) {
  const glm::vec3 p[] = {{0, 0, 0}, {1, 0, 0}, {2, 1, 0}, {1, 2, 0}, {0, 1, 0}};
  TriangleSet s;
  append_polygon(p, {}, {}, &s);
  EXPECT_EQ(s.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4}));
  append_polygon(std::span(p, 3), {}, {}, &s);
  EXPECT_EQ(s.triangle_count(), 4u);
  EXPECT_EQ(s.indices.back(), 7u);
}

}  // namespace
}  // namespace afr::aff
