#include <afr/display/reprojection.h>

#include <cmath>

namespace afr {

Projector::Projector(const Camera& camera, int width, int height) {
  const double tan_half = std::tan(0.5 * camera.yfov);
  const double aspect = double(width) / double(height);
  // Camera::project: x = (sx + 1) W / 2 with sx = dot(d, right) / (z tan_half aspect).
  eye = glm::vec3(camera.eye);
  forward = glm::vec3(camera.forward);
  axis_x = glm::vec3(camera.right * (0.5 * double(width) / (tan_half * aspect)));
  axis_y = glm::vec3(camera.up * (0.5 * double(height) / tan_half));
  znear = float(camera.znear);
  half_width = 0.5f * float(width);
  half_height = 0.5f * float(height);
}

bool Projector::finish(const glm::vec3& d, float z, float* x, float* y) const {
  const float px = half_width + glm::dot(d, axis_x) / z;
  const float py = half_height - glm::dot(d, axis_y) / z;
  if (!(std::abs(px) < kMaxCoordinate) || !(std::abs(py) < kMaxCoordinate)) return false;
  *x = px;
  *y = py;
  return true;
}

bool Projector::project_point(const glm::vec3& p, float* x, float* y) const {
  const glm::vec3 d = p - eye;
  const float z = glm::dot(d, forward);
  if (!(z >= znear)) return false;
  return finish(d, z, x, y);
}

bool Projector::project_direction(const glm::vec3& d, float* x, float* y) const {
  const float z = glm::dot(d, forward);
  if (!(z > kMinDirectionZ)) return false;
  return finish(d, z, x, y);
}

bool Projector::project(const StoredSample& s, float age, float* x, float* y) const {
  if (s.flags & kStoredMiss) return project_direction(s.position, x, y);
  glm::vec3 p = s.position;
  if (s.flags & kStoredHasVelocity) p += s.velocity * age;
  return project_point(p, x, y);
}

}  // namespace afr
