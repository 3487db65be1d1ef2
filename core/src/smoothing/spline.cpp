// Spline smoothing: exact delay of N calculation steps; jerk excesses smoothed by a kernel that
// keeps cubics, computed with an exact wrapping integer chain in O(axes) per step.
// Derivation and figures: core/SMOOTHING.md, "Spline".
#include <algorithm>
#include <cmath>
#include <string>

#include "tgm/smoothing.hpp"

namespace tgm {

namespace {

using U = detail::SplineInt;
__extension__ typedef __int128 S;

constexpr int kRing = 512;  // > kSplineMaxPoints + 4: every lag the step reads
constexpr std::uint64_t kMask = kRing - 1;
static_assert(kRing > kSplineMaxPoints + 4);
//! Quantum of the smoothed third differences [mm] (2^-40 mm, about 1e-12 mm).
constexpr double kQuantum = 1.0 / 1099511627776.0;
//! Largest |third difference| that is quantized [mm]; beyond, it is clamped (never in practice).
constexpr double kMaxD3 = 1e6;
//! since_flag_ value meaning "no flagged step in reach".
constexpr std::uint64_t kNever = 1u << 20;

RequestResult refuse(RequestCode c, std::string why) { return {c, std::move(why)}; }

U u128(std::int64_t v) { return static_cast<U>(static_cast<S>(v)); }
double to_double(U v) { return static_cast<double>(static_cast<S>(v)); }

}  // namespace

SplineSmoother::SplineSmoother(double calc_step_s)
    : dt_(calc_step_s),
      xin_(static_cast<std::size_t>(kRing) * kMaxAxes, 0.0),
      xs_(static_cast<std::size_t>(kRing) * kMaxAxes, 0),
      r1_(static_cast<std::size_t>(kRing) * kMaxAxes, 0),
      r2_(static_cast<std::size_t>(kRing) * kMaxAxes, 0) {}

RequestResult SplineSmoother::check(std::int64_t points, std::int64_t jerk_mm_s3) {
  if (points != 0 && (points < kSplineMinPoints || points > kSplineMaxPoints)) {
    return refuse(RequestCode::kOutOfRange,
                  "Spline points (Command_Parameter[0]) must be 0 (off) or 50..500, not " +
                      std::to_string(points));
  }
  if (points != 0 && jerk_mm_s3 <= 0) {
    return refuse(RequestCode::kOutOfRange,
                  "Spline jerk limit (Command_Parameter[1]) must be > 0 mm/s^3, not " +
                      std::to_string(jerk_mm_s3));
  }
  return {};
}

RequestResult SplineSmoother::configure(int points, double jerk_mm_s3, int axes,
                                        const double* position_mm) {
  RequestResult r = check(points, 1);
  if (!r.ok()) return r;
  if (points != 0 && !(std::isfinite(jerk_mm_s3) && jerk_mm_s3 > 0.0)) {
    return refuse(RequestCode::kOutOfRange, "Spline jerk limit must be > 0 mm/s^3");
  }
  if (axes < 1 || axes > kMaxAxes) return refuse(RequestCode::kInvalid, "Spline: axes must be 1..10");
  axes_ = axes;
  n_ = points;
  jerk_ = points == 0 ? 0.0 : jerk_mm_s3;
  lim_d3_ = jerk_ * dt_ * dt_ * dt_;
  if (n_ > 0) {
    // Kernel K = (alpha B_M1^2 + beta B_M2^2) / D: two discrete triangles (box convolved with
    // itself) of half-widths M1 < M2, weights chosen so sum K = 1 and sum j^2 K = 0.
    m2_ = n_ + 1;
    m1_ = m2_ / 2;
    const std::int64_t a2 = static_cast<std::int64_t>(m2_) * m2_;
    const std::int64_t a1 = static_cast<std::int64_t>(m1_) * m1_;
    alpha_ = u128((a2 - 1) * a2);
    beta_ = u128(-(a1 - 1) * a1);
    d_ = static_cast<U>(a1) * static_cast<U>(a2) * static_cast<U>(a2 - a1);
    scale_ = kQuantum / to_double(d_);
    compute_kernel_figures();
  }
  reset(position_mm);
  return {};
}

void SplineSmoother::compute_kernel_figures() {
  const double d = to_double(d_), a = to_double(alpha_), b = static_cast<double>(static_cast<S>(beta_));
  gain_dv_ = gain_da_ = undershoot_ = 0.0;
  double prev = 0.0, run = 0.0;
  for (int j = -m2_; j <= m2_; ++j) {
    const int aj = std::abs(j);
    const double t1 = aj < m1_ ? m1_ - aj : 0.0, t2 = aj < m2_ ? m2_ - aj : 0.0;
    const double k = (a * t1 + b * t2) / d;
    gain_dv_ = std::max(gain_dv_, std::fabs(k - prev));
    gain_da_ = std::max(gain_da_, std::fabs(k));
    run += k;
    undershoot_ = std::min(undershoot_, run);
    prev = k;
  }
}

void SplineSmoother::reset(const double* position_mm) {
  for (std::size_t s = 0; s < static_cast<std::size_t>(kRing); ++s) {
    for (int i = 0; i < kMaxAxes; ++i) {
      const std::size_t at = s * kMaxAxes + static_cast<std::size_t>(i);
      xin_[at] = i < axes_ ? position_mm[i] : 0.0;
      xs_[at] = r1_[at] = r2_[at] = 0;
    }
  }
  s1_.fill(0);
  s2_.fill(0);
  s3_.fill(0);
  b1_.fill(0);
  bb1_.fill(0);
  b2_.fill(0);
  bb2_.fill(0);
  k_ = 0;
  quiet_ = static_cast<std::uint64_t>(2 * kSplineMaxPoints + 4);
  in_pass_ = false;
  since_flag_ = kNever + 1;
  stats_.current_pass_mm = 0.0;
}

void SplineSmoother::clear_stats() { stats_ = SplineStats{}; }

bool SplineSmoother::settled() const {
  // The output is the input of N steps ago plus the correction: the first is final once the
  // input has stood for N + 1 steps, the second is 0 from 2N - 2 steps after the last flagged
  // step on (see the end of step()); one step of margin on each. A flagged step comes at most
  // two steps after the input's last change, so 2N + 4 quiet steps imply both.
  const auto n = static_cast<std::uint64_t>(n_);
  return n_ == 0 || (quiet_ >= n + 2 && since_flag_ >= 2 * n + 2);
}

void SplineSmoother::step(const double* in_mm, double* out_mm) {
  if (n_ == 0) {
    for (int i = 0; i < axes_; ++i) out_mm[i] = in_mm[i];
    return;
  }
  const std::size_t ax = kMaxAxes;
  const std::uint64_t k = k_;
  const std::size_t now = (k & kMask) * ax;
  const std::size_t p1 = ((k - 1) & kMask) * ax, p2 = ((k - 2) & kMask) * ax, p3 = ((k - 3) & kMask) * ax;
  const auto n = static_cast<std::uint64_t>(n_), m1 = static_cast<std::uint64_t>(m1_),
             m2 = static_cast<std::uint64_t>(m2_);
  const std::uint64_t d1 = n - (m1 - 1);  // delay that centres the M1 triangle at lag N
  const std::size_t out_at = ((k - n) & kMask) * ax;
  const std::size_t lag_m2 = ((k - m2) & kMask) * ax;
  const std::size_t lag_m1 = ((k - m1) & kMask) * ax;
  const std::size_t lag_d1 = ((k - d1) & kMask) * ax;
  const std::size_t lag_d1m1 = ((k - d1 - m1) & kMask) * ax;

  // Third differences; a step is flagged when any axis exceeds the jerk limit. At a flagged
  // step the whole third difference of every axis goes to the smoothed part.
  double d3[kMaxAxes];
  bool flagged = false, changed = false;
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const double x = in_mm[i];
    // As differences of differences: a standing input gives exactly 0 at any position (the
    // expanded x - 3 x1 + 3 x2 - x3 left rounding noise of ~1e-10 mm at 1e6 mm, which a jerk
    // limit of a few mm/s^3 flagged at every step: a smoothing pass that never ended).
    const double v1 = x - xin_[p1 + ui], v2 = xin_[p1 + ui] - xin_[p2 + ui],
                 v3 = xin_[p2 + ui] - xin_[p3 + ui];
    d3[i] = (v1 - v2) - (v2 - v3);
    flagged |= std::fabs(d3[i]) > lim_d3_;
    changed |= x != xin_[p1 + ui];
    xin_[now + ui] = x;
  }
  quiet_ = changed ? 0 : quiet_ + 1;
  if (flagged) {
    ++stats_.flagged_steps;
    since_flag_ = 0;
  } else if (since_flag_ <= kNever) {
    ++since_flag_;
  }

