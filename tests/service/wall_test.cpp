// Multi-process tests of the display wall on loopback (docs/wall.md): a lead display_node with
// a 2 x 2 grid, three follower display_nodes, two sampler_nodes; observed through each node's
// /stats, logs and images.
#include "process.h"

#include <afr/bench/ideal_renderer.h>
#include <afr/common/builtin_scene.h>
#include <afr/common/image.h>
#include <afr/common/rect.h>
#include <afr/protocol/channels.h>
#include <afr/protocol/keys.h>
#include <afr/sampler/tracer.h>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <utility>

namespace afr::testing {
namespace {

namespace fs = std::filesystem;

const std::string kDisplay = AFR_DISPLAY_NODE;
const std::string kSampler = AFR_SAMPLER_NODE;

class WallTest : public ProcessTest {
 protected:
  WallTest() : ProcessTest("afr-wall-") {}

  std::unique_ptr<Process> lead(std::vector<std::string> extra,
                                const std::string& size = "128x128") {
    std::vector<std::string> argv = {kDisplay,
                                     "--headless",
                                     "--bind",
                                     endpoint(port_),
                                     "--metrics-port",
                                     std::to_string(port_ + 3),
                                     "--backend",
                                     "cpu",
                                     "--output",
                                     path("lead"),
                                     "--stats-interval",
                                     "1",
                                     "--size",
                                     size,
                                     "--fps",
                                     "20"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path("lead.log"));
  }
  // A follower for cell (column, row) on a base port of its own (metrics on port + 3).
  std::unique_ptr<Process> follower(int column, int row, int port,
                                    std::vector<std::string> extra = {}) {
    const std::string name = "cell-" + std::to_string(column) + "-" + std::to_string(row);
    std::vector<std::string> argv = {kDisplay,
                                     "--headless",
                                     "--follow",
                                     endpoint(port_),
                                     "--cell",
                                     std::to_string(column) + "," + std::to_string(row),
                                     "--bind",
                                     endpoint(port),
                                     "--metrics-port",
                                     std::to_string(port + 3),
                                     "--backend",
                                     "cpu",
                                     "--output",
                                     path(name),
                                     "--stats-interval",
                                     "1",
                                     "--fps",
                                     "20"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(name + ".log"));
  }
  std::unique_ptr<Process> sampler(const std::string& log, int rate = 40000,
                                   std::vector<std::string> extra = {}) {
    std::vector<std::string> argv = {kSampler,
                                     "--display",
                                     endpoint(port_),
                                     "--cache",
                                     path("cache"),
                                     "--max-samples-per-second",
                                     std::to_string(rate)};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, path(log));
  }
  // Samples a node has received from all samplers (its /stats), -1 when it does not answer.
  static int64_t received(int metrics_port) {
    const nlohmann::json s = get_stats(metrics_port);
    if (s.is_null() || s.is_discarded()) return -1;
    int64_t n = 0;
    for (const auto& m : s["samplers"]) n += m["samples"].get<int64_t>();
    return n;
  }
  // A 2 x 1 wall of 128 x 64: the lead (cell 0,0) and a follower for cell 1,0 on a base port
  // of its own, both admitted.
  void two_by_one_wall(std::unique_ptr<Process>* l, std::unique_ptr<Process>* f, int* port) {
    *l = lead({"--wall", "2x1"}, "128x64");
    ASSERT_TRUE(wait_until([&] { return wall_nodes(port_ + 3) == 1; }, 5.0)) << (*l)->log();
    *port = free_base_port();
    ASSERT_NE(*port, 0);
    *f = follower(1, 0, *port);
    ASSERT_TRUE(wait_until([&] { return wall_nodes(port_ + 3) == 2; }, 5.0)) << (*l)->log();
  }
  // Sends a hostile peer's batch of 32 bright samples inside the follower cell (1,0) of a 128 x
  // 64 wall, naming `sampler_id` with `token`, and waits until it has left.
  static void send_batch(protocol::SampleSender& sender, uint32_t sampler_id, uint64_t token,
                         uint64_t sequence) {
    SampleBatch b;
    b.sampler_id = sampler_id;
    b.token = token;
    b.sequence = sequence;
    b.samples.resize(32);
    for (Sample& x : b.samples) {
      x.time = 1.0;
      x.x = 100.5f;
      x.y = 30.5f;
      x.color = glm::vec3(1e4f);
    }
    const protocol::Status sent = sender.send(b, {128, 64});
    ASSERT_TRUE(sent.ok()) << sent.message();
    ASSERT_TRUE(sender.flush(5000));
  }
  static int wall_nodes(int metrics_port) {
    const nlohmann::json s = get_stats(metrics_port);
    if (s.is_null() || s.is_discarded()) return -1;
    return s["display"]["wall"]["nodes"].get<int>();
  }
};

TEST_F(WallTest, FourNodesEachReceiveTheirCellAndAKilledNodeIsNoticedWithinOneSecond) {
  // A margin of 8 px: each node needs a 72 x 72 part of the 128 x 128 image, so together the
  // four receive about 1.27 x what the samplers send (4 x if every sample went everywhere).
  auto l = lead({"--wall", "2x2", "--margin", "8"});
  const int lead_metrics = port_ + 3;
  ASSERT_TRUE(wait_until([&] { return wall_nodes(lead_metrics) == 1; }, 5.0)) << l->log();
  const int cells[3][2] = {{1, 0}, {0, 1}, {1, 1}};
  int ports[3];
  std::unique_ptr<Process> followers[3];
  for (int i = 0; i < 3; ++i) {
    ports[i] = free_base_port();
    ASSERT_NE(ports[i], 0);
    followers[i] = follower(cells[i][0], cells[i][1], ports[i]);
    ASSERT_TRUE(wait_until([&] { return wall_nodes(ports[i] + 3) >= 0; }, 5.0));
  }
  ASSERT_TRUE(wait_until([&] { return wall_nodes(lead_metrics) == 4; }, 5.0)) << l->log();
  auto s1 = sampler("s1.log");
  auto s2 = sampler("s2.log");
  // Every node receives samples.
  ASSERT_TRUE(wait_until(
      [&] {
        bool all = received(lead_metrics) > 0;
        for (int i = 0; i < 3; ++i) all = all && received(ports[i] + 3) > 0;
        return all;
      },
      scaled(8.0)))
      << l->log() << followers[0]->log() << s1->log();
  std::this_thread::sleep_for(std::chrono::seconds(2));

  // Routing: the samples received over all nodes against those the samplers sent.
  const nlohmann::json lead_stats = get_stats(lead_metrics);
  int64_t sent = 0;
  for (const auto& m : lead_stats["samplers"]) sent += m["reported_samples"].get<int64_t>();
  int64_t total = received(lead_metrics);
  for (int i = 0; i < 3; ++i) total += received(ports[i] + 3);
  const double ratio = double(total) / double(std::max<int64_t>(sent, 1));
  std::printf("samples received by the 4 nodes / sent: %.2f (%lld / %lld)\n", ratio,
              (long long)total, (long long)sent);
  EXPECT_GT(ratio, 0.8);
  EXPECT_LT(ratio, 2.5);
  // The nodes exchange coverage after every image: each received its neighbours' and wrote it
  // into its reconstructor's margin, and sent its own (docs/wall.md, "Seams").
  uint64_t strays = 0;
  for (int port : {lead_metrics, ports[0] + 3, ports[1] + 3, ports[2] + 3}) {
    const nlohmann::json x = get_stats(port)["display"]["wall"]["exchange"];
    SCOPED_TRACE(x.dump());
    EXPECT_GT(x["coverage_in"].get<uint64_t>(), 0u);
    EXPECT_GT(x["coverage_cells_applied"].get<uint64_t>(), 0u);
    EXPECT_GT(x["coverage_out"].get<uint64_t>(), 0u);
    EXPECT_GT(x["bytes_out"].get<uint64_t>(), 0u);
    strays += x["strays_in"].get<uint64_t>();
  }
  std::printf("strays forwarded between the nodes: %llu samples\n", (unsigned long long)strays);
  // Each node's cell, as the lead's layout gives it.
  const nlohmann::json f0 = get_stats(ports[0] + 3);
  EXPECT_EQ(f0["display"]["wall"]["cell"], (nlohmann::json{64, 0, 128, 64}));
  EXPECT_EQ(f0["display"]["wall"]["nodes"].get<int>(), 4);

  // A follower frozen for 0.4 s (SIGSTOP, SIGCONT) is busy, not dead: it stays in the wall.
  for (int i = 0; i < 2; ++i) {
    followers[1]->signal(SIGSTOP);
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    followers[1]->signal(SIGCONT);
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
  }
  EXPECT_EQ(wall_nodes(lead_metrics), 4) << l->log();
  EXPECT_EQ(l->log().find("lost: no word for"), std::string::npos) << l->log();

  // kill -9 of a follower: the lead drops it from the layout within a second (from the kill to
  // the lead's log line), and the others keep receiving.
  followers[2]->signal(SIGKILL);
  const double killed = time_of_day();
  ASSERT_TRUE(wait_until([&] { return wall_nodes(lead_metrics) == 3; }, 3.0, 0.01)) << l->log();
  const double lost = log_time(l->log(), "lost: no word for");
  ASSERT_GE(lost, 0.0) << l->log();
  const double took = seconds_between(killed, lost);
  // Within a second; on a machine whose load spread the heartbeats' arrivals, the failure
  // detector is more patient, and the bound is what it said it would wait (logged).
  const double patience = log_number(l->log(), "lost: no word for", "suspected after ");
  std::printf(
      "display node declared lost %.3f s after kill -9 (suspected after %.3f s of silence)\n", took,
      patience);
  EXPECT_GT(patience, 0.0);
  EXPECT_LT(took, scaled(std::max(1.0, patience + 0.25))) << l->log();
  const int64_t before = received(ports[0] + 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  EXPECT_GT(received(ports[0] + 3), before);
  // The lead's /stats (and its dashboard) list every cell of the grid and who shows it: the
  // killed node's cell is dark.
  const auto cell_nodes = [&] {
    std::map<std::string, uint32_t> out;
    const nlohmann::json st = get_stats(lead_metrics);
    for (const auto& c : st["display"]["wall"]["cells"]) {
      out[c["cell"].dump()] = c["node"].get<uint32_t>();
    }
    return out;
  };
  std::map<std::string, uint32_t> shown = cell_nodes();
  ASSERT_EQ(shown.size(), 4u);
  EXPECT_EQ(shown["[64,64,128,128]"], 0u);
  EXPECT_EQ(shown["[0,0,64,64]"], 1u);
  EXPECT_NE(shown["[64,0,128,64]"], 0u);

  // It comes back on the same cell.
  followers[2] = follower(1, 1, ports[2]);
  ASSERT_TRUE(wait_until([&] { return wall_nodes(lead_metrics) == 4; }, 5.0)) << l->log();
  shown = cell_nodes();
  EXPECT_NE(shown["[64,64,128,128]"], 0u);
  // Until its first image (a follower reconstructs once the lead's layout and views arrive).
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(ports[2] + 3);
        return received(ports[2] + 3) > 0 && !st.is_null() && !st.is_discarded() &&
               st["display"]["frames"].get<uint64_t>() > 0;
      },
      scaled(5.0)))
      << followers[2]->log();

  // Every node writes its cell's image at exit.
  for (auto& f : followers) f->signal(SIGTERM);
  l->signal(SIGTERM);
  EXPECT_EQ(l->wait(10.0), 0) << l->log();
  for (auto& f : followers) EXPECT_EQ(f->wait(10.0), 0) << f->log();
  for (const char* name : {"lead", "cell-1-0", "cell-0-1", "cell-1-1"}) {
    const Image img = read_image(path(std::string(name) + "/final.png"));
    EXPECT_EQ(img.width, 64) << name;
    EXPECT_EQ(img.height, 64) << name;
  }
}

