#include <afr/display/reconstructor.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <thread>

namespace afr {

namespace {

// The config with its viewport, margin, splat rule and capacity resolved and checked.
ReconstructorConfig resolved(const ReconstructorConfig& config) {
  ReconstructorConfig c = config;
  if (c.image.width < 1 || c.image.height < 1 || c.image.width > 32768 || c.image.height > 32768) {
    throw Error(fmt::format("reconstructor: sampling image {}x{} is outside 1..32768 a side",
                            c.image.width, c.image.height));
  }
  SplatSizeRule& rule = c.splat;
  rule.max_radius = std::clamp(rule.max_radius, 1.0f, kSplatRadiusLimit);
  rule.min_radius = std::clamp(rule.min_radius, 0.5f, rule.max_radius);
  if (!(rule.grow >= 1.0f && rule.grow <= 64.0f && rule.shrink > 0.0f && rule.shrink <= 1.0f &&
        rule.relax >= 0.0f && rule.relax <= 1.0f && rule.grow_below >= 0.0f &&
        rule.shrink_above >= rule.grow_below)) {
    throw Error(fmt::format(
        "reconstructor: splat rule grow {} (1..64), shrink {} ((0, 1]), relax {} ([0, 1]), band "
        "[{}, {}] is out of range",
        rule.grow, rule.shrink, rule.relax, rule.grow_below, rule.shrink_above));
  }
  if (!(c.filter.cutoff >= 1.0f && c.filter.cutoff <= 8.0f)) {
    throw Error("reconstructor: the filter cutoff must be in [1, 8] standard deviations");
  }
  const PixelRect image{0, 0, c.image.width, c.image.height};
  if (c.viewport == PixelRect{}) c.viewport = image;
  const PixelRect& v = c.viewport;
  if (v.empty() || v.x0 < 0 || v.y0 < 0 || v.x1 > image.x1 || v.y1 > image.y1) {
    throw Error(
        fmt::format("reconstructor: viewport [{}, {}) x [{}, {}) is empty or not inside "
                    "the {}x{} sampling image",
                    v.x0, v.x1, v.y0, v.y1, c.image.width, c.image.height));
  }
  if (c.viewport_margin == -1) c.viewport_margin = auto_viewport_margin(rule);
  if (c.viewport_margin < 0 || c.viewport_margin > 32768) {
    throw Error(fmt::format("reconstructor: viewport margin {} is outside 0..32768 (or -1)",
                            c.viewport_margin));
  }
  return c;
}

PixelRect grown(const ReconstructorConfig& c) {
  const int m = c.viewport_margin;
  return PixelRect{std::max(0, c.viewport.x0 - m), std::max(0, c.viewport.y0 - m),
                   std::min(c.image.width, c.viewport.x1 + m),
                   std::min(c.image.height, c.viewport.y1 + m)};
}

size_t checked_capacity(const ReconstructorConfig& c) {
  const size_t n = c.capacity != 0 ? c.capacity : 4 * size_t(grown(c).area());
  if (n > kMaxCapacity) {
    throw Error(fmt::format("reconstructor: capacity {} exceeds the limit {}", n, kMaxCapacity));
  }
  return n;
}

// The grid's margins are at most this many output pixels (an upscaled output would otherwise
// reconstruct margin x scale pixels, far more than any splat reaches), and its origin is
// aligned to this many.
constexpr int kMaxGridMargin = 4 * int(kSplatRadiusLimit);
constexpr int kGridAlign = 32;
// New samples from which a frame's count update runs on a worker thread (a thread start costs
// tens of microseconds; 4096 pairs, about 0.2 ms of counting).
constexpr size_t kCountsOnAWorker = 4096;

// One axis of the grid: the viewport [v0, v1) of an image `side` sampling pixels wide, shown
// as `out` output pixels (scale s), with `margin` sampling pixels around it.
void place_axis(int32_t v0, int32_t v1, int32_t side, int out, int margin, int max_margin,
                int* offset, int* size, double* origin) {
  const double s = double(out) / double(v1 - v0);
  const double start = double(v0) * s;  // the viewport's first output pixel in the whole image
  const int m = int(std::min(std::ceil(double(margin) * s), double(max_margin)));
  // Whole output pixels between the image's edges and the viewport's.
  const int room_before = int(std::floor(start + 1e-9));
  const int room_after = int(std::floor(double(side - v1) * s + 1e-9));
  int before = std::min(m, room_before);
  const double nearest = std::round(start);
  if (std::abs(start - nearest) < 1e-9) {
    // The viewport starts on a pixel of the whole image's grid: start the margin on a multiple
    // of kGridAlign there (or at the image's edge).
    const int64_t first = int64_t(nearest) - m;
    const int64_t aligned = first >= 0 ? first / kGridAlign * kGridAlign : 0;
    before = int(int64_t(nearest) - aligned);
  }
  *offset = before;
  *size = before + out + std::min(m, room_after);
  *origin = start - double(before);
}

}  // namespace

Reconstructor::Reconstructor(const ReconstructorConfig& config)
    : config_(resolved(config)),
      received_(grown(config_)),
      store_(checked_capacity(config_)),
      field_(config_.image.width, config_.image.height),
      mode_(config_.mode),
      counts_(received_, store_.capacity()),
      count_threads_(config_.threads > 0
                         ? std::min(config_.threads, 256)
                         : std::clamp(int(std::thread::hardware_concurrency()), 1, 256)) {
  config_.capacity = store_.capacity();
}

Reconstructor::~Reconstructor() = default;

void Reconstructor::reconstruct(const Camera& camera, double time, int width, int height,
                                Image* out) {
  if (width < 1 || height < 1 || width > kMaxOutputSide || height > kMaxOutputSide) {
    throw Error(fmt::format("reconstruct: output {}x{} is outside 1..{} a side", width, height,
                            kMaxOutputSide));
  }
  if (!std::isfinite(time)) throw Error("reconstruct: the display time is not finite");
  const auto start = std::chrono::steady_clock::now();
  if (out != nullptr && (out->width != width || out->height != height)) {
    *out = Image(width, height);
  }
  frame_ = FrameStats{};
  do_reconstruct(camera, time, width, height, out);
  frame_.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

Image Reconstructor::reconstruct(const Camera& camera, double time, int width, int height) {
  Image image(width, height);
  reconstruct(camera, time, width, height, &image);
  return image;
}

void Reconstructor::place_grid(int width, int height, FrameSetup* setup) const {
  const PixelRect& v = config_.viewport;
  const int margin = config_.viewport_margin;
  PixelGrid& g = setup->grid;
  place_axis(v.x0, v.x1, config_.image.width, width, margin, kMaxGridMargin, &setup->view_x,
             &g.width, &g.origin_x);
  place_axis(v.y0, v.y1, config_.image.height, height, margin, kMaxGridMargin, &setup->view_y,
             &g.height, &g.origin_y);
  g.scale_x = double(width) / double(v.width());
  g.scale_y = double(height) / double(v.height());
  // (Exactly width and height for the whole image.)
  setup->scaled_width = double(width) * double(config_.image.width) / double(v.width());
  setup->scaled_height = double(height) * double(config_.image.height) / double(v.height());
}

void Reconstructor::prepare_frame(double time, int width, int height,
                                  const SampleStore::Delta& delta,
                                  const std::vector<StoredSample>& fresh, FrameSetup* setup,
                                  const std::function<void()>& meanwhile) {
  const FilterLimits& limits = config_.filter;
  setup->time = time;
  setup->width = width;
  setup->height = height;
  // The stored samples per block, moved by those that entered the ring and those they
  // replaced (a cache miss each: the frame's largest CPU cost at N = 4 x pixels turned over
  // once a second), on a worker while this thread places the grid and the tile field and runs
  // `meanwhile`; then per tile. (The future's destructor waits for the worker should anything
  // here throw.)
  std::future<void> counted;
  if (delta.end - delta.first >= kCountsOnAWorker) {
    counted = std::async(std::launch::async, [&] { counts_.update(delta, fresh, count_threads_); });
  } else {
    counts_.update(delta, fresh);
  }
  place_grid(width, height, setup);
  setup->scale_x = float(setup->grid.scale_x);
  setup->scale_y = float(setup->grid.scale_y);
  setup->field_changed = field_.update(setup->grid);
  if (meanwhile) meanwhile();
  if (counted.valid()) counted.get();
  counts_.count_tiles(field_.tiles(), count_threads_);

  // How far back the store reaches, and the mean rate it was filled at: the cap of e_t and the
  // rate of pixels no tile with a known rate covers.
  const double reach = delta.stored > 0 ? time - delta.oldest_time : 0.0;
  const double depth =
      std::clamp(std::isfinite(reach) ? reach : 0.0, double(limits.min_temporal_extent),
                 double(limits.max_temporal_extent));
  const double pixels = double(received_.area());
  const double rate = double(counts_.total()) / (pixels * depth);
  frame_.stored = delta.stored;
  frame_.depth = float(depth);
  frame_.default_rate = float(rate);

  const std::vector<FieldTile>& tiles = field_.tiles();
  setup->filters.resize(tiles.size());
  setup->radius_caps.resize(tiles.size());
  tile_states_.resize(tiles.size());
  for (size_t i = 0; i < tiles.size(); ++i) {
    const FieldTile& t = tiles[i];
    // R_l: the samples the store holds in the tile, over its area and the store's depth, both
    // counted inside the received region (a wall node gets no samples outside it). The
    // sampler's rate is what it expects to send there; after a retiling (new tiles, regions
    // moved between samplers) the store's samples were taken under other tiles and can be far
    // fewer or more. A tile with no stored sample keeps the sampler's rate (samples
    // reprojected into it still need a filter), and pixels no tile covers the store's mean.
    float R_l = t.rate > 0.0f ? t.rate : float(rate);
    const uint64_t inside = counts_.count(i);
    if (inside > 0) R_l = float(double(inside) / (double(counts_.area(i)) * depth));
    const FilterExtents e = filter_extents(t.G_x, t.G_y, t.G_t, R_l, float(depth), limits);
    setup->filters[i] = make_tile_filter(e, setup->scale_x, setup->scale_y);
    const double area_out = double(counts_.area(i)) * double(setup->scale_x) * setup->scale_y;
    setup->radius_caps[i] =
        splat_density_cap(area_out > 0.0 ? float(double(inside) / area_out) : 0.0f, config_.splat);
    TileState& state = tile_states_[i];
    state.rect = t.rect;
    state.counted = intersect(t.rect, received_);
    state.stored = inside;
    state.rate = R_l;
    state.extents = e;
  }
}

void Reconstructor::check_coverage_size(const PixelRect& rect,
                                        const std::vector<CoverageCell>& cells) {
  if (rect.empty() ? !cells.empty() : cells.size() != size_t(rect.area())) {
    throw Error(fmt::format("write_coverage: {} cells for a {} x {} rectangle", cells.size(),
                            std::max(rect.width(), 0), std::max(rect.height(), 0)));
  }
}

PixelRect grid_part(const PixelGrid& grid, const PixelRect& rect) {
  const double ox = std::floor(grid.origin_x), oy = std::floor(grid.origin_y);
  if (ox != grid.origin_x || oy != grid.origin_y) return PixelRect{};
  // Both in grid pixels; the grid's origin is at most kMaxOutputSide plus a margin.
  const int32_t gx = int32_t(ox), gy = int32_t(oy);
  return intersect(PixelRect{rect.x0 - gx, rect.y0 - gy, rect.x1 - gx, rect.y1 - gy},
                   PixelRect{0, 0, grid.width, grid.height});
}

}  // namespace afr
