// The glTF loader's meshes: primitives, their attributes, morph targets and skins.
#include "gltf_loader_parts.h"

#include <algorithm>
#include <numeric>

namespace afr::gltf_detail {

// ---- Meshes ----

void Loader::load_meshes() {
  for (size_t m = 0; m < model_.meshes.size(); ++m) {
    const tinygltf::Mesh& in = model_.meshes[m];
    Mesh mesh;
    mesh.name = in.name;
    // Every primitive of a mesh has the same number of morph targets, one per mesh weight.
    const size_t targets = in.primitives.empty() ? 0 : in.primitives[0].targets.size();
    for (size_t k = 0; k < in.primitives.size(); ++k) {
      if (in.primitives[k].targets.size() != targets) {
        fail(fmt::format("mesh {} primitive {} has {} morph targets, but primitive 0 has {}", m, k,
                         in.primitives[k].targets.size(), targets));
      }
    }
    if (!in.weights.empty() && in.weights.size() != targets) {
      fail(fmt::format("mesh {} has {} morph weights for {} morph targets", m, in.weights.size(),
                       targets));
    }
    if (!is_finite(in.weights))
      fail(fmt::format("mesh {} has a morph weight that is not finite", m));
    mesh.weights.assign(targets, 0.0f);
    for (size_t k = 0; k < in.weights.size(); ++k) mesh.weights[k] = float(in.weights[k]);
    for (size_t k = 0; k < in.primitives.size(); ++k) {
      Primitive primitive;
      if (load_primitive(in.primitives[k], fmt::format("mesh {} primitive {}", m, k), &primitive)) {
        mesh.primitives.push_back(std::move(primitive));
      }
    }
    scene_.meshes.push_back(std::move(mesh));
  }
}

// Returns false for a primitive that is skipped (not triangles, no positions, or no triangles).
bool Loader::load_primitive(const tinygltf::Primitive& in, const std::string& what,
                            Primitive* out) {
  const int mode = in.mode < 0 ? TINYGLTF_MODE_TRIANGLES : in.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
      mode != TINYGLTF_MODE_TRIANGLE_FAN) {
    warn_once(
        fmt::format("mode {}", mode),
        fmt::format("primitives of mode {} (points or lines) are not supported (skipped)", mode));
    return false;
  }
  for (const auto& [name, accessor] : in.attributes) {
    // Checked here for every attribute, since only those the scene needs are read.
    if (accessor < 0 || size_t(accessor) >= model_.accessors.size()) {
      fail(fmt::format("{} attribute {} refers to accessor {}, but there are {}", what, name,
                       accessor, model_.accessors.size()));
    }
    if (name.rfind("COLOR_", 0) == 0 && name != "COLOR_0") {
      warn_once("more colors",
                fmt::format("vertex color sets other than COLOR_0 ({}) are ignored", name));
    }
    if (name.rfind("JOINTS_", 0) == 0 && name != "JOINTS_0") {
      warn_once("more joints",
                fmt::format("more than 4 joint influences per vertex ({}) are not supported: the "
                            "4 of JOINTS_0 are used, their weights renormalised",
                            name));
    }
  }
  draco_bytes_.clear();
  decode_draco(in, what);
  if (in.material < -1 || in.material >= int(model_.materials.size())) {
    fail(fmt::format("{} refers to material {}, but there are {}", what, in.material,
                     model_.materials.size()));
  }
  out->material = in.material;

  // glTF 2.0 (3.7.2.1) allows a primitive without positions and asks that it be skipped unless
  // an extension gives them (Draco's are among the attributes by now).
  const auto position = in.attributes.find("POSITION");
  if (position == in.attributes.end()) {
    warn_once("no POSITION",
              fmt::format("primitives without a POSITION attribute draw nothing and are skipped, "
                          "as glTF asks ({} is the first)",
                          what));
    return false;
  }
  const std::vector<float> p =
      read_floats(position->second, TINYGLTF_TYPE_VEC3, what + " POSITION");
  const size_t vertex_count = p.size() / 3;
  out->positions.resize(vertex_count);
  for (size_t i = 0; i < vertex_count; ++i)
    out->positions[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};

