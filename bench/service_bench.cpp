// afr-bench-service: what the display's ingest costs, and a synthetic sampler for goodput runs
// (docs/service.md, "Figures").
//
//   afr-bench-service [--benchmark_repetitions=5 ...]     Google Benchmark (below)
//   afr-bench-service send --display tcp://HOST:PORT      synthetic sample batches, full speed
//   afr-bench-service receive --bind tcp://HOST:PORT      the display's ingest alone
//
// Benchmarks:
//   BM_Ingest: a sender thread pushes batches of 128 samples as fast as it can (SampleSender,
//     the real encoder and socket options) over TCP loopback to the display's ingest thread
//     (SampleReceiver -> run_ingest: decode, ServiceMetrics, and the reconstructor's
//     SampleStore append, or no store). Per window of wall time: the ingest thread's CPU time
//     (CLOCK_THREAD_CPUTIME_ID of that thread) per received sample, samples/s received, the
//     ingest thread's busy share, and what the sender offered and its queue dropped.
//   BM_StoreAppend: SampleStore::append alone, per sample (no network).
//
// send and receive are the two ends of deploy/lan/goodput.sh: both print their cumulative
// counters as one "counters ..." line on SIGUSR1 (so a script reads them at the same moments)
// and at exit. The receiver counts what the display's ingest thread counts (run_ingest into a
// SampleStore); display_node itself can be the receiver instead (its /stats).
#include <afr/common/cli.h>
#include <afr/common/random.h>
#include <afr/display/sample_store.h>
#include <afr/display/service/display_service.h>
#include <afr/display/service/metrics.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/codec.h>
#include <afr/protocol/display_link.h>
#include <afr/protocol/messages.h>

#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <pthread.h>
#include <signal.h>
#include <time.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

