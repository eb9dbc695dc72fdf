#include <afr/sampler/sampler.h>

#include <afr/common/check.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace afr {

namespace {

// Re-derive a tile's sums from the buffer when a new weight would exceed exp(kAgeDecay * this)
// relative to the tile's reference time (about 1e30 at 20 s): keeps the sums far from
// overflow, and old weights are re-based instead of underflowing one by one.
constexpr double kMaxReferenceAge = 20.0;
// Cells of half this many pixels up to about this many keep statistics of their own, from which
// a tile's block is summed instead of visiting its crosshairs (4x4 pixels on 256x256).
constexpr int kCellPixels = 32;
// The smallest time difference a temporal gradient divides by (guards t - t0 near zero).
constexpr double kMinTemporalSeconds = 1e-4;
// At the target tile count, the worst tile is split and the best pair merged only while the
// worst error exceeds the pair's by this factor: splitting halves an error and merging adds
// two, so a factor of 2 would be the break-even; more damps churn.
constexpr double kBalanceRatio = 3.0;
// Reprojections that move a crosshair less than this (pixels) leave its temporal gradient.
constexpr double kMinMoveForTemporal = 1e-3;
// The smallest pixel distance a reprojected spatial gradient divides by.
constexpr double kMinPixelDistance = 0.25;
// A removal or a split that leaves less than this fraction of a block's weight (w, or wt) has
// left mostly rounding: 1 + 1e-45 - 1 is 0 in double. Such sums are re-derived at once.
constexpr double kCancellation = 1e-6;
// `TileSums::updates` at or above this asks for a re-derivation before the sums are next read.
constexpr int32_t kRederiveNow = std::numeric_limits<int32_t>::max() / 2;
// The scene time moves again only after this many times what its last move took by the
// sampler's clock (advance_scene_time): moving takes at most about 1/9 of the sampler's time.
constexpr double kTimeStepPerMoveCost = 8.0;

float sample_luminance(const ShadedSample& s) { return luminance(s.color); }

// Adds (sign +1) or removes (sign -1) a crosshair to the sums of a block. A block that was empty
// takes the crosshair's time as reference and its luminance as shift.
void add_to_sums(TileSums& s, const CrosshairStats& c, double sign) {
  if (sign > 0.0 && s.count == 0) {
    s = TileSums{};
    s.t_ref = c.time;
    s.shift = c.luminance;
  }
  const double w = std::exp(kAgeDecay * (c.time - s.t_ref));
  const double d = double(c.luminance) - s.shift;
  const double w_before = s.w, wt_before = s.wt, wo_before = s.wo;
  s.w += sign * w;
  s.wl += sign * w * d;
  s.wll += sign * w * d * d;
  s.wgx += sign * w * c.G_x;
  s.wgy += sign * w * c.G_y;
  if (c.has(Crosshair::kHasTemporalGradient)) {
    s.wt += sign * w;
    s.wgt += sign * w * c.G_t;
    s.temporal += sign > 0.0 ? 1 : -1;
    if (s.temporal == 0) s.wt = s.wgt = 0.0;  // exactly, not the rounding of what was taken
  }
  s.t_sum += sign * (c.time - s.t_ref);
  s.count += sign > 0.0 ? 1 : -1;
  if (c.has(Crosshair::kOccluded)) {
    s.wo += sign * w;
    s.occluded += sign > 0.0 ? 1 : -1;
    if (s.occluded == 0) s.wo = 0.0;
  }
  ++s.updates;
  if (c.time - s.t_ref > kMaxReferenceAge) s.updates = kRederiveNow;
  // The crosshair held nearly all of the weight (crosshairs of a block seconds apart): what is
  // left is rounding, not the weight of the others.
  if (sign < 0.0 && s.count > 0 &&
      (s.w < kCancellation * w_before || (s.temporal > 0 && s.wt < kCancellation * wt_before) ||
       (s.occluded > 0 && s.wo < kCancellation * wo_before))) {
    s.updates = kRederiveNow;
  }
}

// Sums that add and subtract drift: they are re-derived once the updates outnumber the block,
// when new weights grow too large against the reference time, or after a cancellation.
bool needs_rederive(const TileSums& s) { return s.updates > 4 * s.count + 64; }

// The shift a re-derivation of `old` takes: its weighted mean, which keeps the squares small.
// Sums marked for re-derivation may be rounding only (see kCancellation), so they keep their
// shift, a luminance of the block.
double rederive_shift(const TileSums& old) {
  if (old.count <= 0) return 0.0;
  if (old.updates >= kRederiveNow || !(old.w > 0.0)) return old.shift;
  const double mean = old.shift + old.wl / old.w;
  return std::isfinite(mean) ? mean : old.shift;
}

// The sums of the crosshairs of a block, straight from the deep buffer, with the newest as
// reference time.
TileSums sums_from_buffer(const DeepBuffer& buffer, const PixelRect& rect, double shift) {
  TileSums s;
  s.shift = shift;
  double newest = -std::numeric_limits<double>::infinity();
  // Not only the front: reprojected crosshairs go to the back of their queue.
  buffer.for_each_stats(rect, [&](const CrosshairStats& c) { newest = std::max(newest, c.time); });
  if (!std::isfinite(newest)) return s;
  s.t_ref = newest;
  buffer.for_each_stats(rect, [&](const CrosshairStats& c) {
    const double w = std::exp(kAgeDecay * (c.time - s.t_ref));
    const double d = double(c.luminance) - s.shift;
    s.w += w;
    s.wl += w * d;
    s.wll += w * d * d;
    s.wgx += w * c.G_x;
    s.wgy += w * c.G_y;
    if (c.has(Crosshair::kHasTemporalGradient)) {
      s.wt += w;
      s.wgt += w * c.G_t;
      ++s.temporal;
    }
    s.t_sum += c.time - s.t_ref;
    ++s.count;
    if (c.has(Crosshair::kOccluded)) {
      s.wo += w;
      ++s.occluded;
    }
  });
  return s;
}

// The temporal gradient of a block straight from the deep buffer: the weighted mean of G_t over
// its crosshairs that have one, weights relative to the newest of those. For a block whose sums
// lost them (below).
double temporal_gradient_from_buffer(const DeepBuffer& buffer, const PixelRect& rect) {
  double newest = -std::numeric_limits<double>::infinity();
  buffer.for_each_stats(rect, [&](const CrosshairStats& c) {
    if (c.has(Crosshair::kHasTemporalGradient)) newest = std::max(newest, c.time);
  });
  if (!std::isfinite(newest)) return 0.0;
  double wt = 0.0, wgt = 0.0;
  buffer.for_each_stats(rect, [&](const CrosshairStats& c) {
    if (!c.has(Crosshair::kHasTemporalGradient)) return;
    const double w = std::exp(kAgeDecay * (c.time - newest));
    wt += w;
    wgt += w * c.G_t;
  });
  return wt > 0.0 ? std::max(0.0, wgt / wt) : 0.0;
}

// The sums of a block made of `n` disjoint blocks, moved to a common shift and to the newest of
// their reference times. Every part's own weights stay below exp(kAgeDecay * kMaxReferenceAge)
// and the factors below 1, so nothing overflows.
TileSums sums_from_parts(const TileSums* parts, int n, double shift) {
  TileSums out;
  out.shift = shift;
  double newest = -std::numeric_limits<double>::infinity();
  for (int k = 0; k < n; ++k) {
    if (parts[k].count > 0) newest = std::max(newest, parts[k].t_ref);
  }
  if (!std::isfinite(newest)) return out;
  out.t_ref = newest;
  for (int k = 0; k < n; ++k) {
    const TileSums& s = parts[k];
    if (s.count <= 0) continue;
    const double f = std::exp(kAgeDecay * (s.t_ref - out.t_ref));
    const double d = s.shift - out.shift;
    out.w += f * s.w;
    out.wl += f * (s.wl + d * s.w);
    out.wll += f * (s.wll + 2.0 * d * s.wl + d * d * s.w);
    out.wgx += f * s.wgx;
    out.wgy += f * s.wgy;
    out.wt += f * s.wt;
    out.wgt += f * s.wgt;
    out.t_sum += s.t_sum + s.count * (s.t_ref - out.t_ref);
    out.count += s.count;
    out.wo += f * s.wo;
    out.temporal += s.temporal;
    out.occluded += s.occluded;
  }
  return out;
}

// What the deep buffer keeps of a crosshair: only what the run reads. Reprojection (every step
// with r > 0, and reproject() when called) reads positions and neighbours, and velocities and
// the spaces of points where something moves (the tracer gives zero velocity and no moving
// node elsewhere); nothing reads the old sample back. The baselines never fill the buffer.
uint32_t buffer_fields(const SamplerConfig& config, const Scene& scene) {
  if (config.mode != SamplerMode::kAdaptive) return 0;
  if (!scene.has_moving_geometry()) return kKeepReprojection;
  return kKeepReprojection | kKeepVelocity |
         (config.crosshair_motion == CrosshairMotion::kTransform ? kKeepSpaces : 0u);
}

// A traced point as a crosshair keeps it (Crosshair::space): with CrosshairMotion::kTransform
// in the space of the node it hit when that node moves rigidly, in the world otherwise.
glm::vec3 kept_point(const Tracer& tracer, CrosshairMotion motion, const ShadedSample& s,
                     uint32_t* space) {
  glm::dmat4 inverse;
  if (motion == CrosshairMotion::kTransform && s.hit &&
      tracer.rigid_transform(s.object_id, nullptr, &inverse)) {
    *space = s.object_id;
    return glm::vec3(inverse * glm::dvec4(glm::dvec3(s.position), 1.0));
  }
  *space = Crosshair::kWorld;
  return s.position;
}

}  // namespace

