// The built-in scene, generated in code and used whenever no scene file is given: a room with
// a textured floor, a mirror sphere and a glossy box (view-dependent highlights), a ball that
// bounces and a cube that slides behind a pillar (motion, occlusion and disocclusion), and a
// camera that circles and dollies, all on a 10 s loop.
#pragma once

#include <afr/common/scene.h>

#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace afr {

inline constexpr double kBuiltinSceneLoopSeconds = 10.0;

Scene make_builtin_scene();

// The built-in scene as display_node serves it to the samplers in place of a file's bytes
// (docs/service.md, "Scenes"): the line "afr builtin scene v1", and where the display sets the
// tracers' ray depth (Scene::ray_depth, 0 to kMaxRayDepth) a second line "ray depth N". Both
// nodes build the scene from it alike.
std::string builtin_scene_payload(std::optional<int> ray_depth = std::nullopt);
// Whether `bytes` name the built-in scene (start with the payload's first line).
bool is_builtin_scene_payload(std::span<const uint8_t> bytes);
// The built-in scene such a payload names, with its ray depth. Throws afr::Error naming what is
// wrong with a payload that starts as one but says anything else.
Scene builtin_scene_from_payload(std::span<const uint8_t> bytes);

}  // namespace afr
