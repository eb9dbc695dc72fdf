#include <afr/display/service/coordinator.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>

namespace afr::service {
namespace {

int64_t total_area(const Coordinator& c) {
  int64_t a = 0;
  for (const auto& [id, m] : c.members()) a += m.region.area();
  return a;
}

double area_share(const Coordinator& c, uint32_t id) {
  return double(c.members().at(id).region.area()) / (double(c.width()) * c.height());
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

// Options whose joins are cut in without waiting for others (join_gather 0), to see the other
// rules alone; CoordinatorTest.SamplersThatJoinTogetherComeInWithOneCut looks at the gathering.
CoordinatorOptions ungathered() {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  return o;
}

Member& join(Coordinator* c, const std::string& peer, double now, int threads = 1) {
  bool is_new = false;
  return c->join(peer, peer, "", threads, 1000 + uint64_t(peer[0]), now, &is_new);
}

// Samplers "a" (id 1) and "b" (id 2) joined at time 0, and the first cut made.
void join_two(Coordinator* c) {
  join(c, "a", 0.0);
  join(c, "b", 0.0);
  c->maybe_recut(0.0);
}

// The display's control thread in miniature: a pass every 50 ms from `from` to `to`; in each,
// every member is heard (its heartbeats) and those in `rates` deliver samples at that rate (per
// second), then the coordinator measures and maybe recuts. Returns the time of each recut.
constexpr double kPass = 0.05;
std::vector<double> run(Coordinator* c, double from, double to,
                        const std::map<uint32_t, double>& rates) {
  std::vector<double> cuts;
  const int passes = int(std::lround((to - from) / kPass));
  for (int k = 1; k <= passes; ++k) {
    const double t = from + k * kPass;
    std::vector<uint32_t> ids;
    for (const auto& [id, m] : c->members()) ids.push_back(id);
    for (uint32_t id : ids) c->heard(id, t);
    for (const auto& [id, rate] : rates) c->add_samples(id, uint64_t(rate * kPass), t);
    if (c->maybe_recut(t)) cuts.push_back(t);
  }
  return cuts;
}

// ---------------------------------------------------------------------------------------------
// Membership and ids

TEST(CoordinatorTest, JoinsGetIdsAndTheRegionsPartitionTheImage) {
  Coordinator c(100, 60, ungathered());
  bool is_new = false;
  EXPECT_EQ(c.join("a", "a", "", 1, 11, 0.0, &is_new).id, 1u);
  EXPECT_TRUE(is_new);
  EXPECT_EQ(c.join("b", "b", "", 1, 12, 0.0, &is_new).id, 2u);
  const Member& again = c.join("a", "a", "", 1, 13, 0.1, &is_new);  // a repeated join
  EXPECT_FALSE(is_new);
  EXPECT_EQ(again.id, 1u);
  EXPECT_EQ(again.token, 11u);  // keeps its token
  EXPECT_TRUE(c.maybe_recut(0.1));
  EXPECT_EQ(total_area(c), 6000);
  EXPECT_TRUE(partitions(c));
  EXPECT_FALSE(c.maybe_recut(0.2));  // nothing changed
}

TEST(CoordinatorTest, IdsAreAssignedByTheDisplayAndALiveOneIsNeverGivenAgain) {
  Coordinator c(10, 10, ungathered());
  join(&c, "a", 0.0);
  join(&c, "b", 0.0);
  join(&c, "c", 0.0);
  ASSERT_TRUE(c.remove(2));
  // The departed id is not given again either (its late batches stay a stranger's).
  EXPECT_EQ(join(&c, "d", 0.1).id, 4u);
  EXPECT_EQ(c.members().size(), 3u);
}

// A peer that once made every later sampler get id 4294967295 (a join asking for 0xFFFFFFFE):
// ids near the top of the range now wrap to 1, stay distinct, and no join removes a member.
TEST(CoordinatorTest, IdsWrapPastTheTopWithoutEvictingAnyone) {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.first_id = 0xFFFFFFFEu;
  Coordinator c(64, 64, o);
  std::set<uint32_t> ids;
  for (const char* peer : {"a", "b", "c", "d", "e"}) ids.insert(join(&c, peer, 0.0).id);
  EXPECT_EQ(ids, (std::set<uint32_t>{0xFFFFFFFEu, 0xFFFFFFFFu, 1u, 2u, 3u}));
  EXPECT_EQ(c.members().size(), 5u);
  EXPECT_TRUE(c.maybe_recut(0.0));
  EXPECT_TRUE(partitions(c));
  // Repeated joins keep their ids; membership stays as it is.
  for (const char* peer : {"a", "b", "c", "d", "e"}) join(&c, peer, 0.1);
  EXPECT_EQ(c.members().size(), 5u);
  EXPECT_FALSE(c.maybe_recut(0.1));
}

TEST(CoordinatorTest, SilentMemberExpiresAndItsRegionGoesToTheOthers) {
  // Heartbeats every 0.2 s expected, none heard yet from sampler 2: suspected once its
  // silence passes what the first guess (0.2 s apart, spread 0.1 s) makes unlikely, about
  // 0.76 s; sampler 1, heard at 0.4 s, is not.
  Coordinator c(64, 64, ungathered());
  join_two(&c);
  c.heard(1, 0.4);
  EXPECT_TRUE(c.expire(0.7).empty());
  const std::vector<Member> dead = c.expire(0.8);
  ASSERT_EQ(dead.size(), 1u);
  EXPECT_EQ(dead[0].id, 2u);
  EXPECT_TRUE(c.maybe_recut(0.8));
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 64, 64}));
}

