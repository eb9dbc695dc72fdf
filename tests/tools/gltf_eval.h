// Test-only, independent reading of a written glTF: accessor data as doubles, animation
// samplers evaluated straight from the glTF 2.0 specification (Appendix C: STEP, LINEAR with
// slerp for rotations, CUBICSPLINE Hermite), node lookups and instanced triangle counts.
// Deliberately shares no code with tools/aff2gltf.
#pragma once

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace afr::test {

inline int components_of(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
  }
  throw std::runtime_error("unexpected accessor type");
}

// All elements of a float or uint32 accessor, flattened.
inline std::vector<double> read_accessor(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors.at(size_t(index));
  const tinygltf::BufferView& v = m.bufferViews.at(size_t(a.bufferView));
  const tinygltf::Buffer& b = m.buffers.at(size_t(v.buffer));
  const size_t n = a.count * size_t(components_of(a.type));
  const unsigned char* p = b.data.data() + v.byteOffset + a.byteOffset;
  std::vector<double> out(n);
  for (size_t i = 0; i < n; ++i) {
    if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
      float f;
      std::memcpy(&f, p + 4 * i, 4);
      out[i] = f;
    } else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      uint32_t u;
      std::memcpy(&u, p + 4 * i, 4);
      out[i] = u;
    } else {
      throw std::runtime_error("unexpected component type");
    }
  }
  return out;
}

inline int find_node(const tinygltf::Model& m, const std::string& name) {
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    if (m.nodes[i].name == name) return int(i);
  }
  return -1;
}

// The sampler driving `path` of `node`, or nullptr.
inline const tinygltf::AnimationSampler* find_sampler(const tinygltf::Model& m, int node,
                                                      const std::string& path) {
  for (const auto& anim : m.animations) {
    for (const auto& c : anim.channels) {
      if (c.target_node == node && c.target_path == path) return &anim.samplers[size_t(c.sampler)];
    }
  }
  return nullptr;
}

// glTF Appendix C. `rotation` selects slerp for LINEAR (quaternions x, y, z, w).
inline std::vector<double> evaluate_sampler(const tinygltf::Model& m,
                                            const tinygltf::AnimationSampler& s, double t,
                                            bool rotation) {
  const std::vector<double> times = read_accessor(m, s.input);
  const std::vector<double> values = read_accessor(m, s.output);
  const size_t keys = times.size();
  const bool cubic = s.interpolation == "CUBICSPLINE";
  const size_t per_key = cubic ? 3 : 1;
  const size_t n = values.size() / (keys * per_key);  // components per value
  auto value = [&](size_t k, size_t part) {           // part: 0 in-tangent, 1 value, 2 out-tangent
    const size_t element = cubic ? 3 * k + part : k;
    return std::vector<double>(values.begin() + long(element * n),
                               values.begin() + long((element + 1) * n));
  };
  const size_t vpart = cubic ? 1 : 0;
  if (t <= times.front()) return value(0, vpart);
  if (t >= times.back()) return value(keys - 1, vpart);
  size_t k = 0;
  while (!(times[k] <= t && t < times[k + 1])) ++k;
  const double td = times[k + 1] - times[k];
  const double u = (t - times[k]) / td;
  std::vector<double> out(n);
  if (s.interpolation == "STEP") return value(k, 0);
  if (cubic) {
    const auto p0 = value(k, 1), b0 = value(k, 2), a1 = value(k + 1, 0), p1 = value(k + 1, 1);
    const double u2 = u * u, u3 = u2 * u;
    for (size_t c = 0; c < n; ++c) {
      out[c] = (2 * u3 - 3 * u2 + 1) * p0[c] + td * (u3 - 2 * u2 + u) * b0[c] +
               (-2 * u3 + 3 * u2) * p1[c] + td * (u3 - u2) * a1[c];
    }
    return out;
  }
  const auto v0 = value(k, 0);
  auto v1 = value(k + 1, 0);
  if (!rotation) {
    for (size_t c = 0; c < n; ++c) out[c] = (1 - u) * v0[c] + u * v1[c];
    return out;
  }
  double d = 0;
  for (size_t c = 0; c < 4; ++c) d += v0[c] * v1[c];
  if (d < 0) {
    for (double& x : v1) x = -x;
    d = -d;
  }
  const double angle = std::acos(std::min(1.0, d));
  double w0 = 1 - u, w1 = u;
  if (angle > 1e-9) {
    w0 = std::sin((1 - u) * angle) / std::sin(angle);
    w1 = std::sin(u * angle) / std::sin(angle);
  }
  double len = 0;
  for (size_t c = 0; c < 4; ++c) {
    out[c] = w0 * v0[c] + w1 * v1[c];
    len += out[c] * out[c];
  }
  for (double& x : out) x /= std::sqrt(len);
  return out;
}

// A node property at time t: the animated value if a channel drives it, else the node's own.
inline std::vector<double> node_property(const tinygltf::Model& m, int node,
                                         const std::string& path, double t) {
  if (const auto* s = find_sampler(m, node, path)) {
    return evaluate_sampler(m, *s, t, path == "rotation");
  }
  const tinygltf::Node& n = m.nodes[size_t(node)];
  if (path == "translation")
    return n.translation.empty() ? std::vector<double>{0, 0, 0} : n.translation;
  if (path == "rotation") return n.rotation.empty() ? std::vector<double>{0, 0, 0, 1} : n.rotation;
  return n.scale.empty() ? std::vector<double>{1, 1, 1} : n.scale;
}

inline size_t mesh_triangles(const tinygltf::Model& m, int mesh) {
  size_t n = 0;
  for (const auto& p : m.meshes[size_t(mesh)].primitives) {
    n += m.accessors[size_t(p.indices)].count / 3;
  }
  return n;
}

// Triangles of every mesh instance reachable from the default scene's root nodes.
inline size_t scene_triangles(const tinygltf::Model& m) {
  size_t total = 0;
  std::vector<int> stack(m.scenes[0].nodes.begin(), m.scenes[0].nodes.end());
  while (!stack.empty()) {
    const tinygltf::Node& n = m.nodes[size_t(stack.back())];
    stack.pop_back();
    if (n.mesh >= 0) total += mesh_triangles(m, n.mesh);
    stack.insert(stack.end(), n.children.begin(), n.children.end());
  }
  return total;
}

// A .gltf, or a .glb by its extension.
inline tinygltf::Model load_gltf(const std::string& path) {
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  // Images are checked separately; tinygltf need not decode them.
  loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int,
                           const unsigned char*, int, void*) { return true; },
                        nullptr);
  const bool binary = path.size() > 4 && path.compare(path.size() - 4, 4, ".glb") == 0;
  if (!(binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
               : loader.LoadASCIIFromFile(&model, &err, &warn, path))) {
    throw std::runtime_error(path + ": " + err);
  }
  return model;
}

}  // namespace afr::test
