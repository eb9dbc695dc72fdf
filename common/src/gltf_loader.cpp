#include <afr/common/gltf_loader.h>

#include "gltf_loader_parts.h"

#include <afr/common/builtin_scene.h>
#include <afr/common/error.h>
#include <afr/common/log.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <sodium.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "gltf_meshopt_json.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>
#include <optional>
#include <set>
#include <span>
#include <string_view>
#include <system_error>

namespace afr::gltf_detail {
namespace {

// Extensions whose content afr reads (KHR_mesh_quantization only widens the component types
// of attributes, which the accessor reader converts anyway). A file that requires any other
// extension is refused; one that only uses another is loaded with a warning naming it.
constexpr std::array<std::string_view, 25> kSupportedExtensions = {
    "CESIUM_RTC",  // drawn relative to its center (read_rtc_center)
    "EXT_mesh_gpu_instancing",
    "EXT_meshopt_compression",
    "EXT_texture_webp",
    "KHR_animation_pointer",  // the properties pointer_target names (read_animation_pointers)
    "KHR_draco_mesh_compression",
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_diffuse_transmission",
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
// headlight that moves with the scene's camera and a uniform sky. The headlight comes from
// above and to the right of the view (about 31 degrees off its axis), so faces turned toward
// the camera differ in shade and shadows fall visibly; a white Lambertian surface facing it
// reflects about 0.8 (intensity / pi, the BRDF's convention), and the sky adds 0.2 times the
// base color everywhere, so that no surface the camera sees is black. The sky is also what a
// ray that leaves the scene sees (the background), so that a mirror or glass shows the light
// that lights the rest.
constexpr double kHeadlightIntensity = 2.5;
constexpr std::array<double, 3> kHeadlightFrom = {0.35, 0.5, 1.0};  // in the camera's frame
constexpr float kSkyRadiance = 0.2f;

// ---- File access for tinygltf ----
//
// A glTF file names its buffers and images by URI. Files are untrusted, so tinygltf may read
// only regular files inside the folder of the glTF file (never "/etc/passwd" or "../../x").

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

}  // namespace

// ---- The loader ----

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
    background_given_ = true;
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
// (Light::on_camera) and a uniform sky: the scene's ambient light, and its background unless
// the file gives one (afr_background). A black background under a sky that lights everything
// else would leave polished metal black and glass showing black: the sky is what their
// reflection and refraction rays find. All of it is ordinary scene content that the tracer
// shades like any light, ambient and background; Scene::nodes stay the file's. Emission is
// left as it is.
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
  if (!background_given_) scene_.background = glm::vec3(kSkyRadiance);

  const std::string camera = scene_.camera_node() != -1
                                 ? fmt::format("camera node {}", scene_.camera_node())
                                 : std::string("the default camera");
  spdlog::info(
      "{}: the scene has no lights (no KHR_lights_punctual light, no afr_ambient): added the "
      "default lighting, a headlight on {} (intensity {}) and a sky of {} (the ambient light{})",
      path_.string(), camera, kHeadlightIntensity, kSkyRadiance,
      background_given_ ? "" : " and the background");
}

}  // namespace afr::gltf_detail

namespace afr {

using gltf_detail::Loader;
namespace fs = std::filesystem;

Scene load_gltf(const std::filesystem::path& path, GltfLoadReport* report,
                const GltfLoadOptions& options) {
  return Loader(path, report, options).load();
}

Scene load_gltf_bytes(std::span<const uint8_t> bytes, const std::filesystem::path& path,
                      GltfLoadReport* report, const GltfLoadOptions& options) {
  return Loader(path, report, options).load(bytes);
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
