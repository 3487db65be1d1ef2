// Seeded random programs and machines for the sweeps, the debugging driver and the benchmarks.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "program_builder.hpp"
#include "tgm/config.hpp"
#include "tgm/intercode.hpp"

namespace tgm::test {

inline constexpr double kSweepPi = 3.14159265358979323846;

struct Generated {
  Program program;
  std::array<double, kMaxAxes> end{};
  std::vector<std::pair<double, double>> overrides;
};

// A random program for `axes` axes inside a +-200 mm box.
inline Generated random_program(std::mt19937_64& rng, int axes, int blocks) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto uni = [&](double a, double b) { return a + (b - a) * u(rng); };
  ProgramBuilder b(axes);
  auto clampbox = [](double v) { return std::clamp(v, -200.0, 200.0); };
  for (int k = 0; k < blocks; ++k) {
    const double feed = u(rng) < 0.2 ? uni(50.0, 500.0) : uni(500.0, 15000.0);
    const double kind = u(rng);
    std::array<double, kMaxAxes> p = b.position();
    if (kind < 0.30) {  // line, random length and direction in a random subset of axes
      const double len = u(rng) < 0.3 ? uni(0.001, 0.5) : uni(0.5, 60.0);
      for (int i = 0; i < axes; ++i) {
        if (u(rng) < 0.6 || i == 0) p[static_cast<std::size_t>(i)] = clampbox(p[static_cast<std::size_t>(i)] + uni(-len, len));
      }
      if (u(rng) < 0.1) {
        std::array<double, kMaxAxes> e = p;
        Segment s;
        (void)s;
        b.line_to(e, feed);
        b.program().segments.back().type = SegmentType::kRapid;
        b.program().segments.back().feed_mm_per_min = 0.0;
      } else {
        b.line_to(p, feed);
      }
    } else if (kind < 0.55 && axes >= 2) {  // arc or helix in a random plane
      Plane pl = Plane::kXY;
      if (axes >= 3) {
        const double r = u(rng);
        pl = r < 0.6 ? Plane::kXY : (r < 0.8 ? Plane::kXZ : Plane::kYZ);
      }
      const PlaneAxes pa = plane_xyz(pl);
      const double radius = u(rng) < 0.3 ? uni(0.2, 2.0) : uni(2.0, 40.0);
      const double a0 = uni(0, 2 * kSweepPi);
      const auto f = static_cast<std::size_t>(pa.first), s = static_cast<std::size_t>(pa.second);
      const std::array<double, 2> c = {p[f] - radius * std::cos(a0), p[s] - radius * std::sin(a0)};
      const bool ccw = u(rng) < 0.5;
      const bool full = u(rng) < 0.15;
      const double sweep = full ? 2 * kSweepPi : uni(0.05, 2 * kSweepPi - 0.05);
      const double a1 = a0 + (ccw ? sweep : -sweep);
      std::array<double, kMaxAxes> e = p;
      if (!full) {
        e[f] = c[0] + radius * std::cos(a1);
        e[s] = c[1] + radius * std::sin(a1);
      }
      if (u(rng) < 0.35) {  // helix: the other axes move
        for (int i = 0; i < axes; ++i) {
          if (i != pa.first && i != pa.second) e[static_cast<std::size_t>(i)] = clampbox(p[static_cast<std::size_t>(i)] + uni(-10.0, 10.0));
        }
      }
      b.arc(ccw, e, c, feed, pl, full && u(rng) < 0.2 ? 1 : 0);
    } else if (kind < 0.70) {  // CAM-like polyline: chords of a curve
      const int n = static_cast<int>(uni(5, 200));
      const double step = uni(0.01, 0.3);
      const double curv = uni(-0.2, 0.2);
      double heading = uni(0, 2 * kSweepPi);
      const int ax2 = axes >= 2 ? 1 : 0;
      for (int i = 0; i < n; ++i) {
        heading += curv * step + uni(-0.02, 0.02);
        p[0] = clampbox(p[0] + step * std::cos(heading));
        if (ax2 == 1) p[1] = clampbox(p[1] + step * std::sin(heading));
        if (axes >= 3) p[2] = clampbox(p[2] + uni(-0.002, 0.002));
        b.line_to(p, feed);
      }
    } else if (kind < 0.78) {
      b.m(static_cast<int>(uni(3, 999)), MKind::kNormal);
    } else if (kind < 0.86) {
      b.m(static_cast<int>(uni(1001, 5000)), MKind::kContinuous);
    } else if (kind < 0.90) {
      b.dwell(uni(0.0, 0.05));
    } else if (kind < 0.93) {
      b.message("note " + std::to_string(k));
    } else {  // sharp zig-zag
      for (int i = 0; i < 4; ++i) {
        p[0] = clampbox(p[0] + uni(-5, 5));
        if (axes >= 2) p[1] = clampbox(p[1] + uni(-5, 5));
        b.line_to(p, feed);
      }
    }
  }
  Generated g;
  g.end = b.position();
  b.end();
  g.program = b.program();
  const int changes = static_cast<int>(uni(0, 4));
  for (int i = 0; i < changes; ++i) g.overrides.push_back({uni(0.0, 5.0), uni(0.01, 2.0)});
  return g;
}

