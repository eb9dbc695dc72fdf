// The tracer tests' scene building and comparisons (tracer_test.cpp, tracer_materials_test.cpp,
// tracer_glass_test.cpp): small scenes of quads, boxes, lights and one-texel textures.
#pragma once

#include <afr/common/scene.h>
#include <afr/sampler/tracer.h>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <utility>

namespace afr::tracer_test {

// A quad with corners c, c + eu, c + eu + ev, c + ev, front face toward cross(eu, ev), uvs
// (0,0), (1,0), (1,1), (0,1) at those corners.
inline Primitive quad(glm::vec3 c, glm::vec3 eu, glm::vec3 ev, int material) {
  Primitive p;
  p.positions = {c, c + eu, c + eu + ev, c + ev};
  const glm::vec3 n = glm::normalize(glm::cross(eu, ev));
  p.normals = {n, n, n, n};
  p.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  p.indices = {0, 1, 2, 0, 2, 3};
  p.material = material;
  return p;
}

// An axis-aligned box centered at the origin with outward faces.
inline Mesh box_mesh(glm::vec3 half, int material) {
  Mesh m;
  m.name = "box";
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 n(0.0f), u(0.0f), v(0.0f);
      n[axis] = sign;
      u[(axis + 1) % 3] = 2.0f * half[(axis + 1) % 3];
      v[(axis + 2) % 3] = 2.0f * half[(axis + 2) % 3];
      if (sign < 0.0f) std::swap(u, v);  // keeps cross(u, v) along n
      const glm::vec3 c = n * half - 0.5f * (u + v);
      m.primitives.push_back(quad(c, u, v, material));
    }
  }
  return m;
}

inline Mesh quad_mesh(glm::vec3 c, glm::vec3 eu, glm::vec3 ev, int material) {
  Mesh m;
  m.name = "quad";
  m.primitives.push_back(quad(c, eu, ev, material));
  return m;
}

inline int add_material(Scene* s, glm::vec3 base, float metallic, float roughness) {
  Material m;
  m.base_color_factor = glm::vec4(base, 1.0f);
  m.metallic = metallic;
  m.roughness = roughness;
  s->materials.push_back(m);
  return int(s->materials.size()) - 1;
}

inline int add_mesh_node(Scene* s, Mesh mesh, glm::dvec3 translation = glm::dvec3(0.0)) {
  s->meshes.push_back(std::move(mesh));
  Node n;
  n.mesh = int(s->meshes.size()) - 1;
  n.translation = translation;
  s->nodes.push_back(n);
  s->roots.push_back(int(s->nodes.size()) - 1);
  return int(s->nodes.size()) - 1;
}

// A light node; `rotation` turns the light's -Z into its direction.
inline int add_light_node(Scene* s, Light light, glm::dvec3 position,
                          glm::dquat rotation = glm::dquat(1.0, 0.0, 0.0, 0.0)) {
  s->lights.push_back(light);
  Node n;
  n.light = int(s->lights.size()) - 1;
  n.translation = position;
  n.rotation = rotation;
  s->nodes.push_back(n);
  s->roots.push_back(int(s->nodes.size()) - 1);
  return int(s->nodes.size()) - 1;
}

// Turns -Z into -Y (a light that shines straight down).
inline glm::dquat pointing_down() { return glm::angleAxis(-0.5 * M_PI, glm::dvec3(1.0, 0.0, 0.0)); }

inline Ray ray_to(glm::vec3 from, glm::vec3 to) { return Ray{from, glm::normalize(to - from)}; }

inline bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

