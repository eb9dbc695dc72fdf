#include <afr/common/gltf_loader.h>

#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>
#include <afr/common/image.h>
#include <afr/common/log.h>

#include <draco/compression/decode.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <meshoptimizer.h>
#include <sodium.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "gltf_meshopt_json.h"
#include "image_formats.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <numeric>
#include <optional>
#include <set>
#include <span>
#include <string_view>
#include <system_error>
#include <tuple>

namespace afr {
namespace {

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

// Extensions whose content afr reads (KHR_mesh_quantization only widens the component types
// of attributes, which the accessor reader converts anyway). A file that requires any other
// extension is refused; one that only uses another is loaded with a warning naming it.
constexpr std::array<std::string_view, 24> kSupportedExtensions = {
    "CESIUM_RTC",  // drawn relative to its center (read_rtc_center)
    "EXT_mesh_gpu_instancing",
    "EXT_meshopt_compression",
    "EXT_texture_webp",
    "KHR_animation_pointer",  // the properties pointer_target names (read_animation_pointers)
    "KHR_draco_mesh_compression",
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_dispersion",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",  // the default materials are drawn (read_material_variants)
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_meshopt_compression",
    "KHR_node_visibility",
    "KHR_texture_transform"};

// The default lighting of a scene without lights (what glTF viewers do): a directional
// headlight that moves with the scene's camera and a uniform sky term. The headlight comes from
// above and to the right of the view (about 31 degrees off its axis), so faces turned toward
// the camera differ in shade and shadows fall visibly; a white Lambertian surface facing it
// reflects about 0.8 (intensity / pi, the BRDF's convention), and the sky adds 0.2 times the
// base color everywhere, so that no surface the camera sees is black.
constexpr double kHeadlightIntensity = 2.5;
constexpr std::array<double, 3> kHeadlightFrom = {0.35, 0.5, 1.0};  // in the camera's frame
constexpr float kSkyRadiance = 0.2f;

bool is_finite(std::span<const double> values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// ---- File access for tinygltf ----
//
// A glTF file names its buffers and images by URI. Files are untrusted, so tinygltf may read
// only regular files inside the folder of the glTF file (never "/etc/passwd" or "../../x").

struct FileAccess {
  fs::path root;  // canonical folder of the glTF file
  std::vector<std::string> refused;
};

bool inside_root(const FileAccess& access, const std::string& file, fs::path* resolved) {
  const std::optional<fs::path> p = file_in_gltf_folder(access.root, file);
  if (p) *resolved = *p;
  return p.has_value();
}

// A base64 data URI that tinygltf does not know as one (it knows those of PNG, JPEG and a few
// more; not WebP's): tinygltf takes it for a file name, which it has URI-decoded (a '+' turned
// into a space) and put in the glTF file's folder ("<folder>/data:..."). The URI's bytes, or
// nothing where `file` is not such a URI or does not decode.
std::optional<std::vector<unsigned char>> data_uri_bytes(const std::string& file) {
  const size_t start = file.find("data:");
  if (start == std::string::npos || (start > 0 && file[start - 1] != '/')) return std::nullopt;
  const size_t comma = file.find(";base64,", start);
  if (comma == std::string::npos) return std::nullopt;
  std::string text = file.substr(comma + 8);
  std::replace(text.begin(), text.end(), ' ', '+');
  if (text.size() > kMaxFileBytes) return std::nullopt;
  std::vector<unsigned char> bytes(text.size() / 4 * 3 + 3);
  size_t length = 0;
  if (sodium_base642bin(bytes.data(), bytes.size(), text.data(), text.size(), nullptr, &length,
                        nullptr, sodium_base64_VARIANT_ORIGINAL) != 0) {
    return std::nullopt;
  }
  bytes.resize(length);
  return bytes;
}

bool file_exists(const std::string& file, void* user_data) {
  if (data_uri_bytes(file)) return true;
  auto* access = static_cast<FileAccess*>(user_data);
  fs::path p;
  std::error_code ec;
  if (!inside_root(*access, file, &p)) {
    if (fs::exists(fs::path(file), ec)) access->refused.push_back(file);
    return false;
  }
  return fs::is_regular_file(p, ec);
}

std::string expand_file_path(const std::string& file, void*) { return file; }

bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& file,
                     void* user_data) {
  if (std::optional<std::vector<unsigned char>> bytes = data_uri_bytes(file)) {
    *out = std::move(*bytes);
    return true;
  }
  auto* access = static_cast<FileAccess*>(user_data);
  fs::path p;
  std::error_code ec;
  if (!inside_root(*access, file, &p) || !fs::is_regular_file(p, ec)) {
    if (err) *err += "not a file inside the folder of the glTF file";
    return false;
  }
  const uintmax_t size = fs::file_size(p, ec);
  if (ec || size > kMaxFileBytes) {
    if (err) *err += ec ? ec.message() : std::string("file too large");
    return false;
  }
  std::ifstream in(p, std::ios::binary);
  out->resize(size_t(size));
  if (!in || !in.read(reinterpret_cast<char*>(out->data()), std::streamsize(size))) {
    if (err) *err += "read error";
    return false;
  }
  return true;
}

bool write_whole_file(std::string* err, const std::string&, const std::vector<unsigned char>&,
                      void*) {
  if (err) *err += "afr never writes through the glTF loader";
  return false;
}

// tinygltf's image hook. Images are decoded by afr::decode_image only, and only those a
// material uses, once loading has finished (Loader::texture_for_image): here the encoded bytes
// of a URI image are kept, and a buffer-view image is left in its buffer, whose bounds afr
// checks itself before reading it.
bool keep_encoded_image(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void*) {
  if (image->bufferView >= 0) return true;
  if (bytes != nullptr && size > 0) image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

// ---- The loader ----

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

// The paths in a material of the texture slots afr reads, as KHR_animation_pointer names them
// (the object model's, and those of the archived KHR_materials_pbrSpecularGlossiness).
constexpr std::string_view kTextureSlots[] = {
    "pbrMetallicRoughness/baseColorTexture",
    "pbrMetallicRoughness/metallicRoughnessTexture",
    "emissiveTexture",
    "occlusionTexture",
    "normalTexture",
    "extensions/KHR_materials_transmission/transmissionTexture",
    "extensions/KHR_materials_specular/specularTexture",
    "extensions/KHR_materials_specular/specularColorTexture",
    "extensions/KHR_materials_clearcoat/clearcoatTexture",
    "extensions/KHR_materials_clearcoat/clearcoatRoughnessTexture",
    "extensions/KHR_materials_clearcoat/clearcoatNormalTexture",
    "extensions/KHR_materials_sheen/sheenColorTexture",
    "extensions/KHR_materials_sheen/sheenRoughnessTexture",
    "extensions/KHR_materials_anisotropy/anisotropyTexture",
    "extensions/KHR_materials_iridescence/iridescenceTexture",
    "extensions/KHR_materials_iridescence/iridescenceThicknessTexture",
    "extensions/KHR_materials_pbrSpecularGlossiness/diffuseTexture",
    "extensions/KHR_materials_pbrSpecularGlossiness/specularGlossinessTexture",
};

// Index digits as a pointer writes them (plain decimal, fewer than 10), or nothing.
std::optional<size_t> pointer_index(std::string_view digits) {
  size_t index = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
  if (ec != std::errc() || end != digits.data() + digits.size() || digits.size() >= 10 ||
      digits.find_first_not_of("0123456789") != std::string_view::npos) {
    return std::nullopt;
  }
  return index;
}

// A pointer to a texture slot's KHR_texture_transform offset, rotation or scale
// (/materials/N/SLOT/extensions/KHR_texture_transform/PROPERTY), or nothing.
std::optional<PointerTarget> texture_transform_target(std::string_view pointer) {
  static constexpr std::string_view kPrefix = "/materials/";
  static constexpr std::string_view kTransform = "/extensions/KHR_texture_transform/";
  const size_t at = pointer.rfind(kTransform);
  if (!pointer.starts_with(kPrefix) || at == std::string_view::npos) return std::nullopt;
  const std::string_view property = pointer.substr(at + kTransform.size());
  PointerTarget t;
  t.kind = PointerTarget::Kind::kProperty;
  if (property == "offset") {
    t.property = AnimatedProperty::kUvOffset;
  } else if (property == "rotation") {
    t.property = AnimatedProperty::kUvRotation;
  } else if (property == "scale") {
    t.property = AnimatedProperty::kUvScale;
  } else {
    return std::nullopt;  // texCoord: not animated
  }
  const std::string_view rest = pointer.substr(kPrefix.size(), at - kPrefix.size());
  const size_t slash = rest.find('/');
  if (slash == std::string_view::npos) return std::nullopt;
  const std::optional<size_t> index = pointer_index(rest.substr(0, slash));
  const std::string_view slot = rest.substr(slash + 1);
  if (!index || std::find(std::begin(kTextureSlots), std::end(kTextureSlots), slot) ==
                    std::end(kTextureSlots)) {
    return std::nullopt;
  }
  t.index = *index;
  t.texture = std::string(slot);
  return t;
}

// The target of `pointer` (PREFIX INDEX SUFFIX, the index plain decimal digits), or nothing
// for a pointer afr does not animate.
std::optional<PointerTarget> pointer_target(std::string_view pointer) {
  using Kind = PointerTarget::Kind;
  struct Form {
    std::string_view prefix, suffix;
    Kind kind;
    AnimatedProperty property = AnimatedProperty::kLightIntensity;
  };
  static constexpr std::string_view kLights = "/extensions/KHR_lights_punctual/lights/";
  static const Form kForms[] = {
      {"/nodes/", "/translation", Kind::kNode},
      {"/nodes/", "/rotation", Kind::kNode},
      {"/nodes/", "/scale", Kind::kNode},
      {"/nodes/", "/weights", Kind::kNode},
      {"/nodes/", "/extensions/KHR_node_visibility/visible", Kind::kProperty,
       AnimatedProperty::kNodeVisible},
      {"/meshes/", "/weights", Kind::kMeshWeights},
      {kLights, "/color", Kind::kProperty, AnimatedProperty::kLightColor},
      {kLights, "/intensity", Kind::kProperty, AnimatedProperty::kLightIntensity},
      {kLights, "/range", Kind::kProperty, AnimatedProperty::kLightRange},
      {kLights, "/spot/innerConeAngle", Kind::kProperty, AnimatedProperty::kLightInnerCone},
      {kLights, "/spot/outerConeAngle", Kind::kProperty, AnimatedProperty::kLightOuterCone},
      {"/cameras/", "/perspective/yfov", Kind::kProperty, AnimatedProperty::kCameraYfov},
      {"/cameras/", "/perspective/znear", Kind::kProperty, AnimatedProperty::kCameraZnear},
      {"/cameras/", "/orthographic/znear", Kind::kProperty, AnimatedProperty::kCameraZnear},
      {"/cameras/", "/orthographic/ymag", Kind::kProperty, AnimatedProperty::kCameraYmag},
      {"/materials/", "/pbrMetallicRoughness/baseColorFactor", Kind::kProperty,
       AnimatedProperty::kBaseColorFactor},
      {"/materials/", "/pbrMetallicRoughness/metallicFactor", Kind::kProperty,
       AnimatedProperty::kMetallicFactor},
      {"/materials/", "/pbrMetallicRoughness/roughnessFactor", Kind::kProperty,
       AnimatedProperty::kRoughnessFactor},
      {"/materials/", "/emissiveFactor", Kind::kProperty, AnimatedProperty::kEmissiveFactor},
      {"/materials/", "/extensions/KHR_materials_emissive_strength/emissiveStrength",
       Kind::kProperty, AnimatedProperty::kEmissiveStrength},
      {"/materials/", "/alphaCutoff", Kind::kProperty, AnimatedProperty::kAlphaCutoff},
      {"/materials/", "/normalTexture/scale", Kind::kProperty, AnimatedProperty::kNormalScale},
      {"/materials/", "/occlusionTexture/strength", Kind::kProperty,
       AnimatedProperty::kOcclusionStrength},
      {"/materials/", "/extensions/KHR_materials_clearcoat/clearcoatFactor", Kind::kProperty,
       AnimatedProperty::kClearcoatFactor},
      {"/materials/", "/extensions/KHR_materials_clearcoat/clearcoatRoughnessFactor",
       Kind::kProperty, AnimatedProperty::kClearcoatRoughnessFactor},
      {"/materials/", "/extensions/KHR_materials_sheen/sheenColorFactor", Kind::kProperty,
       AnimatedProperty::kSheenColorFactor},
      {"/materials/", "/extensions/KHR_materials_sheen/sheenRoughnessFactor", Kind::kProperty,
       AnimatedProperty::kSheenRoughnessFactor},
      {"/materials/", "/extensions/KHR_materials_specular/specularFactor", Kind::kProperty,
       AnimatedProperty::kSpecularFactor},
      {"/materials/", "/extensions/KHR_materials_specular/specularColorFactor", Kind::kProperty,
       AnimatedProperty::kSpecularColorFactor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceFactor", Kind::kProperty,
       AnimatedProperty::kIridescenceFactor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceIor", Kind::kProperty,
       AnimatedProperty::kIridescenceIor},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceThicknessMinimum",
       Kind::kProperty, AnimatedProperty::kIridescenceThicknessMinimum},
      {"/materials/", "/extensions/KHR_materials_iridescence/iridescenceThicknessMaximum",
       Kind::kProperty, AnimatedProperty::kIridescenceThicknessMaximum},
      {"/materials/", "/extensions/KHR_materials_anisotropy/anisotropyStrength", Kind::kProperty,
       AnimatedProperty::kAnisotropyStrength},
      {"/materials/", "/extensions/KHR_materials_anisotropy/anisotropyRotation", Kind::kProperty,
       AnimatedProperty::kAnisotropyRotation},
      {"/materials/", "/extensions/KHR_materials_transmission/transmissionFactor", Kind::kProperty,
       AnimatedProperty::kTransmissionFactor},
      {"/materials/", "/extensions/KHR_materials_ior/ior", Kind::kProperty, AnimatedProperty::kIor},
      {"/materials/", "/extensions/KHR_materials_volume/thicknessFactor", Kind::kProperty,
       AnimatedProperty::kThicknessFactor},
      {"/materials/", "/extensions/KHR_materials_volume/attenuationDistance", Kind::kProperty,
       AnimatedProperty::kAttenuationDistance},
      {"/materials/", "/extensions/KHR_materials_volume/attenuationColor", Kind::kProperty,
       AnimatedProperty::kAttenuationColor},
      {"/materials/", "/extensions/KHR_materials_dispersion/dispersion", Kind::kProperty,
       AnimatedProperty::kDispersion},
  };
  for (const Form& f : kForms) {
    if (pointer.size() <= f.prefix.size() + f.suffix.size() || !pointer.starts_with(f.prefix) ||
        !pointer.ends_with(f.suffix)) {
      continue;
    }
    const std::optional<size_t> index = pointer_index(
        pointer.substr(f.prefix.size(), pointer.size() - f.prefix.size() - f.suffix.size()));
    if (index) return PointerTarget{f.kind, f.suffix.substr(1), f.property, *index, {}};
  }
  return texture_transform_target(pointer);
}

class Loader {
 public:
  Loader(const fs::path& path, GltfLoadReport* report) : path_(path), report_(report) {}

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
  void read_sheen(size_t m, const tinygltf::Material& in, const std::string& what, Material* out);
  void read_anisotropy(size_t m, const tinygltf::Material& in, const std::string& what,
                       Material* out);
  void read_iridescence(size_t m, const tinygltf::Material& in, const std::string& what,
                        Material* out);
  std::optional<Material::UvTransform> read_texture_transform(
      const tinygltf::ExtensionMap& extensions, const std::string& what, int* tex_coord);
  // How a texture slot reads its image: as sRGB-encoded color, as linear data, or as linear
  // data taken from the image's alpha channel (KHR_materials_specular's specularTexture,
  // KHR_materials_sheen's sheenRoughnessTexture, the glossiness of
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
  // iridescence, iridescence thickness);
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
  // Per animation, the index in the file of each channel tinygltf kept, where it dropped some
  // (read_animation_pointers), so that messages name the file's channel; empty otherwise.
  std::vector<std::vector<size_t>> kept_channels_;
};

void Loader::warn_once(const std::string& feature, const std::string& message) {
  if (!warned_.insert(feature).second) return;
  std::string line = fmt::format("{}: {}", path_.string(), message);
  spdlog::warn("{}", line);
  if (report_ != nullptr) report_->warnings.push_back(std::move(line));
}

void Loader::repair_key_order(AnimationChannel* channel, const std::string& what) {
  const size_t before = channel->times.size();
  const AnimationChannel::KeyRepair fix = channel->repair_key_order();
  if (!fix.repaired) return;
  std::string line = fmt::format(
      "{}: {}: keyframe times are not strictly increasing, as glTF requires; keys sorted by "
      "time, {} of {} dropped where a later key has the same time",
      path_.string(), what, fix.dropped, before);
  spdlog::warn("{}", line);
  if (report_ != nullptr) report_->warnings.push_back(std::move(line));
}

std::vector<uint8_t> Loader::read_file() const {
  std::error_code ec;
  if (!fs::exists(path_, ec)) fail("no such file");
  if (!fs::is_regular_file(path_, ec)) fail("not a regular file");
  const uintmax_t size = fs::file_size(path_, ec);
  if (ec) fail(fmt::format("cannot read the file size: {}", ec.message()));
  if (size > kMaxFileBytes) fail(fmt::format("file of {} bytes is larger than afr accepts", size));
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  std::ifstream in(path_, std::ios::binary);
  if (!in || !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size))) {
    fail("cannot read the file");
  }
  return bytes;
}

namespace {

// tinygltf's messages, one problem per line, as one line: "a; b; c".
std::string one_line(const std::string& text) {
  std::string out;
  size_t start = 0;
  while (start <= text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\r')) line.pop_back();
    if (!line.empty()) out += (out.empty() ? "" : "; ") + line;
    start = end + 1;
  }
  return out;
}

uint32_t read_u32_le(std::span<const uint8_t> bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v |= uint32_t(bytes[at + i]) << (8 * i);
  return v;
}

}  // namespace

