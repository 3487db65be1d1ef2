// Issue 4 end to end through tgm::Interpolator: spline delay and M-functions leaving the spline
// with the motion, jerk reduction at velocity jumps with the contour deviation reported, the IIR
// filter on masked axes only with M-functions at the interpolator's standstill, Commands with
// valid and invalid parameters and the Command_Status sequence, Ratio / Offset / backlash in
// PositionInc, Number_Axes, and the LookAheadBuffer at chosen points of a program.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "program_builder.hpp"
#include "tgm/command_stage.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/output_stage.hpp"
#include "tgm/simulation.hpp"
#include "tgm/smoothing.hpp"

namespace tgm {
namespace {

using test::ProgramBuilder;
using Params = std::array<std::int32_t, kCommandParameters>;
constexpr double kPi = 3.14159265358979323846;

Interpolator make(const MachineConfig& m) {
  auto ip = Interpolator::create(m, 0);
  EXPECT_TRUE(ip.has_value());
  return std::move(*ip);
}

// Runs a loaded and started interpolator to Status 3, acknowledging every normal M-function
// `ack_cycles` cycles after it was handed over; returns the registers of every cycle.
std::vector<Registers> run(Interpolator& ip, int ack_cycles = 20, int max_cycles = 400000) {
  std::vector<Registers> out;
  int ack_at = -1;
  for (int c = 0; c < max_cycles; ++c) {
    const StepResult r = ip.step();
    const Registers& g = ip.registers();
    out.push_back(g);
    if (r == StepResult::kFinished || r == StepResult::kErrorInternal || r == StepResult::kIdle) break;
    const SectionState sec = run_flag_section(g.run_flag);
    if (sec == SectionState::kWaitMFunc) ack_at = c + ack_cycles;
    if (g.m_func != 0 && g.last_cont_m_func == g.m_func && sec != SectionState::kWaitMFunc &&
        sec != SectionState::kWaitMFuncEnd) {
      ip.write_m_func(0);
    }
    if (ack_at >= 0 && c >= ack_at) {
      ip.write_m_func(0);
      ack_at = -1;
    }
  }
  return out;
}

int first_cycle(const std::vector<Registers>& rs, bool (*pred)(const Registers&)) {
  for (std::size_t i = 0; i < rs.size(); ++i) {
    if (pred(rs[i])) return static_cast<int>(i);
  }
  return -1;
}

Params spline(int points, int jerk) {
  Params p{};
  p[0] = points;
  p[1] = jerk;
  return p;
}

// Command -1's parameters: p, q (x 1e6), f (ms x 1e6), axis mask.
Params iir_params(std::int32_t p_e6, std::int32_t q_e6, std::int32_t f_e6, std::int32_t mask) {
  Params p{};
  p[0] = p_e6;
  p[1] = q_e6;
  p[2] = f_e6;
  p[3] = mask;
  return p;
}

// ---------------- Spline ----------------

// Run_Flag's speed half describes the axes, after the smoothing: while any axis still moves
// (Speed after spline / IIR), it is not "no motion", and while Status is 1 the section is not
// STOP. Before, the half followed the path generator alone: with the spline on, "no motion"
// (and at the program's end STOP) showed for 40 cycles while X still moved at up to 5 mm/s
// into an M-function stop and into the end point, and a PLC that takes "no motion" as "the
// axes stand" acted up to 20 ms early.
TEST(Wiring, RunFlagSaysNoMotionOnlyOnceTheSmoothedAxesStand) {
  MachineConfig m = MachineConfig::default_machine();
  ProgramBuilder b;
  b.line({20.0, 0.0, 0.0}, 3000.0).m(50, MKind::kNormal).line({40.0, 5.0, 0.0}, 3000.0).end();
  struct Case {
    const char* name;
    std::int32_t code;
    Params p;
  };
  const Case cases[] = {{"spline", kCommandSpline, spline(200, 1'000'000)},
                        {"iir", kCommandIir, iir_params(2'000'000, 1'000'000, 6'000'000, 0b011)}};
  for (const Case& k : cases) {
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(k.code, k.p).ok()) << k.name;
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const auto rs = run(ip);
    ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << k.name;
    int moving_cycles_after_the_generator = 0;
    for (std::size_t c = 0; c < rs.size(); ++c) {
      const Registers& g = rs[c];
      // At Status 3 the axes stand exactly at the end (the IIR's last step snaps onto it).
      bool moves = false;
      const bool ended = g.status == static_cast<std::int32_t>(InterpolatorStatus::kEnded);
      for (int i = 0; i < 3 && !ended; ++i)
        moves = moves || g.speed[static_cast<std::size_t>(i)] != 0.0;
      const SpeedState v = run_flag_speed(g.run_flag);
      if (moves) {
        EXPECT_NE(v, SpeedState::kNoMotion) << k.name << " cycle " << c;
        if (g.act_speed == 0.0) {
          ++moving_cycles_after_the_generator;
          EXPECT_EQ(v, SpeedState::kDeceleratingLast) << k.name << " cycle " << c;
        }
      }
      if (g.status == static_cast<std::int32_t>(InterpolatorStatus::kRunning)) {
        EXPECT_NE(run_flag_section(g.run_flag), SectionState::kStop) << k.name << " cycle " << c;
      }
    }
    // The case the rule is for happens: the axes move on after the generator stands.
    EXPECT_GT(moving_cycles_after_the_generator, 10) << k.name;
    EXPECT_EQ(rs.back().run_flag, make_run_flag(SectionState::kStop, SpeedState::kNoMotion))
        << k.name;
  }
}

// The Status a motion comes to waits for the smoothed axes, as Status 3 always did: 4 after
// Command 8 and at M0, 7 after an emergency stop (6 until then), 8 at an underrun. With the
// spline on they showed up to 50 ms early, while X still moved at the full 50 mm/s: a PLC that
// drops the drive enable at Status 7 or opens a guard at M0 did it mid-motion.
TEST(Wiring, StopStatusesWaitUntilTheSmoothedAxesStand) {
  MachineConfig m = MachineConfig::default_machine();
  struct Case {
    const char* name;
    int stop_cycle;  // 0: none
    std::int32_t code;
    bool m0;
    bool underrun;
    InterpolatorStatus expect;
  };
  const Case cases[] = {
      {"command 8", 300, 8, false, false, InterpolatorStatus::kReady},
      {"command 4", 300, 4, false, false, InterpolatorStatus::kEmergencyStopped},
      {"M0", 0, 0, true, false, InterpolatorStatus::kReady},
      {"underrun", 0, 0, false, true, InterpolatorStatus::kUnderrun},
  };
  for (const Case& k : cases) {
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(kCommandSpline, spline(500, 1'000'000)).ok());
    ProgramBuilder b;
    b.line({20.0, 0.0, 0.0}, 3000.0);
    if (k.m0) b.m(0, MKind::kProgramStop);
    b.line({40.0, 0.0, 0.0}, 3000.0);
    if (!k.underrun) b.end();
    const Program p = b.program();
    if (k.underrun) {
      ASSERT_TRUE(ip.append(p, 0, p.segments.size(), false).ok());
    } else {
      ASSERT_TRUE(ip.load(p).ok());
    }
    ASSERT_TRUE(ip.start().ok());
    const Registers& r = ip.registers();
    int generator_stood = -1, status_at = -1, moving_while_6 = 0, last_move = -1;
    for (int c = 0; c < 20000 && status_at < 0; ++c) {
      const auto before = r.position;
      ip.step();
      if (r.position != before) last_move = c;
      if (c == k.stop_cycle && k.code != 0) {
        ASSERT_TRUE(ip.command(k.code).ok());
      }
      bool moves = false;
      for (int i = 0; i < 3; ++i) moves = moves || r.speed[static_cast<std::size_t>(i)] != 0.0;
      if (c > 10 && r.act_speed == 0.0 && generator_stood < 0) generator_stood = c;
      if (r.status == static_cast<std::int32_t>(k.expect)) {
        status_at = c;
        EXPECT_EQ(r.position, r.orig_position) << k.name << " cycle " << c;
        EXPECT_EQ(run_flag_speed(r.run_flag), SpeedState::kNoMotion) << k.name;
      } else if (generator_stood >= 0) {
        // Until then Status still shows the motion.
        const auto shown =
            k.code == 4 ? InterpolatorStatus::kEmergencyRamp : InterpolatorStatus::kRunning;
        EXPECT_EQ(r.status, static_cast<std::int32_t>(shown)) << k.name << " cycle " << c;
        if (k.code == 4 && moves) {
          ++moving_while_6;
          EXPECT_EQ(run_flag_speed(r.run_flag), SpeedState::kEmergencyRamp)
              << k.name << " cycle " << c;
        }
      }
    }
    ASSERT_GE(generator_stood, 0) << k.name;
    ASSERT_GE(status_at, 0) << k.name;
    // The spline's 500 steps (100 cycles) lie between the generator's stop and the Status.
    EXPECT_GE(status_at - generator_stood, 50) << k.name;
    // And the Status comes as soon as the axes stand, not a second spline length later (it
    // waited 2N + 4 steps after the generator stood, 100 ms here, until session 76).
    EXPECT_LE(status_at - last_move, 1) << k.name;
    if (k.code == 4) {
      EXPECT_GT(moving_while_6, 10);
    }
    if (k.m0 || k.code == 8) {
      ASSERT_TRUE(ip.start().ok()) << k.name;  // and the program goes on to its end
      for (int c = 0; c < 20000 && ip.step() != StepResult::kFinished; ++c) {
      }
      EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << k.name;
      EXPECT_EQ(r.position[0], 40.0) << k.name;
    }
  }
}

