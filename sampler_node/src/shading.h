// The shading model of afr's tracer, private to afr_sampler: material and light records
// prepared once from a Scene (so the hot path branches on flags instead of re-deriving them),
// and the local reflection model (emission, ambient, Lambert + GGX from punctual lights, the
// Fresnel weight of mirror reflection and of glass). Ray casting itself is in tracer*.cpp.
//
// Conventions (those of the glTF 2.0 specification and the Khronos sample viewer):
// - a punctual light of intensity I and color c gives irradiance c I / d^2 (inverse-square; a
//   light with inverse_square_falloff = false gives c I at every distance), times the smooth
//   range window of KHR_lights_punctual and, for spots, the cone falloff;
// - BRDF = diffuse / pi + GGX (Trowbridge-Reitz D, height-correlated Smith visibility, Schlick
//   Fresnel), diffuse = base (1 - metallic) (1 - transmission), F0 = mix(0.04, base, metallic);
//   with KHR_materials_anisotropy the GGX lobe stretched along a direction of the surface; with
//   KHR_materials_sheen a Charlie lobe over it, which takes max(sheen color) x E(n.v) (its own
//   directional albedo) from the BRDF beneath; with KHR_materials_clearcoat a GGX coat over
//   both; with KHR_materials_iridescence a thin film's reflectance mixed into the Fresnel term
//   (extended_brdf_cos); with KHR_materials_pbrSpecularGlossiness F0 given, metallic 0;
// - base = base_color_factor x base-color texture x COLOR_0 (interpolated); the ambient
//   reflectance (Material::ambient, else the base color factor) is multiplied by the texture
//   and the vertex colors too, so they show in ambient light.
#pragma once

#include <afr/common/math.h>
#include <afr/common/scene.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace afr::shading {

inline constexpr float kPi = 3.14159265358979323846f;
// Below this roughness the GGX lobe of a point light would be a near-delta spike (fireflies);
// mirror reflection carries the sharp part instead.
inline constexpr float kMinDirectRoughness = 0.1f;

// An animated KHR_texture_transform (Material::UvTransform) as a lookup applies it: uv ->
// linear uv + offset.
struct UvAffine {
  glm::mat2 linear{1.0f};
  glm::vec2 offset{0.0f};
  explicit UvAffine(const Material::UvTransform& t)
      : linear(glm::mat2(glm::dmat2(t.matrix()))), offset(glm::vec2(t.offset)) {}
  glm::vec2 operator()(glm::vec2 uv) const { return linear * uv + offset; }
};

