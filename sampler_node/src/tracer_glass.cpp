// Glass (TracerImpl::glass, tracer_parts.h): Whitted-style reflection and refraction at a
// transmissive surface, the media a refracted ray travels in, and dispersion.
#include <algorithm>
#include <cmath>

#include "tracer_parts.h"

namespace afr::tracer_detail {

namespace {

// Snell's refraction of d about n (on the side d arrives from, cos_i = -n.d) across an
// interface from index n_from to index n_to, with Schlick's Fresnel term of F0 f0 at the cosine
// on the outer side (that of the lower index: the refracted one when the index falls); an index
// of 0 or total internal reflection: t 0, F 1.
struct Refraction {
  glm::vec3 t{0.0f};
  float F = 1.0f;
  float cos_outer = 1.0f;
};
Refraction refraction(const glm::vec3& d, const glm::vec3& n, float cos_i, float n_from, float n_to,
                      float f0) {
  Refraction r;
  r.cos_outer = cos_i;
  if (!(n_from > 0.0f && n_to > 0.0f)) return r;
  const float eta = n_from / n_to;
  const float sin2_t = eta * eta * (1.0f - cos_i * cos_i);
  if (!(sin2_t < 1.0f)) return r;
  const float cos_t = std::sqrt(1.0f - sin2_t);
  r.t = eta * d + (eta * cos_i - cos_t) * n;
  if (eta > 1.0f) r.cos_outer = cos_t;
  r.F = shading::fresnel_schlick(glm::vec3(f0), r.cos_outer).x;
  return r;
}

// The ior of color channel c (0 red, 1 green, 2 blue) in dispersive glass, never below 1.
float channel_ior(const ShadeMaterial& m, int c) {
  return std::max(m.ior + m.dispersion_spread * float(c - 1), 1.0f);
}

// The ior of a medium (1 for air) for color channel c (-1: all, green's where they differ).
float medium_ior(const ShadeMaterial* medium, int c) {
  if (medium == nullptr) return 1.0f;
  return c >= 0 && medium->dispersion_spread > 0.0f ? channel_ior(*medium, c) : medium->ior;
}

// The one color channel a throughput carries, the other two exactly 0; -1 for none or several.
int single_channel(const glm::vec3& t) {
  if (t.g == 0.0f && t.b == 0.0f) return t.r != 0.0f ? 0 : -1;
  if (t.r == 0.0f && t.b == 0.0f) return 1;
  if (t.r == 0.0f && t.g == 0.0f) return 2;
  return -1;
}

}  // namespace

// Two volumes whose surfaces coincide (a liquid filling a glass to its wall, modelled on the same
// surface): the ray crosses both at the one point, but meets only the surface Embree reports, and
// the refracted ray starts beyond the other. Around the hit (within the ray offset on either
// side) a probe collects the glass surfaces there, as a shadow ray does (crosses, through the
// occlusion filter every glass geometry has); each surface of another volume changes the media
// on the far side as its own hit would: entered, or left. The interface then bends light by the
// ratio of the two media's iors, and the ray goes on in the right medium. (What that surface's
// own transmission and base color would take from the ray is not taken.)
void TracerImpl::cross_coincident_surfaces(const Surface& s, const glm::vec3& d,
                                           Media* after) const {
  const float reach = offset_at(s.p);
  ShadowContext ctx(materials_.data());
  RTCRay r;
  init_ray(&r, s.p - reach * d, d, 0.0f, 2.0f * reach);
  r.id = kShadowRayId;
  rtcOccluded1(top_, &ctx.query.embree, &r);
  const ShadeMaterial* self = &materials_[size_t(s.geom->material)];
  for (int k = 0; k < ctx.n_crossed[0]; ++k) {
    const ShadowContext::Crossed& c = ctx.crossed[0][k];
    const Instance& inst = instances_[c.inst];
    const GeomRecord& g = blas_[size_t(inst.blas)].geoms[c.geom];
    const ShadeMaterial* medium = &materials_[g.material];
    if (medium == self || !medium->is_volume) continue;  // s itself, or no medium
    const uint32_t* tri = g.indices + 3 * size_t(c.prim);
    *after = leaves_through(g, inst, tri, d) ? after->left(medium) : after->entered(medium);
  }
}

// Whitted glass at s, hit along d (docs/scene-model.md, "Transmission and refraction"): a
// reflected ray weighted by Schlick's Fresnel and a refracted one (Snell) weighted by the rest
// times transmission and base color; total internal reflection past the critical angle.
glm::vec3 TracerImpl::glass(const glm::vec3& d, const Surface& s, const glm::vec3& tex, int depth,
                            const glm::vec3& throughput, const Media& media,
                            TraceStats* stats) const {
  const ShadeMaterial& m = *s.material;
  // Entering or leaving: the side of the triangle's own geometric normal, before make_surface
  // turned it toward the viewer for a double-sided material.
  const bool entering = !leaves_through(*s.geom, *s.instance, s.triangle, d);

  // Normals on the side the ray arrives from (a single-sided back face keeps its own).
  const glm::vec3 ng = s.back_face ? -s.ng : s.ng;
  glm::vec3 n = s.back_face ? -s.ns : s.ns;
  float cos_i = -glm::dot(n, d);
  if (!(cos_i > 0.0f)) {
    n = ng;
    cos_i = -glm::dot(n, d);
  }
  cos_i = glm::clamp(cos_i, 0.0f, 1.0f);
  const glm::vec3 base = m.base * tex;

  // The media on either side (Media): a volume's surface leads into or out of its medium,
  // within the media around it; a thin wall (no volume) is an interface with air on its outer
  // side, and the rays on both its sides stay in the media around it.
  const ShadeMaterial* self = &materials_[size_t(s.geom->material)];
  Media before = media, after = media;
  if (m.is_volume) {
    if (entering) {
      after = media.entered(self);
    } else {
      if (!media.contains(self)) before = media.entered(self);
      after = before.left(self);
    }
    if (several_volumes_) cross_coincident_surfaces(s, d, &after);
  }
  // The indices of refraction on the side the ray comes from and on the other, for color
  // channel c (-1: all).
  const auto sides = [&](int c) {
    if (!m.is_volume) return entering ? std::pair(1.0f, m.ior) : std::pair(m.ior, 1.0f);
    return std::pair(medium_ior(before.innermost(), c), medium_ior(after.innermost(), c));
  };

  // KHR_materials_dispersion: each color channel refracts with its own ior. A ray that carries
  // more than one channel into or out of dispersive glass splits into one refracted ray per
  // channel (the reflected one stays one ray: its direction is the same for all); a ray that
  // carries one channel only, as every ray inside dispersive glass does, takes that channel's
  // ior.
  int channel = -1;  // the one channel the ray carries, where an ior depends on it
  bool split = false;
  if (sides(0) != sides(2)) {
    channel = single_channel(throughput);
    split = channel < 0;
  }
  Refraction per_channel[3];
  if (split) {
    for (int c = 0; c < 3; ++c) {
      const auto [from_c, to_c] = sides(c);
      per_channel[c] = refraction(d, n, cos_i, from_c, to_c, shading::ior_to_f0(to_c, from_c));
    }
  }
  // Green's refraction stands for all where they split (its cosine on the outer side weighs
  // the film and the metallic part).
  const Refraction main = [&] {
    if (split) return per_channel[1];
    const auto [n_from, n_to] = sides(channel);
    return refraction(d, n, cos_i, n_from, n_to, shading::ior_to_f0(n_to, n_from));
  }();
  const glm::vec3 F =
      split ? glm::vec3(per_channel[0].F, per_channel[1].F, per_channel[2].F) : glm::vec3(main.F);
  // An iridescent film (KHR_materials_iridescence) colors the Fresnel term, seen from the air;
  // a channel past its critical angle reflects all.
  glm::vec3 fresnel = F;
  if (main.F < 1.0f || split) {
    const glm::vec3 film = shading::with_film(m, F, main.cos_outer, glm::vec3(m.f0_dielectric));
    for (int c = 0; c < 3; ++c) fresnel[c] = F[c] < 1.0f ? film[c] : 1.0f;
  }
  // The metallic part reflects as a mirror tinted by the base color.
  const glm::vec3 metal = shading::fresnel_schlick(base, main.cos_outer);
  glm::vec3 reflect_w;
  for (int c = 0; c < 3; ++c) {
    reflect_w[c] = F[c] >= 1.0f ? 1.0f : glm::mix(fresnel[c], metal[c], m.metallic);
  }
  const glm::vec3 transmit_w = (m.transmission * (1.0f - m.metallic)) * (1.0f - fresnel) * base;

  glm::vec3 result(0.0f);
  const float offset = offset_at(s.p);
  const glm::vec3 r_throughput = throughput * reflect_w;
  if (std::max(r_throughput.r, std::max(r_throughput.g, r_throughput.b)) >= kMinThroughput) {
    glm::vec3 r = d + 2.0f * cos_i * n;
    if (glm::dot(r, ng) <= 0.0f) r = d - 2.0f * glm::dot(d, ng) * ng;
    const float len2 = glm::dot(r, r);
    if (len2 > 0.0f && std::isfinite(len2))
      result += secondary(s.p + offset * ng, r * (1.0f / std::sqrt(len2)), s, depth + 1,
                          r_throughput, before, stats);
  }
  // One refracted ray (across the indices of channel c) carrying t_throughput.
  const auto refract_ray = [&](glm::vec3 t, int c, const glm::vec3& t_throughput) {
    if (std::max(t_throughput.r, std::max(t_throughput.g, t_throughput.b)) < kMinThroughput) return;
    // An interpolated normal can bend the ray back to the side it came from: use the true one.
    if (glm::dot(t, ng) >= 0.0f) {
      const auto [from_c, to_c] = sides(c);
      t = refraction(d, ng, -glm::dot(ng, d), from_c, to_c, 0.0f).t;
    }
    const float len2 = glm::dot(t, t);
    if (len2 > 0.0f && std::isfinite(len2))
      result += secondary(s.p - offset * ng, t * (1.0f / std::sqrt(len2)), s, depth + 1,
                          t_throughput, after, stats);
  };
  if (!split) {
    refract_ray(main.t, channel, throughput * transmit_w);
  } else {
    for (int c = 0; c < 3; ++c) {
      glm::vec3 one(0.0f);
      one[c] = throughput[c] * transmit_w[c];
      refract_ray(per_channel[c].t, c, one);
    }
  }
  return result;
}

}  // namespace afr::tracer_detail