// tinygltf says only "Invalid glTF binary." for most broken .glb files; say what is wrong
// (glTF 2.0, 4.4: a 12-byte header of magic, version 2 and the total length, then chunks of
// an 8-byte header, the length and type, the JSON chunk first and at most one BIN chunk).
void Loader::check_glb_layout(std::span<const uint8_t> bytes,
                              std::vector<std::span<const uint8_t>>* kept) {
  constexpr uint32_t kJson = 0x4E4F534Au, kBin = 0x004E4942u;
  if (bytes.size() < 12) {
    fail(fmt::format("truncated .glb: {} bytes, shorter than its 12-byte header", bytes.size()));
  }
  const uint32_t version = read_u32_le(bytes, 4), declared = read_u32_le(bytes, 8);
  if (version != 2) fail(fmt::format(".glb of version {}: afr reads version 2", version));
  if (declared > bytes.size()) {
    fail(fmt::format("truncated .glb: the header declares {} bytes but the file has {}", declared,
                     bytes.size()));
  }
  const size_t end = declared;  // bytes past the declared length are not the file's
  size_t at = 12;
  bool seen_bin = false;
  for (int chunk = 0; at < end; ++chunk) {
    if (end - at < 8) {
      fail(fmt::format("truncated .glb: chunk {} at byte {} has {} of its 8 header bytes", chunk,
                       at, end - at));
    }
    const uint32_t length = read_u32_le(bytes, at), type = read_u32_le(bytes, at + 4);
    if (length > end - at - 8) {
      fail(fmt::format("truncated .glb: chunk {} declares {} bytes but {} follow its header", chunk,
                       length, end - at - 8));
    }
    if (chunk == 0 && type != kJson) {
      fail(fmt::format(".glb's first chunk is of type 0x{:08x}, not JSON (0x{:08x})", type, kJson));
    }
    if (chunk == 0 && length == 0) fail(".glb's JSON chunk is empty");
    if (chunk > 0 && type == kJson) fail(fmt::format(".glb has a second JSON chunk ({})", chunk));
    if (chunk > 0 && type != kBin) {
      // Readers must skip chunks of types they do not know (4.4.3.1); tinygltf refuses them.
      warn_once("glb chunk",
                fmt::format(".glb chunk {} of unknown type 0x{:08x} ignored", chunk, type));
    } else if (type == kBin && seen_bin) {
      warn_once(
          "glb bin",
          fmt::format(".glb chunk {} is a second BIN chunk (one is allowed): ignored", chunk));
    } else {
      seen_bin = seen_bin || type == kBin;
      kept->push_back(bytes.subspan(at, 8 + size_t(length)));
    }
    at += 8 + size_t(length);
  }
  if (at == 12) fail("truncated .glb: no JSON chunk after its 12-byte header");
}

// Two things in a file's JSON that tinygltf refuses although the extensions it uses allow them,
// put right before tinygltf reads it (for tinygltf's sake only):
// - KHR_draco_mesh_compression: a primitive's indices accessor without a buffer view (its
//   indices are in the Draco data) is given its primitive's Draco buffer view; decode_draco
//   fills it before anything reads it.
// - EXT_ and KHR_meshopt_compression: a placeholder buffer without a "uri" (the data of the
//   buffer views that use it exists only compressed), and a buffer the extension marks as a
//   fallback (which a reader that decodes need not load), become a buffer of 3 zero bytes in a
//   data URI. Their indices go to *placeholders; decode_meshopt fills every compressed view,
//   and buffer_view_bytes names a placeholder if anything else reads one.
// Returns the JSON changed, or empty where nothing is to change (or the JSON does not parse:
// tinygltf then says what is wrong).
namespace {

bool point_draco_indices(nlohmann::json* doc) {
  const auto accessors = doc->find("accessors");
  const auto meshes = doc->find("meshes");
  if (accessors == doc->end() || !accessors->is_array() || meshes == doc->end() ||
      !meshes->is_array()) {
    return false;
  }
  bool changed = false;
  for (const nlohmann::json& mesh : *meshes) {
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) {
      continue;
    }
    for (const nlohmann::json& p : mesh["primitives"]) {
      if (!p.is_object() || !p.contains("indices") || !p["indices"].is_number_unsigned() ||
          !p.contains("extensions") || !p["extensions"].is_object() ||
          !p["extensions"].contains("KHR_draco_mesh_compression")) {
        continue;
      }
      const nlohmann::json& draco = p["extensions"]["KHR_draco_mesh_compression"];
      const size_t index = p["indices"].get<size_t>();
      if (!draco.is_object() || !draco.contains("bufferView") ||
          !draco["bufferView"].is_number_unsigned() || index >= accessors->size()) {
        continue;
      }
      nlohmann::json& accessor = (*accessors)[index];
      if (!accessor.is_object() || accessor.contains("bufferView")) continue;
      accessor["bufferView"] = draco["bufferView"];
      changed = true;
    }
  }
  return changed;
}

bool stand_in_meshopt_placeholders(nlohmann::json* doc, bool binary, std::set<int>* placeholders) {
  const auto buffers = doc->find("buffers");
  if (!gltf_meshopt::used(*doc) || buffers == doc->end() || !buffers->is_array()) return false;
  bool changed = false;
  for (size_t i = 0; i < buffers->size(); ++i) {
    nlohmann::json& buffer = (*buffers)[i];
    if (!gltf_meshopt::holds_no_data(buffer, i, binary)) continue;
    buffer["uri"] = "data:application/octet-stream;base64,AAAA";
    buffer["byteLength"] = 3;
    placeholders->insert(int(i));
    changed = true;
  }
  return changed;
}

std::string prepare_json(std::string_view text, bool binary, std::set<int>* placeholders) {
  const bool draco = text.find("KHR_draco_mesh_compression") != std::string_view::npos;
  const bool meshopt = text.find("_meshopt_compression") != std::string_view::npos;
  if (!draco && !meshopt) return {};
  nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) return {};
  bool changed = draco && point_draco_indices(&doc);
  changed = (meshopt && stand_in_meshopt_placeholders(&doc, binary, placeholders)) || changed;
  return changed ? doc.dump() : std::string();
}

// Why afr cannot read an asset of this `asset.version` and `asset.minVersion`, or "" when it
// can: glTF 2.x without a minVersion above 2.0 (a later 2.x stays readable as 2.0). glTF 1.0
// is another format (objects keyed by ID, shaders in the file), which tinygltf would read as an
// empty scene or refuse over some unrelated property, so the version is told first.
std::string version_problem(const std::string& version, const std::string& min_version) {
  const auto major_minor = [](const std::string& text) -> std::optional<std::pair<int, int>> {
    int major = 0;
    int minor = 0;
    char rest = 0;
    if (std::sscanf(text.c_str(), "%d.%d%c", &major, &minor, &rest) != 2) return std::nullopt;
    return std::pair(major, minor);
  };
  const auto v = major_minor(version);
  int major = 0;
  char rest = 0;
  const bool major_only = std::sscanf(version.c_str(), "%d%c", &major, &rest) == 1;
  if (!v && !(major_only && major != 2)) {
    return fmt::format("asset.version \"{}\" is not a glTF version (major.minor, such as 2.0)",
                       version);
  }
  if (!v || v->first != 2) {
    return fmt::format(
        "glTF {}: afr reads glTF 2.0 (a 1.0 file can be converted to 2.0, for "
        "example with gltf-pipeline)",
        version);
  }
  if (min_version.empty()) return {};
  const auto m = major_minor(min_version);
  if (!m) return fmt::format("asset.minVersion \"{}\" is not a glTF version", min_version);
  if (*m > std::pair(2, 0)) {
    return fmt::format("the file requires glTF {} (asset.minVersion): afr reads glTF 2.0",
                       min_version);
  }
  return {};
}

// version_problem() for a file tinygltf refused, read from its JSON; "" when the JSON has no
// asset.version to blame.
std::string version_problem_in(std::string_view json) {
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) return {};
  const auto asset = doc.find("asset");
  if (asset == doc.end() || !asset->is_object()) return {};
  const auto version = asset->find("version");
  if (version == asset->end()) return {};
  // (glTF 1.0 files in the wild write it as a number too.)
  const std::string text = version->is_string() ? version->get<std::string>() : version->dump();
  const auto min_version = asset->find("minVersion");
  return version_problem(text, min_version != asset->end() && min_version->is_string()
                                   ? min_version->get<std::string>()
                                   : std::string());
}

// tinygltf refuses some files without saying why (a skin without joints). The first object
// that lacks a property glTF requires, named, or empty when none does.
std::string missing_property_in(std::string_view json) {
  struct Required {
    const char* array;     // top-level array
    const char* singular;  // how its elements are named
    const char* property;
  };
  static constexpr Required kRequired[] = {
      {"accessors", "accessor", "componentType"},
      {"accessors", "accessor", "count"},
      {"accessors", "accessor", "type"},
      {"animations", "animation", "channels"},
      {"animations", "animation", "samplers"},
      {"buffers", "buffer", "byteLength"},
      {"bufferViews", "buffer view", "buffer"},
      {"bufferViews", "buffer view", "byteLength"},
      {"cameras", "camera", "type"},
      {"meshes", "mesh", "primitives"},
      {"skins", "skin", "joints"},
  };
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) return {};
  for (const Required& r : kRequired) {
    const auto array = doc.find(r.array);
    if (array == doc.end() || !array->is_array()) continue;
    for (size_t i = 0; i < array->size(); ++i) {
      const nlohmann::json& element = (*array)[i];
      if (element.is_object() && !element.contains(r.property)) {
        return fmt::format("{} {} has no \"{}\", which glTF requires", r.singular, i, r.property);
      }
    }
  }
  return {};
}

}  // namespace

void Loader::parse(std::span<const uint8_t> bytes) {
  if (bytes.size() > kMaxFileBytes) {
    fail(fmt::format("file of {} bytes is larger than afr accepts", bytes.size()));
  }
  std::error_code ec;
  access_.root = fs::weakly_canonical(fs::absolute(path_).parent_path(), ec);
  if (ec) fail(fmt::format("cannot resolve its folder: {}", ec.message()));

  tinygltf::TinyGLTF gltf;
  gltf.SetImageLoader(&keep_encoded_image, nullptr);
  gltf.SetFsCallbacks(
      {&file_exists, &expand_file_path, &read_whole_file, &write_whole_file, &access_});

  std::string err;
  std::string warn;
  const std::string base_dir = access_.root.string();
  const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  // A .glb without the chunks check_glb_layout skips, or a file whose JSON prepare_json
  // changed.
  std::vector<uint8_t> rewritten;
  std::string_view json_text;  // as in the file, for version_problem_in
  const auto as_text = [](std::span<const uint8_t> b) {
    return std::string_view(reinterpret_cast<const char*>(b.data()), b.size());
  };
  if (binary) {
    std::vector<std::span<const uint8_t>> chunks;
    check_glb_layout(bytes, &chunks);
    json_text = as_text(chunks[0].subspan(8));
    std::string json = prepare_json(json_text, true, &placeholder_buffers_);
    size_t kept_bytes = 12;
    bool unpadded = false;
    for (size_t c = 0; c < chunks.size(); ++c) {
      kept_bytes += chunks[c].size();
      if (chunks[c].size() % 4 != 0) {
        // The format pads every chunk to 4 bytes; some writers leave the last one unpadded,
        // which viewers read, and so does afr (tinygltf refuses a BIN chunk so left).
        unpadded = true;
        warn_once("glb padding",
                  fmt::format(".glb chunk {} is {} bytes long, not a multiple of 4 as the format "
                              "requires: read as if padded",
                              c, chunks[c].size() - 8));
      }
    }
    if (!json.empty() || unpadded || kept_bytes != size_t(read_u32_le(bytes, 8))) {
      const auto put_u32 = [&](size_t v) {
        for (int i = 0; i < 4; ++i) rewritten.push_back(uint8_t(v >> (8 * i)));
      };
      // A chunk: its length, its type, its data, padded with `pad` to 4 bytes.
      const auto put_chunk = [&](std::span<const uint8_t> type, std::span<const uint8_t> data,
                                 uint8_t pad) {
        const size_t padded = (data.size() + 3) / 4 * 4;
        put_u32(padded);
        rewritten.insert(rewritten.end(), type.begin(), type.end());
        rewritten.insert(rewritten.end(), data.begin(), data.end());
        rewritten.resize(rewritten.size() + (padded - data.size()), pad);
      };
      rewritten.assign(bytes.begin(), bytes.begin() + 8);
      put_u32(0);  // the length, once known
      const auto json_data =
          json.empty() ? chunks[0].subspan(8)
                       : std::span(reinterpret_cast<const uint8_t*>(json.data()), json.size());
      put_chunk(chunks[0].subspan(4, 4), json_data, ' ');
      for (size_t c = 1; c < chunks.size(); ++c) {
        put_chunk(chunks[c].subspan(4, 4), chunks[c].subspan(8), 0);
      }
      for (int i = 0; i < 4; ++i) rewritten[size_t(8 + i)] = uint8_t(rewritten.size() >> (8 * i));
      bytes = rewritten;
    }
  } else {
    json_text = as_text(bytes);
    if (std::string json = prepare_json(json_text, false, &placeholder_buffers_); !json.empty()) {
      rewritten.assign(json.begin(), json.end());
      bytes = rewritten;
    }
  }
  bool ok = false;
  // tinygltf mostly reports through `err`, but some inputs (such as an empty data URI) make it
  // throw a standard exception instead.
  try {
    if (binary) {
      ok = gltf.LoadBinaryFromMemory(&model_, &err, &warn, bytes.data(),
                                     static_cast<unsigned int>(bytes.size()), base_dir);
    } else {
      ok = gltf.LoadASCIIFromString(&model_, &err, &warn,
                                    reinterpret_cast<const char*>(bytes.data()),
                                    static_cast<unsigned int>(bytes.size()), base_dir);
    }
  } catch (const std::exception& e) {
    fail(fmt::format("invalid glTF: {}", e.what()));
  }
  if (!ok) {
    if (std::string problem = version_problem_in(json_text); !problem.empty()) fail(problem);
    // Some failures (an empty image file) are told only as a warning.
    std::string problem = one_line(err.empty() ? warn : err);
    for (const std::string& file : access_.refused) {
      problem += fmt::format(" (refused to read {}: outside the folder of the glTF file)", file);
    }
    if (problem.empty()) problem = missing_property_in(json_text);
    fail(fmt::format("invalid glTF: {}",
                     problem.empty() ? "the parser gave no reason (tinygltf)" : problem));
  }
  if (std::string problem = version_problem(model_.asset.version, model_.asset.minVersion);
      !problem.empty()) {
    fail(problem);
  }
  if (json_text.find("KHR_animation_pointer") != std::string_view::npos ||
      err.find("field is missing in animation") != std::string::npos) {  // a channel dropped
    read_animation_pointers(json_text);
  }
  // tinygltf warns about things such as a missing external image, and tells in `err` what it
  // skipped without failing (an animation channel without a target node: glTF allows those for
  // extensions to drive, tinygltf drops them); pass them on.
  for (const std::string* text : {&warn, &err}) {
    size_t start = 0;
    while (start < text->size()) {
      size_t end = text->find('\n', start);
      if (end == std::string::npos) end = text->size();
      if (end > start) {
        const std::string line = text->substr(start, end - start);
        // (tinygltf says it in two lines: "'node' property is missing." and "`node` field is
        // missing in animation.channels.target".)
        if (line.find("`node` field is missing in animation.channels.target") !=
                std::string::npos ||
            line == "'node' property is missing.") {
          // (KHR_animation_pointer's channels have none; read_animation_pointers reads them.)
          if (!nodeless_channels_are_pointers_) {
            warn_once("channel without node",
                      "animation channels without a target node are not supported (skipped)");
          }
        } else if (line != "'inverseBindMatrices' property is missing in Skin.") {
          // (tinygltf takes that optional property for a required one: glTF's default, identity
          // matrices, is what load_skins uses.)
          warn_once("tinygltf: " + line, line);
        }
      }
      start = end + 1;
    }
  }
}

void Loader::check_extensions() {
  std::set<std::string> used(model_.extensionsUsed.begin(), model_.extensionsUsed.end());
  used.insert(model_.extensionsRequired.begin(), model_.extensionsRequired.end());
  auto add = [&](const tinygltf::ExtensionMap& map) {
    for (const auto& [name, value] : map) used.insert(name);
  };
  add(model_.extensions);
  for (const auto& s : model_.scenes) add(s.extensions);
  for (const auto& n : model_.nodes) add(n.extensions);
  for (const auto& m : model_.meshes) {
    add(m.extensions);
    for (const auto& p : m.primitives) add(p.extensions);
  }
  for (const auto& m : model_.materials) {
    add(m.extensions);
    add(m.pbrMetallicRoughness.baseColorTexture.extensions);
  }
  for (const auto& t : model_.textures) add(t.extensions);
  for (const auto& i : model_.images) add(i.extensions);
  for (const auto& c : model_.cameras) add(c.extensions);
  std::vector<std::string> required_missing;
  for (const auto& name : used) {
    if (std::find(kSupportedExtensions.begin(), kSupportedExtensions.end(), name) !=
        kSupportedExtensions.end()) {
      continue;
    }
    const bool required =
        std::find(model_.extensionsRequired.begin(), model_.extensionsRequired.end(), name) !=
        model_.extensionsRequired.end();
    if (required) {
      required_missing.push_back(name);
    } else {
      warn_once("extension " + name,
                fmt::format("extension {} is not supported (its content is ignored)", name));
    }
  }
  if (!required_missing.empty()) {
    fail(fmt::format("the file requires extension{} {}, which afr does not support",
                     required_missing.size() > 1 ? "s" : "", fmt::join(required_missing, ", ")));
  }
}

// ---- Accessors ----

std::span<const uint8_t> Loader::buffer_view_bytes(int view, const std::string& what) const {
  if (view < 0 || size_t(view) >= model_.bufferViews.size()) {
    fail(fmt::format("{} refers to buffer view {}, but there are {}", what, view,
                     model_.bufferViews.size()));
  }
  if (const auto decoded = meshopt_bytes_.find(view); decoded != meshopt_bytes_.end()) {
    return decoded->second;
  }
  const tinygltf::BufferView& bv = model_.bufferViews[size_t(view)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= model_.buffers.size()) {
    fail(fmt::format("buffer view {} refers to buffer {}, but there are {}", view, bv.buffer,
                     model_.buffers.size()));
  }
  if (placeholder_buffers_.count(bv.buffer) != 0) {
    fail(
        fmt::format("buffer view {} ({}) is not compressed but reads buffer {}, which holds no "
                    "data (a meshopt fallback or placeholder buffer)",
                    view, what, bv.buffer));
  }
  const std::vector<unsigned char>& data = model_.buffers[size_t(bv.buffer)].data;
  if (bv.byteLength > data.size() || bv.byteOffset > data.size() - bv.byteLength) {
    fail(fmt::format("buffer view {} (bytes {} to {}) is out of bounds of buffer {} ({} bytes)",
                     view, bv.byteOffset, uint64_t(bv.byteOffset) + bv.byteLength, bv.buffer,
                     data.size()));
  }
  return {data.data() + bv.byteOffset, bv.byteLength};
}

// What glTF allows for colors and weights: floats, or unsigned bytes or shorts normalized to
// [0, 1].
bool float_or_normalized(const tinygltf::Accessor& a) {
  return a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
         (a.normalized && (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                           a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT));
}

std::string_view type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "an unknown type";
  }
}

// The bytes of every element of accessor `index`, tightly packed, with sparse values applied:
// the one place where accessor offsets, strides and counts meet buffer sizes.
const tinygltf::Accessor& Loader::accessor_at(int index, const std::string& what) const {
  if (index < 0 || size_t(index) >= model_.accessors.size()) {
    fail(fmt::format("{} refers to accessor {}, but there are {}", what, index,
                     model_.accessors.size()));
  }
  return model_.accessors[size_t(index)];
}

