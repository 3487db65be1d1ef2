// Plain configuration structs of the core. The YAML adapter (config/) builds them; tests build
// them directly. `validate()` reports every bad value as "key.path: reason".
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/intercode.hpp"

namespace tgm {

//! Accepted |Ratio| [inc/mm], in the config and in a Ratio write alike: a position within
//! +-1e9 mm times the largest stays within the 64-bit increments of PositionInc.
inline constexpr double kMinRatio = 1e-6;
inline constexpr double kMaxRatio = 1e9;

//! Accepted axis limits (config): the range the motion core is tested over at all three cycle
//! times (`Machines.LimitsAtTheEndsOfTheirRangesRunClean`), far beyond any machine tool. Outside
//! it a calculation step resolves a limit too coarsely or too finely: at 1e-300 mm/s^2 a line
//! never got going, at 1e7 mm/s^2 and 1e10 mm/s^3 with 1 ms cycles a 0.001 mm/s corner
//! tolerance was stepped over by 34 mm/s.
inline constexpr double kMinVelocity = 0.01, kMaxVelocity = 1e5;                // mm/s
inline constexpr double kMinAcceleration = 0.1, kMaxAcceleration = 1e6;         // mm/s^2
inline constexpr double kMinJerk = 10.0, kMaxJerk = 1e10;                       // mm/s^3
inline constexpr double kMinCornerTolerance = 1e-3, kMaxCornerTolerance = 1e4;  // mm/s

//! Limits and mechanics of one axis.
struct AxisConfig {
  //! G-code address letter of the axis (X, Y, Z, A, B, C, U, V, W, E by default).
  char letter = 'X';
  double max_velocity_mm_s = 200.0;
  double max_acceleration_mm_s2 = 2000.0;
  double max_jerk_mm_s3 = 50000.0;
  //! Rapid (G0) velocity of the axis [mm/s]; at most max_velocity_mm_s.
  double rapid_velocity_mm_s = 200.0;
  //! Deceleration of the emergency stop ramp (Command 4/5) [mm/s^2]; at least
  //! max_acceleration_mm_s2 (an emergency stop never brakes softer than a normal one).
  double emergency_deceleration_mm_s2 = 5000.0;
  //! Largest velocity step of this axis accepted at a corner without slowing down [mm/s].
  double corner_velocity_tolerance_mm_s = 2.0;
  //! Largest acceleration step of this axis accepted at a junction where the path's curvature
  //! changes (a line into an arc, two arcs that turn opposite ways) without slowing down
  //! [mm/s^2]. 0, the default: sqrt(2 x max_jerk_mm_s3 x corner_velocity_tolerance_mm_s), the
  //! step that a ramp at the jerk limit follows within the corner velocity tolerance
  //! (corner_acceleration_tolerance()).
  double corner_acceleration_tolerance_mm_s2 = 0.0;
  //! Gear ratio [inc/mm] at start (Command 1024 changes it).
  double ratio_inc_per_mm = 1000.0;
  //! Backlash compensated on direction reversal [mm].
  double backlash_mm = 0.0;
  //! Share of the velocity, acceleration and jerk limits the backlash ramp takes, 0.01..0.5.
  //! An axis with backlash is planned at the rest of its limits (planned_limit_share), so the
  //! drive setpoint, motion and ramp together, stays within them.
  double backlash_ramp_share = 0.1;
  //! Soft limits: the range this axis may be commanded to [mm, machine coordinates]; the
  //! defaults, +-1e9, are the bound of every coordinate (no soft limit). tgm/soft_limits.hpp.
  double min_position_mm = -1.0e9;
  double max_position_mm = 1.0e9;
};

//! Share of the axis limits the motion planner may use: 1 - backlash_ramp_share for an axis
//! with backlash, else 1.
inline double planned_limit_share(const AxisConfig& a) {
  return a.backlash_mm > 0.0 ? 1.0 - a.backlash_ramp_share : 1.0;
}

//! The acceleration step accepted at a junction [mm/s^2]: corner_acceleration_tolerance_mm_s2,
//! or when that is 0 the one derived from the jerk limit and the corner velocity tolerance.
inline double corner_acceleration_tolerance(const AxisConfig& a) {
  return a.corner_acceleration_tolerance_mm_s2 > 0.0
             ? a.corner_acceleration_tolerance_mm_s2
             : std::sqrt(2.0 * a.max_jerk_mm_s3 * a.corner_velocity_tolerance_mm_s);
}

//! One interpolator (axis group).
struct InterpolatorConfig {
  //! Configured axes, 1..kMaxAxes; axis i is register index i.
  std::vector<AxisConfig> axes;
  //! Ring buffer capacity in segments (manual: 1000..100000).
  int buffer_size = 10000;
};

//! One entry of the tool table.
struct ToolConfig {
  int number = 1;
  double radius_mm = 0.0;
  double length_mm = 0.0;
};

//! What a line that starts with '/' (RS274's block delete, an optional block) does.
enum class BlockDelete : std::uint8_t {
  kRefuse,  //!< an error: which lines to leave out is the operator's choice, not a default
  kRun,     //!< the switch off: the '/' is ignored and the line runs
  kSkip,    //!< the switch on: the line does nothing (its words are not read)
};

//! How the G-code compiler reads programs.
struct CompilerConfig {
  //! Distance mode at program start: true = G91 (incremental), false = G90 (absolute).
  bool start_incremental = true;
  //! Lines that start with '/' (compiler.block_delete: error, run or skip).
  BlockDelete block_delete = BlockDelete::kRefuse;
  //! Feed used by G1/G2/G3 before any F word or M99 [mm/min].
  double default_feed_mm_per_min = 1000.0;
  //! Tool in the spindle when a program starts (Tool_Number before the first T word); 0 is no
  //! tool: G41/G42 without D then compensate by radius 0.
  int initial_tool = 0;
  //! M-numbers (from the redefinable set M2..M99) that the PLC handles as plain functions.
  std::vector<int> plc_redefined_m;
  //! Largest expanded program, in segments.
  std::int64_t max_program_segments = 10'000'000;
  //! Deepest subroutine nesting (G25/G26).
  int max_call_depth = 16;
};

//! Default parameters of the smoothing stages (the PLC sets them with Command -1 / -2).
struct SmoothingConfig {
  //! Spline points (0 = off, else 50..500) and jerk limit [mm/s^3].
  int spline_points = 0;
  double spline_jerk_mm_s3 = 1'000'000.0;
  //! IIR p, q, f as integers x 1e6 and the 10-bit axis mask (0 = off).
  std::int64_t iir_p_e6 = 2'000'000;
  std::int64_t iir_q_e6 = 1'000'000;
  std::int64_t iir_f_e6 = 6'000'000;
  std::uint32_t iir_axis_mask = 0;
};

//! The machine as core sees it.
struct MachineConfig {
  //! Interpolation cycle [us]: 250, 500 or 1000.
  int cycle_time_us = 500;
  std::vector<InterpolatorConfig> interpolators;
  std::vector<ToolConfig> tools;
  CompilerConfig compiler;
  SmoothingConfig smoothing;

