#include "aff_scene.h"

namespace afr::aff {

size_t Scene::triangle_count() const {
  size_t n = 0;
  for (const Node& node : nodes) {
    for (const TriangleSet& mesh : node.meshes) n += mesh.triangle_count();
    n += node.animated_triangles.size();
  }
  return n;
}

}  // namespace afr::aff
