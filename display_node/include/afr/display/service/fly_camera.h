// The user's camera in the display's window (docs/service.md, "Camera interaction"): the view
// the samplers trace and the display reconstructs when the user steers, from mouse drags
// (look around) and keys (move). Plain math, no windowing: the window loop feeds it input and
// the display service reads camera() from its control thread, so it is thread-safe.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/scene.h>

#include <glm/glm.hpp>

#include <memory>
#include <mutex>

namespace afr::service {

class FlyCamera {
 public:
  // Starts at `start`; moves `speed` world units per second (e.g. a tenth of the scene's size
  // per second).
  FlyCamera(const Camera& start, double speed);
  // From `start` (where the animation or path begins) at a tenth of the scene's size (its
  // bounds at time 0) per second.
  static std::unique_ptr<FlyCamera> framing(const Scene& scene, const Camera& start);

  // A mouse drag of (dx, dy) pixels: yaw about the world's up (+y) and pitch about the camera's
  // right, `radians_per_pixel` each; pitch stops short of straight up or down.
  void look(double dx, double dy, double radians_per_pixel = 0.003);
  // Moves along the camera's own axes for `seconds`: (right, up, forward) each in -1..1.
  void move(const glm::dvec3& direction, double seconds);
  // Zooms in by `steps` (out where negative), each step narrowing the view by kZoomStep: a
  // perspective view's yfov (kept within kMinYfov..kMaxYfov), an orthographic view's height
  // (ymag).
  void zoom(double steps);
  static constexpr double kZoomStep = 0.9;
  static constexpr double kMinYfov = 0.01;  // radians
  static constexpr double kMaxYfov = 3.0;

  Camera camera() const;

 private:
  mutable std::mutex mutex_;
  Camera camera_;
  double yaw_ = 0.0, pitch_ = 0.0;  // radians; yaw 0 = looking along -z
  double speed_;
};

}  // namespace afr::service
