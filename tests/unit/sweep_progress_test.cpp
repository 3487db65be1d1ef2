// The progress line of the long seeded sweeps (tests/support/sweep_progress.hpp): pinned texts.
#include "../support/sweep_progress.hpp"

#include <gtest/gtest.h>

#include <chrono>

namespace {

using tgm::test::SweepProgress;

TEST(SweepProgress, LineNamesDoneTotalShareElapsedAndTimeLeft) {
  const SweepProgress p("RandomSweep seed 6901", 1000);
  EXPECT_EQ(p.line(140, 186.0),
            "RandomSweep seed 6901: 140 of 1000 programs (14 %), 3.1 min, about 19.0 min left");
  EXPECT_EQ(p.line(0, 12.0), "RandomSweep seed 6901: 0 of 1000 programs (0 %), 12 s");
  EXPECT_EQ(p.line(1000, 7300.0), "RandomSweep seed 6901: 1000 of 1000 programs (100 %), 2.0 h");
  const SweepProgress q("EngineStorm seed 3", 7, "storms");
  EXPECT_EQ(q.line(2, 10.0), "EngineStorm seed 3: 2 of 7 storms (28 %), 10 s, about 25 s left");
}

TEST(SweepProgress, DurationsSwitchUnitsAtHundredSecondsAndHundredMinutes) {
  EXPECT_EQ(SweepProgress::duration_text(0.4), "0 s");
  EXPECT_EQ(SweepProgress::duration_text(99.4), "99 s");
  EXPECT_EQ(SweepProgress::duration_text(100.0), "1.7 min");
  EXPECT_EQ(SweepProgress::duration_text(5999.0), "100.0 min");
  EXPECT_EQ(SweepProgress::duration_text(6000.0), "1.7 h");
}

TEST(SweepProgress, PrintsNothingBeforeItsIntervalHasPassed) {
  SweepProgress p("quiet", 10, "programs", std::chrono::hours(1));
  ::testing::internal::CaptureStderr();
  for (std::uint64_t k = 0; k <= 10; ++k) p.update(k);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  SweepProgress every("loud", 10, "programs", std::chrono::nanoseconds(0));
  ::testing::internal::CaptureStderr();
  every.update(5);
  const std::string out = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(out.rfind("loud: 5 of 10 programs (50 %), ", 0), 0u) << out;
}

}  // namespace
