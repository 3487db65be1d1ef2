// The M-function waits of `tgm-hmi run`'s summary (client/hmi/wait_count.hpp), fed with the
// samples of the event topic as the run sees them.
#include "wait_count.hpp"

#include <gtest/gtest.h>

namespace tgm::hmi {
namespace {

TEST(WaitCount, AWaitRunsFromItsFirstWaitingSampleToTheFirstThatIsNot) {
  WaitCount w;
  w.see(false, 1, 50);   // moving: no wait
  w.see(true, 2, 100);   // M51 waits
  w.see(true, 2, 150);   // another sample of the same wait
  w.see(false, 3, 300);  // acknowledged
  w.see(false, 3, 310);
  EXPECT_EQ(w.waits, 1u);
  EXPECT_EQ(w.cycles, 200u);
  EXPECT_EQ(w.from, 0u);
}

// M7 then M8, each waiting a second: the first sample of M8's wait ends M7's. Its time was
// dropped, and the summary said "2 M-function waits (0.868 s)" where the watch showed 0.74 s
// and 0.87 s of cycles (review of session 76, F8; the cycles of that run).
TEST(WaitCount, AWaitDirectlyAfterAnotherEndsItAndBothCount) {
  WaitCount w;
  w.see(true, 2, 2533);  // M7
  w.see(true, 2, 3000);
  w.see(true, 3, 4011);   // M8, right after
  w.see(false, 4, 5752);  // acknowledged, the motion goes on
  EXPECT_EQ(w.waits, 2u);
  EXPECT_EQ(w.cycles, (4011u - 2533u) + (5752u - 4011u));
  // Three in a row, and the last still waiting at the end: counted, its time open in `from`.
  WaitCount three;
  three.see(true, 5, 1000);
  three.see(true, 6, 1100);
  three.see(true, 7, 1300);
  EXPECT_EQ(three.waits, 3u);
  EXPECT_EQ(three.cycles, 300u);
  EXPECT_EQ(three.from, 1300u);
}

}  // namespace
}  // namespace tgm::hmi
