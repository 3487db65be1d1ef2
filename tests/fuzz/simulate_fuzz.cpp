// Fuzz target: arbitrary bytes as a G-code program that, when it compiles, runs through the
// interpolator with the limit checker on, on one of several machines (see `machine`).
//
// Invariants (issue 3, and "bad input never crashes or hangs"): whatever the compiler accepts,
// the motion core runs without an internal error, NaN or hard stop, keeps every axis within
// its velocity, acceleration and jerk limits (corners within their tolerance), and a program
// that finishes ends at its last motion's end point. The run is cut off after kMaxProgramS of
// program time (a fuzzed feed of F0.001 over a long move is slow, not wrong). Most runs also
// change the override and some give stops on the trajectory (see `Operator`); one in eight is
// resumed at the line of one of its records (block search) and run from there. A finished run
// of intercode (one in four) is timed by record again (program_times): its total is the run's,
// its times never go back, and its moves' lengths make the run's distance.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "../motion/random_program.hpp"
#include "../support/env_params.hpp"
#include "fuzz_support.hpp"
#include "tgm/config.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/program_times.hpp"
#include "tgm/resume.hpp"
#include "tgm/simulation.hpp"

namespace {

constexpr double kMaxProgramS = 20.0;

// The machine a fuzzed program runs on, picked by the input's length (reproducible from the
// input alone): the default machine at each of the manual's cycle times (the shorter the
// cycle, the more a rounding of the position weighs in its differences), the default machine
// with all ten axes, and four of the CTest sweeps' random machines (3 to 10 axes, limits that
// differ from axis to axis). With TGM_FUZZ_MACHINES=wide in the environment the random
// machines come from the wide sweep's envelope instead (sixteen of them; CTest runs that too,
// fuzz.simulate.wide.driver); with TGM_FUZZ_MACHINES=box from the whole range of limits the
// config accepts, each limit of each axis drawn on its own (sixteen; the box sweep's machines).
// Random machine k is drawn from std::mt19937_64(base + k), base 1000 (every finding so far
// names its machine that way); TGM_FUZZ_MACHINE_SEED=N in the environment makes it N, so that a
// long run can explore other machines of the same kind.
constexpr std::size_t kRandomMachines = 4;
constexpr std::size_t kEnvelopeMachines = 16;

using Machines = tgm::test::MachineKind;

Machines machine_kind() {
  static const Machines kind = [] {
    const char* e = std::getenv("TGM_FUZZ_MACHINES");
    Machines k = Machines::kRandom;
    if (e == nullptr || *e == '\0' || tgm::test::machine_kind_from_name(e, k)) return k;
    std::fprintf(stderr, "TGM_FUZZ_MACHINES must be random, wide or box, not '%s'\n", e);
    std::exit(2);
  }();
  return kind;
}

std::uint64_t machine_seed() {
  static const std::uint64_t base = [] {
    const std::uint64_t v = tgm::test::env_u64("TGM_FUZZ_MACHINE_SEED", 1000);
    if (v > (std::uint64_t{1} << 62)) {
      std::fprintf(stderr, "TGM_FUZZ_MACHINE_SEED must be at most 2^62, not %llu\n",
                   static_cast<unsigned long long>(v));
      std::exit(2);
    }
    return v;
  }();
  return base;
}

std::vector<tgm::MachineConfig> make_machines() {
  std::vector<tgm::MachineConfig> c;
  const int cycle_us[3] = {500, 250, 1000};
  for (int us : cycle_us) {
    c.push_back(tgm::MachineConfig::default_machine());
    c.back().cycle_time_us = us;
  }
  tgm::MachineConfig ten = tgm::MachineConfig::default_machine();
  std::vector<tgm::AxisConfig>& axes = ten.interpolators[0].axes;
  while (axes.size() < static_cast<std::size_t>(tgm::kMaxAxes)) {
    axes.push_back(axes.front());
    axes.back().letter = tgm::default_axis_letter(static_cast<int>(axes.size()) - 1);
  }
  c.push_back(ten);
  const Machines kind = machine_kind();
  const std::size_t n = kind == Machines::kRandom ? kRandomMachines : kEnvelopeMachines;
  for (std::size_t k = 0; k < n; ++k) {
    std::mt19937_64 rng(machine_seed() + k);
    const int n_axes = 3 + static_cast<int>(k * 7 / (n - 1));  // 3 .. 10
    c.push_back(tgm::test::machine_of_kind(kind, rng, n_axes));
  }
  return c;
}

const tgm::MachineConfig& machine(std::size_t pick) {
  static const std::vector<tgm::MachineConfig> m = make_machines();
  return m[pick % m.size()];
}

// What the operator does during the run, drawn from a hash of the input (reproducible from the
// input alone): about a third of the runs keep Rel_Speed at 1 and give no stop; the others start
// at an override of 0.05..2 and change it up to twice, and half of them also get one or two
// stops (Command 8 or 4, on the trajectory) at random times, each restarted after 0..0.5 s.
// The program still ends at its last motion's end point, and every limit holds through it.
struct Operator {
  tgm::fuzz::Rng rng{{1469598103934665603ull}};  // seeded with the input's FNV-1a hash
  explicit Operator(std::string_view text) {
    for (char c : text) rng.s = (rng.s ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  }
  double uniform() { return rng.unit(); }
  void apply(tgm::SimulationOptions& o) {
    if (uniform() < 1.0 / 3.0) return;
    o.rel_speed = 0.05 + 1.95 * uniform();
    const int changes = static_cast<int>(uniform() * 3.0);
    // One draw per statement: the order in which a call's arguments are evaluated is the
    // compiler's (GCC right to left, clang left to right), and an input found by the clang
    // fuzzer got another operator in the GCC driver.
    for (int k = 0; k < changes; ++k) {
      const double at_s = 3.0 * uniform();
      o.rel_speed_changes.emplace_back(at_s, 0.05 + 1.95 * uniform());
    }
    if (uniform() < 0.5) return;
    const int stops = 1 + static_cast<int>(uniform() * 2.0);
    for (int k = 0; k < stops; ++k) {
      const double at_s = 3.0 * uniform();
      o.stops.emplace_back(at_s, uniform() < 0.5 ? 8 : 4);
    }
    o.stop_restart_s = 0.5 * uniform();
  }
};

}  // namespace

void tgm::fuzz::prepare_seeds(std::vector<std::string>&) {}
void tgm::fuzz::prepare_tokens(std::vector<std::string>&) {}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const tgm::MachineConfig& m = machine(size);
  tgm::CompileOptions co = tgm::CompileOptions::from_machine(m, 0);
  // Loops (G26/G27 with K) stay short; a fuzzed program is about the motion, not its length.
  co.compiler.max_program_segments = 20'000;
  const tgm::CompileResult r = tgm::compile_gcode(text, co);
  if (!r.ok() || r.program.segments.empty()) return 0;

