// Seeded generator of G-code programs in the subset our dialect shares with RS274/NGC:
// G0/G1, G2/G3 by IJK (incl. full circles) and by R (incl. R < 0), planes G17/G18/G19,
// helices, G90/G91 switches, G92 offsets, F words, comments, N words, case and spacing
// variations. Every arc is consistent (end radius equals start radius to ~1e-4 mm) so both
// interpreters accept it. The same seed gives the same text on every platform (no <random>
// distributions, whose output is implementation-defined).
#pragma once

#include <cstdint>
#include <string>

namespace tgm::ref {

//! Small, portable PRNG (splitmix64).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  //! Uniform in [0, 1).
  double unit() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  //! Uniform integer in [lo, hi].
  int range(int lo, int hi) {
    return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool chance(double p) { return unit() < p; }

 private:
  std::uint64_t s_;
};

//! What a generated program looks like.
struct GeneratedProgram {
  std::string text;
  //! The program's first line states G91 (true) or G90 (false).
  bool starts_incremental = false;
  int lines = 0;
};

//! A program of about `lines` lines (first line states G90 or G91, last line is M2).
GeneratedProgram generate_reference_program(std::uint64_t seed, int lines);

}  // namespace tgm::ref
