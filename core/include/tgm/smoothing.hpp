// Trajectory smoothing (manual: "Trajectory smoothing", "Spline", "IIR Filter"): the stages
// between Orig_Position and Position, run once per calculation step (Cycle_Time / 5).
//
//   Orig_Position --> SplineSmoother (Command -2) --> IirFilter (Command -1) --> Position, Speed
//   M-function events --> delayed by the spline (not by the IIR filter) --> M_Func
//
// Design, definitions and the wiring into the Interpolator: core/SMOOTHING.md. Every class
// allocates in its constructor only; configure / reset / step never allocate.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "tgm/intercode.hpp"
#include "tgm/interpolator.hpp"

namespace tgm {

namespace detail {
//! Wrapping 128-bit integer of the spline's exact integer chain (GCC / Clang extension).
__extension__ typedef unsigned __int128 SplineInt;
}  // namespace detail

// ============================== IIR filter ==============================

//! IIR filter parameters as the PLC writes them (Command -1): integers x 1e6.
struct IirParams {
  std::int64_t p_e6 = 2'000'000;  //!< p of H(s) = q / (s^2 + p s + q) (normalized)
  std::int64_t q_e6 = 1'000'000;  //!< q of H(s)
  //! f: 2 % settling time of the step response [ms] x 1e6 (6'000'000 = 6 ms).
  std::int64_t f_e6 = 6'000'000;
  //! Bit i filters axis i; only bits 0..9 are used, others are ignored (manual).
  std::uint32_t axis_mask = 0;
};

//! Accepted ranges of the IIR parameters (SMOOTHING.md, "IIR filter").
inline constexpr std::int64_t kIirMinPQ_e6 = 1'000;            //!< p, q >= 0.001
inline constexpr std::int64_t kIirMaxPQ_e6 = 1'000'000'000;    //!< p, q <= 1000
inline constexpr std::int64_t kIirMinF_e6 = 1'000'000;         //!< f >= 1 ms
inline constexpr std::int64_t kIirMaxF_e6 = 2'000'000'000;     //!< f <= 2000 ms
inline constexpr double kIirMinZeta = 0.2;                     //!< damping p / (2 sqrt q)
inline constexpr double kIirMaxZeta = 10.0;

//! 2-pole low-pass H(s) = q / ((sT)^2 + p (sT) + q) per axis, discretized exactly (zero-order
//! hold of the input over each calculation step, transition matrix by the matrix exponential).
//! T scales time so the 2 % settling time of the step response equals f.
class IirFilter {
 public:
  //! Off (mask 0) until configure(); `calc_step_s` is the calculation step.
  explicit IirFilter(double calc_step_s = 100e-6);

  //! Checks p, q, f (not the mask): ranges, damping; reason names the parameter.
  static RequestResult check(std::int64_t p_e6, std::int64_t q_e6, std::int64_t f_e6);

  //! The bits of `axis_mask` that name axes 0..axes-1 (bit 0 is axis 0; `axes` 0..10): what
  //! configure() keeps of a mask for an interpolator of `axes` axes.
  static constexpr std::uint32_t mask_of_axes(std::uint32_t axis_mask, int axes) {
    return axis_mask & ((1u << axes) - 1u);
  }

  //! Sets p, q, f and the mask for `axes` axes. Bumpless: the state (lag and velocity of each
  //! axis) is kept, so Position and its velocity stay continuous. An axis newly in the mask
  //! starts at rest on its input. Refused (and nothing changes) when the parameters are out of
  //! range, or when an axis leaves the mask while its output is still behind its input
  //! (Position would jump).
  RequestResult configure(const IirParams& params, int axes);

  //! Every axis at rest on `position` (e.g. after a position set).
  void reset(const double* position_mm);

  //! One calculation step: `in` is Orig_Position (or the spline output) at the end of the step,
  //! held over the step; writes the filtered position (axes outside the mask: out = in).
  void step(const double* in_mm, double* out_mm);
  //! step() with the mask empty (every axis passes through): records the input as the state
  //! step() would leave, without an output array.
  void pass(const double* in_mm) {
    for (int i = 0; i < axes_; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      u_[ui] = in_mm[i];
    }
  }

