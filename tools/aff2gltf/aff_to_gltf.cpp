#include "aff_to_gltf.h"

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/gltf_pack.h>
#include <afr/common/image.h>

#include <fmt/format.h>
#include <unistd.h>

#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <string_view>
#include <unordered_map>

namespace afr::aff {
namespace {

using tinygltf::Value;

constexpr int kMaxRefineDepth = 10;  // at most 1024 baked samples between two breakpoints

Value number(double x) { return Value(x); }
Value vec3_value(const glm::dvec3& v) {
  return Value(Value::Array{number(v.x), number(v.y), number(v.z)});
}

// Below this (largest diffuse channel) a material counts as having no diffuse part.
constexpr double kNoDiffuse = 1e-3;

struct PbrColor {
  glm::dvec3 base{0.0};
  double metallic = 0.0;
};

// The Phong material's diffuse (RGB D, mean d) and specular (mean s) as glTF metallic-roughness
// (docs/aff2gltf.md, "Materials"). afr's BRDF takes base (1 - metallic) as its diffuse
// reflectance and mix(0.04, base, metallic) as its specular one:
// - no specular: base = D, metallic 0;
// - specular but no diffuse: a metal, base = the specular RGB, metallic 1;
// - both: metallic = s / (d + s) and base = D / (1 - metallic), so the diffuse part is D again
//   and the specular one has mean about s (tinted by D's hue; Phong's is white). Where that
//   base would exceed 1 it is scaled down to 1 (the diffuse loses the same factor);
// - transmissive: metallic 0 and base = D's hue at full strength (white for grey or black D),
//   because glTF tints the transmitted light by the base color and AFF does not.
PbrColor phong_to_pbr(const Material& m) {
  const glm::dvec3 diffuse = glm::clamp(m.diffuse, 0.0, 1.0);
  const glm::dvec3 specular = glm::clamp(m.specular, 0.0, 1.0);
  const double d = (diffuse.r + diffuse.g + diffuse.b) / 3.0;
  const double s = (specular.r + specular.g + specular.b) / 3.0;
  const double d_max = std::max(diffuse.r, std::max(diffuse.g, diffuse.b));
  PbrColor out;
  if (m.transmittance > 0.0) {
    out.base = d_max > kNoDiffuse ? diffuse / d_max : glm::dvec3(1.0);
  } else if (s <= 0.0) {
    out.base = diffuse;
  } else if (d_max <= kNoDiffuse) {
    out.base = specular;
    out.metallic = 1.0;
  } else {
    out.metallic = s / (d + s);
    out.base = diffuse / (1.0 - out.metallic);
    const double b_max = std::max(out.base.r, std::max(out.base.g, out.base.b));
    if (b_max > 1.0) out.base /= b_max;
  }
  return out;
}

// Turn between two rotations, in radians, whichever sign the quaternions carry.
double quat_angle(const glm::dquat& a, const glm::dquat& b) {
  return 2.0 * std::acos(std::min(1.0, std::abs(glm::dot(a, b))));
}

// glm's slerp, but without the trigonometry for nearly equal inputs.
glm::dquat shortest_slerp(glm::dquat a, glm::dquat b, double s) {
  if (glm::dot(a, b) < 0.0) b = -b;
  return glm::normalize(glm::slerp(a, b, s));
}

// The rotation of a camera node that looks along `dir` with `up` as the up hint: glTF cameras
// look down local -Z with local +Y up.
glm::dquat look_rotation(const glm::dvec3& dir, const glm::dvec3& up) {
  const glm::dvec3 d = glm::normalize(dir);
  glm::dvec3 x = glm::cross(d, up);
  if (glm::length(x) < 1e-12)
    x = glm::cross(d, std::abs(d.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0));
  x = glm::normalize(x);
  const glm::dvec3 y = glm::cross(x, d);
  return glm::normalize(glm::quat_cast(glm::dmat3(x, y, -d)));
}

glm::dquat axis_angle(const glm::dvec3& axis, double radians) {
  const double len = glm::length(axis);
  if (len <= 0.0 || radians == 0.0) return glm::dquat(1.0, 0.0, 0.0, 0.0);
  return glm::angleAxis(radians, axis / len);
}

// Distance that keeps two float times apart near time t (and is small against any frame).
double time_epsilon(double t) {
  const float f = float(t);
  const double ulp = double(std::nextafter(f, std::numeric_limits<float>::infinity())) - double(f);
  return std::max(5e-5, 16.0 * ulp);
}

template <typename T>
struct Samples {
  std::vector<float> times;  // glTF seconds
  std::vector<T> values;
  void push(float t, const T& v) {
    times.push_back(t);
    values.push_back(v);
  }
};

// A single-channel view of what a node's `k` block turns into.
struct BakedChannel {
  int input = -1;
  int output = -1;
  std::string interpolation;
};
struct KeyframeAccessors {
  BakedChannel translation, rotation, scale, visibility;
};

class Builder {
 public:
  Builder(const Scene& scene, const GltfOptions& options, GltfScene* out)
      : scene_(scene), options_(options), out_(out), model_(out->model) {
    if (scene_.animation && scene_.animation->start < 0.0) time_offset_ = -scene_.animation->start;
    out_->time_offset = time_offset_;
    start_time_ = scene_.animation ? scene_.animation->start : 0.0;
  }

