// Known values: end points, times, peak speeds, arc closure, helix pitch, register sequences.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>
#include <vector>

#include "program_builder.hpp"
#include "tgm/gcode.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/limit_checker.hpp"
#include "tgm/simulation.hpp"

namespace tgm {
namespace {

using test::ProgramBuilder;
constexpr double kPi = 3.14159265358979323846;

MachineConfig machine() { return MachineConfig::default_machine(); }

SimulationSummary simulate(const Program& p, SimulationOptions o = {},
                           const std::function<void(const Registers&)>& on_cycle = {},
                           MachineConfig m = machine(), const std::array<double, kMaxAxes>& start = {}) {
  o.check_limits = true;
  auto sim = Simulation::create(m, o);
  EXPECT_TRUE(sim.has_value());
  EXPECT_TRUE(sim->interpolator().set_position(start).ok());
  return sim->run(p, on_cycle);
}

void expect_clean(const SimulationSummary& s) {
  EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
  EXPECT_FALSE(s.nan);
  EXPECT_EQ(s.hard_stops, 0u);
  EXPECT_EQ(s.violation_count, 0u);
  for (const auto& v : s.violations) {
    ADD_FAILURE() << "cycle " << v.cycle << " line " << v.line << " axis " << v.axis << " "
                  << limit_quantity_name(v.quantity) << " " << v.value << " > " << v.limit;
    break;
  }
}

TEST(KnownValues, StraightMoveEndTimeAndPeak) {
  ProgramBuilder b;
  b.line({100.0, 0.0, 0.0}, 6000.0).end();
  double peak = 0.0;
  const auto s = simulate(b.program(), {}, [&](const Registers& r) { peak = std::max(peak, r.act_speed); });
  expect_clean(s);
  EXPECT_EQ(s.end_position[0], 100.0);
  EXPECT_EQ(s.end_position[1], 0.0);
  EXPECT_NEAR(peak, 6000.0, 1e-6);
  // S-curves with a constant-acceleration phase (v = 100 > A^2/J): each ramp takes v/A + A/J and
  // t = D/v + (ramp up + ramp down) / 2. The planner uses 99.9 % of the limits, and brakes
  // with 98 % of that acceleration and 90 % of that jerk (MOTION.md, "Margins").
  const double a1 = 0.999 * 1500.0, j1 = 0.999 * 30000.0, a2 = 0.98 * a1, j2 = 0.9 * j1;
  const double t = 1.0 + 0.5 * (100.0 / a1 + a1 / j1 + 100.0 / a2 + a2 / j2);
  EXPECT_NEAR(s.program_time_s, t, 0.001);
  EXPECT_NEAR(s.distance_mm, 100.0, 1e-9);
}

TEST(KnownValues, ShortMoveNeverReachesFeed) {
  // 1 mm at F6000: jerk-limited, no cruise. Peak speed from the symmetric S-curve.
  ProgramBuilder b;
  b.line({1.0, 0.0, 0.0}, 6000.0).end();
  double peak = 0.0;
  const auto s = simulate(b.program(), {}, [&](const Registers& r) { peak = std::max(peak, r.act_speed); });
  expect_clean(s);
  EXPECT_EQ(s.end_position[0], 1.0);
  // Without reaching A each ramp covers v * sqrt(v / J): D = v^1.5 (J1^-0.5 + J2^-0.5), with
  // J1 = 99.9 % and J2 = 90 % of that (braking margin).
  const double j1 = 0.999 * 30000.0, j2 = 0.9 * j1;
  const double v = std::pow(1.0 / (1.0 / std::sqrt(j1) + 1.0 / std::sqrt(j2)), 2.0 / 3.0);
  EXPECT_NEAR(peak / 60.0, v, 0.02 * v);
  EXPECT_LT(peak / 60.0, v * 1.0001);
}

TEST(KnownValues, FullCircleClosesInEveryPlane) {
  for (Plane pl : {Plane::kXY, Plane::kXZ, Plane::kYZ}) {
    for (bool ccw : {false, true}) {
      const PlaneAxes pa = plane_xyz(pl);
      std::array<double, kMaxAxes> start{};
      start[static_cast<std::size_t>(pa.first)] = 12.5;
      start[static_cast<std::size_t>(pa.second)] = -3.25;
      ProgramBuilder b(3, start);
      b.arc(ccw, start, {12.5 - 20.0, -3.25}, 3000.0, pl).end();
      const auto s = simulate(b.program(), {}, {}, machine(), start);
      expect_clean(s);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(s.end_position[static_cast<std::size_t>(i)], start[static_cast<std::size_t>(i)], 1e-9);
      EXPECT_NEAR(s.distance_mm, 2.0 * kPi * 20.0, 1e-9);
    }
  }
}

// Arc planes go by the axes' letters (plane_axes): a lathe of axes X, Z closes a G18 circle, and
// an interpolator whose axes 0 and 1 are Y and X runs the program of the X, Y, Z machine with
// those two columns swapped, cycle for cycle.
TEST(KnownValues, ArcPlanesFollowTheAxisLetters) {
  const auto run_gcode = [](MachineConfig m, const std::string& text,
                            std::vector<std::array<double, kMaxAxes>>& path) {
    const CompileResult c = compile_gcode(text, CompileOptions::from_machine(m, 0));
    EXPECT_TRUE(c.ok()) << (c.errors.empty() ? "" : c.errors[0].reason);
    return simulate(
        c.program, {}, [&](const Registers& r) { path.push_back(r.orig_position); }, std::move(m));
  };
  MachineConfig lathe = machine();
  auto& axes = lathe.interpolators[0].axes;
  axes.erase(axes.begin() + 1);  // X, Z
  axes[1].letter = 'Z';
  std::vector<std::array<double, kMaxAxes>> turned;
  const auto l = run_gcode(lathe, "G90 G18 G1 X20 Z-5 F3000\nG2 I-10 K0\nM2\n", turned);
  expect_clean(l);
  EXPECT_NEAR(l.end_position[0], 20.0, 1e-9);
  EXPECT_NEAR(l.end_position[1], -5.0, 1e-9);
  EXPECT_NEAR(l.distance_mm, std::hypot(20.0, 5.0) + 2.0 * kPi * 10.0, 1e-9);
  double far_x = 0.0;  // the circle about X10 reaches X0
  for (const auto& q : turned) far_x = std::min(far_x, q[0] - 10.0);
  EXPECT_NEAR(far_x, -10.0, 1e-3);

  const std::string text = "G90 G1 X10 Y0 F3000\nG2 X20 Y0 I5 J0\nG3 X10 Y0 R5\nM2\n";
  std::vector<std::array<double, kMaxAxes>> xy, yx;
  expect_clean(run_gcode(machine(), text, xy));
  MachineConfig swapped = machine();
  std::swap(swapped.interpolators[0].axes[0].letter, swapped.interpolators[0].axes[1].letter);
  expect_clean(run_gcode(swapped, text, yx));
  ASSERT_EQ(xy.size(), yx.size());
  double deviation = 0.0;
  for (std::size_t k = 0; k < xy.size(); ++k) {
    deviation = std::max({deviation, std::fabs(xy[k][0] - yx[k][1]), std::fabs(xy[k][1] - yx[k][0]),
                          std::fabs(xy[k][2] - yx[k][2])});
  }
  EXPECT_LT(deviation, 1e-12);
  EXPECT_NEAR(yx.back()[1], 10.0, 1e-9);
}

TEST(KnownValues, CircleStaysOnRadiusAndTurnsTheRightWay) {
  ProgramBuilder b;
  b.arc(true, {10.0, 0.0, 0.0}, {0.0, 0.0}, 3000.0).end();  // full CCW circle from (10, 0)
  b.program().segments[0].end = {10.0, 0.0, 0.0};
  std::vector<double> angles;
  double max_dev = 0.0;
  ProgramBuilder c(3, {10.0, 0.0, 0.0});
  c.arc(true, {10.0, 0.0, 0.0}, {0.0, 0.0}, 3000.0).end();
  SimulationOptions o;
  auto m = machine();
  auto sim = Simulation::create(m, o);
  ASSERT_TRUE(sim);
  sim->interpolator().set_position({10.0, 0.0, 0.0});
  const auto s = sim->run(c.program(), [&](const Registers& r) {
    max_dev = std::max(max_dev, std::fabs(std::hypot(r.orig_position[0], r.orig_position[1]) - 10.0));
    angles.push_back(std::atan2(r.orig_position[1], r.orig_position[0]));
  });
  EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
  EXPECT_LT(max_dev, 1e-9);
  // CCW: early samples have positive y.
  ASSERT_GT(angles.size(), 100u);
  EXPECT_GT(angles[50], 0.0);
}

// An arc of a radius of 1e9 mm (what a CAM post or a typo can write: the compiler takes centres
// up to 1e9 mm). Centre + r cos(phi) rounded by 1e-7 mm from cycle to cycle, a jerk of about
// 34,000 mm/s^3 on X (limit 30,000) in the limit check: the simulate fuzz target found it. The
// short way (20 mm, nearly a line) and the long way (nearly the whole circle, cut off after
// 3 s) both keep every limit; the short way ends exactly, its middle on the circle (sagitta
// 400 / 8e9 mm below the chord).
TEST(KnownValues, ArcOfAHugeRadiusKeepsTheLimitsOfALine) {
  const double r = 999999999.0;
  for (bool ccw : {false, true}) {
    ProgramBuilder b(3, {10.0, 0.0, 0.0});
    b.arc(ccw, {-10.0, 0.0, 0.0}, {0.0, r}, 600.0).end();
    SimulationOptions o;
    o.max_time_s = 3.0;
    double worst = 0.0;
    const auto s = simulate(
        b.program(), o,
        [&](const Registers& reg) {
          // Distance from the circle, relative to the centre: exact enough at this size.
          const double dx = reg.orig_position[0], dy = reg.orig_position[1] - r;
          worst = std::max(worst, std::fabs(std::sqrt(dx * dx + dy * dy) - std::hypot(10.0, r)));
        },
        machine(), {10.0, 0.0, 0.0});
    EXPECT_FALSE(s.nan);
    EXPECT_EQ(s.hard_stops, 0u);
    EXPECT_EQ(s.violation_count, 0u) << (ccw ? "long way" : "short way");
    for (const auto& v : s.violations) {
      ADD_FAILURE() << "cycle " << v.cycle << " axis " << v.axis << " "
                    << limit_quantity_name(v.quantity) << " " << v.value << " > " << v.limit;
      break;
    }
    EXPECT_LT(worst, 1e-6);  // the radius rounds to 1.2e-7 mm at 1e9 mm
    if (!ccw) {
      EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
      EXPECT_EQ(s.end_position[0], -10.0);
      EXPECT_EQ(s.end_position[1], 0.0);
      EXPECT_NEAR(s.distance_mm, 20.0, 1e-9);
    } else {
      EXPECT_NE(s.result, StepResult::kFinished);  // 6.3e9 mm at 10 mm/s
      EXPECT_GT(s.distance_mm, 25.0);
    }
  }
}

// An arc whose end lies 0.2 mm from its start is a 0.2 mm arc at any radius: the planner took
// "end at start" relative to the radius (1e-9 x r0) and made this one, of a radius of 5e8 mm,
// a full circle of 3.1e9 mm. The compiler's rule is an absolute 1e-9 mm.
TEST(KnownValues, ShortArcOfALargeRadiusIsNotAFullCircle) {
  const double r = 5e8;
  ProgramBuilder b(3, {0.1, 0.0, 0.0});
  b.arc(false, {-0.1, 0.0, 0.0}, {0.0, r}, 600.0).end();
  SimulationOptions o;
  o.max_time_s = 10.0;
  const auto s = simulate(b.program(), o, {}, machine(), {0.1, 0.0, 0.0});
  expect_clean(s);
  EXPECT_EQ(s.end_position[0], -0.1);
  EXPECT_NEAR(s.distance_mm, 0.2, 1e-9);
}

// An arc is held to one speed cap from its plane axes' velocity limits: each axis' limit over
// the largest share of the path speed that axis takes on the sweep. From 20 to 40 degrees in
// XY, X (at 5 mm/s here) takes at most sin 40 degrees of it and Y cos 20 degrees, so the cap is
// 5 / sin 40 degrees (with the arc margin kArcSafety, 0.97), not 5 mm/s as if X ran along the
// tangent somewhere on the arc (X then peaked at 3.1 mm/s).
TEST(KnownValues, ArcIsCappedByEachPlaneAxisAtItsLargestShareOnTheSweep) {
  MachineConfig m = machine();
  m.interpolators[0].axes[0].max_velocity_mm_s = 5.0;
  m.interpolators[0].axes[0].rapid_velocity_mm_s = 5.0;
  const double r = 10.0, a0 = 20.0 * kPi / 180.0, a1 = 40.0 * kPi / 180.0;
  const std::array<double, 2> c = {-r * std::cos(a0), -r * std::sin(a0)};
  ProgramBuilder b(3);
  b.arc(true, {c[0] + r * std::cos(a1), c[1] + r * std::sin(a1), 0.0}, c, 6000.0).end();
  double peak = 0.0;
  const auto s = simulate(
      b.program(), {}, [&](const Registers& reg) { peak = std::max(peak, reg.act_speed); }, m);
  expect_clean(s);
  EXPECT_NEAR(peak / 60.0, 0.97 * 5.0 / std::sin(a1), 1e-9);
  EXPECT_GT(s.peaks[0].velocity_mm_s, 0.95 * 5.0);
  EXPECT_LE(s.peaks[0].velocity_mm_s, 5.0);
}

// Where a line runs into an arc tangentially, the axis across the line steps its acceleration
// by v^2 / r at once, and where an arc runs into one of the other turn by 2 v^2 / r: held to
// the corner acceleration tolerance (default sqrt(2 J tol) = sqrt(2 x 30,000 x 2) = 346.4
// mm/s^2 on the default machine), the junction is crossed at 0.999 x sqrt(tol_a r / m) (m = 1
// or 2), and the checker's peak curvature step is within 0.5 % below the tolerance. At F 6000
// into an arc of 10 mm the arc's own cap (0.97 x sqrt(A r / 2) = 84.0 mm/s, a centripetal
// acceleration of 705.7 mm/s^2) is above the junction's 58.8 mm/s; a tolerance of 1e6 leaves
// the junction to that cap, 100 mm/s^2 lowers it, and two arcs of one circle have no step.
TEST(KnownValues, ACurvatureStepAtAJunctionIsHeldToTheCornerAccelerationTolerance) {
  const double r = 10.0, tol_a = std::sqrt(2.0 * 30000.0 * 2.0);
  EXPECT_DOUBLE_EQ(corner_acceleration_tolerance(machine().interpolators[0].axes[1]), tol_a);
  const auto with_tolerance = [](double t) {
    MachineConfig m = machine();
    for (AxisConfig& a : m.interpolators[0].axes) a.corner_acceleration_tolerance_mm_s2 = t;
    return m;
  };
  ProgramBuilder into;  // along X, then a quarter circle turning towards +Y
  into.line({20.0, 0.0, 0.0}, 6000.0).arc(true, {20.0 + r, r, 0.0}, {20.0, r}, 6000.0).end();
  const auto s = simulate(into.program());
  expect_clean(s);
  EXPECT_GE(s.peaks[1].corner_acceleration_mm_s2, 0.995 * tol_a);
  EXPECT_LE(s.peaks[1].corner_acceleration_mm_s2, tol_a);
  const auto off = simulate(into.program(), {}, {}, with_tolerance(1e6));
  expect_clean(off);
  const double cap = 0.97 * std::sqrt(0.5 * 1500.0 * r);
  EXPECT_NEAR(off.peaks[1].corner_acceleration_mm_s2, cap * cap / r, 0.01 * cap * cap / r);
  EXPECT_LT(off.program_time_s, s.program_time_s);
  const auto tight = simulate(into.program(), {}, {}, with_tolerance(100.0));
  expect_clean(tight);
  EXPECT_GE(tight.peaks[1].corner_acceleration_mm_s2, 0.995 * 100.0);
  EXPECT_LE(tight.peaks[1].corner_acceleration_mm_s2, 100.0);
  EXPECT_GT(tight.program_time_s, s.program_time_s);

  // On into an arc of the other turn: X's acceleration steps from -v^2 / r to +v^2 / r.
  ProgramBuilder flip;
  flip.line({20.0, 0.0, 0.0}, 6000.0)
      .arc(true, {20.0 + r, r, 0.0}, {20.0, r}, 6000.0)
      .arc(false, {20.0 + 2.0 * r, 2.0 * r, 0.0}, {20.0 + 2.0 * r, r}, 6000.0)
      .end();
  const auto sf = simulate(flip.program());
  expect_clean(sf);
  EXPECT_GE(sf.peaks[0].corner_acceleration_mm_s2, 0.995 * tol_a);
  EXPECT_LE(sf.peaks[0].corner_acceleration_mm_s2, tol_a);

  // Two halves of one circle: no step, and the junction is crossed at the arc's cap.
  ProgramBuilder circle;
  circle.arc(true, {2.0 * r, 0.0, 0.0}, {r, 0.0}, 6000.0)
      .arc(true, {0.0, 0.0, 0.0}, {r, 0.0}, 6000.0)
      .end();
  double at_junction = 0.0;
  std::int32_t part = 0;
  const auto sc = simulate(circle.program(), {}, [&](const Registers& reg) {
    if (reg.act_part == 2 && part == 1) at_junction = reg.act_speed / 60.0;
    part = reg.act_part;
  });
  expect_clean(sc);
  EXPECT_LT(sc.peaks[0].corner_acceleration_mm_s2, 1e-6 * tol_a);
  EXPECT_LT(sc.peaks[1].corner_acceleration_mm_s2, 1e-6 * tol_a);
  EXPECT_NEAR(at_junction, cap, 1e-6 * cap);
}

TEST(KnownValues, HelixPitch) {
  // Two full turns (turns = 1) of radius 5 rising 6 mm: pitch 3 mm per turn.
  ProgramBuilder b(3, {5.0, 0.0, 0.0});
  b.arc(true, {5.0, 0.0, 6.0}, {0.0, 0.0}, 2000.0, Plane::kXY, 1).end();
  double prev = 0.0, unwrapped = 0.0, worst = 0.0;
  auto sim = Simulation::create(machine(), {});
  ASSERT_TRUE(sim);
  sim->interpolator().set_position({5.0, 0.0, 0.0});
  const auto s = sim->run(b.program(), [&](const Registers& r) {
    const double ang = std::atan2(r.orig_position[1], r.orig_position[0]);
    double d = ang - prev;
    if (d < -kPi) d += 2 * kPi;
    if (d > kPi) d -= 2 * kPi;
    unwrapped += d;
    prev = ang;
    worst = std::max(worst, std::fabs(r.orig_position[2] - 3.0 * unwrapped / (2 * kPi)));
  });
  EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
  EXPECT_NEAR(unwrapped, 4 * kPi, 1e-9);
  EXPECT_LT(worst, 1e-9);
  EXPECT_NEAR(s.end_position[2], 6.0, 1e-12);
  EXPECT_NEAR(s.end_position[0], 5.0, 1e-9);
}

// One M-function as it reached M_Func: its m_func_count, number, cycle and axis 0's position.
struct HandedOver {
  std::uint32_t count;
  int m;
  std::uint64_t cycle;
  double x;
};

// Steps `ip` to the end of its program (at most 40,000 cycles), calling `each(registers)` after
// every cycle, and returns every change of m_func_count.
template <class Each>
std::vector<HandedOver> hand_overs(Interpolator& ip, Each each) {
  std::vector<HandedOver> seen;
  std::uint32_t last = 0;
  for (int c = 0; c < 40000; ++c) {
    const StepResult r = ip.step();
    const Registers& g = ip.registers();
    if (g.m_func_count != last) {
      last = g.m_func_count;
      seen.push_back({g.m_func_count, g.m_func, g.cycle, g.orig_position[0]});
    }
    each(g);
    if (r == StepResult::kFinished) break;
  }
  return seen;
}

// M records with nothing between them reach M_Func one per cycle, in program order, so a PLC
// that reads the registers once a cycle sees each (they used to leave the smoothing in the same
// calculation step, the later overwriting the earlier). The motion does not wait for the
// continuous ones.
TEST(KnownValues, AdjacentMFunctionsReachMFuncOnePerCycle) {
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 3000.0)
      .m(1001, MKind::kContinuous)
      .m(1002, MKind::kContinuous)
      .line({20.0, 0.0, 0.0}, 3000.0)
      .m(1003, MKind::kContinuous)
      .m(50, MKind::kNormal)
      .line({30.0, 0.0, 0.0}, 3000.0)
      .end();
  auto ip = Interpolator::create(machine(), 0);
  ASSERT_TRUE(ip);
  ASSERT_TRUE(ip->load(b.program()).ok());
  ASSERT_TRUE(ip->start().ok());
  const std::vector<HandedOver> seen = hand_overs(*ip, [&](const Registers& g) {
    if (g.m_func != 0) {
      EXPECT_EQ(g.act_m_func, g.m_func);
      if (g.m_func > 1000) {
        EXPECT_EQ(g.last_cont_m_func, g.m_func);
      }
    }
    if (g.m_func == 50 && run_flag_section(g.run_flag) == SectionState::kWaitMFuncEnd) {
      ASSERT_TRUE(ip->write_m_func(0, 50).ok());
    }
  });
  std::vector<int> shown;
  for (const HandedOver& h : seen) shown.push_back(h.m);
  ASSERT_EQ(shown, (std::vector<int>{1001, 1002, 1003, 50}));
  EXPECT_EQ(seen[1].cycle, seen[0].cycle + 1);  // the next cycle
  EXPECT_EQ(seen[3].cycle, seen[2].cycle + 1);
  EXPECT_GT(seen[1].x, seen[0].x) << "the motion went on past the continuous M-functions";
  EXPECT_EQ(seen[3].x, 20.0);  // M50 stops the motion at its record
  EXPECT_EQ(ip->registers().status, 3);
  EXPECT_EQ(ip->registers().orig_position[0], 30.0);
}

// Two equal continuous M-functions in a row leave M_Func unchanged from one cycle to the next:
// the count of M-functions handed over (the register the PLC deduplicates by) tells them apart,
// one per cycle, and the normal one after them is counted once although it shows for many cycles.
// An acknowledgement that names an M-function by its count is refused once a later one was
// handed over, also with the same number, and once it was acknowledged already.
TEST(KnownValues, EqualAdjacentMFunctionsAreCountedApart) {
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 3000.0)
      .m(1001, MKind::kContinuous)
      .m(1001, MKind::kContinuous)
      .line({20.0, 0.0, 0.0}, 3000.0)
      .m(50, MKind::kNormal)
      .line({30.0, 0.0, 0.0}, 3000.0)
      .end();
  auto ip = Interpolator::create(machine(), 0);
  ASSERT_TRUE(ip);
  ASSERT_TRUE(ip->load(b.program()).ok());
  ASSERT_EQ(ip->registers().m_func_count, 0u);
  ASSERT_TRUE(ip->start().ok());
  const std::vector<HandedOver> seen = hand_overs(*ip, [&](const Registers& g) {
    if (g.m_func == 50 && run_flag_section(g.run_flag) == SectionState::kWaitMFuncEnd) {
      const RequestResult stale = ip->write_m_func(0, 50, 2);
      EXPECT_EQ(stale.code, RequestCode::kWrongState);
      EXPECT_EQ(stale.reason,
                "M-function #3 was handed over since: the acknowledgement of #2 came after it");
      EXPECT_EQ(ip->registers().m_func, 50);
      ASSERT_TRUE(ip->write_m_func(0, 50, 3).ok());
      EXPECT_EQ(ip->registers().m_func, 0);
      // The same acknowledgement again (a second PLC, or a repeat whose first copy arrived)
      // is refused; it used to be accepted, telling both writers they had released M50.
      const RequestResult again = ip->write_m_func(0, 50, 3);
      EXPECT_EQ(again.code, RequestCode::kWrongState);
      EXPECT_EQ(again.reason,
                "M-function #3 was acknowledged already (by another acknowledgement: a second "
                "PLC, or a repeat whose first copy arrived)");
      EXPECT_TRUE(ip->write_m_func(0).ok());  // one that names none clears whatever shows
      // A count not handed over yet (it was said to have "come after" #3).
      EXPECT_EQ(ip->write_m_func(0, 0, 99).reason,
                "M-function #99 was never handed over (the last is #3)");
    }
  });
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[0].count, 1u);
  EXPECT_EQ(seen[0].m, 1001);
  EXPECT_EQ(seen[1].count, 2u);
  EXPECT_EQ(seen[1].m, 1001);
  EXPECT_EQ(seen[1].cycle, seen[0].cycle + 1);  // the next cycle, M_Func unchanged
  EXPECT_EQ(seen[2].count, 3u);
  EXPECT_EQ(seen[2].m, 50);
  EXPECT_EQ(ip->registers().status, 3);
  EXPECT_EQ(ip->registers().m_func_count, 3u);
}