// What the sweep's time references need of motion record `sg` from `pos`: its length, its
// programmed feed [mm/s] (a rapid's: the rapid velocities projected on it), the cap of the axis
// velocity limits projected on it, and the tangential acceleration and jerk limits an exact stop
// on it may use. Arcs get a conservative share of the limits of the axes they move: half their
// acceleration and a quarter of their jerk along the path, and a speed within what the radius
// allows them (v^2 / r and v^3 / r^2 at half the limits: radius_cap).
struct RecordLimits {
  double length = 0.0;
  double feed = 0.0;
  double cap = std::numeric_limits<double>::infinity();
  double accel = std::numeric_limits<double>::infinity();
  double jerk = std::numeric_limits<double>::infinity();
  //! Arcs: the speed the radius allows at those shares (not part of the lower bound).
  double radius_cap = std::numeric_limits<double>::infinity();
};

inline RecordLimits record_limits(const Segment& sg, const std::array<double, kMaxAxes>& pos,
                                  const MachineConfig& machine, int n) {
  const InterpolatorConfig& ip = machine.interpolators[0];
  const double dt = machine.cycle_time_us * 1e-6 / 5.0;  // the calculation step
  // The interpolator's jerk limit of an axis: at most A / (4 dt) (core/MOTION.md).
  auto jerk_of = [&](const AxisConfig& ax) {
    return std::min(ax.max_jerk_mm_s3, ax.max_acceleration_mm_s2 / (4.0 * dt));
  };
  RecordLimits out;
  out.feed = sg.feed_mm_per_min / 60.0;
  if (!sg.is_arc()) {
    double l2 = 0.0;
    for (int i = 0; i < n; ++i) l2 += (sg.end[i] - pos[i]) * (sg.end[i] - pos[i]);
    out.length = std::sqrt(l2);
    double rapid = std::numeric_limits<double>::infinity();
    for (int i = 0; i < n && out.length > 0.0; ++i) {
      const double c = std::fabs(sg.end[i] - pos[i]) / out.length;
      if (c < 1e-12) continue;
      const AxisConfig& ax = ip.axes[static_cast<std::size_t>(i)];
      out.cap = std::min(out.cap, ax.max_velocity_mm_s / c);
      rapid = std::min(rapid, ax.rapid_velocity_mm_s / c);
      out.accel = std::min(out.accel, ax.max_acceleration_mm_s2 / c);
      out.jerk = std::min(out.jerk, jerk_of(ax) / c);
    }
    if (sg.type == SegmentType::kRapid) out.feed = rapid;
    return out;
  }
  const PlaneAxes pa = plane_xyz(sg.plane);
  const auto f = static_cast<std::size_t>(pa.first), s = static_cast<std::size_t>(pa.second);
  const double sx = pos[f] - sg.center[0], sy = pos[s] - sg.center[1];
  const double ex = sg.end[f] - sg.center[0], ey = sg.end[s] - sg.center[1];
  const double r0 = std::hypot(sx, sy), r1 = std::hypot(ex, ey);
  const double th0 = std::atan2(sy, sx), th1 = std::atan2(ey, ex);
  // A full circle by the interpolator's rule (an absolute distance, kFullCircleMm): one relative
  // to the radius would call an arc of a few 1e-9 mm a full circle on a large radius and put a
  // whole turn into the bound.
  const bool full = std::hypot(ex - sx, ey - sy) < kFullCircleMm;
  double sweep =
      full ? 2.0 * kSweepPi
           : std::fmod((sg.type == SegmentType::kArcCcw ? th1 - th0 : th0 - th1) + 4.0 * kSweepPi,
                       2.0 * kSweepPi);
  if (sweep <= 0.0) sweep += 2.0 * kSweepPi;
  sweep += 2.0 * kSweepPi * std::max(0, sg.turns);
  const double plane_len = sweep * 0.5 * (r0 + r1);
  double lin2 = 0.0;
  for (int i = 0; i < n; ++i) {
    if (i != pa.first && i != pa.second) lin2 += (sg.end[i] - pos[i]) * (sg.end[i] - pos[i]);
  }
  out.length = std::sqrt(plane_len * plane_len + lin2);
  for (int i = 0; i < n && out.length > 0.0; ++i) {
    if (i == pa.first || i == pa.second) continue;
    const double c = std::fabs(sg.end[i] - pos[i]) / out.length;
    if (c > 1e-12)
      out.cap = std::min(out.cap, ip.axes[static_cast<std::size_t>(i)].max_velocity_mm_s / c);
  }
  // The plane axes: the interpolator holds a whole arc record to one cap, each plane axis'
  // velocity limit over an upper bound of the share of the path speed it takes on the sweep,
  // (|r1 - r0| + r_max sweep m) / length with m the largest |sin th| (first axis) or |cos th|
  // (second) over the sweep: 1 where it passes sin th = +-1 (cos th = +-1), else at one of its
  // ends (core/MOTION.md, Planner). The first axis takes |r' cos th - r sin th| /
  // sqrt(r^2 + r'^2 + z'^2) of the path speed (r' = dr/dth, z'^2 the other axes' (dz/dth)^2),
  // the second |r' sin th + r cos th| / sqrt(...); here they are estimated from under by
  // share m with share = r_min / sqrt(r_max^2 + r'^2 + z'^2) <= r_max sweep / length. A
  // smaller share is a higher cap, so the bound stays below the interpolator's time. An arc that
  // ends just short of an axis' direction (Z at 86 degrees of an arc in G18 on a box machine
  // whose Z runs at 0.04 mm/s) used to add no cap for that axis: the bound was 175 s, the
  // program runs 2,000 s at Z's limit, and the time limit (4 x the bound + 60 s) called it a
  // crawl (box sweep seed 3 program 119).
  const double lo_th = sg.type == SegmentType::kArcCcw ? th0 : th0 - sweep;
  const double hi_th = lo_th + sweep;
  auto passes = [&](double target) {  // an angle target + k pi within [lo_th, lo_th + sweep]
    return target + std::ceil((lo_th - target) / kSweepPi) * kSweepPi <= hi_th;
  };
  const double rp = (r1 - r0) / sweep;
  const double share = std::min(r0, r1) / std::sqrt(std::max(r0, r1) * std::max(r0, r1) + rp * rp +
                                                    lin2 / (sweep * sweep));
  const double sin_max = passes(0.5 * kSweepPi)
                             ? 1.0
                             : std::max(std::fabs(std::sin(lo_th)), std::fabs(std::sin(hi_th)));
  const double cos_max =
      passes(0.0) ? 1.0 : std::max(std::fabs(std::cos(lo_th)), std::fabs(std::cos(hi_th)));
  if (share * sin_max > 0.0)
    out.cap = std::min(out.cap, ip.axes[f].max_velocity_mm_s / (share * sin_max));
  if (share * cos_max > 0.0)
    out.cap = std::min(out.cap, ip.axes[s].max_velocity_mm_s / (share * cos_max));
  // Acceleration and jerk: every axis the arc moves, at the conservative shares above.
  double a_min = std::numeric_limits<double>::infinity(), j_min = a_min;
  for (int i = 0; i < n; ++i) {
    if (i != pa.first && i != pa.second && std::fabs(sg.end[i] - pos[i]) <= 1e-12) continue;
    const AxisConfig& ax = ip.axes[static_cast<std::size_t>(i)];
    a_min = std::min(a_min, ax.max_acceleration_mm_s2);
    j_min = std::min(j_min, jerk_of(ax));
  }
  out.accel = 0.5 * a_min;
  out.jerk = 0.25 * j_min;
  const double r_min = std::max(std::min(r0, r1), 1e-9);
  out.radius_cap = std::min(std::sqrt(0.5 * a_min * r_min), std::cbrt(0.5 * j_min * r_min * r_min));
  return out;
}

