#include <afr/display/service/metrics_exposition.h>

#include <fmt/format.h>
#include <prometheus/metric_family.h>
#include <prometheus/text_serializer.h>
#include <nlohmann/json.hpp>

#include <array>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace afr::service {

namespace {

std::vector<std::pair<const char*, double>> gpu_passes(const GpuTimes& g) {
  return {{"upload", g.upload}, {"bin", g.bin},           {"splat", g.splat},
          {"fill", g.fill},     {"readback", g.readback}, {"image", g.total()}};
}

std::vector<std::pair<const char*, double>> call_phases(const CallTimes& c) {
  return {{"wait", c.wait},
          {"copy", c.copy},
          {"prepare", c.prepare},
          {"upload", c.upload},
          {"passes", c.passes}};
}

// A wall lead's cells: [{"cell": [x0, y0, x1, y1], "node": id or 0 (dark)}, ...].
nlohmann::json wall_cells_json(const std::vector<DisplayMetrics::WallCell>& cells) {
  nlohmann::json j = nlohmann::json::array();
  for (const DisplayMetrics::WallCell& c : cells) {
    j.push_back({{"cell", {c.cell.x0, c.cell.y0, c.cell.x1, c.cell.y1}}, {"node", c.node}});
  }
  return j;
}

// null for a CPU backend (no GPU times yet).
nlohmann::json gpu_json(const GpuTimes& g) {
  if (!g.timed) return nullptr;
  nlohmann::json j;
  for (const auto& [pass, ms] : gpu_passes(g)) j[pass] = ms;
  return j;
}

// The GPU backend's call phases over the last stats period, or null (the CPU backend).
nlohmann::json call_json(const DisplayMetrics& d) {
  if (!d.call_timed) return nullptr;
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [phase, ms] : call_phases(d.period_call)) j[phase] = ms;
  return j;
}

}  // namespace