namespace {

using namespace afr;
using namespace afr::protocol;
using Clock = std::chrono::steady_clock;

constexpr size_t kBatch = 128;
constexpr int kWidth = 256, kHeight = 256;  // display_node's default --size

// Batches like the sampler's: 128 crosshair samples within a millisecond, HDR colors, inside
// a width x height image; distinct contents so that nothing is cached between batches.
std::vector<SampleBatch> make_batches(uint32_t fields, size_t n, int width, int height,
                                      size_t count, uint32_t sampler_id) {
  Pcg32 rng(7);
  std::vector<SampleBatch> out(count);
  for (SampleBatch& b : out) {
    b.sampler_id = sampler_id;
    b.fields = fields;
    b.samples.resize(n);
    for (Sample& s : b.samples) {
      s.time = rng.next_double() * 1e-3;
      s.x = rng.next_float() * float(width);
      s.y = rng.next_float() * float(height);
      s.color = glm::vec3(rng.next_float() * 2, rng.next_float(), rng.next_float() * 0.5f);
      if (fields & kFieldPosition) {
        s.position = glm::vec3(rng.next_float() * 10, rng.next_float() * 10, rng.next_float());
        s.miss = rng.next_below(10) == 0;
        if (s.miss) s.position = glm::normalize(s.position + glm::vec3(0.1f));
      }
      if (fields & kFieldVelocity && !s.miss) {
        s.velocity = glm::vec3(rng.next_float(), 0.0f, -rng.next_float());
      }
    }
    // Keep the image positions strictly inside the image after rounding.
    for (Sample& s : b.samples) {
      s.x = std::min(s.x, float(width) - 0.01f);
      s.y = std::min(s.y, float(height) - 0.01f);
    }
  }
  return out;
}

// Stamps a batch at display time t (its samples keep their offsets within the batch).
void stamp(SampleBatch& b, double t, uint64_t sequence) {
  double base = b.samples.front().time;
  for (const Sample& s : b.samples) base = std::min(base, s.time);
  for (Sample& s : b.samples) s.time = t + (s.time - base);
  b.sequence = sequence;
}

double thread_cpu_seconds(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return double(ts.tv_sec) + double(ts.tv_nsec) * 1e-9;
}

struct NullSink : SampleSink {
  void on_batch(SampleBatch&&) override {}
  void on_tiling(TilingSnapshot&&) override {}
};
// What Reconstructor::on_batch does (store_.append); the tile field is not exercised.
struct StoreSink : SampleSink {
  explicit StoreSink(size_t capacity) : store(capacity) {}
  void on_batch(SampleBatch&& batch) override { store.append(batch); }
  void on_tiling(TilingSnapshot&&) override {}
  SampleStore store;
};

uint64_t received_samples(const service::ServiceMetrics& m) {
  uint64_t n = 0;
  for (const service::SamplerMetrics& s : m.samplers()) n += s.samples;
  return n;
}
uint64_t received_bytes(const service::ServiceMetrics& m) {
  uint64_t n = 0;
  for (const service::SamplerMetrics& s : m.samplers()) n += s.bytes;
  return n;
}

// ---------------------------------------------------------------------------------------------
// BM_Ingest

// A sampler thread: sends as fast as it can. drop: never waits (SampleSender drops the oldest
// when ZeroMQ's queue is full, as a sampler does); else it waits for room (flush), which gives
// the highest rate delivered without loss.
class SenderThread {
 public:
  SenderThread(const std::string& endpoint, uint32_t fields, bool drop)
      : sender_(context_, endpoint),
        batches_(make_batches(fields, kBatch, kWidth, kHeight, 64, 1)),
        thread_([this, drop] { run(drop); }) {}
  ~SenderThread() {
    stop_ = true;
    thread_.join();
  }
  uint64_t offered() const { return offered_.load(std::memory_order_relaxed); }
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  void run(bool drop) {
    const auto start = Clock::now();
    uint64_t sequence = 0;
    while (!stop_.load(std::memory_order_relaxed)) {
      if (!drop && !sender_.flush(50)) continue;
      SampleBatch& b = batches_[sequence % batches_.size()];
      stamp(b, std::chrono::duration<double>(Clock::now() - start).count(), sequence++);
      (void)sender_.send(b);
      offered_.store(sequence, std::memory_order_relaxed);
      dropped_.store(sender_.counters().batches_dropped, std::memory_order_relaxed);
    }
  }
  Context context_;  // its own context, as a separate process would have
  SampleSender sender_;
  std::vector<SampleBatch> batches_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> offered_{0}, dropped_{0};
  std::thread thread_;
};

constexpr double kWindowSeconds = 1.0;

// Args: fields (1 position, 3 position + velocity), store capacity (0: no store, decode only),
// drop (0: sender waits for room, 1: sender never waits).
void BM_Ingest(benchmark::State& state) {
  const uint32_t fields = uint32_t(state.range(0));
  const size_t capacity = size_t(state.range(1));
  const bool drop = state.range(2) != 0;

  Context display_context;
  SampleReceiver receiver(display_context, "tcp://127.0.0.1:*");
  receiver.set_image_bounds({kWidth, kHeight});
  service::ServiceMetrics metrics;
  NullSink null_sink;
  std::unique_ptr<StoreSink> store_sink;
  if (capacity > 0) store_sink = std::make_unique<StoreSink>(capacity);
  SampleSink& sink = store_sink ? static_cast<SampleSink&>(*store_sink) : null_sink;
  std::atomic<bool> running{true};
  // The display's ingest thread, as DisplayService::ingest_loop runs it.
  std::thread ingest([&] { service::run_ingest(receiver, sink, metrics, nullptr, running); });
  clockid_t ingest_clock{};
  pthread_getcpuclockid(ingest.native_handle(), &ingest_clock);

  double cpu = 0.0, wall = 0.0;
  uint64_t samples = 0, bytes = 0, offered = 0, dropped = 0;
  {
    SenderThread sender(receiver.endpoint(), fields, drop);
    // Connected, and the store filled past its first lap (the steady state).
    const auto warm = Clock::now();
    while (received_samples(metrics) < std::max<size_t>(capacity, 1) + 100000 &&
           Clock::now() - warm < std::chrono::seconds(10)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    for (auto _ : state) {
      const uint64_t s0 = received_samples(metrics), b0 = received_bytes(metrics);
      const uint64_t o0 = sender.offered(), d0 = sender.dropped();
      const double c0 = thread_cpu_seconds(ingest_clock);
      const auto t0 = Clock::now();
      std::this_thread::sleep_for(std::chrono::duration<double>(kWindowSeconds));
      const double c1 = thread_cpu_seconds(ingest_clock);
      const auto t1 = Clock::now();
      const uint64_t s1 = received_samples(metrics), b1 = received_bytes(metrics);
      const double w = std::chrono::duration<double>(t1 - t0).count();
      state.SetIterationTime(w);
      cpu += c1 - c0;
      wall += w;
      samples += s1 - s0;
      bytes += b1 - b0;
      offered += sender.offered() - o0;
      dropped += sender.dropped() - d0;
    }
  }
  running = false;
  ingest.join();
  if (samples == 0) {
    state.SkipWithError("nothing received");
    return;
  }
  state.counters["ingest_ns/sample"] = cpu * 1e9 / double(samples);
  state.counters["ingest_busy"] = cpu / wall;  // share of one core the ingest thread used
  state.counters["ceiling_Msamples/s"] = double(samples) / cpu / 1e6;  // at 100 % of a core
  state.counters["Msamples/s"] = double(samples) / wall / 1e6;
  state.counters["MB/s"] = double(bytes) / wall / 1e6;
  state.counters["offered_Msamples/s"] = double(offered * kBatch) / wall / 1e6;
  state.counters["dropped_share"] = offered ? double(dropped) / double(offered) : 0.0;
}

void ingest_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"fields", "store", "drop"});
  constexpr int64_t kDisplayStore = 4 * kWidth * kHeight;  // N = 4 x pixels, 256 x 256
  constexpr int64_t kLargeStore = 4 * 1024 * 1024;         // 1024 x 1024 (256 MiB)
  for (int64_t fields : {1, 3}) {
    b->Args({fields, 0, 0});
    b->Args({fields, kDisplayStore, 0});
  }
  b->Args({1, kLargeStore, 0});
  b->Args({1, 0, 1});
  b->Args({1, kDisplayStore, 1});
}
BENCHMARK(BM_Ingest)
    ->Apply(ingest_args)
    ->Iterations(2)
    ->Repetitions(5)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->DisplayAggregatesOnly(true);

