#include <afr/sampler/tracer.h>

#include <afr/common/check.h>
#include <afr/common/error.h>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "shading.h"

namespace afr {

TraceStats& TraceStats::operator+=(const TraceStats& o) {
  primary_rays += o.primary_rays;
  shadow_rays += o.shadow_rays;
  reflection_rays += o.reflection_rays;
  occlusion_rays += o.occlusion_rays;
  sanitized += o.sanitized;
  return *this;
}

namespace {

using shading::LightRecord;
using shading::ShadeMaterial;

// Half-width of the central difference that gives instance velocities.
constexpr double kVelocityDt = 1e-3;
// Secondary rays start this far (relative to the hit point's magnitude plus the scene's, the
// latter at most 1) off the surface.
constexpr float kRayOffset = 5e-5f;
// Shaded colors are clamped to this: the largest half float, as the display keeps them.
constexpr float kMaxRadiance = 65504.0f;
// Mirror chains stop when what they could still add is below this.
constexpr float kMinThroughput = 1e-3f;
// Blended surfaces (alphaMode BLEND) a path passes through at most, with its other secondary
// rays: a pass-through is no bounce, so it has a budget of its own beyond the mirror depth.
constexpr int kMaxBlendDepth = 16;

bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

float max_abs(const glm::vec3& v) {
  return std::max(std::abs(v.x), std::max(std::abs(v.y), std::abs(v.z)));
}

// Enables or disables Embree geometry g as `on` asks; *enabled: whether it is enabled now.
void set_enabled(RTCGeometry g, bool on, bool* enabled) {
  if (on == *enabled) return;
  if (on)
    rtcEnableGeometry(g);
  else
    rtcDisableGeometry(g);
  *enabled = on;
}

// The texture coordinates one texture slot reads on a primitive: its set's per-vertex
// coordinates (null: the primitive has none) and the set's index (for its animated transform,
// ShadeMaterial::uv_in_set).
struct SlotCoords {
  const glm::vec2* uvs = nullptr;
  uint8_t set = 0;
  explicit operator bool() const { return uvs != nullptr; }
  // At barycentrics (u, v) of triangle `tri`, as material m's slot reads them.
  glm::vec2 at(const shading::ShadeMaterial& m, const uint32_t* tri, float u, float v) const {
    return m.uv_in_set(set, (1.0f - u - v) * uvs[tri[0]] + u * uvs[tri[1]] + v * uvs[tri[2]]);
  }
};

// A primitive's texture coordinates as each texture slot of its material reads them
// (Material::TextureSets; none for a slot whose factors then decide). Slots on one set share
// its coordinates.
struct SlotUvs {
  SlotCoords base_color;  // also the opacity's (alphaMode MASK and BLEND)
  SlotCoords metallic_roughness;
  SlotCoords emissive;
  SlotCoords occlusion;
  SlotCoords normal;  // also the normal texture's frame without TANGENT
  SlotCoords transmission;
  SlotCoords specular;
  SlotCoords specular_color;
  SlotCoords clearcoat;
  SlotCoords clearcoat_roughness;
  SlotCoords clearcoat_normal;  // likewise for the clear coat's normal texture
  SlotCoords sheen_color;
  SlotCoords sheen_roughness;
  SlotCoords anisotropy;  // also the anisotropy's tangent frame
  SlotCoords glossiness;
  SlotCoords iridescence;
  SlotCoords iridescence_thickness;
  SlotCoords diffuse_transmission;
  SlotCoords diffuse_transmission_color;
};

// Set k of p's texture coordinates (null where p has none).
SlotCoords uv_data(const Primitive& p, uint8_t k) {
  const std::vector<glm::vec2>& uvs = p.uv_set(k);
  return {!uvs.empty() && uvs.size() == p.positions.size() ? uvs.data() : nullptr, k};
}

// The value of a per-vertex attribute at barycentrics `bary` of triangle `tri`.
template <typename T>
T interpolate(const T* values, const uint32_t* tri, const glm::vec3& bary) {
  return bary.x * values[tri[0]] + bary.y * values[tri[1]] + bary.z * values[tri[2]];
}

// One Embree triangle geometry: one primitive of a mesh. Static and deforming geometry is
// stored in world space and knows its node; geometry of an instanced mesh is in the mesh's
// space and takes its node from the instance.
struct GeomRecord {
  const glm::vec3* positions = nullptr;
  const glm::vec3* normals = nullptr;  // null when the primitive has none per vertex
  SlotUvs uvs;
  const glm::vec3* colors = nullptr;   // COLOR_0; null when the primitive has none
  const float* color_alpha = nullptr;  // COLOR_0's alpha where its material tests alpha, or null
  // TANGENT in the positions' space (w: the bitangent's sign); null: the triangle's own frame
  // (no TANGENT).
  const glm::vec4* tangents = nullptr;
  int tangent_set = -1;  // the set the tangents were generated from; -1: the file's (Primitive)
  const glm::vec3* velocities = nullptr;  // world velocity per vertex: deforming geometry only
  const uint32_t* indices = nullptr;
  uint32_t material = 0;  // index into Impl::materials_
  int node = -1;
  // World-space static geometry of a node whose transform mirrors (negative determinant): glTF
  // then takes clockwise triangles as front faces, so the cross product of the edges points
  // to the back.
  bool flip_winding = false;
};

// A bottom-level Embree scene: all static geometry, one mesh shared by its moving nodes, or all
// deforming geometry.
struct Blas {
  RTCScene scene = nullptr;
  std::vector<GeomRecord> geoms;  // indexed by Embree geomID
};

// One instance in the top-level scene (indexed by its instID).
struct Instance {
  RTCGeometry geom = nullptr;
  int blas = 0;
  int node = -1;  // -1 for the static and the deforming instance
  bool moves = false;
  // Carries a world transform (world, normal_matrix, area_scale below): a moving instance, or a
  // static copy of a shared mesh (TracerOptions::max_copied_vertices), whose transform is set
  // once.
  bool transformed = false;
  bool enabled = true;
  glm::mat3 normal_matrix{1.0f};  // inverse transpose of the world transform's linear part
  float area_scale = 1.0f;   // |det| of that linear part: world area = it x |normal_matrix x n|
  glm::mat4 velocity{0.0f};  // maps a world point to its world velocity (affine)
  // A moving instance's world transform at the current time and its inverse (rigid_transform).
  glm::dmat4 world{1.0}, inverse_world{1.0};
};

// What one Embree ray query returned, whether from a single ray or a packet lane.
struct HitRef {
  float t = 0.0f;
  float u = 0.0f, v = 0.0f;
  unsigned geom = RTC_INVALID_GEOMETRY_ID;
  unsigned prim = 0;
  unsigned inst = RTC_INVALID_GEOMETRY_ID;
};

// A shading point in world space (without its material's own copy: Surface below).
struct SurfacePoint {
  glm::vec3 p{0.0f};
  glm::vec3 ng{0.0f, 0.0f, 1.0f};  // geometric normal, unit, toward the viewer when flipped
  glm::vec3 ns{0.0f, 0.0f, 1.0f};  // shading normal, unit
  // Where the material has a clear coat or anisotropy (only there: other surfaces do not pay
  // for it), the coat's normal (the interpolated normal, bent only by the coat's own normal
  // texture, ShadeMaterial::clearcoat_normal_map) and the anisotropy's directions.
  std::optional<shading::LayerFrame> layers;
  glm::vec2 uv{0.0f};  // in the base-color texture's set of coordinates (SlotUvs)
  const ShadeMaterial* material = nullptr;
  const Instance* instance = nullptr;
  const GeomRecord* geom = nullptr;
  const uint32_t* triangle = nullptr;  // the hit triangle's vertex indices
  glm::vec3 barycentric{0.0f};         // of the hit, weights of triangle[0], [1], [2]
  int node = -1;
  bool back_face = false;  // a single-sided surface seen from behind
  float opacity = 1.0f;    // alphaMode BLEND: the share of its own light it shows (opacity_at)
  // The ray cone (docs/scene-model.md, "Texture filtering"): its width at p, how fast it grows,
  // and the base-color texture's level of detail that width asks for.
  float cone = 0.0f;
  float spread = 0.0f;
  float lod = 0.0f;
};

// A shading point. Where its material varies over the surface (ShadeMaterial::varies),
// `material` points at `at_point`, the material decided at this point; a copy points at its
// own. (An optional: the surfaces of other materials, most of them, never construct one.)
struct Surface : SurfacePoint {
  std::optional<ShadeMaterial> at_point;

