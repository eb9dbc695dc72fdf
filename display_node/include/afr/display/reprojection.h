// Section 6.2: reprojection of stored samples into the current view. Each sample's world hit
// point (moved by its velocity over its age, when it has one) or, for a miss, its ray
// direction is projected with the current camera. Float arithmetic, the same operations as
// the OpenGL backend's vertex shader.
#pragma once

#include <afr/common/camera.h>
#include <afr/display/sample_store.h>

#include <cmath>

namespace afr {

// Image positions are rounded to 1/256 pixel (kPositionStep) in the whole image's coordinates
// before the grid's origin is subtracted: the result is then exact in float, so a viewport's
// reconstructor (a display wall node) places a sample at exactly the whole image's position
// minus a whole number of pixels, and computes bit for bit the weights a reconstruction of the
// whole image does there (docs/reconstruction.md, "Viewports"). Beyond 2^14 pixels a float
// has at most 1/512 pixel to round to and the value is kept.
inline constexpr float kPositionStep = 1.0f / 256.0f;
inline float quantize_position(float v) {
  if (!(std::abs(v) < 16384.0f)) return v;
  // Round to nearest (even) at 2^-8 without a libm call: 1.5 * 2^23 leaves no fraction bits.
  // (Exact IEEE arithmetic: nothing here may be built with -ffast-math.)
  const float t = v * 256.0f;
  return ((t + 12582912.0f) - 12582912.0f) * kPositionStep;
}

class Projector {
 public:
  // The camera's image is width x height pixels (the whole sampling image at the output
  // scale); positions come out relative to its pixel (origin_x, origin_y), where the
  // reconstructed pixels (a viewport and its margin) start.
  Projector(const Camera& camera, double width, double height, double origin_x = 0.0,
            double origin_y = 0.0);

  // The image position of a world point (hit) or of a direction (miss). False when the point
  // is behind the camera or nearer than znear, the direction points away from the view or the
  // view is orthographic (its samplers send misses as points: Sampler::place_miss), or the
  // result is not finite.
  bool project_point(const glm::vec3& p, float* x, float* y) const {
    const glm::vec3 d = p - eye;
    const float z = glm::dot(d, forward);
    if (!(z >= znear)) return false;
    return finish(d, z, x, y);
  }
  bool project_direction(const glm::vec3& d, float* x, float* y) const {
    const float z = glm::dot(d, forward);
    if (!(z > kMinDirectionZ) || orthographic) return false;
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
  //   z = dot(d, forward), w = orthographic ? 1 : z, x = q(half_width + dot(d, axis_x) / w) -
  //   origin_x, y = q(half_height - dot(d, axis_y) / w) - origin_y, q = quantize_position.
  glm::vec3 eye{0.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};
  glm::vec3 axis_x{1.0f, 0.0f, 0.0f};
  glm::vec3 axis_y{0.0f, 1.0f, 0.0f};
  float znear = 0.01f;
  bool orthographic = false;
  float half_width = 0.0f;  // the whole image's center
  float half_height = 0.0f;
  float origin_x = 0.0f;  // the grid's first pixel in the whole image
  float origin_y = 0.0f;

  // A direction counts as in front when dot(d, forward) exceeds this.
  static constexpr float kMinDirectionZ = 1e-6f;
  // Projections beyond this many pixels are treated as off-screen (not finite in practice).
  static constexpr float kMaxCoordinate = 1e7f;

 private:
  bool finish(const glm::vec3& d, float z, float* x, float* y) const {
    const float w = orthographic ? 1.0f : z;
    const float px = half_width + glm::dot(d, axis_x) / w;
    const float py = half_height - glm::dot(d, axis_y) / w;
    if (!(std::abs(px) < kMaxCoordinate) || !(std::abs(py) < kMaxCoordinate)) return false;
    *x = quantize_position(px) - origin_x;
    *y = quantize_position(py) - origin_y;
    return true;
  }
};

}  // namespace afr
