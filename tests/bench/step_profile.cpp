// tgm_step_profile: which steps of BM_StepReplay's program are the slowest, and what they do.
//
//   tgm_step_profile [--axes N] [--steps N] [--top N]
//   valgrind --tool=callgrind --instr-atstart=no tgm_step_profile --callgrind K[,K...]
//
// The program, machine and ring (1,000 records) are BM_StepReplay/N/0's (bench_motion.cpp), and
// the steps are numbered as it numbers them. Timed (the default), every step over 1 us is run
// again seven times from a copy of the state before it and keeps its fastest time, so a
// preemption does not count; the tool prints mean, p99.9 and maximum and the slowest steps by
// number. Timings swing with the host; with --callgrind the listed steps' instructions are
// counted instead (deterministic): each gets a callgrind dump of its own, "step K", and
// instrumentation is off between them, so a profile of a step late in the program takes
// seconds. tests/bench/BENCHMARKS.md, session 87, shows what the slowest steps did.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define TGM_HAVE_CALLGRIND 1
#else
#define TGM_HAVE_CALLGRIND 0
#endif

#include "gen/motion_programs.hpp"
#include "tgm/cli_args.hpp"

namespace {

constexpr const char* kUsage =
    "usage: tgm_step_profile [--axes N] [--steps N] [--top N] [--callgrind K[,K...]]\n"
    "Steps BM_StepReplay's CAM-like program (tests/bench/bench_motion.cpp) through one\n"
    "interpolator and finds its slowest step() calls.\n"
    "  --axes N            axes, 1..10 (default 10)\n"
    "  --steps N           steps, 1..10000000 (default 200000, as BM_StepReplay)\n"
    "  --top N             slowest steps listed, 0..1000 (default 20)\n"
    "  --callgrind K,...   no timing: run under valgrind --tool=callgrind --instr-atstart=no\n"
    "                      and each listed step (0..steps-1) gets a dump of its own\n"
    "                      instructions, named 'step K' (the dump at the program's end\n"
    "                      holds nothing of use)\n";

// "12,40,7" -> {7, 12, 40}; false (and `error`) on anything but whole numbers 0..limit-1.
bool parse_steps(const std::string& text, long long limit, std::vector<long long>& out,
                 std::string& error) {
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = std::min(text.find(',', pos), text.size());
    const std::string item = text.substr(pos, comma - pos);
    char* end = nullptr;
    const long long k = item.empty() ? -1 : std::strtoll(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || k < 0 || k >= limit) {
      error = "--callgrind: '" + item + "' is not a step number 0.." + std::to_string(limit - 1);
      return false;
    }
    out.push_back(k);
    pos = comma + 1;
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  int axes = 10, top = 20;
  long long steps = 200'000;
  std::string picked;
  tgm::cli::ArgReader args(argc, argv, "tgm_step_profile");
  while (args.more()) {
    if (args.help_flag()) {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (args.whole_flag("--axes", 1, tgm::kMaxAxes, axes) ||
        args.whole_flag("--steps", 1LL, 10'000'000LL, steps) ||
        args.whole_flag("--top", 0, 1000, top) || args.flag("--callgrind", picked)) {
      continue;
    }
    return args.fail();
  }
  if (args.failed()) return 2;
  std::vector<long long> pick;
  if (!picked.empty()) {
    std::string error;
    if (!parse_steps(picked, steps, pick, error)) return args.usage_error(error);
#if TGM_HAVE_CALLGRIND
    // Outside valgrind the requests do nothing, and the run would count nothing in silence.
    if (!RUNNING_ON_VALGRIND) {
      return args.usage_error(
          "--callgrind counts only under valgrind --tool=callgrind --instr-atstart=no");
    }
#else
    return args.usage_error(
        "--callgrind: built without valgrind/callgrind.h (apt-get install valgrind, then "
        "rebuild)");
#endif
  }

  tgm::MachineConfig m = tgm::bench::machine_with_axes(axes);
  m.interpolators[0].buffer_size = 1000;  // BM_StepReplay's ring
  const tgm::Program prog = tgm::bench::cam_program(axes, 200000, 42);
  auto ip = tgm::Interpolator::create(m, 0);
  auto snap = tgm::Interpolator::create(m, 0);
  if (!ip || !snap) {
    std::fprintf(stderr, "tgm_step_profile: the benchmark machine does not build\n");
    return 1;
  }
  ip->set_position({});
  std::size_t next = 0;
  std::vector<std::pair<double, long long>> timed;  // (fastest ns, step)
  if (pick.empty()) timed.reserve(static_cast<std::size_t>(steps));
  std::size_t p = 0;
  for (long long k = 0; k < steps; ++k) {
    // The step numbers count the loop's passes, as BM_StepReplay's iterations do, the passes
    // that only restart an ended program included.
    const auto& r = tgm::bench::play_between_cycles(*ip, prog, next);
    if (r.status == 3) {
      if (p < pick.size() && pick[p] == k) {
        std::fprintf(stderr,
                     "tgm_step_profile: pass %lld runs no step (it restarts the ended program)\n",
                     k);
        return 1;
      }
      ip->clear();
      ip->set_position({});
      next = 0;
      continue;
    }
    if (!pick.empty()) {
      if (p < pick.size() && pick[p] == k) {
#if TGM_HAVE_CALLGRIND
        CALLGRIND_START_INSTRUMENTATION;
        CALLGRIND_ZERO_STATS;
        ip->step();
        const std::string name = "step " + std::to_string(k);
        CALLGRIND_DUMP_STATS_AT(name.c_str());
        CALLGRIND_ZERO_STATS;
        CALLGRIND_STOP_INSTRUMENTATION;
#endif
        ++p;
      } else {
        ip->step();
      }
      continue;
    }
    const double ns = tgm::bench::timed_step(*ip, *snap).ns;
    timed.emplace_back(ns, k);
    if ((k + 1) % 20000 == 0) std::fprintf(stderr, "\r%lld / %lld steps", k + 1, steps);
  }
  if (pick.empty()) {
    std::fprintf(stderr, "\r%*s\r", 40, "");
    if (timed.empty()) {
      std::printf("no step ran\n");
      return 0;
    }
    double sum = 0.0;
    for (const auto& t : timed) sum += t.first;
    std::sort(timed.begin(), timed.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    std::printf("%zu steps, %d axes: mean %.0f ns, p99.9 %.0f ns, max %.0f ns\n", timed.size(),
                axes, sum / static_cast<double>(timed.size()), timed[timed.size() / 1000].first,
                timed.front().first);
    std::printf("slowest steps (number, ns):");
    for (std::size_t i = 0; i < std::min(timed.size(), static_cast<std::size_t>(top)); ++i) {
      std::printf("%s%lld %.0f", i % 8 == 0 ? "\n  " : ", ", timed[i].second, timed[i].first);
    }
    std::printf("\n");
  }
  return 0;
}
