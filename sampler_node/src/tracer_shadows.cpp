// Shadow rays and what lets them through: glass, diffusely transmitting, cut-away and blended
// surfaces (TracerImpl, tracer_parts.h).
//
// ---- Shadows through glass, diffuse transmitters and blended surfaces ----
//
// A shadow ray passes through glass, dimmed by each glass surface it crosses
// (ShadeMaterial::shadow_transmittance): a Whitted-style filter shadow, as BART's scenes
// expect of their light behind a glass ceiling: transmission x (1 - metallic) x base color,
// where the transmission and the base color are, as for the camera's rays, the factors times
// the textures (level 0) and COLOR_0 at the point (GeometryFilter::through). The shadow ray is
// not refracted, and Fresnel does not dim it. A surface that transmits diffusely
// (KHR_materials_diffuse_transmission: leaves, paper, a lamp's shade) lets it through the same
// way, dimmed by what it transmits: its strength x color x the diffuse part metal and glass
// leave (ShadeMaterial::diffuse_transmitted), textures included. That light would leave such a
// surface scattered over its hemisphere; going on straight, it keeps the energy the surface
// passes on (the room around a shaded lamp gets the lamp's light times the shade's
// transmission, as from the glowing shade far off) but not its spread (the shade casts no
// soft glow of its own). It passes a blended surface (alphaMode
// BLEND) dimmed by its opacity a at the point: 1 - a goes through, and the rest as through that
// surface, if it lets light through. Embree reports each such surface on the ray's way to
// occlusion_filter (crosses), which multiplies it into the ray's transmittance and lets the ray go
// on, in whatever order (products commute); any other surface ends the ray. The high-quality BVH's
// spatial splits can report one triangle twice, so each ray remembers the ones it has counted.
// Inside absorbing glass (KHR_materials_volume) a shadow ray also keeps exp(-absorption x the
// length it travels there): the crossings are kept with their distances and sorted once the ray is
// through (volume_transmittance). Only shadow rays (id kShadowRayId + lane, with a
// ShadowContext) are filtered: other occlusion queries (Tracer::occluded) stop at glass as at any
// surface.
//
// ---- alphaMode MASK ----
//
// A masked surface (ShadeMaterial::masked) is cut away where its opacity is below the cutoff:
// its geometry's intersection filter (mask_filter) and occlusion filter (occlusion_filter)
// reject hits there, so every ray, the camera's, reflections, shadows and the sampler's
// occlusion rays alike, passes through as if nothing were there. Only masked geometries have
// an intersection filter; the others cost Embree nothing.
//
// ---- alphaMode BLEND ----
//
// A blended surface shows a (its opacity at the point, opacity_at) of its own light and lets
// 1 - a of what lies behind through, as blending does: the surface's local shading and its
// reflections are weighted by a (Surface::opacity), and mirror_chain sends the ray on through
// it (a pass-through, weighted 1 - a) from the far side. Only a point of opacity 0 is cut away
// by the filters; shadow rays are dimmed by 1 - a (above). Every sample is the blend, so a
// blended surface adds no noise; what it costs is one more ray for each one that meets it.
#include <algorithm>
#include <array>
#include <cmath>

#include "tracer_parts.h"

namespace afr::tracer_detail {
namespace {

constexpr float kShadowCutoff = 1e-3f;  // a ray dimmer than this is blocked

// A shadow ray's crossing of a surface that lets `through` of the light pass, in lane i (see
// above): false when the ray is to stop there.
bool crosses(const RTCFilterFunctionNArguments* args, unsigned i, const glm::vec3& through,
             bool volume) {
  const unsigned lane = RTCRayN_id(args->ray, args->N, i) - kShadowRayId;
  if (lane >= unsigned(ShadowContext::kLanes)) return false;  // not a shadow ray: a blocker
  auto* ctx = reinterpret_cast<ShadowContext*>(args->context);
  // The hit's distance is the ray's tfar while the filter runs (the same in an instance's
  // space, whose transform keeps the ray's parameter).
  const ShadowContext::Crossed c{
      RTCHitN_instID(args->hit, args->N, i, 0), RTCHitN_geomID(args->hit, args->N, i),
      RTCHitN_primID(args->hit, args->N, i), RTCRayN_tfar(args->ray, args->N, i)};
  bool seen = false;
  for (int k = 0; k < ctx->n_crossed[lane]; ++k) {
    const ShadowContext::Crossed& o = ctx->crossed[lane][k];
    seen |= o.inst == c.inst && o.geom == c.geom && o.prim == c.prim;
  }
  if (!seen) {
    if (ctx->n_crossed[lane] == ShadowContext::kMaxCrossed) return false;
    ctx->crossed[lane][ctx->n_crossed[lane]++] = c;
    ctx->transmittance[lane] *= through;
    ctx->volume_lanes |= uint32_t(volume) << lane;
  }
  const glm::vec3& tr = ctx->transmittance[lane];
  return std::max(tr.r, std::max(tr.g, tr.b)) >= kShadowCutoff;
}

// The occlusion filter of a masked, blended or glass geometry: a ray goes on through a cut-away

}  // namespace

// point, and shadow rays through glass and blended surfaces.
void occlusion_filter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const GeometryFilter*>(args->geometryUserPtr);
  const ShadeMaterial& m =
      reinterpret_cast<const QueryContext*>(args->context)->materials[f->material];
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    if (m.blended && f->masked) {
      const float a = f->opacity(m, args, i);
      const glm::vec3 through =
          m.lets_shadow_rays_through() ? f->through(m, args, i) : glm::vec3(0.0f);
      if (!(a > 0.0f) || crosses(args, i, (1.0f - a) + a * through, false)) args->valid[i] = 0;
    } else if (f->masked && !f->opaque_at(m, args, i)) {
      args->valid[i] = 0;
    } else if (m.lets_shadow_rays_through() &&
               crosses(args, i, f->through(m, args, i), m.has_volume)) {
      args->valid[i] = 0;
    }
  }
}

