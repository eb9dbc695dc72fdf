// The glTF loader's animations: node channels, and KHR_animation_pointer's
// channels to nodes, meshes, lights, cameras and materials.
#include "gltf_loader_parts.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <limits>
#include <numbers>

namespace afr::gltf_detail {

namespace {

// The paths in a material of the texture slots afr reads, as KHR_animation_pointer names them
// (the object model's, and those of the archived KHR_materials_pbrSpecularGlossiness).
constexpr std::string_view kTextureSlots[] = {
    "pbrMetallicRoughness/baseColorTexture",
    "pbrMetallicRoughness/metallicRoughnessTexture",
    "emissiveTexture",
    "occlusionTexture",
    "normalTexture",
    "extensions/KHR_materials_transmission/transmissionTexture",
    "extensions/KHR_materials_specular/specularTexture",
    "extensions/KHR_materials_specular/specularColorTexture",
    "extensions/KHR_materials_clearcoat/clearcoatTexture",
    "extensions/KHR_materials_clearcoat/clearcoatRoughnessTexture",
    "extensions/KHR_materials_clearcoat/clearcoatNormalTexture",
    "extensions/KHR_materials_sheen/sheenColorTexture",
    "extensions/KHR_materials_sheen/sheenRoughnessTexture",
    "extensions/KHR_materials_anisotropy/anisotropyTexture",
    "extensions/KHR_materials_iridescence/iridescenceTexture",
    "extensions/KHR_materials_iridescence/iridescenceThicknessTexture",
    "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionTexture",
    "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionColorTexture",
    "extensions/KHR_materials_pbrSpecularGlossiness/diffuseTexture",
    "extensions/KHR_materials_pbrSpecularGlossiness/specularGlossinessTexture",
};

// Index digits as a pointer writes them (plain decimal, fewer than 10), or nothing.
std::optional<size_t> pointer_index(std::string_view digits) {
  size_t index = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
  if (ec != std::errc() || end != digits.data() + digits.size() || digits.size() >= 10 ||
      digits.find_first_not_of("0123456789") != std::string_view::npos) {
    return std::nullopt;
  }
  return index;
}

// A pointer to a texture slot's KHR_texture_transform offset, rotation or scale
// (/materials/N/SLOT/extensions/KHR_texture_transform/PROPERTY), or nothing.
std::optional<PointerTarget> texture_transform_target(std::string_view pointer) {
  static constexpr std::string_view kPrefix = "/materials/";
  static constexpr std::string_view kTransform = "/extensions/KHR_texture_transform/";
  const size_t at = pointer.rfind(kTransform);
  if (!pointer.starts_with(kPrefix) || at == std::string_view::npos) return std::nullopt;
  const std::string_view property = pointer.substr(at + kTransform.size());
  PointerTarget t;
  t.kind = PointerTarget::Kind::kProperty;
  if (property == "offset") {
    t.property = AnimatedProperty::kUvOffset;
  } else if (property == "rotation") {
    t.property = AnimatedProperty::kUvRotation;
  } else if (property == "scale") {
    t.property = AnimatedProperty::kUvScale;
  } else {
    return std::nullopt;  // texCoord: not animated
  }
  const std::string_view rest = pointer.substr(kPrefix.size(), at - kPrefix.size());
  const size_t slash = rest.find('/');
  if (slash == std::string_view::npos) return std::nullopt;
  const std::optional<size_t> index = pointer_index(rest.substr(0, slash));
  const std::string_view slot = rest.substr(slash + 1);
  if (!index || std::find(std::begin(kTextureSlots), std::end(kTextureSlots), slot) ==
                    std::end(kTextureSlots)) {
    return std::nullopt;
  }
  t.index = *index;
  t.texture = std::string(slot);
  return t;
}

// The target of `pointer` (PREFIX INDEX SUFFIX, the index plain decimal digits), or nothing
// for a pointer afr does not animate.
std::optional<PointerTarget> pointer_target(std::string_view pointer) {
  using Kind = PointerTarget::Kind;
  struct Form {
    std::string_view prefix, suffix;
    Kind kind;
    AnimatedProperty property = AnimatedProperty::kLightIntensity;
  };
  static constexpr std::string_view kLights = "/extensions/KHR_lights_punctual/lights/";
  static const Form kForms[] = {
      {"/nodes/", "/translation", Kind::kNode},
      {"/nodes/", "/rotation", Kind::kNode},
      {"/nodes/", "/scale", Kind::kNode},
      {"/nodes/", "/weights", Kind::kNode},
      {"/nodes/", "/extensions/KHR_node_visibility/visible", Kind::kProperty,
       AnimatedProperty::kNodeVisible},
      {"/meshes/", "/weights", Kind::kMeshWeights},
      {kLights, "/color", Kind::kProperty, AnimatedProperty::kLightColor},
      {kLights, "/intensity", Kind::kProperty, AnimatedProperty::kLightIntensity},
      {kLights, "/range", Kind::kProperty, AnimatedProperty::kLightRange},
      {kLights, "/spot/innerConeAngle", Kind::kProperty, AnimatedProperty::kLightInnerCone},
      {kLights, "/spot/outerConeAngle", Kind::kProperty, AnimatedProperty::kLightOuterCone},
      {"/cameras/", "/perspective/yfov", Kind::kProperty, AnimatedProperty::kCameraYfov},
      {"/cameras/", "/perspective/znear", Kind::kProperty, AnimatedProperty::kCameraZnear},
      {"/cameras/", "/orthographic/znear", Kind::kProperty, AnimatedProperty::kCameraZnear},
      {"/cameras/", "/orthographic/ymag", Kind::kProperty, AnimatedProperty::kCameraYmag},
      {"/materials/", "/pbrMetallicRoughness/baseColorFactor", Kind::kProperty,
       AnimatedProperty::kBaseColorFactor},
      {"/materials/", "/pbrMetallicRoughness/metallicFactor", Kind::kProperty,
       AnimatedProperty::kMetallicFactor},
      {"/materials/", "/pbrMetallicRoughness/roughnessFactor", Kind::kProperty,
       AnimatedProperty::kRoughnessFactor},
      {"/materials/", "/emissiveFactor", Kind::kProperty, AnimatedProperty::kEmissiveFactor},
      {"/materials/", "/extensions/KHR_materials_emissive_strength/emissiveStrength",
       Kind::kProperty, AnimatedProperty::kEmissiveStrength},
      {"/materials/", "/alphaCutoff", Kind::kProperty, AnimatedProperty::kAlphaCutoff},
      {"/materials/", "/normalTexture/scale", Kind::kProperty, AnimatedProperty::kNormalScale},
      {"/materials/", "/occlusionTexture/strength", Kind::kProperty,
       AnimatedProperty::kOcclusionStrength},
      {"/materials/", "/extensions/KHR_materials_clearcoat/clearcoatFactor", Kind::kProperty,
       AnimatedProperty::kClearcoatFactor},
      {"/materials/", "/extensions/KHR_materials_clearcoat/clearcoatRoughnessFactor",
       Kind::kProperty, AnimatedProperty::kClearcoatRoughnessFactor},
      {"/materials/", "/extensions/KHR_materials_sheen/sheenColorFactor", Kind::kProperty,
       AnimatedProperty::kSheenColorFactor},
      {"/materials/", "/extensions/KHR_materials_sheen/sheenRoughnessFactor", Kind::kProperty,
       AnimatedProperty::kSheenRoughnessFactor},
      {"/materials/", "/extensions/KHR_materials_specular/specularFactor", Kind::kProperty,
       AnimatedProperty::kSpecularFactor},
      {"/materials/", "/extensions/KHR_materials_specular/specularColorFactor", Kind::kProperty,
       AnimatedProperty::kSpecularColorFactor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceFactor", Kind::kProperty,
       AnimatedProperty::kIridescenceFactor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceIor", Kind::kProperty,
       AnimatedProperty::kIridescenceIor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceThicknessMinimum",
       Kind::kProperty, AnimatedProperty::kIridescenceThicknessMinimum},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceThicknessMaximum",
       Kind::kProperty, AnimatedProperty::kIridescenceThicknessMaximum},
      {"/materials/", "/extensions/KHR_materials_anisotropy/anisotropyStrength", Kind::kProperty,
       AnimatedProperty::kAnisotropyStrength},
      {"/materials/", "/extensions/KHR_materials_anisotropy/anisotropyRotation", Kind::kProperty,
       AnimatedProperty::kAnisotropyRotation},
      {"/materials/", "/extensions/KHR_materials_transmission/transmissionFactor", Kind::kProperty,
       AnimatedProperty::kTransmissionFactor},
      {"/materials/", "/extensions/KHR_materials_ior/ior", Kind::kProperty, AnimatedProperty::kIor},
      {"/materials/", "/extensions/KHR_materials_volume/thicknessFactor", Kind::kProperty,
       AnimatedProperty::kThicknessFactor},
      {"/materials/", "/extensions/KHR_materials_volume/attenuationDistance", Kind::kProperty,
       AnimatedProperty::kAttenuationDistance},
      {"/materials/", "/extensions/KHR_materials_volume/attenuationColor", Kind::kProperty,
       AnimatedProperty::kAttenuationColor},
      {"/materials/", "/extensions/KHR_materials_dispersion/dispersion", Kind::kProperty,
       AnimatedProperty::kDispersion},
      {"/materials/", "/extensions/KHR_materials_diffuse_transmission/diffuseTransmissionFactor",
       Kind::kProperty, AnimatedProperty::kDiffuseTransmissionFactor},
      {"/materials/",
       "/extensions/KHR_materials_diffuse_transmission/diffuseTransmissionColorFactor",
       Kind::kProperty, AnimatedProperty::kDiffuseTransmissionColor},
  };
  for (const Form& f : kForms) {
    if (pointer.size() <= f.prefix.size() + f.suffix.size() || !pointer.starts_with(f.prefix) ||
        !pointer.ends_with(f.suffix)) {
      continue;
    }
    const std::optional<size_t> index = pointer_index(
        pointer.substr(f.prefix.size(), pointer.size() - f.prefix.size() - f.suffix.size()));
    if (index) return PointerTarget{f.kind, f.suffix.substr(1), f.property, *index, {}};
  }
  return texture_transform_target(pointer);
}

}  // namespace

