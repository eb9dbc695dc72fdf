#include <afr/common/builtin_scene.h>

#include <afr/common/error.h>
#include <afr/common/image.h>

#include <fmt/format.h>
#include <glm/gtx/quaternion.hpp>

#include <charconv>
#include <cmath>
#include <numbers>
#include <string_view>

namespace afr {

namespace {

constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------------------------------------
// Mesh builders (counter-clockwise front faces, outward normals)

void add_quad(Primitive* p, glm::vec3 origin, glm::vec3 edge_u, glm::vec3 edge_v,
              glm::vec2 uv_scale) {
  const uint32_t base = uint32_t(p->positions.size());
  const glm::vec3 n = glm::normalize(glm::cross(edge_u, edge_v));
  const glm::vec3 corners[4] = {origin, origin + edge_u, origin + edge_u + edge_v, origin + edge_v};
  const glm::vec2 uvs[4] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  for (int i = 0; i < 4; ++i) {
    p->positions.push_back(corners[i]);
    p->normals.push_back(n);
    p->uvs.push_back(uvs[i] * uv_scale);
  }
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) p->indices.push_back(base + i);
}

Primitive make_box(glm::vec3 half) {
  Primitive p;
  const glm::vec3 h = half;
  // +X, -X, +Y, -Y, +Z, -Z faces, each seen from outside.
  add_quad(&p, {h.x, -h.y, h.z}, {0, 0, -2 * h.z}, {0, 2 * h.y, 0}, {1, 1});
  add_quad(&p, {-h.x, -h.y, -h.z}, {0, 0, 2 * h.z}, {0, 2 * h.y, 0}, {1, 1});
  add_quad(&p, {-h.x, h.y, h.z}, {2 * h.x, 0, 0}, {0, 0, -2 * h.z}, {1, 1});
  add_quad(&p, {-h.x, -h.y, -h.z}, {2 * h.x, 0, 0}, {0, 0, 2 * h.z}, {1, 1});
  add_quad(&p, {-h.x, -h.y, h.z}, {2 * h.x, 0, 0}, {0, 2 * h.y, 0}, {1, 1});
  add_quad(&p, {h.x, -h.y, -h.z}, {-2 * h.x, 0, 0}, {0, 2 * h.y, 0}, {1, 1});
  return p;
}

Primitive make_sphere(float radius, int slices, int stacks) {
  Primitive p;
  for (int j = 0; j <= stacks; ++j) {
    const double theta = kPi * j / stacks;
    for (int i = 0; i <= slices; ++i) {
      const double phi = 2.0 * kPi * i / slices;
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta),
                        -std::sin(theta) * std::sin(phi));
      p.positions.push_back(radius * n);
      p.normals.push_back(n);
      p.uvs.push_back({float(i) / slices, float(j) / stacks});
    }
  }
  const uint32_t row = uint32_t(slices + 1);
  for (int j = 0; j < stacks; ++j) {
    for (int i = 0; i < slices; ++i) {
      const uint32_t a = j * row + i, b = a + 1, c = a + row, d = c + 1;
      // Skip the zero-area triangles at the poles.
      if (j != 0) p.indices.insert(p.indices.end(), {a, c, b});
      if (j != stacks - 1) p.indices.insert(p.indices.end(), {b, c, d});
    }
  }
  return p;
}

// A tiled floor: light and dark tiles with grout lines, 8 x 8 tiles per texture repeat.
Texture make_floor_texture() {
  Texture t;
  t.name = "builtin floor tiles";
  t.width = t.height = 256;
  t.texels.resize(size_t(t.width) * t.height);
  const glm::vec3 light(srgb_to_linear(0.86f), srgb_to_linear(0.82f), srgb_to_linear(0.74f));
  const glm::vec3 dark(srgb_to_linear(0.30f), srgb_to_linear(0.24f), srgb_to_linear(0.22f));
  const glm::vec3 grout(srgb_to_linear(0.12f));
  for (int y = 0; y < t.height; ++y) {
    for (int x = 0; x < t.width; ++x) {
      const int tx = x / 32, ty = y / 32;
      const bool line = x % 32 < 2 || y % 32 < 2;
      t.texels[size_t(y) * t.width + x] = line ? grout : ((tx + ty) % 2 ? dark : light);
    }
  }
  return t;
}

