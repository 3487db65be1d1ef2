#include "tgm/limit_checker.hpp"

#include <algorithm>
#include <cmath>

namespace tgm {

const char* limit_quantity_name(LimitQuantity q) {
  switch (q) {
    case LimitQuantity::kVelocity: return "velocity";
    case LimitQuantity::kAcceleration: return "acceleration";
    case LimitQuantity::kJerk: return "jerk";
    case LimitQuantity::kCornerStep: return "corner_step";
    case LimitQuantity::kMeanAcceleration:
      return "mean_acceleration";
    case LimitQuantity::kCornerAcceleration:
      return "corner_acceleration";
  }
  return "?";
}

std::optional<LimitChecker> LimitChecker::create(const InterpolatorConfig& axes, int cycle_time_us,
                                                 std::string* error, double share) {
  if (!valid_share(share)) {
    if (error) *error = "the limit share must be a number in (0, 1]";
    return std::nullopt;
  }
  if (axes.axes.empty() || axes.axes.size() > static_cast<std::size_t>(kMaxAxes) || cycle_time_us <= 0) {
    if (error) *error = "limit checker needs 1..10 axes and a positive cycle time";
    return std::nullopt;
  }
  LimitChecker c;
  c.n_ = static_cast<int>(axes.axes.size());
  c.T_ = cycle_time_us * 1e-6;
  c.k_ = window_cycles_for(c.T_);
  for (std::size_t i = 0; i < axes.axes.size(); ++i) {
    const AxisConfig& a = axes.axes[i];
    c.vmax_[i] = share * a.max_velocity_mm_s;
    c.amax_[i] = share * a.max_acceleration_mm_s2;
    c.jmax_[i] = share * a.max_jerk_mm_s3;
    c.tol_[i] = share * a.corner_velocity_tolerance_mm_s;
    c.tol_a_[i] = share * corner_acceleration_tolerance(a);
    // The emergency ramp may decelerate harder; its jerk scales with the same ratio.
    const double ratio = std::max(1.0, a.emergency_deceleration_mm_s2 / a.max_acceleration_mm_s2);
    c.emax_[i] = c.amax_[i] * ratio;
    c.ejmax_[i] = c.jmax_[i] * ratio;
  }
  c.stored_.reserve(kMaxStored);
  c.events_.reserve(256);  // corners of the last three cycles: no allocation per cycle in a service
  c.kink_dt_.reserve(256);
  return c;
}

void LimitChecker::reset() {
  samples_ = 0;
  wn_ = 0;
  em_left_ = 0;
  acc_left_.fill(0);
  events_.clear();
}

void LimitChecker::report(std::uint64_t cycle, std::int32_t line, int axis, LimitQuantity q,
                          double value, double limit) {
  ++count_;
  if (stored_.size() < kMaxStored) stored_.push_back({cycle, line, axis, q, value, limit});
}

void LimitChecker::add_cycle(const Registers& reg, std::span<const CornerEvent> events) {
  add(reg.cycle, reg.act_line, reg.status, reg.orig_position, events);
}

void LimitChecker::add_trace(std::span<const CycleTrace> trace,
                             std::span<const CornerEvent> events) {
  std::size_t e = 0;  // events in cycle order; each goes with the cycle it names
  for (const CycleTrace& t : trace) {
    const std::uint64_t last = t.cycle + t.count - 1;
    for (std::uint64_t k = 0; k < t.count; ++k) {
      const std::uint64_t c = t.cycle + k;
      const std::size_t first = e;
      while (e < events.size() && events[e].cycle <= c) ++e;
      add(c, t.line, t.status, t.orig_position, events.subspan(first, e - first));
      // Standing (a dwell, an M wait): once the history holds only this position and no corner
      // is within it, every further cycle differentiates to exactly 0 until the next event:
      // only the cycle numbers move on.
      if (k + 1 < t.count && samples_ == 4 && events_.empty() &&
          (e == events.size() || events[e].cycle > last) && history_is(t.orig_position)) {
        // The same status again: a cycle of Status 7 after the first is not part of a ramp.
        emergency_.fill(t.status == static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp));
        last_cycle_ = last;
        break;
      }
    }
  }
}