  //! True when axis `i` is not filtered or its output is on its input (lag < 1e-9 mm, velocity
  //! < 1e-6 mm/s).
  bool settled(int axis) const;
  bool settled() const;
  //! True when every filtered axis is exactly on its input (lag 0, velocity 0): a step with
  //! the same input changes nothing, bit for bit (what Interpolator::advance needs to skip).
  bool at_rest() const;

  const IirParams& params() const { return params_; }
  std::uint32_t mask() const { return mask_; }  //!< the used bits (axes < configured axes)
  double zeta() const { return zeta_; }
  //! Natural frequency of the scaled filter [rad/s].
  double omega_n_rad_s() const { return wn_; }
  //! f [s] and the time scale T [s] (f / normalized settling time).
  double settling_time_s() const { return f_s_; }
  double time_scale_s() const { return T_; }
  //! Transition matrix over one calculation step, row-major (lag, velocity).
  const std::array<double, 4>& transition() const { return phi_; }

  //! 2 % settling time of the normalized step response of q / (s^2 + p s + q) [time units of
  //! the normalized filter]: the last time |y - 1| equals 0.02.
  static double normalized_settling_time(double p, double q);

 private:
  double dt_;
  IirParams params_{};
  std::uint32_t mask_ = 0;
  int axes_ = 0;
  double zeta_ = 1.0, wn_ = 0.0, f_s_ = 0.0, T_ = 0.0;
  std::array<double, 4> phi_{1.0, 0.0, 0.0, 1.0};
  // Per axis: last input u, lag e of the output behind it (position = u + e) and velocity v.
  // The lag is the state, not the position: a position near its input, rounded to the
  // coordinate's resolution, held the lag at a few units in the last place of the coordinate
  // for ever (a dead band: 1.4e-12 mm at 2,400 mm, wider at larger coordinates or slower
  // filters), the filter never settled, and a program whose filtered axis ended there never
  // reached Status 3 (session 41).
  std::array<double, kMaxAxes> u_{}, e_{}, v_{};
};

// ============================== Spline ==============================

//! Spline parameter ranges (manual, "Activation and parameterization of Spline").
inline constexpr int kSplineMinPoints = 50;
inline constexpr int kSplineMaxPoints = 500;

//! Contour deviation bookkeeping of the spline: a "pass" is a run of consecutive output steps
//! within 2N steps of a flagged step: the neighbourhood of one or several jerk
//! excesses, where the output may differ from the delayed input.
struct SplineStats {
  std::uint64_t flagged_steps = 0;  //!< input steps whose jerk exceeded the limit on some axis
  std::uint64_t passes = 0;         //!< completed passes
  //! Largest |smoothed - delayed| of the pass in progress / of the last completed pass / ever:
  //! Euclidean over all axes [mm].
  double current_pass_mm = 0.0;
  double last_pass_mm = 0.0;
  double max_mm = 0.0;
  //! Largest per-axis |smoothed - delayed| ever [mm].
  std::array<double, kMaxAxes> max_axis_mm{};
};

//! Spline smoothing: a delay line of N calculation steps over all axes. The output is the
//! input delayed by exactly N steps; where the jerk (third difference / dt^3) of any axis
//! exceeds the limit, the non-smooth part of the trajectory at those steps is replaced by its
//! convolution with a smooth kernel spanning the buffer on either side (SMOOTHING.md, "Spline").
//! Cost per step O(axes), independent of N and of how many excesses are in the buffer.
class SplineSmoother {
 public:
  //! Allocates for kSplineMaxPoints; off (N = 0) until configure().
  explicit SplineSmoother(double calc_step_s = 100e-6);

  //! Checks points (0 or 50..500) and the jerk limit (> 0 when points > 0).
  static RequestResult check(std::int64_t points, std::int64_t jerk_mm_s3);