Sampler::Sampler(const Scene& scene, Tracer& tracer, Clock& clock, const SamplerConfig& config,
                 SampleSink& sink)
    : scene_(scene),
      tracer_(tracer),
      clock_(clock),
      config_((config.validate(), config)),
      sink_(sink),
      region_(config.owned_region()),
      rng_(mix_seed(config.seed), mix_seed(uint64_t(config.sampler_id) + 1)),
      tiling_(region_, 40, kCellPixels),
      buffer_(region_, config.b, buffer_fields(config, scene)),
      cells_(size_t(tiling_.cell_count())) {
  if (config_.r > 0) fields_ |= kFieldPosition;
  if (config_.r > 0 && scene.has_moving_geometry()) fields_ |= kFieldVelocity;
  batch_.sampler_id = config_.sampler_id;
  batch_.fields = fields_;
  batch_.samples.reserve(size_t(config_.batch_size));
  requested_min_tiles_ = config_.min_tiles;
  requested_max_tiles_ = config_.max_tiles;
  bound_tiles();
  target_tiles_ = config_.min_tiles;
  max_x_ = std::nextafter(float(config_.image.width), 0.0f);
  max_y_ = std::nextafter(float(config_.image.height), 0.0f);
}

void Sampler::bound_tiles() {
  const int64_t pixels = region_.area();
  config_.max_tiles =
      int(std::max<int64_t>(1, std::min<int64_t>(requested_max_tiles_, pixels / 4)));
  config_.min_tiles = std::min(requested_min_tiles_, config_.max_tiles);
}

// ---------------------------------------------------------------------------------------------
// The loop

void Sampler::advance_scene_time() {
  const double t = clock_.now();
  if (!scene_time_set_ || std::abs(t - scene_time_) >= time_step_) {
    // The clock runs on for ever; with loop_animation the scene repeats its keyframe range.
    const double duration = scene_.duration();
    tracer_.set_time(config_.loop_animation && duration > 0.0 ? std::fmod(t, duration) : t);
    camera_ = tracer_.camera();
    if (camera_source_) {
      if (std::optional<Camera> c = camera_source_->camera_at(t)) {
        camera_ = *c;
        tracer_.set_view(camera_);  // a headlight goes where this sampler looks from
      }
    }
    view_half_ = camera_.orthographic() ? camera_.ymag : std::tan(0.5 * camera_.yfov);
    scene_time_ = t;
    scene_time_set_ = true;
    // Moving a deforming mesh to a new time takes the tracer a while (a large skinned mesh,
    // milliseconds). Were the time to move again at the next step, the sampler would do little
    // else: the next move waits until the clock has gone on kTimeStepPerMoveCost times what
    // this one took by the clock, so that moving takes at most about 1 / (1 + that) of the
    // sampler's time. Samples keep the scene time they were traced at. Cheap moves (static and
    // rigid scenes) and clocks that advance only with traced rays leave animation_step as is.
    time_step_ = std::max(config_.animation_step, kTimeStepPerMoveCost * (clock_.now() - t));
  }
}

