// The limit checker on its own: each quantity it differentiates from Orig_Position is reported
// with its cycle, line, axis, size and limit, and nothing else is. The sweeps' "0 violations"
// means something only if a velocity, acceleration or jerk excess on any axis is found, so each
// is fed here as a closed-form series (x = v t, a t^2 / 2, j t^3 / 6) whose finite differences
// are the value itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/limit_checker.hpp"
#include "tgm/registers.hpp"

namespace tgm {
namespace {

// Three axes with round limits: 100 mm/s, 1,000 mm/s^2, 100,000 mm/s^3, corner tolerance
// 1 mm/s, emergency deceleration twice the acceleration; 1 ms cycles.
constexpr int kCycleUs = 1000;
constexpr double kT = 1e-3;

InterpolatorConfig round_axes(int count = 3) {
  InterpolatorConfig ip = MachineConfig::default_machine().interpolators[0];
  const AxisConfig first = ip.axes[0];  // a copy: resize may move the elements
  ip.axes.resize(static_cast<std::size_t>(count), first);
  for (int i = 0; i < count; ++i) {
    AxisConfig& a = ip.axes[static_cast<std::size_t>(i)];
    a.letter = default_axis_letter(i);
    a.max_velocity_mm_s = 100.0;
    a.max_acceleration_mm_s2 = 1000.0;
    a.max_jerk_mm_s3 = 100000.0;
    a.emergency_deceleration_mm_s2 = 2000.0;
    a.corner_velocity_tolerance_mm_s = 1.0;
  }
  return ip;
}

// Feeds cycles first..last with axis `axis` at pos(t), t = (cycle - first) * T, the other
// axes at 0, source line = the cycle number.
template <typename Pos>
void feed(LimitChecker& ch, std::uint64_t first, std::uint64_t last, int axis, Pos pos,
          std::int32_t status = static_cast<std::int32_t>(InterpolatorStatus::kRunning)) {
  for (std::uint64_t c = first; c <= last; ++c) {
    Registers r;
    r.number_axes = 3;
    r.cycle = c;
    r.act_line = static_cast<std::int32_t>(c);
    r.status = status;
    r.orig_position[static_cast<std::size_t>(axis)] = pos(static_cast<double>(c - first) * kT);
    ch.add_cycle(r, {});
  }
}

// Every stored finding is of quantity q on `axis`, of size `value` (relative 1e-6) against
// `limit`, in cycles first..last with their own cycle as line; returns how many there are.
std::size_t expect_only(const LimitChecker& ch, LimitQuantity q, int axis, double value,
                        double limit, std::uint64_t first, std::uint64_t last) {
  for (const LimitViolation& v : ch.violations()) {
    EXPECT_EQ(v.quantity, q) << "cycle " << v.cycle << " " << limit_quantity_name(v.quantity);
    EXPECT_EQ(v.axis, axis) << "cycle " << v.cycle;
    EXPECT_NEAR(v.value, value, 1e-6 * value) << "cycle " << v.cycle;
    EXPECT_DOUBLE_EQ(v.limit, limit) << "cycle " << v.cycle;
    EXPECT_GE(v.cycle, first);
    EXPECT_LE(v.cycle, last);
    EXPECT_EQ(v.line, static_cast<std::int32_t>(v.cycle));
  }
  EXPECT_EQ(ch.violation_count(), ch.violations().size());
  return ch.violations().size();
}

TEST(LimitCheckerQuantities, AVelocityAboveTheLimitIsReportedEveryCycleAndNothingElse) {
  auto ch = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(ch);
  // Axis Y at a constant 110 mm/s from cycle 1 to 20: cycles 2..20 differentiate to 110.
  feed(*ch, 1, 20, 1, [](double t) { return 110.0 * t; });
  EXPECT_EQ(expect_only(*ch, LimitQuantity::kVelocity, 1, 110.0, 100.0, 2, 20), 19u);
  EXPECT_NEAR(ch->peaks()[1].velocity_mm_s, 110.0, 1e-9);
  EXPECT_LT(ch->peaks()[1].acceleration_mm_s2, 1e-6);
  EXPECT_EQ(ch->peaks()[0].velocity_mm_s, 0.0);
  EXPECT_STREQ(limit_quantity_name(ch->violations().front().quantity), "velocity");
  // The same series just under the limit passes.
  auto ok = LimitChecker::create(round_axes(), kCycleUs);
  feed(*ok, 1, 20, 1, [](double t) { return 99.9 * t; });
  EXPECT_EQ(ok->violation_count(), 0u);
}

TEST(LimitCheckerQuantities, AnAccelerationAboveTheLimitIsReportedAndItsJerkIsNot) {
  auto ch = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(ch);
  // Axis Z from rest at a constant 1,100 mm/s^2 for 30 cycles (33 mm/s at the end): cycles
  // 3..30 differentiate twice to 1,100; the third difference of a parabola is 0.
  feed(*ch, 1, 30, 2, [](double t) { return 0.5 * 1100.0 * t * t; });
  EXPECT_EQ(expect_only(*ch, LimitQuantity::kAcceleration, 2, 1100.0, 1000.0, 3, 30), 28u);
  EXPECT_NEAR(ch->peaks()[2].acceleration_mm_s2, 1100.0, 1e-6);
  EXPECT_LT(ch->peaks()[2].jerk_mm_s3, 1.0);
  EXPECT_STREQ(limit_quantity_name(LimitQuantity::kAcceleration), "acceleration");
}

TEST(LimitCheckerQuantities, AJerkAboveTheLimitIsReportedAndItsAccelerationIsNot) {
  auto ch = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(ch);
  // Axis X at a constant jerk of 110,000 mm/s^3 for 8 cycles: 770 mm/s^2 at the end, under
  // the 1,000; cycles 4..8 differentiate three times to 110,000.
  feed(*ch, 1, 8, 0, [](double t) { return 110000.0 * t * t * t / 6.0; });
  EXPECT_EQ(expect_only(*ch, LimitQuantity::kJerk, 0, 110000.0, 100000.0, 4, 8), 5u);
  EXPECT_NEAR(ch->peaks()[0].jerk_mm_s3, 110000.0, 1e-3);
  EXPECT_STREQ(limit_quantity_name(LimitQuantity::kJerk), "jerk");
}

// The emergency ramp (Status 6, and the cycle that reaches Status 7) is judged at the emergency
// deceleration, 2,000 mm/s^2 here, and its jerk at the same ratio; the same motion in Status 1
// is an excess.
TEST(LimitCheckerQuantities, TheEmergencyRampIsJudgedAtTheEmergencyDeceleration) {
  const auto ramp = static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp);
  const auto braking = [](double t) { return 50.0 * t - 0.5 * 1500.0 * t * t; };
  auto em = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(em);
  feed(*em, 1, 20, 0, braking, ramp);
  EXPECT_EQ(em->violation_count(), 0u);
  EXPECT_NEAR(em->peaks()[0].acceleration_mm_s2, 1500.0, 1e-6);
  auto normal = LimitChecker::create(round_axes(), kCycleUs);
  feed(*normal, 1, 20, 0, braking);
  EXPECT_EQ(expect_only(*normal, LimitQuantity::kAcceleration, 0, 1500.0, 1000.0, 3, 20), 18u);
  // Past the emergency deceleration the ramp is reported against it.
  auto hard = LimitChecker::create(round_axes(), kCycleUs);
  feed(
      *hard, 1, 20, 0, [](double t) { return 50.0 * t - 0.5 * 2500.0 * t * t; }, ramp);
  EXPECT_EQ(expect_only(*hard, LimitQuantity::kAcceleration, 0, 2500.0, 2000.0, 3, 20), 18u);
}

// Corner steps that each keep the tolerance but add up: X's velocity steps by 0.9 mm/s (within
// the 1 mm/s) twice a cycle, 1,800 mm/s^2 on average, as short chords of an arc did (review
// of session 82). Between the steps X moves at constant speed, so the per-cycle check, which
// takes the steps out, finds nothing; the velocity change over the 10-cycle window is 18 mm/s
// against 1,000 mm/s^2 x 10 ms plus one tolerance. Steps once every two cycles (450 mm/s^2)
// pass.
TEST(LimitCheckerQuantities, CornerStepsThatAddUpAreAMeanAccelerationExcess) {
  const auto run = [](int steps_per_two_cycles, LimitChecker& ch) {
    std::vector<double> t_step;  // absolute times of the steps; cycle c's sample is at c T
    for (std::uint64_t c = 1; c <= 40; ++c) {
      std::vector<CornerEvent> events;
      if (c >= 2) {
        const std::vector<double> fractions =
            steps_per_two_cycles == 4
                ? std::vector<double>{0.25, 0.75}
                : (c % 2 == 0 ? std::vector<double>{0.5} : std::vector<double>{});
        for (const double f : fractions) {
          CornerEvent e;
          e.cycle = c;
          e.fraction = f;
          e.dv[0] = 0.9;
          events.push_back(e);
          t_step.push_back((static_cast<double>(c) - 1.0 + f) * kT);
        }
      }
      Registers r;
      r.number_axes = 3;
      r.cycle = c;
      r.act_line = static_cast<std::int32_t>(c);
      r.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
      const double now = static_cast<double>(c) * kT;
      for (const double ts : t_step) r.orig_position[0] += 0.9 * (now - ts);
      ch.add_cycle(r, events);
    }
  };
  auto ch = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(ch);
  EXPECT_EQ(ch->window_cycles(), 10);
  run(4, *ch);
  // From cycle 12 on (12 samples make the first window) every cycle: 18 mm/s over 10 ms.
  EXPECT_EQ(expect_only(*ch, LimitQuantity::kMeanAcceleration, 0, 1800.0, 1100.0, 12, 40), 29u);
  EXPECT_STREQ(limit_quantity_name(LimitQuantity::kMeanAcceleration), "mean_acceleration");
  EXPECT_LT(ch->peaks()[0].acceleration_mm_s2, 1e-6);
  auto slow = LimitChecker::create(round_axes(), kCycleUs);
  run(1, *slow);
  EXPECT_EQ(slow->violation_count(), 0u);
}

// The acceleration step a junction's change of curvature makes (CornerEvent::da_curvature) is
// held to corner_acceleration_tolerance_mm_s2, or where that is 0 to sqrt(2 J tol): 447.2
// mm/s^2 on these axes (100,000 mm/s^3, 1 mm/s). The event's da is taken out of the jerk as
// before, so a step alone is no jerk excess; 1.01 x the tolerance is reported with its cycle
// and line, 0.99 x is not, and the share scales the tolerance as it does the limits.
TEST(LimitCheckerQuantities, ACurvatureStepAboveTheCornerAccelerationToleranceIsReported) {
  const auto run = [](LimitChecker& ch, double da) {
    for (std::uint64_t c = 1; c <= 12; ++c) {
      Registers r;
      r.number_axes = 3;
      r.cycle = c;
      r.act_line = static_cast<std::int32_t>(c);
      r.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
      // X at 10 mm/s; from the event (cycle 6, half way) Y accelerates at da.
      const double t = static_cast<double>(c) * kT, t0 = 5.5 * kT;
      r.orig_position[0] = 10.0 * t;
      if (t > t0) r.orig_position[1] = 0.5 * da * (t - t0) * (t - t0);
      CornerEvent e;
      e.cycle = 6;
      e.fraction = 0.5;
      e.da[1] = da;
      e.da_curvature[1] = da;
      ch.add_cycle(r,
                   c == 6 ? std::span<const CornerEvent>(&e, 1) : std::span<const CornerEvent>());
    }
  };
  const double tol_a = std::sqrt(2.0 * 100000.0 * 1.0);
  EXPECT_DOUBLE_EQ(corner_acceleration_tolerance(round_axes().axes[1]), tol_a);
  auto over = LimitChecker::create(round_axes(), kCycleUs);
  auto within = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(over && within);
  run(*over, -1.01 * tol_a);
  run(*within, 0.99 * tol_a);
  EXPECT_EQ(expect_only(*over, LimitQuantity::kCornerAcceleration, 1, 1.01 * tol_a, tol_a, 6, 6),
            1u);
  EXPECT_STREQ(limit_quantity_name(LimitQuantity::kCornerAcceleration), "corner_acceleration");
  EXPECT_EQ(within->violation_count(), 0u);
  EXPECT_NEAR(within->peaks()[1].corner_acceleration_mm_s2, 0.99 * tol_a, 1e-9);
  // A tolerance of its own, and the share.
  InterpolatorConfig ip = round_axes();
  for (AxisConfig& a : ip.axes) a.corner_acceleration_tolerance_mm_s2 = 300.0;
  auto own = LimitChecker::create(ip, kCycleUs);
  auto half = LimitChecker::create(round_axes(), kCycleUs, nullptr, 0.5);
  ASSERT_TRUE(own && half);
  run(*own, 0.99 * tol_a);
  run(*half, 0.99 * tol_a);
  EXPECT_EQ(expect_only(*own, LimitQuantity::kCornerAcceleration, 1, 0.99 * tol_a, 300.0, 6, 6),
            1u);
  EXPECT_EQ(
      expect_only(*half, LimitQuantity::kCornerAcceleration, 1, 0.99 * tol_a, 0.5 * tol_a, 6, 6),
      1u);
}

// A share below 1 scales every limit: 110 mm/s passes at share 1 against 120 and is reported
// at share 0.5 against 60.
TEST(LimitCheckerQuantities, TheShareScalesTheLimits) {
  InterpolatorConfig ip = round_axes();
  for (AxisConfig& a : ip.axes) a.max_velocity_mm_s = 120.0;
  auto full = LimitChecker::create(ip, kCycleUs);
  auto half = LimitChecker::create(ip, kCycleUs, nullptr, 0.5);
  ASSERT_TRUE(full && half);
  EXPECT_DOUBLE_EQ(half->velocity_limit(1), 60.0);
  EXPECT_DOUBLE_EQ(half->acceleration_limit(1), 500.0);
  EXPECT_DOUBLE_EQ(half->jerk_limit(1), 50000.0);
  feed(*full, 1, 10, 1, [](double t) { return 110.0 * t; });
  feed(*half, 1, 10, 1, [](double t) { return 110.0 * t; });
  EXPECT_EQ(full->violation_count(), 0u);
  EXPECT_EQ(expect_only(*half, LimitQuantity::kVelocity, 1, 110.0, 60.0, 2, 10), 9u);
}

// reset() forgets the samples (a new series: no jump across it) but keeps the findings.
TEST(LimitCheckerQuantities, ResetStartsANewSeriesAndKeepsTheFindings) {
  auto ch = LimitChecker::create(round_axes(), kCycleUs);
  ASSERT_TRUE(ch);
  feed(*ch, 1, 5, 0, [](double t) { return 150.0 * t; });  // 4 velocity findings
  ASSERT_EQ(ch->violation_count(), 4u);
  ch->reset();
  feed(*ch, 6, 10, 0, [](double) { return 40.0; });  // 40 mm away from cycle 5: no jump
  EXPECT_EQ(ch->violation_count(), 4u);
  EXPECT_NEAR(ch->peaks()[0].velocity_mm_s, 150.0, 1e-9);
  // Without the reset the same cycles are a jump of 40 mm in one cycle.
  auto cont = LimitChecker::create(round_axes(), kCycleUs);
  feed(*cont, 1, 5, 0, [](double t) { return 150.0 * t; });
  feed(*cont, 6, 10, 0, [](double) { return 40.0; });
  EXPECT_GT(cont->violation_count(), 5u);
}

TEST(LimitCheckerQuantities, CreateRefusesABadShareAxisCountOrCycle) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double share : {0.0, -0.5, 1.5, nan}) {
    std::string error;
    EXPECT_FALSE(LimitChecker::create(round_axes(), kCycleUs, &error, share)) << share;
    EXPECT_EQ(error, "the limit share must be a number in (0, 1]") << share;
  }
  struct Case {
    int axes;
    int cycle_us;
  };
  for (const Case& c : {Case{0, kCycleUs}, Case{11, kCycleUs}, Case{3, 0}, Case{3, -500}}) {
    InterpolatorConfig ip = round_axes(std::clamp(c.axes, 1, 10));
    const AxisConfig first = ip.axes[0];
    ip.axes.resize(static_cast<std::size_t>(c.axes), first);
    std::string error;
    EXPECT_FALSE(LimitChecker::create(ip, c.cycle_us, &error)) << c.axes << " " << c.cycle_us;
    EXPECT_EQ(error, "limit checker needs 1..10 axes and a positive cycle time");
  }
  EXPECT_TRUE(LimitChecker::create(round_axes(10), kCycleUs));
  EXPECT_TRUE(LimitChecker::create(round_axes(1), kCycleUs, nullptr, 1.0));
}

}  // namespace
}  // namespace tgm
