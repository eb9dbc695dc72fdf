// The seam measurement of docs/wall.md ("Seams"): a 2 x 2 wall of 512 x 512 display nodes, each
// sent only what the samplers' routing sends it (protocol::select_samples / select_tiles over its
// cell grown by the layout's margin), against one 1024 x 1024 display fed every sample; the
// real sampler on the built-in scene under a virtual clock. The seam test
// (tests/service/wall_seam_test.cpp) asserts on what it measures at fixed settings;
// afr-bench-seam (bench/seam_bench.cpp) takes the settings as flags and prints the figures.
// Header-only, so that each builds without the other (the tests without the benchmarks, the
// benchmarks without the tests) and without a library target of its own.
#pragma once

#include <afr/common/builtin_scene.h>
#include <afr/common/clock.h>
#include <afr/common/image.h>
#include <afr/display/backend.h>
#include <afr/display/service/wall.h>
#include <afr/display/service/wall_exchange.h>
#include <afr/protocol/messages.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/tracer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace afr::testing {

// What a seam run varies; the defaults are the wall as display_node runs it.
struct SeamSettings {
  int margin = auto_viewport_margin(SplatSizeRule{});  // the layout's margin, 99 px
  int frames = 40;                                     // refreshes, 1/60 s of virtual time apart
  // After each image the nodes send each other what WallExchange gives (coverage, and strays
  // unless `strays` is false), as display_node does; it arrives for their next image.
  bool exchange = true;
  bool strays = true;
  // WallExchange's coverage band (33 px); -1: the whole part of the cell the peer receives.
  int coverage_band = splat_guard_band(SplatSizeRule{});
  bool route_all = false;  // every sample to every node instead of the routing's part
  // The sampler's seed: another sample stream, as another processor's Embree gives.
  uint64_t seed = SamplerConfig{}.seed;
  Backend backend = Backend::kCpu;  // of the nodes and the single display alike
  // Each node's store as display_node sizes it (4 samples per received pixel) instead of the
  // single display's 4 x 1024 x 1024.
  bool node_capacity = false;
  // A second single display fed the same batches with each pair's order swapped: what arrival
  // order alone makes.
  bool twin = false;
};

// RMS of the 8-bit differences between the pixels either side of the vertical line between
// columns x - 1 and x and the horizontal one between rows x - 1 and x. A seam shows as a larger
// step in the wall than in the single display there.
inline double line_step(const Image& img, int x) {
  double sum = 0.0;
  uint64_t n = 0;
  for (int i = 0; i < img.height; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double dv =
          double(linear_to_srgb8(img.at(x - 1, i)[k])) - double(linear_to_srgb8(img.at(x, i)[k]));
      const double dh =
          double(linear_to_srgb8(img.at(i, x - 1)[k])) - double(linear_to_srgb8(img.at(i, x)[k]));
      sum += dv * dv + dh * dh;
      n += 2;
    }
  }
  return std::sqrt(sum / double(n));
}

// One refresh: the stitched wall against the single display, on the displayed 8-bit values
// (0-255; the paper's metric).
struct SeamFrame {
  double rms = 0.0;        // over the image
  double seam_rms = 0.0;   // over the seams: the 16 pixels each side of the cell borders
  double max_diff = 0.0;   // the largest difference of one value
  uint64_t differing = 0;  // values (3 a pixel) that differ at all
  // With SeamSettings::twin: the twin against the single display, and line_step at the seams
  // (x, y = 512) and the mean over interior lines (256, 768) in the wall, the single display
  // and the twin.
  double twin_rms = 0.0;
  double wall_seam_step = 0.0, wall_interior_step = 0.0;
  double one_seam_step = 0.0, one_interior_step = 0.0;
  double twin_seam_step = 0.0, twin_interior_step = 0.0;
};

struct SeamRun {
  bool started = false;  // false: the OpenGL backend asked for could not start; nothing ran
  std::vector<SeamFrame> frames;
  uint64_t traced = 0;          // samples the sampler sent
  uint64_t routed = 0;          // samples the four nodes received from it, together
  uint64_t strays = 0;          // samples the nodes forwarded to each other
  uint64_t coverage_cells = 0;  // coverage pixels the nodes wrote from each other's
  double routed_share() const { return double(routed) / double(std::max<uint64_t>(traced, 1)); }
  double stray_share() const { return double(strays) / double(std::max<uint64_t>(traced, 1)); }
};

