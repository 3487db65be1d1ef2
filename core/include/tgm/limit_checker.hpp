// Limit checker: differentiates Orig_Position per cycle and reports every per-axis velocity,
// acceleration or jerk excess, and every corner velocity step above the tolerance.
//
// Velocity is the first difference of the positions. At a corner the interpolator deliberately
// lets an axis velocity jump (by at most the corner tolerance) and, with it, the acceleration
// (curvature change, tangential acceleration redistributed). The checker removes exactly those
// announced steps (CornerEvents: time inside the cycle, per-axis dv and da) from the positions
// before taking the second difference (dv removed) and the third difference (dv and da removed),
// and checks each announced dv against the tolerance. What remains is a weighted average of the
// physical acceleration / jerk between the corners, so the only tolerance needed is floating
// point noise (MOTION.md, "Limit checker"). The part of each announced acceleration step that
// a change of curvature makes (CornerEvent::da_curvature) is checked against the corner
// acceleration tolerance, as dv is against the corner velocity tolerance.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/registers.hpp"

namespace tgm {

//! Which quantity exceeded its limit.
enum class LimitQuantity : std::uint8_t {
  kVelocity = 0,
  kAcceleration = 1,
  kJerk = 2,
  kCornerStep = 3,  //!< velocity step at a corner above corner_velocity_tolerance_mm_s
  //! The velocity change over a window of about 10 ms (LimitChecker::window_cycles), corner
  //! steps included, as a mean acceleration; its limit is the acceleration limit plus one
  //! corner tolerance spread over the window. Catches steps that each keep the tolerance but
  //! add up (a run of short chords).
  kMeanAcceleration = 4,
  //! Acceleration step at a junction from the change of curvature (CornerEvent::da_curvature)
  //! above corner_acceleration_tolerance_mm_s2.
  kCornerAcceleration = 5,
};

//! "velocity", "acceleration", "jerk", "corner_step", "mean_acceleration",
//! "corner_acceleration".
const char* limit_quantity_name(LimitQuantity q);

//! One excess.
struct LimitViolation {
  std::uint64_t cycle = 0;  //!< Registers::cycle
  std::int32_t line = 0;    //!< source line executing in that cycle
  int axis = 0;
  LimitQuantity quantity = LimitQuantity::kVelocity;
  double value = 0.0;  //!< |value| [mm/s, mm/s^2, mm/s^3]
  double limit = 0.0;
};

//! Largest magnitudes seen per axis.
struct AxisPeaks {
  double velocity_mm_s = 0.0;
  double acceleration_mm_s2 = 0.0;
  double jerk_mm_s3 = 0.0;
  double corner_step_mm_s = 0.0;
  double corner_acceleration_mm_s2 = 0.0;  //!< largest |CornerEvent::da_curvature|
};

//! Checks one interpolator's output cycle by cycle.
class LimitChecker {
 public:
  //! Relative tolerance on every limit (floating point only; see the header comment).
  static constexpr double kRelativeTolerance = 1e-6;
  //! Violations kept in detail; all are counted.
  static constexpr std::size_t kMaxStored = 1000;

  //! The shares create() accepts: (0, 1].
  static bool valid_share(double share) { return share > 0.0 && share <= 1.0; }

  //! `share` in (0, 1]: the part of each configured limit (velocity, acceleration, jerk, corner
  //! tolerance) that counts as the limit; 0.8 reports where a program uses more than 80 % of one.
  static std::optional<LimitChecker> create(const InterpolatorConfig& axes, int cycle_time_us,
                                            std::string* error = nullptr, double share = 1.0);

  //! Forgets the history (after a position set); the next cycle starts a new series.
  void reset();

  //! Feeds the registers after one step() and that step's corner events.
  void add_cycle(const Registers& reg, std::span<const CornerEvent> events);
  //! Feeds the cycles one Interpolator::advance() ran (its cycle_trace() and corner_events()):
  //! the same as add_cycle after each of them.
  void add_trace(std::span<const CycleTrace> trace, std::span<const CornerEvent> events);

