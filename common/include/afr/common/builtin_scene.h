// The built-in scene, generated in code and used whenever no scene file is given: a room with
// a textured floor, a mirror sphere and a glossy box (view-dependent highlights), a ball that
// bounces and a cube that slides behind a pillar (motion, occlusion and disocclusion), and a
// camera that circles and dollies, all on a 10 s loop.
#pragma once

#include <afr/common/scene.h>

namespace afr {

inline constexpr double kBuiltinSceneLoopSeconds = 10.0;

Scene make_builtin_scene();

}  // namespace afr
