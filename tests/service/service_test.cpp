// Multi-process tests of the afr service on loopback: display_node and sampler_node as built,
// started as child processes, observed through the display's /stats and its images.
#include "process.h"

#include <afr/common/clock.h>
#include <afr/common/gltf_loader.h>
#include <afr/common/image.h>
#include <afr/display/backend.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/codec.h>
#include <afr/sampler/sampler_pool.h>

#include <gtest/gtest.h>
#include <zmq.hpp>

#include <filesystem>
#include <fstream>

namespace afr::testing {
namespace {

namespace fs = std::filesystem;

const std::string kDisplay = AFR_DISPLAY_NODE;
const std::string kSampler = AFR_SAMPLER_NODE;
const std::string kStaticScene = AFR_STATIC_SCENE;

class ServiceTest : public ProcessTest {
 protected:
  ServiceTest() : ProcessTest("afr-service-") {}
  using ProcessTest::endpoint;
  std::string endpoint() const { return endpoint(port_); }
  int metrics_port() const { return port_ + 3; }

  std::unique_ptr<Process> display(std::vector<std::string> extra, const std::string& log) {
    std::vector<std::string> argv = {kDisplay,           "--headless",
                                     "--bind",           endpoint(),
                                     "--metrics-port",   std::to_string(metrics_port()),
                                     "--backend",        "cpu",
                                     "--output",         path("out"),
                                     "--stats-interval", "1"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(log));
  }
  std::unique_ptr<Process> sampler(std::vector<std::string> extra, const std::string& log) {
    std::vector<std::string> argv = {kSampler, "--display", endpoint(), "--cache", path("cache")};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(log));
  }
  bool wait_members(int n, double timeout) {
    return wait_until([&] { return members(get_stats(metrics_port())) == n; }, timeout);
  }
  // Region of a member sampler (x0, y0, x1, y1), by position in /stats among members.
  std::vector<std::array<int, 4>> member_regions() {
    std::vector<std::array<int, 4>> out;
    const nlohmann::json s = get_stats(metrics_port());
    if (s.is_null() || s.is_discarded()) return out;
    for (const auto& m : s["samplers"]) {
      if (m["member"].get<bool>()) out.push_back(m["region"].get<std::array<int, 4>>());
    }
    return out;
  }
};

// ---------------------------------------------------------------------------------------------
// Convergence: the service gives the image the libraries give in one process

// The in-process result: the same scene, sampler seed and presets; a SamplerPool with two
// threads (two regions, as two nodes get) feeding a CPU reconstructor directly.
Image in_process_image(const Scene& scene, int w, int h, double seconds) {
  ReconstructorConfig rc;
  rc.image_width = w;
  rc.image_height = h;
  rc.capacity = size_t(4) * w * h;
  std::unique_ptr<Reconstructor> recon = make_reconstructor(Backend::kCpu, rc).reconstructor;
  SamplerConfig sc;
  sc.width = w;
  sc.height = h;
  sc.seed = 7;
  SamplerPoolOptions po;
  po.threads = 2;
  WallClock clock;
  {
    SamplerPool pool(scene, sc, po, clock, *recon);
    pool.start();
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    pool.stop();
  }
  const double t = clock.now();
  Image img = recon->reconstruct(scene.camera_at(scene.evaluate(0.0)), t, w, h);
  return img;
}

// "Close": the RMS difference (0-255 scale of the 8-bit images, the paper's metric) between
// the service's image and an in-process image is at most kRunToRunFactor times the difference
// between two in-process runs plus kRmsSlack: the network adds no more difference than two
// live runs of the libraries already have between them. (Live runs are not bit-reproducible:
// threads and the wall clock decide which samples exist. On this static scene two in-process
// runs differ by 10-17 and the service by 18-20 from one of them; docs/service.md, "Tests".
// Under a heavily loaded machine the service's processes get less CPU than the in-process
// run, hence a factor of 2.)
constexpr double kRunToRunFactor = 2.0;
constexpr double kRmsSlack = 3.0;

TEST_F(ServiceTest, TwoSamplersConvergeToTheInProcessImage) {
  const int w = 96, h = 72;
  const Scene scene = load_gltf(kStaticScene);
  const Image reference_linear = in_process_image(scene, w, h, 3.0);
  write_image(reference_linear, path("reference.png"));
  const Image reference = read_image(path("reference.png"));
  write_image(in_process_image(scene, w, h, 3.0), path("reference2.png"));
  const double rms_in_process = rms_error_255(read_image(path("reference2.png")), reference);
  std::printf("in-process vs in-process RMS (0-255): %.2f\n", rms_in_process);

  auto d =
      display({kStaticScene, "--size", "96x72", "--seconds", "6", "--fps", "60"}, "display.log");
  auto s1 = sampler({"--seed", "7"}, "s1.log");
  auto s2 = sampler({"--seed", "7"}, "s2.log");
  ASSERT_TRUE(wait_members(2, 4.0)) << d->log();
  ASSERT_EQ(d->wait(10.0), 0) << d->log();
  const Image served = read_image(path("out/final.png"));
  const double rms = rms_error_255(served, reference);
  std::printf("service vs in-process RMS (0-255): %.2f\n", rms);
  EXPECT_LE(rms, kRunToRunFactor * rms_in_process + kRmsSlack) << d->log();
  // Both samplers contributed, each to its half.
  EXPECT_NE(d->log().find("sampler 2 joined"), std::string::npos);
  // Both got the scene: sent by the display, or found in the cache the other one filled.
  for (const auto* s : {s1.get(), s2.get()}) {
    const std::string log = s->log();
    EXPECT_TRUE(log.find("scene received") != std::string::npos ||
                log.find("found in the cache") != std::string::npos)
        << log;
  }
}

// ---------------------------------------------------------------------------------------------
// Faults

TEST_F(ServiceTest, KilledSamplersRegionIsReassignedWithinOneSecond) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 4.0)) << d->log();
  auto s2 = sampler({"--max-samples-per-second", "50000"}, "s2.log");
  ASSERT_TRUE(wait_members(2, 4.0)) << d->log();
  ASSERT_TRUE(wait_until([&] { return member_regions().size() == 2; }, 2.0));

  s2->signal(SIGKILL);
  const double killed = time_of_day();
  const bool reassigned = wait_until(
      [&] {
        const auto r = member_regions();
        return r.size() == 1 && r[0] == std::array<int, 4>{0, 0, 64, 64};
      },
      scaled(3.0), 0.01);
  ASSERT_TRUE(reassigned) << d->log();
  // From the kill to the display's own word (its log), not to when this test's poll saw it.
  const double lost = log_time(d->log(), "lost: no word for");
  ASSERT_GE(lost, 0.0) << d->log();
  const double took = seconds_between(killed, lost);
  // Within a second; on a machine whose load spread the heartbeats' arrivals, the failure
  // detector is more patient, and the bound is what it said it would wait (logged).
  const double patience = log_number(d->log(), "lost: no word for", "suspected after ");
  std::printf("sampler declared lost %.3f s after kill -9 (suspected after %.3f s of silence)\n",
              took, patience);
  EXPECT_GT(patience, 0.0);
  EXPECT_LT(took, scaled(std::max(1.0, patience + 0.25))) << d->log();
  // The display keeps reconstructing.
  const uint64_t frames = get_stats(metrics_port())["display"]["frames"].get<uint64_t>();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_GT(get_stats(metrics_port())["display"]["frames"].get<uint64_t>(), frames);
}