// Forty continuous M-functions in a row (setting outputs, say) reach M_Func one per cycle, in
// order, each counted; the motion goes on meanwhile.
// Runs a line, `count` continuous M-functions M1001, M1002, ... and a line on; the hand-overs
// and the registers at the end.
std::pair<std::vector<HandedOver>, Registers> continuous_in_a_row(int count) {
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 3000.0);
  for (int k = 0; k < count; ++k) b.m(1001 + k, MKind::kContinuous);
  b.line({20.0, 0.0, 0.0}, 3000.0).end();
  auto ip = Interpolator::create(machine(), 0);
  EXPECT_TRUE(ip);
  if (!ip || !ip->load(b.program()).ok() || !ip->start().ok()) return {};
  std::vector<HandedOver> seen = hand_overs(*ip, [](const Registers&) {});
  return {std::move(seen), ip->registers()};
}

TEST(KnownValues, FortyMFunctionsInARowReachMFuncOnePerCycle) {
  const auto [seen, end] = continuous_in_a_row(40);
  ASSERT_EQ(seen.size(), 40u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].count, k + 1);  // one at a time
    EXPECT_EQ(seen[k].m, 1001 + static_cast<int>(k));
    if (k > 0) {
      EXPECT_EQ(seen[k].cycle, seen[k - 1].cycle + 1);
    }
  }
  EXPECT_EQ(end.status, 3);
  EXPECT_EQ(end.orig_position[0], 20.0);
}

