// Program time by record (tgm/program_times.hpp), what `tgm-hmi run` shows the time left by.
// Known values on G-code (a move alone, an M-function's acknowledgement time, a dwell), and a
// seeded sweep (--times-seed=N, --times-count=N) of random programs against the registers of
// the same run stepped cycle by cycle: record k is done within the cycle in which Act_Part
// first moves past it.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "../support/test_params.hpp"
#include "packed_gcode.hpp"
#include "random_program.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/program_times.hpp"
#include "tgm/simulation.hpp"

namespace tgm {
namespace {

using test::packed;

double run_time(const MachineConfig& m, const SimulationOptions& o, const PackedProgram& p) {
  auto sim = Simulation::create(m, o);
  EXPECT_TRUE(sim);
  if (!sim) return -1.0;
  const SimulationSummary s = sim->run(p);
  EXPECT_EQ(s.result, StepResult::kFinished) << s.error;
  return s.program_time_s;
}

TEST(ProgramTimes, AMoveAnAcknowledgementAndADwellTakeTheirOwnTimes) {
  const MachineConfig m = MachineConfig::default_machine();
  const double T = m.cycle_time_us * 1e-6;
  SimulationOptions o;
  o.m_ack_s = 0.5;
  // Records: the move, M3 (normal: waits for the PLC), the dwell, the same move again.
  const PackedProgram p = packed("G90\nG1 X10 F600\nM3\nG4 P1.5\nG1 X20\nM2\n");
  std::string error;
  const auto t = program_times(m, o, p, &error);
  ASSERT_TRUE(t) << error;
  ASSERT_EQ(t->done_s.size(), p.size());
  ASSERT_GE(p.size(), 4u);
  // The move alone, as its own program: 10 mm at 10 mm/s plus the ramps.
  const double move = run_time(m, o, packed("G90\nG1 X10 F600\nM2\n"));
  EXPECT_GT(move, 1.0);
  EXPECT_LT(move, 1.2);
  EXPECT_NEAR(t->done_s[0], move, T);
  EXPECT_NEAR(t->done_s[1] - t->done_s[0], 0.5, 2 * T);
  EXPECT_NEAR(t->done_s[2] - t->done_s[1], 1.5, 2 * T);
  EXPECT_NEAR(t->done_s[3] - t->done_s[2], move, 2 * T);
  EXPECT_EQ(t->done_s.back(), static_cast<float>(t->total_s));
  EXPECT_EQ(t->total_s, run_time(m, o, p));
  EXPECT_NEAR(t->total_s, 2 * move + 2.0, 4 * T);

  // Elapsed: nothing before the first record, what the first took once the second runs, at
  // most a record's own time within it, everything past the end.
  EXPECT_EQ(t->elapsed_s(0, 5.0), 0.0);
  EXPECT_EQ(t->elapsed_s(1, 0.25), 0.25);
  EXPECT_EQ(t->elapsed_s(1, 60.0), static_cast<double>(t->done_s[0]));
  EXPECT_EQ(t->elapsed_s(2, 0.0), static_cast<double>(t->done_s[0]));
  EXPECT_EQ(t->elapsed_s(2, 0.1), static_cast<double>(t->done_s[0]) + 0.1);
  EXPECT_EQ(t->elapsed_s(3, -1.0), static_cast<double>(t->done_s[1]));
  EXPECT_EQ(t->elapsed_s(3, std::nan("")), static_cast<double>(t->done_s[1]));
  EXPECT_EQ(t->elapsed_s(static_cast<std::int64_t>(p.size()) + 1, 0.0), t->total_s);
  // Inside a move by the share of its length (10 mm; the M-function and the dwell have none).
  EXPECT_EQ(t->length_mm[0], 10.0F);
  EXPECT_EQ(t->length_mm[1], 0.0F);
  EXPECT_EQ(t->length_mm[2], 0.0F);
  EXPECT_EQ(t->length_mm[3], 10.0F);
  EXPECT_DOUBLE_EQ(t->elapsed_s(1, 0.1, 2.5), 0.25 * t->done_s[0]);
  EXPECT_EQ(t->elapsed_s(1, 0.1, 25.0), static_cast<double>(t->done_s[0]));
  EXPECT_DOUBLE_EQ(t->elapsed_s(4, 0.0, 5.0),
                   t->done_s[2] + 0.5 * (static_cast<double>(t->done_s[3]) - t->done_s[2]));
  EXPECT_EQ(t->elapsed_s(1, 0.1, -1.0), 0.1);
  EXPECT_EQ(t->elapsed_s(1, 0.1, std::nan("")), 0.1);
  EXPECT_EQ(t->elapsed_s(3, 0.5, 3.0), static_cast<double>(t->done_s[1]) + 0.5);

  // Half the override: the moves take about twice as long, the waits the same.
  SimulationOptions slow = o;
  slow.rel_speed = 0.5;
  const auto h = program_times(m, slow, p, &error);
  ASSERT_TRUE(h) << error;
  EXPECT_NEAR(h->done_s[0], 2.0, 0.1);
  EXPECT_NEAR(h->done_s[1] - h->done_s[0], 0.5, 2 * T);

  // The waits: the acknowledgement (0.5 s) and the dwell (1.5 s), summed record by record.
  ASSERT_EQ(t->wait_s.size(), p.size());
  EXPECT_EQ(t->wait_s[0], 0.0F);
  EXPECT_NEAR(t->wait_s[1], 0.5, 2 * T);
  EXPECT_NEAR(t->wait_s[2], 2.0, 3 * T);
  EXPECT_EQ(t->wait_s[3], t->wait_s[2]);
  // Left at the Rel_Speed simulated: the rest of the total.
  for (const auto& [part, in_s, in_mm] :
       {std::tuple{1, 0.0, 0.0}, std::tuple{1, 0.3, 2.5}, std::tuple{2, 0.2, -1.0},
        std::tuple{3, 1.0, -1.0}, std::tuple{4, 0.1, 5.0}, std::tuple{9, 0.0, -1.0}}) {
    EXPECT_NEAR(t->left_s(part, in_s, in_mm, 1.0), t->total_s - t->elapsed_s(part, in_s, in_mm),
                1e-6)
        << part;
  }
  // At twice the time for the moves: the moves' part doubles, the waits' not. Half-way
  // through the dwell: the second move (twice) and the dwell's other half.
  const double move2 = static_cast<double>(t->done_s[3]) - t->done_s[2];
  EXPECT_NEAR(t->left_s(3, 0.75, -1.0, 2.0), 2.0 * move2 + 0.75 + (t->total_s - t->done_s[3]) * 2.0,
              1e-5);
  EXPECT_NEAR(t->left_s(1, 0.0, 0.0, 2.0), 2.0 * (t->total_s - t->wait_s.back()) + t->wait_s.back(),
              1e-5);
  EXPECT_EQ(t->left_s(9, 0.0, -1.0, 2.0), 0.0);
  // Times without the waits by record: all of it scales.
  ProgramTimes bare = *t;
  bare.wait_s.clear();
  EXPECT_NEAR(bare.left_s(1, 0.0, 0.0, 2.0), 2.0 * t->total_s, 1e-6);
  // Against the run at half the override (an independent oracle): within the ramps' share,
  // where scaling the waits with the moves missed by their whole time.
  const double left = t->left_s(1, 0.0, 0.0, 2.0);
  EXPECT_NEAR(left, h->total_s, 0.1 * h->total_s);
  EXPECT_LT(std::fabs(left - h->total_s), std::fabs(2.0 * t->total_s - h->total_s) - 1.5);
}

TEST(ProgramTimes, ARunThatDoesNotEndGivesNoTimesAndSaysWhy) {
  const MachineConfig m = MachineConfig::default_machine();
  SimulationOptions o;
  o.max_time_s = 0.5;
  std::string error;
  EXPECT_FALSE(program_times(m, o, packed("G90\nG1 X100 F600\nM2\n"), &error));
  EXPECT_FALSE(error.empty());
  // Interrupted by its caller.
  SimulationOptions stop;
  stop.fast_forward = false;  // a pass a cycle: 100 s of program time make 200,000
  stop.on_progress = [](const SimulationProgress&) { return false; };
  error.clear();
  EXPECT_FALSE(program_times(m, stop, packed("G90\nG1 X1000 F600\nM2\n"), &error));
  EXPECT_NE(error.find("interrupted"), std::string::npos) << error;
}

// Random programs (the sweeps' generator: lines, arcs, helices, M-functions, dwells, override
// changes) on random machines: each record is done within the cycle in which the stepped
// run's Act_Part first shows a later record (or the run ends), and the total is the run's.
TEST(ProgramTimesSweep, EachRecordIsDoneWhereTheRegistersLeaveIt) {
  const std::uint64_t seed = test::param_u64("times-seed", "TGM_TIMES_SEED", 1);
  const std::uint64_t count = test::param_u64("times-count", "TGM_TIMES_COUNT", 30);
  for (std::uint64_t k = 0; k < count; ++k) {
    std::mt19937_64 rng(seed * 104729u + k);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const test::RandomCase c = test::random_case(rng, 16);
    const MachineConfig& m = c.machine;
    const test::Generated& g = c.generated;
    const std::string ctx = "times seed " + std::to_string(seed) + " program " + std::to_string(k);
    PackedProgram p;
    std::string error;
    ASSERT_TRUE(PackedProgram::from_program(g.program, p, error)) << ctx << ": " << error;
    SimulationOptions o;
    o.start_mm = g.program.start_mm;
    o.m_ack_s = u(rng) * 0.3;
    o.rel_speed_changes = g.overrides;
    o.max_time_s = 1e5;
    const auto t = program_times(m, o, p, &error);
    ASSERT_TRUE(t) << ctx << ": " << error;
    ASSERT_EQ(t->done_s.size(), p.size()) << ctx;

    // The same run stepped: the cycle after which Act_Part first shows a record past k.
    const double T = m.cycle_time_us * 1e-6;
    SimulationOptions stepped = o;
    stepped.fast_forward = false;
    auto sim = Simulation::create(m, stepped);
    ASSERT_TRUE(sim) << ctx;
    std::vector<double> left(p.size(), -1.0);
    std::uint64_t cycles = 0, passed = 0;
    const SimulationSummary s = sim->run(p, [&](const Registers& r) {
      ++cycles;
      const auto beyond =
          r.status == 3 ? p.size() : static_cast<std::uint64_t>(std::max(r.act_part, 1)) - 1;
      for (; passed < beyond && passed < p.size(); ++passed)
        left[passed] = static_cast<double>(cycles) * T;
    });
    ASSERT_EQ(s.result, StepResult::kFinished) << ctx << ": " << s.error;
    EXPECT_EQ(t->total_s, s.program_time_s) << ctx;
    // Every move's length: together the run's distance.
    double length = 0.0;
    for (const float l : t->length_mm) length += l;
    EXPECT_NEAR(length, s.distance_mm, 1e-6 + 1e-6 * s.distance_mm) << ctx;
    EXPECT_EQ(t->done_s.back(), static_cast<float>(s.program_time_s)) << ctx;
    for (std::size_t j = 0; j < p.size(); ++j) {
      const double d = t->done_s[j];
      // A float holds the time to 2^-24 of itself.
      const double eps = 1e-7 + std::fabs(d) * 1.2e-7;
      ASSERT_GE(left[j], 0.0) << ctx << " record " << j;
      EXPECT_LE(d, left[j] + eps) << ctx << " record " << j;
      EXPECT_GE(d, left[j] - T - eps) << ctx << " record " << j;
      if (j > 0) {
        EXPECT_GE(d, t->done_s[j - 1]) << ctx << " record " << j;
      }
    }
    // The waits: the time of the records that do not move, never more than the time so far;
    // at the start the time left at twice the moves' time is the moves twice and the waits once.
    double waits = 0.0;
    for (std::size_t j = 0; j < p.size(); ++j) {
      if (!(t->length_mm[j] > 0.0F)) {
        waits += t->done_s[j] - (j == 0 ? 0.0 : static_cast<double>(t->done_s[j - 1]));
      }
      const double eps = 1e-6 + 1e-6 * t->done_s[j];
      EXPECT_NEAR(t->wait_s[j], waits, eps) << ctx << " record " << j;
      EXPECT_LE(t->wait_s[j], t->done_s[j] + eps) << ctx << " record " << j;
      const auto part = static_cast<std::int64_t>(j) + 1;
      EXPECT_NEAR(t->left_s(part, 0.0, 0.0, 1.0), t->total_s - t->elapsed_s(part, 0.0, 0.0), eps)
          << ctx << " record " << j;
      EXPECT_GE(t->left_s(part, 0.0, 0.0, 2.0), t->left_s(part, 0.0, 0.0, 1.0) - eps) << ctx;
    }
    EXPECT_NEAR(t->left_s(1, 0.0, 0.0, 2.0), 2.0 * t->total_s - t->wait_s.back(),
                1e-5 * (1.0 + t->total_s))
        << ctx;
  }
}

}  // namespace
}  // namespace tgm
