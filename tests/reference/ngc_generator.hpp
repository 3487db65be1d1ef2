// Seeded generator of G-code programs in the subset our dialect shares with RS274/NGC:
// G0/G1, G2/G3 by IJK (incl. full circles) and by R (incl. R < 0), planes G17/G18/G19,
// helices, G90/G91 switches, G92 offsets, F words, comments, N words, case and spacing
// variations. Every arc is consistent (end radius equals start radius to ~1e-4 mm) so both
// interpreters accept it. The same seed gives the same text on every platform (no <random>
// distributions, whose output is implementation-defined).
#pragma once

#include <cstdint>
#include <string>

#include "../support/splitmix64.hpp"

namespace tgm::ref {

//! Small, portable PRNG (tests/support/splitmix64.hpp) with the generator's draws.
struct Rng : tgm::test::SplitMix64 {
  explicit Rng(std::uint64_t seed) : SplitMix64{seed} {}
  //! Uniform integer in [lo, hi].
  int range(int lo, int hi) {
    return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool chance(double p) { return unit() < p; }
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
