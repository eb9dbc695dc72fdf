#include <afr/eval/taa.h>

#include <afr/common/check.h>
#include <afr/display/fast_exp.h>
#include <afr/sampler/sampler.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

namespace afr::eval {

namespace {

double radical_inverse(int64_t i, int base) {
  double inv = 1.0 / base, f = inv, r = 0.0;
  while (i > 0) {
    r += f * double(i % base);
    i /= base;
    f *= inv;
  }
  return r;
}

// Runs f(row) for every row on `threads` threads (rows interleaved).
template <typename F>
void parallel_rows(int rows, int threads, const F& f) {
  threads = std::clamp(threads, 1, std::max(rows, 1));
  const auto work = [&](int t) {
    for (int y = t; y < rows; y += threads) f(y);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& t : pool) t.join();
}

// Catmull-Rom spline weights of the four texels around a sample at fraction f in [0, 1).
void catmull_rom_weights(float f, float w[4]) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = 0.5f * (-f3 + 2.0f * f2 - f);
  w[1] = 0.5f * (3.0f * f3 - 5.0f * f2 + 2.0f);
  w[2] = 0.5f * (-3.0f * f3 + 4.0f * f2 + f);
  w[3] = 0.5f * (f3 - f2);
}

}  // namespace

TemporalAccumulator::TemporalAccumulator(int width, int height, int grid_width, int grid_height,
                                         const TaaOptions& options)
    : width_(width),
      height_(height),
      grid_width_(grid_width),
      grid_height_(grid_height),
      options_(options),
      grid_(size_t(grid_width) * size_t(grid_height)),
      history_(width, height),
      next_(width, height),
      weight_(size_t(width) * size_t(height), 0.0f),
      next_weight_(size_t(width) * size_t(height), 0.0f) {
  AFR_CHECK(width > 0 && height > 0 && grid_width > 0 && grid_height > 0);
}

glm::dvec2 TemporalAccumulator::jitter(int64_t k) {
  const int64_t i = ((k % 16) + 16) % 16 + 1;
  return glm::dvec2(radical_inverse(i, 2), radical_inverse(i, 3));
}

