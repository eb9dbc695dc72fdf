// Where the tools tests find the BART kitchen (AFR_SHARED_DIR, set by tests/CMakeLists.txt) and
// where they may write: a fresh directory per call under the system temp directory.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

namespace afr::test {

// kitchen.aff, or an empty path when the shared folder is not there (tests then skip).
inline std::filesystem::path kitchen_aff() {
  const char* shared = std::getenv("AFR_SHARED_DIR");
  if (!shared || !*shared) return {};
  const std::filesystem::path p =
      std::filesystem::path(shared) / "scenes" / "bart-kitchen" / "aff" / "kitchen.aff";
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec) ? p : std::filesystem::path();
}

inline std::filesystem::path fresh_temp_dir(const std::string& prefix) {
  std::random_device rd;
  const auto dir = std::filesystem::temp_directory_path() /
                   (prefix + "-" + std::to_string(rd()) + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace afr::test
