#include <afr/display/reprojection.h>

#include <cmath>

namespace afr {

Projector::Projector(const Camera& camera, double width, double height, double grid_x,
                     double grid_y) {
  // The view's half height at depth 1 (perspective) or at every depth (orthographic).
  const double half = camera.orthographic() ? camera.ymag : std::tan(0.5 * camera.yfov);
  const double aspect = width / height;
  // Camera::project: x = (sx + 1) W / 2 with sx = dot(d, right) / (z tan_half aspect), or
  // dot(d, right) / (ymag aspect) when orthographic.
  eye = glm::vec3(camera.eye);
  forward = glm::vec3(camera.forward);
  axis_x = glm::vec3(camera.right * (0.5 * width / (half * aspect)));
  axis_y = glm::vec3(camera.up * (0.5 * height / half));
  znear = float(camera.znear);
  orthographic = camera.orthographic();
  // Positions are computed in the whole image and rounded (quantize_position) before the
  // origin is subtracted, so that every grid gets the same positions up to whole pixels.
  half_width = float(0.5 * width);
  half_height = float(0.5 * height);
  origin_x = float(grid_x);
  origin_y = float(grid_y);
}

}  // namespace afr
