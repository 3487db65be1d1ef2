// Seeded random sweeps: random programs of lines, arcs, helices, short-segment polylines,
// M-functions, dwells and override changes must finish at the programmed end point, never give
// NaN, and the limit checker must find no excess on Orig_Position differentiated per cycle.
//
// The sweep is chosen on the command line of the test binary (--seed=N --count=N --first=N,
// after the gtest flags) or by TGM_SEED (default 1), TGM_SWEEP_COUNT (default 200) and
// TGM_SWEEP_FIRST (default 0); the command line wins. A long run:
//   build/tests/motion/tgm_motion_tests --gtest_filter='RandomSweep.*' --seed=7 --count=5000
//
// Time limit per program: 4 x the feed-limited lower bound of its motion (every record at
// min(F x Rel_Speed, axis velocity limits) with the override schedule, see
// motion_time_lower_bound) + 60 s for accelerations, corners, arcs, dwells and M waits. A
// program that crawls or stalls below its target hits it; a program that is merely long (an
// override of 0.02 makes some take two hours) does not.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>
#include <string>

#include "random_program.hpp"
#include "tgm/simulation.hpp"

namespace tgm {
namespace {

using test::Generated;
using test::random_machine;
using test::random_program;

std::uint64_t env_u64(const char* name, std::uint64_t fallback) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  return std::strtoull(v, nullptr, 10);
}

// --name=N among the arguments gtest left (it removes its own flags), else TGM_<env>.
std::uint64_t arg_u64(const std::string& name, const char* env, std::uint64_t fallback) {
  const std::string prefix = "--" + name + "=";
  for (const std::string& a : ::testing::internal::GetArgvs()) {
    if (a.rfind(prefix, 0) == 0) return std::strtoull(a.c_str() + prefix.size(), nullptr, 10);
  }
  return env_u64(env, fallback);
}

TEST(RandomSweep, ProgramsFinishAtTheirEndWithinLimits) {
  const std::uint64_t seed = arg_u64("seed", "TGM_SEED", 1);
  const std::uint64_t count = arg_u64("count", "TGM_SWEEP_COUNT", 200);
  const std::uint64_t first = arg_u64("first", "TGM_SWEEP_FIRST", 0);  // to rerun one program
  std::uint64_t total_cycles = 0;
  for (std::uint64_t k = first; k < first + count; ++k) {
    std::mt19937_64 rng(seed * 1000003ull + k);
    std::uniform_int_distribution<int> axes_d(1, 10);
    const int axes = k % 5 == 0 ? 3 : axes_d(rng);
    const MachineConfig m = random_machine(rng, axes);
    Generated g = random_program(rng, axes, 12);
    SimulationOptions o;
    o.check_limits = true;
    o.m_ack_s = 0.01;
    o.rel_speed_changes = g.overrides;
    const double bound_s = test::motion_time_lower_bound(g.program, m, g.overrides);
    o.max_time_s = 4.0 * bound_s + 60.0;
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    const auto s = sim->run(g.program);
    total_cycles += s.cycles;
    const std::string ctx = "seed " + std::to_string(seed) + " program " + std::to_string(k) + " axes " +
                            std::to_string(axes) + " cycle " + std::to_string(m.cycle_time_us) + " us, lower bound " +
                            std::to_string(bound_s) + " s";
    ASSERT_EQ(s.result, StepResult::kFinished) << ctx << ": " << s.error;
    EXPECT_FALSE(s.nan) << ctx;
    EXPECT_EQ(s.hard_stops, 0u) << ctx;
    for (int i = 0; i < axes; ++i) {
      EXPECT_NEAR(s.end_position[static_cast<std::size_t>(i)], g.end[static_cast<std::size_t>(i)], 1e-9)
          << ctx << " axis " << i;
    }
    EXPECT_EQ(s.violation_count, 0u) << ctx;
    if (!s.violations.empty()) {
      const auto& v = s.violations.front();
      ADD_FAILURE() << ctx << ": first violation cycle " << v.cycle << " line " << v.line << " axis "
                    << v.axis << " " << limit_quantity_name(v.quantity) << " " << v.value << " > "
                    << v.limit;
    }
    if (::testing::Test::HasFailure()) break;
  }
  RecordProperty("cycles", std::to_string(total_cycles));
}

}  // namespace
}  // namespace tgm
