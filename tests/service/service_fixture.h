// The fixture of the multi-process service tests (display_node_test.cpp, sampler_node_test.cpp):
// display_node and sampler_node as built, started as child processes on loopback with a
// scratch folder and ports of their own, observed through the display's /stats, logs and images.
#pragma once

#include "process.h"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace afr::testing {

inline const std::string kDisplay = AFR_DISPLAY_NODE;
inline const std::string kSampler = AFR_SAMPLER_NODE;
inline const std::string kStaticScene = AFR_STATIC_SCENE;

class ServiceTest : public ProcessTest {
 protected:
  ServiceTest() : ProcessTest("afr-service-") {}
  using ProcessTest::endpoint;
  std::string endpoint() const { return endpoint(port_); }
  int metrics_port() const { return port_ + 3; }

  std::unique_ptr<Process> display(std::vector<std::string> extra, const std::string& log) {
    std::vector<std::string> argv = {kDisplay,           "--headless",
                                     "--bind",           endpoint(),
                                     "--metrics-port",   std::to_string(metrics_port()),
                                     "--backend",        "cpu",
                                     "--output",         path("out"),
                                     "--stats-interval", "1"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(log));
  }
  std::unique_ptr<Process> sampler(std::vector<std::string> extra, const std::string& log) {
    std::vector<std::string> argv = {kSampler, "--display", endpoint(), "--cache", path("cache")};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(log));
  }
  // Until n samplers are members and each has its region (a join waits for its cut up to the
  // display's --join-interval).
  bool wait_members(int n, double timeout) {
    return wait_until(
        [&] {
          const nlohmann::json st = get_stats(metrics_port());
          if (members(st) != n) return false;
          for (const auto& m : st["samplers"]) {
            const auto r = m["region"].get<std::array<int, 4>>();
            if (m["member"].get<bool>() && !(r[2] > r[0] && r[3] > r[1])) return false;
          }
          return true;
        },
        timeout);
  }
  // Until one sampler is a member and the display has taken samples from it.
  bool wait_one_sampling(double timeout) {
    return wait_until(
        [&] {
          const nlohmann::json st = get_stats(metrics_port());
          return members(st) == 1 && st["samplers"][0]["samples"].get<uint64_t>() > 0;
        },
        timeout);
  }
  // Region of a member sampler (x0, y0, x1, y1), by position in /stats among members.
  std::vector<std::array<int, 4>> member_regions() {
    std::vector<std::array<int, 4>> out;
    const nlohmann::json s = get_stats(metrics_port());
    if (s.is_null() || s.is_discarded()) return out;
    for (const auto& m : s["samplers"]) {
      if (m["member"].get<bool>()) out.push_back(m["region"].get<std::array<int, 4>>());
    }
    return out;
  }
};

}  // namespace afr::testing
