// sampler_node as a service: back after its display restarts, bounded memory while the display
// stalls, an unreachable display reported, flags checked and winning over the display's preset,
// a scene that does not load told to the display, a large scene that keeps membership.
#include "service_fixture.h"

#include <afr/common/gltf_pack.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/scene_hash.h>

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <optional>

namespace afr::testing {
namespace {

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
  // the other sampler filled. After the restart the sampler kept it (same hash), and its BVHs:
  // the new session's pool shares them.
  for (const auto* s : {s1.get(), s2.get()}) {
    // A pool in each session.
    EXPECT_TRUE(wait_until([&] { return count_of(s->log(), "sampling region") >= 2; }, 5.0))
        << s->log();
    const std::string log = s->log();
    EXPECT_EQ(count_of(log, "scene received") + count_of(log, "found in the cache"), 1u) << log;
    EXPECT_EQ(count_of(log, "BVHs built"), 1u) << log;
  }
}

TEST_F(ServiceTest, StalledDisplayKeepsSamplerMemoryBoundedAndCountsDrops) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  // The most the sampler's RSS rises over 3 s from `from`.
  const auto rise_over_3s = [&](long from) {
    long most = from;
    for (int i = 0; i < 30; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      most = std::max(most, s->rss_kb());
    }
    return most - from;
  };
  // An allocator may keep freed memory for a while whether or not the display reads (ASan's
  // quarantine holds up to 256 MB of it): the stall is charged only what it adds to the rise of
  // the same sampler over as long unstalled, just before.
  const long unstalled = rise_over_3s(s->rss_kb());
  const long rss0 = s->rss_kb();
  d->signal(SIGSTOP);  // the display stops reading: its socket buffers and queues fill
  const long stalled = rise_over_3s(rss0);
  d->signal(SIGCONT);
  std::printf(
      "sampler RSS %ld kB before the stall; it rose %ld kB in 3 s of it, %ld kB in 3 s "
      "unstalled\n",
      rss0, stalled, unstalled);
  EXPECT_LT(stalled - unstalled, 64 * 1024) << "sampler memory grew while the display was stalled";
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

TEST_F(ServiceTest, SamplerFlagOutOfRangeIsNamedAndTheDisplayKeepsServing) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(wait_members(1, 5.0)) << d->log();
  auto bad = sampler({"--kappa", "2"}, "bad.log");
  EXPECT_NE(bad->wait(10.0), 0);
  EXPECT_NE(bad->log().find("kappa = 2 is outside [0, 1]"), std::string::npos) << bad->log();
  auto unknown = sampler({"--crosshair-motion", "sideways"}, "unknown.log");
  EXPECT_NE(unknown->wait(10.0), 0);
  EXPECT_NE(unknown->log().find("--crosshair-motion: Check sideways"), std::string::npos)
      << unknown->log();
  EXPECT_EQ(members(get_stats(metrics_port())), 1);
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

// A display played by the test serves bytes that are no scene: the sampler tells it why in a
// leave (the protocol's kError) and exits 3, instead of staying a member that sends nothing.
TEST_F(ServiceTest, SamplerThatCannotLoadTheSceneTellsTheDisplayWhyAndLeaves) {
  using namespace protocol;
  Context context;
  ControlServer server(context, endpoint());
  const std::string text = "not a scene at all";
  const std::vector<uint8_t> scene(text.begin(), text.end());
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  std::optional<Leave> leave;
  uint64_t beat = 0;
  std::string peer;
  auto last_beat = std::chrono::steady_clock::now();
  wait_until(
      [&] {
        while (auto in = server.receive(10)) {
          if (!in->message.ok()) continue;
          const Message& m = in->message.value();
          if (std::holds_alternative<Join>(m)) {
            peer = in->peer;
            Welcome w;
            w.sampler_id = 1;
            w.session = 42;
            w.token = 7;
            w.image = ImageExtent{64, 64};
            w.refresh_interval = 1.0 / 30.0;
            w.scene_hash = scene_hash(scene);
            w.scene_size = scene.size();
            w.scene_name = "garbage.glb";
            (void)server.send(in->peer, w);
          } else if (const auto* r = std::get_if<SceneRequest>(&m)) {
            SceneChunk c;
            c.scene_hash = r->scene_hash;
            c.scene_size = scene.size();
            c.count = 1;
            c.bytes = scene;
            (void)server.send(in->peer, c);
          } else if (const auto* l = std::get_if<Leave>(&m)) {
            leave = *l;
          }
        }
        if (!peer.empty() && seconds_since(last_beat) > 0.15) {
          (void)server.send(peer, Heartbeat{1, 42, beat++, 0.0});
          last_beat = std::chrono::steady_clock::now();
        }
        return leave.has_value();
      },
      10.0);
  ASSERT_TRUE(leave.has_value()) << s->log();
  EXPECT_EQ(leave->reason, LeaveReason::kError);
  EXPECT_EQ(leave->sampler_id, 1u);
  EXPECT_NE(leave->text.find("cannot load the display's scene garbage.glb: "), std::string::npos)
      << leave->text;
  EXPECT_EQ(s->wait(10.0), 3) << s->log();
  EXPECT_NE(s->log().find("leaving the display"), std::string::npos) << s->log();
}

// A scene of about 50 MB (most of it a buffer no mesh reads, so the tracers' BVH stays small
// on a loaded test machine): while it travels, is hashed, cached and loaded, the samplers keep
// sending heartbeats, so the display never loses them and they join once.
TEST_F(ServiceTest, LargeSceneKeepsMembershipWhileItTravelsAndLoads) {
  const int n = 100;  // n x n quads
  std::vector<float> positions;
  std::vector<uint32_t> indices;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      positions.insert(positions.end(), {float(i) / n - 0.5f, 0.0f, float(j) / n - 0.5f});
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i);
      indices.insert(indices.end(), {a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2});
    }
  }
  const size_t pos_bytes = positions.size() * 4, index_bytes = indices.size() * 4;
  const size_t filler = size_t(50) << 20;
  std::vector<uint8_t> bin(pos_bytes + index_bytes + filler);
  std::memcpy(bin.data(), positions.data(), pos_bytes);
  std::memcpy(bin.data() + pos_bytes, indices.data(), index_bytes);
  for (size_t k = 0; k < filler; ++k)
    bin[pos_bytes + index_bytes + k] = uint8_t(k * 2654435761u >> 24);
  const nlohmann::json doc = {
      {"asset", {{"version", "2.0"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0, 1}}}}},
      {"nodes",
       {{{"mesh", 0}},
        {{"camera", 0},
         {"translation", {0, 1.2, 1.2}},
         {"rotation", {-0.3826834, 0, 0, 0.9238795}}}}},
      {"cameras", {{{"type", "perspective"}, {"perspective", {{"yfov", 0.9}, {"znear", 0.05}}}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"indices", 1}}}}}}},
      {"accessors",
       {{{"bufferView", 0},
         {"componentType", 5126},
         {"count", (n + 1) * (n + 1)},
         {"type", "VEC3"},
         {"min", {-0.5, 0, -0.5}},
         {"max", {0.5, 0, 0.5}}},
        {{"bufferView", 1},
         {"componentType", 5125},
         {"count", indices.size()},
         {"type", "SCALAR"}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", pos_bytes}},
        {{"buffer", 0}, {"byteOffset", pos_bytes}, {"byteLength", index_bytes}},
        {{"buffer", 0}, {"byteOffset", pos_bytes + index_bytes}, {"byteLength", filler}}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
  };
  const std::vector<uint8_t> glb = make_glb(doc.dump(), bin);
  std::ofstream(path("large.glb"), std::ios::binary)
      .write(reinterpret_cast<const char*>(glb.data()), std::streamsize(glb.size()));

  auto d = display({path("large.glb"), "--size", "64x64", "--fps", "20"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  auto s2 = sampler({"--max-samples-per-second", "50000"}, "s2.log");
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(metrics_port());
        if (members(st) != 2) return false;
        for (const auto& m : st["samplers"]) {
          if (m["member"].get<bool>() && m["samples"].get<uint64_t>() == 0) return false;
        }
        return true;
      },
      30.0))
      << d->log() << s1->log() << s2->log();
  EXPECT_EQ(d->log().find(" lost: "), std::string::npos) << d->log();
  for (const auto* s : {s1.get(), s2.get()}) {
    const std::string log = s->log();
    EXPECT_EQ(count_of(log, "joined the display as sampler"), 1u) << log;
    EXPECT_NE(log.find("loaded in"), std::string::npos) << log;
  }
}

}  // namespace
}  // namespace afr::testing
