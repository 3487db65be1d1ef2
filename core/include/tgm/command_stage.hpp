// Command structure (manual: "Command Structure", appendix Command / Command_Status): checks and
// execution of the commands that do not move the path, 1024, 2048, 2049, -1, -2, and the
// Number_Axes write. Commands 4 / 5 / 8 / 9 belong to Interpolator::command(). Reasons and the
// Command_Status sequence: core/SMOOTHING.md, "Commands".
#pragma once

#include <array>
#include <cstdint>

#include "tgm/interpolator.hpp"
#include "tgm/output_stage.hpp"
#include "tgm/registers.hpp"
#include "tgm/smoothing.hpp"

namespace tgm {

//! Command register values.
inline constexpr std::int32_t kCommandSetRatio = 1024;
inline constexpr std::int32_t kCommandSetPositionOn = 2048;
inline constexpr std::int32_t kCommandSetPositionOff = 2049;
inline constexpr std::int32_t kCommandIir = -1;
inline constexpr std::int32_t kCommandSpline = -2;

//! What the checks need to know about the interpolator at the time of the request.
struct CommandContext {
  //! The path generator stands (not moving, not on a stop ramp); M-function waits, dwells,
  //! pauses and the idle states count as standing.
  bool standing = true;
  //! No program is executing (Status 0, 3, 4, 7, 8): what a position set needs.
  bool idle = true;
  int number_axes = 1;      //!< Number_Axes
  int configured_axes = 1;  //!< axes of the interpolator's config
  //! With `idle`: no program is under way either (nothing loaded, ended, dropped, or loaded and
  //! not yet started; not one stopped on its trajectory or starved, which a start resumes).
  bool between_programs = true;
  //! Records of a program are loaded (Status 4, 8, or a resumable emergency stop): a change
  //! of Number_Axes would drop them.
  bool holds_program = false;
};

//! A gear ratio (Command 1024, the Ratio register) may change: standing, between programs.
//! PositionInc jumps by Position x the change in one cycle; during a program (an M-function
//! wait, a dwell, a stop a start resumes from) the program went on at the new scale.
inline bool ratio_may_change(const CommandContext& c) {
  return c.idle && c.between_programs && c.standing;
}

//! True for the commands this stage executes (1024, 2048, 2049, -1, -2).
bool is_stage_command(std::int32_t code);

//! Checks a Command and its parameters without executing it: the code is known, parameters in
//! range, the state allows it. Stage state (drained spline, settled IIR axes) is checked by
//! execute_command(). 4 / 5 / 8 / 9 are accepted here (their checks are the interpolator's).
RequestResult check_command(std::int32_t code,
                            const std::array<std::int32_t, kCommandParameters>& parameter,
                            const CommandContext& context);

//! Checks a write of Number_Axes: 1..10, at most the configured axes, only while idle, and a
//! change not while a program is loaded (holds_program: it would drop its records).
RequestResult check_number_axes(std::int64_t value, const CommandContext& context);

//! Executes 1024, -1, -2 on the stages; for 2048 / 2049 computes the new Orig_Position [mm]
//! into `position_mm` ((inc - Offset - Backlash) / Ratio per axis) and resets the smoothing
//! and the output stage there; the caller then sets the interpolator's position
//! (Interpolator::set_position) and `off_trajectory` (0 for 2048, 1 for 2049).
RequestResult execute_command(std::int32_t code,
                              const std::array<std::int32_t, kCommandParameters>& parameter,
                              const CommandContext& context, SmoothingStage& smoothing,
                              OutputStage& output, std::array<double, kMaxAxes>* position_mm);

//! Command_Status sequence: begin() when the PLC writes Command (Command = code,
//! Command_Status = 1 while it executes); end() when it is done: Command = 0 and
//! Command_Status = 0, or -1 when `result` is an error (the reason goes in the reply).
void command_begin(Registers& r, std::int32_t code);
void command_end(Registers& r, const RequestResult& result);

}  // namespace tgm
