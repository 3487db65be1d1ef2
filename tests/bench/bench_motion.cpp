// Motion core benchmarks (figures and how to reproduce them: tests/bench/BENCHMARKS.md, "Motion").
//
//   BM_Step/3, BM_Step/10   cost of one Interpolator::step() (one 500 us cycle, five calculation
//                           steps) on a long CAM-like program: mean (Google Benchmark time) and the
//                           per-step distribution (counters p50_ns, p99_ns, p999_ns, max_ns)
//   BM_SimulationSpeed      whole offline run (Simulation, limit checker off): program time
//                           over CPU time (counter x_realtime; x_realtime_wall: over wall time)
//   BM_SimulationRegimes    the same program by advance(): skipped share, and per limit factor
//                           the share of wall time and ns per stepped cycle
//   BM_ShortSegmentRatio    circle r = 50 mm of 0.05 mm chords at F6000, default machine:
//                           program time over the feed-limited lower bound (counter ratio)
//   BM_SimulationSpeedShortSegments  the same circle ten times: x_realtime as BM_SimulationSpeed
//   BM_SimulationSpeedManualExample  the manual's example program: x_realtime
//   BM_AppendWorst/0, /1    appends of 1,024 records into a 10,000-slot ring, the ring grown as
//                           records come (0) or built at create (1, tgm-service): mean, worst
//   BM_LimitChecker/3, /10  cost of LimitChecker::add_cycle (the live check tgm-service runs
//                           with --limit-share) per cycle of the CAM-like program: mean and max,
//                           net of the clock read measured around an empty region in the run
#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "../motion/program_builder.hpp"
#include "gen/motion_programs.hpp"
#include "tgm/cli_args.hpp"
#include "tgm/gcode.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/limit_checker.hpp"
#include "tgm/simulation.hpp"

namespace {

using tgm::MachineConfig;
using tgm::Program;
using tgm::test::ProgramBuilder;
constexpr double kPi = 3.14159265358979323846;

// The p-quantile (0..1) of ascending `sorted` (nearest rank below; 0 when empty).
double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  return sorted[std::min(sorted.size() - 1,
                         static_cast<std::size_t>(p * static_cast<double>(sorted.size())))];
}

using tgm::bench::cam_program;
using tgm::bench::machine_with_axes;
using tgm::bench::play_between_cycles;

void BM_Step(benchmark::State& state) {
  const int axes = static_cast<int>(state.range(0));
  const MachineConfig m = machine_with_axes(axes);
  const Program prog = cam_program(axes, 200000, 42);
  auto ip = tgm::Interpolator::create(m, 0);
  std::size_t next = 0;
  std::vector<double> ns;
  ns.reserve(1 << 22);
  auto restart = [&] {
    ip->clear();
    ip->set_position({});
    next = 0;
  };
  restart();
  for (auto _ : state) {
    // Feeding, acknowledging and restarting happen between cycles, outside the timed step().
    state.PauseTiming();
    if (next < prog.segments.size()) {
      std::size_t took = 0;
      ip->append(prog, next, prog.segments.size() - next, true, &took);
      next += took;
    }
    const auto& r = ip->registers();
    if (r.m_func != 0) ip->write_m_func(0);
    if (r.status == 4) ip->start();
    if (r.status == 3) {
      restart();
      ip->append(prog, 0, prog.segments.size(), true, &next);
      ip->start();
    }
    state.ResumeTiming();
    const auto t0 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(ip->step());
    const auto t1 = std::chrono::steady_clock::now();
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count());
  }
  std::sort(ns.begin(), ns.end());
  auto pct = [&](double p) { return percentile(ns, p); };
  state.counters["p50_ns"] = pct(0.5);
  state.counters["p99_ns"] = pct(0.99);
  state.counters["p999_ns"] = pct(0.999);
  state.counters["max_ns"] = ns.empty() ? 0.0 : ns.back();
}
BENCHMARK(BM_Step)->Arg(3)->Arg(10)->Iterations(400000)->Unit(benchmark::kNanosecond);

