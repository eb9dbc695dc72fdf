// Preparing the scenes of the evaluation: a camera path in place of a scene's own camera (the
// toycar close-up and the recorded interaction), and a hash of everything in a scene that
// changes its pictures, which keys the cache of ideal frames.
#pragma once

#include <afr/common/camera_path.h>
#include <afr/common/scene.h>

#include <cstdint>

namespace afr::eval {

// Makes `path` the scene's active camera: a new root camera node, first in scene order, moved
// by LINEAR translation and rotation channels through the path's keys (which is exactly how
// CameraPath interpolates). The scene model cannot animate a field of view, so the path's
// yfov must be the same at every key; otherwise throws afr::Error. Calls scene->finalize().
void apply_camera_path(const CameraPath& path, Scene* scene);

// A 64-bit hash (FNV-1a) of what the scene renders: its geometry, materials, textures,
// lights, cameras, node graph, animation and background; two scenes with the same fingerprint
// render the same images. Names and the source file name are left out. (Not the service's
// protocol::scene_hash, which identifies a scene file's bytes.)
uint64_t render_fingerprint(const Scene& scene);

}  // namespace afr::eval