// The intersection filter of a masked geometry: a ray goes on through a cut-away point.
void mask_filter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const GeometryFilter*>(args->geometryUserPtr);
  const ShadeMaterial& m =
      reinterpret_cast<const QueryContext*>(args->context)->materials[f->material];
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == -1 && !f->opaque_at(m, args, i)) args->valid[i] = 0;
  }
}
glm::vec3 TracerImpl::filtered_shadow(const glm::vec3& o, const glm::vec3& d, float tfar) const {
  ShadowContext ctx(materials_.data());
  RTCRay r;
  init_ray(&r, o, d, 0.0f, tfar);
  r.id = kShadowRayId;
  rtcOccluded1(top_, &ctx.query.embree, &r);
  if (r.tfar < 0.0f) return glm::vec3(0.0f);
  if ((ctx.volume_lanes & 1u) == 0) return ctx.transmittance[0];
  // A ray that passed keeps its direction and tfar (the filters' rejected hits restore it).
  const glm::vec3 dir(r.dir_x, r.dir_y, r.dir_z);
  return ctx.transmittance[0] * volume_transmittance(ctx, 0, dir, r.tfar);
}

// KHR_materials_volume on a shadow ray's way: Embree reports the surfaces of glass it crosses
// in any order, so the crossings of volumes are sorted by distance and each stretch between two
// keeps exp(-absorption x its length), the absorption that of the innermost medium the ray is in
// there, as a refracted ray inside keeps (secondary, Media): media nest, and the innermost
// replaces those around it. The side of each surface is the triangle's own, as glass() tells
// it. A surface the ray leaves by, without having entered it on the way, holds the ray's origin
// (or the light) inside: the media so left are those the ray starts in, the first left the
// innermost.
glm::vec3 TracerImpl::volume_transmittance(const ShadowContext& ctx, int lane, const glm::vec3& d,
                                           float tfar) const {
  struct Stop {
    float t;
    bool entering;
    const ShadeMaterial* medium;
  };
  constexpr size_t kMax = ShadowContext::kMaxCrossed;
  std::array<Stop, kMax> stops;
  int n = 0;
  for (int k = 0; k < ctx.n_crossed[lane]; ++k) {
    const ShadowContext::Crossed& c = ctx.crossed[lane][k];
    const Instance& inst = instances_[c.inst];
    const GeomRecord& g = blas_[size_t(inst.blas)].geoms[c.geom];
    const ShadeMaterial* medium = &materials_[g.material];
    if (!medium->is_volume) continue;
    const uint32_t* tri = g.indices + 3 * size_t(c.prim);
    stops[size_t(n++)] = {c.t, !leaves_through(g, inst, tri, d), medium};
  }
  std::sort(stops.begin(), stops.begin() + n,
            [](const Stop& a, const Stop& b) { return a.t < b.t; });
  // The media the ray is in, innermost last (at most one per stop). The first pass finds those
  // it starts in: each left without having been entered, innermost first.
  std::array<const ShadeMaterial*, kMax> inside;
  int depth = 0;
  const auto leave = [&](const ShadeMaterial* m) {
    for (int k = depth - 1; k >= 0; --k) {
      if (inside[size_t(k)] != m) continue;
      std::copy(inside.begin() + k + 1, inside.begin() + depth, inside.begin() + k);
      --depth;
      return true;
    }
    return false;
  };
  std::array<const ShadeMaterial*, kMax> start;
  int n_start = 0;
  for (int k = 0; k < n; ++k) {
    const Stop& stop = stops[size_t(k)];
    if (stop.entering) {
      inside[size_t(depth++)] = stop.medium;
    } else if (!leave(stop.medium)) {
      start[size_t(n_start++)] = stop.medium;
    }
  }
  depth = n_start;
  std::reverse_copy(start.begin(), start.begin() + n_start, inside.begin());
  glm::vec3 optical_depth(0.0f);  // absorption x length, summed over the stretches
  float from = 0.0f;              // where the current stretch began
  for (int k = 0; k <= n; ++k) {
    const float to = k < n ? stops[size_t(k)].t : tfar;
    if (depth > 0) optical_depth += inside[size_t(depth - 1)]->absorption * (to - from);
    if (k == n) break;
    const Stop& stop = stops[size_t(k)];
    if (stop.entering) {
      inside[size_t(depth++)] = stop.medium;
    } else {
      leave(stop.medium);
    }
    from = stop.t;
  }
  return glm::exp(-optical_depth);
}

bool TracerImpl::blocked(const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) const {
  QueryContext ctx(materials_.data());
  RTCRay r;
  init_ray(&r, o, d, tnear, tfar);
  rtcOccluded1(top_, &ctx.embree, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

}  // namespace afr::tracer_detail
