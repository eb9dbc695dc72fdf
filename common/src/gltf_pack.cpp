#include <afr/common/gltf_pack.h>

#include <afr/common/check.h>
#include <afr/common/error.h>
#include <afr/common/gltf_loader.h>

#include "gltf_meshopt_json.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <fstream>
#include <optional>

namespace afr {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;  // keeps the members in the order the file has them

namespace {

// What load_gltf accepts (gltf_loader.cpp), so a packed scene the samplers cannot load is
// refused where it is made.
constexpr uint64_t kMaxPackedBytes = uint64_t(1) << 31;
constexpr uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;
constexpr uint32_t kChunkBin = 0x004E4942;
// Each buffer starts on this boundary in the binary chunk, so every accessor keeps the
// alignment its component type needs (at most 4 bytes; 8 leaves room for doubles of extras).
constexpr size_t kBufferAlignment = 8;

// A glTF count (byteLength, byteOffset, an index): a non-negative integer, which a writer may
// have spelled as a float.
std::optional<uint64_t> count_of(const Json& v) {
  if (v.is_number_unsigned()) return v.get<uint64_t>();
  if (v.is_number_float()) {
    const double d = v.get<double>();
    if (d >= 0.0 && d <= 9.0e15 && d == double(uint64_t(d))) return uint64_t(d);
  }
  return std::nullopt;
}

uint32_t read_u32(std::span<const uint8_t> bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v |= uint32_t(bytes[at + i]) << (8 * i);
  return v;
}

void append_u32(std::vector<uint8_t>* out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(uint8_t(v >> (8 * i)));
}

void pad_to(std::vector<uint8_t>* v, size_t alignment, uint8_t fill = 0) {
  while (v->size() % alignment != 0) v->push_back(fill);
}

// The image type the glTF names by mimeType, told from the bytes or else the file's name.
std::string image_mime_type(std::span<const uint8_t> b, const std::string& uri) {
  const auto starts = [&](std::string_view magic, size_t at = 0) {
    return b.size() >= at + magic.size() &&
           std::memcmp(b.data() + at, magic.data(), magic.size()) == 0;
  };
  if (starts("\x89PNG")) return "image/png";
  if (starts("\xFF\xD8\xFF")) return "image/jpeg";
  if (starts("RIFF") && starts("WEBP", 8)) return "image/webp";
  if (starts("\xABKTX 20\xBB")) return "image/ktx2";
  std::string ext = fs::path(uri).extension().string();
  for (char& c : ext) c = char(std::tolower(uint8_t(c)));
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".webp") return "image/webp";
  if (ext == ".ktx2") return "image/ktx2";
  return "";
}

// The JSON chunk and the first binary chunk (empty when none) of a .glb.
void split_glb(std::span<const uint8_t> b, const fs::path& path, std::span<const uint8_t>* json,
               std::span<const uint8_t>* bin) {
  const auto fail = [&](const std::string& problem) {
    throw Error(fmt::format("{}: {}", path.string(), problem));
  };
  if (b.size() < 20 || read_u32(b, 0) != kGlbMagic) fail("invalid .glb: no header");
  if (read_u32(b, 4) != 2) fail(fmt::format("invalid .glb: version {}, not 2", read_u32(b, 4)));
  const uint64_t length = std::min<uint64_t>(read_u32(b, 8), b.size());
  uint64_t at = 12;
  bool first = true;
  while (at + 8 <= length) {
    const uint64_t size = read_u32(b, at);
    const uint32_t type = read_u32(b, at + 4);
    if (at + 8 + size > length) fail("invalid .glb: a chunk runs past the end of the file");
    const std::span<const uint8_t> data = b.subspan(at + 8, size);
    if (first && type != kChunkJson) fail("invalid .glb: the first chunk is not JSON");
    if (first) *json = data;
    if (!first && type == kChunkBin && bin->empty()) *bin = data;
    first = false;
    at += 8 + size;
  }
  if (first) fail("invalid .glb: no JSON chunk");
}

class Packer {
 public:
  explicit Packer(const fs::path& path) : path_(path) {
    std::error_code ec;
    root_ = fs::weakly_canonical(fs::absolute(path_).parent_path(), ec);
    if (ec) fail(fmt::format("cannot resolve its folder: {}", ec.message()));
  }