// What the shader needs of one Material, with the work it implies decided once. A material
// whose textures vary it over a surface (`varies`: metallic-roughness, emissive, occlusion, or
// an extension's transmission, specular, clearcoat, sheen, anisotropy, glossiness or
// iridescence texture) is decided
// again at each shading point (vary()), from the factors kept here.
struct ShadeMaterial {
  glm::vec3 base{1.0f};     // base color factor (rgb)
  glm::vec3 ambient{1.0f};  // reflectance of ambient light: ambient_reflectance, less below
  // Added to the ambient reflectance after the base-color texel multiplies it: a
  // specular-glossiness material's F0 (its metal's color), and diffuse_transmitted (the ambient
  // light from behind a surface that transmits diffusely); 0 for others.
  glm::vec3 ambient_specular{0.0f};
  glm::vec3 emissive{0.0f};
  const Texture* texture = nullptr;  // base-color texture, or null
  // Textures that vary the material over its surface (null: none): metallic-roughness (green
  // roughness, blue metallic), emissive (a color), occlusion (red).
  const Texture* metallic_roughness = nullptr;
  const Texture* emissive_texture = nullptr;
  const Texture* occlusion = nullptr;
  float occlusion_strength = 1.0f;
  // The extensions' (null: none, or a factor of 0 that they could not change): transmission
  // (red), specular strength (the image's alpha, held in red), specular color, clearcoat (red),
  // clearcoat roughness (green).
  const Texture* transmission_texture = nullptr;
  const Texture* specular_texture = nullptr;
  const Texture* specular_color_texture = nullptr;
  const Texture* clearcoat_texture = nullptr;
  const Texture* clearcoat_roughness_texture = nullptr;
  const Texture* sheen_color_texture = nullptr;      // sRGB color
  const Texture* sheen_roughness_texture = nullptr;  // the image's alpha, held in red
  // KHR_materials_pbrSpecularGlossiness's glossiness (the image's alpha, held in red).
  const Texture* glossiness_texture = nullptr;
  // KHR_materials_iridescence's weight (red) and film thickness (green).
  const Texture* iridescence_texture = nullptr;
  const Texture* iridescence_thickness_texture = nullptr;
  // KHR_materials_diffuse_transmission's strength (the image's alpha, held in red) and color.
  const Texture* diffuse_transmission_texture = nullptr;
  const Texture* diffuse_transmission_color_texture = nullptr;
  bool varies = false;  // one of the textures above is set
  // The normal texture (tangent space, linear data; null: none) and its scale: it bends the
  // shading normal (Tracer::Impl::make_surface), not the material.
  const Texture* normal_map = nullptr;
  float normal_scale = 1.0f;
  // The clear coat's own normal texture and scale (null: the coat lies on the interpolated
  // normal, unbent by normal_map).
  const Texture* clearcoat_normal_map = nullptr;
  float clearcoat_normal_scale = 1.0f;
  // The factors the textures multiply, and what the derived fields need of the scene.
  float metallic_factor = 1.0f;
  float roughness_factor = 1.0f;
  glm::vec3 emissive_factor{0.0f};
  float transmission_factor = 0.0f;
  float specular_factor = 1.0f;
  glm::vec3 specular_color_factor{1.0f};
  float f0_ior = 0.04f;  // ((ior - 1) / (ior + 1))^2, 1 for ior 0
  float clearcoat_factor = 0.0f;
  float clearcoat_roughness_factor = 0.0f;
  glm::vec3 sheen_color_factor{0.0f};
  float sheen_roughness_factor = 0.0f;
  // KHR_materials_pbrSpecularGlossiness (Material::specular_glossiness): F0 is the specular
  // color, the roughness 1 - (1 - roughness_factor) x the glossiness texel, and the diffuse
  // weight is lowered by max(F0).
  bool specular_glossiness = false;
  glm::vec3 ambient_reflectance{1.0f};  // Material::ambient, else the base color factor
  glm::vec3 scene_ambient{0.0f};
  float mirror_roughness = 0.0f;  // TracerOptions::mirror_roughness
  float metallic = 1.0f;
  // Weight of the base color in the diffuse lobe: (1 - metallic) (1 - transmission)
  // (1 - diffuse_transmission).
  float diffuse_weight = 0.0f;
  // KHR_materials_diffuse_transmission: its factor and color (Material::diffuse_transmission),
  // and what derive() makes of them: the Lambertian transmission's color, diffuse_transmission x
  // diffuse_transmission_color x (1 - metallic) (1 - transmission), which light from the side
  // away from the viewer brings through the surface (over pi, times |n.l|); diffuse_transmits:
  // it is not black.
  float diffuse_transmission = 0.0f;
  glm::vec3 diffuse_transmission_color{1.0f};
  glm::vec3 diffuse_transmitted{0.0f};
  bool diffuse_transmits = false;
  float alpha = 1.0f;  // GGX alpha = roughness^2 for direct light (roughness clamped)
  // KHR_materials_anisotropy: its strength at this point (0: none), the factor it multiplies,
  // its rotation (cos, sin) and texture (direction in red and green, strength in blue; null:
  // none), and the lobe's alpha along its direction, alpha + (1 - alpha) strength^2 (alpha
  // across it).
  float anisotropy = 0.0f;
  float anisotropy_factor = 0.0f;
  glm::vec2 anisotropy_rotation{1.0f, 0.0f};
  const Texture* anisotropy_texture = nullptr;
  float alpha_t = 1.0f;
  // KHR_materials_iridescence: the film's weight at this point (0: none; the factor x the
  // texel), the factor, its ior, and its thickness in nanometres at this point and its range.
  float iridescence = 0.0f;
  float iridescence_factor = 0.0f;
  float iridescence_ior = 1.3f;
  float iridescence_thickness = 400.0f;
  float iridescence_thickness_min = 100.0f;
  float iridescence_thickness_max = 400.0f;
  // Glass (KHR_materials_transmission, KHR_materials_ior): what tracer_glass.cpp's glass() needs.
  float transmission = 0.0f;
  float ior = 1.5f;
  float f0_dielectric = 0.04f;  // ((ior - 1) / (ior + 1))^2, 1 for ior 0
  // KHR_materials_volume: is_volume, the glass bounds a medium (thickness > 0) that rays enter
  // and leave (tracer_parts.h's Media: media nest, and an interface between two bends light by
  // the ratio of their iors); a thin wall (thickness 0) is no medium. Light inside the medium
  // keeps exp(-absorption x distance) (-ln(attenuation color) / attenuation distance); 0 for
  // none or a thin wall. has_volume: it absorbs (shadow rays then measure the stretches
  // inside: volume_transmittance).
  glm::vec3 absorption{0.0f};
  bool is_volume = false;
  bool has_volume = false;
  // KHR_materials_dispersion in a volume: red refracts with ior - this, green with ior, blue
  // with ior + this, (ior - 1) / (2 V_d) as the extension's method spreads them; 0 for none.
  float dispersion_spread = 0.0f;
  // The non-metallic part's specular reflection at normal and at grazing incidence: 0.04 and 1
  // (glTF's core), or with KHR_materials_specular (Material::specular) F0(ior) x its color x its
  // factor and the factor. Metals reflect their base color and 1 (fresnel_f0, fresnel_f90).
  glm::vec3 specular_f0{0.04f};
  float specular_f90 = 1.0f;
  // KHR_materials_clearcoat: the clear layer's weight (0: none) and its GGX alpha for direct
  // light (roughness clamped as the base's); a layer at or below mirror_roughness also
  // reflects its surroundings (tracer.cpp's mirror_chain). The layer takes clearcoat x
  // coat_fresnel(n.v) of the light, the material beneath the rest.
  float clearcoat = 0.0f;
  float clearcoat_alpha = 1.0f;
  bool clearcoat_mirror = false;
  bool layered = false;  // a sheen or a clear coat lies over the material (derive() decides)
  // Layered, anisotropic or iridescent: shaded by extended_brdf_cos (likewise).
  bool extended = false;
  // The material has a clear coat or anisotropy somewhere, so its points need a LayerFrame.
  bool needs_layers = false;
  // KHR_materials_sheen: the fibres' color (black: no sheen, and nothing else below is read),
  // its largest channel, and the Charlie lobe's alpha (sheen roughness^2, the roughness
  // clamped as the base's).
  glm::vec3 sheen_color{0.0f};
  float sheen_max = 0.0f;
  float sheen_alpha = 1.0f;
  bool double_sided = false;
  bool unlit = false;  // KHR_materials_unlit: the base color as it is, no bounce or maps
  // alphaMode MASK and BLEND (Material::alpha_mode): `masked`: the surface's opacity
  // (opacity_factor x the opacity texture's alpha x COLOR_0's alpha) can be below
  // opacity_cutoff somewhere, so its geometry needs the tracer's filters. MASK cuts the surface
  // away there; BLEND (`blended`, cutoff 1) shows the opacity's share of the surface's light over
  // the rest of what lies behind it (tracer_shadows.cpp, "alphaMode BLEND").
  bool masked = false;
  bool blended = false;
  // alphaMode MASK or BLEND: a primitive's COLOR_0 alpha (Primitive::color_alpha) can cut the
  // surface even where `masked` is false (the tracer decides per geometry).
  bool alpha_tested = false;
  const Texture* opacity_texture = nullptr;  // the base-color texture, where it has alpha
  float opacity_factor = 1.0f;               // the base color factor's alpha
  float opacity_cutoff = 0.5f;
  bool has_emission = false;
  bool has_ambient = false;   // scene ambient x ambient reflectance is not black
  bool has_diffuse = false;   // metallic < 1
  bool has_specular = false;  // not (roughness 1 and metallic 0)
  bool is_mirror = false;     // metallic > 0 and roughness <= TracerOptions::mirror_roughness,
                              // and not glass
  bool is_glass = false;      // transmission > 0: reflects and refracts (Whitted), any roughness
  // What a shadow ray keeps of the light crossing this surface (a filter shadow,
  // tracer_shadows.cpp): glass's transmission x (1 - metallic) x base color factor, plus what
  // KHR_materials_diffuse_transmission passes through (diffuse_transmitted); 0 for every other
  // surface, which blocks. Where textures or vertex colors vary it, tracer_parts.h's
  // GeometryFilter::through takes their values at the hit.
  glm::vec3 shadow_transmittance{0.0f};
  // Shadow rays pass through it, dimmed by shadow_transmittance.
  bool lets_shadow_rays_through() const { return is_glass || diffuse_transmits; }
  // The share of a specular-glossiness material's diffuse light its F0 takes (0 for any other).
  float specular_share() const {
    return specular_glossiness ? std::max(specular_f0.r, std::max(specular_f0.g, specular_f0.b))
                               : 0.0f;
  }
  // Where an animation drives texture transforms (Material::uv_transforms), each texture
  // coordinate set's transform at this time, indexed like the sets (the tracer owns them);
  // null where none is animated.
  const UvAffine* uv_transforms = nullptr;
  // Texture coordinates of set `set` as its slots read them.
  glm::vec2 uv_in_set(uint8_t set, glm::vec2 uv) const {
    return uv_transforms ? uv_transforms[set](uv) : uv;
  }
};

