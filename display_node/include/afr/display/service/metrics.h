// What the display node measures, shared by its threads: per sampler (samples, bytes, batches,
// sequence gaps, what the sampler reports about itself, its region) and for the display
// (reconstruction time, refresh rate, store fill, sample-to-display latency). Written out by
// metrics_exposition.h, served by metrics_server.h.
//
// Thread-safety: every method may be called from any thread (one mutex; the ingest thread
// takes it once per batch).
#pragma once

#include <afr/common/rect.h>
#include <afr/common/samples.h>
#include <afr/display/reconstructor.h>
#include <afr/display/service/dashboard.h>
#include <afr/display/service/latency_histogram.h>
#include <afr/protocol/messages.h>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace afr::service {

struct SamplerMetrics {
  uint32_t id = 0;
  std::string name;
  std::string public_key;
  // Currently a member. A sampler that left or died is kept for kDepartedPeriods stats periods
  // (its last figures), then forgotten; of more than kMaxDeparted, the oldest go at once.
  bool member = false;
  int periods_gone = 0;
  PixelRect region;
  int threads = 1;
  // Received by the display (sample channel).
  uint64_t samples = 0;
  uint64_t bytes = 0;        // batches and tilings
  uint64_t batch_bytes = 0;  // batches only: bytes per sample = batch_bytes / samples
  uint64_t batches = 0;
  uint64_t tilings = 0;
  // The pixels its last tiling snapshot describes, as kept: cut to its region.
  int64_t tiled_pixels = 0;
  uint64_t sequence_gaps = 0;  // batches missing between consecutive sequence numbers
  uint64_t last_sequence = 0;
  bool have_sequence = false;
  double samples_per_second = 0.0;  // received, over the last stats period
  double bytes_per_second = 0.0;
  // What the coordinator cuts regions by: the samples per second the display accepted from
  // it, smoothed (coordinator.h), and whether it is starved (nothing delivered while others did).
  double measured_samples_per_second = 0.0;
  bool starved = false;
  // The scene's transfer to it (chunks the display has sent of the scene's count; 0 of 0: it had
  // the scene cached, or no transfer yet), for the dashboard's progress.
  uint32_t scene_chunks_sent = 0;
  uint32_t scene_chunks = 0;
  // Reported by the sampler (stats messages): shown, never used for its share.
  protocol::SamplerStats reported;
  // For the rates.
  uint64_t period_samples = 0;
  uint64_t period_bytes = 0;
};

struct DisplayMetrics {
  uint64_t session = 0;
  double uptime = 0.0;  // display clock, seconds
  int width = 0, height = 0;
  std::string backend;
  std::string mode;
  uint64_t frames = 0;
  double reconstruct_ms = 0.0;  // last frame
  GpuTimes gpu;                 // a GPU backend: the latest image the GPU finished
  // A GPU backend: the mean of each phase of its reconstruct() calls over the last stats
  // period (CallTimes: wall time on the display thread); call_timed says there were any.
  CallTimes period_call;
  bool call_timed = false;
  // The latest image's pixels that no splat reached (filled from wider support) and those
  // with no weight anywhere (black): where the samples are too sparse for the filter.
  uint64_t hole_pixels = 0, empty_pixels = 0;
  double reconstruct_ms_mean = 0.0;  // over the whole run
  double refresh_hz = 0.0;           // frames per second over the last stats period
  // Over the last stats period: the reconstruction time's mean and 99th percentile, and the
  // 99th percentile of the time between consecutive images (the refresh's worst stalls).
  double period_reconstruct_ms_mean = 0.0, period_reconstruct_ms_p99 = 0.0;
  double period_frame_interval_ms_p99 = 0.0;
  uint64_t store_stored = 0;
  uint64_t store_capacity = 0;
  uint64_t members = 0;
  uint64_t recuts = 0;
  uint64_t region_epoch = 0;
  uint64_t joins = 0;
  uint64_t deaths = 0;  // members declared dead (no heartbeat)
  uint64_t leaves = 0;
  uint64_t rejected_samples_channel = 0;
  uint64_t rejected_control = 0;
  // Sample-channel messages dropped before the store (docs/service.md, "Identity"), counted
  // here alone so that made-up ids cannot grow the per-sampler state: those that name an id
  // that is no member, and those that name a member without its token or CurveZMQ key.
  uint64_t unknown_sampler_batches = 0;
  uint64_t unknown_sampler_samples = 0;
  uint64_t unknown_sampler_tilings = 0;
  uint64_t spoofed_batches = 0;
  uint64_t spoofed_samples = 0;
  uint64_t spoofed_tilings = 0;
  uint64_t zap_accepted = 0;
  uint64_t zap_refused = 0;
  uint64_t views = 0;
  uint64_t scene_chunks_sent = 0;
  // Display wall (docs/wall.md): this node's id and cell of the virtual display, and the nodes
  // in the wall (1 without a wall).
  uint32_t wall_node = 1;
  PixelRect wall_cell;
  uint64_t wall_nodes = 1;
  uint64_t wall_epoch = 0;
  // On a wall's lead: every cell of the grid and the node that shows it (0: none, the cell is
  // dark), for the dashboard.
  struct WallCell {
    PixelRect cell;
    uint32_t node = 0;
  };
  std::vector<WallCell> wall_cells;
  // What this node exchanged with the other nodes of its wall (WallExchange, docs/wall.md
  // "Seams"): coverage messages and their pixels, stray samples, bytes.
  struct WallExchange {
    uint64_t coverage_in = 0;
    uint64_t coverage_cells_in = 0;
    uint64_t coverage_cells_applied = 0;  // landed on this node's last grid
    uint64_t strays_in = 0;
    uint64_t bytes_in = 0;
    uint64_t coverage_out = 0;
    uint64_t coverage_cells_out = 0;
    uint64_t strays_out = 0;
    uint64_t bytes_out = 0;
    uint64_t dropped_out = 0;  // messages the peers' queues had no room for
  } wall_exchange;
  double latency_p50 = 0.0, latency_p99 = 0.0;  // seconds, since the start
  double window_latency_p50 = 0.0, window_latency_p99 = 0.0;
};