  double norm2 = 0.0;
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    std::int64_t e = 0;
    if (flagged) e = std::llround(std::clamp(d3[i], -kMaxD3, kMaxD3) / kQuantum);
    // xs = triple sum of the flagged third differences: the non-smooth part of the input.
    s1_[ui] += u128(e);
    s2_[ui] += s1_[ui];
    s3_[ui] += s2_[ui];
    const U xs = s3_[ui];
    xs_[now + ui] = xs;
    // B_M2^2 xs centred at lag M2 - 1 = N.
    b2_[ui] += xs - xs_[lag_m2 + ui];
    r2_[now + ui] = b2_[ui];
    bb2_[ui] += b2_[ui] - r2_[lag_m2 + ui];
    // B_M1^2 of xs delayed by d1, centred at lag d1 + M1 - 1 = N.
    b1_[ui] += xs_[lag_d1 + ui] - xs_[lag_d1m1 + ui];
    r1_[now + ui] = b1_[ui];
    bb1_[ui] += b1_[ui] - r1_[lag_m1 + ui];
    // D (K - delta) * xs at the output sample, exact modulo 2^128 (the true value is small).
    const U corr = alpha_ * bb1_[ui] + beta_ * bb2_[ui] - d_ * xs_[out_at + ui];
    const double c = corr == 0 ? 0.0 : to_double(corr) * scale_;
    out_mm[i] = xin_[out_at + ui] + c;
    if (c != 0.0) {
      norm2 += c * c;
      stats_.max_axis_mm[ui] = std::max(stats_.max_axis_mm[ui], std::fabs(c));
    }
  }
  // A pass lasts while a flagged step is close enough to change the output: with the last
  // flagged step s, xs is one quadratic from s - 2 on, and the window [k - 2N, k] of the input
  // (the kernel's reach) lies in it, so the correction is 0, once k - s >= 2N - 2.
  if (since_flag_ <= static_cast<std::uint64_t>(2 * n_)) {
    in_pass_ = true;
    if (norm2 > 0.0) {
      stats_.current_pass_mm = std::max(stats_.current_pass_mm, std::sqrt(norm2));
      stats_.max_mm = std::max(stats_.max_mm, stats_.current_pass_mm);
    }
  } else if (in_pass_) {
    in_pass_ = false;
    ++stats_.passes;
    stats_.last_pass_mm = stats_.current_pass_mm;
    stats_.current_pass_mm = 0.0;
  }
  k_ = k + 1;
}

}  // namespace tgm