void Sampler::fill() {
  filled_ = true;
  handover_.clear();
  advance_scene_time();
  const double t0 = clock_.now();
  last_snapshot_time_ = t0;
  if (config_.mode == SamplerMode::kAdaptive) {
    // Section 4.2: a gridded, cotemporal pattern. Every crosshair is traced at scene time t0.
    std::array<ShadedSample, 5> s;
    for (int32_t y = region_.y0; y < region_.y1; y += config_.fill_step) {
      for (int32_t x = region_.x0; x < region_.x1; x += config_.fill_step) {
        trace_crosshair(x + 0.5, y + 0.5, &s);
        Crosshair c = make_crosshair(x + 0.5, y + 0.5, s);
        c.time = t0;
        insert_front(c);
      }
    }
    build_tiling(config_.min_tiles);  // no temporal gradients yet: start from the fewest
  }
  flush();
}

void Sampler::build_tiling(int tiles) {
  for (int cell = 0; cell < tiling_.cell_count(); ++cell) rederive_cell(cell);
  rederive(tiling_.root());
  compute_errors();
  target_tiles_ = std::clamp(tiles, config_.min_tiles, config_.max_tiles);
  while (tiling_.tile_count() < target_tiles_) {
    int best = -1;
    for (int t : tiling_.tiles()) {
      if (tiling_.can_split(t) && (best == -1 || error_[t] > error_[best])) best = t;
    }
    if (best == -1) break;
    int a, b;
    tiling_.split(best, &a, &b);
    on_split(best, a, b);
  }
}

// The tiling is rebuilt rather than clipped: a clipped K-D tree over the new region would have
// leaves that no split of the new root makes, and cells that no longer form its complete tree,
// so every invariant the statistics rest on (a tile is a run of cells, a split halves the longer
// side) would need exceptions. A new tree seeded from the kept crosshairs costs one pass over
// the kept pixels and a few hundred splits, once per recut.
void Sampler::set_region(const PixelRect& region) {
  AFR_CHECK(!region.empty() && intersect(region, config_.image.rect()) == region);
  if (region == region_) return;
  const PixelRect old = region_;
  const int old_tiles = tiling_.tile_count();
  region_ = region;
  config_.region = region;
  bound_tiles();
  DeepBuffer kept(region_, config_.b, buffer_.fields());
  kept.copy_pixels(buffer_, intersect(old, region_));
  buffer_ = std::move(kept);
  tiling_ = KdTiling(region_, 40, kCellPixels);
  cells_.assign(size_t(tiling_.cell_count()), TileSums{});
  records_.clear();  // pending crosshairs go with their tiles
  error_.clear();
  chunk_progress_ = 0;
  sweep_next_ = 0;
  handover_.clear();
  if (!filled_ || config_.mode != SamplerMode::kAdaptive) {
    target_tiles_ = config_.min_tiles;
    return;
  }
  // Section 4.2's grid over the new region, where the old one did not reach; in random order,
  // so that a part of the fill is spread over all of the gained pixels.
  for (int32_t y = region_.y0; y < region_.y1; y += config_.fill_step) {
    for (int32_t x = region_.x0; x < region_.x1; x += config_.fill_step) {
      if (!old.contains(x, y)) handover_.push_back(FillPoint{x, y});
    }
  }
  for (size_t k = handover_.size(); k > 1; --k) {
    std::swap(handover_[k - 1], handover_[rng_.next_below(uint32_t(k))]);
  }
  // As many tiles per pixel as before: the gain control moves the count from there.
  const double per_pixel = double(old_tiles) / double(old.area());
  build_tiling(int(std::lround(per_pixel * double(region_.area()))));
}

void Sampler::step() {
  switch (config_.mode) {
    case SamplerMode::kAdaptive:
      if (handover_.empty()) {
        step_adaptive();
      } else {
        step_handover();
      }
      break;
    case SamplerMode::kUniformRandom:
      step_uniform();
      break;
    case SamplerMode::kFramedSweep:
      step_framed();
      break;
  }
  maybe_snapshot();
}

// Figure 5, one iteration.
void Sampler::step_adaptive() {
  advance_scene_time();
  const int tile = tiling_.tiles()[rng_.next_below(uint32_t(tiling_.tile_count()))];
  const PixelRect rect = tiling_.node(tile).rect;

  // Complete the crosshair initiated at the last visit of this tile (x, y, t0), or start
  // one at a random position if there is none (a new tile, or the first visit).
  double x, y;
  Pending old;
  TileRecord& rec = record(tile);
  if (rec.pending.valid) {
    old = rec.pending;
    x = old.x;
    y = old.y;
  } else {
    x = rect.x0 + rect.width() * rng_.next_double();
    y = rect.y0 + rect.height() * rng_.next_double();
  }
  rec.pending = Pending{};
  std::array<ShadedSample, 5> s;
  trace_crosshair(x, y, &s);
  Crosshair c = make_crosshair(x, y, s);
  if (old.valid) {
    c.old_time = old.time;
    c.old_luminance = old.luminance;
    c.G_t = float(std::abs(c.luminance - old.luminance) /
                  std::max(c.time - old.time, kMinTemporalSeconds));
    c.flags |= Crosshair::kHasTemporalGradient;
  }
  insert_front(c);
  ++counters_.crosshairs;

  // Section 6.1: reproject r crosshairs of this tile.
  for (int k = 0; k < config_.r; ++k) reproject(tile);

  // Initiate the next crosshair of this tile (the tiling may not have changed since).
  const double nx = rect.x0 + rect.width() * rng_.next_double();
  const double ny = rect.y0 + rect.height() * rng_.next_double();
  const ShadedSample first = trace_one(nx, ny);
  record(tiling_.tile_at(int32_t(nx), int32_t(ny))).pending =
      Pending{scene_time_, nx, ny, sample_luminance(first), true};

  if (++chunk_progress_ >= config_.chunk) {
    chunk_progress_ = 0;
    adjust_tiling();
  }
}

