// `promtool check metrics` on a Prometheus exposition (Debian package prometheus). Returns
// nullopt when promtool is not installed (the caller skips), else promtool's verdict: its exit
// status and what it printed (empty when the exposition follows every convention it checks).
#pragma once

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

namespace afr::testing {

struct PromtoolVerdict {
  int status = 0;
  std::string output;
};

inline std::optional<PromtoolVerdict> promtool_check_metrics(const std::string& exposition) {
  if (std::system("promtool --version >/dev/null 2>&1") != 0) return std::nullopt;
  static int calls = 0;
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() /
      ("afr_metrics_" + std::to_string(getpid()) + "_" + std::to_string(++calls));
  std::ofstream(file) << exposition;
  const std::string command = "promtool check metrics < " + file.string() + " 2>&1";
  PromtoolVerdict verdict;
  if (FILE* pipe = popen(command.c_str(), "r")) {
    char buffer[512];
    while (fgets(buffer, sizeof buffer, pipe) != nullptr) verdict.output += buffer;
    verdict.status = pclose(pipe);
  } else {
    verdict.status = -1;
    verdict.output = "cannot run promtool";
  }
  std::filesystem::remove(file);
  return verdict;
}

}  // namespace afr::testing