  Surface() = default;
  Surface(const Surface& o) : SurfacePoint(o) { repoint(o); }
  Surface& operator=(const Surface& o) {
    SurfacePoint::operator=(o);
    repoint(o);
    return *this;
  }

 private:
  void repoint(const Surface& o) {
    if (!o.at_point || o.material != &*o.at_point) return;
    at_point = o.at_point;
    material = &*at_point;
  }
};

// The media (KHR_materials_volume: glass with thickness > 0, ShadeMaterial::is_volume) a ray of
// the camera's path travels in, innermost last. Media nest: the innermost replaces those around
// it (a liquid in a glass), so a ray keeps the innermost one's absorption and an interface bends
// light by the ratio of the iors on its two sides. Empty: air (ior 1). A ray that leaves a
// medium it was not known to be in (a camera inside glass) was in it. Deeper nesting than
// kMax forgets the outermost.
struct Media {
  static constexpr int kMax = 4;
  std::array<const ShadeMaterial*, kMax> inside{};
  int n = 0;

  const ShadeMaterial* innermost() const { return n > 0 ? inside[size_t(n - 1)] : nullptr; }
  bool contains(const ShadeMaterial* m) const {
    return std::find(inside.begin(), inside.begin() + n, m) != inside.begin() + n;
  }
  // These media with m entered inside them.
  Media entered(const ShadeMaterial* m) const {
    Media r = *this;
    if (r.n == kMax) {
      std::copy(r.inside.begin() + 1, r.inside.end(), r.inside.begin());
      --r.n;
    }
    r.inside[size_t(r.n++)] = m;
    return r;
  }
  // These media with the innermost occurrence of m left (unchanged without one).
  Media left(const ShadeMaterial* m) const {
    Media r = *this;
    for (int k = r.n - 1; k >= 0; --k) {
      if (r.inside[size_t(k)] != m) continue;
      std::copy(r.inside.begin() + k + 1, r.inside.begin() + r.n, r.inside.begin() + k);
      --r.n;
      break;
    }
    return r;
  }
};

// One primitive of a deforming mesh node (Scene::node_geometry_moves): an Embree geometry whose
// vertex buffer, shared with `positions`, set_time rewrites in world space.
struct DeformingPrimitive {
  int node = -1;
  size_t primitive = 0;
  RTCGeometry geom = nullptr;        // owned by the deforming BLAS
  std::vector<glm::vec3> positions;  // one more than the vertices: Embree reads 16 bytes
  std::vector<glm::vec3> normals;
  std::vector<glm::vec4> tangents;  // where the primitive has them (Primitive::tangents)
  std::vector<glm::vec3> velocities;
  bool enabled = true;  // false while its node is hidden (Scene::node_hidden)
  glm::vec4* tangents_or_null() { return tangents.empty() ? nullptr : tangents.data(); }
};

// What the direct-light loop needs of one shading point, computed once for all lights.
struct LocalTerms {
  glm::vec3 diffuse{0.0f};  // base (1 - metallic)
  glm::vec3 f0{0.0f};
  glm::vec3 origin{0.0f};  // of shadow rays: off the surface on the side it faces
  float offset = 0.0f;
  float n_dot_v = 1.0f;
  float beneath_sheen = 1.0f;  // shading::sheen_scaling at n.v (1 without sheen)
};

void init_ray(RTCRay* r, const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) {
  r->org_x = o.x;
  r->org_y = o.y;
  r->org_z = o.z;
  r->tnear = tnear;
  r->dir_x = d.x;
  r->dir_y = d.y;
  r->dir_z = d.z;
  r->time = 0.0f;
  r->tfar = tfar;
  r->mask = 0xffffffffu;
  r->id = 0;
  r->flags = 0;
}

// Every lane of a packet is set, the inactive ones too: Embree computes on all lanes, and
// uninitialised garbage there made packets twice as slow as single rays (measured with
// afr-bench-tracer on the kitchen).
void set_lane(RTCRay8* r, int k, const glm::vec3& o, const glm::vec3& d, float tfar) {
  r->org_x[k] = o.x;
  r->org_y[k] = o.y;
  r->org_z[k] = o.z;
  r->tnear[k] = 0.0f;
  r->dir_x[k] = d.x;
  r->dir_y[k] = d.y;
  r->dir_z[k] = d.z;
  r->time[k] = 0.0f;
  r->tfar[k] = tfar;
  r->mask[k] = 0xffffffffu;
  r->id[k] = unsigned(k);
  r->flags[k] = 0;
}

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

// ---- Shadows through glass and blended surfaces ----
//
// A shadow ray passes through glass, dimmed by each glass surface it crosses
// (ShadeMaterial::shadow_transmittance): a Whitted-style filter shadow, as BART's scenes
// expect of their light behind a glass ceiling: transmission x (1 - metallic) x base color,
// where the transmission and the base color are, as for the camera's rays, the factors times
// the textures (level 0) and COLOR_0 at the point (GeometryFilter::glass_transmittance). The
// shadow ray is not refracted, and Fresnel does not dim it. It passes a blended surface (alphaMode
// BLEND) dimmed by its opacity a at the point: 1 - a goes through, and the rest as through that
// surface's glass, if it is glass. Embree reports each such surface on the ray's way to
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
constexpr unsigned kShadowRayId = 0x5ad0u;
constexpr float kShadowCutoff = 1e-3f;  // a ray dimmer than this is blocked

struct ShadowContext {
  RTCIntersectContext embree;  // first: Embree hands the filter this address
  static constexpr int kLanes = 8;
  static constexpr int kMaxCrossed = 16;  // more glass surfaces than this: blocked
  struct Crossed {
    unsigned inst, geom, prim;
    float t;  // the distance along the ray
  };
  glm::vec3 transmittance[kLanes];
  Crossed crossed[kLanes][kMaxCrossed];
  int n_crossed[kLanes];
  uint32_t volume_lanes = 0;  // bit k: lane k crossed glass that absorbs (volume_transmittance)

  ShadowContext() {
    rtcInitIntersectContext(&embree);
    for (int k = 0; k < kLanes; ++k) {
      transmittance[k] = glm::vec3(1.0f);
      n_crossed[k] = 0;
    }
  }
};
static_assert(offsetof(ShadowContext, embree) == 0);

// The opacity of a masked or blended material at barycentrics (u, v) of triangle `tri`: the base
// color factor's alpha x the texture's alpha (level 0, bilinear: a mip level would average a
// cutout's edge away) x COLOR_0's alpha. uvs and color_alpha may be null (none).
float opacity_at(const shading::ShadeMaterial& m, SlotCoords uvs, const float* color_alpha,
                 const uint32_t* tri, float u, float v) {
  float opacity = m.opacity_factor;
  if (m.opacity_texture && uvs) opacity *= m.opacity_texture->sample_alpha(uvs.at(m, tri, u, v));
  if (color_alpha) {
    opacity *=
        (1.0f - u - v) * color_alpha[tri[0]] + u * color_alpha[tri[1]] + v * color_alpha[tri[2]];
  }
  return opacity;
}

// What the filters of one Embree geometry read (its user data): its material, and, for a
// masked material, the texture coordinates and triangles that place a hit in its texture.
struct GeometryFilter {
  const shading::ShadeMaterial* material = nullptr;
  bool masked = false;  // the material's `masked`, or a vertex alpha (color_alpha) it tests
  SlotCoords uvs;       // the base color's (none: the factor alone decides)
  const float* color_alpha = nullptr;  // COLOR_0's alpha per vertex, or null
  const uint32_t* indices = nullptr;
  // Glass whose shadow transmittance varies over it (a base-color or transmission texture with
  // coordinates, or COLOR_0), with what places a hit in its textures and colors.
  bool textured_glass = false;
  SlotCoords transmission_uvs;
  const glm::vec3* colors = nullptr;  // COLOR_0 per vertex, or null