// Stopped, not dead: a sampler frozen for 0.4 s (SIGSTOP, SIGCONT), three times, stays a member
// with its region; so do both while the machine is starved by twice as many busy processes as
// it has cores.
TEST_F(ServiceTest, StoppedOrStarvedSamplersAreNotDropped) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  auto s2 = sampler({"--max-samples-per-second", "50000"}, "s2.log");
  ASSERT_TRUE(wait_members(2, scaled(4.0))) << d->log();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  for (int i = 0; i < 3; ++i) {
    s1->signal(SIGSTOP);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    s1->signal(SIGCONT);
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
  }
  {
    std::vector<std::unique_ptr<Process>> burners;
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    for (unsigned i = 0; i < 2 * cores; ++i) {
      burners.push_back(std::make_unique<Process>(
          std::vector<std::string>{"/bin/sh", "-c", "while :; do :; done"}, path("burner.log")));
    }
    std::this_thread::sleep_for(std::chrono::seconds(3));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(members(get_stats(metrics_port())), 2) << d->log();
  EXPECT_EQ(d->log().find("lost: no word for"), std::string::npos) << d->log();
  EXPECT_EQ(count_of(d->log(), " joined: "), 2u) << d->log();
  for (const auto* s : {s1.get(), s2.get()}) {
    EXPECT_EQ(s->log().find("joining again"), std::string::npos) << s->log();
    EXPECT_EQ(s->log().find("reconnecting"), std::string::npos) << s->log();
  }
}