// ---------------------------------------------------------------------------------------------
// BM_StoreAppend: the store's share alone (sanitise + copy into the ring under the lock).

void BM_StoreAppend(benchmark::State& state) {
  const uint32_t fields = uint32_t(state.range(0));
  SampleStore store(size_t(state.range(1)));
  std::vector<SampleBatch> batches = make_batches(fields, kBatch, kWidth, kHeight, 64, 1);
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(store.append(batches[i++ % batches.size()]));
  }
  state.SetItemsProcessed(int64_t(state.iterations() * kBatch));
  state.counters["time/sample"] = benchmark::Counter(
      double(kBatch), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_StoreAppend)
    ->ArgNames({"fields", "capacity"})
    ->Args({1, 4 * kWidth* kHeight})
    ->Args({3, 4 * kWidth* kHeight})
    ->Args({1, 4 * 1024 * 1024})
    ->Repetitions(5)
    ->DisplayAggregatesOnly(true);

// ---------------------------------------------------------------------------------------------
// send / receive: the two ends of deploy/lan/goodput.sh

std::atomic<bool> g_report{false}, g_stop{false};
extern "C" void on_usr1(int) { g_report = true; }
extern "C" void on_stop(int) { g_stop = true; }

void install_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_usr1;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGUSR1, &sa, nullptr);
  sa.sa_handler = on_stop;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
}