bool LimitChecker::history_is(const std::array<double, kMaxAxes>& orig) const {
  for (const auto& x : x_) {
    for (int i = 0; i < n_; ++i) {
      if (x[static_cast<std::size_t>(i)] != orig[static_cast<std::size_t>(i)]) return false;
    }
  }
  // The window too: a skipped cycle must leave it as stepping would (all at `orig`).
  if (wn_ < k_ + 2 || em_left_ > 0) return false;
  for (int k = 0; k < k_ + 2; ++k) {
    const auto& x = window_sample(k);
    for (int i = 0; i < n_; ++i) {
      if (x[static_cast<std::size_t>(i)] != orig[static_cast<std::size_t>(i)]) return false;
    }
  }
  return true;
}

void LimitChecker::add(std::uint64_t cycle, std::int32_t line, std::int32_t status,
                       const std::array<double, kMaxAxes>& orig,
                       std::span<const CornerEvent> events) {
  head_ = (head_ + 1) & 3u;
  const std::size_t s0 = slot(0);
  double xmax = 1.0;
  for (int i = 0; i < n_; ++i) {
    x_[s0][static_cast<std::size_t>(i)] = orig[static_cast<std::size_t>(i)];
    xmax = std::max(xmax, std::fabs(orig[static_cast<std::size_t>(i)]));
  }
  // Cycles must be consecutive; otherwise start a new series. (The older pairs of the history
  // were checked when they came in.)
  if (samples_ > 0 && last_cycle_ + 1 != cycle) {
    samples_ = 0;
    wn_ = 0;
    em_left_ = 0;
    acc_left_.fill(0);
  }
  last_cycle_ = cycle;
  wh_ = (wh_ + 1) % (kMaxWindow + 2);
  wx_[static_cast<std::size_t>(wh_)] = orig;
  if (wn_ < k_ + 2) ++wn_;
  // The emergency ramp's limits hold for its cycles (Status 6) and for the cycle that ends it
  // (the step to Status 7): a ramp from a crawl, or one of a high emergency / normal ratio,
  // may start and end inside one cycle and never show Status 6 (at 1 ms cycles, a stop 3 ms
  // after a start on an axis of 100 mm/s^2 and 10 mm/s^3 braked at 39 mm/s^3 and was reported
  // against the 10 mm/s^3 of normal motion).
  const auto stopped = static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped);
  emergency_[s0] = status == static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp) ||
                   (status == stopped && last_status_ != stopped);
  last_status_ = status;
  if (emergency_[s0]) {
    em_left_ = k_ + 1;
  } else if (em_left_ > 0) {
    --em_left_;
  }
  if (samples_ < 4) ++samples_;
  for (const CornerEvent& e : events) {
    events_.push_back({e.cycle, e.fraction, e.dv, e.da});
    for (int i = 0; i < n_; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const double dv = std::fabs(e.dv[ui]);
      peaks_[ui].corner_step_mm_s = std::max(peaks_[ui].corner_step_mm_s, dv);
      if (dv > tol_[ui] * (1.0 + kRelativeTolerance) + 1e-9) {
        report(cycle, line, i, LimitQuantity::kCornerStep, dv, tol_[ui]);
      }
      const double da = std::fabs(e.da_curvature[ui]);
      peaks_[ui].corner_acceleration_mm_s2 = std::max(peaks_[ui].corner_acceleration_mm_s2, da);
      if (da > tol_a_[ui] * (1.0 + kRelativeTolerance) + 1e-9) {
        report(cycle, line, i, LimitQuantity::kCornerAcceleration, da, tol_a_[ui]);
      }
    }
  }
  // Events older than the jerk window no longer matter.
  const std::uint64_t c = cycle;
  events_.erase(std::remove_if(events_.begin(), events_.end(),
                               [&](const Event& e) { return e.cycle + 3 <= c; }),
                events_.end());

  const double T = T_;
  const double ulp = 2.3e-16 * xmax;  // position rounding [mm]
  bool emergency = false;
  for (int k = 0; k < samples_; ++k) emergency = emergency || emergency_[slot(k)];
  // The samples newest first (taken once: report() below may, for all the compiler knows,
  // move the ring's head).
  const std::array<const double*, 4> xs = {x_[slot(0)].data(), x_[slot(1)].data(),
                                           x_[slot(2)].data(), x_[slot(3)].data()};
  // Sample k (0 = newest) is at time -k*T relative to now; event at (cycle - 1 + f) T - c T.
  // The time from each event to each sample, once for all axes (an event after a sample does
  // not bend it: dt <= 0).
  kink_dt_.resize(events_.size());
  for (std::size_t j = 0; j < events_.size(); ++j) {
    const Event& e = events_[j];
    const double tj = (static_cast<double>(e.cycle) - 1.0 + e.fraction - static_cast<double>(c)) * T;
    for (int k = 0; k < 4; ++k) kink_dt_[j][static_cast<std::size_t>(k)] = -k * T - tj;
  }
  // Locals, for the same reason as xs.
  const int ns = samples_;
  const std::span<const Event> evs(events_);
  const std::span<const std::array<double, 4>> kdt(kink_dt_);
  for (int i = 0; i < n_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    if (ns >= 2) {
      const double v = (xs[0][ui] - xs[1][ui]) / T;
      peaks_[ui].velocity_mm_s = std::max(peaks_[ui].velocity_mm_s, std::fabs(v));
      if (std::fabs(v) > vmax_[ui] * (1.0 + kRelativeTolerance) + 4.0 * ulp / T) {
        report(cycle, line, i, LimitQuantity::kVelocity, std::fabs(v), vmax_[ui]);
      }
    }
    if (ns >= 3) {
      double y[3];
      for (int k = 0; k < 3; ++k) {
        y[k] = xs[static_cast<std::size_t>(k)][ui];
        for (std::size_t j = 0; j < evs.size(); ++j) {
          const Event& e = evs[j];
          if (e.cycle + 2 <= c) continue;  // at or before sample 2: linear on the window
          const double dt = kdt[j][static_cast<std::size_t>(k)];
          if (dt > 0.0) y[k] -= e.dv[ui] * dt;
        }
      }
      const double a = (y[0] - 2.0 * y[1] + y[2]) / (T * T);
      const double lim = emergency ? emax_[ui] : amax_[ui];
      peaks_[ui].acceleration_mm_s2 = std::max(peaks_[ui].acceleration_mm_s2, std::fabs(a));
      if (std::fabs(a) > lim * (1.0 + kRelativeTolerance) + 8.0 * ulp / (T * T)) {
        report(cycle, line, i, LimitQuantity::kAcceleration, std::fabs(a), lim);
        acc_left_[ui] = k_ + 2;
      }
    }
    if (ns >= 4) {
      double z[4];
      for (int k = 0; k < 4; ++k) {
        z[k] = xs[static_cast<std::size_t>(k)][ui];
        for (std::size_t j = 0; j < evs.size(); ++j) {
          const Event& e = evs[j];
          const double dt = kdt[j][static_cast<std::size_t>(k)];
          if (dt > 0.0) z[k] -= e.dv[ui] * dt + 0.5 * e.da[ui] * dt * dt;
        }
      }
      const double j = (z[0] - 3.0 * z[1] + 3.0 * z[2] - z[3]) / (T * T * T);
      const double lim = emergency ? ejmax_[ui] : jmax_[ui];
      peaks_[ui].jerk_mm_s3 = std::max(peaks_[ui].jerk_mm_s3, std::fabs(j));
      if (std::fabs(j) > lim * (1.0 + kRelativeTolerance) + 16.0 * ulp / (T * T * T)) {
        report(cycle, line, i, LimitQuantity::kJerk, std::fabs(j), lim);
      }
    }
  }
  // The velocity change over the window, corner steps included: each step may keep the
  // tolerance while many of them add up (short chords crossed several junctions a cycle and
  // gave the drives 4,000 mm/s^2 against 1,500, review of session 82). Allowed: the
  // acceleration limit over the window plus one corner's step.
  if (wn_ >= k_ + 2) {
    const auto& w0 = window_sample(0);
    const auto& w1 = window_sample(1);
    const auto& wk = window_sample(k_);
    const auto& wk1 = window_sample(k_ + 1);
    const double span = k_ * T;
    for (int i = 0; i < n_; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const double dv = ((w0[ui] - w1[ui]) - (wk[ui] - wk1[ui])) / T;
      const double lim = em_left_ > 0 ? emax_[ui] : amax_[ui];
      if (acc_left_[ui] > 0) {
        --acc_left_[ui];
        continue;
      }
      if (std::fabs(dv) > (lim * span + tol_[ui]) * (1.0 + kRelativeTolerance) + 8.0 * ulp / T) {
        report(cycle, line, i, LimitQuantity::kMeanAcceleration, std::fabs(dv) / span,
               lim + tol_[ui] / span);
      }
    }
  }
}

}  // namespace tgm