// Rel_Speed over time: rel0, then each change from its time on.
class RelSchedule {
 public:
  RelSchedule(std::vector<std::pair<double, double>> changes, double rel0)
      : changes_(std::move(changes)), rel_(rel0) {
    std::sort(changes_.begin(), changes_.end());
  }
  //! Rel_Speed at time t (t must not decrease from call to call).
  double at(double t) {
    while (next_ < changes_.size() && changes_[next_].first <= t) rel_ = changes_[next_++].second;
    return rel_;
  }
  //! Time of the first change not yet applied by at(); infinity when none is left.
  double next_change() const {
    return next_ < changes_.size() ? changes_[next_].first
                                   : std::numeric_limits<double>::infinity();
  }

 private:
  std::vector<std::pair<double, double>> changes_;
  std::size_t next_ = 0;
  double rel_;
};

// Calls f(record_limits) for every motion record of `program` in order, each from the end of
// the one before (the program starts at 0).
template <class F>
void for_each_motion_record(const Program& program, const MachineConfig& machine, F&& f) {
  const int n = program.number_axes;
  std::array<double, kMaxAxes> pos{};
  for (const Segment& sg : program.segments) {
    if (!sg.is_motion()) continue;
    const RecordLimits lim = record_limits(sg, pos, machine, n);
    for (int i = 0; i < n; ++i) pos[i] = sg.end[i];
    f(lim);
  }
}