// One crosshair of a handover's fill (set_region), traced now.
void Sampler::step_handover() {
  advance_scene_time();
  const FillPoint p = handover_.back();
  handover_.pop_back();
  std::array<ShadedSample, 5> s;
  trace_crosshair(p.x + 0.5, p.y + 0.5, &s);
  insert_front(make_crosshair(p.x + 0.5, p.y + 0.5, s));
}

void Sampler::step_uniform() {
  advance_scene_time();
  const double x = region_.x0 + region_.width() * rng_.next_double();
  const double y = region_.y0 + region_.height() * rng_.next_double();
  trace_one(x, y);
}

void Sampler::step_framed() {
  advance_scene_time();
  const int64_t p = sweep_next_;
  sweep_next_ = (sweep_next_ + 1) % region_.area();
  const int32_t x = region_.x0 + int32_t(p % region_.width());
  const int32_t y = region_.y0 + int32_t(p / region_.width());
  trace_one(x + 0.5, y + 0.5);
}

// Section 6.1: relocates the newest crosshair of a random pixel of the tile to where the
// current view and the motion of its points put it, and tests that it is still visible. A
// crosshair keeps the points and the time it was traced at, and every move starts from them,
// so moving it again never adds motion already counted. By default (CrosshairMotion::kVelocity)
// its points extrapolate the center's velocity, v (now - time), as the display moves the
// sample (docs/sampler.md, "Moving points"); with kTransform a point on a rigidly moving
// object is where the object's transform now puts it (exact, however long ago it was traced),
// and a world point of deforming geometry extrapolates its velocity.
void Sampler::reproject(int tile) {
  const PixelRect rect = tiling_.node(tile).rect;
  const int32_t px = rect.x0 + int32_t(rng_.next_below(uint32_t(rect.width())));
  const int32_t py = rect.y0 + int32_t(rng_.next_below(uint32_t(rect.height())));
  if (buffer_.count(px, py) == 0) return;
  ++counters_.reprojections;
  Crosshair c = buffer_.pop_front(px, py);
  const int cell = tiling_.cell_of(tile, px, py);
  add_to_tile(tile, cell, stats_of(c), -1.0);
  settle(tile, cell);

  // The scene (its objects' transforms) and the view of the current time; within a step this
  // was done already and costs nothing.
  advance_scene_time();
  const double now = clock_.now();
  const double dt = now - c.time;
  // A world point moves with the center's velocity when the center is a world point too (with
  // kVelocity every point is one; with kTransform the velocity is zero but on deforming
  // geometry). With kTransform, beside a center on a rigidly moving object a world point
  // belongs to something else (static, or deforming with its own velocity, which the crosshair
  // does not keep) and stays.
  const glm::dvec3 motion =
      c.space[0] == Crosshair::kWorld ? glm::dvec3(c.velocity) * dt : glm::dvec3(0.0);
  // Where traced point k is now (false: on an object hidden now); a miss stays a direction
  // far away.
  const auto now_at = [&](const glm::vec3& position, bool hit, uint32_t space, glm::dvec3* p) {
    if (!hit) {
      // A perspective view's miss is a direction; an orthographic view's a point (place_miss).
      *p = camera_.orthographic()
               ? glm::dvec3(position)
               : camera_.eye + glm::dvec3(position) * (1e3 * (1.0 + camera_.znear));
    } else if (space == Crosshair::kWorld) {
      *p = glm::dvec3(position) + motion;
    } else {
      glm::dmat4 world;
      if (!tracer_.rigid_transform(space, &world, nullptr)) return false;
      *p = glm::dvec3(world * glm::dvec4(glm::dvec3(position), 1.0));
    }
    return true;
  };
  glm::dvec2 xy;
  const bool hit = c.has(Crosshair::kCenterHit);
  glm::dvec3 center;
  if (!now_at(c.position, hit, c.space[0], &center) || !project_point(center, &xy) ||
      !region_.contains(int32_t(std::floor(xy.x)), int32_t(std::floor(xy.y)))) {
    ++counters_.reprojections_dropped;  // left the region or went behind the camera
    return;
  }
  const double moved = glm::length(xy - glm::dvec2(c.x, c.y));
  c.x = float(xy.x);
  c.y = float(xy.y);

  // Spatial gradients from the neighbours' new positions.
  double g[4];
  for (int k = 0; k < 4; ++k) {
    glm::dvec2 nxy;
    const double dl = std::abs(double(c.luminance) - c.neighbor_luminance[k]);
    glm::dvec3 neighbor;
    if (now_at(c.neighbor_position[k], c.neighbor_hit(k), c.space[k + 1], &neighbor) &&
        project_point(neighbor, &nxy)) {
      g[k] = dl / std::max(glm::length(nxy - xy), kMinPixelDistance);
    } else {
      g[k] = dl;  // the neighbour went behind the camera: keep its one-pixel estimate
    }
  }
  c.G_x = float(0.5 * (g[Crosshair::kLeft] + g[Crosshair::kRight]));
  c.G_y = float(0.5 * (g[Crosshair::kUp] + g[Crosshair::kDown]));

  // Temporal gradient against the newest sample at the new pixel (section 6.1). Two changes
  // from the paper: it divides by the time between the two samples (the paper divides by the
  // newest sample's age, which is not what separates them), and it first takes away the
  // difference that the crosshair's own spatial gradients explain for the sub-pixel offset
  // between the two, so that an edge inside a pixel does not pass for change over time. A
  // crosshair that did not move (a still view of a still object) keeps its gradient: its
  // point is where it was, and any difference to its neighbour is spatial.
  const int32_t qx = int32_t(std::floor(xy.x)), qy = int32_t(std::floor(xy.y));
  if (moved > kMinMoveForTemporal && buffer_.count(qx, qy) > 0) {
    const CrosshairStats& newest = buffer_.stats(qx, qy, 0);
    const glm::vec2 newest_xy = buffer_.image_position(qx, qy, 0);
    const double explained =
        c.G_x * std::abs(newest_xy.x - c.x) + c.G_y * std::abs(newest_xy.y - c.y);
    const double change =
        std::max(0.0, std::abs(double(c.luminance) - newest.luminance) - explained);
    c.G_t = float(change / std::max(std::abs(newest.time - c.time), kMinTemporalSeconds));
    c.flags |= Crosshair::kHasTemporalGradient;
  }

  // Occlusion: is the center's surface point still visible from the eye (an orthographic
  // view's eye being the point of its plane that the point is seen from, along its axis)?
  if (hit && config_.occlusion_rays) {
    ++counters_.occlusion_rays;
    const glm::dvec3 eye =
        camera_.orthographic()
            ? center - glm::dot(center - camera_.eye, camera_.forward) * camera_.forward
            : camera_.eye;
    const glm::dvec3 to_eye = eye - center;
    const double len = glm::length(to_eye);
    if (len > 0.0) {
      const glm::dvec3 dir = to_eye / len;
      // Off the surface by a fraction of the way to the eye, plus some float spacings of the
      // point's coordinates: relative to the scene's scale, so that in a scene in micrometres
      // the ray still starts between the point and the eye.
      const double eps = std::min(1e-4 * len + 1e-6 * glm::length(center), 0.5 * len);
      const glm::vec3 from(center + eps * dir);
      if (tracer_.occluded(from, glm::vec3(eye), &trace_stats_)) {
        // Replace it by a new crosshair at the same image location; the hidden sample is its
        // old sample, so the occlusion shows as a temporal edge.
        ++counters_.occlusion_hits;
        std::array<ShadedSample, 5> s;
        trace_crosshair(xy.x, xy.y, &s);
        Crosshair fresh = make_crosshair(xy.x, xy.y, s);
        fresh.old_time = c.time;
        fresh.old_luminance = c.luminance;
        fresh.G_t = float(std::abs(fresh.luminance - c.luminance) /
                          std::max(fresh.time - c.time, kMinTemporalSeconds));
        fresh.flags |= Crosshair::kHasTemporalGradient | Crosshair::kOccluded;
        insert_front(fresh);
        return;
      }
    }
  }
  insert_back(c);
}