// A start given while the axes still brake after an emergency stop is refused with the
// reason; a start while they settle into a normal stop resumes the program at once.
TEST(Wiring, AStartWhileTheAxesSettleIntoAStop) {
  MachineConfig m = MachineConfig::default_machine();
  for (const std::int32_t code : {4, 8}) {
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(kCommandSpline, spline(500, 1'000'000)).ok());
    ProgramBuilder b;
    b.line({40.0, 0.0, 0.0}, 3000.0).end();
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const Registers& r = ip.registers();
    for (int c = 0; c < 300; ++c) ip.step();
    ASSERT_TRUE(ip.command(code).ok());
    for (int c = 0; c < 2000 && r.act_speed != 0.0; ++c) ip.step();
    ASSERT_EQ(r.act_speed, 0.0);
    ASSERT_NE(r.position, r.orig_position);  // the spline still moves the axes
    const RequestResult s = ip.start();
    if (code == 4) {
      EXPECT_EQ(s.code, RequestCode::kWrongState);
      EXPECT_NE(s.reason.find("still braking after the emergency stop"), std::string::npos)
          << s.reason;
      for (int c = 0; c < 2000 && r.status != 7; ++c) ip.step();
      EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped));
      EXPECT_TRUE(ip.start().ok());
    } else {
      EXPECT_TRUE(s.ok()) << s.reason;
      EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kRunning));
    }
    for (int c = 0; c < 20000 && ip.step() != StepResult::kFinished; ++c) {
    }
    EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << code;
    EXPECT_EQ(r.position[0], 40.0) << code;
  }
}

// A stop given while a normal M-function is still inside the spline (the path stands at it,
// the axes not yet): Command 9 / 5 drop the program, and its M-function never reaches M_Func
// (it did, 40 ms after the drop, and a PLC took it for a continuous one); Command 8 hands it
// over when the axes arrive, with Run_Flag WAIT_MFUNC, and the start waits for it.
TEST(Wiring, AStopWhileANormalMIsInsideTheSpline) {
  MachineConfig m = MachineConfig::default_machine();
  for (const std::int32_t code : {9, 5, 8}) {
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(kCommandSpline, spline(500, 1'000'000)).ok());
    ProgramBuilder b;
    b.line({20.0, 0.0, 0.0}, 3000.0).m(51, MKind::kNormal).line({40.0, 0.0, 0.0}, 3000.0).end();
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const Registers& r = ip.registers();
    int c = 0;
    for (; c < 20000 && !(c > 10 && r.act_speed == 0.0); ++c) ip.step();
    ASSERT_EQ(r.m_func, 0);  // the M-function is inside the spline
    ASSERT_TRUE(ip.command(code).ok());
    bool handed = false, said_wait = false;
    for (int k = 0; k < 400; ++k) {
      ip.step();
      if (r.m_func == 51 && !handed) {
        handed = true;
        said_wait = run_flag_section(r.run_flag) == SectionState::kWaitMFunc;
      }
    }
    if (code == 8) {
      EXPECT_TRUE(handed);
      EXPECT_TRUE(said_wait);
      EXPECT_EQ(run_flag_section(r.run_flag), SectionState::kWaitMFuncEnd);
      EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
      ASSERT_TRUE(ip.start().ok());
      for (int k = 0; k < 100; ++k) ip.step();
      EXPECT_EQ(r.orig_position[0], 20.0);  // waits for the acknowledgement
      ASSERT_TRUE(ip.write_m_func(0).ok());
      for (int k = 0; k < 20000 && ip.step() != StepResult::kFinished; ++k) {
      }
      EXPECT_EQ(r.position[0], 40.0);
    } else {
      EXPECT_FALSE(handed) << code;
      EXPECT_EQ(r.m_func, 0) << code;
      EXPECT_EQ(r.m_func_count, 0u) << code;
    }
  }
}