// The Prometheus exposition: the families are built from one reading of ServiceMetrics and
// written by prometheus-cpp's TextSerializer (names, escaping and the text format are its).
// Conventions (https://prometheus.io/docs/practices/naming/): base units (seconds, bytes), a
// counter's name ends in _total, and labels take a bounded set of values (a sampler's id, a
// pass, an edge), never a measurement such as a region's coordinates, which would start new
// series at every recut.
std::string prometheus_text(const ServiceMetrics& metrics) {
  using prometheus::ClientMetric;
  using prometheus::MetricFamily;
  using prometheus::MetricType;
  const DisplayMetrics d = metrics.display();
  const std::vector<SamplerMetrics> ss = metrics.samplers();
  std::vector<MetricFamily> families;

  auto family = [&](std::string name, MetricType type, std::string help) -> MetricFamily& {
    families.push_back({std::move(name), std::move(help), type, {}});
    return families.back();
  };
  auto sample = [](MetricType type, double value, std::vector<ClientMetric::Label> labels = {}) {
    ClientMetric m;
    m.label = std::move(labels);
    if (type == MetricType::Counter)
      m.counter.value = value;
    else
      m.gauge.value = value;
    return m;
  };
  auto scalar = [&](std::string name, MetricType type, std::string help, double value) {
    family(std::move(name), type, std::move(help)).metric.push_back(sample(type, value));
  };
  auto per_sampler = [&](std::string name, MetricType type, std::string help, auto value) {
    MetricFamily& f = family(std::move(name), type, std::move(help));
    for (const SamplerMetrics& s : ss) {
      f.metric.push_back(sample(type, double(value(s)), {{"sampler", std::to_string(s.id)}}));
    }
  };
  auto edges = [](const PixelRect& r) {
    return std::array<std::pair<const char*, int>, 4>{
        {{"x0", r.x0}, {"y0", r.y0}, {"x1", r.x1}, {"y1", r.y1}}};
  };
  // Upper bounds from 1 ms to 2 s (LatencyHistogram's range), and +Inf.
  auto histogram = [&](std::string name, std::string help, const LatencyHistogram& h) {
    ClientMetric m;
    for (double le : {0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0}) {
      m.histogram.bucket.push_back({h.count_at_most(le), le});
    }
    m.histogram.bucket.push_back({h.count(), std::numeric_limits<double>::infinity()});
    m.histogram.sample_count = h.count();
    m.histogram.sample_sum = h.sum();
    family(std::move(name), MetricType::Histogram, std::move(help)).metric.push_back(m);
  };
  constexpr auto counter = MetricType::Counter;
  constexpr auto gauge = MetricType::Gauge;

  per_sampler("afr_sampler_member", gauge, "1 while the sampler is a member",
              [](const SamplerMetrics& s) { return int(s.member); });
  per_sampler("afr_sampler_samples_total", counter, "samples received",
              [](const SamplerMetrics& s) { return s.samples; });
  per_sampler("afr_sampler_samples_per_second", gauge,
              "samples received per second over the last stats period",
              [](const SamplerMetrics& s) { return s.samples_per_second; });
  per_sampler("afr_sampler_bytes_total", counter, "bytes received on the sample channel",
              [](const SamplerMetrics& s) { return s.bytes; });
  per_sampler("afr_sampler_bytes_per_second", gauge,
              "bytes received per second over the last stats period",
              [](const SamplerMetrics& s) { return s.bytes_per_second; });
  per_sampler("afr_sampler_batches_total", counter, "batches received",
              [](const SamplerMetrics& s) { return s.batches; });
  per_sampler("afr_sampler_batches_dropped_total", counter,
              "batches the sampler dropped (its queue was full), as it reports",
              [](const SamplerMetrics& s) { return s.reported.batches_dropped; });
  per_sampler("afr_sampler_sequence_gaps_total", counter,
              "batches missing from the sequence numbers received",
              [](const SamplerMetrics& s) { return s.sequence_gaps; });
  per_sampler("afr_sampler_reported_samples_per_second", gauge,
              "samples per second the sampler reports (shown only: shares are measured)",
              [](const SamplerMetrics& s) { return s.reported.samples_per_second; });
  per_sampler("afr_sampler_measured_samples_per_second", gauge,
              "samples per second accepted from the sampler, smoothed: what its share follows",
              [](const SamplerMetrics& s) { return s.measured_samples_per_second; });
  per_sampler("afr_sampler_starved", gauge,
              "1 while nothing arrives from the sampler and others deliver (its region is a strip)",
              [](const SamplerMetrics& s) { return int(s.starved); });
  per_sampler("afr_sampler_region_pixels", gauge, "pixels of the sampler's region",
              [](const SamplerMetrics& s) { return s.region.area(); });
  {
    MetricFamily& f = family("afr_sampler_region_edge_pixels", gauge,
                             "the sampler's region: its edges x0 y0 (inclusive), x1 y1 "
                             "(exclusive) in pixels of the whole image");
    for (const SamplerMetrics& s : ss) {
      for (const auto& [edge, value] : edges(s.region)) {
        f.metric.push_back(
            sample(gauge, value, {{"edge", edge}, {"sampler", std::to_string(s.id)}}));
      }
    }
  }

  scalar("afr_display_members", gauge, "samplers in the session", double(d.members));
  scalar("afr_display_frames_total", counter, "images reconstructed", double(d.frames));
  scalar("afr_display_last_reconstruct_seconds", gauge, "wall time of the last reconstruction",
         d.reconstruct_ms * 1e-3);
  histogram("afr_display_reconstruct_seconds", "wall time of each reconstruction",
            metrics.reconstruct_times());
  scalar("afr_display_refresh_hz", gauge, "images per second over the last stats period",
         d.refresh_hz);
  if (d.gpu.timed) {
    MetricFamily& f =
        family("afr_display_gpu_pass_seconds", gauge,
               "GPU time of each pass of the latest image the GPU finished (GL_TIME_ELAPSED)");
    for (const auto& [pass, ms] : gpu_passes(d.gpu)) {
      f.metric.push_back(sample(gauge, ms * 1e-3, {{"pass", pass}}));
    }
  }
  scalar("afr_display_hole_pixels", gauge,
         "pixels of the latest image no splat reached (filled from wider support)",
         double(d.hole_pixels));
  scalar("afr_display_empty_pixels", gauge,
         "pixels of the latest image with no sample weight anywhere (black)",
         double(d.empty_pixels));
  if (d.call_timed) {
    MetricFamily& f = family("afr_display_period_call_phase_seconds", gauge,
                             "mean wall time of each phase of a GPU backend's reconstruction call "
                             "over the last stats period");
    for (const auto& [phase, ms] : call_phases(d.period_call)) {
      f.metric.push_back(sample(gauge, ms * 1e-3, {{"phase", phase}}));
    }
  }
  scalar("afr_display_period_reconstruct_mean_seconds", gauge,
         "mean reconstruction time over the last stats period",
         d.period_reconstruct_ms_mean * 1e-3);
  scalar("afr_display_period_reconstruct_p99_seconds", gauge,
         "99th percentile of the reconstruction time over the last stats period",
         d.period_reconstruct_ms_p99 * 1e-3);
  scalar("afr_display_period_frame_interval_p99_seconds", gauge,
         "99th percentile of the time between images over the last stats period",
         d.period_frame_interval_ms_p99 * 1e-3);
  scalar("afr_display_store_samples", gauge, "samples in the store", double(d.store_stored));
  scalar("afr_display_store_capacity", gauge, "capacity of the store", double(d.store_capacity));
  scalar("afr_display_recuts_total", counter, "region recuts", double(d.recuts));
  scalar("afr_display_deaths_total", counter, "samplers declared dead", double(d.deaths));
  scalar("afr_display_rejected_messages_total", counter,
         "messages rejected on the sample and control channels",
         double(d.rejected_samples_channel + d.rejected_control));
  auto by_cause = [&](std::string name, std::string help, uint64_t non_member, uint64_t spoofed) {
    MetricFamily& f = family(std::move(name), counter, std::move(help));
    f.metric.push_back(sample(counter, double(non_member), {{"cause", "non_member"}}));
    f.metric.push_back(sample(counter, double(spoofed), {{"cause", "spoofed"}}));
  };
  by_cause("afr_display_dropped_batches_total",
           "sample batches dropped before the store: from no member, or naming a member without "
           "its token or key",
           d.unknown_sampler_batches, d.spoofed_batches);
  by_cause("afr_display_dropped_samples_total", "samples of the dropped batches",
           d.unknown_sampler_samples, d.spoofed_samples);
  by_cause("afr_display_dropped_tilings_total",
           "tiling snapshots dropped: from no member, or naming a member without its token or key",
           d.unknown_sampler_tilings, d.spoofed_tilings);
  scalar("afr_display_zap_refused_total", counter, "CurveZMQ clients refused",
         double(d.zap_refused));

  scalar("afr_display_wall_nodes", gauge, "display nodes in the wall (1: no wall)",
         double(d.wall_nodes));
  scalar("afr_display_wall_node", gauge, "this node's id in the wall (0: the lead)",
         double(d.wall_node));
  {
    MetricFamily& f = family("afr_display_wall_cell_edge_pixels", gauge,
                             "this node's part of the virtual display: its edges x0 y0 "
                             "(inclusive), x1 y1 (exclusive) in pixels");
    for (const auto& [edge, value] : edges(d.wall_cell)) {
      f.metric.push_back(sample(gauge, value, {{"edge", edge}}));
    }
  }
  const DisplayMetrics::WallExchange& w = d.wall_exchange;
  scalar("afr_display_wall_coverage_in_total", counter,
         "coverage messages from the wall's other nodes", double(w.coverage_in));
  scalar("afr_display_wall_coverage_applied_pixels_total", counter,
         "pixels of this node's coverage map replaced by its peers'",
         double(w.coverage_cells_applied));
  scalar("afr_display_wall_strays_in_total", counter, "samples forwarded by the wall's other nodes",
         double(w.strays_in));
  scalar("afr_display_wall_coverage_out_total", counter,
         "coverage messages sent to the wall's other nodes", double(w.coverage_out));
  scalar("afr_display_wall_strays_out_total", counter,
         "samples forwarded to the wall's other nodes", double(w.strays_out));
  scalar("afr_display_wall_exchange_in_bytes_total", counter,
         "bytes of coverage and strays from the wall's other nodes", double(w.bytes_in));
  scalar("afr_display_wall_exchange_out_bytes_total", counter,
         "bytes of coverage and strays to the wall's other nodes", double(w.bytes_out));
  scalar("afr_display_wall_exchange_dropped_total", counter,
         "coverage and stray messages the peers' queues had no room for", double(w.dropped_out));
  histogram("afr_display_sample_latency_seconds",
            "sample-to-display latency: display time of the frame that first shows a sample "
            "minus the sample's time",
            metrics.latency());
  return prometheus::TextSerializer().Serialize(families);
}

