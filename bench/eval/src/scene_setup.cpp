#include <afr/eval/scene_setup.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <cstring>
#include <type_traits>

namespace afr::eval {

void apply_camera_path(const CameraPath& path, Scene* scene) {
  const std::vector<CameraKey>& keys = path.keys();
  CameraModel lens;
  lens.name = "camera path";
  lens.yfov = keys.front().yfov;
  lens.ymag = keys.front().ymag;
  scene->cameras.push_back(lens);
  Node node;
  node.name = "camera path";
  node.camera = int(scene->cameras.size()) - 1;
  node.translation = keys.front().eye;
  node.rotation = keys.front().rotation;
  const int index = int(scene->nodes.size());
  scene->nodes.push_back(node);
  // First among the roots, so it is the first camera node in scene order: the active one.
  scene->roots.insert(scene->roots.begin(), index);

  AnimationChannel translation, rotation;
  translation.node = rotation.node = index;
  translation.path = AnimatedPath::kTranslation;
  rotation.path = AnimatedPath::kRotation;
  translation.interpolation = rotation.interpolation = Interpolation::kLinear;
  for (const CameraKey& k : keys) {
    translation.times.push_back(k.time);
    rotation.times.push_back(k.time);
    translation.values.push_back(glm::dvec4(k.eye, 0.0));
    rotation.values.push_back(glm::dvec4(k.rotation.x, k.rotation.y, k.rotation.z, k.rotation.w));
  }
  scene->channels.push_back(std::move(translation));
  scene->channels.push_back(std::move(rotation));
  // A zoom (the path's yfov or ymag changing) animates the camera as KHR_animation_pointer's
  // channels do, linear between the keys as the path is.
  const auto zoom = [&](AnimatedProperty property, double CameraKey::*field) {
    bool changes = false;
    for (const CameraKey& k : keys) changes |= k.*field != keys.front().*field;
    if (!changes) return;
    PropertyChannel p;
    p.property = property;
    p.index = node.camera;
    p.curve.interpolation = Interpolation::kLinear;
    for (const CameraKey& k : keys) {
      p.curve.times.push_back(k.time);
      p.curve.values.push_back(glm::dvec4(k.*field, 0.0, 0.0, 0.0));
    }
    scene->property_channels.push_back(std::move(p));
  };
  zoom(AnimatedProperty::kCameraYfov, &CameraKey::yfov);
  zoom(AnimatedProperty::kCameraYmag, &CameraKey::ymag);
  scene->finalize();
}

namespace {

class Fnv1a {
 public:
  void bytes(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) {
      h_ ^= p[i];
      h_ *= 0x100000001b3ULL;
    }
  }
  template <typename T>
  void value(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes(&v, sizeof(T));
  }
  template <typename T>
  void array(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    value(uint64_t(v.size()));
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  uint64_t digest() const { return h_; }

 private:
  uint64_t h_ = 0xcbf29ce484222325ULL;
};

}  // namespace

uint64_t render_fingerprint(const Scene& scene) {
  Fnv1a h;
  h.value(uint64_t(scene.meshes.size()));
  for (const Mesh& m : scene.meshes) {
    h.value(uint64_t(m.primitives.size()));
    for (const Primitive& p : m.primitives) {
      h.array(p.positions);
      h.array(p.normals);
      h.array(p.uvs);
      h.array(p.indices);
      h.value(p.material);
      // Vertex colors, skins and morph targets add bytes only where a mesh has them, so the
      // fingerprints (and cached ideal frames) of other scenes stay what they were.
      if (!p.colors.empty()) h.array(p.colors);
      if (!p.color_alpha.empty()) h.array(p.color_alpha);
      if (!p.tangents.empty()) h.array(p.tangents);
      for (const std::vector<glm::vec2>& uvs : p.more_uvs) h.array(uvs);
      if (!p.joints.empty() || !p.targets.empty()) {
        h.array(p.joints);
        h.array(p.joint_weights);
        h.value(uint64_t(p.targets.size()));
        for (const MorphTarget& t : p.targets) {
          h.array(t.positions);
          h.array(t.normals);
          if (!t.tangents.empty()) h.array(t.tangents);
        }
      }
    }
    if (!m.weights.empty()) h.array(m.weights);
  }
  h.value(uint64_t(scene.materials.size()));
  for (const Material& m : scene.materials) {
    h.value(m.base_color_factor);
    h.value(m.base_color_texture);
    h.value(m.metallic);
    h.value(m.roughness);
    h.value(m.emissive);
    h.value(m.ambient.has_value());
    h.value(m.ambient.value_or(glm::vec3(0.0f)));
    h.value(m.double_sided);
    // Textures beyond the base color, and glass, add bytes only where a material has them
    // (other scenes' fingerprints stay).
    if (m.metallic_roughness_texture >= 0 || m.emissive_texture >= 0 || m.occlusion_texture >= 0 ||
        m.normal_texture >= 0) {
      h.value(m.metallic_roughness_texture);
      h.value(m.emissive_texture);
      h.value(m.occlusion_texture);
      h.value(m.occlusion_strength);
      h.value(m.normal_texture);
      h.value(m.normal_scale);
    }
    // The extensions' textures likewise.
    if (m.transmission_texture >= 0 || m.specular_texture >= 0 || m.specular_color_texture >= 0 ||
        m.clearcoat_texture >= 0 || m.clearcoat_roughness_texture >= 0 ||
        m.clearcoat_normal_texture >= 0) {
      h.value(m.transmission_texture);
      h.value(m.specular_texture);
      h.value(m.specular_color_texture);
      h.value(m.clearcoat_texture);
      h.value(m.clearcoat_roughness_texture);
      h.value(m.clearcoat_normal_texture);
      h.value(m.clearcoat_normal_scale);
    }
    if (m.uv_set != Material::TextureSets{}) {
      const Material::TextureSets& s = m.uv_set;
      for (uint8_t k : {s.base_color, s.metallic_roughness, s.emissive, s.occlusion, s.normal}) {
        h.value(k);
      }
      const Material::TextureSets core{s.base_color, s.metallic_roughness, s.emissive, s.occlusion,
                                       s.normal};
      if (s != core) {
        for (uint8_t k : {s.transmission, s.specular, s.specular_color, s.clearcoat,
                          s.clearcoat_roughness, s.clearcoat_normal}) {
          h.value(k);
        }
      }
    }
    if (m.unlit) h.value(m.unlit);
    if (m.has_specular_extension) {
      h.value(m.specular);
      h.value(m.specular_color);
    }
    if (m.iridescence > 0.0f) {
      h.value(m.iridescence);
      h.value(m.iridescence_ior);
      h.value(m.iridescence_thickness_min);
      h.value(m.iridescence_thickness_max);
      h.value(m.iridescence_texture);
      h.value(m.iridescence_thickness_texture);
      h.value(m.uv_set.iridescence);
      h.value(m.uv_set.iridescence_thickness);
    }
    if (m.specular_glossiness) {
      h.value(m.specular_glossiness);
      h.value(m.glossiness_texture);
      h.value(m.uv_set.glossiness);
    }
    if (m.clearcoat > 0.0f) {
      h.value(m.clearcoat);
      h.value(m.clearcoat_roughness);
    }
    if (m.sheen_color != glm::vec3(0.0f) || m.sheen_color_texture >= 0) {
      h.value(m.sheen_color);
      h.value(m.sheen_roughness);
      h.value(m.sheen_color_texture);
      h.value(m.sheen_roughness_texture);
      h.value(m.uv_set.sheen_color);
      h.value(m.uv_set.sheen_roughness);
    }
    if (m.anisotropy > 0.0f) {
      h.value(m.anisotropy);
      h.value(m.anisotropy_rotation);
      h.value(m.anisotropy_texture);
      h.value(m.uv_set.anisotropy);
    }
    if (m.diffuse_transmission > 0.0f || m.diffuse_transmission_texture >= 0 ||
        m.diffuse_transmission_color_texture >= 0) {
      h.value(m.diffuse_transmission);
      h.value(m.diffuse_transmission_color);
      h.value(m.diffuse_transmission_texture);
      h.value(m.diffuse_transmission_color_texture);
      h.value(m.uv_set.diffuse_transmission);
      h.value(m.uv_set.diffuse_transmission_color);
    }
    if (m.thickness > 0.0f) {
      h.value(m.thickness);
      h.value(m.attenuation_color);
      h.value(m.attenuation_distance);
      if (m.dispersion > 0.0f) h.value(m.dispersion);
    }
    if (m.alpha_mode != Material::AlphaMode::kOpaque) {
      h.value(m.alpha_mode);
      h.value(m.alpha_cutoff);
      // How BLEND is drawn (blended in each sample; builds before drew it opaque or hashed it):
      // a new value whenever that changes, so that frames cached before are not reused.
      if (m.alpha_mode == Material::AlphaMode::kBlend) h.value(uint32_t(2));
    }
    if (m.transmission != 0.0f || m.ior != 1.5f) {
      h.value(m.transmission);
      h.value(m.ior);
    }
    for (const Material::UvTransform& t : m.uv_transforms) {  // animated texture transforms
      h.value(t.offset);
      h.value(t.rotation);
      h.value(t.scale);
    }
  }
  h.value(uint64_t(scene.textures.size()));
  for (const Texture& t : scene.textures) {
    h.value(t.width);
    h.value(t.height);
    h.array(t.texels);
    if (!t.alpha.empty()) h.array(t.alpha);
    // A texture kept as codes (their mip levels coded too) adds them.
    if (!t.codes.empty()) {
      h.array(t.codes);
      h.value(t.encoding);
      h.value(t.coded_alpha);
    }
    if (t.wrap_s != Texture::Wrap::kRepeat || t.wrap_t != Texture::Wrap::kRepeat || t.nearest) {
      h.value(t.wrap_s);
      h.value(t.wrap_t);
      h.value(t.nearest);
    }
  }
  h.value(uint64_t(scene.lights.size()));
  for (const Light& l : scene.lights) {
    h.value(l.type);
    h.value(l.color);
    h.value(l.intensity);
    h.value(l.range);
    h.value(l.inner_cone_angle);
    h.value(l.outer_cone_angle);
    h.value(l.inverse_square_falloff);
    // Only a headlight adds bytes, so the fingerprints (and cached ideal frames) of scenes
    // with lights of their own stay what they were.
    if (l.on_camera) {
      h.value(l.on_camera);
      h.value(l.camera_rotation);
    }
  }
  h.value(uint64_t(scene.cameras.size()));
  for (const CameraModel& c : scene.cameras) {
    h.value(c.yfov);
    h.value(c.znear);
    if (c.ymag > 0.0) h.value(c.ymag);  // perspective cameras' fingerprints stay what they were
  }
  h.value(uint64_t(scene.nodes.size()));
  for (const Node& n : scene.nodes) {
    h.array(n.children);
    h.value(n.translation);
    h.value(n.rotation);
    h.value(n.scale);
    h.value(n.matrix.has_value());
    h.value(n.matrix.value_or(glm::dmat4(0.0)));
    h.value(n.mesh);
    h.value(n.camera);
    h.value(n.light);
    if (n.skin != -1 || !n.weights.empty()) {
      h.value(n.skin);
      h.array(n.weights);
    }
    if (!n.visible) h.value(n.visible);
  }
  if (!scene.skins.empty()) {
    h.value(uint64_t(scene.skins.size()));
    for (const Skin& s : scene.skins) {
      h.array(s.joints);
      h.array(s.inverse_bind_matrices);
    }
  }
  h.array(scene.roots);
  h.value(uint64_t(scene.channels.size()));
  for (const AnimationChannel& c : scene.channels) {
    h.value(c.node);
    h.value(c.path);
    h.value(c.interpolation);
    h.array(c.times);
    h.array(c.values);
    if (c.path == AnimatedPath::kWeights) {
      h.value(uint64_t(c.weight_count));
      h.array(c.weights);
    }
  }
  // KHR_animation_pointer's channels (lights, cameras, materials over time) add bytes only
  // where a scene has them.
  for (const PropertyChannel& p : scene.property_channels) {
    h.value(p.property);
    h.value(p.index);
    if (p.uv_set >= 0) h.value(p.uv_set);
    h.value(p.curve.interpolation);
    h.array(p.curve.times);
    h.array(p.curve.values);
  }
  h.value(scene.background);
  h.value(scene.ambient);
  // The file's ray depth (extras.afr_ray_depth), which replaces the tracer's own.
  if (scene.ray_depth) h.value(*scene.ray_depth);
  return h.digest();
}

}  // namespace afr::eval
