// The seeded generator the test-side program generators and the fuzz driver share: splitmix64,
// the same stream on every platform (no <random> distributions, whose output is
// implementation-defined). Header-only, no dependencies.
#pragma once

#include <cstdint>

namespace tgm::test {

//! splitmix64; `s` is the whole state (aggregate: `SplitMix64{seed}`).
struct SplitMix64 {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  //! Uniform in [0, 1) from the top 53 bits.
  double unit() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  //! Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
};

}  // namespace tgm::test
