#include <afr/display/cpu_reconstructor.h>

#include <afr/display/fast_exp.h>
#include <afr/display/hole_fill.h>
#include <afr/display/reprojection.h>

#include "thread_pool.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <thread>

namespace afr {

namespace {

// A stored sample after reprojection: where it lands in the output image and what it carries.
struct Projected {
  float x = 0.0f, y = 0.0f;  // output pixels
  float age = 0.0f;          // seconds, >= 0
  glm::vec3 color{0.0f};
};

// The splat of a sample landing in a pixel (filter.h): its Gaussian, grown by the coverage map,
// and its extent, in output pixels.
struct PixelShape {
  float k_x = 0.0f, k_y = 0.0f;      // 1 / (2 sigma^2)
  float off_x = 0.0f, off_y = 0.0f;  // the Gaussian at the splat's edge: exp(-r_x^2 k_x), ...
  float r_x = 0.0f, r_y = 0.0f;      // the splat: the square of radius r cut to cutoff sigma
  float k_t = 0.0f;                  // 1 / (2 e_t^2)
  float norm = 1.0f;                 // 1 / (sigma_x sigma_y): the Gaussian's area
  float r = 1.0f;                    // splat size
  float growth = 1.0f;               // r / filter radius (what the coverage map records)
};

// Per-task counts of what happened to samples and pixels (summed after each phase); a cache
// line each, so that tasks on different threads never share one.
struct alignas(64) Counts {
  uint64_t splatted = 0, behind = 0, off_screen = 0, future = 0;
  uint64_t holes = 0, empty = 0, nonfinite = 0;
};

constexpr uint16_t kNoBand = 0xffff;

// Rows per band of pass D, whatever the thread count (so that the image does not depend on it):
// tall enough that few splats reach beyond the next band, short enough that bands outnumber
// threads several times over (for balance).
int band_height_for(int height) { return std::clamp(height / 32, 8, 64); }

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

// w[k] = exp(-d^2 k_) - offset with d = (i + 0.5) - center, for pixels i = i0 + k in [i0, i1]
// (fills up to 3 entries past i1 - i0).
inline void gaussian_row(int i0, int i1, float center, float k_, float offset, float* w) {
#if defined(__SSE2__)
  const __m128 c = _mm_set1_ps(center), k = _mm_set1_ps(-k_), off = _mm_set1_ps(offset);
  for (int i = i0; i <= i1; i += 4, w += 4) {
    const __m128 d = _mm_sub_ps(
        _mm_add_ps(_mm_set1_ps(float(i) + 0.5f), _mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f)), c);
    _mm_storeu_ps(w, _mm_sub_ps(fast_exp4(_mm_mul_ps(_mm_mul_ps(d, d), k)), off));
  }
#else
  for (int i = i0; i <= i1; ++i, ++w) {
    const float d = (float(i) + 0.5f) - center;
    *w = fast_exp(d * d * -k_) - offset;
  }
#endif
}

int default_threads(int requested) {
  if (requested > 0) return std::min(requested, 256);
  return std::clamp(int(std::thread::hardware_concurrency()), 1, 256);
}

}  // namespace

// The adaptive modes run in four passes, each touching memory in order where it can:
//   C. (per pixel) the splat shape every pixel would give a sample: tile filter and coverage;
//   A. (chunks of the ring) reproject each sample, note its home band (the band of horizontal
//      rows its center falls in, or the oversize bucket for a splat taller than a band) and
//      count samples per chunk and home band;
//   B. (chunks) copy the projected samples into home-band order (stable: sample order within
//      a band, whatever the thread count);
//   D. (home bands) look up each sample's shape and splat it. A splat in a band reaches only
//      its home band and the two next to it (taller ones went to the oversize bucket); bands
//      are done in three rounds (home band index mod 3), and within a round no two bands reach
//      the same row: no two threads ever write the same pixel. Then the oversize bucket, on
//      one thread (well under 1% of samples: grown splats in undersampled regions). The shape
//      table and the accumulation rows a band touches stay in cache, which random sample order
//      would not.
struct CpuReconstructor::Impl {
  explicit Impl(int threads, size_t capacity) : pool(threads) { mirror.resize(capacity); }

  ThreadPool pool;
  // The reconstructor's copy of the store's ring, slot for slot.
  std::vector<StoredSample> mirror;
  std::vector<StoredSample> staging;
  uint64_t seen = 0;
  size_t stored = 0;