// Lower bound [s] of the time the motion of `program` needs on `machine` with Rel_Speed
// `rel0` changed at the given times: every record at its speed cap min(F x Rel_Speed, axis
// velocity limits projected on the record) the whole way, no acceleration, no corners, no
// centripetal limits, no waits. Integrated in time, so the override schedule applies where the
// motion is at that time. Unless Rel_Speed drops, the real path position never gets ahead of
// this one (it is never faster at the same place and time), so the real program cannot end
// earlier. A drop acts here at once and in the motion through a ramp: there the bound is
// approximate (the sweep checks it on programs without a drop).
inline double motion_time_lower_bound(const Program& program, const MachineConfig& machine,
                                      std::vector<std::pair<double, double>> changes,
                                      double rel0 = 1.0) {
  RelSchedule rel(std::move(changes), rel0);
  double t = 0.0;
  for_each_motion_record(program, machine, [&](const RecordLimits& lim) {
    double left = lim.length;
    while (left > 0.0) {
      const double v = std::min(lim.feed * rel.at(t), lim.cap);
      const double t_change = rel.next_change();
      if (t + left / v <= t_change) {
        t += left / v;
        left = 0.0;
      } else {
        left -= v * (t_change - t);
        t = t_change;
      }
    }
  });
  return t;
}