  PackedGltf pack(std::span<const uint8_t> bytes) {
    std::span<const uint8_t> json_text = bytes, glb_bin;
    if (is_glb(bytes)) split_glb(bytes, path_, &json_text, &glb_bin);
    Json doc = Json::parse(json_text.begin(), json_text.end(), nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded() || !doc.is_object()) fail("invalid glTF: not a JSON object");

    // Where each buffer starts in the binary chunk; a meshopt placeholder or fallback buffer
    // (which holds no data a reader that decodes needs: gltf_accessors.cpp) is not packed but kept
    // as a buffer without a uri after the binary chunk's, its index in the packed file.
    std::vector<Place> base;
    Json placeholders = Json::array();
    if (Json* buffers = array(doc, "buffers")) {
      const bool meshopt = gltf_meshopt::used(doc);
      for (size_t i = 0; i < buffers->size(); ++i) {
        Json& buffer = (*buffers)[i];
        if (meshopt && gltf_meshopt::holds_no_data(buffer, i, !glb_bin.empty())) {
          Json kept = buffer;
          kept.erase("uri");
          placeholders.push_back(std::move(kept));
          base.push_back({true, placeholders.size()});
        } else {
          base.push_back({false, add_buffer(buffer, i, glb_bin)});
        }
      }
    }
    if (Json* views = array(doc, "bufferViews")) {
      for (size_t i = 0; i < views->size(); ++i) {
        Json& view = (*views)[i];
        const std::string what = fmt::format("bufferViews[{}]", i);
        rebase(&view, base, what);
        // EXT_ and KHR_meshopt_compression's view names a buffer of its own.
        if (view.contains("extensions") && view["extensions"].is_object()) {
          for (std::string_view name : gltf_meshopt::kExtensions) {
            const std::string key(name);
            if (view["extensions"].contains(key)) {
              rebase(&view["extensions"][key], base, fmt::format("{}.extensions.{}", what, key));
            }
          }
        }
      }
    }
    if (Json* images = array(doc, "images")) {
      for (size_t i = 0; i < images->size(); ++i) add_image(&doc, (*images)[i], i);
    }
    if (!bin_.empty() || array(doc, "buffers")) {
      doc["buffers"] = Json::array({Json{{"byteLength", bin_.size()}}});
      for (Json& kept : placeholders) doc["buffers"].push_back(std::move(kept));
    }
    PackedGltf out;
    out.glb = make_glb(doc.dump(), bin_);
    if (out.glb.size() > kMaxPackedBytes) {
      fail(fmt::format("packed into one .glb it has {} bytes, more than afr loads (2 GiB)",
                       out.glb.size()));
    }
    out.packed_files = std::move(buffer_files_);
    out.packed_files.insert(out.packed_files.end(), image_files_.begin(), image_files_.end());
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& problem) const {
    throw Error(fmt::format("{}: {}", path_.string(), problem));
  }

  static Json* array(Json& doc, const char* name) {
    auto it = doc.find(name);
    return it != doc.end() && it->is_array() ? &*it : nullptr;
  }