int add_material(Scene* s, const char* name, glm::vec3 base, float metallic, float roughness,
                 glm::vec3 emissive = glm::vec3(0.0f), int texture = -1) {
  Material m;
  m.name = name;
  m.base_color_factor = glm::vec4(base, 1.0f);
  m.metallic = metallic;
  m.roughness = roughness;
  m.emissive = emissive;
  m.base_color_texture = texture;
  s->materials.push_back(m);
  return int(s->materials.size()) - 1;
}

int add_node(Scene* s, const char* name, Primitive primitive, int material, glm::dvec3 position,
             glm::dquat rotation = glm::dquat(1.0, 0.0, 0.0, 0.0)) {
  primitive.material = material;
  Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(std::move(primitive));
  s->meshes.push_back(std::move(mesh));
  Node node;
  node.name = name;
  node.mesh = int(s->meshes.size()) - 1;
  node.translation = position;
  node.rotation = rotation;
  s->nodes.push_back(node);
  s->roots.push_back(int(s->nodes.size()) - 1);
  return int(s->nodes.size()) - 1;
}

// Samples a periodic motion into a LINEAR channel with `keys` intervals over the loop.
template <typename F>
AnimationChannel sample_channel(int node, AnimatedPath path, int keys, F&& value_at) {
  AnimationChannel ch;
  ch.node = node;
  ch.path = path;
  ch.interpolation = Interpolation::kLinear;
  for (int k = 0; k <= keys; ++k) {
    const double t = kBuiltinSceneLoopSeconds * k / keys;
    ch.times.push_back(t);
    ch.values.push_back(value_at(t));
  }
  return ch;
}

glm::dvec4 quat_xyzw(const glm::dquat& q) { return glm::dvec4(q.x, q.y, q.z, q.w); }

}  // namespace

