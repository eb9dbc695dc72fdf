// A camera at one instant: eye, orthonormal basis, and a perspective lens (vertical field of
// view) or an orthographic one (the view's half height in world units).
// Image coordinates are pixels with x to the right and y down; pixel (i, j) covers
// [i, i + 1) x [j, j + 1), so its center is (i + 0.5, j + 0.5).
#pragma once

#include <afr/common/math.h>

#include <optional>

namespace afr {

struct Ray {
  glm::vec3 origin;
  glm::vec3 direction;  // unit length
  // The ray's cone (ray cones, docs/scene-model.md "Texture filtering"): its width grows by
  // `spread` per unit of distance from `cone` at the origin; a camera ray's is its pixel's (a
  // perspective camera's rays start at a point, an orthographic camera's are as wide as a
  // pixel from the start and do not spread). Both 0: a thin ray, textures read without
  // minification filtering.
  float spread = 0.0f;
  float cone = 0.0f;
};

struct Camera {
  glm::dvec3 eye{0.0};
  glm::dvec3 right{1.0, 0.0, 0.0};
  glm::dvec3 up{0.0, 1.0, 0.0};
  glm::dvec3 forward{0.0, 0.0, -1.0};
  double yfov = 0.8;  // radians, full vertical (a perspective camera)
  double znear = 0.01;
  // > 0: an orthographic camera whose view is 2 ymag high in world units (glTF's ymag; the
  // width follows from the image's aspect ratio) and yfov is unused. 0: perspective.
  double ymag = 0.0;

  bool orthographic() const { return ymag > 0.0; }

  // From a world transform whose local -Z is the view direction and +Y is up (glTF cameras).
  static Camera from_transform(const glm::dmat4& world, double yfov, double znear);
  // From eye, target and an up hint (need not be orthogonal to the view direction).
  static Camera look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up,
                        double yfov, double znear);

  // The primary ray through image position (x, y) of a width x height image: from the eye (a
  // perspective camera) or from the eye's plane along `forward` (an orthographic one).
  Ray ray(double x, double y, int width, int height) const;

  // Projects a world point to image position (x, y). Returns false when the point is behind
  // the camera or closer than znear; depth is the distance along `forward`. An orthographic
  // camera projects along `forward`, so a point's depth does not move it in the image.
  bool project(const glm::dvec3& p, int width, int height, glm::dvec2* xy, double* depth) const;
};

// Where a sampler's camera comes from when it is not the scene's own: a live view from the
// display (interaction, a replayed camera path). Called from sampler threads.
class CameraSource {
 public:
  virtual ~CameraSource() = default;
  // The camera at display time t, or nothing to use the scene's animated camera.
  virtual std::optional<Camera> camera_at(double t) const = 0;
};

}  // namespace afr
