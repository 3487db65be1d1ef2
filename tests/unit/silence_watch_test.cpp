// SilenceWatch (client/lib/include/tgm/client/silence_watch.hpp): tgm-plc and tgm-hmi say once
// when the service's state stops coming and once when it comes back.
#include <gtest/gtest.h>

#include <chrono>

#include "tgm/client/silence_watch.hpp"

namespace tgm::client {
namespace {

using namespace std::chrono_literals;
using Change = SilenceWatch::Change;

TEST(SilenceWatch, SaysOnceWhenTheStateStopsAndOnceWhenItComesBack) {
  const std::chrono::steady_clock::time_point t0{};
  SilenceWatch w(3s);
  EXPECT_EQ(w.update(7, t0), Change::kNone);  // the first call takes the count
  EXPECT_EQ(w.update(9, t0 + 1s), Change::kNone);
  EXPECT_EQ(w.update(9, t0 + 4s), Change::kNone);  // 3 s since the last new sample, not more
  EXPECT_FALSE(w.silent());
  EXPECT_EQ(w.update(9, t0 + 4s + 1ms), Change::kSilent);
  EXPECT_TRUE(w.silent());
  EXPECT_EQ(w.update(9, t0 + 10s), Change::kNone);  // said once
  EXPECT_TRUE(w.silent());
  EXPECT_EQ(w.since_last(t0 + 10s), 9s);
  EXPECT_EQ(w.seconds_since_last(t0 + 10s + 999ms), 9);
  EXPECT_EQ(w.update(10, t0 + 11s), Change::kBack);
  EXPECT_FALSE(w.silent());
  EXPECT_EQ(w.since_last(t0 + 11s + 5ms), 5ms);
  EXPECT_EQ(w.update(11, t0 + 12s), Change::kNone);
  EXPECT_EQ(w.update(11, t0 + 15s + 1ms), Change::kSilent);  // a second silence is said again
}

TEST(SilenceWatch, LastedIsSaidOncePerSilence) {
  const std::chrono::steady_clock::time_point t0{};
  SilenceWatch w(3s);
  EXPECT_EQ(w.update(1, t0), Change::kNone);
  EXPECT_FALSE(w.lasted(5s, t0 + 6s));  // not silent yet: update() has not said so
  EXPECT_EQ(w.update(1, t0 + 4s), Change::kSilent);
  EXPECT_FALSE(w.lasted(5s, t0 + 4s));
  EXPECT_TRUE(w.lasted(5s, t0 + 5s));
  EXPECT_FALSE(w.lasted(5s, t0 + 20s));  // said once
  EXPECT_EQ(w.update(2, t0 + 21s), Change::kBack);
  EXPECT_EQ(w.update(2, t0 + 24s + 1ms), Change::kSilent);
  EXPECT_TRUE(w.lasted(5s, t0 + 26s));  // a second silence is said again
}

TEST(SilenceWatch, ACountThatNeverComesIsSilenceFromTheFirstCall) {
  const std::chrono::steady_clock::time_point t0{};
  SilenceWatch w(3s);
  EXPECT_EQ(w.update(0, t0 + 2s), Change::kNone);
  EXPECT_EQ(w.update(0, t0 + 5s), Change::kNone);
  EXPECT_EQ(w.update(0, t0 + 5s + 1ms), Change::kSilent);
}

}  // namespace
}  // namespace tgm::client