std::vector<uint8_t> Loader::gather(int index, int type, const std::string& what,
                                    const tinygltf::Accessor** out) {
  const tinygltf::Accessor& a = accessor_at(index, what);
  *out = &a;
  const std::string name = fmt::format("accessor {} ({})", index, what);
  const int component_size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  const int components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  if (component_size <= 0 || a.componentType == TINYGLTF_COMPONENT_TYPE_DOUBLE) {
    fail(fmt::format("{} has invalid componentType {}", name, a.componentType));
  }
  if (components <= 0) fail(fmt::format("{} has an invalid type", name));
  if (a.type != type) {
    fail(fmt::format("{} is {} where {} is required", name, type_name(a.type), type_name(type)));
  }
  const auto draco = draco_bytes_.find(index);
  const bool has_bytes = a.bufferView >= 0 || draco != draco_bytes_.end();
  if (a.count > (has_bytes ? kMaxAccessorCount : kMaxAccessorCountWithoutView)) {
    fail(fmt::format("{} has {} elements, more than afr accepts", name, a.count));
  }
  const size_t element_size = size_t(component_size) * size_t(components);
  if (draco != draco_bytes_.end()) {
    AFR_CHECK(draco->second.size() == a.count * element_size);
    return draco->second;
  }
  std::vector<uint8_t> bytes(a.count * element_size, 0);

  if (a.bufferView >= 0) {
    const std::span<const uint8_t> view = buffer_view_bytes(a.bufferView, name);
    const size_t declared_stride = model_.bufferViews[size_t(a.bufferView)].byteStride;
    const size_t stride = declared_stride != 0 ? declared_stride : element_size;
    if (stride < element_size || stride > 252) {
      fail(fmt::format("{} has byteStride {} for elements of {} bytes", name, declared_stride,
                       element_size));
    }
    if (a.count > 0) {
      const uint64_t end = uint64_t(a.byteOffset) + uint64_t(a.count - 1) * stride + element_size;
      if (a.byteOffset > view.size() || end > view.size()) {
        fail(fmt::format("{} is out of bounds of buffer view {}: it reads bytes {} to {} of {}",
                         name, a.bufferView, a.byteOffset, end, view.size()));
      }
      for (size_t i = 0; i < a.count; ++i) {
        std::memcpy(&bytes[i * element_size], &view[a.byteOffset + i * stride], element_size);
      }
    }
  }

  if (a.sparse.isSparse) {
    const int n = a.sparse.count;
    if (n <= 0 || size_t(n) > a.count) {
      fail(fmt::format("{} has sparse count {} for {} elements", name, n, a.count));
    }
    const auto& si = a.sparse.indices;
    const int index_size = tinygltf::GetComponentSizeInBytes(uint32_t(si.componentType));
    if (si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        si.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      fail(
          fmt::format("{} has sparse indices of invalid componentType {}", name, si.componentType));
    }
    const std::span<const uint8_t> index_view =
        buffer_view_bytes(si.bufferView, name + " sparse indices");
    const std::span<const uint8_t> value_view =
        buffer_view_bytes(a.sparse.values.bufferView, name + " sparse values");
    const uint64_t index_end = uint64_t(std::max(si.byteOffset, 0)) + uint64_t(n) * index_size;
    const uint64_t value_end =
        uint64_t(std::max(a.sparse.values.byteOffset, 0)) + uint64_t(n) * element_size;
    if (si.byteOffset < 0 || index_end > index_view.size()) {
      fail(fmt::format("{} sparse indices are out of bounds of buffer view {}", name,
                       si.bufferView));
    }
    if (a.sparse.values.byteOffset < 0 || value_end > value_view.size()) {
      fail(fmt::format("{} sparse values are out of bounds of buffer view {}", name,
                       a.sparse.values.bufferView));
    }
    for (int k = 0; k < n; ++k) {
      const uint8_t* p = &index_view[size_t(si.byteOffset) + size_t(k) * size_t(index_size)];
      uint32_t target = 0;
      if (index_size == 1) {
        target = p[0];
      } else if (index_size == 2) {
        uint16_t v;
        std::memcpy(&v, p, 2);
        target = v;
      } else {
        std::memcpy(&target, p, 4);
      }
      if (target >= a.count) {
        fail(fmt::format("{} has sparse index {} out of range of its {} elements", name, target,
                         a.count));
      }
      std::memcpy(&bytes[size_t(target) * element_size],
                  &value_view[size_t(a.sparse.values.byteOffset) + size_t(k) * element_size],
                  element_size);
    }
  }
  return bytes;
}

// One component as glTF defines it: normalized integers map to [0, 1] or [-1, 1].
double component_value(const uint8_t* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0 : double(p[0]);
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_INT: {
      int32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? std::max(v / 2147483647.0, -1.0) : double(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return normalized ? v / 4294967295.0 : double(v);
    }
    default: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

// EXT_ and KHR_meshopt_compression (one bitstream; KHR adds version 1 of the attribute codec and
// a COLOR filter): every buffer view with the extension is decoded at load through meshoptimizer
// into meshopt_bytes_, `count` elements of `byteStride` bytes (the view's byteLength), then
// filtered; everything after reads it through buffer_view_bytes as if it were in the view's
// buffer. What the extension forbids, data that does not decode, and a codec version or filter
// this meshoptimizer lacks are errors naming the buffer view.
void Loader::decode_meshopt() {
  uint64_t total = 0;
  for (size_t v = 0; v < model_.bufferViews.size(); ++v) {
    const tinygltf::BufferView& bv = model_.bufferViews[v];
    const tinygltf::Value* e = nullptr;
    std::string_view name;
    for (std::string_view ext : gltf_meshopt::kExtensions) {
      if (const auto it = bv.extensions.find(std::string(ext)); it != bv.extensions.end()) {
        e = &it->second;
        name = ext;
        break;
      }
    }
    if (e == nullptr) continue;
    const std::string where = fmt::format("buffer view {} {}", v, name);
    if (!e->IsObject()) fail(where + " is not an object");
    // A non-negative integer property (a JSON number that is one).
    const auto integer = [&](const char* key, std::optional<uint64_t> otherwise) -> uint64_t {
      if (!e->Has(key)) {
        if (otherwise) return *otherwise;
        fail(fmt::format("{} has no \"{}\"", where, key));
      }
      const tinygltf::Value& x = e->Get(key);
      const double d = x.IsNumber() ? x.GetNumberAsDouble() : -1.0;
      if (!(d >= 0.0 && d <= double(uint64_t(1) << 53) && d == std::floor(d))) {
        fail(fmt::format("{} has an invalid \"{}\"", where, key));
      }
      return uint64_t(d);
    };
    const auto text = [&](const char* key, const char* otherwise) -> std::string {
      if (!e->Has(key) && otherwise != nullptr) return otherwise;
      const tinygltf::Value& x = e->Get(key);
      if (!x.IsString()) fail(fmt::format("{} has no valid \"{}\"", where, key));
      return x.Get<std::string>();
    };
    const uint64_t buffer = integer("buffer", std::nullopt);
    const uint64_t offset = integer("byteOffset", 0);
    const uint64_t length = integer("byteLength", std::nullopt);
    const uint64_t stride = integer("byteStride", std::nullopt);
    const uint64_t count = integer("count", std::nullopt);
    const std::string mode = text("mode", nullptr);
    const std::string filter = text("filter", "NONE");

    if (buffer >= model_.buffers.size()) {
      fail(fmt::format("{} refers to buffer {}, but there are {}", where, buffer,
                       model_.buffers.size()));
    }
    if (placeholder_buffers_.count(int(buffer)) != 0) {
      fail(
          fmt::format("{} reads its compressed data from buffer {}, which holds no data (a "
                      "fallback or placeholder buffer)",
                      where, buffer));
    }
    const std::vector<unsigned char>& data = model_.buffers[buffer].data;
    if (length > data.size() || offset > data.size() - length) {
      fail(
          fmt::format("{}: its compressed bytes {} to {} are out of bounds of buffer {} ({} "
                      "bytes)",
                      where, offset, offset + length, buffer, data.size()));
    }
    const bool attributes = mode == "ATTRIBUTES";
    if (!attributes && mode != "TRIANGLES" && mode != "INDICES") {
      fail(fmt::format("{} has mode \"{}\" (ATTRIBUTES, TRIANGLES or INDICES)", where, mode));
    }
    if (attributes && (stride == 0 || stride % 4 != 0 || stride > 256)) {
      fail(fmt::format("{}: ATTRIBUTES need a byteStride of a multiple of 4 up to 256, not {}",
                       where, stride));
    }
    if (!attributes && stride != 2 && stride != 4) {
      fail(fmt::format("{}: {} need a byteStride of 2 or 4, not {}", where, mode, stride));
    }
    if (mode == "TRIANGLES" && count % 3 != 0) {
      fail(fmt::format("{}: TRIANGLES need a count that is a multiple of 3, not {}", where, count));
    }
    if (!attributes && filter != "NONE") {
      fail(fmt::format("{}: {} take no filter, not {}", where, mode, filter));
    }
    if (filter == "COLOR" && name == "KHR_meshopt_compression") {
      fail(
          fmt::format("{} uses the COLOR filter, which afr's meshoptimizer ({}.{}) does not "
                      "decode",
                      where, MESHOPTIMIZER_VERSION / 1000, MESHOPTIMIZER_VERSION % 1000 / 10));
    }
    const bool filter_fits =
        filter == "NONE" || (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) ||
        (filter == "QUATERNION" && stride == 8) || (filter == "EXPONENTIAL" && stride % 4 == 0);
    if (filter != "NONE" && filter != "OCTAHEDRAL" && filter != "QUATERNION" &&
        filter != "EXPONENTIAL") {
      fail(fmt::format("{} has filter \"{}\" (NONE, OCTAHEDRAL, QUATERNION or EXPONENTIAL)", where,
                       filter));
    }
    if (!filter_fits) {
      fail(
          fmt::format("{}: the {} filter does not take a byteStride of {}", where, filter, stride));
    }
    if (count > kMaxAccessorCount) {
      fail(fmt::format("{} has {} elements, more than afr accepts", where, count));
    }
    if (count * stride != bv.byteLength) {
      fail(
          fmt::format("{}: count x byteStride is {} x {} = {} bytes, but the buffer view's "
                      "byteLength is {}",
                      where, count, stride, count * stride, bv.byteLength));
    }
    total += count * stride;
    if (total > kMaxFileBytes) {
      fail(
          fmt::format("{}: the file's compressed buffer views decode to more than {} bytes, "
                      "more than afr accepts",
                      where, kMaxFileBytes));
    }

    std::vector<uint8_t> bytes(count * stride);
    const unsigned char* in = data.data() + offset;
    if (attributes && length > 0 && in[0] == 0xa1) {
      fail(
          fmt::format("{} uses version 1 of the attribute codec, which afr's meshoptimizer "
                      "({}.{}) does not decode",
                      where, MESHOPTIMIZER_VERSION / 1000, MESHOPTIMIZER_VERSION % 1000 / 10));
    }
    int result = 0;
    if (count > 0) {
      if (attributes) {
        result = meshopt_decodeVertexBuffer(bytes.data(), count, stride, in, length);
      } else if (mode == "TRIANGLES") {
        result = meshopt_decodeIndexBuffer(bytes.data(), count, stride, in, length);
      } else {
        result = meshopt_decodeIndexSequence(bytes.data(), count, stride, in, length);
      }
    }
    if (result != 0) {
      fail(fmt::format("{}: cannot decode its {} data (meshoptimizer error {})", where, mode,
                       result));
    }
    if (filter == "OCTAHEDRAL") {
      meshopt_decodeFilterOct(bytes.data(), count, stride);
    } else if (filter == "QUATERNION") {
      meshopt_decodeFilterQuat(bytes.data(), count, stride);
    } else if (filter == "EXPONENTIAL") {
      meshopt_decodeFilterExp(bytes.data(), count, stride);
    }
    meshopt_bytes_[int(v)] = std::move(bytes);
  }
}

// KHR_draco_mesh_compression: the primitive's indices and the attributes the extension names are
// decoded from the Draco data in its buffer view (libdraco) into draco_bytes_, as the elements of
// the accessors they stand for, in those accessors' component types; everything after reads
// them through gather() as if they were in a buffer. Attributes the extension does not name are
// read from their own accessors.
void Loader::decode_draco(const tinygltf::Primitive& in, const std::string& what) {
  const auto ext = in.extensions.find("KHR_draco_mesh_compression");
  if (ext == in.extensions.end()) return;
  const std::string where = what + " KHR_draco_mesh_compression";
  const tinygltf::Value& e = ext->second;
  if (!e.IsObject() || !e.Get("bufferView").IsInt() || !e.Get("attributes").IsObject()) {
    fail(where + " has no valid \"bufferView\" and \"attributes\"");
  }
  const std::span<const uint8_t> data =
      buffer_view_bytes(e.Get("bufferView").GetNumberAsInt(), where);
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(data.data()), data.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    fail(fmt::format("{}: cannot decode its Draco data ({})", where,
                     decoded.status().error_msg_string()));
  }
  const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
  const size_t points = mesh->num_points();
  if (points > kMaxAccessorCount || size_t(mesh->num_faces()) > kMaxAccessorCount) {
    fail(
        fmt::format("{}: its Draco data holds more vertices or triangles than afr accepts", where));
  }
  // The elements of accessor `index` (what the decoded data stands for), `count` of them, each
  // written by value(element, component type, components, out) in the accessor's type.
  const auto store = [&](int index, size_t count, const std::string& part, const auto& value) {
    const tinygltf::Accessor& a = accessor_at(index, where + " " + part);
    if (a.count != count) {
      fail(fmt::format("{} {}: accessor {} has {} elements, but the Draco data {}", where, part,
                       index, a.count, count));
    }
    const int components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
    const int size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
    if (components <= 0 || size <= 0 || a.componentType == TINYGLTF_COMPONENT_TYPE_DOUBLE) {
      fail(fmt::format("{} {}: accessor {} has an invalid type", where, part, index));
    }
    const size_t element_size = size_t(components) * size_t(size);
    std::vector<uint8_t> bytes(count * element_size);
    for (size_t i = 0; i < count; ++i) {
      value(i, a.componentType, components, &bytes[i * element_size]);
    }
    draco_bytes_[index] = std::move(bytes);
  };
  // An integer value in the component type (it fits: checked by the caller or by the data).
  const auto put_integer = [](uint32_t v, int type, uint8_t* out) {
    if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE || type == TINYGLTF_COMPONENT_TYPE_BYTE) {
      *out = uint8_t(v);
    } else if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
               type == TINYGLTF_COMPONENT_TYPE_SHORT) {
      const uint16_t s = uint16_t(v);
      std::memcpy(out, &s, 2);
    } else {
      std::memcpy(out, &v, 4);
    }
  };
  if (in.indices < 0) fail(where + ": the primitive has no indices, which the extension requires");
  {
    const tinygltf::Accessor& a = accessor_at(in.indices, where + " indices");
    const uint64_t limit = a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 0xff
                           : a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 0xffff
                                                                                       : 0xffffffff;
    if (points > limit + 1) {
      fail(fmt::format("{}: {} vertices do not fit the indices' component type", where, points));
    }
    store(in.indices, 3 * size_t(mesh->num_faces()), "indices",
          [&](size_t i, int type, int, uint8_t* out) {
            const draco::Mesh::Face& f = mesh->face(draco::FaceIndex(uint32_t(i / 3)));
            put_integer(f[i % 3].value(), type, out);
          });
  }
  for (const auto& [name, id] : e.Get("attributes").Get<tinygltf::Value::Object>()) {
    const auto accessor = in.attributes.find(name);
    if (accessor == in.attributes.end()) continue;  // the primitive does not use it
    const draco::PointAttribute* attribute =
        id.IsInt() && id.GetNumberAsInt() >= 0
            ? mesh->GetAttributeByUniqueId(uint32_t(id.GetNumberAsInt()))
            : nullptr;
    if (attribute == nullptr) {
      fail(fmt::format("{}: its attribute {} names no attribute of the Draco data", where, name));
    }
    // glTF's component types; Draco's others (64-bit, bool) have no accessor to fill, and
    // libdraco reads a bool's byte as it is, whatever its value.
    switch (attribute->data_type()) {
      case draco::DT_INT8:
      case draco::DT_UINT8:
      case draco::DT_INT16:
      case draco::DT_UINT16:
      case draco::DT_INT32:
      case draco::DT_UINT32:
      case draco::DT_FLOAT32:
        break;
      default:
        fail(
            fmt::format("{}: its attribute {} has Draco data type {}, which no glTF component "
                        "type matches",
                        where, name, int(attribute->data_type())));
    }
    // Up to four components of each point's value (the accessor's beyond the data's are 0).
    const int8_t available = int8_t(std::min(int(attribute->num_components()), 4));
    store(accessor->second, points, name, [&](size_t i, int type, int components, uint8_t* out) {
      const draco::AttributeValueIndex v = attribute->mapped_index(draco::PointIndex(uint32_t(i)));
      const size_t size = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(type)));
      if (type == TINYGLTF_COMPONENT_TYPE_FLOAT) {
        float values[4] = {};
        attribute->ConvertValue<float>(v, available, values);
        std::memcpy(out, values, size_t(std::min(components, 4)) * size);
      } else {
        int32_t values[4] = {};
        attribute->ConvertValue<int32_t>(v, available, values);
        for (int c = 0; c < std::min(components, 4); ++c) {
          put_integer(uint32_t(values[c]), type, out + size_t(c) * size);
        }
      }
    });
  }
}

// Components of accessor `index`, which must be of `type`, as floats; all finite.
std::vector<float> Loader::read_floats(int index, int type, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, type, what, &a);
  const size_t component_size = size_t(tinygltf::GetComponentSizeInBytes(a->componentType));
  const size_t n = bytes.size() / component_size;
  std::vector<float> values(n);
  for (size_t i = 0; i < n; ++i) {
    const double v = component_value(&bytes[i * component_size], a->componentType, a->normalized);
    if (!std::isfinite(v)) {
      fail(fmt::format("accessor {} ({}) holds a NaN or infinite value at element {}", index, what,
                       i / size_t(tinygltf::GetNumComponentsInType(a->type))));
    }
    values[i] = float(v);
  }
  return values;
}

std::vector<uint32_t> Loader::read_indices(int index, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, TINYGLTF_TYPE_SCALAR, what, &a);
  std::vector<uint32_t> indices(a->count);
  switch (a->componentType) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      for (size_t i = 0; i < indices.size(); ++i) indices[i] = bytes[i];
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      for (size_t i = 0; i < indices.size(); ++i) {
        uint16_t v;
        std::memcpy(&v, &bytes[2 * i], 2);
        indices[i] = v;
      }
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      if (!indices.empty()) std::memcpy(indices.data(), bytes.data(), 4 * indices.size());
      break;
    default:
      fail(fmt::format("accessor {} ({}) has componentType {}, not an unsigned integer type", index,
                       what, a->componentType));
  }
  return indices;
}

// JOINTS_0: four unsigned bytes or shorts per vertex (glTF 2.0, 3.7.3.1).
std::vector<std::array<uint16_t, 4>> Loader::read_joints(int index, const std::string& what) {
  const tinygltf::Accessor* a = nullptr;
  const std::vector<uint8_t> bytes = gather(index, TINYGLTF_TYPE_VEC4, what, &a);
  const bool bytes_type = a->componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  if ((!bytes_type && a->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) ||
      a->normalized) {
    fail(fmt::format(
        "accessor {} ({}) has componentType {}{}, not unsigned bytes or shorts as joints must be",
        index, what, a->componentType, a->normalized ? " (normalized)" : ""));
  }
  std::vector<std::array<uint16_t, 4>> joints(a->count);
  for (size_t v = 0; v < joints.size(); ++v) {
    for (size_t c = 0; c < 4; ++c) {
      if (bytes_type) {
        joints[v][c] = bytes[4 * v + c];
      } else {
        std::memcpy(&joints[v][c], &bytes[2 * (4 * v + c)], 2);
      }
    }
  }
  return joints;
}