// Samplers started together join within a moment of each other: the first gets the image at
// once, the others wait out join_interval and come in with one cut (not a handover each). A
// member waiting for its region has nothing to deliver and does not starve meanwhile.
TEST(CoordinatorTest, JoinsWithinAnIntervalAreCutInTogether) {
  Coordinator c(64, 64, ungathered());  // join_interval 1 s
  join(&c, "a", 0.0);
  ASSERT_TRUE(c.maybe_recut(0.0));
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 64, 64}));
  join(&c, "b", 0.1);
  join(&c, "c", 0.3);
  // (Until 1.5 s: from its cut a member that delivers nothing starves after 0.75 s.)
  const std::vector<double> cuts = run(&c, 0.0, 1.5, {{1, 100000.0}});
  ASSERT_EQ(cuts.size(), 1u);
  EXPECT_NEAR(cuts[0], 1.0, 1e-9);
  EXPECT_TRUE(partitions(c));
  for (uint32_t id : {2u, 3u}) {
    EXPECT_FALSE(c.members().at(id).region.empty());
    EXPECT_FALSE(c.members().at(id).starved) << "starved while it waited for a region";
  }
}

// Samplers started together (or back after a display restart) join within moments of each
// other: with the default options the first join waits join_gather (0.2 s) for the others, and
// all come in with one cut, before any sampler has started on a region it would hand over.
TEST(CoordinatorTest, SamplersThatJoinTogetherComeInWithOneCut) {
  Coordinator c(64, 64);
  join(&c, "a", 0.0);
  EXPECT_FALSE(c.maybe_recut(0.0));
  join(&c, "b", 0.05);
  join(&c, "c", 0.12);
  for (double t : {0.05, 0.1, 0.15}) EXPECT_FALSE(c.maybe_recut(t)) << t;
  EXPECT_TRUE(c.maybe_recut(0.2));
  EXPECT_EQ(c.recuts(), 1u);
  EXPECT_TRUE(partitions(c));
  for (uint32_t id : {1u, 2u, 3u}) EXPECT_FALSE(c.members().at(id).region.empty()) << id;
}

// A cut for a leave leaves a waiting join waiting, and does not put its cut off: the join made
// at 0.2 s still comes in at 4 s, the interval after the last join cut (0 s). And a member that
// waits is not measured (it has nothing to deliver): its share at its cut is the provisional
// one, however long it waited.
TEST(CoordinatorTest, ACutForALeaveNeitherCutsInNorPutsOffAWaitingJoin) {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.join_interval = 4.0;  // longer than settle_seconds + measure_seconds after the join
  Coordinator c(128, 128, o);
  join(&c, "a", 0.0);
  join(&c, "b", 0.0);
  join(&c, "c", 0.0);
  ASSERT_TRUE(c.maybe_recut(0.0));
  join(&c, "d", 0.2);
  std::vector<double> cuts = run(&c, 0.0, 0.5, {{1, 100000.0}, {2, 100000.0}, {3, 100000.0}});
  EXPECT_TRUE(cuts.empty());
  ASSERT_TRUE(c.remove(3));  // a leave: cut at once, "d" still waiting
  EXPECT_TRUE(c.maybe_recut(0.5));
  EXPECT_TRUE(c.members().at(4).region.empty());
  EXPECT_TRUE(partitions(c));
  cuts = run(&c, 0.5, 4.5, {{1, 100000.0}, {2, 100000.0}});
  ASSERT_FALSE(cuts.empty());
  EXPECT_NEAR(cuts[0], 4.0, 1e-9);
  EXPECT_FALSE(c.members().at(4).region.empty());
  EXPECT_NEAR(area_share(c, 4), 1.0 / 3.0, 0.05);  // provisional, not measured at 0 meanwhile
}

// When no member has a region (the last one left while a join waited), the join is cut in at
// once: the image is never left without a sampler for an interval.
TEST(CoordinatorTest, AJoinIsCutInAtOnceWhenNoMemberHasARegion) {
  Coordinator c(64, 64, ungathered());
  join(&c, "a", 0.0);
  ASSERT_TRUE(c.maybe_recut(0.0));
  join(&c, "b", 0.3);
  EXPECT_FALSE(c.maybe_recut(0.3));  // waits: a samples the image
  ASSERT_TRUE(c.remove(1));
  EXPECT_TRUE(c.maybe_recut(0.4));
  EXPECT_EQ(c.members().at(2).region, (PixelRect{0, 0, 64, 64}));
}

// A peer that joins and leaves before its cut leaves no region to cover and costs the members
// no recut, even where their shares drifted meanwhile (that waits for the drift rule).
TEST(CoordinatorTest, APeerThatLeavesBeforeItsCutCostsNoRecut) {
  Coordinator c(128, 128, ungathered());
  join_two(&c);
  run(&c, 0.0, 3.0, {{1, 300000.0}, {2, 100000.0}});  // rates now say 3:1, regions 1:1
  const uint64_t epoch = c.epoch();
  const PixelRect a = c.members().at(1).region;
  for (int k = 0; k < 100; ++k) {  // 3 s to 8 s: before the drift rule may look (10 s)
    const double t = 3.0 + k * 0.05;
    EXPECT_TRUE(c.remove(join(&c, "x" + std::to_string(k), t).id));
    c.heard(1, t);
    c.heard(2, t);
    c.add_samples(1, 15000, t);
    c.add_samples(2, 5000, t);
    EXPECT_FALSE(c.maybe_recut(t)) << "at " << t;
  }
  EXPECT_EQ(c.epoch(), epoch);
  EXPECT_EQ(c.members().at(1).region, a);
}

