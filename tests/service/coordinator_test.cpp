#include <afr/display/service/coordinator.h>

#include <gtest/gtest.h>

namespace afr::service {
namespace {

int64_t total_area(const Coordinator& c) {
  int64_t a = 0;
  for (const auto& [id, m] : c.members()) a += m.region.area();
  return a;
}

// The regions partition the image: areas add up and no pixel is owned twice.
bool partitions(const Coordinator& c) {
  std::vector<int> owner(size_t(c.width()) * c.height(), 0);
  for (const auto& [id, m] : c.members()) {
    for (int y = m.region.y0; y < m.region.y1; ++y) {
      for (int x = m.region.x0; x < m.region.x1; ++x) {
        if (owner[size_t(y) * c.width() + x]++) return false;
      }
    }
  }
  for (int o : owner) {
    if (o != 1) return false;
  }
  return true;
}

// Samplers "a" (id 1) and "b" (id 2) joined at time 0, and the first cut made.
void join_two(Coordinator* c) {
  bool is_new = false;
  c->join("a", 0, "a", "", 1, 0.0, &is_new);
  c->join("b", 0, "b", "", 1, 0.0, &is_new);
  c->maybe_recut(0.0);
}

TEST(CoordinatorTest, JoinsGetIdsAndTheRegionsPartitionTheImage) {
  Coordinator c(100, 60);
  bool is_new = false;
  EXPECT_EQ(c.join("a", 0, "a", "", 1, 0.0, &is_new).id, 1u);
  EXPECT_TRUE(is_new);
  EXPECT_EQ(c.join("b", 0, "b", "", 1, 0.0, &is_new).id, 2u);
  EXPECT_EQ(c.join("a", 0, "a", "", 1, 0.1, &is_new).id, 1u);  // a repeated join
  EXPECT_FALSE(is_new);
  EXPECT_TRUE(c.maybe_recut(0.1));
  EXPECT_EQ(total_area(c), 6000);
  EXPECT_TRUE(partitions(c));
  EXPECT_FALSE(c.maybe_recut(0.2));  // nothing changed
}

TEST(CoordinatorTest, RequestedIdIsHonouredWhenFree) {
  Coordinator c(10, 10);
  bool is_new = false;
  EXPECT_EQ(c.join("a", 7, "a", "", 1, 0.0, &is_new).id, 7u);
  EXPECT_EQ(c.join("b", 7, "b", "", 1, 0.0, &is_new).id, 8u);  // taken: a fresh one
}

TEST(CoordinatorTest, SilentMemberExpiresAndItsRegionGoesToTheOthers) {
  // Heartbeats every 0.2 s expected, none heard yet from sampler 2: suspected once its
  // silence passes what the first guess (0.2 s apart, spread 0.1 s) makes unlikely, about
  // 0.76 s; sampler 1, heard at 0.4 s, is not.
  Coordinator c(64, 64);
  join_two(&c);
  c.heard(1, 0.4);
  EXPECT_TRUE(c.expire(0.7).empty());
  const std::vector<Member> dead = c.expire(0.8);
  ASSERT_EQ(dead.size(), 1u);
  EXPECT_EQ(dead[0].id, 2u);
  EXPECT_TRUE(c.maybe_recut(0.8));
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 64, 64}));
}

TEST(CoordinatorTest, AreasFollowThroughputWithHysteresis) {
  CoordinatorOptions o;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  EXPECT_EQ(c.members().at(1).region.area(), 10000);
  // 4:1 against halves: 0.8 / 0.5 is beyond the hysteresis (0.5).
  c.report_throughput(1, 400000.0, 0.5);
  c.report_throughput(2, 100000.0, 0.5);
  EXPECT_FALSE(c.maybe_recut(0.5));  // at most once per recut_interval
  EXPECT_TRUE(c.maybe_recut(1.1));
  EXPECT_NEAR(double(c.members().at(1).region.area()) / 20000.0, 0.8, 0.02);
  EXPECT_TRUE(partitions(c));
  // A 10% change is inside the hysteresis: no recut.
  c.report_throughput(1, 440000.0, 2.0);
  EXPECT_FALSE(c.maybe_recut(2.5));
}

