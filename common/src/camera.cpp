#include <afr/common/camera.h>

#include <cmath>

namespace afr {

namespace {

// An orthonormal right/up pair for a view direction, using `up_hint` unless it is (nearly)
// parallel to the view direction.
void orthonormal_basis(const glm::dvec3& forward, const glm::dvec3& up_hint, glm::dvec3* right,
                       glm::dvec3* up) {
  glm::dvec3 r = glm::cross(forward, up_hint);
  if (glm::dot(r, r) < 1e-20) {
    const glm::dvec3 other =
        std::abs(forward.y) < 0.9 ? glm::dvec3(0.0, 1.0, 0.0) : glm::dvec3(1.0, 0.0, 0.0);
    r = glm::cross(forward, other);
  }
  *right = glm::normalize(r);
  *up = glm::cross(*right, forward);
}

}  // namespace

Camera Camera::from_transform(const glm::dmat4& world, double yfov, double znear) {
  Camera c;
  c.eye = glm::dvec3(world[3]);
  glm::dvec3 back(world[2]);
  c.forward = glm::dot(back, back) > 0.0 ? -glm::normalize(back) : glm::dvec3(0.0, 0.0, -1.0);
  orthonormal_basis(c.forward, glm::dvec3(world[1]), &c.right, &c.up);
  c.yfov = yfov;
  c.znear = znear;
  return c;
}

Camera Camera::look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up,
                       double yfov, double znear) {
  Camera c;
  c.eye = eye;
  const glm::dvec3 d = target - eye;
  c.forward = glm::dot(d, d) > 0.0 ? glm::normalize(d) : glm::dvec3(0.0, 0.0, -1.0);
  orthonormal_basis(c.forward, up, &c.right, &c.up);
  c.yfov = yfov;
  c.znear = znear;
  return c;
}

Ray Camera::ray(double x, double y, int width, int height) const {
  const double aspect = double(width) / double(height);
  if (orthographic()) {
    const double sx = (2.0 * x / width - 1.0) * ymag * aspect;
    const double sy = (1.0 - 2.0 * y / height) * ymag;
    return Ray{glm::vec3(eye + sx * right + sy * up), glm::vec3(forward), 0.0f,
               float(2.0 * ymag / height)};
  }
  const double tan_half = std::tan(0.5 * yfov);
  const double sx = (2.0 * x / width - 1.0) * tan_half * aspect;
  const double sy = (1.0 - 2.0 * y / height) * tan_half;
  const glm::dvec3 d = glm::normalize(forward + sx * right + sy * up);
  // A pixel is 2 tan(yfov / 2) / height wide on the image plane at distance 1 along forward;
  // seen along d that plane is 1 / cos away and tilted by the same angle: cos^2 of it.
  const double c = glm::dot(d, forward);
  return Ray{glm::vec3(eye), glm::vec3(d), float(2.0 * tan_half / height * c * c)};
}

bool Camera::project(const glm::dvec3& p, int width, int height, glm::dvec2* xy,
                     double* depth) const {
  const glm::dvec3 d = p - eye;
  const double z = glm::dot(d, forward);
  if (!(z >= znear)) return false;
  const double aspect = double(width) / double(height);
  // The half height of the view at p's depth: the same at every depth when orthographic.
  const double half = orthographic() ? ymag : z * std::tan(0.5 * yfov);
  const double sx = glm::dot(d, right) / (half * aspect);
  const double sy = glm::dot(d, up) / half;
  *xy = glm::dvec2((sx + 1.0) * 0.5 * width, (1.0 - sy) * 0.5 * height);
  if (depth) *depth = z;
  return true;
}

}  // namespace afr
