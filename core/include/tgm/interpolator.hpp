// The cycle interpolator: ring buffer of intercode records, look-ahead planner, jerk-limited path
// velocity generator, registers (manual: Interpolator). Design and decisions: core/MOTION.md.
//
// Usage: create() once (allocates everything), then call step() once per Cycle_Time. Requests
// (append, start, stop, M_Func acknowledge, Rel_Speed, ...) are made between two step() calls by
// the same thread; each returns a code and a reason the service can forward. step() never
// allocates, never blocks and never reads a clock.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "tgm/config.hpp"
#include "tgm/intercode.hpp"
#include "tgm/registers.hpp"

namespace tgm {

class SmoothingStage;
class OutputStage;

//! Result of one step() (STYLE.md: Working = 0, Finished = 1, errors negative).
enum class StepResult : std::int8_t {
  kWorking = 0,   //!< moving, dwelling or about to continue on its own
  kFinished = 1,  //!< the program ended (Status 3)
  kWaiting = 2,   //!< waiting for a request: M_Func = 0, start (M0, after a stop), more segments
  kIdle = 3,      //!< nothing to do: empty, or standing after a stop / emergency stop
  kErrorInternal = -1,  //!< an invariant broke (never expected; the registers stay consistent)
};

//! Outcome class of a request.
enum class RequestCode : std::int8_t {
  kAccepted = 0,
  kOutOfRange = -1,  //!< a value outside its documented range
  kWrongState = -2,  //!< not allowed in the current Status
  kBufferFull = -3,  //!< the ring buffer has no free slot for the records
  kInvalid = -4,     //!< malformed data (NaN, bad index, axis not configured, ...)
  kUnsupported = -5,  //!< a Command the core does not implement (yet)
};

//! Reply to a request: a code plus a reason the service forwards to the client.
struct RequestResult {
  RequestCode code = RequestCode::kAccepted;
  std::string reason;
  bool ok() const { return code == RequestCode::kAccepted; }
};

//! A deliberate velocity / acceleration step of the axes where two segments meet (a corner
//! within the per-axis tolerance, or a curvature change). Recorded only when
//! `InterpolatorOptions::record_corner_events` is set; the limit checker uses them.
struct CornerEvent {
  //! Cycle (Registers::cycle) in which the junction was crossed.
  std::uint64_t cycle = 0;
  //! Time of the crossing inside that cycle, as a fraction 0..1 of Cycle_Time.
  double fraction = 0.0;
  //! Source line of the segment entered.
  std::int32_t line = 0;
  //! Per-axis velocity step [mm/s] and acceleration step [mm/s^2] at the crossing.
  std::array<double, kMaxAxes> dv{};
  std::array<double, kMaxAxes> da{};
  //! The part of da from the change of curvature, v^2 (k_out - k_in) [mm/s^2]: what the
  //! planner holds to corner_acceleration_tolerance_mm_s2 (the rest is the path acceleration
  //! turned with the tangent).
  std::array<double, kMaxAxes> da_curvature{};
};

//! Summary of one executed motion record: how fast it ran and what limited it.
struct BlockReport {
  std::int32_t act_part = 0;  //!< Act_Part of the record
  std::int32_t line = 0;      //!< source line
  std::int32_t g = 0;         //!< 0..3
  double length_mm = 0.0;
  //! Programmed path speed [mm/min]: F, or the rapid speed along the line for G0.
  double programmed_mm_min = 0.0;
  double peak_mm_min = 0.0;   //!< highest path speed reached in the block
  double duration_s = 0.0;
  //! Time at the block's end [s]: calculation steps since create() x their length, every
  //! state counted (the start of a program run from create() is 0).
  double end_s = 0.0;
  //! What limited the speed at the block's peak (kFeed when the programmed speed was reached).
  LimitFactor factor = LimitFactor::kNone;
};

//! Orig_Position over cycles that Interpolator::advance() ran: `count` consecutive cycles from
//! `cycle` on that all ended there (a dwell, an M wait, standing), or one cycle of a cruise.
//! Recorded only when `InterpolatorOptions::record_cycle_trace` is set; with it the limit
//! checker sees every cycle of a fast-forwarded run.
struct CycleTrace {
  std::uint64_t cycle = 0;  //!< Registers::cycle of the first cycle
  std::uint64_t count = 1;  //!< cycles that ended with these values
  std::int32_t line = 0;    //!< Act_Line
  std::int32_t status = 0;  //!< Status
  std::array<double, kMaxAxes> orig_position{};
};

//! Behaviour switches of one interpolator.
struct InterpolatorOptions {
  //! Record CornerEvents (for the limit checker); off in production.
  bool record_corner_events = false;
  //! Record a CycleTrace of every cycle advance() runs (cycle_trace()); a cruise is then
  //! advanced at most kMaxTracedCycles cycles per call. For the offline limit check.
  bool record_cycle_trace = false;
  //! After an underrun stop (Status 8), continue by itself when segments arrive instead of
  //! waiting for start (DESIGN section 5 asks for start; the option is for streaming tests).
  bool resume_after_underrun = false;
  //! Rebuild the LookAheadBuffer table from the ring in every cycle instead of updating it as
  //! `cur` moves on and records arrive (the reference the tests compare the update with).
  bool full_lookahead_fill = false;
  //! Scan every window of the chord-turn history at every junction instead of skipping the
  //! scans where a bound on the turn shows that nothing binds (the reference the tests compare
  //! the skip with: the trajectories must be the same bit for bit).
  bool full_turn_scan = false;
  //! Construct every ring slot at create (tgm-service). Off, the rings grow as records are
  //! stored, doubling: an append that crossed a doubling wrote up to half the ring (about
  //! 3 MB of 10,000 slots) on the cycle thread, 0.2 ms even with the memory locked and faulted
  //! in (tests/bench/BENCHMARKS.md, Service, session 41). On, create() writes all Buffer_Size
  //! slots (about 8.5 MB for 10,000), which an offline run of a short program need not pay
  //! (Simulation leaves it off).
  bool preallocate_ring = false;
};

//! One interpolator (axis group). Movable, not copyable.
class Interpolator {
 public:
  //! Builds interpolator `number` of `machine`; nullopt (and `error`) when the config is invalid.
  static std::optional<Interpolator> create(const MachineConfig& machine, int number,
                                            const InterpolatorOptions& options = {},
                                            std::string* error = nullptr);
  Interpolator(Interpolator&&) noexcept;
  Interpolator& operator=(Interpolator&&) noexcept;
  ~Interpolator();

