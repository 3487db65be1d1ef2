// Private to core/src/motion: geometry of one planned motion record, parametrised by path length.
#pragma once

#include <array>
#include <cmath>

#include "tgm/intercode.hpp"

namespace tgm::motion {

//! A line, or an arc / helix / (slightly) spiral arc, parametrised by path length s in [0, L].
//! Arcs: plane position = centre + r(u) (cos phi(u), sin phi(u)) with u = s / L,
//! phi(u) = th0 + phi * u (phi signed: + = CCW), r(u) = r0 + dr * u; the other axes are linear.
//! The radius may change by the compiler's tolerance so the arc always ends at the record's end.
//! Arcs of a large radius (`chord_form`) take the plane position from the start point along the
//! chord instead: centre + r cos(phi) loses (|centre| + r) x 1e-16 to rounding, which at a radius
//! of 1e9 mm is 1e-7 mm from one cycle to the next, a jerk of thousands of mm/s^3 in a limit
//! check; start + chord keeps the rounding at the size of the start point and of the chord.
struct Geometry {
  bool arc = false;
  bool chord_form = false;
  int first = 0;   //!< plane axes (arcs)
  int second = 1;
  double length = 0.0;  //!< L [mm]
  std::array<double, kMaxAxes> start{};
  std::array<double, kMaxAxes> end{};
  //! Lines: unit direction. Arcs: d/ds of the non-plane axes (plane entries 0).
  std::array<double, kMaxAxes> dir{};
  double cx = 0.0, cy = 0.0, r0 = 0.0, dr = 0.0, th0 = 0.0, phi = 0.0;
};

//! Position at path length s (exactly `end` for s >= L).
inline void geometry_position(const Geometry& g, int n, double s, double* out) {
  if (s >= g.length) {
    for (int i = 0; i < n; ++i) out[i] = g.end[i];
    return;
  }
  if (s <= 0.0) {
    for (int i = 0; i < n; ++i) out[i] = g.start[i];
    return;
  }
  if (!g.arc) {
    const double u = s / g.length;
    for (int i = 0; i < n; ++i) out[i] = g.start[i] + (g.end[i] - g.start[i]) * u;
    return;
  }
  for (int i = 0; i < n; ++i) out[i] = g.start[i] + g.dir[i] * s;
  const double u = s / g.length;
  const double ph = g.th0 + g.phi * u;
  if (g.chord_form) {
    // r(u) e(ph) - r0 e(th0) = r0 (e(ph) - e(th0)) + dr u e(ph), and e(th0 + d) - e(th0) is the
    // chord 2 sin(d/2) e(th0 + d/2 + 90 deg): no difference of two large numbers.
    const double half = 0.5 * g.phi * u;
    const double c = 2.0 * g.r0 * std::sin(half);
    const double mid = g.th0 + half;
    out[g.first] = g.start[g.first] - c * std::sin(mid) + g.dr * u * std::cos(ph);
    out[g.second] = g.start[g.second] + c * std::cos(mid) + g.dr * u * std::sin(ph);
    return;
  }
  const double r = g.r0 + g.dr * u;
  out[g.first] = g.cx + r * std::cos(ph);
  out[g.second] = g.cy + r * std::sin(ph);
}

//! dx/ds at s (the tangent, |t| = 1 for lines and circles).
inline void geometry_tangent(const Geometry& g, int n, double s, double* out) {
  for (int i = 0; i < n; ++i) out[i] = g.dir[i];
  if (!g.arc) return;
  const double u = std::fmin(std::fmax(s / g.length, 0.0), 1.0);
  const double ph = g.th0 + g.phi * u;
  const double r = g.r0 + g.dr * u;
  const double c = std::cos(ph), sn = std::sin(ph);
  out[g.first] = (g.dr * c - r * g.phi * sn) / g.length;
  out[g.second] = (g.dr * sn + r * g.phi * c) / g.length;
}

//! d^2x/ds^2 at s (curvature vector; 0 for lines).
inline void geometry_curvature(const Geometry& g, int n, double s, double* out) {
  for (int i = 0; i < n; ++i) out[i] = 0.0;
  if (!g.arc) return;
  const double u = std::fmin(std::fmax(s / g.length, 0.0), 1.0);
  const double ph = g.th0 + g.phi * u;
  const double r = g.r0 + g.dr * u;
  const double c = std::cos(ph), sn = std::sin(ph);
  const double l2 = g.length * g.length;
  out[g.first] = (-2.0 * g.dr * g.phi * sn - r * g.phi * g.phi * c) / l2;
  out[g.second] = (2.0 * g.dr * g.phi * c - r * g.phi * g.phi * sn) / l2;
}

}  // namespace tgm::motion
