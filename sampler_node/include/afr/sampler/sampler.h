// The adaptive frameless sampler (sections 4 and 6.1): the closed loop of the paper's
// Figure 5 over the region a sampler owns. Library code with no I/O: it reads time from a
// Clock, traces with a Tracer, draws random numbers from its own seeded generator and hands
// samples and tiling snapshots to a SampleSink.
//
// Order of calls: construct, fill() once, then step() as often as wanted (each step is one
// iteration of Figure 5, or one sample of a baseline mode), flush() to emit the last partial
// batch. set_region() may come between any two of these calls. Not thread-safe: one sampler per
// thread, each with its own Tracer.
#pragma once

#include <afr/common/clock.h>
#include <afr/common/random.h>
#include <afr/common/samples.h>
#include <afr/common/scene.h>
#include <afr/sampler/deep_buffer.h>
#include <afr/sampler/sampler_config.h>
#include <afr/sampler/tiling.h>
#include <afr/sampler/tracer.h>

#include <array>
#include <vector>

namespace afr {

// What the sampler counts.
struct SamplerCounters {
  uint64_t samples = 0;     // primary rays traced and emitted
  uint64_t crosshairs = 0;  // crosshairs completed
  uint64_t reprojections = 0;
  uint64_t reprojections_dropped = 0;  // left the region or went behind the camera
  uint64_t occlusion_rays = 0;
  uint64_t occlusion_hits = 0;
  uint64_t splits = 0;
  uint64_t merges = 0;
  uint64_t sanitized = 0;    // non-finite shading values replaced by the tracer
  uint64_t shadow_rays = 0;  // the tracer's, for the samples (TraceStats::shadow_rays)
  uint64_t snapshots = 0;
  uint64_t batches = 0;
};

// How far along its ray, in units of the view's half height (Camera::ymag), an orthographic
// camera's miss is placed (Sampler::place_miss): far enough that the camera moving forward
// rarely passes it, near enough that a float still places it within 1/50 pixel at 4096 rows
// (6e-8 x 100 ymag against a pixel's 2 ymag / 4096).
inline constexpr double kOrthographicMissDistance = 100.0;

// Image positions beyond this many pixels do not project (Sampler::project_point).
inline constexpr double kMaxProjected = 1e9;

// Sample weights decline with age a as exp(-kAgeDecay * a) (section 4).
inline constexpr double kAgeDecay = 3.47;

// Statistics of one tile's block, kept as age-weighted running sums. Weights are
// exp(kAgeDecay * (t - t_ref)) relative to a per-tile reference time, so the sums never need
// to decay: every weight shrinks by the same factor as time passes, which ratios ignore.
struct TileSums {
  double t_ref = 0.0;           // reference time of the weights
  double shift = 0.0;           // luminance subtracted before summing (numerically stable variance)
  double w = 0.0;               // sum of weights
  double wl = 0.0;              // sum of w * (L - shift)
  double wll = 0.0;             // sum of w * (L - shift)^2
  double wgx = 0.0, wgy = 0.0;  // sums of w * G_x, w * G_y
  double wt = 0.0, wgt = 0.0;   // over crosshairs with a temporal gradient: w, w * G_t
  double t_sum = 0.0;           // sum of (t - t_ref), for the mean age
  int32_t count = 0;            // crosshairs in the block
  int32_t temporal = 0;         // of them, with a temporal gradient (those in wt)
  int32_t occluded = 0;         // of them, made to replace an occluded crosshair
  double wo = 0.0;              // their sum of weights (the occlusion term's age-weighted count)
  int32_t updates = 0;          // adds and removes since the sums were last re-derived, or a
                                // large value when they must be re-derived before use
};

// The sums of two disjoint blocks together (sign +1: a merge of two tiles), or of block a
// without block b that it contains (sign -1: one child of a split, from the other).
TileSums combine(const TileSums& a, const TileSums& b, double sign = 1.0);

// What the sums say about a block.
struct TileStats {
  double v = 0.0;  // age-weighted luminance variance, >= 0
  double G_x = 0.0, G_y = 0.0, G_t = 0.0;
  double mean_age = 0.0;  // seconds
  int32_t count = 0;
  // Section 6.1's |O|, age-weighted as the other statistics: the crosshairs made to replace an
  // occluded one, each counting exp(-3.47 a) at age a. An occlusion is an event: a crosshair
  // that recorded one seconds ago says nothing of occlusion now, and would otherwise keep
  // drawing samples to where a moving object used to be for as long as it stays in the buffer.
  double occluded = 0.0;
};

// Section 4.1, gain control: dC/ds S = i dC/dt T solved for the mean tile width S, as a tile
// count for a region of `pixels`, clamped to [min_tiles, max_tiles]. dC_ds is the image's
// mean spatial gradient (luminance per pixel), dC_dt its mean temporal gradient (per second),
// T the mean sample age (seconds). Finite for every input: with no spatial change the count
// is min_tiles, with no temporal change max_tiles, with neither `current`.
double gain_tile_count(double dC_ds, double dC_dt, double T, double i, double pixels,
                       double min_tiles, double max_tiles, double current);

class Sampler {
 public:
  Sampler(const Scene& scene, Tracer& tracer, Clock& clock, const SamplerConfig& config,
          SampleSink& sink);