  //! Advances one Cycle_Time (five calculation steps) and updates every register.
  StepResult step();

  //! Offline fast path for the simulator (the real-time service calls step()): advances up to
  //! `max_cycles` cycles and returns how many in `advanced`. Either exactly one step(), or a run
  //! of cycles in which nothing changes qualitatively (constant-speed cruise, also through
  //! junctions into records of the same target speed; dwell, M wait, standing), computed with
  //! the same arithmetic as step(): the registers afterwards equal those after as many step()
  //! calls (the per-cycle registers in between are not produced; block_reports() and
  //! corner_events() hold those of every junction the run crossed). Requests between calls act
  //! as between steps.
  StepResult advance(std::uint64_t max_cycles, std::uint64_t* advanced);
  //! Cycles of a cruise one advance() runs at most while recording the cycle trace.
  static constexpr std::uint64_t kMaxTracedCycles = 4096;
  //! With `InterpolatorOptions::record_cycle_trace`: Orig_Position, line and Status of every
  //! cycle the last advance() ran, oldest first, the last one equal to registers() (one entry
  //! for a step). Empty without the option, and after step().
  std::span<const CycleTrace> cycle_trace() const;

  //! Makes this interpolator an exact copy of `other` (created from the same config: the ring
  //! is copied in place, only message texts may allocate). For benchmarks and tests that replay
  //! the same step; not for the cycle path.
  void copy_state_from(const Interpolator& other);