// A peer that waits for its region each time before it leaves and joins again buys a cut for its
// join and one for its leave: at most two recuts a join_interval, however fast it loops.
TEST(CoordinatorTest, APeerThatJoinsAndLeavesInALoopRecutsAtMostTwiceAJoinInterval) {
  Coordinator c(128, 128, ungathered());
  join_two(&c);
  run(&c, 0.0, 3.0, {{1, 100000.0}, {2, 100000.0}});
  const uint64_t before = c.recuts();
  uint32_t churn = 0;
  int k = 0;
  constexpr double kFrom = 3.0, kSeconds = 20.0;
  for (double t = kFrom; t < kFrom + kSeconds; t += 0.01) {
    if (churn == 0 || !c.members().at(churn).region.empty()) {
      // The moment it has a region it leaves, and joins again in the same pass (a leave's cut
      // must not cut in the next join).
      if (churn != 0) c.remove(churn);
      churn = join(&c, "x" + std::to_string(k++), t).id;
    }
    c.heard(1, t);
    c.heard(2, t);
    c.add_samples(1, 1000, t);
    c.add_samples(2, 1000, t);
    c.maybe_recut(t);
    EXPECT_TRUE(partitions(c)) << "at " << t;
  }
  EXPECT_GE(k, 10);  // it did get regions, about once a second
  EXPECT_LE(c.recuts() - before, uint64_t(2.0 * (kSeconds / 1.0 + 1.0)));
}

// ---------------------------------------------------------------------------------------------
// Shares from measured rates

TEST(CoordinatorTest, AreasFollowMeasuredRatesWithHysteresis) {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  EXPECT_EQ(c.members().at(1).region.area(), 10000);
  // 4:1 against halves: 0.8 / 0.5 is beyond the hysteresis (0.5); the cut waits until both
  // rates have been measured for measure_seconds and an interval has passed.
  const std::vector<double> cuts = run(&c, 0.0, 1.5, {{1, 400000.0}, {2, 100000.0}});
  ASSERT_EQ(cuts.size(), 1u);
  EXPECT_GE(cuts[0], 1.0 - 1e-9);
  EXPECT_NEAR(c.members().at(1).rate, 400000.0, 1.0);
  EXPECT_NEAR(area_share(c, 1), 0.8, 0.02);
  EXPECT_TRUE(partitions(c));
  // A 10% change is inside the hysteresis: no recut.
  EXPECT_TRUE(run(&c, 1.5, 4.0, {{1, 440000.0}, {2, 100000.0}}).empty());
}

TEST(CoordinatorTest, OnlyAnOverloadedMemberIsReasonToRecut) {
  // Regions cut for rates 9:91; then the rates become 20:80. Sampler 1 now has less than half
  // of what it could take, but sampler 2, which finishes last, carries 0.91 against 0.80 of its
  // share: 14% over, inside the hysteresis. A recut (two pool restarts) would gain less than it
  // costs. At 40:60, sampler 2 carries 0.91 / 0.60 = 1.5x: recut.
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  ASSERT_EQ(run(&c, 0.0, 1.5, {{1, 90000.0}, {2, 910000.0}}).size(), 1u);
  ASSERT_NEAR(area_share(c, 1), 0.09, 0.01);
  EXPECT_TRUE(run(&c, 1.5, 4.0, {{1, 200000.0}, {2, 800000.0}}).empty());
  EXPECT_EQ(run(&c, 4.0, 6.0, {{1, 400000.0}, {2, 600000.0}}).size(), 1u);
  EXPECT_NEAR(area_share(c, 1), 0.4, 0.02);
}

TEST(CoordinatorTest, NoDriftRecutUntilEveryRegionHasSettled) {
  // A new region restarts the sampler's pool: for settle_seconds its figures are not used.
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.settle_seconds = 2.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  MassDensity error(200, 100, 50, 25);
  error.add(PixelRect{0, 0, 20, 100}, 1000.0);
  c.set_error(error);
  const std::map<uint32_t, double> rates = {{1, 100000.0}, {2, 100000.0}};
  EXPECT_TRUE(run(&c, 0.0, 1.5, rates).empty());  // regions 1.5 s old
  const std::vector<double> cuts = run(&c, 1.5, 2.5, rates);
  ASSERT_EQ(cuts.size(), 1u);  // settled, and the error is far from half and half
  EXPECT_GE(cuts[0], 2.0 - 1e-9);
  EXPECT_LT(c.members().at(1).region.x1, 20);
  // The left half held all the error against half of the throughput: load 2 before, about 1
  // after (the log line of a drift cut).
  EXPECT_NEAR(c.drift_loads().first, 2.0, 0.01);
  EXPECT_NEAR(c.drift_loads().second, 1.0, 0.1);
  // The joining of a third sampler recuts at once, settled or not; not a drift cut.
  join(&c, "c", 2.5);
  EXPECT_TRUE(c.maybe_recut(2.5));
  EXPECT_TRUE(partitions(c));
  EXPECT_EQ(c.drift_loads().first, 0.0);
}