  if (const auto normal = in.attributes.find("NORMAL"); normal != in.attributes.end()) {
    const std::vector<float> n = read_floats(normal->second, TINYGLTF_TYPE_VEC3, what + " NORMAL");
    if (n.size() != p.size()) {
      fail(fmt::format("{} has {} normals for {} positions", what, n.size() / 3, vertex_count));
    }
    out->normals.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) {
      const glm::vec3 v(n[3 * i], n[3 * i + 1], n[3 * i + 2]);
      const float length = glm::length(v);
      out->normals[i] = length > 0.0f ? v / length : glm::vec3(0.0f, 0.0f, 1.0f);
    }
  }
  // Its material (loaded before the meshes; null: the default material) decides which
  // attributes it reads. The set its textures read: TEXCOORD_0 without a material or textures.
  const Material* material = in.material >= 0 && size_t(in.material) < scene_.materials.size()
                                 ? &scene_.materials[size_t(in.material)]
                                 : nullptr;
  read_texture_coordinates(in,
                           material ? uv_sources_[size_t(in.material)] : std::vector<UvSource>{},
                           what, vertex_count, out);
  // TANGENT (VEC4 of floats, or of normalized bytes or shorts with KHR_mesh_quantization), read
  // only where the material's normal textures use it; w taken by its sign.
  if (const auto tangent = in.attributes.find("TANGENT");
      material &&
      (material->normal_texture >= 0 || material->clearcoat_normal_texture >= 0 ||
       material->anisotropy > 0.0f) &&
      tangent != in.attributes.end()) {
    const std::vector<float> t =
        read_floats(tangent->second, TINYGLTF_TYPE_VEC4, what + " TANGENT");
    if (t.size() / 4 != vertex_count) {
      fail(fmt::format("{} has {} tangents for {} positions", what, t.size() / 4, vertex_count));
    }
    out->tangents.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) {
      out->tangents[i] = {t[4 * i], t[4 * i + 1], t[4 * i + 2], t[4 * i + 3] < 0.0f ? -1.0f : 1.0f};
    }
  }
  if (const auto color = in.attributes.find("COLOR_0"); color != in.attributes.end()) {
    // Its alpha matters only to a material that masks or blends.
    const bool keep_alpha = material && material->alpha_mode != Material::AlphaMode::kOpaque;
    load_colors(color->second, what + " COLOR_0", vertex_count, keep_alpha, out);
  }
  load_skinning(in, what, out);
  load_targets(in, what, out);

  std::vector<uint32_t> indices;
  if (in.indices >= 0) {
    indices = read_indices(in.indices, what + " indices");
  } else {
    indices.resize(vertex_count);
    std::iota(indices.begin(), indices.end(), 0u);
  }
  for (size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] >= vertex_count) {
      fail(
          fmt::format("index {} of {} (element {}) is out of range: the primitive has {} "
                      "vertices",
                      indices[i], what, i, vertex_count));
    }
  }
  // glTF 2.0, section 3.7.2.1: strips and fans as lists, keeping the winding.
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    // The glTF Validator warns of such a count (MESH_PRIMITIVE_INCOMPATIBLE_MODE) rather than
    // refusing it; the whole triangles are drawn.
    if (indices.size() % 3 != 0) {
      warn_once("incomplete triangle",
                fmt::format("{} has {} {}, not a multiple of 3: the last {} not drawn (said once "
                            "for every such primitive)",
                            what, indices.size(), in.indices >= 0 ? "indices" : "vertices",
                            indices.size() % 3 == 1 ? "one is" : "two are"));
      indices.resize(indices.size() - indices.size() % 3);
    }
    out->indices = std::move(indices);
  } else {
    const size_t triangles = indices.size() >= 3 ? indices.size() - 2 : 0;
    out->indices.reserve(3 * triangles);
    for (size_t i = 0; i < triangles; ++i) {
      if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        out->indices.insert(out->indices.end(),
                            {indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]});
      } else {
        out->indices.insert(out->indices.end(), {indices[i + 1], indices[i + 2], indices[0]});
      }
    }
  }
  if (out->indices.empty()) return false;
  if (out->normals.empty()) generate_normals(out);
  // A material that needs a tangent frame gets smooth tangents where the file has none, from the
  // coordinates of its normal texture, else of its clearcoat normal's, else of its anisotropy's.
  if (material && out->tangents.empty()) {
    if (material->normal_texture >= 0) {
      generate_tangents(out, material->uv_set.normal);
    } else if (material->clearcoat_normal_texture >= 0) {
      generate_tangents(out, material->uv_set.clearcoat_normal);
    } else if (material->anisotropy > 0.0f) {
      generate_tangents(out, material->uv_set.anisotropy);
    }
  }
  return true;
}

