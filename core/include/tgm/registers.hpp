// The registers of one interpolator (manual, appendix "Interpolator structure" and
// "LookAheadBuffer structure") as one plain struct.
//
// The interpolator core fills a `Registers` at the end of every cycle; the service copies it to a
// snapshot that another thread publishes. Names follow the manual (snake_case), units are in the
// comments. Fields after "Extensions" are not in the manual and say why they exist.
#pragma once

#include <array>
#include <cstdint>

#include "tgm/intercode.hpp"

namespace tgm {

//! Entries of the LookAheadBuffer table (manual: the executing section plus the next seven).
inline constexpr int kLookAheadEntries = 8;
//! Command_Parameter registers.
inline constexpr int kCommandParameters = 12;
//! M_Function_Parameter registers (26 letters used, 32 reserved).
inline constexpr int kMFunctionParameters = 32;

//! `Status` register values (manual, plus 0 = empty from DESIGN section 5).
enum class InterpolatorStatus : std::int32_t {
  kEmpty = 0,              //!< nothing loaded
  kRunning = 1,            //!< trajectory movement in progress (includes M waits and dwells)
  kEnded = 3,              //!< stopped at the end of the trajectory (M2/M30 or end of a complete program)
  kReady = 4,              //!< at least one segment in the buffer, start can be called
  kEmergencyRamp = 6,      //!< decelerating on the emergency ramp (Command 4/5)
  kEmergencyStopped = 7,   //!< standing after an emergency stop
  kUnderrun = 8,           //!< stopped on the trajectory because the buffer ran empty
};

//! Lower 16 bits of `Run_Flag`: state of the current section.
enum class SectionState : std::uint16_t {
  kStop = 0,            //!< interpolator inactive
  kRun = 1,             //!< a G-instruction is executed (motion, or a G4 dwell)
  kWaitWindow = 2,      //!< rotary machining (not used)
  kWaitPulse = 3,       //!< rotary machining (not used)
  kWaitMFunc = 4,       //!< the cycle in which a normal M-function was handed to the PLC
  kWaitMFuncEnd = 5,    //!< waiting for the PLC to write M_Func = 0
};

//! Upper 16 bits of `Run_Flag`: state of the speed profile.
enum class SpeedState : std::uint16_t {
  kNoMotion = 1,
  kAccelerating = 2,
  kConstant = 3,          //!< at the target speed of the section (feed x override or a limit)
  kDecelerating = 4,      //!< slowing for a corner, a lower section limit or an override change
  kNextSection = 5,       //!< constant speed held below the section's target by a later section
  kDeceleratingLast = 6,  //!< decelerating to a standstill (stop point, end, stop command)
  kEmergencyRamp = 7,     //!< decelerating on the emergency ramp
};

//! `Run_Flag` = section state (low 16 bits) | speed state << 16.
inline constexpr std::uint32_t make_run_flag(SectionState s, SpeedState v) {
  return static_cast<std::uint32_t>(s) | (static_cast<std::uint32_t>(v) << 16);
}
inline constexpr SectionState run_flag_section(std::uint32_t f) {
  return static_cast<SectionState>(f & 0xFFFFu);
}
inline constexpr SpeedState run_flag_speed(std::uint32_t f) {
  return static_cast<SpeedState>(f >> 16);
}
//! The section waits for the PLC to acknowledge a normal M-function (M_Func = 0).
inline constexpr bool run_flag_waits_for_m(std::uint32_t f) {
  const SectionState s = run_flag_section(f);
  return s == SectionState::kWaitMFunc || s == SectionState::kWaitMFuncEnd;
}

//! What kept the path speed below the programmed feed (MOTION.md, "Limit factors").
enum class LimitFactor : std::uint8_t {
  kNone = 0,          //!< standing still / nothing executed
  kFeed = 1,          //!< the programmed feed (or the rapid speed) was reached
  kAxisVelocity = 2,  //!< an axis velocity limit projected on the path
  kAccelJerk = 3,     //!< still accelerating within the acceleration / jerk limits
  kCorner = 4,        //!< a corner: per-axis velocity-change tolerance
  kArc = 5,           //!< arc centripetal acceleration / jerk
  kLookAhead = 6,     //!< the look-ahead window reached its per-step extension budget
  kStarvation = 7,    //!< end of the buffered segments (program not completely loaded)
  kOverride = 8,      //!< Rel_Speed (feed override) below or above 1
  kMStop = 9,         //!< a stop point: normal M-function, M0, G4, program end
  kStopCommand = 10,  //!< Command 4/5/8/9
};

//! Short lowercase name of a limit factor ("feed", "corner", ...), as in the simulator output.
const char* limit_factor_name(LimitFactor f);

//! One entry of the LookAheadBuffer (manual appendix; entry 0 = section being executed).
struct LookAheadEntry {
  //! AllParams: M-function addresses A..Z of the section; kNotSet where not given [any unit],
  //! and in every letter of an invalid entry (a section that is not there gave no address).
  MParams all_params = unset_params();
  //! Tangent of motion in the XY plane [deg, 0..360): the direction of the XY velocity,
  //! atan2(dY, dX), counterclockwise from +X (0 = moving in +X, 90 = +Y). For entry 0 on an
  //! arc the current one (updated every cycle), otherwise the initial one of the section;
  //! kNotSet (> 1e38) when the section has no XY motion (M-functions, pure Z moves).
  double tangent_deg = kNotSet;
  //! 0 = invalid (fewer sections left), 1 = motion (G0..G3), 2 = normal M-function (M3..M999).
  std::int32_t movement_type = 0;
  //! G number or M number.
  std::int32_t movement_code = 0;
  //! 17 XY, 18 XZ, 19 YZ.
  std::int32_t plane = 17;
  std::int32_t tool = 0;
  //! End position of every axis [mm, absolute].
  std::array<double, kMaxAxes> end_pos_mm{};
  //! Arc start / end angle [deg, 0..360); kNotSet (> 1e38) for lines and M-functions.
  double start_angle_deg = kNotSet;
  double end_angle_deg = kNotSet;
  //! Arc radius [mm]; 0 for lines and M-functions.
  double radius_mm = 0.0;
  //! Extension: source line of the section (0 when invalid).
  std::int32_t line = 0;
};

//! Every register of one interpolator (manual appendix). Plain data, trivially copyable.
struct Registers {
  std::int32_t number = 0;        //!< Number: interpolator 0..2
  std::int32_t number_axes = 0;   //!< Number_Axes: 1..10
  std::int32_t buffer_size = 0;   //!< Buffer_Size: ring capacity [segments] 1000..100000
  std::int32_t command = 0;       //!< Command (4, 5, 8, 9, 1024, 2048, 2049, -1, -2); 0 when done
  std::array<std::int32_t, kCommandParameters> command_parameter{};  //!< Command_Parameter[0..11]
  std::int32_t command_status = 0;  //!< Command_Status: 0 done, 1 executing, -1 error
  std::int32_t status = 0;          //!< Status: see InterpolatorStatus
  //! Act_Part: ordinal of the executing record since the program was loaded (1-based; 0 = none).
  std::int32_t act_part = 0;
  std::int32_t address_external_position = 0;  //!< Address_External_Position (not used by core)
  std::int32_t m_func = 0;            //!< M_Func: M number handed to the PLC; PLC writes 0 to ack
  std::int32_t act_g_func = 0;        //!< Act_G_Func: G number of the executing instruction
  std::int32_t act_m_func = 0;        //!< Act_M_Func: number of the executing M-function
  std::int32_t last_cont_m_func = 0;  //!< Last_Cont_M_Func: last continuous M (> 1000)
  std::uint32_t run_flag = 0;         //!< Run_Flag: SectionState | SpeedState << 16
  std::int32_t tool_number = 0;       //!< Tool_Number
  std::array<double, kMaxAxes> orig_position{};  //!< Orig_Position: interpolated position [mm]
  std::array<double, kMaxAxes> position{};       //!< Position: after spline / IIR [mm]
  std::array<std::int64_t, kMaxAxes> position_inc{};  //!< PositionInc: Position x Ratio + Offset + Backlash [inc]
  std::array<std::int64_t, kMaxAxes> backlash{};      //!< Backlash: current clearance [inc]
  std::array<std::int64_t, kMaxAxes> offset{};        //!< Offset: user offset [inc]
  std::array<double, kMaxAxes> speed{};  //!< Speed: axis velocity after spline / IIR [mm/s], signed
  std::array<double, kMaxAxes> ratio{};  //!< Ratio: [inc/mm]
  //! M_Function_Parameter: letters A..Z of the last M-function (kNotSet where not given).
  std::array<double, kMFunctionParameters> m_function_parameter{};
  double rel_speed = 1.0;      //!< Rel_Speed: feed override 0.01..2
  double set_speed = 0.0;      //!< Set_Speed: programmed speed of the section [mm/min]
  double act_speed = 0.0;      //!< Act_Speed: current path speed [mm/min]
  double move_distance = 0.0;  //!< Move_Distance: path travelled since the program was loaded [mm]
  std::array<LookAheadEntry, kLookAheadEntries> lookahead{};  //!< LookAheadBuffer

