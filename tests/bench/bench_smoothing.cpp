// Smoothing benchmarks (figures and how to reproduce them: tests/bench/BENCHMARKS.md, "Smoothing").
//
//   BM_CalcStep/<spline points>   one calculation step of SmoothingStage (spline + IIR) on 10
//                                 axes, input with a velocity jump on every axis every 3..40
//                                 steps (the spline's integer chain works every step anyway)
//   BM_Cycle/<spline points>      one cycle: five calculation steps + OutputStage update + fill
//                                 of the registers (what Interpolator::step() adds), with the
//                                 per-cycle distribution (counters p50_ns, p99_ns, p999_ns, max_ns)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <random>
#include <vector>

#include "tgm/command_stage.hpp"
#include "tgm/output_stage.hpp"
#include "tgm/smoothing.hpp"

namespace {

using tgm::kMaxAxes;

tgm::InterpolatorConfig ten_axes() {
  tgm::InterpolatorConfig c;
  for (int i = 0; i < kMaxAxes; ++i) {
    tgm::AxisConfig a;
    a.letter = tgm::default_axis_letter(i);
    a.backlash_mm = 0.01;
    c.axes.push_back(a);
  }
  return c;
}

// Random polyline input: every axis gets a new velocity every 3..40 steps.
struct Input {
  std::mt19937_64 rng{1};
  std::uniform_real_distribution<double> u{-1.0, 1.0};
  std::uniform_int_distribution<int> len{3, 40};
  std::array<double, kMaxAxes> x{}, v{};
  int left = 0;
  const double* next(double dt) {
    if (left-- <= 0) {
      for (auto& vi : v) vi = 200.0 * u(rng);
      left = len(rng);
    }
    for (int i = 0; i < kMaxAxes; ++i) x[static_cast<std::size_t>(i)] += v[static_cast<std::size_t>(i)] * dt;
    return x.data();
  }
};

tgm::SmoothingStage make_stage(int points) {
  tgm::SmoothingStage s(kMaxAxes, 500);
  if (points > 0) s.configure_spline(points, 1'000'000);
  s.configure_iir({3'000'000, 3'000'000, 10'000'000, 0x3FF});
  return s;
}

void BM_CalcStep(benchmark::State& state) {
  tgm::SmoothingStage s = make_stage(static_cast<int>(state.range(0)));
  Input in;
  // Inputs precomputed so only the stage is timed.
  std::vector<std::array<double, kMaxAxes>> xs(1 << 16);
  for (auto& x : xs) {
    const double* p = in.next(s.calc_step_s());
    std::copy(p, p + kMaxAxes, x.begin());
  }
  std::size_t k = 0;
  for (auto _ : state) {
    s.step(xs[k].data());
    k = (k + 1) & (xs.size() - 1);
    benchmark::DoNotOptimize(s.position().data());
  }
}
BENCHMARK(BM_CalcStep)->Arg(0)->Arg(50)->Arg(200)->Arg(500);

void BM_Cycle(benchmark::State& state) {
  tgm::SmoothingStage s = make_stage(static_cast<int>(state.range(0)));
  tgm::OutputStage out(ten_axes());
  tgm::Registers reg;
  Input in;
  std::vector<std::array<double, kMaxAxes>> xs(1 << 16);
  for (auto& x : xs) {
    const double* p = in.next(s.calc_step_s());
    std::copy(p, p + kMaxAxes, x.begin());
  }
  std::vector<double> ns;
  ns.reserve(1 << 20);
  std::size_t k = 0;
  tgm::SmoothingEvent ev;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int c = 0; c < 5; ++c) {
      s.step(xs[k].data());
      k = (k + 1) & (xs.size() - 1);
      while (s.pop_event(&ev)) reg.m_func = ev.value;
    }
    out.update(s.position().data(), 500e-6);
    for (int i = 0; i < kMaxAxes; ++i) {
      reg.position[static_cast<std::size_t>(i)] = s.position()[static_cast<std::size_t>(i)];
      reg.speed[static_cast<std::size_t>(i)] = s.speed()[static_cast<std::size_t>(i)];
    }
    out.fill(reg);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(reg.position_inc.data());
    if (ns.size() < ns.capacity()) ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count());
  }
  std::sort(ns.begin(), ns.end());
  auto at = [&](double q) { return ns.empty() ? 0.0 : ns[static_cast<std::size_t>(q * static_cast<double>(ns.size() - 1))]; };
  state.counters["p50_ns"] = at(0.5);
  state.counters["p99_ns"] = at(0.99);
  state.counters["p999_ns"] = at(0.999);
  state.counters["max_ns"] = ns.empty() ? 0.0 : ns.back();
}
BENCHMARK(BM_Cycle)->Arg(0)->Arg(500);

}  // namespace

BENCHMARK_MAIN();
