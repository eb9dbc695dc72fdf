#include "shading.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

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
  m->alpha_t = m->alpha + (1.0f - m->alpha) * m->anisotropy * m->anisotropy;
  m->diffuse_weight = (1.0f - m->metallic) * (1.0f - m->transmission);
  const float specular_share = m->specular_share();
  m->diffuse_weight *= 1.0f - specular_share;
  // KHR_materials_diffuse_transmission takes its share of the diffuse part (what neither metal
  // nor glass has taken) from the diffuse reflection and passes it through the surface.
  const float transmitted_share = m->diffuse_transmission * m->diffuse_weight;
  m->diffuse_transmitted = transmitted_share * m->diffuse_transmission_color;
  m->diffuse_transmits = !is_black(m->diffuse_transmitted);
  m->diffuse_weight *= 1.0f - m->diffuse_transmission;
  // An anisotropic surface is a mirror only where its roughness along the anisotropy is too.
  const float r2 = roughness * roughness;
  const float stretched = m->anisotropy > 0.0f
                              ? std::sqrt(r2 + (1.0f - r2) * m->anisotropy * m->anisotropy)
                              : roughness;
  m->is_mirror = !m->is_glass && m->metallic > 0.0f && stretched <= m->mirror_roughness;
  // The metallic part of a mirror sees its surroundings through the reflection ray, so only
  // the rest of it takes ambient light; of glass, only its diffuse part.
  m->ambient = m->ambient_reflectance;
  if (m->is_mirror) m->ambient *= 1.0f - m->metallic;
  if (m->is_glass) {
    m->ambient *= m->diffuse_weight;
  } else if (transmitted_share > 0.0f && !m->specular_glossiness) {
    // The metal keeps reflecting (a mirror's already left to its reflection ray).
    m->ambient *= m->is_mirror ? 1.0f - m->diffuse_transmission : 1.0f - transmitted_share;
  }
  // A metallic-roughness surface reflects ambient light by its base color, whatever its metal;
  // a specular-glossiness one by its diffuse, as its diffuse light, and its F0 (where the color
  // of its metal lies). A surface that transmits diffusely lets the (uniform) ambient light
  // through from behind, by its transmission's color.
  m->ambient_specular = m->diffuse_transmitted;
  if (m->specular_glossiness) {
    m->ambient *= (1.0f - specular_share) * (1.0f - m->diffuse_transmission);
    m->ambient_specular += m->specular_f0;
  }
  m->has_emission = !is_black(m->emissive);
  m->has_ambient = !is_black(m->scene_ambient * (m->ambient + m->ambient_specular));
  m->has_diffuse = m->diffuse_weight > 0.0f && !is_black(m->base);
  m->layered = m->sheen_max > 0.0f || m->clearcoat > 0.0f;
  m->extended = m->layered || m->anisotropy > 0.0f || m->iridescence > 0.0f;
  // A fully rough dielectric is left Lambertian (AFF and NFF materials, glTF's rough
  // plastics), but not a specular-glossiness material, whose F0 may be a metal's.
  m->has_specular = !(roughness >= 1.0f && m->metallic <= 0.0f && !m->specular_glossiness) &&
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

