// In-process compile throughput on a generated CAM-like program (short G1 moves, small arcs).
// The whole-process comparison with LinuxCNC's rs274 is compile_bench.sh; results in
// BENCHMARKS.md ("Compiler").
#include <benchmark/benchmark.h>

#include <string>

#include "gen/cam_program.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"

namespace {

constexpr long kLines = 100'000;

const std::string& program(bool incremental) {
  static const std::string abs = [] {
    std::string s;
    tgm::bench::generate_cam_program(s, kLines, 1, false);
    return s;
  }();
  static const std::string inc = [] {
    std::string s;
    tgm::bench::generate_cam_program(s, kLines, 1, true);
    return s;
  }();
  return incremental ? inc : abs;
}

void compile(benchmark::State& state, bool incremental, bool encode) {
  const std::string& text = program(incremental);
  tgm::CompileOptions opt;
  opt.axis_letters = "XYZ";
  opt.compiler.start_incremental = incremental;
  std::size_t segments = 0;
  for (auto _ : state) {
    tgm::CompileResult r = tgm::compile_gcode(text, opt);
    if (!r.ok()) {
      state.SkipWithError(r.errors.front().reason.c_str());
      break;
    }
    segments = r.program.segments.size();
    if (encode) {
      std::string bytes;
      tgm::encode_intercode(r.program, bytes);
      benchmark::DoNotOptimize(bytes.data());
    }
    benchmark::DoNotOptimize(r.program.segments.data());
  }
  state.counters["lines_per_s"] =
      benchmark::Counter(static_cast<double>(kLines), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["segments"] = static_cast<double>(segments);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(text.size()));
}

// The program as intercode: PackedProgram::open (checksum and a checking pass over every
// record), then a cursor reading every record, as simulate and run read them.
const std::string& intercode() {
  static const std::string bytes = [] {
    tgm::CompileOptions opt;
    opt.axis_letters = "XYZ";
    std::string b;
    tgm::encode_intercode(tgm::compile_gcode(program(false), opt).program, b);
    return b;
  }();
  return bytes;
}

void BM_OpenIntercode(benchmark::State& state) {
  std::uint64_t records = 0;
  for (auto _ : state) {
    tgm::PackedProgram p;
    std::string error;
    if (!tgm::PackedProgram::open(intercode(), p, error)) {
      state.SkipWithError(error.c_str());
      break;
    }
    records = p.size();
  }
  state.counters["records_per_s"] = benchmark::Counter(
      static_cast<double>(records), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_ReadIntercode(benchmark::State& state) {
  tgm::PackedProgram p;
  std::string error;
  if (!tgm::PackedProgram::open(intercode(), p, error)) state.SkipWithError(error.c_str());
  for (auto _ : state) {
    auto cursor = p.cursor();
    tgm::Segment s;
    double sum = 0.0;
    while (cursor.next(s)) sum += s.end[0];
    benchmark::DoNotOptimize(sum);
  }
  state.counters["records_per_s"] = benchmark::Counter(
      static_cast<double>(p.size()), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_CompileCamG90(benchmark::State& s) { compile(s, false, false); }
void BM_CompileCamG91(benchmark::State& s) { compile(s, true, false); }
void BM_CompileAndEncodeCamG90(benchmark::State& s) { compile(s, false, true); }

}  // namespace

BENCHMARK(BM_CompileCamG90)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CompileCamG91)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CompileAndEncodeCamG90)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_OpenIntercode)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ReadIntercode)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