// `material` may be null (the glTF default material). `textures` is the scene's list.
ShadeMaterial make_shade_material(const Material* material, const Scene& scene,
                                  float mirror_roughness);

// The texels of a varying material's textures at one point, as looked up (linear; white for an
// absent texture). vary() reads the channels each slot defines.
struct Texels {
  glm::vec3 metallic_roughness{1.0f};   // green x the roughness factor, blue x the metallic
  glm::vec3 emissive{1.0f};             // x the emissive factor
  glm::vec3 occlusion{1.0f};            // red: moved toward 1 by 1 - strength, x the ambient
  glm::vec3 transmission{1.0f};         // red x the transmission factor
  glm::vec3 specular{1.0f};             // red (the image's alpha) x the specular factor
  glm::vec3 specular_color{1.0f};       // x the specular color factor
  glm::vec3 clearcoat{1.0f};            // red x the clearcoat factor
  glm::vec3 clearcoat_roughness{1.0f};  // green x the clearcoat roughness factor
  glm::vec3 sheen_color{1.0f};          // x the sheen color factor
  glm::vec3 sheen_roughness{1.0f};      // red (the image's alpha) x the sheen roughness factor
  glm::vec3 anisotropy{1.0f};           // blue x the anisotropy strength (red, green: make_surface)
  glm::vec3 glossiness{1.0f};           // red (the image's alpha) x the glossiness (1 - roughness)
  glm::vec3 iridescence{1.0f};          // red x the iridescence factor
  glm::vec3 iridescence_thickness{1.0f};  // green: the thickness from its minimum to its maximum
  glm::vec3 diffuse_transmission{1.0f};   // red (the image's alpha) x the diffuse transmission
  glm::vec3 diffuse_transmission_color{1.0f};  // x the diffuse transmission's color
};

