#include <afr/display/service/metrics.h>

#include <algorithm>
#include <cmath>

namespace afr::service {

// ---------------------------------------------------------------------------------------------
// Updates

void ServiceMetrics::on_batch(const SampleBatch& batch, size_t bytes, bool member) {
  double sum = 0.0;
  for (const Sample& s : batch.samples) sum += s.time;
  std::lock_guard<std::mutex> lock(mutex_);
  if (!member) {
    ++display_.unknown_sampler_batches;
    display_.unknown_sampler_samples += batch.samples.size();
    return;
  }
  SamplerMetrics& m = samplers_[batch.sampler_id];
  m.id = batch.sampler_id;
  m.samples += batch.samples.size();
  m.period_samples += batch.samples.size();
  m.bytes += bytes;
  m.batch_bytes += bytes;
  m.period_bytes += bytes;
  ++m.batches;
  // A sequence that goes back is a restarted sampler, not a gap.
  if (m.have_sequence && batch.sequence > m.last_sequence) {
    m.sequence_gaps += batch.sequence - m.last_sequence - 1;
  }
  m.last_sequence = batch.sequence;
  m.have_sequence = true;
  if (!batch.samples.empty()) {
    if (pending_.size() >= 65536) pending_.erase(pending_.begin(), pending_.begin() + 32768);
    pending_.emplace_back(sum / double(batch.samples.size()), batch.samples.size());
  }
}

void ServiceMetrics::on_wall_coverage_in(uint64_t cells, size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.wall_exchange.coverage_in;
  display_.wall_exchange.coverage_cells_in += cells;
  display_.wall_exchange.bytes_in += bytes;
}

void ServiceMetrics::on_wall_strays_in(uint64_t samples, size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.wall_exchange.strays_in += samples;
  display_.wall_exchange.bytes_in += bytes;
}

void ServiceMetrics::on_wall_exchanged(uint64_t cells_applied, uint64_t coverage_out,
                                       uint64_t cells_out, uint64_t strays_out,
                                       uint64_t bytes_out_total, uint64_t dropped_out_total) {
  std::lock_guard<std::mutex> lock(mutex_);
  DisplayMetrics::WallExchange& w = display_.wall_exchange;
  w.coverage_cells_applied += cells_applied;
  w.coverage_out += coverage_out;
  w.coverage_cells_out += cells_out;
  w.strays_out += strays_out;
  w.bytes_out = bytes_out_total;
  w.dropped_out = dropped_out_total;
}

void ServiceMetrics::on_tiling(uint32_t sampler_id, size_t bytes, bool member) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!member) {
    ++display_.unknown_sampler_tilings;
    return;
  }
  SamplerMetrics& m = samplers_[sampler_id];
  m.id = sampler_id;
  ++m.tilings;
  m.bytes += bytes;
  m.period_bytes += bytes;
}

void ServiceMetrics::set_tiled_pixels(uint32_t sampler_id, int64_t pixels) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = samplers_.find(sampler_id);
  if (it != samplers_.end()) it->second.tiled_pixels = pixels;
}

void ServiceMetrics::on_spoofed_batch(uint64_t samples) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.spoofed_batches;
  display_.spoofed_samples += samples;
}

void ServiceMetrics::on_spoofed_tiling() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.spoofed_tilings;
}

void ServiceMetrics::on_rejected_sample_message() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.rejected_samples_channel;
}

void ServiceMetrics::on_member(const std::string& name, uint32_t id, const std::string& key,
                               int threads) {
  std::lock_guard<std::mutex> lock(mutex_);
  SamplerMetrics& m = samplers_[id];
  m.id = id;
  m.name = name;
  m.public_key = key;
  m.threads = threads;
  m.member = true;
  m.periods_gone = 0;
  ++display_.joins;
  display_.members = 0;
  for (const auto& [i, s] : samplers_) display_.members += s.member;
}

void ServiceMetrics::on_member_gone(uint32_t id, bool dead) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = samplers_.find(id);
  if (it != samplers_.end()) {
    it->second.member = false;
    it->second.region = PixelRect{};
  }
  ++(dead ? display_.deaths : display_.leaves);
  // Beyond kMaxDeparted departed samplers, the longest gone first, and of those gone as long
  // the first to join (ids are handed out in order).
  std::vector<std::pair<int, uint32_t>> departed;
  for (const auto& [i, s] : samplers_) {
    if (!s.member) departed.emplace_back(-s.periods_gone, i);
  }
  if (departed.size() > kMaxDeparted) {
    std::sort(departed.begin(), departed.end());
    for (size_t k = 0; k < departed.size() - kMaxDeparted; ++k) samplers_.erase(departed[k].second);
  }
  display_.members = 0;
  for (const auto& [i, s] : samplers_) display_.members += s.member;
}

void ServiceMetrics::on_region(uint32_t id, const PixelRect& region, uint64_t epoch,
                               uint64_t recuts) {
  std::lock_guard<std::mutex> lock(mutex_);
  samplers_[id].region = region;
  display_.region_epoch = epoch;
  display_.recuts = recuts;
}

void ServiceMetrics::set_measured(uint32_t id, double samples_per_second, bool starved) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = samplers_.find(id);
  if (it == samplers_.end() || !it->second.member) return;
  it->second.measured_samples_per_second = samples_per_second;
  it->second.starved = starved;
}

void ServiceMetrics::on_reported(uint32_t member_id, const protocol::SamplerStats& stats) {
  std::lock_guard<std::mutex> lock(mutex_);
  SamplerMetrics& m = samplers_[member_id];
  m.id = member_id;
  m.reported = stats;
  m.reported.sampler_id = member_id;
}