double since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int send_main(int argc, char** argv) {
  install_signals();  // before anything slow: a script may signal early
  CLI::App app{"afr-bench-service send: synthetic sample batches at full speed"};
  std::string display;
  std::string mode = "drop";
  uint32_t fields = 1, id = 1;
  size_t batch = kBatch;
  int width = kWidth, height = kHeight;
  double seconds = 0.0, max_samples_per_second = 0.0;
  ChannelOptions options = ChannelOptions::samples();
  app.add_option("--display", display, "display base endpoint tcp://HOST:PORT (samples: PORT+2)")
      ->required();
  app.add_option("--mode", mode,
                 "drop: never wait, the sampler's behaviour (the sender's queue drops the "
                 "oldest); flush: wait for room, nothing dropped")
      ->check(CLI::IsMember({"drop", "flush"}))
      ->capture_default_str();
  app.add_option("--fields", fields, "1 world position, 3 position + velocity")
      ->check(CLI::IsMember({0u, 1u, 2u, 3u}))
      ->capture_default_str();
  app.add_option("--batch", batch, "samples per batch")->capture_default_str();
  app.add_option("--id", id, "sampler id in the batches (without --join)")->capture_default_str();
  bool join = false;
  app.add_flag("--join", join,
               "join the display first as a member (display_node drops batches from non-members) "
               "and send heartbeats: the id and token are the welcome's");
  app.add_option("--width", width, "the display's image width")->capture_default_str();
  app.add_option("--height", height, "the display's image height")->capture_default_str();
  app.add_option("--seconds", seconds, "stop after this long (0: at SIGTERM or SIGINT)");
  app.add_option("--max-samples-per-second", max_samples_per_second,
                 "pace (0: unpaced); time the sender was not scheduled is not made up for");
  // Diagnosis only: the protocol's sample channel options are the defaults.
  app.add_option("--sndhwm", options.send_hwm, "ZMQ_SNDHWM (messages)")->capture_default_str();
  app.add_option("--sndbuf", options.send_buffer, "SO_SNDBUF (bytes, 0: OS default)")
      ->capture_default_str();
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  Context context;
  // With --join: membership through the control channel, as a sampler has it.
  std::unique_ptr<DisplayLink> link;
  uint64_t token = 0, session = 0, heartbeats = 0;
  const auto drain = [&] {
    while (std::optional<Result<Message>> m = link->receive_control()) {
      if (!m->ok()) continue;
      if (const auto* w = std::get_if<Welcome>(&m->value()); w && !link->joined()) {
        link->welcomed();
        id = w->sampler_id;
        token = w->token;
        session = w->session;
      }
    }
  };
  if (join) {
    DisplayLinkOptions lo;
    lo.display = display;
    link = std::make_unique<DisplayLink>(context, lo);
    const auto asked = Clock::now();
    while (!link->joined()) {
      if (g_stop.load() || since(asked) > 20.0) {
        std::fprintf(stderr, "send: no welcome from %s\n", display.c_str());
        return 1;
      }
      if (link->join_due()) {
        Join j;
        j.name = "afr-bench-service";
        (void)link->send(j);
      }
      link->wait(50);
      drain();
    }
  }
  SampleSender sender(context, service_endpoints(display).samples, Security::none(), options);
  std::vector<SampleBatch> batches = make_batches(fields, batch, width, height, 64, id);
  for (SampleBatch& b : batches) b.token = token;
  const ImageExtent bounds{width, height};
  std::printf("ready\n");
  std::fflush(stdout);
  const auto start = Clock::now();
  uint64_t offered = 0;
  double next = 0.0;  // paced: when the next batch is due
  auto report = [&] {
    const SampleSender::Counters& c = sender.counters();
    std::printf(
        "counters t=%.6f offered=%llu sent=%llu dropped=%llu bytes_sent=%llu batch_samples=%zu "
        "batch_bytes=%zu\n",
        since(start), (unsigned long long)offered, (unsigned long long)c.batches_sent,
        (unsigned long long)c.batches_dropped, (unsigned long long)c.bytes_sent, batch,
        batch_message_bytes(fields, batch));
    std::fflush(stdout);
  };
  while (!g_stop.load(std::memory_order_relaxed)) {
    if (g_report.exchange(false)) report();
    const double t = since(start);
    if (link) {
      drain();
      if (link->heartbeat_due()) (void)link->send(Heartbeat{id, session, ++heartbeats, 0.0});
    }
    if (seconds > 0.0 && t >= seconds) break;
    if (max_samples_per_second > 0.0) {
      if (next > t) {
        std::this_thread::sleep_for(std::chrono::duration<double>(std::min(next - t, 0.01)));
        continue;
      }
      // A sampler that was not running traced nothing: catch up at most 1 ms, no backlog.
      next = std::max(next, t - 1e-3) + double(batch) / max_samples_per_second;
    }
    if (mode == "flush" && !sender.flush(20)) continue;
    SampleBatch& b = batches[offered % batches.size()];
    stamp(b, t, offered);
    if (Status s = sender.send(b, bounds); !s) {
      std::fprintf(stderr, "send: %s\n", s.message().c_str());
      return 1;
    }
    ++offered;
  }
  report();
  return 0;
}

