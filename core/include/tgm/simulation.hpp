// Offline run of a whole program through one interpolator: what `tgm-hmi simulate`, the motion
// tests and the benchmarks share. No clock: it calls step() (or Interpolator::advance, which
// skips cycles where nothing changes qualitatively) as fast as it can, streams the
// program into the ring buffer as slots free up, plays the PLC (acknowledges each normal
// M-function after a configurable time, restarts after M0) and optionally checks the limits.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/intercode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/limit_checker.hpp"

namespace tgm {

//! Where a run is, for a progress display.
struct SimulationProgress {
  std::uint64_t cycles = 0;     //!< cycles run so far
  double program_time_s = 0.0;  //!< cycles x Cycle_Time
  std::int32_t act_part = 0;    //!< Act_Part: 1-based ordinal of the executing record
  std::int32_t act_line = 0;    //!< its source line
  std::size_t records = 0;      //!< records in the program
};

//! How the offline run behaves.
struct SimulationOptions {
  int interpolator = 0;
  //! Rel_Speed at start, 0.01..2.
  double rel_speed = 1.0;
  //! Rel_Speed changes at given times [s].
  std::vector<std::pair<double, double>> rel_speed_changes;
  //! Time the emulated PLC takes per normal M-function [s], and per M number.
  double m_ack_s = 0.1;
  std::map<int, double> m_ack_by_number;
  //! Time after an M0 pause until the emulated operator presses start [s].
  double m0_restart_s = 0.0;
  //! Stops given at program times [s] (sorted by time when run), each Command 8 (normal stop)
  //! or 4 (emergency stop), both on the trajectory: what an operator's feed hold or emergency
  //! button does at that moment. Once the motion stands, the emulated operator presses start
  //! after `stop_restart_s`. A stop given while the motion stands (M wait, dwell, M0 pause)
  //! takes effect at once, as on the machine; one given after the end does nothing.
  std::vector<std::pair<double, std::int32_t>> stops;
  double stop_restart_s = 0.5;
  //! Where the interpolator stands when the program starts [mm] (set_position, as Command
  //! 2048 would; machine zero by default): compile the program from the same point
  //! (CompileOptions::start_mm), as tgm-hmi run compiles from where the machine stands.
  std::array<double, kMaxAxes> start_mm{};
  //! Run the limit checker (records corner events).
  bool check_limits = false;
  //! The part of each limit the checker holds the motion to (LimitChecker::create).
  double limit_share = 1.0;
  //! Give up after this much program time [s] (> 0; SimulationSummary::time_limit_reached).
  double max_time_s = 24.0 * 3600.0;
  //! When run() has no per-cycle callback, advance through cruise, dwells, M waits and
  //! standstill with Interpolator::advance (same registers, far fewer evaluations; the limit
  //! checker sees each of those cycles through the interpolator's cycle trace).
  //! false = step() every cycle (what the equivalence tests compare against).
  bool fast_forward = true;
  //! Commands given before the program starts, in order, with their Command_Parameter (e.g.
  //! {-2, {200, 1000000}} for the spline, {-1, {p, q, f, mask}} for the IIR filter); a refusal
  //! makes create() fail with the reason.
  std::vector<std::pair<std::int32_t, std::array<std::int32_t, kCommandParameters>>> commands;
  //! Called every kProgressPasses passes of the run loop (each one step() or one advance()),
  //! i.e. every few milliseconds of wall time; returning false ends the run there (result
  //! kWorking, error "interrupted"). Core reads no clock: the caller decides what to show when.
  std::function<bool(const SimulationProgress&)> on_progress;
  static constexpr std::uint64_t kProgressPasses = 1024;
  //! Called after each pass of the run loop in which Act_Part changed (after the pass's block
  //! reports), with the new Act_Part and the program time at the pass's end [s]: the records
  //! before it are done by then. A pass is one cycle, or a run of cycles advance() skipped.
  std::function<void(std::int32_t act_part, double program_time_s)> on_part;
  //! Largest max_time_s [s] (about 31 years of program time).
  static constexpr double kMaxTimeS = 1e9;
};

//! Outcome of a run.
struct SimulationSummary {
  StepResult result = StepResult::kWorking;  //!< kFinished when the program ended normally
  std::string error;                          //!< why it did not finish (empty when it did)
  std::uint64_t cycles = 0;
  double program_time_s = 0.0;  //!< until Status 3
  double distance_mm = 0.0;     //!< Move_Distance at the end
  //! Highest path speed [mm/min]: the block reports' peaks and Act_Speed of every cycle (so a
  //! run that ends inside a block, interrupted or at the time limit, has it too).
  double peak_speed_mm_min = 0.0;
  bool time_limit_reached = false;  //!< ended by SimulationOptions::max_time_s
  //! Orig_Position at the end (before smoothing) [mm].
  std::array<double, kMaxAxes> end_position{};
  //! Position at the end (after spline / IIR) [mm]; the run ends (Status 3) only once every
  //! axis stands there, so it equals end_position unless the program was not finished.
  std::array<double, kMaxAxes> end_position_smoothed{};
  //! Largest spline contour deviation [mm] (SplineStats::max_mm; 0 with the spline off).
  double spline_deviation_mm = 0.0;
  bool nan = false;             //!< a NaN / inf appeared in a register
  std::uint64_t hard_stops = 0;
  std::uint64_t m_functions = 0;  //!< normal M-functions acknowledged
  std::uint64_t stops = 0;        //!< SimulationOptions::stops given before the end
  //! Time [s] during which each LimitFactor limited the path speed (indexed by the enum value).
  std::array<double, 11> factor_time_s{};
  //! Limit checker (when enabled).
  std::array<AxisPeaks, kMaxAxes> peaks{};
  std::uint64_t violation_count = 0;
  std::vector<LimitViolation> violations;
  //! With the limit checker on and the spline or IIR filter on, or an axis with backlash: the
  //! peaks of the drive setpoint, Position after the smoothing plus the backlash compensation
  //! (|v| from Speed plus the compensation's rate, |a| from its change per cycle; jerk and
  //! corner steps 0). The checker holds Orig_Position to the limits; an IIR filter below
  //! critical damping overshoots them here (|v| 356 against 250 mm/s, said as "violations: 0",
  //! session 75), which the summary says; a backlash ramp adds its share on top of the motion,
  //! which the planner leaves free (planned_limit_share).
  bool smoothed_measured = false;
  std::array<AxisPeaks, kMaxAxes> smoothed_peaks{};
};

//! One offline run.
class Simulation {
 public:
  static std::optional<Simulation> create(const MachineConfig& machine, const SimulationOptions& options,
                                          std::string* error = nullptr);