  //! Every problem as "key.path: reason"; empty when the config is usable.
  std::vector<std::string> validate() const;

  //! Axis letters of interpolator `n`, e.g. "XYZ".
  std::string axis_letters(int n) const;

  //! A realistic small 3-axis milling machine, three interpolators; what config/default.yaml holds.
  static MachineConfig default_machine();
};

//! A digest of what shapes interpolator `n`'s motion in `machine`, over its first `axes` axes
//! (fewer when it has fewer): the cycle time, the smoothing defaults, Buffer_Size and each
//! axis's letter, limits, backlash and soft limits. Not the compiler, the tools, the start gear
//! ratios (the PLC writes Ratio), other interpolators or the axes beyond. tgm-service publishes
//! it (InterpolatorState.machine_digest), so a client that simulates with its own config (the
//! time estimate of `tgm-hmi run`) can tell that the service moves by another. FNV-1a over the
//! values in a fixed order (integers as 64-bit, doubles by their IEEE bits, -0 as 0, all little
//! endian): a format that clients and services of other versions share, pinned by a test.
//! Never 0 (0 in the state: a service that does not say); 0 for no interpolator `n`.
std::uint64_t machine_digest(const MachineConfig& machine, int n, int axes);

//! Why M`m` cannot be listed in compiler.plc_redefined_m: empty for the M-numbers the manual
//! marks "can be redefined" (M2-M9, M17, M29, M30, M99), else "M<m> cannot be redefined (...)".
std::string redefine_m_problem(long long m);

//! Default letter of axis `i` (X Y Z A B C U V W E).
char default_axis_letter(int i);

//! compiler.block_delete's words: "error", "run", "skip" (as written; false for anything else,
//! `out` unchanged).
bool parse_block_delete(std::string_view word, BlockDelete& out);

}  // namespace tgm