TEST_F(WallTest, FollowersAskingForATakenCellOrANonWallAreRefusedWithTheReason) {
  auto l = lead({"--wall", "2x1"});
  ASSERT_TRUE(wait_until([&] { return wall_nodes(port_ + 3) == 1; }, 5.0)) << l->log();
  // The lead's own cell.
  auto f = follower(0, 0, free_base_port());
  EXPECT_TRUE(wait_until(
      [&] { return l->log().find("is the lead display's own") != std::string::npos; }, 5.0))
      << l->log();
  EXPECT_TRUE(wait_until(
      [&] { return f->log().find("is the lead display's own") != std::string::npos; }, 5.0))
      << f->log();
  // Outside the grid.
  auto g = follower(3, 0, free_base_port());
  EXPECT_TRUE(
      wait_until([&] { return g->log().find("outside the 2x1 wall") != std::string::npos; }, 5.0))
      << g->log();
  // The lead keeps serving: one node, frames going on.
  EXPECT_EQ(wall_nodes(port_ + 3), 1);
  const uint64_t frames = get_stats(port_ + 3)["display"]["frames"].get<uint64_t>();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_GT(get_stats(port_ + 3)["display"]["frames"].get<uint64_t>(), frames);
}

TEST_F(WallTest, CapacityFlagSetsTheSamplesEachNodeKeeps) {
  // Without --capacity a node keeps the preset's samples per pixel of what it receives; with
  // it, exactly that many (a wall of large cells on small machines).
  auto l = lead({"--wall", "2x1", "--capacity", "5000"});
  const int port = free_base_port();
  auto f = follower(1, 0, port);
  const auto capacity = [](int port) -> int64_t {
    const nlohmann::json s = get_stats(port);
    if (s.is_null() || s.is_discarded()) return -1;
    return s["display"]["store_capacity"].get<int64_t>();
  };
  ASSERT_TRUE(wait_until([&] { return capacity(port_ + 3) == 5000; }, 5.0)) << l->log();
  // The follower was not given --capacity: 4 samples per pixel (the lead's balanced preset)
  // of its 64 x 128 cell grown by the 66-pixel margin inside the 128 x 128 image: all of it.
  EXPECT_TRUE(wait_until([&] { return capacity(port + 3) == 4 * 128 * 128; }, 5.0)) << f->log();
}

