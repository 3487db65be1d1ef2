#include "tgm/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "tgm/output_stage.hpp"
#include "tgm/smoothing.hpp"

namespace tgm {

namespace {
// Records decoded and appended at a time when a run reads intercode (Simulation::run).
constexpr std::size_t kFeedPiece = 512;

std::string seconds(double s) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%g s", s);
  return buf;
}
}  // namespace

std::optional<Simulation> Simulation::create(const MachineConfig& machine, const SimulationOptions& options,
                                             std::string* error) {
  InterpolatorOptions io;
  io.record_corner_events = options.check_limits;
  // The checker sees the cycles advance() runs through their trace.
  io.record_cycle_trace = options.check_limits && options.fast_forward;
  auto ip = Interpolator::create(machine, options.interpolator, io, error);
  if (!ip) return std::nullopt;
  Simulation s;
  s.opt_ = options;
  s.cycle_time_us_ = machine.cycle_time_us;
  if (options.check_limits) {
    s.checker_ =
        LimitChecker::create(ip->config(), machine.cycle_time_us, error, options.limit_share);
    if (!s.checker_) return std::nullopt;
  }
  const auto r = ip->set_rel_speed(options.rel_speed);
  if (!r.ok()) {
    if (error) *error = "rel speed: " + r.reason;
    return std::nullopt;
  }
  if (!(options.max_time_s > 0.0 && options.max_time_s <= SimulationOptions::kMaxTimeS)) {
    if (error)
      *error = "max_time_s must be > 0 and at most 1e9 s, not " + seconds(options.max_time_s);
    return std::nullopt;
  }
  for (const auto& [t, code] : options.stops) {
    if (code != 4 && code != 8) {
      if (error) {
        *error = "stop at " + std::to_string(t) + " s: Command " + std::to_string(code) +
                 " is not a stop on the trajectory (4 emergency, 8 normal)";
      }
      return std::nullopt;
    }
    if (!(t >= 0.0 && t <= options.max_time_s)) {
      if (error) {
        *error = "stop time " + seconds(t) + " is not within 0.." + seconds(options.max_time_s) +
                 " (the run's program time limit)";
      }
      return std::nullopt;
    }
  }
  if (!(options.stop_restart_s >= 0.0 && options.stop_restart_s <= 3600.0)) {
    if (error) *error = "stop_restart_s must be 0..3600 s";
    return std::nullopt;
  }
  if (options.start_mm != std::array<double, kMaxAxes>{}) {
    if (const auto placed = ip->set_position(options.start_mm); !placed.ok()) {
      if (error) *error = "start position: " + placed.reason;
      return std::nullopt;
    }
  }
  for (const auto& [code, parameter] : options.commands) {
    const auto c = ip->command(code, parameter);
    if (!c.ok()) {
      // Prefixed only where the reason does not name its Command itself ("Command -1: Command
      // -1: the axis mask ...", session 75).
      const std::string prefix = "Command " + std::to_string(code) + ": ";
      if (error) *error = c.reason.rfind(prefix, 0) == 0 ? c.reason : prefix + c.reason;
      return std::nullopt;
    }
    if (ip->registers().command_status != 0) {
      if (error) *error = "Command " + std::to_string(code) + " did not complete before the start";
      return std::nullopt;
    }
  }
  s.ip_ = std::move(ip);
  return s;
}

SimulationSummary Simulation::run(const Program& program, const std::function<void(const Registers&)>& on_cycle,
                                  const std::function<void(const BlockReport&)>& on_block) {
  return run_records(
      program.segments.size(),
      [&program](Interpolator& ip, std::size_t next, std::size_t count, bool last,
                 std::size_t* took) { return ip.append(program, next, count, last, took); },
      on_cycle, on_block);
}

SimulationSummary Simulation::run(const PackedProgram& program,
                                  const std::function<void(const Registers&)>& on_cycle,
                                  const std::function<void(const BlockReport&)>& on_block) {
  PackedProgram::Window window(program);
  return run_records(
      static_cast<std::size_t>(program.size()),
      [&window](Interpolator& ip, std::size_t next, std::size_t count, bool last,
                std::size_t* took) {
        // In pieces, each appended as a continuation of the one before (as the service's
        // batches are), so that the window decodes a piece at a time: the first feed fills the
        // whole ring, and decoded at once it held a ring's worth of records (1.5 MB for the
        // default 10,000 slots and 950 page faults: a quarter of a short program's run on a VM).
        *took = 0;
        while (true) {
          const std::size_t piece = std::min(count - *took, kFeedPiece);
          const std::size_t at = next + *took;
          const Program& records = window.from(at, piece);
          std::size_t accepted = 0;
          const RequestResult r = ip.append(records, static_cast<std::size_t>(at - window.base()),
                                            piece, last && *took + piece == count, &accepted);
          *took += accepted;
          if (!r.ok() || *took == count) return r;
        }
      },
      on_cycle, on_block);
}

