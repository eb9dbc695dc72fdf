// Sample-to-display latency as the display measures it: a histogram of fixed 0.1 ms bins up
// to 2 s (and one bin beyond), for quantiles and the Prometheus histogram. Not thread-safe:
// ServiceMetrics holds it under its mutex.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace afr::service {

class LatencyHistogram {
 public:
  static constexpr double kBin = 1e-4;
  static constexpr size_t kBins = 20000;
  void add(double seconds, uint64_t weight);
  // The q-quantile (0..1) in seconds; 0 when empty.
  double quantile(double q) const;
  uint64_t count() const { return count_; }
  double sum() const { return sum_; }
  // Samples at or below `seconds`.
  uint64_t count_at_most(double seconds) const;
  void clear();

 private:
  std::vector<uint64_t> bins_ = std::vector<uint64_t>(kBins + 1, 0);
  uint64_t count_ = 0;
  double sum_ = 0.0;
};

}  // namespace afr::service
