#include <afr/display/cpu_reconstructor.h>

// This file's helpers (and exp_series, fast_exp.h) take and return 8-lane vectors by value;
// they are inlined into the hot passes (GCC notes that such a function's ABI would differ
// without AVX).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#include <afr/display/fast_exp.h>
#include <afr/display/hole_fill.h>
#include <afr/display/reprojection.h>

#include "thread_pool.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
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
  float growth = 1.0f;               // r / filter radius (what the coverage map records)
};

// Per-task counts of what happened to samples and pixels (summed after each phase); a cache
// line each, so that tasks on different threads never share one.
struct alignas(64) Counts {
  uint64_t splatted = 0, behind = 0, off_screen = 0, future = 0;
  uint64_t holes = 0, empty = 0, nonfinite = 0;
};

// Rows per band of splat_bands, whatever the thread count (so that the image does not depend
// on it): tall enough that few splats reach beyond the next band, short enough that bands
// outnumber threads several times over (for balance).
int band_height_for(int height) { return std::clamp(height / 32, 8, 64); }
// Pixels per block of a band (Bands): 36 bytes of splat shape and 24 of sums and coverage each.
constexpr int kBlockArea = 128;
// Blocks are widened where the whole image would have more bins than this (each chunk of the
// ring has a chain of pages per bin: BinPages).
constexpr double kMaxBins = 8192.0;

// The hot passes are compiled twice with GCC, for the baseline x86-64 and for x86-64-v3 (AVX2,
// FMA: Haswell and later); the dynamic loader picks one per machine (an ifunc that tests the
// ISA level). flatten inlines every helper they call (fast_exp, the projection, the coverage
// rule), so those are compiled for the clone's target too. The v3 clone fuses multiply-adds:
// its images differ from the baseline's in the last bits, as they do between compilers (every
// comparison across machines and backends has a tolerance). Clang 14's resolver for ISA levels
// tests the wrong thing, so Clang builds (the sanitizer builds) keep the baseline only.
// Measured in docs/reconstruction.md ("Benchmark").
#if defined(__x86_64__) && defined(__linux__) && defined(__GNUC__) && !defined(__clang__) && \
    __GNUC__ >= 12 && !defined(AFR_NO_CLONES)
#define AFR_HOT_CLONES __attribute__((target_clones("arch=x86-64-v3", "default"), flatten))
#else
#define AFR_HOT_CLONES
#endif

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

// GCC/Clang vector types for the arithmetic of eight samples and for splat_band's sums: 8
// floats are one AVX register in the x86-64-v3 clone and two SSE registers in the baseline
// (and whatever the target has elsewhere). The 8-float loads and stores are unaligned and may
// alias the float sums.
typedef float Float8 __attribute__((vector_size(32), aligned(4), may_alias));
typedef int32_t Int8 __attribute__((vector_size(32), aligned(4), may_alias));
typedef float Float4 __attribute__((vector_size(16)));
typedef float Float4u __attribute__((vector_size(16), aligned(4), may_alias));  // unaligned
typedef int32_t Int4 __attribute__((vector_size(16)));

// Lane-wise a where m is set, else b (m: all ones or zeros per lane, as comparisons give).
inline Float8 select8(Int8 m, Float8 a, Float8 b) { return Float8((Int8(a) & m) | (Int8(b) & ~m)); }
inline Int8 select8(Int8 m, Int8 a, Int8 b) { return (a & m) | (b & ~m); }
inline Float8 splat8(float v) { return Float8{v, v, v, v, v, v, v, v}; }
inline Int8 splat8(int32_t v) { return Int8{v, v, v, v, v, v, v, v}; }
inline Float8 abs8(Float8 v) { return Float8(Int8(v) & splat8(0x7fffffff)); }
// quantize_position (reprojection.h) on eight lanes, with its operations.
inline Float8 quantize8(Float8 v) {
  const Float8 t = v * 256.0f;
  const Float8 q = ((t + 12582912.0f) - 12582912.0f) * kPositionStep;
  return select8(abs8(v) < splat8(16384.0f), q, v);
}
// The square root of each lane (correctly rounded, as std::sqrt).
inline Float8 sqrt8(Float8 v) {
#if defined(__SSE2__)
  const Float4 lo = Float4(_mm_sqrt_ps(__m128(__builtin_shufflevector(v, v, 0, 1, 2, 3))));
  const Float4 hi = Float4(_mm_sqrt_ps(__m128(__builtin_shufflevector(v, v, 4, 5, 6, 7))));
  return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
#else
  Float8 r;
  for (int l = 0; l < 8; ++l) r[l] = std::sqrt(v[l]);
  return r;
#endif
}
// Each lane clamped to [0, hi].
inline Int8 clamp8(Int8 v, int32_t hi) {
  const Int8 zero = splat8(0), top = splat8(hi);
  return select8(v < zero, zero, select8(v > top, top, v));
}
// floor_int and ceil_int on eight lanes.
inline Int8 floor_int8(Float8 v) {
  const Int8 i = __builtin_convertvector(v, Int8);
  return i + Int8(v < __builtin_convertvector(i, Float8));  // true is -1
}
inline Int8 ceil_int8(Float8 v) {
  const Int8 i = __builtin_convertvector(v, Int8);
  return i - Int8(v > __builtin_convertvector(i, Float8));
}
// fast_exp (fast_exp.h) on eight lanes, with its operations.
inline Float8 fast_exp8(Float8 x) {
  const Float8 lowest = splat8(-87.0f), zero = splat8(0.0f);
  const Int8 valid = x > lowest;  // false for NaN and x <= -87: result 0
  x = select8(x < zero, x, zero);
  x = select8(x > lowest, x, lowest);
  const Int8 i = __builtin_convertvector(x * 1.44269504088896341f - 0.5f, Int8);
  const Float8 fi = __builtin_convertvector(i, Float8);
  const Float8 u = (x - fi * 0.693145751953125f) - fi * 1.42860682030941723e-6f;
  const Float8 p = exp_series(u);
  const Int8 bits = (i + 127) << 23;
  return Float8(Int8(p * Float8(bits)) & valid);
}

