// Spline -> IIR pipeline with the event delay line (core/SMOOTHING.md, "Pipeline", "Events").
#include <string>

#include "tgm/smoothing.hpp"

namespace tgm {

SmoothingStage::SmoothingStage(int axes, int cycle_time_us)
    : axes_(axes < 1 ? 1 : (axes > kMaxAxes ? kMaxAxes : axes)),
      dt_(cycle_time_us * 1e-6 / 5.0),
      inv_dt_(1.0 / dt_),
      spline_(dt_),
      iir_(dt_) {
  const std::array<double, kMaxAxes> zero{};
  spline_.configure(0, 0.0, axes_, zero.data());
  iir_.configure(IirParams{0, 0, 0, 0}, axes_);
}

RequestResult SmoothingStage::configure_spline(std::int64_t points, std::int64_t jerk_mm_s3) {
  RequestResult r = SplineSmoother::check(points, jerk_mm_s3);
  if (!r.ok()) return r;
  if (!spline_.settled() || ev_count_ != 0) {
    return {RequestCode::kWrongState,
            "Spline: the buffer still holds motion or M-functions (it drains within " +
                std::to_string(2 * spline_.delay_steps() + 4) +
                " calculation steps after the interpolator stands)"};
  }
  // The spline input equals its output here; the new buffer starts full of that position.
  return spline_.configure(static_cast<int>(points), static_cast<double>(jerk_mm_s3), axes_,
                           mid_.data());
}

RequestResult SmoothingStage::configure_iir(const IirParams& params) {
  return iir_.configure(params, axes_);
}

SmoothingConfig SmoothingStage::in_effect() const {
  SmoothingConfig c;
  c.spline_points = spline_.delay_steps();
  c.spline_jerk_mm_s3 = spline_.jerk_limit_mm_s3();
  const IirParams& p = iir_.params();
  c.iir_p_e6 = p.p_e6;
  c.iir_q_e6 = p.q_e6;
  c.iir_f_e6 = p.f_e6;
  c.iir_axis_mask = iir_.mask();
  return c;
}

void SmoothingStage::reset(const double* position_mm) {
  spline_.reset(position_mm);
  iir_.reset(position_mm);
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    mid_[ui] = pos_[ui] = position_mm[i];
    speed_[ui] = 0.0;
  }
  ev_head_ = ev_count_ = 0;
}

void SmoothingStage::step(const double* orig_mm) {
  if (passes_through()) {
    // Both off (the default): Position is Orig_Position. The same values as the general path
    // below, bit for bit, without its copies through two arrays (perf put a tenth of a dense
    // CAM program's simulation on the reload of the filter's output array; the bypass gained
    // 3-5 % of that run).
    iir_.pass(orig_mm);
    for (int i = 0; i < axes_; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const double x = orig_mm[i];
      speed_[ui] = (x - pos_[ui]) * inv_dt_;
      mid_[ui] = pos_[ui] = x;
    }
    ++steps_;
    return;
  }
  double out[kMaxAxes];
  spline_.step(orig_mm, mid_.data());
  iir_.step(mid_.data(), out);
  for (int i = 0; i < axes_; ++i) {
    const auto ui = static_cast<std::size_t>(i);
    speed_[ui] = (out[i] - pos_[ui]) * inv_dt_;
    pos_[ui] = out[i];
  }
  ++steps_;
}

bool SmoothingStage::push_event(const SmoothingEvent& e) {
  if (ev_count_ == kEventCapacity) return false;
  Slot& s = ev_[(ev_head_ + ev_count_) % kEventCapacity];
  s.release = steps_ + static_cast<std::uint64_t>(spline_.delay_steps());
  s.e = e;
  ++ev_count_;
  return true;
}

bool SmoothingStage::push_event_next(const SmoothingEvent& e) {
  if (ev_count_ == kEventCapacity) return false;
  Slot& s = ev_[(ev_head_ + ev_count_) % kEventCapacity];
  s.release = steps_ + 1 + static_cast<std::uint64_t>(spline_.delay_steps());
  s.e = e;
  ++ev_count_;
  return true;
}

bool SmoothingStage::pop_event(SmoothingEvent* e) {
  if (ev_count_ == 0 || ev_[ev_head_].release > steps_) return false;
  return pop_oldest(e);
}

bool SmoothingStage::pop_oldest(SmoothingEvent* e) {
  if (ev_count_ == 0) return false;
  *e = ev_[ev_head_].e;
  ev_head_ = (ev_head_ + 1) % kEventCapacity;
  --ev_count_;
  return true;
}

bool SmoothingStage::settled() const {
  return spline_.settled() && iir_.settled() && ev_count_ == 0;
}

bool SmoothingStage::at_rest() const { return settled() && iir_.at_rest(); }

void SmoothingStage::skip(std::uint64_t steps, const double* before_last_mm, const double* last_mm) {
  // A drained spline with a standing input: its output is the input, and restarting the buffer
  // there changes no later output (the correction of the old excesses is an exact integer 0
  // once the kernel's reach lies behind them, SMOOTHING.md "Exact O(axes) computation").
  const bool spline_on = spline_.delay_steps() > 0;
  if (spline_on) spline_.reset(last_mm);
  double out[kMaxAxes];
  for (int k = 0; k < 2; ++k) {
    const double* in = (k == 0 && !spline_on) ? before_last_mm : last_mm;
    for (int i = 0; i < axes_; ++i) mid_[static_cast<std::size_t>(i)] = in[i];
    iir_.step(mid_.data(), out);
    for (int i = 0; i < axes_; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      speed_[ui] = (out[i] - pos_[ui]) * inv_dt_;
      pos_[ui] = out[i];
    }
  }
  steps_ += steps;
}

}  // namespace tgm
