#include <afr/common/check.h>

#include <cstdio>
#include <cstdlib>

namespace afr::detail {

void check_failed(const char* condition, const char* file, int line) {
  std::fprintf(stderr, "afr: internal check failed: %s at %s:%d\n", condition, file, line);
  std::fflush(stderr);
  std::abort();
}

}  // namespace afr::detail
