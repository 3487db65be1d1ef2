// Spline: exact delay, jerk reduction on velocity jumps with the contour deviation reported,
// acceleration steps, locality, events delayed identically, no allocation per step.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "tgm/smoothing.hpp"

namespace tgm {
namespace {

constexpr double kDt = 100e-6;  // Cycle_Time 500 us
constexpr double kLimit = 1'000'000.0;  // mm/s^3, the manual's suggestion

using Traj = std::vector<std::array<double, kMaxAxes>>;

// Runs `in` through a spline of `points`, `axes` axes; returns the outputs (one per input).
Traj run(SplineSmoother& s, const Traj& in, int axes, int points, double jerk = kLimit) {
  EXPECT_TRUE(s.configure(points, jerk, axes, in.front().data()).ok());
  Traj out(in.size());
  for (std::size_t k = 0; k < in.size(); ++k) s.step(in[k].data(), out[k].data());
  return out;
}

// Largest |third difference| / dt^3 of axis `a` over samples [from, to).
double max_jerk(const Traj& x, int a, std::size_t from, std::size_t to) {
  double m = 0.0;
  const auto ua = static_cast<std::size_t>(a);
  for (std::size_t k = std::max<std::size_t>(from, 3); k < to; ++k) {
    const double d3 = x[k][ua] - 3.0 * x[k - 1][ua] + 3.0 * x[k - 2][ua] - x[k - 3][ua];
    m = std::max(m, std::fabs(d3) / (kDt * kDt * kDt));
  }
  return m;
}

// A square corner without slow-down: X at 100 mm/s stops at the corner, Y starts at 100 mm/s.
Traj square_corner(std::size_t steps, std::size_t corner, double v = 100.0) {
  Traj x(steps);
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * kDt, tc = static_cast<double>(corner) * kDt;
    x[k][0] = v * std::min(t, tc);
    x[k][1] = v * std::max(0.0, t - tc);
  }
  return x;
}

TEST(Spline, SmoothInputIsDelayedExactly) {
  // Jerk well below the limit everywhere: output == input N steps earlier, bit for bit.
  for (int points : {50, 200, 500}) {
    Traj in(6000);
    for (std::size_t k = 0; k < in.size(); ++k) {
      const double t = static_cast<double>(k) * kDt;
      // Starting at rest (the buffer is filled with the first point): velocity, acceleration
      // and jerk start at 0; jerk below 1e5 mm/s^3 throughout.
      const double c = 1.0 - std::cos(2.0 * M_PI * 2.0 * t);
      in[k][0] = 10.0 * c * c + 1000.0;
      in[k][1] = 5.0 * t * t * t * t;
      in[k][2] = -300.0;
    }
    SplineSmoother s(kDt);
    const Traj out = run(s, in, 3, points);
    EXPECT_EQ(s.delay_steps(), points);
    for (std::size_t k = 0; k < in.size(); ++k) {
      const auto& ref = k >= static_cast<std::size_t>(points) ? in[k - static_cast<std::size_t>(points)] : in.front();
      for (std::size_t a = 0; a < 3; ++a) ASSERT_EQ(out[k][a], ref[a]) << points << " " << k;
    }
    EXPECT_EQ(s.stats().flagged_steps, 0u);
    EXPECT_EQ(s.stats().max_mm, 0.0);
  }
}

TEST(Spline, DelayOf200PointsIs20msAtCycle500us) {
  SplineSmoother s(kDt);
  const std::array<double, kMaxAxes> zero{};
  ASSERT_TRUE(s.configure(200, kLimit, 1, zero.data()).ok());
  EXPECT_DOUBLE_EQ(s.delay_steps() * kDt, 0.020);
}

TEST(Spline, SquareCornerJerkReducedByTheKernelFactor) {
  const int points = 200;
  const std::size_t corner = 3000, steps = 6000;
  const Traj in = square_corner(steps, corner);
  SplineSmoother s(kDt);
  const Traj out = run(s, in, 2, points);
  const double raw = std::max(max_jerk(in, 0, 0, steps), max_jerk(in, 1, 0, steps));
  EXPECT_NEAR(raw, 100.0 / (kDt * kDt), 1.0);  // a sampled velocity jump: dv / dt^2
  const double smooth = std::max(max_jerk(out, 0, 0, steps), max_jerk(out, 1, 0, steps));
  // Predicted: dv * gain / dt^2, reduction 1 / gain (about (N+1)^2 / 5 = 8,080 for N = 200).
  const double gain = s.velocity_jump_jerk_gain();
  EXPECT_NEAR(1.0 / gain, (points + 1.0) * (points + 1.0) / 5.0, 0.02 * (points + 1.0) * (points + 1.0) / 5.0);
  EXPECT_LE(smooth, 100.0 * gain / (kDt * kDt) * (1.0 + 1e-6) + 1.0);
  EXPECT_GE(raw / smooth, 0.99 / gain);
  std::printf("square corner 100 mm/s, N = %d: raw jerk %.3g, after spline %.3g mm/s^3 (factor %.0f), "
              "contour deviation %.4f mm, velocity undershoot %.1f %%\n",
              points, raw, smooth, raw / smooth, s.stats().max_mm, -100.0 * s.velocity_undershoot());
  // Contour deviation reported per pass: the motion starts at full speed (pass 1, X only) and
  // the corner (pass 2); the corner's maximum = max |out - delayed in| around it.
  double dev = 0.0;
  for (std::size_t k = corner - 10; k < steps; ++k) {
    const double dx = out[k][0] - in[k - points][0], dy = out[k][1] - in[k - points][1];
    dev = std::max(dev, std::hypot(dx, dy));
  }
  EXPECT_EQ(s.stats().passes, 2u);
  EXPECT_NEAR(s.stats().last_pass_mm, dev, 1e-12);
  EXPECT_NEAR(s.stats().max_mm, dev, 1e-12);
  EXPECT_GT(dev, 0.0);
  EXPECT_LT(dev, 100.0 * points * kDt);  // less than the travel in the buffer
  // Local: outside +-N around the corner the output is the delayed input exactly.
  for (std::size_t k = points; k < steps; ++k) {
    const std::size_t src = k - points;
    if ((src > points + 4 && src + points + 2 < corner) || src > corner + points + 2) {
      ASSERT_EQ(out[k][0], in[src][0]) << k;
      ASSERT_EQ(out[k][1], in[src][1]) << k;
    }
  }
}

TEST(Spline, LongerBufferSmoothsMore) {
  const Traj in = square_corner(4000, 2000);
  double prev = 1e300;
  for (int points : {50, 100, 200, 500}) {
    SplineSmoother s(kDt);
    const Traj out = run(s, in, 2, points);
    const double j = std::max(max_jerk(out, 0, 0, in.size()), max_jerk(out, 1, 0, in.size()));
    EXPECT_LT(j, prev);
    prev = j;
  }
}

TEST(Spline, AccelerationStepIsSmoothedLocally) {
  // Acceleration jumps from 0 to 2000 mm/s^2 (jerk 2e7 when sampled) and back after 0.1 s.
  const std::size_t steps = 5000, t0 = 1000, t1 = 2000;
  Traj in(steps);
  double v = 0.0, x = 0.0;
  for (std::size_t k = 0; k < steps; ++k) {
    const double a = (k > t0 && k <= t1) ? 2000.0 : 0.0;
    x += v * kDt + 0.5 * a * kDt * kDt;
    v += a * kDt;
    in[k][0] = x;
  }
  SplineSmoother s(kDt);
  const int points = 200;
  const Traj out = run(s, in, 1, points);
  const double smooth = max_jerk(out, 0, 0, steps);
  EXPECT_LE(smooth, 2000.0 * s.acceleration_step_jerk_gain() / kDt * 1.001);
  EXPECT_LT(smooth, kLimit);
  // Exact delay away from the two steps (the kernel keeps cubics: no offset after the step).
  for (std::size_t k = points; k < steps; ++k) {
    const std::size_t src = k - points;
    const bool near = src < static_cast<std::size_t>(2 * points + 4) || (src + points + 3 >= t0 && src <= t0 + points + 3) ||
                      (src + points + 3 >= t1 && src <= t1 + points + 3);
    if (!near) {
      ASSERT_EQ(out[k][0], in[src][0]) << k;
    }
  }
  EXPECT_EQ(s.stats().passes, 2u);
}

TEST(Spline, CoarseSegmentsCircle) {
  // Circle r = 10 mm at 100 mm/s made of 1 mm chords: a direction jump every 100 steps.
  const double r = 10.0, v = 100.0, chord_angle = 2.0 * std::asin(0.5 / r);
  const int chords = static_cast<int>(std::floor(2.0 * M_PI / chord_angle));
  const double chord_len = 2.0 * r * std::sin(0.5 * chord_angle);
  const std::size_t per_chord = static_cast<std::size_t>(std::llround(chord_len / v / kDt));
  Traj in;
  for (int c = 0; c < chords; ++c) {
    const double a0 = c * chord_angle, a1 = (c + 1) * chord_angle;
    for (std::size_t k = 0; k < per_chord; ++k) {
      const double u = static_cast<double>(k) / static_cast<double>(per_chord);
      std::array<double, kMaxAxes> p{};
      p[0] = r * ((1 - u) * std::cos(a0) + u * std::cos(a1));
      p[1] = r * ((1 - u) * std::sin(a0) + u * std::sin(a1));
      in.push_back(p);
    }
  }
  for (int k = 0; k < 1000; ++k) in.push_back(in.back());
  SplineSmoother s(kDt);
  const int points = 200;
  const Traj out = run(s, in, 2, points);
  const double raw = std::max(max_jerk(in, 0, 0, in.size()), max_jerk(in, 1, 0, in.size()));
  const double smooth = std::max(max_jerk(out, 0, 0, in.size()), max_jerk(out, 1, 0, in.size()));
  double radial = 0.0;  // distance from the circle, while on it
  for (std::size_t k = points + per_chord * 3; k + 3 * per_chord < in.size() - 1000; ++k) {
    radial = std::max(radial, std::fabs(std::hypot(out[k][0], out[k][1]) - r));
  }
  std::printf("1 mm chords of r 10 mm at 100 mm/s, N = %d: raw jerk %.3g, after spline %.3g mm/s^3 "
              "(factor %.0f), spline deviation %.4f mm, radial error %.4f mm (chord sagitta %.4f)\n",
              points, raw, smooth, raw / smooth, s.stats().max_mm, radial,
              r * (1.0 - std::cos(0.5 * chord_angle)));
  EXPECT_LT(smooth, raw / 1000.0);
  EXPECT_GT(s.stats().max_mm, 0.0);
  EXPECT_EQ(out.back()[0], in.back()[0]);  // back on the delayed input after the motion
  EXPECT_EQ(out.back()[1], in.back()[1]);
}

TEST(Spline, LongRandomRunStaysExact) {
  // 10 axes, random polyline with velocity jumps every 3..40 steps (every step near one): the
  // wrapping integer chain stays exact; when the input stands, the output is on it exactly.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> len(3, 40);
  SplineSmoother s(kDt);
  std::array<double, kMaxAxes> x{}, out{}, vel{};
  for (auto& xi : x) xi = 500.0 * u(rng);
  ASSERT_TRUE(s.configure(500, kLimit, kMaxAxes, x.data()).ok());
  int left = 0;
  for (int k = 0; k < 200'000; ++k) {
    if (left-- <= 0) {
      for (auto& vi : vel) vi = 200.0 * u(rng);
      left = len(rng);
    }
    for (int a = 0; a < kMaxAxes; ++a) x[static_cast<std::size_t>(a)] += vel[static_cast<std::size_t>(a)] * kDt;
    s.step(x.data(), out.data());
    for (double o : out) ASSERT_TRUE(std::isfinite(o));
  }
  EXPECT_FALSE(s.settled());
  for (int k = 0; k < 2 * 500 + 4; ++k) s.step(x.data(), out.data());
  EXPECT_TRUE(s.settled());
  s.step(x.data(), out.data());
  for (int a = 0; a < kMaxAxes; ++a) EXPECT_EQ(out[static_cast<std::size_t>(a)], x[static_cast<std::size_t>(a)]);
  EXPECT_GT(s.stats().passes, 0u);
}

// settled() is what Status 3/4 and the commands that wait for the smoothing go by: it must
// never say so while the output will still move, and should say so soon after it stops.
// Seeded sweep: random N, jerk limits that flag many steps, some or none, random motions that
// end standing. Oracle: the first step f from which the output equals the standing input
// exactly, for 3N steps. settled() is false before f; without a flagged step it is true at
// f + 2 (the margin), and at most N + 6 steps after f otherwise (the correction's reach).
TEST(Spline, SettledOnlyWhenTheOutputStandsAndSoonAfter) {
  std::mt19937_64 rng(20261205);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int unflagged = 0, flagged = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int n = std::uniform_int_distribution<int>(50, 500)(rng);
    const int axes = std::uniform_int_distribution<int>(1, kMaxAxes)(rng);
    const double jerk = trial % 3 == 0 ? 1e12 : (trial % 3 == 1 ? 1e4 : kLimit);
    SplineSmoother s(kDt);
    std::array<double, kMaxAxes> x{}, out{}, vel{}, acc{};
    for (int a = 0; a < axes; ++a) x[static_cast<std::size_t>(a)] = 100.0 * u(rng);
    ASSERT_TRUE(s.configure(n, jerk, axes, x.data()).ok());
    ASSERT_TRUE(s.settled());
    // Motion: constant-acceleration pieces (smooth, or with velocity jumps at odd trials).
    const int moving = std::uniform_int_distribution<int>(5, 3000)(rng);
    int left = 0;
    for (int k = 0; k < moving; ++k) {
      if (left-- <= 0) {
        for (int a = 0; a < axes; ++a) {
          const auto ua = static_cast<std::size_t>(a);
          acc[ua] = 5000.0 * u(rng);
          if (trial % 2 == 1) vel[ua] = 100.0 * u(rng);
        }
        left = std::uniform_int_distribution<int>(1, 400)(rng);
      }
      for (int a = 0; a < axes; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        vel[ua] += acc[ua] * kDt;
        x[ua] += vel[ua] * kDt;
      }
      s.step(x.data(), out.data());
    }
    // Stand for 3N + 10 steps; record when settled() first holds and the outputs.
    const int standing = 3 * n + 10;
    int first_settled = -1;
    std::vector<bool> settled_at(static_cast<std::size_t>(standing));
    std::vector<bool> on_input(static_cast<std::size_t>(standing));
    for (int k = 0; k < standing; ++k) {
      s.step(x.data(), out.data());
      bool eq = true;
      for (int a = 0; a < axes; ++a)
        eq &= out[static_cast<std::size_t>(a)] == x[static_cast<std::size_t>(a)];
      on_input[static_cast<std::size_t>(k)] = eq;
      settled_at[static_cast<std::size_t>(k)] = s.settled();
      if (first_settled < 0 && s.settled()) first_settled = k;
    }
    int f = standing;
    while (f > 0 && on_input[static_cast<std::size_t>(f - 1)]) --f;
    ASSERT_LT(f, standing - n) << "trial " << trial << ": the output never stood";
    ASSERT_GE(first_settled, 0) << "trial " << trial;
    EXPECT_GE(first_settled, f) << "trial " << trial << " N " << n << ": settled while moving";
    for (int k = first_settled; k < standing; ++k) {
      ASSERT_TRUE(settled_at[static_cast<std::size_t>(k)]) << "trial " << trial << " step " << k;
    }
    if (s.stats().flagged_steps == 0) {
      ++unflagged;
      EXPECT_EQ(first_settled, f + 2) << "trial " << trial << " N " << n;
    } else {
      ++flagged;
      EXPECT_LE(first_settled, f + n + 6) << "trial " << trial << " N " << n;
    }
  }
  // Both kinds were drawn.
  EXPECT_GT(unflagged, 10);
  EXPECT_GT(flagged, 10);
}

