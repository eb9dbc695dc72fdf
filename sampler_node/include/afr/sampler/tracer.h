// The ray tracer of afr: an Embree 3 two-level BVH over a Scene (one instance of all static
// geometry, one instance per rigidly moving mesh node, so a new time only updates instance
// transforms and re-commits the top level; and one instance of all skinned or morphed meshes
// that move, whose world-space vertices a new time rewrites and refits) and the shading model
// the scene's materials ask for.
// Shading follows glTF's conventions: BRDF = diffuse / pi + GGX, so a light of intensity I
// (color 1) at distance d gives a white Lambertian surface facing it radiance I / (pi d^2)
// (I / pi without falloff); ambient = Scene::ambient x (Material::ambient or base color) x
// texture. The details are in sampler_node/src/shading.h.
//
// Order of calls: construct (the tracer keeps its own copy of the scene, or holds the one it is
// given, or shares another tracer's, and starts at time 0),
// optionally set_time(t) and then set_view(camera), then any number of
// trace/trace_crosshair/occluded calls from any number of threads (each thread with its own
// TraceStats), then set_time again. set_time and set_view must not overlap with tracing.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/scene.h>

#include <array>
#include <cstdint>
#include <memory>

namespace afr {

struct TracerOptions {
  // Secondary rays in a row: mirror reflections of smooth metals and the reflected and refracted
  // rays of glass share it (docs/scene-model.md, "Transmission and refraction"). A scene that
  // gives its own (Scene::ray_depth) replaces it.
  int max_mirror_depth = 3;
  bool shadows = true;
  // Roughness at or below which a metallic material reflects as a mirror.
  float mirror_roughness = 0.1f;
  // How trace_crosshair casts its rays: as 8-wide packets (one rtcIntersect8 for the five
  // primary rays, one rtcOccluded8 per light for their shadow rays) or as five trace() calls.
  // Both give the same samples; afr-bench-tracer measures which is faster.
  bool packet_crosshair = true;
  // Threads Embree may use to build and commit BVHs (0: its default, every core). Embree's TBB
  // scheduler takes this for the whole process, so the tracers of one process should agree.
  // A sampler moves its tracer's scene time about a thousand times a second of animation, and
  // each move commits the top-level BVH: with every core allowed, each commit wakes TBB
  // workers that then spin for a while on cores that other threads trace on. Where every
  // thread traces with its own tracer (afr-eval's runs), 1 is faster (docs/evaluation.md,
  // "Cost of a full Table 1 run"); the initial build of a large scene is then slower.
  int embree_threads = 0;
  // Static nodes that share a mesh: their copies are transformed into the one static BVH in
  // world space while the copies beyond the first hold at most this many vertices in all;
  // beyond, every static copy of the mesh is an instance of the mesh's own BVH, so that a forest
  // of instanced trees (EXT_mesh_gpu_instancing) costs one tree's memory. Instances traced as
  // fast as copies at 16 copies of a 2,145-vertex mesh and faster at 256 (afr-bench-tracer
  // --forest, docs/benchmarks.md), so copying stops early.
  size_t max_copied_vertices = size_t(1) << 16;
  // Shadow rays of a surface's direct light: 0 casts one toward every light that reaches it
  // (exact); K >= 1, where more than K lights reach a surface, casts K toward lights picked with
  // probabilities proportional to what each would send there unshadowed, weighted by the
  // inverse: an unbiased estimate whose noise is only where some of the lights are blocked
  // (docs/sampler.md, "Many lights"). At most kMaxLightSamples.
  int light_samples = 0;
};

inline constexpr int kMaxLightSamples = 32;

// Counters of one tracing thread; add them up across threads.
struct TraceStats {
  uint64_t primary_rays = 0;
  uint64_t shadow_rays = 0;
  uint64_t reflection_rays = 0;  // mirror and glass reflections, and refractions
  uint64_t occlusion_rays = 0;   // visibility tests asked for by the sampler (occluded())
  uint64_t sanitized = 0;        // shaded values that were NaN or Inf and were replaced

