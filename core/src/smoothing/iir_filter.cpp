// IIR filter H(s) = q / ((sT)^2 + p (sT) + q): exact step-invariant discretization per axis.
// Definitions (f = 2 % settling time, units, ranges): core/SMOOTHING.md, "IIR filter".
#include <cmath>
#include <string>

#include <Eigen/Core>
#include <unsupported/Eigen/MatrixFunctions>

#include "tgm/printable.hpp"
#include "tgm/smoothing.hpp"

namespace tgm {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kBand = 0.02;  // 2 % settling band

RequestResult refuse(RequestCode c, std::string why) { return {c, std::move(why)}; }

std::string e6(std::int64_t v) {
  // The physical value of an integer x 1e6 parameter, for messages ("1.414214", "1e-06").
  return number_text(static_cast<double>(v) * 1e-6);
}

// Step response of the normalized q / (s^2 + p s + q) at time t (closed form).
struct Normalized {
  double wn, zeta;
  double y(double t) const {
    if (zeta < 1.0 - 1e-8) {
      const double s = zeta * wn, wd = wn * std::sqrt(1.0 - zeta * zeta);
      return 1.0 - std::exp(-s * t) * (std::cos(wd * t) + s / wd * std::sin(wd * t));
    }
    if (zeta <= 1.0 + 1e-8) return 1.0 - std::exp(-wn * t) * (1.0 + wn * t);
    const double r = std::sqrt(zeta * zeta - 1.0);
    const double r1 = -wn * (zeta - r), r2 = -wn * (zeta + r);
    return 1.0 + (r2 * std::exp(r1 * t) - r1 * std::exp(r2 * t)) / (r1 - r2);
  }
};

// Root of h on [lo, hi] with h(lo) > 0 >= h(hi), by bisection to machine precision.
template <class H>
double bisect(double lo, double hi, H h) {
  for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (h(mid) > 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

double IirFilter::normalized_settling_time(double p, double q) {
  const Normalized m{std::sqrt(q), p / (2.0 * std::sqrt(q))};
  if (m.zeta < 1.0 - 1e-8) {
    // Extrema of y - 1 at t_k = k pi / wd with |y - 1| = exp(-sigma t_k). The settling time is
    // the 0.02 crossing after the last extremum outside the band (before the first peak when
    // the overshoot is within the band).
    const double s = m.zeta * m.wn, wd = m.wn * std::sqrt(1.0 - m.zeta * m.zeta);
    const double period = kPi / wd;
    int k = static_cast<int>(std::floor(std::log(1.0 / kBand) / (s * period)));
    while (k > 0 && std::exp(-s * k * period) <= kBand) --k;
    while (std::exp(-s * (k + 1) * period) > kBand) ++k;
    if (k == 0) return bisect(0.0, period, [&](double t) { return 1.0 - kBand - m.y(t); });
    const double sign = (k % 2 == 1) ? 1.0 : -1.0;  // odd extrema are overshoots
    return bisect(k * period, (k + 1) * period,
                  [&](double t) { return sign * (m.y(t) - 1.0) - kBand; });
  }
  double hi = 1.0 / m.wn;
  while (m.y(hi) < 1.0 - kBand) hi *= 2.0;
  return bisect(0.0, hi, [&](double t) { return 1.0 - kBand - m.y(t); });
}

IirFilter::IirFilter(double calc_step_s) : dt_(calc_step_s) {}

RequestResult IirFilter::check(std::int64_t p_e6, std::int64_t q_e6, std::int64_t f_e6) {
  if (p_e6 < kIirMinPQ_e6 || p_e6 > kIirMaxPQ_e6) {
    return refuse(RequestCode::kOutOfRange, "IIR p (Command_Parameter[0]) must be " +
                                                std::to_string(kIirMinPQ_e6) + ".." +
                                                std::to_string(kIirMaxPQ_e6) + " (x 1e-6), not " +
                                                std::to_string(p_e6));
  }
  if (q_e6 < kIirMinPQ_e6 || q_e6 > kIirMaxPQ_e6) {
    return refuse(RequestCode::kOutOfRange, "IIR q (Command_Parameter[1]) must be " +
                                                std::to_string(kIirMinPQ_e6) + ".." +
                                                std::to_string(kIirMaxPQ_e6) + " (x 1e-6), not " +
                                                std::to_string(q_e6));
  }
  if (f_e6 < kIirMinF_e6 || f_e6 > kIirMaxF_e6) {
    return refuse(RequestCode::kOutOfRange, "IIR f (Command_Parameter[2]) must be " +
                                                std::to_string(kIirMinF_e6) + ".." +
                                                std::to_string(kIirMaxF_e6) +
                                                " (1..2000 ms x 1e6), not " + std::to_string(f_e6));
  }
  const double zeta = static_cast<double>(p_e6) / (2.0 * std::sqrt(static_cast<double>(q_e6) * 1e6));
  if (zeta < kIirMinZeta || zeta > kIirMaxZeta) {
    return refuse(RequestCode::kOutOfRange, "IIR damping p / (2 sqrt q) = " + number_text(zeta) +
                                                " (p " + e6(p_e6) + ", q " + e6(q_e6) +
                                                ") must be 0.2..10");
  }
  return {};
}

RequestResult IirFilter::configure(const IirParams& params, int axes) {
  if (axes < 1 || axes > kMaxAxes) return refuse(RequestCode::kInvalid, "IIR: axes must be 1..10");
  const std::uint32_t mask = mask_of_axes(params.axis_mask, axes);
  const bool any = mask != 0;
  if (any) {
    RequestResult r = check(params.p_e6, params.q_e6, params.f_e6);
    if (!r.ok()) return r;
  }
  for (int i = 0; i < axes_; ++i) {
    const std::uint32_t bit = 1u << i;
    if ((mask_ & bit) && !(mask & bit) && !settled(i)) {
      const auto ui = static_cast<std::size_t>(i);
      return refuse(RequestCode::kWrongState,
                    "IIR: axis " + std::to_string(i) + " is still " + std::to_string(-e_[ui]) +
                        " mm behind Orig_Position; it can leave the mask when it has settled");
    }
  }
  if (any) {
    const double p = static_cast<double>(params.p_e6) * 1e-6;
    const double q = static_cast<double>(params.q_e6) * 1e-6;
    f_s_ = static_cast<double>(params.f_e6) * 1e-9;  // x 1e6 ms -> s
    T_ = f_s_ / normalized_settling_time(p, q);
    wn_ = std::sqrt(q) / T_;
    zeta_ = p / (2.0 * std::sqrt(q));
    Eigen::Matrix2d a;
    a << 0.0, 1.0, -wn_ * wn_, -2.0 * zeta_ * wn_;
    const Eigen::Matrix2d phi = (a * dt_).exp();
    phi_ = {phi(0, 0), phi(0, 1), phi(1, 0), phi(1, 1)};
    params_ = params;
  }
  for (int i = 0; i < axes; ++i) {
    const std::uint32_t bit = 1u << i;
    const auto ui = static_cast<std::size_t>(i);
    if (!(mask_ & bit) || i >= axes_) {  // entering (or not filtered): at rest on the input
      e_[ui] = 0.0;
      v_[ui] = 0.0;
    }
  }
  params_.axis_mask = params.axis_mask;
  mask_ = mask;
  axes_ = axes;
  return {};
}

void IirFilter::reset(const double* position_mm) {
  for (int i = 0; i < kMaxAxes; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const double p = i < axes_ ? position_mm[i] : 0.0;
    u_[ui] = p;
    e_[ui] = 0.0;
    v_[ui] = 0.0;
  }
}

void IirFilter::step(const double* in_mm, double* out_mm) {
  const double p00 = phi_[0], p01 = phi_[1], p10 = phi_[2], p11 = phi_[3];
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    const double u = in_mm[i];
    if (!(mask_ & (1u << i))) {
      u_[ui] = out_mm[i] = u;
      continue;
    }
    // Input held at u over the step: the lag e = y - u and the velocity follow x' = A x. The
    // lag behind the new input from the lag behind the last one (the inputs' difference is
    // exact for nearby values), never from the rounded position.
    const double e = e_[ui] + (u_[ui] - u), v = v_[ui];
    u_[ui] = u;
    double en = p00 * e + p01 * v;
    double vn = p10 * e + p11 * v;
    if (std::fabs(en) < 1e-12 && std::fabs(vn) < 1e-9) en = vn = 0.0;  // on the input
    e_[ui] = en;
    out_mm[i] = u + en;
    v_[ui] = vn;
  }
}

bool IirFilter::settled(int axis) const {
  if (axis < 0 || axis >= axes_ || !(mask_ & (1u << axis))) return true;
  const auto ui = static_cast<std::size_t>(axis);
  return std::fabs(e_[ui]) < 1e-9 && std::fabs(v_[ui]) < 1e-6;
}

bool IirFilter::settled() const {
  for (int i = 0; i < axes_; ++i) {
    if (!settled(i)) return false;
  }
  return true;
}

bool IirFilter::at_rest() const {
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    if ((mask_ & (1u << i)) && (e_[ui] != 0.0 || v_[ui] != 0.0)) return false;
  }
  return true;
}

}  // namespace tgm