  void build() {
    model_.asset.version = "2.0";
    model_.asset.generator = "afr aff2gltf";
    model_.buffers.emplace_back();
    add_materials();

    tinygltf::Scene gscene;
    gscene.name = scene_.root_file.filename().string();
    const int camera = add_camera();
    if (camera >= 0) gscene.nodes.push_back(camera);
    gscene.nodes.push_back(add_node(0));
    for (size_t i = 0; i < scene_.lights.size(); ++i) gscene.nodes.push_back(add_light(i));
    gscene.extras = scene_extras();
    model_.scenes.push_back(std::move(gscene));
    model_.defaultScene = 0;

    if (!animation_.channels.empty()) {
      animation_.name = "aff";
      model_.animations.push_back(std::move(animation_));
    }
    model_.buffers[0].data = std::move(bin_);
  }

 private:
  // ---- binary data --------------------------------------------------------------------------

  int add_view(const void* data, size_t bytes, int target) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = bin_.size();
    view.byteLength = bytes;
    view.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    bin_.insert(bin_.end(), p, p + bytes);
    model_.bufferViews.push_back(std::move(view));
    return int(model_.bufferViews.size() - 1);
  }

  // Float data of `components` per element (1, 2, 3 or 4), with min/max when asked.
  int add_floats(const float* data, size_t count, int components, int target, bool bounds) {
    static constexpr int kTypes[] = {0, TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_VEC2,
                                     TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4};
    tinygltf::Accessor a;
    a.bufferView = add_view(data, count * size_t(components) * sizeof(float), target);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = kTypes[components];
    a.count = count;
    if (bounds && count > 0) {
      a.minValues.assign(size_t(components), std::numeric_limits<double>::infinity());
      a.maxValues.assign(size_t(components), -std::numeric_limits<double>::infinity());
      for (size_t i = 0; i < count; ++i) {
        for (int c = 0; c < components; ++c) {
          const double x = data[i * size_t(components) + size_t(c)];
          a.minValues[size_t(c)] = std::min(a.minValues[size_t(c)], x);
          a.maxValues[size_t(c)] = std::max(a.maxValues[size_t(c)], x);
        }
      }
    }
    model_.accessors.push_back(std::move(a));
    return int(model_.accessors.size() - 1);
  }
  int add_vec3s(const std::vector<glm::vec3>& v, int target, bool bounds) {
    return add_floats(&v[0].x, v.size(), 3, target, bounds);
  }
  int add_indices(const std::vector<uint32_t>& indices) {
    tinygltf::Accessor a;
    a.bufferView = add_view(indices.data(), indices.size() * sizeof(uint32_t),
                            TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    a.type = TINYGLTF_TYPE_SCALAR;
    a.count = indices.size();
    model_.accessors.push_back(std::move(a));
    return int(model_.accessors.size() - 1);
  }

  // ---- materials and textures ---------------------------------------------------------------

  void add_materials() {
    std::map<std::filesystem::path, int> textures;
    std::set<std::string> uris;
    for (size_t i = 0; i < scene_.materials.size(); ++i) {
      const Material& m = scene_.materials[i];
      tinygltf::Material g;
      g.name = "material" + std::to_string(i);
      g.doubleSided = true;
      g.emissiveFactor = {0.0, 0.0, 0.0};
      auto& pbr = g.pbrMetallicRoughness;
      const PbrColor pbr_color = phong_to_pbr(m);
      pbr.baseColorFactor = {pbr_color.base.r, pbr_color.base.g, pbr_color.base.b, 1.0};
      pbr.metallicFactor = pbr_color.metallic;
      if (m.transmittance > 0.0) {
        g.extensions["KHR_materials_transmission"] =
            Value(Value::Object{{"transmissionFactor", number(std::min(m.transmittance, 1.0))}});
        use_extension("KHR_materials_transmission");
        // An index below 1 (0 is written for opaque materials) is no refraction glTF can say:
        // the glTF default, 1.5, applies.
        if (m.ior >= 1.0) {
          g.extensions["KHR_materials_ior"] = Value(Value::Object{{"ior", number(m.ior)}});
          use_extension("KHR_materials_ior");
        }
      }
      pbr.roughnessFactor = std::clamp(std::sqrt(2.0 / (std::max(m.shine, 0.0) + 2.0)), 0.02, 1.0);
      if (!m.texture.empty()) {
        auto it = textures.find(m.texture);
        if (it == textures.end())
          it = textures.emplace(m.texture, add_texture(m.texture, &uris)).first;
        pbr.baseColorTexture.index = it->second;
        g.name += " " + m.texture.filename().string();
      }
      g.extras = Value(Value::Object{{"afr_ambient", vec3_value(m.ambient)},
                                     {"afr_specular", vec3_value(m.specular)},
                                     {"afr_shine", number(m.shine)},
                                     {"afr_transmittance", number(m.transmittance)},
                                     {"afr_ior", number(m.ior)}});
      model_.materials.push_back(std::move(g));
    }
  }

  // Listed in extensionsUsed, never in extensionsRequired: a reader without them still shows
  // the scene, opaque.
  void use_extension(const std::string& name) {
    auto& used = model_.extensionsUsed;
    if (std::find(used.begin(), used.end(), name) == used.end()) used.push_back(name);
  }

  int add_texture(const std::filesystem::path& source, std::set<std::string>* uris) {
    if (model_.samplers.empty()) {
      tinygltf::Sampler s;  // AFF textures wrap like OpenGL REPEAT
      s.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
      s.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
      s.wrapS = TINYGLTF_TEXTURE_WRAP_REPEAT;
      s.wrapT = TINYGLTF_TEXTURE_WRAP_REPEAT;
      model_.samplers.push_back(s);
    }
    const std::string stem = source.stem().string();
    std::string uri = stem + ".png";
    for (int k = 2; uris->count(uri); ++k) uri = stem + "_" + std::to_string(k) + ".png";
    uris->insert(uri);
    tinygltf::Image image;
    image.name = stem;
    image.uri = uri;
    image.mimeType = "image/png";
    model_.images.push_back(std::move(image));
    out_->images.push_back({source, uri});
    tinygltf::Texture texture;
    texture.name = stem;
    texture.sampler = 0;
    texture.source = int(model_.images.size() - 1);
    model_.textures.push_back(std::move(texture));
    return int(model_.textures.size() - 1);
  }

  // ---- geometry -----------------------------------------------------------------------------

  struct PrimitiveAccessors {
    int position = -1, normal = -1, uv = -1, indices = -1;
  };

  // Accessors of a triangle set, shared by every instance with the same content (an included
  // file parsed twice gives equal sets).
  PrimitiveAccessors geometry(const TriangleSet& set) {
    auto bytes = [](const auto& v) {
      return std::string_view(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(v[0]));
    };
    const std::hash<std::string_view> h;
    size_t key = h(bytes(set.positions));
    key = key * 31 + h(bytes(set.normals));
    key = key * 31 + h(bytes(set.uvs));
    key = key * 31 + h(bytes(set.indices));
    auto& bucket = geometry_cache_[key];
    for (const auto& [other, accessors] : bucket) {
      if (other->positions == set.positions && other->normals == set.normals &&
          other->uvs == set.uvs && other->indices == set.indices) {
        return accessors;
      }
    }
    PrimitiveAccessors a;
    a.position = add_vec3s(set.positions, TINYGLTF_TARGET_ARRAY_BUFFER, true);
    if (!set.normals.empty())
      a.normal = add_vec3s(set.normals, TINYGLTF_TARGET_ARRAY_BUFFER, false);
    if (!set.uvs.empty()) {
      a.uv = add_floats(&set.uvs[0].x, set.uvs.size(), 2, TINYGLTF_TARGET_ARRAY_BUFFER, false);
    }
    a.indices = add_indices(set.indices);
    bucket.emplace_back(&set, a);
    return a;
  }

  static tinygltf::Primitive primitive(const PrimitiveAccessors& a, int material) {
    tinygltf::Primitive p;
    p.attributes["POSITION"] = a.position;
    if (a.normal >= 0) p.attributes["NORMAL"] = a.normal;
    if (a.uv >= 0) p.attributes["TEXCOORD_0"] = a.uv;
    p.indices = a.indices;
    p.material = material;
    p.mode = TINYGLTF_MODE_TRIANGLES;
    return p;
  }

  // One glTF mesh for the triangle sets of a node; equal meshes are shared between nodes.
  int add_mesh(const std::vector<TriangleSet>& sets, const std::string& name) {
    std::vector<int> key;
    std::vector<tinygltf::Primitive> primitives;
    for (const TriangleSet& set : sets) {
      if (set.indices.empty()) continue;
      const PrimitiveAccessors a = geometry(set);
      key.insert(key.end(), {a.position, a.normal, a.uv, a.indices, set.material});
      primitives.push_back(primitive(a, set.material));
    }
    if (primitives.empty()) return -1;
    const auto it = mesh_cache_.find(key);
    if (it != mesh_cache_.end()) return it->second;
    tinygltf::Mesh mesh;
    mesh.name = name;
    mesh.primitives = std::move(primitives);
    model_.meshes.push_back(std::move(mesh));
    mesh_cache_.emplace(std::move(key), int(model_.meshes.size() - 1));
    return int(model_.meshes.size() - 1);
  }

  static size_t triangles_of(const tinygltf::Model& model, int mesh) {
    size_t n = 0;
    for (const auto& p : model.meshes[size_t(mesh)].primitives) {
      n += model.accessors[size_t(p.indices)].count / 3;
    }
    return n;
  }

  // ---- nodes --------------------------------------------------------------------------------

  int new_node(const std::string& name) {
    model_.nodes.emplace_back();
    model_.nodes.back().name = name;
    return int(model_.nodes.size() - 1);
  }

  static void set_trs(tinygltf::Node* g, const glm::dvec3& t, const glm::dquat& r,
                      const glm::dvec3& s) {
    g->translation.clear();
    g->rotation.clear();
    g->scale.clear();
    if (t != glm::dvec3(0.0)) g->translation = {t.x, t.y, t.z};
    if (r != glm::dquat(1.0, 0.0, 0.0, 0.0)) g->rotation = {r.x, r.y, r.z, r.w};
    if (s != glm::dvec3(1.0)) g->scale = {s.x, s.y, s.z};
  }

  // The glTF node of AFF node `index` and, recursively, its subtree.
  int add_node(size_t index) {
    const Node& node = scene_.nodes[index];
    std::string name;
    switch (node.kind) {
      case Node::Kind::kRoot:
        name = scene_.root_file.filename().string();
        break;
      case Node::Kind::kStatic:
        name = "xs " + node.where.str();
        break;
      case Node::Kind::kAnimated:
        name = node.name;
        break;
    }
    const int self = new_node(name);
    // The node that holds the geometry and children: `self`, or a child of it that carries the
    // visibility of an `x` whose `k` also animates scale (one node has one scale channel).
    int holder = self;
    if (node.kind == Node::Kind::kStatic) {
      set_trs(&model_.nodes[size_t(self)], node.translation,
              axis_angle(node.axis, node.angle_deg * std::numbers::pi / 180.0), node.scale);
    } else if (node.kind == Node::Kind::kAnimated) {
      holder = animate_node(self, node.name);
    }
    std::vector<int> children;
    const int mesh = add_mesh(node.meshes, name);
    if (mesh >= 0) {
      model_.nodes[size_t(holder)].mesh = mesh;
      out_->triangle_count += triangles_of(model_, mesh);
    }
    for (const int child : node.children) children.push_back(add_node(size_t(child)));
    add_animated_triangles(node, &children);
    auto& own = model_.nodes[size_t(holder)].children;
    own.insert(own.end(), children.begin(), children.end());
    return self;
  }

  // ---- animation ----------------------------------------------------------------------------

  void add_channel(int node, const std::string& path, const BakedChannel& baked) {
    tinygltf::AnimationSampler sampler;
    sampler.input = baked.input;
    sampler.output = baked.output;
    sampler.interpolation = baked.interpolation;
    animation_.samplers.push_back(std::move(sampler));
    tinygltf::AnimationChannel channel;
    channel.sampler = int(animation_.samplers.size() - 1);
    channel.target_node = node;
    channel.target_path = path;
    animation_.channels.push_back(std::move(channel));
  }

  int add_times(const std::vector<float>& times) {
    return add_floats(times.data(), times.size(), 1, 0, true);
  }

  // Sample times and values of a channel whose keys sit at `key_times` (n >= 4; the value moves
  // only between t_1 and t_{n-2}): every key time (and, with `frames`, every frame time) in that
  // range, a sample just before each jump (two keys at one time), then halving where
  // `needs_split(a, mid, b)` says the straight interpolation from a to b misses the value at
  // the midpoint.
  template <typename T, typename Eval, typename NeedsSplit>
  Samples<T> bake(bool frames, const std::vector<double>& key_times, Eval eval,
                  NeedsSplit needs_split) {
    const size_t n = key_times.size();
    const double lo = std::max(key_times[1] + time_offset_, 0.0);
    const double hi = std::max(key_times[n - 2] + time_offset_, lo);
    std::vector<float> times = {float(lo), float(hi)};
    for (size_t k = 1; k + 1 < n; ++k) {
      const double t = key_times[k] + time_offset_;
      if (key_times[k] == key_times[k - 1]) continue;  // the second key of a pair: done below
      if (k + 2 < n && key_times[k] == key_times[k + 1] && t > lo && t <= hi) {
        // A jump: a sample just before it, and the jump's own sample at the first float time
        // not before it (a float rounded down would still see the value before the jump).
        const double before = t - time_epsilon(t);
        if (before > lo) times.push_back(float(before));
        float at = float(t);
        if (double(at) < t) at = std::nextafter(at, std::numeric_limits<float>::infinity());
        times.push_back(at);
      } else if (t > lo && t < hi) {
        times.push_back(float(t));
      }
    }
    if (frames && scene_.animation) {
      for (int f = 0; f < scene_.animation->frames; ++f) {
        const double t = scene_.animation->frame_time(f) + time_offset_;
        if (t > lo && t < hi) times.push_back(float(t));
      }
    }
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());

    auto at = [&](float t) { return eval(double(t) - time_offset_); };
    Samples<T> samples;
    std::function<void(float, const T&, float, const T&, int)> refine =
        [&](float a, const T& va, float b, const T& vb, int depth) {
          if (depth >= kMaxRefineDepth) return;
          if (double(b) - double(a) < 3.0 * time_epsilon(b)) return;
          const float m = float(0.5 * (double(a) + double(b)));
          if (m <= a || m >= b) return;
          const T vm = at(m);
          if (!needs_split(va, vm, vb)) return;
          refine(a, va, m, vm, depth + 1);
          samples.push(m, vm);
          refine(m, vm, b, vb, depth + 1);
        };
    T previous = at(times[0]);
    samples.push(times[0], previous);
    for (size_t i = 1; i < times.size(); ++i) {
      const T v = at(times[i]);
      refine(times[i - 1], previous, times[i], v, 0);
      samples.push(times[i], v);
      previous = v;
    }
    return samples;
  }