// The material at one point of a surface whose material varies: `m` (as make_shade_material
// made it) with its textures' texels there. Whether the material is glass stays the factor's:
// a transmission texel of 0 leaves glass that only reflects and scatters diffusely there (and
// lets no shadow ray through there: the shadow rays' filter reads the textures itself).
void vary(ShadeMaterial* m, const Texels& texels);

// One punctual light placed in the world at the current time.
struct LightRecord {
  Light::Type type = Light::Type::kPoint;
  glm::vec3 radiance{1.0f};   // color x intensity
  glm::vec3 position{0.0f};   // world (point, spot)
  glm::vec3 direction{0.0f};  // world, unit: where the light shines (its node's -Z)
  float inv_range = 0.0f;     // 1 / range, 0 for an infinite range
  float range = 0.0f;         // 0 = infinite
  float spot_scale = 0.0f;    // KHR_lights_punctual cone: clamp(cos * scale + offset, 0, 1)^2
  float spot_offset = 0.0f;
  bool inverse_square = true;
};

LightRecord make_light_record(const Light& light, const glm::dmat4& world);

// The light arriving at p from one light: direction to the light (unit), distance to it
// (infinity for directional lights) and radiance scale. Returns false when the light cannot
// reach p (beyond its range, outside its cone, or at p itself).
inline bool light_incidence(const LightRecord& light, const glm::vec3& p, glm::vec3* to_light,
                            float* distance, glm::vec3* incident) {
  if (light.type == Light::Type::kDirectional) {
    *to_light = -light.direction;
    *distance = INFINITY;
    *incident = light.radiance;
    return true;
  }
  const glm::vec3 d = light.position - p;
  const float d2 = glm::dot(d, d);
  if (!(d2 >= std::numeric_limits<float>::min())) return false;  // 1 / d2 stays finite
  const float dist = std::sqrt(d2);
  *to_light = d / dist;
  *distance = dist;
  float scale = light.inverse_square ? 1.0f / d2 : 1.0f;
  if (light.range > 0.0f) {
    if (dist >= light.range) return false;
    // KHR_lights_punctual's recommended window, clamp(1 - (d / range)^4, 0, 1) (the Khronos
    // sample viewer's too), with d / range taken first: d^4 or range^4 alone overflows a float
    // for a light some 4e9 units away.
    const float x = dist * light.inv_range;
    scale *= glm::clamp(1.0f - (x * x) * (x * x), 0.0f, 1.0f);
  }
  if (light.type == Light::Type::kSpot) {
    const float cd = -glm::dot(*to_light, light.direction);
    const float a = glm::clamp(cd * light.spot_scale + light.spot_offset, 0.0f, 1.0f);
    if (a <= 0.0f) return false;
    scale *= a * a;
  }
  *incident = light.radiance * scale;
  return true;
}

