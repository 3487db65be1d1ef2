// Ratio, Offset, backlash compensation and PositionInc (core/SMOOTHING.md, "Output stage").
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "tgm/output_stage.hpp"
#include "tgm/printable.hpp"

namespace tgm {

namespace {

RequestResult refuse(RequestCode c, std::string why) { return {c, std::move(why)}; }

// Peaks of the minimum-jerk quintic's derivatives on [0, 1] (the backlash ramp, update()).
constexpr double kQuinticPeakVelocity = 15.0 / 8.0;
constexpr double kQuinticPeakAcceleration = 5.773502691896257645;  // 10 / sqrt(3)
constexpr double kQuinticPeakJerk = 60.0;

}  // namespace

OutputStage::OutputStage(const InterpolatorConfig& config)
    : axes_(std::min(static_cast<int>(config.axes.size()), kMaxAxes)) {
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const AxisConfig& a = config.axes[ui];
    ratio_[ui] = a.ratio_inc_per_mm;
    half_backlash_[ui] = 0.5 * a.backlash_mm;
    // The planner leaves this share of the limits free on an axis with backlash
    // (planned_limit_share): motion and ramp together stay within the limits.
    ramp_v_[ui] = a.backlash_ramp_share * a.max_velocity_mm_s;
    ramp_a_[ui] = a.backlash_ramp_share * a.max_acceleration_mm_s2;
    ramp_j_[ui] = a.backlash_ramp_share * a.max_jerk_mm_s3;
  }
}

void OutputStage::reset(const double* position_mm) {
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    pos_[ui] = extreme_[ui] = position_mm[i];
  }
}

void OutputStage::update(const double* position_mm, double dt_s) {
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const double p = position_mm[i];
    pos_[ui] = p;
    // Direction: follow the extreme in the current direction; a reversal is travel of more than
    // the threshold back from it, and more than one increment: the spline overshoots an axis
    // that stops at a corner by 0.25..0.5 um, which PositionInc at 1,000 inc/mm never shows,
    // and the whole backlash was driven back and forth for it (review of session 82).
    const double threshold = std::max(kReversalThresholdMm, 1.0 / std::fabs(ratio_[ui]));
    int& d = dir_[ui];
    double& x = extreme_[ui];
    if (d == 0) {
      if (p - x > threshold) {
        d = 1;
        x = p;
      } else if (x - p > threshold) {
        d = -1;
        x = p;
      }
    } else if (d == 1) {
      if (p > x) {
        x = p;
      } else if (x - p > threshold) {
        d = -1;
        x = p;
      }
    } else {
      if (p < x) {
        x = p;
      } else if (p - x > threshold) {
        d = 1;
        x = p;
      }
    }
    // Ramp of the compensation towards +-backlash/2 (SMOOTHING.md): from rest to rest along
    // the minimum-jerk quintic s(u) = u^3 (10 - 15 u + 6 u^2), u = t / T, whose peaks are
    // |s'| = 15/8 (u = 1/2), |s''| = 10/sqrt(3) and |s'''| = 60 (u = 0 and 1); T is the
    // shortest duration that keeps the compensation's velocity, acceleration and jerk within
    // their shares. The setpoint gets no step, and its velocity none either. A reversal during
    // a ramp is taken up by the next ramp, which starts where this one comes to rest.
    double& c = comp_[ui];
    double& T = ramp_duration_[ui];
    if (T == 0.0) {
      const double target = d * half_backlash_[ui];
      if (c == target) continue;
      const double dist = std::fabs(target - c);
      ramp_from_[ui] = c;
      ramp_to_[ui] = target;
      ramp_elapsed_[ui] = 0.0;
      T = std::max({kQuinticPeakVelocity * dist / ramp_v_[ui],
                    std::sqrt(kQuinticPeakAcceleration * dist / ramp_a_[ui]),
                    std::cbrt(kQuinticPeakJerk * dist / ramp_j_[ui])});
    }
    double& t = ramp_elapsed_[ui];
    t += dt_s;
    if (!(t < T)) {
      c = ramp_to_[ui];
      comp_v_[ui] = 0.0;
      T = 0.0;
      continue;
    }
    const double u = t / T, span = ramp_to_[ui] - ramp_from_[ui];
    c = ramp_from_[ui] + span * (u * u * u * (10.0 + u * (-15.0 + 6.0 * u)));
    comp_v_[ui] = span * 30.0 * u * u * (1.0 - u) * (1.0 - u) / T;
  }
}

std::int64_t OutputStage::backlash_inc(int axis) const {
  const auto ui = static_cast<std::size_t>(axis);
  return static_cast<std::int64_t>(std::llround(comp_[ui] * ratio_[ui]));
}

std::int64_t OutputStage::position_inc(int axis) const {
  const auto ui = static_cast<std::size_t>(axis);
  return static_cast<std::int64_t>(std::llround(pos_[ui] * ratio_[ui])) + offset_[ui] +
         backlash_inc(axis);
}

void OutputStage::fill(Registers& r) const {
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    r.ratio[ui] = ratio_[ui];
    r.offset[ui] = offset_[ui];
    r.backlash[ui] = backlash_inc(i);
    r.position_inc[ui] = position_inc(i);
  }
}

