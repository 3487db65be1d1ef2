// One-dimensional jerk-limited path velocity helpers used by the interpolator's online generator.
//
// The path state is (s, v, a): position along the path [mm], path velocity [mm/s], path
// acceleration [mm/s^2]. During one calculation step of length dt the jerk is constant, so a step
// is fully described by the acceleration at its end (`x`).
#pragma once

#include <cmath>

namespace tgm::jerk {

//! Path state.
struct State {
  double s = 0.0;  //!< [mm]
  double v = 0.0;  //!< [mm/s]
  double a = 0.0;  //!< [mm/s^2]
};

//! State after `dt` seconds at constant jerk that ends with acceleration `x`.
inline State advance(const State& st, double x, double dt) {
  // s + v dt + a dt^2 / 2 + j dt^3 / 6 with j = (x - a) / dt, without the two divisions.
  State n;
  n.s = st.s + dt * (st.v + dt * (st.a * (1.0 / 3.0) + x * (1.0 / 6.0)));
  n.v = st.v + 0.5 * (st.a + x) * dt;
  n.a = x;
  return n;
}

//! Path distance [mm] the interpolator needs, from velocity v and acceleration a, before the
//! velocity is at most w and can stay there, braking with acceleration magnitude at most A and
//! jerk at most J. 0 when no braking is needed; infinity when the deceleration is already so
//! large that the velocity would cross zero before the acceleration is back at zero.
//!
//! Three cases: (1) no braking needed; (2) the acceleration is already so negative that ramping
//! it back to zero at +J passes below w: the distance until v = w on that ramp; (3) the
//! time-optimal S-curve to (w, 0): jerk -J to a peak deceleration <= A, hold, jerk +J to zero.
double braking_distance(double v, double a, double w, double A, double J);

//! Velocity [mm/s] once acceleration a is brought to zero at jerk J along the shortest ramp.
//! braking_plan needs no braking when both v and this are within w; callers that decide on the
//! same condition use this function so that both sides round alike.
inline double settled_velocity(double v, double a, double J) {
  return v + 0.5 * a * std::fabs(a) * (1.0 / J);
}

//! A braking plan's distance [mm] and peak deceleration [mm/s^2] (0 when no braking is needed).
struct Braking {
  double distance = 0.0;
  double peak = 0.0;
};

//! braking_distance with the plan's peak deceleration (one evaluation for both).
Braking braking_plan(double v, double a, double w, double A, double J);

//! braking_distance with limits (A, J) that hold from here on, when the current deceleration may
//! exceed what they allow: the deceleration is first eased at the current jerk limit J_now.
double braking_distance_from(double v, double a, double w, double A, double J, double J_now);

//! braking_distance_from with the plan's peak deceleration.
Braking braking_plan_from(double v, double a, double w, double A, double J, double J_now);

//! The easing braking_plan_from starts with, for a deceleration too hard for jerk J to take
//! back before standstill: the acceleration ramps from a towards `target` (starting at
//! `start` >= a) at jerk J_now, taking t [s] and d0 [mm] and leaving speed v0 [mm/s]; after
//! each ramp a target below -sqrt(2 J v0) is raised to 0.999 of that, three ramps at most. A
//! third raise keeps the last ramp's t, v0 and d0 (the target is regular for that v0).
//! `reverses` when a ramp ends at or below zero speed.
struct Easing {
  double target = 0.0;
  double t = 0.0;
  double v0 = 0.0;
  double d0 = 0.0;
  bool reverses = false;
};
Easing ease_deceleration(double v, double a, double start, double J, double J_now);

//! End-of-step acceleration x whose state, after bringing the acceleration back to zero at
//! jerk J, has velocity vt: v + (a + x) dt / 2 + x |x| / (2J) = vt (unclipped; increasing in x).
double landing_acceleration(double v, double a, double vt, double J, double dt);

//! The largest share of vt by which track_velocity's two-step landing may pass above vt
//! between its steps (a quarter of the 0.1 % margin the interpolator keeps below the limits).
inline constexpr double kDeadBeatOvershoot = 2.5e-4;

//! End-of-step acceleration that tracks the target velocity `vt` time-optimally without
//! overshoot (the velocity after bringing a to zero at full jerk equals vt), clipped to the
//! jerk limit (|x - a| <= J dt) and to |x| <= A. Close to vt it lands in two steps; rising
//! towards vt, their middle state stays within vt (1 + kDeadBeatOvershoot).
double track_velocity(double v, double a, double vt, double A, double J, double dt);

//! Lowest end-of-step acceleration that keeps the motion from reversing: with x < 0 the velocity
//! at the end of the step must still allow ramping the acceleration back to 0 at jerk J before v
//! reaches 0 (v' >= x^2 / (2J)).
double floor_acceleration(double v, double a, double J, double dt);

//! Distance to stop from (v, a) with limits A, J: braking_distance(v, a, 0, A, J).
inline double stopping_distance(double v, double a, double A, double J) {
  return braking_distance(v, a, 0.0, A, J);
}

}  // namespace tgm::jerk
