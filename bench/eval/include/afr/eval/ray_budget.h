// The ray budget R of the evaluation: every method may trace R rays per second of display
// time, and every ray it traces to make its pictures counts. For the sampler that is its
// primary rays (which it reports to its Clock) and its occlusion rays (section 6.1), which it
// counts but does not report; BudgetClock charges both, so that a sampler that spends rays on
// visibility tests has fewer left for new samples (docs/evaluation.md, "What is compared").
#pragma once

#include <afr/common/check.h>
#include <afr/common/clock.h>

#include <cstdint>

namespace afr {
class Sampler;
}

namespace afr::eval {

// Virtual time that advances 1/rate seconds per primary ray and occlusion_ray_cost / rate
// seconds per occlusion ray: now() = start + (primary + cost x occlusion) / rate, from integer
// counts, so that no rounding accumulates. occlusion_ray_cost = 0 is the former accounting
// (occlusion rays free); 1 charges an occlusion ray as one ray.
class BudgetClock final : public Clock {
 public:
  // rays_per_second finite and > 0, occlusion_ray_cost >= 0 (run_method validates them).
  BudgetClock(double rays_per_second, double start_seconds, double occlusion_ray_cost)
      : rate_(rays_per_second), start_(start_seconds), occlusion_cost_(occlusion_ray_cost) {}

  double now() const override { return start_ + charged_rays() / rate_; }
  void primary_rays_traced(uint64_t count) override { primary_ += count; }
  // The sampler's running total of occlusion rays (SamplerCounters::occlusion_rays). Totals
  // never decrease.
  void set_occlusion_rays(uint64_t total) {
    AFR_CHECK(total >= occlusion_);
    occlusion_ = total;
  }

  uint64_t primary_rays() const { return primary_; }
  uint64_t occlusion_rays() const { return occlusion_; }
  // What the budget has paid for, in rays.
  double charged_rays() const { return double(primary_) + occlusion_cost_ * double(occlusion_); }
  double rate() const { return rate_; }

 private:
  double rate_;
  double start_;
  double occlusion_cost_;
  uint64_t primary_ = 0;
  uint64_t occlusion_ = 0;
};

// Steps `sampler` (built on `clock`) until clock.now() >= t, charging its occlusion rays after
// every step. A step's occlusion rays (at most r plus the fill's) reach the clock at the end
// of that step: the sampler sees time up to r / R late within one step (12.5 us at 400K).
void sample_until(Sampler& sampler, BudgetClock& clock, double t);

}  // namespace afr::eval