TEST(CoordinatorTest, OnlyAnOverloadedMemberIsReasonToRecut) {
  // Regions cut for throughputs 9:91; then the throughputs become 20:80. Sampler 1 now has
  // less than half of what it could take, but sampler 2, which finishes last, carries 0.91
  // against 0.80 of its share: 14% over, inside the hysteresis. A recut (two pool restarts)
  // would gain less than it costs. At 40:60, sampler 2 carries 0.91 / 0.60 = 1.5x: recut.
  CoordinatorOptions o;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  c.report_throughput(1, 90000.0, 0.5);
  c.report_throughput(2, 910000.0, 0.5);
  c.report_throughput(1, 90000.0, 0.6);
  c.report_throughput(2, 910000.0, 0.6);
  ASSERT_TRUE(c.maybe_recut(1.1));
  ASSERT_NEAR(double(c.members().at(1).region.area()) / 20000.0, 0.09, 0.01);
  for (double t = 1.2; t < 3.0; t += 0.2) {  // the running mean settles on the new figures
    c.report_throughput(1, 200000.0, t);
    c.report_throughput(2, 800000.0, t);
  }
  EXPECT_FALSE(c.maybe_recut(3.0));
  for (double t = 3.2; t < 5.0; t += 0.2) {
    c.report_throughput(1, 400000.0, t);
    c.report_throughput(2, 600000.0, t);
  }
  EXPECT_TRUE(c.maybe_recut(5.0));
  EXPECT_NEAR(double(c.members().at(1).region.area()) / 20000.0, 0.4, 0.02);
}

TEST(CoordinatorTest, NoDriftRecutUntilEveryRegionHasSettled) {
  // A new region restarts the sampler's pool: for settle_seconds its figures are not used.
  CoordinatorOptions o;
  o.settle_seconds = 2.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  MassDensity error(200, 100, 50, 25);
  error.add(PixelRect{0, 0, 20, 100}, 1000.0);
  c.set_error(error);
  EXPECT_FALSE(c.maybe_recut(1.5));  // regions 1.5 s old
  EXPECT_TRUE(c.maybe_recut(2.1));   // settled, and the error is far from half and half
  EXPECT_LT(c.members().at(1).region.x1, 20);
  // The joining of a third sampler recuts at once, settled or not.
  bool is_new = false;
  c.join("c", 0, "c", "", 1, 2.5, &is_new);
  EXPECT_TRUE(c.maybe_recut(2.5));
  EXPECT_TRUE(partitions(c));
}

TEST(CoordinatorTest, ErrorSharesFollowThroughputOnceTheErrorIsKnown) {
  // Equal throughputs; then the error sits mostly in the left quarter of the image: the cut
  // gives each sampler half of the error, so the left region shrinks to about an eighth.
  CoordinatorOptions o;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  c.report_throughput(1, 100000.0, 0.1);
  c.report_throughput(2, 100000.0, 0.1);
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 100, 100}));
  MassDensity error(200, 100, 50, 25);
  error.add(PixelRect{0, 0, 50, 100}, 1000.0);
  error.add_uniform(1e-3);
  c.set_error(error);
  EXPECT_TRUE(c.maybe_recut(1.1));  // the halves hold 0.998 and 0.002 of the error
  const PixelRect left = c.members().at(1).region;
  EXPECT_NEAR(left.x1, 25, 1);
  EXPECT_NEAR(error.mass(left) / error.total(), 0.5, 0.02);
  EXPECT_TRUE(partitions(c));
  // The same error again: the shares hold, no recut.
  c.set_error(error);
  EXPECT_FALSE(c.maybe_recut(2.2));
  // No error anywhere (an all-black image): back to areas at the next recut.
  c.set_error(MassDensity(200, 100, 50, 25));
  EXPECT_TRUE(c.maybe_recut(3.3));
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 100, 100}));
}

}  // namespace
}  // namespace afr::service