  // What a shadow ray keeps of the light crossing the glass at the hit: the material's
  // shadow_transmittance, or with textures and colors their values there multiplied in.
  glm::vec3 glass_transmittance(const RTCFilterFunctionNArguments* args, unsigned i) const {
    const shading::ShadeMaterial& m = *material;
    if (!textured_glass) return m.shadow_transmittance;
    const uint32_t* tri = indices + 3 * size_t(RTCHitN_primID(args->hit, args->N, i));
    const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
    const float w = 1.0f - u - v;
    const auto at = [&](const auto* values) {
      return w * values[tri[0]] + u * values[tri[1]] + v * values[tri[2]];
    };
    glm::vec3 base = m.base;
    if (m.texture && uvs) base *= m.texture->sample(uvs.at(m, tri, u, v), 0.0f);
    if (colors) base *= at(colors);
    float transmission = m.transmission_factor;
    if (m.transmission_texture && transmission_uvs) {
      transmission *= m.transmission_texture->sample(transmission_uvs.at(m, tri, u, v), 0.0f).r;
    }
    return glm::clamp(glm::clamp(transmission, 0.0f, 1.0f) * (1.0f - m.metallic_factor) * base,
                      glm::vec3(0.0f), glm::vec3(1.0f));
  }

  float opacity(const RTCFilterFunctionNArguments* args, unsigned i) const {
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    return opacity_at(*material, uvs, color_alpha, indices + 3 * size_t(prim),
                      RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
  }
  // alphaMode MASK: whether the hit is kept; BLEND: whether anything of it shows.
  bool opaque_at(const RTCFilterFunctionNArguments* args, unsigned i) const {
    const float a = opacity(args, i);
    return material->blended ? a > 0.0f : a >= material->opacity_cutoff;
  }
};

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
// point, and shadow rays through glass and blended surfaces.
void occlusion_filter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const GeometryFilter*>(args->geometryUserPtr);
  const shading::ShadeMaterial& m = *f->material;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    if (m.blended && f->masked) {
      const float a = f->opacity(args, i);
      const glm::vec3 glass = m.is_glass ? f->glass_transmittance(args, i) : glm::vec3(0.0f);
      if (!(a > 0.0f) || crosses(args, i, (1.0f - a) + a * glass, false)) args->valid[i] = 0;
    } else if (f->masked && !f->opaque_at(args, i)) {
      args->valid[i] = 0;
    } else if (m.is_glass && crosses(args, i, f->glass_transmittance(args, i), m.has_volume)) {
      args->valid[i] = 0;
    }
  }
}

// The intersection filter of a masked geometry: a ray goes on through a cut-away point.
void mask_filter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const GeometryFilter*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == -1 && !f->opaque_at(args, i)) args->valid[i] = 0;
  }
}

void error_callback(void* /*user*/, RTCError code, const char* message) {
  spdlog::error("embree error {}: {}", int(code), message ? message : "");
}

// Column-major 3x4 for rtcSetGeometryTransform.
void to_float3x4(const glm::dmat4& m, float out[12]) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) out[c * 3 + r] = float(m[c][r]);
}

}  // namespace

// =============================================================================================
// Impl

struct Tracer::Impl {
  Scene scene_;
  TracerOptions options_;
  RTCDevice device_ = nullptr;
  RTCScene top_ = nullptr;
  std::vector<Blas> blas_;
  std::vector<Instance> instances_;
  std::vector<int> moving_instance_of_node_;  // per scene node: its moving instance or -1
  std::vector<ShadeMaterial> materials_;      // scene materials, then the default material
  // Per scene material, its sets' animated texture transforms at this time (empty: none),
  // which its ShadeMaterial's uv_transforms points at (use_uv_transforms).
  std::vector<std::vector<shading::UvAffine>> uv_transforms_;
  void use_uv_transforms(size_t i, const Material& m) {
    uv_transforms_[i].clear();
    for (const Material::UvTransform& t : m.uv_transforms) uv_transforms_[i].emplace_back(t);
    if (!m.uv_transforms.empty()) materials_[i].uv_transforms = uv_transforms_[i].data();
  }
  bool has_translucent_ = false;  // glass or blended geometry lets shadow rays through (crosses)
  // Per material, whether an animation drives its transmission (KHR_animation_pointer): it may
  // be glass at some times and not at others, so its geometry carries the glass filter, which
  // asks the material of the time (set_filters).
  std::vector<char> animated_transmission_;
  std::deque<GeometryFilter> filters_;  // the user data of masked and glass geometries
  std::vector<int> light_nodes_;        // scene nodes that carry a light
  std::vector<int> camera_lights_;      // lights on the camera (Light::on_camera)
  std::vector<LightRecord> lights_;     // placed at the current time: nodes', then camera's
  size_t node_light_count_ = 0;         // how many of lights_ come from nodes
  // Static geometry transformed to world space (GeomRecord points into these).
  std::vector<std::vector<glm::vec3>> static_positions_;
  std::vector<std::vector<glm::vec3>> static_normals_;
  std::vector<std::vector<glm::vec4>> static_tangents_;  // world space, where a primitive has them
  // Deforming geometry, in one BLAS (deforming_blas_, -1 when there is none) refitted at every
  // set_time; positions at the two times of the velocity's difference quotient.
  std::vector<DeformingPrimitive> deforming_;
  int deforming_blas_ = -1;
  int deforming_instance_ = -1;
  std::vector<glm::vec3> positions_before_, positions_after_;
  SceneState state_, state_minus_, state_plus_;
  Camera camera_;
  // The scene's size (largest coordinate at time 0), at most 1: the part of a ray offset that
  // does not grow with the hit point. A fixed 1 would exceed the whole of a scene in
  // micrometres, so that shadow rays started beyond every blocker.
  float offset_floor_ = 1.0f;

  Impl(const Scene& scene, const TracerOptions& options);
  ~Impl() { release(); }
  void release();