inline void expect_near3(const glm::vec3& a, const glm::vec3& b, float tol, const char* what) {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

// The color of a square of a white Lambertian material (metallic 0, roughness 1) as `dress`
// changes it, lit by a sun of intensity 3 from behind the camera and seen straight on
// (v = l = n).
inline glm::vec3 square_lit_straight_on_scene(const std::function<void(Scene*, Material*)>& dress) {
  Scene s;
  const int mat = add_material(&s, glm::vec3(1.0f), 0.0f, 1.0f);
  Material m = s.materials[size_t(mat)];
  dress(&s, &m);  // may add textures to s
  s.materials[size_t(mat)] = m;
  add_mesh_node(&s, quad_mesh({-1, -1, -2}, {2, 0, 0}, {0, 2, 0}, mat));
  Light sun;
  sun.type = Light::Type::kDirectional;  // along -Z: from behind the camera
  sun.intensity = 3.0f;
  add_light_node(&s, sun, glm::dvec3(0.0));
  s.finalize();
  Tracer tracer(s);
  TraceStats stats;
  return tracer.trace(Ray{{0.2f, 0.1f, 0.0f}, {0, 0, -1}}, &stats).color;
}
inline glm::vec3 square_lit_straight_on(const std::function<void(Material*)>& dress) {
  return square_lit_straight_on_scene([&](Scene*, Material* m) { dress(m); });
}

// Adds a box node that slides from x = 0 to x = 2 and turns by 90 degrees about +Y over 2 s
// (linear keys: constant velocity (1, 0, 0), constant angular velocity pi/4 rad/s).
inline int add_moving_box(Scene* s, int material) {
  const int box = add_mesh_node(s, box_mesh(glm::vec3(0.5f), material), glm::dvec3(0, 0, -5));
  AnimationChannel move;
  move.node = box;
  move.path = AnimatedPath::kTranslation;
  move.times = {0.0, 2.0};
  move.values = {{0.0, 0.0, -5.0, 0.0}, {2.0, 0.0, -5.0, 0.0}};
  AnimationChannel turn;
  turn.node = box;
  turn.path = AnimatedPath::kRotation;
  turn.times = {0.0, 2.0};
  const double h = 0.25 * M_PI;                                                // half of 90 degrees
  turn.values = {{0.0, 0.0, 0.0, 1.0}, {0.0, std::sin(h), 0.0, std::cos(h)}};  // x y z w
  s->channels.push_back(move);
  s->channels.push_back(turn);
  return box;
}

// A one-texel texture of (linear) value `texel` appended to s; returns its index.
inline int add_texel(Scene* s, glm::vec3 texel) {
  Texture t;
  t.width = t.height = 1;
  t.texels = {texel};
  s->textures.push_back(t);
  return int(s->textures.size()) - 1;
}

// A lit, partly glossy scene with a moving box for comparisons between query paths.
inline Scene busy_scene() {
  Scene s;
  s.ambient = glm::vec3(0.1f);
  s.background = glm::vec3(0.3f, 0.4f, 0.5f);
  const int mat = add_material(&s, glm::vec3(0.5f), 0.0f, 0.5f);
  add_mesh_node(&s, quad_mesh({-10, -1, 10}, {20, 0, 0}, {0, 0, -20}, mat));
  add_moving_box(&s, mat);
  const int mirror = add_material(&s, glm::vec3(0.9f), 1.0f, 0.05f);
  s.meshes.push_back(box_mesh(glm::vec3(0.7f), mirror));
  Node n;
  n.mesh = int(s.meshes.size()) - 1;
  n.translation = glm::dvec3(-2.0, 0.0, -6.0);
  s.nodes.push_back(n);
  s.roots.push_back(int(s.nodes.size()) - 1);
  add_light_node(&s, Light{}, glm::dvec3(1.0, 4.0, -2.0));
  s.finalize();
  return s;
}

inline void expect_same_sample(const ShadedSample& a, const ShadedSample& b, float tol) {
  EXPECT_EQ(a.hit, b.hit);
  EXPECT_EQ(a.object_id, b.object_id);
  expect_near3(a.color, b.color, tol, "color");
  expect_near3(a.position, b.position, tol, "position");
  expect_near3(a.velocity, b.velocity, tol, "velocity");
}

// Traces a crosshair every `step` pixels of a w x h image (away from its border) and expects
// each of its five samples to equal the single ray's of the same pixel position.
inline void expect_crosshairs_equal_single_rays(const Tracer& tracer, const Camera& cam, int w,
                                                int h, int step, TraceStats* stats) {
  const double dx[5] = {0, -1, 1, 0, 0}, dy[5] = {0, 0, 0, -1, 1};
  for (int j = 1; j < h - 1; j += step) {
    for (int i = 1; i < w - 1; i += step) {
      const double x = i + 0.37, y = j + 0.61;
      std::array<ShadedSample, 5> cross;
      tracer.trace_crosshair(cam, x, y, w, h, &cross, stats);
      for (int k = 0; k < 5; ++k) {
        const ShadedSample single = tracer.trace(cam.ray(x + dx[k], y + dy[k], w, h), stats);
        expect_same_sample(cross[size_t(k)], single, 1e-4f);
      }
    }
  }
}

inline int add_glass(Scene* s, float ior, bool double_sided = false) {
  const int m = add_material(s, glm::vec3(1.0f), 0.0f, 0.0f);
  s->materials[size_t(m)].transmission = 1.0f;
  s->materials[size_t(m)].ior = ior;
  s->materials[size_t(m)].double_sided = double_sided;
  return m;
}

}  // namespace afr::tracer_test
