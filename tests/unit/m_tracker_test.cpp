// tgm-plc's M-function tracker (client/plc/m_tracker.hpp): each M-function the service numbered
// is claimed once, whichever topic shows it first and in whatever order the two threads see
// their samples; a restarted service starts afresh, and a sample of the service it replaced
// says nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "../support/splitmix64.hpp"
#include "m_tracker.hpp"

namespace tgm::plc {
namespace {

constexpr std::uint64_t kA = 0x1111;  // service instances
constexpr std::uint64_t kB = 0x2222;

TEST(MTracker, EachCountIsClaimedOnceAlsoForEqualMFunctions) {
  MTracker t;
  EXPECT_FALSE(t.claim(0, kA, 0, 0));     // nothing announced yet
  EXPECT_TRUE(t.claim(0, kA, 1, 1001));   // the event
  EXPECT_FALSE(t.claim(0, kA, 1, 1001));  // the state of the same cycle
  EXPECT_TRUE(t.claim(0, kA, 2, 1001));   // the same M again, next cycle: another M-function
  EXPECT_FALSE(t.claim(0, kA, 2, 0));     // noted: M_Func 0, nothing to claim
  EXPECT_TRUE(t.claim(0, kA, 3, 50));
  EXPECT_FALSE(t.claim(0, kA, 3, 50));  // still waiting for the acknowledgement
  // Interpolators are apart.
  EXPECT_TRUE(t.claim(1, kA, 3, 50));
  EXPECT_TRUE(t.claim(2, kA, 1, 51));
}

TEST(MTracker, AnOlderSampleClaimsOnlyWhatNobodyClaimed) {
  MTracker t;
  EXPECT_TRUE(t.claim(0, kA, 7, 1001));
  // The state of count 9 is taken before the event of count 8 (two threads, two topics).
  EXPECT_TRUE(t.claim(0, kA, 9, 50));
  EXPECT_TRUE(t.claim(0, kA, 8, 1002));
  EXPECT_FALSE(t.claim(0, kA, 8, 1002));
  EXPECT_FALSE(t.claim(0, kA, 7, 1001));
  // A count more than 64 behind the newest is history.
  EXPECT_TRUE(t.claim(0, kA, 200, 51));
  EXPECT_FALSE(t.claim(0, kA, 100, 51));
}

TEST(MTracker, ARestartedServiceStartsAfreshAndTheOldOneSaysNothing) {
  MTracker t;
  EXPECT_TRUE(t.claim(0, kA, 40, 50));
  // The new service counts from 1 again: its M-functions are new although the counts are lower.
  EXPECT_TRUE(t.claim(0, kB, 1, 50));
  // The main loop still holds the old service's last state: not claimed, and it must not make
  // the tracker forget what it claimed of the new one.
  EXPECT_FALSE(t.claim(0, kA, 41, 51));
  EXPECT_FALSE(t.claim(0, kB, 1, 50));
  EXPECT_TRUE(t.claim(0, kB, 2, 1001));
}

// Seeded sweep: every count of a random announcement sequence, delivered twice (event and state)
// in a random interleaving with bounded reordering, is claimed exactly once.
TEST(MTracker, RandomInterleavingsClaimEveryCountOnce) {
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    test::SplitMix64 rng{seed};
    const std::uint32_t n = 1 + static_cast<std::uint32_t>(rng.next() % 300);
    struct Sample {
      std::uint32_t count;
      std::int32_t m;
    };
    std::vector<Sample> samples;
    for (std::uint32_t c = 1; c <= n; ++c) {
      const std::int32_t m = rng.unit() < 0.5 ? 50 : 1001;
      samples.push_back({c, m});
      samples.push_back({c, m});
      if (rng.unit() < 0.3) samples.push_back({c, 0});  // acknowledged by the next sample
    }
    // Reorder within a window of 8 samples (the two threads drift apart by a few samples).
    for (std::size_t i = 0; i + 1 < samples.size(); ++i) {
      const std::size_t j = i + rng.next() % std::min<std::size_t>(8, samples.size() - i);
      std::swap(samples[i], samples[j]);
    }
    MTracker t;
    std::vector<int> claimed(n + 1, 0);
    for (const Sample& s : samples) {
      if (t.claim(0, kA, s.count, s.m)) ++claimed[s.count];
    }
    for (std::uint32_t c = 1; c <= n; ++c) {
      ASSERT_EQ(claimed[c], 1) << "seed " << seed << " count " << c;
    }
  }
}

// A script's refuse_ack applies to the interpolator its step names (a step for interpolator 1
// refused M51 on all three); --refuse-ack to every one.
TEST(RefusedM, AScriptRefusalIsForItsInterpolatorAndTheFlagsForAll) {
  RefusedM r;
  r.refuse(1, 51);
  EXPECT_TRUE(r.refused(1, 51));
  EXPECT_FALSE(r.refused(0, 51));
  EXPECT_FALSE(r.refused(2, 51));
  EXPECT_FALSE(r.refused(1, 50));
  r.refuse_everywhere(60);
  for (int i = 0; i < kMaxInterpolators; ++i) EXPECT_TRUE(r.refused(i, 60)) << i;
  // Numbers outside 0..2 change nothing and are never refused (no out-of-range access).
  r.refuse(-1, 70);
  r.refuse(kMaxInterpolators, 70);
  for (int i = -1; i <= kMaxInterpolators; ++i) EXPECT_FALSE(r.refused(i, 70)) << i;
}

}  // namespace
}  // namespace tgm::plc
