// The glTF loader's materials and textures, with the material extensions afr reads.
#include "gltf_loader_parts.h"

#include <afr/common/image.h>

#include "image_formats.h"

#include <algorithm>
#include <cstring>

namespace afr::gltf_detail {

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

// KHR_materials_diffuse_transmission: diffuseTransmissionFactor (0 to 1, default 0) and
// diffuseTransmissionColorFactor (three numbers 0 to 1, default 1), and the textures that
// multiply them (the factor's texture's alpha channel; the color's, sRGB).
void Loader::read_diffuse_transmission(size_t m, const tinygltf::Material& in,
                                       const std::string& what, Material* out) {
  std::string where;
  const tinygltf::Value* e =
      material_extension(in, "KHR_materials_diffuse_transmission", what, &where);
  if (e == nullptr) return;
  read_number(*e, "diffuseTransmissionFactor", where, unit_interval, "a number 0 to 1",
              &out->diffuse_transmission);
  read_color(*e, "diffuseTransmissionColorFactor", where, unit_interval, "three numbers 0 to 1",
             &out->diffuse_transmission_color);
  out->diffuse_transmission_texture =
      read_extension_texture(m, *e, "diffuseTransmissionTexture", where, ImageData::kAlpha,
                             &out->uv_set.diffuse_transmission);
  out->diffuse_transmission_color_texture =
      read_extension_texture(m, *e, "diffuseTransmissionColorTexture", where, ImageData::kColor,
                             &out->uv_set.diffuse_transmission_color);
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
    read_diffuse_transmission(m, in, what, &out);
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
  if (!options_.textures) {  // checked, not kept (GltfLoadOptions::textures)
    Texture white;
    white.name = image.name.empty() ? image.uri : image.name;
    white.width = white.height = 1;
    white.codes = {0xffffffffu};
    sampling.apply(&white);
    return textures_[key] = add_texture(std::move(white));
  }

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

}  // namespace afr::gltf_detail