// Far from the origin a standing input flagged every step with a jerk limit of a few mm/s^3:
// x - 3 x1 + 3 x2 - x3 left rounding noise of an ulp (1.2e-10 mm at 1e6 mm), above the limit's
// 2e-12 mm: a smoothing pass that never ended, and with settled() going by the flags, an
// interpolator that stayed in Status 6 after an emergency stop (the service's request storm,
// seed 2). Third differences are differences of differences now: exactly 0 for a standing input.
TEST(Spline, SettlesFarFromTheOriginWithATinyJerkLimit) {
  for (const double jerk : {1.0, 2.0, 1000.0}) {
    SplineSmoother s(kDt);
    std::array<double, kMaxAxes> x{987654.321, -123456.789, 0.3, 1e6 - 0.1}, out{};
    ASSERT_TRUE(s.configure(50, jerk, 4, x.data()).ok());
    for (int k = 0; k < 40; ++k) {
      x[0] += 0.001;
      x[3] -= 0.002;
      s.step(x.data(), out.data());
    }
    const std::uint64_t flagged_moving = s.stats().flagged_steps;
    EXPECT_GT(flagged_moving, 0u);  // the start and the stop are flagged at these limits
    for (int k = 0; k < 3 * 50 + 10; ++k) s.step(x.data(), out.data());
    EXPECT_TRUE(s.settled()) << "jerk " << jerk;
    EXPECT_LE(s.stats().flagged_steps, flagged_moving + 3) << "jerk " << jerk;
    for (int a = 0; a < 4; ++a) {
      EXPECT_EQ(out[static_cast<std::size_t>(a)], x[static_cast<std::size_t>(a)]) << "jerk " << jerk;
    }
  }
}