// gaussian_row of columns x0 .. x0 + 3 into wx[0..3] and of rows y0 .. y0 + 3 into wy[0..3]
// at once, each lane with gaussian_row's operations (a splat of at most 4 x 4 pixels).
inline void gaussian_rows_4x4(int x0, int y0, float center_x, float center_y,
                              const PixelShape& shape, float* wx, float* wy) {
  const Float8 lane = {0.0f, 1.0f, 2.0f, 3.0f, 0.0f, 1.0f, 2.0f, 3.0f};
  const float bx = float(x0) + 0.5f, by = float(y0) + 0.5f;
  const Float8 d =
      (Float8{bx, bx, bx, bx, by, by, by, by} + lane) -
      Float8{center_x, center_x, center_x, center_x, center_y, center_y, center_y, center_y};
  const float kx = -shape.k_x, ky = -shape.k_y, ox = shape.off_x, oy = shape.off_y;
  const Float8 w = fast_exp8((d * d) * Float8{kx, kx, kx, kx, ky, ky, ky, ky}) -
                   Float8{ox, ox, ox, ox, oy, oy, oy, oy};
  std::memcpy(wx, &w, 4 * sizeof(float));
  std::memcpy(wy, reinterpret_cast<const float*>(&w) + 4, 4 * sizeof(float));
}

#if defined(__SSE2__)
// One row of a splat, four pixels on: the weights wx4 (the splat's columns) times wyt (its
// row's weight and the temporal weight) in the lanes that are inside and above
// kMinSplatWeight, exactly 0 in the others; *added: those lanes (all ones or zeros).
inline Float4 row_weights(__m128 inside, __m128 wx4, float wyt, Int4* added) {
  const __m128 w4 = _mm_mul_ps(wx4, _mm_set1_ps(wyt));
  const __m128 ok = _mm_and_ps(inside, _mm_cmpgt_ps(w4, _mm_set1_ps(kMinSplatWeight)));
  *added = Int4(ok);
  return Float4(_mm_and_ps(w4, ok));
}
// row_weights added with the color to the sums (r, g, b, w) of the four pixels from acc on. The
// sums of two pixels are one 8-float vector: one operation in the x86-64-v3 clone, two in the
// baseline. Returns the lanes added.
inline Int4 add_four_columns(glm::vec4* acc, __m128 inside, __m128 wx4, float wyt, Float8 color2) {
  Int4 added;
  const Float4 w = row_weights(inside, wx4, wyt, &added);
  Float8* sums = reinterpret_cast<Float8*>(&acc->x);  // pixels 0, 1; 2, 3
  sums[0] += color2 * __builtin_shufflevector(w, w, 0, 0, 0, 0, 1, 1, 1, 1);
  sums[1] += color2 * __builtin_shufflevector(w, w, 2, 2, 2, 2, 3, 3, 3, 3);
  return added;
}
// add_four_columns for a splat at most two pixels wide: its first two lanes only.
inline Int4 add_two_columns(glm::vec4* acc, __m128 inside, __m128 wx4, float wyt, Float8 color2) {
  Int4 added;
  const Float4 w = row_weights(inside, wx4, wyt, &added);
  *reinterpret_cast<Float8*>(&acc->x) +=
      color2 * __builtin_shufflevector(w, w, 0, 0, 0, 0, 1, 1, 1, 1);
  return added;
}
// The coverage (count, growth) of the four pixels from cov on, for the lanes added (ok): one
// 8-float vector. one_g: (1, g) four times.
inline void add_coverage4(CoverageCell* cov, Int4 ok, Float8 one_g) {
  *reinterpret_cast<Float8*>(&cov->count) +=
      Float8(Int8(one_g) & __builtin_shufflevector(ok, ok, 0, 0, 1, 1, 2, 2, 3, 3));
}
// add_coverage4 for the first two pixels.
inline void add_coverage2(CoverageCell* cov, Int4 ok, Float8 one_g) {
  *reinterpret_cast<Float4u*>(&cov->count) +=
      Float4u(Int4(__builtin_shufflevector(one_g, one_g, 0, 1, 2, 3)) &
              __builtin_shufflevector(ok, ok, 0, 0, 1, 1));
}
#endif

int default_threads(int requested) {
  if (requested > 0) return std::min(requested, 256);
  return std::clamp(int(std::thread::hardware_concurrency()), 1, 256);
}

// The pixels an image computes (FrameSetup::grid: the viewport with its margin, or the whole
// image), as the phases below use them.
struct Grid {
  int width = 0, height = 0;
  float origin_x = 0.0f, origin_y = 0.0f;  // its first pixel, in the whole image's pixels
  size_t pixels() const { return size_t(width) * size_t(height); }
};

// The horizontal bands of rows that samples are binned into and splatted by. They are rows of
// the whole image's lattice (their height from the whole image's, band k its rows
// [k h, (k + 1) h)), and the splat rounds go by the whole image's band index: a viewport's grid
// then adds each pixel's splats in the order the whole image's reconstruction does, so its sums
// are the same bit for bit (docs/reconstruction.md, "Viewports").
struct Bands {
  int height = 0;  // rows per band
  int first = 0;   // the whole image's index of the band holding grid row 0
  int offset = 0;  // grid row 0's row in that band
  int count = 0;   // bands over the grid
  // Each band is binned in blocks of columns of the whole image's lattice (block k: columns
  // [k w, (k + 1) w)), so that a band's samples are splatted block after block: the shapes and
  // sums a block touches fit in the first-level cache, where a whole band's would not.
  int block_width = 0;   // columns per block
  int block_offset = 0;  // grid column 0's column in its block
  int blocks = 0;        // blocks over the grid
  // Bin of band b, block k: b * blocks + k; bin `oversize()` is the oversize bucket.
  uint32_t oversize() const { return uint32_t(count) * uint32_t(blocks); }
  size_t bins() const { return size_t(oversize()) + 1; }
};

Bands bands_for(const PixelGrid& grid, double scaled_width, double scaled_height, int grid_width,
                int grid_height) {
  Bands b;
  b.height = band_height_for(int(std::min(scaled_height, 1e9)));
  // From the whole image's size, so that a viewport's blocks are the whole image's.
  const double whole_bands = std::ceil(std::min(scaled_height, 1e9) / double(b.height));
  b.block_width = int(std::clamp(std::ceil(std::min(scaled_width, 1e9) * whole_bands / kMaxBins),
                                 double(kBlockArea / b.height), 1e9));
  const int first_row = int(std::floor(grid.origin_y));
  b.first = first_row / b.height;
  b.offset = first_row - b.first * b.height;
  b.count = (b.offset + grid_height + b.height - 1) / b.height;
  const int first_column = int(std::floor(grid.origin_x));
  b.block_offset = first_column % b.block_width;
  b.blocks = (b.block_offset + grid_width + b.block_width - 1) / b.block_width;
  return b;
}