  //! Runs `program` (kept by reference until run() returns) to its end.
  //! `on_cycle` sees the registers after every cycle, `on_block` every completed block.
  SimulationSummary run(const Program& program,
                        const std::function<void(const Registers&)>& on_cycle = {},
                        const std::function<void(const BlockReport&)>& on_block = {});
  //! The same for a program held as intercode: its records are decoded as the ring takes them,
  //! a buffer's worth at a time, so a run holds about 20 bytes a record instead of 152. The
  //! same run to the bit as run() of the decoded Program.
  SimulationSummary run(const PackedProgram& program,
                        const std::function<void(const Registers&)>& on_cycle = {},
                        const std::function<void(const BlockReport&)>& on_block = {});

  Interpolator& interpolator() { return *ip_; }
  const LimitChecker* checker() const { return checker_ ? &*checker_ : nullptr; }

 private:
  Simulation() = default;
  //! Appends records [next, next + count) of the program; `last`: they end it.
  using AppendRecords = std::function<RequestResult(
      Interpolator&, std::size_t next, std::size_t count, bool last, std::size_t* took)>;
  SimulationSummary run_records(std::size_t total, const AppendRecords& append,
                                const std::function<void(const Registers&)>& on_cycle,
                                const std::function<void(const BlockReport&)>& on_block);
  SimulationOptions opt_;
  int cycle_time_us_ = 500;
  std::optional<Interpolator> ip_;
  std::optional<LimitChecker> checker_;
};

}  // namespace tgm