// A VEC3 attribute of `count` elements.
std::vector<glm::vec3> Loader::read_vec3s(int index, size_t count, const std::string& attribute,
                                          const std::string& what) {
  const std::vector<float> f = read_floats(index, TINYGLTF_TYPE_VEC3, what + " " + attribute);
  if (f.size() != 3 * count) {
    fail(fmt::format("{} has {} {} values for {} positions", what, f.size() / 3, attribute, count));
  }
  std::vector<glm::vec3> v(count);
  for (size_t i = 0; i < count; ++i) v[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
  return v;
}

// ---- Meshes ----

void Loader::load_meshes() {
  for (size_t m = 0; m < model_.meshes.size(); ++m) {
    const tinygltf::Mesh& in = model_.meshes[m];
    Mesh mesh;
    mesh.name = in.name;
    // Every primitive of a mesh has the same number of morph targets, one per mesh weight.
    const size_t targets = in.primitives.empty() ? 0 : in.primitives[0].targets.size();
    for (size_t k = 0; k < in.primitives.size(); ++k) {
      if (in.primitives[k].targets.size() != targets) {
        fail(fmt::format("mesh {} primitive {} has {} morph targets, but primitive 0 has {}", m, k,
                         in.primitives[k].targets.size(), targets));
      }
    }
    if (!in.weights.empty() && in.weights.size() != targets) {
      fail(fmt::format("mesh {} has {} morph weights for {} morph targets", m, in.weights.size(),
                       targets));
    }
    if (!is_finite(in.weights))
      fail(fmt::format("mesh {} has a morph weight that is not finite", m));
    mesh.weights.assign(targets, 0.0f);
    for (size_t k = 0; k < in.weights.size(); ++k) mesh.weights[k] = float(in.weights[k]);
    for (size_t k = 0; k < in.primitives.size(); ++k) {
      Primitive primitive;
      if (load_primitive(in.primitives[k], fmt::format("mesh {} primitive {}", m, k), &primitive)) {
        mesh.primitives.push_back(std::move(primitive));
      }
    }
    scene_.meshes.push_back(std::move(mesh));
  }
}

// Returns false for a primitive that is skipped (not triangles, no positions, or no triangles).
bool Loader::load_primitive(const tinygltf::Primitive& in, const std::string& what,
                            Primitive* out) {
  const int mode = in.mode < 0 ? TINYGLTF_MODE_TRIANGLES : in.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
      mode != TINYGLTF_MODE_TRIANGLE_FAN) {
    warn_once(
        fmt::format("mode {}", mode),
        fmt::format("primitives of mode {} (points or lines) are not supported (skipped)", mode));
    return false;
  }
  for (const auto& [name, accessor] : in.attributes) {
    // Checked here for every attribute, since only those the scene needs are read.
    if (accessor < 0 || size_t(accessor) >= model_.accessors.size()) {
      fail(fmt::format("{} attribute {} refers to accessor {}, but there are {}", what, name,
                       accessor, model_.accessors.size()));
    }
    if (name.rfind("COLOR_", 0) == 0 && name != "COLOR_0") {
      warn_once("more colors",
                fmt::format("vertex color sets other than COLOR_0 ({}) are ignored", name));
    }
    if (name.rfind("JOINTS_", 0) == 0 && name != "JOINTS_0") {
      warn_once("more joints",
                fmt::format("more than 4 joint influences per vertex ({}) are not supported: the "
                            "4 of JOINTS_0 are used, their weights renormalised",
                            name));
    }
  }
  draco_bytes_.clear();
  decode_draco(in, what);
  if (in.material < -1 || in.material >= int(model_.materials.size())) {
    fail(fmt::format("{} refers to material {}, but there are {}", what, in.material,
                     model_.materials.size()));
  }
  out->material = in.material;

  // glTF 2.0 (3.7.2.1) allows a primitive without positions and asks that it be skipped unless
  // an extension gives them (Draco's are among the attributes by now).
  const auto position = in.attributes.find("POSITION");
  if (position == in.attributes.end()) {
    warn_once("no POSITION",
              fmt::format("primitives without a POSITION attribute draw nothing and are skipped, "
                          "as glTF asks ({} is the first)",
                          what));
    return false;
  }
  const std::vector<float> p =
      read_floats(position->second, TINYGLTF_TYPE_VEC3, what + " POSITION");
  const size_t vertex_count = p.size() / 3;
  out->positions.resize(vertex_count);
  for (size_t i = 0; i < vertex_count; ++i)
    out->positions[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};

  if (const auto normal = in.attributes.find("NORMAL"); normal != in.attributes.end()) {
    const std::vector<float> n = read_floats(normal->second, TINYGLTF_TYPE_VEC3, what + " NORMAL");
    if (n.size() != p.size()) {
      fail(fmt::format("{} has {} normals for {} positions", what, n.size() / 3, vertex_count));
    }
    out->normals.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) {
      const glm::vec3 v(n[3 * i], n[3 * i + 1], n[3 * i + 2]);
      const float length = glm::length(v);
      out->normals[i] = length > 0.0f ? v / length : glm::vec3(0.0f, 0.0f, 1.0f);
    }
  }
  // Its material (loaded before the meshes; null: the default material) decides which
  // attributes it reads. The set its textures read: TEXCOORD_0 without a material or textures.
  const Material* material = in.material >= 0 && size_t(in.material) < scene_.materials.size()
                                 ? &scene_.materials[size_t(in.material)]
                                 : nullptr;
  read_texture_coordinates(in,
                           material ? uv_sources_[size_t(in.material)] : std::vector<UvSource>{},
                           what, vertex_count, out);
  // TANGENT (VEC4 of floats, or of normalized bytes or shorts with KHR_mesh_quantization), read
  // only where the material's normal textures use it; w taken by its sign.
  if (const auto tangent = in.attributes.find("TANGENT");
      material &&
      (material->normal_texture >= 0 || material->clearcoat_normal_texture >= 0 ||
       material->anisotropy > 0.0f) &&
      tangent != in.attributes.end()) {
    const std::vector<float> t =
        read_floats(tangent->second, TINYGLTF_TYPE_VEC4, what + " TANGENT");
    if (t.size() / 4 != vertex_count) {
      fail(fmt::format("{} has {} tangents for {} positions", what, t.size() / 4, vertex_count));
    }
    out->tangents.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) {
      out->tangents[i] = {t[4 * i], t[4 * i + 1], t[4 * i + 2], t[4 * i + 3] < 0.0f ? -1.0f : 1.0f};
    }
  }
  if (const auto color = in.attributes.find("COLOR_0"); color != in.attributes.end()) {
    // Its alpha matters only to a material that masks or blends.
    const bool keep_alpha = material && material->alpha_mode != Material::AlphaMode::kOpaque;
    load_colors(color->second, what + " COLOR_0", vertex_count, keep_alpha, out);
  }
  load_skinning(in, what, out);
  load_targets(in, what, out);

  std::vector<uint32_t> indices;
  if (in.indices >= 0) {
    indices = read_indices(in.indices, what + " indices");
  } else {
    indices.resize(vertex_count);
    std::iota(indices.begin(), indices.end(), 0u);
  }
  for (size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] >= vertex_count) {
      fail(
          fmt::format("index {} of {} (element {}) is out of range: the primitive has {} "
                      "vertices",
                      indices[i], what, i, vertex_count));
    }
  }
  // glTF 2.0, section 3.7.2.1: strips and fans as lists, keeping the winding.
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    // The glTF Validator warns of such a count (MESH_PRIMITIVE_INCOMPATIBLE_MODE) rather than
    // refusing it; the whole triangles are drawn.
    if (indices.size() % 3 != 0) {
      warn_once("incomplete triangle",
                fmt::format("{} has {} {}, not a multiple of 3: the last {} not drawn (said once "
                            "for every such primitive)",
                            what, indices.size(), in.indices >= 0 ? "indices" : "vertices",
                            indices.size() % 3 == 1 ? "one is" : "two are"));
      indices.resize(indices.size() - indices.size() % 3);
    }
    out->indices = std::move(indices);
  } else {
    const size_t triangles = indices.size() >= 3 ? indices.size() - 2 : 0;
    out->indices.reserve(3 * triangles);
    for (size_t i = 0; i < triangles; ++i) {
      if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        out->indices.insert(out->indices.end(),
                            {indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]});
      } else {
        out->indices.insert(out->indices.end(), {indices[i + 1], indices[i + 2], indices[0]});
      }
    }
  }
  if (out->indices.empty()) return false;
  if (out->normals.empty()) generate_normals(out);
  // A material that needs a tangent frame gets smooth tangents where the file has none, from the
  // coordinates of its normal texture, else of its clearcoat normal's, else of its anisotropy's.
  if (material && out->tangents.empty()) {
    if (material->normal_texture >= 0) {
      generate_tangents(out, material->uv_set.normal);
    } else if (material->clearcoat_normal_texture >= 0) {
      generate_tangents(out, material->uv_set.clearcoat_normal);
    } else if (material->anisotropy > 0.0f) {
      generate_tangents(out, material->uv_set.anisotropy);
    }
  }
  return true;
}

// COLOR_0 (glTF 2.0, 3.7.2.1): VEC3 or VEC4 of floats or of normalized unsigned bytes or shorts,
// a linear RGB(A) multiplier of the base color. Alpha is kept (clamped to 0 to 1) where
// keep_alpha (a MASK or BLEND material) and it is below 1 somewhere, and dropped otherwise: an
// OPAQUE material ignores it (glTF 2.0, 3.9.4). Negative color floats become 0.
void Loader::load_colors(int accessor, const std::string& what, size_t vertex_count,
                         bool keep_alpha, Primitive* out) {
  const tinygltf::Accessor& a = accessor_at(accessor, what);
  if (a.type != TINYGLTF_TYPE_VEC3 && a.type != TINYGLTF_TYPE_VEC4) {
    fail(fmt::format("accessor {} ({}) is {}: vertex colors must be VEC3 or VEC4", accessor, what,
                     type_name(a.type)));
  }
  const int components = a.type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
  if (!float_or_normalized(a)) {
    fail(
        fmt::format("accessor {} ({}) has componentType {}{}: vertex colors must be floats or "
                    "normalized unsigned bytes or shorts",
                    accessor, what, a.componentType, a.normalized ? " (normalized)" : ""));
  }
  const std::vector<float> c =
      read_floats(accessor, components == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3, what);
  if (c.size() / size_t(components) != vertex_count) {
    fail(fmt::format("{} has {} vertex colors for {} positions", what, c.size() / components,
                     vertex_count));
  }
  out->colors.resize(vertex_count);
  bool negative = false;
  for (size_t i = 0; i < vertex_count; ++i) {
    const float* v = &c[size_t(components) * i];
    for (int k = 0; k < 3; ++k) {
      negative |= v[k] < 0.0f;
      out->colors[i][k] = std::max(v[k], 0.0f);
    }
  }
  if (keep_alpha && components == 4) {
    bool below_one = false;
    for (size_t i = 0; i < vertex_count; ++i) below_one |= !(c[4 * i + 3] >= 1.0f);
    if (below_one) {
      out->color_alpha.resize(vertex_count);
      for (size_t i = 0; i < vertex_count; ++i) {
        const float a = c[4 * i + 3];
        out->color_alpha[i] = a >= 0.0f ? std::min(a, 1.0f) : 0.0f;  // NaN too
      }
    }
  }
  if (negative) {
    warn_once("negative vertex colors",
              fmt::format("{}: negative vertex color components are taken as 0", what));
  }
}

// JOINTS_0 and WEIGHTS_0. Weights are renormalised to sum to 1 (as viewers do: quantized
// weights rarely sum to 1 exactly, and JOINTS_1 influences are dropped); a vertex whose weights
// sum to 0 follows its first joint.
void Loader::load_skinning(const tinygltf::Primitive& in, const std::string& what, Primitive* out) {
  const auto joints = in.attributes.find("JOINTS_0");
  const auto weights = in.attributes.find("WEIGHTS_0");
  if (joints == in.attributes.end() && weights == in.attributes.end()) return;
  if (joints == in.attributes.end() || weights == in.attributes.end()) {
    fail(fmt::format("{} has {} but no {}", what,
                     joints == in.attributes.end() ? "WEIGHTS_0" : "JOINTS_0",
                     joints == in.attributes.end() ? "JOINTS_0" : "WEIGHTS_0"));
  }
  const size_t vertex_count = out->positions.size();
  out->joints = read_joints(joints->second, what + " JOINTS_0");
  if (out->joints.size() != vertex_count) {
    fail(fmt::format("{} has {} JOINTS_0 values for {} positions", what, out->joints.size(),
                     vertex_count));
  }
  const std::vector<float> w =
      read_floats(weights->second, TINYGLTF_TYPE_VEC4, what + " WEIGHTS_0");
  const tinygltf::Accessor& wa = model_.accessors[size_t(weights->second)];
  if (!float_or_normalized(wa)) {
    fail(
        fmt::format("accessor {} ({} WEIGHTS_0) has componentType {}{}: weights are floats or "
                    "normalized unsigned bytes or shorts",
                    weights->second, what, wa.componentType, wa.normalized ? " (normalized)" : ""));
  }
  if (w.size() != 4 * vertex_count) {
    fail(fmt::format("{} has {} WEIGHTS_0 values for {} positions", what, w.size() / 4,
                     vertex_count));
  }
  out->joint_weights.resize(vertex_count);
  for (size_t v = 0; v < vertex_count; ++v) {
    glm::vec4 jw(w[4 * v], w[4 * v + 1], w[4 * v + 2], w[4 * v + 3]);
    if (jw.x < 0.0f || jw.y < 0.0f || jw.z < 0.0f || jw.w < 0.0f) {
      fail(fmt::format("{} WEIGHTS_0 of vertex {} has a negative weight", what, v));
    }
    const float sum = jw.x + jw.y + jw.z + jw.w;
    if (sum > 0.0f) {
      jw /= sum;
    } else {
      warn_once("zero joint weights",
                "vertices whose joint weights sum to 0 follow their first joint");
      jw = glm::vec4(1.0f, 0.0f, 0.0f, 0.0f);
    }
    out->joint_weights[v] = jw;
  }
}

// Morph targets: POSITION and NORMAL displacements, and TANGENT ones where the primitive keeps
// its tangents (its material has a normal texture); other attributes warn.
void Loader::load_targets(const tinygltf::Primitive& in, const std::string& what, Primitive* out) {
  const size_t vertex_count = out->positions.size();
  out->targets.resize(in.targets.size());
  for (size_t k = 0; k < in.targets.size(); ++k) {
    const std::string where = fmt::format("{} morph target {}", what, k);
    MorphTarget& target = out->targets[k];
    for (const auto& [name, accessor] : in.targets[k]) {
      const bool tangent = name == "TANGENT";
      if (name != "POSITION" && name != "NORMAL" && !(tangent && !out->tangents.empty())) {
        if (!tangent) {
          warn_once("target " + name,
                    fmt::format("morph targets of {} are not supported (ignored)", name));
        }
        continue;
      }
      morph_displacements_ += vertex_count;
      if (morph_displacements_ > kMaxMorphDisplacements) {
        fail(
            fmt::format("{}: the file's morph targets displace more than {} vertex attributes, "
                        "more than afr accepts",
                        where, kMaxMorphDisplacements));
      }
      std::vector<glm::vec3> d = read_vec3s(accessor, vertex_count, name, where);
      (name == "POSITION" ? target.positions
       : tangent          ? target.tangents
                          : target.normals) = std::move(d);
    }
  }
}

// ---- Materials and textures ----

glm::vec3 Loader::read_rgb_extra(const tinygltf::Value& extras, const char* key,
                                 const std::string& what) const {
  const tinygltf::Value& v = extras.Get(key);
  std::array<double, 3> rgb{};
  bool ok = v.IsArray() && v.ArrayLen() == 3;
  for (int i = 0; ok && i < 3; ++i) {
    ok = v.Get(i).IsNumber() && std::isfinite(v.Get(i).GetNumberAsDouble());
    if (ok) rgb[size_t(i)] = v.Get(i).GetNumberAsDouble();
  }
  if (!ok) fail(fmt::format("{} extra \"{}\" is not an array of 3 numbers", what, key));
  return glm::vec3(float(rgb[0]), float(rgb[1]), float(rgb[2]));
}

// Material extension `name`'s object, or null where the material has none (fails where it is
// not an object); *where names it in errors.
const tinygltf::Value* Loader::material_extension(const tinygltf::Material& in, const char* name,
                                                  const std::string& what,
                                                  std::string* where) const {
  const auto ext = in.extensions.find(name);
  if (ext == in.extensions.end()) return nullptr;
  *where = fmt::format("{} {}", what, name);
  if (!ext->second.IsObject()) fail(*where + " is not an object");
  return &ext->second;
}

// An extension's number `key`, where it has one: it must be a number that `ok` accepts (else an
// error naming it and `range`).
void Loader::read_number(const tinygltf::Value& e, const char* key, const std::string& where,
                         bool (*ok)(double), const char* range, float* out) const {
  if (!e.Has(key)) return;
  const tinygltf::Value& f = e.Get(key);
  const double v = f.IsNumber() ? f.GetNumberAsDouble() : std::nan("");
  if (!ok(v)) fail(fmt::format("{} has an invalid {} ({})", where, key, range));
  *out = float(v);
}

// An extension's array `key` of out.size() numbers, where it has one: each a number that `ok`
// accepts (else an error naming the key and `range`).
void Loader::read_numbers(const tinygltf::Value& e, const char* key, const std::string& where,
                          bool (*ok)(double), const char* range, std::span<float> out) const {
  if (!e.Has(key)) return;
  const tinygltf::Value& c = e.Get(key);
  bool good = c.IsArray() && c.ArrayLen() == out.size();
  std::vector<float> values(out.size());
  for (size_t i = 0; good && i < out.size(); ++i) {
    const double v = c.Get(int(i)).IsNumber() ? c.Get(int(i)).GetNumberAsDouble() : std::nan("");
    good = ok(v);
    values[i] = float(v);
  }
  if (!good) fail(fmt::format("{} has an invalid {} ({})", where, key, range));
  std::copy(values.begin(), values.end(), out.begin());
}

// An extension's color `key`, where it has one: three numbers that `ok` accepts.
void Loader::read_color(const tinygltf::Value& e, const char* key, const std::string& where,
                        bool (*ok)(double), const char* range, glm::vec3* out) const {
  read_numbers(e, key, where, ok, range, std::span<float>(&(*out)[0], 3));
}

namespace {
bool unit_interval(double v) { return v >= 0.0 && v <= 1.0; }
bool non_negative(double v) { return v >= 0.0 && std::isfinite(v); }
bool positive(double v) { return v > 0.0; }  // infinity too: no attenuation
bool finite(double v) { return std::isfinite(v); }
bool at_least_one(double v) { return v >= 1.0 && std::isfinite(v); }
// KHR_materials_ior: 0 stands for a Fresnel term of 1.
bool ior_value(double v) { return v == 0.0 || (v >= 1.0 && std::isfinite(v)); }
}  // namespace

