#include <afr/display/service/metrics.h>

#include <afr/common/error.h>

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <thread>

namespace afr::service {

// ---------------------------------------------------------------------------------------------
// Latency histogram

void LatencyHistogram::add(double seconds, uint64_t weight) {
  if (!std::isfinite(seconds)) return;
  seconds = std::max(0.0, seconds);
  const size_t bin = std::min(kBins, size_t(seconds / kBin));
  bins_[bin] += weight;
  count_ += weight;
  sum_ += seconds * double(weight);
}

double LatencyHistogram::quantile(double q) const {
  if (count_ == 0) return 0.0;
  const uint64_t target = uint64_t(std::ceil(std::clamp(q, 0.0, 1.0) * double(count_)));
  uint64_t seen = 0;
  for (size_t i = 0; i <= kBins; ++i) {
    seen += bins_[i];
    if (seen >= std::max<uint64_t>(1, target)) return (double(i) + 0.5) * kBin;
  }
  return double(kBins) * kBin;
}

uint64_t LatencyHistogram::count_at_most(double seconds) const {
  uint64_t n = 0;
  const size_t last = std::min(kBins, size_t(std::max(0.0, seconds) / kBin));
  for (size_t i = 0; i < last; ++i) n += bins_[i];
  return n;
}

void LatencyHistogram::clear() {
  std::fill(bins_.begin(), bins_.end(), 0);
  count_ = 0;
  sum_ = 0.0;
}

// ---------------------------------------------------------------------------------------------
// Updates

void ServiceMetrics::on_batch(const SampleBatch& batch, size_t bytes, bool member) {
  double sum = 0.0;
  for (const Sample& s : batch.samples) sum += s.time;
  std::lock_guard<std::mutex> lock(mutex_);
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
  if (!member) ++display_.unknown_sampler_batches;
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

void ServiceMetrics::on_tiling(uint32_t sampler_id, size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  SamplerMetrics& m = samplers_[sampler_id];
  m.id = sampler_id;
  ++m.tilings;
  m.bytes += bytes;
  m.period_bytes += bytes;
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

void ServiceMetrics::on_reported(const protocol::SamplerStats& stats) {
  std::lock_guard<std::mutex> lock(mutex_);
  SamplerMetrics& m = samplers_[stats.sampler_id];
  m.id = stats.sampler_id;
  m.reported = stats;
}

void ServiceMetrics::on_rejected_control() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.rejected_control;
}

void ServiceMetrics::on_view() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++display_.views;
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
  display_.reconstruct_ms = ms;
  reconstruct_ms_sum_ += ms;
  display_.reconstruct_ms_mean = reconstruct_ms_sum_ / double(display_.frames);
  display_.store_stored = stored;
  display_.store_capacity = capacity;
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
  }
  display_.refresh_hz = double(period_frames_) / seconds;
  period_frames_ = 0;
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

std::string ServiceMetrics::prometheus() const {
  const DisplayMetrics d = display();
  const std::vector<SamplerMetrics> ss = samplers();
  const LatencyHistogram lat = latency();
  std::string o;
  auto metric = [&](const char* name, const char* type, const char* help) {
    o += fmt::format("# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  };
  auto per_sampler = [&](const char* name, const char* type, const char* help, auto value) {
    metric(name, type, help);
    for (const SamplerMetrics& s : ss) {
      o += fmt::format("{}{{sampler=\"{}\"}} {}\n", name, s.id, value(s));
    }
  };
  per_sampler("afr_sampler_member", "gauge", "1 while the sampler is a member",
              [](const SamplerMetrics& s) { return int(s.member); });
  per_sampler("afr_sampler_samples_total", "counter", "samples received",
              [](const SamplerMetrics& s) { return s.samples; });
  per_sampler("afr_sampler_samples_per_second", "gauge", "samples received per second",
              [](const SamplerMetrics& s) { return s.samples_per_second; });
  per_sampler("afr_sampler_bytes_total", "counter", "bytes received on the sample channel",
              [](const SamplerMetrics& s) { return s.bytes; });
  per_sampler("afr_sampler_bytes_per_second", "gauge", "bytes received per second",
              [](const SamplerMetrics& s) { return s.bytes_per_second; });
  per_sampler("afr_sampler_batches_total", "counter", "batches received",
              [](const SamplerMetrics& s) { return s.batches; });
  per_sampler("afr_sampler_batches_dropped_total", "counter",
              "batches the sampler dropped (its queue was full), as it reports",
              [](const SamplerMetrics& s) { return s.reported.batches_dropped; });
  per_sampler("afr_sampler_sequence_gaps_total", "counter",
              "batches missing from the sequence numbers received",
              [](const SamplerMetrics& s) { return s.sequence_gaps; });
  per_sampler("afr_sampler_reported_samples_per_second", "gauge",
              "samples per second the sampler reports",
              [](const SamplerMetrics& s) { return s.reported.samples_per_second; });
  per_sampler("afr_sampler_region_pixels", "gauge", "pixels of the sampler's region",
              [](const SamplerMetrics& s) { return s.region.area(); });
  metric("afr_sampler_region", "gauge", "the sampler's region, labels x0 y0 x1 y1");
  for (const SamplerMetrics& s : ss) {
    o += fmt::format(
        "afr_sampler_region{{sampler=\"{}\",x0=\"{}\",y0=\"{}\",x1=\"{}\",y1=\"{}\"}} 1\n", s.id,
        s.region.x0, s.region.y0, s.region.x1, s.region.y1);
  }
  auto scalar = [&](const char* name, const char* type, const char* help, auto value) {
    metric(name, type, help);
    o += fmt::format("{} {}\n", name, value);
  };
  scalar("afr_display_members", "gauge", "samplers in the session", d.members);
  scalar("afr_display_frames_total", "counter", "images reconstructed", d.frames);
  scalar("afr_display_reconstruct_ms", "gauge", "wall time of the last reconstruction",
         d.reconstruct_ms);
  scalar("afr_display_refresh_hz", "gauge", "images per second", d.refresh_hz);
  scalar("afr_display_store_samples", "gauge", "samples in the store", d.store_stored);
  scalar("afr_display_store_capacity", "gauge", "capacity of the store", d.store_capacity);
  scalar("afr_display_recuts_total", "counter", "region recuts", d.recuts);
  scalar("afr_display_deaths_total", "counter", "samplers declared dead", d.deaths);
  scalar("afr_display_rejected_messages_total", "counter",
         "messages rejected on the sample and control channels",
         d.rejected_samples_channel + d.rejected_control);
  scalar("afr_display_zap_refused_total", "counter", "CurveZMQ clients refused", d.zap_refused);
  scalar("afr_display_wall_nodes", "gauge", "display nodes in the wall (1: no wall)", d.wall_nodes);
  metric("afr_display_wall_cell", "gauge",
         "this node's part of the virtual display, labels node x0 y0 x1 y1");
  o += fmt::format(
      "afr_display_wall_cell{{node=\"{}\",x0=\"{}\",y0=\"{}\",x1=\"{}\",y1=\"{}\"}} 1\n",
      d.wall_node, d.wall_cell.x0, d.wall_cell.y0, d.wall_cell.x1, d.wall_cell.y1);
  const DisplayMetrics::WallExchange& w = d.wall_exchange;
  scalar("afr_display_wall_coverage_in_total", "counter",
         "coverage messages from the wall's other nodes", w.coverage_in);
  scalar("afr_display_wall_coverage_applied_pixels_total", "counter",
         "pixels of this node's coverage map replaced by its peers'", w.coverage_cells_applied);
  scalar("afr_display_wall_strays_in_total", "counter",
         "samples forwarded by the wall's other nodes", w.strays_in);
  scalar("afr_display_wall_coverage_out_total", "counter",
         "coverage messages sent to the wall's other nodes", w.coverage_out);
  scalar("afr_display_wall_strays_out_total", "counter",
         "samples forwarded to the wall's other nodes", w.strays_out);
  scalar("afr_display_wall_exchange_bytes_in_total", "counter",
         "bytes of coverage and strays from the wall's other nodes", w.bytes_in);
  scalar("afr_display_wall_exchange_bytes_out_total", "counter",
         "bytes of coverage and strays to the wall's other nodes", w.bytes_out);
  scalar("afr_display_wall_exchange_dropped_total", "counter",
         "coverage and stray messages the peers' queues had no room for", w.dropped_out);
  metric("afr_display_sample_latency_seconds", "histogram",
         "sample-to-display latency: display time of the frame that first shows a sample "
         "minus the sample's time");
  for (double le : {0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0}) {
    o += fmt::format("afr_display_sample_latency_seconds_bucket{{le=\"{}\"}} {}\n", le,
                     lat.count_at_most(le));
  }
  o += fmt::format("afr_display_sample_latency_seconds_bucket{{le=\"+Inf\"}} {}\n", lat.count());
  o += fmt::format("afr_display_sample_latency_seconds_sum {}\n", lat.sum());
  o += fmt::format("afr_display_sample_latency_seconds_count {}\n", lat.count());
  return o;
}

std::string ServiceMetrics::json() const {
  const DisplayMetrics d = display();
  nlohmann::json j;
  j["display"] = {{"session", fmt::format("{:x}", d.session)},
                  {"uptime", d.uptime},
                  {"width", d.width},
                  {"height", d.height},
                  {"backend", d.backend},
                  {"mode", d.mode},
                  {"frames", d.frames},
                  {"reconstruct_ms", d.reconstruct_ms},
                  {"reconstruct_ms_mean", d.reconstruct_ms_mean},
                  {"refresh_hz", d.refresh_hz},
                  {"store_samples", d.store_stored},
                  {"store_capacity", d.store_capacity},
                  {"members", d.members},
                  {"joins", d.joins},
                  {"deaths", d.deaths},
                  {"leaves", d.leaves},
                  {"recuts", d.recuts},
                  {"region_epoch", d.region_epoch},
                  {"views", d.views},
                  {"scene_chunks_sent", d.scene_chunks_sent},
                  {"rejected_sample_messages", d.rejected_samples_channel},
                  {"rejected_control_messages", d.rejected_control},
                  {"unknown_sampler_batches", d.unknown_sampler_batches},
                  {"zap_accepted", d.zap_accepted},
                  {"zap_refused", d.zap_refused},
                  {"latency_p50", d.latency_p50},
                  {"latency_p99", d.latency_p99},
                  {"window_latency_p50", d.window_latency_p50},
                  {"window_latency_p99", d.window_latency_p99},
                  {"wall",
                   {{"node", d.wall_node},
                    {"cell", {d.wall_cell.x0, d.wall_cell.y0, d.wall_cell.x1, d.wall_cell.y1}},
                    {"nodes", d.wall_nodes},
                    {"epoch", d.wall_epoch},
                    {"exchange",
                     {{"coverage_in", d.wall_exchange.coverage_in},
                      {"coverage_cells_in", d.wall_exchange.coverage_cells_in},
                      {"coverage_cells_applied", d.wall_exchange.coverage_cells_applied},
                      {"strays_in", d.wall_exchange.strays_in},
                      {"bytes_in", d.wall_exchange.bytes_in},
                      {"coverage_out", d.wall_exchange.coverage_out},
                      {"coverage_cells_out", d.wall_exchange.coverage_cells_out},
                      {"strays_out", d.wall_exchange.strays_out},
                      {"bytes_out", d.wall_exchange.bytes_out},
                      {"dropped_out", d.wall_exchange.dropped_out}}}}}};
  j["samplers"] = nlohmann::json::array();
  for (const SamplerMetrics& s : samplers()) {
    j["samplers"].push_back({{"id", s.id},
                             {"name", s.name},
                             {"member", s.member},
                             {"threads", s.threads},
                             {"region", {s.region.x0, s.region.y0, s.region.x1, s.region.y1}},
                             {"samples", s.samples},
                             {"bytes", s.bytes},
                             {"batch_bytes", s.batch_bytes},
                             {"batches", s.batches},
                             {"tilings", s.tilings},
                             {"sequence_gaps", s.sequence_gaps},
                             {"samples_per_second", s.samples_per_second},
                             {"bytes_per_second", s.bytes_per_second},
                             {"reported_samples", s.reported.samples},
                             {"reported_samples_per_second", s.reported.samples_per_second},
                             {"batches_dropped", s.reported.batches_dropped},
                             {"bytes_sent", s.reported.bytes_sent}});
  }
  return j.dump(1);
}

std::string ServiceMetrics::log_line() const {
  const DisplayMetrics d = display();
  std::string o = fmt::format(
      "t={:.1f}s {} sampler(s) | display {:.1f} Hz, reconstruct {:.1f} ms, store {:.0f}%, "
      "latency p50 {:.1f} ms p99 {:.1f} ms",
      d.uptime, d.members, d.refresh_hz, d.reconstruct_ms,
      d.store_capacity ? 100.0 * double(d.store_stored) / double(d.store_capacity) : 0.0,
      d.window_latency_p50 * 1e3, d.window_latency_p99 * 1e3);
  for (const SamplerMetrics& s : samplers()) {
    if (!s.member) continue;
    o += fmt::format(" | #{} {:.0f} k/s dropped {} gaps {}", s.id, s.samples_per_second * 1e-3,
                     s.reported.batches_dropped, s.sequence_gaps);
  }
  return o;
}

// ---------------------------------------------------------------------------------------------
// HTTP

struct MetricsServer::Impl {
  httplib::Server server;
  std::thread thread;
  std::string address;
  int port = 0;
};

MetricsServer::MetricsServer(const ServiceMetrics& metrics, const std::string& address, int port)
    : impl_(std::make_unique<Impl>()) {
  impl_->address = address;
  impl_->port = port;
  impl_->server.Get("/metrics", [&metrics](const httplib::Request&, httplib::Response& res) {
    res.set_content(metrics.prometheus(), "text/plain; version=0.0.4");
  });
  impl_->server.Get("/stats", [&metrics](const httplib::Request&, httplib::Response& res) {
    res.set_content(metrics.json(), "application/json");
  });
  if (!impl_->server.bind_to_port(address.c_str(), port)) {
    throw Error(fmt::format("cannot serve metrics on {}:{} (port in use?)", address, port));
  }
}

MetricsServer::~MetricsServer() { stop(); }

void MetricsServer::start() {
  if (impl_->thread.joinable()) return;
  impl_->thread = std::thread([this] { impl_->server.listen_after_bind(); });
  spdlog::info("metrics on http://{}:{}/metrics and /stats", impl_->address, impl_->port);
}

void MetricsServer::stop() {
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace afr::service