// The RMS difference of `image` against the part `rect` of `whole`.
double rms_in(const Image& image, const Image& whole, const PixelRect& rect) {
  Image part(rect.width(), rect.height());
  for (int y = 0; y < part.height; ++y) {
    for (int x = 0; x < part.width; ++x) part.at(x, y) = whole.at(rect.x0 + x, rect.y0 + y);
  }
  return rms_error_255(image, part);
}

// A snapshot of a 2 x 1 wall (docs/wall.md, "Snapshots"): the lead asks, over HTTP, for every
// cell's image of one display time; each node writes its cell's image of that time, and the
// cells, stitched, are the image of that moment of a moving scene (the built-in scene's camera
// turns): each cell and the whole are nearer the ideal image of that time than of 0.3 s
// before or after. Before snapshots each node wrote its last image at its own moment.
TEST_F(WallTest, ASnapshotIsEveryCellsImageOfOneMoment) {
  const int lead_metrics = port_ + 3;
  int port = 0;
  std::unique_ptr<Process> l, f;
  ASSERT_NO_FATAL_FAILURE(two_by_one_wall(&l, &f, &port));
  auto s = sampler("s1.log", 150000);
  ASSERT_TRUE(
      wait_until([&] { return received(lead_metrics) > 0 && received(port + 3) > 0; }, scaled(8.0)))
      << l->log() << f->log() << s->log();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));

  httplib::Client client("127.0.0.1", lead_metrics);
  client.set_read_timeout(std::chrono::seconds(5));
  const auto res = client.Post("/snapshot?delay=0.3");
  ASSERT_TRUE(res) << "no answer from POST /snapshot";
  ASSERT_EQ(res->status, 200) << res->body;
  const nlohmann::json ticket = nlohmann::json::parse(res->body);
  const uint64_t id = ticket["id"].get<uint64_t>();
  const double t = ticket["time"].get<double>();
  ASSERT_EQ(ticket["cells"].size(), 2u) << res->body;
  // A second request at once is refused with the reason, not queued without end. (On a machine
  // so loaded that 0.2 s of display time passed between the two requests, the lead may take it:
  // then its time, asked with no delay, says so.)
  const auto again = client.Post("/snapshot?delay=0");
  ASSERT_TRUE(again);
  if (again->status == 200) {
    const double asked_first = t - 0.3;
    EXPECT_GE(nlohmann::json::parse(again->body)["time"].get<double>() - asked_first, 0.2)
        << again->body;
  } else {
    EXPECT_EQ(again->status, 409) << again->body;
    EXPECT_NE(again->body.find("less than 0.2 s ago"), std::string::npos) << again->body;
  }
  // Both nodes say they made the image of that time (after writing it).
  const std::string stem = fmt::format("snapshot_{:06d}", id);
  const std::string made = fmt::format("snapshot {}: the image of t={:.3f}s", id, t);
  ASSERT_TRUE(wait_until(
      [&] {
        return l->log().find(made) != std::string::npos && f->log().find(made) != std::string::npos;
      },
      scaled(5.0)))
      << made << "\n"
      << l->log() << f->log();

  const Image left = read_image(path("lead/" + stem + ".exr"));
  const Image right = read_image(path("cell-1-0/" + stem + ".exr"));
  ASSERT_EQ(left.width, 64);
  ASSERT_EQ(right.width, 64);
  Image whole(128, 64);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      whole.at(x, y) = left.at(x, y);
      whole.at(64 + x, y) = right.at(x, y);
    }
  }
  const Scene scene = make_builtin_scene();
  Tracer tracer(scene);
  const auto ideal = [&](double time) {
    IdealRenderOptions o;
    o.width = 128;
    o.height = 64;
    o.strata = 3;
    o.time = time;
    return render_ideal(tracer, o);
  };
  const Image at = ideal(t), before = ideal(t - 0.3), after = ideal(t + 0.3);
  const PixelRect all{0, 0, 128, 64}, l_cell{0, 0, 64, 64}, r_cell{64, 0, 128, 64};
  std::printf("snapshot of t=%.3f s against the ideal of t-0.3, t, t+0.3: %.1f %.1f %.1f\n", t,
              rms_in(whole, before, all), rms_in(whole, at, all), rms_in(whole, after, all));
  EXPECT_LT(rms_in(whole, at, all), rms_in(whole, before, all));
  EXPECT_LT(rms_in(whole, at, all), rms_in(whole, after, all));
  for (const auto& [image, rect] : {std::pair{&left, l_cell}, std::pair{&right, r_cell}}) {
    EXPECT_LT(rms_in(*image, at, rect), rms_in(*image, before, rect)) << rect.x0;
    EXPECT_LT(rms_in(*image, at, rect), rms_in(*image, after, rect)) << rect.x0;
  }
}