  void check_device(const char* what) const;
  // Sets the filters of geometry g of primitive p (glTF's alphaMode MASK, glass) where its
  // material needs them.
  void set_filters(RTCGeometry g, uint32_t material, const Primitive& p);
  // A GeomRecord with what comes straight from primitive p and its material (an index into
  // materials_): texture coordinates, colors, tested vertex alpha, indices. The caller sets the
  // positions and what follows from them.
  GeomRecord record_of(const Primitive& p, uint32_t material) const {
    GeomRecord r;
    r.uvs = slot_uvs(p);
    r.colors = p.colors.size() == p.positions.size() ? p.colors.data() : nullptr;
    r.tangent_set = p.tangent_set;
    r.color_alpha = tested_alpha(p, material);
    r.indices = p.indices.data();
    r.material = material;
    return r;
  }
  // p's texture coordinates for each slot of its material (the default material has none).
  SlotUvs slot_uvs(const Primitive& p) const {
    const bool own = p.material >= 0 && size_t(p.material) < scene_.materials.size();
    const Material::TextureSets sets =
        own ? scene_.materials[size_t(p.material)].uv_set : Material::TextureSets{};
    return SlotUvs{uv_data(p, sets.base_color),
                   uv_data(p, sets.metallic_roughness),
                   uv_data(p, sets.emissive),
                   uv_data(p, sets.occlusion),
                   uv_data(p, sets.normal),
                   uv_data(p, sets.transmission),
                   uv_data(p, sets.specular),
                   uv_data(p, sets.specular_color),
                   uv_data(p, sets.clearcoat),
                   uv_data(p, sets.clearcoat_roughness),
                   uv_data(p, sets.clearcoat_normal),
                   uv_data(p, sets.sheen_color),
                   uv_data(p, sets.sheen_roughness),
                   uv_data(p, sets.anisotropy),
                   uv_data(p, sets.glossiness),
                   uv_data(p, sets.iridescence),
                   uv_data(p, sets.iridescence_thickness),
                   uv_data(p, sets.diffuse_transmission),
                   uv_data(p, sets.diffuse_transmission_color)};
  }
  // p's COLOR_0 alpha where its material (an index into materials_) tests alpha, else null.
  const float* tested_alpha(const Primitive& p, uint32_t material) const {
    return materials_[material].alpha_tested && p.color_alpha.size() == p.positions.size()
               ? p.color_alpha.data()
               : nullptr;
  }
  RTCGeometry new_triangle_geometry(uint32_t material, const Primitive& p,
                                    const glm::vec3* positions, size_t vertex_count,
                                    const uint32_t* indices, size_t triangle_count);
  void build();
  void build_deforming(const std::vector<int>& nodes, uint32_t default_material);
  void deform(double before, double after);
  void set_time(double t);
  // Whether world-space triangles of node n's mesh take clockwise faces as front faces: its
  // world transform mirrors (glTF 2.0, 3.7.4). A skin's joints decide a skinned mesh's
  // placement, and its own transform is ignored: never for it.
  bool flips_winding(int n, const SceneState& state) const {
    if (scene_.nodes[size_t(n)].skin != -1) return false;
    return glm::determinant(glm::dmat3(state.world[size_t(n)])) < 0.0;
  }
  void place_camera_lights(const Camera& camera);

  // ---- queries (const, thread-safe) ----
  HitRef intersect(const glm::vec3& o, const glm::vec3& d, float tnear) const;
  bool blocked(const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) const;
  // What a shadow ray from o along d (unit) up to tfar keeps: 0 when an opaque surface blocks
  // it, the product of the glass surfaces' transmittances it crosses otherwise. Scenes without
  // glass or blending ask only whether it is blocked.
  glm::vec3 shadow_transmittance(const glm::vec3& o, const glm::vec3& d, float tfar) const {
    if (!has_translucent_) return blocked(o, d, 0.0f, tfar) ? glm::vec3(0.0f) : glm::vec3(1.0f);
    return filtered_shadow(o, d, tfar);
  }
  // Out of line, so that scenes without glass, and shadow rays that cross no absorbing glass,
  // pay nothing for them.
  [[gnu::noinline]] glm::vec3 filtered_shadow(const glm::vec3& o, const glm::vec3& d,
                                              float tfar) const;
  [[gnu::noinline]] glm::vec3 volume_transmittance(const ShadowContext& ctx, int lane,
                                                   const glm::vec3& d, float tfar) const;
  // The surface of `hit` on the ray from o along d, whose cone was `cone` wide at o and grows by
  // `spread` per unit of distance.
  void make_surface(const HitRef& hit, const glm::vec3& o, const glm::vec3& d, float cone,
                    float spread, Surface* s) const;
  // The base color's multiplier at s: its material's texture (1 without one) times the
  // primitive's interpolated vertex colors (1 without them).
  glm::vec3 texture_color(const Surface& s) const;
  bool prepare_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex, glm::vec3* c,
                     LocalTerms* terms) const;
  bool light_contribution(const LightRecord& light, const Surface& s, const LocalTerms& terms,
                          const glm::vec3& wo, glm::vec3* contribution, glm::vec3* origin,
                          glm::vec3* l, float* shadow_tfar) const;
  glm::vec3 shade_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex,
                        TraceStats* stats) const;
  void shade_local8(const Surface* s, const glm::vec3* wo, const glm::vec3* tex, const bool* hit,
                    int n, glm::vec3* out, TraceStats* stats) const;
  // The camera's rays start in air; `media` is what a secondary ray travels in.
  glm::vec3 mirror_chain(glm::vec3 d, Surface s, glm::vec3 tex, TraceStats* stats, int depth = 0,
                         glm::vec3 throughput = glm::vec3(1.0f), const Media& media = {}) const;
  // Out of line, so that the mirror chain of scenes without glass compiles as it did.
  [[gnu::noinline]] glm::vec3 pass_through(const glm::vec3& d, const Surface& s, int depth,
                                           const glm::vec3& throughput, const Media& media,
                                           TraceStats* stats) const;
  [[gnu::noinline]] glm::vec3 glass(const glm::vec3& d, const Surface& s, const glm::vec3& tex,
                                    int depth, const glm::vec3& throughput, const Media& media,
                                    TraceStats* stats) const;
  glm::vec3 secondary(const glm::vec3& origin, const glm::vec3& d, const Surface& from, int depth,
                      const glm::vec3& throughput, const Media& media, TraceStats* stats) const;
  bool begin_sample(const Ray& ray, const HitRef& hit, ShadedSample* o, Surface* s,
                    TraceStats* stats) const;
  void sanitize(ShadedSample* o, TraceStats* stats) const;
  // The offset that keeps a ray leaving the surface at p from hitting that surface again.
  float offset_at(const glm::vec3& p) const { return kRayOffset * (offset_floor_ + max_abs(p)); }
  void finish(const Ray& ray, const HitRef& hit, ShadedSample* out, TraceStats* stats) const;
};