// Camera::project with the tangent of the half field of view taken once per camera instead of
// once per point: the same arithmetic in the same order, so the same results bit for bit.
bool Sampler::project_point(const glm::dvec3& p, glm::dvec2* xy) const {
  const glm::dvec3 d = p - camera_.eye;
  const double z = glm::dot(d, camera_.forward);
  if (!(z >= camera_.znear)) return false;
  const double aspect = double(config_.image.width) / double(config_.image.height);
  const double half = camera_.orthographic() ? view_half_ : z * view_half_;
  const double sx = glm::dot(d, camera_.right) / (half * aspect);
  const double sy = glm::dot(d, camera_.up) / half;
  *xy = glm::dvec2((sx + 1.0) * 0.5 * config_.image.width, (1.0 - sy) * 0.5 * config_.image.height);
  // Beyond any image (a point a hair in front of the eye, a view a hair high) it is as good as
  // behind the camera, and its pixel would not fit an integer.
  return std::abs(xy->x) < kMaxProjected && std::abs(xy->y) < kMaxProjected;
}

// ---------------------------------------------------------------------------------------------
// Tracing and output

void Sampler::trace_crosshair(double x, double y, std::array<ShadedSample, 5>* out) {
  const uint64_t sanitized = trace_stats_.sanitized, shadow_rays = trace_stats_.shadow_rays;
  tracer_.trace_crosshair(camera_, x, y, config_.image.width, config_.image.height, out,
                          &trace_stats_);
  counters_.sanitized += trace_stats_.sanitized - sanitized;
  counters_.shadow_rays += trace_stats_.shadow_rays - shadow_rays;
  clock_.primary_rays_traced(5);
  static constexpr double kOffsets[5][2] = {{0, 0}, {-1, 0}, {1, 0}, {0, -1}, {0, 1}};
  for (int k = 0; k < 5; ++k) {
    place_miss(x + kOffsets[k][0], y + kOffsets[k][1], &(*out)[k]);
    emit(x + kOffsets[k][0], y + kOffsets[k][1], (*out)[k]);
  }
}

ShadedSample Sampler::trace_one(double x, double y) {
  const uint64_t sanitized = trace_stats_.sanitized, shadow_rays = trace_stats_.shadow_rays;
  ShadedSample s =
      tracer_.trace(camera_.ray(x, y, config_.image.width, config_.image.height), &trace_stats_);
  counters_.sanitized += trace_stats_.sanitized - sanitized;
  counters_.shadow_rays += trace_stats_.shadow_rays - shadow_rays;
  clock_.primary_rays_traced(1);
  place_miss(x, y, &s);
  emit(x, y, s);
  return s;
}

// An orthographic camera's rays all run along `forward`, so a miss's direction cannot say
// where it is seen. It becomes a point far along its ray instead, which projects back to its
// pixel wherever the camera moves across the view (and less than that distance along it), and
// is sent as a point, not a miss.
void Sampler::place_miss(double x, double y, ShadedSample* s) const {
  if (s->hit || !camera_.orthographic()) return;
  const Ray ray = camera_.ray(x, y, config_.image.width, config_.image.height);
  s->position = ray.origin + ray.direction * float(kOrthographicMissDistance * camera_.ymag);
}

void Sampler::emit(double x, double y, const ShadedSample& s) {
  // Neighbours of a crosshair at the image border can fall outside it: they feed gradients
  // but show nowhere.
  if (x < 0.0 || y < 0.0 || x >= config_.image.width || y >= config_.image.height) return;
  Sample out;
  out.time = scene_time_;
  // Rounding to float can carry 255.99999999 to 256: keep the sample inside its pixel row.
  out.x = std::min(float(x), max_x_);
  out.y = std::min(float(y), max_y_);
  out.color = s.color;
  if (fields_ & kFieldPosition) {
    out.position = s.position;
    out.miss = !s.hit && !camera_.orthographic();  // place_miss made an orthographic one a point
  }
  if (fields_ & kFieldVelocity) out.velocity = s.velocity;
  batch_.samples.push_back(out);
  ++counters_.samples;
  if (int(batch_.samples.size()) >= config_.batch_size) flush();
}