// Shortest time [s] to travel `length` from rest to rest with speed, acceleration and jerk at
// most v, a, j (the S-curve: jerk phases of a / j, a constant-acceleration phase when the speed
// reaches a^2 / j, a cruise at v when the length allows it).
inline double rest_to_rest_time(double length, double v, double a, double j) {
  if (!(length > 0.0)) return 0.0;
  // Speeding up from 0 to u and back down again takes time 2 t(u) over distance 2 d(u).
  auto t_of = [&](double u) { return u >= a * a / j ? u / a + a / j : 2.0 * std::sqrt(u / j); };
  auto d_of = [&](double u) { return 0.5 * u * t_of(u); };
  if (2.0 * d_of(v) <= length) return 2.0 * t_of(v) + (length - 2.0 * d_of(v)) / v;
  // The peak u < v where 2 d(u) = length: jerk phases only (2 u sqrt(u / j) = length), or with
  // a constant-acceleration phase (u^2 / a + u a / j = length) once u >= a^2 / j.
  double u = std::cbrt(0.25 * length * length * j);
  if (u >= a * a / j)
    u = 0.5 * (-a * a / j + std::sqrt(a * a * a * a / (j * j) + 4.0 * a * length));
  return 2.0 * t_of(u);
}

// Time [s] of an exact stop at every junction: each motion record of `program` from rest to
// rest at its cap min(F x Rel_Speed, axis velocity limits, radius_cap) with the tangential
// acceleration and jerk limits of record_limits, at the planner's margins (98 % of A, 90 % of J,
// 99.9 % of both). Rel_Speed is the one in force when the record starts, in this reference's own
// time. Carrying speed through junctions, a look-ahead planner is faster than this.
inline double motion_time_exact_stop(const Program& program, const MachineConfig& machine,
                                     std::vector<std::pair<double, double>> changes,
                                     double rel0 = 1.0) {
  RelSchedule rel(std::move(changes), rel0);
  double t = 0.0;
  for_each_motion_record(program, machine, [&](const RecordLimits& lim) {
    const double v = std::min({lim.feed * rel.at(t), lim.cap, lim.radius_cap});
    t += rest_to_rest_time(lim.length, v, 0.999 * 0.98 * lim.accel, 0.999 * 0.9 * lim.jerk);
  });
  return t;
}

// Time limit [s] of a sweep program: the time of a reference motion that runs every record at
// 1/`slowdown` of its cap min(F x Rel_Speed, axis velocity limits), with Rel_Speed changed at the
// given times, plus `slack_s` for accelerations, corners, arcs, dwells and M waits. A program
// that takes longer runs, on average, more than `slowdown` times below its caps: a crawl or a
// stall.
//
// The override schedule must apply at the reference's own times. `slowdown` x the lower bound
// with the changes at their real times (the earlier limit) does not do that: it places each
// change where the lower-bound motion is at that time, which can be past the program's end. A
// program that runs legitimately slower than its caps (corner-limited CAM chords at ~20 % of F)
// is then still in the middle of its path when Rel_Speed drops (e.g. to 0.0156 at 4.2 s) and
// runs the rest 64 x slower, which no limit computed without that drop allows for (seed 3
// program 465: lower bound 2.42 s, earlier limit 69.7 s; the program takes 103.5 s, at its
// corner limits before the drop and at F x Rel_Speed after it). Slowing the reference by `slowdown`
// with the changes at their real times is the same as the lower bound with the change times divided
// by `slowdown`, multiplied by `slowdown`.
//
// Or, when that is longer, 1.25 x the time of an exact stop at every junction
// (motion_time_exact_stop) + `slack_s`: no planner with look-ahead should be slower than that.
// On machines with a very soft axis the caps are far out of reach: box sweep seed 1 program 19
// (5 axes, Y at 0.12 mm/s^2 with a corner tolerance of 0.003 mm/s) runs at its acceleration,
// corner and arc limits and takes 269.3 s, against a lower bound of 15.5 s (limit 122.0 s) and
// an exact stop reference of 408.9 s.
inline double motion_time_limit(const Program& program, const MachineConfig& machine,
                                std::vector<std::pair<double, double>> changes, double slowdown = 4.0,
                                double slack_s = 60.0, double rel0 = 1.0) {
  const double stop_s = motion_time_exact_stop(program, machine, changes, rel0);
  for (auto& c : changes) c.first /= slowdown;
  const double bound_s = motion_time_lower_bound(program, machine, std::move(changes), rel0);
  return std::max(slowdown * bound_s, 1.25 * stop_s) + slack_s;
}

