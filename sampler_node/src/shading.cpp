#include "shading.h"

#include <algorithm>

namespace afr::shading {

namespace {

// Exactly zero. NaN is not black: a broken value must reach the sanitiser and be counted
// there, not vanish here.
bool is_black(const glm::vec3& c) { return c.r == 0.0f && c.g == 0.0f && c.b == 0.0f; }

// The fields that follow from metallic and roughness (the factors, or the factors times a
// metallic-roughness texel), given the material's other fields.
void derive(ShadeMaterial* m, float metallic, float roughness) {
  m->metallic = glm::clamp(metallic, 0.0f, 1.0f);
  roughness = glm::clamp(roughness, 0.0f, 1.0f);
  const float r = std::max(roughness, kMinDirectRoughness);
  m->alpha = r * r;
  m->diffuse_weight = (1.0f - m->metallic) * (1.0f - m->transmission);
  m->is_mirror = !m->is_glass && m->metallic > 0.0f && roughness <= m->mirror_roughness;
  // The metallic part of a mirror sees its surroundings through the reflection ray, so only
  // the rest of it takes ambient light; of glass, only its diffuse part.
  m->ambient = m->ambient_reflectance;
  if (m->is_mirror) m->ambient *= 1.0f - m->metallic;
  if (m->is_glass) m->ambient *= m->diffuse_weight;
  m->has_emission = !is_black(m->emissive);
  m->has_ambient = !is_black(m->scene_ambient * m->ambient);
  m->has_diffuse = m->diffuse_weight > 0.0f && !is_black(m->base);
  m->has_specular = !(roughness >= 1.0f && m->metallic <= 0.0f) &&
                    !(m->metallic <= 0.0f && m->specular_f90 <= 0.0f && is_black(m->specular_f0));
}

// KHR_materials_specular's F0 and F90 from its strength and color (factor x texel).
void set_specular(ShadeMaterial* m, float specular, const glm::vec3& color) {
  const float strength = glm::clamp(specular, 0.0f, 1.0f);
  m->specular_f0 =
      glm::min(m->f0_ior * glm::max(color, glm::vec3(0.0f)), glm::vec3(1.0f)) * strength;
  m->specular_f90 = strength;
}

// KHR_materials_clearcoat's weight and GGX alpha from its factor x texel and roughness.
void set_clearcoat(ShadeMaterial* m, float clearcoat, float roughness) {
  roughness = glm::clamp(roughness, 0.0f, 1.0f);
  const float r = std::max(roughness, kMinDirectRoughness);
  m->clearcoat = glm::clamp(clearcoat, 0.0f, 1.0f);
  m->clearcoat_alpha = r * r;
  m->clearcoat_mirror = m->clearcoat > 0.0f && roughness <= m->mirror_roughness;
}

// The scene's texture `index`, or null when there is none (or it is empty).
const Texture* texture_at(int index, const Scene& scene) {
  if (index < 0 || size_t(index) >= scene.textures.size()) return nullptr;
  const Texture& t = scene.textures[size_t(index)];
  return t.whole() ? &t : nullptr;
}

}  // namespace

ShadeMaterial make_shade_material(const Material* material, const Scene& scene,
                                  float mirror_roughness) {
  const Material defaults;  // glTF's default material: white, metallic 1, roughness 1
  const Material& mat = material ? *material : defaults;
  ShadeMaterial m;
  m.base = glm::vec3(mat.base_color_factor);
  m.ambient_reflectance = mat.ambient ? *mat.ambient : m.base;
  m.scene_ambient = scene.ambient;
  m.mirror_roughness = mirror_roughness;
  m.emissive_factor = mat.emissive;
  m.emissive = mat.emissive;
  m.texture = texture_at(mat.base_color_texture, scene);
  m.metallic_roughness = texture_at(mat.metallic_roughness_texture, scene);
  // An emissive texture only matters where the factor it multiplies is not black.
  if (!is_black(mat.emissive)) m.emissive_texture = texture_at(mat.emissive_texture, scene);
  m.occlusion = mat.occlusion_strength > 0.0f ? texture_at(mat.occlusion_texture, scene) : nullptr;
  m.occlusion_strength = glm::clamp(mat.occlusion_strength, 0.0f, 1.0f);
  m.normal_map = texture_at(mat.normal_texture, scene);
  m.normal_scale = mat.normal_scale;
  m.metallic_factor = glm::clamp(mat.metallic, 0.0f, 1.0f);
  m.roughness_factor = glm::clamp(mat.roughness, 0.0f, 1.0f);
  m.double_sided = mat.double_sided;
  if (mat.alpha_mode != Material::AlphaMode::kOpaque) {
    m.opacity_factor = mat.base_color_factor.a;
    if (m.texture && (!m.texture->alpha.empty() || m.texture->coded_alpha)) {
      m.opacity_texture = m.texture;
    }
    m.blended = mat.alpha_mode == Material::AlphaMode::kBlend;
    // BLEND: the filters matter wherever the opacity can be below 1.
    m.opacity_cutoff = m.blended ? 1.0f : mat.alpha_cutoff;
    // Without a texture's alpha the factor alone decides: MASK the same everywhere, BLEND
    // everywhere only at 1.
    m.masked = m.opacity_texture || !(m.opacity_factor >= m.opacity_cutoff);
    m.alpha_tested = true;
  }
  // Normal-incidence Fresnel of a dielectric of this ior (KHR_materials_ior: ior 0 means F = 1),
  // for glass and KHR_materials_specular.
  const float r = (mat.ior - 1.0f) / (mat.ior + 1.0f);
  const float f0_ior = mat.ior > 0.0f ? r * r : 1.0f;
  m.f0_ior = f0_ior;
  m.transmission = glm::clamp(mat.transmission, 0.0f, 1.0f);
  m.transmission_factor = m.transmission;
  m.is_glass = m.transmission > 0.0f;
  if (m.is_glass) {
    m.transmission_texture = texture_at(mat.transmission_texture, scene);
    m.shadow_transmittance = glm::clamp(m.transmission * (1.0f - m.metallic_factor) * m.base,
                                        glm::vec3(0.0f), glm::vec3(1.0f));
    m.ior = mat.ior;
    m.f0_dielectric = f0_ior;
    if (mat.thickness > 0.0f && mat.attenuation_distance > 0.0f &&
        std::isfinite(mat.attenuation_distance)) {
      // A color of 0 absorbs everything over any distance: 1e-6 per attenuation distance.
      const glm::vec3 c = glm::clamp(mat.attenuation_color, glm::vec3(1e-6f), glm::vec3(1.0f));
      m.absorption = -glm::log(c) / mat.attenuation_distance;
    }
  }
  if (mat.has_specular_extension) {
    m.specular_factor = mat.specular;
    m.specular_color_factor = mat.specular_color;
    set_specular(&m, m.specular_factor, m.specular_color_factor);
    // A strength of 0, or a black color, the textures multiply to nothing.
    if (mat.specular > 0.0f) {
      m.specular_texture = texture_at(mat.specular_texture, scene);
      if (!is_black(mat.specular_color)) {
        m.specular_color_texture = texture_at(mat.specular_color_texture, scene);
      }
    }
  }
  if (mat.clearcoat > 0.0f) {
    m.clearcoat_factor = mat.clearcoat;
    m.clearcoat_roughness_factor = mat.clearcoat_roughness;
    set_clearcoat(&m, m.clearcoat_factor, m.clearcoat_roughness_factor);
    m.clearcoat_texture = texture_at(mat.clearcoat_texture, scene);
    if (mat.clearcoat_roughness > 0.0f) {
      m.clearcoat_roughness_texture = texture_at(mat.clearcoat_roughness_texture, scene);
    }
    m.clearcoat_normal_map = texture_at(mat.clearcoat_normal_texture, scene);
    m.clearcoat_normal_scale = mat.clearcoat_normal_scale;
  }
  m.varies = m.metallic_roughness || m.emissive_texture || m.occlusion || m.transmission_texture ||
             m.specular_texture || m.specular_color_texture || m.clearcoat_texture ||
             m.clearcoat_roughness_texture;
  derive(&m, m.metallic_factor, m.roughness_factor);
  if (mat.unlit) {
    // Only the base color (and alpha) is left: prepare_local shows it and stops there, and
    // nothing bounces off, passes through or varies the surface.
    m.unlit = true;
    m.is_mirror = m.is_glass = m.varies = m.clearcoat_mirror = false;
    m.clearcoat = 0.0f;
    m.normal_map = m.clearcoat_normal_map = nullptr;
    m.shadow_transmittance = glm::vec3(0.0f);
  }
  return m;
}

void vary(ShadeMaterial* m, const Texels& t) {
  m->emissive = m->emissive_factor * t.emissive;
  if (m->transmission_texture) {
    m->transmission = glm::clamp(m->transmission_factor * t.transmission, 0.0f, 1.0f);
  }
  if (m->specular_texture || m->specular_color_texture) {
    set_specular(m, m->specular_factor * t.specular, m->specular_color_factor * t.specular_color);
  }
  if (m->clearcoat_texture || m->clearcoat_roughness_texture) {
    set_clearcoat(m, m->clearcoat_factor * t.clearcoat,
                  m->clearcoat_roughness_factor * t.clearcoat_roughness);
  }
  derive(m, m->metallic_factor * t.metallic_roughness.b,
         m->roughness_factor * t.metallic_roughness.g);
  const float o = 1.0f + m->occlusion_strength * (t.occlusion - 1.0f);
  if (o != 1.0f) {
    m->ambient *= o;
    m->has_ambient = !is_black(m->scene_ambient * m->ambient);
  }
}

LightRecord make_light_record(const Light& light, const glm::dmat4& world) {
  LightRecord r;
  r.type = light.type;
  r.radiance = light.color * light.intensity;
  r.position = glm::vec3(world[3]);
  const glm::dvec3 back(world[2]);  // the light shines along its node's -Z
  const double len = glm::length(back);
  r.direction = len > 0.0 ? glm::vec3(-back / len) : glm::vec3(0.0f, 0.0f, -1.0f);
  r.range = light.range > 0.0f ? light.range : 0.0f;
  r.inv_range4 = r.range > 0.0f ? 1.0f / (r.range * r.range * r.range * r.range) : 0.0f;
  r.inverse_square = light.inverse_square_falloff;
  if (light.type == Light::Type::kSpot) {
    const float cos_outer = std::cos(light.outer_cone_angle);
    const float cos_inner = std::cos(light.inner_cone_angle);
    r.spot_scale = 1.0f / std::max(0.001f, cos_inner - cos_outer);
    r.spot_offset = -cos_outer * r.spot_scale;
  }
  return r;
}

}  // namespace afr::shading
