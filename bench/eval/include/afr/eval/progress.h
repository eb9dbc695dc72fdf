// A progress bar on stderr for long evaluations: done/total units of work, the current task,
// elapsed time and an estimate of the time left. On a terminal it redraws one line; otherwise
// it prints a line at most every `log_interval` seconds. Safe to call from several threads.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace afr::eval {

class Progress {
 public:
  // total: units of work (e.g. frames to render and frames to compare).
  explicit Progress(uint64_t total, bool enabled = true, double log_interval = 30.0);
  ~Progress();

  void set_task(std::string task);
  void advance(uint64_t units = 1);
  void add_total(uint64_t units) {
    std::lock_guard<std::mutex> lock(mutex_);
    total_ += units;
  }
  // Ends the bar's line (the next output starts on a fresh line).
  void finish();

 private:
  void draw(bool force);  // with mutex_ held

  std::mutex mutex_;
  uint64_t total_;
  uint64_t done_ = 0;
  bool enabled_;
  bool terminal_;
  double log_interval_;
  std::string task_;
  std::chrono::steady_clock::time_point start_, last_draw_;
  bool drawn_ = false;
};

}  // namespace afr::eval
