// Interpolator::advance (the simulator's fast path) against step(): on seeded random programs
// the registers after every advance() call must equal, bit for bit, those after as many step()
// calls, and whole simulations must give the same summary and block reports.
//
// TGM_SEED (default 1) and TGM_ADVANCE_COUNT (default 40) choose the programs.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "../support/test_params.hpp"
#include "limit_findings.hpp"
#include "program_builder.hpp"
#include "random_program.hpp"
#include "same_registers.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/simulation.hpp"

namespace tgm {
namespace {

using test::random_machine;
using test::random_program;

bool same_block(const BlockReport& a, const BlockReport& b) {
  return a.act_part == b.act_part && a.line == b.line && a.g == b.g && a.length_mm == b.length_mm &&
         a.programmed_mm_min == b.programmed_mm_min && a.peak_mm_min == b.peak_mm_min &&
         a.duration_s == b.duration_s && a.end_s == b.end_s && a.factor == b.factor;
}

struct SkipCounts {
  std::uint64_t skipped = 0, total = 0, skipped_smoothing = 0, skipped_plain = 0, total_plain = 0;
  std::uint64_t skipped_across = 0;  // in advance() calls that ended in another record
  // Backlash: cycles skipped while an axis' compensation is applied (not 0), and the times an
  // axis' compensation changed sign between two advance() calls (a reversal ramped through).
  std::uint64_t skipped_compensated = 0, compensation_reversals = 0;
};

// Two interpolators driven alike: `stepped` by step(), `fast` by advance() limited to the next
// cycle at which the driver acts (override change, M acknowledge, restart after M0). Smoothing:
// 0 off, 1 spline, 2 IIR on random axes, 3 both. For an odd smoothing_seed `fast` records its
// cycle trace, and each cycle of it must equal the stepped registers of that cycle.
void compare_stepping(const MachineConfig& m, const test::Generated& g, int smoothing,
                      std::uint64_t smoothing_seed, const std::string& ctx0, SkipCounts& counts) {
  InterpolatorOptions fo;
  fo.record_cycle_trace = smoothing_seed % 2 == 1;
  auto stepped = Interpolator::create(m, 0);
  auto fast = Interpolator::create(m, 0, fo);
  ASSERT_TRUE(stepped && fast);
  if (smoothing != 0) {
    std::mt19937_64 srng(smoothing_seed);
    std::array<std::int32_t, kCommandParameters> sp{}, ip{};
    sp[0] = std::uniform_int_distribution<int>(50, 500)(srng);
    sp[1] = std::uniform_int_distribution<int>(100'000, 5'000'000)(srng);
    ip[0] = 2'000'000;
    ip[1] = 1'000'000;
    ip[2] = std::uniform_int_distribution<int>(1'000'000, 30'000'000)(srng);
    ip[3] = std::uniform_int_distribution<int>(1, 1023)(srng);
    for (Interpolator* x : {&*stepped, &*fast}) {
      if (smoothing & 1) {
        ASSERT_TRUE(x->command(-2, sp).ok());
      }
      // A mask of none of the machine's axes is refused (it left the filter off, as here).
      const auto axes = m.interpolators[0].axes.size();
      if ((smoothing & 2) && (static_cast<std::uint32_t>(ip[3]) & ((1u << axes) - 1u)) != 0) {
        ASSERT_TRUE(x->command(-1, ip).ok());
      }
    }
  }
  const double T = stepped->cycle_time_s();
  // Override changes at whole cycles.
  std::vector<std::pair<std::uint64_t, double>> changes;
  for (const auto& [t, r] : g.overrides)
    changes.push_back({static_cast<std::uint64_t>(t / T) + 1, r});
  std::sort(changes.begin(), changes.end());
  const std::size_t n = g.program.segments.size();
  std::size_t next_s = 0, next_f = 0;
  auto feed = [&](Interpolator& ip, std::size_t& next) {
    if (next >= n || ip.free_slots() == 0) return;
    const std::size_t c = std::min(n - next, ip.free_slots());
    std::size_t took = 0;
    ip.append(g.program, next, c, next + c == n, &took);
    next += took;
  };
  feed(*stepped, next_s);
  feed(*fast, next_f);
  ASSERT_TRUE(stepped->start().ok());
  ASSERT_TRUE(fast->start().ok());
  std::uint64_t cycle = 0, m_ack_at = 0, m0_at = 0;
  std::int32_t part = 0;
  std::array<int, kMaxAxes> backlash_sign{};  // of each axis' last compensation other than 0
  bool m_pending = false, m0_pending = false;
  std::size_t change = 0;
  std::vector<BlockReport> blocks_s, blocks_f;
  const std::uint64_t limit = static_cast<std::uint64_t>(600.0 / T);
  while (cycle < limit) {
    while (change < changes.size() && changes[change].first <= cycle) {
      stepped->set_rel_speed(changes[change].second);
      fast->set_rel_speed(changes[change].second);
      ++change;
    }
    feed(*stepped, next_s);
    feed(*fast, next_f);
    std::uint64_t allow = limit - cycle;
    if (change < changes.size()) allow = std::min(allow, changes[change].first - cycle);
    if (m_pending) allow = std::min(allow, m_ack_at - cycle);
    if (m0_pending) allow = std::min(allow, m0_at - cycle);
    std::uint64_t done = 0;
    const StepResult rf = fast->advance(allow, &done);
    ASSERT_GE(done, 1u) << ctx0;
    ASSERT_LE(done, allow) << ctx0;
    for (const BlockReport& b : fast->block_reports()) blocks_f.push_back(b);
    StepResult rs = StepResult::kWorking;
    const std::span<const CycleTrace> trace = fast->cycle_trace();
    std::size_t te = 0;  // trace entry of the cycle stepped
    if (fo.record_cycle_trace) {
      ASSERT_FALSE(trace.empty()) << ctx0;
      EXPECT_EQ(trace.front().cycle, cycle + 1) << ctx0;
    }
    for (std::uint64_t i = 0; i < done; ++i) {
      rs = stepped->step();
      for (const BlockReport& b : stepped->block_reports()) blocks_s.push_back(b);
      if (!fo.record_cycle_trace) continue;
      const Registers& r = stepped->registers();
      while (te < trace.size() && trace[te].cycle + trace[te].count <= r.cycle) ++te;
      const std::string ctx = ctx0 + " traced cycle " + std::to_string(r.cycle);
      ASSERT_LT(te, trace.size()) << ctx;
      ASSERT_LE(trace[te].cycle, r.cycle) << ctx;
      EXPECT_EQ(trace[te].line, r.act_line) << ctx;
      EXPECT_EQ(trace[te].status, r.status) << ctx;
      for (int a = 0; a < r.number_axes; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        ASSERT_EQ(trace[te].orig_position[ua], r.orig_position[ua]) << ctx << " axis " << a;
      }
    }
    if (fo.record_cycle_trace) {
      EXPECT_EQ(te + 1, trace.size()) << ctx0 << ": trace entries beyond the cycles run";
      EXPECT_EQ(trace.back().cycle + trace.back().count, cycle + done + 1) << ctx0;
    }
    cycle += done;
    const std::int32_t part_before = part;
    part = fast->registers().act_part;
    {
      const Registers& r = fast->registers();
      bool compensated = false;
      for (int a = 0; a < r.number_axes; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        compensated = compensated || r.backlash[ua] != 0;
        if (r.backlash[ua] != 0 && backlash_sign[ua] != 0 &&
            (r.backlash[ua] > 0) != (backlash_sign[ua] > 0))
          ++counts.compensation_reversals;
        if (r.backlash[ua] != 0) backlash_sign[ua] = r.backlash[ua] > 0 ? 1 : -1;
      }
      if (done > 1 && compensated) counts.skipped_compensated += done;
    }
    counts.total += done;
    if (done > 1) counts.skipped += done;
    if (done > 1 && part != part_before) counts.skipped_across += done;
    if (done > 1 && smoothing != 0) counts.skipped_smoothing += done;
    if (smoothing == 0) {
      counts.total_plain += done;
      if (done > 1) counts.skipped_plain += done;
    }
    const std::string ctx = ctx0 + " cycle " + std::to_string(cycle);
    ASSERT_EQ(rs, rf) << ctx;
    test::expect_same_registers(stepped->registers(), fast->registers(), ctx);
    if (::testing::Test::HasFailure()) return;
    if (rs == StepResult::kFinished || rs == StepResult::kErrorInternal || rs == StepResult::kIdle)
      break;
    const Registers& r = fast->registers();
    const SectionState sec = run_flag_section(r.run_flag);
    const bool waiting_m = sec == SectionState::kWaitMFunc || sec == SectionState::kWaitMFuncEnd;
    if (r.m_func != 0 && r.last_cont_m_func == r.m_func && !waiting_m) {
      stepped->write_m_func(0);
      fast->write_m_func(0);
    }
    if (waiting_m && !m_pending) {
      m_pending = true;
      m_ack_at = cycle + 37;  // the PLC takes 37 cycles
    }
    if (m_pending && cycle >= m_ack_at) {
      stepped->write_m_func(0);
      fast->write_m_func(0);
      m_pending = false;
    }
    if (rs == StepResult::kWaiting &&
        r.status == static_cast<std::int32_t>(InterpolatorStatus::kReady)) {
      if (!m0_pending) {
        m0_pending = true;
        m0_at = cycle + 11;
      }
      if (cycle >= m0_at) {
        stepped->start();
        fast->start();
        m0_pending = false;
      }
    }
    if (rs == StepResult::kWaiting &&
        r.status == static_cast<std::int32_t>(InterpolatorStatus::kUnderrun)) {
      stepped->start();
      fast->start();
    }
  }
  // (A program slowed by a low override may not end within the limit; what ran is compared.)
  ASSERT_EQ(blocks_s.size(), blocks_f.size()) << ctx0;
  for (std::size_t i = 0; i < blocks_s.size(); ++i) {
    EXPECT_TRUE(same_block(blocks_s[i], blocks_f[i])) << ctx0 << " block " << i;
  }
}

TEST(Advance, RegistersEqualSteppingBitForBit) {
  const std::uint64_t seed = test::env_u64("TGM_SEED", 1);
  const std::uint64_t count = test::env_u64("TGM_ADVANCE_COUNT", 40);
  SkipCounts c;
  for (std::uint64_t k = 0; k < count; ++k) {
    std::mt19937_64 rng(seed * 7919ull + k);
    std::uniform_int_distribution<int> axes_d(1, 10);
    const int axes = k % 4 == 0 ? 3 : axes_d(rng);
    const MachineConfig m = random_machine(rng, axes);
    const test::Generated g = random_program(rng, axes, 12);
    const std::string ctx = "seed " + std::to_string(seed) + " program " + std::to_string(k);
    compare_stepping(m, g, static_cast<int>(k % 4), seed * 31337ull + k, ctx, c);
    if (::testing::Test::HasFailure()) return;
  }
  // The fast path must actually be exercised (cruise, dwells, M waits).
  EXPECT_GT(c.skipped_plain, c.total_plain / 4)
      << c.skipped_plain << " of " << c.total_plain << " cycles skipped without smoothing";
  EXPECT_GT(c.skipped_smoothing, 0u);  // and with smoothing on (standing after the drain)
  RecordProperty("skipped_cycles", std::to_string(c.skipped));
  RecordProperty("cycles", std::to_string(c.total));
}

// CAM finishing programs: polylines of short chords at a constant feed, so that a cruise runs
// through many junctions in one advance() call, with feed changes between polylines, override
// changes, normal M-functions and the smoothing variants. The chords are a few cycles of travel
// or shorter, some shorter than one calculation step.
test::Generated chord_program(std::mt19937_64& rng, int axes) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  test::ProgramBuilder b(axes);
  std::array<double, kMaxAxes> p{};
  double heading = u(rng) * 6.0;
  for (int run = 0; run < 6; ++run) {
    const double feed = 600.0 + 6000.0 * u(rng);
    const double chord = u(rng) < 0.3 ? 0.002 + 0.02 * u(rng) : 0.02 + 0.3 * u(rng);
    const double turn = (u(rng) - 0.5) * 0.02;  // [rad per chord]: gentle curves
    const int n = 100 + static_cast<int>(400 * u(rng));
    const double climb = u(rng) - 0.5;
    for (int i = 0; i < n; ++i) {
      // Now and then a sharper corner (a limit below the cruise speed ahead).
      heading += u(rng) < 0.01 ? (u(rng) - 0.5) : turn;
      p[0] += chord * std::cos(heading);
      if (axes > 1) p[1] += chord * std::sin(heading);
      // Climbing, at another slope in each polyline and with a small jitter: the records'
      // tangential limits differ (what the window's minima hold may lie beyond what a slower
      // cruise needs to scan).
      if (axes > 2) p[2] += chord * (climb + 0.01 * (u(rng) - 0.5));
      for (int a = 3; a < axes; ++a) p[static_cast<std::size_t>(a)] += 0.01 * chord * a;
      b.line_to(p, feed);
    }
    if (u(rng) < 0.5) b.m(8, MKind::kNormal);
  }
  b.end();
  test::Generated g;
  g.program = b.program();
  g.end = p;
  for (int i = 0; i < 3; ++i) g.overrides.push_back({0.2 + 2.0 * u(rng), 0.5 + u(rng)});
  return g;
}

TEST(Advance, ChordCruiseAcrossJunctionsEqualsStepping) {
  const std::uint64_t seed = test::env_u64("TGM_SEED", 1);
  SkipCounts c;
  for (std::uint64_t k = 0; k < 12; ++k) {
    std::mt19937_64 rng(seed * 6151ull + k);
    const int axes = k % 3 == 0 ? 2 : (k % 3 == 1 ? 3 : 6);
    const MachineConfig m = random_machine(rng, axes);
    const test::Generated g = chord_program(rng, axes);
    const std::string ctx = "seed " + std::to_string(seed) + " chord program " + std::to_string(k);
    compare_stepping(m, g, static_cast<int>(k % 4), seed * 7001ull + k, ctx, c);
    if (::testing::Test::HasFailure()) return;
  }
  // The chord cruises are mostly skipped, across junctions.
  EXPECT_GT(c.skipped_across, c.total_plain / 4) << c.skipped_across << " of " << c.total_plain;
  RecordProperty("skipped_across", std::to_string(c.skipped_across));
  RecordProperty("cycles", std::to_string(c.total));
}

// Backlash compensation on some axes. The cruise skip passes a cruise through the output stage
// only while every such axis stands, or moves on in the direction detected last with its ramp
// done (stage_passes; an arc's plane axes not at all), and skips a standstill only once the
// ramps are done. No other comparison gave an axis backlash, so that proof never ran in a test
// (session 44, found by line coverage). Chord polylines, whose sharper corners reverse X or Y
// now and then, and random programs with arcs, helices and M-functions; IIR on some axes in
// every fourth.
TEST(Advance, CruisesWithBacklashEqualStepping) {
  const std::uint64_t seed = test::env_u64("TGM_SEED", 1);
  SkipCounts c;
  for (std::uint64_t k = 0; k < 16; ++k) {
    std::mt19937_64 rng(seed * 5167ull + k);
    const int axes = k % 3 == 0 ? 2 : (k % 3 == 1 ? 3 : 5);
    MachineConfig m = random_machine(rng, axes);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (AxisConfig& a : m.interpolators[0].axes) {
      if (u(rng) < 0.75) a.backlash_mm = 0.002 + 0.1 * u(rng);
    }
    const test::Generated g = k % 2 == 0 ? chord_program(rng, axes) : random_program(rng, axes, 12);
    const std::string ctx =
        "seed " + std::to_string(seed) + " backlash program " + std::to_string(k);
    compare_stepping(m, g, k % 4 == 3 ? 2 : 0, seed * 2909ull + k, ctx, c);
    if (::testing::Test::HasFailure()) return;
  }
  // The proof ran and passed with compensation applied, and reversals were ramped through.
  EXPECT_GT(c.skipped_compensated, c.total_plain / 8)
      << c.skipped_compensated << " of " << c.total_plain;
  EXPECT_GT(c.compensation_reversals, 10u);
  RecordProperty("skipped_compensated", std::to_string(c.skipped_compensated));
  RecordProperty("compensation_reversals", std::to_string(c.compensation_reversals));
  RecordProperty("cycles", std::to_string(c.total));
}

// Cruises below kArriveV (1e-3 mm/s: a feed under 0.06 mm/min, or F6 at 1 % override) are
// skipped too, across junctions and up to just before a stop point, with the registers of
// stepping: chords of 2..20 nm at F0.002..0.05 mm/min, normal M-functions between polylines.
TEST(Advance, SlowCruiseBelowOneMicronPerSecondEqualsStepping) {
  const std::uint64_t seed = test::env_u64("TGM_SEED", 1);
  SkipCounts c;
  for (std::uint64_t k = 0; k < 4; ++k) {
    std::mt19937_64 rng(seed * 4099ull + k);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const int axes = k % 2 == 0 ? 3 : 5;
    const MachineConfig m = random_machine(rng, axes);
    test::ProgramBuilder b(axes);
    std::array<double, kMaxAxes> p{};
    double heading = u(rng) * 6.0;
    for (int run = 0; run < 3; ++run) {
      const double feed = 0.002 + 0.048 * u(rng);  // mm/min
      const double chord = 2e-6 + 18e-6 * u(rng);
      for (int i = 0; i < 40; ++i) {
        heading += 0.01;
        p[0] += chord * std::cos(heading);
        p[1] += chord * std::sin(heading);
        b.line_to(p, feed);
      }
      b.m(8, MKind::kNormal);
    }
    b.end();
    test::Generated g;
    g.program = b.program();
    g.end = p;
    const std::string ctx = "seed " + std::to_string(seed) + " slow program " + std::to_string(k);
    compare_stepping(m, g, 0, seed * 3001ull + k, ctx, c);
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GT(c.skipped_across, c.total_plain / 2) << c.skipped_across << " of " << c.total_plain;
  RecordProperty("skipped_across", std::to_string(c.skipped_across));
  RecordProperty("cycles", std::to_string(c.total));
}

// The figures of a run `b` that must be the run `a`.
void expect_same_summary(const SimulationSummary& a, const SimulationSummary& b,
                         const std::string& ctx) {
  EXPECT_EQ(b.result, a.result) << ctx << ": " << b.error;
  EXPECT_EQ(b.cycles, a.cycles) << ctx;
  EXPECT_EQ(b.distance_mm, a.distance_mm) << ctx;
  EXPECT_EQ(b.end_position, a.end_position) << ctx;
  EXPECT_EQ(b.m_functions, a.m_functions) << ctx;
  EXPECT_EQ(b.stops, a.stops) << ctx;
  EXPECT_EQ(b.factor_time_s, a.factor_time_s) << ctx;
}

// Whole simulations: fast-forward and stepping give the same summary and block reports.
// Three seeds' programs from TGM_SEED on (the default run includes seed 3 program 3, where a
// cruise skip once ignored the part of the window beyond what the cruise itself needed). Every
// second program gets one or two stops (Command 8 or 4) in its first 3 s, restarted after
// 0.05 s: the fast-forward must stop at them and restart as the stepping run does.
// `program` run with `o` stepped (index 0) and fast-forwarded (index 1); with `blocks`, the
// block reports of each run.
std::array<SimulationSummary, 2> run_stepped_and_fast(
    const MachineConfig& m, SimulationOptions o, const Program& program,
    std::array<std::vector<BlockReport>, 2>* blocks = nullptr) {
  std::array<SimulationSummary, 2> s;
  for (std::size_t mode = 0; mode < 2; ++mode) {
    o.fast_forward = mode == 1;
    auto sim = Simulation::create(m, o);
    if (!sim) {
      ADD_FAILURE() << "Simulation::create refused the options";
      return s;
    }
    s[mode] = sim->run(program, {}, [&](const BlockReport& r) {
      if (blocks != nullptr) (*blocks)[mode].push_back(r);
    });
  }
  return s;
}

TEST(Advance, SimulationSummaryEqualsStepping) {
  const std::uint64_t first = test::env_u64("TGM_SEED", 1);
  for (std::uint64_t run = 0; run < 30; ++run) {
    const std::uint64_t seed = first + run / 10, k = run % 10;
    std::mt19937_64 rng(seed * 104729ull + k);
    const int axes = 3;
    const MachineConfig m = random_machine(rng, axes);
    const test::Generated g = random_program(rng, axes, 16);
    SimulationOptions o;
    o.m_ack_s = 0.0123;
    o.rel_speed_changes = g.overrides;
    if (k % 2 == 1) {
      std::uniform_real_distribution<double> u(0.0, 1.0);
      const int n = 1 + static_cast<int>(k % 4 == 1);
      for (int i = 0; i < n; ++i) {
        const std::int32_t code = u(rng) < 0.5 ? 8 : 4;  // drawn first, as GCC evaluated it
        o.stops.emplace_back(3.0 * u(rng), code);
      }
      o.stop_restart_s = 0.05;
    }
    std::array<std::vector<BlockReport>, 2> b;
    const auto s = run_stepped_and_fast(m, o, g.program, &b);
    const std::string ctx = "seed " + std::to_string(seed) + " program " + std::to_string(k);
    ASSERT_EQ(s[0].result, StepResult::kFinished) << ctx << ": " << s[0].error;
    expect_same_summary(s[0], s[1], ctx);
    if (k % 2 == 1) {
      EXPECT_GE(s[0].stops, 1u) << ctx;
    }
    ASSERT_EQ(b[0].size(), b[1].size()) << ctx;
    for (std::size_t i = 0; i < b[0].size(); ++i)
      EXPECT_TRUE(same_block(b[0][i], b[1][i])) << ctx << " block " << i;
  }
}

// A program held as intercode (PackedProgram, what tgm-hmi simulate holds) runs as its decoded
// Program to the bit: the records are decoded as the ring takes them, a window at a time. A
// ring of 1,000 slots, chord programs of 600..3,000 records (a record a cycle and more), random
// programs with stops; every register of every cycle compared in the stepped runs.
TEST(Advance, APackedProgramRunsAsItsProgramToTheBit) {
  const std::uint64_t seed = test::env_u64("TGM_SEED", 1);
  for (std::uint64_t k = 0; k < 8; ++k) {
    std::mt19937_64 rng(seed * 7919ull + k);
    const int axes = k % 2 == 0 ? 3 : 5;
    MachineConfig m = random_machine(rng, axes);
    m.interpolators[0].buffer_size = 1000;
    test::Generated g = k < 5 ? chord_program(rng, axes) : random_program(rng, axes, 60);
    // Intercode names a parameter set for every M record (the builder leaves them unset).
    for (Segment& r : g.program.segments) {
      if (r.type != SegmentType::kMFunction || r.aux >= 0) continue;
      r.aux = static_cast<std::int32_t>(g.program.params.size());
      g.program.params.push_back(unset_params());
    }
    PackedProgram packed;
    std::string err;
    ASSERT_TRUE(PackedProgram::from_program(g.program, packed, err)) << err;
    SimulationOptions o;
    o.m_ack_s = 0.0123;
    o.rel_speed_changes = g.overrides;
    if (k >= 5) o.stops.emplace_back(1.0, k % 2 == 0 ? 8 : 4);
    o.stop_restart_s = 0.05;
    const bool stepped = k % 3 == 0;
    const std::string ctx = "seed " + std::to_string(seed) + " program " + std::to_string(k) +
                            (stepped ? " stepped" : " fast-forwarded");
    std::array<SimulationSummary, 2> s;
    std::array<std::vector<BlockReport>, 2> blocks;
    // Each cycle's position, status and part; every 64th cycle's registers whole (all of them
    // held 100,000s of copies of the LookAheadBuffer).
    struct Cycle {
      std::array<double, kMaxAxes> orig;
      std::int32_t status, part;
      bool operator==(const Cycle&) const = default;
    };
    std::array<std::vector<Cycle>, 2> cycles;
    std::array<std::vector<Registers>, 2> whole;
    for (std::size_t mode = 0; mode < 2; ++mode) {
      auto sim = Simulation::create(m, o);
      ASSERT_TRUE(sim.has_value()) << ctx;
      const auto on_block = [&](const BlockReport& r) { blocks[mode].push_back(r); };
      std::function<void(const Registers&)> on_cycle;
      if (stepped) {
        on_cycle = [&](const Registers& r) {
          if (cycles[mode].size() % 64 == 0) whole[mode].push_back(r);
          cycles[mode].push_back({r.orig_position, r.status, r.act_part});
        };
      }
      s[mode] = mode == 0 ? sim->run(g.program, on_cycle, on_block)
                          : sim->run(packed, on_cycle, on_block);
    }
    ASSERT_EQ(s[0].result, StepResult::kFinished) << ctx << ": " << s[0].error;
    expect_same_summary(s[0], s[1], ctx);
    EXPECT_GT(g.program.segments.size(), 60u) << ctx;
    ASSERT_EQ(blocks[1].size(), blocks[0].size()) << ctx;
    for (std::size_t i = 0; i < blocks[0].size(); ++i)
      ASSERT_TRUE(same_block(blocks[0][i], blocks[1][i])) << ctx << " block " << i;
    ASSERT_EQ(cycles[1].size(), cycles[0].size()) << ctx;
    for (std::size_t i = 0; i < cycles[0].size(); ++i)
      ASSERT_TRUE(cycles[0][i] == cycles[1][i]) << ctx << " cycle " << i;
    ASSERT_EQ(whole[1].size(), whole[0].size()) << ctx;
    for (std::size_t i = 0; i < whole[0].size(); ++i) {
      test::expect_same_registers(whole[0][i], whole[1][i],
                                  ctx + " cycle " + std::to_string(64 * i));
      if (::testing::Test::HasFailure()) return;
    }
    if (stepped) {
      EXPECT_EQ(cycles[0].size(), s[0].cycles) << ctx;
    }
  }
}

// A program that ends inside start() (only M2, a move of no length before it, or an M0 pause
// whose restart runs into the end) is finished after the first cycle. The fast-forward took the
// ended interpolator for a standing one and skipped to the time limit: `tgm-hmi simulate` said
// "finished" after 500 s of program time for a file holding only M30.
TEST(Advance, AProgramThatEndsAtItsStartTakesOneCycle) {
  const MachineConfig m = MachineConfig::default_machine();
  const MParams none{};
  std::vector<std::pair<std::string, Program>> programs;
  programs.emplace_back("only the end", test::ProgramBuilder().end().program());
  programs.emplace_back("a line of no length",
                        test::ProgramBuilder().line({0.0, 0.0, 0.0}, 100.0).end().program());
  programs.emplace_back("a dwell of 0 s", test::ProgramBuilder().dwell(0.0).end().program());
  programs.emplace_back("an M0 pause",
                        test::ProgramBuilder().m(0, MKind::kProgramStop, &none).end().program());
  for (const auto& [what, program] : programs) {
    SimulationOptions o;
    const auto s = run_stepped_and_fast(m, o, program);
    ASSERT_EQ(s[0].result, StepResult::kFinished) << what << ": " << s[0].error;
    EXPECT_EQ(s[1].result, StepResult::kFinished) << what << ": " << s[1].error;
    EXPECT_LE(s[0].cycles, 2u) << what;
    EXPECT_EQ(s[0].cycles, s[1].cycles) << what;
    EXPECT_FALSE(s[1].time_limit_reached) << what;
  }
  // advance() itself: an ended interpolator takes one cycle per call, as step() does.
  auto ip = Interpolator::create(m, 0);
  ASSERT_TRUE(ip);
  ASSERT_TRUE(ip->load(programs[0].second).ok());
  ASSERT_TRUE(ip->start().ok());
  std::uint64_t done = 0;
  EXPECT_EQ(ip->advance(1000, &done), StepResult::kFinished);
  EXPECT_EQ(done, 1u);
}

// A stop given while the motion already stands after an earlier one cancels the pending restart
// and is restarted after its own wait. The fast-forward skipped such a standstill to the next
// stop or to the time limit, as it knew of no restart to stop at (sweep seed 1 program 50).
TEST(Advance, AStopGivenWhileStandingIsRestartedAsWhenStepping) {
  const MachineConfig m = MachineConfig::default_machine();
  test::ProgramBuilder b;
  b.line({200.0, 0.0, 0.0}, 3000.0).end();
  for (const std::int32_t code : {4, 8}) {
    SimulationOptions o;
    // The first stop brakes from the start, the second comes while standing, the third during
    // the motion after the restart.
    o.stops = {{0.05, code}, {0.2, code}, {1.0, code}};
    o.stop_restart_s = 0.3;
    o.max_time_s = 60.0;
    const auto s = run_stepped_and_fast(m, o, b.program());
    const std::string ctx = "Command " + std::to_string(code);
    ASSERT_EQ(s[0].result, StepResult::kFinished) << ctx << ": " << s[0].error;
    EXPECT_EQ(s[1].result, StepResult::kFinished) << ctx << ": " << s[1].error;
    EXPECT_EQ(s[0].stops, 3u) << ctx;
    EXPECT_EQ(s[1].stops, 3u) << ctx;
    EXPECT_EQ(s[0].cycles, s[1].cycles) << ctx;
    EXPECT_EQ(s[0].end_position, s[1].end_position) << ctx;
  }
}

// Standing on the path after a stop on the trajectory (Command 4 or 8), advance() skips the
// standing cycles with the registers of stepping them: Speed 0. It fed the smoothing the position
// of the last cruise it had skipped as the second to last step's, and Speed showed the distance
// from there to the stop point over one calculation step (found by RandomRequests, seed 1 case 1).
TEST(Advance, StandingOnThePathAfterAStopEqualsStepping) {
  const MachineConfig m = MachineConfig::default_machine();
  test::ProgramBuilder b;
  b.line({200.0, 50.0, 0.0}, 3000.0).end();
  for (const std::int32_t code : {4, 8}) {
    const std::string ctx = "Command " + std::to_string(code);
    auto ip = Interpolator::create(m, 0);
    ASSERT_TRUE(ip);
    ASSERT_TRUE(ip->load(b.program()).ok());
    ASSERT_TRUE(ip->start().ok());
    // Into the cruise, skipped in pieces of 50 cycles.
    std::uint64_t skipped = 0;
    for (int c = 0; c < 2000 && skipped < 200; ++c) {
      std::uint64_t done = 0;
      ip->advance(50, &done);
      if (done > 1) skipped += done;
    }
    ASSERT_GE(skipped, 200u) << ctx << ": the cruise was not skipped";
    ASSERT_TRUE(ip->command(code).ok()) << ctx;
    for (int c = 0; c < 20000 && ip->registers().act_speed != 0.0; ++c) ip->step();
    for (int c = 0; c < 100; ++c) ip->step();  // the smoothing comes to rest
    ASSERT_EQ(ip->registers().act_speed, 0.0) << ctx;
    auto stepped = Interpolator::create(m, 0);
    ASSERT_TRUE(stepped);
    stepped->copy_state_from(*ip);
    std::uint64_t done = 0;
    ip->advance(300, &done);
    ASSERT_GT(done, 1u) << ctx << ": the standing cycles were not skipped";
    for (std::uint64_t c = 0; c < done; ++c) stepped->step();
    test::expect_same_registers(ip->registers(), stepped->registers(), ctx);
    EXPECT_EQ(ip->registers().speed[0], 0.0) << ctx;
  }
}

// The limit check of a fast-forwarded run (the checker fed from the interpolator's cycle
// trace) equals that of a stepped run: the same peaks and the same violations, bit for bit. Every
// second run holds the motion to 80 % of each limit, so that the checker has excesses to report;
// the M-functions take 0.3 s, so that standing runs are traced too.
TEST(Advance, LimitCheckOfFastForwardEqualsStepping) {
  const std::uint64_t first = test::env_u64("TGM_SEED", 1);
  std::uint64_t violations = 0, corner_steps = 0;
  for (std::uint64_t k = 0; k < 16; ++k) {
    std::mt19937_64 rng(first * 92821ull + k);
    const int axes = k % 2 == 0 ? 3 : 1 + static_cast<int>(k % 10);
    const MachineConfig m = random_machine(rng, axes);
    const test::Generated g = random_program(rng, axes, 16);
    SimulationOptions o;
    o.m_ack_s = 0.3;
    o.rel_speed_changes = g.overrides;
    o.check_limits = true;
    o.limit_share = k % 2 == 1 ? 0.8 : 1.0;
    const auto s = run_stepped_and_fast(m, o, g.program);
    const std::string ctx = "seed " + std::to_string(first) + " program " + std::to_string(k);
    ASSERT_EQ(s[0].result, StepResult::kFinished) << ctx << ": " << s[0].error;
    EXPECT_EQ(s[0].cycles, s[1].cycles) << ctx;
    if (k % 2 == 0) {
      EXPECT_EQ(s[0].violation_count, 0u) << ctx;
    }
    violations += s[0].violation_count;
    for (const LimitViolation& v : s[0].violations) {
      corner_steps += v.quantity == LimitQuantity::kCornerStep;
    }
    EXPECT_EQ(s[0].violation_count, s[1].violation_count) << ctx;
    ASSERT_NO_FATAL_FAILURE(test::expect_same_findings(s[0].violations, s[1].violations, s[0].peaks,
                                                       s[1].peaks, axes, ctx));
  }
  // At 80 % of the limits the random programs exceed some: the lists compared were not empty.
  EXPECT_GT(violations, 0u);
  EXPECT_GT(corner_steps, 0u);  // (reported in the cycle of their corner event)
  RecordProperty("violations_compared", std::to_string(violations));
  RecordProperty("corner_steps_compared", std::to_string(corner_steps));
}

// A stop given at a program time: the motion brakes on the line, stands until the emulated
// operator restarts it, and ends at the programmed end; the run takes the restart time and the
// braking and acceleration longer. Stops that are not on the trajectory, or at times or with
// restart times out of range, are refused when the simulation is made, with the reason.
TEST(Simulation, StopsAreGivenAtTheirTimesAndBadOnesRefused) {
  const MachineConfig m = MachineConfig::default_machine();
  test::ProgramBuilder b;
  b.line({100.0, 0.0, 0.0}, 6000.0).end();
  SimulationOptions o;
  auto plain = Simulation::create(m, o);
  ASSERT_TRUE(plain);
  const auto s0 = plain->run(b.program());
  ASSERT_EQ(s0.result, StepResult::kFinished);
  for (const std::int32_t code : {8, 4}) {
    SimulationOptions os;
    os.stops = {{0.5, code}};
    os.stop_restart_s = 0.2;
    std::vector<std::int32_t> statuses;
    auto sim = Simulation::create(m, os);
    ASSERT_TRUE(sim);
    const auto s = sim->run(b.program(), [&](const Registers& r) {
      if (statuses.empty() || statuses.back() != r.status) statuses.push_back(r.status);
    });
    ASSERT_EQ(s.result, StepResult::kFinished) << s.error;
    EXPECT_EQ(s.stops, 1u);
    EXPECT_EQ(s.end_position[0], 100.0);
    EXPECT_GT(s.program_time_s, s0.program_time_s + 0.2);
    const std::vector<std::int32_t> expected = code == 8 ? std::vector<std::int32_t>{1, 4, 1, 3}
                                                         : std::vector<std::int32_t>{1, 6, 7, 1, 3};
    EXPECT_EQ(statuses, expected) << "Command " << code;
  }
  // A stop after the end does nothing.
  SimulationOptions late;
  late.stops = {{s0.program_time_s + 1.0, 8}};
  auto after = Simulation::create(m, late);
  ASSERT_TRUE(after);
  const auto s1 = after->run(b.program());
  EXPECT_EQ(s1.stops, 0u);
  EXPECT_EQ(s1.program_time_s, s0.program_time_s);
  auto refused = [&](const SimulationOptions& bad, const std::string& part) {
    std::string error;
    EXPECT_FALSE(Simulation::create(m, bad, &error));
    EXPECT_NE(error.find(part), std::string::npos) << error;
  };
  for (const std::int32_t code : {5, 9, 1, 0}) {
    SimulationOptions bad;
    bad.stops = {{1.0, code}};
    refused(bad, "Command " + std::to_string(code) + " is not a stop on the trajectory");
  }
  SimulationOptions early;
  early.stops = {{-0.1, 8}};
  refused(early, "stop time");
  SimulationOptions nan_time;
  nan_time.stops = {{std::nan(""), 4}};
  refused(nan_time, "stop time");
  SimulationOptions restart;
  restart.stop_restart_s = -1.0;
  refused(restart, "stop_restart_s");
  // The other options Simulation::create checks (no test gave them before session 44).
  SimulationOptions fast;
  fast.rel_speed = 2.5;
  refused(fast, "rel speed: ");
  for (const double t : {0.0, -1.0, 2e9, std::nan("")}) {
    SimulationOptions limit;
    limit.max_time_s = t;
    refused(limit, "max_time_s must be > 0 and at most 1e9 s");
  }
  // An empty program is an error, not a run of no cycles.
  auto empty = Simulation::create(m, {});
  ASSERT_TRUE(empty);
  const auto s2 = empty->run(Program{});
  EXPECT_EQ(s2.result, StepResult::kErrorInternal);
  EXPECT_EQ(s2.error, "empty program");
}

// The progress hook: called while the run goes on with cycles, program time and Act_Part
// growing, both when stepping and when advancing; returning false ends the run right there.
TEST(Simulation, ProgressIsReportedAndCanEndTheRun) {
  std::mt19937_64 rng(11);
  const MachineConfig m = random_machine(rng, 3);
  const test::Generated g = random_program(rng, 3, 16);
  for (const bool fast : {false, true}) {
    SimulationOptions o;
    o.fast_forward = fast;
    std::vector<SimulationProgress> seen;
    o.on_progress = [&](const SimulationProgress& p) {
      seen.push_back(p);
      return true;
    };
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    const SimulationSummary whole = sim->run(g.program);
    ASSERT_EQ(whole.result, StepResult::kFinished) << whole.error;
    ASSERT_GE(seen.size(), 2u) << "fast_forward " << fast;
    for (std::size_t i = 1; i < seen.size(); ++i) {
      EXPECT_GT(seen[i].cycles, seen[i - 1].cycles);
      EXPECT_GE(seen[i].act_part, seen[i - 1].act_part);
      EXPECT_DOUBLE_EQ(seen[i].program_time_s,
                       static_cast<double>(seen[i].cycles) * m.cycle_time_us * 1e-6);
      EXPECT_EQ(seen[i].records, g.program.segments.size());
    }
    EXPECT_LT(seen.back().cycles, whole.cycles);

    // Ended at the second report: the summary is where the run was then.
    int calls = 0;
    o.on_progress = [&](const SimulationProgress&) { return ++calls < 2; };
    auto cut = Simulation::create(m, o);
    ASSERT_TRUE(cut);
    const SimulationSummary part = cut->run(g.program);
    EXPECT_EQ(calls, 2);
    EXPECT_EQ(part.result, StepResult::kWorking);
    EXPECT_EQ(part.error, "interrupted");
    EXPECT_EQ(part.cycles, seen[1].cycles);
  }
}

}  // namespace
}  // namespace tgm
