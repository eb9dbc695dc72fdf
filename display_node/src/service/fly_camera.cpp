#include <afr/display/service/fly_camera.h>

#include <algorithm>
#include <cmath>

namespace afr::service {

namespace {

constexpr double kMaxPitch = 1.55;  // radians: just short of straight up or down

Camera oriented(const Camera& c, double yaw, double pitch) {
  const glm::dvec3 forward(-std::sin(yaw) * std::cos(pitch), std::sin(pitch),
                           -std::cos(yaw) * std::cos(pitch));
  Camera out = Camera::look_at(c.eye, c.eye + forward, glm::dvec3(0.0, 1.0, 0.0), c.yfov, c.znear);
  out.ymag = c.ymag;  // an orthographic view stays one
  return out;
}

}  // namespace

FlyCamera::FlyCamera(const Camera& start, double speed) : camera_(start), speed_(speed) {
  const glm::dvec3 f = glm::normalize(start.forward);
  pitch_ = std::clamp(std::asin(std::clamp(f.y, -1.0, 1.0)), -kMaxPitch, kMaxPitch);
  yaw_ = std::atan2(-f.x, -f.z);
  camera_ = oriented(start, yaw_, pitch_);
}

void FlyCamera::look(double dx, double dy, double radians_per_pixel) {
  if (!std::isfinite(dx) || !std::isfinite(dy)) return;
  std::lock_guard<std::mutex> lock(mutex_);
  // Dragging right turns the view right; dragging up looks up (window y grows downwards).
  yaw_ -= dx * radians_per_pixel;
  pitch_ = std::clamp(pitch_ - dy * radians_per_pixel, -kMaxPitch, kMaxPitch);
  camera_ = oriented(camera_, yaw_, pitch_);
}

void FlyCamera::move(const glm::dvec3& direction, double seconds) {
  if (!(seconds > 0.0) || !std::isfinite(seconds)) return;
  const glm::dvec3 d = glm::clamp(direction, glm::dvec3(-1.0), glm::dvec3(1.0));
  std::lock_guard<std::mutex> lock(mutex_);
  camera_.eye +=
      (d.x * camera_.right + d.y * camera_.up + d.z * camera_.forward) * (speed_ * seconds);
}

void FlyCamera::zoom(double steps) {
  if (!std::isfinite(steps)) return;
  const double factor = std::pow(kZoomStep, std::clamp(steps, -100.0, 100.0));
  std::lock_guard<std::mutex> lock(mutex_);
  if (camera_.ymag > 0.0) {
    camera_.ymag = std::clamp(camera_.ymag * factor, 1e-9, 1e12);
  } else {
    camera_.yfov = std::clamp(camera_.yfov * factor, kMinYfov, kMaxYfov);
  }
}

Camera FlyCamera::camera() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return camera_;
}

std::unique_ptr<FlyCamera> FlyCamera::framing(const Scene& scene, const Camera& start) {
  glm::dvec3 lo, hi;
  scene.bounds(scene.evaluate(0.0), &lo, &hi);
  const double size = glm::length(hi - lo);
  return std::make_unique<FlyCamera>(start, std::isfinite(size) && size > 0.0 ? 0.1 * size : 1.0);
}

}  // namespace afr::service
