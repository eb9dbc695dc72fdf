#include <afr/display/cpu_reconstructor.h>

#include <afr/display/fast_exp.h>
#include <afr/display/hole_fill.h>
#include <afr/display/reprojection.h>

#include "thread_pool.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <array>
#include <cmath>
#include <limits>
#include <thread>

namespace afr {

namespace {

// One sample ready to splat, in output pixels. x0 > x1 marks a sample that reaches nothing.
struct Splat {
  float x = 0.0f, y = 0.0f;
  float k_x = 0.0f, k_y = 0.0f;      // 1 / (2 sigma^2)
  float off_x = 0.0f, off_y = 0.0f;  // the Gaussian's value at the splat's edge
  float r = 0.0f;                    // splat size (coverage map), >= the extents below
  float w_t = 0.0f;                  // temporal weight
  glm::vec3 color{0.0f};
  int16_t x0 = 1, x1 = 0, y0 = 1, y1 = 0;  // inclusive pixel ranges (sides <= 16384)
};
static_assert(sizeof(Splat) == 52);

// Per-chunk counts of what happened to samples (summed after the phase).
struct SampleCounts {
  uint64_t splatted = 0, behind = 0, off_screen = 0, future = 0;
};

// The splat of a sample landing in a pixel: its Gaussian (grown by the coverage map) and size.
struct PixelShape {
  float sigma_x = 1.0f, sigma_y = 1.0f;  // output pixels
  float k_t = 0.0f;                      // 1 / (2 e_t^2)
  float r = 1.0f;                        // splat size
};

struct PixelCounts {
  uint64_t holes = 0, empty = 0, nonfinite = 0;
};

// floor and ceil to int without a libm call (the baseline x86-64 target has no roundss);
// |v| < 2^31.
inline int floor_int(float v) {
  const int i = int(v);
  return i - (v < float(i));
}
inline int ceil_int(float v) {
  const int i = int(v);
  return i + (v > float(i));
}

int default_threads(int requested) {
  if (requested > 0) return std::min(requested, 256);
  return std::clamp(int(std::thread::hardware_concurrency()), 1, 256);
}

}  // namespace

struct CpuReconstructor::Impl {
  explicit Impl(int threads, size_t capacity) : pool(threads) { mirror.resize(capacity); }

  ThreadPool pool;
  // The reconstructor's copy of the store's ring, slot for slot.
  std::vector<StoredSample> mirror;
  std::vector<StoredSample> staging;
  uint64_t seen = 0;
  size_t stored = 0;

  // Splatting.
  std::vector<PixelShape> shapes;           // per pixel
  std::vector<Splat> splats;                // one per stored sample
  std::vector<uint32_t> counts;             // [chunk * bands + band]
  std::vector<size_t> cursor;               // [chunk * bands + band], then write positions
  std::vector<size_t> band_start;           // bands + 1
  // Splats copied band by band (one reaching two bands is in both), so each band's thread
  // reads its splats in one sequential sweep instead of gathering them from all over.
  std::vector<Splat> binned;
  std::vector<SampleCounts> chunk_counts;   // per chunk
  std::vector<glm::vec4> accum;             // (sum w c, sum w) per pixel
  std::vector<CoverageCell> coverage_next;  // this image's coverage
  CoverageMap previous;                     // the previous image's
  HolePyramid pyramid;
  std::vector<PixelCounts> row_counts;  // per normalise task
  // Traditional frameless.
  std::vector<double> newest_age;

