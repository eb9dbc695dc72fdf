// display_node against peers that lie (issue 19): a join that claims the largest thread count,
// the id next to the top of the range and an absurd sample rate, and sends no samples; batches
// that name a real sampler's id or an id nobody holds. Real sampler_node processes beside them
// keep their regions and their samples. The exact rules are tested on the coordinator and the
// ingest alone (coordinator_test.cpp, member_gate_test.cpp); these check the display as run.
#include "service_fixture.h"
#include "support/promtool.h"

#include <afr/protocol/channels.h>

#include <gtest/gtest.h>
#include <zmq.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

namespace afr::testing {
namespace {

using namespace protocol;

// A client that joins with whatever it claims, then heartbeats (so it stays a member) and sends
// stats, on a thread of its own, until destroyed. It never sends a sample.
class LyingMember {
 public:
  LyingMember(const std::string& endpoint, Join join, double claimed_rate)
      : thread_([this, endpoint, join, claimed_rate] { run(endpoint, join, claimed_rate); }) {}
  ~LyingMember() {
    running_ = false;
    thread_.join();
  }
  std::optional<Welcome> welcome() {
    std::lock_guard<std::mutex> lock(mutex_);
    return welcome_;
  }

 private:
  void run(const std::string& endpoint, const Join& join, double claimed_rate) {
    Context context;
    ControlClient client(context, endpoint);
    (void)client.send(join);
    uint64_t beat = 0;
    auto last = std::chrono::steady_clock::now() - std::chrono::seconds(1);
    while (running_) {
      while (auto m = client.receive(10)) {
        if (m->ok() && std::holds_alternative<Welcome>(m->value())) {
          std::lock_guard<std::mutex> lock(mutex_);
          welcome_ = std::get<Welcome>(m->value());
        }
      }
      const std::optional<Welcome> w = welcome();
      if (!w || seconds_since(last) < 0.15) continue;
      last = std::chrono::steady_clock::now();
      (void)client.send(Heartbeat{w->sampler_id, w->session, beat++, 0.0});
      SamplerStats s;
      s.sampler_id = w->sampler_id;
      s.samples = 1ull << 60;
      s.samples_per_second = claimed_rate;
      s.rays_per_second = claimed_rate;
      s.threads = kMaxThreads;
      (void)client.send(s);
    }
  }