SimulationSummary Simulation::run_records(std::size_t total, const AppendRecords& append,
                                          const std::function<void(const Registers&)>& on_cycle,
                                          const std::function<void(const BlockReport&)>& on_block) {
  SimulationSummary sum;
  Interpolator& ip = *ip_;
  const double T = ip.cycle_time_s();
  std::size_t next = 0;
  auto feed = [&]() -> bool {
    // During an emergency ramp the records wait for its end.
    if (next >= total || !ip.takes_records()) return true;
    std::size_t took = 0;
    // Only what fits, so a full ring is not a refusal (whose reason would be formatted).
    const std::size_t count = std::min(total - next, std::max<std::size_t>(ip.free_slots(), 1));
    const auto r = append(ip, next, count, next + count == total, &took);
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
  std::int32_t part_seen = ip.registers().act_part;
  std::size_t change = 0;
  auto changes = opt_.rel_speed_changes;
  std::sort(changes.begin(), changes.end());
  // The emulated PLC and operator count whole cycles, so stepping and advance() agree: a wait
  // of s seconds first seen after cycle c ends after cycle c + n - 1, n = max(1, ceil(s / T)).
  auto wait_cycles = [&](double s) -> std::uint64_t {
    const double n = std::ceil((s - 1e-12) / T);
    return n < 1.0 ? 1 : static_cast<std::uint64_t>(n);
  };
  // An action of the emulated PLC or operator, due `wait_cycles` after it was first seen.
  struct Due {
    bool armed = false;
    std::uint64_t at = 0;
    void arm(std::uint64_t cycle, std::uint64_t n) {
      at = cycle - 1 + n;
      armed = true;
    }
    // True (and disarmed) once `cycle` has reached it.
    bool fire(std::uint64_t cycle) {
      if (!armed || cycle < at) return false;
      armed = false;
      return true;
    }
    // `allow` cut to the cycles that may pass before it.
    std::uint64_t limit(std::uint64_t cycle, std::uint64_t allow) const {
      return armed ? std::min(allow, std::max<std::uint64_t>(at, cycle + 1) - cycle) : allow;
    }
  };
  Due m_ack, m0_start, restart;
  auto stops = opt_.stops;
  std::stable_sort(stops.begin(), stops.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  std::size_t next_stop = 0;
  bool stopped = false;  // a stop given and the motion not yet restarted
  // A start() given by the emulated operator: the next call runs one cycle, so that the PLC
  // emulation sees the registers it left (a restart into an M wait whose acknowledgement was
  // not yet armed let advance() skip the wait to the time limit: wide stop sweep seed 169
  // program 127, a feed hold given in the cycle after the motion reached an M-function). The
  // start above is one too: a program that pauses at an M0 inside it stands from the start.
  bool started = true;
  const std::uint64_t max_cycles = static_cast<std::uint64_t>(opt_.max_time_s / T) + 1;
  const bool batch = opt_.fast_forward && !on_cycle;
  std::array<std::uint64_t, 11> factor_cycles{};
  std::uint64_t cycle = 0, passes = 0;
  // The axes stand at the start before the first cycle: the checker differentiates the first
  // cycles against that, as a live run's checker does with the cycles before the start.
  if (checker_) checker_->add_cycle(ip.registers(), {});
  // The drives' setpoint velocity: Speed (Position after the spline / IIR) plus the rate of
  // the backlash compensation, as PositionInc moves.
  const OutputStage& out = ip.output();
  bool has_backlash = false;
  for (int i = 0; i < out.axes(); ++i) has_backlash = has_backlash || out.backlash_mm(i) > 0.0;
  const auto setpoint_velocity = [&](const Registers& reg) {
    std::array<double, kMaxAxes> v = reg.speed;
    for (int i = 0; i < reg.number_axes && i < out.axes(); ++i) {
      v[static_cast<std::size_t>(i)] += out.compensation_rate_mm_s(i);
    }
    return v;
  };
  std::array<double, kMaxAxes> smoothed_prev = setpoint_velocity(ip.registers());  // last cycle's
  bool smoothed_prev_valid = true;
  while (true) {
    const double t = static_cast<double>(cycle) * T;
    while (change < changes.size() && changes[change].first <= t) {
      ip.set_rel_speed(changes[change].second);
      ++change;
    }
    while (next_stop < stops.size() && stops[next_stop].first <= t) {
      if (ip.registers().status != static_cast<std::int32_t>(InterpolatorStatus::kEnded)) {
        const auto c = ip.command(stops[next_stop].second);
        if (c.ok()) {
          ++sum.stops;
          stopped = true;
          restart.armed = false;
        }
      }
      ++next_stop;
    }
    if (ip.free_slots() > 0 && !feed()) {
      sum.result = StepResult::kErrorInternal;
      break;
    }
    // Cycles that may pass before this loop has something to do.
    std::uint64_t allow = 1;
    if (batch) {
      allow = max_cycles - cycle;
      // A change or stop at time `first` applies before the first cycle c > cycle with
      // c T >= first.
      auto until = [&](double first) {
        auto c = static_cast<std::uint64_t>(std::max(0.0, std::ceil(first / T)));
        while (static_cast<double>(c) * T < first) ++c;
        while (c > cycle + 1 && static_cast<double>(c - 1) * T >= first) --c;
        return std::max<std::uint64_t>(c, cycle + 1) - cycle;
      };
      if (change < changes.size()) allow = std::min(allow, until(changes[change].first));
      if (next_stop < stops.size()) allow = std::min(allow, until(stops[next_stop].first));
      for (const Due* d : {&restart, &m_ack, &m0_start}) allow = d->limit(cycle, allow);
      // A stop not yet followed by its restart: the restart is armed after the cycle in which
      // the motion is found standing, so that cycle is run alone. (A stop given while the motion
      // already stood, its restart thereby cancelled, let the standstill be skipped to the next
      // stop or the time limit: sweep seed 1 program 50 with three emergency stops.)
      if (stopped && !restart.armed) allow = 1;
      if (started) allow = 1;
    }
    started = false;
    std::uint64_t done = 1;
    const StepResult r = batch ? ip.advance(allow, &done) : ip.step();
    cycle += done;
    const Registers& reg = ip.registers();
    for (int i = 0; i < reg.number_axes; ++i) {
      if (!std::isfinite(reg.orig_position[static_cast<std::size_t>(i)])) sum.nan = true;
    }
    if (!std::isfinite(reg.act_speed)) sum.nan = true;
    // A skip runs at constant speed, so the registers after each call see every peak of
    // Act_Speed; a block's peak inside a cycle comes with its report.
    sum.peak_speed_mm_min = std::max(sum.peak_speed_mm_min, reg.act_speed);
    for (const BlockReport& b : ip.block_reports()) {
      sum.peak_speed_mm_min = std::max(sum.peak_speed_mm_min, b.peak_mm_min);
    }
    const auto lf = static_cast<std::size_t>(reg.limit_factor);
    if (lf < factor_cycles.size()) factor_cycles[lf] += done;
    if (checker_) {
      if (batch) {
        checker_->add_trace(ip.cycle_trace(), ip.corner_events());
      } else {
        checker_->add_cycle(reg, ip.corner_events());
      }
      // The drive setpoint (Position after the smoothing, plus the backlash compensation),
      // while it does more than pass Orig_Position through (that the checker covers).
      // Acceleration from successive cycles only: a skip of several (standstill) starts the
      // difference afresh.
      // Unsmoothed, a corner's velocity step (within its tolerance, which the checker holds)
      // reaches the setpoint as it is: not an acceleration.
      const std::array<double, kMaxAxes> v = setpoint_velocity(reg);
      const bool unsmoothed = ip.smoothing().passes_through();
      if (!unsmoothed || has_backlash) {
        sum.smoothed_measured = true;
        const bool corner = unsmoothed && !ip.corner_events().empty();
        for (int i = 0; i < reg.number_axes; ++i) {
          const auto u = static_cast<std::size_t>(i);
          AxisPeaks& pk = sum.smoothed_peaks[u];
          pk.velocity_mm_s = std::max(pk.velocity_mm_s, std::fabs(v[u]));
          if (smoothed_prev_valid && done == 1 && !corner) {
            pk.acceleration_mm_s2 =
                std::max(pk.acceleration_mm_s2, std::fabs(v[u] - smoothed_prev[u]) / T);
          }
        }
      }
      smoothed_prev = v;
      smoothed_prev_valid = done == 1;
    }
    if (on_cycle) on_cycle(reg);
    if (on_block) {
      for (const BlockReport& b : ip.block_reports()) on_block(b);
    }
    if (opt_.on_part && reg.act_part != part_seen) {
      part_seen = reg.act_part;
      opt_.on_part(reg.act_part, static_cast<double>(cycle) * T);
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
    const SectionState sec = run_flag_section(reg.run_flag);
    const bool waiting_m = sec == SectionState::kWaitMFunc || sec == SectionState::kWaitMFuncEnd;
    if (reg.m_func != 0 && reg.last_cont_m_func == reg.m_func && !waiting_m) {
      ip.write_m_func(0);  // continuous M: the PLC takes note at once
    }
    if (waiting_m) {
      if (!m_ack.armed) {
        const auto it = opt_.m_ack_by_number.find(reg.m_func);
        m_ack.arm(cycle, wait_cycles(it != opt_.m_ack_by_number.end() ? it->second : opt_.m_ack_s));
      }
      if (m_ack.fire(cycle)) {
        ip.write_m_func(0);
        ++sum.m_functions;
      }
    }
    if (r == StepResult::kWaiting &&
        reg.status == static_cast<std::int32_t>(InterpolatorStatus::kReady)) {  // paused at M0
      if (!m0_start.armed) m0_start.arm(cycle, wait_cycles(opt_.m0_restart_s));
      if (m0_start.fire(cycle)) {
        ip.start();
        started = true;
        stopped = restart.armed = false;  // a stop given in the pause ends with it
      }
    }
    // The operator restarts a motion that a stop brought to rest (Status 4, or 7 after an
    // emergency stop on the trajectory).
    bool held = false;
    if (stopped && r == StepResult::kIdle &&
        (reg.status == static_cast<std::int32_t>(InterpolatorStatus::kReady) ||
         reg.status == static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped))) {
      if (!restart.armed) restart.arm(cycle, wait_cycles(opt_.stop_restart_s));
      if (restart.fire(cycle)) {
        const auto st2 = ip.start();
        if (!st2.ok()) {
          sum.result = StepResult::kIdle;
          sum.error = "start after a stop refused: " + st2.reason;
          break;
        }
        stopped = false;
        started = true;
      }
      held = true;
    }
    if (r == StepResult::kWaiting &&
        reg.status == static_cast<std::int32_t>(InterpolatorStatus::kUnderrun)) {
      // More records arrive and the HMI restarts. Fed first: a run of zero-time records longer
      // than the ring (10,000 continuous M-functions in a G26 loop) empties it within one
      // cycle, and a start on the empty ring was refused unseen; with the last records fed in
      // the next cycle, the run then ended "underrun with no more records" half-way.
      const std::size_t fed_before = next;
      if (ip.free_slots() > 0 && !feed()) {
        sum.result = StepResult::kErrorInternal;
        break;
      }
      const bool more = next > fed_before || next < total;
      const auto restarted = ip.start();
      if (restarted.ok()) {
        started = true;
        stopped = restart.armed = false;
      } else {
        sum.result = r;
        sum.error = more ? "start after an underrun refused: " + restarted.reason
                         : std::string("buffer underrun with no more records");
        break;
      }
    }
    if (r == StepResult::kIdle && !held) {
      sum.result = r;
      sum.error = "interpolator went idle (status " + std::to_string(reg.status) + ")";
      break;
    }
    if (cycle >= max_cycles) {
      sum.result = StepResult::kWorking;
      sum.error = "program time limit of " + seconds(opt_.max_time_s) + " reached";
      sum.time_limit_reached = true;
      break;
    }
    if (opt_.on_progress && ++passes % SimulationOptions::kProgressPasses == 0) {
      SimulationProgress p;
      p.cycles = cycle;
      p.program_time_s = static_cast<double>(cycle) * T;
      p.act_part = reg.act_part;
      p.act_line = reg.act_line;
      p.records = total;
      if (!opt_.on_progress(p)) {
        sum.result = StepResult::kWorking;
        sum.error = "interrupted";
        break;
      }
    }
  }
  for (std::size_t k = 0; k < factor_cycles.size(); ++k) {
    sum.factor_time_s[k] = static_cast<double>(factor_cycles[k]) * T;
  }
  const Registers& reg = ip.registers();
  sum.cycles = cycle;
  sum.program_time_s = static_cast<double>(cycle) * T;
  sum.distance_mm = reg.move_distance;
  sum.end_position = reg.orig_position;
  sum.end_position_smoothed = reg.position;
  sum.spline_deviation_mm = ip.smoothing().spline().stats().max_mm;
  sum.hard_stops = ip.hard_stops();
  if (checker_) {
    sum.peaks = checker_->peaks();
    sum.violation_count = checker_->violation_count();
    sum.violations = checker_->violations();
  }
  return sum;
}

}  // namespace tgm
