// The M-function waits of a `tgm-hmi run`, counted from a stream of samples (tgm_event, or the
// state as the fall-back) for the run's summary. Header-only, no DDS (unit-tested).
#pragma once

#include <cstdint>

namespace tgm::hmi {

// Each record whose section waits for the PLC counts once; its time runs from the first sample
// that waits to the first that does not, or to the first of the next record that waits (an
// M-function right after another: M7 then M8 are waits of two records in a row, and the first
// one's time was lost, "2 M-function waits (0.868 s)" for two waits of a second each).
struct WaitCount {
  std::uint64_t waits = 0;
  std::uint64_t cycles = 0;
  std::uint64_t from = 0;  // cycle the current wait began; 0 = none
  std::int32_t part = -1;
  //! One sample: whether its section waits for the PLC, its Act_Part and its cycle counter.
  void see(bool waiting, std::int32_t at_part, std::uint64_t cycle) {
    if (waiting && at_part != part) {
      if (from != 0) cycles += cycle - from;  // the wait before ends where this one begins
      part = at_part;
      ++waits;
      from = cycle;
    } else if (!waiting && from != 0) {
      cycles += cycle - from;
      from = 0;
    }
  }
};

}  // namespace tgm::hmi