  TraceStats& operator+=(const TraceStats& o);
};

// The result of one primary ray.
struct ShadedSample {
  glm::vec3 color{0.0f};           // linear RGB, finite, >= 0
  glm::vec3 position{0.0f};        // world hit point; the ray direction when nothing was hit
  glm::vec3 velocity{0.0f};        // world velocity of the hit point (m/s); 0 for static objects
  uint32_t object_id = kNoObject;  // scene node of the hit, kNoObject on a miss
  bool hit = false;

  static constexpr uint32_t kNoObject = 0xffffffffu;
};

class Tracer {
 public:
  // Builds the BVH of a finalized scene, of which it keeps a copy. Throws afr::Error if Embree
  // fails.
  Tracer(const Scene& scene, const TracerOptions& options = {});
  // The same without the copy: the tracer holds `scene` (a pointer that owns nothing, from
  // shared_ptr's aliasing constructor, leaves its lifetime to the caller), which must not change
  // while the tracer or one sharing its geometry lives. For large scenes whose caller keeps them
  // anyway (a sampler pool: its textures and meshes, once, not twice).
  explicit Tracer(std::shared_ptr<const Scene> scene, const TracerOptions& options = {});
  // A tracer of `other`'s scene and options that shares with it what no time changes: the scene
  // (the copy `other` keeps, or the one it holds), the BVHs of the static geometry and of the
  // meshes that moving nodes carry, and their world-space vertices. It builds only its own top
  // level and deforming meshes, and moves to its own times as any tracer does. So the tracers of a
  // sampler pool's threads cost one scene's memory and one build, not one per thread
  // (docs/sampler.md, "Threads"). `other` must not be in set_time meanwhile; it may be destroyed
  // first.
  struct ShareGeometry {};
  Tracer(const Tracer& other, ShareGeometry);
  ~Tracer();
  Tracer(const Tracer&) = delete;
  Tracer& operator=(const Tracer&) = delete;

  // Moves every animated instance to time t (seconds), deforms the skinned and morphed meshes
  // that move (Scene::deform: their vertices, normals and per-vertex velocities) and
  // re-commits. Costs about the same for static and rigid scenes whatever their size, and for
  // a deforming one grows with its vertex count (afr-bench-tracer --deforming).
  void set_time(double t);
  double time() const;
  // The scene's active camera at the current time.
  const Camera& camera() const;
  // Places the lights that ride on the camera (Light::on_camera: the default headlight of a
  // scene without lights) in `view` rather than in camera(), until the next set_time: for a
  // sampler whose camera comes from a CameraSource.
  void set_view(const Camera& view);

  const TracerOptions& options() const;

  // The world transform at the current time, and its inverse, of a scene node whose geometry
  // moves rigidly (an animated mesh instance): a point on it in the node's space is at
  // world x p at this time. False for any other node (static or deforming geometry, a light,
  // a camera, kNoObject) and for one that a singular transform hides at this time.
  bool rigid_transform(uint32_t node, glm::dmat4* world, glm::dmat4* inverse) const;

  // The vertices of static geometry the tracer holds transformed into world space (copies of
  // meshes; TracerOptions::max_copied_vertices), beside the scene's own.
  size_t copied_vertices() const;

  ShadedSample trace(const Ray& ray, TraceStats* stats) const;
  // The crosshair of section 4.1: the center sample at image position (x, y) and its four
  // neighbours one pixel away, in the order center, x-1, x+1, y-1, y+1.
  void trace_crosshair(const Camera& camera, double x, double y, int width, int height,
                       std::array<ShadedSample, 5>* out, TraceStats* stats) const;
  // True if anything blocks the segment from `from` to `to` (the sampler's occlusion ray).
  // Hits within a small distance of either end do not count, so a surface point does not
  // occlude itself.
  bool occluded(const glm::vec3& from, const glm::vec3& to, TraceStats* stats) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr
