// Logging goes through spdlog; this header sets the one format every afr program uses.
#pragma once

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>

namespace afr {

// Sets the process-wide log level ("trace", "debug", "info", "warn", "error", "off") and the
// line format. Throws afr::Error naming the level if it is not one of those.
void init_logging(std::string_view level);

// Log lines for events a peer can repeat at will (bad messages, refused keys, stray requests):
// at most one line per cause per interval, each telling how many events it stands for, so a
// flood of one fault costs a line a second and a different fault still gets its own line.
//
//   if (const uint64_t n = limiter.due(LogLimiter::cause_of(error))) {
//     spdlog::warn("control: rejected {} message(s) like this one: {}", n, error);
//   }
//
// A cause is a short string; cause_of() makes one from an error message by blanking its
// numbers, so "unknown type 7" and "unknown type 9" are one cause. At most max_causes causes
// are tracked (the state a peer can grow is bounded): beyond them, events share one cause,
// "other". Not thread-safe: one limiter per thread.
class LogLimiter {
 public:
  explicit LogLimiter(std::chrono::steady_clock::duration interval = std::chrono::seconds(1),
                      size_t max_causes = 32)
      : interval_(interval), max_causes_(max_causes) {}

  // Counts one event of `cause` at `now`; returns the events of that cause since its last line
  // (this one included) when a line is due, else 0.
  uint64_t due(std::string_view cause,
               std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now());

  // The events held back since their cause's last line, once that line is an interval old:
  // calls f(cause, count) for each and clears it, so the end of a flood is logged too. Call
  // it from the loop that logs (a few times a second is enough).
  template <typename F>
  void flush(F&& f, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    for (auto& [cause, c] : causes_) {
      if (c.count == 0 || now - c.last_line < interval_) continue;
      f(cause, c.count);
      c.count = 0;
      c.last_line = now;
    }
  }

  // The cause of an error message: its first 80 characters, each run of digits as '#'.
  static std::string cause_of(std::string_view message);

  size_t causes() const { return causes_.size(); }

 private:
  struct Cause {
    std::chrono::steady_clock::time_point last_line;
    bool logged = false;
    uint64_t count = 0;
  };
  std::chrono::steady_clock::duration interval_;
  size_t max_causes_;
  std::map<std::string, Cause, std::less<>> causes_;
};

// Log lines for events each worth a line of its own (a sampler joined, left, got a region)
// that a peer can still repeat at will, joining and leaving in a loop: up to `lines` lines per
// interval, the events beyond them counted, and their sum logged in at most one line per
// interval.
//
//   if (budget.take()) spdlog::info("sampler {} joined: {}", id, name);
//   budget.flush([](uint64_t n) { spdlog::warn("{} membership events not logged", n); });
//
// Not thread-safe: one budget per thread.
class LogBudget {
 public:
  explicit LogBudget(size_t lines = 32,
                     std::chrono::steady_clock::duration interval = std::chrono::seconds(1))
      : lines_(lines), interval_(interval) {}

  // Whether the event at `now` gets its line; false: it is counted for flush().
  bool take(std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    roll(now);
    if (used_ < lines_) {
      ++used_;
      return true;
    }
    ++held_;
    return false;
  }

  // Calls f(count) with the events held back since its last call, unless that was less than an
  // interval ago (the first call with any held back calls it at once); clears the count.
  template <typename F>
  void flush(F&& f, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    if (held_ == 0 || (flushed_ && now - last_flush_ < interval_)) return;
    f(held_);
    held_ = 0;
    flushed_ = true;
    last_flush_ = now;
  }

 private:
  void roll(std::chrono::steady_clock::time_point now) {
    if (now - start_ < interval_) return;
    start_ = now;
    used_ = 0;
  }

  size_t lines_;
  std::chrono::steady_clock::duration interval_;
  std::chrono::steady_clock::time_point start_{};
  size_t used_ = 0;
  uint64_t held_ = 0;
  bool flushed_ = false;
  std::chrono::steady_clock::time_point last_flush_{};
};

}  // namespace afr