  //! The registers after the last step (or after creation).
  const Registers& registers() const;

  // ---- Requests (between two steps) ----

  //! Appends records [first, first + count) of `program` (with their M parameters and messages)
  //! to the ring buffer. Takes as many as fit; `accepted` says how many. `program_complete`
  //! says that no further record will follow: the end of the buffer then ends the program
  //! (Status 3) instead of being an underrun (Status 8). Allowed in every state except the
  //! emergency ramp; appending to an empty or ended interpolator makes it Ready (Status 4).
  RequestResult append(const Program& program, std::size_t first, std::size_t count,
                       bool program_complete = false, std::size_t* accepted = nullptr);
  //! Whole program, all records (must fit into the ring buffer).
  RequestResult load(const Program& program);
  //! Starts or resumes (Status 4, 7 after Command 4, 8, or a pause at M0).
  RequestResult start();
  //! Drops every record not yet executed; only while no program runs (not while moving,
  //! dwelling or waiting for an M-function: stop first). Status becomes 0.
  RequestResult clear();
  //! Command register: 4 / 5 emergency stop on / off trajectory, 8 / 9 normal stop on / off
  //! trajectory. Other codes are refused with kUnsupported here: they take parameters (below).
  RequestResult command(std::int32_t code);
  //! Command with its Command_Parameter[0..11] (manual "Command Structure"): 1024 Ratio (axis,
  //! numerator [inc], denominator [mm]); 2048 / 2049 set the position [inc per axis] on / off
  //! the trajectory; -1 IIR (p, q, f x 1e6, axis mask); -2 Spline (points, jerk [mm/s^3]);
  //! 4 / 5 / 8 / 9 as command(code). The parameters are copied to Command_Parameter.
  //! Command_Status: 1 while executing, 0 done (Command back to 0), -1 error (Command back to
  //! 0, the reason returned and kept in command_error()). A valid command whose only obstacle
  //! is motion still inside the smoothing (1024 / 2048 / 2049 wait for the spline and IIR to
  //! settle, -2 for the spline to drain, -1 for an axis leaving the mask to settle) is accepted
  //! and stays at Command_Status 1 until step() executes it; meanwhile other stage commands
  //! are refused (kWrongState) and 4 / 5 / 8 / 9 cancel it (Command_Status -1).
  RequestResult command(std::int32_t code, const std::array<std::int32_t, kCommandParameters>& parameter);
  //! Reason of the last Command that ended with Command_Status -1 ("" after a success).
  const std::string& command_error() const;
  //! How many commands accepted at Command_Status 1 ended without being executed (cancelled by
  //! 4 / 5 / 8 / 9, or no longer allowed), and the reason of the last (a later command's
  //! success does not clear it, as it does command_error()).
  std::uint64_t unexecuted_commands() const;
  const std::string& unexecuted_reason() const;
  //! M-functions and messages that reached M_Func (or the HMIs) before the motion sample they
  //! belong to, in program order: more than SmoothingStage::kEventCapacity of them inside the
  //! spline's delay. 0 on any program with fewer.
  std::uint64_t early_smoothing_events() const;
  //! Ratio register write [inc/mm]: axis 0..Number_Axes-1, |ratio| 1e-6..1e9, only between
  //! programs with the smoothing settled (ratio_may_change: PositionInc jumps by Position x
  //! dRatio).
  RequestResult write_ratio(int axis, double ratio_inc_per_mm);
  //! Offset register write [inc]: axis 0..Number_Axes-1, |offset| <= 1e15, any time (added as
  //! is: a change is a step of the setpoint).
  RequestResult write_offset(int axis, std::int64_t offset_inc);
  //! Number_Axes write: 1..10, at most the configured axes, only while no program executes
  //! (Status 0, 3, 4, 7, 8 and standing). Programs must then be compiled for that many axes;
  //! the registers of the axes above keep their last values.
  RequestResult write_number_axes(int number_axes);
  //! PLC write of M_Func; only 0 (acknowledge) is accepted. `acknowledged` != 0 names the
  //! M-function the PLC acknowledges: while M_Func shows another one, the write is refused
  //! (kWrongState) and changes nothing, so a late acknowledgement of a continuous M-function
  //! cannot release the normal one shown after it. 0 clears whatever M_Func shows. `count` != 0
  //! names it exactly, by its `m_func_count`: the write is refused (kWrongState) once a later
  //! M-function was handed over, also one with the same number (a delayed acknowledgement from
  //! a program that was cleared meanwhile), and once that M-function was acknowledged already
  //! (M_Func 0: a second PLC, or a repeat whose first copy arrived).
  RequestResult write_m_func(std::int32_t value, std::int32_t acknowledged = 0,
                             std::uint32_t count = 0);
  //! Rel_Speed 0.01..2; takes effect in the next calculation step through the jerk-limited ramp.
  RequestResult set_rel_speed(double rel_speed);
  //! Sets Orig_Position = Position [mm] while standing with the smoothing settled; drops the
  //! program. (Command 2048 / 2049 set it in increments through the output stage.)
  RequestResult set_position(const std::array<double, kMaxAxes>& position_mm);

