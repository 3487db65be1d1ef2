// The machines and the CAM-like intercode program of the motion benchmarks (bench_motion.cpp)
// and of tgm_step_profile (step_profile.cpp), the PLC and operator a step replay plays between
// cycles, and how a replay times one step. Header-only. A seed builds the same program wherever the
// standard library is the same (std::uniform_real_distribution is not specified bit for bit).
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <random>

#include "../../motion/program_builder.hpp"
#include "tgm/config.hpp"
#include "tgm/interpolator.hpp"

namespace tgm::bench {

// The default machine with `axes` copies of its first axis and a ring of 10,000 records.
inline tgm::MachineConfig machine_with_axes(int axes) {
  tgm::MachineConfig m = tgm::MachineConfig::default_machine();
  auto& ip = m.interpolators[0];
  const tgm::AxisConfig base = ip.axes[0];
  ip.axes.clear();
  for (int i = 0; i < axes; ++i) {
    tgm::AxisConfig a = base;
    a.letter = tgm::default_axis_letter(i);
    ip.axes.push_back(a);
  }
  ip.buffer_size = 10000;
  return m;
}

// A CAM-like program: polylines of 0.02..0.5 mm chords along wavy curves, arcs, helices and
// longer moves, all axes moving a little, one normal M-function every 500 records.
inline tgm::Program cam_program(int axes, int records, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  tgm::test::ProgramBuilder b(axes);
  std::array<double, tgm::kMaxAxes> p{};
  double heading = 0.0;
  int count = 0;
  while (count < records) {
    const double kind = u(rng);
    if (kind < 0.7) {
      const int n = 50 + static_cast<int>(u(rng) * 200);
      const double step = 0.02 + 0.48 * u(rng);
      const double curv = (u(rng) - 0.5) * 0.4;
      for (int i = 0; i < n; ++i, ++count) {
        heading += curv * step;
        p[0] += step * std::cos(heading);
        if (axes > 1) p[1] += step * std::sin(heading);
        for (int a = 2; a < axes; ++a)
          p[static_cast<std::size_t>(a)] += 0.001 * std::sin(0.01 * count + a);
        b.line_to(p, 4000.0);
      }
    } else if (kind < 0.85 && axes >= 2) {
      const double r = 2.0 + 20.0 * u(rng);
      const std::array<double, 2> c = {p[0] - r, p[1]};
      auto e = p;
      const double ang = 0.5 + 2.0 * u(rng);
      e[0] = c[0] + r * std::cos(ang);
      e[1] = c[1] + r * std::sin(ang);
      if (axes > 2) e[2] += 1.0;
      b.arc(true, e, c, 3000.0);
      p = e;
      ++count;
    } else {
      p[0] += 20.0 * (u(rng) - 0.5);
      if (axes > 1) p[1] += 20.0 * (u(rng) - 0.5);
      b.line_to(p, 8000.0);
      ++count;
    }
    if (count % 500 < 2) {
      b.m(10, tgm::MKind::kNormal);
      ++count;
    }
  }
  b.end();
  return b.program();
}

// Between two cycles, as the PLC and the operator would: stream what fits of `prog` from
// record `next` on, acknowledge an M-function, start again after M0 or an underrun.
inline const tgm::Registers& play_between_cycles(tgm::Interpolator& ip, const tgm::Program& prog,
                                                 std::size_t& next) {
  if (next < prog.segments.size() && ip.free_slots() > 0) {
    std::size_t took = 0;
    const std::size_t c = std::min(prog.segments.size() - next, ip.free_slots());
    ip.append(prog, next, c, next + c == prog.segments.size(), &took);
    next += took;
  }
  const auto& r = ip.registers();
  if (r.m_func != 0) ip.write_m_func(0);
  if (r.status == 4 || r.status == 8) ip.start();
  return r;
}

// One step() of `ip`, timed [ns] with preemption removed: `snap` gets the state before it, and
// a step over 1 us runs again seven times from there and keeps its fastest time. first_ns is
// the first run's time (a preemption included), replayed whether it ran again.
struct TimedStep {
  double first_ns = 0.0;
  double ns = 0.0;
  bool replayed = false;
};
inline TimedStep timed_step(tgm::Interpolator& ip, tgm::Interpolator& snap) {
  using Clock = std::chrono::steady_clock;
  const auto once = [&ip] {
    const auto t0 = Clock::now();
    ip.step();
    return std::chrono::duration<double, std::nano>(Clock::now() - t0).count();
  };
  snap.copy_state_from(ip);
  TimedStep t;
  t.first_ns = t.ns = once();
  if (t.ns > 1000.0) {
    t.replayed = true;
    for (int k = 0; k < 7; ++k) {
      ip.copy_state_from(snap);
      t.ns = std::min(t.ns, once());
    }
  }
  return t;
}

}  // namespace tgm::bench