class ServiceMetrics {
 public:
  // Stats periods a departed sampler's figures stay (a minute at the default 2 s period).
  static constexpr int kDepartedPeriods = 30;
  // Departed samplers kept at most: samplers joining and leaving in a loop cannot grow the
  // figures (and /metrics) beyond the members and these.
  static constexpr size_t kMaxDeparted = 64;

  // Ingest thread. `member`: whether the message comes from the member batch.sampler_id names;
  // per-sampler figures are kept for members only, the others are counted as dropped from a
  // non-member.
  void on_batch(const SampleBatch& batch, size_t bytes, bool member);
  void on_tiling(uint32_t sampler_id, size_t bytes, bool member);
  // A member's tiling snapshot as kept (cut to its region): the pixels its tiles cover.
  void set_tiled_pixels(uint32_t sampler_id, int64_t pixels);
  // Ingest thread: a batch or snapshot that named a member without its token or key (dropped).
  void on_spoofed_batch(uint64_t samples);
  void on_spoofed_tiling();
  void on_rejected_sample_message();
  // A display wall's peers: coverage (pixels) and strays (samples) that arrived.
  void on_wall_coverage_in(uint64_t cells, size_t bytes);
  void on_wall_strays_in(uint64_t samples, size_t bytes);
  // Control thread.
  void on_member(const std::string& name, uint32_t id, const std::string& public_key, int threads);
  void on_member_gone(uint32_t id, bool dead);
  void on_region(uint32_t id, const PixelRect& region, uint64_t epoch, uint64_t recuts);
  // The coordinator's measured rate of a member and whether it is starved.
  void set_measured(uint32_t id, double samples_per_second, bool starved);
  // A member's stats message, under the id its control connection belongs to (not the one the
  // message claims).
  void on_reported(uint32_t member_id, const protocol::SamplerStats& stats);
  void on_rejected_control();
  void on_view();
  void on_chunks_sent(uint64_t n);
  // Control thread: how far the scene's transfer to member `id` is.
  void on_scene_progress(uint32_t id, uint32_t sent, uint32_t count);
  void set_zap(uint64_t accepted, uint64_t refused);
  // Display thread: a frame finished at display time `time` (samples received before it are
  // now on screen).
  void on_frame(double time, double reconstruct_ms, uint64_t stored, uint64_t capacity);
  void set_gpu(const GpuTimes& gpu);
  // Display thread: the phases of a GPU backend's reconstruct() call (all zero: none timed).
  void add_call(const CallTimes& call);
  void set_image_counts(uint64_t hole_pixels, uint64_t empty_pixels);
  void set_display(uint64_t session, int width, int height, const std::string& backend,
                   const std::string& mode);
  void set_uptime(double seconds);
  // Display thread: what it applied from and sent to the wall's peers after an image (counts
  // since the previous call; bytes_out and dropped_out are totals).
  void on_wall_exchanged(uint64_t cells_applied, uint64_t coverage_out, uint64_t cells_out,
                         uint64_t strays_out, uint64_t bytes_out_total, uint64_t dropped_out_total);
  // Either thread: the wall as this node knows it.
  void set_wall(uint32_t node_id, const PixelRect& cell, uint64_t nodes, uint64_t epoch);
  // The lead: the grid's cells and who shows each.
  void set_wall_cells(std::vector<DisplayMetrics::WallCell> cells);

  // Rates and windowed latencies: call once per stats period (the log line's).
  void end_period(double seconds);

  DisplayMetrics display() const;
  std::vector<SamplerMetrics> samplers() const;
  LatencyHistogram latency() const;
  // The wall time of every reconstruction since the start, in seconds.
  LatencyHistogram reconstruct_times() const;
  // What the web dashboard shows: the display thread feeds it, the metrics server reads it
  // (it has its own lock).
  DashboardFeed& dashboard() const { return dashboard_; }

 private:
  mutable std::mutex mutex_;
  DisplayMetrics display_;
  std::map<uint32_t, SamplerMetrics> samplers_;
  // Batches received since the last frame: (mean sample time, count).
  std::vector<std::pair<double, uint64_t>> pending_;
  LatencyHistogram latency_, window_latency_, reconstruct_;
  LatencyHistogram period_reconstruct_, period_interval_;  // seconds, this stats period
  double last_frame_time_ = -1.0;
  uint64_t period_frames_ = 0;
  CallTimes period_call_sum_;  // this stats period's sums of add_call()'s phases
  uint64_t period_calls_ = 0;
  double reconstruct_ms_sum_ = 0.0;
  mutable DashboardFeed dashboard_;
};

}  // namespace afr::service