  BakedChannel bake_vectors(const TcbSpline& spline) {
    double largest = 0.0;
    for (const TcbKey& k : spline.keys()) {
      largest = std::max({largest, std::abs(k.value.x), std::abs(k.value.y), std::abs(k.value.z)});
    }
    const double tolerance = std::max(options_.position_tolerance * largest, 1e-7);
    const Samples<glm::dvec3> s = bake<glm::dvec3>(
        /*frames=*/true, spline.times(), [&](double t) { return spline.evaluate(t); },
        [&](const glm::dvec3& a, const glm::dvec3& m, const glm::dvec3& b) {
          return glm::length(0.5 * (a + b) - m) > tolerance;
        });
    std::vector<glm::vec3> values(s.values.begin(), s.values.end());
    return {add_times(s.times), add_vec3s(values, 0, false), "LINEAR"};
  }

  // Section 4.1: a TCB channel is exactly a glTF CUBICSPLINE over keys 1..n-2, with tangents
  // per second: out(i) = D_o / h_i, in(i+1) = D_i / h_i. Baked when the key times repeat or
  // fall before glTF time 0.
  BakedChannel vector_channel(const TcbSpline& spline) {
    const auto& keys = spline.keys();
    const size_t n = keys.size();
    std::vector<float> times;
    for (size_t k = 1; k + 1 < n; ++k) {
      const float t = float(keys[k].t + time_offset_);
      if (t < 0.0f || (!times.empty() && t <= times.back())) return bake_vectors(spline);
      times.push_back(t);
    }
    // Hermite per segment in the float times a glTF reader sees, so that its u matches ours.
    std::vector<glm::vec3> values(3 * times.size(), glm::vec3(0.0f));
    for (size_t j = 0; j < times.size(); ++j) values[3 * j + 1] = glm::vec3(keys[j + 1].value);
    for (size_t j = 0; j + 1 < times.size(); ++j) {
      const double h = double(times[j + 1]) - double(times[j]);
      const TcbSpline::Tangents d = spline.segment_tangents(j + 1);
      values[3 * j + 2] = glm::vec3(d.out_of_start / h);  // out-tangent of key j
      values[3 * (j + 1)] = glm::vec3(d.into_end / h);    // in-tangent of key j + 1
    }
    return {add_times(times), add_vec3s(values, 0, false), "CUBICSPLINE"};
  }

