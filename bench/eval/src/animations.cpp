#include <afr/eval/animations.h>

#include <afr/common/error.h>

#include <fmt/format.h>

namespace afr::eval {

std::vector<std::string> animation_preset_names() {
  return {"bart", "toycar", "interactive", "builtin"};
}

AnimationSpec animation_preset(std::string_view name, const PresetFiles& files) {
  // docs/evaluation.md, "Animations", says why these views and windows.
  AnimationSpec spec;
  if (name == "bart") {
    spec = scene_animation(files.kitchen, "own", 8.5);
  } else if (name == "toycar") {
    spec = scene_animation(files.kitchen, (files.paths / "toycar.path").string(), 11.0);
  } else if (name == "interactive") {
    spec = scene_animation(files.kitchen, (files.paths / "interactive.path").string(), 1.0);
  } else if (name == "builtin") {
    spec = scene_animation("", "own", 2.0);
  } else {
    std::string names;
    for (const std::string& n : animation_preset_names()) names += (names.empty() ? "" : ", ") + n;
    throw Error(
        fmt::format("unknown animation '{}' (expected one of {}, or --scene FILE)", name, names));
  }
  spec.name = std::string(name);
  return spec;
}

AnimationSpec scene_animation(const std::filesystem::path& scene, std::string_view camera,
                              double start) {
  if (camera.empty()) throw Error("camera: expected 'own' or a camera path file");
  AnimationSpec spec;
  spec.scene = scene;
  spec.name = scene.empty() ? std::string("builtin") : scene.stem().string();
  if (camera != "own") spec.camera_path = std::filesystem::path(camera);
  spec.start = start;
  return spec;
}

}  // namespace afr::eval
