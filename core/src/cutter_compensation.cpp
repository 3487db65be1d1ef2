#include "cutter_compensation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <utility>

namespace tgm::detail {
namespace {

using V = Vec2;

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;
//! Offset ends closer than this meet without a corner [mm].
constexpr double kJoinMm = 1e-9;
//! How far an intersection may lie outside an element and still count as on it [mm].
constexpr double kOnMm = 1e-7;
//! Moves that meet at a smaller angle join without a corner (rs274's rule) [rad].
constexpr double kTangentRad = 0.05;
//! Smallest compensated arc radius [mm].
constexpr double kMinRadiusMm = 1e-6;

V operator+(V a, V b) {
  return {a.x + b.x, a.y + b.y};
}
V operator-(V a, V b) {
  return {a.x - b.x, a.y - b.y};
}
V operator*(double k, V a) {
  return {k * a.x, k * a.y};
}
double dot(V a, V b) {
  return a.x * b.x + a.y * b.y;
}
double cross(V a, V b) {
  return a.x * b.y - a.y * b.x;
}
double norm(V a) {
  return std::hypot(a.x, a.y);
}
//! Left normal of a direction.
V left(V t) {
  return {-t.y, t.x};
}

//! Unit tangent of an arc around `c` at `p`, in its direction of travel.
V arc_tangent(V c, V p, bool cw) {
  const V u = p - c;
  const double n = norm(u);
  const V r = n > 0 ? (1.0 / n) * u : V{1, 0};
  return cw ? V{r.y, -r.x} : V{-r.y, r.x};
}

//! Angle from `from` to `to` around `c` in the arc's direction, in [0, 2 pi).
double arc_angle(V c, V from, V to, bool cw) {
  double a = std::atan2(to.y - c.y, to.x - c.x) - std::atan2(from.y - c.y, from.x - c.x);
  if (cw) a = -a;
  a = std::fmod(a, kTwoPi);
  if (a < 0) a += kTwoPi;
  return a;
}

std::string mm(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

//! Intersections of the line a + t d (d unit) with the circle (c, r).
int line_circle(V a, V d, V c, double r, V out[2]) {
  const V f = a - c;
  const double b = dot(d, f);
  const double disc = b * b - (dot(f, f) - r * r);
  if (disc < 0) {
    // Tangent within rounding: the point of closest approach.
    if (disc > -1e-12 * r * r) {
      out[0] = a + (-b) * d;
      return 1;
    }
    return 0;
  }
  const double s = std::sqrt(disc);
  out[0] = a + (-b - s) * d;
  out[1] = a + (-b + s) * d;
  return 2;
}

//! Intersections of the circles (c0, r0) and (c1, r1).
int circle_circle(V c0, double r0, V c1, double r1, V out[2]) {
  const V d = c1 - c0;
  const double l = norm(d);
  if (l < 1e-15) return 0;
  const double x = (l * l + r0 * r0 - r1 * r1) / (2 * l);
  double h2 = r0 * r0 - x * x;
  if (h2 < 0) {
    if (h2 < -1e-12 * r0 * r0) return 0;
    h2 = 0;
  }
  const double h = std::sqrt(h2);
  const V u = (1.0 / l) * d;
  const V m = c0 + x * u;
  out[0] = m + h * left(u);
  out[1] = m + (-h) * left(u);
  return 2;
}

//! The distance mu along the unit direction u from b to the point b + mu u that lies as far
//! from p as from q; nothing when that line runs square to p-q (no such point, or every one).
std::optional<double> equidistant_along(V b, V u, V p, V q) {
  const double den = 2.0 * dot(u, q - p);
  if (std::fabs(den) < 1e-12) return std::nullopt;
  return (dot(b - q, b - q) - dot(b - p, b - p)) / den;
}

}  // namespace

CutterCompensation::CutterCompensation(std::string_view axis_letters, Emit emit, Fail fail)
    : letters_(axis_letters), emit_(std::move(emit)), fail_(std::move(fail)) {}

void CutterCompensation::fail(int line, std::string reason) {
  if (failed_) return;
  failed_ = true;
  held_.clear();
  fail_(line, std::move(reason));
}

bool CutterCompensation::in_plane_move(const Segment& s, V from) const {
  if (s.is_arc()) return true;
  if (!s.is_motion()) return false;
  return norm(plane_point(s) - from) > kFullCircleMm;
}

double CutterCompensation::param(const Elem& el, V p) {
  if (el.arc) return arc_angle(el.c, el.s, p, el.cw);
  return dot(p - el.a, el.d);
}

bool CutterCompensation::offset_element(const Segment& s, V from, Elem& el) {
  const double sigma = side_ == Compensation::kLeft ? 1.0 : -1.0;
  const V p = plane_point(s);
  el = Elem{};
  el.line = s.line;
  el.from = from;
  el.corner = p;
  if (!s.is_arc()) {
    const double len = norm(p - from);
    el.d = (1.0 / len) * (p - from);
    const V n = (sigma * radius_) * left(el.d);
    el.a = from + n;
    el.s = el.a;
    el.e = p + n;
    el.t0 = 0;
    el.t1 = len;
    el.t_start = el.t_end = el.d;
    return true;
  }
  el.arc = true;
  el.cw = s.type == SegmentType::kArcCw;
  el.c = {s.center[0], s.center[1]};
  // Left of a CW arc is away from its centre, left of a CCW arc towards it.
  // A programmed arc may end off the circle through its start, within the arc tolerance: the
  // start is offset on the one, the end on the other (rs274 alike).
  const double r0 = std::min(norm(from - el.c), norm(p - el.c));
  const double grow = el.cw ? sigma * radius_ : -sigma * radius_;
  const double r = norm(from - el.c) + grow;
  el.r_end = norm(p - el.c) + grow;
  if (r0 + grow < kMinRadiusMm) {
    fail(s.line, "tool radius compensation: the tool radius " + mm(radius_) +
                     " mm is not smaller than the radius " + mm(r0) +
                     " mm of this arc, whose inside it follows");
    return false;
  }
  el.r = r;
  const auto on_circle = [&](V q, double radius) {
    const V u = q - el.c;
    const double n = norm(u);
    return n > 0 ? el.c + (radius / n) * u : el.c + V{radius, 0};
  };
  el.s = on_circle(from, r);
  el.e = on_circle(p, el.r_end);
  const bool full = norm(p - from) < kFullCircleMm;
  el.sweep = (full ? kTwoPi : arc_angle(el.c, el.s, el.e, el.cw)) + kTwoPi * std::max(0, s.turns);
  el.t_start = arc_tangent(el.c, from, el.cw);
  el.t_end = arc_tangent(el.c, p, el.cw);
  return true;
}

bool CutterCompensation::entry_element(const Segment& s, V from, Elem& el) {
  const double sigma = side_ == Compensation::kLeft ? 1.0 : -1.0;
  const V p = plane_point(s);
  const double dist = norm(p - from);
  const std::string g = side_ == Compensation::kLeft ? "G41" : "G42";
  if (!s.is_arc()) {
    if (dist <= radius_) {
      fail(s.line, "tool radius compensation: the entry move after " + g + " (" + mm(dist) +
                       " mm in the plane) must be longer than the tool radius " + mm(radius_) +
                       " mm");
      return false;
    }
    if (!offset_element(s, from, el)) return false;
    el.s = from;  // the move starts where the tool stands
    // It runs from there straight to wherever the next corner cuts its offset line, before
    // that line's start too (rs274 alike): no start to run behind.
    el.t0 = -std::numeric_limits<double>::infinity();
    return true;
  }
  if (dist < kFullCircleMm) {
    fail(s.line, "tool radius compensation: the entry move after " + g +
                     " cannot be a full circle (start it with a straight move)");
    return false;
  }
  el = Elem{};
  el.arc = true;
  el.cw = s.type == SegmentType::kArcCw;
  el.line = s.line;
  el.from = from;
  el.corner = p;
  const V c{s.center[0], s.center[1]};
  el.t_end = arc_tangent(c, p, el.cw);
  const V e = p + (sigma * radius_) * left(el.t_end);
  // The centre stays on the radial line through the end: c' = p + mu u, as far from the
  // start as from the offset end.
  const V u = (1.0 / norm(c - p)) * (c - p);
  const std::optional<double> mu = equidistant_along(p, u, from, e);
  if (!mu) {
    fail(s.line,
         "tool radius compensation: the entry arc after " + g +
             " has no centre that reaches its compensated end (start with a straight move)");
    return false;
  }
  el.c = p + *mu * u;
  el.r = norm(from - el.c);
  el.r_end = norm(e - el.c);
  if (el.r < kMinRadiusMm) {
    fail(s.line, "tool radius compensation: the entry arc after " + g +
                     " shrinks to a point (start with a straight move)");
    return false;
  }
  el.s = from;
  el.e = e;
  el.sweep = arc_angle(el.c, el.s, el.e, el.cw) + kTwoPi * std::max(0, s.turns);
  el.t_start = arc_tangent(el.c, from, el.cw);
  return true;
}

bool CutterCompensation::join(Elem& next, bool& corner) {
  corner = false;
  Elem& prev = cur_;
  if (norm(prev.e - next.s) <= kJoinMm) {
    next.s = prev.e;
    return true;
  }
  const double turn = cross(prev.t_end, next.t_start);
  const double sigma = side_ == Compensation::kLeft ? 1.0 : -1.0;
  if (std::atan2(std::fabs(turn), dot(prev.t_end, next.t_start)) < kTangentRad) {
    // Tangent as programmed (a CAM post rounds its numbers): no corner, the next move starts
    // where this one ends, as rs274 runs it.
    next.s = prev.e;
    if (!next.arc) {
      const double len = norm(next.e - next.s);
      if (len > 0) {
        next.a = next.s;
        next.d = (1.0 / len) * (next.e - next.s);
        next.t0 = 0;
        next.t1 = len;
      }
      return true;
    }
    // The arc starts off its circle by the square of the angle: within the arc tolerance it
    // runs so; beyond it its centre moves along the radius through its end to where the two
    // points are equally far (the interpolator refuses a record whose start is off).
    if (std::fabs(norm(next.s - next.c) - next.r_end) > 0.5 * arc_radius_tolerance_mm(next.r_end)) {
      const V u = (1.0 / norm(next.c - next.e)) * (next.c - next.e);
      const std::optional<double> mu = equidistant_along(next.e, u, next.s, next.e);
      if (mu && *mu > kMinRadiusMm) {
        next.c = next.e + *mu * u;
        next.r = next.r_end = *mu;
      }
    }
    next.sweep = arc_angle(next.c, next.s, next.e, next.cw) +
                 (next.sweep >= kTwoPi ? kTwoPi * std::floor(next.sweep / kTwoPi) : 0.0);
    return true;
  }
  // Within kTangentRad of a reversal the tangents do not say which side the corner opens to:
  // where an arc bends back, the two moves cross a little way on and the tool stands in the
  // narrowing gap between them (a CAM post's rounded numbers make such a cusp). Round the tip
  // it would come back through the move before, closer than r; where the offsets cross on both
  // moves the cut is there, as at a concave corner (rs274 alike), else the corner goes round.
  const bool reversal =
      kPi - std::atan2(std::fabs(turn), dot(prev.t_end, next.t_start)) < kTangentRad;
  const bool concave = sigma * turn > 1e-12;
  if (concave || reversal) {
    // Both elements on their whole line or circle; the cut is the intersection that lies on
    // both and comes first along the next one. Behind the held move's start it would run
    // backwards; beyond the next move's end that one would run back to its end, and there
    // the tool stands closer than r to the held move's contour (rs274 lets this pass when
    // the next corner turns away: its path cuts in).
    V x;
    double along = 0;
    if (first_crossing(prev, next, false, x, along)) {
      if (prev.arc) prev.sweep = param(prev, x);
      prev.e = x;
      if (next.arc) {
        next.sweep -= std::max(0.0, along / next.r);
      } else {
        next.t0 = param(next, x);
      }
      next.s = x;
      return true;
    }
    if (concave) {
      fail(next.line, "tool radius compensation: the tool (radius " + mm(radius_) +
                          " mm) cannot reach the concave corner at line " +
                          std::to_string(prev.line) + "'s end without cutting into the contour");
      return false;
    }
    // Round the tip of a reversal: right where the material between the moves narrows to it,
    // a cut into the move before where the moves cross behind it and the gap is the tool's.
    if (first_crossing(prev, next, true, x, along)) {
      fail(next.line, "tool radius compensation: this move crosses line " +
                          std::to_string(prev.line) + "'s move " + mm(norm(x - prev.corner)) +
                          " mm from their corner; the tool (radius " + mm(radius_) +
                          " mm) cannot reach that corner without cutting into the contour");
      return false;
    }
  }
  corner = true;
  return true;
}

bool CutterCompensation::first_crossing(const Elem& prev, const Elem& next, bool programmed, V& x,
                                        double& along) const {
  // The programmed contour lies r to the other side of the tool's path; an arc's centre is
  // the same, its circle runs through the corner.
  const double sigma = side_ == Compensation::kLeft ? 1.0 : -1.0;
  const V corner = prev.corner;
  const auto anchor = [&](const Elem& el) {
    return programmed ? el.a + (-sigma * radius_) * left(el.d) : el.a;
  };
  V cand[2];
  int n = 0;
  if (!prev.arc && !next.arc) {
    const double den = cross(prev.d, next.d);
    if (std::fabs(den) > 1e-15) {
      const V pa = anchor(prev);
      cand[0] = pa + (cross(anchor(next) - pa, next.d) / den) * prev.d;
      n = 1;
    }
  } else if (!prev.arc) {
    n = line_circle(anchor(prev), prev.d, next.c, programmed ? norm(corner - next.c) : next.r,
                    cand);
  } else if (!next.arc) {
    n = line_circle(anchor(next), next.d, prev.c, programmed ? norm(corner - prev.c) : prev.r_end,
                    cand);
  } else {
    n = circle_circle(prev.c, programmed ? norm(corner - prev.c) : prev.r_end, next.c,
                      programmed ? norm(corner - next.c) : next.r_end, cand);
  }
  int pick = -1;
  for (int k = 0; k < n; ++k) {
    const V q = cand[k];
    if (programmed && norm(q - corner) <= kOnMm) continue;  // the corner itself
    // On prev, between its start and its nominal end (its contour: from its programmed start,
    // where an earlier corner may have cut the tool's path short).
    if (programmed && prev.arc) {
      const double a = arc_angle(prev.c, prev.from, q, prev.cw);
      const double sweep = norm(prev.corner - prev.from) < kFullCircleMm
                               ? kTwoPi
                               : arc_angle(prev.c, prev.from, prev.corner, prev.cw);
      if (a * prev.r_end > sweep * prev.r_end + kOnMm) continue;
    } else if (prev.arc) {
      const double a = param(prev, q);
      if (a * prev.r_end > prev.sweep * prev.r_end + kOnMm && prev.sweep < kTwoPi) continue;
    } else {
      const double t = param(prev, q);
      if (t < (programmed ? 0.0 : prev.t0) - kOnMm || t > prev.t1 + kOnMm) continue;
    }
    // On next, from its start on.
    double d = 0;
    if (next.arc) {
      d = param(next, q);
      if ((kTwoPi - d) * next.r <= kOnMm) d = 0;  // just behind the start
      if (d > next.sweep) continue;
      d *= next.r;
    } else {
      const double t = param(next, q);
      if (t < next.t0 - kOnMm || t > next.t1 + kOnMm) continue;
      d = t - next.t0;
    }
    if (pick < 0 || d < along) {
      pick = k;
      along = d;
      x = q;
    }
  }
  return pick >= 0;
}

void CutterCompensation::flush() {
  if (held_.empty()) return;
  for (std::size_t k = 0; k < held_.size(); ++k) {
    Segment& s = held_[k];
    set_plane_point(s, cur_.e);
    if (k == 0 && cur_.arc) {
      s.center = {cur_.c.x, cur_.c.y};
      s.radius = cur_.r;
      // Cut to nothing: its end at its start would read as a full circle.
      if (cur_.sweep * cur_.r_end < kFullCircleMm * 10) {
        s.type = SegmentType::kLinear;
        s.center = {};
        s.radius = 0;
      }
    }
    emit_(s);
  }
  out_ = cur_.e;
  held_.clear();
}

void CutterCompensation::push(const Segment& in, const std::array<double, kMaxAxes>& from_all) {
  if (failed_) return;
  Segment s = in;
  const bool comp = s.compensation != Compensation::kOff && s.compensation_radius_mm > 0;
  if (on_ && (!comp || s.compensation != side_ || s.compensation_radius_mm != radius_ ||
              s.plane != plane_)) {
    // G40 (the compiler refuses other changes while it is on).
    flush();
    on_ = false;
    const V prog{from_all[p0_], from_all[p1_]};
    exit_pending_ = norm(out_ - prog) > kJoinMm;
  }
  if (!comp) {
    if (exit_pending_) {
      if (s.is_motion()) {
        exit_pending_ = false;
        if (s.is_arc()) {
          fail(s.line,
               "tool radius compensation: the move after G40 leads from the "
               "compensated path back to the programmed one and must be straight, "
               "not an arc");
          return;
        }
      } else {
        // Stands at the compensated point until the exit move.
        set_plane_point(s, out_);
      }
    }
    emit_(s);
    return;
  }
  if (!on_) {
    const PlaneAxes pa = plane_axes(s.plane, letters_);
    if (pa.first >= kMaxAxes || pa.second >= kMaxAxes) {
      fail(s.line, "tool radius compensation needs both axes of plane G" +
                       std::to_string(static_cast<int>(s.plane)));
      return;
    }
    p0_ = static_cast<std::size_t>(pa.first);
    p1_ = static_cast<std::size_t>(pa.second);
    if (!exit_pending_) out_ = {from_all[p0_], from_all[p1_]};
    exit_pending_ = false;
    on_ = true;
    entry_ = true;
    side_ = s.compensation;
    radius_ = s.compensation_radius_mm;
    plane_ = s.plane;
  }
  const V from{from_all[p0_], from_all[p1_]};
  if (!in_plane_move(s, from)) {
    if (held_.empty()) {
      set_plane_point(s, out_);
      emit_(s);
    } else {
      held_.push_back(s);
    }
    return;
  }
  Elem next;
  if (entry_) {
    if (!entry_element(s, out_, next)) return;
    entry_ = false;
  } else {
    if (!offset_element(s, from, next)) return;
    bool corner = false;
    if (!join(next, corner)) return;
    const std::array<double, kMaxAxes> at = held_.back().end;
    flush();
    if (corner && s.type == SegmentType::kRapid) {
      // Around the corner of a rapid move straight, at rapid (rs274 does the same).
      Segment link = s;
      link.end = at;
      set_plane_point(link, next.s);
      emit_(link);
      out_ = next.s;
    } else if (corner) {
      Segment arc = s;
      arc.type = side_ == Compensation::kLeft ? SegmentType::kArcCw : SegmentType::kArcCcw;
      arc.end = at;
      set_plane_point(arc, next.s);
      arc.center = {cur_.corner.x, cur_.corner.y};
      arc.radius = radius_;
      arc.turns = 0;
      emit_(arc);
      out_ = next.s;
    }
  }
  if (next.arc) {
    s.center = {next.c.x, next.c.y};
    s.radius = next.r;
  }
  set_plane_point(s, next.e);
  cur_ = next;
  held_.push_back(s);
}

void CutterCompensation::finish() {
  if (failed_) return;
  flush();
}

}  // namespace tgm::detail
