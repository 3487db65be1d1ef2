// Cycle lateness statistics: how late each cycle started behind its absolute deadline. A fixed
// histogram (no allocation while recording): 1 us buckets up to 2 ms, then 100 us buckets up to
// 100 ms, then one overflow bucket.
#pragma once

#include <array>
#include <cstdint>

namespace tgm::service {

//! What the service publishes (InterpolatorState.lateness_*, missed_cycles).
struct LatenessStats {
  std::int64_t last_ns = 0;
  std::int64_t max_ns = 0;
  //! 99.9th percentile over all cycles so far (upper edge of its bucket) [ns].
  std::int64_t p999_ns = 0;
  std::uint64_t missed_cycles = 0;
  std::uint64_t cycles = 0;
};

class LatenessHistogram {
 public:
  static constexpr int kFine = 2000;    // 1 us buckets: 0 .. 2 ms
  static constexpr int kCoarse = 980;   // 100 us buckets: 2 .. 100 ms
  static constexpr int kBuckets = kFine + kCoarse + 1;

  void record(std::int64_t lateness_ns) {
    if (lateness_ns < 0) lateness_ns = 0;
    const std::int64_t us = lateness_ns / 1000;
    int b = 0;
    if (us < kFine) {
      b = static_cast<int>(us);
    } else if (us < kFine + kCoarse * 100) {
      b = kFine + static_cast<int>((us - kFine) / 100);
    } else {
      b = kBuckets - 1;
    }
    ++counts_[static_cast<std::size_t>(b)];
    ++total_;
    if (lateness_ns > max_ns_) max_ns_ = lateness_ns;
  }
  //! Upper edge [ns] of the bucket that holds quantile q (0..1); 0 when empty.
  std::int64_t quantile_ns(double q) const {
    if (total_ == 0) return 0;
    const auto rank = static_cast<std::uint64_t>(q * static_cast<double>(total_ - 1)) + 1;
    std::uint64_t seen = 0;
    for (int b = 0; b < kBuckets; ++b) {
      seen += counts_[static_cast<std::size_t>(b)];
      if (seen >= rank) return upper_edge_ns(b);
    }
    return max_ns_;
  }
  std::int64_t max_ns() const { return max_ns_; }
  std::uint64_t total() const { return total_; }

 private:
  static std::int64_t upper_edge_ns(int b) {
    if (b < kFine) return (static_cast<std::int64_t>(b) + 1) * 1000;
    if (b < kFine + kCoarse) return (kFine + (static_cast<std::int64_t>(b - kFine) + 1) * 100) * 1000;
    return INT64_MAX;
  }
  std::array<std::uint64_t, kBuckets> counts_{};
  std::uint64_t total_ = 0;
  std::int64_t max_ns_ = 0;
};

}  // namespace tgm::service