TEST_F(ServiceTest, SamplersAreBackWithinTwoSecondsOfADisplayRestart) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display1.log");
  auto s1 = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  auto s2 = sampler({"--max-samples-per-second", "50000"}, "s2.log");
  ASSERT_TRUE(wait_members(2, 5.0)) << d->log();
  const std::string session = get_stats(metrics_port())["display"]["session"];
  d->signal(SIGKILL);
  d->wait(2.0);
  auto d2 = display({"--size", "64x64", "--fps", "20"}, "display2.log");
  ASSERT_TRUE(wait_members(2, scaled(4.0))) << d2->log() << s1->log() << s2->log();
  // From the new display's bind (its first log line about its sockets) to its second join.
  const double bound = log_time(d2->log(), "display session");
  const double back = log_time(d2->log(), " joined: ", 2);
  ASSERT_GE(bound, 0.0) << d2->log();
  ASSERT_GE(back, 0.0) << d2->log();
  const double took = seconds_between(bound, back);
  std::printf("samplers back %.3f s after the display bound its sockets\n", took);
  EXPECT_LT(took, scaled(2.0)) << d2->log() << s1->log() << s2->log();
  EXPECT_NE(get_stats(metrics_port())["display"]["session"], session);
  // The scene was loaded once, before the restart: sent by the display, or found in the cache
  // the other sampler filled. After the restart the sampler kept it (same hash).
  for (const auto* s : {s1.get(), s2.get()}) {
    const std::string log = s->log();
    EXPECT_EQ(count_of(log, "scene received") + count_of(log, "found in the cache"), 1u) << log;
  }
}

TEST_F(ServiceTest, SamplerWithAnUnknownKeyIsRefusedAndLogged) {
  Process keygen({kDisplay, "keygen", path("keys"), "--samplers", "1"}, path("keygen.log"));
  ASSERT_EQ(keygen.wait(10.0), 0) << keygen.log();
  Process stranger_key({kSampler, "keygen", path("stranger.key")}, path("keygen2.log"));
  ASSERT_EQ(stranger_key.wait(10.0), 0) << stranger_key.log();

  auto d = display({"--size", "64x64", "--fps", "20", "--keys", path("keys")}, "display.log");
  auto good = sampler({"--key", path("keys/sampler-1.key"), "--server-key",
                       path("keys/display.pub"), "--max-samples-per-second", "50000"},
                      "good.log");
  auto bad =
      sampler({"--key", path("stranger.key"), "--server-key", path("keys/display.pub")}, "bad.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  ASSERT_TRUE(wait_until(
      [&] {
        const auto s = get_stats(metrics_port());
        return !s.is_null() && s["display"]["zap_refused"].get<int>() >= 1;
      },
      5.0))
      << d->log();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
  EXPECT_NE(d->log().find("REFUSED CURVE key"), std::string::npos) << d->log();
  EXPECT_EQ(bad->log().find("joined the display"), std::string::npos);
}