Tracer::Impl::Impl(const Scene& scene, const TracerOptions& options)
    : scene_(scene), options_(options) {
  if (scene.ray_depth) options_.max_mirror_depth = *scene.ray_depth;
  glm::dvec3 lo, hi;
  scene_.bounds(scene_.evaluate(0.0), &lo, &hi);
  const glm::dvec3 m = glm::max(glm::abs(lo), glm::abs(hi));
  const double extent = std::max(m.x, std::max(m.y, m.z));
  offset_floor_ = float(std::clamp(extent, 1e-30, 1.0));
  if (options_.embree_threads < 0) {
    throw Error(fmt::format("tracer: {} Embree threads (0 for Embree's default, or more)",
                            options_.embree_threads));
  }
  const std::string config = options_.embree_threads > 0
                                 ? fmt::format("verbose=0,threads={}", options_.embree_threads)
                                 : std::string("verbose=0");
  device_ = rtcNewDevice(config.c_str());
  if (!device_)
    throw Error("embree: cannot create a device (error " +
                std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(device_, error_callback, nullptr);
  try {
    build();
    set_time(0.0);
  } catch (...) {
    release();  // the destructor does not run when the constructor throws
    throw;
  }
}

void Tracer::Impl::release() {
  for (Instance& inst : instances_)
    if (inst.geom) rtcReleaseGeometry(inst.geom);
  instances_.clear();
  if (top_) rtcReleaseScene(top_);
  top_ = nullptr;
  for (Blas& b : blas_)
    if (b.scene) rtcReleaseScene(b.scene);
  blas_.clear();
  if (device_) rtcReleaseDevice(device_);
  device_ = nullptr;
}

void Tracer::Impl::check_device(const char* what) const {
  const RTCError e = rtcGetDeviceError(device_);
  if (e != RTC_ERROR_NONE)
    throw Error(std::string("embree: ") + what + " failed (error " + std::to_string(int(e)) +
                ") for scene " + scene_.source);
}

void Tracer::Impl::set_filters(RTCGeometry g, uint32_t material, const Primitive& p) {
  AFR_DCHECK(material < materials_.size());
  const shading::ShadeMaterial& m = materials_[material];
  const float* vertex_alpha = tested_alpha(p, material);
  const bool masked = m.masked || vertex_alpha;
  const bool glass = m.is_glass || animated_transmission_[material];
  if (!glass && !masked) return;
  has_translucent_ |= glass || (m.blended && masked);
  GeometryFilter& f = filters_.emplace_back();
  f.material = &m;
  f.masked = masked;
  const SlotUvs uvs = slot_uvs(p);
  f.uvs = uvs.base_color;
  f.color_alpha = vertex_alpha;
  f.indices = p.indices.data();
  if (glass) {
    // (A material that is not glass now has no transmission texture yet: the scene's says.)
    const bool transmission_texture =
        material < scene_.materials.size() && scene_.materials[material].transmission_texture >= 0;
    f.transmission_uvs = uvs.transmission;
    f.colors = p.colors.size() == p.positions.size() ? p.colors.data() : nullptr;
    f.textured_glass =
        (m.texture && f.uvs) || (transmission_texture && f.transmission_uvs) || f.colors != nullptr;
  }
  rtcSetGeometryUserData(g, &f);
  rtcSetGeometryOccludedFilterFunction(g, &occlusion_filter);
  if (masked) rtcSetGeometryIntersectFilterFunction(g, &mask_filter);
}

RTCGeometry Tracer::Impl::new_triangle_geometry(uint32_t material, const Primitive& p,
                                                const glm::vec3* positions, size_t vertex_count,
                                                const uint32_t* indices, size_t triangle_count) {
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  // Embree's own buffers carry the padding its SIMD loads need.
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count));
  auto* i = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), triangle_count));
  if (!v || !i) {
    rtcReleaseGeometry(g);
    check_device("allocating a vertex buffer");
    throw Error("embree: cannot allocate geometry buffers for scene " + scene_.source);
  }
  std::copy_n(&positions[0].x, 3 * vertex_count, v);
  std::copy_n(indices, 3 * triangle_count, i);
  set_filters(g, material, p);
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  rtcCommitGeometry(g);
  return g;
}

// ---------------------------------------------------------------------------------------------
// Building: one BLAS of all static geometry in world space, one BLAS per mesh that a moving
// node carries or that static nodes share beyond TracerOptions::max_copied_vertices, and a top
// level of instances.

