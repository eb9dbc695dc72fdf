#include <afr/eval/ray_budget.h>

#include <afr/sampler/sampler.h>

namespace afr::eval {

void sample_until(Sampler& sampler, BudgetClock& clock, double t) {
  while (clock.now() < t) {
    sampler.step();
    clock.set_occlusion_rays(sampler.counters().occlusion_rays);
  }
}

}  // namespace afr::eval