  std::atomic<bool> running_{true};
  std::mutex mutex_;
  std::optional<Welcome> welcome_;
  std::thread thread_;  // last: starts once the rest is built
};

struct MemberView {
  uint32_t id = 0;
  std::string name;
  int64_t area = 0;
  bool starved = false;
  uint64_t samples = 0;
  uint64_t gaps = 0;
};

std::vector<MemberView> member_views(const nlohmann::json& st) {
  std::vector<MemberView> out;
  if (st.is_null() || st.is_discarded()) return out;
  for (const auto& m : st["samplers"]) {
    if (!m["member"].get<bool>()) continue;
    const auto r = m["region"].get<std::array<int, 4>>();
    out.push_back(MemberView{m["id"].get<uint32_t>(), m["name"].get<std::string>(),
                             int64_t(r[2] - r[0]) * (r[3] - r[1]), m["starved"].get<bool>(),
                             m["samples"].get<uint64_t>(), m["sequence_gaps"].get<uint64_t>()});
  }
  return out;
}

// Whether /stats on `port` lists n members, each with samples, within 10 s.
bool members_streaming(int port, size_t n) {
  return wait_until(
      [&] {
        const std::vector<MemberView> ms = member_views(get_stats(port));
        return ms.size() == n &&
               std::all_of(ms.begin(), ms.end(), [](const MemberView& m) { return m.samples > 0; });
      },
      10.0);
}

// The n members keep streaming over their regions: 0.8 s on, each has more samples, an area
// and no sequence gaps.
void expect_members_keep_streaming(int port, size_t n) {
  const std::vector<MemberView> before = member_views(get_stats(port));
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  const std::vector<MemberView> after = member_views(get_stats(port));
  ASSERT_EQ(before.size(), n);
  ASSERT_EQ(after.size(), n);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_GT(after[i].samples, before[i].samples) << after[i].name;
    EXPECT_GT(after[i].area, 0) << after[i].name;
    EXPECT_EQ(after[i].gaps, 0u) << after[i].name;
  }
}

// A raw control connection to the display at `port` that queues what it is given without bound
// (a flood) and delivers it before it closes.
zmq::socket_t raw_control(zmq::context_t& context, int port) {
  zmq::socket_t dealer(context, zmq::socket_type::dealer);
  dealer.set(zmq::sockopt::linger, 5000);
  dealer.set(zmq::sockopt::sndhwm, 0);
  dealer.connect("tcp://127.0.0.1:" + std::to_string(port));
  return dealer;
}

// The greedy join of issue 19 (4096 threads, 1e300 samples/s in its stats, id 0xFFFFFFFE asked
// for, no sample ever) joins beside a real sampler, and a second real sampler joins after it.
// The display assigns the ids (distinct, none at the top of the range), nobody is evicted,
// membership stays as it is, and the liar's region shrinks to a strip about starve_seconds
// after it got one (a join waits for its cut up to --join-interval) while the real samplers
// share the image.
TEST_F(ServiceTest, GreedyJoinGetsNoRegionAndLaterSamplersGetDistinctIds) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "30000", "--name", "real-1"}, "s1.log");
  ASSERT_TRUE(members_streaming(metrics_port(), 1)) << d->log();
  Join greedy;
  greedy.sampler_id = 0xFFFFFFFEu;
  greedy.threads = kMaxThreads;
  greedy.name = "greedy";
  LyingMember liar(endpoint(), greedy, 1e300);
  ASSERT_TRUE(wait_until([&] { return liar.welcome().has_value(); }, 5.0)) << d->log();
  const uint32_t liar_id = liar.welcome()->sampler_id;
  EXPECT_NE(liar_id, 0xFFFFFFFEu);  // a proposal, not followed
  auto s2 = sampler({"--max-samples-per-second", "30000", "--name", "real-2"}, "s2.log");
  ASSERT_TRUE(wait_members(3, 10.0)) << d->log();

  const bool settled = wait_until(
      [&] {
        const std::vector<MemberView> ms = member_views(get_stats(metrics_port()));
        if (ms.size() != 3) return false;
        int64_t real = 0, lied = 0;
        bool starved = false;
        for (const MemberView& m : ms) {
          (m.id == liar_id ? lied : real) += m.area;
          if (m.id == liar_id) starved = m.starved;
        }
        return starved && lied * 50 <= 64 * 64 && real + lied == 64 * 64;
      },
      15.0);
  ASSERT_TRUE(settled) << d->log();
  // Distinct ids, none at the top of the range; the claimed rate is shown, not believed.
  const nlohmann::json st = get_stats(metrics_port());
  std::set<uint32_t> ids;
  for (const MemberView& m : member_views(st)) ids.insert(m.id);
  EXPECT_EQ(ids.size(), 3u);
  EXPECT_EQ(ids.count(0xFFFFFFFFu) + ids.count(0xFFFFFFFEu), 0u);
  for (const auto& m : st["samplers"]) {
    if (m["id"].get<uint32_t>() == liar_id) {
      EXPECT_EQ(m["reported_samples_per_second"].get<double>(), 1e300);
      EXPECT_TRUE(m["starved"].get<bool>());
    }
  }
  // How long the liar held more than a strip: from its join to the display's "starved" line
  // (the rule is starve_seconds, 0.75 s; the bound only catches a rule that does not work).
  const std::string log = d->log();
  const double joined = log_time(log, "joined: greedy");
  const double starved = log_time(log, "(greedy) starved: no samples from it");
  ASSERT_GE(joined, 0.0) << log;
  ASSERT_GE(starved, 0.0) << log;
  std::printf("greedy member starved %.3f s after it joined\n", seconds_between(joined, starved));
  EXPECT_LT(seconds_between(joined, starved), scaled(3.0)) << log;

  // Membership holds still: nobody evicted, nobody joining again.
  std::this_thread::sleep_for(std::chrono::seconds(2));
  EXPECT_EQ(members(get_stats(metrics_port())), 3) << d->log();
  EXPECT_EQ(count_of(d->log(), " joined: "), 3u) << d->log();
  EXPECT_EQ(d->log().find(" lost: "), std::string::npos) << d->log();
  for (const auto* s : {s1.get(), s2.get()}) {
    EXPECT_EQ(count_of(s->log(), "joined the display as sampler"), 1u) << s->log();
  }
}