// COLOR_0 (glTF 2.0, 3.7.2.1): VEC3 or VEC4 of floats or of normalized unsigned bytes or shorts,
// a linear RGB(A) multiplier of the base color. Alpha is kept (clamped to 0 to 1) where
// keep_alpha (a MASK or BLEND material) and it is below 1 somewhere, and dropped otherwise: an
// OPAQUE material ignores it (glTF 2.0, 3.9.4). Negative color floats become 0.
void Loader::load_colors(int accessor, const std::string& what, size_t vertex_count,
                         bool keep_alpha, Primitive* out) {
  const tinygltf::Accessor& a = accessor_at(accessor, what);
  if (a.type != TINYGLTF_TYPE_VEC3 && a.type != TINYGLTF_TYPE_VEC4) {
    fail(fmt::format("accessor {} ({}) is {}: vertex colors must be VEC3 or VEC4", accessor, what,
                     type_name(a.type)));
  }
  const int components = a.type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
  if (!float_or_normalized(a)) {
    fail(
        fmt::format("accessor {} ({}) has componentType {}{}: vertex colors must be floats or "
                    "normalized unsigned bytes or shorts",
                    accessor, what, a.componentType, a.normalized ? " (normalized)" : ""));
  }
  const std::vector<float> c =
      read_floats(accessor, components == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3, what);
  if (c.size() / size_t(components) != vertex_count) {
    fail(fmt::format("{} has {} vertex colors for {} positions", what, c.size() / components,
                     vertex_count));
  }
  out->colors.resize(vertex_count);
  bool negative = false;
  for (size_t i = 0; i < vertex_count; ++i) {
    const float* v = &c[size_t(components) * i];
    for (int k = 0; k < 3; ++k) {
      negative |= v[k] < 0.0f;
      out->colors[i][k] = std::max(v[k], 0.0f);
    }
  }
  if (keep_alpha && components == 4) {
    bool below_one = false;
    for (size_t i = 0; i < vertex_count; ++i) below_one |= !(c[4 * i + 3] >= 1.0f);
    if (below_one) {
      out->color_alpha.resize(vertex_count);
      for (size_t i = 0; i < vertex_count; ++i) {
        const float a = c[4 * i + 3];
        out->color_alpha[i] = a >= 0.0f ? std::min(a, 1.0f) : 0.0f;  // NaN too
      }
    }
  }
  if (negative) {
    warn_once("negative vertex colors",
              fmt::format("{}: negative vertex color components are taken as 0", what));
  }
}

// JOINTS_0 and WEIGHTS_0. Weights are renormalised to sum to 1 (as viewers do: quantized
// weights rarely sum to 1 exactly, and JOINTS_1 influences are dropped); a vertex whose weights
// sum to 0 follows its first joint.
void Loader::load_skinning(const tinygltf::Primitive& in, const std::string& what, Primitive* out) {
  const auto joints = in.attributes.find("JOINTS_0");
  const auto weights = in.attributes.find("WEIGHTS_0");
  if (joints == in.attributes.end() && weights == in.attributes.end()) return;
  if (joints == in.attributes.end() || weights == in.attributes.end()) {
    fail(fmt::format("{} has {} but no {}", what,
                     joints == in.attributes.end() ? "WEIGHTS_0" : "JOINTS_0",
                     joints == in.attributes.end() ? "JOINTS_0" : "WEIGHTS_0"));
  }
  const size_t vertex_count = out->positions.size();
  out->joints = read_joints(joints->second, what + " JOINTS_0");
  if (out->joints.size() != vertex_count) {
    fail(fmt::format("{} has {} JOINTS_0 values for {} positions", what, out->joints.size(),
                     vertex_count));
  }
  const std::vector<float> w =
      read_floats(weights->second, TINYGLTF_TYPE_VEC4, what + " WEIGHTS_0");
  const tinygltf::Accessor& wa = model_.accessors[size_t(weights->second)];
  if (!float_or_normalized(wa)) {
    fail(
        fmt::format("accessor {} ({} WEIGHTS_0) has componentType {}{}: weights are floats or "
                    "normalized unsigned bytes or shorts",
                    weights->second, what, wa.componentType, wa.normalized ? " (normalized)" : ""));
  }
  if (w.size() != 4 * vertex_count) {
    fail(fmt::format("{} has {} WEIGHTS_0 values for {} positions", what, w.size() / 4,
                     vertex_count));
  }
  out->joint_weights.resize(vertex_count);
  for (size_t v = 0; v < vertex_count; ++v) {
    glm::vec4 jw(w[4 * v], w[4 * v + 1], w[4 * v + 2], w[4 * v + 3]);
    if (jw.x < 0.0f || jw.y < 0.0f || jw.z < 0.0f || jw.w < 0.0f) {
      fail(fmt::format("{} WEIGHTS_0 of vertex {} has a negative weight", what, v));
    }
    const float sum = jw.x + jw.y + jw.z + jw.w;
    if (sum > 0.0f) {
      jw /= sum;
    } else {
      warn_once("zero joint weights",
                "vertices whose joint weights sum to 0 follow their first joint");
      jw = glm::vec4(1.0f, 0.0f, 0.0f, 0.0f);
    }
    out->joint_weights[v] = jw;
  }
}

