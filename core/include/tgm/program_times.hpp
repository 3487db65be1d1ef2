// When each record of a program is done, from an offline run: what an HMI needs to show the
// time a running program has left and its progress by time rather than by records (a program
// of one long move and a thousand short ones is not 0.1 % done after its first minute).
//
// The run is a Simulation of the program with the machine's limits, so the times are the
// interpolator's own, cycle for cycle, as long as the machine runs as simulated: the same
// Rel_Speed, M-functions acknowledged after the times the options give, no operator stop and
// no wait for the operator (M0 restarts after SimulationOptions::m0_restart_s).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/simulation.hpp"

namespace tgm {

struct ProgramTimes {
  //! done_s[k]: the program time [s] at which record k (0-based) is done: a move's end (to
  //! the calculation step), the end of an M-function's wait or of a dwell (to the cycle), for a
  //! record that takes no time between two moves the start of the second. Non-decreasing.
  //! Floats, with length_mm and wait_s 12 bytes a record (a float resolves 4 ms at 9 hours).
  std::vector<float> done_s;
  //! length_mm[k]: the path length of record k [mm] (0 for a record that does not move).
  std::vector<float> length_mm;
  //! wait_s[k]: the program time [s] that records 0..k which do not move take together (an
  //! M-function's wait, a dwell): the part of done_s[k] a Rel_Speed change does not scale.
  std::vector<float> wait_s;
  //! Program time of the whole run [s] (SimulationSummary::program_time_s).
  double total_s = 0.0;

  //! Program time [s] elapsed when record `act_part` (Act_Part: 1-based, as the registers
  //! count) has run for `in_record_s` and moved `in_record_mm` along the path: what the
  //! records before it take, plus at most what it takes itself. Inside a move its share of
  //! that goes by the share of its length moved, which a feed override does not skew (by time
  //! alone, a long move at half the override read as done when it was half-way); by time where
  //! it does not move, or where in_record_mm is negative or NaN (not known). Past the last
  //! record, or with act_part beyond the program, total_s; 0 before the first.
  double elapsed_s(std::int64_t act_part, double in_record_s, double in_record_mm = -1.0) const;

  //! Program time [s] left at the point elapsed_s() places (the same arguments), with the
  //! moves taking `move_scale` times as long as simulated and the waits as long: at a Rel_Speed
  //! r against the r0 simulated, move_scale r0 / r. The moves' part is approximate (a ramp, or a
  //! speed an axis limit sets, does not scale with the feed); a dwell or an acknowledgement
  //! scaled with them made a 60 s dwell at half the override count 120 s.
  double left_s(std::int64_t act_part, double in_record_s, double in_record_mm,
                double move_scale) const;
};

//! Runs `program` through Simulation with `options` (its on_progress too: returning false
//! ends the run) and records when each record is done. nullopt, with the reason in `error`,
//! when the run does not end the program (an error, the time limit, interrupted).
std::optional<ProgramTimes> program_times(const MachineConfig& machine,
                                          const SimulationOptions& options,
                                          const PackedProgram& program,
                                          std::string* error = nullptr);

}  // namespace tgm