int receive_main(int argc, char** argv) {
  install_signals();
  CLI::App app{"afr-bench-service receive: the display's ingest thread alone"};
  std::string bind;
  int width = kWidth, height = kHeight;
  size_t capacity = 4 * kWidth * kHeight;
  ChannelOptions options = ChannelOptions::samples();
  app.add_option("--bind", bind, "base endpoint tcp://HOST:PORT (samples: PORT+2)")->required();
  app.add_option("--width", width, "image width")->capture_default_str();
  app.add_option("--height", height, "image height")->capture_default_str();
  app.add_option("--store", capacity, "SampleStore capacity (0: no store)")->capture_default_str();
  app.add_option("--rcvhwm", options.receive_hwm, "ZMQ_RCVHWM (messages)")->capture_default_str();
  app.add_option("--rcvbuf", options.receive_buffer, "SO_RCVBUF (bytes, 0: OS default)")
      ->capture_default_str();
  afr::refuse_non_finite(app);
  CLI11_PARSE(app, argc, argv);

  Context context;
  SampleReceiver receiver(context, service_endpoints(bind).samples, Security::none(), options);
  receiver.set_image_bounds({width, height});
  service::ServiceMetrics metrics;
  NullSink null_sink;
  std::unique_ptr<StoreSink> store_sink;
  if (capacity > 0) store_sink = std::make_unique<StoreSink>(capacity);
  SampleSink& sink = store_sink ? static_cast<SampleSink&>(*store_sink) : null_sink;
  std::atomic<bool> running{true};
  std::thread ingest([&] { service::run_ingest(receiver, sink, metrics, nullptr, running); });
  clockid_t ingest_clock{};
  pthread_getcpuclockid(ingest.native_handle(), &ingest_clock);
  std::printf("ready\n");
  std::fflush(stdout);
  const auto start = Clock::now();
  auto report = [&] {
    uint64_t samples = 0, bytes = 0, batches = 0, gaps = 0;
    for (const service::SamplerMetrics& s : metrics.samplers()) {
      samples += s.samples;
      bytes += s.bytes;
      batches += s.batches;
      gaps += s.sequence_gaps;
    }
    std::printf(
        "counters t=%.6f samples=%llu bytes=%llu batches=%llu gaps=%llu rejected=%llu "
        "ingest_cpu=%.6f\n",
        since(start), (unsigned long long)samples, (unsigned long long)bytes,
        (unsigned long long)batches, (unsigned long long)gaps,
        (unsigned long long)metrics.display().rejected_samples_channel,
        thread_cpu_seconds(ingest_clock));
    std::fflush(stdout);
  };
  while (!g_stop.load()) {
    if (g_report.exchange(false)) report();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  report();
  running = false;
  ingest.join();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "send") == 0) return send_main(argc - 1, argv + 1);
  if (argc > 1 && std::strcmp(argv[1], "receive") == 0) return receive_main(argc - 1, argv + 1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