  tgm::SimulationOptions o;
  o.check_limits = true;
  o.m_ack_s = 0.002;
  o.max_time_s = kMaxProgramS;
  Operator op(text);
  op.apply(o);
  std::string error;
  std::optional<tgm::Simulation> sim = tgm::Simulation::create(m, o, &error);
  TGM_FUZZ_CHECK(sim.has_value(), "Simulation::create: " + error);
  // One run in four holds the program as intercode, as tgm-hmi simulate does: decoded a piece
  // at a time as the ring takes it (PackedProgram::Window).
  tgm::SimulationSummary s;
  if (op.uniform() < 0.25) {
    tgm::PackedProgram packed;
    TGM_FUZZ_CHECK(tgm::PackedProgram::from_program(r.program, packed, error),
                   "a compiled program does not encode: " + error);
    // Half of those resume at the line of a record (block search, tgm/resume.hpp): an approach
    // from machine zero, where the run stands, then the program's records from that line on.
    // Its last motion ends where the whole program's does.
    if (op.uniform() < 0.5) {
      const double pick = op.uniform();
      const std::size_t at =
          std::min(r.program.segments.size() - 1,
                   static_cast<std::size_t>(pick * static_cast<double>(r.program.segments.size())));
      tgm::ResumeOptions ro;
      ro.line = r.program.segments[at].line;
      ro.approach_feed_mm_per_min = 50.0 + 4950.0 * op.uniform();
      tgm::Resume resumed;
      TGM_FUZZ_CHECK(
          tgm::resume_from_line(packed, ro, resumed, error),
          "line " + std::to_string(ro.line) + " of a record cannot be resumed at: " + error);
      packed = std::move(resumed.program);
    }
    s = sim->run(packed);
    // The time by record of the same run (tgm/program_times.hpp, the time left of tgm-hmi
    // run): the run's own total, non-decreasing, and the moves' lengths make its distance.
    if (s.result == tgm::StepResult::kFinished) {
      tgm::SimulationOptions plain = o;
      plain.check_limits = false;  // the same trajectory, checked above
      const auto t = tgm::program_times(m, plain, packed, &error);
      TGM_FUZZ_CHECK(t.has_value(), "program_times of a finished run: " + error);
      TGM_FUZZ_CHECK(t->total_s == s.program_time_s,
                     "program_times total " + std::to_string(t->total_s) + " s, the run " +
                         std::to_string(s.program_time_s) + " s");
      double length = 0.0;
      for (std::size_t k = 0; k < t->done_s.size(); ++k) {
        TGM_FUZZ_CHECK(k == 0 || t->done_s[k] >= t->done_s[k - 1],
                       "record " + std::to_string(k) + " done before the one before it");
        length += static_cast<double>(t->length_mm[k]);
      }
      TGM_FUZZ_CHECK(t->done_s.back() == static_cast<float>(s.program_time_s),
                     "the last record is not done at the end");
      TGM_FUZZ_CHECK(std::fabs(length - s.distance_mm) <= 1e-6 + 1e-6 * s.distance_mm,
                     "lengths " + std::to_string(length) + " mm, the run's distance " +
                         std::to_string(s.distance_mm) + " mm");
    }
  } else {
    s = sim->run(r.program);
  }
  TGM_FUZZ_CHECK(s.result != tgm::StepResult::kErrorInternal, "internal error: " + s.error);
  TGM_FUZZ_CHECK(!s.nan, "NaN or inf in a register");
  TGM_FUZZ_CHECK(s.hard_stops == 0, std::to_string(s.hard_stops) + " hard stops");
  std::string found;
  for (const tgm::LimitViolation& v : s.violations) {
    if (found.size() > 400) break;
    found += " [line " + std::to_string(v.line) + " axis " + std::to_string(v.axis) + " " +
             tgm::limit_quantity_name(v.quantity) + " " + std::to_string(v.value) + " > " +
             std::to_string(v.limit) + "]";
  }
  TGM_FUZZ_CHECK(s.violation_count == 0,
                 std::to_string(s.violation_count) + " limit violations:" + found);
  if (s.result == tgm::StepResult::kFinished) {
    // The last motion's end point (absolute machine millimetres in the intercode).
    const tgm::Segment* last = nullptr;
    for (const tgm::Segment& g : r.program.segments) {
      if (g.is_motion()) last = &g;
    }
    for (int i = 0; last != nullptr && i < r.program.number_axes; ++i) {
      const auto k = static_cast<std::size_t>(i);
      TGM_FUZZ_CHECK(std::fabs(s.end_position[k] - last->end[k]) <= 1e-6,
                     "axis " + std::to_string(i) + " ends at " + std::to_string(s.end_position[k]) +
                         ", the program at " + std::to_string(last->end[k]));
    }
  }
  return 0;
}