TEST(Spline, ChecksWithReasons) {
  EXPECT_TRUE(SplineSmoother::check(0, 0).ok());
  EXPECT_TRUE(SplineSmoother::check(50, 1).ok());
  EXPECT_TRUE(SplineSmoother::check(500, 1'000'000).ok());
  auto r = SplineSmoother::check(49, 1'000'000);
  EXPECT_EQ(r.code, RequestCode::kOutOfRange);
  EXPECT_EQ(r.reason, "Spline points (Command_Parameter[0]) must be 0 (off) or 50..500, not 49");
  r = SplineSmoother::check(501, 1'000'000);
  EXPECT_EQ(r.reason, "Spline points (Command_Parameter[0]) must be 0 (off) or 50..500, not 501");
  r = SplineSmoother::check(200, 0);
  EXPECT_EQ(r.reason, "Spline jerk limit (Command_Parameter[1]) must be > 0 mm/s^3, not 0");
}

TEST(SmoothingStage, EventsLeaveWithTheMotion) {
  SmoothingStage st(2, 500);
  ASSERT_TRUE(st.configure_spline(200, 1'000'000).ok());
  const Traj in = square_corner(3000, 1000);
  SmoothingEvent e;
  std::vector<std::size_t> released;
  for (std::size_t k = 0; k < in.size(); ++k) {
    st.step(in[k].data());
    if (k == 1000 || k == 1500) {
      ASSERT_TRUE(st.push_event({1, static_cast<std::int32_t>(k), k}));
    }
    while (st.pop_event(&e)) {
      released.push_back(k);
      // The output of this step is the sample the event belonged to (the corner for k 1000).
      EXPECT_EQ(e.tag + 200, k);
    }
  }
  ASSERT_EQ(released.size(), 2u);
  EXPECT_EQ(released[0], 1200u);
  EXPECT_EQ(released[1], 1700u);
}