// The normal-incidence reflectance between media of indices n_t and n_i (outside: 1).
inline float ior_to_f0(float n_t, float n_i = 1.0f) {
  const float r = (n_t - n_i) / (n_t + n_i);
  return r * r;
}

inline glm::vec3 fresnel_schlick(const glm::vec3& f0, float cos_theta, float f90 = 1.0f) {
  const float m = 1.0f - glm::clamp(cos_theta, 0.0f, 1.0f);
  const float m2 = m * m;
  return f0 + (glm::vec3(f90) - f0) * (m2 * m2 * m);
}

// The specular reflection's F0 and F90 at a point of base color `base` (factor x texture).
inline glm::vec3 fresnel_f0(const ShadeMaterial& m, const glm::vec3& base) {
  return glm::mix(m.specular_f0, base, m.metallic);
}
inline float fresnel_f90(const ShadeMaterial& m) {
  return m.specular_f90 + (1.0f - m.specular_f90) * m.metallic;
}

// KHR_materials_iridescence: the reflectance of a thin film of index film_ior and thickness
// `thickness_nm` over a base of normal-incidence reflectance base_f0, in air, seen at cosine
// cos_theta: the extension's evaluation (Belcour and Barla's, the interference of the film's
// first two orders of reflection, integrated against the CIE observer through its Gaussian fit
// and turned into linear sRGB), clamped at 0. A film of thickness 0 vanishes (ior -> 1).
glm::vec3 iridescent_fresnel(float film_ior, float thickness_nm, float cos_theta,
                             const glm::vec3& base_f0);
// A Fresnel term `fresnel` of base reflectance f0 at cosine cos_theta, with m's iridescent film
// mixed in by its weight (unchanged without one).
inline glm::vec3 with_film(const ShadeMaterial& m, const glm::vec3& fresnel, float cos_theta,
                           const glm::vec3& f0) {
  if (!(m.iridescence > 0.0f)) return fresnel;
  return glm::mix(fresnel,
                  iridescent_fresnel(m.iridescence_ior, m.iridescence_thickness, cos_theta, f0),
                  m.iridescence);
}

// The share of the light a clear coat (F0 0.04, glTF's fresnel_coat) reflects at n.v.
inline float coat_fresnel(float n_dot_v) { return fresnel_schlick(glm::vec3(0.04f), n_dot_v).x; }

// GGX's D x visibility for alpha `a` (Smith height-correlated), unit n and half vector h.
inline float ggx_d_vis(float a, float n_dot_h, float n_dot_v, float n_dot_l) {
  const float a2 = a * a;
  const float dd = n_dot_h * n_dot_h * (a2 - 1.0f) + 1.0f;
  const float D = a2 / (kPi * dd * dd);
  const float vis = 0.5f / (n_dot_l * std::sqrt(n_dot_v * n_dot_v * (1.0f - a2) + a2) +
                            n_dot_v * std::sqrt(n_dot_l * n_dot_l * (1.0f - a2) + a2));
  return D * vis;
}

// KHR_materials_sheen's lobe (the extension's "Charlie" sheen): its distribution D at n.h for
// alpha `a`, and its visibility at n.v and n.l (Estevez and Kulla's fitted lambda), each as
// the extension defines them.
inline float charlie_d(float a, float n_dot_h) {
  const float inv = 1.0f / a;
  const float sin2 = std::max(1.0f - n_dot_h * n_dot_h, 0.0f);
  return (2.0f + inv) * std::pow(sin2, 0.5f * inv) / (2.0f * kPi);
}
float sheen_visibility(float a, float n_dot_v, float n_dot_l);