// KHR_materials_transmission (transmissionFactor in [0, 1], default 0) and KHR_materials_ior
// (ior >= 1 or exactly 0, default 1.5).
void Loader::read_transmission_and_ior(size_t m, const tinygltf::Material& in,
                                       const std::string& what, Material* out) {
  std::string where;
  if (const tinygltf::Value* e =
          material_extension(in, "KHR_materials_transmission", what, &where)) {
    read_number(*e, "transmissionFactor", where, unit_interval, "a number 0 to 1",
                &out->transmission);
    out->transmission_texture = read_extension_texture(
        m, *e, "transmissionTexture", where, ImageData::kLinear, &out->uv_set.transmission);
  }
  if (const tinygltf::Value* e = material_extension(in, "KHR_materials_ior", what, &where)) {
    read_number(*e, "ior", where, ior_value, "a number >= 1, or 0", &out->ior);
  }
}

// KHR_materials_specular: specularFactor (0 to 1, default 1) and specularColorFactor (three
// numbers >= 0, default 1), and the textures that multiply them.
void Loader::read_specular(size_t m, const tinygltf::Material& in, const std::string& what,
                           Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_specular", what, &where);
  if (e == nullptr) return;
  if (out->specular_glossiness) {
    warn_once("specular with specular-glossiness",
              fmt::format("{} is ignored: the material's KHR_materials_pbrSpecularGlossiness "
                          "gives its specular color",
                          where));
    return;
  }
  out->has_specular_extension = true;
  read_number(*e, "specularFactor", where, unit_interval, "a number 0 to 1", &out->specular);
  read_color(*e, "specularColorFactor", where, non_negative, "three numbers >= 0",
             &out->specular_color);
  out->specular_texture = read_extension_texture(m, *e, "specularTexture", where, ImageData::kAlpha,
                                                 &out->uv_set.specular);
  out->specular_color_texture = read_extension_texture(
      m, *e, "specularColorTexture", where, ImageData::kColor, &out->uv_set.specular_color);
}

void Loader::read_clearcoat(size_t m, const tinygltf::Material& in, const std::string& what,
                            Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_clearcoat", what, &where);
  if (e == nullptr) return;
  read_number(*e, "clearcoatFactor", where, unit_interval, "a number 0 to 1", &out->clearcoat);
  read_number(*e, "clearcoatRoughnessFactor", where, unit_interval, "a number 0 to 1",
              &out->clearcoat_roughness);
  out->clearcoat_texture = read_extension_texture(m, *e, "clearcoatTexture", where,
                                                  ImageData::kLinear, &out->uv_set.clearcoat);
  out->clearcoat_roughness_texture =
      read_extension_texture(m, *e, "clearcoatRoughnessTexture", where, ImageData::kLinear,
                             &out->uv_set.clearcoat_roughness);
  out->clearcoat_normal_texture =
      read_extension_texture(m, *e, "clearcoatNormalTexture", where, ImageData::kLinear,
                             &out->uv_set.clearcoat_normal, &out->clearcoat_normal_scale);
}

int Loader::read_extension_texture(size_t m, const tinygltf::Value& e, const char* key,
                                   const std::string& where, ImageData data, uint8_t* set,
                                   float* scale) {
  if (!e.Has(key)) return -1;
  const tinygltf::Value& info = e.Get(key);
  const std::string slot = fmt::format("{} {}", where, key);
  if (!info.IsObject()) fail(slot + " is not an object");
  const tinygltf::Value& index = info.Get("index");
  if (!index.IsInt() || index.GetNumberAsInt() < 0) {
    fail(slot + " has no valid index (a texture index >= 0)");
  }
  int tex_coord = 0;
  if (info.Has("texCoord")) {
    const tinygltf::Value& t = info.Get("texCoord");
    if (!t.IsInt() || t.GetNumberAsInt() < 0) {
      fail(slot + " has an invalid texCoord (an integer >= 0)");
    }
    tex_coord = t.GetNumberAsInt();
  }
  tinygltf::ExtensionMap extensions;
  if (info.Has("extensions")) {
    const tinygltf::Value& x = info.Get("extensions");
    if (!x.IsObject()) fail(slot + " extensions is not an object");
    for (const std::string& name : x.Keys()) extensions[name] = x.Get(name);
  }
  if (scale != nullptr) {
    read_number(info, "scale", slot, finite, "a number", scale);
  }
  // (`where` is material_extension's "material M EXTENSION".)
  const std::string path = fmt::format("extensions/{}/{}", where.substr(where.rfind(' ') + 1), key);
  return read_texture_slot(m, path, index.GetNumberAsInt(), tex_coord, extensions, data, set);
}

// KHR_materials_pbrSpecularGlossiness (archived by Khronos, still in files from older exporters),
// in place of the material's pbrMetallicRoughness, which a file may add for viewers without it:
// diffuseFactor and diffuseTexture are the base color; specularFactor and the color of
// specularGlossinessTexture (sRGB) the specular color at normal incidence, F0 itself; and
// glossinessFactor times that texture's alpha is 1 - roughness. Material::specular_glossiness
// says how the shader reads them.
void Loader::read_specular_glossiness(size_t m, const tinygltf::Value& e, const std::string& where,
                                      Material* out) {
  out->specular_glossiness = true;
  out->base_color_factor = glm::vec4(1.0f);
  read_numbers(e, "diffuseFactor", where, unit_interval, "four numbers 0 to 1",
               std::span<float>(&out->base_color_factor[0], 4));
  out->metallic = 0.0f;
  out->has_specular_extension = true;
  out->specular = 1.0f;
  out->specular_color = glm::vec3(1.0f);
  read_color(e, "specularFactor", where, unit_interval, "three numbers 0 to 1",
             &out->specular_color);
  float glossiness = 1.0f;
  read_number(e, "glossinessFactor", where, unit_interval, "a number 0 to 1", &glossiness);
  out->roughness = 1.0f - glossiness;
  out->base_color_texture = read_extension_texture(m, e, "diffuseTexture", where, ImageData::kColor,
                                                   &out->uv_set.base_color);
  out->specular_color_texture = read_extension_texture(
      m, e, "specularGlossinessTexture", where, ImageData::kColor, &out->uv_set.specular_color);
  out->glossiness_texture = read_extension_texture(m, e, "specularGlossinessTexture", where,
                                                   ImageData::kAlpha, &out->uv_set.glossiness);
}

// KHR_materials_variants: a file's alternative materials per primitive, named by variant. afr
// draws the primitives' own materials, which the extension defines as what a viewer shows when
// no variant is chosen, and says which variants the file offers. The variants are not drawn, so
// a malformed list warns, naming what is wrong, and the file loads.
void Loader::read_material_variants() {
  const auto ext = model_.extensions.find("KHR_materials_variants");
  if (ext == model_.extensions.end()) return;
  const tinygltf::Value& variants = ext->second.Get("variants");
  std::string problem;
  std::vector<std::string> names;
  if (!ext->second.IsObject() || !variants.IsArray() || variants.ArrayLen() == 0) {
    problem = "has no \"variants\" array of one variant or more";
  }
  for (size_t i = 0; problem.empty() && i < variants.ArrayLen(); ++i) {
    const tinygltf::Value& name = variants.Get(int(i)).Get("name");
    if (!name.IsString())
      problem = fmt::format("variant {} has no name", i);
    else
      names.push_back(fmt::format("\"{}\"", name.Get<std::string>()));
  }
  if (!problem.empty()) {
    warn_once("KHR_materials_variants",
              fmt::format("KHR_materials_variants {} (the default materials are drawn)", problem));
    return;
  }
  constexpr size_t kNamed = 8;  // the rest only counted
  const size_t count = names.size();
  names.resize(std::min(count, kNamed));
  spdlog::info("{}: {} material variant{} ({}{}): drawn with the default materials", path_.string(),
               count, count == 1 ? "" : "s", fmt::join(names, ", "),
               count > kNamed ? fmt::format(" and {} more", count - kNamed) : "");
}

// CESIUM_RTC (3D Tiles' batched models): the positions are relative to a center, often a point on
// the Earth millions of meters out. Adding it would move the whole scene, camera nodes included,
// and leave positions with a float's half meter of precision; the picture is the same without
// it, so afr draws the scene relative to its center. The center must still be three finite
// numbers.
void Loader::read_rtc_center() {
  const auto ext = model_.extensions.find("CESIUM_RTC");
  if (ext == model_.extensions.end()) return;
  const tinygltf::Value& center = ext->second.Get("center");
  bool valid = center.IsArray() && center.ArrayLen() == 3;
  std::array<double, 3> c{};
  for (size_t i = 0; valid && i < 3; ++i) {
    const tinygltf::Value& v = center.Get(int(i));
    valid = v.IsNumber() && std::isfinite(v.GetNumberAsDouble());
    if (valid) c[i] = v.GetNumberAsDouble();
  }
  if (!valid) fail("CESIUM_RTC: \"center\" must be an array of 3 finite numbers");
  spdlog::info("{}: CESIUM_RTC: drawn relative to its center ({}, {}, {})", path_.string(), c[0],
               c[1], c[2]);
}

void Loader::read_volume(const tinygltf::Material& in, const std::string& what, Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_volume", what, &where);
  if (e == nullptr) return;
  read_number(*e, "thicknessFactor", where, non_negative, ">= 0", &out->thickness);
  read_number(*e, "attenuationDistance", where, positive, "> 0", &out->attenuation_distance);
  read_color(*e, "attenuationColor", where, unit_interval, "three numbers 0 to 1",
             &out->attenuation_color);
  if (e->Has("thicknessTexture")) {
    warn_once("thickness texture",
              fmt::format("{}: its thicknessTexture is not read (the tracer measures the "
                          "distance light travels inside)",
                          where));
  }
}

// KHR_materials_dispersion: dispersion (>= 0, default 0), 20 / the Abbe number. It builds on
// KHR_materials_volume's refraction, so on a material without a volume it is told and unused.
void Loader::read_dispersion(const tinygltf::Material& in, const std::string& what, Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_dispersion", what, &where);
  if (e == nullptr) return;
  read_number(*e, "dispersion", where, non_negative, ">= 0", &out->dispersion);
  if (out->dispersion > 0.0f && !(out->transmission > 0.0f && out->thickness > 0.0f)) {
    warn_once("dispersion without volume",
              fmt::format("{}: dispersion has no effect without transmission and a volume "
                          "(KHR_materials_volume thicknessFactor > 0), which it builds on",
                          where));
  }
}

// KHR_materials_sheen: sheenColorFactor (three numbers 0 to 1, default 0) and
// sheenRoughnessFactor (0 to 1, default 0), and the textures that multiply them (the roughness
// texture's alpha channel).
void Loader::read_sheen(size_t m, const tinygltf::Material& in, const std::string& what,
                        Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_sheen", what, &where);
  if (e == nullptr) return;
  read_color(*e, "sheenColorFactor", where, unit_interval, "three numbers 0 to 1",
             &out->sheen_color);
  read_number(*e, "sheenRoughnessFactor", where, unit_interval, "a number 0 to 1",
              &out->sheen_roughness);
  out->sheen_color_texture = read_extension_texture(m, *e, "sheenColorTexture", where,
                                                    ImageData::kColor, &out->uv_set.sheen_color);
  out->sheen_roughness_texture = read_extension_texture(
      m, *e, "sheenRoughnessTexture", where, ImageData::kAlpha, &out->uv_set.sheen_roughness);
}

// KHR_materials_anisotropy: anisotropyStrength (0 to 1, default 0), anisotropyRotation
// (radians, default 0) and anisotropyTexture (direction in red and green, strength in blue).
void Loader::read_anisotropy(size_t m, const tinygltf::Material& in, const std::string& what,
                             Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_anisotropy", what, &where);
  if (e == nullptr) return;
  read_number(*e, "anisotropyStrength", where, unit_interval, "a number 0 to 1", &out->anisotropy);
  read_number(*e, "anisotropyRotation", where, finite, "a number", &out->anisotropy_rotation);
  out->anisotropy_texture = read_extension_texture(m, *e, "anisotropyTexture", where,
                                                   ImageData::kLinear, &out->uv_set.anisotropy);
}

// KHR_materials_iridescence: iridescenceFactor (0 to 1, default 0), iridescenceIor (>= 1,
// default 1.3), iridescenceThicknessMinimum and Maximum (nanometres >= 0, defaults 100 and 400),
// iridescenceTexture (red: the factor) and iridescenceThicknessTexture (green: the thickness
// between the two).
void Loader::read_iridescence(size_t m, const tinygltf::Material& in, const std::string& what,
                              Material* out) {
  std::string where;
  const tinygltf::Value* e = material_extension(in, "KHR_materials_iridescence", what, &where);
  if (e == nullptr) return;
  read_number(*e, "iridescenceFactor", where, unit_interval, "a number 0 to 1", &out->iridescence);
  read_number(*e, "iridescenceIor", where, at_least_one, "a number >= 1", &out->iridescence_ior);
  read_number(*e, "iridescenceThicknessMinimum", where, non_negative, "nanometres >= 0",
              &out->iridescence_thickness_min);
  read_number(*e, "iridescenceThicknessMaximum", where, non_negative, "nanometres >= 0",
              &out->iridescence_thickness_max);
  out->iridescence_texture = read_extension_texture(m, *e, "iridescenceTexture", where,
                                                    ImageData::kLinear, &out->uv_set.iridescence);
  out->iridescence_thickness_texture =
      read_extension_texture(m, *e, "iridescenceThicknessTexture", where, ImageData::kLinear,
                             &out->uv_set.iridescence_thickness);
}

void Loader::load_materials() {
  uv_sources_.assign(model_.materials.size(), {});
  for (size_t m = 0; m < model_.materials.size(); ++m) {
    const tinygltf::Material& in = model_.materials[m];
    const tinygltf::PbrMetallicRoughness& pbr = in.pbrMetallicRoughness;
    const std::string what = fmt::format("material {}", m);
    Material out;
    out.name = in.name;
    if (pbr.baseColorFactor.size() != 4 || !is_finite(pbr.baseColorFactor)) {
      fail(what + " has an invalid baseColorFactor");
    }
    out.base_color_factor = glm::vec4(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]),
                                      float(pbr.baseColorFactor[2]), float(pbr.baseColorFactor[3]));
    if (!std::isfinite(pbr.metallicFactor) || !std::isfinite(pbr.roughnessFactor)) {
      fail(what + " has an invalid metallicFactor or roughnessFactor");
    }
    out.metallic = float(std::clamp(pbr.metallicFactor, 0.0, 1.0));
    out.roughness = float(std::clamp(pbr.roughnessFactor, 0.0, 1.0));
    if (!in.emissiveFactor.empty()) {
      if (in.emissiveFactor.size() != 3 || !is_finite(in.emissiveFactor)) {
        fail(what + " has an invalid emissiveFactor");
      }
      out.emissive = glm::vec3(float(in.emissiveFactor[0]), float(in.emissiveFactor[1]),
                               float(in.emissiveFactor[2]));
    }
    out.emissive_factor = out.emissive;
    std::string where;
    if (const tinygltf::Value* e =
            material_extension(in, "KHR_materials_emissive_strength", what, &where)) {
      float strength = 1.0f;
      read_number(*e, "emissiveStrength", where, non_negative, ">= 0", &strength);
      out.emissive_strength = strength;
      out.emissive *= strength;
    }
    out.unlit = in.extensions.count("KHR_materials_unlit") > 0;
    out.double_sided = in.doubleSided;
    if (in.alphaMode == "MASK") {
      out.alpha_mode = Material::AlphaMode::kMask;
      if (!(in.alphaCutoff >= 0.0 && std::isfinite(in.alphaCutoff))) {
        fail(
            fmt::format("{} has an invalid alphaCutoff ({}; a number >= 0)", what, in.alphaCutoff));
      }
      out.alpha_cutoff = float(in.alphaCutoff);
    } else if (in.alphaMode == "BLEND") {
      out.alpha_mode = Material::AlphaMode::kBlend;
    } else if (in.alphaMode != "OPAQUE") {
      warn_once("alphaMode " + in.alphaMode,
                fmt::format("{} has alphaMode \"{}\", which glTF does not define (drawn "
                            "opaque)",
                            what, in.alphaMode));
    }
    Material::TextureSets& sets = out.uv_set;
    if (const tinygltf::Value* e =
            material_extension(in, "KHR_materials_pbrSpecularGlossiness", what, &where)) {
      read_specular_glossiness(m, *e, where, &out);
    } else {
      const tinygltf::TextureInfo& base = pbr.baseColorTexture;
      out.base_color_texture =
          read_texture_slot(m, "pbrMetallicRoughness/baseColorTexture", base.index, base.texCoord,
                            base.extensions, ImageData::kColor, &sets.base_color);
      const tinygltf::TextureInfo& mr = pbr.metallicRoughnessTexture;
      out.metallic_roughness_texture = read_texture_slot(
          m, "pbrMetallicRoughness/metallicRoughnessTexture", mr.index, mr.texCoord, mr.extensions,
          ImageData::kLinear, &sets.metallic_roughness);
    }
    const tinygltf::TextureInfo& emissive = in.emissiveTexture;
    out.emissive_texture =
        read_texture_slot(m, "emissiveTexture", emissive.index, emissive.texCoord,
                          emissive.extensions, ImageData::kColor, &sets.emissive);
    const tinygltf::OcclusionTextureInfo& occlusion = in.occlusionTexture;
    out.occlusion_texture =
        read_texture_slot(m, "occlusionTexture", occlusion.index, occlusion.texCoord,
                          occlusion.extensions, ImageData::kLinear, &sets.occlusion);
    const tinygltf::NormalTextureInfo& normal = in.normalTexture;
    out.normal_texture = read_texture_slot(m, "normalTexture", normal.index, normal.texCoord,
                                           normal.extensions, ImageData::kLinear, &sets.normal);
    if (out.normal_texture >= 0) {
      if (!std::isfinite(normal.scale)) {
        fail(fmt::format("{} has an invalid normalTexture scale ({})", what, normal.scale));
      }
      out.normal_scale = float(normal.scale);
    }
    if (out.occlusion_texture >= 0) {
      if (!(occlusion.strength >= 0.0 && occlusion.strength <= 1.0)) {
        fail(fmt::format("{} has an invalid occlusionTexture strength ({}; 0 to 1)", what,
                         occlusion.strength));
      }
      out.occlusion_strength = float(occlusion.strength);
    }
    // The extensions' texture slots come after the core's in uv_sources_.
    read_transmission_and_ior(m, in, what, &out);
    read_specular(m, in, what, &out);
    read_clearcoat(m, in, what, &out);
    read_volume(in, what, &out);
    read_dispersion(in, what, &out);
    read_sheen(m, in, what, &out);
    read_anisotropy(m, in, what, &out);
    read_iridescence(m, in, what, &out);
    if (in.extras.Has("afr_ambient")) out.ambient = read_rgb_extra(in.extras, "afr_ambient", what);
    const std::vector<UvSource>& sources = uv_sources_[m];
    if (std::any_of(sources.begin(), sources.end(), [](const UvSource& u) { return u.animated; })) {
      out.uv_transforms.resize(sources.size());
      for (size_t k = 0; k < sources.size(); ++k) {
        if (sources[k].animated) out.uv_transforms[k] = *sources[k].animated;
      }
    }
    scene_.materials.push_back(std::move(out));
  }
  keep_mask_alphas();
}

