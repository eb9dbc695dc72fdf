// The sampler node as a network service (DESIGN.md, "Network"; docs/service.md): it joins a
// display, receives the scene (chunked, hash-checked, cached on disk) and its region, follows
// the display's clock from view messages, runs a SamplerPool on its region and streams sample
// batches and tiling snapshots back, with heartbeats and stats on the control channel. It
// follows region changes (restarting its pool on the new region) and, when the display goes
// away or restarts, joins again by itself. On a display wall it sends each sample to the
// display nodes whose part of the image needs it (docs/wall.md).
//
// Threads: run() is the control loop (one thread); the pool's workers call the network sink,
// which serialises them on the sample socket. Stop by setting the flag run() watches.
#pragma once

#include <afr/protocol/channels.h>
#include <afr/sampler/sampler_config.h>
#include <afr/sampler/service/scene_cache.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace afr::service {

// Knobs a preset sets (afr/common/presets.h) that the user gave explicitly: they win over the
// preset the display names.
struct PresetOverrides {
  std::optional<int> b, r, chunk, min_tiles, max_tiles;
  void apply(SamplerConfig* c) const {
    if (b) c->b = *b;
    if (r) c->r = *r;
    if (chunk) c->chunk = *chunk;
    if (min_tiles) c->min_tiles = *min_tiles;
    if (max_tiles) c->max_tiles = *max_tiles;
  }
};

struct SamplerServiceOptions {
  std::string display;  // base endpoint of the display, "tcp://HOST:PORT"
  int threads = 1;
  double max_samples_per_second = 0.0;  // over all threads; 0 = no cap
  int worker_nice = 0;                  // SamplerPoolOptions::worker_nice
  bool worker_idle = false;             // SamplerPoolOptions::worker_idle
  int light_samples = 0;                // TracerOptions::light_samples
  std::string preset;                   // empty: the preset the display names in its welcome
  SamplerConfig config;                 // knobs from flags; size and region come from the display
  PresetOverrides overrides;            // flags given explicitly: applied after the preset
  std::string name;                     // for the display's logs; default: host name + pid
  std::filesystem::path cache_dir;      // received scenes
  uint64_t cache_max_bytes = SceneCache::kDefaultMaxBytes;  // beyond: least recently used go
  protocol::Security security;                              // CurveZMQ client keys, or none
  // The sample channel's kernel send buffer, bytes (0: ChannelOptions::samples()'s): what a
  // saturated link holds of this sampler's samples beyond ZeroMQ's queue.
  int send_buffer = 0;
  // Seconds of silence on the display's control channel (heartbeats, anything; views do not
  // count: they carry no session) before the sampler may drop its connections and join again:
  // the floor of its failure detector (afr/common/failure_detector.h), which waits longer
  // when the display's messages have come irregularly.
  double display_timeout = 1.5;
  double heartbeat_interval = protocol::kMemberHeartbeatInterval;
  double stats_interval = 1.0;
};

// Counters over the life of the process (all sessions).
struct SamplerServiceCounters {
  uint64_t sessions = 0;
  uint64_t joins_sent = 0;
  uint64_t regions = 0;
  uint64_t wall_layouts = 0;  // display-wall layouts followed
  uint64_t scenes_received = 0;
  uint64_t scene_cache_hits = 0;
  uint64_t rejected_messages = 0;
};

class SamplerService {
 public:
  explicit SamplerService(SamplerServiceOptions options);
  ~SamplerService();
  SamplerService(const SamplerService&) = delete;
  SamplerService& operator=(const SamplerService&) = delete;

  // Runs until `stop` becomes true; then leaves the display politely. Returns the process exit
  // code: 0 after a stop, 2 when the display refused this sampler for good (version mismatch).
  int run(const std::atomic<bool>& stop);

  SamplerServiceCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace afr::service