// Per-step CPU cost without OS preemption: every step is timed once; a step slower than 1 us is
// replayed 7 times from a copy of the state before it (copy_state_from) and its minimum kept, so a
// preempted run cannot inflate it while an algorithmically slow step stays slow in every replay.
// The 64 slowest steps are kept (their states) and replayed 15 times more after the run, when a
// burst of load on this shared machine that lasted through all 7 first replays has passed.
// Counters: mean / p99 / p99.9 / max of the per-step minima, the maximum before the second
// round of replays (max_first_ns), and the raw maximum.
// Second argument 1: spline 500 points (jerk limit 1e6 mm/s^3) and IIR (p 3, q 3, f 10 ms) on
// every axis, through the real Interpolator (issue 4: worst case goal 10 us).
void BM_StepReplay(benchmark::State& state) {
  const int axes = static_cast<int>(state.range(0));
  const bool smoothing = state.range(1) != 0;
  MachineConfig m = machine_with_axes(axes);
  m.interpolators[0].buffer_size = 1000;  // the state copy per step stays small
  if (smoothing) {
    m.smoothing.spline_points = 500;
    m.smoothing.spline_jerk_mm_s3 = 1e6;
    m.smoothing.iir_p_e6 = 3'000'000;
    m.smoothing.iir_q_e6 = 3'000'000;
    m.smoothing.iir_f_e6 = 10'000'000;
    m.smoothing.iir_axis_mask = (1u << axes) - 1u;
  }
  const Program prog = cam_program(axes, 200000, 42);
  auto ip = tgm::Interpolator::create(m, 0);
  auto snap = tgm::Interpolator::create(m, 0);
  std::size_t next = 0;
  std::vector<double> best;
  best.reserve(1 << 20);
  double raw_max = 0.0;
  std::size_t replayed = 0;
  // The slowest steps so far: (time, index into best, slot of the state before the step).
  constexpr std::size_t kKept = 64;
  std::vector<std::tuple<double, std::size_t, std::size_t>> slowest;  // min-heap on time
  std::vector<tgm::Interpolator> kept;
  auto by_time = [](const auto& x, const auto& y) { return std::get<0>(x) > std::get<0>(y); };
  ip->set_position({});
  for (auto _ : state) {
    const auto& r = play_between_cycles(*ip, prog, next);
    if (r.status == 3) {
      ip->clear();
      ip->set_position({});
      next = 0;
      continue;
    }
    const tgm::bench::TimedStep t = tgm::bench::timed_step(*ip, *snap);
    const double ns = t.ns;
    raw_max = std::max(raw_max, t.first_ns);
    if (t.replayed) ++replayed;
    if (slowest.size() < kKept || ns > std::get<0>(slowest.front())) {
      std::size_t slot = kept.size();
      if (slowest.size() < kKept) {
        kept.push_back(std::move(*tgm::Interpolator::create(m, 0)));
      } else {
        std::pop_heap(slowest.begin(), slowest.end(), by_time);
        slot = std::get<2>(slowest.back());
        slowest.pop_back();
      }
      kept[slot].copy_state_from(*snap);
      slowest.emplace_back(ns, best.size(), slot);
      std::push_heap(slowest.begin(), slowest.end(), by_time);
    }
    best.push_back(ns);
  }
  double max_first = 0.0;
  for (double b : best) max_first = std::max(max_first, b);
  for (const auto& [t, index, slot] : slowest) {
    for (int k = 0; k < 15; ++k) {
      ip->copy_state_from(kept[slot]);
      const auto t0 = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(ip->step());
      const auto t1 = std::chrono::steady_clock::now();
      best[index] =
          std::min(best[index], std::chrono::duration<double, std::nano>(t1 - t0).count());
    }
  }
  double sum = 0.0;
  for (double b : best) sum += b;
  std::sort(best.begin(), best.end());
  auto pct = [&](double p) { return percentile(best, p); };
  state.counters["mean_ns"] = best.empty() ? 0.0 : sum / static_cast<double>(best.size());
  state.counters["p99_ns"] = pct(0.99);
  state.counters["p999_ns"] = pct(0.999);
  state.counters["max_ns"] = best.empty() ? 0.0 : best.back();
  state.counters["max_first_ns"] = max_first;
  state.counters["raw_max_ns"] = raw_max;
  state.counters["replayed"] = static_cast<double>(replayed);
}
BENCHMARK(BM_StepReplay)
    ->Args({3, 0})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Iterations(200000)
    ->Unit(benchmark::kNanosecond);