// How far ahead of the reprojection the ring is prefetched, in samples (8 KiB).
constexpr size_t kPrefetchAhead = 128;

// Chunks of the ring for binning: at most 4 per thread, and about 8192 samples or more each,
// at least 16 per bin (so that a chunk's bins fill most of their pages: BinPages).
int chunks_for(size_t samples, int threads, uint32_t bins) {
  const size_t per_chunk = std::max<size_t>(8192, 16 * size_t(bins));
  return int(std::clamp<size_t>(samples / per_chunk, 1, size_t(threads) * 4));
}

// The binned samples of one chunk of the ring: each bin a chain of pages of kPageSamples
// records, in sample order, from the chunk's own pool. The reprojection writes each sample's
// record straight into its bin, so that binning needs no counting pass and no sort; the splat
// reads a bin's chains chunk after chunk (so in sample order, whatever the thread count).
constexpr uint32_t kPageSamples = 16;
constexpr uint32_t kNoPage = 0xffffffffu;

class BinPages {
 public:
  struct Chain {
    uint32_t head = kNoPage, tail = kNoPage;
    uint32_t fill = kPageSamples;  // records in the tail page
  };

  // Empties every chain, for `bins` bins; the pool keeps its memory.
  void reset(size_t bins) {
    chains_.assign(bins, Chain{});
    pages_ = 0;
  }

  // The place of a new record at the end of bin b's chain.
  Projected& append(uint32_t b) {
    Chain& c = chains_[b];
    if (c.fill == kPageSamples) {
      const uint32_t page = pages_++;
      if (next_.size() < size_t(pages_) + 1) grow();
      // The pool's next page (the next chain to fill one takes it) is asked for from memory
      // now, to be written: pages are written far apart in time, line by line.
      prefetch_page(page + 1, true);
      next_[page] = kNoPage;
      (c.tail == kNoPage ? c.head : next_[c.tail]) = page;
      c.tail = page;
      c.fill = 0;
    }
    return records_[size_t(c.tail) * kPageSamples + c.fill++];
  }

  // f(records, count) for each page of bin b's chain, in order. Each page's successor is asked
  // for from memory while f works on it (pages lie anywhere in the pool: the hardware's
  // prefetcher cannot guess them).
  template <typename F>
  void for_each_page(uint32_t b, F&& f) const {
    const Chain& c = chains_[b];
    for (uint32_t page = c.head; page != kNoPage; page = next_[page]) {
      if (next_[page] != kNoPage) prefetch_page(next_[page]);
      f(records_.data() + size_t(page) * kPageSamples, page == c.tail ? c.fill : kPageSamples);
    }
  }

  // Asks for the first page of bin b's chain from memory.
  void prefetch_head(uint32_t b) const {
    if (chains_[b].head != kNoPage) prefetch_page(chains_[b].head);
  }

 private:
  void grow() {
    const size_t pages = std::max<size_t>(2 * next_.size(), 256);
    next_.resize(pages);
    records_.resize(pages * kPageSamples);
  }

  void prefetch_page(uint32_t page, bool to_write = false) const {
    const char* p = reinterpret_cast<const char*>(records_.data() + size_t(page) * kPageSamples);
    for (size_t k = 0; k < kPageSamples * sizeof(Projected); k += 64) {
      if (to_write) {
        __builtin_prefetch(p + k, 1);
      } else {
        __builtin_prefetch(p + k);
      }
    }
  }

  std::vector<Chain> chains_;       // per bin
  std::vector<Projected> records_;  // page p: [p kPageSamples, (p + 1) kPageSamples)
  std::vector<uint32_t> next_;      // per page: the next page of its chain, or kNoPage
  uint32_t pages_ = 0;              // pages in use
};

}  // namespace

// The adaptive modes run in three phases, each touching memory in order where it can:
//   shape_splats_and_clear_sums (rows of pixels): the splat shape every pixel would give a
//     sample, from its tile's filter and the coverage; first, since binning needs its reach;
//   reproject_and_bin (chunks of the ring): reproject each sample and write its record into
//     its bin (the block of columns of the band of horizontal rows its center falls in, or the
//     oversize bucket for a splat taller than a band): a chain of pages per bin and chunk
//     (BinPages), so in sample order within a bin, whatever the thread count;
//   splat_bands (home bands): look up each sample's shape and splat it, block after block
//     (the shapes and sums of a block stay in the first-level cache). A splat in a band
//     reaches only its home band and the two next to it (taller ones went to the oversize
//     bucket); bands are done in three rounds (home band index mod 3), and within a round no
//     two bands reach the same row: no two threads ever write the same pixel. Then the
//     oversize bucket, on one thread (well under 1% of samples: grown splats in undersampled
//     regions). The shape table and the accumulation rows a band touches stay in cache, which
//     random sample order would not.
// Every mode ends with normalize_and_fill_holes (rows of the output). The per-sample work of
// reproject_and_bin and splat_bands runs eight samples at a time in 8-lane vector arithmetic
// (GCC/Clang vector extensions: AVX in the x86-64-v3 clone) where it is arithmetic, and one
// sample at a time where it writes.
struct CpuReconstructor::Impl {
  explicit Impl(int threads, size_t capacity) : pool(threads) { mirror.resize(capacity); }

  ThreadPool pool;
  // The reconstructor's copy of the store's ring, slot for slot.
  std::vector<StoredSample> mirror;
  std::vector<StoredSample> staging;
  uint64_t seen = 0;
  size_t stored = 0;

  // A pixel's bin is row_bin[y] + column_bin[x] (reproject_and_bin).
  std::vector<uint32_t> row_bin, column_bin;
  std::vector<BinPages> binned;    // per chunk of the ring: its samples by bin (reproject_and_bin)
  int chunks = 0;                  // chunks of this image
  std::vector<PixelShape> shapes;  // per pixel (shape_splats_and_clear_sums)
  std::vector<uint8_t> reach;      // per pixel: ceil(shape.r_y), at most 255 (likewise)
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