  // The bytes of an external file named by `uri`, from inside the glTF's folder only.
  std::vector<uint8_t> read_external(const std::string& uri, const std::string& what) const {
    const std::optional<fs::path> inside = file_in_gltf_folder(root_, uri);
    if (!inside) {
      fail(
          fmt::format("{} refers to {}: not a file inside the folder of the glTF file", what, uri));
    }
    const fs::path& p = *inside;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      fail(fmt::format("{} refers to {}: no such file in the folder of the glTF file", what, uri));
    }
    const uintmax_t size = fs::file_size(p, ec);
    if (ec || size > kMaxPackedBytes) {
      fail(fmt::format("{} refers to {}: {}", what, uri,
                       ec ? ec.message() : std::string("larger than afr loads (2 GiB)")));
    }
    std::vector<uint8_t> bytes(size_t(size), 0);
    std::ifstream in(p, std::ios::binary);
    if (!in || !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size))) {
      fail(fmt::format("{} refers to {}: cannot read it", what, uri));
    }
    return bytes;
  }

  // Appends buffer i to the binary chunk; returns where it starts.
  uint64_t add_buffer(const Json& buffer, size_t i, std::span<const uint8_t> glb_bin) {
    const std::string what = fmt::format("buffers[{}]", i);
    const std::optional<uint64_t> byte_length = buffer.is_object() && buffer.contains("byteLength")
                                                    ? count_of(buffer["byteLength"])
                                                    : std::nullopt;
    if (!byte_length) fail(fmt::format("invalid glTF: {} has no byteLength", what));
    const uint64_t length = *byte_length;
    std::vector<uint8_t> owned;
    std::span<const uint8_t> data;
    if (!buffer.contains("uri")) {
      // Only a .glb's first buffer may leave out its URI: it is the binary chunk.
      if (i != 0 || glb_bin.empty()) fail(fmt::format("invalid glTF: {} has no uri", what));
      data = glb_bin;
    } else {
      if (!buffer["uri"].is_string())
        fail(fmt::format("invalid glTF: {}.uri is not a string", what));
      const std::string& uri = buffer["uri"].get_ref<const std::string&>();
      if (uri.rfind("data:", 0) == 0) {
        // tinygltf's decoder, the one the loader reads the buffer with.
        std::string mime;
        if (!tinygltf::IsDataURI(uri) || !tinygltf::DecodeDataURI(&owned, mime, uri, 0, false)) {
          fail(fmt::format("invalid glTF: {}.uri is not a base64 data: URI", what));
        }
      } else {
        owned = read_external(uri, what);
        buffer_files_.push_back(uri);
      }
      data = owned;
    }
    if (data.size() < length) {
      fail(fmt::format("{} has {} bytes, fewer than its byteLength {}", what, data.size(), length));
    }
    pad_to(&bin_, kBufferAlignment);
    const uint64_t start = bin_.size();
    if (start + length > kMaxPackedBytes) {
      fail("its buffers and images together have more than afr loads (2 GiB)");
    }
    bin_.insert(bin_.end(), data.begin(), data.begin() + ptrdiff_t(length));
    return start;
  }

  // A buffer's place in the packed file: an offset into buffer 0, or the index of a buffer
  // kept without data.
  struct Place {
    bool placeholder = false;
    uint64_t at = 0;
  };

  // A buffer view (or an extension's view) into buffer 0, at its buffer's place in it, or onto
  // its placeholder buffer as it was.
  void rebase(Json* view, const std::vector<Place>& base, const std::string& what) const {
    const std::optional<uint64_t> buffer =
        view->is_object() && view->contains("buffer") ? count_of((*view)["buffer"]) : std::nullopt;
    if (!buffer) fail(fmt::format("invalid glTF: {} has no buffer", what));
    const uint64_t b = *buffer;
    if (b >= base.size()) {
      fail(fmt::format("invalid glTF: {} refers to buffer {}, but there are {}", what, b,
                       base.size()));
    }
    uint64_t offset = 0;
    if (view->contains("byteOffset")) {
      const std::optional<uint64_t> given = count_of((*view)["byteOffset"]);
      if (!given) fail(fmt::format("invalid glTF: {}.byteOffset is not a count", what));
      offset = *given;
    }
    if (base[b].placeholder) {
      (*view)["buffer"] = base[b].at;
      return;
    }
    (*view)["buffer"] = 0;
    (*view)["byteOffset"] = base[b].at + offset;
  }

  // An external image into the binary chunk, behind a new buffer view.
  void add_image(Json* doc, Json& image, size_t i) {
    if (!image.is_object() || !image.contains("uri") || !image["uri"].is_string()) return;
    const std::string uri = image["uri"].get<std::string>();
    if (uri.rfind("data:", 0) == 0) return;  // travels inside the JSON as it is
    const std::string what = fmt::format("images[{}]", i);
    const std::vector<uint8_t> bytes = read_external(uri, what);
    std::string mime = image.contains("mimeType") && image["mimeType"].is_string()
                           ? image["mimeType"].get<std::string>()
                           : image_mime_type(bytes, uri);
    if (mime.empty()) {
      fail(fmt::format("{} refers to {}: cannot tell its type (PNG, JPEG, WebP or KTX2)", what,
                       uri));
    }
    pad_to(&bin_, 4);
    const uint64_t start = bin_.size();
    if (start + bytes.size() > kMaxPackedBytes) {
      fail("its buffers and images together have more than afr loads (2 GiB)");
    }
    bin_.insert(bin_.end(), bytes.begin(), bytes.end());
    if (!doc->contains("bufferViews") || !(*doc)["bufferViews"].is_array()) {
      (*doc)["bufferViews"] = Json::array();
    }
    Json& views = (*doc)["bufferViews"];
    views.push_back(Json{{"buffer", 0}, {"byteOffset", start}, {"byteLength", bytes.size()}});
    image.erase("uri");
    image["bufferView"] = views.size() - 1;
    image["mimeType"] = mime;
    image_files_.push_back(uri);
  }

  fs::path path_;
  fs::path root_;  // canonical folder of the glTF file
  std::vector<uint8_t> bin_;
  std::vector<std::string> buffer_files_, image_files_;
};

}  // namespace

