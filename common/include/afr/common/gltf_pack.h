// Packs a glTF scene and every file it refers to (external buffers and images) into one .glb
// held in memory, so that the scene is one payload: the display serves it to the samplers as
// one transfer, and aff2gltf writes it for `-o x.glb`. The JSON keeps everything as written
// except the references: all buffers become the one binary chunk, each external image a buffer
// view in it; a buffer that holds no data under EXT_ or KHR_meshopt_compression (a placeholder
// without a uri, or a fallback, never read) stays a buffer without a uri after it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace afr {

struct PackedGltf {
  std::vector<uint8_t> glb;
  // The URIs of the files now inside, as the glTF wrote them: buffers first, then images, each
  // in document order (gltf_external_uris' order).
  std::vector<std::string> packed_files;
};

// `bytes` is the .gltf (JSON text) or .glb at `path`. The files it names are read from the
// folder of `path`, and only from inside it, as load_gltf reads them; data: URIs of buffers
// are decoded into the binary chunk, those of images are kept. Throws afr::Error naming `path`
// and the problem: not glTF, a missing file or one outside the folder, a file shorter than
// its buffer's byteLength, an image whose type cannot be told, or a result over 2 GiB (what
// load_gltf accepts).
PackedGltf pack_gltf(std::span<const uint8_t> bytes, const std::filesystem::path& path);

// The files a .gltf or .glb refers to (gltf_external_uris of its JSON): when there are none,
// the bytes are already one payload. Throws afr::Error naming `path` when they are not glTF.
std::vector<std::string> gltf_external_files(std::span<const uint8_t> bytes,
                                             const std::filesystem::path& path);

// The bytes of the scene file at `path`. Throws afr::Error naming it when it cannot be read or
// is empty.
std::vector<uint8_t> read_scene_file(const std::filesystem::path& path);

// KHR_materials_variants: the .gltf or .glb `bytes` (at `path`, named in errors) with material
// variant `variant` chosen, as one file of the same kind: each primitive that maps a material
// to that variant takes it as its `material`, the others keep theirs, and the extension is
// removed (so the file loads anywhere as the variant, and its identity is the variant's).
// Throws afr::Error naming `path` and the problem: not glTF, no variant of that name (the
// error lists those the file offers), or a primitive's mappings that are malformed.
std::vector<uint8_t> select_material_variant(std::span<const uint8_t> bytes,
                                             const std::filesystem::path& path,
                                             std::string_view variant);

// The .gltf or .glb `bytes` (at `path`, named in errors) with camera `camera` chosen as the
// scene's camera, the one the views start from, as one file of the same kind: every other
// node loses its `camera`, so that the loader's camera node (the first in the displayed scene
// that carries one) is the chosen node. `camera` is the name of a node that carries a camera,
// the name of a camera (its first node), or an index into `cameras` (its first node). Throws
// afr::Error naming `path` and the problem: not glTF, or no such camera on any node (the error
// lists the file's cameras).
std::vector<uint8_t> select_camera(std::span<const uint8_t> bytes,
                                   const std::filesystem::path& path, std::string_view camera);

// The .gltf or .glb `bytes` (at `path`, named in errors) with its tracers' ray depth set to
// `depth` (Scene::ray_depth: the root's extras.afr_ray_depth, added or replaced), as one file of
// the same kind, so that every node that loads it traces that deep. Throws afr::Error naming
// `path` and the problem: not glTF, a depth outside 0 to kMaxRayDepth, or root extras that are
// not a JSON object.
std::vector<uint8_t> set_ray_depth(std::span<const uint8_t> bytes,
                                   const std::filesystem::path& path, int depth);

// Whether `bytes` start as a .glb does ("glTF").
bool is_glb(std::span<const uint8_t> bytes);

// A .glb of this JSON text and binary chunk (none when `bin` is empty), each chunk padded to
// 4 bytes as the format requires (the JSON with spaces, the binary with zeros).
std::vector<uint8_t> make_glb(std::string_view json, std::span<const uint8_t> bin);

}  // namespace afr
