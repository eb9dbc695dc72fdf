// Clocks. The whole system runs on one clock, the display node's (DESIGN.md, "Time"): absolute
// times are double seconds from the session start. The sampler reads time only through a
// Clock, so the same code runs live (WallClock) and in evaluations (VirtualClock), where time
// advances by 1/R seconds per traced primary ray at a simulated rate R and results do not
// depend on the speed of the machine.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>

namespace afr {

class Clock {
 public:
  virtual ~Clock() = default;
  // Seconds since the session start on the display's clock.
  virtual double now() const = 0;
  // Told after every traced primary ray (in counts); a virtual clock advances with them.
  virtual void primary_rays_traced(uint64_t count) {}
};

// Real time from a steady clock, plus an offset that ties it to the display's clock (the
// display time at this process's start, learned from view messages).
class WallClock final : public Clock {
 public:
  WallClock() : start_(std::chrono::steady_clock::now()) {}
  double now() const override { return offset_.load(std::memory_order_relaxed) + elapsed(); }
  // Makes now() return `display_time` at this instant. Safe while other threads read now().
  void sync_to(double display_time) {
    offset_.store(display_time - elapsed(), std::memory_order_relaxed);
  }

 private:
  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  std::chrono::steady_clock::time_point start_;
  std::atomic<double> offset_{0.0};
};

// The display's clock as another process learns it from the display's messages (views):
// now() = local steady time + offset. Each message stamped with the display time gives a
// candidate offset (its display time minus the local time it arrived); the largest candidate
// is the one that travelled fastest, so the clock follows the largest seen, re-anchored every
// few seconds so that it also follows a slow drift between machines. now() from any thread;
// observe() and reset_to() from one.
class RemoteClock final : public Clock {
 public:
  double now() const override { return offset_.load(std::memory_order_relaxed) + local(); }

  void observe(double display_time) {
    const double e = local();
    const double c = display_time - e;
    if (!set_) {
      reset_to(display_time);
      return;
    }
    if (c > offset_.load()) offset_.store(c);
    window_max_ = c > window_max_ ? c : window_max_;
    if (e - window_start_ > kWindowSeconds) {
      offset_.store(window_max_);
      window_max_ = c;
      window_start_ = e;
    }
  }
  // A new session: the display's clock starts over.
  void reset_to(double display_time) {
    const double e = local();
    offset_.store(display_time - e);
    window_max_ = display_time - e;
    window_start_ = e;
    set_ = true;
  }
  bool is_set() const { return set_; }

 private:
  static constexpr double kWindowSeconds = 2.0;
  static double local() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }

  std::atomic<double> offset_{-local()};
  double window_max_ = 0.0;
  double window_start_ = 0.0;
  bool set_ = false;
};

// Time that advances 1/rate seconds per traced primary ray. It counts rays in an integer and
// computes now() = start + rays / rate, so it does not accumulate rounding error.
class VirtualClock final : public Clock {
 public:
  // rays_per_second must be finite and > 0 (callers validate user input first).
  VirtualClock(double rays_per_second, double start_seconds = 0.0)
      : rate_(rays_per_second), start_(start_seconds) {}
  double now() const override { return start_ + double(rays_) / rate_; }
  void primary_rays_traced(uint64_t count) override { rays_ += count; }
  double rate() const { return rate_; }
  uint64_t rays() const { return rays_; }

 private:
  double rate_;
  double start_;
  uint64_t rays_ = 0;
};

}  // namespace afr