// Texture alpha is kept only where a masking or blending material's base color reads it, and
// where it is not 1 everywhere: other materials are opaque whatever their images hold.
void Loader::keep_mask_alphas() {
  std::vector<bool> masks(scene_.textures.size(), false);
  for (const Material& m : scene_.materials) {
    if (m.alpha_mode != Material::AlphaMode::kOpaque && m.base_color_texture >= 0) {
      masks[size_t(m.base_color_texture)] = true;
    }
  }
  for (size_t t = 0; t < scene_.textures.size(); ++t) {
    Texture& texture = scene_.textures[t];
    const bool opaque = std::all_of(texture.codes.begin(), texture.codes.end(),
                                    [](uint32_t code) { return code >> 24 == 255; });
    if (!masks[t] || opaque) texture.coded_alpha = false;
  }
}

int Loader::read_texture_slot(size_t m, std::string_view path, int index, int tex_coord,
                              const tinygltf::ExtensionMap& extensions, ImageData data,
                              uint8_t* set) {
  if (index < 0) return -1;
  const std::string slot(path.substr(path.rfind('/') + 1));  // its name, as messages give it
  const std::string what = fmt::format("material {} {}", m, slot);
  if (size_t(index) >= model_.textures.size()) {
    fail(fmt::format("{} refers to texture {}, but there are {}", what, index,
                     model_.textures.size()));
  }
  const std::optional<Material::UvTransform> transform =
      read_texture_transform(extensions, what, &tex_coord);
  std::vector<UvSource>& sources = uv_sources_[m];
  const auto animated = animated_uv_slots_.find({m, std::string(path)});
  if (animated != animated_uv_slots_.end()) {
    // An animated transform: applied at each lookup, to a set of the slot's own.
    animated->second = int(sources.size());
    *set = uint8_t(sources.size());
    sources.push_back(
        {tex_coord, glm::dmat3(1.0), slot, transform.value_or(Material::UvTransform{})});
  } else {
    // Slots that read one TEXCOORD_n through one transform share a set: a primitive stores
    // each set once (applied at load, so a lookup costs the tracer no transform).
    const glm::dmat3 matrix = transform ? transform->matrix() : glm::dmat3(1.0);
    size_t k = 0;
    while (k < sources.size() && !(sources[k].tex_coord == tex_coord && !sources[k].animated &&
                                   sources[k].transform == matrix)) {
      ++k;
    }
    if (k == sources.size()) sources.push_back({tex_coord, matrix, slot, std::nullopt});
    *set = uint8_t(k);
  }
  const tinygltf::Texture& texture = model_.textures[size_t(index)];
  if (texture.sampler >= int(model_.samplers.size())) {
    fail(fmt::format("texture {} refers to sampler {}, but there are {}", index, texture.sampler,
                     model_.samplers.size()));
  }
  const TextureSampling sampling = read_sampler(texture.sampler);
  // EXT_texture_webp names the WebP image; `source`, if any, is the fallback for viewers
  // without it.
  int source = texture.source;
  if (const auto webp = texture.extensions.find("EXT_texture_webp");
      webp != texture.extensions.end()) {
    const tinygltf::Value& s = webp->second.Get("source");
    if (!webp->second.IsObject() || !s.IsInt() || s.GetNumberAsInt() < 0) {
      fail(fmt::format("texture {} EXT_texture_webp has no valid \"source\" (an image index)",
                       index));
    }
    source = s.GetNumberAsInt();
  }
  if (source < 0) {
    warn_once("texture without source",
              "textures without a PNG, JPEG or WebP source are not supported (ignored)");
    return -1;
  }
  if (size_t(source) >= model_.images.size()) {
    fail(fmt::format("texture {} refers to image {}, but there are {}", index, source,
                     model_.images.size()));
  }
  return texture_for_image(source, data, sampling);
}

// glTF sampler s (-1: none, the defaults: REPEAT, linear): its wrap modes and magnification.
// minFilter is not needed: minified lookups always filter through the mip levels (ray cones).
Loader::TextureSampling Loader::read_sampler(int s) {
  TextureSampling out;
  if (s < 0) return out;
  const tinygltf::Sampler& sampler = model_.samplers[size_t(s)];
  const auto wrap = [&](int mode, const char* name) {
    switch (mode) {
      case TINYGLTF_TEXTURE_WRAP_REPEAT:
        return Texture::Wrap::kRepeat;
      case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
        return Texture::Wrap::kClampToEdge;
      case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
        return Texture::Wrap::kMirroredRepeat;
    }
    fail(fmt::format("sampler {} has an invalid {} ({}; 10497, 33071 or 33648)", s, name, mode));
  };
  out.wrap_s = wrap(sampler.wrapS, "wrapS");
  out.wrap_t = wrap(sampler.wrapT, "wrapT");
  if (sampler.magFilter != -1 && sampler.magFilter != TINYGLTF_TEXTURE_FILTER_NEAREST &&
      sampler.magFilter != TINYGLTF_TEXTURE_FILTER_LINEAR) {
    fail(fmt::format("sampler {} has an invalid magFilter ({}; 9728 or 9729)", s,
                     sampler.magFilter));
  }
  out.nearest = sampler.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST;
  return out;
}

// KHR_texture_transform on a texture reference: the transform that maps the primitive's
// texture coordinates to the texture's, and its texCoord (which replaces the reference's own).
// The order is the Khronos sample viewer's, translation x rotation x scale, with the rotation
// turning (u, v) to (c u + s v, -s u + c v) (Material::UvTransform): TextureTransformTest's
// green marker. The GLSL of the extension's text writes the rotation transposed; viewers and
// the test model agree on this one.
std::optional<Material::UvTransform> Loader::read_texture_transform(
    const tinygltf::ExtensionMap& extensions, const std::string& what, int* tex_coord) {
  const auto ext = extensions.find("KHR_texture_transform");
  if (ext == extensions.end()) return std::nullopt;
  const tinygltf::Value& t = ext->second;
  const std::string where = what + " KHR_texture_transform";
  if (!t.IsObject()) fail(where + " is not an object");
  auto pair = [&](const char* key, double fallback) {
    std::array<double, 2> v = {fallback, fallback};
    if (!t.Has(key)) return v;
    const tinygltf::Value& a = t.Get(key);
    bool ok = a.IsArray() && a.ArrayLen() == 2;
    for (int i = 0; ok && i < 2; ++i) {
      ok = a.Get(i).IsNumber() && std::isfinite(a.Get(i).GetNumberAsDouble());
      if (ok) v[size_t(i)] = a.Get(i).GetNumberAsDouble();
    }
    if (!ok) fail(fmt::format("{} \"{}\" is not an array of 2 numbers", where, key));
    return v;
  };
  const std::array<double, 2> offset = pair("offset", 0.0);
  const std::array<double, 2> scale = pair("scale", 1.0);
  double rotation = 0.0;
  if (t.Has("rotation")) {
    const tinygltf::Value& r = t.Get("rotation");
    if (!r.IsNumber() || !std::isfinite(r.GetNumberAsDouble())) {
      fail(where + " \"rotation\" is not a number");
    }
    rotation = r.GetNumberAsDouble();
  }
  if (t.Has("texCoord")) {
    const tinygltf::Value& c = t.Get("texCoord");
    if (!c.IsInt() || c.GetNumberAsInt() < 0) {
      fail(where + " \"texCoord\" is not a non-negative integer");
    }
    *tex_coord = c.GetNumberAsInt();
  }
  return Material::UvTransform{{offset[0], offset[1]}, rotation, {scale[0], scale[1]}};
}

// A primitive's texture coordinate sets, those of its material (`sources`; none: TEXCOORD_0
// as it is), each through its transform. A set the primitive lacks stays empty (one warning
// unless it is TEXCOORD_0, which untextured content often leaves out): the slots reading it
// take their factors alone.
void Loader::read_texture_coordinates(const tinygltf::Primitive& in,
                                      const std::vector<UvSource>& sources, const std::string& what,
                                      size_t vertex_count, Primitive* out) {
  const size_t sets = std::max<size_t>(sources.size(), 1);
  out->more_uvs.resize(sets - 1);
  for (size_t k = 0; k < sets; ++k) {
    const int tex_coord = k < sources.size() ? sources[k].tex_coord : 0;
    const std::string name = fmt::format("TEXCOORD_{}", tex_coord);
    const auto uv = in.attributes.find(name);
    if (uv == in.attributes.end()) {
      if (tex_coord != 0) {
        warn_once("missing " + name,
                  fmt::format("{} has no {}, which its material's {} reads: the textures on that "
                              "set are left out (the material's factors decide)",
                              what, name, sources[k].slot));
      }
      continue;
    }
    const std::vector<float> t = read_floats(uv->second, TINYGLTF_TYPE_VEC2, what + " " + name);
    if (t.size() / 2 != vertex_count) {
      fail(fmt::format("{} has {} texture coordinates for {} positions", what, t.size() / 2,
                       vertex_count));
    }
    std::vector<glm::vec2>& set = k == 0 ? out->uvs : out->more_uvs[k - 1];
    set.resize(vertex_count);
    const glm::dmat3 m = k < sources.size() ? sources[k].transform : glm::dmat3(1.0);
    const bool moved = m != glm::dmat3(1.0);
    for (size_t i = 0; i < vertex_count; ++i) {
      const glm::vec2 v(t[2 * i], t[2 * i + 1]);
      set[i] = moved ? glm::vec2(m * glm::dvec3(v, 1.0)) : v;
    }
  }
}

// Image `image_index` in Scene::textures, decoded as sRGB color or as data, with `sampling`:
// its index there. Each image is decoded once per way it is read; a second sampling of it
// copies the texels.
int Loader::texture_for_image(int image_index, ImageData data, const TextureSampling& sampling) {
  const TextureKey key{image_index, data, sampling.wrap_s, sampling.wrap_t, sampling.nearest};
  if (const auto found = textures_.find(key); found != textures_.end()) return found->second;
  const auto decoded_before = textures_.lower_bound(TextureKey{image_index, data, {}, {}, false});
  if (decoded_before != textures_.end() && std::get<0>(decoded_before->first) == image_index &&
      std::get<1>(decoded_before->first) == data) {
    Texture texture = scene_.textures[size_t(decoded_before->second)];
    sampling.apply(&texture);
    return textures_[key] = add_texture(std::move(texture));
  }
  const tinygltf::Image& image = model_.images[size_t(image_index)];
  const bool file = !image.uri.empty() && image.uri.rfind("data:", 0) != 0;
  const std::string label = file ? fmt::format("image {} ({})", image_index, image.uri)
                                 : fmt::format("image {}", image_index);
  const std::string name = fmt::format("{} of {}", label, path_.string());
  std::span<const uint8_t> bytes;
  if (image.bufferView >= 0) {
    bytes = buffer_view_bytes(image.bufferView, fmt::format("image {}", image_index));
  } else {
    bytes = image.image;
  }
  if (bytes.empty()) {
    std::string reason = "its data could not be read";
    if (!access_.refused.empty()) {
      reason += " (files outside the folder of the glTF are refused)";
    } else if (const fs::path where = path_.parent_path() / image.uri; file) {
      std::error_code ec;
      if (!fs::exists(where, ec)) reason = fmt::format("no such file: {}", where.string());
    }
    throw Error(fmt::format("{}: {}", name, reason));
  }
  // An image of a format afr does not decode (KTX2, as files written for KHR_texture_basisu
  // viewers name without the extension) leaves its textures out, as a texture without a
  // source is; broken data of a format afr decodes is an error.
  if (const std::string format = image_formats::sniff(bytes);
      format.empty() || !image_formats::decoded_in_memory(format)) {
    const bool ktx2 = bytes.size() >= 8 && std::memcmp(bytes.data(), "\xABKTX 20\xBB", 8) == 0;
    warn_once(fmt::format("image format {}", image_index),
              fmt::format("{}: {} is not an image format afr decodes as a texture (PNG, JPEG or "
                          "WebP): the textures of it are ignored",
                          label,
                          ktx2             ? std::string("KTX2")
                          : format.empty() ? std::string("its data")
                                           : format));
    return -1;
  }
  const DecodedImage decoded = decode_image(bytes, name);

  // The image's 8-bit values are kept as they are (Texture::codes), decoded at each lookup:
  // sRGB-encoded color, or data (metallic-roughness, occlusion, normal) as it is.
  Texture texture;
  texture.name = image.name.empty() ? image.uri : image.name;
  texture.width = decoded.width;
  texture.height = decoded.height;
  const bool srgb = data == ImageData::kColor;
  texture.encoding = srgb ? Texture::Encoding::kSrgb : Texture::Encoding::kLinear;
  texture.codes.resize(size_t(decoded.width) * size_t(decoded.height));
  const size_t c = size_t(decoded.channels);
  const bool has_alpha = c == 2 || c == 4;
  for (size_t i = 0; i < texture.codes.size(); ++i) {
    const uint8_t* p = &decoded.data[i * c];
    // One channel is gray, two are gray and alpha.
    const uint32_t r = p[0], g = c >= 3 ? p[1] : p[0], b = c >= 3 ? p[2] : p[0];
    const uint32_t a = has_alpha ? p[c - 1] : 255;
    texture.codes[i] = data == ImageData::kAlpha ? a | (a << 8) | (a << 16) | (255u << 24)
                                                 : r | (g << 8) | (b << 16) | (a << 24);
  }
  // Alpha (linear in glTF) of a color image that has it, until load_materials() knows whether
  // a masking material reads it (keep_mask_alphas()).
  texture.coded_alpha = srgb && has_alpha;
  sampling.apply(&texture);
  return textures_[key] = add_texture(std::move(texture));
}

int Loader::add_texture(Texture texture) {
  scene_.textures.push_back(std::move(texture));
  return int(scene_.textures.size()) - 1;
}

// ---- Cameras and lights ----

void Loader::load_cameras() {
  for (size_t i = 0; i < model_.cameras.size(); ++i) {
    const tinygltf::Camera& in = model_.cameras[i];
    const std::string what =
        fmt::format("camera {}{}", i, in.name.empty() ? "" : " ('" + in.name + "')");
    CameraModel camera;
    camera.name = in.name;
    if (in.type == "perspective") {
      const double yfov = in.perspective.yfov;
      const double znear = in.perspective.znear;
      if (!(yfov > 0.0 && yfov < std::numbers::pi)) {
        fail(fmt::format("{} has a yfov of {} radians, outside (0, pi)", what, yfov));
      }
      if (!(znear > 0.0 && std::isfinite(znear))) {
        fail(fmt::format("{} has a znear of {}: a perspective camera's is finite and > 0", what,
                         znear));
      }
      camera.yfov = yfov;
      camera.znear = znear;
    } else if (in.type == "orthographic") {
      // The view is 2 ymag high; its width follows from the image's aspect ratio, as a
      // perspective camera's does (aspectRatio), so xmag is not used. zfar is not either: a
      // ray tracer needs no far plane.
      const double ymag = in.orthographic.ymag;
      const double znear = in.orthographic.znear;
      if (!std::isfinite(ymag) || ymag == 0.0) {
        fail(
            fmt::format("{} is orthographic with a ymag of {}: glTF requires a finite ymag "
                        "other than 0",
                        what, ymag));
      }
      if (!(znear >= 0.0 && std::isfinite(znear))) {
        fail(
            fmt::format("{} is orthographic with a znear of {}: glTF requires a finite znear "
                        ">= 0",
                        what, znear));
      }
      if (ymag < 0.0) {
        warn_once("negative ymag " + what,
                  fmt::format("{} has a negative ymag ({}): its magnitude is used", what, ymag));
      }
      camera.ymag = std::abs(ymag);
      // The near plane at 0 (glTF allows it here) is kept just in front of the eye's plane.
      camera.znear = std::max(znear, 1e-9);
    } else {
      warn_once("camera " + in.type,
                fmt::format("{} cameras are not supported: {} is skipped, and the first other "
                            "camera (else the default camera) is used",
                            in.type, what));
      camera_map_.push_back(-1);
      continue;
    }
    camera_map_.push_back(int(scene_.cameras.size()));
    scene_.cameras.push_back(std::move(camera));
  }
}

void Loader::load_lights() {
  for (size_t i = 0; i < model_.lights.size(); ++i) {
    const tinygltf::Light& in = model_.lights[i];
    const std::string what = fmt::format("light {}", i);
    Light light;
    light.name = in.name;
    if (in.type == "point") {
      light.type = Light::Type::kPoint;
    } else if (in.type == "directional") {
      light.type = Light::Type::kDirectional;
    } else if (in.type == "spot") {
      light.type = Light::Type::kSpot;
    } else {
      warn_once("light " + in.type, fmt::format("lights of type \"{}\" are not supported "
                                                "(skipped)",
                                                in.type));
      light_map_.push_back(-1);
      continue;
    }
    if (!in.color.empty()) {
      if (in.color.size() != 3 || !is_finite(in.color)) fail(what + " has an invalid color");
      light.color = glm::vec3(float(in.color[0]), float(in.color[1]), float(in.color[2]));
    }
    if (!std::isfinite(in.intensity) || in.intensity < 0.0) {
      fail(fmt::format("{} has an invalid intensity {}", what, in.intensity));
    }
    if (!std::isfinite(in.range) || in.range < 0.0) {
      fail(fmt::format("{} has an invalid range {}", what, in.range));
    }
    light.intensity = float(in.intensity);
    light.range = float(in.range);
    if (light.type == Light::Type::kSpot) {
      const double inner = in.spot.innerConeAngle;
      const double outer = in.spot.outerConeAngle;
      if (!(inner >= 0.0 && inner <= outer && outer > 0.0 &&
            outer <= std::numbers::pi / 2 + 1e-9)) {
        fail(fmt::format("{} has invalid cone angles (inner {}, outer {})", what, inner, outer));
      }
      light.inner_cone_angle = float(inner);
      light.outer_cone_angle = float(outer);
    }
    if (in.extras.Has("afr_falloff")) {
      const tinygltf::Value& falloff = in.extras.Get("afr_falloff");
      if (falloff.IsString() && falloff.Get<std::string>() == "none") {
        light.inverse_square_falloff = false;
      } else if (!(falloff.IsString() && falloff.Get<std::string>() == "inverse_square")) {
        fail(what + " extra \"afr_falloff\" is neither \"none\" nor \"inverse_square\"");
      }
    }
    light_map_.push_back(int(scene_.lights.size()));
    scene_.lights.push_back(std::move(light));
  }
}

// ---- Nodes ----