  // Notes where this image's pixels lie (read_weights, read_coverage), forgets the previous
  // coverage when the grid moved (its cells would be other pixels') and sizes the sums.
  Grid fit_buffers_to_grid(const FrameSetup& setup, int width, int height) {
    Grid grid;
    grid.width = setup.grid.width;
    grid.height = setup.grid.height;
    grid.origin_x = float(setup.grid.origin_x);
    grid.origin_y = float(setup.grid.origin_y);
    grid_width = grid.width;
    view_x = setup.view_x;
    view_y = setup.view_y;
    out_width = width;
    out_height = height;
    if (!(previous_grid == setup.grid)) {
      previous.reset(grid.width, grid.height);
      previous_grid = setup.grid;
    }
    accum.resize(grid.pixels());
    coverage_next.resize(grid.pixels());
    return grid;
  }

  // [BFMS94]: the newest sample at each pixel, at its original position. Counts the samples
  // placed (splatted), stamped too far ahead (future) and outside the grid (off_screen).
  Counts keep_newest_samples(const FrameSetup& setup, const Grid& grid, double time,
                             double max_future) {
    const int width = grid.width, height = grid.height;
    const float origin_x = grid.origin_x, origin_y = grid.origin_y;
    Counts c;
    newest_age.assign(grid.pixels(), std::numeric_limits<double>::infinity());
    std::fill(accum.begin(), accum.end(), glm::vec4(0.0f));
    for (size_t i = 0; i < stored; ++i) {
      const StoredSample& s = mirror[i];
      const double age = time - s.time;
      if (age < -max_future) {
        ++c.future;
        continue;
      }
      const float x = s.x * setup.scale_x - origin_x, y = s.y * setup.scale_y - origin_y;
      if (!(x >= 0.0f && x < float(width) && y >= 0.0f && y < float(height))) {
        ++c.off_screen;
        continue;
      }
      const size_t p = size_t(int(y)) * size_t(width) + size_t(int(x));
      ++c.splatted;
      const double a = std::max(age, 0.0);
      if (a < newest_age[p]) {
        newest_age[p] = a;
        accum[p] = glm::vec4(s.color, 1.0f);
      }
    }
    previous.reset(width, height);  // no splat sizes to remember
    std::fill(coverage_next.begin(), coverage_next.end(), CoverageCell{});
    return c;
  }