bool is_glb(std::span<const uint8_t> bytes) {
  return bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
}

std::vector<uint8_t> make_glb(std::string_view json, std::span<const uint8_t> bin) {
  std::vector<uint8_t> json_chunk(json.begin(), json.end());
  pad_to(&json_chunk, 4, ' ');
  std::vector<uint8_t> out;
  const uint64_t total =
      12 + 8 + json_chunk.size() + (bin.empty() ? 0 : 8 + (bin.size() + 3) / 4 * 4);
  AFR_CHECK(total <= UINT32_MAX);
  out.reserve(size_t(total));
  append_u32(&out, kGlbMagic);
  append_u32(&out, 2);
  append_u32(&out, uint32_t(total));
  append_u32(&out, uint32_t(json_chunk.size()));
  append_u32(&out, kChunkJson);
  out.insert(out.end(), json_chunk.begin(), json_chunk.end());
  if (!bin.empty()) {
    append_u32(&out, uint32_t((bin.size() + 3) / 4 * 4));
    append_u32(&out, kChunkBin);
    out.insert(out.end(), bin.begin(), bin.end());
    pad_to(&out, 4);
  }
  return out;
}

PackedGltf pack_gltf(std::span<const uint8_t> bytes, const std::filesystem::path& path) {
  return Packer(path).pack(bytes);
}

std::vector<std::string> gltf_external_files(std::span<const uint8_t> bytes,
                                             const std::filesystem::path& path) {
  std::span<const uint8_t> json = bytes, bin;
  if (is_glb(bytes)) split_glb(bytes, path, &json, &bin);
  return gltf_external_uris(
      std::string_view(reinterpret_cast<const char*>(json.data()), json.size()), path);
}

std::vector<uint8_t> read_scene_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(fmt::format("{}: cannot open the scene file", path.string()));
  std::vector<uint8_t> bytes{std::istreambuf_iterator<char>(in), {}};
  if (bytes.empty()) throw Error(fmt::format("{}: the scene file is empty", path.string()));
  return bytes;
}