TEST(CoordinatorTest, ErrorSharesFollowRatesOnceTheErrorIsKnown) {
  // Equal rates; then the error sits mostly in the left quarter of the image: the cut gives
  // each sampler half of the error, so the left region shrinks to about an eighth.
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.settle_seconds = 0.0;
  o.recut_interval = 1.0;
  Coordinator c(200, 100, o);
  join_two(&c);
  const std::map<uint32_t, double> rates = {{1, 100000.0}, {2, 100000.0}};
  EXPECT_TRUE(run(&c, 0.0, 1.0, rates).empty());
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 100, 100}));
  MassDensity error(200, 100, 50, 25);
  error.add(PixelRect{0, 0, 50, 100}, 1000.0);
  error.add_uniform(1e-3);
  c.set_error(error);
  EXPECT_EQ(run(&c, 1.0, 1.1, rates).size(), 1u);  // the halves hold 0.998 and 0.002 of it
  const PixelRect left = c.members().at(1).region;
  EXPECT_NEAR(left.x1, 25, 1);
  EXPECT_NEAR(error.mass(left) / error.total(), 0.5, 0.02);
  EXPECT_TRUE(partitions(c));
  // The same error again: the shares hold, no recut.
  c.set_error(error);
  EXPECT_TRUE(run(&c, 1.1, 2.2, rates).empty());
  // No error anywhere (an all-black image): back to areas at the next recut.
  c.set_error(MassDensity(200, 100, 50, 25));
  EXPECT_EQ(run(&c, 2.2, 3.3, rates).size(), 1u);
  EXPECT_EQ(c.members().at(1).region, (PixelRect{0, 0, 100, 100}));
}

TEST(CoordinatorTest, ErrorThatNoCutCanShareOutMovesNoBorder) {
  // Nine tenths of the error in one column that moves between x = 60 and x = 61 from one
  // interval to the next: every cut leaves the column's owner about 0.9 of the error against
  // half of the throughput, beyond the hysteresis, and a cut can only move the border by a
  // pixel. With no least gain the border follows the column (a handover for both samplers each
  // time); with the default min_gain no cut is made, since none lowers the worst load.
  const auto spike = [](int x) {
    MassDensity e(200, 100, 200, 100);
    e.add(PixelRect{x, 0, x + 1, 100}, 900.0);
    e.add_uniform(100.0 / (200.0 * 100.0));
    return e;
  };
  const std::map<uint32_t, double> rates = {{1, 100000.0}, {2, 100000.0}};
  const auto recuts = [&](double min_gain) {
    CoordinatorOptions o;
    o.join_gather = 0.0;
    o.settle_seconds = 0.0;
    o.recut_interval = 1.0;
    o.min_gain = min_gain;
    Coordinator c(200, 100, o);
    join_two(&c);
    EXPECT_TRUE(run(&c, 0.0, 1.0, rates).empty());  // rates measured, no error known yet
    size_t n = 0;
    for (int k = 0; k < 6; ++k) {
      c.set_error(spike(60 + k % 2));
      n += run(&c, 1.0 + k * 1.1, 2.1 + k * 1.1, rates).size();
      EXPECT_TRUE(partitions(c));
    }
    return n;
  };
  EXPECT_GE(recuts(0.0), 4u);
  EXPECT_EQ(recuts(CoordinatorOptions{}.min_gain), 0u);
}

