// Loads glTF 2.0 (.gltf with external or embedded buffers, and .glb) into the scene model.
// Unsupported features (skins, morph targets, unknown extensions, non-triangle primitives,
// orthographic cameras) are skipped with one warning each that names them; a broken file is
// an afr::Error naming the file and what is wrong.
#pragma once

#include <afr/common/scene.h>

#include <filesystem>
#include <string>
#include <vector>

namespace afr {

struct GltfLoadReport {
  std::vector<std::string> warnings;  // one per unsupported feature, already logged
};

Scene load_gltf(const std::filesystem::path& path, GltfLoadReport* report = nullptr);

// A scene from a file, or the built-in scene when `path` is empty.
Scene load_scene(const std::filesystem::path& path);

}  // namespace afr
