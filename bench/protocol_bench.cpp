// afr-bench-protocol: what the wire costs. Encode and decode time per sample for each field
// combination (ns/sample), the size per sample, and the throughput of sample batches through
// the sample channel (SampleSender -> SampleReceiver over TCP loopback, with and without
// CurveZMQ), decoded on the receiving side as the display does; and, on raw sockets, why a
// non-blocking sender must read ZMQ_EVENTS after a refused send. Sender and receiver use
// separate ZeroMQ contexts, as separate processes would.
//   afr-bench-protocol --benchmark_min_time=1
#include <afr/common/random.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/codec.h>

#include <benchmark/benchmark.h>
#include <zmq.hpp>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace {

using namespace afr;
using namespace afr::protocol;

// A batch like the sampler's: crosshair samples within a millisecond, HDR colors.
SampleBatch make_batch(uint32_t fields, size_t n, uint64_t seed = 1) {
  Pcg32 rng(seed);
  SampleBatch b;
  b.sampler_id = 3;
  b.fields = fields;
  const double base = 1234.5;
  b.samples.resize(n);
  for (Sample& s : b.samples) {
    s.time = base + rng.next_double() * 1e-3;
    s.x = rng.next_float() * 1920.0f;
    s.y = rng.next_float() * 1080.0f;
    s.color = glm::vec3(rng.next_float() * 2, rng.next_float(), rng.next_float() * 0.5f);
    if (fields & kFieldPosition) {
      s.position = glm::vec3(rng.next_float() * 10, rng.next_float() * 10, rng.next_float() * 10);
      s.miss = rng.next_below(10) == 0;
    }
    if (fields & kFieldVelocity) s.velocity = glm::vec3(rng.next_float(), 0.0f, -rng.next_float());
  }
  return b;
}

void set_counters(benchmark::State& state, size_t samples, size_t bytes) {
  state.SetItemsProcessed(int64_t(state.iterations() * samples));
  state.SetBytesProcessed(int64_t(state.iterations() * bytes));
  // Seconds per sample, printed with an SI prefix ("7.9ns").
  state.counters["time/sample"] = benchmark::Counter(
      double(samples), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["bytes/sample"] = double(bytes) / double(samples);
}

// ---------------------------------------------------------------------------------------------
// Codec

void BM_EncodeBatch(benchmark::State& state) {
  const uint32_t fields = uint32_t(state.range(0));
  const SampleBatch batch = make_batch(fields, size_t(state.range(1)));
  std::vector<uint8_t> bytes;
  for (auto _ : state) {
    if (!encode(batch, &bytes).ok()) state.SkipWithError("encode failed");
    benchmark::DoNotOptimize(bytes.data());
    benchmark::ClobberMemory();
  }
  set_counters(state, batch.samples.size(), bytes.size());
}

void BM_DecodeBatch(benchmark::State& state) {
  const uint32_t fields = uint32_t(state.range(0));
  const SampleBatch batch = make_batch(fields, size_t(state.range(1)));
  std::vector<uint8_t> bytes;
  if (!encode(batch, &bytes).ok()) state.SkipWithError("encode failed");
  SampleBatch out;
  for (auto _ : state) {
    if (!decode(Bytes(bytes), &out).ok()) state.SkipWithError("decode failed");
    benchmark::DoNotOptimize(out.samples.data());
    benchmark::ClobberMemory();
  }
  set_counters(state, batch.samples.size(), bytes.size());
}

// fields: 0 none, 1 position, 2 velocity, 3 both; batch sizes: the sampler's default and large.
void codec_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"fields", "n"});
  for (int fields : {0, 1, 2, 3}) b->Args({fields, 128});
  b->Args({1, 4096});
}
BENCHMARK(BM_EncodeBatch)->Apply(codec_args);
BENCHMARK(BM_DecodeBatch)->Apply(codec_args);

void BM_DecodeTiling(benchmark::State& state) {
  Pcg32 rng(2);
  TilingSnapshot t;
  t.region = PixelRect{0, 0, 1920, 1080};
  t.tiles.resize(size_t(state.range(0)));
  for (size_t i = 0; i < t.tiles.size(); ++i) {
    // 20 x 20 tiles side by side, row by row, as a tiling's (tiles do not overlap).
    TileInfo& tile = t.tiles[i];
    const int32_t x = int32_t(i % 96) * 20, y = int32_t(i / 96 % 54) * 20;
    tile.rect = PixelRect{x, y, x + 20, y + 20};
    tile.v = rng.next_float();
    tile.rate = 100.0f;
  }
  std::vector<uint8_t> bytes;
  if (!encode(t, &bytes).ok()) state.SkipWithError("encode failed");
  TilingSnapshot out;
  for (auto _ : state) {
    if (!decode(Bytes(bytes), &out).ok()) state.SkipWithError("decode failed");
    benchmark::DoNotOptimize(out.tiles.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations() * t.tiles.size()));
}
BENCHMARK(BM_DecodeTiling)->Arg(1024);

// ---------------------------------------------------------------------------------------------
// Channel throughput: one sampler thread sending, one display thread receiving and decoding

