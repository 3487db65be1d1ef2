// Output stage (manual appendix: PositionInc, Backlash, Offset, Ratio): Position [mm] to the
// drive setpoint PositionInc [inc] = round(Position x Ratio) + Offset + Backlash, with the
// backlash compensation ramped on direction reversal. Design: core/SMOOTHING.md, "Output stage".
#pragma once

#include <array>
#include <cstdint>

#include "tgm/config.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/registers.hpp"

namespace tgm {

//! Accepted |Offset| [inc] (|Ratio|: kMinRatio..kMaxRatio, config.hpp).
inline constexpr std::int64_t kMaxOffsetInc = 1'000'000'000'000'000;
//! Travel against the last direction that counts as a reversal [mm], at the least: a reversal
//! is also more than one increment (1 / |Ratio|) back, one the setpoint can show.
inline constexpr double kReversalThresholdMm = 1e-6;

//! Per-axis Ratio, Offset and backlash compensation of one interpolator. No allocation.
class OutputStage {
 public:
  //! Ratio from `ratio_inc_per_mm`, backlash from `backlash_mm` and the ramp from
  //! `backlash_ramp_share` of the velocity / acceleration / jerk limits of each configured axis;
  //! Offset 0; compensation 0 (direction unknown).
  explicit OutputStage(const InterpolatorConfig& config);

  //! New reference position (Command 2048 / 2049): direction tracking restarts there; the
  //! compensation keeps its value (it describes the mechanics, not the position).
  void reset(const double* position_mm);

  //! Takes Position [mm] after the smoothing and advances direction detection and the backlash
  //! ramp by `dt_s` (call it per calculation step or per cycle; SMOOTHING.md uses per cycle).
  void update(const double* position_mm, double dt_s);

  //! Writes Ratio, Offset, Backlash and PositionInc of the configured axes into `r`
  //! (PositionInc from the Position given to the last update()).
  void fill(Registers& r) const;

  //! Command 1024: Ratio = numerator [inc] / denominator [mm] (checks: check_ratio).
  RequestResult set_ratio(std::int64_t axis, std::int64_t numerator_inc, std::int64_t denominator_mm);
  //! The checks of Command 1024 without a stage (check_command uses them too, so that a ratio
  //! refused at run time is refused by a check made in advance): the axis is 0..axes-1, the
  //! numerator not 0, the denominator > 0, |numerator / denominator| kMinRatio..kMaxRatio.
  static RequestResult check_ratio(std::int64_t axis, std::int64_t numerator_inc,
                                   std::int64_t denominator_mm, int axes);
  //! Command 1024's parameters for a Ratio [inc/mm]: the 32-bit numerator [inc] and denominator
  //! [mm] (> 0) whose quotient, as set_ratio divides it, is `ratio_inc_per_mm` to the last bit.
  //! exact = false when no such pair exists (e.g. 1/3 or most ratios with more than nine
  //! significant digits); the pair is then the nearest fraction found, and a PLC that must keep
  //! the value writes the Ratio register instead (tgm-plc does).
  struct RatioFraction {
    bool exact = false;
    std::int32_t numerator_inc = 0;
    std::int32_t denominator_mm = 1;
  };
  static RatioFraction ratio_as_fraction(double ratio_inc_per_mm);
  //! Register writes (PLC): Ratio [inc/mm] and Offset [inc].
  RequestResult write_ratio(std::int64_t axis, double ratio_inc_per_mm);
  RequestResult write_offset(std::int64_t axis, std::int64_t offset_inc);

  //! Position [mm] whose PositionInc is `inc` (Command 2048 / 2049): (inc - Offset - Backlash) / Ratio.
  double position_from_inc(int axis, std::int64_t inc) const;

  int axes() const { return axes_; }
  double ratio(int axis) const { return ratio_[static_cast<std::size_t>(axis)]; }
  std::int64_t offset(int axis) const { return offset_[static_cast<std::size_t>(axis)]; }
  //! Backlash register [inc]: round(compensation [mm] x Ratio).
  std::int64_t backlash_inc(int axis) const;
  //! Compensation [mm] (ramping between -backlash/2 and +backlash/2) and its rate [mm/s].
  double compensation_mm(int axis) const { return comp_[static_cast<std::size_t>(axis)]; }
  double compensation_rate_mm_s(int axis) const { return comp_v_[static_cast<std::size_t>(axis)]; }
  //! Last detected direction of motion: +1, -1, 0 (none yet).
  int direction(int axis) const { return dir_[static_cast<std::size_t>(axis)]; }
  std::int64_t position_inc(int axis) const;
  //! Configured backlash of the axis [mm].
  double backlash_mm(int axis) const { return 2.0 * half_backlash_[static_cast<std::size_t>(axis)]; }
  //! True when the compensation of the axis rests on its target (no ramp in progress), so
  //! update() with a position that keeps the detected direction changes nothing.
  bool ramp_settled(int axis) const {
    const auto ui = static_cast<std::size_t>(axis);
    return ramp_duration_[ui] == 0.0 && comp_[ui] == dir_[ui] * half_backlash_[ui];
  }

 private:
  int axes_ = 0;
  std::array<double, kMaxAxes> ratio_{}, half_backlash_{}, ramp_v_{}, ramp_a_{}, ramp_j_{};
  std::array<std::int64_t, kMaxAxes> offset_{};
  std::array<double, kMaxAxes> pos_{}, extreme_{}, comp_{}, comp_v_{};
  // The ramp in progress (duration 0: none): from, to [mm], elapsed and duration [s].
  std::array<double, kMaxAxes> ramp_from_{}, ramp_to_{}, ramp_elapsed_{}, ramp_duration_{};
  std::array<int, kMaxAxes> dir_{};
};

}  // namespace tgm