// ---- Animations ----

// KHR_animation_pointer: a channel whose target's path is "pointer" animates the property its
// JSON pointer names. Those pointer_target knows become channels: a node's (add_channel, as
// any node's channel), a mesh's weights (those of the nodes showing them), a light's, camera's
// or material's property (add_property_channel). Any other pointer is not animated, and one
// warning names the kinds skipped. tinygltf drops every channel without a target node, so this
// also notes which of the file's channels it kept (kept_channels_).
void Loader::read_animation_pointers(std::string_view json) {
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("animations") ||
      !doc["animations"].is_array()) {
    return;
  }
  bool other_nodeless = false;
  std::vector<std::string> skipped;  // the kinds of property not animated, in file order
  const nlohmann::json& animations = doc["animations"];
  kept_channels_.assign(animations.size(), {});
  for (size_t a = 0; a < animations.size(); ++a) {
    if (!animations[a].is_object() || !animations[a].contains("channels") ||
        !animations[a]["channels"].is_array()) {
      continue;  // tinygltf has named it
    }
    const nlohmann::json& channels = animations[a]["channels"];
    for (size_t c = 0; c < channels.size(); ++c) {
      const nlohmann::json& channel = channels[c];
      if (!channel.is_object()) continue;
      // tinygltf keeps a channel with a sampler and either no target or one naming a node and
      // a path.
      const bool sampled = channel.contains("sampler") && channel["sampler"].is_number_integer();
      if (!channel.contains("target") || !channel["target"].is_object()) {
        if (sampled) kept_channels_[a].push_back(c);
        continue;
      }
      const nlohmann::json& target = channel["target"];
      if (target.contains("node")) {
        if (sampled && target["node"].is_number_integer() && target.contains("path") &&
            target["path"].is_string()) {
          kept_channels_[a].push_back(c);
        }
        continue;
      }
      if (target.value("path", "") != "pointer") {
        other_nodeless = true;
        continue;
      }
      const std::string what = fmt::format("animation {} channel {} KHR_animation_pointer", a, c);
      const nlohmann::json* e = nullptr;
      if (target.contains("extensions") && target["extensions"].is_object() &&
          target["extensions"].contains("KHR_animation_pointer")) {
        e = &target["extensions"]["KHR_animation_pointer"];
      }
      if (e == nullptr || !e->is_object() || !e->contains("pointer") ||
          !(*e)["pointer"].is_string()) {
        fail(what + " has no \"pointer\" string");
      }
      const std::string pointer = (*e)["pointer"].get<std::string>();
      const int sampler = sampled ? channel["sampler"].get<int>() : -1;
      const std::optional<PointerTarget> named = pointer_target(pointer);
      if (!named) {
        // The kind of property: the pointer with its indices left out.
        std::string kind;
        for (char ch : pointer) {
          if (ch >= '0' && ch <= '9') {
            if (kind.empty() || kind.back() != '#') kind += '#';
          } else {
            kind += ch;
          }
        }
        if (std::find(skipped.begin(), skipped.end(), kind) == skipped.end()) {
          skipped.push_back(kind);
        }
        continue;
      }
      // Nodes and meshes are checked here; lights, cameras and materials once loaded.
      const bool node = named->kind == PointerTarget::Kind::kNode;
      const size_t count = node ? model_.nodes.size() : model_.meshes.size();
      if (named->kind != PointerTarget::Kind::kProperty && named->index >= count) {
        fail(fmt::format("{} \"{}\" targets {} {}, but there are {}", what, pointer,
                         node ? "node" : "mesh", named->index, count));
      }
      if (is_uv_property(named->property)) animated_uv_slots_[{named->index, named->texture}] = -1;
      pointer_channels_.push_back({a, c, sampler, *named, pointer});
    }
  }
  nodeless_channels_are_pointers_ = !other_nodeless;
  if (!skipped.empty()) {
    constexpr size_t kNamed = 3;
    const size_t count = skipped.size();
    skipped.resize(std::min(count, kNamed));
    warn_once("animation pointers",
              fmt::format("KHR_animation_pointer animations of {}{} are not supported (skipped: "
                          "see docs/scene-model.md for the properties afr animates)",
                          fmt::join(skipped, ", "),
                          count > kNamed ? fmt::format(" and {} more kinds", count - kNamed) : ""));
  }
}