void Tracer::Impl::build() {
  const uint32_t default_material = uint32_t(scene_.materials.size());
  materials_.reserve(scene_.materials.size() + 1);
  for (const Material& m : scene_.materials)
    materials_.push_back(shading::make_shade_material(&m, scene_, options_.mirror_roughness));
  materials_.push_back(shading::make_shade_material(nullptr, scene_, options_.mirror_roughness));
  uv_transforms_.resize(scene_.materials.size());
  for (size_t i = 0; i < scene_.materials.size(); ++i) use_uv_transforms(i, scene_.materials[i]);
  // An animated material is made again at each time (set_time); where its alpha is tested, its
  // opacity may cross the cutoff, so its geometry gets the opacity filter whatever the factor
  // is now.
  for (int i : scene_.animated_materials()) {
    if (materials_[size_t(i)].alpha_tested) materials_[size_t(i)].masked = true;
  }
  animated_transmission_.assign(materials_.size(), 0);
  for (const PropertyChannel& c : scene_.property_channels) {
    if (c.property == AnimatedProperty::kTransmissionFactor) {
      animated_transmission_[size_t(c.index)] = 1;
    }
  }
  auto material_of = [&](const Primitive& p) {
    return p.material >= 0 && size_t(p.material) < scene_.materials.size() ? uint32_t(p.material)
                                                                           : default_material;
  };
  auto usable = [](const Primitive& p) { return p.triangle_count() > 0 && !p.positions.empty(); };

  const SceneState at0 = scene_.evaluate(0.0);
  top_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(top_, RTC_BUILD_QUALITY_LOW);
  rtcSetSceneFlags(top_, RTC_SCENE_FLAG_DYNAMIC);

  // The static BLAS, pre-transformed to world space.
  Blas statics;
  statics.scene = rtcNewScene(device_);
  std::vector<int> mesh_blas(scene_.meshes.size(), -1);
  std::vector<int> moving_nodes;
  std::vector<int> deforming_nodes;
  std::vector<int> shared_static_nodes;  // static copies of a mesh instanced, not copied
  // The static, undeformed nodes that carry each mesh: a mesh whose copies beyond the first
  // would hold more than max_copied_vertices is instanced.
  std::vector<size_t> static_copies(scene_.meshes.size(), 0);
  // A node whose visibility varies is placed as a moving one (its instance, or its deformed
  // geometry, is left out while it is hidden: set_time); one hidden for good is left out here.
  auto moves = [&](int n) { return scene_.node_moves(n) || scene_.node_visibility_varies(n); };
  auto geometry_moves = [&](int n) {
    return scene_.node_geometry_moves(n) || scene_.node_visibility_varies(n);
  };
  auto shown = [&](int n) {
    return scene_.node_visibility_varies(n) || !scene_.node_hidden(at0, n);
  };
  for (int n : scene_.scene_nodes()) {
    const Node& node = scene_.nodes[size_t(n)];
    if (node.mesh >= 0 && !scene_.node_deforms(n) && !moves(n) && shown(n)) {
      ++static_copies[size_t(node.mesh)];
    }
  }
  std::vector<char> mesh_shared(scene_.meshes.size(), 0);
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    size_t vertices = 0;
    for (const Primitive& p : scene_.meshes[m].primitives) vertices += p.positions.size();
    const size_t copies = static_copies[m];
    mesh_shared[m] = copies > 1 && (copies - 1) * vertices > options_.max_copied_vertices;
  }
  for (int n : scene_.scene_nodes()) {
    const Node& node = scene_.nodes[size_t(n)];
    if (!shown(n)) continue;
    if (node.light >= 0 && size_t(node.light) < scene_.lights.size()) light_nodes_.push_back(n);
    if (node.mesh < 0) continue;
    const bool deformed = scene_.node_deforms(n);
    if (deformed && geometry_moves(n)) {
      deforming_nodes.push_back(n);
      continue;
    }
    if (!deformed && moves(n)) {
      moving_nodes.push_back(n);
      continue;
    }
    if (!deformed && mesh_shared[size_t(node.mesh)]) {
      shared_static_nodes.push_back(n);
      continue;
    }
    // Static: a deformed mesh that does not move is deformed once, here.
    const glm::dmat4& world = at0.world[size_t(n)];
    const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
    const std::vector<Primitive>& primitives = scene_.meshes[size_t(node.mesh)].primitives;
    for (size_t pi = 0; pi < primitives.size(); ++pi) {
      const Primitive& p = primitives[pi];
      if (!usable(p)) continue;
      std::vector<glm::vec3> positions(p.positions.size());
      std::vector<glm::vec3> normals;
      std::vector<glm::vec4> tangents;
      if (deformed) {
        normals.resize(p.positions.size());
        tangents.resize(p.tangents.size() == p.positions.size() ? p.tangents.size() : 0);
        scene_.deform(n, pi, at0, positions.data(), normals.data(),
                      tangents.empty() ? nullptr : tangents.data());
      } else {
        for (size_t i = 0; i < positions.size(); ++i)
          positions[i] = glm::vec3(world * glm::dvec4(glm::dvec3(p.positions[i]), 1.0));
        if (p.normals.size() == p.positions.size()) {
          normals.resize(p.normals.size());
          // Not normalised here: a zero normal must stay zero so shading can detect it.
          for (size_t i = 0; i < normals.size(); ++i)
            normals[i] = glm::vec3(normal_matrix * glm::dvec3(p.normals[i]));
        }
        if (p.tangents.size() == p.positions.size()) {
          // Tangents turn with the surface; a mirroring transform turns the bitangent's sign.
          const glm::dmat3 linear(world);
          const float mirror = glm::determinant(linear) < 0.0 ? -1.0f : 1.0f;
          tangents.resize(p.tangents.size());
          for (size_t i = 0; i < tangents.size(); ++i) {
            tangents[i] = glm::vec4(glm::vec3(linear * glm::dvec3(glm::vec3(p.tangents[i]))),
                                    p.tangents[i].w * mirror);
          }
        }
      }
      RTCGeometry g = new_triangle_geometry(material_of(p), p, positions.data(), positions.size(),
                                            p.indices.data(), p.triangle_count());
      rtcAttachGeometryByID(statics.scene, g, unsigned(statics.geoms.size()));
      rtcReleaseGeometry(g);
      static_positions_.push_back(std::move(positions));
      static_normals_.push_back(std::move(normals));
      static_tangents_.push_back(std::move(tangents));
      GeomRecord r = record_of(p, material_of(p));
      r.positions = static_positions_.back().data();
      r.normals = static_normals_.back().empty() ? nullptr : static_normals_.back().data();
      r.tangents = static_tangents_.back().empty() ? nullptr : static_tangents_.back().data();
      r.node = n;
      r.flip_winding = flips_winding(n, at0);
      statics.geoms.push_back(r);
    }
  }
  if (!statics.geoms.empty()) {
    rtcSetSceneBuildQuality(statics.scene, RTC_BUILD_QUALITY_HIGH);
    rtcCommitScene(statics.scene);
    check_device("building the static BVH");
    blas_.push_back(std::move(statics));
    Instance inst;
    inst.blas = 0;
    instances_.push_back(inst);
  } else {
    rtcReleaseScene(statics.scene);
  }

  // One BLAS per mesh of a moving node or of shared static copies, in the mesh's own space;
  // false where the mesh has no triangles.
  const auto mesh_bvh = [&](int mesh) {
    if (mesh_blas[size_t(mesh)] >= 0) return true;
    Blas b;
    b.scene = rtcNewScene(device_);
    for (const Primitive& p : scene_.meshes[size_t(mesh)].primitives) {
      if (!usable(p)) continue;
      RTCGeometry g =
          new_triangle_geometry(material_of(p), p, p.positions.data(), p.positions.size(),
                                p.indices.data(), p.triangle_count());
      rtcAttachGeometryByID(b.scene, g, unsigned(b.geoms.size()));
      rtcReleaseGeometry(g);
      GeomRecord r = record_of(p, material_of(p));
      r.positions = p.positions.data();
      r.normals = p.normals.size() == p.positions.size() ? p.normals.data() : nullptr;
      r.tangents = p.tangents.size() == p.positions.size() ? p.tangents.data() : nullptr;
      b.geoms.push_back(r);
    }
    if (b.geoms.empty()) {
      rtcReleaseScene(b.scene);
      return false;
    }
    rtcSetSceneBuildQuality(b.scene, RTC_BUILD_QUALITY_HIGH);
    rtcCommitScene(b.scene);
    check_device("building a mesh BVH");
    mesh_blas[size_t(mesh)] = int(blas_.size());
    blas_.push_back(std::move(b));
    return true;
  };
  for (int n : moving_nodes) {
    const int mesh = scene_.nodes[size_t(n)].mesh;
    if (!mesh_bvh(mesh)) continue;
    Instance inst;
    inst.blas = mesh_blas[size_t(mesh)];
    inst.node = n;
    inst.moves = true;
    inst.transformed = true;
    instances_.push_back(inst);
  }
  for (int n : shared_static_nodes) {
    const int mesh = scene_.nodes[size_t(n)].mesh;
    const glm::dmat4& world = at0.world[size_t(n)];
    const glm::dmat3 linear(world);
    const double det = glm::determinant(linear);
    // A singular transform (a scale of 0 hides an object) has no inverse for the ray: as a
    // moving instance's, the copy is left out.
    if (!(std::isfinite(det) && std::abs(det) > 1e-30) || !mesh_bvh(mesh)) continue;
    Instance inst;
    inst.blas = mesh_blas[size_t(mesh)];
    inst.node = n;
    inst.transformed = true;
    inst.world = world;
    inst.inverse_world = glm::inverse(world);
    inst.normal_matrix = glm::mat3(glm::transpose(glm::inverse(linear)));
    inst.area_scale = float(std::abs(det));
    instances_.push_back(inst);
  }
  build_deforming(deforming_nodes, default_material);

  for (size_t l = 0; l < scene_.lights.size(); ++l) {
    if (scene_.lights[l].on_camera) camera_lights_.push_back(int(l));
  }
  lights_.reserve(light_nodes_.size() + camera_lights_.size());

  moving_instance_of_node_.assign(scene_.nodes.size(), -1);
  for (size_t i = 0; i < instances_.size(); ++i) {
    Instance& inst = instances_[i];
    if (inst.moves && inst.node >= 0) moving_instance_of_node_[size_t(inst.node)] = int(i);
    inst.geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(inst.geom, blas_[size_t(inst.blas)].scene);
    // A moving instance's transform is set at each time (set_time); a shared static copy's
    // here; the static and the deforming instance are in world space already.
    float xfm[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    if (inst.transformed && !inst.moves) to_float3x4(inst.world, xfm);
    rtcSetGeometryTransform(inst.geom, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
    rtcCommitGeometry(inst.geom);
    rtcAttachGeometryByID(top_, inst.geom, unsigned(i));
  }
  check_device("building the instances");
}

// One BLAS of all deforming geometry in world space: Embree's two-level build (scene quality
// LOW) with a BVH per primitive that set_time refits (geometry quality REFIT) instead of
// rebuilding, since only vertex positions change. The BVH is built once over the positions at
// time 0, so that its topology fits the shape.
void Tracer::Impl::build_deforming(const std::vector<int>& nodes, uint32_t default_material) {
  size_t max_vertices = 0;
  for (int n : nodes) {
    const std::vector<Primitive>& primitives =
        scene_.meshes[size_t(scene_.nodes[size_t(n)].mesh)].primitives;
    for (size_t pi = 0; pi < primitives.size(); ++pi) {
      const size_t count = primitives[pi].positions.size();
      if (primitives[pi].triangle_count() == 0 || count == 0) continue;
      DeformingPrimitive d;
      d.node = n;
      d.primitive = pi;
      d.positions.assign(count + 1, glm::vec3(0.0f));
      d.normals.assign(count, glm::vec3(0.0f));
      if (primitives[pi].tangents.size() == count) d.tangents.assign(count, glm::vec4(0.0f));
      d.velocities.assign(count, glm::vec3(0.0f));
      deforming_.push_back(std::move(d));
      max_vertices = std::max(max_vertices, count);
    }
  }
  if (deforming_.empty()) return;
  positions_before_.resize(max_vertices);
  positions_after_.resize(max_vertices);
  scene_.evaluate(0.0, &state_);

  Blas b;
  b.scene = rtcNewScene(device_);
  rtcSetSceneFlags(b.scene, RTC_SCENE_FLAG_DYNAMIC);
  rtcSetSceneBuildQuality(b.scene, RTC_BUILD_QUALITY_LOW);
  for (DeformingPrimitive& d : deforming_) {
    const Primitive& p =
        scene_.meshes[size_t(scene_.nodes[size_t(d.node)].mesh)].primitives[d.primitive];
    scene_.deform(d.node, d.primitive, state_, d.positions.data(), d.normals.data(),
                  d.tangents_or_null());
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, d.positions.data(),
                               0, sizeof(glm::vec3), d.normals.size());
    auto* i = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), p.triangle_count()));
    if (!i) {
      rtcReleaseGeometry(g);
      check_device("allocating an index buffer");
      throw Error("embree: cannot allocate geometry buffers for scene " + scene_.source);
    }
    std::copy_n(p.indices.data(), 3 * p.triangle_count(), i);
    const uint32_t material = p.material >= 0 && size_t(p.material) < scene_.materials.size()
                                  ? uint32_t(p.material)
                                  : default_material;
    set_filters(g, material, p);
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(b.scene, g, unsigned(b.geoms.size()));
    rtcReleaseGeometry(g);  // the BLAS holds it as long as d.geom is used
    d.geom = g;
    GeomRecord r = record_of(p, material);
    r.positions = d.positions.data();
    r.normals = d.normals.data();
    r.tangents = d.tangents_or_null();
    r.velocities = d.velocities.data();
    r.node = d.node;
    r.flip_winding = flips_winding(d.node, state_);
    b.geoms.push_back(r);
  }
  rtcCommitScene(b.scene);
  check_device("building the deforming BVH");
  deforming_blas_ = int(blas_.size());
  blas_.push_back(std::move(b));
  Instance inst;
  inst.blas = deforming_blas_;
  deforming_instance_ = int(instances_.size());
  instances_.push_back(inst);
}