// The .gltf or .glb `bytes` (at `path`) with its JSON changed by edit(doc, fail), as one file of
// the same kind (a .glb keeps its binary chunk). `fail` throws afr::Error naming `path`.
template <typename Edit>
std::vector<uint8_t> edited_gltf(std::span<const uint8_t> bytes, const std::filesystem::path& path,
                                 Edit edit) {
  const auto fail = [&](const std::string& problem) {
    throw Error(fmt::format("{}: {}", path.string(), problem));
  };
  std::span<const uint8_t> json_text = bytes, bin;
  const bool glb = is_glb(bytes);
  if (glb) split_glb(bytes, path, &json_text, &bin);
  Json doc = Json::parse(json_text.begin(), json_text.end(), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) fail("invalid glTF: not a JSON object");
  edit(doc, fail);
  const std::string text = doc.dump();
  if (glb) return make_glb(text, bin);
  return std::vector<uint8_t>(text.begin(), text.end());
}

std::vector<uint8_t> select_material_variant(std::span<const uint8_t> bytes,
                                             const std::filesystem::path& path,
                                             std::string_view variant) {
  return edited_gltf(bytes, path, [&](Json& doc, const auto& fail) {
    constexpr const char* kExtension = "KHR_materials_variants";

    // The variant's index among those the file offers.
    std::vector<std::string> names;
    if (doc.contains("extensions") && doc["extensions"].is_object() &&
        doc["extensions"].contains(kExtension)) {
      const Json& list = doc["extensions"][kExtension];
      if (list.is_object() && list.contains("variants") && list["variants"].is_array()) {
        for (const Json& v : list["variants"]) {
          names.push_back(v.is_object() && v.contains("name") && v["name"].is_string()
                              ? v["name"].get<std::string>()
                              : std::string());
        }
      }
    }
    const auto found = std::find(names.begin(), names.end(), variant);
    if (found == names.end()) {
      if (names.empty())
        fail(fmt::format("no material variant \"{}\": the file has none", variant));
      std::vector<std::string> quoted;
      for (const std::string& n : names) quoted.push_back(fmt::format("\"{}\"", n));
      fail(fmt::format("no material variant \"{}\" (the file has {})", variant,
                       fmt::join(quoted, ", ")));
    }
    const uint64_t index = uint64_t(found - names.begin());

    // Each primitive's mapping for it, if any, becomes its material.
    if (doc.contains("meshes") && doc["meshes"].is_array()) {
      Json& meshes = doc["meshes"];
      for (size_t m = 0; m < meshes.size(); ++m) {
        if (!meshes[m].is_object() || !meshes[m].contains("primitives") ||
            !meshes[m]["primitives"].is_array()) {
          continue;  // the loader names what is wrong with the mesh
        }
        Json& primitives = meshes[m]["primitives"];
        for (size_t p = 0; p < primitives.size(); ++p) {
          Json& primitive = primitives[p];
          if (!primitive.is_object() || !primitive.contains("extensions") ||
              !primitive["extensions"].is_object() ||
              !primitive["extensions"].contains(kExtension)) {
            continue;
          }
          const std::string what = fmt::format("mesh {} primitive {} {}", m, p, kExtension);
          const Json& e = primitive["extensions"][kExtension];
          if (!e.is_object() || !e.contains("mappings") || !e["mappings"].is_array()) {
            fail(what + " has no \"mappings\" array");
          }
          std::optional<uint64_t> chosen;
          for (const Json& mapping : e["mappings"]) {
            const bool good = mapping.is_object() && mapping.contains("material") &&
                              count_of(mapping["material"]) && mapping.contains("variants") &&
                              mapping["variants"].is_array();
            if (!good) fail(what + " has a mapping without a material index and a variants array");
            const Json& listed = mapping["variants"];
            if (std::any_of(listed.begin(), listed.end(),
                            [&](const Json& v) { return count_of(v) == index; })) {
              chosen = count_of(mapping["material"]);
            }
          }
          // Set once the mappings are read: adding "material" may move the primitive's members
          // (an ordered JSON object is a vector), and `e` with them.
          if (chosen) primitive["material"] = *chosen;
          primitive["extensions"].erase(kExtension);
          if (primitive["extensions"].empty()) primitive.erase("extensions");
        }
      }
    }
    doc["extensions"].erase(kExtension);
    if (doc["extensions"].empty()) doc.erase("extensions");
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
      if (!doc.contains(key) || !doc[key].is_array()) continue;
      Json& list = doc[key];
      list.erase(std::remove(list.begin(), list.end(), Json(kExtension)), list.end());
      if (list.empty()) doc.erase(key);
    }
  });
}

