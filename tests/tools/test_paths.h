// Where the tools tests find the BART scenes (AFR_SHARED_DIR, set by tests/CMakeLists.txt) and
// where they may write: a fresh directory per call under the system temp directory.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

namespace afr::test {

// <AFR_SHARED_DIR>/scenes/<scene>/aff/<file>, or an empty path when it is not there (tests
// then skip).
inline std::filesystem::path shared_aff(const std::string& scene, const std::string& file) {
  const char* shared = std::getenv("AFR_SHARED_DIR");
  if (!shared || !*shared) return {};
  const std::filesystem::path p = std::filesystem::path(shared) / "scenes" / scene / "aff" / file;
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec) ? p : std::filesystem::path();
}

inline std::filesystem::path kitchen_aff() { return shared_aff("bart-kitchen", "kitchen.aff"); }
inline std::filesystem::path robots_aff() { return shared_aff("bart-robots", "Robot.aff"); }

inline std::filesystem::path fresh_temp_dir(const std::string& prefix) {
  std::random_device rd;
  const auto dir = std::filesystem::temp_directory_path() /
                   (prefix + "-" + std::to_string(rd()) + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace afr::test
