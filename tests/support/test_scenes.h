// Small scenes built in code for tests of the sampler and the renderers: a camera at the origin
// looking down -Z at emissive quads one unit away (no lights, so every color is exact).
#pragma once

#include <afr/common/samples.h>
#include <afr/common/scene.h>

#include <vector>

namespace afr::testing {

inline int add_quad(Scene* s, glm::vec3 emission, glm::vec2 lo, glm::vec2 hi, float z = -1.0f) {
  Material m;
  m.base_color_factor = glm::vec4(0, 0, 0, 1);
  m.metallic = 0.0f;
  m.emissive = emission;
  s->materials.push_back(m);
  Primitive p;
  p.positions = {{lo.x, lo.y, z}, {hi.x, lo.y, z}, {hi.x, hi.y, z}, {lo.x, hi.y, z}};
  p.indices = {0, 1, 2, 0, 2, 3};
  p.material = int(s->materials.size()) - 1;
  s->meshes.push_back(Mesh{"quad", {p}});
  Node n;
  n.mesh = int(s->meshes.size()) - 1;
  s->nodes.push_back(n);
  return int(s->nodes.size()) - 1;
}

inline Scene camera_scene() {
  Scene s;
  s.source = "test";
  CameraModel lens;
  lens.yfov = glm::radians(60.0);
  s.cameras.push_back(lens);
  Node cam;
  cam.camera = 0;
  s.nodes.push_back(cam);
  return s;
}

// White on the left, black on the right: one vertical edge a little right of the center (not
// on a pixel boundary of a 64-pixel image, so no tile boundary can line up with it).
inline Scene edge_scene() {
  Scene s = camera_scene();
  add_quad(&s, glm::vec3(1.0f), {-10, -10}, {0.0123f, 10});
  s.finalize();
  return s;
}

// A grey wall with a white square sliding left and right in front of it, 2 s period.
inline Scene moving_scene() {
  Scene s = camera_scene();
  add_quad(&s, glm::vec3(0.2f), {-10, -10}, {10, 10}, -2.0f);
  const int square = add_quad(&s, glm::vec3(1.0f), {-0.1f, -0.1f}, {0.1f, 0.1f});
  AnimationChannel ch;
  ch.node = square;
  ch.path = AnimatedPath::kTranslation;
  ch.interpolation = Interpolation::kLinear;
  ch.times = {0.0, 1.0, 2.0};
  ch.values = {{-0.4, 0, 0, 0}, {0.4, 0, 0, 0}, {-0.4, 0, 0, 0}};
  s.channels.push_back(ch);
  s.finalize();
  return s;
}

struct CollectingSink : SampleSink {
  std::vector<Sample> samples;
  std::vector<SampleBatch> batches;
  std::vector<TilingSnapshot> snapshots;
  bool keep_batches = false;
  void on_batch(SampleBatch&& b) override {
    samples.insert(samples.end(), b.samples.begin(), b.samples.end());
    if (keep_batches) batches.push_back(std::move(b));
  }
  void on_tiling(TilingSnapshot&& s) override { snapshots.push_back(std::move(s)); }
};

}  // namespace afr::testing
