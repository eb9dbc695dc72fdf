#include <afr/eval/progress.h>

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace afr::eval {

namespace {

std::string clock_text(double seconds) {
  const int s = int(std::max(0.0, seconds) + 0.5);
  return s >= 3600 ? fmt::format("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
                   : fmt::format("{}:{:02}", s / 60, s % 60);
}

}  // namespace

Progress::Progress(uint64_t total, bool enabled, double log_interval)
    : total_(total),
      enabled_(enabled),
      terminal_(::isatty(STDERR_FILENO) != 0),
      log_interval_(log_interval),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

Progress::~Progress() { finish(); }

void Progress::set_task(std::string task) {
  std::lock_guard<std::mutex> lock(mutex_);
  task_ = std::move(task);
  draw(!terminal_ ? false : true);
}

void Progress::advance(uint64_t units) {
  std::lock_guard<std::mutex> lock(mutex_);
  done_ += units;
  draw(false);
}

void Progress::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (enabled_ && drawn_ && terminal_) std::fputc('\n', stderr);
  drawn_ = false;
}

void Progress::draw(bool force) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_draw_).count();
  if (!force && since < (terminal_ ? 0.2 : log_interval_)) return;
  last_draw_ = now;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double fraction = total_ > 0 ? std::min(1.0, double(done_) / double(total_)) : 0.0;
  const double left = fraction > 0.0 ? elapsed * (1.0 - fraction) / fraction : 0.0;
  constexpr int kWidth = 30;
  const int filled = int(fraction * kWidth);
  const std::string bar =
      std::string(size_t(filled), '#') + std::string(size_t(kWidth - filled), '.');
  const std::string line =
      fmt::format("[{}] {:5.1f}% {} elapsed, {} left  {}", bar, 100.0 * fraction,
                  clock_text(elapsed), fraction > 0.0 ? clock_text(left) : "?:??", task_);
  if (terminal_) {
    fmt::print(stderr, "\r{:<120.120}", line);
  } else {
    fmt::print(stderr, "{}\n", line);
  }
  std::fflush(stderr);
  drawn_ = true;
}

}  // namespace afr::eval