void Loader::load_animations() {
  for (size_t a = 0; a < model_.animations.size(); ++a) {
    const tinygltf::Animation& animation = model_.animations[a];
    for (size_t c = 0; c < animation.channels.size(); ++c) {
      const tinygltf::AnimationChannel& in = animation.channels[c];
      const bool renumbered = a < kept_channels_.size() && c < kept_channels_[a].size();
      const std::string what =
          fmt::format("animation {} channel {}", a, renumbered ? kept_channels_[a][c] : c);
      if (in.target_node < 0) {
        warn_once("channel without node",
                  "animation channels without a target node are not supported (skipped)");
        continue;
      }
      add_channel(animation, in.sampler, in.target_node, in.target_path, what);
    }
    for (const PointerChannel& p : pointer_channels_) {
      if (p.animation != a) continue;
      const std::string what = fmt::format("animation {} channel {} (KHR_animation_pointer \"{}\")",
                                           a, p.channel, p.pointer);
      const PointerTarget& t = p.target;
      switch (t.kind) {
        case PointerTarget::Kind::kNode:
          add_channel(animation, p.sampler, int(t.index), std::string(t.path), what);
          break;
        case PointerTarget::Kind::kMeshWeights:  // those of each node showing the mesh's own
          for (size_t n = 0; n < model_.nodes.size(); ++n) {
            if (model_.nodes[n].mesh == int(t.index) && model_.nodes[n].weights.empty()) {
              add_channel(animation, p.sampler, int(n), "weights", what);
            }
          }
          break;
        case PointerTarget::Kind::kProperty:
          if (is_uv_property(t.property)) {
            // The set read_texture_slot gave the slot; -1 where the material has no texture
            // there (or no such material: add_property_channel names that).
            const auto slot = animated_uv_slots_.find({t.index, t.texture});
            if (t.index < scene_.materials.size() && slot->second < 0) {
              warn_once("animated empty texture slot",
                        fmt::format("{} animates the transform of a texture slot without a "
                                    "texture (skipped)",
                                    what));
              break;
            }
            add_property_channel(animation, p.sampler, t.property, t.index, what, slot->second);
          } else {
            add_property_channel(animation, p.sampler, t.property, t.index, what);
          }
          break;
      }
    }
  }
}