TEST_F(ServiceTest, StalledDisplayKeepsSamplerMemoryBoundedAndCountsDrops) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const long rss0 = s->rss_kb();
  d->signal(SIGSTOP);  // the display stops reading: its socket buffers and queues fill
  long rss_max = rss0;
  for (int i = 0; i < 30; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    rss_max = std::max(rss_max, s->rss_kb());
  }
  d->signal(SIGCONT);
  std::printf("sampler RSS %ld kB before the stall, at most %ld kB during 3 s of it\n", rss0,
              rss_max);
  EXPECT_LT(rss_max - rss0, 64 * 1024) << "sampler memory grew while the display was stalled";
  const bool counted = wait_until(
      [&] {
        const auto st = get_stats(metrics_port());
        if (st.is_null() || st.is_discarded()) return false;
        for (const auto& m : st["samplers"]) {
          if (m["batches_dropped"].get<uint64_t>() > 0) return true;
        }
        return false;
      },
      5.0);
  EXPECT_TRUE(counted) << d->log() << s->log();
}

TEST_F(ServiceTest, MalformedMessagesAreRejectedAndTheOthersKeepServing) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  {
    zmq::context_t ctx;
    zmq::socket_t push(ctx, zmq::socket_type::push);
    push.set(zmq::sockopt::linger, 1000);
    push.connect("tcp://127.0.0.1:" + std::to_string(port_ + 2));
    const std::string junk = "AFRP this is not a sample batch";
    for (int i = 0; i < 10; ++i) push.send(zmq::buffer(junk), zmq::send_flags::none);
    // A well-formed wall_coverage, which only a wall's node takes: this display is none.
    protocol::WallCoverage coverage;
    coverage.node_id = 2;
    coverage.time = 1.0;
    coverage.rect = PixelRect{0, 0, 4, 4};
    coverage.cells.assign(32, 1.0f);
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(protocol::encode(coverage, &bytes).ok());
    push.send(zmq::buffer(bytes), zmq::send_flags::none);
    zmq::socket_t dealer(ctx, zmq::socket_type::dealer);
    dealer.set(zmq::sockopt::linger, 1000);
    dealer.connect("tcp://127.0.0.1:" + std::to_string(port_));
    dealer.send(zmq::buffer(junk), zmq::send_flags::none);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
  ASSERT_TRUE(wait_until(
      [&] {
        const auto st = get_stats(metrics_port());
        return !st.is_null() && st["display"]["rejected_sample_messages"].get<int>() >= 11 &&
               st["display"]["rejected_control_messages"].get<int>() >= 1;
      },
      3.0))
      << d->log();
  const uint64_t samples = get_stats(metrics_port())["samplers"][0]["samples"].get<uint64_t>();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
  EXPECT_GT(get_stats(metrics_port())["samplers"][0]["samples"].get<uint64_t>(), samples);
  EXPECT_NE(get_text(metrics_port(), "/metrics").find("afr_display_frames_total"),
            std::string::npos);
  EXPECT_NE(d->log().find("rejected wall_coverage from node 2"), std::string::npos) << d->log();
  EXPECT_EQ(get_stats(metrics_port())["display"]["wall"]["exchange"]["coverage_in"].get<int>(), 0);
}

TEST_F(ServiceTest, SamplerOfAnotherProtocolVersionIsToldWhyAndTheOthersKeepServing) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();

  // A join of this build, its header's version changed to one the display does not speak.
  protocol::Join join;
  join.name = "from-the-future";
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(protocol::encode(join, &bytes).ok());
  const uint16_t other = protocol::kProtocolVersion + 1;
  bytes[4] = uint8_t(other);
  bytes[5] = uint8_t(other >> 8);
  zmq::context_t ctx;
  zmq::socket_t dealer(ctx, zmq::socket_type::dealer);
  dealer.set(zmq::sockopt::linger, 0);
  dealer.set(zmq::sockopt::rcvtimeo, 3000);
  dealer.connect(endpoint());
  dealer.send(zmq::buffer(bytes), zmq::send_flags::none);
  zmq::message_t reply;
  ASSERT_TRUE(dealer.recv(reply, zmq::recv_flags::none)) << d->log();
  const auto m = protocol::decode_message(
      protocol::Bytes(static_cast<const uint8_t*>(reply.data()), reply.size()));
  ASSERT_TRUE(m.ok()) << m.error();
  const auto* leave = std::get_if<protocol::Leave>(&m.value());
  ASSERT_NE(leave, nullptr);
  EXPECT_EQ(leave->reason, protocol::LeaveReason::kVersionMismatch);
  EXPECT_NE(leave->text.find("version " + std::to_string(protocol::kProtocolVersion)),
            std::string::npos);
  EXPECT_NE(d->log().find("unsupported protocol version " + std::to_string(other)),
            std::string::npos)
      << d->log();
  // The sampler of this version keeps streaming.
  const uint64_t samples = get_stats(metrics_port())["samplers"][0]["samples"].get<uint64_t>();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
  EXPECT_GT(get_stats(metrics_port())["samplers"][0]["samples"].get<uint64_t>(), samples);
}

