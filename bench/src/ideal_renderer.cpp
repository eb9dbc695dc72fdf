#include <afr/bench/ideal_renderer.h>

#include <afr/common/check.h>
#include <afr/common/random.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

namespace afr {

namespace {

constexpr int kBlockRows = 16;

struct FilterSample {
  float x, y;  // image position
  glm::vec3 color;
};

}  // namespace

Image render_ideal(Tracer& tracer, const IdealRenderOptions& o, IdealRenderStats* stats) {
  AFR_CHECK(o.width > 0 && o.height > 0 && o.strata > 0 && o.filter_radius >= 0.5);
  const auto start = std::chrono::steady_clock::now();
  tracer.set_time(o.time);
  const Camera camera = tracer.camera();
  Image image(o.width, o.height);

  const int reach = int(std::ceil(o.filter_radius - 0.5));  // neighbour pixels a sample reaches
  const double edge = std::exp(-o.filter_alpha * o.filter_radius * o.filter_radius);
  const auto filter_1d = [&](double d) {
    return std::max(0.0, std::exp(-o.filter_alpha * d * d) - edge);
  };
  const int blocks = (o.height + kBlockRows - 1) / kBlockRows;
  const int threads = std::max(
      1, std::min(o.threads > 0 ? o.threads : int(std::thread::hardware_concurrency()), blocks));
  std::atomic<int> next_block{0};
  std::vector<TraceStats> thread_stats(threads);

  // Each thread takes blocks of rows. A block traces the samples of its own rows and of the
  // `reach` rows around it (their samples are seeded by pixel, so they are the same samples
  // the neighbouring block traces) and writes only its own rows: no two threads write a pixel.
  const auto work = [&](int thread) {
    TraceStats& ts = thread_stats[thread];
    std::vector<glm::dvec3> sum;
    std::vector<double> weight;
    std::vector<FilterSample> row_samples;
    for (int b = next_block++; b < blocks; b = next_block++) {
      const int y0 = b * kBlockRows, y1 = std::min(o.height, y0 + kBlockRows);
      sum.assign(size_t(y1 - y0) * o.width, glm::dvec3(0.0));
      weight.assign(size_t(y1 - y0) * o.width, 0.0);
      for (int y = std::max(0, y0 - reach); y < std::min(o.height, y1 + reach); ++y) {
        for (int x = 0; x < o.width; ++x) {
          Pcg32 rng(mix_seed(o.seed ^ mix_seed(uint64_t(y) * uint64_t(o.width) + uint64_t(x))));
          for (int sy = 0; sy < o.strata; ++sy) {
            for (int sx = 0; sx < o.strata; ++sx) {
              const double px = x + (sx + rng.next_double()) / o.strata;
              const double py = y + (sy + rng.next_double()) / o.strata;
              // Each of the S x S samples stands for 1 / S of the pixel's width: its ray cone
              // filters textures over that much (docs/scene-model.md, "Texture filtering").
              Ray ray = camera.ray(px, py, o.width, o.height);
              ray.spread /= float(o.strata);
              ray.cone /= float(o.strata);
              const ShadedSample s = tracer.trace(ray, &ts);
              // Splat into the pixels of this block within the filter radius.
              for (int qy = std::max(y0, y - reach); qy <= std::min(y1 - 1, y + reach); ++qy) {
                const double wy = filter_1d(py - (qy + 0.5));
                if (wy == 0.0) continue;
                for (int qx = std::max(0, x - reach); qx <= std::min(o.width - 1, x + reach);
                     ++qx) {
                  const double w = wy * filter_1d(px - (qx + 0.5));
                  if (w == 0.0) continue;
                  const size_t i = size_t(qy - y0) * o.width + qx;
                  sum[i] += w * glm::dvec3(s.color);
                  weight[i] += w;
                }
              }
            }
          }
        }
      }
      for (int y = y0; y < y1; ++y) {
        for (int x = 0; x < o.width; ++x) {
          const size_t i = size_t(y - y0) * o.width + x;
          // Every pixel receives its own samples, and a pixel's own samples always weigh > 0
          // for radius >= 0.5 (checked at entry), so the weight is positive.
          image.at(x, y) = weight[i] > 0.0 ? glm::vec3(sum[i] / weight[i]) : glm::vec3(0.0f);
        }
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& t : pool) t.join();

  if (stats) {
    stats->trace = TraceStats{};
    for (const TraceStats& ts : thread_stats) stats->trace += ts;
    stats->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return image;
}

}  // namespace afr