TEST(CoordinatorTest, ATileCountsNoMoreErrorThanTheDisplayCanShow) {
  const PixelRect pixel{24, 116, 25, 117}, tile{0, 0, 16, 16};
  EXPECT_DOUBLE_EQ(shown_error_mass(0.01f, tile), double(0.01f) * 256.0);
  // A specular highlight's variance in unclamped radiance counts as a shown one's largest.
  EXPECT_DOUBLE_EQ(shown_error_mass(4.0e6f, pixel), 0.25);
  EXPECT_DOUBLE_EQ(shown_error_mass(std::numeric_limits<float>::infinity(), pixel), 0.25);
  EXPECT_EQ(shown_error_mass(std::numeric_limits<float>::quiet_NaN(), tile), 0.0);
  EXPECT_EQ(shown_error_mass(-1.0f, tile), 0.0);
  // So one such pixel beside the 256 ordinary tiles of a 256 x 256 image holds a small part of
  // the error instead of nearly all of it.
  MassDensity error(256, 256, 64, 64);
  for (int k = 0; k < 256; ++k) {
    const PixelRect t{(k % 16) * 16, (k / 16) * 16, (k % 16) * 16 + 16, (k / 16) * 16 + 16};
    error.add(t, shown_error_mass(0.01f, t));
  }
  error.add(pixel, shown_error_mass(4.0e6f, pixel));
  EXPECT_LT(error.mass(pixel) / error.total(), 0.001);
}

// ---------------------------------------------------------------------------------------------
// Claims and silence

// A join that claims 4096 threads (and would claim any rate) gets no more than a provisional
// equal share, and loses even that within starve_seconds when nothing comes from it; the two
// samplers that deliver keep the image between them.
TEST(CoordinatorTest, GreedyJoinThatSendsNothingDoesNotTakeTheRealSamplersRegions) {
  Coordinator c(256, 256, ungathered());
  join_two(&c);
  const std::map<uint32_t, double> real = {{1, 100000.0}, {2, 100000.0}};
  run(&c, 0.0, 1.0, real);
  const Member& greedy = join(&c, "greedy", 1.0, protocol::kMaxThreads);
  const uint32_t g = greedy.id;
  ASSERT_TRUE(c.maybe_recut(1.0));
  EXPECT_LE(area_share(c, g), 1.0 / 3.0 + 0.01);  // its claim bought nothing
  const std::vector<double> cuts = run(&c, 1.0, 2.0, real);
  ASSERT_FALSE(cuts.empty());
  EXPECT_LE(cuts.front(), 1.0 + 0.75 + kPass + 1e-9);  // starve_seconds, a pass
  EXPECT_TRUE(c.members().at(g).starved);
  EXPECT_LT(area_share(c, g), 0.01);
  EXPECT_GT(area_share(c, 1) + area_share(c, 2), 0.99);
  EXPECT_TRUE(partitions(c));
  // And it stays so while the real samplers deliver; the rates, not the claim, split the rest.
  run(&c, 2.0, 6.0, real);
  EXPECT_LT(area_share(c, g), 0.01);
  EXPECT_NEAR(area_share(c, 1), area_share(c, 2), 0.05);
}

// A new member's provisional share is the mean of the measured rates: between the slow and the
// fast sampler, whatever it says about itself.
TEST(CoordinatorTest, NewMemberStartsWithTheMeanMeasuredRate) {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.settle_seconds = 0.5;
  Coordinator c(300, 100, o);
  join_two(&c);
  run(&c, 0.0, 2.0, {{1, 100000.0}, {2, 300000.0}});
  ASSERT_TRUE(c.measured(c.members().at(1)) && c.measured(c.members().at(2)));
  const uint32_t n = join(&c, "new", 2.0, protocol::kMaxThreads).id;
  ASSERT_TRUE(c.maybe_recut(2.0));
  EXPECT_FALSE(c.measured(c.members().at(n)));
  EXPECT_NEAR(area_share(c, n), 200.0 / 600.0, 0.02);
  EXPECT_NEAR(area_share(c, 1), 100.0 / 600.0, 0.02);
}