TEST(SmoothingStage, EventsPassAtOnceWithoutSplineAndWithIirOnly) {
  SmoothingStage st(1, 500);
  ASSERT_TRUE(st.configure_iir({2'000'000, 1'000'000, 6'000'000, 1u}).ok());
  const double x = 5.0;
  st.step(&x);
  ASSERT_TRUE(st.push_event({1, 7, 0}));
  SmoothingEvent e;
  ASSERT_TRUE(st.pop_event(&e));  // the IIR filter does not delay M-functions
  EXPECT_EQ(e.value, 7);
  EXPECT_LT(st.position()[0], x);  // while the filtered axis still moves
  EXPECT_FALSE(st.settled());
}

TEST(SmoothingStage, BothOffPassesOrigPositionAndKeepsTheFilterInputForABumplessStart) {
  // Both stages off (the default): Position is the input and Speed its difference quotient,
  // exactly; the filter still records each input, so an axis that enters the IIR mask later
  // starts at rest where Position stands (a stale input would pull it back towards 0).
  SmoothingStage st(2, 500);
  const double dt = st.calc_step_s();
  double x[2] = {0.0, 0.0};
  for (int k = 1; k <= 50; ++k) {
    const double prev[2] = {x[0], x[1]};
    x[0] = 0.003 * k * k;
    x[1] = -1.5 * k;
    st.step(x);
    ASSERT_EQ(st.position()[0], x[0]);
    ASSERT_EQ(st.position()[1], x[1]);
    ASSERT_EQ(st.speed()[0], (x[0] - prev[0]) * (1.0 / dt));
    ASSERT_EQ(st.speed()[1], (x[1] - prev[1]) * (1.0 / dt));
  }
  // A step nobody reads (Interpolator: the first three of a cycle) releases events as a step
  // does, and the two steps after it make Position and Speed as if it had been made.
  ASSERT_TRUE(st.passes_through());
  ASSERT_TRUE(st.push_event_next({1, 5, 0}));
  SmoothingEvent e;
  EXPECT_FALSE(st.pop_event(&e));
  st.step_unread();
  ASSERT_TRUE(st.pop_event(&e));
  EXPECT_EQ(e.value, 5);
  const double far[2] = {x[0] + 1.0, x[1] + 2.0};
  st.step(far);
  const double last[2] = {far[0] + 0.25, far[1] - 0.5};
  st.step(last);
  EXPECT_EQ(st.position()[0], last[0]);
  EXPECT_EQ(st.speed()[1], (last[1] - far[1]) * (1.0 / dt));
  ASSERT_TRUE(st.configure_iir({2'000'000, 1'000'000, 6'000'000, 1u}).ok());
  EXPECT_FALSE(st.passes_through());
  st.step(last);
  EXPECT_EQ(st.position()[0], last[0]);
  EXPECT_EQ(st.speed()[0], 0.0);
  EXPECT_TRUE(st.settled());
}