// A hundred in a row: 64 wait, and beyond that the oldest waiting ones reach M_Func in the same
// cycle. A PLC reading once a cycle misses some, but every one it sees comes in program order
// with its own count (the k-th handed over is M1000+k). The newest used to be handed over at
// once: M1100 reached M_Func before M1002.
TEST(KnownValues, MoreMFunctionsInARowThanWaitKeepTheirOrder) {
  const auto [seen, end] = continuous_in_a_row(100);
  ASSERT_GE(seen.size(), 65u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].m, 1000 + static_cast<int>(seen[k].count)) << k;
    if (k > 0) {
      EXPECT_GT(seen[k].count, seen[k - 1].count) << k;
    }
  }
  EXPECT_EQ(seen.back().m, 1100);
  EXPECT_EQ(seen.back().count, 100u);
  // The last 64 one per cycle.
  for (std::size_t k = seen.size() - 64; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].count, seen[k - 1].count + 1) << k;
    EXPECT_EQ(seen[k].cycle, seen[k - 1].cycle + 1) << k;
  }
  EXPECT_EQ(end.status, 3);
  EXPECT_EQ(end.last_cont_m_func, 1100);
}

// A PLC's note of a continuous M-function (M_Func = 0) that arrives after the next, normal
// M-function is shown must not acknowledge that one: the write names the M-function it means.
TEST(KnownValues, LateNoteOfAContinuousMFunctionDoesNotReleaseTheNextOne) {
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 3000.0)
      .m(1001, MKind::kContinuous)
      .line({10.5, 0.0, 0.0}, 3000.0)
      .m(50, MKind::kNormal)
      .line({20.0, 0.0, 0.0}, 3000.0)
      .end();
  auto ip = Interpolator::create(machine(), 0);
  ASSERT_TRUE(ip);
  ASSERT_TRUE(ip->load(b.program()).ok());
  ASSERT_TRUE(ip->start().ok());
  bool saw_continuous = false;
  int waited = 0;
  for (int c = 0; c < 40000; ++c) {
    const StepResult r = ip->step();
    const Registers& g = ip->registers();
    if (g.m_func == 1001) saw_continuous = true;  // not noted: still shown when M50 comes
    if (g.m_func == 50 && run_flag_section(g.run_flag) == SectionState::kWaitMFuncEnd) {
      ++waited;
      if (waited == 5) {
        const RequestResult late = ip->write_m_func(0, 1001);
        EXPECT_EQ(late.code, RequestCode::kWrongState) << late.reason;
        EXPECT_EQ(late.reason, "M_Func shows M50 now: the acknowledgement of M1001 came after it");
        EXPECT_EQ(ip->registers().m_func, 50);
      }
      if (waited == 50) {
        EXPECT_EQ(g.orig_position[0], 10.5);  // still waiting at the M50 stop
        ASSERT_TRUE(ip->write_m_func(0, 50).ok());
        EXPECT_EQ(ip->registers().m_func, 0);
        // Naming an M-function when M_Func is 0 already changes nothing and is no error.
        EXPECT_TRUE(ip->write_m_func(0, 50).ok());
      }
    }
    if (r == StepResult::kFinished) break;
  }
  EXPECT_TRUE(saw_continuous);
  EXPECT_EQ(waited, 50);  // released by the M50 write, not by the late one
  EXPECT_EQ(ip->registers().status, 3);
  EXPECT_EQ(ip->registers().orig_position[0], 20.0);
}