// The directional albedo E of a white sheen lobe of alpha `a` seen at n.v (0 to 1): the share
// of uniform light it reflects, which the material beneath gives up (its albedo scaling,
// 1 - max(sheen color) x E). Integrated once per process over a table of n.v and roughness, and
// read bilinearly.
float sheen_albedo(float a, float n_dot_v);

// The share of light the material beneath a sheen keeps, seen at n.v (1 without sheen).
inline float sheen_scaling(const ShadeMaterial& m, float n_dot_v) {
  return m.sheen_max > 0.0f ? 1.0f - m.sheen_max * sheen_albedo(m.sheen_alpha, n_dot_v) : 1.0f;
}

// KHR_materials_anisotropy's GGX D x height-correlated visibility, with alpha a_t along the
// anisotropy's direction t and a_b along b = n x t (t, b, n unit and orthogonal), as the
// extension defines them; the dot products are those of h, v and l with t, b and n.
inline float ggx_anisotropic_d_vis(float a_t, float a_b, const glm::vec3& h_tbn,
                                   const glm::vec3& v_tbn, const glm::vec3& l_tbn) {
  const glm::vec3 f(a_b * h_tbn.x, a_t * h_tbn.y, a_t * a_b * h_tbn.z);
  const float w = a_t * a_b / glm::dot(f, f);
  const float D = a_t * a_b * w * w / kPi;
  const float view = l_tbn.z * glm::length(glm::vec3(a_t * v_tbn.x, a_b * v_tbn.y, v_tbn.z));
  const float light = v_tbn.z * glm::length(glm::vec3(a_t * l_tbn.x, a_b * l_tbn.y, l_tbn.z));
  return D * glm::clamp(0.5f / (view + light), 0.0f, 1.0f);
}

// Where the layers of a shading point lie, for a material with a clear coat or anisotropy
// (Tracer::Impl::make_surface sets it only for those).
struct LayerFrame {
  glm::vec3 coat_n{0.0f, 0.0f, 1.0f};  // the clear coat's normal (glTF's clearcoatNormal), unit
  // The anisotropy's direction and its bitangent (unit, orthogonal to the shading normal);
  // zero where the point has no tangent frame (isotropic then).
  glm::vec3 aniso_t{0.0f};
  glm::vec3 aniso_b{0.0f};
};

// BRDF x cos(theta_l) for unit n, v (toward the viewer), l (toward the light); n.v and n.l > 0,
// for a material without the extensions' layers or anisotropy (ShadeMaterial::extended false).
inline glm::vec3 brdf_cos(const ShadeMaterial& m, const glm::vec3& diffuse, const glm::vec3& f0,
                          const glm::vec3& n, const glm::vec3& v, const glm::vec3& l, float n_dot_v,
                          float n_dot_l) {
  glm::vec3 f = diffuse * (1.0f / kPi);
  if (m.has_specular) {
    glm::vec3 h = v + l;
    const float h_len2 = glm::dot(h, h);
    if (h_len2 > 1e-12f) {
      h *= 1.0f / std::sqrt(h_len2);
      const float n_dot_h = glm::max(glm::dot(n, h), 0.0f);
      const float v_dot_h = glm::max(glm::dot(v, h), 0.0f);
      f += fresnel_schlick(f0, v_dot_h, fresnel_f90(m)) *
           ggx_d_vis(m.alpha, n_dot_h, n_dot_v, n_dot_l);
    }
  }
  return f * n_dot_l;
}

// brdf_cos for a material with a sheen, a clear coat, anisotropy or iridescence
// (ShadeMaterial::extended), out of line so that the others' shading does not carry it. An
// iridescent film mixes iridescent_fresnel at n.v (not at v.h, as the extension's sample viewer
// evaluates it) into the specular lobe's Fresnel term by its weight. `layers` is the point's
// (null
// where the material has neither a coat nor anisotropy): the specular lobe is anisotropic along
// aniso_t where the material has anisotropy and the point a tangent frame; a sheen takes
// max(sheen color) x E from what lies beneath it (`beneath_sheen`: sheen_scaling(m, n.v), 1
// without sheen); a coat takes clearcoat x F_coat(coat_n.v) of the light, with its own lobe
// and cosine, and the material beneath the rest.
glm::vec3 extended_brdf_cos(const ShadeMaterial& m, const glm::vec3& diffuse, const glm::vec3& f0,
                            const glm::vec3& n, const glm::vec3& v, const glm::vec3& l,
                            float n_dot_v, float n_dot_l, const LayerFrame* layers,
                            float beneath_sheen);

}  // namespace afr::shading
