// The math types of afr: GLM, with the extensions the project uses. Absolute positions and
// times that must stay exact over long runs are double (dvec3, dmat4); per-sample data that
// crosses the network or fills buffers is float.
#pragma once

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

namespace afr {

// Rec. 709 luminance of a linear RGB color.
inline float luminance(const glm::vec3& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; }

// T * R * S, the transform order of glTF nodes (and of AFF transforms).
inline glm::dmat4 compose_trs(const glm::dvec3& t, const glm::dquat& r, const glm::dvec3& s) {
  glm::dmat4 m = glm::mat4_cast(r);
  m[0] *= s.x;
  m[1] *= s.y;
  m[2] *= s.z;
  m[3] = glm::dvec4(t, 1.0);
  return m;
}

}  // namespace afr