// One channel of `animation`: its sampler `sampler_index` drives `path` of node `node_index`.
void Loader::add_channel(const tinygltf::Animation& animation, int sampler_index, int node_index,
                         const std::string& path, const std::string& what) {
  if (size_t(node_index) >= model_.nodes.size()) {
    fail(
        fmt::format("{} targets node {}, but there are {}", what, node_index, model_.nodes.size()));
  }
  AnimationChannel channel;
  channel.node = node_index;
  int value_type = TINYGLTF_TYPE_VEC3;
  if (path == "translation") {
    channel.path = AnimatedPath::kTranslation;
  } else if (path == "rotation") {
    channel.path = AnimatedPath::kRotation;
    value_type = TINYGLTF_TYPE_VEC4;
  } else if (path == "scale") {
    channel.path = AnimatedPath::kScale;
  } else if (path == "weights") {
    channel.path = AnimatedPath::kWeights;
    value_type = TINYGLTF_TYPE_SCALAR;
  } else {
    warn_once("path " + path,
              fmt::format("animations of \"{}\" are not supported (skipped)", path));
    return;
  }
  if (channel.path == AnimatedPath::kWeights && hidden_nodes_.count(node_index) != 0) {
    return;  // KHR_node_visibility hid its mesh: nothing is drawn to morph
  }
  if (channel.path == AnimatedPath::kWeights && instanced_nodes_.count(node_index) != 0) {
    warn_once("instanced weights",
              "animated morph weights of a node with EXT_mesh_gpu_instancing are not "
              "supported (its instances keep the node's weights)");
    return;
  }
  if (channel.path != AnimatedPath::kWeights && scene_.nodes[size_t(node_index)].matrix) {
    warn_once("animated matrix node",
              "animations of nodes given as a matrix are not supported (skipped)");
    return;
  }
  std::vector<float> values;
  if (!read_sampler(animation, sampler_index, value_type, what, &channel, &values)) return;
  const std::vector<double>& times = channel.times;
  const size_t per_key = channel.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (channel.path == AnimatedPath::kWeights) {
    // As many weights per value as the node's mesh has morph targets (glTF 2.0, 3.11).
    const Node& node = scene_.nodes[size_t(node_index)];
    const size_t targets = node.mesh >= 0 ? scene_.meshes[size_t(node.mesh)].weights.size() : 0;
    if (targets == 0) {
      fail(fmt::format("{} animates the morph weights of node {}, which has {}", what, node_index,
                       node.mesh >= 0 ? "a mesh without morph targets" : "no mesh"));
    }
    if (times.empty() || values.size() != times.size() * per_key * targets) {
      fail(fmt::format(
          "{} has {} keyframe times and {} weights ({} per key expected: {} morph targets{})", what,
          times.size(), values.size(), per_key * targets, targets,
          per_key == 3 ? " times in-tangent, value, out-tangent" : ""));
    }
    channel.weights.assign(values.begin(), values.end());
    channel.weight_count = targets;
  } else {
    const size_t width = value_type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
    if (times.empty() || values.size() != times.size() * per_key * width) {
      fail(fmt::format("{} has {} keyframe times and {} values ({} per key expected)", what,
                       times.size(), values.size() / width, per_key));
    }
    channel.values.resize(values.size() / width);
    for (size_t i = 0; i < channel.values.size(); ++i) {
      const float* v = &values[i * width];
      channel.values[i] = glm::dvec4(v[0], v[1], v[2], width == 4 ? v[3] : 0.0f);
    }
  }
  repair_key_order(&channel, what);
  channel.validate(fmt::format("{} of {}", what, path_.string()));
  scene_.channels.push_back(std::move(channel));
}

