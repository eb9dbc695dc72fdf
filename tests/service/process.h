// Helpers of the multi-process service tests: child processes (fork/exec, logs to files, kill
// on scope exit), waiting for conditions, free ports, and HTTP GETs of the display's /stats.
#pragma once

#include "support/timing.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace afr::testing {

// How many times `needle` occurs in `text` (a log), overlapping occurrences not counted.
inline size_t count_of(const std::string& text, const std::string& needle) {
  size_t n = 0;
  for (size_t at = text.find(needle); at != std::string::npos;
       at = text.find(needle, at + needle.size())) {
    ++n;
  }
  return n;
}

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The local time of day in seconds, as the nodes' log lines give it ("%H:%M:%S.%e").
inline double time_of_day() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm tm{};
  ::localtime_r(&t, &tm);
  const double ms = double(
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000);
  return tm.tm_hour * 3600.0 + tm.tm_min * 60.0 + tm.tm_sec + ms / 1000.0;
}

// The time of day of the `nth` (1-based) log line containing `needle`, or -1. Timing bounds
// are measured between such events (a node's bind, a join, a loss), not from when a test
// started a process or polled its /stats.
inline double log_time(const std::string& log, const std::string& needle, int nth = 1) {
  size_t at = 0;
  for (int k = 0; k < nth; ++k, ++at) {
    at = log.find(needle, at);
    if (at == std::string::npos) return -1.0;
  }
  --at;
  const size_t line = log.rfind('\n', at);
  const size_t begin = line == std::string::npos ? 0 : line + 1;
  int h = 0, m = 0, sec = 0, ms = 0;
  if (std::sscanf(log.c_str() + begin, "%2d:%2d:%2d.%3d", &h, &m, &sec, &ms) != 4) return -1.0;
  return h * 3600.0 + m * 60.0 + sec + ms / 1000.0;
}

// The number that follows `key` on the first log line containing `needle` (e.g. the seconds in
// "suspected after 0.76 s"), or -1.
inline double log_number(const std::string& log, const std::string& needle,
                         const std::string& key) {
  const size_t at = log.find(needle);
  if (at == std::string::npos) return -1.0;
  const size_t end = log.find('\n', at);
  const size_t k = log.find(key, at);
  if (k == std::string::npos || (end != std::string::npos && k > end)) return -1.0;
  return std::atof(log.c_str() + k + key.size());
}

// Seconds from time of day `a` to `b`, across midnight if need be.
inline double seconds_between(double a, double b) {
  double d = b - a;
  if (d < -43200.0) d += 86400.0;
  return d;
}

class Process {
 public:
  Process(std::vector<std::string> argv, const std::string& log) : log_(log) {
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      std::vector<char*> args;
      for (std::string& a : argv) args.push_back(a.data());
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      std::perror("execv");
      ::_exit(127);
    }
  }
  ~Process() {
    if (alive()) {
      signal(SIGKILL);
      wait(5.0);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  void signal(int sig) {
    if (pid_ > 0) ::kill(pid_, sig);
  }
  bool alive() {
    if (pid_ <= 0 || exited_) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      status_ = status;
      return false;
    }
    return true;
  }
  // Waits for the exit; returns the exit code, or -1 on timeout or death by a signal.
  int wait(double timeout) {
    const auto t0 = std::chrono::steady_clock::now();
    while (alive() && seconds_since(t0) < timeout) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (!exited_) return -1;
    return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
  }
  std::string log() const {
    std::ifstream in(log_);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  // Resident memory in kB (VmRSS), 0 when unknown.
  long rss_kb() const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    }
    return 0;
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int status_ = 0;
  std::string log_;
};

// Polls until `done` holds, for up to `timeout` seconds times kWaitPatience (times
// kTimingScale under the sanitizers). The timeouts the tests give are what a quiet machine
// needs; no test waits for something *not* to happen, so waiting longer on a loaded one costs
// only time when the test fails anyway (measured: a node's start took over 5 s beside a
// Table 1 run and a sanitizer build on 2 cores). Tests that measure a time read it from the
// nodes' logs, not from how long this waited.
inline constexpr double kWaitPatience = 4.0;
inline bool wait_until(const std::function<bool()>& done, double timeout, double poll = 0.02) {
  const auto t0 = std::chrono::steady_clock::now();
  timeout = scaled(timeout) * kWaitPatience;
  while (seconds_since(t0) < timeout) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::duration<double>(poll));
  }
  return done();
}

inline bool port_free(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  ::close(fd);
  return ok;
}

// A base port P with P..P+3 free (the display's three channels and its metrics port).
// Four free ports in a row, below the kernel's ephemeral range (outgoing connections of
// tests running beside, a browser's say, take ports from that range and could take one of
// ours between this check and the display's bind).
inline int free_base_port() {
  std::mt19937 rng(std::random_device{}());
  int ephemeral_low = 32768;
  if (std::ifstream range("/proc/sys/net/ipv4/ip_local_port_range"); range) {
    range >> ephemeral_low;
  }
  const int lo = 10000, hi = std::max(lo + 1000, ephemeral_low - 4);
  for (int attempt = 0; attempt < 200; ++attempt) {
    const int p = lo + int(rng() % uint32_t(hi - lo));
    if (port_free(p) && port_free(p + 1) && port_free(p + 2) && port_free(p + 3)) return p;
  }
  return 0;
}

// The display's /stats, or null when it does not answer.
inline nlohmann::json get_stats(int port) {
  httplib::Client client("127.0.0.1", port);
  client.set_connection_timeout(0, 300000);
  client.set_read_timeout(std::chrono::duration<double>(scaled(1.0)));
  auto res = client.Get("/stats");
  if (!res || res->status != 200) return nullptr;
  return nlohmann::json::parse(res->body, nullptr, false);
}

inline std::string get_text(int port, const std::string& path) {
  httplib::Client client("127.0.0.1", port);
  auto res = client.Get(path.c_str());
  return res && res->status == 200 ? res->body : std::string();
}

inline int members(const nlohmann::json& stats) {
  if (stats.is_null() || stats.is_discarded()) return -1;
  return stats["display"]["members"].get<int>();
}

// A multi-process test: a scratch folder of its own (removed unless the test failed, to read
// the nodes' logs) and a free base port (4 ports from it: a node's data, control, spare and
// metrics ports).
class ProcessTest : public ::testing::Test {
 protected:
  explicit ProcessTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + info->name() + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    port_ = free_base_port();
    ASSERT_NE(port_, 0);
  }
  void TearDown() override {
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string endpoint(int port) { return "tcp://127.0.0.1:" + std::to_string(port); }

  std::string prefix_;
  std::filesystem::path dir_;
  int port_ = 0;  // the base port of the first display node
};

}  // namespace afr::testing