TEST(KnownValues, MFunctionHandshakeSequence) {
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 3000.0).m(10, MKind::kNormal).line({20.0, 0.0, 0.0}, 3000.0).end();
  auto ip = Interpolator::create(machine(), 0);
  ASSERT_TRUE(ip);
  ASSERT_TRUE(ip->load(b.program()).ok());
  EXPECT_EQ(ip->registers().status, 4);
  ASSERT_TRUE(ip->start().ok());
  // (status, section state, speed state, m_func) whenever it changes.
  std::vector<std::array<int, 4>> seq;
  int waiting = 0;
  for (int c = 0; c < 20000; ++c) {
    const StepResult r = ip->step();
    const Registers& g = ip->registers();
    const std::array<int, 4> now = {g.status, static_cast<int>(run_flag_section(g.run_flag)),
                                    static_cast<int>(run_flag_speed(g.run_flag)), g.m_func};
    if (seq.empty() || seq.back() != now) seq.push_back(now);
    if (run_flag_section(g.run_flag) == SectionState::kWaitMFuncEnd && ++waiting == 10) {
      EXPECT_EQ(g.m_func, 10);
      EXPECT_EQ(g.act_m_func, 10);
      EXPECT_EQ(g.orig_position[0], 10.0);
      EXPECT_FALSE(ip->write_m_func(5).ok());
      ASSERT_TRUE(ip->write_m_func(0).ok());
    }
    if (r == StepResult::kFinished) break;
  }
  const std::vector<std::array<int, 4>> expect = {
      {1, 1, 2, 0},   // run, accelerating
      {1, 1, 3, 0},   // run, at feed
      {1, 1, 4, 0},   // decelerating ... (to the stop: 6)
  };
  ASSERT_GE(seq.size(), 8u);
  EXPECT_EQ(seq[0], expect[0]);
  EXPECT_EQ(seq[1], expect[1]);
  // Deceleration to the M stop is "decelerating on last section" (6).
  EXPECT_EQ(seq[2], (std::array<int, 4>{1, 1, 6, 0}));
  EXPECT_EQ(seq[3], (std::array<int, 4>{1, 4, 1, 10}));  // M handed over
  EXPECT_EQ(seq[4], (std::array<int, 4>{1, 5, 1, 10}));  // waiting for M_Func = 0
  EXPECT_EQ(seq[5], (std::array<int, 4>{1, 1, 2, 0}));   // acknowledged: moving again
  EXPECT_EQ(seq.back(), (std::array<int, 4>{3, 0, 1, 0}));  // end of program
  EXPECT_EQ(ip->registers().orig_position[0], 20.0);
}

}  // namespace
}  // namespace tgm