// An M-function the PLC never acknowledged goes with its program: a Command 9 drops it, and
// a clear after a Command 8 does too. M_Func 51 stayed through a clear and two later programs,
// and a PLC started later executed it for a program cleared long before.
TEST(Wiring, AnUnacknowledgedMGoesWithItsProgram) {
  MachineConfig m = MachineConfig::default_machine();
  for (const bool clear : {false, true}) {
    Interpolator ip = make(m);
    ProgramBuilder b;
    b.line({5.0, 0.0, 0.0}, 3000.0).m(51, MKind::kNormal).line({9.0, 0.0, 0.0}, 3000.0).end();
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const Registers& r = ip.registers();
    for (int c = 0; c < 20000 && r.m_func == 0; ++c) ip.step();
    ASSERT_EQ(r.m_func, 51);
    const std::uint32_t handed = r.m_func_count;
    ASSERT_TRUE(ip.command(clear ? 8 : 9).ok());
    if (clear) {
      EXPECT_EQ(r.m_func, 51);  // stopped, the M-function still waits for its acknowledgement
      ASSERT_TRUE(ip.clear().ok());
    }
    EXPECT_EQ(r.m_func, 0) << clear;
    EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEmpty));
    // The PLC's acknowledgement that comes after is told why it is refused (it was "acknowledged
    // already: a second PLC, or a repeat").
    const RequestResult late = ip.write_m_func(0, 51, handed);
    EXPECT_EQ(late.code, RequestCode::kWrongState);
    EXPECT_EQ(late.reason, "M-function #" + std::to_string(handed) +
                               " (M51) went with its program (an off-trajectory stop, Command 9 / "
                               "5, a clear or the next program's load): there is nothing to "
                               "acknowledge");
    // The next program runs to its end without it.
    ProgramBuilder home;
    home.line({0.0, 0.0, 0.0}, 6000.0).end();
    ASSERT_TRUE(ip.load(home.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    for (int c = 0; c < 20000 && ip.step() != StepResult::kFinished; ++c) {
    }
    EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
    EXPECT_EQ(r.m_func, 0);
    // A late acknowledgement of it is still taken without an error (a PLC repeating one).
    EXPECT_TRUE(ip.write_m_func(0).ok());
  }
}

// A braking to a stop lands its deceleration with a slight overshoot: in its last cycle the
// acceleration ends just above zero while the speed still falls. Run_Flag said ACCELERATING
// for that one cycle (a line of 20 mm at F3000 into an M-function, spline off); the speed half
// says accelerating only in cycles where Act_Speed did not fall.
TEST(Wiring, RunFlagNeverSaysAcceleratingWhileTheSpeedFalls) {
  MachineConfig m = MachineConfig::default_machine();
  int landings = 0;
  for (const double x : {20.0, 7.5, 1.0, 33.3}) {
    for (const double f : {3000.0, 600.0, 6000.0}) {
      ProgramBuilder b;
      b.line({x, 0.0, 0.0}, f).m(50, MKind::kNormal).line({x, x, 0.0}, f).end();
      Interpolator ip = make(m);
      ASSERT_TRUE(ip.load(b.program()).ok());
      ASSERT_TRUE(ip.start().ok());
      const auto rs = run(ip);
      ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
      for (std::size_t c = 1; c < rs.size(); ++c) {
        const bool falls = rs[c].act_speed < rs[c - 1].act_speed;
        if (falls && rs[c].act_speed < 1.0 && rs[c].act_speed > 0.0) ++landings;
        if (falls) {
          EXPECT_NE(run_flag_speed(rs[c].run_flag), SpeedState::kAccelerating)
              << "X" << x << " F" << f << " cycle " << c << ": " << rs[c - 1].act_speed << " -> "
              << rs[c].act_speed << " mm/min";
        }
      }
    }
  }
  EXPECT_GT(landings, 0);
}

// Smooth motion (jerk far below the limit): Position is Orig_Position exactly N calculation
// steps (N / 5 cycles) earlier, bit for bit; M_Func is raised exactly N steps later than
// without the spline, and the run ends (Status 3) only when Position stands at the end.
TEST(Wiring, SplineDelaysPositionAndMFunctionsByExactlyNSteps) {
  MachineConfig m = MachineConfig::default_machine();
  ProgramBuilder b;
  b.line({10.0, 5.0, 0.0}, 3000.0).m(8, MKind::kNormal).line({20.0, 0.0, 1.0}, 6000.0).end();
  int m_cycle[2] = {-1, -1};
  std::size_t cycles[2] = {0, 0};
  for (int points : {0, 200, 50}) {
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(kCommandSpline, spline(points, 1'000'000)).ok());
    ASSERT_EQ(ip.smoothing().spline().delay_steps(), points);
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const auto rs = run(ip);
    ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << points;
    const int d = points / 5;  // cycles
    // Exact delay, every axis, every cycle.
    for (std::size_t c = static_cast<std::size_t>(d); c < rs.size(); ++c) {
      ASSERT_EQ(rs[c].position, rs[c - static_cast<std::size_t>(d)].orig_position) << points << " cycle " << c;
    }
    EXPECT_EQ(rs.back().position, rs.back().orig_position);
    EXPECT_EQ(rs.back().spline_deviation_mm, 0.0);  // no jerk excess: the spline only delays
    const int mc = first_cycle(rs, [](const Registers& r) { return r.m_func == 8; });
    ASSERT_GE(mc, 0);
    // Handed over in the cycle Position arrives where the path stopped for it.
    EXPECT_EQ(run_flag_section(rs[static_cast<std::size_t>(mc)].run_flag), SectionState::kWaitMFunc);
    EXPECT_NEAR(rs[static_cast<std::size_t>(mc)].position[0], 10.0, 1e-12);
    if (points == 0) {
      m_cycle[0] = mc;
      cycles[0] = rs.size();
    } else if (points == 200) {
      m_cycle[1] = mc;
      cycles[1] = rs.size();
      // Before the hand-over the section still runs (M inside the spline), M_Func still 0.
      EXPECT_EQ(rs[static_cast<std::size_t>(mc - 1)].m_func, 0);
      EXPECT_EQ(run_flag_section(rs[static_cast<std::size_t>(mc - 1)].run_flag), SectionState::kRun);
    }
  }
  EXPECT_EQ(m_cycle[1], m_cycle[0] + 40);  // 200 points = 20 ms = 40 cycles at 500 us
  // The whole run is longer by the delay twice (before the M and at the end) plus the drain
  // the settled test waits for (N + 4 steps after Position stands, rounded up to cycles).
  EXPECT_GE(cycles[1], cycles[0] + 80);
  EXPECT_LE(cycles[1], cycles[0] + 80 + 42);
}

// Continuous M-functions one after another inside the spline's delay (a laser's power after
// every chord): they reach Last_Cont_M_Func in program order, none before the motion sample
// it belongs to while they fit the event queue, and in order still when more than it holds
// arrive at once (then some early, counted). Past 256 each new one used to be handed over at
// once, ahead of those queued: M1257 before M1256, and the run ended on Last_Cont_M_Func 1256
// where the program's last was M1300 (session 75).
TEST(Wiring, ContinuousMFunctionsLeaveTheSplineInProgramOrder) {
  MachineConfig m = MachineConfig::default_machine();
  for (const int count : {300, 3000, static_cast<int>(SmoothingStage::kEventCapacity) + 900}) {
    ProgramBuilder b;
    b.line({10.0, 0.0, 0.0}, 6000.0);
    for (int k = 1; k <= count; ++k) b.m(1000 + k, MKind::kContinuous);
    b.line({20.0, 0.0, 0.0}, 6000.0).end();
    Interpolator ip = make(m);
    ASSERT_TRUE(ip.command(kCommandSpline, spline(500, 1'000'000)).ok());
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const auto rs = run(ip);
    ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << count;
    std::int32_t last = 0;
    std::uint64_t before_sample = 0;
    for (const Registers& r : rs) {
      ASSERT_GE(r.last_cont_m_func, last) << count << ": out of program order";
      if (r.last_cont_m_func != 0 && r.position[0] < 10.0 - 1e-9) ++before_sample;
      last = r.last_cont_m_func;
    }
    EXPECT_EQ(last, 1000 + count) << count;
    EXPECT_EQ(rs.back().m_func_count, static_cast<std::uint32_t>(count)) << count;
    if (count <= static_cast<int>(SmoothingStage::kEventCapacity)) {
      EXPECT_EQ(before_sample, 0u) << count;
      EXPECT_EQ(ip.early_smoothing_events(), 0u) << count;
    } else {
      EXPECT_GT(before_sample, 0u);
      EXPECT_EQ(ip.early_smoothing_events(),
                static_cast<std::uint64_t>(count) - SmoothingStage::kEventCapacity);
    }
  }
}