void BM_PushPullLoopback(benchmark::State& state) {
  const bool curve = state.range(0) != 0;
  const size_t n = size_t(state.range(1));
  const SampleBatch batch = make_batch(kFieldPosition, n);

  Context display_context, sampler_context;
  Security server, client;
  if (curve) {
    const CurveKeyPair display = generate_curve_keypair(), sampler = generate_curve_keypair();
    display_context.allow_curve_clients({sampler.public_key});
    server = Security::server(display);
    client = Security::client(sampler, display.public_key);
  }
  SampleReceiver receiver(display_context, "tcp://127.0.0.1:*", server);
  SampleSender sender(sampler_context, receiver.endpoint(), client);

  std::atomic<bool> stop{false};
  std::atomic<uint64_t> received{0};
  std::thread display([&] {
    while (!stop.load(std::memory_order_relaxed)) {
      if (receiver.receive(50) == SampleReceiver::Got::kBatch) {
        received.fetch_add(receiver.batch().samples.size(), std::memory_order_relaxed);
      }
    }
  });
  // Connect first, so that the timed loop measures the steady state.
  while (received.load() == 0) {
    (void)sender.send(batch);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const uint64_t start_received = received.load();
  const uint64_t start_dropped = sender.counters().batches_dropped;
  const auto start = std::chrono::steady_clock::now();
  uint64_t sent = 0;
  for (auto _ : state) {
    // Wait for room rather than drop: this measures what the channel carries without loss.
    sender.flush(-1);
    (void)sender.send(batch);
    sent += n;
  }
  sender.flush(-1);
  // Until everything sent has arrived (or a second has passed without progress).
  const uint64_t target = start_received + sent;
  uint64_t last = 0;
  auto last_progress = std::chrono::steady_clock::now();
  while (received.load() < target) {
    const uint64_t r = received.load();
    if (r != last) last = r, last_progress = std::chrono::steady_clock::now();
    if (std::chrono::steady_clock::now() - last_progress > std::chrono::seconds(1)) break;
    std::this_thread::yield();
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop = true;
  display.join();
  const double got = double(received.load() - start_received);
  const double bytes_per_sample = double(batch_message_bytes(kFieldPosition, n)) / double(n);
  state.counters["samples/s"] = got / seconds;
  state.counters["MB/s"] = got * bytes_per_sample / seconds / 1e6;
  state.counters["lost"] = double(sent) - got;
  state.counters["dropped"] = double(sender.counters().batches_dropped - start_dropped);
}
BENCHMARK(BM_PushPullLoopback)
    ->ArgNames({"curve", "n"})
    ->Args({0, 128})
    ->Args({0, 1024})
    ->Args({1, 128})
    ->Args({1, 1024})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------------------------------------
// The fact behind send_retry's ZMQ_EVENTS check, on raw sockets with the sample channel's marks
// and buffers: a sender that never blocks (send with dontwait; when refused, yield and try
// again). libzmq reads a socket's commands at most every 3 million TSC ticks on a non-blocking
// send, so without the check the sender learns that the pipe has room only that often.

void BM_NonBlockingSendRaw(benchmark::State& state) {
  const bool recheck = state.range(0) != 0;
  zmq::context_t display_context, sampler_context;
  zmq::socket_t pull(display_context, zmq::socket_type::pull);
  zmq::socket_t push(sampler_context, zmq::socket_type::push);
  const ChannelOptions o = ChannelOptions::samples();
  pull.set(zmq::sockopt::rcvhwm, o.receive_hwm);
  pull.set(zmq::sockopt::rcvbuf, o.receive_buffer);
  pull.set(zmq::sockopt::linger, 0);
  push.set(zmq::sockopt::sndhwm, o.send_hwm);
  push.set(zmq::sockopt::sndbuf, o.send_buffer);
  push.set(zmq::sockopt::linger, 0);
  pull.bind("tcp://127.0.0.1:*");
  push.connect(pull.get(zmq::sockopt::last_endpoint));
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> received{0};
  std::thread display([&] {
    zmq::pollitem_t item = {pull.handle(), 0, ZMQ_POLLIN, 0};
    while (!stop.load(std::memory_order_relaxed)) {
      if (zmq::poll(&item, 1, std::chrono::milliseconds(50)) <= 0) continue;
      zmq::message_t m;
      while (pull.recv(m, zmq::recv_flags::dontwait)) received.fetch_add(1);
    }
  });
  std::vector<uint8_t> bytes(batch_message_bytes(kFieldPosition, 128));
  while (received.load() == 0) {
    zmq::message_t m(bytes.data(), bytes.size());
    (void)push.send(m, zmq::send_flags::dontwait);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const uint64_t start_received = received.load();
  const auto start = std::chrono::steady_clock::now();
  for (auto _ : state) {
    zmq::message_t m(bytes.data(), bytes.size());
    if (push.send(m, zmq::send_flags::dontwait)) continue;
    if (recheck && (push.get(zmq::sockopt::events) & ZMQ_POLLOUT)) continue;
    std::this_thread::yield();
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop = true;
  display.join();
  state.counters["delivered msg/s"] = double(received.load() - start_received) / seconds;
}
BENCHMARK(BM_NonBlockingSendRaw)->ArgName("recheck")->Arg(0)->Arg(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