  template <typename Eval>
  BakedChannel rotation_channel(const std::vector<double>& key_times, Eval eval) {
    const double max_step = options_.max_rotation_step_deg * std::numbers::pi / 180.0;
    const double rotation_tolerance = options_.rotation_tolerance_deg * std::numbers::pi / 180.0;
    const Samples<glm::dquat> s = bake<glm::dquat>(
        /*frames=*/false, key_times, eval,
        [&](const glm::dquat& a, const glm::dquat& m, const glm::dquat& b) {
          return quat_angle(a, m) + quat_angle(m, b) > max_step ||
                 quat_angle(shortest_slerp(a, b, 0.5), m) > rotation_tolerance;
        });
    // glTF order x, y, z, w; consecutive samples in one hemisphere so LINEAR (slerp) takes the
    // short way, which is the way the spline turns since samples are at most max_step apart.
    std::vector<float> values;
    glm::dquat previous(1.0, 0.0, 0.0, 0.0);
    for (size_t i = 0; i < s.values.size(); ++i) {
      glm::dquat q = s.values[i];
      if (i > 0 && glm::dot(previous, q) < 0.0) q = -q;
      values.insert(values.end(), {float(q.x), float(q.y), float(q.z), float(q.w)});
      previous = q;
    }
    return {add_times(s.times), add_floats(values.data(), s.values.size(), 4, 0, false), "LINEAR"};
  }