// Batches naming the real sampler's id (with a guessed token) and batches under an id nobody
// holds: dropped, counted by cause in /stats and /metrics, logged once per cause a second; the
// real sampler's figures are untouched (before, a spoofed sequence number made its gap counter
// jump by 7e14) and it keeps streaming.
TEST_F(ServiceTest, SpoofedAndNonMemberBatchesAreDroppedAndCounted) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s = sampler({"--max-samples-per-second", "50000"}, "s1.log");
  ASSERT_TRUE(members_streaming(metrics_port(), 1)) << d->log();
  const uint32_t real_id = member_views(get_stats(metrics_port()))[0].id;
  // Kept until the display has counted everything: closing a sender drops what ZeroMQ has not
  // yet written (ZMQ_LINGER 0 on the sample channel).
  Context context;
  SampleSender hostile(context, service_endpoints(endpoint()).samples);
  for (uint64_t k = 0; k < 200; ++k) {
    SampleBatch b;
    b.sampler_id = k % 2 ? real_id : 4242;
    b.token = 0x0123456789abcdefull + k;
    b.sequence = 0x7000000000000000ull + k;
    b.samples.resize(64);
    for (Sample& x : b.samples) {
      x.time = 1.0;
      x.x = x.y = 1.5f;
      x.color = glm::vec3(1e4f);  // would show as a white smear where the real one samples
    }
    ASSERT_TRUE(hostile.send(b, {64, 64}).ok());
    ASSERT_TRUE(hostile.flush(5000));
  }
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(metrics_port());
        return !st.is_null() && st["display"]["spoofed_batches"].get<int>() == 100 &&
               st["display"]["unknown_sampler_batches"].get<int>() == 100;
      },
      10.0))
      << d->log();
  const nlohmann::json st = get_stats(metrics_port());
  EXPECT_EQ(st["display"]["spoofed_samples"].get<int>(), 6400);
  EXPECT_EQ(st["display"]["unknown_sampler_samples"].get<int>(), 6400);
  const std::string metrics = get_text(metrics_port(), "/metrics");
  EXPECT_NE(metrics.find("afr_display_dropped_batches_total{cause=\"spoofed\"} 100"),
            std::string::npos);
  EXPECT_NE(metrics.find("afr_display_dropped_batches_total{cause=\"non_member\"} 100"),
            std::string::npos);
  // The live exposition, hostile traffic counted in it, follows Prometheus' conventions.
  if (const auto verdict = testing::promtool_check_metrics(metrics)) {
    EXPECT_EQ(verdict->status, 0) << verdict->output;
    EXPECT_EQ(verdict->output, "");
  }
  const std::string log = d->log();
  EXPECT_NE(log.find("naming a member without its token or key"), std::string::npos) << log;
  EXPECT_NE(log.find("from no member"), std::string::npos) << log;
  // A second of 200 bad batches makes a few lines, not 200.
  EXPECT_LE(count_of(log, "sample channel: dropped"), 10u) << log;
  const std::vector<MemberView> ms = member_views(st);
  ASSERT_EQ(ms.size(), 1u);
  EXPECT_EQ(ms[0].id, real_id);
  EXPECT_LT(ms[0].gaps, 1000u);  // its own sequence only
  const uint64_t samples = ms[0].samples;
  EXPECT_TRUE(wait_until(
      [&] {
        const std::vector<MemberView> now = member_views(get_stats(metrics_port()));
        return now.size() == 1 && now[0].samples > samples;
      },
      5.0));
}