Scene make_builtin_scene() {
  Scene s;
  s.source = "builtin";
  s.background = glm::vec3(0.55f, 0.70f, 0.95f);
  s.ambient = glm::vec3(0.06f);
  s.textures.push_back(make_floor_texture());

  const int floor_mat =
      add_material(&s, "floor tiles", glm::vec3(1.0f), 0.0f, 0.45f, glm::vec3(0.0f), 0);
  const int wall_warm = add_material(&s, "warm wall", {0.80f, 0.74f, 0.62f}, 0.0f, 1.0f);
  const int wall_cool = add_material(&s, "cool wall", {0.45f, 0.55f, 0.75f}, 0.0f, 1.0f);
  const int mirror = add_material(&s, "mirror", {0.95f, 0.95f, 0.95f}, 1.0f, 0.0f);
  const int glossy = add_material(&s, "glossy red", {0.75f, 0.08f, 0.06f}, 0.0f, 0.2f);
  const int ball_mat = add_material(&s, "yellow ball", {0.90f, 0.65f, 0.08f}, 0.0f, 0.35f);
  const int cube_mat = add_material(&s, "green cube", {0.10f, 0.60f, 0.20f}, 0.0f, 0.6f);
  const int pillar_mat = add_material(&s, "pillar", {0.55f, 0.55f, 0.58f}, 0.0f, 0.8f);
  const int window_mat =
      add_material(&s, "window", {0.0f, 0.0f, 0.0f}, 0.0f, 1.0f, {3.0f, 2.8f, 2.4f});

  // The room: a 12 m x 12 m tiled floor, three 4 m walls, open to the sky in front and above.
  Primitive floor;
  add_quad(&floor, {-6, 0, 6}, {12, 0, 0}, {0, 0, -12}, {3, 3});
  add_node(&s, "floor", std::move(floor), floor_mat, {0, 0, 0});
  Primitive back;
  add_quad(&back, {-6, 0, -6}, {12, 0, 0}, {0, 4, 0}, {1, 1});
  add_node(&s, "back wall", std::move(back), wall_warm, {0, 0, 0});
  Primitive left;
  add_quad(&left, {-6, 0, 6}, {0, 0, -12}, {0, 4, 0}, {1, 1});
  add_node(&s, "left wall", std::move(left), wall_cool, {0, 0, 0});
  Primitive right;
  add_quad(&right, {6, 0, -6}, {0, 0, 12}, {0, 4, 0}, {1, 1});
  add_node(&s, "right wall", std::move(right), wall_cool, {0, 0, 0});
  Primitive window;
  add_quad(&window, {-1.5f, 2.0f, -5.97f}, {3, 0, 0}, {0, 1.2f, 0}, {1, 1});
  add_node(&s, "window", std::move(window), window_mat, {0, 0, 0});

  // Static objects: a mirror sphere and a glossy box for view-dependent highlights, and a
  // pillar that hides the sliding cube for part of its path.
  add_node(&s, "mirror sphere", make_sphere(0.9f, 64, 32), mirror, {-2.5, 0.9, 0.5});
  add_node(&s, "glossy box", make_box({0.6f, 0.6f, 0.6f}), glossy, {2.6, 0.6, 0.2},
           glm::angleAxis(glm::radians(30.0), glm::dvec3(0, 1, 0)));
  add_node(&s, "pillar", make_box({0.35f, 1.6f, 0.35f}), pillar_mat, {0.0, 1.6, -1.6});

  // Moving objects.
  const int ball = add_node(&s, "bouncing ball", make_sphere(0.4f, 48, 24), ball_mat, {0, 0.4, 2});
  s.channels.push_back(sample_channel(ball, AnimatedPath::kTranslation, 160, [](double t) {
    const double a = 2.0 * kPi * t / kBuiltinSceneLoopSeconds;
    return glm::dvec4(1.4 * std::cos(a), 0.4 + 1.6 * std::abs(std::sin(kPi * t / 1.25)),
                      1.8 + 0.8 * std::sin(a), 0.0);
  }));
  const int cube =
      add_node(&s, "sliding cube", make_box({0.45f, 0.45f, 0.45f}), cube_mat, {0, 0.45, -3.2});
  s.channels.push_back(sample_channel(cube, AnimatedPath::kTranslation, 160, [](double t) {
    return glm::dvec4(3.5 * std::sin(2.0 * kPi * t / 5.0), 0.45, -3.2, 0.0);
  }));
  s.channels.push_back(sample_channel(cube, AnimatedPath::kRotation, 160, [](double t) {
    return quat_xyzw(glm::angleAxis(2.0 * kPi * t / 2.5, glm::dvec3(0, 1, 0)));
  }));

  // Lights: a warm point light under the open ceiling and a low sun for long, sharp shadows.
  Light lamp;
  lamp.name = "lamp";
  lamp.type = Light::Type::kPoint;
  lamp.color = {1.0f, 0.92f, 0.8f};
  lamp.intensity = 30.0f;
  s.lights.push_back(lamp);
  Node lamp_node;
  lamp_node.name = "lamp";
  lamp_node.light = 0;
  lamp_node.translation = {0.5, 3.8, 1.5};
  s.nodes.push_back(lamp_node);
  s.roots.push_back(int(s.nodes.size()) - 1);

  Light sun;
  sun.name = "sun";
  sun.type = Light::Type::kDirectional;
  sun.color = {1.0f, 0.97f, 0.9f};
  sun.intensity = 2.0f;
  s.lights.push_back(sun);
  Node sun_node;
  sun_node.name = "sun";
  sun_node.light = 1;
  sun_node.rotation =
      glm::rotation(glm::dvec3(0, 0, -1), glm::normalize(glm::dvec3(-0.5, -1, -0.6)));
  s.nodes.push_back(sun_node);
  s.roots.push_back(int(s.nodes.size()) - 1);

  // The camera sweeps left and right around the room's center while dollying in and out.
  CameraModel lens;
  lens.name = "orbit";
  lens.yfov = glm::radians(50.0);
  lens.znear = 0.05;
  s.cameras.push_back(lens);
  Node cam;
  cam.name = "camera";
  cam.camera = 0;
  s.nodes.push_back(cam);
  const int cam_node = int(s.nodes.size()) - 1;
  s.roots.push_back(cam_node);
  const glm::dvec3 target(0.0, 0.8, 0.0);
  auto eye_at = [](double t) {
    const double a = 2.0 * kPi * t / kBuiltinSceneLoopSeconds;
    const double phi = 0.65 * std::sin(a);
    const double radius = 6.8 + 1.2 * std::sin(2.0 * a);
    return glm::dvec3(radius * std::sin(phi), 2.2 + 0.4 * std::cos(a), radius * std::cos(phi));
  };
  s.channels.push_back(sample_channel(cam_node, AnimatedPath::kTranslation, 160,
                                      [&](double t) { return glm::dvec4(eye_at(t), 0.0); }));
  s.channels.push_back(sample_channel(cam_node, AnimatedPath::kRotation, 160, [&](double t) {
    // glTF cameras look down local -Z with +Y up.
    const glm::dvec3 eye = eye_at(t);
    const glm::dmat4 view = glm::lookAt(eye, target, glm::dvec3(0, 1, 0));
    return quat_xyzw(glm::quat_cast(glm::inverse(view)));
  }));

  s.finalize();
  return s;
}