  std::vector<Projected> projected;  // per stored sample (pass A)
  std::vector<uint16_t> home;        // per stored sample: home band or kNoBand
  std::vector<uint32_t> counts;      // [chunk * bands + band]
  std::vector<size_t> cursor;        // [chunk * bands + band]: write positions of pass B
  std::vector<size_t> band_start;    // bands + 1
  std::vector<Projected> sorted;     // in home-band order (pass B)
  std::vector<PixelShape> shapes;    // per pixel (pass C)
  std::vector<uint8_t> reach;        // per pixel: ceil(shape.r_y), at most 255 (pass C)
  std::vector<Counts> task_counts;
  std::vector<glm::vec4> accum;             // (sum w c, sum w) per grid pixel
  std::vector<CoverageCell> coverage_next;  // this image's coverage
  CoverageMap previous;                     // the previous image's
  PixelGrid previous_grid;                  // ... and where its pixels lie
  HolePyramid pyramid;
  // The last image's grid size and the output's place in it (read_weights, read_coverage).
  int grid_width = 0;
  int view_x = 0, view_y = 0, out_width = 0, out_height = 0;

  // The output's part of a per-grid-pixel buffer.
  template <typename T>
  void crop(const std::vector<T>& grid, std::vector<T>* out) const {
    out->resize(size_t(out_width) * size_t(out_height));
    if (grid.empty()) {
      std::fill(out->begin(), out->end(), T{});
      return;
    }
    for (int v = 0; v < out_height; ++v) {
      const T* row = grid.data() + size_t(v + view_y) * size_t(grid_width) + size_t(view_x);
      std::copy_n(row, out_width, out->data() + size_t(v) * size_t(out_width));
    }
  }
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

  Counts sum_counts() const {
    Counts total;
    for (const Counts& c : task_counts) {
      total.splatted += c.splatted;
      total.behind += c.behind;
      total.off_screen += c.off_screen;
      total.future += c.future;
      total.holes += c.holes;
      total.empty += c.empty;
      total.nonfinite += c.nonfinite;
    }
    return total;
  }
};

CpuReconstructor::CpuReconstructor(const ReconstructorConfig& config)
    : Reconstructor(config),
      impl_(std::make_unique<Impl>(default_threads(config.threads), store_.capacity())) {}

CpuReconstructor::~CpuReconstructor() = default;

int CpuReconstructor::threads() const { return impl_->pool.size(); }

void CpuReconstructor::read_weights(std::vector<float>* out) {
  std::vector<glm::vec4> accum;
  impl_->crop(impl_->accum, &accum);
  out->resize(accum.size());
  for (size_t i = 0; i < accum.size(); ++i) (*out)[i] = accum[i].w;
}

void CpuReconstructor::read_coverage(std::vector<CoverageCell>* out) {
  impl_->crop(impl_->previous.cells(), out);
}

bool CpuReconstructor::read_coverage(const PixelRect& rect, std::vector<CoverageCell>* out) {
  out->clear();
  const Impl& m = *impl_;
  if (!m.previous.valid() || rect.empty()) return false;
  const PixelRect part = grid_part(m.previous_grid, rect);
  if (part.empty() || part.area() != rect.area()) return false;
  out->resize(size_t(rect.area()));
  for (int32_t y = part.y0; y < part.y1; ++y) {
    std::copy_n(
        m.previous.cells().data() + size_t(y) * size_t(m.previous.width()) + size_t(part.x0),
        part.width(), out->data() + size_t(y - part.y0) * size_t(rect.width()));
  }
  return true;
}

Reconstructor::StoredSlots CpuReconstructor::stored_samples() {
  const Impl& m = *impl_;
  return StoredSlots{m.mirror.data(), m.mirror.size(), m.seen, m.stored};
}

size_t CpuReconstructor::write_coverage(const PixelRect& rect,
                                        const std::vector<CoverageCell>& cells) {
  check_coverage_size(rect, cells);
  Impl& m = *impl_;
  if (!m.previous.valid()) return 0;
  const PixelRect part = grid_part(m.previous_grid, rect);
  const int32_t gx = int32_t(m.previous_grid.origin_x), gy = int32_t(m.previous_grid.origin_y);
  for (int32_t y = part.y0; y < part.y1; ++y) {
    const CoverageCell* from = cells.data() + size_t(y + gy - rect.y0) * size_t(rect.width()) +
                               size_t(part.x0 + gx - rect.x0);
    std::copy_n(
        from, part.width(),
        m.previous.cells().data() + size_t(y) * size_t(m.previous.width()) + size_t(part.x0));
  }
  return size_t(part.area());
}