// The interpolation and key times of sampler `sampler_index` into `channel`, its output values
// of `value_type` into `values`. False, with a warning, for an interpolation glTF lacks or a
// sampler without keys; an error for a sampler the animation lacks.
bool Loader::read_sampler(const tinygltf::Animation& animation, int sampler_index, int value_type,
                          const std::string& what, AnimationChannel* channel,
                          std::vector<float>* values) {
  if (sampler_index < 0 || size_t(sampler_index) >= animation.samplers.size()) {
    fail(fmt::format("{} refers to sampler {}, but there are {}", what, sampler_index,
                     animation.samplers.size()));
  }
  const tinygltf::AnimationSampler& sampler = animation.samplers[size_t(sampler_index)];
  if (sampler.interpolation == "LINEAR") {
    channel->interpolation = Interpolation::kLinear;
  } else if (sampler.interpolation == "STEP") {
    channel->interpolation = Interpolation::kStep;
  } else if (sampler.interpolation == "CUBICSPLINE") {
    channel->interpolation = Interpolation::kCubicSpline;
  } else {
    warn_once("interpolation " + sampler.interpolation,
              fmt::format("interpolation \"{}\" is not supported (channel skipped)",
                          sampler.interpolation));
    return false;
  }
  const std::vector<float> times =
      read_floats(sampler.input, TINYGLTF_TYPE_SCALAR, what + " input");
  *values = read_floats(sampler.output, value_type, what + " output");
  // glTF's accessors hold at least one element, but exporters write empty tracks, which animate
  // nothing: skipped rather than refusing the scene.
  if (times.empty() && values->empty()) {
    warn_once("no keyframes",
              fmt::format("animation channels without keyframes animate nothing and are skipped "
                          "({} is the first)",
                          what));
    return false;
  }
  channel->times.assign(times.begin(), times.end());
  return true;
}