void Sampler::flush() {
  if (batch_.samples.empty()) return;
  batch_.sequence = sequence_++;
  ++counters_.batches;
  SampleBatch out;
  out.sampler_id = batch_.sampler_id;
  out.fields = batch_.fields;
  std::swap(out, batch_);
  batch_.samples.reserve(size_t(config_.batch_size));
  sink_.on_batch(std::move(out));
}

Crosshair Sampler::make_crosshair(double x, double y, const std::array<ShadedSample, 5>& s) const {
  Crosshair c;
  c.time = scene_time_;
  c.x = float(x);
  c.y = float(y);
  c.position = kept_point(tracer_, config_.crosshair_motion, s[0], &c.space[0]);
  c.velocity = s[0].velocity;
  c.luminance = sample_luminance(s[0]);
  if (s[0].hit) c.flags |= Crosshair::kCenterHit;
  for (int k = 0; k < 4; ++k) {
    c.neighbor_luminance[k] = sample_luminance(s[k + 1]);
    c.neighbor_position[k] =
        kept_point(tracer_, config_.crosshair_motion, s[k + 1], &c.space[k + 1]);
    if (s[k + 1].hit) c.flags |= uint8_t(Crosshair::kNeighborHit0 << k);
  }
  // Section 4.1: the average absolute differences to the neighbours one pixel away.
  c.G_x = 0.5f * (std::abs(c.luminance - c.neighbor_luminance[Crosshair::kLeft]) +
                  std::abs(c.luminance - c.neighbor_luminance[Crosshair::kRight]));
  c.G_y = 0.5f * (std::abs(c.luminance - c.neighbor_luminance[Crosshair::kUp]) +
                  std::abs(c.luminance - c.neighbor_luminance[Crosshair::kDown]));
  return c;
}

void Sampler::maybe_snapshot() {
  const double now = clock_.now();
  if (now - last_snapshot_time_ < config_.refresh_interval) return;
  const double elapsed = now - last_snapshot_time_;
  const double rate = double(counters_.samples - samples_at_snapshot_) / elapsed;
  sample_rate_ = sample_rate_ == 0.0 ? rate : 0.7 * sample_rate_ + 0.3 * rate;
  samples_at_snapshot_ = counters_.samples;
  last_snapshot_time_ = now;
  flush();
  ++counters_.snapshots;
  sink_.on_tiling(snapshot());
}

TilingSnapshot Sampler::snapshot() const {
  TilingSnapshot snap;
  snap.sampler_id = config_.sampler_id;
  snap.time = clock_.now();
  snap.region = region_;
  if (config_.mode != SamplerMode::kAdaptive) {
    // Baselines sample uniformly: one tile, no gradients.
    TileInfo info;
    info.rect = region_;
    info.rate = float(sample_rate_ / double(region_.area()));
    snap.tiles.push_back(info);
    return snap;
  }
  snap.tiles.reserve(size_t(tiling_.tile_count()));
  // Every tile is chosen with the same probability, so its expected share of the samples is
  // 1 / tiles; spread over its pixels, that is its local rate.
  const double per_tile = sample_rate_ / double(tiling_.tile_count());
  for (int t : tiling_.tiles()) {
    const TileStats st = tile_stats(t, snap.time);
    TileInfo info;
    info.rect = tiling_.node(t).rect;
    info.G_x = float(st.G_x);
    info.G_y = float(st.G_y);
    info.G_t = float(st.G_t);
    info.v = float(st.v);
    info.E = float(error_[t]);
    info.count = uint32_t(st.count);
    info.rate = float(per_tile / double(info.rect.area()));
    snap.tiles.push_back(info);
  }
  return snap;
}

// ---------------------------------------------------------------------------------------------
// Deep buffer and tile statistics

Sampler::TileRecord& Sampler::record(int tile) {
  if (size_t(tile) >= records_.size()) {
    records_.resize(size_t(tiling_.node_capacity()));
    error_.resize(size_t(tiling_.node_capacity()), 0.0);
  }
  return records_[size_t(tile)];
}

// The region pixel holding a crosshair. Positions are floats: one that rounded up onto the
// region's far edge still belongs to the last pixel.
void Sampler::pixel_of(const Crosshair& c, int32_t* x, int32_t* y) const {
  *x = std::clamp(int32_t(std::floor(c.x)), region_.x0, region_.x1 - 1);
  *y = std::clamp(int32_t(std::floor(c.y)), region_.y0, region_.y1 - 1);
}

void Sampler::insert_front(const Crosshair& c) {
  int32_t x, y;
  pixel_of(c, &x, &y);
  int cell;
  const int tile = tiling_.tile_at(x, y, &cell);
  CrosshairStats evicted;
  if (buffer_.push_front(x, y, c, &evicted)) add_to_tile(tile, cell, evicted, -1.0);
  add_to_tile(tile, cell, stats_of(c), 1.0);
  settle(tile, cell);
}

void Sampler::insert_back(const Crosshair& c) {
  int32_t x, y;
  pixel_of(c, &x, &y);
  int cell;
  const int tile = tiling_.tile_at(x, y, &cell);
  CrosshairStats evicted;
  if (buffer_.push_back(x, y, c, &evicted)) add_to_tile(tile, cell, evicted, -1.0);
  add_to_tile(tile, cell, stats_of(c), 1.0);
  settle(tile, cell);
}

// Keeps the sums of a tile and of a cell in step with the buffer: called once for every
// crosshair that enters or leaves a pixel of that cell.
void Sampler::add_to_tile(int tile, int cell, const CrosshairStats& c, double sign) {
  add_to_sums(record(tile).sums, c, sign);
  add_to_sums(cells_[size_t(cell)], c, sign);
}

// Re-derives the sums of a cell and a tile that may have drifted (see needs_rederive). Called
// after the buffer and the sums agree again; the cell first, as the tile may be summed from it.
void Sampler::settle(int tile, int cell) {
  if (needs_rederive(cells_[size_t(cell)])) rederive_cell(cell);
  if (needs_rederive(records_[size_t(tile)].sums)) rederive(tile);
}