void Loader::load_nodes() {
  const size_t count = model_.nodes.size();
  std::vector<int> parent(count, -1);
  for (size_t i = 0; i < count; ++i) {
    const tinygltf::Node& in = model_.nodes[i];
    const std::string what = fmt::format("node {}", i);
    Node node;
    node.name = in.name;
    for (int child : in.children) {
      if (child < 0 || size_t(child) >= count) {
        fail(fmt::format("{} has child {}, but there are {} nodes", what, child, count));
      }
      if (size_t(child) == i)
        fail(fmt::format("{} is its own child: a cycle in the node graph", what));
      if (parent[size_t(child)] >= 0) {
        fail(
            fmt::format("node {} is a child of both node {} and node {}: the node graph is not a "
                        "tree",
                        child, parent[size_t(child)], i));
      }
      parent[size_t(child)] = int(i);
      node.children.push_back(child);
    }
    if (in.mesh < -1 || in.mesh >= int(model_.meshes.size())) {
      fail(fmt::format("{} refers to mesh {}, but there are {}", what, in.mesh,
                       model_.meshes.size()));
    }
    node.mesh = in.mesh;
    if (in.camera < -1 || in.camera >= int(model_.cameras.size())) {
      fail(fmt::format("{} refers to camera {}, but there are {}", what, in.camera,
                       model_.cameras.size()));
    }
    node.camera = in.camera >= 0 ? camera_map_[size_t(in.camera)] : -1;
    if (in.skin < -1 || in.skin >= int(model_.skins.size())) {
      fail(fmt::format("{} refers to skin {}, but there are {}", what, in.skin,
                       model_.skins.size()));
    }
    if (in.skin >= 0 && in.mesh < 0) fail(fmt::format("{} has skin {} but no mesh", what, in.skin));
    node.skin = in.skin;
    if (!in.weights.empty()) {
      const size_t targets = in.mesh >= 0 ? scene_.meshes[size_t(in.mesh)].weights.size() : 0;
      if (in.weights.size() != targets) {
        fail(fmt::format("{} has {} morph weights, but {} {} morph targets", what,
                         in.weights.size(), in.mesh >= 0 ? "its mesh has" : "it has no mesh and",
                         targets));
      }
      if (!is_finite(in.weights)) fail(what + " has a morph weight that is not finite");
      node.weights.assign(in.weights.begin(), in.weights.end());
    }
    if (const auto ext = in.extensions.find("KHR_lights_punctual"); ext != in.extensions.end()) {
      const int light = ext->second.Has("light") && ext->second.Get("light").IsInt()
                            ? ext->second.Get("light").GetNumberAsInt()
                            : -1;
      if (light < 0 || size_t(light) >= light_map_.size()) {
        fail(fmt::format("{} refers to an invalid light (there are {})", what, light_map_.size()));
      }
      node.light = light_map_[size_t(light)];
    }
    if (!in.matrix.empty()) {
      if (in.matrix.size() != 16 || !is_finite(in.matrix)) fail(what + " has an invalid matrix");
      glm::dmat4 m;
      for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) m[c][r] = in.matrix[size_t(4 * c + r)];
      }
      node.matrix = m;
    }
    if (!in.translation.empty()) {
      if (in.translation.size() != 3 || !is_finite(in.translation)) {
        fail(what + " has an invalid translation");
      }
      node.translation = {in.translation[0], in.translation[1], in.translation[2]};
    }
    if (!in.rotation.empty()) {
      if (in.rotation.size() != 4 || !is_finite(in.rotation)) {
        fail(what + " has an invalid rotation");
      }
      // glTF stores (x, y, z, w); glm's constructor takes w first.
      const glm::dquat q(in.rotation[3], in.rotation[0], in.rotation[1], in.rotation[2]);
      const double length = glm::length(q);
      if (!(length > 1e-12)) fail(what + " has a zero rotation quaternion");
      node.rotation = q / length;
    }
    if (!in.scale.empty()) {
      if (in.scale.size() != 3 || !is_finite(in.scale)) fail(what + " has an invalid scale");
      node.scale = {in.scale[0], in.scale[1], in.scale[2]};
    }
    scene_.nodes.push_back(std::move(node));
  }
  // Every node has at most one parent now; a node not reachable from a parentless node lies
  // on a cycle (or below one).
  std::vector<char> reached(count, 0);
  std::vector<int> stack;
  for (size_t i = 0; i < count; ++i) {
    if (parent[i] < 0) stack.push_back(int(i));
  }
  while (!stack.empty()) {
    const int n = stack.back();
    stack.pop_back();
    reached[size_t(n)] = 1;
    for (int child : scene_.nodes[size_t(n)].children) stack.push_back(child);
  }
  for (size_t i = 0; i < count; ++i) {
    if (!reached[i]) fail(fmt::format("node {} is part of a cycle in the node graph", i));
  }
  for (size_t i = 0; i < count; ++i) instance_node(int(i));
  hide_invisible_nodes();
}

// KHR_node_visibility: a node whose `visible` is false hides its own and all its descendants'
// meshes and lights, whatever theirs say (cameras stay: visibility does not affect them). The
// value is the file's: KHR_animation_pointer does not animate it (read_animation_pointers).
void Loader::hide_invisible_nodes() {
  // Nodes whose visibility an animation drives keep what they carry (Node::visible).
  std::set<size_t> animated;
  for (const PointerChannel& p : pointer_channels_) {
    if (p.target.property == AnimatedProperty::kNodeVisible) animated.insert(p.target.index);
  }
  size_t hidden = 0;
  std::vector<int> stack;
  for (size_t i = 0; i < model_.nodes.size(); ++i) {
    const auto ext = model_.nodes[i].extensions.find("KHR_node_visibility");
    if (ext == model_.nodes[i].extensions.end()) continue;
    const tinygltf::Value& e = ext->second;
    if (!e.IsObject()) fail(fmt::format("node {} KHR_node_visibility is not an object", i));
    if (!e.Has("visible")) continue;  // default: true
    if (!e.Get("visible").IsBool()) {
      fail(fmt::format("node {} KHR_node_visibility has an invalid visible (true or false)", i));
    }
    if (e.Get("visible").Get<bool>()) continue;
    if (animated.count(i) != 0) {
      scene_.nodes[i].visible = false;
      continue;
    }
    stack.push_back(int(i));
    while (!stack.empty()) {  // the node graph is a tree here (load_nodes checked)
      hidden_nodes_.insert(stack.back());
      Node& node = scene_.nodes[size_t(stack.back())];
      stack.pop_back();
      hidden += node.mesh >= 0 || node.light >= 0 ? 1 : 0;
      node.mesh = -1;
      node.light = -1;
      node.skin = -1;
      node.weights.clear();
      for (int child : node.children) stack.push_back(child);
    }
  }
  if (hidden > 0) {
    spdlog::info("{}: {} node(s) with a mesh or light hidden by KHR_node_visibility",
                 path_.string(), hidden);
  }
}

// EXT_mesh_gpu_instancing: a node's mesh drawn once for each element of its instance attributes
// (TRANSLATION, ROTATION, SCALE, any of them; all of one count), each instance's transform
// applied before the node's own. Each instance becomes a child node carrying the mesh (added
// after the file's nodes, so that no index changes) and the node keeps none; the tracer then
// instances the copies of a mesh that would take much memory (TracerOptions::
// max_copied_vertices) rather than copying them.
void Loader::instance_node(int index) {
  const tinygltf::Node& in = model_.nodes[size_t(index)];
  const auto ext = in.extensions.find("EXT_mesh_gpu_instancing");
  if (ext == in.extensions.end()) return;
  const std::string what = fmt::format("node {} EXT_mesh_gpu_instancing", index);
  const tinygltf::Value& e = ext->second;
  if (!e.IsObject() || !e.Get("attributes").IsObject()) fail(what + " has no \"attributes\"");
  if (scene_.nodes[size_t(index)].mesh < 0) fail(what + ": the node has no mesh");
  if (scene_.nodes[size_t(index)].skin >= 0) {
    warn_once("instanced skin",
              "EXT_mesh_gpu_instancing on a node with a skin is not supported (the mesh is drawn "
              "once)");
    return;
  }
  const tinygltf::Value& attributes = e.Get("attributes");
  // Attribute `name` of `type`, as floats, or empty where the extension does not give it.
  std::optional<size_t> count;
  const auto read = [&](const char* name, int type) -> std::vector<float> {
    if (!attributes.Has(name)) return {};
    const tinygltf::Value& v = attributes.Get(name);
    if (!v.IsInt()) fail(fmt::format("{} attribute {} is not an accessor index", what, name));
    const std::string part = fmt::format("{} {}", what, name);
    std::vector<float> values = read_floats(v.GetNumberAsInt(), type, part);
    const size_t n = values.size() / (type == TINYGLTF_TYPE_VEC4 ? 4 : 3);
    if (count && *count != n) {
      fail(fmt::format("{} has {} instances in {} but {} in another attribute", what, n, name,
                       *count));
    }
    count = n;
    return values;
  };
  for (const std::string& name : attributes.Keys()) {
    if (name != "TRANSLATION" && name != "ROTATION" && name != "SCALE") {
      warn_once("instance attribute " + name,
                fmt::format("EXT_mesh_gpu_instancing attribute {} is not read", name));
    }
  }
  const std::vector<float> t = read("TRANSLATION", TINYGLTF_TYPE_VEC3);
  const std::vector<float> r = read("ROTATION", TINYGLTF_TYPE_VEC4);
  const std::vector<float> s = read("SCALE", TINYGLTF_TYPE_VEC3);
  if (!count) fail(what + " has none of TRANSLATION, ROTATION and SCALE");
  instanced_nodes_.insert(index);
  if (scene_.nodes.size() + *count > kMaxNodes) {
    fail(fmt::format("{} makes {} nodes, more than afr accepts ({})", what,
                     scene_.nodes.size() + *count, kMaxNodes));
  }
  Node copy;
  copy.parent = index;
  {
    Node& node = scene_.nodes[size_t(index)];
    copy.mesh = node.mesh;
    copy.weights = node.weights;
    node.mesh = -1;
    node.weights.clear();
  }
  const std::string name = scene_.nodes[size_t(index)].name;
  scene_.nodes.reserve(scene_.nodes.size() + *count);
  for (size_t k = 0; k < *count; ++k) {
    copy.name = fmt::format("{} instance {}", name, k);
    if (!t.empty()) copy.translation = {t[3 * k], t[3 * k + 1], t[3 * k + 2]};
    if (!r.empty()) {
      const glm::dquat q(r[4 * k + 3], r[4 * k], r[4 * k + 1], r[4 * k + 2]);
      const double length = glm::length(q);
      if (!(length > 1e-12)) fail(fmt::format("{} instance {} has a zero rotation", what, k));
      copy.rotation = q / length;
    }
    if (!s.empty()) copy.scale = {s[3 * k], s[3 * k + 1], s[3 * k + 2]};
    scene_.nodes[size_t(index)].children.push_back(int(scene_.nodes.size()));
    scene_.nodes.push_back(copy);
  }
}

// ---- Skins ----

void Loader::load_skins() {
  for (size_t k = 0; k < model_.skins.size(); ++k) {
    const tinygltf::Skin& in = model_.skins[k];
    const std::string what = fmt::format("skin {}", k);
    Skin skin;
    skin.name = in.name;
    if (in.joints.empty()) fail(what + " has no joints");
    for (int joint : in.joints) {
      if (joint < 0 || size_t(joint) >= model_.nodes.size()) {
        fail(fmt::format("{} has joint node {}, but there are {} nodes", what, joint,
                         model_.nodes.size()));
      }
    }
    skin.joints = in.joints;
    if (in.skeleton < -1 || in.skeleton >= int(model_.nodes.size())) {
      fail(fmt::format("{} has skeleton node {}, but there are {} nodes", what, in.skeleton,
                       model_.nodes.size()));
    }
    skin.skeleton = in.skeleton;
    // Without inverse bind matrices, each is the identity (glTF 2.0, 5.29).
    skin.inverse_bind_matrices.assign(in.joints.size(), glm::dmat4(1.0));
    if (in.inverseBindMatrices >= 0) {
      const std::vector<float> m =
          read_floats(in.inverseBindMatrices, TINYGLTF_TYPE_MAT4, what + " inverseBindMatrices");
      if (m.size() != 16 * in.joints.size()) {
        fail(fmt::format("{} has {} inverse bind matrices for {} joints", what, m.size() / 16,
                         in.joints.size()));
      }
      for (size_t j = 0; j < in.joints.size(); ++j) {
        for (int c = 0; c < 4; ++c) {
          for (int r = 0; r < 4; ++r) skin.inverse_bind_matrices[j][c][r] = m[16 * j + 4 * c + r];
        }
      }
    }
    scene_.skins.push_back(std::move(skin));
  }
}

// Joints and weights of meshes that no skinned node shows are never read: not kept.
void Loader::drop_unused_joints() {
  std::vector<char> skinned(scene_.meshes.size(), 0);
  for (const Node& n : scene_.nodes) {
    if (n.skin >= 0 && n.mesh >= 0) skinned[size_t(n.mesh)] = 1;
  }
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    if (skinned[m]) continue;
    for (Primitive& p : scene_.meshes[m].primitives) {
      p.joints = {};
      p.joint_weights = {};
    }
  }
}

// ---- Animations ----

// KHR_animation_pointer: a channel whose target's path is "pointer" animates the property its
// JSON pointer names. Those pointer_target knows become channels: a node's (add_channel, as
// any node's channel), a mesh's weights (those of the nodes showing them), a light's, camera's
// or material's property (add_property_channel). Any other pointer is not animated, and one
// warning names the kinds skipped. tinygltf drops every channel without a target node, so this
// also notes which of the file's channels it kept (kept_channels_).
void Loader::read_animation_pointers(std::string_view json) {
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, false);
  if (doc.is_discarded() || !doc.is_object() || !doc.contains("animations") ||
      !doc["animations"].is_array()) {
    return;
  }
  bool other_nodeless = false;
  std::vector<std::string> skipped;  // the kinds of property not animated, in file order
  const nlohmann::json& animations = doc["animations"];
  kept_channels_.assign(animations.size(), {});
  for (size_t a = 0; a < animations.size(); ++a) {
    if (!animations[a].is_object() || !animations[a].contains("channels") ||
        !animations[a]["channels"].is_array()) {
      continue;  // tinygltf has named it
    }
    const nlohmann::json& channels = animations[a]["channels"];
    for (size_t c = 0; c < channels.size(); ++c) {
      const nlohmann::json& channel = channels[c];
      if (!channel.is_object()) continue;
      // tinygltf keeps a channel with a sampler and either no target or one naming a node and
      // a path.
      const bool sampled = channel.contains("sampler") && channel["sampler"].is_number_integer();
      if (!channel.contains("target") || !channel["target"].is_object()) {
        if (sampled) kept_channels_[a].push_back(c);
        continue;
      }
      const nlohmann::json& target = channel["target"];
      if (target.contains("node")) {
        if (sampled && target["node"].is_number_integer() && target.contains("path") &&
            target["path"].is_string()) {
          kept_channels_[a].push_back(c);
        }
        continue;
      }
      if (target.value("path", "") != "pointer") {
        other_nodeless = true;
        continue;
      }
      const std::string what = fmt::format("animation {} channel {} KHR_animation_pointer", a, c);
      const nlohmann::json* e = nullptr;
      if (target.contains("extensions") && target["extensions"].is_object() &&
          target["extensions"].contains("KHR_animation_pointer")) {
        e = &target["extensions"]["KHR_animation_pointer"];
      }
      if (e == nullptr || !e->is_object() || !e->contains("pointer") ||
          !(*e)["pointer"].is_string()) {
        fail(what + " has no \"pointer\" string");
      }
      const std::string pointer = (*e)["pointer"].get<std::string>();
      const int sampler = sampled ? channel["sampler"].get<int>() : -1;
      const std::optional<PointerTarget> named = pointer_target(pointer);
      if (!named) {
        // The kind of property: the pointer with its indices left out.
        std::string kind;
        for (char ch : pointer) {
          if (ch >= '0' && ch <= '9') {
            if (kind.empty() || kind.back() != '#') kind += '#';
          } else {
            kind += ch;
          }
        }
        if (std::find(skipped.begin(), skipped.end(), kind) == skipped.end()) {
          skipped.push_back(kind);
        }
        continue;
      }
      // Nodes and meshes are checked here; lights, cameras and materials once loaded.
      const bool node = named->kind == PointerTarget::Kind::kNode;
      const size_t count = node ? model_.nodes.size() : model_.meshes.size();
      if (named->kind != PointerTarget::Kind::kProperty && named->index >= count) {
        fail(fmt::format("{} \"{}\" targets {} {}, but there are {}", what, pointer,
                         node ? "node" : "mesh", named->index, count));
      }
      if (is_uv_property(named->property)) animated_uv_slots_[{named->index, named->texture}] = -1;
      pointer_channels_.push_back({a, c, sampler, *named, pointer});
    }
  }
  nodeless_channels_are_pointers_ = !other_nodeless;
  if (!skipped.empty()) {
    constexpr size_t kNamed = 3;
    const size_t count = skipped.size();
    skipped.resize(std::min(count, kNamed));
    warn_once("animation pointers",
              fmt::format("KHR_animation_pointer animations of {}{} are not supported (skipped: "
                          "see docs/scene-model.md for the properties afr animates)",
                          fmt::join(skipped, ", "),
                          count > kNamed ? fmt::format(" and {} more kinds", count - kNamed) : ""));
  }
}

void Loader::load_animations() {
  for (size_t a = 0; a < model_.animations.size(); ++a) {
    const tinygltf::Animation& animation = model_.animations[a];
    for (size_t c = 0; c < animation.channels.size(); ++c) {
      const tinygltf::AnimationChannel& in = animation.channels[c];
      const bool renumbered = a < kept_channels_.size() && c < kept_channels_[a].size();
      const std::string what =
          fmt::format("animation {} channel {}", a, renumbered ? kept_channels_[a][c] : c);
      if (in.target_node < 0) {
        warn_once("channel without node",
                  "animation channels without a target node are not supported (skipped)");
        continue;
      }
      add_channel(animation, in.sampler, in.target_node, in.target_path, what);
    }
    for (const PointerChannel& p : pointer_channels_) {
      if (p.animation != a) continue;
      const std::string what = fmt::format("animation {} channel {} (KHR_animation_pointer \"{}\")",
                                           a, p.channel, p.pointer);
      const PointerTarget& t = p.target;
      switch (t.kind) {
        case PointerTarget::Kind::kNode:
          add_channel(animation, p.sampler, int(t.index), std::string(t.path), what);
          break;
        case PointerTarget::Kind::kMeshWeights:  // those of each node showing the mesh's own
          for (size_t n = 0; n < model_.nodes.size(); ++n) {
            if (model_.nodes[n].mesh == int(t.index) && model_.nodes[n].weights.empty()) {
              add_channel(animation, p.sampler, int(n), "weights", what);
            }
          }
          break;
        case PointerTarget::Kind::kProperty:
          if (is_uv_property(t.property)) {
            // The set read_texture_slot gave the slot; -1 where the material has no texture
            // there (or no such material: add_property_channel names that).
            const auto slot = animated_uv_slots_.find({t.index, t.texture});
            if (t.index < scene_.materials.size() && slot->second < 0) {
              warn_once("animated empty texture slot",
                        fmt::format("{} animates the transform of a texture slot without a "
                                    "texture (skipped)",
                                    what));
              break;
            }
            add_property_channel(animation, p.sampler, t.property, t.index, what, slot->second);
          } else {
            add_property_channel(animation, p.sampler, t.property, t.index, what);
          }
          break;
      }
    }
  }
}

