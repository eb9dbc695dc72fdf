// Large memory copies on a refresh's path (the new samples out of the store, into the GPU's
// staging ring) split over threads: at 3840x2160 a refresh moves 35 MB twice, which one
// core copies at a few GB/s and several at the memory's bandwidth.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <future>
#include <thread>
#include <vector>

namespace afr {

// Copies `bytes` from `src` to `dst` (not overlapping) in parts of at least 8 MiB, one per
// thread up to the hardware's count.
inline void parallel_copy(void* dst, const void* src, size_t bytes) {
  constexpr size_t kPart = size_t(8) << 20;
  const size_t parts = std::clamp<size_t>(bytes / kPart, 1,
                                          std::max<size_t>(std::thread::hardware_concurrency(), 1));
  if (parts == 1) {
    std::memcpy(dst, src, bytes);
    return;
  }
  const auto piece = [&](size_t p) {
    const size_t lo = bytes * p / parts, hi = bytes * (p + 1) / parts;
    std::memcpy(static_cast<char*>(dst) + lo, static_cast<const char*>(src) + lo, hi - lo);
  };
  std::vector<std::future<void>> others;
  for (size_t p = 1; p < parts; ++p) others.push_back(std::async(std::launch::async, piece, p));
  piece(0);
  for (std::future<void>& f : others) f.get();
}

}  // namespace afr