  std::uint64_t violation_count() const { return count_; }
  const std::vector<LimitViolation>& violations() const { return stored_; }
  const std::array<AxisPeaks, kMaxAxes>& peaks() const { return peaks_; }
  //! Limits used (the configured ones times the share): velocity, acceleration, jerk per axis
  //! (normal, not emergency).
  double velocity_limit(int axis) const { return vmax_[static_cast<std::size_t>(axis)]; }
  double acceleration_limit(int axis) const { return amax_[static_cast<std::size_t>(axis)]; }
  double jerk_limit(int axis) const { return jmax_[static_cast<std::size_t>(axis)]; }
  //! Cycles of the mean-acceleration window: 10 ms rounded, 4..kMaxWindow.
  int window_cycles() const { return k_; }
  static constexpr int kMaxWindow = 40;
  //! The window for a cycle of `cycle_s` seconds; the planner's chord-turn limit holds the
  //! same mean acceleration (core/MOTION.md, Planner).
  static int window_cycles_for(double cycle_s) {
    return std::clamp(static_cast<int>(std::lround(0.01 / cycle_s)), 4, kMaxWindow);
  }

 private:
  LimitChecker() = default;
  // One cycle: its number, source line, Status, Orig_Position and corner events.
  void add(std::uint64_t cycle, std::int32_t line, std::int32_t status,
           const std::array<double, kMaxAxes>& orig, std::span<const CornerEvent> events);
  // True when every sample of the history is at `orig`.
  bool history_is(const std::array<double, kMaxAxes>& orig) const;
  void report(std::uint64_t cycle, std::int32_t line, int axis, LimitQuantity q, double value,
              double limit);

  struct Event {
    std::uint64_t cycle;
    double fraction;
    std::array<double, kMaxAxes> dv;
    std::array<double, kMaxAxes> da;
  };

  int n_ = 0;
  double T_ = 0.0;
  std::array<double, kMaxAxes> vmax_{}, amax_{}, jmax_{}, tol_{}, tol_a_{}, emax_{}, ejmax_{};
  // The last four cycles, a ring: sample k (0 = newest) is in slot (head_ - k) & 3.
  std::array<std::array<double, kMaxAxes>, 4> x_{};
  std::array<bool, 4> emergency_{};
  // Status of the newest sample: a ramp that starts and ends inside one cycle shows only as
  // the step to Status 7, never as Status 6.
  std::int32_t last_status_ = static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped);
  std::uint64_t last_cycle_ = 0;  // the newest sample's cycle (the series needs consecutive ones)
  unsigned head_ = 0;
  int samples_ = 0;
  std::size_t slot(int k) const { return (head_ - static_cast<unsigned>(k)) & 3u; }
  // The last window_cycles() + 2 positions, a ring (newest at wx_[wh_]), for the velocity
  // change over the window; wn_ counts the samples of the series (up to the ring's size).
  int k_ = 4;
  std::array<std::array<double, kMaxAxes>, kMaxWindow + 2> wx_{};
  int wh_ = 0, wn_ = 0;
  int em_left_ = 0;  // cycles the window still holds a sample of the emergency ramp
  // Per axis: cycles the window still holds an acceleration excess reported per cycle (the
  // mean over the window says nothing new then).
  std::array<int, kMaxAxes> acc_left_{};
  const std::array<double, kMaxAxes>& window_sample(int k) const {
    return wx_[static_cast<std::size_t>((wh_ - k + (kMaxWindow + 2)) % (kMaxWindow + 2))];
  }
  std::vector<Event> events_;
  std::vector<std::array<double, 4>> kink_dt_;  // add(): time from events_[j] to sample k
  std::uint64_t count_ = 0;
  std::vector<LimitViolation> stored_;
  std::array<AxisPeaks, kMaxAxes> peaks_{};
};

}  // namespace tgm
