#include "tgm/jerk_profile.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tgm::jerk {

Braking braking_plan(double v, double a, double w, double A, double J) {
  if (w < 0.0) w = 0.0;
  if (v <= w && a <= 0.0) return {0.0, 0.0};  // the common case of a far or high limit, cheaply
  // No clamp of a to [-A, A]: the planner may check with limits slightly below those the
  // generator uses, and an acceleration above A must be ramped down, not assumed away.
  // One division for 1/J instead of five by J: this runs several times per calculation step.
  const double iJ = 1.0 / J;
  const double vz = settled_velocity(v, a, J);
  if (v <= w && vz <= w) return {0.0, 0.0};
  // Braking so hard that even ramping the acceleration back at +J ends below standstill: the
  // motion would have to reverse. No distance makes that state acceptable.
  if (vz < 0.0) return {std::numeric_limits<double>::infinity(), -a};
  if (vz <= w) {
    // Case 2: a < 0 and v > w; ramp a up at +J, v reaches w before a reaches 0.
    const double disc = std::max(0.0, a * a - 2.0 * J * (v - w));
    const double t = (-a - std::sqrt(disc)) * iJ;
    return {t * (v + t * (0.5 * a + t * J * (1.0 / 6.0))), -a};
  }
  // Case 3: S-curve from (v, a) to (w, 0).
  double ap = std::sqrt(J * (v - w) + 0.5 * a * a);  // peak deceleration without a hold phase
  double t2 = 0.0;
  const double cap = std::max(A, -a);  // already braking harder than A: hold that
  if (ap > cap) {
    ap = cap;
    t2 = (v + 0.5 * (a * a - 2.0 * ap * ap) * iJ - w) / ap;
    if (t2 < 0.0) t2 = 0.0;
  }
  const double t1 = (a + ap) * iJ;  // jerk -J from a to -ap
  const double d1 = t1 * (v + t1 * (0.5 * a - t1 * J * (1.0 / 6.0)));
  const double v1 = v + t1 * (a - 0.5 * J * t1);
  const double d2 = t2 * (v1 - 0.5 * ap * t2);
  const double v2 = v1 - ap * t2;
  const double t3 = ap * iJ;  // jerk +J from -ap to 0
  const double d3 = t3 * (v2 + t3 * (-0.5 * ap + t3 * J * (1.0 / 6.0)));
  return {d1 + d2 + d3, ap};
}

double braking_distance(double v, double a, double w, double A, double J) {
  return braking_plan(v, a, w, A, J).distance;
}

double landing_acceleration(double v, double a, double vt, double J, double dt) {
  // With end acceleration x the velocity after the step is v + (a + x) dt / 2, and bringing x to
  // zero at full jerk then adds x|x| / (2J). Solve v + (a + x) dt / 2 + x|x| / (2J) = vt.
  const double c = v + 0.5 * a * dt - vt;
  return c <= 0.0 ? J * (-0.5 * dt + std::sqrt(0.25 * dt * dt - 2.0 * c / J))
                  : J * (0.5 * dt - std::sqrt(0.25 * dt * dt + 2.0 * c / J));
}

double track_velocity(double v, double a, double vt, double A, double J, double dt) {
  // Close to the target: two steps, this one to x and the next one back to zero acceleration,
  // land exactly on vt (dead-beat; the one-step landing below would oscillate around vt).
  const double x2 = -(v + 0.5 * a * dt - vt) / dt;
  if (std::fabs(x2) <= J * dt && std::fabs(x2 - a) <= J * dt && std::fabs(x2) <= A) {
    // Rising towards vt with an acceleration the step cannot take back in time, the two-step
    // landing passes above vt between its steps, by (v - vt) / 2 + a dt / 4 (up to J dt^2 / 16).
    // The caps keep a 0.1 % margin below the axis limits for that; where one step of jerk is
    // large against the speed (a velocity limit of 0.027 mm/s with 4e6 mm/s^3 at 1 ms cycles:
    // 0.5 % over the cap), this step ends on vt instead, and the steps after it land from there
    // (below vt).
    const double over = 0.5 * (v - vt) + 0.25 * a * dt;
    if (v >= vt || over <= kDeadBeatOvershoot * vt) return x2;
    const double x1 = 2.0 * (vt - v) / dt - a;  // v + (a + x1) dt / 2 = vt
    if (std::fabs(x1 - a) <= J * dt && std::fabs(x1) <= A) return x1;
  }
  const double x = landing_acceleration(v, a, vt, J, dt);
  const double lo = std::max(a - J * dt, -A);
  const double hi = std::min(a + J * dt, A);
  if (lo > hi) return a > A ? std::max(a - J * dt, -A) : std::min(a + J * dt, A);
  return std::clamp(x, lo, hi);
}

double floor_acceleration(double v, double a, double J, double dt) {
  // x^2 <= 2J (v + (a + x) dt / 2) for x < 0  <=>  x >= (J dt - sqrt(J^2 dt^2 + 8J (v + a dt/2))) / 2.
  const double c = v + 0.5 * a * dt;
  if (c <= 0.0) return -a - 2.0 * v / dt;  // even x = 0 would reverse: end the step at v' = 0
  return 0.5 * (J * dt - std::sqrt(J * J * dt * dt + 8.0 * J * c));
}

}  // namespace tgm::jerk

namespace tgm::jerk {

Braking braking_plan_from(double v, double a, double w, double A, double J, double J_now) {
  if (a >= 0.0 || J_now <= J) {
    if (a >= -A && 2.0 * J * v >= a * a) return braking_plan(v, a, w, A, J);
  }
  // Decelerating harder than the limits ahead allow (|a| > A, or too hard for jerk J to take back
  // before standstill): first ease the deceleration at the current jerk J_now.
  const Easing e = ease_deceleration(v, a, std::max(a, -A), J, J_now);
  if (e.reverses) return {std::numeric_limits<double>::infinity(), -a};
  const Braking rest = braking_plan(e.v0, e.target, w, A, J);
  return {e.d0 + rest.distance, std::max(-a, rest.peak)};
}

Easing ease_deceleration(double v, double a, double start, double J, double J_now) {
  Easing e;
  e.target = start;
  e.v0 = v;
  for (int it = 0; it < 3; ++it) {
    e.t = std::max(0.0, (e.target - a) / J_now);
    e.v0 = v + e.t * (a + 0.5 * J_now * e.t);
    if (e.v0 <= 0.0) {
      e.reverses = true;
      return e;
    }
    const double floor_a = -std::sqrt(2.0 * J * e.v0);
    if (e.target >= floor_a) break;
    e.target = floor_a * 0.999;
  }
  e.d0 = e.t * (v + e.t * (0.5 * a + e.t * J_now * (1.0 / 6.0)));
  return e;
}

double braking_distance_from(double v, double a, double w, double A, double J, double J_now) {
  return braking_plan_from(v, a, w, A, J, J_now).distance;
}

}  // namespace tgm::jerk