  // Section 4.3: hidden/visible as a STEP scale (0 or 1), visible before the first key.
  BakedChannel visibility_channel(const std::vector<VisibilityKey>& keys) {
    std::vector<float> times;
    std::vector<glm::vec3> values;
    for (const VisibilityKey& k : keys) {
      const float t = float(std::max(k.t + time_offset_, 0.0));
      const glm::vec3 v(k.visible ? 1.0f : 0.0f);
      if (times.empty() && t > 0.0f && !k.visible) {
        times.push_back(0.0f);
        values.push_back(glm::vec3(1.0f));
      }
      if (!times.empty() && t <= times.back()) {
        values.back() = v;  // the last key at one time wins
      } else {
        times.push_back(t);
        values.push_back(v);
      }
    }
    return {add_times(times), add_vec3s(values, 0, false), "STEP"};
  }

  static bool visible_at(const std::vector<VisibilityKey>& keys, double t) {
    bool visible = true;
    for (const VisibilityKey& k : keys) {
      if (k.t <= t) visible = k.visible;
    }
    return visible;
  }

  const KeyframeAccessors& keyframe_accessors(const Keyframes& k) {
    const auto cached = keyframe_cache_.find(k.name);
    if (cached != keyframe_cache_.end()) return cached->second;
    KeyframeAccessors a;
    if (!k.translation.empty()) a.translation = vector_channel(TcbSpline(k.translation));
    if (!k.scale.empty()) a.scale = vector_channel(TcbSpline(k.scale));
    if (!k.rotation.empty()) {
      const RotationSpline spline(k.rotation);
      a.rotation = rotation_channel(spline.times(), [&](double t) { return spline.evaluate(t); });
    }
    if (!k.visibility.empty()) a.visibility = visibility_channel(k.visibility);
    return keyframe_cache_.emplace(k.name, a).first->second;
  }