// CPU time of this thread [s]: what a run costs, whatever else shares the machine.
double thread_cpu_s() {
  timespec t{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Program time over the CPU time of whole offline runs (counter x_realtime; BENCHMARKS.md
// quotes it so), and over their wall time (x_realtime_wall: the same on a quiet host, about
// half of it at a load of twice the cores); program_s is the program time of one run.
void measure_simulation_speed(benchmark::State& state, const MachineConfig& m, const Program& prog,
                              const std::array<double, tgm::kMaxAxes>& start = {}) {
  double program_s = 0.0, wall_s = 0.0, cpu_s = 0.0;
  for (auto _ : state) {
    tgm::SimulationOptions o;
    o.m_ack_s = 0.0;
    auto sim = tgm::Simulation::create(m, o);
    sim->interpolator().set_position(start);
    const double c0 = thread_cpu_s();
    const auto t0 = std::chrono::steady_clock::now();
    const auto s = sim->run(prog);
    wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu_s += thread_cpu_s() - c0;
    program_s += s.program_time_s;
    if (s.result != tgm::StepResult::kFinished) state.SkipWithError(s.error.c_str());
  }
  state.counters["x_realtime"] = program_s / cpu_s;
  state.counters["x_realtime_wall"] = program_s / wall_s;
  state.counters["program_s"] = program_s / static_cast<double>(state.iterations());
}

void BM_SimulationSpeed(benchmark::State& state) {
  const int axes = 3;
  measure_simulation_speed(state, machine_with_axes(axes), cam_program(axes, 50000, 7));
}
BENCHMARK(BM_SimulationSpeed)->Iterations(3)->Unit(benchmark::kMillisecond);

// Where BM_SimulationSpeed's time goes: the same program driven by Interpolator::advance as
// Simulation does, each call timed and filed under the limit factor of the cycle it ended in.
// Counters: the share of cycles skipped (cruise, dwell, waits), and per factor the share of
// the wall time and the cost of one stepped cycle. 5,000 x real time at 500 us cycles leaves
// 100 ns per cycle on average: the stepped factors show what would have to be skipped.
void BM_SimulationRegimes(benchmark::State& state) {
  const MachineConfig m = machine_with_axes(3);
  const Program prog = cam_program(3, 50000, 7);
  constexpr std::size_t kFactors = 11;
  std::array<double, kFactors> step_ns{}, stepped{};
  double skip_ns = 0.0, skipped = 0.0;
  for (auto _ : state) {
    auto ip = tgm::Interpolator::create(m, 0);
    std::size_t next = 0;
    ip->set_position({});
    while (true) {
      const auto& r = play_between_cycles(*ip, prog, next);
      std::uint64_t done = 0;
      const auto t0 = std::chrono::steady_clock::now();
      const tgm::StepResult res = ip->advance(1'000'000, &done);
      const double ns =
          std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
      const auto f = std::min<std::size_t>(static_cast<std::size_t>(r.limit_factor), kFactors - 1);
      if (done > 1) {
        skip_ns += ns;
        skipped += static_cast<double>(done);
      } else {
        step_ns[f] += ns;
        stepped[f] += 1.0;
      }
      if (res == tgm::StepResult::kFinished) break;
      if (static_cast<int>(res) < 0) {
        state.SkipWithError("interpolator error");
        break;
      }
    }
  }
  double total_ns = skip_ns, cycles = skipped;
  for (std::size_t f = 0; f < kFactors; ++f) {
    total_ns += step_ns[f];
    cycles += stepped[f];
  }
  state.counters["skipped_cycles_share"] = cycles > 0.0 ? skipped / cycles : 0.0;
  state.counters["skip_time_share"] = total_ns > 0.0 ? skip_ns / total_ns : 0.0;
  state.counters["ns_per_cycle"] = cycles > 0.0 ? total_ns / cycles : 0.0;
  for (std::size_t f = 1; f < kFactors; ++f) {
    if (stepped[f] < 1000.0) continue;
    const std::string name = tgm::limit_factor_name(static_cast<tgm::LimitFactor>(f));
    state.counters[name + "_time_share"] = step_ns[f] / total_ns;
    state.counters[name + "_ns_per_step"] = step_ns[f] / stepped[f];
  }
}
BENCHMARK(BM_SimulationRegimes)->Iterations(1)->Unit(benchmark::kMillisecond);

// The short-segment program: `laps` times around a circle r = 50 mm of 0.05 mm chords
// at F6000, from (50, 0, 0).
constexpr double kCircleR = 50.0, kCircleFeed = 6000.0;
// `decimals` > 0: the chord ends rounded to that many decimals, as CAM output writes them.
Program short_segment_circle(int laps, int decimals = 0) {
  const double chord = 0.05;
  const int n = static_cast<int>(std::ceil(2 * kPi * kCircleR / chord));
  const double scale = decimals > 0 ? std::pow(10.0, decimals) : 0.0;
  const auto round = [&](double x) { return scale > 0.0 ? std::round(x * scale) / scale : x; };
  ProgramBuilder b(3, {kCircleR, 0.0, 0.0});
  for (int lap = 0; lap < laps; ++lap) {
    for (int i = 1; i <= n; ++i) {
      const double a = 2 * kPi * i / n;
      b.line({round(kCircleR * std::cos(a)), round(kCircleR * std::sin(a)), 0.0}, kCircleFeed);
    }
  }
  b.end();
  return b.program();
}

// Arg: decimals the chord ends are rounded to (0: exact). Rounded to 3 decimals (1 um, as CAM
// posts often write), each chord's direction is off by up to 0.02 rad, twenty times the
// circle's turn per chord. Session 83's chord-turn limit took each junction's noise as a turn
// (2.544 at 3 decimals, 1.084 at 4, 1.0385 exact); the windowed one of session 84 lets the
// alternating steps cancel (1.175, 1.0385, 1.0385; at 3 decimals the corner tolerance holds
// the rest: core/MOTION.md, Planner).
void BM_ShortSegmentRatio(benchmark::State& state) {
  const Program prog = short_segment_circle(1, static_cast<int>(state.range(0)));
  double ratio = 0.0;
  for (auto _ : state) {
    auto sim = tgm::Simulation::create(MachineConfig::default_machine(), {});
    sim->interpolator().set_position({kCircleR, 0.0, 0.0});
    const auto s = sim->run(prog);
    ratio = s.program_time_s / (s.distance_mm / (kCircleFeed / 60.0));
  }
  state.counters["ratio"] = ratio;
}
BENCHMARK(BM_ShortSegmentRatio)
    ->Arg(0)
    ->Arg(4)
    ->Arg(3)
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// Simulation speed on the short-segment program (ten laps, default machine).
void BM_SimulationSpeedShortSegments(benchmark::State& state) {
  measure_simulation_speed(state, MachineConfig::default_machine(), short_segment_circle(10),
                           {kCircleR, 0.0, 0.0});
}
BENCHMARK(BM_SimulationSpeedShortSegments)->Iterations(3)->Unit(benchmark::kMillisecond);

// Simulation speed on the manual's example program (tests/programs/manual_example.ngc, default
// machine, M-functions acknowledged at once): long moves, arcs and M-functions.
void BM_SimulationSpeedManualExample(benchmark::State& state) {
  std::ifstream in(TGM_SOURCE_DIR "/tests/programs/manual_example.ngc");
  std::stringstream text;
  text << in.rdbuf();
  const MachineConfig m = MachineConfig::default_machine();
  const auto compiled = tgm::compile_gcode(text.str(), tgm::CompileOptions::from_machine(m, 0));
  if (!compiled.ok()) {
    state.SkipWithError("the manual example does not compile");
    return;
  }
  measure_simulation_speed(state, m, compiled.program);
}
BENCHMARK(BM_SimulationSpeedManualExample)->Iterations(20)->Unit(benchmark::kMillisecond);

// The live limit check's share of a cycle: add_cycle after every step() of the CAM-like
// program, each call timed, and the same clock pair around nothing after each step as the
// reference (its mean is subtracted; the maxima are reported raw, both: on a shared VM a max is
// a preemption as often as not). 0 violations expected, as in the sweeps.
void BM_LimitChecker(benchmark::State& state) {
  const int axes = static_cast<int>(state.range(0));
  const MachineConfig m = machine_with_axes(axes);
  const Program prog = cam_program(axes, 50000, 11);
  double check_ns = 0.0, clock_ns = 0.0, clock_max = 0.0, cycles = 0.0;
  double violations = 0.0;
  std::vector<double> each;
  each.reserve(1 << 20);
  tgm::InterpolatorOptions io;
  io.record_corner_events = true;  // as tgm-service with --limit-share
  for (auto _ : state) {
    auto ip = tgm::Interpolator::create(m, 0, io);
    std::string error;
    auto checker = tgm::LimitChecker::create(m.interpolators[0], m.cycle_time_us, &error, 1.0);
    if (!checker) {
      state.SkipWithError(error.c_str());
      return;
    }
    std::size_t next = 0;
    ip->set_position({});
    checker->add_cycle(ip->registers(), {});
    while (true) {
      play_between_cycles(*ip, prog, next);
      const tgm::StepResult res = ip->step();
      auto t0 = std::chrono::steady_clock::now();
      checker->add_cycle(ip->registers(), ip->corner_events());
      auto t1 = std::chrono::steady_clock::now();
      const double ns = std::chrono::duration<double, std::nano>(t1 - t0).count();
      check_ns += ns;
      each.push_back(ns);
      t0 = std::chrono::steady_clock::now();
      benchmark::ClobberMemory();
      t1 = std::chrono::steady_clock::now();
      const double empty_ns = std::chrono::duration<double, std::nano>(t1 - t0).count();
      clock_ns += empty_ns;
      clock_max = std::max(clock_max, empty_ns);
      cycles += 1.0;
      if (res == tgm::StepResult::kFinished) break;
      if (static_cast<int>(res) < 0) {
        state.SkipWithError("interpolator error");
        return;
      }
    }
    violations += static_cast<double>(checker->violation_count());
  }
  state.counters["check_mean_ns"] = cycles > 0.0 ? (check_ns - clock_ns) / cycles : 0.0;
  std::sort(each.begin(), each.end());
  state.counters["check_max_raw_ns"] = each.empty() ? 0.0 : each.back();
  state.counters["check_p99_raw_ns"] = percentile(each, 0.99);
  state.counters["check_p999_raw_ns"] = percentile(each, 0.999);
  state.counters["clock_ns"] = cycles > 0.0 ? clock_ns / cycles : 0.0;
  state.counters["clock_max_raw_ns"] = clock_max;  // what the VM's preemption alone shows
  state.counters["violations"] = violations;
}
BENCHMARK(BM_LimitChecker)->Arg(3)->Arg(10)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

// Appends on tgm-service's cycle thread (the engine's budget: 1,024 records a cycle) into an
// empty 10,000-slot ring until it is full, with the ring grown as records are stored (arg 0)
// or built at create (arg 1, InterpolatorOptions::preallocate_ring, what tgm-service uses).
// Counters: the mean append of 1,024 records and the slowest one per fill (mean over the
// fills, and the maximum). Each fill gets a new interpolator; after the first its memory comes
// back from the allocator already faulted in, as tgm-service's is locked and faulted at start.
void BM_AppendWorst(benchmark::State& state) {
  const tgm::MachineConfig m = tgm::MachineConfig::default_machine();
  tgm::InterpolatorOptions o;
  o.preallocate_ring = state.range(0) != 0;
  ProgramBuilder b(3);
  for (int i = 0; i < 10240; ++i) b.line({0.05 * (i + 1), 0.01 * (i % 2), 0.0}, 6000);
  const Program& prog = b.program();
  double sum_ns = 0.0, appends = 0.0, sum_worst = 0.0, worst = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    auto ip = tgm::Interpolator::create(m, 0, o);
    state.ResumeTiming();
    double fill_worst = 0.0;
    for (std::size_t first = 0; first + 1024 <= prog.segments.size() && ip->free_slots() > 0;
         first += 1024) {
      const std::size_t n = std::min<std::size_t>(1024, ip->free_slots());
      const auto t0 = std::chrono::steady_clock::now();
      ip->append(prog, first, n, false);
      const double ns =
          std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
      sum_ns += ns;
      appends += 1.0;
      fill_worst = std::max(fill_worst, ns);
    }
    sum_worst += fill_worst;
    worst = std::max(worst, fill_worst);
  }
  state.counters["append_mean_us"] = sum_ns / std::max(appends, 1.0) * 1e-3;
  state.counters["worst_mean_us"] = sum_worst / static_cast<double>(state.iterations()) * 1e-3;
  state.counters["worst_max_us"] = worst * 1e-3;
}
BENCHMARK(BM_AppendWorst)->Arg(0)->Arg(1)->Iterations(50)->Unit(benchmark::kMillisecond);

// The allocator as tgm-hmi sets it (large blocks from the heap, reused rather than faulted in
// afresh: tgm::cli::prefer_heap_for_large_blocks), unless --glibc-default-malloc is given, which
// measures with glibc's defaults (every block over 128 kB mapped afresh) for comparison.
int main(int argc, char** argv) {
  bool glibc_default = false;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--glibc-default-malloc") {
      glibc_default = true;
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  if (!glibc_default) tgm::cli::prefer_heap_for_large_blocks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::AddCustomContext("malloc", glibc_default ? "glibc default" : "heap (as tgm-hmi)");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
