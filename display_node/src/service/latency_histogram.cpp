#include <afr/display/service/latency_histogram.h>

#include <algorithm>
#include <cmath>

namespace afr::service {

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

}  // namespace afr::service