  // Animates glTF node `self` with `k name`; returns the node that should hold the geometry.
  int animate_node(int self, const std::string& name) {
    const auto it = scene_.keyframes.find(name);
    if (it == scene_.keyframes.end()) return self;  // the parser warned
    const Keyframes& k = it->second;
    const KeyframeAccessors& a = keyframe_accessors(k);
    const double t0 = start_time_;
    const glm::dvec3 t =
        k.translation.empty() ? glm::dvec3(0.0) : TcbSpline(k.translation).evaluate(t0);
    const glm::dquat r = k.rotation.empty() ? glm::dquat(1.0, 0.0, 0.0, 0.0)
                                            : RotationSpline(k.rotation).evaluate(t0);
    glm::dvec3 s = k.scale.empty() ? glm::dvec3(1.0) : TcbSpline(k.scale).evaluate(t0);
    const bool own_visibility = !k.visibility.empty() && k.scale.empty();
    if (own_visibility && !visible_at(k.visibility, t0)) s = glm::dvec3(0.0);
    set_trs(&model_.nodes[size_t(self)], t, r, s);
    if (a.translation.input >= 0) add_channel(self, "translation", a.translation);
    if (a.rotation.input >= 0) add_channel(self, "rotation", a.rotation);
    if (a.scale.input >= 0) add_channel(self, "scale", a.scale);
    if (k.visibility.empty()) return self;
    if (own_visibility) {
      add_channel(self, "scale", a.visibility);
      return self;
    }
    const int holder = new_node(name + ".visibility");
    if (!visible_at(k.visibility, t0)) model_.nodes[size_t(holder)].scale = {0.0, 0.0, 0.0};
    add_channel(holder, "scale", a.visibility);
    model_.nodes[size_t(self)].children.push_back(holder);
    return holder;
  }

  // `tpa` triangles: per (material, time list) one child node whose mesh morphs linearly
  // between the samples (sample 0 is the base; target j-1 holds sample j minus sample 0).
  void add_animated_triangles(const Node& node, std::vector<int>* children) {
    std::map<std::pair<int, std::vector<double>>, std::vector<const AnimatedTriangle*>> groups;
    for (const AnimatedTriangle& tri : node.animated_triangles) {
      groups[{tri.material, tri.times}].push_back(&tri);
    }
    for (const auto& group : groups) {
      // Not a structured binding: clang before 16 cannot capture one in the lambda below.
      const std::vector<const AnimatedTriangle*>& tris = group.second;
      const auto& [material, times] = group.first;
      const size_t samples = times.size();
      auto corners = [&](size_t j, bool normals) {
        std::vector<glm::vec3> v;
        for (const AnimatedTriangle* tri : tris) {
          const auto& c = normals ? tri->normals[j] : tri->positions[j];
          v.insert(v.end(), c.begin(), c.end());
        }
        return v;
      };
      const std::vector<glm::vec3> base_p = corners(0, false), base_n = corners(0, true);
      std::vector<uint32_t> indices(base_p.size());
      for (size_t i = 0; i < indices.size(); ++i) indices[i] = uint32_t(i);
      PrimitiveAccessors a;
      a.position = add_vec3s(base_p, TINYGLTF_TARGET_ARRAY_BUFFER, true);
      a.normal = add_vec3s(base_n, TINYGLTF_TARGET_ARRAY_BUFFER, false);
      a.indices = add_indices(indices);
      tinygltf::Primitive p = primitive(a, material);
      for (size_t j = 1; j < samples; ++j) {
        std::vector<glm::vec3> dp = corners(j, false), dn = corners(j, true);
        for (size_t i = 0; i < dp.size(); ++i) {
          dp[i] -= base_p[i];
          dn[i] -= base_n[i];
        }
        p.targets.push_back({{"POSITION", add_vec3s(dp, TINYGLTF_TARGET_ARRAY_BUFFER, true)},
                             {"NORMAL", add_vec3s(dn, TINYGLTF_TARGET_ARRAY_BUFFER, false)}});
      }
      tinygltf::Mesh mesh;
      mesh.name = "tpa " + node.where.str();
      mesh.primitives.push_back(std::move(p));
      const int child = new_node(mesh.name);
      if (samples > 1) {
        // Weights: sample j is the unit vector e_j (all zero for sample 0); glTF times must
        // increase strictly, so repeated (or negative) times are nudged up by one float step.
        std::vector<float> gtimes;
        std::vector<float> weights;
        for (size_t j = 0; j < samples; ++j) {
          float t = float(std::max(times[j] + time_offset_, 0.0));
          if (!gtimes.empty() && t <= gtimes.back()) {
            t = std::nextafter(gtimes.back(), std::numeric_limits<float>::infinity());
          }
          gtimes.push_back(t);
          for (size_t w = 1; w < samples; ++w) weights.push_back(w == j ? 1.0f : 0.0f);
        }
        mesh.weights.assign(samples - 1, 0.0);
        // The weights at the start time: linear between the samples around it.
        const double t0 = start_time_;
        if (t0 >= times.back()) {
          mesh.weights.back() = 1.0;
        } else if (t0 > times.front()) {
          size_t j = 1;
          while (times[j] <= t0) ++j;
          const double u = (t0 - times[j - 1]) / (times[j] - times[j - 1]);
          if (j - 1 >= 1) mesh.weights[j - 2] = 1.0 - u;
          mesh.weights[j - 1] = u;
        }
        add_channel(
            child, "weights",
            {add_times(gtimes), add_floats(weights.data(), weights.size(), 1, 0, false), "LINEAR"});
      }
      model_.meshes.push_back(std::move(mesh));
      model_.nodes[size_t(child)].mesh = int(model_.meshes.size() - 1);
      out_->triangle_count += tris.size();
      children->push_back(child);
    }
  }

