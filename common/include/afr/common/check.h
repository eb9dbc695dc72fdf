// Invariant checks that stay on in Release builds. AFR_CHECK is for cheap checks of internal
// invariants (a failure is a bug in afr, so the process stops with file and line);
// AFR_DCHECK is for checks too costly for Release. Bad input is never checked with these:
// boundaries throw afr::Error instead (error.h).
#pragma once

namespace afr::detail {
[[noreturn]] void check_failed(const char* condition, const char* file, int line);
}  // namespace afr::detail

#define AFR_CHECK(condition)                                       \
  do {                                                             \
    if (!(condition)) [[unlikely]]                                 \
      ::afr::detail::check_failed(#condition, __FILE__, __LINE__); \
  } while (false)

#ifdef NDEBUG
#define AFR_DCHECK(condition) \
  do {                        \
  } while (false)
#else
#define AFR_DCHECK(condition) AFR_CHECK(condition)
#endif