  void sync(const SampleStore& store, SampleStore::Delta* delta) {
    *delta = store.copy_since(seen, &staging);
    RingRun runs[2];
    const int k = ring_runs(delta->first, delta->end, mirror.size(), runs);
    for (int r = 0; r < k; ++r) {
      std::copy_n(staging.begin() + ptrdiff_t(runs[r].offset), runs[r].count,
                  mirror.begin() + ptrdiff_t(runs[r].slot));
    }
    seen = delta->end;
    stored = delta->stored;
  }
};

CpuReconstructor::CpuReconstructor(const ReconstructorConfig& config)
    : Reconstructor(config),
      impl_(std::make_unique<Impl>(default_threads(config.threads), store_.capacity())) {}

CpuReconstructor::~CpuReconstructor() = default;

int CpuReconstructor::threads() const { return impl_->pool.size(); }

void CpuReconstructor::read_weights(std::vector<float>* out) {
  out->resize(impl_->accum.size());
  for (size_t i = 0; i < impl_->accum.size(); ++i) (*out)[i] = impl_->accum[i].w;
}

void CpuReconstructor::read_coverage(std::vector<CoverageCell>* out) {
  *out = impl_->previous.cells();
}

void CpuReconstructor::do_reconstruct(const Camera& camera, double time, int width, int height,
                                      Image* out) {
  Impl& m = *impl_;
  auto T0 = std::chrono::steady_clock::now();
  auto lap = [&](const char* what) { auto t = std::chrono::steady_clock::now(); fprintf(stderr, "%s %.2f  ", what, std::chrono::duration<double, std::milli>(t - T0).count()); T0 = t; };
  SampleStore::Delta delta;
  m.sync(store_, &delta);
  lap("sync");
  FrameSetup setup;
  prepare_frame(time, width, height, delta, &setup);

  const size_t pixels = size_t(width) * size_t(height);
  if (m.previous.width() != width || m.previous.height() != height) {
    m.previous.reset(width, height);
  }
  m.accum.resize(pixels);
  m.coverage_next.resize(pixels);
  const ReconstructionMode current_mode = mode();
  const FilterLimits& limits = config_.filter;
  const SplatSizeRule& rule = config_.splat;
  const int threads = m.pool.size();
  const size_t n = m.stored;

  if (current_mode == ReconstructionMode::kTraditionalFrameless) {
    // [BFMS94]: the newest sample at each pixel, at its original position.
    m.newest_age.assign(pixels, std::numeric_limits<double>::infinity());
    std::fill(m.accum.begin(), m.accum.end(), glm::vec4(0.0f));
    SampleCounts c;
    for (size_t i = 0; i < n; ++i) {
      const StoredSample& s = m.mirror[i];
      const double age = time - s.time;
      if (age < -double(limits.max_future)) {
        ++c.future;
        continue;
      }
      const float x = s.x * setup.scale_x, y = s.y * setup.scale_y;
      if (!(x >= 0.0f && x < float(width) && y >= 0.0f && y < float(height))) {
        ++c.off_screen;
        continue;
      }
      const size_t p = size_t(int(y)) * size_t(width) + size_t(int(x));
      ++c.splatted;
      const double a = std::max(age, 0.0);
      if (a < m.newest_age[p]) {
        m.newest_age[p] = a;
        m.accum[p] = glm::vec4(s.color, 1.0f);
      }
    }
    frame_.splatted = c.splatted;
    frame_.off_screen = c.off_screen;
    frame_.future = c.future;
    m.previous.reset(width, height);  // no splat sizes to remember
    std::fill(m.coverage_next.begin(), m.coverage_next.end(), CoverageCell{});
  } else {
    lap("prep");
    // ---- Phase 1: samples to splats (parallel over chunks of the ring), counted per band.
    const bool reproject = current_mode == ReconstructionMode::kAdaptive;
    const Projector projector(camera, width, height);
    const int band_height = std::max(8, (height + threads * 8 - 1) / (threads * 8));
    const int bands = (height + band_height - 1) / band_height;
    const int chunks = int(std::clamp<size_t>(n / 4096, 1, size_t(threads) * 4));
    m.splats.resize(std::max<size_t>(n, 1));
    m.counts.assign(size_t(chunks) * size_t(bands), 0u);
    m.cursor.resize(m.counts.size());
    m.chunk_counts.assign(size_t(chunks), SampleCounts{});
    const float guard = rule.max_radius + 1.0f;
    const float min_wt = limits.min_temporal_weight, cutoff = limits.cutoff;

    // ---- Per pixel, what a splat landing there gets: its tile's filter and (section 6.2)
    // the splat size from the previous image's coverage there. One lookup per sample then.
    m.shapes.resize(pixels);
    const std::vector<uint32_t>& index_map = field_.index_map();
    const int shape_tasks = std::min(height, threads * 4);
    m.pool.run(shape_tasks, [&](int task) {
      const size_t p0 = pixels * size_t(task) / size_t(shape_tasks);
      const size_t p1 = pixels * size_t(task + 1) / size_t(shape_tasks);
      const CoverageCell* previous = m.previous.valid() ? m.previous.cells().data() : nullptr;
      for (size_t p = p0; p < p1; ++p) {
        const TileFilter& f = setup.filters[index_map[p]];
        const float r_filter = cutoff * std::max(f.sigma_x, f.sigma_y);
        const float r = splat_radius(previous != nullptr ? previous + p : nullptr, r_filter, rule);
        // A splat the coverage map grew beyond the filter's radius widens its Gaussian by the
        // same factor (keeping its shape); a shrunk one cuts the Gaussian short.
        const float grown = std::max(1.0f, r / r_filter);
        m.shapes[p] = PixelShape{f.sigma_x * grown, f.sigma_y * grown, f.k_t, r};
      }
    });

    lap("shapes");
    m.pool.run(chunks, [&](int chunk) {
      const size_t begin = n * size_t(chunk) / size_t(chunks);
      const size_t end = n * size_t(chunk + 1) / size_t(chunks);
      SampleCounts c;
      uint32_t* counts = m.counts.data() + size_t(chunk) * size_t(bands);
      for (size_t i = begin; i < end; ++i) {
        Splat& sp = m.splats[i];
        sp.x0 = 1;
        sp.x1 = 0;
        const StoredSample& s = m.mirror[i];
        const double age_d = time - s.time;
        if (age_d < -double(limits.max_future)) {
          ++c.future;
          continue;
        }
        const float age_signed = float(age_d);
        const float age = std::max(age_signed, 0.0f);
        float x, y;
        if (reproject && (s.flags & kStoredHasPosition)) {
          if (!projector.project(s, age_signed, &x, &y)) {
            ++c.behind;
            continue;
          }
        } else {
          x = s.x * setup.scale_x;
          y = s.y * setup.scale_y;
        }
        if (!(x > -guard && x < float(width) + guard && y > -guard && y < float(height) + guard)) {
          ++c.off_screen;
          continue;
        }
        const int px = std::clamp(floor_int(x), 0, width - 1);
        const int py = std::clamp(floor_int(y), 0, height - 1);
        const PixelShape& shape = m.shapes[size_t(py) * size_t(width) + size_t(px)];
        const float r = shape.r, sigma_x = shape.sigma_x, sigma_y = shape.sigma_y;
        // The splat is the square of radius r cut to the Gaussian's own cutoff box.
        const float r_x = std::min(r, cutoff * sigma_x);
        const float r_y = std::min(r, cutoff * sigma_y);
        sp.x = x;
        sp.y = y;
        sp.r = r;
        sp.k_x = 0.5f / (sigma_x * sigma_x);
        sp.k_y = 0.5f / (sigma_y * sigma_y);
        sp.off_x = fast_exp(-r_x * r_x * sp.k_x);
        sp.off_y = fast_exp(-r_y * r_y * sp.k_y);
        sp.w_t = std::max(fast_exp(-age * age * shape.k_t), min_wt);
        sp.color = s.color;
        // Pixels i with |i + 0.5 - x| < r_x, rows likewise.
        const int x0 = std::max(0, floor_int(x - r_x - 0.5f) + 1);
        const int x1 = std::min(width - 1, ceil_int(x + r_x - 0.5f) - 1);
        const int y0 = std::max(0, floor_int(y - r_y - 0.5f) + 1);
        const int y1 = std::min(height - 1, ceil_int(y + r_y - 0.5f) - 1);
        if (x0 > x1 || y0 > y1) {
          ++c.off_screen;
          continue;
        }
        sp.x0 = int16_t(x0);
        sp.x1 = int16_t(x1);
        sp.y0 = int16_t(y0);
        sp.y1 = int16_t(y1);
        ++c.splatted;
        for (int b = y0 / band_height; b <= y1 / band_height; ++b) ++counts[b];
      }
      m.chunk_counts[size_t(chunk)] = c;
    });

    lap("phase1");
    // ---- Band lists: band-major, and inside a band chunk by chunk, so in sample order.
    m.band_start.resize(size_t(bands) + 1);
    size_t total = 0;
    for (int b = 0; b < bands; ++b) {
      m.band_start[size_t(b)] = total;
      for (int c = 0; c < chunks; ++c) {
        const size_t k = size_t(c) * size_t(bands) + size_t(b);
        m.cursor[k] = total;
        total += m.counts[k];
      }
    }
    m.band_start[size_t(bands)] = total;
    if (m.binned.size() < total) m.binned.resize(total);
    m.pool.run(chunks, [&](int chunk) {
      const size_t begin = n * size_t(chunk) / size_t(chunks);
      const size_t end = n * size_t(chunk + 1) / size_t(chunks);
      size_t* cursor = m.cursor.data() + size_t(chunk) * size_t(bands);
      for (size_t i = begin; i < end; ++i) {
        const Splat& sp = m.splats[i];
        if (sp.x0 > sp.x1) continue;
        for (int b = sp.y0 / band_height; b <= sp.y1 / band_height; ++b) {
          m.binned[cursor[b]++] = sp;
        }
      }
    });

    lap("bin");
    // ---- Phase 2: each band accumulated by one thread.
    m.pool.run(bands, [&](int band) {
      const int row0 = band * band_height;
      const int row1 = std::min(height, row0 + band_height);
      const size_t first = size_t(row0) * size_t(width), last = size_t(row1) * size_t(width);
      std::fill(m.accum.begin() + ptrdiff_t(first), m.accum.begin() + ptrdiff_t(last),
                glm::vec4(0.0f));
      std::fill(m.coverage_next.begin() + ptrdiff_t(first),
                m.coverage_next.begin() + ptrdiff_t(last), CoverageCell{});
      std::array<float, 2 * int(kSplatRadiusLimit) + 4> wx;
      for (size_t k = m.band_start[size_t(band)]; k < m.band_start[size_t(band) + 1]; ++k) {
        const Splat& sp = m.binned[k];
        for (int i = sp.x0; i <= sp.x1; ++i) {
          const float dx = (float(i) + 0.5f) - sp.x;
          wx[size_t(i - sp.x0)] = fast_exp(-dx * dx * sp.k_x) - sp.off_x;
        }
        const int j0 = std::max(int(sp.y0), row0), j1 = std::min(int(sp.y1), row1 - 1);
        for (int j = j0; j <= j1; ++j) {
          const float dy = (float(j) + 0.5f) - sp.y;
          const float wy = fast_exp(-dy * dy * sp.k_y) - sp.off_y;
          if (!(wy > 0.0f)) continue;
          const float wyt = wy * sp.w_t;
          glm::vec4* acc = m.accum.data() + size_t(j) * size_t(width);
          CoverageCell* cov = m.coverage_next.data() + size_t(j) * size_t(width);
          for (int i = sp.x0; i <= sp.x1; ++i) {
            const float w = wx[size_t(i - sp.x0)] * wyt;
            if (!(w > kMinSplatWeight)) continue;
            acc[i] += glm::vec4(sp.color * w, w);
            cov[i].count += 1.0f;
            cov[i].radius_sum += sp.r;
          }
        }
      }
    });
    { double ops = 0, rs = 0; for (size_t i = 0; i < n; ++i) { const Splat& sp = m.splats[i]; if (sp.x0 > sp.x1) continue; ops += double(sp.x1 - sp.x0 + 1) * (sp.y1 - sp.y0 + 1); rs += sp.r; }
      fprintf(stderr, "DBG ops %.0f mean r %.3f bands %d total %zu\n", ops, rs / n, bands, total); }
    for (const SampleCounts& c : m.chunk_counts) {
      frame_.splatted += c.splatted;
      frame_.behind_camera += c.behind;
      frame_.off_screen += c.off_screen;
      frame_.future += c.future;
    }
  }

  lap("phase2");
  // ---- Normalise; holes from wider support (hole_fill.h).
  m.pyramid.build(m.accum, width, height);
  lap("pyramid");
  const int tasks = std::min(height, threads * 4);
  m.row_counts.assign(size_t(tasks), PixelCounts{});
  m.pool.run(tasks, [&](int task) {
    const int row0 = height * task / tasks, row1 = height * (task + 1) / tasks;
    PixelCounts c;
    for (int y = row0; y < row1; ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t p = size_t(y) * size_t(width) + size_t(x);
        const glm::vec4 a = m.accum[p];
        glm::vec3 color;
        if (a.w > 0.0f) {
          color = glm::vec3(a) / a.w;
        } else {
          ++c.holes;
          if (!m.pyramid.fill(x, y, &color)) ++c.empty;
        }
        if (!std::isfinite(color.x) || !std::isfinite(color.y) || !std::isfinite(color.z)) {
          ++c.nonfinite;
          color = glm::vec3(0.0f);
        }
        if (out != nullptr) out->pixels[p] = color;
      }
    }
    m.row_counts[size_t(task)] = c;
  });
  for (const PixelCounts& c : m.row_counts) {
    frame_.hole_pixels += c.holes;
    frame_.empty_pixels += c.empty;
    frame_.nonfinite_pixels += c.nonfinite;
  }
  lap("norm"); fprintf(stderr, "\n");
  if (current_mode != ReconstructionMode::kTraditionalFrameless) {
    m.previous.cells().swap(m.coverage_next);
    m.previous.set_valid(true);
  }
}

}  // namespace afr