std::string stats_json(const ServiceMetrics& metrics) {
  const DisplayMetrics d = metrics.display();
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
                  {"gpu_ms", gpu_json(d.gpu)},
                  {"refresh_hz", d.refresh_hz},
                  {"period_reconstruct_ms_mean", d.period_reconstruct_ms_mean},
                  {"period_reconstruct_ms_p99", d.period_reconstruct_ms_p99},
                  {"period_frame_interval_ms_p99", d.period_frame_interval_ms_p99},
                  {"period_call_ms", call_json(d)},
                  {"hole_pixels", d.hole_pixels},
                  {"empty_pixels", d.empty_pixels},
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
                  {"unknown_sampler_samples", d.unknown_sampler_samples},
                  {"unknown_sampler_tilings", d.unknown_sampler_tilings},
                  {"spoofed_batches", d.spoofed_batches},
                  {"spoofed_samples", d.spoofed_samples},
                  {"spoofed_tilings", d.spoofed_tilings},
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
                    {"cells", wall_cells_json(d.wall_cells)},
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
  for (const SamplerMetrics& s : metrics.samplers()) {
    j["samplers"].push_back(
        {{"id", s.id},
         {"name", s.name},
         {"member", s.member},
         {"threads", s.threads},
         {"region", {s.region.x0, s.region.y0, s.region.x1, s.region.y1}},
         {"samples", s.samples},
         {"bytes", s.bytes},
         {"batch_bytes", s.batch_bytes},
         {"batches", s.batches},
         {"tilings", s.tilings},
         {"tiled_pixels", s.tiled_pixels},
         {"sequence_gaps", s.sequence_gaps},
         {"samples_per_second", s.samples_per_second},
         {"bytes_per_second", s.bytes_per_second},
         {"reported_samples", s.reported.samples},
         {"reported_samples_per_second", s.reported.samples_per_second},
         {"measured_samples_per_second", s.measured_samples_per_second},
         {"starved", s.starved},
         {"scene", {{"chunks_sent", s.scene_chunks_sent}, {"chunks", s.scene_chunks}}},
         {"batches_dropped", s.reported.batches_dropped},
         {"bytes_sent", s.reported.bytes_sent}});
  }
  return j.dump(1);
}

