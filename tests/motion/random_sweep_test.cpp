// Seeded random sweeps: random programs of lines, arcs, helices, short-segment polylines,
// M-functions, dwells and override changes must finish at the programmed end point, never give
// NaN, and the limit checker must find no excess on Orig_Position differentiated per cycle.
//
// TGM_SEED (default 1), TGM_SWEEP_COUNT (default 200) and TGM_SWEEP_FIRST (default 0) choose the
// sweep; a long run:
//   TGM_SEED=7 TGM_SWEEP_COUNT=5000 build/tests/motion/tgm_motion_tests --gtest_filter='RandomSweep.*'
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

TEST(RandomSweep, ProgramsFinishAtTheirEndWithinLimits) {
  const std::uint64_t seed = env_u64("TGM_SEED", 1);
  const std::uint64_t count = env_u64("TGM_SWEEP_COUNT", 200);
  const std::uint64_t first = env_u64("TGM_SWEEP_FIRST", 0);  // to rerun one program
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
    o.max_time_s = 3600.0;
    auto sim = Simulation::create(m, o);
    ASSERT_TRUE(sim);
    const auto s = sim->run(g.program);
    total_cycles += s.cycles;
    const std::string ctx = "seed " + std::to_string(seed) + " program " + std::to_string(k) + " axes " +
                            std::to_string(axes) + " cycle " + std::to_string(m.cycle_time_us) + " us";
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