// A follower stores only the batches of the lead's members, with their tokens (member_list):
// batches naming the real sampler with a guessed token, and batches under an id nobody holds,
// sent straight to the follower's sample channel, are dropped and counted by cause, and the
// real sampler's samples keep arriving there. Before, a follower counted every id as a member.
TEST_F(WallTest, AFollowerDropsBatchesThatAreNotFromTheLeadsMembers) {
  const int lead_metrics = port_ + 3;
  int port = 0;
  std::unique_ptr<Process> l, f;
  ASSERT_NO_FATAL_FAILURE(two_by_one_wall(&l, &f, &port));
  auto s = sampler("s1.log");
  ASSERT_TRUE(wait_until([&] { return received(port + 3) > 0; }, scaled(8.0)))
      << l->log() << f->log() << s->log();
  const nlohmann::json lead_stats = get_stats(lead_metrics);
  ASSERT_EQ(lead_stats["samplers"].size(), 1u);
  const uint32_t real_id = lead_stats["samplers"][0]["id"].get<uint32_t>();

  protocol::Context context;
  protocol::SampleSender hostile(context, protocol::service_endpoints(endpoint(port)).samples);
  for (uint64_t k = 0; k < 100; ++k) {
    ASSERT_NO_FATAL_FAILURE(send_batch(hostile, k % 2 ? real_id : 4242, 0x0123456789abcdefull + k,
                                       0x7000000000000000ull + k));
  }
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(port + 3);
        return !st.is_null() && !st.is_discarded() &&
               st["display"]["spoofed_batches"].get<int>() == 50 &&
               st["display"]["unknown_sampler_batches"].get<int>() == 50;
      },
      scaled(10.0)))
      << get_stats(port + 3).dump() << f->log();
  const nlohmann::json st = get_stats(port + 3);
  ASSERT_EQ(st["samplers"].size(), 1u) << st.dump();  // no state for the made-up id
  EXPECT_EQ(st["samplers"][0]["id"].get<uint32_t>(), real_id);
  EXPECT_EQ(st["samplers"][0]["sequence_gaps"].get<uint64_t>(), 0u);
  const int64_t before = received(port + 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_GT(received(port + 3), before);
}