std::string stats_line(const ServiceMetrics& metrics) {
  const DisplayMetrics d = metrics.display();
  std::string o = fmt::format(
      "t={:.1f}s {} sampler(s) | display {:.1f} Hz (interval p99 {:.1f} ms), reconstruct mean "
      "{:.1f} ms p99 {:.1f} ms, store {:.0f}%, latency p50 {:.1f} ms p99 {:.1f} ms",
      d.uptime, d.members, d.refresh_hz, d.period_frame_interval_ms_p99,
      d.period_reconstruct_ms_mean, d.period_reconstruct_ms_p99,
      d.store_capacity ? 100.0 * double(d.store_stored) / double(d.store_capacity) : 0.0,
      d.window_latency_p50 * 1e3, d.window_latency_p99 * 1e3);
  if (d.gpu.timed) o += fmt::format(", GPU {:.2f} ms", d.gpu.total());
  if (d.call_timed) {
    const CallTimes& c = d.period_call;
    o += fmt::format(
        " (call: wait {:.1f} copy {:.1f} prepare {:.1f} upload {:.1f} passes {:.1f} ms)", c.wait,
        c.copy, c.prepare, c.upload, c.passes);
  }
  for (const SamplerMetrics& s : metrics.samplers()) {
    if (!s.member) continue;
    o += fmt::format(" | #{} {:.0f} k/s dropped {} gaps {}", s.id, s.samples_per_second * 1e-3,
                     s.reported.batches_dropped, s.sequence_gaps);
  }
  return o;
}

}  // namespace afr::service