// Gives every M record of `p` a parameter set, as intercode does (the compiler's "not set"
// letters), so that the program survives PackedProgram::from_program unchanged.
inline void give_m_records_params(Program& p) {
  for (Segment& s : p.segments) {
    if (s.type == SegmentType::kMFunction && s.aux < 0) {
      s.aux = static_cast<std::int32_t>(p.params.size());
      p.params.push_back(unset_params());
    }
  }
}

inline MachineConfig random_machine(std::mt19937_64& rng, int axes) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  MachineConfig m = MachineConfig::default_machine();
  m.cycle_time_us = std::array<int, 3>{250, 500, 1000}[static_cast<std::size_t>(u(rng) * 2.999)];
  InterpolatorConfig& ip = m.interpolators[0];
  ip.buffer_size = u(rng) < 0.3 ? 1000 : 10000;
  ip.axes.clear();
  for (int i = 0; i < axes; ++i) {
    AxisConfig a;
    a.letter = default_axis_letter(i);
    a.max_velocity_mm_s = 50.0 + 300.0 * u(rng);
    a.rapid_velocity_mm_s = a.max_velocity_mm_s * (0.5 + 0.5 * u(rng));
    a.max_acceleration_mm_s2 = 300.0 + 3000.0 * u(rng);
    a.max_jerk_mm_s3 = 5000.0 + 100000.0 * u(rng);
    a.emergency_deceleration_mm_s2 = a.max_acceleration_mm_s2 * (1.0 + 2.0 * u(rng));
    a.corner_velocity_tolerance_mm_s = 0.5 + 5.0 * u(rng);
    ip.axes.push_back(a);
  }
  return m;
}

// A random machine of 1..4 axes and a random program of 4 up to 4 + extra_blocks blocks for
// it, its M records given their parameter sets (give_m_records_params): what the block search
// and the program-times sweeps draw first from a program's generator.
struct RandomCase {
  int axes = 0;
  MachineConfig machine;
  Generated generated;
};

inline RandomCase random_case(std::mt19937_64& rng, int extra_blocks) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  RandomCase c;
  c.axes = 1 + static_cast<int>(u(rng) * 4.0);
  c.machine = random_machine(rng, c.axes);
  c.generated = random_program(rng, c.axes, 4 + static_cast<int>(u(rng) * extra_blocks));
  give_m_records_params(c.generated.program);
  return c;
}

