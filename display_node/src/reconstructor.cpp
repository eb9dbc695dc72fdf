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

void Reconstructor::prepare_frame(double time, int width, int height,
                                  const SampleStore::Delta& delta, FrameSetup* setup) {
  const FilterLimits& limits = config_.filter;
  setup->time = time;
  setup->width = width;
  setup->height = height;
  setup->scale_x = float(width) / float(config_.image_width);
  setup->scale_y = float(height) / float(config_.image_height);
  setup->field_changed = field_.update(width, height);

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
    const float R_l = t.rate > 0.0f ? t.rate : float(rate);
    setup->filters[i] =
        make_tile_filter(filter_extents(t.G_x, t.G_y, t.G_t, R_l, float(depth), limits),
                         setup->scale_x, setup->scale_y);
  }
}

}  // namespace afr