TEST_F(ServiceTest, SamplerFlagOutOfRangeIsNamedAndTheDisplayKeepsServing) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  auto bad = sampler({"--kappa", "2"}, "bad.log");
  EXPECT_NE(bad->wait(10.0), 0);
  EXPECT_NE(bad->log().find("kappa = 2 is outside [0, 1]"), std::string::npos) << bad->log();
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
}

TEST_F(ServiceTest, MissingAndBrokenSceneFilesAreNamed) {
  const std::string broken = path("broken.gltf");
  std::ofstream(broken) << R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":64)";
  auto missing = display({path("no-such-scene.gltf"), "--seconds", "1"}, "missing.log");
  EXPECT_NE(missing->wait(10.0), 0);
  EXPECT_NE(missing->log().find("no-such-scene.gltf"), std::string::npos) << missing->log();
  auto truncated = display({broken, "--seconds", "1"}, "broken.log");
  EXPECT_NE(truncated->wait(10.0), 0);
  EXPECT_NE(truncated->log().find("broken.gltf: invalid glTF"), std::string::npos)
      << truncated->log();
}

TEST_F(ServiceTest, UnreachableDisplayIsReportedAndTheSamplerKeepsTrying) {
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_until(
      [&] { return s->log().find("no answer from the display") != std::string::npos; }, 10.0))
      << s->log();
  EXPECT_TRUE(s->alive());
  // The display comes up late: the sampler joins it.
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  EXPECT_TRUE(wait_members(1, 15.0)) << d->log() << s->log();
}

TEST_F(ServiceTest, NonLoopbackBindWithoutKeysIsRefused) {
  auto d =
      std::make_unique<Process>(std::vector<std::string>{kDisplay, "--headless", "--bind",
                                                         "tcp://0.0.0.0:" + std::to_string(port_)},
                                path("display.log"));
  EXPECT_EQ(d->wait(10.0), 1);
  EXPECT_NE(d->log().find("reachable from other machines"), std::string::npos) << d->log();
}

TEST_F(ServiceTest, SamplerFlagsGivenExplicitlyWinOverTheDisplaysPreset) {
  // The display names the fast preset (r = 2, chunk 100); the sampler is given --b 1 and
  // --chunk 50 and keeps those, taking the rest (r) from the preset.
  auto d = display({"--size", "64x64", "--preset", "fast"}, "display.log");
  auto s = sampler({"--b", "1", "--chunk", "50", "--max-samples-per-second", "20000"}, "s.log");
  ASSERT_TRUE(wait_until([&] { return s->log().find("sampler knobs:") != std::string::npos; }, 5.0))
      << s->log();
  const std::string log = s->log();
  EXPECT_NE(log.find("preset fast, b = 1, r = 2, chunk = 50"), std::string::npos) << log;
}

TEST_F(ServiceTest, InteractiveCameraWithoutAWindowIsRefusedWithTheReason) {
  auto d = display({"--interactive"}, "display.log");  // the fixture runs --headless
  EXPECT_EQ(d->wait(10.0), 1);
  EXPECT_NE(d->log().find("--interactive needs a window"), std::string::npos) << d->log();
}

}  // namespace
}  // namespace afr::testing