RequestResult OutputStage::write_ratio(std::int64_t axis, double ratio_inc_per_mm) {
  if (axis < 0 || axis >= axes_) {
    return refuse(RequestCode::kOutOfRange, "Ratio: axis " + std::to_string(axis) + " is not 0.." +
                                                std::to_string(axes_ - 1));
  }
  const double m = std::fabs(ratio_inc_per_mm);
  if (!std::isfinite(ratio_inc_per_mm) || m < kMinRatio || m > kMaxRatio) {
    return refuse(RequestCode::kOutOfRange, "Ratio: |ratio| must be 1e-06..1e+09 inc/mm, not " +
                                                number_text(ratio_inc_per_mm));
  }
  ratio_[static_cast<std::size_t>(axis)] = ratio_inc_per_mm;
  return {};
}

RequestResult OutputStage::check_ratio(std::int64_t axis, std::int64_t numerator_inc,
                                       std::int64_t denominator_mm, int axes) {
  if (axis < 0 || axis >= axes) {
    return refuse(RequestCode::kOutOfRange,
                  "Command 1024: axis (Command_Parameter[0]) must be 0.." +
                      std::to_string(axes - 1) + ", not " + std::to_string(axis));
  }
  if (numerator_inc == 0) {
    return refuse(RequestCode::kOutOfRange,
                  "Command 1024: numerator (Command_Parameter[1]) must not be 0 inc");
  }
  if (denominator_mm <= 0) {
    return refuse(RequestCode::kOutOfRange,
                  "Command 1024: denominator (Command_Parameter[2]) must be > 0 mm, not " +
                      std::to_string(denominator_mm));
  }
  const double ratio = static_cast<double>(numerator_inc) / static_cast<double>(denominator_mm);
  if (std::fabs(ratio) < kMinRatio || std::fabs(ratio) > kMaxRatio) {
    return refuse(RequestCode::kOutOfRange,
                  "Command 1024: |numerator / denominator| must be 1e-06..1e+09 inc/mm, not " +
                      std::to_string(numerator_inc) + " / " + std::to_string(denominator_mm) +
                      " = " + number_text(ratio));
  }
  return {};
}

OutputStage::RatioFraction OutputStage::ratio_as_fraction(double ratio_inc_per_mm) {
  RatioFraction best;
  if (!std::isfinite(ratio_inc_per_mm) || ratio_inc_per_mm == 0.0) return best;
  constexpr double kMax = 2147483647.0;
  const double target = std::fabs(ratio_inc_per_mm);
  const double sign = ratio_inc_per_mm < 0.0 ? -1.0 : 1.0;
  // Convergents h/k of the continued fraction of |ratio|, while both fit: the best
  // approximations there are, and a ratio written with few decimals (3333.3333, 0.0004) ends in
  // one that is exact.
  double h_prev = 1.0, h_prev2 = 0.0, k_prev = 0.0, k_prev2 = 1.0;
  double x = target;
  double best_err = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 64; ++it) {
    const double a = std::floor(x);
    const double h = a * h_prev + h_prev2, k = a * k_prev + k_prev2;
    if (h > kMax || k > kMax) break;
    if (h >= 1.0) {
      const double q = sign * h / k;  // h and k are whole numbers below 2^31: exact in double
      const double err = std::fabs(q - ratio_inc_per_mm);
      if (err < best_err) {
        best_err = err;
        best.numerator_inc = static_cast<std::int32_t>(sign * h);
        best.denominator_mm = static_cast<std::int32_t>(k);
        best.exact = q == ratio_inc_per_mm;
        if (best.exact) break;
      }
    }
    const double frac = x - a;
    if (!(frac > 0.0)) break;
    x = 1.0 / frac;
    h_prev2 = h_prev;
    h_prev = h;
    k_prev2 = k_prev;
    k_prev = k;
  }
  return best;
}

RequestResult OutputStage::set_ratio(std::int64_t axis, std::int64_t numerator_inc,
                                     std::int64_t denominator_mm) {
  if (RequestResult r = check_ratio(axis, numerator_inc, denominator_mm, axes_); !r.ok()) return r;
  ratio_[static_cast<std::size_t>(axis)] =
      static_cast<double>(numerator_inc) / static_cast<double>(denominator_mm);
  return {};
}

RequestResult OutputStage::write_offset(std::int64_t axis, std::int64_t offset_inc) {
  if (axis < 0 || axis >= axes_) {
    return refuse(RequestCode::kOutOfRange, "Offset: axis " + std::to_string(axis) + " is not 0.." +
                                                std::to_string(axes_ - 1));
  }
  if (offset_inc < -kMaxOffsetInc || offset_inc > kMaxOffsetInc) {
    return refuse(RequestCode::kOutOfRange, "Offset: |offset| must be <= 1e15 inc, not " +
                                                std::to_string(offset_inc));
  }
  offset_[static_cast<std::size_t>(axis)] = offset_inc;
  return {};
}

double OutputStage::position_from_inc(int axis, std::int64_t inc) const {
  const auto ui = static_cast<std::size_t>(axis);
  return static_cast<double>(inc - offset_[ui] - backlash_inc(axis)) / ratio_[ui];
}

}  // namespace tgm