// A square run without corner slow-down (tolerance above the feed): velocity jumps of 100 mm/s
// per axis at every corner. After the spline (N = 200) the per-axis jerk is below the raw one
// by the factor the kernel allows, the contour deviation is reported, and the end is exact.
TEST(Wiring, SplineSmoothsVelocityJumpsOfASquare) {
  MachineConfig m = MachineConfig::default_machine();
  for (auto& a : m.interpolators[0].axes) a.corner_velocity_tolerance_mm_s = 1000.0;
  ProgramBuilder b;
  b.line({20.0, 0.0, 0.0}, 6000.0).line({20.0, 20.0, 0.0}, 6000.0).line({0.0, 20.0, 0.0}, 6000.0)
      .line({0.0, 0.0, 0.0}, 6000.0).end();
  Interpolator ip = make(m);
  ASSERT_TRUE(ip.command(kCommandSpline, spline(200, 1'000'000)).ok());
  ASSERT_TRUE(ip.load(b.program()).ok());
  ASSERT_TRUE(ip.start().ok());
  const auto rs = run(ip);
  ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
  const double T = ip.cycle_time_s(), dt = ip.calc_step_s();
  double raw = 0.0, smooth = 0.0, dev = 0.0;
  for (std::size_t c = 3; c < rs.size(); ++c) {
    for (std::size_t i = 0; i < 2; ++i) {
      auto j3 = [&](auto get) {
        return std::fabs(get(rs[c]) - 3.0 * get(rs[c - 1]) + 3.0 * get(rs[c - 2]) - get(rs[c - 3])) / (T * T * T);
      };
      raw = std::max(raw, j3([&](const Registers& r) { return r.orig_position[i]; }));
      smooth = std::max(smooth, j3([&](const Registers& r) { return r.position[i]; }));
    }
    dev = std::max(dev, rs[c].spline_deviation_mm);
  }
  const SplineSmoother& sp = ip.smoothing().spline();
  // Predicted bound: a velocity jump dv leaves with jerk dv * g / dt^2, plus the machine's own
  // jerk (below the limit, not flagged); dv <= 100 mm/s per axis.
  const double predicted = 100.0 * sp.velocity_jump_jerk_gain() / (dt * dt) + 30000.0;
  RecordProperty("raw_jerk_mm_s3", std::to_string(raw));
  RecordProperty("smoothed_jerk_mm_s3", std::to_string(smooth));
  RecordProperty("contour_deviation_mm", std::to_string(sp.stats().max_mm));
  EXPECT_GT(raw, 1e8);                  // ~ dv / T^2 at cycle sampling
  EXPECT_LT(smooth, 1.05 * predicted);  // ~ 1.3e6 mm/s^3
  EXPECT_GT(raw / smooth, 100.0);
  EXPECT_GT(sp.stats().flagged_steps, 0u);
  EXPECT_GE(sp.stats().passes, 3u);     // the three corners (start and end are jerk-limited)
  EXPECT_GT(sp.stats().max_mm, 0.01);   // the corners are cut, and it is reported
  EXPECT_LT(sp.stats().max_mm, 0.5);
  EXPECT_GT(dev, 0.01);                 // also in the register
  EXPECT_EQ(rs.back().position, rs.back().orig_position);
}

// ---------------- IIR ----------------

