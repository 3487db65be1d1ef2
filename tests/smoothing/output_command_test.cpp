// Output stage (Ratio, Offset, backlash ramp, PositionInc) and the command stage (checks with
// exact reasons, Command_Status sequence, position set, Number_Axes).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>

#include "tgm/command_stage.hpp"

namespace tgm {
namespace {

InterpolatorConfig three_axes(double backlash_mm = 0.0) {
  InterpolatorConfig c;
  for (int i = 0; i < 3; ++i) {
    AxisConfig a;
    a.letter = default_axis_letter(i);
    a.ratio_inc_per_mm = 1000.0;
    a.backlash_mm = backlash_mm;
    a.max_velocity_mm_s = 200.0;
    a.max_acceleration_mm_s2 = 2000.0;
    c.axes.push_back(a);
  }
  return c;
}

TEST(OutputStage, PositionIncIsPositionTimesRatioPlusOffsetPlusBacklash) {
  OutputStage o(three_axes());
  ASSERT_TRUE(o.set_ratio(1, 4096, 5).ok());  // 819.2 inc/mm
  ASSERT_TRUE(o.write_offset(0, 123).ok());
  ASSERT_TRUE(o.write_offset(1, -7).ok());
  ASSERT_TRUE(o.write_ratio(2, -250.0).ok());  // a reversed axis
  const double p[3] = {1.2345, 10.0, 2.0};
  o.update(p, 0.0);
  Registers r;
  o.fill(r);
  EXPECT_EQ(r.position_inc[0], 1235 + 123);  // round(1234.5) = 1235
  EXPECT_EQ(r.position_inc[1], 8192 - 7);
  EXPECT_EQ(r.position_inc[2], -500);
  EXPECT_DOUBLE_EQ(r.ratio[1], 819.2);
  EXPECT_EQ(r.offset[0], 123);
  EXPECT_EQ(r.backlash[0], 0);
  for (int i = 0; i < 3; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    EXPECT_EQ(r.position_inc[ui], std::llround(p[i] * r.ratio[ui]) + r.offset[ui] + r.backlash[ui]);
    EXPECT_NEAR(o.position_from_inc(i, r.position_inc[ui]), p[i], 0.5 / std::fabs(r.ratio[ui]) + 1e-12);
  }
}

TEST(OutputStage, RefusedWritesWithReasons) {
  OutputStage o(three_axes());
  EXPECT_EQ(o.write_offset(3, 0).reason, "Offset: axis 3 is not 0..2");
  EXPECT_EQ(o.write_offset(0, 2'000'000'000'000'000).reason,
            "Offset: |offset| must be <= 1e15 inc, not 2000000000000000");
  EXPECT_EQ(o.write_ratio(0, 0.0).reason, "Ratio: |ratio| must be 1e-06..1e+09 inc/mm, not 0");
  // Below the range but not 0 (it read "not 0.000000").
  EXPECT_EQ(o.write_ratio(0, 4e-7).reason, "Ratio: |ratio| must be 1e-06..1e+09 inc/mm, not 4e-07");
  EXPECT_EQ(o.write_ratio(0, NAN).code, RequestCode::kOutOfRange);
  EXPECT_EQ(o.set_ratio(0, 1, 0).reason, "Command 1024: denominator (Command_Parameter[2]) must be > 0 mm, not 0");
  EXPECT_EQ(o.set_ratio(0, 0, 1).reason, "Command 1024: numerator (Command_Parameter[1]) must not be 0 inc");
  EXPECT_EQ(o.set_ratio(-1, 1, 1).reason, "Command 1024: axis (Command_Parameter[0]) must be 0..2, not -1");
  // The value is named (the reason said only the range).
  EXPECT_EQ(o.set_ratio(0, 2'000'000'000, 1).reason,
            "Command 1024: |numerator / denominator| must be 1e-06..1e+09 inc/mm, not 2000000000 / "
            "1 = 2e+09");
  EXPECT_EQ(o.ratio(0), 1000.0);
}

// Command 1024 carries a ratio as a 32-bit numerator over a 32-bit denominator: tgm-plc sent
// ratio x 1000 + 0.5 over 1000, which turned -1000 into -999.999 and 3e6 into -2147483.648.
TEST(OutputStage, RatioAsFractionIsExactWherePossible) {
  struct Known {
    double ratio;
    std::int32_t num, den;
  };
  for (const Known k :
       {Known{1000.0, 1000, 1}, Known{-1000.0, -1000, 1}, Known{3e6, 3000000, 1},
        Known{0.0004, 1, 2500}, Known{3333.3333, 33333333, 10000}, Known{1e9, 1000000000, 1},
        Known{1e-6, 1, 1000000}, Known{-2.5, -5, 2}, Known{4096.0 / 5.0, 4096, 5}}) {
    SCOPED_TRACE(k.ratio);
    const auto f = OutputStage::ratio_as_fraction(k.ratio);
    EXPECT_TRUE(f.exact);
    EXPECT_EQ(f.numerator_inc, k.num);
    EXPECT_EQ(f.denominator_mm, k.den);
  }
  // Not representable: the nearest fraction found, flagged inexact.
  const auto third = OutputStage::ratio_as_fraction(1.0 / 3.0 + 1e-12);
  EXPECT_FALSE(third.exact);
  EXPECT_NEAR(static_cast<double>(third.numerator_inc) / third.denominator_mm, 1.0 / 3.0, 1e-11);
  EXPECT_FALSE(OutputStage::ratio_as_fraction(0.0).exact);
  EXPECT_FALSE(OutputStage::ratio_as_fraction(NAN).exact);
}

// Seeded sweep: every ratio of the config's range written with up to 4 decimals and at most
// 9 significant digits comes out exact, and set_ratio then holds the very same double.
TEST(OutputStage, RatioAsFractionRoundTripsDecimalRatios) {
  unsigned state = 12345u;
  auto next = [&state]() {
    state = state * 1103515245u + 12345u;
    return (state >> 8) & 0xFFFFFFu;
  };
  OutputStage o(three_axes());
  int checked = 0;
  for (int i = 0; i < 20000; ++i) {
    const int decimals = static_cast<int>(next() % 5);
    const long long digits = static_cast<long long>(next()) % 100000000LL + 1;  // < 1e8 + 1
    const double scale = std::pow(10.0, decimals);
    const double ratio = (next() % 2 ? -1.0 : 1.0) * std::stod(std::to_string(digits)) / scale;
    if (std::fabs(ratio) < 1e-6 || std::fabs(ratio) > 1e9) continue;
    SCOPED_TRACE(ratio);
    const auto f = OutputStage::ratio_as_fraction(ratio);
    ASSERT_TRUE(f.exact);
    ASSERT_TRUE(o.set_ratio(0, f.numerator_inc, f.denominator_mm).ok());
    ASSERT_EQ(o.ratio(0), ratio);
    ++checked;
  }
  EXPECT_GT(checked, 19000);
}

TEST(OutputStage, BacklashRampsOnReversalWithoutStep) {
  // Backlash 0.02 mm: +0.01 mm moving +, -0.01 mm moving -; ramp at 10 % of 200 mm/s,
  // 2000 mm/s^2 and 50,000 mm/s^3. Per calculation step of 100 us.
  OutputStage o(three_axes(0.02));
  const double dt = 100e-6;
  double p[3] = {0.0, 0.0, 0.0};
  o.reset(p);
  double prev_c = 0.0, prev_v = 0.0, prev_a = 0.0, max_v = 0.0, max_a = 0.0, max_j = 0.0;
  int flips = 0, last_dir = 0, reversal_steps = 0;
  for (int k = 0; k < 4000; ++k) {
    // X: forward 50 mm/s for 0.1 s, back for 0.1 s, forward again.
    const double t = k * dt;
    const double v = (t < 0.1 || t >= 0.2) ? 50.0 : -50.0;
    p[0] += v * dt;
    o.update(p, dt);
    const double c = o.compensation_mm(0);
    const double cv = (c - prev_c) / dt, ca = (cv - prev_v) / dt;
    max_v = std::max(max_v, std::fabs(cv));
    max_a = std::max(max_a, std::fabs(ca));
    max_j = std::max(max_j, std::fabs((ca - prev_a) / dt));
    if (k >= 1000 && k < 2000 && c != prev_c) ++reversal_steps;
    prev_v = cv;
    prev_a = ca;
    prev_c = c;
    if (o.direction(0) != last_dir) ++flips;
    last_dir = o.direction(0);
    if (k == 999) {
      EXPECT_EQ(c, 0.01);  // settled moving +
      EXPECT_TRUE(o.ramp_settled(0));
    }
    if (k == 1999) {
      EXPECT_EQ(c, -0.01);  // settled moving -
    }
    Registers r;
    o.fill(r);
    ASSERT_EQ(r.position_inc[0], std::llround(p[0] * 1000.0) + r.backlash[0]);
    ASSERT_EQ(r.backlash[0], std::llround(c * 1000.0));
  }
  EXPECT_EQ(flips, 3);  // 0 -> +, + -> -, - -> +
  EXPECT_EQ(prev_c, 0.01);
  // The reversal's 0.02 mm are jerk-bound: the quintic's peak jerk 60 D / T^3 = 5,000 mm/s^3
  // gives T = cbrt(60 x 0.02 / 5000) = 62.1 ms, 622 steps of 100 us (the last lands).
  const double T = std::cbrt(60.0 * 0.02 / 5000.0);
  EXPECT_EQ(reversal_steps, static_cast<int>(std::ceil(T / dt)));
  EXPECT_LE(max_v, 20.0);    // 10 % of the axis velocity limit
  EXPECT_LE(max_a, 200.0);   // of the acceleration limit: no landing step
  EXPECT_LE(max_j, 5000.0);  // and of the jerk limit
  EXPECT_GT(max_j, 4500.0);  // which binds
  EXPECT_NEAR(max_v, 1.875 * 0.02 / T, 0.005 * 1.875 * 0.02 / T);  // the quintic's peak, 15/8 D / T
  EXPECT_EQ(o.direction(1), 0);
  EXPECT_EQ(o.compensation_mm(1), 0.0);
}

// Seeded random sweep: backlash, limits, step and a motion of random reversals. The
// compensation's velocity, acceleration and jerk (differences of its samples) stay within 10 %
// of the axis limits, and once the motion keeps one direction it settles on +-backlash/2.
TEST(OutputStage, BacklashRampKeepsItsSharesOfEveryLimit) {
  std::uint64_t state = 79;
  const auto uniform = [&](double lo, double hi) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  for (int run = 0; run < 200; ++run) {
    InterpolatorConfig cfg = three_axes(uniform(1e-4, 0.5));
    AxisConfig& a = cfg.axes[0];
    a.max_velocity_mm_s = uniform(10.0, 500.0);
    a.max_acceleration_mm_s2 = uniform(100.0, 20000.0);
    a.max_jerk_mm_s3 = std::exp(uniform(std::log(1e3), std::log(1e7)));
    const double dt = std::array{50e-6, 100e-6, 200e-6}[run % 3];
    SCOPED_TRACE("run " + std::to_string(run) + ": backlash " + std::to_string(a.backlash_mm) +
                 " mm, v " + std::to_string(a.max_velocity_mm_s) + ", a " +
                 std::to_string(a.max_acceleration_mm_s2) + ", j " +
                 std::to_string(a.max_jerk_mm_s3) + ", dt " + std::to_string(dt));
    const double vmax = 0.1 * a.max_velocity_mm_s, amax = 0.1 * a.max_acceleration_mm_s2,
                 jmax = 0.1 * a.max_jerk_mm_s3;
    OutputStage o(cfg);
    double p[3] = {0.0, 0.0, 0.0};
    o.reset(p);
    double prev_c = 0.0, prev_v = 0.0, prev_a = 0.0, max_v = 0.0, max_a = 0.0, max_j = 0.0;
    // Random pieces of motion, then one direction for longer than the longest ramp.
    const double longest = std::cbrt(60.0 * a.backlash_mm / jmax) +
                           std::sqrt(5.78 * a.backlash_mm / amax) + 1.9 * a.backlash_mm / vmax;
    const int settle = static_cast<int>(2.0 * longest / dt) + 10;
    double speed = 0.0;
    int left = 0;
    for (int k = 0; k < 5000 + settle; ++k) {
      if (k < 5000 && left-- <= 0) {
        speed = uniform(-100.0, 100.0);
        left = static_cast<int>(uniform(1.0, 300.0));
      }
      if (k == 5000) speed = speed >= 0.0 ? 20.0 : -20.0;
      p[0] += speed * dt;
      o.update(p, dt);
      const double c = o.compensation_mm(0);
      const double cv = (c - prev_c) / dt, ca = (cv - prev_v) / dt, cj = (ca - prev_a) / dt;
      max_v = std::max(max_v, std::fabs(cv));
      max_a = std::max(max_a, std::fabs(ca));
      max_j = std::max(max_j, std::fabs(cj));
      prev_c = c;
      prev_v = cv;
      prev_a = ca;
    }
    // Rounding of the samples (<= 0.25 mm): 1e-16 mm, over dt^3 = 1.25e-13 s^3 at most 1e-3.
    EXPECT_LE(max_v, vmax * (1.0 + 1e-9));
    EXPECT_LE(max_a, amax * (1.0 + 1e-9) + 1e-6);
    EXPECT_LE(max_j, jmax * (1.0 + 1e-9) + 0.05);
    EXPECT_TRUE(o.ramp_settled(0));
    EXPECT_EQ(o.compensation_mm(0), o.direction(0) * 0.5 * a.backlash_mm);
    EXPECT_NE(o.direction(0), 0);
  }
}

// Travel back below the threshold (one increment, at least 1e-6 mm) keeps the direction.
TEST(OutputStage, TinyJitterIsNotAReversal) {
  OutputStage o(three_axes(0.02));
  double p[3] = {0.0, 0.0, 0.0};
  o.reset(p);
  for (int k = 0; k < 100; ++k) {
    p[0] += 0.001;
    o.update(p, 1e-4);
  }
  ASSERT_EQ(o.direction(0), 1);
  // One increment (1 / 1,000 mm) is the threshold here: the spline's overshoot at a stopping
  // corner, 0.25..0.5 um, is no reversal.
  p[0] -= 0.5e-3;
  o.update(p, 1e-4);
  EXPECT_EQ(o.direction(0), 1);
  p[0] -= 0.49e-3;
  o.update(p, 1e-4);
  EXPECT_EQ(o.direction(0), 1);
  p[0] -= 0.02e-3;
  o.update(p, 1e-4);
  EXPECT_EQ(o.direction(0), -1);
  // A fine ratio (1e7 inc/mm): 1e-6 mm is the threshold.
  ASSERT_TRUE(o.write_ratio(1, 1e7).ok());
  for (int k = 0; k < 100; ++k) {
    p[1] += 0.001;
    o.update(p, 1e-4);
  }
  ASSERT_EQ(o.direction(1), 1);
  p[1] -= 0.5e-6;
  o.update(p, 1e-4);
  EXPECT_EQ(o.direction(1), 1);
  p[1] -= 1e-6;
  o.update(p, 1e-4);
  EXPECT_EQ(o.direction(1), -1);
}

// ---- Commands ----

using Params = std::array<std::int32_t, kCommandParameters>;

CommandContext standing(int axes = 3) { return CommandContext{true, true, axes, axes}; }
CommandContext moving(int axes = 3) { return CommandContext{false, false, axes, axes}; }

TEST(Commands, ValidAndInvalidParametersWithExactReasons) {
  struct Case {
    std::int32_t code;
    Params p;
    CommandContext c;
    RequestCode want;
    const char* reason;
  };
  const Case cases[] = {
      {1024, {0, 4096, 5}, standing(), RequestCode::kAccepted, ""},
      {1024,
       {3, 4096, 5},
       standing(),
       RequestCode::kOutOfRange,
       "Command 1024: axis (Command_Parameter[0]) must be 0..2, not 3"},
      {1024,
       {0, 0, 5},
       standing(),
       RequestCode::kOutOfRange,
       "Command 1024: numerator (Command_Parameter[1]) must not be 0 inc"},
      {1024,
       {0, 10, -5},
       standing(),
       RequestCode::kOutOfRange,
       "Command 1024: denominator (Command_Parameter[2]) must be > 0 mm, not -5"},
      {1024,
       {0, 4096, 5},
       moving(),
       RequestCode::kWrongState,
       "Command 1024: the ratio can only be set while no program is executing (PositionInc "
       "jumps by Position x the change)"},
      // Standing at an M-function wait: PositionInc jumped by Position x the change, and the
      // program went on at the new scale.
      // Stopped on the trajectory of a program a start resumes (Status 4): idle, but not
      // between programs.
      {1024,
       {0, 4096, 5},
       CommandContext{true, true, 3, 3, false},
       RequestCode::kWrongState,
       "Command 1024: the ratio can only be set while no program is executing (PositionInc "
       "jumps by Position x the change)"},
      {1024,
       {0, 4096, 5},
       CommandContext{true, false, 3, 3},
       RequestCode::kWrongState,
       "Command 1024: the ratio can only be set while no program is executing (PositionInc "
       "jumps by Position x the change)"},
      // The range set_ratio refuses at run time is refused by the check too (a PLC script's
      // ratio of 2e9 inc/mm passed it), with the value.
      {1024,
       {0, 2'000'000'000, 1},
       standing(),
       RequestCode::kOutOfRange,
       "Command 1024: |numerator / denominator| must be 1e-06..1e+09 inc/mm, not 2000000000 / 1 "
       "= 2e+09"},
      {1024,
       {1, -1, 2'000'000'000},
       standing(),
       RequestCode::kOutOfRange,
       "Command 1024: |numerator / denominator| must be 1e-06..1e+09 inc/mm, not -1 / 2000000000 "
       "= -5e-10"},
      {1024, {2, -1'000'000'000, 1}, standing(), RequestCode::kAccepted, ""},  // the bounds
      {1024, {2, 1, 1'000'000}, standing(), RequestCode::kAccepted, ""},
      {2048, {1, 2, 3}, standing(), RequestCode::kAccepted, ""},
      {2049,
       {1, 2, 3},
       moving(),
       RequestCode::kWrongState,
       "Command 2049: the position can only be set while no program is executing"},
      {2048,
       {1, 2, 3},
       CommandContext{true, false, 3, 3},
       RequestCode::kWrongState,
       "Command 2048: the position can only be set while no program is executing"},
      // A program is loaded (stopped on its trajectory, starved or not started): a set
      // dropped it without a word.
      {2048,
       {1, 2, 3},
       CommandContext{true, true, 3, 3, false, true},
       RequestCode::kWrongState,
       "Command 2048: a program is loaded, which a start would run from the new position (stop "
       "it off the trajectory, Command 9 or 5, or clear it first)"},
      {2049,
       {1, 2, 3},
       CommandContext{true, true, 3, 3, false, true},
       RequestCode::kWrongState,
       "Command 2049: a program is loaded, which a start would run from the new position (stop "
       "it off the trajectory, Command 9 or 5, or clear it first)"},
      {-1, {2'000'000, 1'000'000, 6'000'000, 0b111}, standing(), RequestCode::kAccepted, ""},
      {-1,
       {2'000'000, 1'000'000, 6'000'000, 0b111},
       CommandContext{true, false, 3, 3},
       RequestCode::kAccepted,
       ""},  // standing at an M-function: fine (bumpless)
      {-1, {0, 0, 0, 0}, standing(), RequestCode::kAccepted, ""},  // mask 0: off
      // Only axes the interpolator lacks (axes counted from 1: 8 meant Z of three): it was
      // done, and nothing was filtered. Bits beyond the axes are ignored where one is an axis.
      {-1,
       {2'000'000, 1'000'000, 6'000'000, 0b1000},
       standing(),
       RequestCode::kOutOfRange,
       "Command -1: the axis mask (Command_Parameter[3]) 8 selects none of axes 0..2 (bit 0 is "
       "axis 0; bits above 9 are ignored)"},
      // Only bits the manual ignores (above 9): the filter stayed off without a word.
      {-1,
       {2'000'000, 1'000'000, 6'000'000, 1024},
       standing(),
       RequestCode::kOutOfRange,
       "Command -1: the axis mask (Command_Parameter[3]) 1024 selects none of axes 0..2 (bit 0 "
       "is axis 0; bits above 9 are ignored)"},
      // A negative mask is named as written (it was "1016" for -8).
      {-1,
       {2'000'000, 1'000'000, 6'000'000, -8},
       standing(),
       RequestCode::kOutOfRange,
       "Command -1: the axis mask (Command_Parameter[3]) -8 selects none of axes 0..2 (bit 0 "
       "is axis 0; bits above 9 are ignored)"},
      {-1, {2'000'000, 1'000'000, 6'000'000, 0x3FF}, standing(), RequestCode::kAccepted, ""},
      {-1,
       {0, 1'000'000, 6'000'000, 1},
       standing(),
       RequestCode::kOutOfRange,
       "IIR p (Command_Parameter[0]) must be 1000..1000000000 (x 1e-6), not 0"},
      {-1,
       {2'000'000, 1'000'000, 0, 1},
       standing(),
       RequestCode::kOutOfRange,
       "IIR f (Command_Parameter[2]) must be 1000000..2000000000 (1..2000 ms x 1e6), not 0"},
      {-1,
       {2'000'000, 1'000'000, 6'000'000, 1},
       moving(),
       RequestCode::kWrongState,
       "Command -1: IIR parameters can only be set while standing"},
      {-2, {200, 1'000'000}, standing(), RequestCode::kAccepted, ""},
      {-2, {0, 0}, standing(), RequestCode::kAccepted, ""},
      {-2,
       {20, 1'000'000},
       standing(),
       RequestCode::kOutOfRange,
       "Spline points (Command_Parameter[0]) must be 0 (off) or 50..500, not 20"},
      {-2,
       {200, -1},
       standing(),
       RequestCode::kOutOfRange,
       "Spline jerk limit (Command_Parameter[1]) must be > 0 mm/s^3, not -1"},
      {-2,
       {200, 1'000'000},
       moving(),
       RequestCode::kWrongState,
       "Command -2: Spline parameters can only be set while standing"},
      {7,
       {},
       standing(),
       RequestCode::kOutOfRange,
       "unknown Command 7 (valid: 4, 5, 8, 9, 1024, 2048, 2049, -1, -2)"},
      {8, {}, moving(), RequestCode::kAccepted, ""},
  };
  for (const Case& c : cases) {
    const RequestResult r = check_command(c.code, c.p, c.c);
    EXPECT_EQ(r.code, c.want) << c.code << " " << r.reason;
    EXPECT_EQ(r.reason, c.reason) << c.code;
  }
}

TEST(Commands, NumberAxes) {
  EXPECT_TRUE(check_number_axes(1, standing()).ok());
  EXPECT_TRUE(check_number_axes(3, standing()).ok());
  EXPECT_EQ(check_number_axes(0, standing()).reason, "Number_Axes must be 1..10, not 0");
  EXPECT_EQ(check_number_axes(11, standing()).reason, "Number_Axes must be 1..10, not 11");
  EXPECT_EQ(check_number_axes(4, standing()).reason, "Number_Axes 4: only 3 axes are configured");
  // A change while a program is loaded (it dropped the program's records); the same count is
  // no change.
  CommandContext loaded = standing();
  loaded.holds_program = true;
  EXPECT_EQ(check_number_axes(2, loaded).reason,
            "Number_Axes 2: a program is loaded, whose records are planned for 3 axes (clear it "
            "first)");
  EXPECT_TRUE(check_number_axes(3, loaded).ok());
  EXPECT_EQ(check_number_axes(2, moving()).code, RequestCode::kWrongState);
  EXPECT_EQ(check_number_axes(2, moving()).reason,
            "Number_Axes can only be written while no program is executing");
}

TEST(Commands, StatusSequence) {
  Registers r;
  command_begin(r, -2);
  EXPECT_EQ(r.command, -2);
  EXPECT_EQ(r.command_status, 1);
  command_end(r, {});
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(r.command_status, 0);
  command_begin(r, 1024);
  EXPECT_EQ(r.command_status, 1);
  command_end(r, {RequestCode::kOutOfRange, "x"});
  EXPECT_EQ(r.command, 0);
  EXPECT_EQ(r.command_status, -1);
}

TEST(Commands, ExecuteRatioSplineIirAndPositionSet) {
  const InterpolatorConfig cfg = three_axes(0.0);
  SmoothingStage s(3, 500);
  OutputStage o(cfg);
  std::array<double, kMaxAxes> pos{};
  Params p{};
  // 1024: axis 2, 8192 inc per 5 mm.
  p = {2, 8192, 5};
  ASSERT_TRUE(execute_command(1024, p, standing(), s, o, nullptr).ok());
  EXPECT_DOUBLE_EQ(o.ratio(2), 1638.4);
  // -2 and -1.
  p = {100, 1'000'000};
  ASSERT_TRUE(execute_command(-2, p, standing(), s, o, nullptr).ok());
  EXPECT_EQ(s.spline().delay_steps(), 100);
  p = {3'000'000, 3'000'000, 10'000'000, 0b011};
  ASSERT_TRUE(execute_command(-1, p, standing(), s, o, nullptr).ok());
  EXPECT_EQ(s.iir().mask(), 0b011u);
  // 2048 with offsets: Orig = (inc - Offset - Backlash) / Ratio; PositionInc reproduces inc.
  ASSERT_TRUE(o.write_offset(0, 500).ok());
  p = {1500, -2000, 16384};
  ASSERT_TRUE(execute_command(2048, p, standing(), s, o, &pos).ok());
  EXPECT_DOUBLE_EQ(pos[0], 1.0);
  EXPECT_DOUBLE_EQ(pos[1], -2.0);
  EXPECT_DOUBLE_EQ(pos[2], 10.0);
  Registers r;
  o.fill(r);
  EXPECT_EQ(r.position_inc[0], 1500);
  EXPECT_EQ(r.position_inc[1], -2000);
  EXPECT_EQ(r.position_inc[2], 16384);
  EXPECT_EQ(s.position()[2], 10.0);
  // Moving: the smoothing does not stand still -> 2049 and 1024 refused for state.
  const double target[3] = {5.0, -2.0, 10.0};
  for (int k = 0; k < 10; ++k) s.step(target);
  EXPECT_EQ(execute_command(2049, p, standing(), s, o, &pos).reason,
            "Command 2049: the axes are still moving behind the spline / IIR filter");
  p = {0, 1, 1};
  EXPECT_EQ(execute_command(1024, p, standing(), s, o, nullptr).code, RequestCode::kWrongState);
  p = {50, 1'000'000};
  EXPECT_EQ(execute_command(-2, p, standing(), s, o, nullptr).code, RequestCode::kWrongState);
  EXPECT_EQ(execute_command(4, p, standing(), s, o, nullptr).code, RequestCode::kUnsupported);
}

// in_effect() says what Commands -2 / -1 set (the state publishes it, tgm-hmi run simulates with
// it), and a stage configured from it smooths the same, bit for bit.
TEST(Commands, TheSmoothingInEffectIsWhatTheCommandsSetAndConfiguresTheSame) {
  const InterpolatorConfig cfg = three_axes(0.0);
  SmoothingStage s(3, 500);
  OutputStage o(cfg);
  // Both off: the spline's points 0, the IIR's mask 0 and IirParams' defaults.
  SmoothingConfig c = s.in_effect();
  EXPECT_EQ(c.spline_points, 0);
  EXPECT_EQ(c.iir_axis_mask, 0u);
  EXPECT_EQ(c.iir_p_e6, IirParams{}.p_e6);
  Params p{};
  p = {120, 3'000'000};
  ASSERT_TRUE(execute_command(-2, p, standing(), s, o, nullptr).ok());
  p = {3'000'000, 2'000'000, 8'000'000, 0b1111'0110};  // bits beyond the 3 axes are not used
  ASSERT_TRUE(execute_command(-1, p, standing(), s, o, nullptr).ok());
  c = s.in_effect();
  EXPECT_EQ(c.spline_points, 120);
  EXPECT_EQ(c.spline_jerk_mm_s3, 3e6);
  EXPECT_EQ(c.iir_p_e6, 3'000'000);
  EXPECT_EQ(c.iir_q_e6, 2'000'000);
  EXPECT_EQ(c.iir_f_e6, 8'000'000);
  EXPECT_EQ(c.iir_axis_mask, 0b110u);

  SmoothingStage t(3, 500);
  ASSERT_TRUE(t.configure_spline(c.spline_points, std::llround(c.spline_jerk_mm_s3)).ok());
  ASSERT_TRUE(t.configure_iir({c.iir_p_e6, c.iir_q_e6, c.iir_f_e6, c.iir_axis_mask}).ok());
  const double zero[3] = {0.0, 0.0, 0.0};
  s.reset(zero);
  t.reset(zero);
  for (int k = 0; k < 2000; ++k) {
    // A ramp with a corner: the spline and both filtered axes have work.
    const double x = 0.01 * std::min(k, 500);
    const double in[3] = {x, 0.5 * x, k < 500 ? 0.0 : 0.002 * (k - 500)};
    s.step(in);
    t.step(in);
    for (int i = 0; i < 3; ++i) ASSERT_EQ(s.position()[i], t.position()[i]) << k << " " << i;
  }
  EXPECT_EQ(t.in_effect().spline_points, c.spline_points);
  EXPECT_EQ(t.in_effect().iir_axis_mask, c.iir_axis_mask);
}

// A position set lands within the +-1e9 mm every record's end point is held to, or is refused
// before anything changes: with an Offset of 1e15 inc and a Ratio of 1e-6 inc/mm it computed
// -1e21 mm, and the first move from there ran for ever (RandomRequests found it through
// Interpolator::set_position, which holds the same bound).
TEST(Commands, APositionSetBeyondTheCoordinateBoundIsRefusedAndChangesNothing) {
  const InterpolatorConfig cfg = three_axes(0.0);
  SmoothingStage s(3, 500);
  OutputStage o(cfg);
  std::array<double, kMaxAxes> pos{};
  Params p{};
  p = {1000, 2000, 3000};
  ASSERT_TRUE(execute_command(2048, p, standing(), s, o, &pos).ok());
  const std::array<double, kMaxAxes> before = pos;
  ASSERT_TRUE(o.write_offset(1, 1'000'000'000'000'000).ok());
  p = {1, 1, 1'000'000};  // axis 1: 1 inc per 1e6 mm
  ASSERT_TRUE(execute_command(1024, p, standing(), s, o, nullptr).ok());
  p = {0, 0, 0};
  const RequestResult r = execute_command(2049, p, standing(), s, o, &pos);
  EXPECT_EQ(r.code, RequestCode::kOutOfRange);
  EXPECT_EQ(r.reason,
            "Command 2049: axis 1 would be at -1e+21 mm ((inc - Offset - Backlash) / Ratio), "
            "outside +-1e9 mm");
  EXPECT_EQ(pos, before);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(s.position()[i], before[i]) << "axis " << i;
  // Within the bound it is taken: 999 inc at 1e-6 inc/mm are 9.99e8 mm.
  p = {0, 999, 0};
  ASSERT_TRUE(o.write_offset(1, 0).ok());
  ASSERT_TRUE(execute_command(2048, p, standing(), s, o, &pos).ok());
  EXPECT_DOUBLE_EQ(pos[1], 9.99e8);
}

}  // namespace
}  // namespace tgm
