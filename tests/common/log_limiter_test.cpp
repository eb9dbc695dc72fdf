#include <afr/common/log.h>

#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace afr {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

TEST(LogLimiterTest, OneLinePerCausePerIntervalCountingWhatItStandsFor) {
  LogLimiter limiter(std::chrono::seconds(1));
  const Clock::time_point t0 = Clock::now();
  // The first event of a cause gets a line at once.
  EXPECT_EQ(limiter.due("a", t0), 1u);
  // 99 more within the second: no line, counted.
  for (int i = 1; i < 100; ++i) EXPECT_EQ(limiter.due("a", t0 + milliseconds(i * 5)), 0u);
  // Another cause is not held back by the first.
  EXPECT_EQ(limiter.due("b", t0 + milliseconds(600)), 1u);
  // A second on: the line stands for the 99 held back and this one.
  EXPECT_EQ(limiter.due("a", t0 + milliseconds(1000)), 100u);
  EXPECT_EQ(limiter.due("a", t0 + milliseconds(1500)), 0u);
  EXPECT_EQ(limiter.due("a", t0 + milliseconds(2100)), 2u);
}

TEST(LogLimiterTest, FlushLogsTheEndOfAFloodOnceItsIntervalHasPassed) {
  LogLimiter limiter(std::chrono::seconds(1));
  const Clock::time_point t0 = Clock::now();
  EXPECT_EQ(limiter.due("a", t0), 1u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(limiter.due("a", t0 + milliseconds(10)), 0u);
  std::vector<std::pair<std::string, uint64_t>> flushed;
  const auto collect = [&](const std::string& cause, uint64_t n) {
    flushed.emplace_back(cause, n);
  };
  limiter.flush(collect, t0 + milliseconds(500));  // too early: the line is not a second old
  EXPECT_TRUE(flushed.empty());
  limiter.flush(collect, t0 + milliseconds(1000));
  ASSERT_EQ(flushed.size(), 1u);
  EXPECT_EQ(flushed[0], std::make_pair(std::string("a"), uint64_t(50)));
  limiter.flush(collect, t0 + milliseconds(5000));  // nothing held back since
  EXPECT_EQ(flushed.size(), 1u);
  // The flush counts as the cause's line: the next event within the second is held back.
  EXPECT_EQ(limiter.due("a", t0 + milliseconds(1500)), 0u);
}

TEST(LogLimiterTest, CausesAreBoundedAndTheRestShareOne) {
  LogLimiter limiter(std::chrono::seconds(1), 4);
  const Clock::time_point t0 = Clock::now();
  for (int i = 0; i < 4; ++i) EXPECT_EQ(limiter.due("cause " + std::to_string(i), t0), 1u);
  // 1000 made-up causes: one line for all of them, and the state stays at five causes.
  uint64_t lines = 0;
  for (int i = 4; i < 1004; ++i) lines += limiter.due("cause " + std::to_string(i), t0) > 0;
  EXPECT_EQ(lines, 1u);
  EXPECT_EQ(limiter.causes(), 5u);
  EXPECT_EQ(limiter.due("cause 5000", t0 + milliseconds(1000)), 1000u);
}

TEST(LogLimiterTest, CauseOfBlanksNumbersAndIsShort) {
  EXPECT_EQ(LogLimiter::cause_of("message: unknown type 7"), "message: unknown type #");
  EXPECT_EQ(LogLimiter::cause_of("message: unknown type 1234"),
            LogLimiter::cause_of("message: unknown type 9"));
  EXPECT_EQ(LogLimiter::cause_of("batch.samples[12]: 3.5e7 is not finite"),
            "batch.samples[#]: #.#e# is not finite");
  EXPECT_EQ(LogLimiter::cause_of(std::string(500, 'x')).size(), 80u);
}

TEST(LogBudgetTest, LinesUpToTheBudgetThenTheRestSummedInALineASecond) {
  LogBudget budget(3, std::chrono::seconds(1));
  const Clock::time_point t0 = Clock::now();
  std::vector<uint64_t> flushed;
  const auto flush = [&](Clock::time_point now) {
    budget.flush([&](uint64_t n) { flushed.push_back(n); }, now);
  };
  flush(t0);  // nothing held back: no line
  EXPECT_TRUE(flushed.empty());
  // Three events of the second get their lines, the next five do not.
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(budget.take(t0 + milliseconds(i)));
  for (int i = 3; i < 8; ++i) EXPECT_FALSE(budget.take(t0 + milliseconds(i * 100)));
  // The first sum comes at once; the next no sooner than a second later.
  flush(t0 + milliseconds(750));
  EXPECT_EQ(flushed, std::vector<uint64_t>{5});
  EXPECT_FALSE(budget.take(t0 + milliseconds(800)));
  flush(t0 + milliseconds(1000));
  EXPECT_EQ(flushed.size(), 1u);
  // The next second has its own lines.
  EXPECT_TRUE(budget.take(t0 + milliseconds(1100)));
  EXPECT_TRUE(budget.take(t0 + milliseconds(1200)));
  flush(t0 + milliseconds(1750));
  EXPECT_EQ(flushed, (std::vector<uint64_t>{5, 1}));
  flush(t0 + milliseconds(3000));  // nothing held back since
  EXPECT_EQ(flushed.size(), 2u);
}

}  // namespace
}  // namespace afr
