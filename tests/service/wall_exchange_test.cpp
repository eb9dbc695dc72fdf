// WallExchange (docs/wall.md, "Seams"): which nodes are a node's peers, the coverage it gives
// each, and the strays: samples traced in its cell that the view now projects near a peer's
// received region though the samplers did not send them there, each given once. The network
// side (WallPeerLinks) runs in the wall's process tests.
#include <afr/display/service/wall_exchange.h>

#include <afr/common/error.h>
#include <afr/display/backend.h>
#include <afr/display/reprojection.h>
#include <afr/display/service/wall.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

namespace afr::service {
namespace {

// A 3 x 3 wall of 100 x 100 cells over 300 x 300, margin 20.
protocol::WallLayout three_by_three(int margin = 20) {
  WallGrid grid;
  grid.columns = grid.rows = 3;
  protocol::WallLayout layout;
  layout.image.width = layout.image.height = 300;
  layout.margin = margin;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      layout.nodes.push_back(
          protocol::WallNode{uint32_t(1 + 3 * r + c), grid.cell(c, r, 300, 300), ""});
    }
  }
  return layout;
}

TEST(WallExchangeTest, PeersAreTheNodesWhoseReceivedRegionsReachTheCellNearestFirst) {
  const protocol::WallLayout layout = three_by_three();
  const WallExchange center(layout, 5);
  ASSERT_EQ(center.peers().size(), 8u);
  // The four edge neighbours first, then the diagonal ones.
  for (size_t k = 0; k < 4; ++k) {
    const uint32_t id = center.peers()[k].node_id;
    EXPECT_TRUE(id == 2 || id == 4 || id == 6 || id == 8) << id;
  }
  // What the left neighbour (node 4, cell x 0..100) receives of the center cell: 20 px.
  const auto left = std::find_if(center.peers().begin(), center.peers().end(),
                                 [](const WallPeer& p) { return p.node_id == 4; });
  EXPECT_EQ(left->coverage_rect, (PixelRect{100, 100, 120, 200}));
  const auto corner = std::find_if(center.peers().begin(), center.peers().end(),
                                   [](const WallPeer& p) { return p.node_id == 1; });
  EXPECT_EQ(corner->coverage_rect, (PixelRect{100, 100, 120, 120}));

  const WallExchange top_left(layout, 1);
  EXPECT_EQ(top_left.peers().size(), 3u);
  // Without a margin no node receives any part of another's cell: no peers.
  EXPECT_TRUE(WallExchange(three_by_three(0), 5).peers().empty());
  EXPECT_THROW(WallExchange(layout, 42), Error);
}

// A camera looking down -z from the origin whose image is the 300 x 300 virtual display.
Camera camera_at_x(double x) {
  return Camera::look_at({x, 0.0, 0.0}, {x, 0.0, -1.0}, {0, 1, 0}, 1.0, 0.01);
}

// A sample hit on the plane z = -5 at the image position (px, py) of camera_at_x(0).
Sample sample_at(float px, float py, double time) {
  const Camera cam = camera_at_x(0.0);
  Sample s;
  s.time = time;
  s.x = px;
  s.y = py;
  s.color = glm::vec3(0.5f);
  // Invert the projection onto the plane z = -5.
  const Projector p(cam, 300.0, 300.0);
  const float fx = (px - p.half_width) / glm::length(p.axis_x);
  const float fy = (p.half_height - py) / glm::length(p.axis_y);
  s.position = glm::vec3(5.0f * fx, 5.0f * fy, -5.0f);
  return s;
}