TEST(SmoothingStage, SplineChangeOnlyWhenDrainedAndSpeedIsAfterSmoothing) {
  SmoothingStage st(1, 500);
  ASSERT_TRUE(st.configure_spline(50, 1'000'000).ok());
  double x = 0.0;
  for (int k = 0; k < 300; ++k) {
    x += 0.01;  // 100 mm/s (the start from rest is smoothed; after 2N + 4 steps: delayed input)
    st.step(&x);
  }
  EXPECT_NEAR(st.speed()[0], 100.0, 1e-6);
  auto r = st.configure_spline(100, 1'000'000);
  EXPECT_EQ(r.code, RequestCode::kWrongState);
  EXPECT_EQ(r.reason,
            "Spline: the buffer still holds motion or M-functions (it drains within 104 "
            "calculation steps after the interpolator stands)");
  for (int k = 0; k < 104; ++k) st.step(&x);
  EXPECT_EQ(st.position()[0], x);
  EXPECT_EQ(st.speed()[0], 0.0);
  EXPECT_TRUE(st.configure_spline(100, 1'000'000).ok());
  EXPECT_EQ(st.spline().delay_steps(), 100);
  st.step(&x);
  EXPECT_EQ(st.position()[0], x);
}

}  // namespace
}  // namespace tgm
