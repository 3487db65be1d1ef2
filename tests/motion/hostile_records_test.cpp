// Records as a DDS client that bypasses the compiler could send them (the wire mapping only
// checks enums and finiteness): zero, negative, tiny and huge feeds, coordinates up to 1e300,
// arcs around their own start point, absurd turn counts and dwells, M records with missing
// kinds and side-table indexes out of range. Every program is either refused with a reason
// (nothing appended) or runs without NaN, internal error or crash; a seeded sweep.
#include <gtest/gtest.h>

#include <array>
#include <climits>
#include <cmath>
#include <random>
#include <string>

#include "tgm/interpolator.hpp"

namespace tgm {
namespace {

template <typename T, std::size_t N>
T pick(std::mt19937_64& rng, const std::array<T, N>& values) {
  return values[std::uniform_int_distribution<std::size_t>(0, N - 1)(rng)];
}

// Mostly ordinary, one time in `odds` drawn from the hostile values.
bool hostile(std::mt19937_64& rng, int odds) { return std::uniform_int_distribution<int>(1, odds)(rng) == 1; }

double coordinate(std::mt19937_64& rng) {
  static constexpr std::array<double, 12> kValues = {0.0,  1e-12, -1e-300, 1e6,   -1e6, 1e9,
                                                     -1e9, 1.1e9, 1e15,    -1e15, 1e300, -1e300};
  return hostile(rng, 12) ? pick(rng, kValues) : std::normal_distribution<double>(0.0, 20.0)(rng);
}

Program hostile_program(std::mt19937_64& rng) {
  Program p;
  p.number_axes = 3;
  p.axis_letters = "XYZ";
  const int params = std::uniform_int_distribution<int>(0, 2)(rng);
  for (int k = 0; k < params; ++k) p.params.push_back(unset_params());
  if (std::uniform_int_distribution<int>(0, 1)(rng) == 1) p.messages.push_back("hostile");
  const int count = std::uniform_int_distribution<int>(1, 12)(rng);
  std::array<double, kMaxAxes> at{};
  for (int i = 0; i < count; ++i) {
    Segment s;
    s.line = i + 1;
    s.type = static_cast<SegmentType>(std::uniform_int_distribution<int>(0, hostile(rng, 20) ? 7 : 6)(rng));
    s.plane = static_cast<Plane>(hostile(rng, 10) ? pick(rng, std::array<int, 2>{0, 200})
                                                  : pick(rng, std::array<int, 3>{17, 18, 19}));
    s.compensation = static_cast<Compensation>(pick(rng, std::array<int, 4>{40, 41, 42, 7}));
    s.m_kind = static_cast<MKind>(std::uniform_int_distribution<int>(hostile(rng, 10) ? 0 : 1, hostile(rng, 10) ? 6 : 4)(rng));
    s.m = pick(rng, std::array<std::int32_t, 7>{-5, 0, 3, 51, 999, 1001, INT_MAX});
    s.turns = hostile(rng, 6) ? pick(rng, std::array<std::int32_t, 3>{-1, 1000, INT_MAX})
                              : pick(rng, std::array<std::int32_t, 3>{0, 0, 1});
    s.aux = hostile(rng, 6) ? pick(rng, std::array<std::int32_t, 3>{-1, 5, INT_MIN}) : 0;
    s.tool = hostile(rng, 40) ? pick(rng, std::array<std::int32_t, 3>{-7, kMaxTool + 1, INT_MIN})
                              : pick(rng, std::array<std::int32_t, 3>{0, 1, kMaxTool});
    // Near the previous end mostly (ordinary moves), anywhere sometimes.
    for (int a = 0; a < 3; ++a) {
      const auto ua = static_cast<std::size_t>(a);
      s.end[ua] = hostile(rng, 4) ? coordinate(rng) : at[ua] + std::normal_distribution<double>(0.0, 5.0)(rng);
    }
    at = s.end;
    s.center = {coordinate(rng), coordinate(rng)};
    if (hostile(rng, 4)) s.center = {s.end[0], s.end[1]};  // around the end point: radius 0 there
    s.radius = coordinate(rng);
    s.feed_mm_per_min = hostile(rng, 8) ? pick(rng, std::array<double, 6>{-1.0, 0.0, 1e-300, 1e-3, 1e9, 1e300})
                                        : pick(rng, std::array<double, 4>{1.0, 1000.0, 6000.0, 1e6});
    s.dwell_s = hostile(rng, 8) ? pick(rng, std::array<double, 5>{-1.0, 1e-9, 1e6, 2e6, 1e300})
                                : pick(rng, std::array<double, 3>{0.0, 0.01, 0.25});
    s.compensation_radius_mm = coordinate(rng);
    p.segments.push_back(s);
  }
  return p;
}

TEST(HostileRecords, AreRefusedWithAReasonOrRunWithoutNaN) {
  MachineConfig m = MachineConfig::default_machine();
  m.interpolators[0].buffer_size = 1000;
  int refused = 0, ran = 0, finished = 0;
  for (std::uint64_t k = 0; k < 2000; ++k) {
    std::mt19937_64 rng(977 * k + 5);
    const Program p = hostile_program(rng);
    const std::string ctx = "program " + std::to_string(k);
    auto ip = Interpolator::create(m, 0);
    ASSERT_TRUE(ip) << ctx;
    std::size_t took = 0;
    const RequestResult a = ip->append(p, 0, p.segments.size(), true, &took);
    if (!a.ok()) {
      ++refused;
      EXPECT_FALSE(a.reason.empty()) << ctx;
      EXPECT_EQ(took, 0u) << ctx << ": " << a.reason;
      EXPECT_EQ(ip->free_slots(), 1000u) << ctx << ": a refused program left records behind";
      continue;
    }
    ++ran;
    if (!ip->start().ok()) continue;
    // A few hundred thousand cycles at most: a 1e9 mm move at F1 never ends, which is fine.
    for (int call = 0; call < 2000; ++call) {
      std::uint64_t done = 0;
      const StepResult r = ip->advance(1000, &done);
      ASSERT_NE(r, StepResult::kErrorInternal) << ctx << " call " << call;
      const Registers& reg = ip->registers();
      for (int i = 0; i < 3; ++i) {
        ASSERT_TRUE(std::isfinite(reg.orig_position[static_cast<std::size_t>(i)])) << ctx;
        ASSERT_TRUE(std::isfinite(reg.position[static_cast<std::size_t>(i)])) << ctx;
      }
      ASSERT_TRUE(std::isfinite(reg.act_speed)) << ctx;
      ASSERT_TRUE(std::isfinite(reg.move_distance)) << ctx;
      if (r == StepResult::kFinished) {
        ++finished;
        break;
      }
      if (reg.m_func != 0) ip->write_m_func(0);
      if (r == StepResult::kWaiting && reg.status == 4) ip->start();  // M0
      if (r == StepResult::kIdle) break;
    }
  }
  // Both branches were exercised (the generator is not all-refused or all-accepted).
  EXPECT_GT(refused, 200);
  EXPECT_GT(ran, 200);
  EXPECT_GT(finished, 100);
  std::printf("%d refused, %d ran (%d to their end)\n", refused, ran, finished);
}

}  // namespace
}  // namespace tgm
