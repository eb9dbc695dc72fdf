// Loads glTF 2.0 (.gltf with external or embedded buffers, and .glb) into the scene model.
// Unsupported features (unknown extensions the file does not require, non-triangle primitives,
// ...: docs/scene-model.md) are skipped with one warning each that names them; a broken file,
// or one that requires an extension afr lacks, is an afr::Error naming the file and what is
// wrong. A scene without lights gets the default lighting (docs/scene-model.md), said in one
// info line.
#pragma once

#include <afr/common/scene.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace afr {

struct GltfLoadReport {
  std::vector<std::string> warnings;  // one per unsupported feature, already logged
};

// What a scene is loaded for.
struct GltfLoadOptions {
  // The materials' texture images, decoded and kept: what shading reads. Without them each
  // image is still decoded, one at a time, so that broken image data is the same error, but its
  // texture keeps one white texel: for a display node, which reconstructs, never shades, and
  // would otherwise hold every texture of the scene (4 bytes a texel and mip levels) for nothing.
  bool textures = true;
};

Scene load_gltf(const std::filesystem::path& path, GltfLoadReport* report = nullptr,
                const GltfLoadOptions& options = {});
// The same for the bytes of a .gltf or .glb held in memory, with every check of a file: `path`
// names it in errors, and its folder is where external buffers and images are looked for.
Scene load_gltf_bytes(std::span<const uint8_t> bytes, const std::filesystem::path& path,
                      GltfLoadReport* report = nullptr, const GltfLoadOptions& options = {});

// After select_camera (gltf_pack.h): logs which node views from the chosen `camera`, or throws
// afr::Error naming the scene's file when that node is not in the displayed scene (which then
// has no camera node).
void check_chosen_camera(const Scene& scene, std::string_view camera);

// A scene from a file, or the built-in scene when `path` is empty.
Scene load_scene(const std::filesystem::path& path);

// The files a .gltf (JSON text) refers to: the URIs of its buffers and images that are not
// data: URIs, buffers first, each in document order. Throws afr::Error ("PATH: invalid glTF:
// ...", as load_gltf words it) when the text is not a JSON object.
std::vector<std::string> gltf_external_uris(std::string_view json_text,
                                            const std::filesystem::path& path);

// The rule for a glTF's external files, which are untrusted names: `file` resolved (symbolic
// links and "..") lies inside `folder` (canonical), never "/etc/passwd" or "../../x". The
// resolved path, or nothing. The loader reads and the packer (gltf_pack.h) packs by it.
std::optional<std::filesystem::path> file_in_gltf_folder(const std::filesystem::path& folder,
                                                         const std::filesystem::path& file);

}  // namespace afr
