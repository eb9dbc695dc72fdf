#include <afr/display/reconstructor.h>

#include <afr/common/error.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace afr {

namespace {

size_t checked_capacity(const ReconstructorConfig& c) {
  if (c.image_width < 1 || c.image_height < 1 || c.image_width > 32768 || c.image_height > 32768) {
    throw Error(fmt::format("reconstructor: sampling image {}x{} is outside 1..32768 a side",
                            c.image_width, c.image_height));
  }
  const size_t n =
      c.capacity != 0 ? c.capacity : 4 * size_t(c.image_width) * size_t(c.image_height);
  if (n > kMaxCapacity) {
    throw Error(fmt::format("reconstructor: capacity {} exceeds the limit {}", n, kMaxCapacity));
  }
  return n;
}

}  // namespace

Reconstructor::Reconstructor(const ReconstructorConfig& config)
    : config_(config),
      store_(checked_capacity(config)),
      field_(config.image_width, config.image_height),
      mode_(config.mode) {
  config_.capacity = store_.capacity();
  slot_pixel_.assign(store_.capacity(), kNoPixel);
  pixel_count_.assign(size_t(config.image_width) * size_t(config.image_height), 0u);
  count_table_.assign(size_t(config.image_width + 1) * size_t(config.image_height + 1), 0u);
  SplatSizeRule& rule = config_.splat;
  rule.max_radius = std::clamp(rule.max_radius, 1.0f, kSplatRadiusLimit);
  rule.min_radius = std::clamp(rule.min_radius, 0.5f, rule.max_radius);
  if (!(config_.filter.cutoff >= 1.0f && config_.filter.cutoff <= 8.0f)) {
    throw Error("reconstructor: the filter cutoff must be in [1, 8] standard deviations");
  }
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

void Reconstructor::count_fresh_samples(const SampleStore::Delta& delta,
                                        const std::vector<StoredSample>& fresh) {
  const int W = config_.image_width, H = config_.image_height;
  RingRun runs[2];
  const int k = ring_runs(delta.first, delta.end, slot_pixel_.size(), runs);
  for (int r = 0; r < k; ++r) {
    for (size_t j = 0; j < runs[r].count; ++j) {
      uint32_t& slot = slot_pixel_[runs[r].slot + j];
      if (slot != kNoPixel) --pixel_count_[slot];
      const StoredSample& s = fresh[runs[r].offset + j];
      // (NaN and far-away positions were rejected at the door; the comparisons keep the
      // cast in range anyway.)
      if (s.x >= 0.0f && s.y >= 0.0f && s.x < float(W) && s.y < float(H)) {
        const int x = std::min(int(s.x), W - 1), y = std::min(int(s.y), H - 1);
        slot = uint32_t(y) * uint32_t(W) + uint32_t(x);
        ++pixel_count_[slot];
      } else {
        slot = kNoPixel;
      }
    }
  }
  // The summed-area table: entry (x, y) counts the samples in [0, x) x [0, y).
  const size_t stride = size_t(W) + 1;
  for (int y = 0; y < H; ++y) {
    uint64_t row = 0;
    const uint64_t* above = count_table_.data() + size_t(y) * stride;
    uint64_t* here = count_table_.data() + size_t(y + 1) * stride;
    for (int x = 0; x < W; ++x) {
      row += pixel_count_[size_t(y) * size_t(W) + size_t(x)];
      here[x + 1] = above[x + 1] + row;
    }
  }
}

uint64_t Reconstructor::stored_in(const PixelRect& rect) const {
  const size_t stride = size_t(config_.image_width) + 1;
  const auto at = [&](int32_t x, int32_t y) {
    return count_table_[size_t(y) * stride + size_t(x)];
  };
  return at(rect.x1, rect.y1) - at(rect.x0, rect.y1) - at(rect.x1, rect.y0) + at(rect.x0, rect.y0);
}

void Reconstructor::prepare_frame(double time, int width, int height,
                                  const SampleStore::Delta& delta,
                                  const std::vector<StoredSample>& fresh, FrameSetup* setup) {
  const FilterLimits& limits = config_.filter;
  setup->time = time;
  setup->width = width;
  setup->height = height;
  setup->scale_x = float(width) / float(config_.image_width);
  setup->scale_y = float(height) / float(config_.image_height);
  setup->field_changed = field_.update(width, height);
  count_fresh_samples(delta, fresh);

  // How far back the store reaches, and the mean rate it was filled at: the cap of e_t and the
  // rate of pixels no tile with a known rate covers.
  const double reach = delta.stored > 0 ? time - delta.oldest_time : 0.0;
  const double depth =
      std::clamp(std::isfinite(reach) ? reach : 0.0, double(limits.min_temporal_extent),
                 double(limits.max_temporal_extent));
  const double pixels = double(config_.image_width) * double(config_.image_height);
  const double rate = double(delta.stored) / (pixels * depth);
  frame_.stored = delta.stored;
  frame_.depth = float(depth);
  frame_.default_rate = float(rate);

  const std::vector<FieldTile>& tiles = field_.tiles();
  setup->filters.resize(tiles.size());
  for (size_t i = 0; i < tiles.size(); ++i) {
    const FieldTile& t = tiles[i];
    // R_l: the samples the store holds in the tile, over its area and the store's depth. The
    // sampler's rate is what it expects to send there; after a retiling (new tiles, regions
    // moved between samplers) the store's samples were taken under other tiles and can be far
    // fewer or more. A tile with no stored sample keeps the sampler's rate (samples
    // reprojected into it still need a filter), and pixels no tile covers the store's mean.
    float R_l = t.rate > 0.0f ? t.rate : float(rate);
    if (i > 0 && !t.rect.empty()) {
      const uint64_t inside = stored_in(t.rect);
      if (inside > 0) R_l = float(double(inside) / (double(t.rect.area()) * depth));
    }
    setup->filters[i] =
        make_tile_filter(filter_extents(t.G_x, t.G_y, t.G_t, R_l, float(depth), limits),
                         setup->scale_x, setup->scale_y);
  }
}

}  // namespace afr
