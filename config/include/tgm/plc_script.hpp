// The timed actions of `tgm-plc --script`: a YAML list of steps, each at a time after the PLC
// found the service. Read here, next to the config it is written like, so that the reading can
// be tested and fuzzed without DDS.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tgm {

//! One step: what the emulated PLC does at `at_s`.
struct PlcScriptStep {
  double at_s = 0.0;  //!< seconds from the moment the service was found, 0..1e9
  int interpolator = 0;
  std::optional<double> rel_speed;  //!< Rel_Speed write, 0.01..2
  std::optional<int> command;       //!< a Command (plc_script_command)
  //! Its Command_Parameter[0..11] (`parameters: [..]`, 32-bit integers); the rest are 0.
  std::array<std::int32_t, 12> parameters{};
  std::optional<int> number_axes;  //!< Number_Axes write, 1..10 (`number_axes: 2`)
  //! Ratio writes [inc/mm], |ratio| 1e-6..1e9, by axis letter (`ratio: {X: 2000}`), in the
  //! order given.
  std::vector<std::pair<char, double>> ratio;
  //! Offset writes [inc], |offset| <= 1e15, by axis letter (`offset: {X: 500, Z: -20}`).
  std::vector<std::pair<char, std::int64_t>> offset_inc;
  bool start = false;               //!< a start request as the PLC (the service refuses it)
  std::vector<int> refuse_ack;      //!< M numbers, 1..999999, no longer acknowledged
  int line = 0;                     //!< line of the step in the script (1-based)
};

//! The steps, or the problems as "PATH:LINE: reason" lines, one per bad step in line order
//! (at most 20, then "PATH: ... and N more not shown"), or "PATH: reason" for the file as a
//! whole. Text taken from the script is shown with control characters escaped.
struct PlcScriptLoad {
  std::vector<PlcScriptStep> steps;
  std::string error;
  bool ok() const { return error.empty(); }
};

//! The Commands a script may send: the stops 4, 5, 8, 9 and the smoothing / output stage's
//! Commands (gear ratios, position set, IIR and spline parameters), with zero parameters.
bool plc_script_command(long long code);

//! Why `step` cannot run on a PLC whose config has `count` interpolators and that serves them
//! all (`only` < 0) or interpolator `only` alone (--interpolator); "" when it can. The reason
//! goes after "PATH:LINE: ".
std::string plc_script_interpolator_problem(const PlcScriptStep& step, int count, int only);

//! Why the axis writes of `step` (ratio, offset, number_axes) cannot go to an interpolator whose
//! axes are `letters` (the config's, in order); "" when they can. The reason goes after
//! "PATH:LINE: ".
std::string plc_script_axes_problem(const PlcScriptStep& step, const std::string& letters);

//! A register write of a step by axis letter (ratio, offset), addressed to the service's axis
//! of that letter.
struct PlcAxisWrite {
  enum class Register { kRatio, kOffset };
  Register reg = Register::kRatio;
  char letter = 0;
  //! The axis index of `letter` among the letters the service publishes for the interpolator
  //! (InterpolatorState.axis_letters), or -1 when it has no such axis: then nothing may be
  //! written (the index of the letter in tgm-plc's own config set another drive's ratio).
  int axis = -1;
  double ratio_inc_per_mm = 0.0;  //!< kRatio
  std::int64_t offset_inc = 0;    //!< kOffset
};

//! The ratio writes of `step`, then its offset writes, each in the order given, with the index
//! of its letter in `service_letters` (the axes the service drives, in order; "" when it
//! publishes none: every write then has axis -1).
std::vector<PlcAxisWrite> plc_script_axis_writes(const PlcScriptStep& step,
                                                 std::string_view service_letters);

//! Why a run of at most `duration_s` seconds from the PLC's start (--duration) cannot run a step
//! of `steps`: at_s counts from when the service is found, which is never before the start, so
//! a step at or after the duration never runs. Names the step of the latest such at_s as
//! "--duration ... PATH:LINE ..."; "" when every step can run in time.
std::string plc_script_duration_problem(const std::vector<PlcScriptStep>& steps, double duration_s,
                                        const std::string& path);

//! "N of M script steps never ran (the first: PATH:LINE, at_s X)" for the steps whose `ran`
//! is false (same order as `steps`), "" when every one ran.
std::string plc_script_unrun(const std::vector<PlcScriptStep>& steps, const std::vector<bool>& ran,
                             const std::string& path);

//! Parses script text; `path` names it in messages.
PlcScriptLoad parse_plc_script(std::string_view text, const std::string& path);

//! Reads and parses a script file, bounded as a config is (kMaxConfigBytes).
PlcScriptLoad load_plc_script(const std::string& path);

}  // namespace tgm