// A sampler that starved while it loaded the scene comes back at once when it delivers: its
// first return recuts immediately, with the provisional share.
TEST(CoordinatorTest, StarvedMemberThatStartsDeliveringGetsAShareBack) {
  Coordinator c(256, 256, ungathered());
  join(&c, "a", 0.0);
  join(&c, "b", 0.0);
  join(&c, "slow", 0.0);
  ASSERT_TRUE(c.maybe_recut(0.0));
  const std::vector<double> starved = run(&c, 0.0, 1.0, {{1, 100000.0}, {2, 100000.0}});
  ASSERT_EQ(starved.size(), 1u);
  EXPECT_LT(area_share(c, 3), 0.01);
  const std::vector<double> back = run(&c, 3.0, 3.1, {{1, 100000.0}, {2, 100000.0}, {3, 100000.0}});
  ASSERT_EQ(back.size(), 1u);
  EXPECT_FALSE(c.members().at(3).starved);
  EXPECT_NEAR(area_share(c, 3), 1.0 / 3.0, 0.02);
}

// Silence is starvation only when others deliver meanwhile: when nobody delivers (all loading,
// the network down) nobody's region moves, and a stall of this display itself (no measure()
// for a while) is not the members' silence.
TEST(CoordinatorTest, NoStarvationWhileNobodyDeliversOrWhileTheDisplayStalled) {
  Coordinator c(128, 128, ungathered());
  join_two(&c);
  EXPECT_TRUE(run(&c, 0.0, 3.0, {}).empty());
  EXPECT_FALSE(c.members().at(1).starved || c.members().at(2).starved);
  // Both deliver; then the display stalls for 3 s; then only sampler 1's batches have come in
  // (sampler 2's are still queued): sampler 2 has starve_seconds from the stall's end, not from
  // its last batch 3 s before.
  run(&c, 3.0, 6.0, {{1, 100000.0}, {2, 100000.0}});
  c.add_samples(1, 300000, 9.0);
  EXPECT_FALSE(c.maybe_recut(9.0));
  EXPECT_FALSE(c.members().at(2).starved);
  EXPECT_TRUE(run(&c, 9.0, 9.6, {{1, 100000.0}}).empty());
  EXPECT_FALSE(c.members().at(2).starved);
  EXPECT_EQ(run(&c, 9.6, 10.0, {{1, 100000.0}}).size(), 1u);
  EXPECT_TRUE(c.members().at(2).starved);
}

// A sampler that has delivered before gets settle_seconds after a region change (its pool
// restarts and sends nothing meanwhile) before its silence counts.
TEST(CoordinatorTest, ARestartingPoolIsNotTakenForStarvation) {
  Coordinator c(128, 128, ungathered());
  join_two(&c);
  run(&c, 0.0, 3.0, {{1, 100000.0}, {2, 100000.0}});
  join(&c, "c", 3.0);
  ASSERT_TRUE(c.maybe_recut(3.0));  // every region changes
  // 1 and 3 deliver; 2 rebuilds its pool for 2.5 s: settle_seconds (2) + starve_seconds (0.75)
  // is its patience.
  EXPECT_TRUE(run(&c, 3.0, 5.5, {{1, 100000.0}, {3, 100000.0}}).empty());
  EXPECT_FALSE(c.members().at(2).starved);
  EXPECT_TRUE(run(&c, 5.5, 6.5, {{1, 100000.0}, {2, 100000.0}, {3, 100000.0}}).empty());
  // 2 stops for good: starved after its patience, which its 0.55 s of counted silence during
  // the restart raised a little above starve_seconds (1.5 x 0.55, fading).
  const std::vector<double> cuts = run(&c, 6.5, 8.0, {{1, 100000.0}, {3, 100000.0}});
  ASSERT_EQ(cuts.size(), 1u);
  EXPECT_GE(cuts[0], 6.5 + 0.75);
  EXPECT_LE(cuts[0], 6.5 + 1.5 * 0.55 + kPass + 1e-9);
  EXPECT_TRUE(c.members().at(2).starved);
}

