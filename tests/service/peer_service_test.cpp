// Which of two tgm-services on one domain gives way (tgm/service/peer_service.hpp): pinned
// cases, and a seeded sweep of two services that start close together and each decide once,
// from a sample of the other that is some cycles old, at some moment of its own first cycles.
#include <gtest/gtest.h>

#include <cstdlib>
#include <random>
#include <string>

#include "tgm/service/peer_service.hpp"

namespace tgm::service {
namespace {

constexpr std::uint64_t kWindow = 10'000;

TEST(PeerService, PinnedCases) {
  // Same age: the higher instance gives way, the lower does not.
  EXPECT_TRUE(gives_way(500, 9, 480, 4, kWindow));
  EXPECT_FALSE(gives_way(480, 4, 500, 9, kWindow));
  // The other has run more than a fifth of the window longer: give way whatever the instances.
  EXPECT_TRUE(gives_way(100, 1, 2'101, 9, kWindow));
  EXPECT_FALSE(gives_way(100, 1, 2'100, 9, kWindow));
  // This one is that much older: it stays, even with the higher instance.
  EXPECT_FALSE(gives_way(2'101, 9, 100, 1, kWindow));
  EXPECT_TRUE(gives_way(2'100, 9, 100, 1, kWindow));
  // Past the window nobody gives way; window 0 never.
  EXPECT_FALSE(gives_way(kWindow, 9, kWindow + 50'000, 1, kWindow));
  EXPECT_FALSE(gives_way(0, 9, 0, 1, 0));
}

// Two services (same cycle time) start up to 1,000 cycles apart. Each first sees the other at
// some moment of its first 12,100 cycles (discovery), from a sample up to 100 cycles old. The
// counts of both grow alike, so their difference does not depend on the moments: never do both
// give way, and when both decide young exactly one does (their ages differ by less than the
// margin less the lags, so the instances decide).
TEST(PeerService, SeededSweepNeverBothAndExactlyOneOfTwoYoungOnes) {
  const char* env_seed = std::getenv("TGM_PEER_SEED");
  const std::uint32_t seed =
      env_seed ? static_cast<std::uint32_t>(std::strtoul(env_seed, nullptr, 10)) : 1;
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::uint64_t> start(0, 1'000), moment(0, 12'000), lag(0, 100),
      id(1, 1'000);
  const auto count = [](std::uint64_t since, std::uint64_t t) { return t > since ? t - since : 0; };
  int one = 0, young = 0;
  const int cases = 200'000;
  for (int k = 0; k < cases; ++k) {
    const std::uint64_t a0 = start(rng), b0 = start(rng);  // start cycles on a common clock
    const std::uint64_t ia = id(rng), drawn = id(rng), ib = drawn == ia ? ia + 1'000 : drawn;
    // A sample is at least as new as the other's start: decisions come 100 cycles after both.
    const std::uint64_t ta = std::max(a0, b0) + 100 + moment(rng),
                        tb = std::max(a0, b0) + 100 + moment(rng);
    const std::uint64_t la = lag(rng), lb = lag(rng);
    const bool a_gives = gives_way(count(a0, ta), ia, count(b0, ta - la), ib, kWindow);
    const bool b_gives = gives_way(count(b0, tb), ib, count(a0, tb - lb), ia, kWindow);
    ASSERT_FALSE(a_gives && b_gives) << "case " << k << " of seed " << seed << ": starts " << a0
                                     << ", " << b0 << ", decisions " << ta << ", " << tb;
    one += a_gives || b_gives;
    if (count(a0, ta) < kWindow && count(b0, tb) < kWindow) {
      ++young;
      ASSERT_TRUE(a_gives || b_gives) << "case " << k << " of seed " << seed;
    }
  }
  EXPECT_GT(young, cases / 2);
  EXPECT_GT(one, cases / 2);  // otherwise both stay and report (old samples, past the window)
}

}  // namespace
}  // namespace tgm::service