  // Section 4.2: fills the deep buffer with a gridded, cotemporal pattern of crosshairs (all
  // traced at the clock's current time) and builds the first tiling.
  void fill();
  // One iteration of the loop; while a region handover is filling (set_region), one crosshair
  // of that fill instead.
  void step();
  // Hands the sampler over to another region of the same image (a recut). The deep buffer keeps
  // the crosshairs of the pixels both regions share, as they were; the tiling is rebuilt over
  // the new region with its statistics taken from them and about as many tiles per pixel as
  // before. Pixels gained get the fill's grid of crosshairs, one crosshair per following
  // step(), so the fill goes at the pace of the loop (and of whatever caps it) instead of in a
  // burst; handover_remaining() counts what is left of it. set_region() itself traces nothing.
  // Before fill() it only moves the region, which fill() then fills whole.
  void set_region(const PixelRect& region);
  // Crosshairs of the handover's fill not yet traced.
  int64_t handover_remaining() const { return int64_t(handover_.size()); }
  // Emits the samples of the current, partial batch.
  void flush();
  // Takes the camera from `source` (when it gives one) instead of the scene's. The source
  // must outlive the sampler; nullptr restores the scene's camera.
  void set_camera_source(const CameraSource* source) { camera_source_ = source; }
  // One reprojection of section 6.1 in `tile` (a leaf of tiling()): what step() does r times.
  // Public so that benchmarks can time it alone.
  void reproject(int tile);
  // What step() does after every chunk of crosshairs: recompute every tile's error and the
  // gain's target count, then split the tile of largest error and merge the sibling pair of
  // smallest summed error (at most max_tiling_ops times). Public for tests.
  void adjust_tiling();

  const SamplerConfig& config() const { return config_; }
  const PixelRect& region() const { return region_; }
  const SamplerCounters& counters() const { return counters_; }
  const KdTiling& tiling() const { return tiling_; }
  const DeepBuffer& buffer() const { return buffer_; }
  // The statistics of a tile (a leaf of tiling()) at the clock's current time.
  TileStats tile_stats(int tile) const;
  // The error E_tile of the last tiling adjustment.
  double tile_error(int tile) const { return error_[tile]; }
  // Gain control's current target tile count (section 4.1).
  int target_tiles() const { return target_tiles_; }
  // The occlusion term's share at the last tiling adjustment, in [0, 1]: the recent
  // (age-weighted) occlusions against a tile's block of crosshairs, at most 1
  // (docs/sampler.md, "The occlusion term").
  double occlusion_share() const { return occlusion_share_; }
  TilingSnapshot snapshot() const;
  // Samples per second emitted, as measured over recent refresh intervals.
  double sample_rate() const { return sample_rate_; }