// A member describes only its own pixels at a follower too (the lead's member_list carries the
// regions): a member that sends the follower a tiling snapshot naming the whole 128 x 64 image,
// its tiles over every pixel, has kept of it only what lies in a region the lead gave it
// (/stats tiled_pixels). Before, a follower took it as it came: 8192 pixels, shaping the filter
// over the other members' regions.
TEST_F(WallTest, AFollowerCutsAMembersSnapshotToItsRegion) {
  int port = 0;
  std::unique_ptr<Process> l, f;
  ASSERT_NO_FATAL_FAILURE(two_by_one_wall(&l, &f, &port));
  auto s = sampler("s1.log");  // a real member beside it: the raw member's region is a share
  ASSERT_TRUE(wait_until([&] { return received(port + 3) > 0; }, scaled(8.0)))
      << l->log() << f->log() << s->log();

  protocol::Context context;
  protocol::ControlClient control(context, endpoint(port_));
  protocol::SampleSender to_follower(context, protocol::service_endpoints(endpoint(port)).samples);
  protocol::Join join;
  join.name = "raw member";
  ASSERT_TRUE(control.send(join).ok());
  std::optional<protocol::Welcome> welcome;
  int64_t largest_region = 0;
  int64_t kept = 0;
  auto beat = std::chrono::steady_clock::now(), sent = beat;
  const auto started = beat;
  while (kept == 0 && seconds_since(started) < scaled(10.0)) {
    if (auto m = control.receive(10); m && m->ok()) {
      if (const auto* w = std::get_if<protocol::Welcome>(&m->value())) welcome = *w;
      if (const auto* r = std::get_if<protocol::RegionAssignment>(&m->value())) {
        largest_region = std::max(largest_region, r->region.area());
      }
    }
    if (!welcome) continue;
    if (seconds_since(beat) > 0.1) {  // a member heartbeats
      beat = std::chrono::steady_clock::now();
      ASSERT_TRUE(
          control.send(protocol::Heartbeat{welcome->sampler_id, welcome->session, 0, 0.0}).ok());
    }
    if (largest_region == 0 || seconds_since(sent) < 0.1) continue;
    sent = std::chrono::steady_clock::now();
    TilingSnapshot whole;
    whole.sampler_id = welcome->sampler_id;
    whole.token = welcome->token;
    whole.time = 1.0;
    whole.region = PixelRect{0, 0, 128, 64};
    for (const PixelRect& r : {PixelRect{0, 0, 64, 64}, PixelRect{64, 0, 128, 64}}) {
      TileInfo tile;
      tile.rect = r;
      tile.v = 1.0f;
      tile.E = 1.0f;
      whole.tiles.push_back(tile);
    }
    ASSERT_TRUE(to_follower.send(whole, {128, 64}).ok());
    const nlohmann::json st = get_stats(port + 3);
    if (st.is_null() || st.is_discarded()) continue;
    for (const auto& m : st["samplers"]) {
      if (m["id"].get<uint32_t>() == welcome->sampler_id) kept = m["tiled_pixels"].get<int64_t>();
    }
  }
  ASSERT_TRUE(welcome.has_value()) << l->log();
  ASSERT_GT(kept, 0) << f->log();
  std::printf("the follower kept %lld of the 8192 pixels; the member's largest region %lld\n",
              static_cast<long long>(kept), static_cast<long long>(largest_region));
  EXPECT_LE(kept, largest_region);
  EXPECT_LT(kept, 128 * 64);
}