namespace seam_detail {

// Feeds the single display (and its twin) everything and each wall node what the routing
// sends it.
class WallSink final : public SampleSink {
 public:
  WallSink(Reconstructor& whole, Reconstructor* twin, const protocol::WallLayout& layout,
           std::vector<std::unique_ptr<Reconstructor>>& nodes, bool route_all)
      : whole_(whole), twin_(twin), layout_(layout), nodes_(nodes), route_all_(route_all) {}
  void on_batch(SampleBatch&& batch) override {
    whole_.add_batch(batch);
    if (twin_ != nullptr) {
      // The twin gets the same batches with each pair's order swapped: another arrival order.
      if (held_.samples.empty()) {
        held_ = batch;
      } else {
        twin_->add_batch(batch);
        twin_->add_batch(held_);
        held_.samples.clear();
      }
    }
    total_ += batch.samples.size();
    const PixelRect image{0, 0, layout_.image.width, layout_.image.height};
    for (size_t i = 0; i < nodes_.size(); ++i) {
      protocol::select_samples(
          batch, route_all_ ? image : protocol::wall_receive_rect(layout_, layout_.nodes[i]),
          &part_);
      routed_ += part_.samples.size();
      if (!part_.samples.empty()) nodes_[i]->add_batch(part_);
    }
  }
  void on_tiling(TilingSnapshot&& snapshot) override {
    whole_.set_tiling(snapshot);
    if (twin_ != nullptr) twin_->set_tiling(snapshot);
    for (size_t i = 0; i < nodes_.size(); ++i) {
      protocol::select_tiles(snapshot, protocol::wall_receive_rect(layout_, layout_.nodes[i]),
                             &tiles_);
      nodes_[i]->set_tiling(tiles_);
    }
  }
  uint64_t total() const { return total_; }
  uint64_t routed() const { return routed_; }

 private:
  Reconstructor& whole_;
  Reconstructor* twin_;
  const protocol::WallLayout& layout_;
  std::vector<std::unique_ptr<Reconstructor>>& nodes_;
  const bool route_all_;
  SampleBatch part_;
  TilingSnapshot tiles_;
  uint64_t total_ = 0, routed_ = 0;
  SampleBatch held_;
};

}  // namespace seam_detail

