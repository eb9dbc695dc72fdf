// Small scenes for the evaluation's tests.
#pragma once

#include <afr/common/image.h>
#include <afr/common/scene.h>
#include <afr/sampler/tracer.h>

namespace afr::eval::testing {

// A camera at the origin looking down -Z (60 degree yfov) at a white emissive quad on black,
// 2 m wide, sliding along +X at `speed` m/s (LINEAR, keys at t = 0 and t = 10 s) at z = -3.
inline Scene sliding_quad_scene(double speed = 1.0) {
  Scene s;
  s.source = "test";
  CameraModel lens;
  lens.yfov = glm::radians(60.0);
  s.cameras.push_back(lens);
  Node cam;
  cam.name = "camera";
  cam.camera = 0;
  s.nodes.push_back(cam);
  Material m;
  m.base_color_factor = glm::vec4(0, 0, 0, 1);
  m.metallic = 0.0f;
  m.emissive = glm::vec3(1.0f);
  s.materials.push_back(m);
  Primitive p;
  p.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  p.indices = {0, 1, 2, 0, 2, 3};
  p.material = 0;
  s.meshes.push_back(Mesh{"quad", {p}});
  Node q;
  q.name = "quad";
  q.mesh = 0;
  q.translation = glm::dvec3(-2.0, 0.0, -3.0);
  s.nodes.push_back(q);
  AnimationChannel ch;
  ch.node = 1;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 10.0};
  ch.values = {glm::dvec4(-2.0, 0.0, -3.0, 0.0), glm::dvec4(-2.0 + 10.0 * speed, 0.0, -3.0, 0.0)};
  s.channels.push_back(ch);
  s.finalize();
  return s;
}

// The reference: one ray through every pixel center at scene time t, traced with the tracer's
// plain interface (not through the evaluation's framed code).
inline Image reference_frame(Tracer& tracer, double t, int w, int h) {
  tracer.set_time(t);
  const Camera cam = tracer.camera();
  TraceStats stats;
  Image image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x)
      image.at(x, y) = tracer.trace(cam.ray(x + 0.5, y + 0.5, w, h), &stats).color;
  }
  return image;
}

}  // namespace afr::eval::testing
