// afr-bench-seam: how far a 2 x 2 display wall of 512 x 512 nodes is from one 1024 x 1024
// display fed every sample (docs/wall.md, "Seams"): the seam test's measurement
// (tests/support/wall_seam.h) with its settings as flags, over one or more sampler seeds.
// Prints a Markdown table, a row per seed: the first refresh where any 8-bit value differs,
// the largest difference and the most values differing (and where), the same over the first
// --close refreshes (what the test bounds), RMS (image and seams) at chosen refreshes, and
// what the routing and the exchange moved. With --twin, a second table of means over the last
// refreshes: the wall and a single display fed each batch pair swapped, against the single
// display, and the step across seam and interior lines in each.
//   afr-bench-seam --seed 1-7                  # the wall as display_node runs it
//   afr-bench-seam --seed 1-10 --frames 6 --no-exchange
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/log.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <string>
#include <vector>

#include "support/wall_seam.h"

namespace {

// "S", "A-B" or "S,T,...", each part one seed or a range.
std::vector<uint64_t> parse_seeds(const std::string& text) {
  std::vector<uint64_t> seeds;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma - start);
    try {
      size_t used = 0;
      const uint64_t first = std::stoull(item, &used);
      uint64_t last = first;
      if (used < item.size()) {
        if (item[used] != '-') throw std::invalid_argument(item);
        size_t used_last = 0;
        last = std::stoull(item.substr(used + 1), &used_last);
        if (used + 1 + used_last != item.size()) throw std::invalid_argument(item);
      }
      if (last < first || last - first >= 10000) throw std::invalid_argument(item);
      for (uint64_t s = first; s <= last; ++s) seeds.push_back(s);
    } catch (const std::logic_error&) {
      throw afr::Error(fmt::format("--seed: '{}' is not a seed, a range A-B or a list", text));
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return seeds;
}

// "value (refresh)" of the first refresh where `key` is largest among [0, end), or "-".
template <typename Key>
std::string largest(const std::vector<afr::testing::SeamFrame>& frames, size_t end, Key key) {
  end = std::min(end, frames.size());
  if (end == 0) return "-";
  size_t best = 0;
  for (size_t i = 1; i < end; ++i) {
    if (key(frames[i]) > key(frames[best])) best = i;
  }
  return fmt::format("{} ({})", key(frames[best]), best);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"afr-bench-seam: a 2 x 2 wall of 512² nodes against one 1024² display"};
  afr::testing::SeamSettings s;
  std::string seeds_text = "1", backend_text = "cpu";
  std::vector<int> at_refreshes{6, 12, 27, 39};
  int close = 35, mean_from = -1;
  bool no_exchange = false, no_strays = false, per_frame = false;
  app.add_option("--frames", s.frames, "refreshes, 1/60 s of virtual time apart")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--margin", s.margin, "the wall's margin in pixels")
      ->check(CLI::Range(0, 512))
      ->capture_default_str();
  app.add_flag("--no-exchange", no_exchange, "nodes send each other nothing (the margin alone)");
  app.add_flag("--no-strays", no_strays, "the exchange sends coverage only");
  app.add_option("--band", s.coverage_band,
                 "coverage band in pixels around a peer's cell; -1: all it receives")
      ->check(CLI::Range(-1, 1024))
      ->capture_default_str();
  app.add_flag("--route-all", s.route_all, "every sample to every node");
  app.add_option("--seed,--seeds", seeds_text, "sampler seeds: S, A-B or S,T,...")
      ->capture_default_str();
  app.add_option("--backend", backend_text, "cpu or gl (nodes and single display alike)")
      ->check(CLI::IsMember({"cpu", "gl"}))
      ->capture_default_str();
  app.add_flag("--node-capacity", s.node_capacity,
               "size each node's store as display_node does (4 per received pixel)");
  app.add_flag("--twin", s.twin, "add a single display fed each batch pair swapped");
  app.add_option("--close", close, "refreshes the test bounds value by value (first N)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--at", at_refreshes, "refreshes whose RMS the table gives, comma separated")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--mean-from", mean_from, "--twin: means over refreshes from this one (-1: half)");
  app.add_flag("--per-frame", per_frame, "print a line per refresh as it is measured");
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);
  try {
    afr::init_logging("warn");
    s.exchange = !no_exchange;
    s.strays = !no_strays;
    s.backend = afr::parse_backend(backend_text);
    const std::vector<uint64_t> seeds = parse_seeds(seeds_text);
    std::vector<int> at;
    for (int k : at_refreshes) {
      if (k >= 0 && k < s.frames) at.push_back(k);
    }
    if (mean_from < 0 || mean_from >= s.frames) mean_from = s.frames / 2;

    fmt::print(
        "2 x 2 wall of 512² ({} backend) against one 1024² display: margin {} px, {} refreshes, "
        "exchange {}, coverage band {}, routing {}{}; 8-bit values (0-255), refresh k 0-based\n\n",
        backend_text, s.margin, s.frames,
        s.exchange ? (s.strays ? "coverage and strays" : "coverage only") : "off", s.coverage_band,
        s.route_all ? "every sample to every node" : "by cell and margin",
        s.node_capacity ? ", node stores as display_node sizes them" : "");
    std::string head = fmt::format(
        "| seed | first difference | max difference (refresh) | most values differing "
        "(refresh) | first {}: max / most differing |",
        close);
    std::string rule = "|---|---:|---:|---:|---:|";
    for (int k : at) {
      head += fmt::format(" RMS at {} (seams) |", k);
      rule += "---:|";
    }
    head += " worst RMS (seams) | routed / traced | strays / traced | coverage px / refresh |";
    rule += "---:|---:|---:|---:|";
    std::vector<std::string> rows, twin_rows;
    for (uint64_t seed : seeds) {
      s.seed = seed;
      const afr::testing::SeamRun run =
          afr::testing::run_wall_seam(s, [&](int frame, const afr::testing::SeamFrame& f) {
            if (!per_frame) return;
            fmt::print("seed {} refresh {}: RMS {:.4f}, seams {:.4f}, max {:.0f}, {} values differ",
                       seed, frame, f.rms, f.seam_rms, f.max_diff, f.differing);
            if (s.twin) {
              fmt::print(
                  "; twin RMS {:.4f}; step at seams / interior: wall {:.2f} / {:.2f}, one "
                  "display {:.2f} / {:.2f}, twin {:.2f} / {:.2f}",
                  f.twin_rms, f.wall_seam_step, f.wall_interior_step, f.one_seam_step,
                  f.one_interior_step, f.twin_seam_step, f.twin_interior_step);
            }
            fmt::print("\n");
            std::fflush(stdout);
          });
      if (!run.started) throw afr::Error("the OpenGL backend could not start");
      const std::vector<afr::testing::SeamFrame>& f = run.frames;
      const auto first = std::find_if(f.begin(), f.end(),
                                      [](const afr::testing::SeamFrame& x) { return x.differing; });
      const auto max_diff = [](const afr::testing::SeamFrame& x) { return x.max_diff; };
      const auto differing = [](const afr::testing::SeamFrame& x) { return x.differing; };
      double close_max = 0.0;
      uint64_t close_most = 0;
      for (size_t i = 0; i < std::min(f.size(), size_t(close)); ++i) {
        close_max = std::max(close_max, f[i].max_diff);
        close_most = std::max(close_most, f[i].differing);
      }
      std::string row = fmt::format("| {} | {} | {} | {} | {} / {} |", seed,
                                    first == f.end() ? fmt::format("none in {}", f.size())
                                                     : std::to_string(first - f.begin()),
                                    largest(f, f.size(), max_diff), largest(f, f.size(), differing),
                                    close_max, close_most);
      for (int k : at)
        row += fmt::format(" {:.4g} ({:.4g}) |", f[size_t(k)].rms, f[size_t(k)].seam_rms);
      const auto worst =
          std::max_element(f.begin(), f.end(),
                           [](const afr::testing::SeamFrame& a, const afr::testing::SeamFrame& b) {
                             return a.rms < b.rms;
                           });
      double worst_seams = 0.0;
      for (const afr::testing::SeamFrame& x : f) worst_seams = std::max(worst_seams, x.seam_rms);
      row += fmt::format(" {:.4g} ({:.4g}) | {:.3f} | {:.3f} | {:.0f} |", worst->rms, worst_seams,
                         run.routed_share(), run.stray_share(),
                         double(run.coverage_cells) / double(f.size()));
      rows.push_back(row);
      if (s.twin) {
        afr::testing::SeamFrame mean;
        const size_t n = f.size() - size_t(mean_from);
        for (size_t i = size_t(mean_from); i < f.size(); ++i) {
          mean.rms += f[i].rms / double(n);
          mean.seam_rms += f[i].seam_rms / double(n);
          mean.twin_rms += f[i].twin_rms / double(n);
          mean.wall_seam_step += f[i].wall_seam_step / double(n);
          mean.wall_interior_step += f[i].wall_interior_step / double(n);
          mean.one_seam_step += f[i].one_seam_step / double(n);
          mean.one_interior_step += f[i].one_interior_step / double(n);
          mean.twin_seam_step += f[i].twin_seam_step / double(n);
          mean.twin_interior_step += f[i].twin_interior_step / double(n);
        }
        twin_rows.push_back(fmt::format(
            "| {} | {:.2f} ({:.2f}) | {:.2f} | {:.2f} / {:.2f} / {:.2f} | {:.2f} / {:.2f} / {:.2f} "
            "|",
            seed, mean.rms, mean.seam_rms, mean.twin_rms, mean.wall_seam_step, mean.one_seam_step,
            mean.twin_seam_step, mean.wall_interior_step, mean.one_interior_step,
            mean.twin_interior_step));
      }
      std::fflush(stdout);
    }
    if (per_frame) fmt::print("\n");
    fmt::print("{}\n{}\n", head, rule);
    for (const std::string& row : rows) fmt::print("{}\n", row);
    if (s.twin) {
      fmt::print(
          "\nMeans over refreshes {}-{}: RMS against the single display; step across the seam "
          "lines (x, y = 512) and interior lines (256, 768)\n\n",
          mean_from, s.frames - 1);
      fmt::print(
          "| seed | wall RMS (seams) | twin RMS | seam step: wall / one display / twin | "
          "interior step: wall / one display / twin |\n|---|---:|---:|---:|---:|\n");
      for (const std::string& row : twin_rows) fmt::print("{}\n", row);
    }
  } catch (const afr::Error& e) {
    fmt::print(stderr, "afr-bench-seam: {}\n", e.what());
    return 1;
  }
  return 0;
}
