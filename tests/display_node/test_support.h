// Shared inputs and references of the display_node tests: random sample sets, uniform
// tilings, an analytic scene (a textured floor under a sky) to sample and to render exactly,
// and 8-bit image comparison.
#pragma once

#include <afr/common/camera.h>
#include <afr/common/image.h>
#include <afr/common/random.h>
#include <afr/common/samples.h>
#include <afr/display/gl_context.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

namespace afr::test {

// n samples at uniform random positions of a width x height image, times uniform in
// [t0, t1], random colors in [0, 1]; world fields absent.
inline SampleBatch random_batch(Pcg32& rng, size_t n, int width, int height, double t0, double t1,
                                uint32_t sampler_id = 0) {
  SampleBatch b;
  b.sampler_id = sampler_id;
  b.samples.resize(n);
  for (Sample& s : b.samples) {
    s.x = rng.next_float() * float(width);
    s.y = rng.next_float() * float(height);
    s.time = t0 + (t1 - t0) * rng.next_double();
    s.color = glm::vec3(rng.next_float(), rng.next_float(), rng.next_float());
  }
  return b;
}

// One tile over the whole image.
inline TilingSnapshot uniform_tiling(int width, int height, float G_x, float G_y, float G_t,
                                     float rate, double time = 0.0, uint32_t sampler_id = 0) {
  TilingSnapshot s;
  s.sampler_id = sampler_id;
  s.time = time;
  s.region = PixelRect{0, 0, width, height};
  TileInfo t;
  t.rect = s.region;
  t.G_x = G_x;
  t.G_y = G_y;
  t.G_t = G_t;
  t.rate = rate;
  s.tiles.push_back(t);
  return s;
}

// A grid of tiles of `side` pixels with random gradients and rates in ranges that exercise
// the filter's clamps only sometimes.
inline TilingSnapshot random_tiling(Pcg32& rng, int width, int height, int side, double time) {
  TilingSnapshot s;
  s.time = time;
  s.region = PixelRect{0, 0, width, height};
  for (int y = 0; y < height; y += side) {
    for (int x = 0; x < width; x += side) {
      TileInfo t;
      t.rect = PixelRect{x, y, std::min(x + side, width), std::min(y + side, height)};
      t.G_x = 0.2f * rng.next_float();
      t.G_y = 0.2f * rng.next_float();
      t.G_t = 2.0f * rng.next_float();
      t.rate = 2.0f + 20.0f * rng.next_float();
      s.tiles.push_back(t);
    }
  }
  return s;
}

// ---- The analytic scene: the floor y = -1 with a smooth procedural color that fades to the
// horizon color with distance, moving with `velocity`, under a sky whose color depends on the
// direction only.
struct FloorScene {
  glm::dvec3 velocity{0.0};
  glm::dvec3 horizon{0.55, 0.6, 0.7};

  glm::dvec3 sky(const glm::dvec3& d) const {
    const double up = std::clamp(d.y, 0.0, 1.0);
    return horizon + (glm::dvec3(0.15, 0.25, 0.6) - horizon) * std::sqrt(up) +
           glm::dvec3(0.1, 0.0, 0.0) * std::clamp(d.x, -1.0, 1.0);
  }
  // The floor's color at world point p at time t (its texture moves with `velocity`).
  glm::dvec3 floor(const glm::dvec3& p, const glm::dvec3& eye, double t) const {
    const glm::dvec3 q = p - velocity * t;
    const glm::dvec3 albedo(0.5 + 0.35 * std::sin(0.9 * q.x) * std::cos(0.7 * q.z),
                            0.45 + 0.3 * std::cos(0.6 * q.x + 0.4 * q.z),
                            0.4 + 0.3 * std::sin(0.5 * q.z));
    const double fog = 1.0 - std::exp(-glm::length(p - eye) / 25.0);
    return albedo + (horizon - albedo) * fog;
  }
  // What a ray sees at time t: color, and the hit point or (miss) the direction.
  glm::dvec3 trace(const Ray& ray, double t, glm::dvec3* world, bool* miss) const {
    const glm::dvec3 o(ray.origin), d(ray.direction);
    if (d.y < -1e-9) {
      const double s = (-1.0 - o.y) / d.y;
      *world = o + s * d;
      *miss = false;
      return floor(*world, o, t);
    }
    *world = d;
    *miss = true;
    return sky(d);
  }
};

// n samples of the scene seen by `camera` at random image positions and times in [t0, t1].
inline SampleBatch scene_batch(const FloorScene& scene, const Camera& camera, Pcg32& rng, size_t n,
                               int width, int height, double t0, double t1, bool with_velocity) {
  SampleBatch b;
  b.fields = kFieldPosition | (with_velocity ? kFieldVelocity : 0u);
  b.samples.resize(n);
  for (Sample& s : b.samples) {
    s.x = rng.next_float() * float(width);
    s.y = rng.next_float() * float(height);
    s.time = t0 + (t1 - t0) * rng.next_double();
    glm::dvec3 world;
    bool miss;
    s.color = glm::vec3(scene.trace(camera.ray(s.x, s.y, width, height), s.time, &world, &miss));
    s.position = glm::vec3(world);
    s.miss = miss;
    if (with_velocity && !miss) s.velocity = glm::vec3(scene.velocity);
  }
  return b;
}

// The exact image of the scene at time t, k x k samples per pixel.
inline Image scene_image(const FloorScene& scene, const Camera& camera, int width, int height,
                         double t, int k = 4) {
  Image image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      glm::dvec3 sum(0.0);
      for (int j = 0; j < k; ++j) {
        for (int i = 0; i < k; ++i) {
          glm::dvec3 world;
          bool miss;
          sum += scene.trace(camera.ray(x + (i + 0.5) / k, y + (j + 0.5) / k, width, height), t,
                             &world, &miss);
        }
      }
      image.at(x, y) = glm::vec3(sum / double(k * k));
    }
  }
  return image;
}

// ---- Comparison on the 8-bit display scale.
struct Diff8 {
  double rms = 0.0;
  int max = 0;
  size_t compared = 0;
};
// Over the pixels where mask (if given) is true.
inline Diff8 diff8(const Image& a, const Image& b, const std::vector<bool>* mask = nullptr) {
  Diff8 d;
  double sum = 0.0;
  for (size_t p = 0; p < a.pixels.size(); ++p) {
    if (mask != nullptr && !(*mask)[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const int e =
          std::abs(int(linear_to_srgb8(a.pixels[p][c])) - int(linear_to_srgb8(b.pixels[p][c])));
      sum += double(e) * e;
      d.max = std::max(d.max, e);
    }
    ++d.compared;
  }
  d.rms = d.compared ? std::sqrt(sum / double(3 * d.compared)) : 0.0;
  return d;
}

inline bool all_finite(const Image& image) {
  for (const glm::vec3& c : image.pixels) {
    if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z)) return false;
  }
  return true;
}

// One headless GL context for all GL tests of the process; nullptr (with a reason) when EGL
// gives none.
inline std::shared_ptr<GlContext> shared_gl_context(std::string* why) {
  static std::string error;
  static std::shared_ptr<GlContext> context = [] {
    std::shared_ptr<GlContext> c = EglContext::create_headless(&error);
    return c;
  }();
  *why = error;
  return context;
}

}  // namespace afr::test