  // ---- Extensions (not in the manual) ----
  //! Cycles executed since creation.
  std::uint64_t cycle = 0;
  //! Source line of the executing record (0 = none): the HMI shows it, the limit checker cites it.
  std::int32_t act_line = 0;
  //! Free ring slots: flow control for the program stream.
  std::int32_t free_slots = 0;
  //! Count of M29 messages executed, and the message slot of the last one (see
  //! `Interpolator::message_text`): the service publishes the text when the count changes.
  std::uint32_t message_count = 0;
  std::int32_t message_slot = -1;
  //! M-functions handed to M_Func since creation (normal and continuous): the PLC tells two
  //! successive M-functions apart by it, also two equal ones whose M_Func never changes.
  std::uint32_t m_func_count = 0;
  //! Source line of the M-function last handed to M_Func (0 = none). A continuous one is handed
  //! over when the record after it starts, so Act_Line is then that record's line.
  std::int32_t m_func_line = 0;
  //! 1 after Command 5 / 9 (or Command 4 with nothing loaded): the program was abandoned; a new
  //! program or a position set is needed.
  std::int32_t off_trajectory = 0;
  //! 1 while the program stands at an M0 program stop (Status 4, as after a stop command): the
  //! operator's start continues it.
  std::int32_t program_stop = 0;
  //! Path acceleration [mm/s^2] at the end of the cycle.
  double act_acceleration_mm_s2 = 0.0;
  //! What limits the path speed right now.
  LimitFactor limit_factor = LimitFactor::kNone;
  //! Spline contour deviation [mm]: largest Euclidean |smoothed - delayed| of the pass in
  //! progress, else of the last completed pass (0 while the spline is off or never engaged).
  double spline_deviation_mm = 0.0;
};

//! The registers of the M-function handshake and of the interpolator's status: what a PLC must
//! see in every cycle in which one of them changes (tgm-service queues each such change for its
//! event topic, where the full Registers are only published as the newest value).
struct EventRegisters {
  std::uint64_t cycle = 0;
  std::int32_t status = 0;
  std::uint32_t run_flag = 0;
  std::int32_t act_part = 0;
  std::int32_t act_line = 0;
  std::int32_t m_func = 0;
  std::int32_t act_m_func = 0;
  std::int32_t last_cont_m_func = 0;
  std::int32_t command = 0;
  std::int32_t command_status = 0;
  std::uint32_t m_func_count = 0;
  std::int32_t m_func_line = 0;
  std::array<double, kMFunctionParameters> m_function_parameter{};
};

inline EventRegisters event_registers(const Registers& r) {
  EventRegisters e;
  e.cycle = r.cycle;
  e.status = r.status;
  e.run_flag = r.run_flag;
  e.act_part = r.act_part;
  e.act_line = r.act_line;
  e.m_func = r.m_func;
  e.act_m_func = r.act_m_func;
  e.last_cont_m_func = r.last_cont_m_func;
  e.command = r.command;
  e.command_status = r.command_status;
  e.m_func_count = r.m_func_count;
  e.m_func_line = r.m_func_line;
  e.m_function_parameter = r.m_function_parameter;
  return e;
}

}  // namespace tgm
