// The tracer (afr/sampler/tracer.h): a hit's surface (textures, normals, tangent frames), its
// local shading under the lights, the paths through mirrors and blended surfaces, and the
// public Tracer. Tracer::Impl (TracerImpl) and the parts it shares with the other tracer_*.cpp
// files are in tracer_parts.h.
#include <afr/sampler/tracer.h>

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/math.h>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "tracer_parts.h"

namespace afr {

TraceStats& TraceStats::operator+=(const TraceStats& o) {
  primary_rays += o.primary_rays;
  shadow_rays += o.shadow_rays;
  reflection_rays += o.reflection_rays;
  occlusion_rays += o.occlusion_rays;
  sanitized += o.sanitized;
  return *this;
}

}  // namespace afr

namespace afr::tracer_detail {
namespace {

// ---- Texture filtering (ray cones) ----
//
// The level of detail of a texture lookup (docs/scene-model.md, "Texture filtering"): log2 of
// the cone's footprint on the surface in level-0 texels. The footprint is the cone's width
// over the cosine of the incidence (the long axis of its ellipse, so a grazing floor blurs
// rather than aliases), times the texels per unit of length on the triangle: the square root of
// its area in texels over its area in the world. Both areas come as twice the area (cross
// products); 0 for a degenerate triangle or one without uv area (then no filtering).
constexpr float kMinLodCosine = 0.05f;  // at most 20x the cone's width

float texture_lod(const Texture& texture, glm::vec2 t0, glm::vec2 t1, glm::vec2 t2,
                  float world_area2, float cone, float cosine) {
  const glm::vec2 e1 = t1 - t0, e2 = t2 - t0;
  const float texel_area2 =
      std::abs(e1.x * e2.y - e1.y * e2.x) * float(texture.width) * float(texture.height);
  if (!(texel_area2 > 0.0f) || !(world_area2 > 0.0f)) return 0.0f;
  const float footprint =
      cone / std::max(cosine, kMinLodCosine) * std::sqrt(texel_area2 / world_area2);
  const float lod = std::log2(footprint);
  return std::isfinite(lod) ? std::max(lod, 0.0f) : 0.0f;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Queries

HitRef TracerImpl::intersect(const glm::vec3& o, const glm::vec3& d, float tnear) const {
  QueryContext ctx(materials_.data());
  RTCRayHit rh;
  init_ray(&rh.ray, o, d, tnear, INFINITY);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(top_, &ctx.embree, &rh);
  HitRef h;
  h.t = rh.ray.tfar;
  h.u = rh.hit.u;
  h.v = rh.hit.v;
  h.geom = rh.hit.geomID;
  h.prim = rh.hit.primID;
  h.inst = rh.hit.instID[0];
  return h;
}

// The tangent frame (t, bt) at barycentrics (w, u, v) of triangle `tri` of material m, whose
// shading normal is n (unit), for a texture read through coordinates `uvs` (none: no
// coordinates). The frame is the primitive's where it has tangents (GeomRecord::tangents): t
// interpolated and made orthogonal to n, and b = n x t times the tangent's w. Otherwise it is
// the triangle's own: t = dp/du made orthogonal to n, and b = n x t, turned to point against
// dp/dv as glTF's flipped v expects (so a mirrored mapping gets a mirrored b, as MikkTSpace's
// sign gives). `turned`: n is the back of a double-sided surface, whose b stays the front's as
// in the triangle's own frame. False where there is no usable frame (no coordinates or uv area,
// degenerate).
//
// A frame that follows texture coordinates follows them through their animated
// KHR_texture_transform (ShadeMaterial::uv_in_set), as the frame of the same transform written
// in the file follows the coordinates it transforms at load: the triangle's own frame is taken
// from the transformed corners, and generated tangents (GeomRecord::tangent_set) are turned
// with their set's transform: with (u', v') = L (u, v) + offset, dp/du' = dp/du du/du' +
// dp/dv dv/du', the columns of L's inverse mixing the frame's dp/du (t) and dp/dv (-b). The
// file's own TANGENT does not follow a transform.
static bool tangent_frame(const GeomRecord& g, const Instance& inst,
                          const shading::ShadeMaterial& m, const uint32_t* tri,
                          const glm::vec3& bary, const glm::vec3& n, bool turned, SlotCoords uvs,
                          glm::vec3* t_out, glm::vec3* bt_out) {
  glm::vec3& t = *t_out;
  glm::vec3& bt = *bt_out;
  // t = `along_u` made orthogonal to n and unit; false where nothing of it is left.
  const auto orthogonal_t = [&](const glm::vec3& along_u) {
    t = along_u - n * glm::dot(n, along_u);
    const float t_len2 = glm::dot(t, t);
    if (!(t_len2 > 1e-30f) || !std::isfinite(t_len2)) return false;
    t *= 1.0f / std::sqrt(t_len2);
    return true;
  };
  // That t, and bt = n x t pointing against `along_v`.
  const auto orthogonal_frame = [&](const glm::vec3& along_u, const glm::vec3& along_v) {
    if (!orthogonal_t(along_u)) return false;
    bt = glm::cross(n, t);
    if (glm::dot(bt, along_v) > 0.0f) bt = -bt;
    return true;
  };
  if (g.tangents) {
    const glm::vec4& t0 = g.tangents[tri[0]];
    glm::vec3 tangent = bary.x * glm::vec3(t0) + bary.y * glm::vec3(g.tangents[tri[1]]) +
                        bary.z * glm::vec3(g.tangents[tri[2]]);
    float sign = t0.w * (turned ? -1.0f : 1.0f);
    if (inst.transformed) {
      const glm::mat3 linear(inst.world);
      tangent = linear * tangent;
      if (glm::determinant(linear) < 0.0f) sign = -sign;
    }
    if (!orthogonal_t(tangent)) return false;
    bt = glm::cross(n, t) * sign;
    if (g.tangent_set >= 0 && m.uv_transforms) {
      const glm::mat2& linear = m.uv_transforms[g.tangent_set].linear;
      if (linear != glm::mat2(1.0f)) {
        const glm::mat2 inverse = glm::inverse(linear);
        const glm::vec3 along_v = -bt;
        return orthogonal_frame(t * inverse[0][0] + along_v * inverse[0][1],
                                t * inverse[1][0] + along_v * inverse[1][1]);
      }
    }
    return true;
  }
  if (!uvs) return false;
  const glm::vec2 uv0 = m.uv_in_set(uvs.set, uvs.uvs[tri[0]]);
  const glm::vec2 d1 = m.uv_in_set(uvs.set, uvs.uvs[tri[1]]) - uv0;
  const glm::vec2 d2 = m.uv_in_set(uvs.set, uvs.uvs[tri[2]]) - uv0;
  const glm::vec3 e1 = g.positions[tri[1]] - g.positions[tri[0]];
  const glm::vec3 e2 = g.positions[tri[2]] - g.positions[tri[0]];
  const float det = d1.x * d2.y - d2.x * d1.y;
  if (!(std::abs(det) > 1e-20f)) return false;
  glm::vec3 along_u = (e1 * d2.y - e2 * d1.y) / det;  // dp/du
  glm::vec3 along_v = (e2 * d1.x - e1 * d2.x) / det;  // dp/dv
  if (inst.transformed) {
    const glm::mat3 linear(inst.world);
    along_u = linear * along_u;
    along_v = linear * along_v;
  }
  return orthogonal_frame(along_u, along_v);
}

// The shading normal that a normal texture's texel asks for at barycentrics `bary` of triangle
// `tri` of material m, whose shading normal is n (unit), the texture read through coordinates
// `uvs`, in the tangent frame above (n stays where there is none).
static glm::vec3 mapped_normal(const GeomRecord& g, const Instance& inst,
                               const shading::ShadeMaterial& m, const uint32_t* tri,
                               const glm::vec3& bary, const glm::vec3& n, bool turned,
                               SlotCoords uvs, const glm::vec3& texel, float scale) {
  glm::vec3 t, bt;
  if (!tangent_frame(g, inst, m, tri, bary, n, turned, uvs, &t, &bt)) return n;
  const glm::vec3 local = texel * 2.0f - 1.0f;
  const glm::vec3 mapped = t * (local.x * scale) + bt * (local.y * scale) + n * local.z;
  const float len2 = glm::dot(mapped, mapped);
  if (!(len2 > 1e-20f) || !std::isfinite(len2)) return n;
  return mapped * (1.0f / std::sqrt(len2));
}

void TracerImpl::make_surface(const HitRef& hit, const glm::vec3& o, const glm::vec3& d, float cone,
                              float spread, Surface* s) const {
  AFR_DCHECK(hit.inst < instances_.size());
  const Instance& inst = instances_[hit.inst];
  AFR_DCHECK(hit.geom < blas_[size_t(inst.blas)].geoms.size());
  const GeomRecord& g = blas_[size_t(inst.blas)].geoms[hit.geom];
  const uint32_t* tri = g.indices + 3 * size_t(hit.prim);
  const float w = 1.0f - hit.u - hit.v;
  s->p = o + hit.t * d;
  s->instance = &inst;
  s->geom = &g;
  s->triangle = tri;
  s->barycentric = glm::vec3(w, hit.u, hit.v);
  s->node = inst.transformed ? inst.node : g.node;
  const ShadeMaterial& m = materials_[g.material];
  s->material = &m;
  s->opacity = m.blended ? opacity_at(m, g.uvs.base_color, g.color_alpha, tri, hit.u, hit.v) : 1.0f;

  const glm::vec3& p0 = g.positions[tri[0]];
  glm::vec3 ng = glm::cross(g.positions[tri[1]] - p0, g.positions[tri[2]] - p0);
  if (g.flip_winding) ng = -ng;
  glm::vec3 ns(0.0f);
  if (g.normals) ns = w * g.normals[tri[0]] + hit.u * g.normals[tri[1]] + hit.v * g.normals[tri[2]];
  if (inst.transformed) {
    ng = inst.normal_matrix * ng;
    ns = inst.normal_matrix * ns;
  }
  // Degenerate triangles and zero or broken vertex normals fall back to whatever is valid.
  const float ng_len2 = glm::dot(ng, ng);
  const float ns_len2 = glm::dot(ns, ns);
  const float world_area2 = std::sqrt(ng_len2) * (inst.transformed ? inst.area_scale : 1.0f);
  const bool ng_ok = ng_len2 > 1e-30f && std::isfinite(ng_len2);
  const bool ns_ok = ns_len2 > 1e-20f && std::isfinite(ns_len2);
  if (ns_ok) ns *= 1.0f / std::sqrt(ns_len2);
  if (ng_ok)
    ng *= 1.0f / std::sqrt(ng_len2);
  else
    ng = ns_ok ? ns : -d;
  if (!ns_ok) ns = ng;

  s->back_face = false;
  bool turned = false;  // the back of a double-sided surface: its normals turned to face d
  if (glm::dot(ng, d) > 0.0f) {
    if (s->material->double_sided) {
      ng = -ng;
      ns = -ns;
      turned = true;
    } else {
      s->back_face = true;
    }
  }
  s->ng = ng;
  s->ns = ns;
  s->spread = spread;
  s->cone = cone + spread * hit.t;
  // A texture's lookup through the coordinates its slot reads (`uvs`): the point's coordinates
  // and the level of detail of this ray cone there (textures and sets differ in size).
  const float cosine = std::abs(glm::dot(d, ng));
  auto place = [&](const Texture& t, SlotCoords c, glm::vec2* uv, float* lod) {
    // (An animated transform is affine: the corners' transformed coordinates interpolate to the
    // point's, and give the texels the triangle covers.)
    const glm::vec2 t0 = m.uv_in_set(c.set, c.uvs[tri[0]]), t1 = m.uv_in_set(c.set, c.uvs[tri[1]]),
                    t2 = m.uv_in_set(c.set, c.uvs[tri[2]]);
    const glm::vec3& b = s->barycentric;
    *uv = b.x * t0 + b.y * t1 + b.z * t2;
    *lod = s->cone > 0.0f ? texture_lod(t, t0, t1, t2, world_area2, s->cone, cosine) : 0.0f;
  };
  // Texture t at this point; white where there is none or its slot has no coordinates (the
  // factors alone decide then, as glTF viewers read it).
  auto texel = [&](const Texture* t, SlotCoords uvs) {
    if (!t || !uvs) return glm::vec3(1.0f);
    glm::vec2 uv;
    float lod;
    place(*t, uvs, &uv, &lod);
    return t->sample(uv, lod);
  };
  s->uv = glm::vec2(0.0f);
  s->lod = 0.0f;
  if (m.texture && g.uvs.base_color) place(*m.texture, g.uvs.base_color, &s->uv, &s->lod);
  if (m.normal_map && g.uvs.normal) {
    s->ns = mapped_normal(g, inst, m, tri, s->barycentric, s->ns, turned, g.uvs.normal,
                          texel(m.normal_map, g.uvs.normal), m.normal_scale);
  }
  // A material that varies over the surface, decided here from its textures (those whose slot
  // has coordinates on this primitive).
  if (m.varies) {
    shading::Texels t;
    bool any = false;
    auto read = [&](const Texture* texture, SlotCoords uvs, glm::vec3* out) {
      if (!texture || !uvs) return;
      *out = texel(texture, uvs);
      any = true;
    };
    read(m.metallic_roughness, g.uvs.metallic_roughness, &t.metallic_roughness);
    read(m.emissive_texture, g.uvs.emissive, &t.emissive);
    read(m.occlusion, g.uvs.occlusion, &t.occlusion);
    read(m.transmission_texture, g.uvs.transmission, &t.transmission);
    read(m.specular_texture, g.uvs.specular, &t.specular);
    read(m.specular_color_texture, g.uvs.specular_color, &t.specular_color);
    read(m.clearcoat_texture, g.uvs.clearcoat, &t.clearcoat);
    read(m.clearcoat_roughness_texture, g.uvs.clearcoat_roughness, &t.clearcoat_roughness);
    read(m.sheen_color_texture, g.uvs.sheen_color, &t.sheen_color);
    read(m.sheen_roughness_texture, g.uvs.sheen_roughness, &t.sheen_roughness);
    read(m.anisotropy_texture, g.uvs.anisotropy, &t.anisotropy);  // its blue: the strength
    read(m.glossiness_texture, g.uvs.glossiness, &t.glossiness);
    read(m.iridescence_texture, g.uvs.iridescence, &t.iridescence);
    read(m.iridescence_thickness_texture, g.uvs.iridescence_thickness, &t.iridescence_thickness);
    read(m.diffuse_transmission_texture, g.uvs.diffuse_transmission, &t.diffuse_transmission);
    read(m.diffuse_transmission_color_texture, g.uvs.diffuse_transmission_color,
         &t.diffuse_transmission_color);
    if (any) {
      ShadeMaterial& here = s->at_point.emplace(m);
      shading::vary(&here, t);
      s->material = &here;
    }
  }
  if (!m.needs_layers) return;
  // Where the layers lie (shading::LayerFrame): the coat on the interpolated normal, bent only
  // by its own normal texture.
  shading::LayerFrame& layers = s->layers.emplace();
  layers.coat_n = ns;
  if (m.clearcoat_normal_map && g.uvs.clearcoat_normal) {
    layers.coat_n = mapped_normal(
        g, inst, m, tri, s->barycentric, ns, turned, g.uvs.clearcoat_normal,
        texel(m.clearcoat_normal_map, g.uvs.clearcoat_normal), m.clearcoat_normal_scale);
  }
  // KHR_materials_anisotropy's direction: the texture's red and green (else the tangent) in the
  // tangent frame of its coordinates, turned by its rotation; none without a frame (isotropic).
  if (m.anisotropy_factor > 0.0f) {
    glm::vec3 tangent, bitangent;
    if (tangent_frame(g, inst, m, tri, s->barycentric, s->ns, turned, g.uvs.anisotropy, &tangent,
                      &bitangent)) {
      const glm::vec2 texel_direction =
          m.anisotropy_texture && g.uvs.anisotropy
              ? glm::vec2(texel(m.anisotropy_texture, g.uvs.anisotropy)) * 2.0f - 1.0f
              : glm::vec2(1.0f, 0.0f);
      const glm::vec2 c = m.anisotropy_rotation;  // cos, sin
      const glm::vec2 direction(c.x * texel_direction.x - c.y * texel_direction.y,
                                c.y * texel_direction.x + c.x * texel_direction.y);
      const glm::vec3 along = tangent * direction.x + bitangent * direction.y;
      const float len2 = glm::dot(along, along);
      if (len2 > 1e-12f && std::isfinite(len2)) {
        layers.aniso_t = along * (1.0f / std::sqrt(len2));
        layers.aniso_b = glm::cross(s->ns, layers.aniso_t);
      }
    }
  }
}

// Emission and ambient light, and whether the surface takes direct light (then `terms` is set).
bool TracerImpl::prepare_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex,
                               glm::vec3* c, LocalTerms* terms) const {
  const ShadeMaterial& m = *s.material;
  *c = glm::vec3(0.0f);
  if (m.unlit) {
    *c = m.base * tex;
    return false;
  }
  if (m.has_emission) *c += m.emissive;
  float beneath_sheen = 1.0f;
  if (m.layered && !s.back_face) {
    // A sheen reflects E(n.v) x its color of the (uniform) ambient light, and the material
    // beneath keeps the rest.
    if (m.sheen_max > 0.0f) {
      const float albedo =
          shading::sheen_albedo(m.sheen_alpha, std::max(glm::dot(s.ns, wo), 1e-4f));
      beneath_sheen = 1.0f - m.sheen_max * albedo;  // shading::sheen_scaling
      *c += scene_.ambient * m.sheen_color * albedo;
    }
    if (m.has_ambient) {
      *c += scene_.ambient * (m.ambient * tex + m.ambient_specular) * beneath_sheen;
    }
    // A clear coat lies over the emission and all the ambient light reflected beneath it: they
    // keep 1 - clearcoat x F_coat(n.v) (the direct light's share is in extended_brdf_cos).
    if (m.clearcoat > 0.0f) {
      *c *= 1.0f -
            m.clearcoat * shading::coat_fresnel(std::max(glm::dot(s.layers->coat_n, wo), 0.0f));
    }
  } else if (m.has_ambient) {
    *c += scene_.ambient * (m.ambient * tex + m.ambient_specular);
  }
  if (lights_.empty() || s.back_face ||
      !(m.has_diffuse || m.has_specular || m.layered || m.diffuse_transmits)) {
    return false;
  }
  terms->beneath_sheen = beneath_sheen;
  const glm::vec3 base = m.base * tex;
  terms->diffuse = base * m.diffuse_weight;
  terms->f0 = shading::fresnel_f0(m, base);
  terms->offset = offset_at(s.p);
  terms->origin = s.p + terms->offset * s.ng;
  terms->n_dot_v = std::max(glm::dot(s.ns, wo), 1e-4f);
  return true;
}

// The light one light sends toward the viewer if nothing blocks it; false when it sends none.
// `origin`, `l` and `shadow_tfar` describe the shadow ray.
bool TracerImpl::light_contribution(const LightRecord& light, const Surface& s,
                                    const LocalTerms& terms, const glm::vec3& wo,
                                    glm::vec3* contribution, glm::vec3* origin, glm::vec3* l,
                                    float* shadow_tfar) const {
  glm::vec3 incident;
  float distance;
  if (!shading::light_incidence(light, s.p, l, &distance, &incident)) return false;
  const ShadeMaterial& m = *s.material;
  *shadow_tfar = distance - 2.0f * terms.offset;
  // The light must be on the side the surface faces, for both normals; or, where the surface
  // transmits diffusely (KHR_materials_diffuse_transmission), on the other side for both, its
  // light coming through as a Lambertian transmission, the shadow ray leaving from that side.
  if (glm::dot(*l, s.ng) <= 0.0f) {
    if (!m.diffuse_transmits) return false;
    const float n_dot_l = -glm::dot(s.ns, *l);
    if (n_dot_l <= 0.0f) return false;
    *contribution = incident * m.diffuse_transmitted * (n_dot_l / shading::kPi);
    *origin = s.p - terms.offset * s.ng;
    return true;
  }
  const float n_dot_l = glm::dot(s.ns, *l);
  if (n_dot_l <= 0.0f) return false;
  *contribution =
      incident * (m.extended ? shading::extended_brdf_cos(
                                   m, terms.diffuse, terms.f0, s.ns, wo, *l, terms.n_dot_v, n_dot_l,
                                   m.needs_layers ? &*s.layers : nullptr, terms.beneath_sheen)
                             : shading::brdf_cos(m, terms.diffuse, terms.f0, s.ns, wo, *l,
                                                 terms.n_dot_v, n_dot_l));
  *origin = terms.origin;
  return true;
}

// A number in [0, 1) from a surface point and the direction it is seen from: the one random
// number of a surface's light picks. Samples at other points or instants get other numbers;
// the same point seen the same way gets the same one, so a sample is a function of its ray
// (the crosshair's packets and trace() agree) and reproducible.
static float pick_number(const glm::vec3& p, const glm::vec3& wo) {
  uint32_t h = 0x9e3779b9u;
  for (const float x : {p.x, p.y, p.z, wo.x, wo.y, wo.z}) {
    h ^= std::bit_cast<uint32_t>(x);
    // MurmurHash3's finaliser: every input bit reaches every output bit.
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    h ^= h >> 13;
    h *= 0xc2b2ae35u;
    h ^= h >> 16;
  }
  return float(h >> 8) * 0x1p-24f;
}

// Light picking (docs/sampler.md, "Many lights"). Each light that reaches s is weighted by the
// luminance of the irradiance it would bring unshadowed (what the surface does with it left
// out: a cheap estimate, its light's direction and distance only); K = light_samples picks are
// K evenly spaced points, offset by one number u, along the running sum of the weights
// (systematic sampling), and each pick's light is scaled by (sum of weights) / (its weight x
// K). So each light's expected share is its own light: the estimate is unbiased, exact wherever
// none of the lights is blocked on a matte surface under lights of one color, and a light of
// at least 1/K of the weight is always picked. Where at most K lights reach s, each is cast
// once, as without picking.
int TracerImpl::pick_lights(const Surface& s, const LocalTerms& terms, const glm::vec3& wo,
                            ShadowJob* picks) const {
  thread_local std::vector<uint32_t> reaching;
  thread_local std::vector<float> weights;
  reaching.clear();
  weights.clear();
  const bool transmits = s.material->diffuse_transmits;
  float sum = 0.0f;
  for (size_t i = 0; i < lights_.size(); ++i) {
    glm::vec3 l, incident;
    float distance;
    if (!shading::light_incidence(lights_[i], s.p, &l, &distance, &incident)) continue;
    // The sides light_contribution lets light through: the one the surface faces, or through a
    // diffuse transmitter from the other.
    const bool front = glm::dot(l, s.ng) > 0.0f;
    if (!front && !transmits) continue;
    const float n_dot_l = front ? glm::dot(s.ns, l) : -glm::dot(s.ns, l);
    const float weight = luminance(incident) * n_dot_l;
    if (!(weight > 0.0f && weight < std::numeric_limits<float>::infinity())) continue;
    sum += weight;
    reaching.push_back(uint32_t(i));
    weights.push_back(weight);
  }
  const size_t k = size_t(options_.light_samples);
  int n = 0;
  const auto cast = [&](size_t i, float scale) {
    ShadowJob& job = picks[n];
    if (!light_contribution(lights_[reaching[i]], s, terms, wo, &job.contribution, &job.origin,
                            &job.l, &job.tfar)) {
      return;
    }
    job.contribution *= scale;
    ++n;
  };
  if (reaching.size() <= k) {
    for (size_t i = 0; i < reaching.size(); ++i) cast(i, 1.0f);
    return n;
  }
  const float u = pick_number(s.p, wo);
  size_t i = 0;
  float below = 0.0f;  // the sum of the weights before light i
  for (size_t j = 0; j < k; ++j) {
    const float at = (float(j) + u) / float(k) * sum;
    while (i + 1 < reaching.size() && below + weights[i] <= at) below += weights[i++];
    cast(i, sum / (weights[i] * float(k)));
  }
  return n;
}

// Emission, ambient and direct light at a surface seen from direction wo (unit, toward the
// viewer). `tex` is texture_color(s).
glm::vec3 TracerImpl::shade_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex,
                                  TraceStats* stats) const {
  glm::vec3 c;
  LocalTerms terms;
  if (!prepare_local(s, wo, tex, &c, &terms)) return c;
  const auto cast = [&](const ShadowJob& job) {
    glm::vec3 contribution = job.contribution;
    if (options_.shadows) {
      ++stats->shadow_rays;
      contribution *= shadow_transmittance(job.origin, job.l, job.tfar);
    }
    c += contribution;
  };
  if (picks_lights()) {
    ShadowJob picks[kMaxLightSamples];
    const int n = pick_lights(s, terms, wo, picks);
    for (int j = 0; j < n; ++j) cast(picks[j]);
    return c;
  }
  for (const LightRecord& light : lights_) {
    ShadowJob job;
    if (light_contribution(light, s, terms, wo, &job.contribution, &job.origin, &job.l, &job.tfar))
      cast(job);
  }
  return c;
}

// shade_local for up to 8 surfaces at once (lanes where `hit` is false are skipped): the shadow
// rays toward one light go out as one rtcOccluded8.
void TracerImpl::shade_local8(const Surface* s, const glm::vec3* wo, const glm::vec3* tex,
                              const bool* hit, int n, glm::vec3* out, TraceStats* stats) const {
  LocalTerms terms[8];
  bool lit[8] = {};
  bool any_lit = false;
  for (int k = 0; k < n; ++k) {
    if (!hit[k]) continue;
    lit[k] = prepare_local(s[k], wo[k], tex[k], &out[k], &terms[k]);
    any_lit |= lit[k];
  }
  if (!any_lit) return;
  // Round r casts each lit lane's r-th shadow ray: toward light r, or toward its r-th pick.
  const bool picking = picks_lights();
  // The lanes' picks, per thread: 10 KB that the packets of scenes that do not pick need not
  // carry in their stack frame.
  thread_local std::array<std::array<ShadowJob, kMaxLightSamples>, 8> picks;
  int picked[8] = {};
  size_t rounds = lights_.size();
  if (picking) {
    rounds = 0;
    for (int k = 0; k < n; ++k) {
      if (lit[k]) picked[k] = pick_lights(s[k], terms[k], wo[k], picks[size_t(k)].data());
      rounds = std::max(rounds, size_t(picked[k]));
    }
  }
  for (size_t r = 0; r < rounds; ++r) {
    alignas(32) int valid[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    RTCRay8 rays;
    for (int k = 0; k < 8; ++k) set_lane(&rays, k, glm::vec3(0.0f), glm::vec3(0, 0, 1), 0.0f);
    glm::vec3 contribution[8];
    bool any_ray = false;
    for (int k = 0; k < n; ++k) {
      ShadowJob job;
      if (picking) {
        if (int(r) >= picked[k]) continue;
        job = picks[size_t(k)][r];
      } else if (!lit[k] ||
                 !light_contribution(lights_[r], s[k], terms[k], wo[k], &job.contribution,
                                     &job.origin, &job.l, &job.tfar)) {
        continue;
      }
      contribution[k] = job.contribution;
      if (!options_.shadows) {
        out[k] += contribution[k];
        continue;
      }
      valid[k] = -1;
      any_ray = true;
      set_lane(&rays, k, job.origin, job.l, job.tfar);
      ++stats->shadow_rays;
    }
    if (!any_ray) continue;
    if (!has_translucent_) {  // scenes without glass or blending skip the filter's context
      QueryContext ctx(materials_.data());
      rtcOccluded8(valid, top_, &ctx.embree, &rays);
      for (int k = 0; k < n; ++k)
        if (valid[k] && rays.tfar[k] >= 0.0f) out[k] += contribution[k];
      continue;
    }
    for (int k = 0; k < 8; ++k) rays.id[k] = kShadowRayId + unsigned(k);
    ShadowContext ctx(materials_.data());
    float tfar[8];
    std::copy_n(rays.tfar, 8, tfar);
    rtcOccluded8(valid, top_, &ctx.query.embree, &rays);
    for (int k = 0; k < n; ++k) {
      if (!valid[k] || rays.tfar[k] < 0.0f) continue;
      glm::vec3 kept = ctx.transmittance[k];
      if ((ctx.volume_lanes >> k) & 1u) {
        const glm::vec3 d(rays.dir_x[k], rays.dir_y[k], rays.dir_z[k]);
        kept *= volume_transmittance(ctx, k, d, tfar[k]);
      }
      out[k] += contribution[k] * kept;
    }
  }
}

glm::vec3 TracerImpl::texture_color(const Surface& s) const {
  glm::vec3 c = s.material->texture && s.geom->uvs.base_color
                    ? s.material->texture->sample(s.uv, s.lod)
                    : glm::vec3(1.0f);
  if (const glm::vec3* colors = s.geom->colors) {
    const uint32_t* tri = s.triangle;
    c *= s.barycentric.x * colors[tri[0]] + s.barycentric.y * colors[tri[1]] +
         s.barycentric.z * colors[tri[2]];
  }
  return c;
}

// A surface's own light (its local shading) as the viewer gets it: all of it, or a blended
// surface's opacity's share (the rest comes through it: pass_through).
inline glm::vec3 own_share(const Surface& s, const glm::vec3& local) {
  return s.opacity < 1.0f ? local * s.opacity : local;
}

// The mirror reflection of direction d at surface s about its normal n (unit; s.ns, or the
// coat's); false where there is none. An interpolated or mapped normal can send the reflection
// under the surface: the true one is used then.
static bool mirror_direction(const glm::vec3& d, const Surface& s, const glm::vec3& n,
                             glm::vec3* r) {
  *r = d - 2.0f * glm::dot(d, n) * n;
  if (glm::dot(*r, s.ng) <= 0.0f) *r = d - 2.0f * glm::dot(d, s.ng) * s.ng;
  const float r_len2 = glm::dot(*r, *r);
  if (!(r_len2 > 0.0f)) return false;
  *r *= 1.0f / std::sqrt(r_len2);
  return true;
}

// The light reaching the viewer from surface s (seen along d, with texture color tex) by way
// of mirror reflections and glass, up to the depth limit, times `throughput` (what the path
// before s passes on). s's own local shading is not included. `depth` counts the secondary
// rays already on the path; `media`, what the ray that hit s travels in (its reflections stay
// there).
glm::vec3 TracerImpl::mirror_chain(glm::vec3 d, Surface s, glm::vec3 tex, TraceStats* stats,
                                   int depth, glm::vec3 throughput, const Media& media) const {
  glm::vec3 result(0.0f);
  for (;; ++depth) {
    const ShadeMaterial& m = *s.material;
    if (s.opacity < 1.0f) {  // blended: 1 - a of what lies behind, a of s's own reflections
      if (depth < kMaxBlendDepth) result += pass_through(d, s, depth, throughput, media, stats);
      throughput *= s.opacity;
    }
    if (m.layered && !s.back_face) {
      if (m.clearcoat_mirror && depth < options_.max_mirror_depth) {
        // A smooth clear coat reflects clearcoat x its Fresnel of the surroundings; what lies
        // beneath (a metal's mirror reflection below) keeps the rest.
        const float w = m.clearcoat * shading::coat_fresnel(-glm::dot(s.layers->coat_n, d));
        glm::vec3 r;
        if (mirror_direction(d, s, s.layers->coat_n, &r) &&
            w * std::max(throughput.r, std::max(throughput.g, throughput.b)) >= kMinThroughput) {
          result +=
              secondary(s.p + offset_at(s.p) * s.ng, r, s, depth + 1, throughput * w, media, stats);
        }
        throughput *= 1.0f - w;
      }
      // A sheen takes its share from the mirror reflection and the glass beneath it too.
      if (m.sheen_max > 0.0f) {
        throughput *= shading::sheen_scaling(m, std::max(-glm::dot(s.ns, d), 0.0f));
      }
    }
    if (!m.is_mirror || s.back_face || depth >= options_.max_mirror_depth) {
      // Glass (never is_mirror) branches; the test is here so that other surfaces pay nothing.
      if (m.is_glass && depth < options_.max_mirror_depth)
        result += glass(d, s, tex, depth, throughput, media, stats);
      break;
    }
    const float n_dot_v = -glm::dot(s.ns, d);
    const glm::vec3 f0 = shading::fresnel_f0(m, m.base * tex);
    throughput *= shading::with_film(
        m, shading::fresnel_schlick(f0, n_dot_v, shading::fresnel_f90(m)), n_dot_v, f0);
    if (std::max(throughput.r, std::max(throughput.g, throughput.b)) < kMinThroughput) break;
    glm::vec3 r;
    if (!mirror_direction(d, s, s.ns, &r)) break;
    const glm::vec3 origin = s.p + offset_at(s.p) * s.ng;
    ++stats->reflection_rays;
    const HitRef hit = intersect(origin, r, 0.0f);
    if (hit.geom == RTC_INVALID_GEOMETRY_ID) {
      result += throughput * scene_.background;
      break;
    }
    if (const ShadeMaterial* medium = media.innermost(); medium && medium->has_volume)
      throughput *= glm::exp(-medium->absorption * hit.t);
    make_surface(hit, origin, r, s.cone, s.spread, &s);
    d = r;
    tex = texture_color(s);
    result += throughput * own_share(s, shade_local(s, -d, tex, stats));
  }
  return result;
}

// One secondary ray, and what it brings back (local shading and further bounces) times
// `throughput`; `depth` counts this ray. A ray in an absorbing medium (`media`'s innermost,
// KHR_materials_volume) keeps exp(-absorption x the distance to what it hits).
glm::vec3 TracerImpl::secondary(const glm::vec3& origin, const glm::vec3& d, const Surface& from,
                                int depth, const glm::vec3& throughput, const Media& media,
                                TraceStats* stats) const {
  ++stats->reflection_rays;
  const HitRef hit = intersect(origin, d, 0.0f);
  if (hit.geom == RTC_INVALID_GEOMETRY_ID) return throughput * scene_.background;
  Surface s;
  make_surface(hit, origin, d, from.cone, from.spread, &s);
  const glm::vec3 tex = texture_color(s);
  glm::vec3 kept = throughput;
  if (const ShadeMaterial* medium = media.innermost(); medium && medium->has_volume)
    kept *= glm::exp(-medium->absorption * hit.t);
  return kept * own_share(s, shade_local(s, -d, tex, stats)) +
         mirror_chain(d, s, tex, stats, depth, kept, media);
}

// What a blended surface s, hit along d, lets through from behind it: the ray goes on from its
// far side, weighted 1 - s.opacity; `depth` counts the rays already on the path.
glm::vec3 TracerImpl::pass_through(const glm::vec3& d, const Surface& s, int depth,
                                   const glm::vec3& throughput, const Media& media,
                                   TraceStats* stats) const {
  const glm::vec3 behind = throughput * (1.0f - s.opacity);
  if (std::max(behind.r, std::max(behind.g, behind.b)) < kMinThroughput) return glm::vec3(0.0f);
  const glm::vec3 ng = s.back_face ? -s.ng : s.ng;  // toward the side the ray arrives from
  return secondary(s.p - offset_at(s.p) * ng, d, s, depth + 1, behind, media, stats);
}

// Fills everything of a primary sample but its color, and the surface it hit. Returns false on
// a miss (then the color is the background).
bool TracerImpl::begin_sample(const Ray& ray, const HitRef& hit, ShadedSample* o, Surface* s,
                              TraceStats* stats) const {
  ++stats->primary_rays;
  if (hit.geom == RTC_INVALID_GEOMETRY_ID) {
    o->color = scene_.background;
    o->position = ray.direction;
    o->velocity = glm::vec3(0.0f);
    o->object_id = ShadedSample::kNoObject;
    o->hit = false;
    return false;
  }
  make_surface(hit, ray.origin, ray.direction, ray.cone, ray.spread, s);
  o->position = s->p;
  if (s->instance->moves) {
    o->velocity = glm::vec3(s->instance->velocity * glm::vec4(s->p, 1.0f));
  } else if (const glm::vec3* v = s->geom->velocities) {
    const uint32_t* tri = s->triangle;
    o->velocity = s->barycentric[0] * v[tri[0]] + s->barycentric[1] * v[tri[1]] +
                  s->barycentric[2] * v[tri[2]];
  } else {
    o->velocity = glm::vec3(0.0f);
  }
  o->object_id = uint32_t(s->node);
  o->hit = true;
  return true;
}

// No NaN or Inf leaves the tracer. Radiance that overflowed to +Inf (many lights each within a
// float) is as bright as a sample can be: it is clamped like finite radiance beyond the range.
// A NaN says nothing about the radiance: the sample is black.
void TracerImpl::sanitize(ShadedSample* o, TraceStats* stats) const {
  if (!finite(o->color)) {
    const bool nan = std::isnan(o->color.r) || std::isnan(o->color.g) || std::isnan(o->color.b);
    for (int c = 0; c < 3; ++c) {
      if (std::isinf(o->color[c])) o->color[c] = o->color[c] > 0.0f ? kMaxRadiance : 0.0f;
    }
    if (nan) o->color = glm::vec3(0.0f);
    ++stats->sanitized;
  }
  // Finite but huge radiance would overflow the sampler's float gradients and variances; the
  // wire (RGB9E5) and the display (half-float range) clamp to about this anyway.
  o->color = glm::clamp(o->color, glm::vec3(0.0f), glm::vec3(kMaxRadiance));
  if (!finite(o->position)) {
    o->position = glm::vec3(0.0f);
    ++stats->sanitized;
  }
  if (!finite(o->velocity)) {
    o->velocity = glm::vec3(0.0f);
    ++stats->sanitized;
  }
}

void TracerImpl::finish(const Ray& ray, const HitRef& hit, ShadedSample* out,
                        TraceStats* stats) const {
  Surface s;
  if (begin_sample(ray, hit, out, &s, stats)) {
    const glm::vec3 tex = texture_color(s);
    out->color = own_share(s, shade_local(s, -ray.direction, tex, stats)) +
                 mirror_chain(ray.direction, s, tex, stats);
  }
  sanitize(out, stats);
}

}  // namespace afr::tracer_detail

namespace afr {

// =============================================================================================
// Tracer

Tracer::Tracer(const Scene& scene, const TracerOptions& options)
    : impl_(std::make_unique<Impl>(std::make_shared<const Scene>(scene), options)) {}

Tracer::Tracer(std::shared_ptr<const Scene> scene, const TracerOptions& options)
    : impl_(std::make_unique<Impl>(std::move(scene), options)) {}

Tracer::Tracer(const Tracer& other, ShareGeometry)
    : impl_(std::make_unique<Impl>(other.impl_->shared_)) {}

Tracer::~Tracer() = default;

void Tracer::set_time(double t) { impl_->set_time(t); }
void Tracer::set_view(const Camera& view) { impl_->place_camera_lights(view); }
double Tracer::time() const { return impl_->state_.time; }
const Camera& Tracer::camera() const { return impl_->camera_; }
const TracerOptions& Tracer::options() const { return impl_->options_; }

size_t Tracer::copied_vertices() const {
  size_t n = 0;
  for (const std::vector<glm::vec3>& p : impl_->shared_->static_positions) n += p.size();
  return n;
}

bool Tracer::rigid_transform(uint32_t node, glm::dmat4* world, glm::dmat4* inverse) const {
  using namespace tracer_detail;  // the parts (tracer_parts.h), in this function only
  const Impl& m = *impl_;
  if (node >= m.moving_instance_of_node_.size()) return false;
  const int i = m.moving_instance_of_node_[node];
  if (i < 0) return false;
  const Instance& inst = m.instances_[size_t(i)];
  if (!inst.enabled) return false;
  if (world != nullptr) *world = inst.world;
  if (inverse != nullptr) *inverse = inst.inverse_world;
  return true;
}

ShadedSample Tracer::trace(const Ray& ray, TraceStats* stats) const {
  using namespace tracer_detail;  // the parts (tracer_parts.h), in this function only
  ShadedSample s;
  // Embree's behaviour on rays with NaN or Inf is undefined: they miss.
  const HitRef hit = finite(ray.origin) && finite(ray.direction)
                         ? impl_->intersect(ray.origin, ray.direction, 0.0f)
                         : HitRef{};
  impl_->finish(ray, hit, &s, stats);
  return s;
}

void Tracer::trace_crosshair(const Camera& camera, double x, double y, int width, int height,
                             std::array<ShadedSample, 5>* out, TraceStats* stats) const {
  using namespace tracer_detail;  // the parts (tracer_parts.h), in this function only
  static constexpr double kDx[5] = {0.0, -1.0, 1.0, 0.0, 0.0};
  static constexpr double kDy[5] = {0.0, 0.0, 0.0, -1.0, 1.0};
  Ray rays[5];
  for (int k = 0; k < 5; ++k) rays[k] = camera.ray(x + kDx[k], y + kDy[k], width, height);

  if (!impl_->options_.packet_crosshair) {
    for (int k = 0; k < 5; ++k) (*out)[size_t(k)] = trace(rays[k], stats);
    return;
  }
  alignas(32) int valid[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  RTCRayHit8 rh;
  for (int k = 0; k < 8; ++k) {
    const bool ok = k < 5 && finite(rays[k].origin) && finite(rays[k].direction);
    if (ok) {
      valid[k] = -1;
      set_lane(&rh.ray, k, rays[k].origin, rays[k].direction, INFINITY);
    } else {
      set_lane(&rh.ray, k, glm::vec3(0.0f), glm::vec3(0, 0, 1), 0.0f);
    }
    rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
  }
  QueryContext ctx(impl_->materials_.data());
  rtcIntersect8(valid, impl_->top_, &ctx.embree, &rh);
  Surface surfaces[5];
  glm::vec3 wo[5], tex[5], local[5];
  bool hit[5];
  for (int k = 0; k < 5; ++k) {
    HitRef h;
    if (valid[k]) {
      h.t = rh.ray.tfar[k];
      h.u = rh.hit.u[k];
      h.v = rh.hit.v[k];
      h.geom = rh.hit.geomID[k];
      h.prim = rh.hit.primID[k];
      h.inst = rh.hit.instID[0][k];
    }
    hit[k] = impl_->begin_sample(rays[k], h, &(*out)[size_t(k)], &surfaces[k], stats);
    if (hit[k]) {
      wo[k] = -rays[k].direction;
      tex[k] = impl_->texture_color(surfaces[k]);
    }
  }
  impl_->shade_local8(surfaces, wo, tex, hit, 5, local, stats);
  for (int k = 0; k < 5; ++k) {
    ShadedSample& o = (*out)[size_t(k)];
    if (hit[k])
      o.color = own_share(surfaces[k], local[k]) +
                impl_->mirror_chain(rays[k].direction, surfaces[k], tex[k], stats);
    impl_->sanitize(&o, stats);
  }
}

bool Tracer::occluded(const glm::vec3& from, const glm::vec3& to, TraceStats* stats) const {
  using namespace tracer_detail;  // the parts (tracer_parts.h), in this function only
  ++stats->occlusion_rays;
  const glm::vec3 d = to - from;
  const float len = glm::length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) return false;
  const float near = std::min(impl_->offset_at(from), 0.5f * len);
  const float far = std::max(len - impl_->offset_at(to), near);
  return impl_->blocked(from, d / len, near, far);
}

}  // namespace afr