void CpuReconstructor::do_reconstruct(const Camera& camera, double time, int width, int height,
                                      Image* out) {
  Impl& m = *impl_;
  SampleStore::Delta delta;
  m.sync(store_, &delta);
  FrameSetup setup;
  prepare_frame(time, width, height, delta, m.staging, &setup);

  // From here on the image is the grid: the viewport with its margin. The output is its
  // viewport part (the whole grid when the viewport is the whole image).
  const int out_width = width, out_height = height;
  width = setup.grid.width;
  height = setup.grid.height;
  const float origin_x = float(setup.grid.origin_x), origin_y = float(setup.grid.origin_y);
  m.grid_width = width;
  m.view_x = setup.view_x;
  m.view_y = setup.view_y;
  m.out_width = out_width;
  m.out_height = out_height;
  const size_t pixels = size_t(width) * size_t(height);
  if (!(m.previous_grid == setup.grid)) {
    m.previous.reset(width, height);
    m.previous_grid = setup.grid;
  }
  m.accum.resize(pixels);
  m.coverage_next.resize(pixels);
  const ReconstructionMode current_mode = mode();
  const FilterLimits& limits = config_.filter;
  const SplatSizeRule& rule = config_.splat;
  const int threads = m.pool.size();
  const size_t n = m.stored;
  const double max_future = double(limits.max_future);
  // Tasks over rows of pixels.
  const int row_tasks = std::min(height, threads * 4);
  const auto rows_of = [&](int task, size_t* p0, size_t* p1) {
    *p0 = size_t(height * task / row_tasks) * size_t(width);
    *p1 = size_t(height * (task + 1) / row_tasks) * size_t(width);
  };

  if (current_mode == ReconstructionMode::kTraditionalFrameless) {
    // [BFMS94]: the newest sample at each pixel, at its original position.
    m.newest_age.assign(pixels, std::numeric_limits<double>::infinity());
    std::fill(m.accum.begin(), m.accum.end(), glm::vec4(0.0f));
    for (size_t i = 0; i < n; ++i) {
      const StoredSample& s = m.mirror[i];
      const double age = time - s.time;
      if (age < -max_future) {
        ++frame_.future;
        continue;
      }
      const float x = s.x * setup.scale_x - origin_x, y = s.y * setup.scale_y - origin_y;
      if (!(x >= 0.0f && x < float(width) && y >= 0.0f && y < float(height))) {
        ++frame_.off_screen;
        continue;
      }
      const size_t p = size_t(int(y)) * size_t(width) + size_t(int(x));
      ++frame_.splatted;
      const double a = std::max(age, 0.0);
      if (a < m.newest_age[p]) {
        m.newest_age[p] = a;
        m.accum[p] = glm::vec4(s.color, 1.0f);
      }
    }
    m.previous.reset(width, height);  // no splat sizes to remember
    std::fill(m.coverage_next.begin(), m.coverage_next.end(), CoverageCell{});
  } else {
    const bool reproject = current_mode == ReconstructionMode::kAdaptive;
    const Projector projector(camera, setup.image_width, setup.image_height, setup.grid.origin_x,
                              setup.grid.origin_y);
    // Samples are kept while their center is inside the image grown by this (a whole number
    // of pixels, as the GL backend's viewport): their splats may still reach it.
    const float guard = float(splat_guard_band(rule));
    const float min_wt = limits.min_temporal_weight, cutoff = limits.cutoff;

    // ---- C (first: it gives the band height). Per pixel, what a splat landing there gets:
    // its tile's filter and, section 6.2, the size from the previous image's coverage there.
    m.shapes.resize(pixels);
    m.reach.resize(pixels);
    const std::vector<uint32_t>& index_map = field_.index_map();
    m.pool.run(row_tasks, [&](int task) {
      size_t p0, p1;
      rows_of(task, &p0, &p1);
      const CoverageCell* previous = m.previous.valid() ? m.previous.cells().data() : nullptr;
      for (size_t p = p0; p < p1; ++p) {
        const TileFilter& f = setup.filters[index_map[p]];
        const float r_filter = cutoff * std::max(f.sigma_x, f.sigma_y);
        const float r = splat_radius(previous != nullptr ? previous + p : nullptr, r_filter, rule);
        // A splat the coverage map grew beyond the filter's radius widens its Gaussian by the
        // same factor (keeping its shape); a shrunk one cuts the Gaussian short.
        const float grown = std::max(1.0f, r / r_filter);
        const float sigma_x = f.sigma_x * grown, sigma_y = f.sigma_y * grown;
        PixelShape& shape = m.shapes[p];
        shape.k_x = 0.5f / (sigma_x * sigma_x);
        shape.k_y = 0.5f / (sigma_y * sigma_y);
        // The splat is the square of radius r cut to the Gaussian's own cutoff box, rounded
        // as positions are, so that a splat's pixel range is exact (reprojection.h).
        shape.r_x = quantize_position(std::min(r, cutoff * sigma_x));
        shape.r_y = quantize_position(std::min(r, cutoff * sigma_y));
        shape.off_x = fast_exp(-shape.r_x * shape.r_x * shape.k_x);
        shape.off_y = fast_exp(-shape.r_y * shape.r_y * shape.k_y);
        shape.k_t = f.k_t;
        shape.norm = 1.0f / (sigma_x * sigma_y);
        shape.r = r;
        shape.growth = splat_growth(r, r_filter);
        m.reach[p] = uint8_t(std::min(ceil_int(shape.r_y), 255));
      }
      // Clear this image's sums while here.
      std::fill(m.accum.begin() + ptrdiff_t(p0), m.accum.begin() + ptrdiff_t(p1), glm::vec4(0.0f));
      std::fill(m.coverage_next.begin() + ptrdiff_t(p0), m.coverage_next.begin() + ptrdiff_t(p1),
                CoverageCell{});
    });
    // Bands, and the oversize bucket after them (index `bands`). Bands are rows of the whole
    // image's lattice (their height from the whole image's, band k its rows [k h, (k + 1) h)),
    // and the rounds go by the whole image's band index: a viewport's grid then adds each
    // pixel's splats in the order the whole image's reconstruction does, so its sums are the
    // same bit for bit (docs/reconstruction.md, "Viewports").
    const int band_height = std::max(band_height_for(int(std::min(setup.image_height, 1e9))),
                                     (height + kNoBand - 2) / (kNoBand - 2));
    const int first_row = int(std::floor(setup.grid.origin_y));
    const int first_band = first_row / band_height;
    const int band_offset = first_row - first_band * band_height;  // grid row 0 in its band
    const int bands = (band_offset + height + band_height - 1) / band_height;
    // A row of counts per chunk, padded to whole cache lines (chunks run on different threads).
    const size_t count_stride = (size_t(bands) + 1 + 15) / 16 * 16;

    // ---- A. Reproject; count per chunk and home band.
    const int chunks = int(std::clamp<size_t>(n / 8192, 1, size_t(threads) * 4));
    m.projected.resize(std::max<size_t>(n, 1));
    m.home.resize(std::max<size_t>(n, 1));
    m.counts.assign(size_t(chunks) * count_stride, 0u);
    m.cursor.resize(m.counts.size());
    m.task_counts.assign(size_t(std::max(chunks, bands + 1)), Counts{});
    m.pool.run(chunks, [&](int chunk) {
      const size_t begin = n * size_t(chunk) / size_t(chunks);
      const size_t end = n * size_t(chunk + 1) / size_t(chunks);
      Counts& c = m.task_counts[size_t(chunk)];
      uint32_t* counts = m.counts.data() + size_t(chunk) * count_stride;
      for (size_t i = begin; i < end; ++i) {
        m.home[i] = kNoBand;
        const StoredSample& s = m.mirror[i];
        const double age_d = time - s.time;
        if (age_d < -max_future) {
          ++c.future;
          continue;
        }
        const float age_signed = float(age_d);
        float x, y;
        if (reproject && (s.flags & kStoredHasPosition)) {
          if (!projector.project(s, age_signed, &x, &y)) {
            ++c.behind;
            continue;
          }
        } else {
          x = quantize_position(s.x * setup.scale_x) - origin_x;
          y = quantize_position(s.y * setup.scale_y) - origin_y;
        }
        if (!(x > -guard && x < float(width) + guard && y > -guard && y < float(height) + guard)) {
          ++c.off_screen;
          continue;
        }
        m.projected[i] = Projected{x, y, std::max(age_signed, 0.0f), s.color};
        const int py = std::clamp(floor_int(y), 0, height - 1);
        const int px = std::clamp(floor_int(x), 0, width - 1);
        const int band = m.reach[size_t(py) * size_t(width) + size_t(px)] < band_height
                             ? (py + band_offset) / band_height
                             : bands;
        m.home[i] = uint16_t(band);
        ++counts[band];
      }
    });

    // ---- B. Home-band order: band-major, chunk by chunk inside a band (so sample order).
    m.band_start.resize(size_t(bands) + 2);
    size_t total = 0;
    for (int b = 0; b <= bands; ++b) {
      m.band_start[size_t(b)] = total;
      for (int c = 0; c < chunks; ++c) {
        const size_t k = size_t(c) * count_stride + size_t(b);
        m.cursor[k] = total;
        total += m.counts[k];
      }
    }
    m.band_start[size_t(bands) + 1] = total;
    m.sorted.resize(std::max<size_t>(total, 1));
    m.pool.run(chunks, [&](int chunk) {
      const size_t begin = n * size_t(chunk) / size_t(chunks);
      const size_t end = n * size_t(chunk + 1) / size_t(chunks);
      size_t* cursor = m.cursor.data() + size_t(chunk) * count_stride;
      for (size_t i = begin; i < end; ++i) {
        if (m.home[i] != kNoBand) m.sorted[cursor[m.home[i]]++] = m.projected[i];
      }
    });

    // ---- D. Splat: three rounds of bands, then the oversize bucket.
    const auto splat_band = [&](int band) {
      Counts& c = m.task_counts[size_t(band)];
      std::array<float, 2 * int(kSplatRadiusLimit) + 4> wx, wy;
      const size_t q_end = m.band_start[size_t(band) + 1];
      for (size_t q = m.band_start[size_t(band)]; q < q_end; ++q) {
        const Projected& s = m.sorted[q];
        if (q + 8 < q_end) {  // the shape table is read in random order: fetch ahead
          const Projected& ahead = m.sorted[q + 8];
          const int ax = std::clamp(int(ahead.x), 0, width - 1);
          const int ay = std::clamp(int(ahead.y), 0, height - 1);
          __builtin_prefetch(&m.shapes[size_t(ay) * size_t(width) + size_t(ax)]);
        }
        const int px = std::clamp(floor_int(s.x), 0, width - 1);
        const int py = std::clamp(floor_int(s.y), 0, height - 1);
        const PixelShape& shape = m.shapes[size_t(py) * size_t(width) + size_t(px)];
        const float r_x = shape.r_x, r_y = shape.r_y, g = shape.growth;
        // Pixels i with |i + 0.5 - x| < r_x, rows likewise.
        const int x0 = std::max(0, floor_int(s.x - r_x - 0.5f) + 1);
        const int x1 = std::min(width - 1, ceil_int(s.x + r_x - 0.5f) - 1);
        const int y0 = std::max(0, floor_int(s.y - r_y - 0.5f) + 1);
        const int y1 = std::min(height - 1, ceil_int(s.y + r_y - 0.5f) - 1);
        if (x0 > x1 || y0 > y1) {
          ++c.off_screen;
          continue;
        }
        ++c.splatted;
        const float w_t = std::max(fast_exp(-s.age * s.age * shape.k_t), min_wt) * shape.norm;
#if defined(__SSE2__)
        const __m128 color1 = _mm_setr_ps(s.color.r, s.color.g, s.color.b, 1.0f);
#endif
        // The Gaussian of every column and row of the splat.
        gaussian_row(x0, x1, s.x, shape.k_x, shape.off_x, wx.data());
        gaussian_row(y0, y1, s.y, shape.k_y, shape.off_y, wy.data());
        for (int j = y0; j <= y1; ++j) {
          const float wyj = wy[size_t(j - y0)];
          if (!(wyj > 0.0f)) continue;
          const float wyt = wyj * w_t;
          glm::vec4* acc = m.accum.data() + size_t(j) * size_t(width);
          CoverageCell* cov = m.coverage_next.data() + size_t(j) * size_t(width);
          int i = x0;
#if defined(__SSE2__)
          // Four pixels at a time without a branch per pixel: lanes past x1 or with a weight
          // at or below kMinSplatWeight add exactly 0 (and nothing to the coverage).
          const __m128 wyt4 = _mm_set1_ps(wyt);
          const __m128 one_g = _mm_setr_ps(1.0f, g, 1.0f, g);
          for (; i + 3 < width && i <= x1; i += 4) {
            const __m128 lane = _mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f);
            const __m128 inside = _mm_cmplt_ps(lane, _mm_set1_ps(float(x1 - i + 1)));
            const __m128 w4 = _mm_mul_ps(_mm_loadu_ps(&wx[size_t(i - x0)]), wyt4);
            const __m128 ok = _mm_and_ps(inside, _mm_cmpgt_ps(w4, _mm_set1_ps(kMinSplatWeight)));
            const __m128 w = _mm_and_ps(w4, ok);
            float* a = &acc[i].x;
            _mm_storeu_ps(
                a, _mm_add_ps(_mm_loadu_ps(a), _mm_mul_ps(color1, _mm_shuffle_ps(w, w, 0x00))));
            _mm_storeu_ps(a + 4, _mm_add_ps(_mm_loadu_ps(a + 4),
                                            _mm_mul_ps(color1, _mm_shuffle_ps(w, w, 0x55))));
            _mm_storeu_ps(a + 8, _mm_add_ps(_mm_loadu_ps(a + 8),
                                            _mm_mul_ps(color1, _mm_shuffle_ps(w, w, 0xaa))));
            _mm_storeu_ps(a + 12, _mm_add_ps(_mm_loadu_ps(a + 12),
                                             _mm_mul_ps(color1, _mm_shuffle_ps(w, w, 0xff))));
            float* cv = &cov[i].count;
            _mm_storeu_ps(cv,
                          _mm_add_ps(_mm_loadu_ps(cv), _mm_and_ps(one_g, _mm_unpacklo_ps(ok, ok))));
            _mm_storeu_ps(cv + 4, _mm_add_ps(_mm_loadu_ps(cv + 4),
                                             _mm_and_ps(one_g, _mm_unpackhi_ps(ok, ok))));
          }
#endif
          for (; i <= x1; ++i) {  // the image's last columns (and builds without SSE2)
            const float w = wx[size_t(i - x0)] * wyt;
            if (!(w > kMinSplatWeight)) continue;
            acc[i] += glm::vec4(s.color * w, w);
            cov[i].count += 1.0f;
            cov[i].growth_sum += g;
          }
        }
      }
    };
    for (int round = 0; round < 3; ++round) {
      const int start = ((round - first_band) % 3 + 3) % 3;  // whole-image band index mod 3
      m.pool.run((bands - start + 2) / 3, [&](int k) { splat_band(start + 3 * k); });
    }
    splat_band(bands);
    const Counts c = m.sum_counts();
    frame_.splatted = c.splatted;
    frame_.behind_camera = c.behind;
    frame_.off_screen = c.off_screen;
    frame_.future = c.future;
  }

  // ---- Normalise the output's pixels; holes from wider support (hole_fill.h) over the grid.
  m.pyramid.build(m.accum, width, height);
  const int out_tasks = std::min(out_height, threads * 4);
  m.task_counts.assign(size_t(out_tasks), Counts{});
  m.pool.run(out_tasks, [&](int task) {
    Counts& c = m.task_counts[size_t(task)];
    for (int v = out_height * task / out_tasks; v < out_height * (task + 1) / out_tasks; ++v) {
      const int y = v + setup.view_y;
      const glm::vec4* row = m.accum.data() + size_t(y) * size_t(width) + size_t(setup.view_x);
      for (int u = 0; u < out_width; ++u) {
        const glm::vec4 a = row[u];
        glm::vec3 color;
        if (a.w > 0.0f) {
          color = glm::vec3(a) / a.w;
        } else {
          ++c.holes;
          if (!m.pyramid.fill(u + setup.view_x, y, &color)) ++c.empty;
        }
        if (!std::isfinite(color.x) || !std::isfinite(color.y) || !std::isfinite(color.z)) {
          ++c.nonfinite;
          color = glm::vec3(0.0f);
        }
        if (out != nullptr) out->pixels[size_t(v) * size_t(out_width) + size_t(u)] = color;
      }
    }
  });
  const Counts c = m.sum_counts();
  frame_.hole_pixels = c.holes;
  frame_.empty_pixels = c.empty;
  frame_.nonfinite_pixels = c.nonfinite;
  if (current_mode != ReconstructionMode::kTraditionalFrameless) {
    m.previous.cells().swap(m.coverage_next);
    m.previous.set_valid(true);
  }
}

}  // namespace afr