  // ---- Read access for the service, the simulator and the checker ----

  //! Free ring slots.
  std::size_t free_slots() const;
  //! Ring slots constructed so far (InterpolatorOptions::preallocate_ring: all of them).
  std::size_t ring_slots() const;
  //! False while an emergency ramp runs (Command 4/5): append() refuses records then, and
  //! callers that stream keep them until it has ended.
  bool takes_records() const;
  //! M29 messages kept for message_slot_of() and message_text(): the last this many.
  static constexpr std::uint32_t kMessageRing = 256;
  //! The message_slot of the message that made Registers::message_count `count` (several can
  //! come out in one cycle); -1 when it is not among the last kMessageRing or not yet out.
  std::int32_t message_slot_of(std::uint32_t count) const;
  //! Text of an M29 message by Registers::message_slot ("" when the slot is empty).
  std::string_view message_text(std::int32_t slot) const;
  //! Source line of that M29 (0 when the slot is empty). Act_Line when the message comes out is
  //! the record executing then, which is a later one: an M29 is passed, not executed.
  std::int32_t message_line(std::int32_t slot) const;
  //! Corner events of the last step (empty unless recording).
  std::span<const CornerEvent> corner_events() const;
  //! Motion records completed during the last step.
  std::span<const BlockReport> block_reports() const;
  //! Count of times the generator had to clamp at a stop point while still moving faster than
  //! 1e-3 mm/s and than 1/16 of J dt^2, the speed one calculation step changes at the record's
  //! jerk limit (a planning defect; 0 expected).
  std::uint64_t hard_stops() const;
  //! Count of position sets (set_position, Command 2048 / 2049): Orig_Position jumps there by
  //! design, so a per-cycle check of the motion (LimitChecker) starts afresh when it changes.
  std::uint64_t position_sets() const;
  //! Cycle time [s] and calculation step [s].
  double cycle_time_s() const;
  double calc_step_s() const;
  //! The axis group's config.
  const InterpolatorConfig& config() const;
  //! Spline -> IIR stage between Orig_Position and Position (include tgm/smoothing.hpp):
  //! configuration, contour deviation statistics (spline().stats()), settled().
  const SmoothingStage& smoothing() const;
  //! Ratio / Offset / backlash stage (include tgm/output_stage.hpp).
  const OutputStage& output() const;

 private:
  struct Impl;
  explicit Interpolator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace tgm
