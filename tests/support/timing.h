// Bounds on time in the tests are the Release build's. Under the sanitizers the code runs 2-3
// times slower (a node's start, a reconstruction, a join, a parse), so there each bound and
// wait is multiplied by kTimingScale; the product's own figures come from Release benchmarks
// (bench/liveness.py and the tables of docs/benchmarks.md), not from these tests.
#pragma once

namespace afr::testing {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
inline constexpr double kTimingScale = 3.0;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
inline constexpr double kTimingScale = 3.0;
#else
inline constexpr double kTimingScale = 1.0;
#endif
#else
inline constexpr double kTimingScale = 1.0;
#endif

inline double scaled(double seconds) { return seconds * kTimingScale; }

}  // namespace afr::testing