void Sampler::rederive_cell(int cell) {
  cells_[size_t(cell)] =
      sums_from_buffer(buffer_, tiling_.cell_rect(cell), rederive_shift(cells_[size_t(cell)]));
}

// Recomputes a tile's sums from the crosshairs in its block, with the newest as reference
// time and the block's previous weighted mean as shift (a split passes the parent's).
void Sampler::rederive(int tile) { rederive(tile, rederive_shift(record(tile).sums)); }

void Sampler::rederive(int tile, double shift) {
  shift = std::isfinite(shift) ? shift : 0.0;
  // A tile of cell size or more is its cells; a smaller one is visited.
  record(tile).sums = tiling_.covers_cells(tile)
                          ? sums_from_parts(&cells_[size_t(tiling_.first_cell(tile))],
                                            tiling_.cells_in(tile), shift)
                          : sums_from_buffer(buffer_, tiling_.node(tile).rect, shift);
}

TileStats Sampler::tile_stats(int tile) const { return tile_stats(tile, clock_.now()); }

TileStats Sampler::tile_stats(int tile, double now) const {
  const TileSums& s = records_[size_t(tile)].sums;
  TileStats st;
  st.count = s.count;
  if (s.count <= 0 || !(s.w > 0.0)) return st;
  // The weights are relative to t_ref: exp(-3.47 (now - t_ref)) makes them absolute.
  if (s.occluded > 0) {
    st.occluded = std::max(0.0, s.wo) * std::exp(-kAgeDecay * std::max(0.0, now - s.t_ref));
  }
  const double mean = s.wl / s.w;
  st.v = std::max(0.0, s.wll / s.w - mean * mean);
  st.G_x = std::max(0.0, s.wgx / s.w);
  st.G_y = std::max(0.0, s.wgy / s.w);
  if (s.temporal > 0 && !(s.wt >= std::numeric_limits<double>::min())) {
    // Every crosshair of the block with a temporal gradient is so much older than its newest
    // (over 200 s: a tile visited once every few minutes) that their weights underflowed in
    // sums referred to the newest; G_t is still their weighted mean.
    st.G_t = temporal_gradient_from_buffer(buffer_, tiling_.node(tile).rect);
  } else {
    st.G_t = s.wt > 0.0 ? std::max(0.0, s.wgt / s.wt) : 0.0;
  }
  st.mean_age = std::max(0.0, now - (s.t_ref + s.t_sum / s.count));
  return st;
}

// ---------------------------------------------------------------------------------------------
// Tiling: gain control, error, split and merge

double gain_tile_count(double dC_ds, double dC_dt, double T, double i, double pixels,
                       double min_tiles, double max_tiles, double current) {
  constexpr double kTiny = 1e-12;
  const auto finite_or = [](double v, double fallback) { return std::isfinite(v) ? v : fallback; };
  dC_ds = finite_or(dC_ds, 0.0);
  const double change_in_time = finite_or(dC_dt * T, 0.0);
  if (dC_ds <= kTiny && change_in_time <= kTiny) return std::clamp(current, min_tiles, max_tiles);
  if (dC_ds <= kTiny) return min_tiles;  // change only in time: least gain
  const double S = i * change_in_time / dC_ds;
  if (!(S > kTiny)) return max_tiles;  // a still image: most gain
  const double tiles = pixels / (S * S);
  return std::isfinite(tiles) ? std::clamp(tiles, min_tiles, max_tiles) : max_tiles;
}

// One pass over the tiles: section 6.1's error
//   E_tile = s (kappa v / sum v + lambda u / sum u + (1 - kappa - lambda) f o / sum o)
// for every tile, with f in [0, 1] the occlusion term's share (below), and section 4.1's gain
// control, dC/ds S = i dC/dt T, from the image-wide gradients and the mean sample age.
void Sampler::compute_errors() {
  record(tiling_.node_capacity() - 1);  // sizes error_
  const auto& tiles = tiling_.tiles();
  const double b = config_.b;
  const double empty_total = double(buffer_.capacity() - buffer_.size());
  const double mean_empty = empty_total / tiles.size();
  double sum_v = 0.0, sum_u = 0.0, sum_o = 0.0, occluded = 0.0;
  double area = 0.0, spatial = 0.0, temporal = 0.0, age = 0.0;
  terms_.resize(tiles.size());
  const double now = clock_.now();
  for (size_t k = 0; k < tiles.size(); ++k) {
    const TileStats st = tile_stats(tiles[k], now);
    const double s = double(tiling_.node(tiles[k]).rect.area());
    const double empty = s * b - st.count;
    const double u = empty > 0.0 ? 1.0 - std::min(1.0, config_.m * mean_empty / empty) : 0.0;
    const double o = st.occluded / (s * b);
    terms_[k] = {st.v, u, o};
    sum_v += st.v;
    sum_u += u;
    sum_o += o;
    occluded += st.occluded;
    area += s;
    spatial += s * 0.5 * (st.G_x + st.G_y);
    temporal += s * st.G_t;
    age += st.mean_age;
  }
  const double kv = config_.kappa, ku = config_.lambda;
  // The occlusion term takes its whole share only while the recent occlusions (age-weighted)
  // amount to at least a tile's block of crosshairs, and a part in proportion below that:
  // normalised by its sum alone, a handful of occlusions anywhere in the region would draw
  // (1 - kappa - lambda) of all the error, and so of the tiles, to themselves (docs/sampler.md,
  // "The occlusion term").
  const double block = double(buffer_.size()) / double(tiles.size());
  occlusion_share_ = block > 0.0 ? std::min(1.0, occluded / block) : 0.0;
  const double ko = (1.0 - kv - ku) * occlusion_share_;
  for (size_t k = 0; k < tiles.size(); ++k) {
    const double s = double(tiling_.node(tiles[k]).rect.area());
    double e = 0.0;
    if (sum_v > 0.0) e += kv * terms_[k][0] / sum_v;
    if (sum_u > 0.0) e += ku * terms_[k][1] / sum_u;
    if (sum_o > 0.0) e += ko * terms_[k][2] / sum_o;
    error_[tiles[k]] = s * e;
  }
  target_tiles_ = int(std::lround(gain_tile_count(
      spatial / area, temporal / area, age / double(tiles.size()), config_.i,
      double(region_.area()), config_.min_tiles, config_.max_tiles, target_tiles_)));
}