const Image& TemporalAccumulator::render(Tracer& tracer, int64_t k, double time, int threads,
                                         TraceStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  tracer.set_time(time);
  const Camera camera = tracer.camera();
  const glm::dvec2 j = jitter(k);
  const double cell_x = double(width_) / grid_width_, cell_y = double(height_) / grid_height_;
  const double dt = time - previous_time_;

  // ---- Trace the jittered grid; motion of every sample back to the previous frame.
  std::vector<TraceStats> per_thread(size_t(std::max(threads, 1)));
  parallel_rows(grid_height_, threads, [&](int b) {
    TraceStats& ts = per_thread[size_t(b % std::max(threads, 1))];
    for (int a = 0; a < grid_width_; ++a) {
      GridSample& g = grid_[size_t(b) * size_t(grid_width_) + size_t(a)];
      const double px = (a + j.x) * cell_x, py = (b + j.y) * cell_y;
      const Ray ray = camera.ray(px, py, width_, height_);
      const ShadedSample s = tracer.trace(ray, &ts);
      g.color = s.color;
      g.position = glm::vec2(float(px), float(py));
      g.has_motion = false;
      if (!has_history_) continue;
      // A miss is far along its direction: from the eye, or, as a sampler places it, along
      // an orthographic camera's own ray (all of its rays share one direction).
      const glm::dvec3 p =
          s.hit ? glm::dvec3(s.position) - glm::dvec3(s.velocity) * dt
          : camera.orthographic()
              ? glm::dvec3(ray.origin) +
                    glm::dvec3(s.position) * (kOrthographicMissDistance * camera.ymag)
              : previous_camera_.eye + glm::dvec3(s.position) * 1e3;
      glm::dvec2 xy;
      if (previous_camera_.project(p, width_, height_, &xy, nullptr)) {
        g.motion = glm::vec2(float(xy.x - px), float(xy.y - py));
        g.has_motion = true;
      }
    }
  });
  for (const TraceStats& s : per_thread) *stats += s;
  const auto traced = std::chrono::steady_clock::now();
  trace_seconds_ += std::chrono::duration<double>(traced - start).count();

  // ---- Resolve every output pixel.
  const float k_near = float(0.5 / (options_.sample_sigma * options_.sample_sigma));
  const float k_wide = float(0.5 / (cell_x * cell_y));
  const float max_w = float(options_.max_history_weight);
  // The grid is regular (every sample of a grid column has the same x, of a grid row the same
  // y), so a pixel's Gaussians over its 3 x 3 grid neighbours are products of per-column and
  // per-row factors: exp(-(dx^2 + dy^2) k) = exp(-dx^2 k) exp(-dy^2 k), computed once per
  // output column and row rather than per pixel and neighbour.
  struct Axis {
    int center = 0, first = 0, last = -1;          // grid index nearest, and the neighbours used
    float d2[3] = {}, near[3] = {}, wide[3] = {};  // for grid index center - 1 + i
  };
  const auto make_axis = [&](int pixel, double cell, double jitter, int cells) {
    Axis axis;
    const float c = float(pixel) + 0.5f;
    axis.center = std::clamp(int(std::lround(c / cell - jitter)), 0, cells - 1);
    axis.first = std::max(0, axis.center - 1);
    axis.last = std::min(cells - 1, axis.center + 1);
    for (int g = axis.first; g <= axis.last; ++g) {
      const int i = g - axis.center + 1;
      const float d = float((g + jitter) * cell) - c;
      axis.d2[i] = d * d;
      axis.near[i] = fast_exp(-axis.d2[i] * k_near);
      axis.wide[i] = fast_exp(-axis.d2[i] * k_wide);
    }
    return axis;
  };
  std::vector<Axis> columns(static_cast<size_t>(width_)), rows(static_cast<size_t>(height_));
  for (int x = 0; x < width_; ++x) columns[size_t(x)] = make_axis(x, cell_x, j.x, grid_width_);
  for (int y = 0; y < height_; ++y) rows[size_t(y)] = make_axis(y, cell_y, j.y, grid_height_);
  parallel_rows(height_, threads, [&](int y) {
    const float cy = float(y) + 0.5f;
    const Axis& row = rows[size_t(y)];
    for (int x = 0; x < width_; ++x) {
      const float cx = float(x) + 0.5f;
      const Axis& column = columns[size_t(x)];
      glm::vec3 lo(1e30f), hi(-1e30f), near_sum(0.0f), wide_sum(0.0f), m1(0.0f), m2(0.0f);
      int count = 0;
      float near_w = 0.0f, wide_w = 0.0f, best_d2 = 1e30f;
      const GridSample* nearest = nullptr;
      for (int bb = row.first; bb <= row.last; ++bb) {
        const int iy = bb - row.center + 1;
        for (int aa = column.first; aa <= column.last; ++aa) {
          const int ix = aa - column.center + 1;
          const GridSample& g = grid_[size_t(bb) * size_t(grid_width_) + size_t(aa)];
          const float d2 = column.d2[ix] + row.d2[iy];
          lo = glm::min(lo, g.color);
          hi = glm::max(hi, g.color);
          m1 += g.color;
          m2 += g.color * g.color;
          ++count;
          const float wn = column.near[ix] * row.near[iy], ww = column.wide[ix] * row.wide[iy];
          near_sum += wn * g.color;
          near_w += wn;
          wide_sum += ww * g.color;
          wide_w += ww;
          if (d2 < best_d2) {
            best_d2 = d2;
            nearest = &g;
          }
        }
      }
      const size_t p = size_t(y) * size_t(width_) + size_t(x);
      const glm::vec3 upsampled = wide_w > 0.0f ? wide_sum / wide_w : nearest->color;
      // History where the nearest sample's motion says this pixel was.
      bool valid = has_history_ && nearest != nullptr && nearest->has_motion;
      glm::vec3 h(0.0f);
      float hw = 0.0f;
      if (valid) {
        const float u = cx + nearest->motion.x - 0.5f, v = cy + nearest->motion.y - 0.5f;
        if (u < -0.5f || v < -0.5f || u > float(width_) - 0.5f || v > float(height_) - 0.5f) {
          valid = false;
        } else {
          // Catmull-Rom (bicubic) for the color, which keeps detail over many reprojections
          // where bilinear would blur it a little every frame; bilinear for the weight.
          const float uc = std::clamp(u, 0.0f, float(width_ - 1));
          const float vc = std::clamp(v, 0.0f, float(height_ - 1));
          const int x0 = int(uc), y0 = int(vc);
          const float fx = uc - float(x0), fy = vc - float(y0);
          float wx[4], wy[4];
          catmull_rom_weights(fx, wx);
          catmull_rom_weights(fy, wy);
          glm::vec3 sum(0.0f);
          for (int m = 0; m < 4; ++m) {
            const int yy = std::clamp(y0 - 1 + m, 0, height_ - 1);
            for (int n = 0; n < 4; ++n) {
              const int xx = std::clamp(x0 - 1 + n, 0, width_ - 1);
              sum += (wx[n] * wy[m]) * history_.pixels[size_t(yy) * size_t(width_) + size_t(xx)];
            }
          }
          h = glm::max(sum, glm::vec3(0.0f));
          const int x1 = std::min(x0 + 1, width_ - 1), y1 = std::min(y0 + 1, height_ - 1);
          const auto at = [&](int xx, int yy) { return size_t(yy) * size_t(width_) + size_t(xx); };
          hw = (1 - fx) * (1 - fy) * weight_[at(x0, y0)] + fx * (1 - fy) * weight_[at(x1, y0)] +
               (1 - fx) * fy * weight_[at(x0, y1)] + fx * fy * weight_[at(x1, y1)];
        }
      }
      glm::vec3 out;
      float w_out;
      if (!valid) {
        out = near_w > 1e-6f ? (near_sum + float(options_.fallback_weight) * upsampled) /
                                   (near_w + float(options_.fallback_weight))
                             : upsampled;
        w_out = near_w + float(options_.fallback_weight);
      } else {
        if (options_.clamp) {
          // Variance clipping [Salvi 2016] inside the min/max box: mean +- gamma sigma.
          const glm::vec3 mean = m1 / float(count);
          const glm::vec3 sigma = glm::sqrt(glm::max(m2 / float(count) - mean * mean, 0.0f));
          const float gamma = float(options_.clamp_gamma);
          h = glm::clamp(h, glm::max(lo, mean - gamma * sigma), glm::min(hi, mean + gamma * sigma));
        }
        hw = std::min(hw, max_w);
        out = (hw * h + near_sum) / std::max(hw + near_w, 1e-12f);
        if (!(hw + near_w > 1e-12f)) out = upsampled;
        w_out = std::min(hw + near_w, max_w);
      }
      next_.pixels[p] = out;
      next_weight_[p] = w_out;
    }
  });
  std::swap(history_, next_);
  std::swap(weight_, next_weight_);
  has_history_ = true;
  previous_camera_ = camera;
  previous_time_ = time;
  resolve_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - traced).count();
  return history_;
}

}  // namespace afr::eval