// Deforming geometry at the current time (state_), with per-vertex velocities by the
// difference quotient of the positions at `before` and `after` (state_minus_, state_plus_).
void Tracer::Impl::deform(double before, double after) {
  const float inverse_dt = float(1.0 / (after - before));
  Blas& b = blas_[size_t(deforming_blas_)];
  for (size_t k = 0; k < deforming_.size(); ++k) {
    DeformingPrimitive& d = deforming_[k];
    const bool show = !scene_.node_hidden(state_, d.node);
    set_enabled(d.geom, show, &d.enabled);
    if (!show) continue;  // deformed again once shown
    const size_t count = d.normals.size();
    scene_.deform(d.node, d.primitive, state_minus_, positions_before_.data(), nullptr);
    scene_.deform(d.node, d.primitive, state_plus_, positions_after_.data(), nullptr);
    scene_.deform(d.node, d.primitive, state_, d.positions.data(), d.normals.data(),
                  d.tangents_or_null());
    for (size_t v = 0; v < count; ++v) {
      d.velocities[v] = (positions_after_[v] - positions_before_[v]) * inverse_dt;
    }
    b.geoms[k].flip_winding = flips_winding(d.node, state_);
    rtcUpdateGeometryBuffer(d.geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(d.geom);
  }
  rtcCommitScene(b.scene);
  rtcCommitGeometry(instances_[size_t(deforming_instance_)].geom);
}

void Tracer::Impl::set_time(double t) {
  scene_.evaluate(t, &state_);
  const bool moving = !deforming_.empty() || std::any_of(instances_.begin(), instances_.end(),
                                                         [](const Instance& i) { return i.moves; });
  // The velocity's difference quotient: central, except at the ends of the keyframe range
  // [0, duration], where a central difference would straddle a clamped state and halve the
  // velocity (at t = 0, where every run starts): one-sided there.
  double before = t - kVelocityDt, after = t + kVelocityDt;
  if (t >= 0.0 && before < 0.0) before = 0.0;
  if (t <= scene_.duration() && after > scene_.duration()) after = scene_.duration();
  if (after <= before) {  // a range shorter than the step: central
    before = t - kVelocityDt;
    after = t + kVelocityDt;
  }
  if (moving) {
    scene_.evaluate(before, &state_minus_);
    scene_.evaluate(after, &state_plus_);
  }
  for (Instance& inst : instances_) {
    if (!inst.moves) continue;
    const glm::dmat4& m = state_.world[size_t(inst.node)];
    const double det = glm::determinant(glm::dmat3(m));
    // A singular or broken transform (a scale of 0 hides an object) cannot be inverted for
    // the ray: the instance is left out at this time, as it is while its node is hidden.
    const bool ok =
        std::isfinite(det) && std::abs(det) > 1e-30 && !scene_.node_hidden(state_, inst.node);
    if (ok) {
      float xfm[12];
      to_float3x4(m, xfm);
      rtcSetGeometryTransform(inst.geom, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm);
      inst.normal_matrix = glm::mat3(glm::transpose(glm::inverse(glm::dmat3(m))));
      inst.area_scale = float(std::abs(glm::determinant(glm::dmat3(m))));
      // v(p) = dM/dt M^-1 p, with dM/dt from the difference quotient above.
      const glm::dmat4 dm =
          (state_plus_.world[size_t(inst.node)] - state_minus_.world[size_t(inst.node)]) *
          (1.0 / (after - before));
      inst.world = m;
      inst.inverse_world = glm::inverse(m);
      inst.velocity = glm::mat4(dm * inst.inverse_world);
    }
    set_enabled(inst.geom, ok, &inst.enabled);
    rtcCommitGeometry(inst.geom);
  }
  if (!deforming_.empty()) deform(before, after);
  rtcCommitScene(top_);
  check_device("committing the top-level scene");

  for (int i : scene_.animated_materials()) {
    shading::ShadeMaterial& m = materials_[size_t(i)];
    const Material& now = scene_.material_at(state_, size_t(i));
    m = shading::make_shade_material(&now, scene_, options_.mirror_roughness);
    m.masked = m.masked || m.alpha_tested;  // as build() chose for its filter
    use_uv_transforms(size_t(i), now);
  }
  camera_ = scene_.camera_at(state_);
  lights_.clear();  // capacity stays: no allocation after the first call
  // A black light would cost a shadow ray per shading point for nothing.
  for (int n : light_nodes_) {
    if (scene_.node_hidden(state_, n)) continue;
    const LightRecord r = shading::make_light_record(
        scene_.light_at(state_, size_t(scene_.nodes[size_t(n)].light)), state_.world[size_t(n)]);
    if (r.radiance != glm::vec3(0.0f)) lights_.push_back(r);
  }
  node_light_count_ = lights_.size();
  place_camera_lights(camera_);
}

// The lights that ride on the camera (Light::on_camera) go after the nodes' lights.
void Tracer::Impl::place_camera_lights(const Camera& camera) {
  lights_.resize(node_light_count_);
  if (camera_lights_.empty()) return;
  // The camera's frame as a node transform: x right, y up, z back, at the eye.
  const glm::dmat4 frame(glm::dvec4(camera.right, 0.0), glm::dvec4(camera.up, 0.0),
                         glm::dvec4(-camera.forward, 0.0), glm::dvec4(camera.eye, 1.0));
  for (int l : camera_lights_) {
    const Light& light = scene_.light_at(state_, size_t(l));
    const LightRecord r =
        shading::make_light_record(light, frame * glm::mat4_cast(light.camera_rotation));
    if (r.radiance != glm::vec3(0.0f)) lights_.push_back(r);
  }
}

// ---------------------------------------------------------------------------------------------
// Queries

HitRef Tracer::Impl::intersect(const glm::vec3& o, const glm::vec3& d, float tnear) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  init_ray(&rh.ray, o, d, tnear, INFINITY);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(top_, &ctx, &rh);
  HitRef h;
  h.t = rh.ray.tfar;
  h.u = rh.hit.u;
  h.v = rh.hit.v;
  h.geom = rh.hit.geomID;
  h.prim = rh.hit.primID;
  h.inst = rh.hit.instID[0];
  return h;
}