// ---------------------------------------------------------------------------------------------
// The payload that stands for the scene

namespace {

constexpr std::string_view kPayloadFirstLine = "afr builtin scene v1\n";
constexpr std::string_view kRayDepthKey = "ray depth ";

std::string_view as_text(std::span<const uint8_t> bytes) {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

}  // namespace

std::string builtin_scene_payload(std::optional<int> ray_depth) {
  std::string text(kPayloadFirstLine);
  if (ray_depth) text += fmt::format("{}{}\n", kRayDepthKey, *ray_depth);
  return text;
}

bool is_builtin_scene_payload(std::span<const uint8_t> bytes) {
  return as_text(bytes).starts_with(kPayloadFirstLine);
}

Scene builtin_scene_from_payload(std::span<const uint8_t> bytes) {
  const std::string_view text = as_text(bytes);
  if (!text.starts_with(kPayloadFirstLine)) {
    throw Error("the built-in scene's payload does not start with \"afr builtin scene v1\"");
  }
  std::string_view rest = text.substr(kPayloadFirstLine.size());
  std::optional<int> ray_depth;
  if (!rest.empty()) {
    // One more line, "ray depth N"; nothing else may follow.
    int depth = -1;
    const char* end = rest.data() + rest.size();
    const auto [digits_end, ec] =
        rest.starts_with(kRayDepthKey)
            ? std::from_chars(rest.data() + kRayDepthKey.size(), end, depth)
            : std::from_chars_result{rest.data(), std::errc::invalid_argument};
    if (ec != std::errc() || digits_end + 1 != end || *digits_end != '\n') {
      throw Error(
          fmt::format("the built-in scene's payload has {} bytes after its first line that are "
                      "not the one line \"ray depth N\" (N from 0 to {})",
                      rest.size(), kMaxRayDepth));
    }
    if (depth < 0 || depth > kMaxRayDepth) {
      throw Error(fmt::format("the built-in scene's payload asks for ray depth {} (0 to {})", depth,
                              kMaxRayDepth));
    }
    ray_depth = depth;
  }
  Scene scene = make_builtin_scene();
  scene.ray_depth = ray_depth;
  return scene;
}

}  // namespace afr