void ServiceMetrics::on_rejected_control() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.rejected_control;
}

void ServiceMetrics::on_view() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.views;
}

void ServiceMetrics::on_scene_progress(uint32_t id, uint32_t sent, uint32_t count) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = samplers_.find(id);
  if (it == samplers_.end()) return;  // members only
  it->second.scene_chunks_sent = sent;
  it->second.scene_chunks = count;
}

void ServiceMetrics::on_chunks_sent(uint64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.scene_chunks_sent += n;
}

void ServiceMetrics::set_zap(uint64_t accepted, uint64_t refused) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.zap_accepted = accepted;
  display_.zap_refused = refused;
}

void ServiceMetrics::on_frame(double time, double ms, uint64_t stored, uint64_t capacity) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [t, n] : pending_) {
    latency_.add(time - t, n);
    window_latency_.add(time - t, n);
  }
  pending_.clear();
  ++display_.frames;
  ++period_frames_;
  period_reconstruct_.add(ms * 1e-3, 1);
  reconstruct_.add(ms * 1e-3, 1);
  if (last_frame_time_ >= 0.0 && time >= last_frame_time_) {
    period_interval_.add(time - last_frame_time_, 1);
  }
  last_frame_time_ = time;
  display_.reconstruct_ms = ms;
  reconstruct_ms_sum_ += ms;
  display_.reconstruct_ms_mean = reconstruct_ms_sum_ / double(display_.frames);
  display_.store_stored = stored;
  display_.store_capacity = capacity;
}

void ServiceMetrics::set_gpu(const GpuTimes& gpu) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.gpu = gpu;
}

void ServiceMetrics::add_call(const CallTimes& call) {
  if (call.wait + call.copy + call.prepare + call.upload + call.passes <= 0.0) return;
  std::lock_guard<std::mutex> lock(mutex_);
  period_call_sum_.wait += call.wait;
  period_call_sum_.copy += call.copy;
  period_call_sum_.prepare += call.prepare;
  period_call_sum_.upload += call.upload;
  period_call_sum_.passes += call.passes;
  ++period_calls_;
}

void ServiceMetrics::set_image_counts(uint64_t hole_pixels, uint64_t empty_pixels) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.hole_pixels = hole_pixels;
  display_.empty_pixels = empty_pixels;
}

void ServiceMetrics::set_display(uint64_t session, int width, int height,
                                 const std::string& backend, const std::string& mode) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.session = session;
  display_.width = width;
  display_.height = height;
  display_.backend = backend;
  display_.mode = mode;
}

void ServiceMetrics::set_wall_cells(std::vector<DisplayMetrics::WallCell> cells) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.wall_cells = std::move(cells);
}

void ServiceMetrics::set_wall(uint32_t node_id, const PixelRect& cell, uint64_t nodes,
                              uint64_t epoch) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.wall_node = node_id;
  display_.wall_cell = cell;
  display_.wall_nodes = nodes;
  display_.wall_epoch = epoch;
}

void ServiceMetrics::set_uptime(double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  display_.uptime = seconds;
}

void ServiceMetrics::end_period(double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (seconds <= 0.0) return;
  for (auto& [id, m] : samplers_) {
    m.samples_per_second = double(m.period_samples) / seconds;
    m.bytes_per_second = double(m.period_bytes) / seconds;
    m.period_samples = m.period_bytes = 0;
    if (!m.member) ++m.periods_gone;
  }
  std::erase_if(samplers_, [](const auto& e) { return e.second.periods_gone > kDepartedPeriods; });
  display_.refresh_hz = double(period_frames_) / seconds;
  period_frames_ = 0;
  display_.period_reconstruct_ms_mean =
      period_reconstruct_.count() > 0
          ? 1e3 * period_reconstruct_.sum() / double(period_reconstruct_.count())
          : 0.0;
  display_.period_reconstruct_ms_p99 = 1e3 * period_reconstruct_.quantile(0.99);
  display_.period_frame_interval_ms_p99 = 1e3 * period_interval_.quantile(0.99);
  display_.call_timed = period_calls_ > 0;
  if (period_calls_ > 0) {
    const double n = double(period_calls_);
    const CallTimes& c = period_call_sum_;
    display_.period_call =
        CallTimes{c.wait / n, c.copy / n, c.prepare / n, c.upload / n, c.passes / n};
  }
  period_call_sum_ = CallTimes{};
  period_calls_ = 0;
  period_reconstruct_.clear();
  period_interval_.clear();
  display_.window_latency_p50 = window_latency_.quantile(0.5);
  display_.window_latency_p99 = window_latency_.quantile(0.99);
  window_latency_.clear();
}

// ---------------------------------------------------------------------------------------------
// Reading

DisplayMetrics ServiceMetrics::display() const {
  std::lock_guard<std::mutex> lock(mutex_);
  DisplayMetrics d = display_;
  d.latency_p50 = latency_.quantile(0.5);
  d.latency_p99 = latency_.quantile(0.99);
  return d;
}

std::vector<SamplerMetrics> ServiceMetrics::samplers() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<SamplerMetrics> out;
  for (const auto& [id, m] : samplers_) out.push_back(m);
  return out;
}

LatencyHistogram ServiceMetrics::latency() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latency_;
}

LatencyHistogram ServiceMetrics::reconstruct_times() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reconstruct_;
}

}  // namespace afr::service