void Sampler::adjust_tiling() {
  compute_errors();
  const auto max_leaf = [&] {
    int best = -1;
    for (int t : tiling_.tiles()) {
      if (tiling_.can_split(t) && (best == -1 || error_[t] > error_[best])) best = t;
    }
    return best;
  };
  const auto min_pair = [&](int avoid) {
    int best = -1;
    double best_e = 0.0;
    for (int p : tiling_.mergeable()) {
      if (p == avoid) continue;
      const auto& n = tiling_.node(p);
      const double e = error_[n.child[0]] + error_[n.child[1]];
      if (best == -1 || e < best_e) {
        best = p;
        best_e = e;
      }
    }
    return best;
  };
  const auto do_split = [&](int t) {
    int a, b;
    tiling_.split(t, &a, &b);
    on_split(t, a, b);
    ++counters_.splits;
    return t;
  };
  const auto do_merge = [&](int p) {
    const auto& n = tiling_.node(p);
    const int a = n.child[0], b = n.child[1];
    error_[p] = error_[a] + error_[b];
    tiling_.merge(p);
    on_merge(p, a, b);
    ++counters_.merges;
  };
  for (int ops = 0; ops < config_.max_tiling_ops; ++ops) {
    const int count = tiling_.tile_count();
    if (count < target_tiles_) {
      const int t = max_leaf();
      if (t == -1) break;
      do_split(t);
    } else if (count > target_tiles_) {
      const int p = min_pair(-1);
      if (p == -1) break;
      do_merge(p);
    } else {
      // At the target count: trade the worst tile for the best pair while errors are
      // clearly unequal (splitting halves an error, merging adds two).
      const int t = max_leaf();
      if (t == -1) break;
      const int p = min_pair(-1);
      if (p == -1) break;
      const auto& n = tiling_.node(p);
      const double pair_e = error_[n.child[0]] + error_[n.child[1]];
      if (error_[t] <= kBalanceRatio * pair_e || n.child[0] == t || n.child[1] == t) break;
      do_merge(p);
      do_split(t);
    }
  }
}

void Sampler::on_split(int parent, int a, int b) {
  const Pending pending = record(parent).pending;
  record(parent).pending = Pending{};
  record(a).pending = record(b).pending = Pending{};
  // Re-derive the smaller child (from its cells, or when smaller than a cell from the buffer)
  // and take the other as the parent's sums minus it. The difference carries the parent's
  // updates, so it is re-derived as soon as the parent would have been, or at once when the
  // smaller child held nearly all of the parent's weight (combine() marks it).
  const bool a_smaller = tiling_.node(a).rect.area() <= tiling_.node(b).rect.area();
  const int scanned = a_smaller ? a : b, derived = a_smaller ? b : a;
  const TileSums ps = records_[parent].sums;
  rederive(scanned, rederive_shift(ps));
  records_[derived].sums = combine(ps, records_[scanned].sums, -1.0);
  if (needs_rederive(records_[derived].sums)) rederive(derived);
  for (int c : {a, b}) {
    // Until the next adjustment, a child's error is its share of the parent's.
    error_[c] = error_[parent] * double(tiling_.node(c).rect.area()) /
                double(tiling_.node(parent).rect.area());
  }
  if (pending.valid) {
    const int32_t x = int32_t(pending.x), y = int32_t(pending.y);
    record(tiling_.node(a).rect.contains(x, y) ? a : b).pending = pending;
  }
}

void Sampler::on_merge(int parent, int a, int b) {
  TileRecord& rec = record(parent);
  rec.pending = records_[a].pending.valid ? records_[a].pending : records_[b].pending;
  records_[a].pending = records_[b].pending = Pending{};
  rec.sums = combine(records_[a].sums, records_[b].sums);
}

// The sums of the union of two disjoint blocks (sign +1), or of a block without a block it
// contains (sign -1), without visiting their crosshairs: both are moved to a common reference
// time and shift, then added or subtracted.
TileSums combine(const TileSums& a, const TileSums& b, double sign) {
  if (b.count <= 0) return a;
  if (a.count <= 0 && sign > 0.0) return b;
  if (sign < 0.0 && a.count <= b.count) return TileSums{};  // nothing is left
  TileSums out;
  out.t_ref = sign > 0.0 ? std::max(a.t_ref, b.t_ref) : a.t_ref;
  const double mean_a = a.w > 0.0 ? a.shift + a.wl / a.w : a.shift;
  const double mean_b = b.w > 0.0 ? b.shift + b.wl / b.w : b.shift;
  out.shift = sign > 0.0 ? 0.5 * (mean_a + mean_b) : a.shift;
  const double signs[2] = {1.0, sign};
  const TileSums* parts[2] = {&a, &b};
  for (int k = 0; k < 2; ++k) {
    const TileSums* s = parts[k];
    const double f = signs[k] * std::exp(kAgeDecay * (s->t_ref - out.t_ref));
    const double d = s->shift - out.shift;
    out.w += f * s->w;
    out.wl += f * (s->wl + d * s->w);
    out.wll += f * (s->wll + 2.0 * d * s->wl + d * d * s->w);
    out.wgx += f * s->wgx;
    out.wgy += f * s->wgy;
    out.wt += f * s->wt;
    out.wgt += f * s->wgt;
    out.t_sum += signs[k] * (s->t_sum + s->count * (s->t_ref - out.t_ref));
    out.count += int32_t(signs[k]) * s->count;
    out.temporal += int32_t(signs[k]) * s->temporal;
    out.wo += f * s->wo;
    out.occluded += int32_t(signs[k]) * s->occluded;
  }
  out.updates = a.updates + b.updates;
  if (out.temporal <= 0) out.wt = out.wgt = 0.0;
  if (out.occluded <= 0) out.wo = 0.0;
  // Block b held nearly all of a's weight: the difference is mostly rounding.
  if (sign < 0.0 &&
      (out.w < kCancellation * a.w || (out.temporal > 0 && out.wt < kCancellation * a.wt) ||
       (out.occluded > 0 && out.wo < kCancellation * a.wo))) {
    out.updates = kRederiveNow;
  }
  return out;
}

}  // namespace afr