// A sampler on a loaded machine delivers in bursts: after gaps of 0.65 s its patience is 1.5
// times that, so the next such gap, or a somewhat longer one, does not take its region. A
// member that never delivered has no such history: starve_seconds.
TEST(CoordinatorTest, ASamplerThatDeliversInBurstsGetsMorePatience) {
  Coordinator c(128, 128, ungathered());
  join_two(&c);
  run(&c, 0.0, 3.0, {{1, 100000.0}, {2, 100000.0}});
  double t = 3.0;
  for (int burst = 0; burst < 3; ++burst) {  // 2: nothing for 0.6 s, a batch 0.65 s after the last
    EXPECT_TRUE(run(&c, t, t + 0.6, {{1, 100000.0}}).empty());
    EXPECT_TRUE(run(&c, t + 0.6, t + 0.65, {{1, 100000.0}, {2, 100000.0}}).empty());
    t += 0.65;
  }
  EXPECT_NEAR(c.patience(c.members().at(2)), 1.5 * 0.65, 0.01);
  EXPECT_TRUE(run(&c, t, t + 0.8, {{1, 100000.0}}).empty());
  EXPECT_FALSE(c.members().at(2).starved);
  // A newcomer that sends nothing starves after starve_seconds all the same.
  const double joined = t + 0.8;
  const uint32_t n = join(&c, "silent", joined).id;
  EXPECT_DOUBLE_EQ(c.patience(c.members().at(n)), 0.75);
  const std::vector<double> cuts = run(&c, joined, joined + 1.0, {{1, 100000.0}, {2, 100000.0}});
  ASSERT_EQ(cuts.size(), 2u);  // its join, its starvation
  EXPECT_NEAR(cuts[1], joined + 0.75, kPass + 1e-9);
  EXPECT_TRUE(c.members().at(n).starved);
}

// A member that starves and returns over and over (a batch every 2 s) buys at most one
// immediate recut per recut_interval with its returns; the others' pools are not restarted at
// its pace. (No settling and no extra patience here, to see the rule alone.)
TEST(CoordinatorTest, ReturnsFromStarvingRecutAtOnceAtMostOncePerInterval) {
  CoordinatorOptions o;
  o.join_gather = 0.0;
  o.recut_interval = 10.0;
  o.settle_seconds = 0.0;
  o.starve_ceiling = o.starve_seconds;
  Coordinator c(128, 128, o);
  join_two(&c);
  run(&c, 0.0, 3.0, {{1, 100000.0}, {2, 100000.0}});
  std::vector<double> immediate;
  int returns = 0;
  for (int k = 1; k <= 400; ++k) {  // 3 s to 23 s
    const double t = 3.0 + k * kPass;
    c.heard(1, t);
    c.heard(2, t);
    c.add_samples(1, 5000, t);
    if (k % 40 == 0) c.add_samples(2, 128, t);
    bool returned = false;
    for (const auto& change : c.measure(t)) returned |= change.first == 2 && !change.second;
    returns += int(returned);
    if (c.maybe_recut(t) && returned) immediate.push_back(t);
  }
  EXPECT_EQ(returns, 10);
  ASSERT_EQ(immediate.size(), 2u);  // at 5 s, and 10 s later
  EXPECT_NEAR(immediate[0], 5.0, 1e-9);
  EXPECT_NEAR(immediate[1], 15.0, 1e-9);
}

}  // namespace
}  // namespace afr::service