// A KHR_animation_pointer channel that drives a property of a light, camera or material. A key
// outside the property's glTF range is taken as the same value without an animation is
// (clamped, or an error); the target must exist, and a light or camera that afr skipped (an
// unsupported type) takes its animation with it.
void Loader::add_property_channel(const tinygltf::Animation& animation, int sampler_index,
                                  AnimatedProperty property, size_t gltf_index,
                                  const std::string& what, int uv_set) {
  const bool light = is_light_property(property), camera = is_camera_property(property);
  const bool node = is_node_property(property);
  const std::vector<int>* map = light ? &light_map_ : camera ? &camera_map_ : nullptr;
  const size_t count = map ? map->size() : node ? model_.nodes.size() : scene_.materials.size();
  if (gltf_index >= count) {
    fail(fmt::format("{} targets {} {}, but there are {}", what,
                     light    ? "light"
                     : camera ? "camera"
                     : node   ? "node"
                              : "material",
                     gltf_index, count));
  }
  const int index = map ? (*map)[gltf_index] : int(gltf_index);
  if (index < 0) return;  // a skipped light or camera: named when it was skipped

  PropertyChannel out;
  out.property = property;
  out.index = index;
  out.uv_set = uv_set;
  const int width = component_count(property);
  const int type = width == 1   ? TINYGLTF_TYPE_SCALAR
                   : width == 2 ? TINYGLTF_TYPE_VEC2
                   : width == 3 ? TINYGLTF_TYPE_VEC3
                                : TINYGLTF_TYPE_VEC4;
  std::vector<float> values;
  if (!read_sampler(animation, sampler_index, type, what, &out.curve, &values)) return;
  const size_t per_key = out.curve.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  const size_t keys = out.curve.times.size();
  if (keys == 0 || values.size() != keys * per_key * size_t(width)) {
    fail(fmt::format("{} has {} keyframe times and {} values ({} per key expected)", what, keys,
                     values.size() / size_t(width), per_key));
  }
  // The range each key's value must lie in (tangents are not values).
  double lo = 0.0, hi = std::numeric_limits<double>::infinity();
  bool open_lo = false;
  switch (property) {
    case AnimatedProperty::kLightRange:
    case AnimatedProperty::kCameraYfov:
      open_lo = true;
      hi = std::numbers::pi;
      break;
    case AnimatedProperty::kCameraZnear:
      // glTF lets an orthographic camera's near plane be 0, not a perspective one's.
      open_lo = scene_.cameras[size_t(index)].ymag == 0.0;
      break;
    case AnimatedProperty::kCameraYmag:
      lo = -hi;  // any finite number but 0 (below); a negative one is taken as its magnitude
      break;
    case AnimatedProperty::kLightInnerCone:
    case AnimatedProperty::kLightOuterCone:
      hi = 0.5 * std::numbers::pi;
      break;
    case AnimatedProperty::kBaseColorFactor:
    case AnimatedProperty::kMetallicFactor:
    case AnimatedProperty::kRoughnessFactor:
    case AnimatedProperty::kOcclusionStrength:
    case AnimatedProperty::kClearcoatFactor:
    case AnimatedProperty::kClearcoatRoughnessFactor:
    case AnimatedProperty::kSheenColorFactor:
    case AnimatedProperty::kSheenRoughnessFactor:
    case AnimatedProperty::kSpecularFactor:
    case AnimatedProperty::kIridescenceFactor:
    case AnimatedProperty::kAnisotropyStrength:
    case AnimatedProperty::kTransmissionFactor:
    case AnimatedProperty::kAttenuationColor:
    case AnimatedProperty::kDiffuseTransmissionFactor:
    case AnimatedProperty::kDiffuseTransmissionColor:
      hi = 1.0;  // the extensions' own ranges, as the loader reads them unanimated
      break;
    case AnimatedProperty::kIridescenceIor:
    case AnimatedProperty::kIor:
      // An animated ior stays a glass's (KHR_materials_ior's 0, "reflect all", would pass
      // through (0, 1) between keys, which no material has).
      lo = 1.0;
      break;
    case AnimatedProperty::kAttenuationDistance:
      open_lo = true;
      break;
    case AnimatedProperty::kAnisotropyRotation:
    case AnimatedProperty::kNormalScale:
    case AnimatedProperty::kUvOffset:
    case AnimatedProperty::kUvRotation:
    case AnimatedProperty::kUvScale:
      lo = -hi;  // any finite number
      break;
    default:
      break;
  }
  out.curve.values.resize(values.size() / size_t(width));
  for (size_t i = 0; i < out.curve.values.size(); ++i) {
    const float* v = &values[i * size_t(width)];
    glm::dvec4& value = out.curve.values[i];
    for (int k = 0; k < width; ++k) value[k] = v[k];
    if (per_key == 3 && i % 3 != 1) continue;
    for (int k = 0; k < width; ++k) {
      const double x = value[k];
      if (!std::isfinite(x) || (property == AnimatedProperty::kCameraYmag && x == 0.0)) {
        fail(fmt::format("{}: key {} sets the {} to {}{}", what, i / per_key, to_string(property),
                         x, std::isfinite(x) ? " (glTF forbids a view of height 0)" : ""));
      }
      if ((open_lo ? x > lo : x >= lo) && x <= hi) continue;
      const std::string problem =
          // (The key is a float: 7 digits give it back.)
          fmt::format("{}: key {} sets the {} to {:.7g}, outside {}{}, {}]", what, i / per_key,
                      to_string(property), x, open_lo ? "(" : "[", lo,
                      std::isinf(hi) ? std::string("inf") : fmt::format("{:.6g}", hi));
      // As the loader takes these factors when they are not animated: clamped where they are
      // used. What is an error there (a camera's yfov, a negative intensity, ...) is one here.
      const bool clamped = property == AnimatedProperty::kBaseColorFactor ||
                           property == AnimatedProperty::kMetallicFactor ||
                           property == AnimatedProperty::kRoughnessFactor ||
                           property == AnimatedProperty::kEmissiveFactor;
      if (!clamped) fail(problem);
      warn_once("clamped " + what, problem + ": clamped where it is used");
    }
  }
  repair_key_order(&out.curve, what);
  out.curve.validate(fmt::format("{} of {}", what, path_.string()));
  scene_.property_channels.push_back(std::move(out));
}

}  // namespace afr::gltf_detail
