#include "tgm/simulation.hpp"

#include <algorithm>
#include <cmath>

namespace tgm {

std::optional<Simulation> Simulation::create(const MachineConfig& machine, const SimulationOptions& options,
                                             std::string* error) {
  InterpolatorOptions io;
  io.record_corner_events = options.check_limits;
  auto ip = Interpolator::create(machine, options.interpolator, io, error);
  if (!ip) return std::nullopt;
  Simulation s;
  s.opt_ = options;
  s.cycle_time_us_ = machine.cycle_time_us;
  if (options.check_limits) {
    s.checker_ = LimitChecker::create(ip->config(), machine.cycle_time_us, error);
    if (!s.checker_) return std::nullopt;
  }
  const auto r = ip->set_rel_speed(options.rel_speed);
  if (!r.ok()) {
    if (error) *error = "rel speed: " + r.reason;
    return std::nullopt;
  }
  s.ip_ = std::move(ip);
  return s;
}

SimulationSummary Simulation::run(const Program& program, const std::function<void(const Registers&)>& on_cycle,
                                  const std::function<void(const BlockReport&)>& on_block) {
  SimulationSummary sum;
  Interpolator& ip = *ip_;
  const double T = ip.cycle_time_s();
  std::size_t next = 0;
  const std::size_t total = program.segments.size();
  auto feed = [&]() -> bool {
    if (next >= total) return true;
    std::size_t took = 0;
    const auto r = ip.append(program, next, total - next, true, &took);
    next += took;
    if (!r.ok() && r.code != RequestCode::kBufferFull) {
      sum.error = "append: " + r.reason;
      return false;
    }
    return true;
  };
  if (!feed()) {
    sum.result = StepResult::kErrorInternal;
    return sum;
  }
  if (total == 0) {
    sum.error = "empty program";
    sum.result = StepResult::kErrorInternal;
    return sum;
  }
  auto st = ip.start();
  if (!st.ok()) {
    sum.error = "start: " + st.reason;
    sum.result = StepResult::kErrorInternal;
    return sum;
  }
  std::size_t change = 0;
  auto changes = opt_.rel_speed_changes;
  std::sort(changes.begin(), changes.end());
  double m_wait_left = -1.0;
  double m0_wait_left = -1.0;
  const std::uint64_t max_cycles = static_cast<std::uint64_t>(opt_.max_time_s / T) + 1;
  std::uint64_t cycle = 0;
  while (true) {
    const double t = static_cast<double>(cycle) * T;
    while (change < changes.size() && changes[change].first <= t) {
      ip.set_rel_speed(changes[change].second);
      ++change;
    }
    if (!feed()) {
      sum.result = StepResult::kErrorInternal;
      break;
    }
    const StepResult r = ip.step();
    ++cycle;
    const Registers& reg = ip.registers();
    for (int i = 0; i < reg.number_axes; ++i) {
      if (!std::isfinite(reg.orig_position[static_cast<std::size_t>(i)])) sum.nan = true;
    }
    if (!std::isfinite(reg.act_speed)) sum.nan = true;
    const auto lf = static_cast<std::size_t>(reg.limit_factor);
    if (lf < sum.factor_time_s.size()) sum.factor_time_s[lf] += T;
    if (checker_) checker_->add_cycle(reg, ip.corner_events());
    if (on_cycle) on_cycle(reg);
    if (on_block) {
      for (const BlockReport& b : ip.block_reports()) on_block(b);
    }
    if (r == StepResult::kFinished) {
      sum.result = r;
      break;
    }
    if (r == StepResult::kErrorInternal) {
      sum.result = r;
      sum.error = "internal error in step()";
      break;
    }
    if (sum.nan) {
      sum.result = StepResult::kErrorInternal;
      sum.error = "NaN in the registers";
      break;
    }
    // The emulated PLC and operator.
    if (reg.m_func != 0 && reg.last_cont_m_func == reg.m_func &&
        run_flag_section(reg.run_flag) != SectionState::kWaitMFunc &&
        run_flag_section(reg.run_flag) != SectionState::kWaitMFuncEnd) {
      ip.write_m_func(0);  // continuous M: the PLC takes note at once
    }
    if (run_flag_section(reg.run_flag) == SectionState::kWaitMFunc ||
        run_flag_section(reg.run_flag) == SectionState::kWaitMFuncEnd) {
      if (m_wait_left < 0.0) {
        const auto it = opt_.m_ack_by_number.find(reg.m_func);
        m_wait_left = it != opt_.m_ack_by_number.end() ? it->second : opt_.m_ack_s;
      }
      m_wait_left -= T;
      if (m_wait_left <= 1e-12) {
        ip.write_m_func(0);
        ++sum.m_functions;
        m_wait_left = -1.0;
      }
    }
    if (r == StepResult::kWaiting &&
        reg.status == static_cast<std::int32_t>(InterpolatorStatus::kReady)) {  // paused at M0
      if (m0_wait_left < 0.0) m0_wait_left = opt_.m0_restart_s;
      m0_wait_left -= T;
      if (m0_wait_left <= 1e-12) {
        ip.start();
        m0_wait_left = -1.0;
      }
    }
    if (r == StepResult::kWaiting &&
        reg.status == static_cast<std::int32_t>(InterpolatorStatus::kUnderrun)) {
      if (next < total) {
        ip.start();  // more records arrived: the HMI restarts
      } else {
        sum.result = r;
        sum.error = "buffer underrun with no more records";
        break;
      }
    }
    if (r == StepResult::kIdle) {
      sum.result = r;
      sum.error = "interpolator went idle (status " + std::to_string(reg.status) + ")";
      break;
    }
    if (cycle >= max_cycles) {
      sum.result = StepResult::kWorking;
      sum.error = "time limit reached";
      break;
    }
  }
  const Registers& reg = ip.registers();
  sum.cycles = cycle;
  sum.program_time_s = static_cast<double>(cycle) * T;
  sum.distance_mm = reg.move_distance;
  sum.end_position = reg.orig_position;
  sum.hard_stops = ip.hard_stops();
  if (checker_) {
    sum.peaks = checker_->peaks();
    sum.violation_count = checker_->violation_count();
    sum.violations = checker_->violations();
  }
  return sum;
}

}  // namespace tgm