// A machine from a much wider envelope than random_machine's (which the CTest sweeps use): per
// axis, log-uniform velocity 1..1e4 mm/s, acceleration 10..1e5 mm/s^2, jerk 100..1e8 mm/s^3 and
// corner tolerance 0.01..100 mm/s, held to realistic relations (v / A 5 ms..5 s, A / J
// 2 ms..0.5 s), and axes that differ from each other by orders of magnitude. Not in CTest:
// `--machines=wide` on the sweep's command line (core/MOTION_LOG.md, "Machines far from the
// swept envelope").
inline MachineConfig wide_machine(std::mt19937_64& rng, int axes) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto log_uniform = [&](double lo, double hi) { return std::exp(std::log(lo) + (std::log(hi) - std::log(lo)) * u(rng)); };
  MachineConfig m = random_machine(rng, axes);
  for (AxisConfig& a : m.interpolators[0].axes) {
    a.max_velocity_mm_s = log_uniform(1.0, 1e4);
    a.rapid_velocity_mm_s = a.max_velocity_mm_s * (0.5 + 0.5 * u(rng));
    a.max_acceleration_mm_s2 =
        std::clamp(log_uniform(10.0, 1e5), a.max_velocity_mm_s / 5.0, a.max_velocity_mm_s / 0.005);
    a.max_jerk_mm_s3 =
        std::clamp(log_uniform(100.0, 1e8), a.max_acceleration_mm_s2 / 0.5, a.max_acceleration_mm_s2 / 0.002);
    a.emergency_deceleration_mm_s2 = a.max_acceleration_mm_s2 * (1.0 + 2.0 * u(rng));
    a.corner_velocity_tolerance_mm_s = log_uniform(0.01, 100.0);
  }
  return m;
}

// A machine from the whole box of axis limits the config accepts (config.hpp, kMin* / kMax*):
// per axis log-uniform velocity 0.01..1e5 mm/s, acceleration 0.1..1e6 mm/s^2, jerk 10..1e10
// mm/s^3 and corner tolerance 0.001..1e4 mm/s, with no relation between them (v / A from 1e-8 s
// to 1e6 s). `--machines=box` on the sweep's command line (core/MOTION.md, "Accepted machine
// limits"); CTest runs the first 50 programs of seed 2 (motion.sweep.box2).
inline MachineConfig box_machine(std::mt19937_64& rng, int axes) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto log_uniform = [&](double lo, double hi) {
    return std::exp(std::log(lo) + (std::log(hi) - std::log(lo)) * u(rng));
  };
  MachineConfig m = random_machine(rng, axes);
  for (AxisConfig& a : m.interpolators[0].axes) {
    a.max_velocity_mm_s = log_uniform(kMinVelocity, kMaxVelocity);
    a.rapid_velocity_mm_s = std::max(kMinVelocity, a.max_velocity_mm_s * (0.5 + 0.5 * u(rng)));
    a.max_acceleration_mm_s2 = log_uniform(kMinAcceleration, kMaxAcceleration);
    a.max_jerk_mm_s3 = log_uniform(kMinJerk, kMaxJerk);
    a.emergency_deceleration_mm_s2 =
        std::min(kMaxAcceleration, a.max_acceleration_mm_s2 * (1.0 + 2.0 * u(rng)));
    a.corner_velocity_tolerance_mm_s = log_uniform(kMinCornerTolerance, kMaxCornerTolerance);
  }
  return m;
}

// The machines a sweep or the simulate fuzzer draws: random_machine, wide_machine, box_machine.
enum class MachineKind { kRandom, kWide, kBox };

inline const char* machine_kind_name(MachineKind kind) {
  return kind == MachineKind::kWide ? "wide" : kind == MachineKind::kBox ? "box" : "random";
}

// The kind named "random", "wide" or "box"; false for any other name.
inline bool machine_kind_from_name(std::string_view name, MachineKind& kind) {
  for (const MachineKind k : {MachineKind::kRandom, MachineKind::kWide, MachineKind::kBox}) {
    if (name == machine_kind_name(k)) {
      kind = k;
      return true;
    }
  }
  return false;
}

inline MachineConfig machine_of_kind(MachineKind kind, std::mt19937_64& rng, int axes) {
  return kind == MachineKind::kWide  ? wide_machine(rng, axes)
         : kind == MachineKind::kBox ? box_machine(rng, axes)
                                     : random_machine(rng, axes);
}

}  // namespace tgm::test
