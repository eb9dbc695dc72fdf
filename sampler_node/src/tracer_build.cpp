// Building the tracer's Embree scenes (TracerImpl, tracer_parts.h) and setting them to a
// time: the geometry's records and filters, the instances' transforms and velocities, the
// deforming meshes' vertices, and the lights.
#include <afr/common/check.h>
#include <afr/common/error.h>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "tracer_parts.h"

namespace afr::tracer_detail {
namespace {

// Half-width of the central difference that gives instance velocities.
constexpr double kVelocityDt = 1e-3;

// Enables or disables Embree geometry g as `on` asks; *enabled: whether it is enabled now.
void set_enabled(RTCGeometry g, bool on, bool* enabled) {
  if (on == *enabled) return;
  if (on)
    rtcEnableGeometry(g);
  else
    rtcDisableGeometry(g);
  *enabled = on;
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

TracerImpl::TracerImpl(std::shared_ptr<const Scene> scene, const TracerOptions& options)
    : shared_(std::make_shared<TracerShared>(std::move(scene), options)),
      scene_(shared_->scene),
      options_(options) {
  if (scene_.ray_depth) options_.max_mirror_depth = *scene_.ray_depth;
  shared_->options = options_;
  glm::dvec3 lo, hi;
  scene_.bounds(scene_.evaluate(0.0), &lo, &hi);
  const glm::dvec3 m = glm::max(glm::abs(lo), glm::abs(hi));
  const double extent = std::max(m.x, std::max(m.y, m.z));
  offset_floor_ = shared_->offset_floor = float(std::clamp(extent, 1e-30, 1.0));
  if (options_.light_samples < 0 || options_.light_samples > kMaxLightSamples) {
    throw Error(fmt::format("tracer: {} light samples (0 for every light, or 1 to {})",
                            options_.light_samples, kMaxLightSamples));
  }
  if (options_.embree_threads < 0) {
    throw Error(fmt::format("tracer: {} Embree threads (0 for Embree's default, or more)",
                            options_.embree_threads));
  }
  const std::string config = options_.embree_threads > 0
                                 ? fmt::format("verbose=0,threads={}", options_.embree_threads)
                                 : std::string("verbose=0");
  device_ = shared_->device = rtcNewDevice(config.c_str());
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

TracerImpl::TracerImpl(std::shared_ptr<TracerShared> shared)
    : shared_(std::move(shared)),
      scene_(shared_->scene),
      options_(shared_->options),
      device_(shared_->device),
      blas_(shared_->blas),
      instances_(shared_->instances),
      has_translucent_(shared_->has_translucent),
      animated_through_(shared_->animated_through),
      light_nodes_(shared_->light_nodes),
      camera_lights_(shared_->camera_lights),
      several_volumes_(shared_->several_volumes),
      offset_floor_(shared_->offset_floor) {
  try {
    make_materials();
    build_own();
    set_time(0.0);
  } catch (...) {
    release();
    throw;
  }
}

TracerShared::~TracerShared() {
  for (Blas& b : blas)
    if (b.scene) rtcReleaseScene(b.scene);
  if (device) rtcReleaseDevice(device);
}

// This tracer's Embree objects; the shared ones go with the last tracer that holds them.
void TracerImpl::release() {
  for (Instance& inst : instances_)
    if (inst.geom) rtcReleaseGeometry(inst.geom);
  instances_.clear();
  if (top_) rtcReleaseScene(top_);
  top_ = nullptr;
  if (deforming_blas_ >= 0 && blas_[size_t(deforming_blas_)].scene) {
    rtcReleaseScene(blas_[size_t(deforming_blas_)].scene);
  }
  blas_.clear();
}

void TracerImpl::check_device(const char* what) const {
  const RTCError e = rtcGetDeviceError(device_);
  if (e != RTC_ERROR_NONE)
    throw Error(std::string("embree: ") + what + " failed (error " + std::to_string(int(e)) +
                ") for scene " + scene_.source);
}

void TracerImpl::set_filters(RTCGeometry g, uint32_t material, const Primitive& p,
                             std::deque<GeometryFilter>* filters) {
  AFR_DCHECK(material < materials_.size());
  const shading::ShadeMaterial& m = materials_[material];
  const float* vertex_alpha = tested_alpha(p, material);
  const bool masked = m.masked || vertex_alpha;
  const bool through = m.lets_shadow_rays_through() || animated_through_[material];
  if (!through && !masked) return;
  has_translucent_ |= through || (m.blended && masked);
  GeometryFilter& f = filters->emplace_back();
  f.material = material;
  f.masked = masked;
  const SlotUvs uvs = slot_uvs(p);
  f.uvs = uvs.base_color;
  f.color_alpha = vertex_alpha;
  f.indices = p.indices.data();
  if (through) {
    // (A material that does not let light through now has no transmission textures yet: the
    // scene's says.)
    const Material* own =
        material < scene_.materials.size() ? &scene_.materials[material] : nullptr;
    f.transmission_uvs = uvs.transmission;
    f.diffuse_transmission_uvs = uvs.diffuse_transmission;
    f.diffuse_transmission_color_uvs = uvs.diffuse_transmission_color;
    f.colors = p.colors.size() == p.positions.size() ? p.colors.data() : nullptr;
    f.textured_through =
        (m.texture && f.uvs) || f.colors != nullptr ||
        (own && own->transmission_texture >= 0 && f.transmission_uvs) ||
        (own && own->diffuse_transmission_texture >= 0 && f.diffuse_transmission_uvs) ||
        (own && own->diffuse_transmission_color_texture >= 0 && f.diffuse_transmission_color_uvs);
  }
  rtcSetGeometryUserData(g, &f);
  rtcSetGeometryOccludedFilterFunction(g, &occlusion_filter);
  if (masked) rtcSetGeometryIntersectFilterFunction(g, &mask_filter);
}

RTCGeometry TracerImpl::new_triangle_geometry(uint32_t material, const Primitive& p,
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
  set_filters(g, material, p, &shared_->filters);
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
  rtcCommitGeometry(g);
  return g;
}

// ---------------------------------------------------------------------------------------------
// Building: one BLAS of all static geometry in world space, one BLAS per mesh that a moving
// node carries or that static nodes share beyond TracerOptions::max_copied_vertices, and a top
// level of instances.

void TracerImpl::make_materials() {
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
}

void TracerImpl::build() {
  const uint32_t default_material = uint32_t(scene_.materials.size());
  make_materials();
  animated_through_.assign(materials_.size(), 0);
  for (const PropertyChannel& c : scene_.property_channels) {
    if (c.property == AnimatedProperty::kTransmissionFactor ||
        c.property == AnimatedProperty::kDiffuseTransmissionFactor ||
        c.property == AnimatedProperty::kDiffuseTransmissionColor) {
      animated_through_[size_t(c.index)] = 1;
    }
  }
  // A material is a volume where its thickness is above 0, or may become one where an animation
  // drives its thickness or transmission.
  std::vector<char> volume(scene_.materials.size(), 0);
  for (size_t i = 0; i < scene_.materials.size(); ++i) {
    volume[i] = materials_[i].is_volume || scene_.materials[i].thickness > 0.0f;
  }
  for (const PropertyChannel& c : scene_.property_channels) {
    if (c.property == AnimatedProperty::kThicknessFactor ||
        c.property == AnimatedProperty::kTransmissionFactor) {
      volume[size_t(c.index)] = 1;
    }
  }
  several_volumes_ = std::count(volume.begin(), volume.end(), 1) >= 2;
  auto material_of = [&](const Primitive& p) {
    return p.material >= 0 && size_t(p.material) < scene_.materials.size() ? uint32_t(p.material)
                                                                           : default_material;
  };
  auto usable = [](const Primitive& p) { return p.triangle_count() > 0 && !p.positions.empty(); };

  const SceneState at0 = scene_.evaluate(0.0);

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
      TracerShared& sh = *shared_;
      sh.static_positions.push_back(std::move(positions));
      sh.static_normals.push_back(std::move(normals));
      sh.static_tangents.push_back(std::move(tangents));
      GeomRecord r = record_of(p, material_of(p));
      r.positions = sh.static_positions.back().data();
      r.normals = sh.static_normals.back().empty() ? nullptr : sh.static_normals.back().data();
      r.tangents = sh.static_tangents.back().empty() ? nullptr : sh.static_tangents.back().data();
      r.node = n;
      r.flip_winding = flips_winding(n, at0);
      statics.geoms.push_back(r);
    }
  }
  if (!statics.geoms.empty()) {
    rtcSetSceneBuildQuality(statics.scene, RTC_BUILD_QUALITY_HIGH);
    rtcCommitScene(statics.scene);
    check_device("building the static BVH");
    shared_->blas.push_back(std::move(statics));
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
    mesh_blas[size_t(mesh)] = int(shared_->blas.size());
    shared_->blas.push_back(std::move(b));
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
  for (size_t l = 0; l < scene_.lights.size(); ++l) {
    if (scene_.lights[l].on_camera) camera_lights_.push_back(int(l));
  }

  // What tracers sharing this one's geometry take as it is (TracerImpl(shared)).
  TracerShared& sh = *shared_;
  blas_ = sh.blas;
  sh.instances = instances_;
  sh.deforming_nodes = std::move(deforming_nodes);
  sh.light_nodes = light_nodes_;
  sh.camera_lights = camera_lights_;
  sh.animated_through = animated_through_;
  sh.has_translucent = has_translucent_;
  sh.several_volumes = several_volumes_;
  build_own();
}

void TracerImpl::build_own() {
  build_deforming(shared_->deforming_nodes);
  lights_.reserve(light_nodes_.size() + camera_lights_.size());

  top_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(top_, RTC_BUILD_QUALITY_LOW);
  rtcSetSceneFlags(top_, RTC_SCENE_FLAG_DYNAMIC);
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
void TracerImpl::build_deforming(const std::vector<int>& nodes) {
  const uint32_t default_material = uint32_t(scene_.materials.size());
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
    set_filters(g, material, p, &filters_);
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
void TracerImpl::deform(double before, double after) {
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

void TracerImpl::set_time(double t) {
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
void TracerImpl::place_camera_lights(const Camera& camera) {
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

}  // namespace afr::tracer_detail
