#include "tessellate.h"

#include <afr/common/check.h>

#include <cmath>
#include <numbers>

namespace afr::aff {
namespace {

// Appends a triangle, reversing it when the inside is the front face.
void push_triangle(TriangleSet* out, uint32_t a, uint32_t b, uint32_t c, bool reversed) {
  out->indices.push_back(a);
  out->indices.push_back(reversed ? c : b);
  out->indices.push_back(reversed ? b : c);
}

uint32_t push_vertex(TriangleSet* out, const glm::dvec3& p, const glm::dvec3& n) {
  out->positions.push_back(glm::vec3(p));
  out->normals.push_back(glm::vec3(n));
  return uint32_t(out->positions.size() - 1);
}

// Two unit vectors that make a right-handed orthonormal frame (u, v, w) with unit w.
void orthonormal_frame(const glm::dvec3& w, glm::dvec3* u, glm::dvec3* v) {
  const glm::dvec3 helper = std::abs(w.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  *u = glm::normalize(glm::cross(helper, w));
  *v = glm::cross(w, *u);
}

}  // namespace

size_t sphere_triangle_count(const TessellationOptions& options) {
  return 2 * size_t(options.sphere_slices) * size_t(options.sphere_stacks - 1);
}

size_t cone_triangle_count(const TessellationOptions& options, double r0, double r1) {
  const size_t halves = (r0 != 0.0 ? 1 : 0) + (r1 != 0.0 ? 1 : 0);
  return halves * size_t(options.cone_slices);
}

void append_sphere(const glm::dvec3& center, double radius, const TessellationOptions& options,
                   TriangleSet* out) {
  AFR_CHECK(options.sphere_slices >= 3 && options.sphere_stacks >= 2);
  AFR_CHECK(out->uvs.empty() && out->normals.size() == out->positions.size());
  const bool inside = radius < 0.0;
  const double r = std::abs(radius);
  const double sign = inside ? -1.0 : 1.0;  // normals point to the visible side
  const int slices = options.sphere_slices;
  const int stacks = options.sphere_stacks;
  // Direction at polar angle theta (from +Y) and azimuth phi (from +X towards +Z). With this
  // orientation the triangles below are counter-clockwise seen from outside.
  auto direction = [](double theta, double phi) {
    return glm::dvec3(std::sin(theta) * std::cos(phi), std::cos(theta),
                      std::sin(theta) * std::sin(phi));
  };
  const uint32_t top = push_vertex(out, center + glm::dvec3(0, r, 0), glm::dvec3(0, sign, 0));
  const uint32_t first_ring = uint32_t(out->positions.size());
  for (int j = 1; j < stacks; ++j) {
    const double theta = std::numbers::pi * j / stacks;
    for (int i = 0; i < slices; ++i) {
      const glm::dvec3 d = direction(theta, 2.0 * std::numbers::pi * i / slices);
      push_vertex(out, center + r * d, sign * d);
    }
  }
  const uint32_t bottom = push_vertex(out, center - glm::dvec3(0, r, 0), glm::dvec3(0, -sign, 0));
  auto ring = [&](int j, int i) { return first_ring + uint32_t((j - 1) * slices + i % slices); };
  for (int i = 0; i < slices; ++i) {
    push_triangle(out, top, ring(1, i + 1), ring(1, i), inside);
    for (int j = 1; j + 1 < stacks; ++j) {
      push_triangle(out, ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), inside);
      push_triangle(out, ring(j, i), ring(j + 1, i + 1), ring(j + 1, i), inside);
    }
    push_triangle(out, bottom, ring(stacks - 1, i), ring(stacks - 1, i + 1), inside);
  }
}

void append_cone(const glm::dvec3& base, double r0, const glm::dvec3& apex, double r1,
                 const TessellationOptions& options, TriangleSet* out) {
  AFR_CHECK(options.cone_slices >= 3);
  AFR_CHECK(out->uvs.empty() && out->normals.size() == out->positions.size());
  const bool inside = r0 < 0.0;
  if (inside) {
    r0 = -r0;
    r1 = -r1;
  }
  const glm::dvec3 axis = apex - base;
  const double length = glm::length(axis);
  if (length <= 0.0) return;  // base and apex coincide: no surface
  const glm::dvec3 w = axis / length;
  glm::dvec3 u, v;
  orthonormal_frame(w, &u, &v);
  const double sign = inside ? -1.0 : 1.0;
  const int slices = options.cone_slices;
  const uint32_t first = uint32_t(out->positions.size());
  for (int i = 0; i < slices; ++i) {
    const double phi = 2.0 * std::numbers::pi * i / slices;
    const glm::dvec3 radial = std::cos(phi) * u + std::sin(phi) * v;
    // Perpendicular to both the ring tangent and the slant line from base to apex.
    const glm::dvec3 n = sign * glm::normalize(length * radial + (r0 - r1) * w);
    push_vertex(out, base + r0 * radial, n);
    push_vertex(out, apex + r1 * radial, n);
  }
  for (int i = 0; i < slices; ++i) {
    const uint32_t b0 = first + uint32_t(2 * i);
    const uint32_t a0 = b0 + 1;
    const uint32_t b1 = first + uint32_t(2 * ((i + 1) % slices));
    const uint32_t a1 = b1 + 1;
    if (r0 != 0.0) push_triangle(out, b0, b1, a1, inside);
    if (r1 != 0.0) push_triangle(out, b0, a1, a0, inside);
  }
}

void append_polygon(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals,
                    std::span<const glm::vec2> uvs, TriangleSet* out) {
  // The set carries an attribute for all of its vertices or for none.
  AFR_CHECK(out->normals.size() == (normals.empty() ? 0 : out->positions.size()));
  AFR_CHECK(out->uvs.size() == (uvs.empty() ? 0 : out->positions.size()));
  if (positions.size() < 3) return;
  const uint32_t first = uint32_t(out->positions.size());
  out->positions.insert(out->positions.end(), positions.begin(), positions.end());
  out->normals.insert(out->normals.end(), normals.begin(), normals.end());
  out->uvs.insert(out->uvs.end(), uvs.begin(), uvs.end());
  for (uint32_t k = 1; k + 1 < positions.size(); ++k) {
    push_triangle(out, first, first + k, first + k + 1, false);
  }
}

}  // namespace afr::aff
