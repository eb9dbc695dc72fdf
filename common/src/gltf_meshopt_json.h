// What a glTF document's JSON says about EXT_ and KHR_meshopt_compression (one bitstream under
// two names), for the loader, which decodes it, and the packer, which keeps its placeholder
// buffers without data. Json: nlohmann::json or nlohmann::ordered_json.
#pragma once

#include <array>
#include <string>
#include <string_view>

namespace afr::gltf_meshopt {

inline constexpr std::array<std::string_view, 2> kExtensions = {"KHR_meshopt_compression",
                                                                "EXT_meshopt_compression"};

// Whether extensionsUsed or extensionsRequired names either extension.
template <typename Json>
bool used(const Json& doc) {
  for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
    const auto list = doc.find(key);
    if (list == doc.end() || !list->is_array()) continue;
    for (const Json& name : *list) {
      if (!name.is_string()) continue;
      for (std::string_view ext : kExtensions) {
        if (name.template get<std::string>() == ext) return true;
      }
    }
  }
  return false;
}

// Whether a buffer is marked as a fallback ({"extensions": {"EXT_meshopt_compression":
// {"fallback": true}}}): only compressed views read it, and a reader that decodes them need not
// load it.
template <typename Json>
bool is_fallback(const Json& buffer) {
  const auto e = buffer.find("extensions");
  if (e == buffer.end() || !e->is_object()) return false;
  for (std::string_view ext : kExtensions) {
    const auto m = e->find(std::string(ext));
    if (m != e->end() && m->is_object() && m->contains("fallback") && (*m)["fallback"] == true) {
      return true;
    }
  }
  return false;
}

// Whether buffer `index` holds no data under the extension: a placeholder without a uri (but
// not a .glb's first buffer, its binary chunk) or a fallback. Only where the file uses it.
template <typename Json>
bool holds_no_data(const Json& buffer, size_t index, bool glb_with_bin) {
  if (!buffer.is_object()) return false;
  const bool bin_chunk = index == 0 && glb_with_bin && !buffer.contains("uri");
  return (!buffer.contains("uri") && !bin_chunk) || is_fallback(buffer);
}

}  // namespace afr::gltf_meshopt