std::vector<uint8_t> select_camera(std::span<const uint8_t> bytes,
                                   const std::filesystem::path& path, std::string_view camera) {
  return edited_gltf(bytes, path, [&](Json& doc, const auto& fail) {
    const auto name_of = [](const Json& object) {
      return object.is_object() && object.contains("name") && object["name"].is_string()
                 ? object["name"].get<std::string>()
                 : std::string();
    };
    const Json empty = Json::array();
    const Json& nodes = doc.contains("nodes") && doc["nodes"].is_array() ? doc["nodes"] : empty;
    const Json& cameras =
        doc.contains("cameras") && doc["cameras"].is_array() ? doc["cameras"] : empty;
    // The camera each node carries, if any.
    const auto camera_of = [&](size_t n) -> std::optional<uint64_t> {
      const Json& node = nodes[n];
      if (!node.is_object() || !node.contains("camera")) return std::nullopt;
      return count_of(node["camera"]);
    };
    const auto first_node_with = [&](uint64_t c) -> std::optional<size_t> {
      for (size_t n = 0; n < nodes.size(); ++n) {
        if (camera_of(n) == c) return n;
      }
      return std::nullopt;
    };

    std::optional<size_t> chosen;
    for (size_t n = 0; n < nodes.size() && !chosen; ++n) {
      if (camera_of(n) && name_of(nodes[n]) == camera) chosen = n;
    }
    std::optional<uint64_t> index;
    for (size_t c = 0; c < cameras.size() && !chosen && !index; ++c) {
      if (name_of(cameras[c]) == camera) index = c;
    }
    if (!chosen && !index && !camera.empty() &&
        std::all_of(camera.begin(), camera.end(), [](char ch) { return ch >= '0' && ch <= '9'; }) &&
        camera.size() < 10) {
      const uint64_t i = std::stoull(std::string(camera));
      if (i < cameras.size()) index = i;
    }
    if (!chosen && index) {
      chosen = first_node_with(*index);
      if (!chosen) fail(fmt::format("camera \"{}\" (cameras[{}]) is on no node", camera, *index));
    }
    if (!chosen) {
      std::vector<std::string> listed;
      for (size_t c = 0; c < cameras.size(); ++c) {
        const std::string name = name_of(cameras[c]);
        const std::optional<size_t> node = first_node_with(c);
        std::string entry = name.empty() ? fmt::format("{}", c) : fmt::format("{} \"{}\"", c, name);
        if (node && !name_of(nodes[*node]).empty()) {
          entry += fmt::format(" on node \"{}\"", name_of(nodes[*node]));
        }
        listed.push_back(std::move(entry));
      }
      if (listed.empty()) fail(fmt::format("no camera \"{}\": the file has none", camera));
      fail(fmt::format("no camera \"{}\" (the file's cameras: {})", camera,
                       fmt::join(listed, ", ")));
    }
    for (size_t n = 0; n < nodes.size(); ++n) {
      if (n != *chosen && doc["nodes"][n].is_object()) doc["nodes"][n].erase("camera");
    }
  });
}

std::vector<uint8_t> set_ray_depth(std::span<const uint8_t> bytes,
                                   const std::filesystem::path& path, int depth) {
  return edited_gltf(bytes, path, [&](Json& doc, const auto& fail) {
    if (depth < 0 || depth > kMaxRayDepth) {
      fail(fmt::format("a ray depth of {} is outside 0 to {}", depth, kMaxRayDepth));
    }
    if (doc.contains("extras") && !doc["extras"].is_object()) {
      fail("the root's extras is not an object, so afr_ray_depth cannot be added to it");
    }
    doc["extras"]["afr_ray_depth"] = depth;
  });
}

}  // namespace afr