  // shape_splats_and_clear_sums' work on pixels [p0, p1): eight pixels at a time in vector
  // arithmetic (the last group padded with copies, so that every pixel takes the same
  // arithmetic whichever group it falls in), then each pixel's record. The thresholds rule
  // (a baseline for comparison) goes pixel by pixel.
  AFR_HOT_CLONES void shape_pixels(size_t p0, size_t p1, const FrameSetup& setup,
                                   const std::vector<uint32_t>& index_map, float cutoff,
                                   const SplatSizeRule& rule) {
    if (rule.thresholds) {
      shape_pixels_one_by_one(p0, p1, setup, index_map, cutoff, rule);
      return;
    }
    const CoverageCell* cells = previous.valid() ? previous.cells().data() : nullptr;
    const Int8 all = splat8(-1);
    for (size_t q0 = p0; q0 < p1; q0 += 8) {
      const size_t n = std::min<size_t>(8, p1 - q0);
      const TileFilter* f[8];
      float cap[8], count[8], growth_sum[8];
      for (size_t l = 0; l < 8; ++l) {
        const size_t p = q0 + std::min(l, n - 1);
        const uint32_t tile = index_map[p];
        f[l] = &setup.filters[tile];
        cap[l] = setup.radius_caps[tile];
        count[l] = cells != nullptr ? cells[p].count : 0.0f;
        growth_sum[l] = cells != nullptr ? cells[p].growth_sum : 0.0f;
      }
#define AFR_LANES(a) \
  { a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7] }
      const Float8 fsx = {f[0]->sigma_x, f[1]->sigma_x, f[2]->sigma_x, f[3]->sigma_x,
                          f[4]->sigma_x, f[5]->sigma_x, f[6]->sigma_x, f[7]->sigma_x};
      const Float8 fsy = {f[0]->sigma_y, f[1]->sigma_y, f[2]->sigma_y, f[3]->sigma_y,
                          f[4]->sigma_y, f[5]->sigma_y, f[6]->sigma_y, f[7]->sigma_y};
      const Float8 caps = AFR_LANES(cap);
#undef AFR_LANES
      // r_filter = cutoff * max(sigma_x, sigma_y), as std::max.
      const Float8 r_filter = splat8(cutoff) * select8(fsx < fsy, fsy, fsx);
      // splat_radius (coverage_map.h), each branch a selection.
      Float8 g = splat8(1.0f);
      if (cells != nullptr) {
        const Float8 c =
            Float8{count[0], count[1], count[2], count[3], count[4], count[5], count[6], count[7]};
        const Float8 gs = Float8{growth_sum[0], growth_sum[1], growth_sum[2], growth_sum[3],
                                 growth_sum[4], growth_sum[5], growth_sum[6], growth_sum[7]};
        const Int8 hole = (c > splat8(0.0f)) ^ all;
        const Float8 safe_c = select8(hole, splat8(1.0f), c);
        const Float8 mean = gs / safe_c;
        const Float8 base = mean + rule.relax * (1.0f - mean);
        const Float8 up = sqrt8(rule.grow_below / safe_c);
        const Float8 down = sqrt8(sqrt8(rule.shrink_above / safe_c));
        const Float8 grow_g = base * select8(up < splat8(rule.grow), up, splat8(rule.grow));
        const Float8 shrink_g =
            base * select8(down > splat8(rule.shrink), down, splat8(rule.shrink));
        g = select8(hole, splat8(rule.grow),
                    select8(c < splat8(rule.grow_below), grow_g,
                            select8(c > splat8(rule.shrink_above), shrink_g, base)));
      }
      Float8 r = g * r_filter;
      r = select8(r >= splat8(rule.min_radius),
                  select8(r < splat8(rule.max_radius), r, splat8(rule.max_radius)),
                  splat8(rule.min_radius));
      // No wider than std::max({cap, r_filter, min_radius}).
      Float8 widest = select8(caps < r_filter, r_filter, caps);
      widest = select8(widest < splat8(rule.min_radius), splat8(rule.min_radius), widest);
      r = select8(widest < r, widest, r);
      const Float8 q = r / r_filter;
      const Float8 grown = select8(splat8(1.0f) < q, q, splat8(1.0f));
      const Float8 sigma_x = fsx * grown, sigma_y = fsy * grown;
      const Float8 k_x = 0.5f / (sigma_x * sigma_x), k_y = 0.5f / (sigma_y * sigma_y);
      const Float8 cx = splat8(cutoff) * sigma_x, cy = splat8(cutoff) * sigma_y;
      const Float8 r_x = quantize8(select8(cx < r, cx, r));
      const Float8 r_y = quantize8(select8(cy < r, cy, r));
      const Float8 off_x = fast_exp8(-r_x * r_x * k_x), off_y = fast_exp8(-r_y * r_y * k_y);
      const Float8 norm = 1.0f / (sigma_x * sigma_y);
      const Int8 reach8 = ceil_int8(r_y);
      for (size_t l = 0; l < n; ++l) {
        PixelShape& shape = shapes[q0 + l];
        shape.k_x = k_x[l];
        shape.k_y = k_y[l];
        shape.off_x = off_x[l];
        shape.off_y = off_y[l];
        shape.r_x = r_x[l];
        shape.r_y = r_y[l];
        shape.k_t = f[l]->k_t;
        shape.norm = norm[l];
        shape.growth = q[l];  // splat_growth(r, r_filter)
        reach[q0 + l] = uint8_t(std::min(reach8[l], 255));
      }
    }
  }

  // shape_pixels one pixel at a time (the thresholds rule).
  AFR_HOT_CLONES void shape_pixels_one_by_one(size_t p0, size_t p1, const FrameSetup& setup,
                                              const std::vector<uint32_t>& index_map, float cutoff,
                                              const SplatSizeRule& rule) {
    const CoverageCell* cells = previous.valid() ? previous.cells().data() : nullptr;
    for (size_t p = p0; p < p1; ++p) {
      const uint32_t tile = index_map[p];
      const TileFilter& f = setup.filters[tile];
      const float r_filter = cutoff * std::max(f.sigma_x, f.sigma_y);
      // The coverage map's size, no wider than the tile's density calls for (nor than the
      // filter's own radius needs).
      const float r = std::min(splat_radius(cells != nullptr ? cells + p : nullptr, r_filter, rule),
                               std::max({setup.radius_caps[tile], r_filter, rule.min_radius}));
      // A splat the coverage map grew beyond the filter's radius widens its Gaussian by the
      // same factor (keeping its shape); a shrunk one cuts the Gaussian short.
      const float grown = std::max(1.0f, r / r_filter);
      const float sigma_x = f.sigma_x * grown, sigma_y = f.sigma_y * grown;
      PixelShape& shape = shapes[p];
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
      shape.growth = splat_growth(r, r_filter);
      reach[p] = uint8_t(std::min(ceil_int(shape.r_y), 255));
    }
  }

  // Per pixel, what a splat landing there gets (shapes, and reach for binning): its tile's
  // filter and, section 6.2, the size from the previous image's coverage there. Clears this
  // image's sums and coverage while here.
  void shape_splats_and_clear_sums(const FrameSetup& setup, const Grid& grid,
                                   const FilterLimits& limits, const SplatSizeRule& rule,
                                   const std::vector<uint32_t>& index_map) {
    const int width = grid.width, height = grid.height;
    const float cutoff = limits.cutoff;
    shapes.resize(grid.pixels());
    reach.resize(grid.pixels());
    // Tasks over rows of pixels.
    const int row_tasks = std::min(height, pool.size() * 4);
    pool.run(row_tasks, [&](int task) {
      const size_t p0 = size_t(height * task / row_tasks) * size_t(width);
      const size_t p1 = size_t(height * (task + 1) / row_tasks) * size_t(width);
      shape_pixels(p0, p1, setup, index_map, cutoff, rule);
      std::fill(accum.begin() + ptrdiff_t(p0), accum.begin() + ptrdiff_t(p1), glm::vec4(0.0f));
      std::fill(coverage_next.begin() + ptrdiff_t(p0), coverage_next.begin() + ptrdiff_t(p1),
                CoverageCell{});
    });
  }

  // reproject_and_bin's work on the stored samples [begin, end): eight at a time, the
  // projection (Projector::project and the unreprojected position, the same arithmetic) in
  // vector arithmetic, then each sample's checks, record and band.
  AFR_HOT_CLONES void reproject_chunk(size_t begin, size_t end, Counts* counts_out, BinPages* pages,
                                      const Projector& pr, const FrameSetup& setup,
                                      const Grid& grid, const Bands& bands, double time,
                                      double max_future, bool reproject, float guard) {
    const int width = grid.width, height = grid.height;
    const float origin_x = grid.origin_x, origin_y = grid.origin_y;
    Counts& c = *counts_out;
    const Int8 zero = splat8(0), all = splat8(-1);
    for (size_t i0 = begin; i0 < end; i0 += 8) {
      const size_t n = std::min<size_t>(8, end - i0);
      const StoredSample* r[8];
      double age_d[8];
      // The samples kPrefetchAhead on are asked for now: the pass streams the ring, and the
      // hardware's prefetcher alone leaves it waiting on memory (measured: 5-7% of the pass).
      if (i0 + kPrefetchAhead + 8 <= end) {
        for (size_t l = 0; l < 8; ++l) __builtin_prefetch(&mirror[i0 + kPrefetchAhead + l]);
      }
      for (size_t l = 0; l < 8; ++l) {
        r[l] = &mirror[i0 + std::min(l, n - 1)];
        age_d[l] = time - r[l]->time;
      }
      // Field f of the eight samples, as one vector.
#define AFR_LANES(f) \
  { r[0]->f, r[1]->f, r[2]->f, r[3]->f, r[4]->f, r[5]->f, r[6]->f, r[7]->f }
      const Float8 age = {float(age_d[0]), float(age_d[1]), float(age_d[2]), float(age_d[3]),
                          float(age_d[4]), float(age_d[5]), float(age_d[6]), float(age_d[7])};
      const Float8 sx = AFR_LANES(x), sy = AFR_LANES(y);
      const Float8 px = AFR_LANES(position.x), py = AFR_LANES(position.y),
                   pz = AFR_LANES(position.z);
      const Float8 vx = AFR_LANES(velocity.x), vy = AFR_LANES(velocity.y),
                   vz = AFR_LANES(velocity.z);
      const Int8 flags = {int32_t(r[0]->flags), int32_t(r[1]->flags), int32_t(r[2]->flags),
                          int32_t(r[3]->flags), int32_t(r[4]->flags), int32_t(r[5]->flags),
                          int32_t(r[6]->flags), int32_t(r[7]->flags)};
#undef AFR_LANES
      // Projector::project: a hit's point, moved by its velocity over its age when it has one,
      // or a miss's direction, with the current camera.
      const Int8 miss = (flags & int32_t(kStoredMiss)) != zero;
      const Int8 moving = ~miss & ((flags & int32_t(kStoredHasVelocity)) != zero);
      const Float8 fzero = splat8(0.0f);
      const Float8 qx = px + select8(moving, vx * age, fzero);
      const Float8 qy = py + select8(moving, vy * age, fzero);
      const Float8 qz = pz + select8(moving, vz * age, fzero);
      const Float8 dx = qx - select8(miss, fzero, splat8(pr.eye.x));
      const Float8 dy = qy - select8(miss, fzero, splat8(pr.eye.y));
      const Float8 dz = qz - select8(miss, fzero, splat8(pr.eye.z));
      const Float8 z = dx * pr.forward.x + dy * pr.forward.y + dz * pr.forward.z;
      const Int8 in_front =
          select8(miss, pr.orthographic ? zero : Int8(z > splat8(Projector::kMinDirectionZ)),
                  Int8(z >= splat8(pr.znear)));
      const Float8 w = pr.orthographic ? splat8(1.0f) : z;
      const Float8 ix =
          pr.half_width + (dx * pr.axis_x.x + dy * pr.axis_x.y + dz * pr.axis_x.z) / w;
      const Float8 iy =
          pr.half_height - (dx * pr.axis_y.x + dy * pr.axis_y.y + dz * pr.axis_y.z) / w;
      const Float8 max_coordinate = splat8(Projector::kMaxCoordinate);
      const Int8 projects = in_front & (abs8(ix) < max_coordinate) & (abs8(iy) < max_coordinate);
      // Where the sample lands: reprojected, or where it was traced.
      const Int8 moved = reproject ? ((flags & int32_t(kStoredHasPosition)) != zero) : zero;
      const Float8 x8 = select8(moved, quantize8(ix), quantize8(sx * setup.scale_x)) - origin_x;
      const Float8 y8 = select8(moved, quantize8(iy), quantize8(sy * setup.scale_y)) - origin_y;
      const Int8 lost = moved & (projects ^ all);
      // The pixel each lands in (the nearest, beyond the grid) and its splat's reach, read
      // for the eight at once (independent loads, where one at a time would wait for each).
      const Int8 cx = clamp8(floor_int8(x8), width - 1), cy = clamp8(floor_int8(y8), height - 1);
      const Int8 pixel = cy * width + cx;
      uint8_t reach8[8];
      for (size_t l = 0; l < 8; ++l) reach8[l] = reach[size_t(uint32_t(pixel[l]))];
      for (size_t l = 0; l < n; ++l) {
        if (age_d[l] < -max_future) {
          ++c.future;
          continue;
        }
        if (lost[l]) {
          ++c.behind;
          continue;
        }
        const float x = x8[l], y = y8[l];
        if (!(x > -guard && x < float(width) + guard && y > -guard && y < float(height) + guard)) {
          ++c.off_screen;
          continue;
        }
        const uint32_t bin = reach8[l] < bands.height
                                 ? row_bin[size_t(cy[l])] + column_bin[size_t(cx[l])]
                                 : bands.oversize();
        pages->append(bin) = Projected{x, y, std::max(age[l], 0.0f), r[l]->color};
      }
    }
  }

  // Reprojects each stored sample (with `reproject` and a position; else it stays where it
  // was traced) into its chunk's pages of its bin (the block of columns of the band of rows its
  // center falls in, or the oversize bucket). Counts those stamped too far ahead (future),
  // behind the camera (behind) and beyond the guard band around the grid (off_screen).
  Counts reproject_and_bin(const Camera& camera, const FrameSetup& setup, const Grid& grid,
                           const Bands& bands, double time, double max_future, bool reproject,
                           float guard) {
    const size_t n = stored;
    const Projector projector(camera, setup.scaled_width, setup.scaled_height, setup.grid.origin_x,
                              setup.grid.origin_y);
    row_bin.resize(size_t(grid.height));
    for (int y = 0; y < grid.height; ++y) {
      row_bin[size_t(y)] = uint32_t((y + bands.offset) / bands.height) * uint32_t(bands.blocks);
    }
    column_bin.resize(size_t(grid.width));
    for (int x = 0; x < grid.width; ++x) {
      column_bin[size_t(x)] = uint32_t((x + bands.block_offset) / bands.block_width);
    }
    chunks = chunks_for(n, pool.size(), uint32_t(bands.bins()));
    if (binned.size() < size_t(chunks)) binned.resize(size_t(chunks));
    task_counts.assign(size_t(chunks), Counts{});
    pool.run(chunks, [&](int chunk) {
      const size_t begin = n * size_t(chunk) / size_t(chunks);
      const size_t end = n * size_t(chunk + 1) / size_t(chunks);
      BinPages& pages = binned[size_t(chunk)];
      pages.reset(bands.bins());
      reproject_chunk(begin, end, &task_counts[size_t(chunk)], &pages, projector, setup, grid,
                      bands, time, max_future, reproject, guard);
    });
    return sum_counts();
  }

  // Splats the samples of one home band (or of the oversize bucket: band `bands.count`) into
  // the sums and this image's coverage, bin after bin (the band's blocks of columns), each bin's
  // pages chunk after chunk. Counts those splatted and those whose splat covers no pixel
  // (off_screen).
  AFR_HOT_CLONES void splat_band(int band, const Grid& grid, const Bands& bands, float min_wt) {
    Counts& c = task_counts[size_t(band)];
    std::array<float, 2 * int(kSplatRadiusLimit) + 4> wx, wy;
    const uint32_t first =
        band < bands.count ? uint32_t(band) * uint32_t(bands.blocks) : bands.oversize();
    const uint32_t last = band < bands.count ? first + uint32_t(bands.blocks) : first + 1;
    for (uint32_t bin = first; bin < last; ++bin) {
      for (int chunk = 0; chunk < chunks; ++chunk) {
        // The next chain's first page, while this one is splatted.
        if (chunk + 1 < chunks) {
          binned[size_t(chunk) + 1].prefetch_head(bin);
        } else if (bin + 1 < last) {
          binned[0].prefetch_head(bin + 1);
        }
        binned[size_t(chunk)].for_each_page(bin, [&](const Projected* records, uint32_t count) {
          splat_records(records, count, grid, min_wt, &c, wx.data(), wy.data());
        });
      }
    }
  }

  // splat_band's work on `count` records: eight samples at a time (the last group padded with
  // copies, so that every sample goes through the same arithmetic whichever group it falls in:
  // a viewport's pages hold other groups than the whole image's), their shapes, pixel ranges
  // and temporal weights in vector arithmetic; then each sample's splat. wx and wy: room for
  // a splat's column and row weights.
  inline void splat_records(const Projected* records, size_t count, const Grid& grid, float min_wt,
                            Counts* counts, float* wx, float* wy) {
    const int width = grid.width, height = grid.height;
    Counts& c = *counts;
    for (size_t q0 = 0; q0 < count; q0 += 8) {
      const size_t n = std::min<size_t>(8, count - q0);
      // The group's positions and ages, and the shape of the pixel each lands in.
      const Projected* g[8];
      for (size_t l = 0; l < 8; ++l) g[l] = &records[q0 + std::min(l, n - 1)];
#define AFR_LANES(a, f) \
  { a[0]->f, a[1]->f, a[2]->f, a[3]->f, a[4]->f, a[5]->f, a[6]->f, a[7]->f }
      const Float8 x = AFR_LANES(g, x), y = AFR_LANES(g, y), age = AFR_LANES(g, age);
      const Int8 zero = splat8(0);
      const Int8 pixel =
          clamp8(floor_int8(y), height - 1) * width + clamp8(floor_int8(x), width - 1);
      const PixelShape* shape_of[8];
      for (size_t l = 0; l < 8; ++l) shape_of[l] = &shapes[size_t(uint32_t(pixel[l]))];
      const Float8 r_x = AFR_LANES(shape_of, r_x), r_y = AFR_LANES(shape_of, r_y);
      const Float8 k_t = AFR_LANES(shape_of, k_t), norm = AFR_LANES(shape_of, norm);
#undef AFR_LANES
      // Pixels i with |i + 0.5 - x| < r_x, rows likewise.
      const Int8 x0v = floor_int8(x - r_x - 0.5f) + 1, x1v = ceil_int8(x + r_x - 0.5f) - 1;
      const Int8 y0v = floor_int8(y - r_y - 0.5f) + 1, y1v = ceil_int8(y + r_y - 0.5f) - 1;
      const Int8 x0s = select8(x0v < zero, zero, x0v), y0s = select8(y0v < zero, zero, y0v);
      const Int8 x1s = select8(x1v > splat8(width - 1), splat8(width - 1), x1v);
      const Int8 y1s = select8(y1v > splat8(height - 1), splat8(height - 1), y1v);
      // The temporal weight of section 5.1 at each sample's age, at least min_wt, over its
      // splat's Gaussian area.
      const Float8 e = fast_exp8(-age * age * k_t);
      const Float8 w_t8 = select8(e < splat8(min_wt), splat8(min_wt), e) * norm;
      for (size_t l = 0; l < n; ++l) {
        const Projected& s = records[q0 + l];
        const PixelShape& shape = *shape_of[l];
        const int x0 = x0s[l], x1 = x1s[l], y0 = y0s[l], y1 = y1s[l];
        if (x0 > x1 || y0 > y1) {
          ++c.off_screen;
          continue;
        }
        ++c.splatted;
        const float w_t = w_t8[l], g = shape.growth;
#if defined(__SSE2__)
        const Float8 color2 = {s.color.r, s.color.g, s.color.b, 1.0f,
                               s.color.r, s.color.g, s.color.b, 1.0f};
        const Float8 one_g = {1.0f, g, 1.0f, g, 1.0f, g, 1.0f, g};
        if (x1 - x0 < 4 && y1 - y0 < 4 && x0 + 3 < width) {
          // A splat of at most 4 x 4 pixels (most of them): its columns and rows in one 8-lane
          // exp, one group of columns per row, and for one or two columns (about half of the
          // splats) half the sums.
          gaussian_rows_4x4(x0, y0, s.x, s.y, shape, wx, wy);
          const __m128 inside =
              _mm_cmplt_ps(_mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f), _mm_set1_ps(float(x1 - x0 + 1)));
          const __m128 wx4 = _mm_loadu_ps(wx);
          if (x1 - x0 <= 1) {
            for (int j = y0; j <= y1; ++j) {
              const float wyj = wy[size_t(j - y0)];
              if (!(wyj > 0.0f)) continue;
              const Int4 ok = add_two_columns(accum.data() + size_t(j) * size_t(width) + x0, inside,
                                              wx4, wyj * w_t, color2);
              add_coverage2(coverage_next.data() + size_t(j) * size_t(width) + x0, ok, one_g);
            }
          } else {
            for (int j = y0; j <= y1; ++j) {
              const float wyj = wy[size_t(j - y0)];
              if (!(wyj > 0.0f)) continue;
              const Int4 ok = add_four_columns(accum.data() + size_t(j) * size_t(width) + x0,
                                               inside, wx4, wyj * w_t, color2);
              add_coverage4(coverage_next.data() + size_t(j) * size_t(width) + x0, ok, one_g);
            }
          }
          continue;
        }
#endif
        // The Gaussian of every column and row of the splat.
        gaussian_row(x0, x1, s.x, shape.k_x, shape.off_x, wx);
        gaussian_row(y0, y1, s.y, shape.k_y, shape.off_y, wy);
        for (int j = y0; j <= y1; ++j) {
          const float wyj = wy[size_t(j - y0)];
          if (!(wyj > 0.0f)) continue;
          const float wyt = wyj * w_t;
          glm::vec4* acc = accum.data() + size_t(j) * size_t(width);
          CoverageCell* cov = coverage_next.data() + size_t(j) * size_t(width);
          int i = x0;
#if defined(__SSE2__)
          // Four pixels at a time without a branch per pixel.
          for (; i + 3 < width && i <= x1; i += 4) {
            const __m128 inside =
                _mm_cmplt_ps(_mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f), _mm_set1_ps(float(x1 - i + 1)));
            const Int4 ok =
                add_four_columns(acc + i, inside, _mm_loadu_ps(&wx[size_t(i - x0)]), wyt, color2);
            add_coverage4(cov + i, ok, one_g);
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
    }
  }

  // Splats every binned sample: three rounds of bands (by the whole image's band index mod 3:
  // the bands of a round reach no common row), then the oversize bucket on this thread.
  Counts splat_bands(const Grid& grid, const Bands& bands, float min_wt) {
    task_counts.assign(size_t(bands.count) + 1, Counts{});
    for (int round = 0; round < 3; ++round) {
      const int start = ((round - bands.first) % 3 + 3) % 3;  // whole-image band index mod 3
      pool.run((bands.count - start + 2) / 3,
               [&](int k) { splat_band(start + 3 * k, grid, bands, min_wt); });
    }
    splat_band(bands.count, grid, bands, min_wt);
    return sum_counts();
  }

  // The output's pixels into *out (when not nullptr): each grid pixel's sums divided by its
  // weight; where there is none, a hole filled from wider support over the grid (hole_fill.h);
  // anything not finite, 0. Counts the holes, the empty pixels and the non-finite ones.
  Counts normalize_and_fill_holes(const FrameSetup& setup, const Grid& grid, Image* out) {
    const int width = grid.width;
    pyramid.build(accum, width, grid.height);
    const int out_tasks = std::min(out_height, pool.size() * 4);
    task_counts.assign(size_t(out_tasks), Counts{});
    pool.run(out_tasks, [&](int task) {
      Counts& c = task_counts[size_t(task)];
      for (int v = out_height * task / out_tasks; v < out_height * (task + 1) / out_tasks; ++v) {
        const int y = v + setup.view_y;
        const glm::vec4* row = accum.data() + size_t(y) * size_t(width) + size_t(setup.view_x);
        for (int u = 0; u < out_width; ++u) {
          const glm::vec4 a = row[u];
          glm::vec3 color;
          if (a.w > 0.0f) {
            color = glm::vec3(a) / a.w;
          } else {
            ++c.holes;
            if (!pyramid.fill(u + setup.view_x, y, &color)) ++c.empty;
          }
          if (!std::isfinite(color.x) || !std::isfinite(color.y) || !std::isfinite(color.z)) {
            ++c.nonfinite;
            color = glm::vec3(0.0f);
          }
          if (out != nullptr) out->pixels[size_t(v) * size_t(out_width) + size_t(u)] = color;
        }
      }
    });
    return sum_counts();
  }

  // This image's coverage becomes the map the next image sizes its splats from.
  void keep_coverage() {
    previous.cells().swap(coverage_next);
    previous.set_valid(true);
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
  // Each phase's wall time into frame_.cpu.
  frame_.cpu = CpuPhaseTimes{};
  auto mark = std::chrono::steady_clock::now();
  const auto lap = [&mark](double* phase) {
    const auto now = std::chrono::steady_clock::now();
    *phase = std::chrono::duration<double, std::milli>(now - mark).count();
    mark = now;
  };
  // The samples that arrived since the last image join the mirror of the store's ring; the
  // base class places the grid (viewport and margin) and computes each tile's filter.
  SampleStore::Delta delta;
  m.sync(store_, &delta);
  FrameSetup setup;
  prepare_frame(time, width, height, delta, m.staging, &setup);
  // From here on the image is the grid; the output (width x height) is its viewport part.
  const Grid grid = m.fit_buffers_to_grid(setup, width, height);
  const ReconstructionMode current_mode = mode();
  const FilterLimits& limits = config_.filter;
  const double max_future = double(limits.max_future);
  lap(&frame_.cpu.prepare);

  if (current_mode == ReconstructionMode::kTraditionalFrameless) {
    // The baseline [BFMS94]: each pixel shows its newest sample; no filter, no splat sizes.
    const Counts c = m.keep_newest_samples(setup, grid, time, max_future);
    frame_.splatted = c.splatted;
    frame_.off_screen = c.off_screen;
    frame_.future = c.future;
    lap(&frame_.cpu.splat);  // placing the newest samples
  } else {
    // Each pixel's splat shape first: binning needs its reach (a splat taller than a band
    // goes to the oversize bucket).
    m.shape_splats_and_clear_sums(setup, grid, limits, config_.splat, field_.index_map());
    lap(&frame_.cpu.shape);
    const Bands bands =
        bands_for(setup.grid, setup.scaled_width, setup.scaled_height, grid.width, grid.height);
    // Where each sample lands now, and its bin. Samples within the guard band beyond the grid
    // (whole pixels, as the GL backend's viewport) are kept: their splats may reach it.
    const Counts binned = m.reproject_and_bin(camera, setup, grid, bands, time, max_future,
                                              current_mode == ReconstructionMode::kAdaptive,
                                              float(splat_guard_band(config_.splat)));
    lap(&frame_.cpu.reproject);
    // Sections 5.1 and 6.2: the Gaussian splats, in rounds of bands that share no row: no
    // locks, and each pixel's sums in an order that does not depend on the thread count.
    const Counts splats = m.splat_bands(grid, bands, limits.min_temporal_weight);
    lap(&frame_.cpu.splat);
    frame_.splatted = splats.splatted;
    frame_.behind_camera = binned.behind;
    frame_.off_screen = binned.off_screen + splats.off_screen;
    frame_.future = binned.future;
  }

  // The image: each pixel's weighted mean, holes filled from wider support.
  const Counts pixels = m.normalize_and_fill_holes(setup, grid, out);
  frame_.hole_pixels = pixels.holes;
  frame_.empty_pixels = pixels.empty;
  frame_.nonfinite_pixels = pixels.nonfinite;
  lap(&frame_.cpu.fill);
  // The next image sizes its splats from this one's coverage (the baseline sizes none).
  if (current_mode != ReconstructionMode::kTraditionalFrameless) m.keep_coverage();
}

}  // namespace afr