// One channel of `animation`: its sampler `sampler_index` drives `path` of node `node_index`.
void Loader::add_channel(const tinygltf::Animation& animation, int sampler_index, int node_index,
                         const std::string& path, const std::string& what) {
  if (size_t(node_index) >= model_.nodes.size()) {
    fail(
        fmt::format("{} targets node {}, but there are {}", what, node_index, model_.nodes.size()));
  }
  AnimationChannel channel;
  channel.node = node_index;
  int value_type = TINYGLTF_TYPE_VEC3;
  if (path == "translation") {
    channel.path = AnimatedPath::kTranslation;
  } else if (path == "rotation") {
    channel.path = AnimatedPath::kRotation;
    value_type = TINYGLTF_TYPE_VEC4;
  } else if (path == "scale") {
    channel.path = AnimatedPath::kScale;
  } else if (path == "weights") {
    channel.path = AnimatedPath::kWeights;
    value_type = TINYGLTF_TYPE_SCALAR;
  } else {
    warn_once("path " + path,
              fmt::format("animations of \"{}\" are not supported (skipped)", path));
    return;
  }
  if (channel.path == AnimatedPath::kWeights && hidden_nodes_.count(node_index) != 0) {
    return;  // KHR_node_visibility hid its mesh: nothing is drawn to morph
  }
  if (channel.path == AnimatedPath::kWeights && instanced_nodes_.count(node_index) != 0) {
    warn_once("instanced weights",
              "animated morph weights of a node with EXT_mesh_gpu_instancing are not "
              "supported (its instances keep the node's weights)");
    return;
  }
  if (channel.path != AnimatedPath::kWeights && scene_.nodes[size_t(node_index)].matrix) {
    warn_once("animated matrix node",
              "animations of nodes given as a matrix are not supported (skipped)");
    return;
  }
  std::vector<float> values;
  if (!read_sampler(animation, sampler_index, value_type, what, &channel, &values)) return;
  const std::vector<double>& times = channel.times;
  const size_t per_key = channel.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (channel.path == AnimatedPath::kWeights) {
    // As many weights per value as the node's mesh has morph targets (glTF 2.0, 3.11).
    const Node& node = scene_.nodes[size_t(node_index)];
    const size_t targets = node.mesh >= 0 ? scene_.meshes[size_t(node.mesh)].weights.size() : 0;
    if (targets == 0) {
      fail(fmt::format("{} animates the morph weights of node {}, which has {}", what, node_index,
                       node.mesh >= 0 ? "a mesh without morph targets" : "no mesh"));
    }
    if (times.empty() || values.size() != times.size() * per_key * targets) {
      fail(fmt::format(
          "{} has {} keyframe times and {} weights ({} per key expected: {} morph targets{})", what,
          times.size(), values.size(), per_key * targets, targets,
          per_key == 3 ? " times in-tangent, value, out-tangent" : ""));
    }
    channel.weights.assign(values.begin(), values.end());
    channel.weight_count = targets;
  } else {
    const size_t width = value_type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
    if (times.empty() || values.size() != times.size() * per_key * width) {
      fail(fmt::format("{} has {} keyframe times and {} values ({} per key expected)", what,
                       times.size(), values.size() / width, per_key));
    }
    channel.values.resize(values.size() / width);
    for (size_t i = 0; i < channel.values.size(); ++i) {
      const float* v = &values[i * width];
      channel.values[i] = glm::dvec4(v[0], v[1], v[2], width == 4 ? v[3] : 0.0f);
    }
  }
  repair_key_order(&channel, what);
  channel.validate(fmt::format("{} of {}", what, path_.string()));
  scene_.channels.push_back(std::move(channel));
}

// The interpolation and key times of sampler `sampler_index` into `channel`, its output values
// of `value_type` into `values`. False, with a warning, for an interpolation glTF lacks or a
// sampler without keys; an error for a sampler the animation lacks.
bool Loader::read_sampler(const tinygltf::Animation& animation, int sampler_index, int value_type,
                          const std::string& what, AnimationChannel* channel,
                          std::vector<float>* values) {
  if (sampler_index < 0 || size_t(sampler_index) >= animation.samplers.size()) {
    fail(fmt::format("{} refers to sampler {}, but there are {}", what, sampler_index,
                     animation.samplers.size()));
  }
  const tinygltf::AnimationSampler& sampler = animation.samplers[size_t(sampler_index)];
  if (sampler.interpolation == "LINEAR") {
    channel->interpolation = Interpolation::kLinear;
  } else if (sampler.interpolation == "STEP") {
    channel->interpolation = Interpolation::kStep;
  } else if (sampler.interpolation == "CUBICSPLINE") {
    channel->interpolation = Interpolation::kCubicSpline;
  } else {
    warn_once("interpolation " + sampler.interpolation,
              fmt::format("interpolation \"{}\" is not supported (channel skipped)",
                          sampler.interpolation));
    return false;
  }
  const std::vector<float> times =
      read_floats(sampler.input, TINYGLTF_TYPE_SCALAR, what + " input");
  *values = read_floats(sampler.output, value_type, what + " output");
  // glTF's accessors hold at least one element, but exporters write empty tracks, which animate
  // nothing: skipped rather than refusing the scene.
  if (times.empty() && values->empty()) {
    warn_once("no keyframes",
              fmt::format("animation channels without keyframes animate nothing and are skipped "
                          "({} is the first)",
                          what));
    return false;
  }
  channel->times.assign(times.begin(), times.end());
  return true;
}

// A KHR_animation_pointer channel that drives a property of a light, camera or material. A key
// outside the property's glTF range is taken as the same value without an animation is
// (clamped, or an error); the target must exist, and a light or camera that afr skipped (an
// unsupported type) takes its animation with it.
void Loader::add_property_channel(const tinygltf::Animation& animation, int sampler_index,
                                  AnimatedProperty property, size_t gltf_index,
                                  const std::string& what, int uv_set) {
  const bool light = is_light_property(property), camera = is_camera_property(property);
  const bool node = is_node_property(property);
  const std::vector<int>* map = light ? &light_map_ : camera ? &camera_map_ : nullptr;
  const size_t count = map ? map->size() : node ? model_.nodes.size() : scene_.materials.size();
  if (gltf_index >= count) {
    fail(fmt::format("{} targets {} {}, but there are {}", what,
                     light    ? "light"
                     : camera ? "camera"
                     : node   ? "node"
                              : "material",
                     gltf_index, count));
  }
  const int index = map ? (*map)[gltf_index] : int(gltf_index);
  if (index < 0) return;  // a skipped light or camera: named when it was skipped

  PropertyChannel out;
  out.property = property;
  out.index = index;
  out.uv_set = uv_set;
  const int width = component_count(property);
  const int type = width == 1   ? TINYGLTF_TYPE_SCALAR
                   : width == 2 ? TINYGLTF_TYPE_VEC2
                   : width == 3 ? TINYGLTF_TYPE_VEC3
                                : TINYGLTF_TYPE_VEC4;
  std::vector<float> values;
  if (!read_sampler(animation, sampler_index, type, what, &out.curve, &values)) return;
  const size_t per_key = out.curve.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  const size_t keys = out.curve.times.size();
  if (keys == 0 || values.size() != keys * per_key * size_t(width)) {
    fail(fmt::format("{} has {} keyframe times and {} values ({} per key expected)", what, keys,
                     values.size() / size_t(width), per_key));
  }
  // The range each key's value must lie in (tangents are not values).
  double lo = 0.0, hi = std::numeric_limits<double>::infinity();
  bool open_lo = false;
  switch (property) {
    case AnimatedProperty::kLightRange:
    case AnimatedProperty::kCameraYfov:
      open_lo = true;
      hi = std::numbers::pi;
      break;
    case AnimatedProperty::kCameraZnear:
      // glTF lets an orthographic camera's near plane be 0, not a perspective one's.
      open_lo = scene_.cameras[size_t(index)].ymag == 0.0;
      break;
    case AnimatedProperty::kCameraYmag:
      lo = -hi;  // any finite number but 0 (below); a negative one is taken as its magnitude
      break;
    case AnimatedProperty::kLightInnerCone:
    case AnimatedProperty::kLightOuterCone:
      hi = 0.5 * std::numbers::pi;
      break;
    case AnimatedProperty::kBaseColorFactor:
    case AnimatedProperty::kMetallicFactor:
    case AnimatedProperty::kRoughnessFactor:
    case AnimatedProperty::kOcclusionStrength:
    case AnimatedProperty::kClearcoatFactor:
    case AnimatedProperty::kClearcoatRoughnessFactor:
    case AnimatedProperty::kSheenColorFactor:
    case AnimatedProperty::kSheenRoughnessFactor:
    case AnimatedProperty::kSpecularFactor:
    case AnimatedProperty::kIridescenceFactor:
    case AnimatedProperty::kAnisotropyStrength:
    case AnimatedProperty::kTransmissionFactor:
    case AnimatedProperty::kAttenuationColor:
      hi = 1.0;  // the extensions' own ranges, as the loader reads them unanimated
      break;
    case AnimatedProperty::kIridescenceIor:
    case AnimatedProperty::kIor:
      // An animated ior stays a glass's (KHR_materials_ior's 0, "reflect all", would pass
      // through (0, 1) between keys, which no material has).
      lo = 1.0;
      break;
    case AnimatedProperty::kAttenuationDistance:
      open_lo = true;
      break;
    case AnimatedProperty::kAnisotropyRotation:
    case AnimatedProperty::kNormalScale:
    case AnimatedProperty::kUvOffset:
    case AnimatedProperty::kUvRotation:
    case AnimatedProperty::kUvScale:
      lo = -hi;  // any finite number
      break;
    default:
      break;
  }
  out.curve.values.resize(values.size() / size_t(width));
  for (size_t i = 0; i < out.curve.values.size(); ++i) {
    const float* v = &values[i * size_t(width)];
    glm::dvec4& value = out.curve.values[i];
    for (int k = 0; k < width; ++k) value[k] = v[k];
    if (per_key == 3 && i % 3 != 1) continue;
    for (int k = 0; k < width; ++k) {
      const double x = value[k];
      if (!std::isfinite(x) || (property == AnimatedProperty::kCameraYmag && x == 0.0)) {
        fail(fmt::format("{}: key {} sets the {} to {}{}", what, i / per_key, to_string(property),
                         x, std::isfinite(x) ? " (glTF forbids a view of height 0)" : ""));
      }
      if ((open_lo ? x > lo : x >= lo) && x <= hi) continue;
      const std::string problem =
          // (The key is a float: 7 digits give it back.)
          fmt::format("{}: key {} sets the {} to {:.7g}, outside {}{}, {}]", what, i / per_key,
                      to_string(property), x, open_lo ? "(" : "[", lo,
                      std::isinf(hi) ? std::string("inf") : fmt::format("{:.6g}", hi));
      // As the loader takes these factors when they are not animated: clamped where they are
      // used. What is an error there (a camera's yfov, a negative intensity, ...) is one here.
      const bool clamped = property == AnimatedProperty::kBaseColorFactor ||
                           property == AnimatedProperty::kMetallicFactor ||
                           property == AnimatedProperty::kRoughnessFactor ||
                           property == AnimatedProperty::kEmissiveFactor;
      if (!clamped) fail(problem);
      warn_once("clamped " + what, problem + ": clamped where it is used");
    }
  }
  repair_key_order(&out.curve, what);
  out.curve.validate(fmt::format("{} of {}", what, path_.string()));
  scene_.property_channels.push_back(std::move(out));
}

// ---- Scene ----

void Loader::load_scene_roots() {
  if (model_.scenes.empty()) {
    // Without scenes, every parentless node is shown.
    std::vector<char> is_child(scene_.nodes.size(), 0);
    for (const Node& node : scene_.nodes) {
      for (int child : node.children) is_child[size_t(child)] = 1;
    }
    for (size_t i = 0; i < scene_.nodes.size(); ++i) {
      if (!is_child[i]) scene_.roots.push_back(int(i));
    }
    return;
  }
  const int index = model_.defaultScene >= 0 ? model_.defaultScene : 0;
  if (size_t(index) >= model_.scenes.size()) {
    fail(
        fmt::format("default scene {} does not exist (there are {})", index, model_.scenes.size()));
  }
  const tinygltf::Scene& in = model_.scenes[size_t(index)];
  const std::string what = fmt::format("scene {}", index);
  std::vector<int> parent(scene_.nodes.size(), -1);
  for (size_t i = 0; i < scene_.nodes.size(); ++i) {
    for (int child : scene_.nodes[i].children) parent[size_t(child)] = int(i);
  }
  std::vector<char> listed(scene_.nodes.size(), 0);
  for (int root : in.nodes) {
    if (root < 0 || size_t(root) >= scene_.nodes.size()) {
      fail(fmt::format("{} refers to node {}, but there are {}", what, root, scene_.nodes.size()));
    }
    listed[size_t(root)] = 1;
  }
  // glTF requires a scene's nodes to be distinct roots, but exporters list children too
  // (UniGLTF lists its only node and not the parent it adds): a child whose ancestors are not
  // in the scene is drawn as a root, without their transforms, as viewers draw it; one under
  // a listed ancestor, or listed twice, is drawn once.
  std::vector<char> taken(scene_.nodes.size(), 0);
  for (int root : in.nodes) {
    int listed_ancestor = -1;  // (steps bounded, though load_nodes has refused cycles)
    int a = parent[size_t(root)];
    for (size_t step = 0; a >= 0 && step < parent.size(); ++step, a = parent[size_t(a)]) {
      if (listed[size_t(a)]) {
        listed_ancestor = a;
        break;
      }
    }
    if (taken[size_t(root)] || listed_ancestor >= 0) {
      warn_once("scene lists a node twice",
                fmt::format("{} lists node {} {}, which glTF forbids: it is drawn once", what, root,
                            listed_ancestor >= 0
                                ? fmt::format("and its ancestor node {}", listed_ancestor)
                                : std::string("twice")));
      continue;
    }
    taken[size_t(root)] = 1;
    if (const int p = parent[size_t(root)]; p >= 0) {
      warn_once("scene lists a child",
                fmt::format("{} lists node {}, a child of node {}, which is not in the scene; "
                            "glTF requires a scene's nodes to be roots: it is drawn as one, "
                            "without its parents' transforms",
                            what, root, p));
      std::vector<int>& siblings = scene_.nodes[size_t(p)].children;
      siblings.erase(std::find(siblings.begin(), siblings.end(), root));
    }
    scene_.roots.push_back(root);
  }
  if (in.extras.Has("afr_background")) {
    scene_.background = read_rgb_extra(in.extras, "afr_background", what);
  }
  if (in.extras.Has("afr_ambient")) {
    scene_.ambient = read_rgb_extra(in.extras, "afr_ambient", what);
  }
  // A setting of the file's rendering, not of one scene: on the root object.
  if (model_.extras.Has("afr_ray_depth")) {
    const tinygltf::Value& v = model_.extras.Get("afr_ray_depth");
    const double depth = v.IsNumber() ? v.GetNumberAsDouble() : -1.0;
    if (!(depth >= 0.0 && depth <= kMaxRayDepth && depth == std::floor(depth))) {
      fail(
          fmt::format("extras \"afr_ray_depth\" is not a whole number from 0 to {}", kMaxRayDepth));
    }
    scene_.ray_depth = int(depth);
  }
}

Scene Loader::load() { return load(read_file()); }

Scene Loader::load(std::span<const uint8_t> bytes) {
  parse(bytes);
  check_extensions();
  read_rtc_center();
  decode_meshopt();
  scene_.source = path_.string();
  load_materials();  // first: a primitive reads the texture coordinates its material's do
  read_material_variants();
  load_meshes();
  draco_bytes_.clear();
  load_cameras();
  load_lights();
  load_nodes();
  load_skins();
  drop_unused_joints();
  load_animations();
  load_scene_roots();
  try {
    scene_.finalize();
  } catch (const Error& e) {
    const std::string message = e.what();
    if (message.find(path_.string()) != std::string::npos) throw;
    fail(message);
  }
  if (scene_.triangle_count() == 0) {
    warn_once("nothing to draw",
              "the displayed scene has no triangles: its images show only the background");
  }
  add_default_lighting();
  return std::move(scene_);
}

// ---- Default lighting ----

// A scene that brings no light of its own (no KHR_lights_punctual light in the displayed
// scene and no afr_ambient) gets the default lighting of glTF viewers, so that content made
// for them does not render black: a directional headlight that moves with the active camera
// (Light::on_camera) and a sky term as the scene's ambient light. Both are ordinary scene
// content that the tracer shades like any light and ambient; Scene::nodes stay the file's.
// Emission and the background are left as they are.
void Loader::add_default_lighting() {
  for (int n : scene_.scene_nodes()) {
    if (scene_.nodes[size_t(n)].light >= 0) return;
  }
  if (scene_.ambient != glm::vec3(0.0f)) return;

  Light headlight;
  headlight.name = "afr default headlight";
  headlight.type = Light::Type::kDirectional;
  headlight.intensity = float(kHeadlightIntensity);
  headlight.on_camera = true;
  // The light shines along its -Z, away from kHeadlightFrom; the camera's up stays up.
  const glm::dvec3 from =
      glm::normalize(glm::dvec3(kHeadlightFrom[0], kHeadlightFrom[1], kHeadlightFrom[2]));
  headlight.camera_rotation = glm::quatLookAt(-from, glm::dvec3(0.0, 1.0, 0.0));
  scene_.lights.push_back(std::move(headlight));
  scene_.ambient = glm::vec3(kSkyRadiance);

  const std::string camera = scene_.camera_node() != -1
                                 ? fmt::format("camera node {}", scene_.camera_node())
                                 : std::string("the default camera");
  spdlog::info(
      "{}: the scene has no lights (no KHR_lights_punctual light, no afr_ambient): added the "
      "default lighting, a headlight on {} (intensity {}) and a sky term of {}",
      path_.string(), camera, kHeadlightIntensity, kSkyRadiance);
}

}  // namespace

Scene load_gltf(const std::filesystem::path& path, GltfLoadReport* report) {
  return Loader(path, report).load();
}

Scene load_gltf_bytes(std::span<const uint8_t> bytes, const std::filesystem::path& path,
                      GltfLoadReport* report) {
  return Loader(path, report).load(bytes);
}

void check_chosen_camera(const Scene& scene, std::string_view camera) {
  const int node = scene.camera_node();
  if (node == -1) {
    throw Error(fmt::format("{}: camera \"{}\" is on no node of the displayed scene", scene.source,
                            camera));
  }
  const std::string& name = scene.nodes[size_t(node)].name;
  spdlog::info("{}: camera \"{}\" chosen (node {}{})", scene.source, camera, node,
               name.empty() ? std::string() : fmt::format(" \"{}\"", name));
}

Scene load_scene(const std::filesystem::path& path) {
  if (path.empty()) return make_builtin_scene();
  return load_gltf(path);
}

std::optional<fs::path> file_in_gltf_folder(const fs::path& folder, const fs::path& file) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(folder / file, ec), ec);
  if (ec) return std::nullopt;
  const fs::path relative = p.lexically_relative(folder);
  if (relative.empty() || *relative.begin() == "..") return std::nullopt;
  return p;
}

std::vector<std::string> gltf_external_uris(std::string_view json_text,
                                            const std::filesystem::path& path) {
  const nlohmann::json doc = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    throw Error(fmt::format("{}: invalid glTF: not a JSON object", path.string()));
  }
  std::vector<std::string> uris;
  for (const char* array : {"buffers", "images"}) {
    const auto it = doc.find(array);
    if (it == doc.end() || !it->is_array()) continue;
    for (const nlohmann::json& item : *it) {
      if (!item.is_object() || !item.contains("uri") || !item["uri"].is_string()) continue;
      // A meshopt fallback buffer is never read (the compressed views are).
      if (std::string_view(array) == "buffers" && gltf_meshopt::used(doc) &&
          gltf_meshopt::is_fallback(item)) {
        continue;
      }
      const std::string& uri = item["uri"].get_ref<const std::string&>();
      if (uri.rfind("data:", 0) != 0) uris.push_back(uri);
    }
  }
  return uris;
}

}  // namespace afr