// KHR_materials_sheen's color and alpha from its color and roughness (factor x texel).
void set_sheen(ShadeMaterial* m, const glm::vec3& color, float roughness) {
  m->sheen_color = glm::clamp(color, glm::vec3(0.0f), glm::vec3(1.0f));
  m->sheen_max = std::max(m->sheen_color.r, std::max(m->sheen_color.g, m->sheen_color.b));
  const float r = std::max(glm::clamp(roughness, 0.0f, 1.0f), kMinDirectRoughness);
  m->sheen_alpha = r * r;
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
  const float f0_ior = mat.ior > 0.0f ? ior_to_f0(mat.ior) : 1.0f;
  m.f0_ior = f0_ior;
  m.transmission = glm::clamp(mat.transmission, 0.0f, 1.0f);
  m.transmission_factor = m.transmission;
  m.diffuse_transmission = glm::clamp(mat.diffuse_transmission, 0.0f, 1.0f);
  m.diffuse_transmission_color =
      glm::clamp(mat.diffuse_transmission_color, glm::vec3(0.0f), glm::vec3(1.0f));
  m.is_glass = m.transmission > 0.0f;
  if (m.is_glass) {
    m.transmission_texture = texture_at(mat.transmission_texture, scene);
    m.shadow_transmittance = m.transmission * (1.0f - m.metallic_factor) * m.base;
    m.ior = mat.ior;
    m.f0_dielectric = f0_ior;
    m.is_volume = mat.thickness > 0.0f;
    if (mat.thickness > 0.0f && mat.attenuation_distance > 0.0f &&
        std::isfinite(mat.attenuation_distance)) {
      // A color of 0 absorbs everything over any distance: 1e-6 per attenuation distance.
      const glm::vec3 c = glm::clamp(mat.attenuation_color, glm::vec3(1e-6f), glm::vec3(1.0f));
      m.absorption = -glm::log(c) / mat.attenuation_distance;
      m.has_volume = true;
    }
    if (mat.thickness > 0.0f && mat.dispersion > 0.0f && mat.ior > 0.0f) {
      // (ior - 1) / (2 V_d), dispersion being 20 / V_d.
      m.dispersion_spread = (mat.ior - 1.0f) * 0.025f * mat.dispersion;
    }
  }
  if (mat.has_specular_extension) {
    // KHR_materials_pbrSpecularGlossiness gives F0 itself as the specular color.
    m.specular_glossiness = mat.specular_glossiness;
    if (m.specular_glossiness) m.f0_ior = 1.0f;
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
  if (!is_black(mat.sheen_color)) {
    m.sheen_color_factor = mat.sheen_color;
    m.sheen_roughness_factor = mat.sheen_roughness;
    set_sheen(&m, m.sheen_color_factor, m.sheen_roughness_factor);
    // The albedo table's integration (a fifth of a second) happens here, as the tracer is
    // built, not in the first sample that meets the sheen.
    sheen_albedo(m.sheen_alpha, 1.0f);
    m.sheen_color_texture = texture_at(mat.sheen_color_texture, scene);
    if (mat.sheen_roughness > 0.0f) {
      m.sheen_roughness_texture = texture_at(mat.sheen_roughness_texture, scene);
    }
  }
  if (mat.anisotropy > 0.0f) {
    m.anisotropy = m.anisotropy_factor = std::min(mat.anisotropy, 1.0f);
    m.anisotropy_rotation =
        glm::vec2(std::cos(mat.anisotropy_rotation), std::sin(mat.anisotropy_rotation));
    m.anisotropy_texture = texture_at(mat.anisotropy_texture, scene);
  }
  if (mat.iridescence > 0.0f) {
    m.iridescence = m.iridescence_factor = std::min(mat.iridescence, 1.0f);
    m.iridescence_ior = mat.iridescence_ior;
    m.iridescence_thickness_min = mat.iridescence_thickness_min;
    m.iridescence_thickness_max = m.iridescence_thickness = mat.iridescence_thickness_max;
    m.iridescence_texture = texture_at(mat.iridescence_texture, scene);
    m.iridescence_thickness_texture = texture_at(mat.iridescence_thickness_texture, scene);
  }
  if (m.specular_glossiness && mat.roughness < 1.0f) {
    m.glossiness_texture = texture_at(mat.glossiness_texture, scene);
  }
  // A factor of 0, or a black color, the textures multiply to nothing.
  if (m.diffuse_transmission > 0.0f && !is_black(m.diffuse_transmission_color)) {
    m.diffuse_transmission_texture = texture_at(mat.diffuse_transmission_texture, scene);
    m.diffuse_transmission_color_texture =
        texture_at(mat.diffuse_transmission_color_texture, scene);
  }
  m.varies = m.anisotropy_texture || m.metallic_roughness || m.emissive_texture || m.occlusion ||
             m.transmission_texture || m.specular_texture || m.specular_color_texture ||
             m.clearcoat_texture || m.clearcoat_roughness_texture || m.sheen_color_texture ||
             m.sheen_roughness_texture || m.glossiness_texture || m.iridescence_texture ||
             m.iridescence_thickness_texture || m.diffuse_transmission_texture ||
             m.diffuse_transmission_color_texture;
  m.needs_layers = m.clearcoat > 0.0f || m.anisotropy_factor > 0.0f;
  derive(&m, m.metallic_factor, m.roughness_factor);
  // A shadow ray crossing a surface that transmits diffusely keeps what it lets through, as if
  // the light went on straight (filter shadows): the light beyond a lamp's paper shade is the
  // lamp's dimmed by the shade, where it would be the shade's glow, scattered over the shade.
  m.shadow_transmittance =
      glm::clamp(m.shadow_transmittance + m.diffuse_transmitted, glm::vec3(0.0f), glm::vec3(1.0f));
  if (mat.unlit) {
    // Only the base color (and alpha) is left: prepare_local shows it and stops there, and
    // nothing bounces off, passes through or varies the surface.
    m.unlit = true;
    m.is_mirror = m.is_glass = m.varies = m.clearcoat_mirror = m.diffuse_transmits = false;
    m.clearcoat = m.sheen_max = m.anisotropy = m.iridescence = 0.0f;
    m.layered = m.extended = m.needs_layers = false;
    m.normal_map = m.clearcoat_normal_map = nullptr;
    m.shadow_transmittance = glm::vec3(0.0f);
  }
  return m;
}

void vary(ShadeMaterial* m, const Texels& t) {
  m->emissive = m->emissive_factor * t.emissive;
  if (m->transmission_texture) {
    m->transmission = glm::clamp(m->transmission_factor * t.transmission.r, 0.0f, 1.0f);
  }
  if (m->specular_texture || m->specular_color_texture) {
    set_specular(m, m->specular_factor * t.specular.r, m->specular_color_factor * t.specular_color);
  }
  if (m->clearcoat_texture || m->clearcoat_roughness_texture) {
    set_clearcoat(m, m->clearcoat_factor * t.clearcoat.r,
                  m->clearcoat_roughness_factor * t.clearcoat_roughness.g);
  }
  if (m->sheen_color_texture || m->sheen_roughness_texture) {
    set_sheen(m, m->sheen_color_factor * t.sheen_color,
              m->sheen_roughness_factor * t.sheen_roughness.r);
  }
  if (m->anisotropy_texture) m->anisotropy = m->anisotropy_factor * t.anisotropy.b;
  if (m->iridescence_texture) m->iridescence = m->iridescence_factor * t.iridescence.r;
  if (m->iridescence_thickness_texture) {
    m->iridescence_thickness =
        m->iridescence_thickness_min +
        (m->iridescence_thickness_max - m->iridescence_thickness_min) * t.iridescence_thickness.g;
  }
  // m is the point's own copy, its diffuse transmission still the factors.
  if (m->diffuse_transmission_texture) m->diffuse_transmission *= t.diffuse_transmission.r;
  if (m->diffuse_transmission_color_texture) {
    m->diffuse_transmission_color *= t.diffuse_transmission_color;
  }
  const float roughness = m->specular_glossiness
                              ? 1.0f - (1.0f - m->roughness_factor) * t.glossiness.r
                              : m->roughness_factor * t.metallic_roughness.g;
  derive(m, m->metallic_factor * t.metallic_roughness.b, roughness);
  const float o = 1.0f + m->occlusion_strength * (t.occlusion.r - 1.0f);
  if (o != 1.0f) {
    m->ambient *= o;
    m->ambient_specular *= o;
    m->has_ambient = !is_black(m->scene_ambient * (m->ambient + m->ambient_specular));
  }
}

namespace {

// The extension's fit of the Charlie lobe's lambda at cosine x, for alpha a: five coefficients
// blended between its fits at alpha 0 and 1 by (1 - a)^2.
float sheen_lambda_fit(float x, float a) {
  const float t = (1.0f - a) * (1.0f - a);
  const auto mix = [t](float at1, float at0) { return at1 + (at0 - at1) * t; };
  const float ca = mix(21.5473f, 25.3245f), cb = mix(3.82987f, 3.32435f);
  const float cc = mix(0.19823f, 0.16801f), cd = mix(-1.97760f, -1.27393f);
  const float ce = mix(-4.32054f, -4.85967f);
  return ca / (1.0f + cb * std::pow(x, cc)) + cd * x + ce;
}

float sheen_lambda(float cosine, float a) {
  if (cosine < 0.5f) return std::exp(sheen_lambda_fit(cosine, a));
  return std::exp(2.0f * sheen_lambda_fit(0.5f, a) - sheen_lambda_fit(1.0f - cosine, a));
}

// sheen_albedo's table: E at n.v = i / (kCosines - 1) and roughness (the square root of alpha)
// j / (kRoughnesses - 1), clamped as set_sheen clamps it.
constexpr int kCosines = 32, kRoughnesses = 32;
using AlbedoTable = std::array<float, size_t(kCosines) * kRoughnesses>;

// E(n.v, alpha) = the integral over the hemisphere of D V n.l for a white sheen: a midpoint rule
// in n.l (which the integrand's n.l factor makes smooth) and in the azimuth from the viewer's
// plane (0 to pi, doubled by symmetry).
AlbedoTable integrate_sheen_albedo() {
  constexpr int kSteps = 64;
  AlbedoTable table{};
  for (int j = 0; j < kRoughnesses; ++j) {
    const float r = std::max(float(j) / (kRoughnesses - 1), kMinDirectRoughness);
    const float a = r * r;
    for (int i = 0; i < kCosines; ++i) {
      const float nv = std::max(float(i) / (kCosines - 1), 1e-3f);
      const glm::vec3 v(std::sqrt(1.0f - nv * nv), 0.0f, nv);
      double sum = 0.0;
      for (int p = 0; p < kSteps; ++p) {
        const float nl = (p + 0.5f) / kSteps;
        const float sl = std::sqrt(1.0f - nl * nl);
        for (int q = 0; q < kSteps; ++q) {
          const float phi = kPi * (q + 0.5f) / kSteps;
          const glm::vec3 l(sl * std::cos(phi), sl * std::sin(phi), nl);
          const glm::vec3 h = glm::normalize(v + l);
          sum += double(charlie_d(a, h.z) * sheen_visibility(a, nv, nl) * nl);
        }
      }
      // d(omega) = d(n.l) d(phi), over phi in (0, 2 pi).
      table[size_t(j) * kCosines + size_t(i)] =
          float(sum * (1.0 / kSteps) * (2.0 * double(kPi) / kSteps));
    }
  }
  return table;
}

}  // namespace

float sheen_visibility(float a, float n_dot_v, float n_dot_l) {
  const float v = 1.0f / ((1.0f + sheen_lambda(n_dot_v, a) + sheen_lambda(n_dot_l, a)) *
                          (4.0f * n_dot_v * n_dot_l));
  return glm::clamp(v, 0.0f, 1.0f);
}

float sheen_albedo(float a, float n_dot_v) {
  static const AlbedoTable table = integrate_sheen_albedo();
  const float x = glm::clamp(n_dot_v, 0.0f, 1.0f) * (kCosines - 1);
  const float y = std::sqrt(glm::clamp(a, 0.0f, 1.0f)) * (kRoughnesses - 1);
  const int i = std::min(int(x), kCosines - 2), j = std::min(int(y), kRoughnesses - 2);
  const float fx = x - float(i), fy = y - float(j);
  const float* row0 = &table[size_t(j) * kCosines];
  const float* row1 = row0 + kCosines;
  const float e0 = row0[i] + (row0[i + 1] - row0[i]) * fx;
  const float e1 = row1[i] + (row1[i + 1] - row1[i]) * fx;
  return glm::clamp(e0 + (e1 - e0) * fy, 0.0f, 1.0f);
}

glm::vec3 extended_brdf_cos(const ShadeMaterial& m, const glm::vec3& diffuse, const glm::vec3& f0,
                            const glm::vec3& n, const glm::vec3& v, const glm::vec3& l,
                            float n_dot_v, float n_dot_l, const LayerFrame* layers,
                            float beneath_sheen) {
  glm::vec3 h = v + l;
  const float h_len2 = glm::dot(h, h);
  if (!(h_len2 > 1e-12f)) return diffuse * (n_dot_l / kPi);
  h *= 1.0f / std::sqrt(h_len2);
  const float n_dot_h = glm::max(glm::dot(n, h), 0.0f);
  glm::vec3 f = diffuse * (1.0f / kPi);
  if (m.has_specular) {
    const float v_dot_h = glm::max(glm::dot(v, h), 0.0f);
    float d_vis;
    if (m.anisotropy > 0.0f && layers != nullptr && layers->aniso_t != glm::vec3(0.0f)) {
      const glm::vec3& t = layers->aniso_t;
      const glm::vec3& b = layers->aniso_b;
      d_vis = ggx_anisotropic_d_vis(m.alpha_t, m.alpha,
                                    glm::vec3(glm::dot(t, h), glm::dot(b, h), n_dot_h),
                                    glm::vec3(glm::dot(t, v), glm::dot(b, v), n_dot_v),
                                    glm::vec3(glm::dot(t, l), glm::dot(b, l), n_dot_l));
    } else {
      d_vis = ggx_d_vis(m.alpha, n_dot_h, n_dot_v, n_dot_l);
    }
    // The film at n.v, not v.h, as the extension's sample viewer evaluates it.
    f += with_film(m, fresnel_schlick(f0, v_dot_h, fresnel_f90(m)), n_dot_v, f0) * d_vis;
  }
  if (m.sheen_max > 0.0f) {
    // The sheen takes, from what lies beneath it, the larger of its albedos toward the viewer and
    // toward the light (the extension's min of the two scalings).
    const float keep =
        std::min(beneath_sheen, 1.0f - m.sheen_max * sheen_albedo(m.sheen_alpha, n_dot_l));
    f = f * keep + m.sheen_color * (charlie_d(m.sheen_alpha, n_dot_h) *
                                    sheen_visibility(m.sheen_alpha, n_dot_v, n_dot_l));
  }
  glm::vec3 result = f * n_dot_l;
  if (m.clearcoat > 0.0f && layers != nullptr) {
    const glm::vec3& coat_n = layers->coat_n;
    const float c_v = glm::max(glm::dot(coat_n, v), 1e-4f);
    const float c_l = glm::dot(coat_n, l);
    const float w = m.clearcoat * coat_fresnel(c_v);
    result *= 1.0f - w;
    if (c_l > 0.0f) {
      const float c_h = glm::max(glm::dot(coat_n, h), 0.0f);
      result += glm::vec3(w * ggx_d_vis(m.clearcoat_alpha, c_h, c_v, c_l) * c_l);
    }
  }
  return result;
}

namespace {

// iridescent_fresnel's helpers, as the extension defines them.
// The CIE observer's sensitivity in Fourier space at optical path difference opd (nanometres)
// with phase shift `shift` per channel, as linear sRGB: the extension's Gaussian fit of X, Y
// and Z (X with a second lobe), through the XYZ-to-Rec.709 matrix.
glm::dvec3 eval_sensitivity(double opd, const glm::dvec3& shift) {
  const double phase = 2.0 * std::numbers::pi * opd * 1.0e-9;
  const glm::dvec3 val(5.4856e-13, 4.4201e-13, 5.2481e-13);
  const glm::dvec3 pos(1.6810e+06, 1.7953e+06, 2.2084e+06);
  const glm::dvec3 var(4.3278e+09, 9.3046e+09, 6.6121e+09);
  glm::dvec3 xyz = val * glm::sqrt(2.0 * std::numbers::pi * var) * glm::cos(pos * phase + shift) *
                   glm::exp(-(phase * phase) * var);
  xyz.x += 9.7470e-14 * std::sqrt(2.0 * std::numbers::pi * 4.5282e+09) *
           std::cos(2.2399e+06 * phase + shift.x) * std::exp(-4.5282e+09 * phase * phase);
  xyz /= 1.0685e-7;
  const glm::dmat3 xyz_to_rec709(3.2404542, -0.9692660, 0.0556434,   // column x
                                 -1.5371385, 1.8760108, -0.2040259,  // column y
                                 -0.4985314, 0.0415560, 1.0572252);  // column z
  return xyz_to_rec709 * xyz;
}

}  // namespace

glm::vec3 iridescent_fresnel(float film_ior, float thickness_nm, float cos_theta,
                             const glm::vec3& base_f0) {
  constexpr float kOutside = 1.0f;  // air
  cos_theta = glm::clamp(cos_theta, 0.0f, 1.0f);
  // The film's ior goes to the outside's as its thickness goes to 0 (no film).
  const float t = glm::clamp(thickness_nm / 0.03f, 0.0f, 1.0f);
  const float ior = kOutside + (film_ior - kOutside) * (t * t * (3.0f - 2.0f * t));
  // Snell into the film; total internal reflection reflects everything.
  const float sin2_film = (kOutside / ior) * (kOutside / ior) * (1.0f - cos_theta * cos_theta);
  const float cos2_film = 1.0f - sin2_film;
  if (cos2_film < 0.0f) return glm::vec3(1.0f);
  const float cos_film = std::sqrt(cos2_film);

  // The first interface (outside to film), and its phase shifts.
  const float r12 = fresnel_schlick(glm::vec3(ior_to_f0(ior, kOutside)), cos_theta).x;
  const float t121 = 1.0f - r12;
  const double phi12 = ior < kOutside ? std::numbers::pi : 0.0;
  const double phi21 = std::numbers::pi - phi12;
  // The second (film to base): the base's ior from its F0, guarded below 1.
  glm::vec3 f0_23(0.0f);
  glm::dvec3 phi23(0.0);
  for (int c = 0; c < 3; ++c) {
    const float s = std::sqrt(glm::clamp(base_f0[c], 0.0f, 0.9999f));
    const float base_ior = (1.0f + s) / (1.0f - s);
    f0_23[c] = ior_to_f0(base_ior, ior);
    if (base_ior < ior) phi23[c] = std::numbers::pi;
  }
  const glm::vec3 r23 = fresnel_schlick(f0_23, cos_film);
  // The optical path difference of one round trip through the film, and the phase.
  const double opd = 2.0 * double(ior) * double(thickness_nm) * double(cos_film);
  const glm::dvec3 phi = glm::dvec3(phi21) + phi23;
  // The series of reflections: its mean (m = 0) and its first two orders.
  const glm::dvec3 r123 = glm::clamp(glm::dvec3(r12 * r23), 1e-5, 0.9999);
  const glm::dvec3 root = glm::sqrt(r123);
  const glm::dvec3 rs = double(t121) * double(t121) * glm::dvec3(r23) / (1.0 - r123);
  glm::dvec3 reflectance = double(r12) + rs;
  glm::dvec3 cm = rs - double(t121);
  for (int m = 1; m <= 2; ++m) {
    cm *= root;
    reflectance += cm * 2.0 * eval_sensitivity(m * opd, double(m) * phi);
  }
  return glm::vec3(glm::max(reflectance, glm::dvec3(0.0)));
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
  r.inv_range = r.range > 0.0f ? 1.0f / r.range : 0.0f;
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
