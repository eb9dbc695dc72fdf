// sampler_node: one sampler of the afr service. It needs only the display's address:
//   sampler_node --display tcp://127.0.0.1:7100 --threads 2
//   sampler_node --display tcp://10.0.0.1:7100 --key sampler.key --server-key display.pub
//   sampler_node keygen sampler.key          (writes sampler.key and sampler.pub)
// The display sends the scene, the image size and the region to sample (docs/service.md).
#include <afr/common/cli.h>
#include <afr/common/error.h>
#include <afr/common/log.h>
#include <afr/common/presets.h>
#include <afr/protocol/keys.h>
#include <afr/sampler/sampler_flags.h>
#include <afr/sampler/service/sampler_service.h>
#include <afr/sampler/service/scene_cache.h>
#include <afr/sampler/tracer.h>

#include <fmt/format.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <filesystem>

namespace {

std::atomic<bool> g_stop{false};  // set by SIGINT / SIGTERM
extern "C" void on_signal(int) { g_stop.store(true); }

std::string host_name() {
  char buf[256] = {};
  if (gethostname(buf, sizeof(buf) - 1) != 0) return "sampler";
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sampler_node: an afr sampler that joins a display node and streams samples"};
  afr::service::SamplerServiceOptions o;
  std::string log_level = "info", key_file, server_key_file, keys_dir, cache_dir;
  app.add_option("--display", o.display, "the display's base endpoint, tcp://HOST:PORT");
  app.add_option("-j,--threads", o.threads, "sampling threads")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  app.add_option("--preset", o.preset,
                 "fast, balanced or accurate (default: the preset the display names)");
  app.add_option("--max-samples-per-second", o.max_samples_per_second,
                 "cap on samples per second over all threads (0 = none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e12));
  app.add_option("--light-samples", o.light_samples,
                 "shadow rays of a surface's direct light: 0 = one toward every light (exact); "
                 "K = K toward lights picked by what each sends, where more than K reach it "
                 "(faster on scenes of many lights, noisier where some are blocked; "
                 "docs/sampler.md, \"Many lights\")")
      ->capture_default_str()
      ->check(CLI::Range(0, afr::kMaxLightSamples));
  app.add_flag("--worker-idle", o.worker_idle,
               "run the sampling threads only when no other thread wants the core (Linux "
               "SCHED_IDLE), not the node's control thread: a display on the same cores never "
               "waits for them");
  app.add_option("--worker-nice", o.worker_nice,
                 "lower the sampling threads' priority by this much (0-19), not the node's "
                 "control thread: a display on the same cores keeps its refresh and the "
                 "heartbeats stay on time")
      ->capture_default_str()
      ->check(CLI::Range(0, 19));
  app.add_option(
         "--send-buffer", o.send_buffer,
         "the sample channel's kernel send buffer in bytes (0: the protocol's 256 KiB, "
         "for a gigabit LAN; on a slower link a smaller one keeps samples fresher, a link of "
         "long round trips needs its bandwidth x round trip)")
      ->capture_default_str()
      ->check(CLI::Range(0, 64 << 20));
  app.add_option("--key", key_file, "this sampler's CurveZMQ key pair file (enables CurveZMQ)");
  app.add_option("--server-key", server_key_file, "the display's public key file");
  app.add_option("--keys", keys_dir,
                 "folder with sampler.key and display.pub (instead of --key and --server-key)");
  app.add_option("--name", o.name, "name shown in the display's logs (default: host:pid)");
  app.add_option("--cache", cache_dir, "folder for received scenes (default: ~/.cache/afr/scenes)");
  double cache_mb = double(afr::service::SceneCache::kDefaultMaxBytes) / (1 << 20);
  app.add_option("--cache-max-mb", cache_mb,
                 "MiB of scenes the cache folder keeps; beyond, the least recently used go (the "
                 "scene being served always stays)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--display-timeout", o.display_timeout,
                 "seconds of silence from the display before reconnecting")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 60.0));
  app.add_option("--log", log_level, "log level")->capture_default_str();
  afr::add_sampler_flags(app, &o.config);

  std::string keygen_path;
  CLI::App* keygen =
      app.add_subcommand("keygen", "write a new CurveZMQ key pair FILE and FILE.pub");
  keygen->add_option("file", keygen_path, "key pair file to write (mode 0600)")->required();
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  try {
    afr::init_logging(log_level);
    if (*keygen) {
      const afr::protocol::CurveKeyPair pair = afr::protocol::generate_curve_keypair();
      std::filesystem::path pub = keygen_path;
      pub.replace_extension(".pub");
      afr::protocol::save_curve_keypair(keygen_path, pair);
      afr::protocol::save_curve_public_key(pub.string(), pair.public_key);
      fmt::print("wrote {} and {} (public key {})\n", keygen_path, pub.string(), pair.public_key);
      return 0;
    }
    if (o.display.empty()) throw afr::Error("--display tcp://HOST:PORT is required");
    if (!keys_dir.empty()) {
      if (key_file.empty()) key_file = (std::filesystem::path(keys_dir) / "sampler.key").string();
      if (server_key_file.empty()) {
        server_key_file = (std::filesystem::path(keys_dir) / "display.pub").string();
      }
    }
    if (key_file.empty() != server_key_file.empty()) {
      throw afr::Error(
          "CurveZMQ needs both --key (this sampler's pair) and --server-key (the "
          "display's public key)");
    }
    if (!key_file.empty()) {
      o.security =
          afr::protocol::Security::client(afr::protocol::load_curve_keypair(key_file),
                                          afr::protocol::load_curve_public_key(server_key_file));
      spdlog::info("CurveZMQ on: this sampler's public key is {}", o.security.own.public_key);
    }
    if (o.name.empty()) o.name = fmt::format("{}:{}", host_name(), ::getpid());
    o.cache_dir = cache_dir.empty() ? afr::service::default_scene_cache_dir()
                                    : std::filesystem::path(cache_dir);
    o.cache_max_bytes = uint64_t(cache_mb * (1 << 20));
    o.config.validate();
    // Flags given on the command line win over the preset the display names.
    const auto given = [&](const char* flag) { return app.count(flag) > 0; };
    if (given("--b")) o.overrides.b = o.config.b;
    if (given("--r")) o.overrides.r = o.config.r;
    if (given("--chunk")) o.overrides.chunk = o.config.chunk;
    if (given("--min-tiles")) o.overrides.min_tiles = o.config.min_tiles;
    if (given("--max-tiles")) o.overrides.max_tiles = o.config.max_tiles;

    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::signal(SIGPIPE, SIG_IGN);
    afr::service::SamplerService service(o);
    spdlog::info("sampler {} connecting to {} with {} thread(s){}", o.name, o.display, o.threads,
                 o.max_samples_per_second > 0
                     ? fmt::format(", capped at {:.0f} samples/s", o.max_samples_per_second)
                     : "");
    return service.run(g_stop);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