  // ---- camera and lights --------------------------------------------------------------------

  // Section 4.4: a root node with the perspective camera of `v`, moved by `k camera`.
  int add_camera() {
    const auto k = scene_.keyframes.find("camera");
    const Keyframes* keys = k == scene_.keyframes.end() ? nullptr : &k->second;
    if (!scene_.view && !keys) return -1;
    View view;
    if (scene_.view) {
      view = *scene_.view;
    } else {
      out_->warnings.push_back("k camera without a v block: yfov 45 degrees, no aspect ratio");
    }
    tinygltf::Camera camera;
    camera.type = "perspective";
    camera.name = "camera";
    camera.perspective.yfov = view.angle * std::numbers::pi / 180.0;
    if (view.width > 0 && view.height > 0) {
      camera.perspective.aspectRatio = double(view.width) / double(view.height);
    }
    camera.perspective.znear = view.hither;
    camera.perspective.zfar = 0.0;  // infinite: write_gltf drops the member
    model_.cameras.push_back(std::move(camera));

    const int node = new_node("camera");
    model_.nodes[size_t(node)].camera = int(model_.cameras.size() - 1);
    const double t0 = start_time_;
    glm::dvec3 eye = view.from;
    glm::dquat rotation = look_rotation(view.at - view.from, view.up);
    if (keys) {
      if (!keys->scale.empty() || !keys->visibility.empty()) {
        out_->warnings.push_back(keys->where.str() +
                                 ": k camera: scale and visibility do not apply to a camera");
      }
      if (!keys->translation.empty()) {
        const TcbSpline eye_spline(keys->translation);
        eye = eye_spline.evaluate(t0);
        add_channel(node, "translation", vector_channel(eye_spline));
        if (keys->rotation.empty()) {
          // Only `transl`: the camera keeps looking at v's fixed `at` with v's `up`.
          rotation = look_rotation(view.at - eye, view.up);
          add_channel(node, "rotation", rotation_channel(eye_spline.times(), [&](double t) {
                        return look_rotation(view.at - eye_spline.evaluate(t), view.up);
                      }));
        }
      }
      if (!keys->rotation.empty()) {
        // The rotation is absolute: identity looks down -Z with +Y up, like a glTF camera.
        const RotationSpline spline(keys->rotation);
        rotation = spline.evaluate(t0);
        add_channel(node, "rotation",
                    rotation_channel(spline.times(), [&](double t) { return spline.evaluate(t); }));
      }
    }
    set_trs(&model_.nodes[size_t(node)], eye, rotation, glm::dvec3(1.0));
    return node;
  }

  // KHR_lights_punctual point light; AFF lights do not fall off (extras.afr_falloff). NFF
  // shades diffuse x light colour x cos; glTF's Lambertian BRDF divides by pi, so an intensity
  // of pi gives the same brightness (GltfOptions::light_intensity = 1).
  int add_light(size_t index) {
    const Light& l = scene_.lights[index];
    tinygltf::Light light;
    light.name = l.name.empty() ? "light" + std::to_string(index) : l.name;
    light.type = "point";
    const double n = double(scene_.lights.size());
    light.intensity = std::numbers::pi * (options_.spd_light_intensity ? std::sqrt(n) / (2.0 * n)
                                                                       : options_.light_intensity);
    light.color = {l.color.r, l.color.g, l.color.b};
    light.extras = Value(Value::Object{{"afr_falloff", Value(std::string("none"))}});
    model_.lights.push_back(std::move(light));

    const int node = new_node(model_.lights.back().name);
    model_.nodes[size_t(node)].extensions["KHR_lights_punctual"] =
        Value(Value::Object{{"light", Value(int(model_.lights.size() - 1))}});
    glm::dvec3 position = l.position;
    if (!l.name.empty()) {
      const auto k = scene_.keyframes.find(l.name);
      if (k != scene_.keyframes.end()) {
        const Keyframes& keys = k->second;
        if (!keys.rotation.empty() || !keys.scale.empty() || !keys.visibility.empty()) {
          out_->warnings.push_back(keys.where.str() + ": k " + l.name +
                                   ": only transl applies to a light");
        }
        if (!keys.translation.empty()) {
          // Taken as the absolute world position, like the camera's (the format leaves it open).
          const TcbSpline spline(keys.translation);
          position = spline.evaluate(start_time_);
          add_channel(node, "translation", vector_channel(spline));
        }
      }
    }
    set_trs(&model_.nodes[size_t(node)], position, glm::dquat(1.0, 0.0, 0.0, 0.0), glm::dvec3(1.0));
    return node;
  }

  Value scene_extras() const {
    Value::Object extras{{"afr_background", vec3_value(scene_.background)},
                         {"afr_ambient", vec3_value(scene_.ambient)},
                         {"afr_time_offset", number(time_offset_)}};
    if (scene_.animation) {
      const AnimationRange& a = *scene_.animation;
      extras["afr_animation"] = Value(Value::Object{
          {"start", number(a.start)}, {"end", number(a.end)}, {"frames", Value(a.frames)}});
    }
    if (scene_.view && scene_.view->width > 0 && scene_.view->height > 0) {
      extras["afr_resolution"] =
          Value(Value::Array{Value(scene_.view->width), Value(scene_.view->height)});
    }
    return Value(std::move(extras));
  }