// IIR (critically damped, f = 6 ms) on axis 0 only: axis 1 passes unchanged, axis 0 lags while
// moving; the M-function is signalled when the interpolator stands (same cycle as without the
// filter) while axis 0 still moves; Status 3 only once axis 0 has settled on the end.
TEST(Wiring, IirFiltersOnlyMaskedAxesAndMFunctionsSignalAtStandstill) {
  MachineConfig m = MachineConfig::default_machine();
  ProgramBuilder b;
  b.line({10.0, 10.0, 0.0}, 6000.0).m(8, MKind::kNormal).line({0.0, 0.0, 0.0}, 6000.0).end();
  int m_cycle[2] = {-1, -1};
  for (int with : {0, 1}) {
    Interpolator ip = make(m);
    Params p{};
    p[0] = 2'000'000;
    p[1] = 1'000'000;
    p[2] = 6'000'000;
    p[3] = with ? 0b1 : 0;
    ASSERT_TRUE(ip.command(kCommandIir, p).ok()) << ip.command_error();
    ASSERT_TRUE(ip.load(b.program()).ok());
    ASSERT_TRUE(ip.start().ok());
    const auto rs = run(ip, 100);
    ASSERT_EQ(rs.back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
    const int mc = first_cycle(rs, [](const Registers& r) { return r.m_func == 8; });
    ASSERT_GE(mc, 0);
    m_cycle[with] = mc;
    if (!with) continue;
    double lag = 0.0;
    for (const Registers& r : rs) {
      ASSERT_EQ(r.position[1], r.orig_position[1]);  // not in the mask: unfiltered, bit for bit
      lag = std::max(lag, std::fabs(r.position[0] - r.orig_position[0]));
    }
    EXPECT_GT(lag, 0.01);
    const Registers& at_m = rs[static_cast<std::size_t>(mc)];
    EXPECT_EQ(at_m.orig_position[0], 10.0);
    EXPECT_GT(std::fabs(at_m.position[0] - 10.0), 1e-6);  // still moving behind the filter
    EXPECT_GT(std::fabs(at_m.speed[0]), 1e-3);
    // At the end it stands exactly (the filter snaps onto its input) and Status says so.
    EXPECT_EQ(rs.back().position[0], 0.0);
    // Settled within f (6 ms = 12 cycles) of the interpolator's stop, to 2 % of the move...
    // and Status 3 not before the axis settled.
    const int end_orig = first_cycle(rs, [](const Registers& r) {
      return r.orig_position[0] == 0.0 && r.orig_position[1] == 0.0 && r.act_speed == 0.0 && r.m_func == 0 &&
             r.act_part == 3;
    });
    ASSERT_GE(end_orig, 0);
    const auto e = static_cast<std::size_t>(end_orig);
    EXPECT_LT(std::fabs(rs[e + 12].position[0]), 0.02 * 10.0);
    for (std::size_t c = e; c + 1 < rs.size(); ++c) {
      EXPECT_NE(rs[c].status, static_cast<std::int32_t>(InterpolatorStatus::kEnded)) << c;
    }
  }
  EXPECT_EQ(m_cycle[0], m_cycle[1]);  // the IIR filter does not delay M-functions
}

// ---------------- Commands ----------------

TEST(Wiring, CommandsWithValidAndInvalidParametersAndStatusSequence) {
  MachineConfig m = MachineConfig::default_machine();
  m.interpolators[0].axes[0].backlash_mm = 0.02;
  Interpolator ip = make(m);
  const Registers& r = ip.registers();
  // Ratio: 4096 inc per 2 mm on axis 0.
  Params p{};
  p[0] = 0;
  p[1] = 4096;
  p[2] = 2;
  RequestResult res = ip.command(kCommandSetRatio, p);
  ASSERT_TRUE(res.ok()) << res.reason;
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(r.command_status, 0);
  EXPECT_EQ(r.ratio[0], 2048.0);
  EXPECT_EQ(r.command_parameter, p);
  // Invalid: axis out of range, zero numerator, denominator <= 0, unknown code.
  p[0] = 3;
  res = ip.command(kCommandSetRatio, p);
  EXPECT_EQ(res.code, RequestCode::kOutOfRange);
  EXPECT_EQ(res.reason, "Command 1024: axis (Command_Parameter[0]) must be 0..2, not 3");
  EXPECT_EQ(r.command_status, -1);
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(ip.command_error(), res.reason);
  p[0] = 1;
  p[1] = 0;
  EXPECT_EQ(ip.command(kCommandSetRatio, p).code, RequestCode::kOutOfRange);
  p[1] = 10;
  p[2] = 0;
  EXPECT_EQ(ip.command(kCommandSetRatio, p).code, RequestCode::kOutOfRange);
  res = ip.command(7, p);
  EXPECT_EQ(res.code, RequestCode::kOutOfRange);
  EXPECT_EQ(res.reason, "unknown Command 7 (valid: 4, 5, 8, 9, 1024, 2048, 2049, -1, -2)");
  EXPECT_EQ(ip.command(1024).code, RequestCode::kUnsupported);  // needs its parameters
  // IIR and spline parameter ranges.
  const Params iir = iir_params(100, 1'000'000, 6'000'000, 1);  // p 0.0001
  res = ip.command(kCommandIir, iir);
  EXPECT_EQ(res.code, RequestCode::kOutOfRange);
  EXPECT_NE(res.reason.find("p"), std::string::npos);
  EXPECT_EQ(r.command_status, -1);
  res = ip.command(kCommandSpline, spline(20, 1'000'000));
  EXPECT_EQ(res.reason, "Spline points (Command_Parameter[0]) must be 0 (off) or 50..500, not 20");
  ASSERT_TRUE(ip.command(kCommandSpline, spline(100, 1'000'000)).ok());
  EXPECT_EQ(r.command_status, 0);
  EXPECT_TRUE(ip.command_error().empty());
  // Offset and Number_Axes writes.
  EXPECT_TRUE(ip.write_offset(1, 500).ok());
  EXPECT_EQ(r.offset[1], 500);
  EXPECT_EQ(r.position_inc[1], 500);
  EXPECT_EQ(ip.write_offset(3, 1).code, RequestCode::kOutOfRange);
  EXPECT_EQ(ip.write_offset(0, 2'000'000'000'000'000).code, RequestCode::kOutOfRange);
  EXPECT_EQ(ip.write_ratio(0, 0.0).code, RequestCode::kOutOfRange);
  EXPECT_EQ(ip.write_number_axes(0).reason, "Number_Axes must be 1..10, not 0");
  EXPECT_EQ(ip.write_number_axes(11).code, RequestCode::kOutOfRange);
  EXPECT_EQ(ip.write_number_axes(4).reason, "Number_Axes 4: only 3 axes are configured");

  // A program: X +5 then back to 1 (a reversal for the backlash), with Y and Z.
  ProgramBuilder b;
  b.line({5.0, 2.0, 0.0}, 3000.0).line({1.0, 2.0, 1.0}, 3000.0).end();
  ASSERT_TRUE(ip.load(b.program()).ok());
  ASSERT_TRUE(ip.start().ok());
  for (int c = 0; c < 50; ++c) ip.step();
  // Wrong state while moving, with the reason.
  Params pos{};
  res = ip.command(kCommandSetPositionOn, pos);
  EXPECT_EQ(res.code, RequestCode::kWrongState);
  EXPECT_EQ(res.reason, "Command 2048: the position can only be set while no program is executing");
  EXPECT_EQ(r.command_status, -1);
  EXPECT_EQ(ip.command(kCommandSpline, spline(200, 1'000'000)).code, RequestCode::kWrongState);
  EXPECT_EQ(ip.write_number_axes(2).code, RequestCode::kWrongState);
  EXPECT_EQ(ip.write_ratio(0, 1000.0).code, RequestCode::kWrongState);
  // PositionInc identity and the backlash ramp: every cycle, no step larger than the ramp.
  const double half = 0.01 * 2048.0;  // compensation 0.01 mm in inc
  double prev_bl = static_cast<double>(r.backlash[0]);
  double bl_max = 0.0, bl_min = 0.0, max_bl_step = 0.0;
  for (int c = 0; c < 20000; ++c) {
    const StepResult s = ip.step();
    for (std::size_t i = 0; i < 3; ++i) {
      ASSERT_EQ(r.position_inc[i],
                static_cast<std::int64_t>(std::llround(r.position[i] * r.ratio[i])) + r.offset[i] + r.backlash[i])
          << c;
    }
    const double bl = static_cast<double>(r.backlash[0]);
    max_bl_step = std::max(max_bl_step, std::fabs(bl - prev_bl));
    bl_max = std::max(bl_max, bl);
    bl_min = std::min(bl_min, bl);
    prev_bl = bl;
    if (s == StepResult::kFinished) break;
  }
  ASSERT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
  EXPECT_NEAR(bl_max, half, 0.5);   // +backlash/2 while moving in +X
  EXPECT_NEAR(bl_min, -half, 0.5);  // -backlash/2 after the reversal
  EXPECT_EQ(r.backlash[0], std::llround(-half));
  // Ramp velocity <= 10 % of 250 mm/s: at most 0.0125 mm = 25.6 inc per cycle.
  EXPECT_LE(max_bl_step, 0.1 * 250.0 * 0.0005 * 2048.0 + 1.0);
  EXPECT_GT(max_bl_step, 0.0);

  // Position set (2048) when ended: Position = (inc - Offset - Backlash) / Ratio, PositionInc = inc.
  pos[0] = 10'000;
  pos[1] = 3'000;
  pos[2] = -500;
  res = ip.command(kCommandSetPositionOn, pos);
  ASSERT_TRUE(res.ok()) << res.reason;
  EXPECT_EQ(r.command_status, 0);
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(r.position_inc[0], 10'000);
  EXPECT_EQ(r.position_inc[1], 3'000);
  EXPECT_EQ(r.position_inc[2], -500);
  EXPECT_DOUBLE_EQ(r.position[0], (10'000.0 - static_cast<double>(std::llround(-half))) / 2048.0);
  EXPECT_DOUBLE_EQ(r.orig_position[1], (3'000.0 - 500.0) / 1000.0);
  EXPECT_EQ(r.off_trajectory, 0);
  ASSERT_TRUE(ip.command(kCommandSetPositionOff, pos).ok());
  EXPECT_EQ(r.off_trajectory, 1);
  // Number_Axes while idle.
  ASSERT_TRUE(ip.write_number_axes(2).ok());
  EXPECT_EQ(r.number_axes, 2);
  EXPECT_EQ(ip.write_offset(2, 1).code, RequestCode::kOutOfRange);
  ASSERT_TRUE(ip.write_number_axes(3).ok());
}

// A gear ratio changes PositionInc by Position x the change in one cycle: not while a program
// is under way, at an M-function wait (it was accepted there, the drive setpoint jumped 100 mm
// and the program went on at the new scale), at a stop it resumes from, or while it waits for
// more records; before it starts and after it ended, yes.
TEST(Wiring, TheRatioIsSetOnlyBetweenPrograms) {
  MachineConfig m = MachineConfig::default_machine();
  Interpolator ip = make(m);
  const Registers& r = ip.registers();
  Params p{};
  p[0] = 0;
  p[1] = 2000;
  p[2] = 1;
  const std::string refused =
      "Command 1024: the ratio can only be set while no program is executing (PositionInc jumps "
      "by Position x the change)";
  const std::string refused_register =
      "Ratio can only be written while no program is executing (PositionInc jumps by Position x "
      "the change)";
  ProgramBuilder b;
  b.line({100.0, 0.0, 0.0}, 6000.0).m(50, MKind::kNormal).line({0.0, 0.0, 0.0}, 6000.0).end();
  ASSERT_TRUE(ip.load(b.program()).ok());
  // Loaded, not started: allowed.
  ASSERT_TRUE(ip.command(kCommandSetRatio, p).ok());
  EXPECT_EQ(r.ratio[0], 2000.0);
  p[1] = 1000;
  ASSERT_TRUE(ip.write_ratio(0, 1000.0).ok());
  ASSERT_TRUE(ip.start().ok());
  int c = 0;
  while (r.m_func != 50 && c++ < 100000) ip.step();
  ASSERT_EQ(r.m_func, 50);
  const std::int64_t inc = r.position_inc[0];
  EXPECT_EQ(inc, 100000);
  EXPECT_EQ(ip.command(kCommandSetRatio, p).reason, refused);
  EXPECT_EQ(ip.write_ratio(0, 2000.0).reason, refused_register);
  ip.step();
  EXPECT_EQ(r.position_inc[0], inc);
  EXPECT_EQ(r.ratio[0], 1000.0);
  ASSERT_TRUE(ip.write_m_func(0).ok());
  // Stopped on the trajectory mid-move (Status 4): a start resumes it.
  for (int k = 0; k < 200; ++k) ip.step();
  ASSERT_TRUE(ip.command(8).ok());
  c = 0;
  while (r.status != static_cast<std::int32_t>(InterpolatorStatus::kReady) && c++ < 100000) {
    ip.step();
  }
  ASSERT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
  EXPECT_EQ(ip.command(kCommandSetRatio, p).reason, refused);
  EXPECT_EQ(ip.write_ratio(0, 2000.0).code, RequestCode::kWrongState);
  ASSERT_TRUE(ip.start().ok());
  EXPECT_EQ(run(ip).back().status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
  // Ended: allowed again.
  ASSERT_TRUE(ip.write_ratio(0, 2000.0).ok());
  EXPECT_EQ(r.ratio[0], 2000.0);
}

// An axis entering the IIR mask starts at rest on its input: while the spline still carries
// motion after a stop, Command -1 waits at Command_Status 1 until it has drained (it was done
// at once, and Position X went from 34.7 mm/s to 1.4 in one cycle). Position's velocity then
// changes per cycle no more than in the same run without the command.
TEST(Wiring, AnAxisEntersTheIirMaskOnlyWhenItsInputStands) {
  const auto largest_step = [](bool enter) {
    MachineConfig m = MachineConfig::default_machine();
    Interpolator ip = make(m);
    const Registers& r = ip.registers();
    EXPECT_TRUE(ip.command(kCommandSpline, spline(500, 1'000'000)).ok());
    ProgramBuilder b;
    b.line({200.0, 0.0, 0.0}, 6000.0).end();
    EXPECT_TRUE(ip.load(b.program()).ok());
    EXPECT_TRUE(ip.start().ok());
    double prev_pos = 0.0, prev_v = 0.0, largest = 0.0;
    bool sent = false;
    int waited = -1;
    for (int c = 0; c < 4000; ++c) {
      ip.step();
      const double v = (r.position[0] - prev_pos) / 0.0005;
      if (c > 2) largest = std::max(largest, std::fabs(v - prev_v));
      prev_v = v;
      prev_pos = r.position[0];
      if (c == 600) {
        EXPECT_TRUE(ip.command(8).ok());
      }
      // The path generator stands after the stop, the spline still moves the axes.
      if (enter && !sent && c > 600 && r.act_speed == 0.0) {
        EXPECT_FALSE(ip.smoothing().spline().settled());
        EXPECT_TRUE(ip.command(kCommandIir, iir_params(2'000'000, 1'000'000, 6'000'000, 1)).ok());
        EXPECT_EQ(r.command_status, 1);
        sent = true;
        waited = 0;
      } else if (sent && r.command_status == 1) {
        ++waited;
      }
    }
    if (enter) {
      EXPECT_EQ(r.command_status, 0);
      EXPECT_EQ(ip.smoothing().iir().mask(), 1u);
      EXPECT_GT(waited, 10);  // the spline's drain: 2 x 500 steps = 200 cycles at most
    }
    return largest;
  };
  const double without = largest_step(false);
  const double with = largest_step(true);
  EXPECT_GT(without, 0.0);
  EXPECT_LE(with, without + 1e-9);
}

// Command_Status 1 while a command waits for the smoothing: a spline change and a position set
// after a stop, executed when the spline has drained; a stop cancels a waiting command.
TEST(Wiring, CommandStatusOneWhileWaitingForTheSmoothing) {
  MachineConfig m = MachineConfig::default_machine();
  Interpolator ip = make(m);
  const Registers& r = ip.registers();
  ASSERT_TRUE(ip.command(kCommandSpline, spline(200, 1'000'000)).ok());
  ProgramBuilder b;
  b.line({30.0, 0.0, 0.0}, 6000.0).end();
  ASSERT_TRUE(ip.load(b.program()).ok());
  ASSERT_TRUE(ip.start().ok());
  for (int c = 0; c < 100; ++c) ip.step();
  ASSERT_TRUE(ip.command(8).ok());  // stop on the trajectory
  int c = 0;
  while (r.act_speed != 0.0 && c < 10000) {
    ip.step();
    ++c;
  }
  ASSERT_EQ(r.command_status, 0);
  // The path stands, the spline still holds motion: Command -2 waits at Command_Status 1, and
  // Status waits for the axes (4 once they stand).
  ASSERT_FALSE(ip.smoothing().spline().settled());
  EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kRunning));
  ASSERT_TRUE(ip.command(kCommandSpline, spline(300, 2'000'000)).ok());
  EXPECT_EQ(r.command, kCommandSpline);
  EXPECT_EQ(r.command_status, 1);
  EXPECT_EQ(ip.command(kCommandSpline, spline(100, 1'000'000)).code, RequestCode::kWrongState);
  std::vector<std::int32_t> seq;
  int waited = 0;
  while (r.command_status == 1 && waited < 1000) {
    ip.step();
    ++waited;
    seq.push_back(r.command_status);
  }
  EXPECT_EQ(r.command_status, 0);
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(ip.smoothing().spline().delay_steps(), 300);
  EXPECT_EQ(r.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
  // It took about the drain: N + 2 = 202 steps after the path stood (2N + 2 after a flagged
  // step), in cycles.
  EXPECT_GT(waited, 20);
  EXPECT_LE(waited, 82);
  EXPECT_EQ(r.position, r.orig_position);
  // Resume, stop again, and a position set waits for the new 300-point buffer.
  ASSERT_TRUE(ip.start().ok());
  for (int k = 0; k < 30; ++k) ip.step();
  ASSERT_TRUE(ip.command(9).ok());  // stop off the trajectory: the program is dropped
  while (r.command_status != 0) ip.step();
  Params pos{};
  pos[0] = 1234;
  ASSERT_TRUE(ip.command(kCommandSetPositionOn, pos).ok());
  EXPECT_EQ(r.command_status, 1);
  EXPECT_EQ(r.command, kCommandSetPositionOn);
  // A stop command cancels it, with the reason kept.
  ASSERT_TRUE(ip.command(8).ok());
  EXPECT_EQ(ip.command_error(), "Command 2048: cancelled by Command 8");
  ASSERT_TRUE(ip.command(kCommandSetPositionOn, pos).ok());
  while (r.command_status == 1) ip.step();
  EXPECT_EQ(r.command_status, 0);
  EXPECT_EQ(r.position_inc[0], 1234);
  EXPECT_EQ(r.orig_position[0], 1.234);
}

// ---------------- LookAheadBuffer ----------------

TEST(Wiring, LookAheadBufferThroughAProgram) {
  MachineConfig m = MachineConfig::default_machine();
  Interpolator ip = make(m);
  const Registers& r = ip.registers();
  MParams p = unset_params();
  p[static_cast<std::size_t>('S' - 'A')] = 800.0;
  ProgramBuilder b;
  b.line({10.0, 0.0, 0.0}, 6000.0)              // line 1
      .m(1003, MKind::kContinuous)               // 2: belongs to the arc
      .arc(true, {10.0, 20.0, 0.0}, {10.0, 10.0}, 3000.0)  // 3: half circle CCW, r 10, 270 -> 90
      .dwell(0.01)                               // 4: not a section
      .m(6, MKind::kNormal, &p)                  // 5
      .message("hello")                          // 6: not a section
      .line({0.0, 20.0, 0.0}, 6000.0)            // 7
      .line({0.0, 20.0, 5.0}, 6000.0)            // 8: pure Z, no XY tangent
      .m(7, MKind::kNormal)                      // 9
      .line({0.0, 0.0, 5.0}, 6000.0)             // 10
      .line({5.0, 0.0, 5.0}, 6000.0)             // 11
      .end();                                    // 12: M2, not a section
  ASSERT_TRUE(ip.load(b.program()).ok());
  ASSERT_TRUE(ip.start().ok());
  ip.step();
  auto la = r.lookahead;
  const int lines0[8] = {1, 3, 5, 7, 8, 9, 10, 11};
  for (std::size_t e = 0; e < 8; ++e) EXPECT_EQ(la[e].line, lines0[e]) << e;
  EXPECT_EQ(la[0].movement_type, 1);
  EXPECT_EQ(la[0].movement_code, 1);
  EXPECT_EQ(la[0].tangent_deg, 0.0);
  EXPECT_TRUE(is_not_set(la[0].start_angle_deg));
  EXPECT_EQ(la[0].radius_mm, 0.0);
  EXPECT_EQ(la[1].movement_code, 3);
  EXPECT_EQ(la[1].all_params[static_cast<std::size_t>('M' - 'A')], 1003.0);  // continuous M
  EXPECT_NEAR(la[1].start_angle_deg, 270.0, 1e-9);
  EXPECT_NEAR(la[1].end_angle_deg, 90.0, 1e-9);
  EXPECT_NEAR(la[1].radius_mm, 10.0, 1e-12);
  EXPECT_NEAR(la[1].tangent_deg, 0.0, 1e-9);  // initial tangent of the arc: +X
  EXPECT_EQ(la[2].movement_type, 2);
  EXPECT_EQ(la[2].movement_code, 6);
  EXPECT_EQ(la[2].all_params[static_cast<std::size_t>('S' - 'A')], 800.0);
  EXPECT_NEAR(la[3].tangent_deg, 180.0, 1e-9);
  EXPECT_TRUE(is_not_set(la[4].tangent_deg));  // pure Z
  EXPECT_EQ(la[4].end_pos_mm[2], 5.0);
  EXPECT_EQ(la[5].movement_code, 7);
  for (const auto& e : la) EXPECT_EQ(e.plane, 17);
  // On the arc: entry 0 is the arc with its M letter; the tangent follows the motion.
  int c = 0;
  while (r.lookahead[0].line != 3 && c++ < 100000) ip.step();
  ASSERT_EQ(r.lookahead[0].line, 3);
  EXPECT_EQ(r.lookahead[0].all_params[static_cast<std::size_t>('M' - 'A')], 1003.0);
  EXPECT_EQ(r.lookahead[7].movement_type, 0);  // 7 sections left: the arc and 6 more
  EXPECT_EQ(r.lookahead[6].line, 11);
  double last_t = -1.0;
  int changes = 0;
  while (r.lookahead[0].line == 3) {
    const double t = r.lookahead[0].tangent_deg;
    // Tangent of a CCW arc = polar angle of the point + 90 degrees.
    const double ang = std::atan2(r.orig_position[1] - 10.0, r.orig_position[0] - 10.0) * 180.0 / kPi;
    double expect = std::fmod(ang + 90.0 + 720.0, 360.0);
    double diff = std::fabs(t - expect);
    diff = std::min(diff, 360.0 - diff);
    EXPECT_LT(diff, 1e-6) << t << " vs " << expect;
    if (last_t >= 0.0 && t != last_t) ++changes;
    last_t = t;
    ip.step();
  }
  EXPECT_GT(changes, 50);
  // Shifts down to the end: with k sections left, entries k..7 are invalid.
  const int lines_left[] = {5, 7, 8, 9, 10, 11};
  for (int k = 0; k < 6; ++k) {
    int guard = 0;
    while (r.lookahead[0].line != lines_left[k] && guard++ < 100000) {
      ip.step();
      if (run_flag_section(r.run_flag) == SectionState::kWaitMFunc) ip.write_m_func(0);
    }
    ASSERT_EQ(r.lookahead[0].line, lines_left[k]) << k;
    const int left = 6 - k;
    for (int e = 0; e < 8; ++e) {
      EXPECT_EQ(r.lookahead[static_cast<std::size_t>(e)].movement_type == 0, e >= left) << k << " " << e;
    }
  }
}

// ---------------- Simulation ----------------

// The offline run with spline and IIR ends where the program ends, on every axis, and the
// fast path gives the same summary as stepping.
TEST(Wiring, SimulationEndsWhenEveryAxisArrived) {
  MachineConfig m = MachineConfig::default_machine();
  ProgramBuilder b;
  b.line({10.0, 5.0, 0.0}, 6000.0).m(8, MKind::kNormal).dwell(0.2).line({-3.0, 1.0, 2.0}, 6000.0).end();
  SimulationOptions o;
  o.commands.push_back({kCommandSpline, spline(500, 1'000'000)});
  o.commands.push_back({kCommandIir, iir_params(1'414'214, 2'000'000, 20'000'000, 0b101)});
  SimulationSummary s[2];
  for (int fast = 0; fast < 2; ++fast) {
    o.fast_forward = fast == 1;
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    s[fast] = sim->run(b.program());
    ASSERT_EQ(s[fast].result, StepResult::kFinished) << s[fast].error;
    EXPECT_EQ(s[fast].end_position_smoothed[0], -3.0);
    EXPECT_EQ(s[fast].end_position_smoothed[1], 1.0);
    EXPECT_EQ(s[fast].end_position_smoothed[2], 2.0);
  }
  EXPECT_EQ(s[0].cycles, s[1].cycles);
  EXPECT_EQ(s[0].m_functions, s[1].m_functions);
  // A refused command makes create() fail with the reason.
  o.commands = {{kCommandSpline, spline(5000, 1)}};
  std::string err;
  EXPECT_FALSE(Simulation::create(m, o, &err));
  EXPECT_NE(err.find("50..500"), std::string::npos) << err;
}

// The limit check holds Orig_Position to the limits; Position after the smoothing is what the
// drives get. At a corner crossed at full speed (a tolerance above the feed), Y's velocity
// steps from 0 to 233 mm/s: an IIR filter below critical damping overshoots that step by half
// (356 mm/s against 250), and the summary has the peaks of Position to say so; a critically
// damped one does not overshoot (its step response is monotone), and without the filter
// nothing is measured (Position is Orig_Position). Before session 75 the first said
// "violations: 0" and nothing else.
TEST(Wiring, TheLimitCheckMeasuresPositionAfterTheSmoothing) {
  MachineConfig m = MachineConfig::default_machine();
  for (AxisConfig& a : m.interpolators[0].axes) a.corner_velocity_tolerance_mm_s = 10000.0;
  const double vmax = m.interpolators[0].axes[1].max_velocity_mm_s;
  ProgramBuilder b;
  // Lines of 100 mm: on lines of 50 mm the turn of the corner alone, taken as part of a run of
  // chords, holds the speed to 188 mm/s (Planner, junction limits).
  b.line({100.0, 0.0, 0.0}, 14000.0).line({100.0, 100.0, 0.0}, 14000.0).end();
  const auto peak_v = [&](std::vector<std::pair<std::int32_t, Params>> commands, bool* measured) {
    SimulationOptions o;
    o.check_limits = true;
    o.commands = std::move(commands);
    auto sim = Simulation::create(m, o);
    EXPECT_TRUE(sim);
    const SimulationSummary s = sim->run(b.program());
    EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
    EXPECT_EQ(s.violation_count, 0u);
    *measured = s.smoothed_measured;
    return s.smoothed_peaks[1].velocity_mm_s;
  };
  bool measured = false;
  // zeta 0.2: overshoot exp(-pi zeta / sqrt(1 - zeta^2)) = 53 % of a step.
  const double under =
      peak_v({{kCommandIir, iir_params(400'000, 1'000'000, 50'000'000, 3)}}, &measured);
  EXPECT_TRUE(measured);
  EXPECT_GT(under, 1.4 * vmax);
  const double critical =
      peak_v({{kCommandIir, iir_params(2'000'000, 1'000'000, 50'000'000, 3)}}, &measured);
  EXPECT_TRUE(measured);
  EXPECT_LE(critical, 14000.0 / 60.0 * (1.0 + 1e-9));
  EXPECT_GT(critical, 0.99 * 14000.0 / 60.0);
  EXPECT_EQ(peak_v({}, &measured), 0.0);
  EXPECT_FALSE(measured);
}

// The backlash ramp takes its share of the limits on top of the motion, so the planner plans an
// axis with backlash at the rest. A reversal at a stop: X back from 20 mm at full
// acceleration, a backlash of 0.05 mm whose ramp is bound by acceleration (J high: the
// quintic's acceleration peak, 10/sqrt(3) D / T^2, is the share of A, 9 ms into the ramp while
// the motion still accelerates). Planned at the full limits (before session 83), the drive
// setpoint reached 1.1 x A there, and the summary measured only the smoothed Position, not the
// setpoint. Share 0.1 and 0.3: Orig_Position peaks at (1 - share) x A, the setpoint at A.
TEST(Wiring, TheBacklashRampHasItsShareOfTheLimitsFree) {
  for (const double share : {0.1, 0.3}) {
    SCOPED_TRACE(share);
    MachineConfig m = MachineConfig::default_machine();
    for (AxisConfig& a : m.interpolators[0].axes) a.max_jerk_mm_s3 = 1e6;
    AxisConfig& x = m.interpolators[0].axes[0];
    x.backlash_mm = 0.05;
    x.backlash_ramp_share = share;
    const double A = x.max_acceleration_mm_s2;
    ProgramBuilder b;
    b.line({20.0, 0.0, 0.0}, 15000.0).line({0.0, 0.0, 0.0}, 15000.0).end();
    SimulationOptions o;
    o.check_limits = true;
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    const SimulationSummary s = sim->run(b.program());
    ASSERT_EQ(s.result, StepResult::kFinished) << s.error;
    EXPECT_EQ(s.violation_count, 0u);
    // The ramp happened and ended where it should: -backlash/2 after motion in -X.
    EXPECT_NEAR(sim->interpolator().output().compensation_mm(0), -0.025, 1e-12);
    EXPECT_LE(s.peaks[0].acceleration_mm_s2, (1.0 - share) * A * (1.0 + 1e-6));
    EXPECT_GE(s.peaks[0].acceleration_mm_s2, (1.0 - share) * A * 0.99);
    ASSERT_TRUE(s.smoothed_measured);
    // Per-cycle differences of the setpoint velocity: 1 % for the discretisation.
    EXPECT_LE(s.smoothed_peaks[0].acceleration_mm_s2, A * 1.01);
    EXPECT_GE(s.smoothed_peaks[0].acceleration_mm_s2, A * 0.97);
  }
}

// A program whose IIR-filtered axis ends far from the origin ends too (Status 3 at the
// filtered position equal to the end point). Before session 41 the filter's lag stuck at a
// few units in the last place of such a coordinate (X at 2,400 mm: 1.4e-12 mm), it never came
// to rest, and the run went on to the simulation's time limit (tgm-service: Status 1 for ever).
TEST(Wiring, SimulationEndsWithTheIirOnFarFromTheOrigin) {
  MachineConfig m = MachineConfig::default_machine();
  for (const double x : {2400.0, 5000.0, -123456.7}) {
    ProgramBuilder b;
    b.line({x - 1.0, 0.5, 0.0}, 6000.0).line({x, 0.0, 0.0}, 6000.0).end();
    SimulationOptions o;
    o.commands.push_back({kCommandIir, iir_params(2'000'000, 1'000'000, 5'000'000, 0b011)});
    o.max_time_s = 600.0;
    std::array<double, kMaxAxes> start{};
    start[0] = x - 2.0;
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    sim->interpolator().set_position(start);
    const SimulationSummary s = sim->run(b.program());
    ASSERT_EQ(s.result, StepResult::kFinished) << x << ": " << s.error;
    EXPECT_EQ(s.end_position_smoothed[0], x);
    EXPECT_EQ(s.end_position_smoothed[1], 0.0);
    EXPECT_LT(s.program_time_s, 1.0) << x;
  }
}

}  // namespace
}  // namespace tgm
