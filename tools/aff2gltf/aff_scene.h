// A BART AFF scene after parsing: the transform tree with its geometry already expanded into
// triangle lists (includes inlined, spheres and cones tessellated, mesh indices de-indexed),
// the materials, lights, view and the keyframe table. Plain data; aff_parser.h fills it and
// aff_to_gltf.h turns it into glTF.
#pragma once

#include "kb_spline.h"

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace afr::aff {

// A place in an AFF file, for messages: "kitchen.aff:12".
struct Location {
  std::string file;  // as the user named it, or the include's name
  int line = 0;
  std::string str() const { return file + ":" + std::to_string(line); }
};

// `v`: the static view. `angle` is the full vertical field of view in degrees.
struct View {
  glm::dvec3 from{0.0};
  glm::dvec3 at{0.0, 0.0, -1.0};
  glm::dvec3 up{0.0, 1.0, 0.0};
  double angle = 45.0;
  double hither = 1.0;  // already replaced by 1.0 when the file gives < 1e-4
  int width = 0;
  int height = 0;
};

// `f`/`fm` parameters plus the texture of the primitive that uses them. `f` is stored in `fm`
// form: diffuse = Kd * RGB, specular = Ks (white), ambient = 0.
struct Material {
  glm::dvec3 ambient{0.0};
  glm::dvec3 diffuse{0.0};
  glm::dvec3 specular{0.0};
  double shine = 0.0;          // Phong exponent
  double transmittance = 0.0;  // 0 = opaque
  double ior = 0.0;
  std::filesystem::path texture;  // resolved .ppm file; empty = untextured

  bool operator==(const Material&) const = default;
};

// One glTF primitive's worth of triangles with per-vertex attributes (no shared AFF indices
// left). `normals` and `uvs` are empty or as long as `positions`.
struct TriangleSet {
  int material = -1;  // index into Scene::materials
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec2> uvs;
  std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise front faces

  size_t triangle_count() const { return indices.size() / 3; }
};

// `tpa`: one triangle whose corners (and normals) are sampled at `times` and interpolated
// linearly in between; clamped outside.
struct AnimatedTriangle {
  int material = -1;
  std::vector<double> times;
  std::vector<std::array<glm::vec3, 3>> positions;  // one per time
  std::vector<std::array<glm::vec3, 3>> normals;    // one per time
};

struct VisibilityKey {
  double t = 0.0;
  bool visible = true;
};

// `k NAME { ... }`. Empty vectors are missing channels (identity; always visible).
struct Keyframes {
  std::string name;
  Location where;
  std::vector<TcbKey> translation;
  std::vector<RotationKey> rotation;
  std::vector<TcbKey> scale;
  std::vector<VisibilityKey> visibility;
};

// A node of the transform tree: the root (the scene outside every transform), an `xs` static
// transform M = T(translation) R(axis, angle) S(scale), or an `x NAME` animated transform.
struct Node {
  enum class Kind { kRoot, kStatic, kAnimated };
  Kind kind = Kind::kRoot;
  std::string name;  // the animation name of an `x`; empty otherwise
  Location where;
  glm::dvec3 scale{1.0};
  glm::dvec3 axis{1.0, 0.0, 0.0};
  double angle_deg = 0.0;
  glm::dvec3 translation{0.0};
  std::vector<int> children;  // indices into Scene::nodes
  std::vector<TriangleSet> meshes;
  std::vector<AnimatedTriangle> animated_triangles;
};

// `l` or `la`: a point light at a world position (`la` names the `k` block that moves it).
struct Light {
  std::string name;  // empty for `l`
  Location where;
  glm::dvec3 position{0.0};
  glm::dvec3 color{1.0};
};

// `a START END NFRAMES`: frame k is at START + k (END - START) / (NFRAMES - 1).
struct AnimationRange {
  double start = 0.0;
  double end = 0.0;
  int frames = 0;

  double frame_time(int k) const {
    return frames > 1 ? start + k * (end - start) / (frames - 1) : start;
  }
};

struct Scene {
  std::filesystem::path root_file;
  std::optional<View> view;
  glm::dvec3 background{0.0};
  glm::dvec3 ambient{1.0};
  std::optional<AnimationRange> animation;
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Node> nodes;                     // nodes[0] is the root
  std::map<std::string, Keyframes> keyframes;  // by name; the last definition wins
  std::vector<std::string> warnings;           // "file:line: what", in parse order

  // Triangles of the expanded scene (every included copy counts), animated ones included.
  size_t triangle_count() const;
};

}  // namespace afr::aff
