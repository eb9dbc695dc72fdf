// glTF 2.0 animation samplers: keyframe times and values for one animated property of one
// node (its translation, rotation, scale or morph weights), evaluated at a time in seconds with
// STEP, LINEAR (slerp for rotations) or CUBICSPLINE (Hermite) interpolation, exactly as the
// glTF 2.0 specification, Appendix C, defines them.
#pragma once

#include <afr/common/math.h>

#include <string_view>
#include <vector>

namespace afr {

enum class Interpolation { kStep, kLinear, kCubicSpline };
enum class AnimatedPath { kTranslation, kRotation, kScale, kWeights };

std::string_view to_string(Interpolation interpolation);
std::string_view to_string(AnimatedPath path);

// One channel: drives `path` of node `node`. Values are vec3 (translation, scale) stored in
// xyz, or quaternions stored as (x, y, z, w) like glTF. For CUBICSPLINE there are three values
// per key in glTF order: in-tangent, value, out-tangent (tangents per second).
//
// A weights channel (kWeights) drives the morph weights of the node's mesh: `values` is empty
// and `weights` holds `weight_count` numbers per value (one value per key, three for
// CUBICSPLINE, in the same order), key after key, as glTF's output accessor lists them.
struct AnimationChannel {
  int node = -1;
  AnimatedPath path = AnimatedPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<double> times;  // strictly increasing, seconds
  std::vector<glm::dvec4> values;
  std::vector<double> weights;  // kWeights only
  size_t weight_count = 0;      // kWeights only: morph targets of the node's mesh

  // Keys whose times are not strictly increasing (out of order, or repeated: glTF 2.0 forbids
  // both, and exporters write them) put right: the keys sorted by time (stable), and of keys
  // that share a time only the last in the file kept, as aff2gltf repairs AFF key blocks. A
  // key's values (three for CUBICSPLINE) and weights move with it. Leaves the channel as it
  // is when its times are already in order, or when a time is not finite or the value count
  // does not match (validate names those).
  struct KeyRepair {
    bool repaired = false;
    size_t dropped = 0;  // keys dropped for a later key at the same time
  };
  KeyRepair repair_key_order();

  // Throws afr::Error if times are not strictly increasing and finite, the value count does
  // not match the interpolation (and, for weights, the weight count), a value is not finite,
  // or the channel is empty. `what` names the channel in the message.
  void validate(std::string_view what) const;

  // Value at time t (seconds) of a translation, rotation or scale channel. Before the first
  // key: the first value; after the last: the last value. Rotations come back normalised.
  glm::dvec4 evaluate(double t) const;
  // The `weight_count` morph weights of a weights channel at time t, written to `out`, with
  // the same rules at and beyond the ends.
  void evaluate_weights(double t, float* out) const;

  double start_time() const { return times.front(); }
  double end_time() const { return times.back(); }
};

// A property of a light, a camera or a material that a KHR_animation_pointer channel drives
// (a node's transform and weights are AnimationChannel's paths). Light angles are radians, as
// in glTF; colors and factors are the glTF values (a base color factor with its alpha).
enum class AnimatedProperty {
  kLightColor,         // /extensions/KHR_lights_punctual/lights/N/color
  kLightIntensity,     //   .../intensity
  kLightRange,         //   .../range
  kLightInnerCone,     //   .../spot/innerConeAngle
  kLightOuterCone,     //   .../spot/outerConeAngle
  kCameraYfov,         // /cameras/N/perspective/yfov
  kCameraZnear,        //   .../znear (/perspective/ or /orthographic/)
  kCameraYmag,         // /cameras/N/orthographic/ymag
  kBaseColorFactor,    // /materials/N/pbrMetallicRoughness/baseColorFactor
  kMetallicFactor,     //   .../pbrMetallicRoughness/metallicFactor
  kRoughnessFactor,    //   .../pbrMetallicRoughness/roughnessFactor
  kEmissiveFactor,     // /materials/N/emissiveFactor
  kEmissiveStrength,   //   .../extensions/KHR_materials_emissive_strength/emissiveStrength
  kAlphaCutoff,        // /materials/N/alphaCutoff
  kNormalScale,        // /materials/N/normalTexture/scale
  kOcclusionStrength,  // /materials/N/occlusionTexture/strength
  // The material extensions' factors, /materials/N/extensions/EXTENSION/PROPERTY:
  kClearcoatFactor,              //   KHR_materials_clearcoat/clearcoatFactor
  kClearcoatRoughnessFactor,     //   .../clearcoatRoughnessFactor
  kSheenColorFactor,             //   KHR_materials_sheen/sheenColorFactor
  kSheenRoughnessFactor,         //   .../sheenRoughnessFactor
  kSpecularFactor,               //   KHR_materials_specular/specularFactor
  kSpecularColorFactor,          //   .../specularColorFactor
  kIridescenceFactor,            //   KHR_materials_iridescence/iridescenceFactor
  kIridescenceIor,               //   .../iridescenceIor
  kIridescenceThicknessMinimum,  //   .../iridescenceThicknessMinimum (nanometres)
  kIridescenceThicknessMaximum,  //   .../iridescenceThicknessMaximum
  kAnisotropyStrength,           //   KHR_materials_anisotropy/anisotropyStrength
  kAnisotropyRotation,           //   .../anisotropyRotation (radians)
  kTransmissionFactor,           //   KHR_materials_transmission/transmissionFactor
  kIor,                          //   KHR_materials_ior/ior
  kThicknessFactor,              //   KHR_materials_volume/thicknessFactor
  kAttenuationDistance,          //   .../attenuationDistance
  kAttenuationColor,             //   .../attenuationColor
  kDispersion,                   //   KHR_materials_dispersion/dispersion
  kDiffuseTransmissionFactor,    //   KHR_materials_diffuse_transmission/diffuseTransmissionFactor
  kDiffuseTransmissionColor,     //   .../diffuseTransmissionColorFactor
  // /materials/N/TEXTURE/extensions/KHR_texture_transform/offset, TEXTURE a texture slot's
  // path (pbrMetallicRoughness/baseColorTexture, extensions/KHR_materials_clearcoat/
  // clearcoatTexture, ...): PropertyChannel::uv_set names the set it transforms.
  kUvOffset,
  kUvRotation,  //   .../rotation (radians)
  kUvScale,     //   .../scale
  // /nodes/N/extensions/KHR_node_visibility/visible: a key other than 0 shows node N and its
  // descendants, 0 hides them (a step: the value holds from its key to the next).
  kNodeVisible,
};

std::string_view to_string(AnimatedProperty property);
// Components of the property's value: 1 (a scalar), 2 (a texture transform's offset or scale),
// 3 (a color) or 4 (a base color factor).
int component_count(AnimatedProperty property);
// True for the properties of lights, of cameras, of materials.
bool is_light_property(AnimatedProperty property);
bool is_camera_property(AnimatedProperty property);

// True for a node's property (its visibility).
bool is_node_property(AnimatedProperty property);
// True for the properties of a texture slot's KHR_texture_transform.
bool is_uv_property(AnimatedProperty property);

// One property channel: `curve` (path kTranslation: each component interpolated on its own;
// node unused) drives `property` of node, light, camera or material `index` of the Scene; a texture
// transform's, that of the material's texture coordinate set `uv_set` (Material::uv_transforms).
struct PropertyChannel {
  AnimatedProperty property = AnimatedProperty::kLightIntensity;
  int index = -1;
  int uv_set = -1;
  AnimationChannel curve;
};

}  // namespace afr
