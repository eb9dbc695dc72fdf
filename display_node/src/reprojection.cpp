#include <afr/display/reprojection.h>

#include <cmath>

namespace afr {

Projector::Projector(const Camera& camera, double width, double height, double origin_x,
                     double origin_y) {
  const double tan_half = std::tan(0.5 * camera.yfov);
  const double aspect = width / height;
  // Camera::project: x = (sx + 1) W / 2 with sx = dot(d, right) / (z tan_half aspect).
  eye = glm::vec3(camera.eye);
  forward = glm::vec3(camera.forward);
  axis_x = glm::vec3(camera.right * (0.5 * width / (tan_half * aspect)));
  axis_y = glm::vec3(camera.up * (0.5 * height / tan_half));
  znear = float(camera.znear);
  // The image's center relative to the origin, in double: exact for whole pixels, and the
  // float projection then works with numbers of the size of the grid, not of the image.
  half_width = float(0.5 * width - origin_x);
  half_height = float(0.5 * height - origin_y);
}

}  // namespace afr