// Runs the wall and the single display side by side for settings.frames refreshes, calling
// on_frame (when given) after each with its 0-based index.
inline SeamRun run_wall_seam(const SeamSettings& settings,
                             const std::function<void(int, const SeamFrame&)>& on_frame = {}) {
  constexpr int kSide = 1024;
  const int margin = settings.margin;
  const Backend backend = settings.backend;
  const Scene scene = make_builtin_scene();
  ReconstructorConfig base;
  base.image.width = base.image.height = kSide;
  base.threads = 2;

  service::WallGrid grid;
  grid.columns = grid.rows = 2;
  grid.margin = margin;
  protocol::WallLayout layout;
  layout.image.width = layout.image.height = kSide;
  layout.margin = margin;
  std::vector<std::unique_ptr<Reconstructor>> nodes;
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) {
      const PixelRect cell = grid.cell(c, r, kSide, kSide);
      layout.nodes.push_back(protocol::WallNode{uint32_t(1 + 2 * r + c), cell, ""});
      ReconstructorConfig rc = base;
      rc.viewport = cell;
      rc.viewport_margin = margin;
      // Each node keeps everything it receives, as the whole display does, unless sized as
      // display_node sizes it: 4 per pixel of what it receives.
      rc.capacity = size_t(4) * kSide * kSide;
      if (settings.node_capacity) {
        rc.capacity =
            size_t(4) * size_t(protocol::wall_receive_rect(layout, layout.nodes.back()).area());
      }
      nodes.push_back(make_reconstructor(backend, rc).reconstructor);
    }
  }
  ReconstructorConfig wc = base;
  wc.capacity = size_t(4) * kSide * kSide;
  std::unique_ptr<Reconstructor> whole = make_reconstructor(backend, wc).reconstructor;
  SeamRun run;
  if (backend == Backend::kGl && std::string(whole->backend_name()) != "gl") return run;
  run.started = true;
  std::unique_ptr<Reconstructor> twin;
  if (settings.twin) twin = make_reconstructor(backend, wc).reconstructor;
  std::vector<service::WallExchange> exchanges;
  for (const protocol::WallNode& n : layout.nodes) {
    exchanges.emplace_back(layout, n.node_id, service::WallExchange::kDefaultLookahead,
                           settings.coverage_band);
  }

  // The sampler at 2M rays/s of virtual time; frames 1/60 s apart, so the coverage map of
  // each image sizes the splats of the next, as a live display's does.
  seam_detail::WallSink sink(*whole, twin.get(), layout, nodes, settings.route_all);
  Tracer tracer(scene);
  VirtualClock clock(2e6, 2.0);
  SamplerConfig sc;
  sc.image.width = sc.image.height = kSide;
  sc.fill_step = 4;
  sc.seed = settings.seed;
  Sampler sampler(scene, tracer, clock, sc, sink);
  sampler.fill();
  for (int frame = 0; frame < settings.frames; ++frame) {
    const double until = clock.now() + 1.0 / 60.0;
    while (clock.now() < until) sampler.step();
    sampler.flush();
    const double t = clock.now();
    const Camera camera = scene.camera_at(scene.evaluate(t));
    const Image expected = whole->reconstruct(camera, t, kSide, kSide);
    Image stitched(kSide, kSide);
    std::vector<service::WallOutbox> outboxes(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) {
      const PixelRect cell = layout.nodes[i].cell;
      const Image part = nodes[i]->reconstruct(camera, t, cell.width(), cell.height());
      for (int y = 0; y < cell.height(); ++y) {
        for (int x = 0; x < cell.width(); ++x) {
          stitched.at(cell.x0 + x, cell.y0 + y) = part.at(x, y);
        }
      }
      if (settings.exchange) exchanges[i].collect(*nodes[i], camera, t, true, &outboxes[i]);
    }
    // Delivered: each node's coverage replaces its peers' where their grids hold it, and the
    // strays join the peers' stores, before anyone's next image.
    for (size_t i = 0; settings.exchange && i < nodes.size(); ++i) {
      const std::vector<service::WallPeer>& peers = exchanges[i].peers();
      for (const service::WallOutbox::Coverage& c : outboxes[i].coverage) {
        Reconstructor& peer = *nodes[peers[c.peer].node_id - 1];
        run.coverage_cells += peer.write_coverage(c.rect, c.cells);
      }
      for (size_t k = 0; k < peers.size() && settings.strays; ++k) {
        for (const SampleBatch& b : outboxes[i].strays[k]) {
          nodes[peers[k].node_id - 1]->add_batch(b);
          run.strays += b.samples.size();
        }
      }
    }
    SeamFrame f;
    f.rms = rms_error_255(stitched, expected);
    double seam_sum = 0.0;
    uint64_t seam_n = 0;
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        const bool seam = std::abs(x - kSide / 2) < 16 || std::abs(y - kSide / 2) < 16;
        for (int k = 0; k < 3; ++k) {
          const double d = std::abs(double(linear_to_srgb8(stitched.at(x, y)[k])) -
                                    double(linear_to_srgb8(expected.at(x, y)[k])));
          f.max_diff = std::max(f.max_diff, d);
          f.differing += d > 0.0;
          if (seam) {
            seam_sum += d * d;
            ++seam_n;
          }
        }
      }
    }
    f.seam_rms = std::sqrt(seam_sum / double(std::max<uint64_t>(seam_n, 1)));
    if (twin != nullptr) {
      const Image other = twin->reconstruct(camera, t, kSide, kSide);
      const auto interior = [](const Image& img) {
        return 0.5 * (line_step(img, kSide / 4) + line_step(img, 3 * kSide / 4));
      };
      f.twin_rms = rms_error_255(other, expected);
      f.wall_seam_step = line_step(stitched, kSide / 2);
      f.wall_interior_step = interior(stitched);
      f.one_seam_step = line_step(expected, kSide / 2);
      f.one_interior_step = interior(expected);
      f.twin_seam_step = line_step(other, kSide / 2);
      f.twin_interior_step = interior(other);
    }
    run.frames.push_back(f);
    if (on_frame) on_frame(frame, f);
  }
  run.traced = sink.total();
  run.routed = sink.routed();
  return run;
}

}  // namespace afr::testing
