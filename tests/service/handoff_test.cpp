// The lock-free hand-off structures between the cycle thread and the DDS threads, and the
// lateness histogram.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "tgm/service/lateness.hpp"
#include "tgm/service/latest_value.hpp"
#include "tgm/service/port.hpp"
#include "tgm/service/spsc_queue.hpp"

namespace tgm::service {
namespace {

// The texts the ports hand over (reasons, errors, client names): cut to capacity, always
// terminated. An empty view may carry a null data(), which the service passes for "no error":
// copying from it was undefined (UBSan stopped the service at its first accepted reply).
TEST(FixedText, TakesEmptyNullAndLongTexts) {
  FixedText<8> t;
  t.set("abc");
  EXPECT_EQ(t.view(), "abc");
  t.set(std::string_view{});
  EXPECT_EQ(t.view(), "");
  t.set("0123456789");
  EXPECT_EQ(t.view(), "0123456");  // N - 1 characters and the terminator
  t.set("");
  EXPECT_EQ(t.view(), "");
}

TEST(SpscQueue, KeepsOrderAndRefusesWhenFull) {
  SpscQueue<int> q(4);
  EXPECT_EQ(q.capacity(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(q.push(i));
  EXPECT_FALSE(q.push(9));
  EXPECT_TRUE(q.full());
  int v = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(q.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(q.pop(v));
}

TEST(SpscQueue, TwoThreadsPassValuesInOrder) {
  SpscQueue<std::uint64_t> q(64);
  constexpr std::uint64_t kCount = 200'000;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kCount;) {
      if (q.push(i)) {
        ++i;
      } else {
        std::this_thread::yield();
      }
    }
  });
  std::uint64_t expected = 0;
  bool ordered = true;
  while (expected < kCount) {
    std::uint64_t v = 0;
    if (q.pop(v)) {
      ordered = ordered && v == expected;
      ++expected;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_TRUE(ordered);
}

struct Pair {
  std::uint64_t a = 0;
  std::uint64_t b = 0;
};

TEST(LatestValue, ReaderAlwaysSeesACompleteAndNewerValue) {
  LatestValue<Pair> lv;
  const Pair* p = nullptr;
  EXPECT_FALSE(lv.read(p));
  lv.write_slot() = {1, 1};
  lv.publish();
  lv.write_slot() = {2, 2};
  lv.publish();
  ASSERT_TRUE(lv.read(p));
  EXPECT_EQ(p->a, 2u);  // the newest wins
  EXPECT_FALSE(lv.read(p));

  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::uint64_t i = 3; i < 100'000; ++i) {
      lv.write_slot() = {i, i};
      lv.publish();
      if (i % 64 == 0) std::this_thread::yield();
    }
    done = true;
  });
  std::uint64_t last = 2;
  bool ok = true;
  while (!done || lv.read(p)) {
    if (lv.read(p)) {
      ok = ok && p->a == p->b && p->a > last;
      last = p->a;
    } else {
      std::this_thread::yield();
    }
  }
  writer.join();
  EXPECT_TRUE(ok);
}

TEST(LatenessHistogram, QuantilesAtBucketEdges) {
  LatenessHistogram h;
  EXPECT_EQ(h.quantile_ns(0.999), 0);
  for (int i = 0; i < 999; ++i) h.record(10'500);  // 10.5 us -> bucket 10..11 us
  h.record(5'000'000);                              // one 5 ms outlier
  EXPECT_EQ(h.quantile_ns(0.5), 11'000);
  EXPECT_EQ(h.quantile_ns(0.999), 11'000);
  EXPECT_EQ(h.quantile_ns(1.0), 5'100'000);  // upper edge of the 100 us bucket
  EXPECT_EQ(h.max_ns(), 5'000'000);
  h.record(-5);  // early wake-ups count as on time
  EXPECT_EQ(h.total(), 1001u);
}

}  // namespace
}  // namespace tgm::service
