// The animations the evaluation runs. An animation is any scene (a glTF file, or the built-in
// scene), a camera (the scene's own, animated or not, or a camera path file in its place) and
// the display time of its first frame; the paper's kitchen animations and the built-in
// scene's are named presets of that (docs/evaluation.md, "Animations").
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace afr::eval {

struct AnimationSpec {
  std::string name;
  std::filesystem::path scene;        // .gltf or .glb; empty: the built-in scene
  std::filesystem::path camera_path;  // empty: the scene's own camera
  double start = 0.0;                 // display time of the first frame, seconds (scene time)
};

// Where the presets find their files.
struct PresetFiles {
  std::filesystem::path kitchen;  // the BART kitchen as glTF (aff2gltf)
  std::filesystem::path paths;    // the folder of toycar.path and interactive.path
};

// bart, toycar, interactive, builtin.
std::vector<std::string> animation_preset_names();

// A preset by name. Throws afr::Error naming an unknown name and the known ones.
AnimationSpec animation_preset(std::string_view name, const PresetFiles& files);

// Any scene: named after the file's stem ("builtin" for an empty path); `camera` is "own" (the
// scene's camera) or a camera path file (common/camera_path.h).
AnimationSpec scene_animation(const std::filesystem::path& scene, std::string_view camera,
                              double start);

}  // namespace afr::eval