// Morph targets: POSITION and NORMAL displacements, and TANGENT ones where the primitive keeps
// its tangents (its material has a normal texture); other attributes warn.
void Loader::load_targets(const tinygltf::Primitive& in, const std::string& what, Primitive* out) {
  const size_t vertex_count = out->positions.size();
  out->targets.resize(in.targets.size());
  for (size_t k = 0; k < in.targets.size(); ++k) {
    const std::string where = fmt::format("{} morph target {}", what, k);
    MorphTarget& target = out->targets[k];
    for (const auto& [name, accessor] : in.targets[k]) {
      const bool tangent = name == "TANGENT";
      if (name != "POSITION" && name != "NORMAL" && !(tangent && !out->tangents.empty())) {
        if (!tangent) {
          warn_once("target " + name,
                    fmt::format("morph targets of {} are not supported (ignored)", name));
        }
        continue;
      }
      morph_displacements_ += vertex_count;
      if (morph_displacements_ > kMaxMorphDisplacements) {
        fail(
            fmt::format("{}: the file's morph targets displace more than {} vertex attributes, "
                        "more than afr accepts",
                        where, kMaxMorphDisplacements));
      }
      std::vector<glm::vec3> d = read_vec3s(accessor, vertex_count, name, where);
      (name == "POSITION" ? target.positions
       : tangent          ? target.tangents
                          : target.normals) = std::move(d);
    }
  }
}

// ---- Skins ----

void Loader::load_skins() {
  for (size_t k = 0; k < model_.skins.size(); ++k) {
    const tinygltf::Skin& in = model_.skins[k];
    const std::string what = fmt::format("skin {}", k);
    Skin skin;
    skin.name = in.name;
    if (in.joints.empty()) fail(what + " has no joints");
    for (int joint : in.joints) {
      if (joint < 0 || size_t(joint) >= model_.nodes.size()) {
        fail(fmt::format("{} has joint node {}, but there are {} nodes", what, joint,
                         model_.nodes.size()));
      }
    }
    skin.joints = in.joints;
    if (in.skeleton < -1 || in.skeleton >= int(model_.nodes.size())) {
      fail(fmt::format("{} has skeleton node {}, but there are {} nodes", what, in.skeleton,
                       model_.nodes.size()));
    }
    skin.skeleton = in.skeleton;
    // Without inverse bind matrices, each is the identity (glTF 2.0, 5.29).
    skin.inverse_bind_matrices.assign(in.joints.size(), glm::dmat4(1.0));
    if (in.inverseBindMatrices >= 0) {
      const std::vector<float> m =
          read_floats(in.inverseBindMatrices, TINYGLTF_TYPE_MAT4, what + " inverseBindMatrices");
      if (m.size() != 16 * in.joints.size()) {
        fail(fmt::format("{} has {} inverse bind matrices for {} joints", what, m.size() / 16,
                         in.joints.size()));
      }
      for (size_t j = 0; j < in.joints.size(); ++j) {
        for (int c = 0; c < 4; ++c) {
          for (int r = 0; r < 4; ++r) skin.inverse_bind_matrices[j][c][r] = m[16 * j + 4 * c + r];
        }
      }
    }
    scene_.skins.push_back(std::move(skin));
  }
}

// Joints and weights of meshes that no skinned node shows are never read: not kept.
void Loader::drop_unused_joints() {
  std::vector<char> skinned(scene_.meshes.size(), 0);
  for (const Node& n : scene_.nodes) {
    if (n.skin >= 0 && n.mesh >= 0) skinned[size_t(n.mesh)] = 1;
  }
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    if (skinned[m]) continue;
    for (Primitive& p : scene_.meshes[m].primitives) {
      p.joints = {};
      p.joint_weights = {};
    }
  }
}

}  // namespace afr::gltf_detail
