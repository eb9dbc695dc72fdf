// One sampler on a scene under a virtual clock, with a sink that keeps what it emits: the set-up
// most sampler tests share. The sampler refers to the other members, which it outlives in no
// case (members are built in this order and destroyed in reverse). A test names the parts with
// a structured binding:
//
//   SamplerRig rig(testing::edge_scene(), 1e5, config);
//   auto& [scene, tracer, clock, sink, sampler] = rig;
#pragma once

#include <afr/common/clock.h>
#include <afr/common/scene.h>
#include <afr/sampler/sampler.h>
#include <afr/sampler/tracer.h>

#include <utility>

#include "support/test_scenes.h"

namespace afr::testing {

struct SamplerRig {
  SamplerRig(Scene s, double rays_per_second, const SamplerConfig& config)
      : scene(std::move(s)),
        tracer(scene),
        clock(rays_per_second),
        sampler(scene, tracer, clock, config, sink) {}
  SamplerRig(const SamplerRig&) = delete;
  SamplerRig& operator=(const SamplerRig&) = delete;

  const Scene scene;
  Tracer tracer;
  VirtualClock clock;
  CollectingSink sink;
  Sampler sampler;
};

}  // namespace afr::testing