TEST(WallExchangeTest, StraysAreTheCellsSamplesThatNowProjectNearAPeerAndAreSentOnce) {
  const protocol::WallLayout layout = three_by_three();
  ReconstructorConfig rc;
  rc.image.width = rc.image.height = 300;
  rc.viewport = layout.nodes[4].cell;  // the center, [100, 200)^2
  rc.viewport_margin = 20;
  rc.threads = 1;
  std::unique_ptr<Reconstructor> recon = make_reconstructor(Backend::kCpu, rc).reconstructor;
  SampleBatch b;
  b.sampler_id = 3;
  b.fields = kFieldPosition;
  b.samples.push_back(sample_at(150.5f, 150.5f, 0.0));  // the middle of the cell
  b.samples.push_back(sample_at(110.5f, 150.5f, 0.0));  // 10 px from the left border
  b.samples.push_back(sample_at(85.5f, 150.5f, 0.0));   // in the margin: not this node's
  recon->add_batch(b);
  SampleBatch no_position;
  no_position.sampler_id = 3;
  no_position.samples.push_back(b.samples[1]);
  no_position.samples.back().position = glm::vec3(0.0f);
  recon->add_batch(no_position);

  WallExchange ex(layout, 5, /*lookahead=*/16);
  const auto peer_index = [&](uint32_t id) {
    return size_t(std::find_if(ex.peers().begin(), ex.peers().end(),
                               [&](const WallPeer& p) { return p.node_id == id; }) -
                  ex.peers().begin());
  };
  const size_t left = peer_index(4), right = peer_index(6);
  WallOutbox out;

  // Unmoved: the sample 10 px from the border is inside the left node's received region
  // (x < 120), so the samplers sent it there: nothing to forward.
  Camera cam = camera_at_x(0.0);
  recon->reconstruct(cam, 0.1, 100, 100);
  ex.collect(*recon, cam, 0.1, true, &out);
  EXPECT_EQ(out.stray_samples(), 0u);
  ASSERT_EQ(out.coverage.size(), ex.peers().size());
  for (const WallOutbox::Coverage& c : out.coverage) {
    EXPECT_EQ(c.cells.size(), size_t(c.rect.area()));
    EXPECT_EQ(c.rect, ex.peers()[c.peer].coverage_rect);
  }

  // The camera moves right: the middle sample moves left in the image, to about x = 150 - d.
  // Project it to find how far; choose a move that puts it 10 px right of the left node's
  // received region (x in [120, 136): within the lookahead).
  const Projector p0(cam, 300.0, 300.0);
  const double px_per_unit = glm::length(p0.axis_x) / 5.0;  // at depth 5
  cam = camera_at_x(22.0 / px_per_unit);                    // 150.5 - 22 = 128.5
  recon->reconstruct(cam, 0.2, 100, 100);
  ex.collect(*recon, cam, 0.2, true, &out);
  ASSERT_EQ(out.stray_samples(), 1u);
  ASSERT_EQ(out.strays[left].size(), 1u);
  const SampleBatch& stray = out.strays[left][0];
  EXPECT_EQ(stray.sampler_id, protocol::kWallPeerSamplerId);
  EXPECT_EQ(stray.fields, kFieldPosition);
  EXPECT_EQ(stray.samples[0].x, 150.5f);  // as traced
  EXPECT_EQ(stray.samples[0].position, b.samples[0].position);
  EXPECT_TRUE(out.strays[right].empty());

  // Sent once: the next image does not send it again, however near it comes.
  cam = camera_at_x(40.0 / px_per_unit);
  recon->reconstruct(cam, 0.3, 100, 100);
  ex.collect(*recon, cam, 0.3, true, &out);
  EXPECT_EQ(out.stray_samples(), 0u);

  // Not at the cell's size: no coverage (the peers' pixels would not match), strays still.
  // The camera moves left: a new sample traced at x = 160.5 and the middle one move 30 px
  // right, to 190.5 and 180.5, into the right node's received region (x >= 180), where the
  // samplers did not send them (they were traced left of it).
  recon->add_batch(SampleBatch{3, 1, kFieldPosition, {sample_at(160.5f, 150.5f, 0.25)}});
  cam = camera_at_x(-30.0 / px_per_unit);
  recon->reconstruct(cam, 0.4, 50, 50);
  ex.collect(*recon, cam, 0.4, false, &out);
  EXPECT_TRUE(out.coverage.empty());
  EXPECT_EQ(out.stray_samples(), 2u);
  size_t to_right = 0;
  for (const SampleBatch& s : out.strays[right]) to_right += s.samples.size();
  EXPECT_EQ(to_right, 2u);
}

TEST(WallExchangeTest, TheInboxKeepsTheNewestMessagesAndCountsWhatItDrops) {
  WallCoverageInbox inbox;
  for (size_t i = 0; i < WallCoverageInbox::kMaxPending + 3; ++i) {
    protocol::WallCoverage c;
    c.node_id = 2;
    c.time = double(i);
    inbox.put(std::move(c));
  }
  std::vector<protocol::WallCoverage> got;
  inbox.take(&got);
  ASSERT_EQ(got.size(), WallCoverageInbox::kMaxPending);
  EXPECT_EQ(got.front().time, 3.0);
  EXPECT_EQ(inbox.dropped(), 3u);
  inbox.take(&got);
  EXPECT_TRUE(got.empty());
}

}  // namespace
}  // namespace afr::service