// A wall whose nodes use CurveZMQ on loopback: the lead and a follower, holding the display's
// key pair, reach each other's sample channels and exchange coverage and strays; a sampler
// with its own allowed key streams to both. That sampler's key cannot send strays (sampler id
// 0, which name no member) to a node: they are dropped and counted as spoofed, and the node
// stores none of them; nor can it join the wall as a node. The real exchange goes on.
TEST_F(WallTest, WithCurveTheNodesExchangeAndASamplersKeyCannotSendStraysNorJoinAsANode) {
  Process keygen({kDisplay, "keygen", path("keys"), "--samplers", "1"}, path("keygen.log"));
  ASSERT_EQ(keygen.wait(10.0), 0) << keygen.log();
  const std::vector<std::string> keys = {"--keys", path("keys")};
  auto l = lead({"--wall", "2x2", "--keys", path("keys")}, "128x64");
  ASSERT_TRUE(wait_until([&] { return wall_nodes(port_ + 3) == 1; }, 5.0)) << l->log();
  const int port = free_base_port();
  ASSERT_NE(port, 0);
  auto f = follower(1, 0, port, keys);
  ASSERT_TRUE(wait_until([&] { return wall_nodes(port_ + 3) == 2; }, 5.0)) << l->log();
  auto s = sampler("s1.log", 40000,
                   {"--key", path("keys/sampler-1.key"), "--server-key", path("keys/display.pub")});
  const auto exchange = [](int metrics_port) {
    const nlohmann::json st = get_stats(metrics_port);
    if (st.is_null() || st.is_discarded()) return nlohmann::json();
    return st["display"]["wall"]["exchange"];
  };
  const auto coverage_in = [&](int metrics_port) {
    const nlohmann::json x = exchange(metrics_port);
    return x.is_null() ? uint64_t(0) : x["coverage_in"].get<uint64_t>();
  };
  ASSERT_TRUE(wait_until(
      [&] {
        return received(port_ + 3) > 0 && received(port + 3) > 0 && coverage_in(port_ + 3) > 0 &&
               coverage_in(port + 3) > 0;
      },
      scaled(10.0)))
      << l->log() << f->log() << s->log();

  protocol::Context context;
  const protocol::CurveKeyPair sampler_key =
      protocol::load_curve_keypair(path("keys/sampler-1.key"));
  const std::string display_key = protocol::load_curve_keypair(path("keys/display.key")).public_key;
  protocol::SampleSender hostile(context, protocol::service_endpoints(endpoint(port)).samples,
                                 protocol::Security::client(sampler_key, display_key));
  for (uint64_t k = 0; k < 30; ++k) {
    ASSERT_NO_FATAL_FAILURE(send_batch(hostile, protocol::kWallPeerSamplerId, 0, k));
  }
  ASSERT_TRUE(wait_until(
      [&] {
        const nlohmann::json st = get_stats(port + 3);
        return !st.is_null() && !st.is_discarded() &&
               st["display"]["spoofed_batches"].get<int>() == 30;
      },
      scaled(10.0)))
      << get_stats(port + 3).dump() << f->log();
  EXPECT_NE(f->log().find("from a key that is not the wall's"), std::string::npos) << f->log();

  // Nor can that key join the wall as a display node, even for a free cell: it would get the
  // members' list and keep the cell from its node.
  protocol::ControlClient intruder(context, protocol::service_endpoints(endpoint(port_)).control,
                                   protocol::Security::client(sampler_key, display_key));
  protocol::DisplayJoin join;
  join.column = 1;
  join.row = 1;
  join.samples_endpoint = "tcp://127.0.0.1:9";
  join.name = "intruder";
  ASSERT_TRUE(intruder.send(join).ok());
  std::string refusal;
  ASSERT_TRUE(wait_until(
      [&] {
        const auto m = intruder.receive(50);
        if (m && m->ok()) {
          if (const auto* leave = std::get_if<protocol::Leave>(&m->value())) refusal = leave->text;
        }
        return !refusal.empty();
      },
      scaled(5.0)))
      << l->log();
  EXPECT_NE(refusal.find("is not the display's"), std::string::npos) << refusal;
  EXPECT_NE(l->log().find("display intruder refused"), std::string::npos) << l->log();
  EXPECT_EQ(wall_nodes(port_ + 3), 2);

  // The exchange between the nodes goes on.
  const uint64_t before = coverage_in(port + 3);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_GT(coverage_in(port + 3), before);
}

}  // namespace
}  // namespace afr::testing