// A display that admits two samplers (--max-samplers 2) refuses a third join with the reason;
// a flood of malformed control messages of two kinds costs at most a log line per kind a second,
// each with its count; the real samplers keep their regions and keep streaming.
TEST_F(ServiceTest, ControlFloodAndJoinsBeyondTheLimitCostALineASecondAndNoMember) {
  auto d = display({"--size", "64x64", "--fps", "20", "--max-samplers", "2"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "30000", "--name", "real-1"}, "s1.log");
  auto s2 = sampler({"--max-samples-per-second", "30000", "--name", "real-2"}, "s2.log");
  ASSERT_TRUE(members_streaming(metrics_port(), 2)) << d->log();

  {
    Context context;
    ControlClient third(context, endpoint());
    Join join;
    join.name = "third";
    ASSERT_TRUE(third.send(join).ok());
    std::optional<Leave> refused;
    ASSERT_TRUE(wait_until(
        [&] {
          while (auto m = third.receive(10)) {
            if (m->ok() && std::holds_alternative<Leave>(m->value())) {
              refused = std::get<Leave>(m->value());
            }
          }
          return refused.has_value();
        },
        5.0))
        << d->log();
    EXPECT_EQ(refused->reason, LeaveReason::kRefused);
    EXPECT_NE(refused->text.find("at most 2 samplers"), std::string::npos) << refused->text;
  }

  // 20000 malformed messages: half too short for a header, half of the wrong magic.
  const auto started = std::chrono::steady_clock::now();
  constexpr int kFlood = 20000;
  {
    zmq::context_t ctx;
    zmq::socket_t dealer = raw_control(ctx, port_);
    const std::string short_junk = "xy", wrong_magic(64, 'J');
    for (int i = 0; i < kFlood; ++i) {
      const std::string& junk = i % 2 ? short_junk : wrong_magic;
      dealer.send(zmq::buffer(junk), zmq::send_flags::none);
    }
  }
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(metrics_port());
        return !st.is_null() && st["display"]["rejected_control_messages"].get<int>() >= kFlood;
      },
      20.0))
      << d->log();
  // Every malformed message is accounted for in the log: the lines of each kind, what they
  // held back included (logged once their second has passed), add up to the messages sent.
  const auto logged = [&](const std::string& kind) {
    uint64_t total = 0;
    std::istringstream in(d->log());
    for (std::string line; std::getline(in, line);) {
      if (line.find(kind) == std::string::npos) continue;
      for (const char* lead : {"control: rejected ", "control: "}) {
        const size_t at = line.find(lead);
        if (at == std::string::npos) continue;
        const char* digits = line.c_str() + at + std::strlen(lead);
        if (*digits >= '0' && *digits <= '9') {
          total += std::strtoull(digits, nullptr, 10);
          break;
        }
      }
    }
    return total;
  };
  EXPECT_TRUE(wait_until(
      [&] { return logged("wrong magic") == kFlood / 2 && logged("shorter than") == kFlood / 2; },
      10.0))
      << "logged " << logged("wrong magic") << " and " << logged("shorter than") << "\n"
      << d->log();
  const double seconds = seconds_since(started);
  const std::string log = d->log();
  const size_t lines = count_of(log, "control: ");
  std::printf("%d malformed control messages in %.2f s: %zu log lines\n", kFlood, seconds, lines);
  // At most a line per kind per second, and the first line of each.
  EXPECT_LE(double(lines), 2.0 * (seconds + 1.0)) << log;
  EXPECT_NE(log.find("sampler join(s) refused"), std::string::npos) << log;

  // The real samplers: still the two members, still streaming, nobody lost.
  expect_members_keep_streaming(metrics_port(), 2);
  EXPECT_EQ(log.find(" lost: "), std::string::npos) << log;
}