glm::vec3 Tracer::Impl::filtered_shadow(const glm::vec3& o, const glm::vec3& d, float tfar) const {
  ShadowContext ctx;
  RTCRay r;
  init_ray(&r, o, d, 0.0f, tfar);
  r.id = kShadowRayId;
  rtcOccluded1(top_, &ctx.embree, &r);
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
glm::vec3 Tracer::Impl::volume_transmittance(const ShadowContext& ctx, int lane, const glm::vec3& d,
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
    const glm::vec3& p0 = g.positions[tri[0]];
    glm::vec3 face = glm::cross(g.positions[tri[1]] - p0, g.positions[tri[2]] - p0);
    if (g.flip_winding) face = -face;
    if (inst.transformed) face = inst.normal_matrix * face;
    stops[size_t(n++)] = {c.t, !(glm::dot(face, d) > 0.0f), medium};
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

bool Tracer::Impl::blocked(const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  init_ray(&r, o, d, tnear, tfar);
  rtcOccluded1(top_, &ctx, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
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

void Tracer::Impl::make_surface(const HitRef& hit, const glm::vec3& o, const glm::vec3& d,
                                float cone, float spread, Surface* s) const {
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
bool Tracer::Impl::prepare_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex,
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
bool Tracer::Impl::light_contribution(const LightRecord& light, const Surface& s,
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

// Emission, ambient and direct light at a surface seen from direction wo (unit, toward the
// viewer). `tex` is texture_color(s).
glm::vec3 Tracer::Impl::shade_local(const Surface& s, const glm::vec3& wo, const glm::vec3& tex,
                                    TraceStats* stats) const {
  glm::vec3 c;
  LocalTerms terms;
  if (!prepare_local(s, wo, tex, &c, &terms)) return c;
  for (const LightRecord& light : lights_) {
    glm::vec3 contribution, origin, l;
    float tfar;
    if (!light_contribution(light, s, terms, wo, &contribution, &origin, &l, &tfar)) continue;
    if (options_.shadows) {
      ++stats->shadow_rays;
      contribution *= shadow_transmittance(origin, l, tfar);
    }
    c += contribution;
  }
  return c;
}

// shade_local for up to 8 surfaces at once (lanes where `hit` is false are skipped): the shadow
// rays toward one light go out as one rtcOccluded8.
void Tracer::Impl::shade_local8(const Surface* s, const glm::vec3* wo, const glm::vec3* tex,
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
  for (const LightRecord& light : lights_) {
    alignas(32) int valid[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    RTCRay8 rays;
    for (int k = 0; k < 8; ++k) set_lane(&rays, k, glm::vec3(0.0f), glm::vec3(0, 0, 1), 0.0f);
    glm::vec3 contribution[8];
    bool any_ray = false;
    for (int k = 0; k < n; ++k) {
      glm::vec3 origin, l;
      float tfar;
      if (!lit[k] ||
          !light_contribution(light, s[k], terms[k], wo[k], &contribution[k], &origin, &l, &tfar))
        continue;
      if (!options_.shadows) {
        out[k] += contribution[k];
        continue;
      }
      valid[k] = -1;
      any_ray = true;
      set_lane(&rays, k, origin, l, tfar);
      ++stats->shadow_rays;
    }
    if (!any_ray) continue;
    if (!has_translucent_) {  // scenes without glass or blending skip the filter's context
      RTCIntersectContext ctx;
      rtcInitIntersectContext(&ctx);
      rtcOccluded8(valid, top_, &ctx, &rays);
      for (int k = 0; k < n; ++k)
        if (valid[k] && rays.tfar[k] >= 0.0f) out[k] += contribution[k];
      continue;
    }
    for (int k = 0; k < 8; ++k) rays.id[k] = kShadowRayId + unsigned(k);
    ShadowContext ctx;
    float tfar[8];
    std::copy_n(rays.tfar, 8, tfar);
    rtcOccluded8(valid, top_, &ctx.embree, &rays);
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

glm::vec3 Tracer::Impl::texture_color(const Surface& s) const {
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
glm::vec3 Tracer::Impl::mirror_chain(glm::vec3 d, Surface s, glm::vec3 tex, TraceStats* stats,
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
glm::vec3 Tracer::Impl::secondary(const glm::vec3& origin, const glm::vec3& d, const Surface& from,
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
glm::vec3 Tracer::Impl::pass_through(const glm::vec3& d, const Surface& s, int depth,
                                     const glm::vec3& throughput, const Media& media,
                                     TraceStats* stats) const {
  const glm::vec3 behind = throughput * (1.0f - s.opacity);
  if (std::max(behind.r, std::max(behind.g, behind.b)) < kMinThroughput) return glm::vec3(0.0f);
  const glm::vec3 ng = s.back_face ? -s.ng : s.ng;  // toward the side the ray arrives from
  return secondary(s.p - offset_at(s.p) * ng, d, s, depth + 1, behind, media, stats);
}

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

// Whitted glass at s, hit along d (docs/scene-model.md, "Transmission and refraction"): a
// reflected ray weighted by Schlick's Fresnel and a refracted one (Snell) weighted by the rest
// times transmission and base color; total internal reflection past the critical angle.
glm::vec3 Tracer::Impl::glass(const glm::vec3& d, const Surface& s, const glm::vec3& tex, int depth,
                              const glm::vec3& throughput, const Media& media,
                              TraceStats* stats) const {
  const ShadeMaterial& m = *s.material;
  // Entering or leaving: the side of the triangle's own geometric normal, before make_surface
  // turned it toward the viewer for a double-sided material.
  const uint32_t* tri = s.triangle;
  const glm::vec3& p0 = s.geom->positions[tri[0]];
  glm::vec3 face = glm::cross(s.geom->positions[tri[1]] - p0, s.geom->positions[tri[2]] - p0);
  if (s.geom->flip_winding) face = -face;
  if (s.instance->transformed) face = s.instance->normal_matrix * face;
  const bool entering = !(glm::dot(face, d) > 0.0f);

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

// Fills everything of a primary sample but its color, and the surface it hit. Returns false on
// a miss (then the color is the background).
bool Tracer::Impl::begin_sample(const Ray& ray, const HitRef& hit, ShadedSample* o, Surface* s,
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

// No NaN or Inf leaves the tracer.
void Tracer::Impl::sanitize(ShadedSample* o, TraceStats* stats) const {
  if (!finite(o->color)) {
    o->color = glm::vec3(0.0f);
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

void Tracer::Impl::finish(const Ray& ray, const HitRef& hit, ShadedSample* out,
                          TraceStats* stats) const {
  Surface s;
  if (begin_sample(ray, hit, out, &s, stats)) {
    const glm::vec3 tex = texture_color(s);
    out->color = own_share(s, shade_local(s, -ray.direction, tex, stats)) +
                 mirror_chain(ray.direction, s, tex, stats);
  }
  sanitize(out, stats);
}

// =============================================================================================
// Tracer

Tracer::Tracer(const Scene& scene, const TracerOptions& options)
    : impl_(std::make_unique<Impl>(scene, options)) {}

Tracer::~Tracer() = default;

void Tracer::set_time(double t) { impl_->set_time(t); }
void Tracer::set_view(const Camera& view) { impl_->place_camera_lights(view); }
double Tracer::time() const { return impl_->state_.time; }
const Camera& Tracer::camera() const { return impl_->camera_; }
const TracerOptions& Tracer::options() const { return impl_->options_; }

size_t Tracer::copied_vertices() const {
  size_t n = 0;
  for (const std::vector<glm::vec3>& p : impl_->static_positions_) n += p.size();
  return n;
}

bool Tracer::rigid_transform(uint32_t node, glm::dmat4* world, glm::dmat4* inverse) const {
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
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  rtcIntersect8(valid, impl_->top_, &ctx, &rh);
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
  ++stats->occlusion_rays;
  const glm::vec3 d = to - from;
  const float len = glm::length(d);
  if (!(len > 0.0f) || !std::isfinite(len)) return false;
  const float near = std::min(impl_->offset_at(from), 0.5f * len);
  const float far = std::max(len - impl_->offset_at(to), near);
  return impl_->blocked(from, d / len, near, far);
}

}  // namespace afr
