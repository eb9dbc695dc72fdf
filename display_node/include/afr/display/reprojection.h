// Section 6.2: reprojection of stored samples into the current view. Each sample's world hit
// point (moved by its velocity over its age, when it has one) or, for a miss, its ray
// direction is projected with the current camera. Float arithmetic, the same operations as
// the OpenGL backend's vertex shader.
#pragma once

#include <afr/common/camera.h>
#include <afr/display/sample_store.h>

#include <cmath>

namespace afr {

class Projector {
 public:
  // The camera's image is width x height pixels (the whole sampling image at the output
  // scale); positions come out relative to its pixel (origin_x, origin_y), where the
  // reconstructed pixels (a viewport and its margin) start.
  Projector(const Camera& camera, double width, double height, double origin_x = 0.0,
            double origin_y = 0.0);

  // The image position of a world point (hit) or of a direction (miss). False when the point
  // is behind the camera or nearer than znear, the direction points away from the view, or
  // the result is not finite.
  bool project_point(const glm::vec3& p, float* x, float* y) const {
    const glm::vec3 d = p - eye;
    const float z = glm::dot(d, forward);
    if (!(z >= znear)) return false;
    return finish(d, z, x, y);
  }
  bool project_direction(const glm::vec3& d, float* x, float* y) const {
    const float z = glm::dot(d, forward);
    if (!(z > kMinDirectionZ)) return false;
    return finish(d, z, x, y);
  }
  // A stored sample at `age` seconds (signed: now - sample time); uses velocity when present.
  // The caller checks kStoredHasPosition.
  bool project(const StoredSample& s, float age, float* x, float* y) const {
    if (s.flags & kStoredMiss) return project_direction(s.position, x, y);
    glm::vec3 p = s.position;
    if (s.flags & kStoredHasVelocity) p += s.velocity * age;
    return project_point(p, x, y);
  }

  // The projection, as uniforms for a shader: with d = p - eye (or the direction),
  //   z = dot(d, forward), x = half_width + dot(d, axis_x) / z, y = half_height - dot(d, axis_y) /
  //   z.
  glm::vec3 eye{0.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};
  glm::vec3 axis_x{1.0f, 0.0f, 0.0f};
  glm::vec3 axis_y{0.0f, 1.0f, 0.0f};
  float znear = 0.01f;
  float half_width = 0.0f;
  float half_height = 0.0f;

  // A direction counts as in front when dot(d, forward) exceeds this.
  static constexpr float kMinDirectionZ = 1e-6f;
  // Projections beyond this many pixels are treated as off-screen (not finite in practice).
  static constexpr float kMaxCoordinate = 1e7f;

 private:
  bool finish(const glm::vec3& d, float z, float* x, float* y) const {
    const float px = half_width + glm::dot(d, axis_x) / z;
    const float py = half_height - glm::dot(d, axis_y) / z;
    if (!(std::abs(px) < kMaxCoordinate) || !(std::abs(py) < kMaxCoordinate)) return false;
    *x = px;
    *y = py;
    return true;
  }
};

}  // namespace afr