// A peer that joins and leaves in a loop (a member's leave needs no reply to wait for) makes
// each join a member and each leave a departure: the display's log takes at most 32 of these
// lines a second plus a line summing up the rest, /stats keeps the members and at most 64
// departed samplers, and the real sampler keeps streaming.
TEST_F(ServiceTest, JoiningAndLeavingInALoopCostsBoundedRecutsLogLinesAndFigures) {
  auto d = display({"--size", "64x64", "--fps", "20"}, "display.log");
  auto s1 = sampler({"--max-samples-per-second", "30000", "--name", "real-1"}, "s1.log");
  ASSERT_TRUE(members_streaming(metrics_port(), 1)) << d->log();
  const auto started = std::chrono::steady_clock::now();
  const int recuts_before = get_stats(metrics_port())["display"]["recuts"].get<int>();
  constexpr int kCycles = 3000;
  {
    Join join;
    join.name = "churn";
    std::vector<uint8_t> join_bytes, leave_bytes;
    ASSERT_TRUE(encode(Message(join), &join_bytes).ok());
    ASSERT_TRUE(encode(Message(Leave{0, LeaveReason::kShutdown, "again"}), &leave_bytes).ok());
    zmq::context_t ctx;
    zmq::socket_t dealer = raw_control(ctx, port_);
    for (int i = 0; i < kCycles; ++i) {
      dealer.send(zmq::buffer(join_bytes), zmq::send_flags::none);
      dealer.send(zmq::buffer(leave_bytes), zmq::send_flags::none);
    }
    ASSERT_TRUE(wait_until(
        [&] {
          const nlohmann::json st = get_stats(metrics_port());
          return !st.is_null() && st["display"]["leaves"].get<int>() >= kCycles;
        },
        60.0))
        << d->log();
  }
  // Then a peer that waits for its region each time before it leaves, for 4 s.
  int regions_got = 0;
  {
    Context context;
    ControlClient client(context, endpoint());
    Join join;
    join.name = "patient churn";
    const auto phase = std::chrono::steady_clock::now();
    while (seconds_since(phase) < 4.0) {
      ASSERT_TRUE(client.send(join).ok());
      std::optional<RegionAssignment> region;
      std::optional<Welcome> welcome;
      auto beat = std::chrono::steady_clock::now();
      const auto asked = std::chrono::steady_clock::now();
      while (!region && seconds_since(asked) < 10.0) {
        if (auto m = client.receive(10); m && m->ok()) {
          if (const auto* r = std::get_if<RegionAssignment>(&m->value())) region = *r;
          if (const auto* w = std::get_if<Welcome>(&m->value())) welcome = *w;
        }
        if (welcome && seconds_since(beat) > 0.1) {  // a member heartbeats while it waits
          beat = std::chrono::steady_clock::now();
          ASSERT_TRUE(client.send(Heartbeat{welcome->sampler_id, welcome->session, 0, 0.0}).ok());
        }
      }
      ASSERT_TRUE(region.has_value()) << d->log();
      ++regions_got;
      ASSERT_TRUE(client.send(Leave{region->sampler_id, LeaveReason::kShutdown, "again"}).ok());
    }
  }
  const double seconds = seconds_since(started);
  std::printf("the patient peer got %d regions\n", regions_got);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the last summing-up line
  const std::string log = d->log();
  const size_t lines =
      count_of(log, " joined: ") + count_of(log, ") left: ") + count_of(log, "region epoch");
  std::printf("%d joins and leaves in %.2f s: %zu membership lines\n", kCycles, seconds, lines);
  EXPECT_LE(double(lines), 32.0 * (seconds + 3.0)) << log.substr(0, 4000);
  EXPECT_NE(log.find("more sampler joins, leaves and regions than the log shows"),
            std::string::npos);
  const nlohmann::json st = get_stats(metrics_port());
  EXPECT_LE(st["samplers"].size(), 1u + 64u);
  EXPECT_GE(st["display"]["joins"].get<int>(), kCycles + 1 + regions_got);
  // Joins are cut in at most once a second (--join-interval) and a peer that left before its
  // cut leaves nothing to recut: the real sampler's region moved at most twice a second (the
  // patient peer's join and leave).
  const int recuts = st["display"]["recuts"].get<int>() - recuts_before;
  std::printf("%d recuts\n", recuts);
  EXPECT_LE(double(recuts), 2.0 * (seconds + 3.0));
  // The real sampler: still the one member, still streaming.
  expect_members_keep_streaming(metrics_port(), 1);
}

}  // namespace
}  // namespace afr::testing