  //! Sets N and the limit for `axes` axes and fills the buffer with `position_mm` (the caller
  //! makes sure the buffer is drained, see settled(), so Position does not jump).
  RequestResult configure(int points, double jerk_mm_s3, int axes, const double* position_mm);

  //! Empties the buffer: every stored point = `position_mm`, no correction pending.
  void reset(const double* position_mm);

  //! One calculation step: pushes `in` and writes the output of N steps ago (smoothed).
  void step(const double* in_mm, double* out_mm);

  //! N (0 when off): the delay in calculation steps.
  int delay_steps() const { return n_; }
  double jerk_limit_mm_s3() const { return jerk_; }
  //! True when the output equals the current input and stays so while the input stands:
  //! the input has not changed for N + 2 steps and no step was flagged in the last 2N + 2
  //! (or the spline is off).
  bool settled() const;
  const SplineStats& stats() const { return stats_; }
  void clear_stats();

  //! Largest |K[j] - K[j-1]| of the discrete kernel: a velocity jump dv (jerk dv/dt^2 when
  //! sampled) leaves the spline with jerk <= dv * gain / dt^2 (plus the unflagged jerk).
  //! The reduction factor is 1 / gain (about (N+1)^2 / 5).
  double velocity_jump_jerk_gain() const { return gain_dv_; }
  //! Largest |K[j]|: an acceleration step da leaves with jerk <= da * gain / dt.
  double acceleration_step_jerk_gain() const { return gain_da_; }
  //! Most negative running sum of K: a velocity jump dv undershoots by dv * this (< 0).
  double velocity_undershoot() const { return undershoot_; }
  //! Half-widths of the two triangles of the kernel (M2 = N + 1, M1 = M2 / 2).
  int m1() const { return m1_; }
  int m2() const { return m2_; }

 private:
  void compute_kernel_figures();

  double dt_;
  int axes_ = 0;
  int n_ = 0;
  double jerk_ = 0.0;
  double lim_d3_ = 0.0;  // jerk limit as a third difference [mm]
  int m1_ = 0, m2_ = 0;
  std::uint64_t k_ = 0;  // steps done
  std::uint64_t quiet_ = 0;  // steps since the input last changed
  std::uint64_t since_flag_ = 0;  // steps since the last flagged step (saturates)
  // Kernel integer coefficients: D K = alpha B_M1^2 + beta B_M2^2.
  detail::SplineInt alpha_ = 0, beta_ = 0, d_ = 0;
  double scale_ = 0.0;  // q / D [mm]
  double gain_dv_ = 0.0, gain_da_ = 0.0, undershoot_ = 0.0;
  // Rings of kRing entries x kMaxAxes (index [slot * kMaxAxes + axis]).
  std::vector<double> xin_;
  std::vector<detail::SplineInt> xs_, r1_, r2_;
  // Per-axis accumulators (wrapping integers, SMOOTHING.md).
  std::array<detail::SplineInt, kMaxAxes> s1_{}, s2_{}, s3_{}, b1_{}, bb1_{}, b2_{}, bb2_{};
  SplineStats stats_{};
  bool in_pass_ = false;
};

// ============================== Events ==============================

//! A side-channel event that leaves the smoothing with the motion (an M-function hand-over, a
//! message). The payload is opaque to the smoothing.
struct SmoothingEvent {
  std::int32_t kind = 0;   //!< caller-defined (e.g. 1 normal M, 2 continuous M, 3 message)
  std::int32_t value = 0;  //!< e.g. the M number or the message slot
  std::uint64_t tag = 0;   //!< e.g. the ring index of the record
};

// ============================== Pipeline ==============================

//! Spline then IIR filter, plus the event delay line; what the Interpolator holds.
class SmoothingStage {
 public:
  //! Capacity of the event delay line: the M-functions and messages inside the spline's
  //! delay (500 steps at most). 256 overflowed on a program of a continuous M-function after
  //! every 0.01 mm chord (session 75); 4096 holds eight a calculation step over the longest
  //! delay.
  static constexpr std::size_t kEventCapacity = 4096;

