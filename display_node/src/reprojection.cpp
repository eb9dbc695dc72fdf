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

}  // namespace afr