 private:
  // The first sample of a crosshair initiated at a tile's last visit (x, y, t0), which the
  // next visit completes. A tile has at most one, inside it; kept with the tile, not per pixel.
  struct Pending {
    double time = 0.0;
    double x = 0.0, y = 0.0;
    float luminance = 0.0f;
    bool valid = false;
  };
  struct TileRecord {
    TileSums sums;
    Pending pending;
  };

  // Loop steps.
  void step_adaptive();
  void step_handover();
  void step_uniform();
  void step_framed();
  void advance_scene_time();
  void maybe_snapshot();

  // Tracing, with emission to the sink.
  void trace_crosshair(double x, double y, std::array<ShadedSample, 5>* out);
  ShadedSample trace_one(double x, double y);
  void place_miss(double x, double y, ShadedSample* s) const;
  void emit(double x, double y, const ShadedSample& s);
  Crosshair make_crosshair(double x, double y, const std::array<ShadedSample, 5>& s) const;

  bool project_point(const glm::dvec3& p, glm::dvec2* xy) const;

  // Deep buffer and statistics.
  void pixel_of(const Crosshair& c, int32_t* x, int32_t* y) const;
  void insert_front(const Crosshair& c);
  void insert_back(const Crosshair& c);
  void add_to_tile(int tile, int cell, const CrosshairStats& c, double sign);
  void settle(int tile, int cell);
  void rederive(int tile);
  void rederive(int tile, double shift);
  void rederive_cell(int cell);
  TileRecord& record(int tile);
  void on_split(int parent, int a, int b);
  void on_merge(int parent, int a, int b);
  TileStats tile_stats(int tile, double now) const;
  void compute_errors();
  // Tile count bounds for the current region: the config's, at most the region's pixels / 4.
  void bound_tiles();
  // Statistics of every cell and of the root from the buffer, then splits of the largest error
  // up to `tiles` tiles. On a tiling that is one tile.
  void build_tiling(int tiles);

  const Scene& scene_;
  Tracer& tracer_;
  Clock& clock_;
  SamplerConfig config_;
  SampleSink& sink_;
  PixelRect region_;
  Pcg32 rng_;
  KdTiling tiling_;
  DeepBuffer buffer_;
  std::vector<TileSums> cells_;               // by cell of the tiling (KdTiling::cell_at)
  std::vector<TileRecord> records_;           // by tiling node id
  std::vector<double> error_;                 // by tiling node id
  std::vector<std::array<double, 3>> terms_;  // v, u, o per tile, scratch of compute_errors
  Camera camera_;
  double view_half_ = 0.0;  // camera_'s tan(yfov / 2), or its ymag when orthographic
  const CameraSource* camera_source_ = nullptr;
  double scene_time_ = 0.0;
  bool scene_time_set_ = false;
  // The scene time moves in steps of at least this: animation_step, or more where moving the
  // tracer to a new time is costly (advance_scene_time).
  double time_step_ = 0.0;
  uint32_t fields_ = 0;
  float max_x_ = 0.0f, max_y_ = 0.0f;  // the largest emitted positions: just short of the edge
  SampleBatch batch_;
  uint64_t sequence_ = 0;
  SamplerCounters counters_;
  TraceStats trace_stats_;
  int chunk_progress_ = 0;
  int target_tiles_ = 1;
  double occlusion_share_ = 0.0;
  int64_t sweep_next_ = 0;
  double last_snapshot_time_ = 0.0;
  uint64_t samples_at_snapshot_ = 0;
  double sample_rate_ = 0.0;
  int requested_min_tiles_ = 0, requested_max_tiles_ = 0;  // the config's, before bound_tiles
  bool filled_ = false;
  // The pixels a handover gained that still wait for their fill crosshair, the next at the
  // back.
  struct FillPoint {
    int32_t x = 0, y = 0;
  };
  std::vector<FillPoint> handover_;
};

}  // namespace afr