  const Scene& scene_;
  const GltfOptions& options_;
  GltfScene* out_;
  tinygltf::Model& model_;
  std::vector<unsigned char> bin_;
  tinygltf::Animation animation_;
  double time_offset_ = 0.0;
  double start_time_ = 0.0;
  std::unordered_map<size_t, std::vector<std::pair<const TriangleSet*, PrimitiveAccessors>>>
      geometry_cache_;
  std::map<std::vector<int>, int> mesh_cache_;
  std::map<std::string, KeyframeAccessors> keyframe_cache_;
};

// tinygltf writes "zfar": 0 for an infinite perspective camera; glTF wants the member absent.
void drop_zero_zfar(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  nlohmann::ordered_json json = nlohmann::ordered_json::parse(in);
  in.close();
  bool changed = false;
  if (json.contains("cameras")) {
    for (auto& camera : json["cameras"]) {
      if (!camera.contains("perspective")) continue;
      auto& perspective = camera["perspective"];
      if (perspective.contains("zfar") && perspective["zfar"].get<double>() == 0.0) {
        perspective.erase("zfar");
        changed = true;
      }
    }
  }
  if (!changed) return;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << json.dump(2) << '\n';
  if (!out) throw Error(path.string() + ": write error");
}

}  // namespace

GltfScene build_gltf(const Scene& scene, const GltfOptions& options) {
  GltfScene out;
  Builder(scene, options, &out).build();
  return out;
}

namespace {

// The .gltf, its .bin and its PNG textures, written by afr (write_image8; tinygltf only
// references their uri).
void write_gltf_files(GltfScene* gltf, const std::filesystem::path& path) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  // A scene without geometry or keys has no bytes: glTF allows no empty buffer, so it has none.
  if (gltf->model.buffers.at(0).data.empty() && gltf->model.bufferViews.empty()) {
    gltf->model.buffers.clear();
  } else {
    gltf->model.buffers.at(0).uri = path.stem().string() + ".bin";
  }
  for (const GltfImage& image : gltf->images) {
    write_image8(decode_image_file(image.source), dir / image.uri);
  }
  tinygltf::TinyGLTF writer;
  // Without an image writer tinygltf keeps each image's uri and never encodes pixels.
  writer.SetImageWriter(nullptr, nullptr);
  if (!writer.WriteGltfSceneToFile(&gltf->model, path.string(), /*embedImages=*/false,
                                   /*embedBuffers=*/false, /*prettyPrint=*/true,
                                   /*writeBinary=*/false)) {
    throw Error(path.string() + ": cannot write glTF");
  }
  drop_zero_zfar(path);
}

// One .glb: the .gltf and its files written to a scratch folder beside `path`, then packed by
// afr's packer (afr/common/gltf_pack.h), the one the display serves .gltf scenes with.
void write_glb(GltfScene* gltf, const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  const fs::path dir = path.has_parent_path() ? path.parent_path() : ".";
  std::error_code ec;
  fs::create_directories(dir, ec);
  const fs::path scratch = dir / fmt::format(".{}.{}.parts", path.filename().string(), ::getpid());
  struct Scratch {
    fs::path dir;
    ~Scratch() {
      std::error_code ignored;
      fs::remove_all(dir, ignored);
    }
  } remove_scratch{scratch};
  const fs::path gltf_path = scratch / (path.stem().string() + ".gltf");
  write_gltf_files(gltf, gltf_path);
  std::ifstream in(gltf_path, std::ios::binary);
  const std::vector<uint8_t> text{std::istreambuf_iterator<char>(in), {}};
  const PackedGltf packed = pack_gltf(text, gltf_path);
  const fs::path part = path.string() + ".part";
  {
    std::ofstream out(part, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(packed.glb.data()), std::streamsize(packed.glb.size()));
    if (!out) throw Error(path.string() + ": write error");
  }
  fs::rename(part, path, ec);
  if (ec) throw Error(fmt::format("{}: cannot rename into place: {}", path.string(), ec.message()));
}

}  // namespace

void write_gltf(GltfScene* gltf, const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".glb") {
    write_glb(gltf, path);
  } else {
    write_gltf_files(gltf, path);
  }
}

ConvertReport convert_aff_to_gltf(const std::filesystem::path& aff_path,
                                  const std::filesystem::path& gltf_path,
                                  const ParseOptions& parse_options,
                                  const GltfOptions& gltf_options) {
  const Scene scene = parse_aff_file(aff_path, parse_options);
  GltfScene gltf = build_gltf(scene, gltf_options);
  write_gltf(&gltf, gltf_path);
  ConvertReport report;
  report.triangles = gltf.triangle_count;
  report.nodes = gltf.model.nodes.size();
  report.meshes = gltf.model.meshes.size();
  report.materials = gltf.model.materials.size();
  report.textures = gltf.model.textures.size();
  for (const auto& a : gltf.model.animations) report.animation_channels += a.channels.size();
  report.warnings = scene.warnings;
  report.warnings.insert(report.warnings.end(), gltf.warnings.begin(), gltf.warnings.end());
  if (report.triangles == 0) {
    report.warnings.push_back(aff_path.filename().string() +
                              ": no geometry: the glTF has no triangles to draw");
  }
  return report;
}

}  // namespace afr::aff
