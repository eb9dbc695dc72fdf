// The parts of the tracer that its source files share: the records of the Embree geometry, the
// shading point, the media a ray travels in, the shadow rays' context, and Tracer::Impl itself,
// whose work the files divide: tracer.cpp (surfaces, shading, the paths of mirror and blended
// surfaces, the public Tracer), tracer_build.cpp (the Embree scenes and setting them to a time),
// tracer_shadows.cpp (shadow rays through glass and cut-away or blended surfaces) and
// tracer_glass.cpp (refraction), all in namespace afr::tracer_detail. Private to afr_sampler:
// only those files include it.
#pragma once

#include <afr/sampler/tracer.h>

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "shading.h"

namespace afr::tracer_detail {

using shading::LightRecord;
using shading::ShadeMaterial;

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

inline bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

inline float max_abs(const glm::vec3& v) {
  return std::max(std::abs(v.x), std::max(std::abs(v.y), std::abs(v.z)));
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
inline SlotCoords uv_data(const Primitive& p, uint8_t k) {
  const std::vector<glm::vec2>& uvs = p.uv_set(k);
  return {!uvs.empty() && uvs.size() == p.positions.size() ? uvs.data() : nullptr, k};
}

// The value of a per-vertex attribute at barycentrics `bary` of triangle `tri`.
template <typename T>
inline T interpolate(const T* values, const uint32_t* tri, const glm::vec3& bary) {
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

// Whether a ray along d leaves through triangle `tri` of g, placed by instance `inst`: whether it
// meets the triangle's own front (glTF's winding, turned where the node mirrors) from behind. A
// volume's surfaces face out of it, so this tells leaving from entering, whichever side of a
// double-sided surface make_surface turned toward the viewer.
inline bool leaves_through(const GeomRecord& g, const Instance& inst, const uint32_t* tri,
                           const glm::vec3& d) {
  const glm::vec3& p0 = g.positions[tri[0]];
  glm::vec3 face = glm::cross(g.positions[tri[1]] - p0, g.positions[tri[2]] - p0);
  if (g.flip_winding) face = -face;
  if (inst.transformed) face = inst.normal_matrix * face;
  return glm::dot(face, d) > 0.0f;
}

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

// One shadow ray toward one light, and the light it brings if nothing blocks it. Left
// uninitialised by default: the tracer keeps arrays of them on the stack and fills what it uses.
struct ShadowJob {
  glm::vec3 contribution;
  glm::vec3 origin;
  glm::vec3 l;  // unit, toward the light
  float tfar;
};

inline void init_ray(RTCRay* r, const glm::vec3& o, const glm::vec3& d, float tnear, float tfar) {
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
inline void set_lane(RTCRay8* r, int k, const glm::vec3& o, const glm::vec3& d, float tfar) {
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

// What every ray query of a tracer hands Embree: the context, and the tracer's materials at its
// time, which the filters read. Geometry is shared by tracers at different times (TracerShared),
// so its filters cannot hold a material of their own.
struct QueryContext {
  RTCIntersectContext embree;  // first: Embree hands the filters this address
  const ShadeMaterial* materials = nullptr;
  explicit QueryContext(const ShadeMaterial* m) : materials(m) { rtcInitIntersectContext(&embree); }
};
static_assert(offsetof(QueryContext, embree) == 0);

// Shadow rays (tracer_shadows.cpp) carry this id (plus their lane) and a ShadowContext, in
// which the occlusion filter gathers what the surfaces they cross let through.
constexpr unsigned kShadowRayId = 0x5ad0u;

struct ShadowContext {
  QueryContext query;  // first: Embree hands the filters this address
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

  explicit ShadowContext(const ShadeMaterial* materials) : query(materials) {
    for (int k = 0; k < kLanes; ++k) {
      transmittance[k] = glm::vec3(1.0f);
      n_crossed[k] = 0;
    }
  }
};
static_assert(offsetof(ShadowContext, query) == 0);

// The opacity of a masked or blended material at barycentrics (u, v) of triangle `tri`: the base
// color factor's alpha x the texture's alpha (level 0, bilinear: a mip level would average a
// cutout's edge away) x COLOR_0's alpha. uvs and color_alpha may be null (none).
inline float opacity_at(const shading::ShadeMaterial& m, SlotCoords uvs, const float* color_alpha,
                        const uint32_t* tri, float u, float v) {
  float opacity = m.opacity_factor;
  if (m.opacity_texture && uvs) opacity *= m.opacity_texture->sample_alpha(uvs.at(m, tri, u, v));
  if (color_alpha) {
    opacity *=
        (1.0f - u - v) * color_alpha[tri[0]] + u * color_alpha[tri[1]] + v * color_alpha[tri[2]];
  }
  return opacity;
}

// What the filters of one Embree geometry read (its user data): its material (an index into the
// querying tracer's materials, QueryContext), and, for a masked material, the texture
// coordinates and triangles that place a hit in its texture.
struct GeometryFilter {
  uint32_t material = 0;
  bool masked = false;  // the material's `masked`, or a vertex alpha (color_alpha) it tests
  SlotCoords uvs;       // the base color's (none: the factor alone decides)
  const float* color_alpha = nullptr;  // COLOR_0's alpha per vertex, or null
  const uint32_t* indices = nullptr;
  // Glass or a diffuse transmitter whose shadow transmittance varies over it (a base-color,
  // transmission or diffuse-transmission texture with coordinates, or COLOR_0), with what places
  // a hit in its textures and colors.
  bool textured_through = false;
  SlotCoords transmission_uvs;
  SlotCoords diffuse_transmission_uvs;
  SlotCoords diffuse_transmission_color_uvs;
  const glm::vec3* colors = nullptr;  // COLOR_0 per vertex, or null

  // What a shadow ray keeps of the light crossing the surface at the hit: the material's
  // shadow_transmittance, or with textures and colors their values there (level 0) multiplied
  // in: glass's transmission x (1 - metallic) x base color, and the diffuse transmission's
  // strength x its color x what metal and glass leave of the diffuse part (the factors'
  // metallic and specular: ShadeMaterial's diffuse_transmitted).
  glm::vec3 through(const ShadeMaterial& m, const RTCFilterFunctionNArguments* args,
                    unsigned i) const {
    if (!textured_through) return m.shadow_transmittance;
    const uint32_t* tri = indices + 3 * size_t(RTCHitN_primID(args->hit, args->N, i));
    const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
    const float w = 1.0f - u - v;
    const auto at = [&](const auto* values) {
      return w * values[tri[0]] + u * values[tri[1]] + v * values[tri[2]];
    };
    float transmission = m.transmission_factor;
    if (m.transmission_texture && transmission_uvs) {
      transmission *= m.transmission_texture->sample(transmission_uvs.at(m, tri, u, v), 0.0f).r;
    }
    transmission = glm::clamp(transmission, 0.0f, 1.0f);
    glm::vec3 kept(0.0f);
    if (m.is_glass) {
      glm::vec3 base = m.base;
      if (m.texture && uvs) base *= m.texture->sample(uvs.at(m, tri, u, v), 0.0f);
      if (colors) base *= at(colors);
      kept = transmission * (1.0f - m.metallic_factor) * base;
    }
    // (Gated by the factor: the transmission's texture may leave a diffuse part where the
    // factor leaves none.)
    if (m.diffuse_transmission > 0.0f) {
      float strength = m.diffuse_transmission;
      if (m.diffuse_transmission_texture && diffuse_transmission_uvs) {
        strength *=
            m.diffuse_transmission_texture->sample(diffuse_transmission_uvs.at(m, tri, u, v), 0.0f)
                .r;  // the image's alpha, held in red
      }
      glm::vec3 color = m.diffuse_transmission_color;
      if (m.diffuse_transmission_color_texture && diffuse_transmission_color_uvs) {
        color *= m.diffuse_transmission_color_texture->sample(
            diffuse_transmission_color_uvs.at(m, tri, u, v), 0.0f);
      }
      // The diffuse part metal, glass and a specular-glossiness F0 leave, as derive() takes it.
      kept += strength * color * (1.0f - m.metallic_factor) * (1.0f - transmission) *
              (1.0f - m.specular_share());
    }
    return glm::clamp(kept, glm::vec3(0.0f), glm::vec3(1.0f));
  }

  float opacity(const ShadeMaterial& m, const RTCFilterFunctionNArguments* args, unsigned i) const {
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    return opacity_at(m, uvs, color_alpha, indices + 3 * size_t(prim),
                      RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
  }
  // alphaMode MASK: whether the hit is kept; BLEND: whether anything of it shows.
  bool opaque_at(const ShadeMaterial& m, const RTCFilterFunctionNArguments* args,
                 unsigned i) const {
    const float a = opacity(m, args, i);
    return m.blended ? a > 0.0f : a >= m.opacity_cutoff;
  }
};

// The occlusion filter of a masked, blended, glass or diffusely transmitting geometry, and the
// intersection filter of a masked one (tracer_shadows.cpp).
void occlusion_filter(const RTCFilterFunctionNArguments* args);
void mask_filter(const RTCFilterFunctionNArguments* args);

// =============================================================================================
// What no time changes, built once by the first tracer of a scene and shared by the tracers
// made from it (Tracer's sharing constructor: the threads of a sampler pool): the scene's copy,
// the Embree device, the BVHs of the static geometry and of the meshes that moving nodes carry
// or static nodes share, with their records and filters, and the instances' templates. Each
// tracer adds what a time changes: its top level, its moving instances' transforms, its
// deforming geometry, its materials and lights. Read-only once built; released with the last
// tracer that holds it.
struct TracerShared {
  TracerShared(std::shared_ptr<const Scene> s, const TracerOptions& o)
      : scene_owner(std::move(s)), scene(*scene_owner), options(o) {}
  ~TracerShared();
  TracerShared(const TracerShared&) = delete;
  TracerShared& operator=(const TracerShared&) = delete;

  std::shared_ptr<const Scene> scene_owner;  // null owner: the caller keeps the scene alive
  const Scene& scene;
  TracerOptions options;  // with the scene's ray depth in place
  RTCDevice device = nullptr;
  std::vector<Blas> blas;              // every BLAS but the deforming one; owns their scenes
  std::vector<Instance> instances;     // their instances (geom null: each tracer makes its own)
  std::deque<GeometryFilter> filters;  // the user data of those BLASes' filtered geometries
  // Static geometry transformed to world space (the static BLAS's GeomRecords point into these).
  std::vector<std::vector<glm::vec3>> static_positions;
  std::vector<std::vector<glm::vec3>> static_normals;
  std::vector<std::vector<glm::vec4>> static_tangents;  // world space, where a primitive has them
  std::vector<int> deforming_nodes;                     // each tracer deforms these in its own BLAS
  std::vector<int> light_nodes;                         // scene nodes that carry a light
  std::vector<int> camera_lights;                       // lights on the camera (Light::on_camera)
  std::vector<char> animated_through;                   // TracerImpl::animated_through_
  bool has_translucent = false;  // of the geometry above (TracerImpl::has_translucent_)
  bool several_volumes = false;
  float offset_floor = 1.0f;
};

// =============================================================================================
// Tracer::Impl: the tracer's state, and the work its files share out. It is declared here, in
// tracer_detail, where its parts have their short names; Tracer::Impl (below) only names it.

struct TracerImpl {
  std::shared_ptr<TracerShared> shared_;
  const Scene& scene_;  // shared_->scene
  TracerOptions options_;
  RTCDevice device_ = nullptr;  // shared_->device
  RTCScene top_ = nullptr;
  // The shared BLASes (TracerShared::blas), then this tracer's deforming one (deforming_blas_).
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
  // Glass, diffusely transmitting or blended geometry lets shadow rays through (crosses).
  bool has_translucent_ = false;
  // Per material, whether an animation drives its transmission or diffuse transmission
  // (KHR_animation_pointer): it may let shadow rays through at some times and not at others, so
  // its geometry carries the filter, which asks the material of the time (set_filters).
  std::vector<char> animated_through_;
  // The user data of the deforming geometries' filters (the shared ones': TracerShared).
  std::deque<GeometryFilter> filters_;
  std::vector<int> light_nodes_;     // scene nodes that carry a light
  std::vector<int> camera_lights_;   // lights on the camera (Light::on_camera)
  std::vector<LightRecord> lights_;  // placed at the current time: nodes', then camera's
  size_t node_light_count_ = 0;      // how many of lights_ come from nodes
  // Deforming geometry, in one BLAS (deforming_blas_, -1 when there is none) refitted at every
  // set_time; positions at the two times of the velocity's difference quotient.
  std::vector<DeformingPrimitive> deforming_;
  int deforming_blas_ = -1;
  int deforming_instance_ = -1;
  // Whether two or more materials are volumes (KHR_materials_volume), at some time: only then
  // can two media's surfaces coincide (cross_coincident_surfaces).
  bool several_volumes_ = false;
  std::vector<glm::vec3> positions_before_, positions_after_;
  SceneState state_, state_minus_, state_plus_;
  Camera camera_;
  // The scene's size (largest coordinate at time 0), at most 1: the part of a ray offset that
  // does not grow with the hit point. A fixed 1 would exceed the whole of a scene in
  // micrometres, so that shadow rays started beyond every blocker.
  float offset_floor_ = 1.0f;

  // Builds everything: the shared part, then this tracer's.
  TracerImpl(std::shared_ptr<const Scene> scene, const TracerOptions& options);
  // Shares what `shared` holds, and builds only this tracer's part.
  explicit TracerImpl(std::shared_ptr<TracerShared> shared);
  ~TracerImpl() { release(); }
  void release();

  void check_device(const char* what) const;
  // Sets the filters of geometry g of primitive p (glTF's alphaMode MASK, glass) where its
  // material needs them, their user data kept in `filters`.
  void set_filters(RTCGeometry g, uint32_t material, const Primitive& p,
                   std::deque<GeometryFilter>* filters);
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
  // A static geometry of the shared part (its filters in TracerShared::filters).
  RTCGeometry new_triangle_geometry(uint32_t material, const Primitive& p,
                                    const glm::vec3* positions, size_t vertex_count,
                                    const uint32_t* indices, size_t triangle_count);
  // The materials at time 0 (materials_, uv_transforms_).
  void make_materials();
  // The shared part (shared_), then this tracer's.
  void build();
  // This tracer's part: the deforming BLAS, the top level with an instance of each BLAS.
  void build_own();
  void build_deforming(const std::vector<int>& nodes);
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
  // Whether surfaces pick among the lights (TracerOptions::light_samples) rather than cast a
  // shadow ray toward each.
  bool picks_lights() const {
    return options_.light_samples > 0 && lights_.size() > size_t(options_.light_samples);
  }
  // The shadow rays of surface s when it picks among the lights: writes at most
  // options_.light_samples of them to `picks` and returns how many.
  int pick_lights(const Surface& s, const LocalTerms& terms, const glm::vec3& wo,
                  ShadowJob* picks) const;
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
  // The media on the far side of volume surface s, hit along d, changed by the other volumes'
  // surfaces that coincide with it there (tracer_glass.cpp).
  void cross_coincident_surfaces(const Surface& s, const glm::vec3& d, Media* after) const;
  glm::vec3 secondary(const glm::vec3& origin, const glm::vec3& d, const Surface& from, int depth,
                      const glm::vec3& throughput, const Media& media, TraceStats* stats) const;
  bool begin_sample(const Ray& ray, const HitRef& hit, ShadedSample* o, Surface* s,
                    TraceStats* stats) const;
  void sanitize(ShadedSample* o, TraceStats* stats) const;
  // The offset that keeps a ray leaving the surface at p from hitting that surface again.
  float offset_at(const glm::vec3& p) const { return kRayOffset * (offset_floor_ + max_abs(p)); }
  void finish(const Ray& ray, const HitRef& hit, ShadedSample* out, TraceStats* stats) const;
};

}  // namespace afr::tracer_detail

namespace afr {

struct Tracer::Impl : tracer_detail::TracerImpl {
  using TracerImpl::TracerImpl;
};

}  // namespace afr