  //! Allocates everything; both stages off. `cycle_time_us` 250 / 500 / 1000.
  SmoothingStage(int axes, int cycle_time_us);

  //! Applies a SmoothingConfig-like start configuration (spline points / jerk, IIR params).
  RequestResult configure_spline(std::int64_t points, std::int64_t jerk_mm_s3);
  RequestResult configure_iir(const IirParams& params);

  //! Everything at rest on `position_mm` (creation, Command 2048 / 2049); pending events dropped.
  void reset(const double* position_mm);

  //! One calculation step: Orig_Position at the end of the step in, Position / Speed out.
  void step(const double* orig_mm);

  //! True when both stages are off: Position is Orig_Position and Speed its difference.
  bool passes_through() const { return spline_.delay_steps() == 0 && iir_.mask() == 0; }
  //! Instead of step() while passes_through(), for a calculation step whose Position and Speed
  //! nobody reads: only the step count moves on (events are released as after step()). The
  //! two step() calls that follow make Position and Speed what step() would have made them.
  void step_unread() { ++steps_; }

  //! Queues an event that belongs to the input sample of the last step(); it is released by
  //! pop_event() after the step whose output is that sample (N steps later; at once when the
  //! spline is off). False when the queue is full (never with fewer than kEventCapacity events
  //! in N steps).
  bool push_event(const SmoothingEvent& e);
  //! Same, for an event that belongs to the input sample of the *next* step() (raised while
  //! that sample is being computed): released after the step whose output is that sample.
  bool push_event_next(const SmoothingEvent& e);
  //! Next released event, oldest first; false when none is due.
  bool pop_event(SmoothingEvent* e);
  //! The oldest pending event, due or not (a full queue makes room, keeping the order); false
  //! when none is pending.
  bool pop_oldest(SmoothingEvent* e);
  std::size_t pending_events() const { return ev_count_; }

  //! Position after spline and IIR [mm] and Speed = (Position - Position one step ago) / dt
  //! [mm/s], as of the last step().
  const std::array<double, kMaxAxes>& position() const { return pos_; }
  const std::array<double, kMaxAxes>& speed() const { return speed_; }
  //! True when the spline is drained, every filtered axis is on its input, no event pending.
  bool settled() const;
  //! settled(), and every filtered axis exactly at rest (IirFilter::at_rest): `steps` steps
  //! with a standing input can be replaced by skip().
  bool at_rest() const;
  //! Offline fast path (Interpolator::advance): the effect of `steps` (>= 2) step() calls whose
  //! last two inputs are `before_last_mm` and `last_mm`, bit for bit, provided either at_rest()
  //! and the input stands (both equal the current input), or the spline is off and every
  //! filtered axis is at rest and stands during the steps (the other axes pass through).
  void skip(std::uint64_t steps, const double* before_last_mm, const double* last_mm);

  const SplineSmoother& spline() const { return spline_; }
  const IirFilter& iir() const { return iir_; }
  //! The smoothing in effect as the config and Commands -2 / -1 give it: spline points (0 =
  //! off) and jerk limit, IIR p, q, f and the used bits of the mask (0 = off; p, q, f are then
  //! the last ones applied, or IirParams' defaults). configure_spline / configure_iir of it
  //! make a stage that smooths the same.
  SmoothingConfig in_effect() const;
  int axes() const { return axes_; }
  double calc_step_s() const { return dt_; }

 private:
  int axes_;
  double dt_;
  double inv_dt_;  // 1 / dt_
  SplineSmoother spline_;
  IirFilter iir_;
  std::array<double, kMaxAxes> mid_{}, pos_{}, speed_{};
  std::uint64_t steps_ = 0;
  struct Slot {
    std::uint64_t release = 0;
    SmoothingEvent e;
  };
  std::array<Slot, kEventCapacity> ev_{};
  std::size_t ev_head_ = 0, ev_count_ = 0;
};

}  // namespace tgm
