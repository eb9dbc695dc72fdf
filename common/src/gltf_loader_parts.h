// The glTF loader's parts: the Loader class that reads a file into a Scene, shared by the files
// that define its steps (gltf_loader.cpp: the file, its parsing and the scene; gltf_accessors.cpp,
// gltf_meshes.cpp, gltf_materials.cpp, gltf_nodes.cpp, gltf_animation.cpp). Not a public header.
#pragma once

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/log.h>
#include <afr/common/scene.h>

#include <fmt/format.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

namespace afr::gltf_detail {

namespace fs = std::filesystem;

// tinygltf takes the file length as unsigned int; larger files are refused before reading.
constexpr uint64_t kMaxFileBytes = uint64_t(1) << 31;
// Elements of one accessor. An accessor without a buffer view (all zeros, or sparse) has no
// bytes behind its count, so the count alone must not decide how much memory is allocated.
constexpr size_t kMaxAccessorCount = size_t(1) << 26;
constexpr size_t kMaxAccessorCountWithoutView = size_t(1) << 22;
// Morph target displacements (positions, normals, tangents) in one file: targets may share one
// accessor, so the accessor limits alone do not bound their memory.
constexpr size_t kMaxMorphDisplacements = size_t(1) << 24;
// Nodes, counting one for each instance EXT_mesh_gpu_instancing adds (each costs a few hundred
// bytes in the scene and a world transform in every scene state).
constexpr size_t kMaxNodes = size_t(1) << 20;

inline bool is_finite(std::span<const double> values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// What glTF allows for colors and weights: floats, or unsigned bytes or shorts normalized to
// [0, 1].
bool float_or_normalized(const tinygltf::Accessor& a);
// An accessor type's name as glTF writes it ("VEC3").
std::string_view type_name(int type);

// The folder tinygltf may read a file's buffers and images from (gltf_loader.cpp).
struct FileAccess {
  fs::path root;  // canonical folder of the glTF file
  std::vector<std::string> refused;
};

// What a KHR_animation_pointer names that afr animates, with the glTF index of its node, mesh,
// light, camera or material.
struct PointerTarget {
  enum class Kind { kNode, kMeshWeights, kProperty };
  Kind kind = Kind::kNode;
  std::string_view path;  // kNode: translation, rotation, scale or weights
  AnimatedProperty property = AnimatedProperty::kLightIntensity;  // kProperty
  size_t index = 0;
  // A texture transform's property (is_uv_property): its texture slot's path in the material
  // (kTextureSlots).
  std::string texture;
};

// Reads one glTF file into a Scene; one Loader serves one load. load() takes the steps in this
// order: parse (the file through tinygltf, with the KHR_animation_pointer channels tinygltf drops),
// check_extensions, decode_meshopt, the materials before the meshes (a primitive reads the texture
// coordinate sets its material's slots read), cameras, lights, nodes, skins, animations, and the
// scene's roots. Any problem with the file is an Error naming the file and what in it is wrong
// (fail); what afr reads differently from the file is one warning per kind (warn_once).
class Loader {
 public:
  Loader(const fs::path& path, GltfLoadReport* report, const GltfLoadOptions& options = {})
      : path_(path), report_(report), options_(options) {}

  // Loads the file at path_, or `bytes` as if they were its contents.
  Scene load();
  Scene load(std::span<const uint8_t> bytes);

 private:
  [[noreturn]] void fail(const std::string& problem) const {
    throw Error(fmt::format("{}: {}", path_.string(), problem));
  }
  // Logs one warning per feature key, however often the feature occurs.
  void warn_once(const std::string& feature, const std::string& message);
  // AnimationChannel::repair_key_order with a warning naming the channel when it repairs.
  void repair_key_order(AnimationChannel* channel, const std::string& what);

  std::vector<uint8_t> read_file() const;
  void parse(std::span<const uint8_t> bytes);
  // Fails naming what is wrong with a .glb's header and chunks; *kept: the chunks (header and
  // data) of the JSON and the BIN chunk, in order, those of unknown types left out (warned).
  void check_glb_layout(std::span<const uint8_t> bytes,
                        std::vector<std::span<const uint8_t>>* kept);
  void check_extensions();
  void hide_invisible_nodes();
  void read_animation_pointers(std::string_view json);
  void add_property_channel(const tinygltf::Animation& animation, int sampler_index,
                            AnimatedProperty property, size_t gltf_index, const std::string& what,
                            int uv_set = -1);
  bool read_sampler(const tinygltf::Animation& animation, int sampler_index, int value_type,
                    const std::string& what, AnimationChannel* channel, std::vector<float>* values);
  void add_channel(const tinygltf::Animation& animation, int sampler_index, int node_index,
                   const std::string& path, const std::string& what);
  void add_default_lighting();

  // Accessors.
  const tinygltf::Accessor& accessor_at(int index, const std::string& what) const;
  std::vector<uint8_t> gather(int index, int type, const std::string& what,
                              const tinygltf::Accessor** out);
  std::span<const uint8_t> buffer_view_bytes(int view, const std::string& what) const;
  std::vector<float> read_floats(int index, int type, const std::string& what);
  std::vector<uint32_t> read_indices(int index, const std::string& what);
  void decode_draco(const tinygltf::Primitive& in, const std::string& what);
  void decode_meshopt();
  std::vector<std::array<uint16_t, 4>> read_joints(int index, const std::string& what);
  std::vector<glm::vec3> read_vec3s(int index, size_t count, const std::string& attribute,
                                    const std::string& what);

  void load_meshes();
  bool load_primitive(const tinygltf::Primitive& in, const std::string& what, Primitive* out);
  void load_colors(int accessor, const std::string& what, size_t vertex_count, bool keep_alpha,
                   Primitive* out);
  void load_skinning(const tinygltf::Primitive& in, const std::string& what, Primitive* out);
  void load_targets(const tinygltf::Primitive& in, const std::string& what, Primitive* out);
  void load_skins();
  void drop_unused_joints();
  void load_materials();
  void read_transmission_and_ior(size_t m, const tinygltf::Material& in, const std::string& what,
                                 Material* out);
  const tinygltf::Value* material_extension(const tinygltf::Material& in, const char* name,
                                            const std::string& what, std::string* where) const;
  void read_number(const tinygltf::Value& e, const char* key, const std::string& where,
                   bool (*ok)(double), const char* range, float* out) const;
  void read_color(const tinygltf::Value& e, const char* key, const std::string& where,
                  bool (*ok)(double), const char* range, glm::vec3* out) const;
  void read_numbers(const tinygltf::Value& e, const char* key, const std::string& where,
                    bool (*ok)(double), const char* range, std::span<float> out) const;
  void read_specular_glossiness(size_t m, const tinygltf::Value& e, const std::string& where,
                                Material* out);
  void read_material_variants();
  void read_rtc_center();
  void read_specular(size_t m, const tinygltf::Material& in, const std::string& what,
                     Material* out);
  void read_clearcoat(size_t m, const tinygltf::Material& in, const std::string& what,
                      Material* out);
  void read_volume(const tinygltf::Material& in, const std::string& what, Material* out);
  void read_dispersion(const tinygltf::Material& in, const std::string& what, Material* out);
  void read_diffuse_transmission(size_t m, const tinygltf::Material& in, const std::string& what,
                                 Material* out);
  void read_sheen(size_t m, const tinygltf::Material& in, const std::string& what, Material* out);
  void read_anisotropy(size_t m, const tinygltf::Material& in, const std::string& what,
                       Material* out);
  void read_iridescence(size_t m, const tinygltf::Material& in, const std::string& what,
                        Material* out);
  std::optional<Material::UvTransform> read_texture_transform(
      const tinygltf::ExtensionMap& extensions, const std::string& what, int* tex_coord);
  // How a texture slot reads its image: as sRGB-encoded color, as linear data, or as linear
  // data taken from the image's alpha channel (KHR_materials_specular's specularTexture,
  // KHR_materials_sheen's sheenRoughnessTexture, KHR_materials_diffuse_transmission's
  // diffuseTransmissionTexture, the glossiness of
  // KHR_materials_pbrSpecularGlossiness), which the Texture then holds in its red, green and
  // blue.
  enum class ImageData : uint8_t { kColor, kLinear, kAlpha };
  // One texture slot of material m (its path in the material, kTextureSlots, its index,
  // texCoord and extensions as glTF gives them): the index of its decoded texture in
  // Scene::textures, or -1 where the slot is empty or its texture has no image. *set: the
  // material's texture coordinate set the slot reads (uv_sources_), added where no slot before
  // it reads the same TEXCOORD_n through the same KHR_texture_transform, or where an animation
  // drives the slot's transform (animated_uv_slots_).
  int read_texture_slot(size_t m, std::string_view path, int index, int tex_coord,
                        const tinygltf::ExtensionMap& extensions, ImageData data, uint8_t* set);
  // The same for a texture slot inside a material extension's object e (glTF's textureInfo:
  // index, texCoord, extensions); -1 where e has no such key. *scale: the slot's "scale" where
  // it is a normal texture (else null).
  int read_extension_texture(size_t m, const tinygltf::Value& e, const char* key,
                             const std::string& where, ImageData data, uint8_t* set,
                             float* scale = nullptr);
  struct UvSource;
  void read_texture_coordinates(const tinygltf::Primitive& in, const std::vector<UvSource>& sources,
                                const std::string& what, size_t vertex_count, Primitive* out);
  // A texture's sampler as a Texture holds it.
  struct TextureSampling {
    Texture::Wrap wrap_s = Texture::Wrap::kRepeat;
    Texture::Wrap wrap_t = Texture::Wrap::kRepeat;
    bool nearest = false;
    void apply(Texture* t) const {
      t->wrap_s = wrap_s;
      t->wrap_t = wrap_t;
      t->nearest = nearest;
    }
  };
  TextureSampling read_sampler(int sampler);
  int texture_for_image(int image_index, ImageData data, const TextureSampling& sampling);
  int add_texture(Texture texture);
  void keep_mask_alphas();
  void load_cameras();
  void load_lights();
  void load_nodes();
  void instance_node(int index);
  void load_animations();
  void load_scene_roots();

  glm::vec3 read_rgb_extra(const tinygltf::Value& extras, const char* key,
                           const std::string& what) const;

  fs::path path_;
  GltfLoadReport* report_;
  GltfLoadOptions options_;
  std::set<std::string> warned_;
  FileAccess access_;
  tinygltf::Model model_;
  Scene scene_;
  std::vector<int> camera_map_;  // glTF camera -> Scene::cameras, -1 when skipped
  std::vector<int> light_map_;   // glTF light -> Scene::lights, -1 when skipped
  // (glTF image, how it is read, wrap s, wrap t, nearest) -> Scene::textures: an image may be
  // read several ways (a base color reused as a mask, a specular color whose alpha is the
  // specular strength) and through several samplers.
  using TextureKey = std::tuple<int, ImageData, Texture::Wrap, Texture::Wrap, bool>;
  std::map<TextureKey, int> textures_;
  // A texture coordinate set of a material (Material::TextureSets): a TEXCOORD_n through a
  // KHR_texture_transform (none: the identity), and the first slot that reads it.
  struct UvSource {
    int tex_coord = 0;
    glm::dmat3 transform{1.0};
    std::string slot;
    // A slot whose transform an animation drives: its set holds TEXCOORD_n as it is (transform
    // stays the identity), shared with no other slot, and this is the file's transform, where
    // the animation starts from (Material::uv_transforms).
    std::optional<Material::UvTransform> animated;
  };
  // (glTF material, slot path) of each texture slot whose KHR_texture_transform a
  // KHR_animation_pointer channel drives (read_animation_pointers), and once the materials are
  // read, the set each of them reads.
  std::map<std::pair<size_t, std::string>, int> animated_uv_slots_;
  // Per glTF material, its sets in slot order (base color, metallic-roughness, or for
  // KHR_materials_pbrSpecularGlossiness diffuse, specular color and glossiness; emissive,
  // occlusion, normal, then the other extensions' slots: transmission, specular, specular color,
  // clearcoat, clearcoat roughness, clearcoat normal, sheen color, sheen roughness, anisotropy,
  // iridescence, iridescence thickness, diffuse transmission, diffuse transmission color);
  // empty for a material without textures, whose primitives read TEXCOORD_0 as they are.
  std::vector<std::vector<UvSource>> uv_sources_;
  size_t morph_displacements_ = 0;  // read so far, at most kMaxMorphDisplacements
  // The primitive being loaded, where it is Draco-compressed: its accessors' elements, decoded
  // (decode_draco), by accessor index; gather() reads them instead of a buffer.
  std::map<int, std::vector<uint8_t>> draco_bytes_;
  // EXT_ and KHR_meshopt_compression: the buffers that stand in for data that exists only
  // compressed (prepare_json), and each compressed buffer view's decoded bytes (decode_meshopt),
  // which buffer_view_bytes gives in place of its buffer's.
  std::set<int> placeholder_buffers_;
  std::map<int, std::vector<uint8_t>> meshopt_bytes_;
  // Nodes whose mesh EXT_mesh_gpu_instancing moved to one child node per instance.
  std::set<int> instanced_nodes_;
  // Nodes KHR_node_visibility hides (hide_invisible_nodes): they keep no mesh or light.
  std::set<int> hidden_nodes_;
  // KHR_animation_pointer channels whose pointer afr animates (read_animation_pointers), which
  // tinygltf drops for want of a target node.
  struct PointerChannel {
    size_t animation = 0;
    size_t channel = 0;  // its index among the animation's channels in the file
    int sampler = -1;
    PointerTarget target;
    std::string pointer;
  };
  std::vector<PointerChannel> pointer_channels_;
  bool nodeless_channels_are_pointers_ = false;
  bool background_given_ = false;  // the scene's extras give afr_background
  // Per animation, the index in the file of each channel tinygltf kept, where it dropped some
  // (read_animation_pointers), so that messages name the file's channel; empty otherwise.
  std::vector<std::vector<size_t>> kept_channels_;
};

}  // namespace afr::gltf_detail
