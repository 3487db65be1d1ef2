// Soak: tgm-service and tgm-plc stay up while `tgm-hmi run` runs one seeded random program
// after the other, a new HMI process (participant, readers, writers, program stream) each time.
// Every run must end exactly where the offline simulation of the same program ends, with every
// record executed and every normal M-function acknowledged once; the service's resident memory
// must not grow with the number of programs run.
//
// CI runs a few programs. A longer soak (README.md, "Tests and benchmarks"):
//   TGM_SOAK_PROGRAMS=500 build/tests/integration/tgm_service_soak_test
// TGM_SOAK_SEED picks another series of programs.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>
#include <thread>

#include "../support/splitmix64.hpp"
#include "../support/test_params.hpp"
#include "service_test_env.hpp"
#include "tgm/gcode.hpp"
#include "tgm/simulation.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {
namespace {

using namespace std::chrono_literals;
using test::Child;
using test::ServiceEnv;

constexpr auto kHang = 120s;
constexpr double kPi = 3.14159265358979323846;

// A program of the soak: G90 lines, arcs and helices in G17 (I J from the start point, the end
// on the circle), dwells, feed changes, normal (M50, M51) and continuous (M1001, M1002)
// M-functions, also several in a row with nothing between them (they reach M_Func in
// successive cycles; two equal ones differ only in m_func_count) and right before the end.
// It first goes to the origin in a straight line: each run starts where the last one ended.
struct SoakProgram {
  std::string text;
  int normal_m = 0;
  int continuous_m = 0;
};

SoakProgram soak_program(std::uint64_t seed) {
  test::SplitMix64 rng{seed};
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * rng.unit(); };
  SoakProgram p;
  char buf[160];
  p.text = "G21 G90 G17\nG0 X0 Y0 Z0\n";
  std::snprintf(buf, sizeof buf, "G1 F%.0f\n", uniform(4000, 15000));
  p.text += buf;
  double x = 0, y = 0, z = 0;
  auto line_to_random_point = [&] {
    x = uniform(-20, 20);
    y = uniform(-20, 20);
    z = rng.unit() < 0.3 ? uniform(-5, 5) : z;
    std::snprintf(buf, sizeof buf, "G1 X%.6f Y%.6f Z%.6f\n", x, y, z);
    p.text += buf;
  };
  const int blocks = 8 + static_cast<int>(rng.next() % 7);
  for (int b = 0; b < blocks; ++b) {
    const std::uint64_t what = rng.next() % 8;
    switch (what) {
      case 0:
      case 1:
      case 2:
        line_to_random_point();
        continue;
      case 3: {  // arc or helix: centre at radius r from the start, end at the swept angle
        const double r = uniform(2, 12);
        const double a0 = uniform(-kPi, kPi);
        const double cx = x - r * std::cos(a0), cy = y - r * std::sin(a0);
        const double sweep = uniform(0.3, 3 * kPi) * (rng.unit() < 0.5 ? -1 : 1);
        const double i = cx - x, j = cy - y;
        x = cx + r * std::cos(a0 + sweep);
        y = cy + r * std::sin(a0 + sweep);
        z = rng.unit() < 0.4 ? uniform(-5, 5) : z;
        // The arc runs in the sweep's direction to that end, less than one turn.
        std::snprintf(buf, sizeof buf, "%s X%.6f Y%.6f Z%.6f I%.6f J%.6f\n",
                      sweep < 0 ? "G2" : "G3", x, y, z, i, j);
        break;
      }
      case 4:
        std::snprintf(buf, sizeof buf, "M%d\n", rng.unit() < 0.5 ? 50 : 51);
        ++p.normal_m;
        break;
      case 5:
        std::snprintf(buf, sizeof buf, "M%d\n", rng.unit() < 0.5 ? 1001 : 1002);
        ++p.continuous_m;
        break;
      case 6:
        std::snprintf(buf, sizeof buf, "G4 P%.2f\n", uniform(0.01, 0.1));
        break;
      default:
        std::snprintf(buf, sizeof buf, "F%.0f\n", uniform(2000, 15000));
        break;
    }
    p.text += buf;
  }
  p.text += "M2\n";
  return p;
}

// "done: N records" and "end position X.. Y.. Z.." of `tgm-hmi run`'s summary.
struct RunSummary {
  long records = -1;
  std::array<double, 3> end{};
};
RunSummary parse_summary(const std::string& log) {
  RunSummary s;
  if (const auto at = log.find("done: "); at != std::string::npos)
    std::sscanf(log.c_str() + at, "done: %ld records", &s.records);
  s.end = test::run_end_position(log);
  return s;
}

TEST(ServiceSoak, ProgramAfterProgramEndsWhereTheSimulationEndsAndMemoryStaysBounded) {
  const std::uint64_t programs = test::env_u64("TGM_SOAK_PROGRAMS", 6);
  const std::uint64_t seed = test::env_u64("TGM_SOAK_SEED", 1);
  ASSERT_GE(programs, 3u) << "TGM_SOAK_PROGRAMS: at least 3 (memory is compared after the 2nd)";
  constexpr double kAckDelay = 0.02;
  ServiceEnv env;
  const ConfigLoad load = load_config_file(env.config());
  ASSERT_TRUE(load.config.has_value());
  const MachineConfig& machine = load.config->machine;
  SimulationOptions sim_options;
  sim_options.m_ack_s = kAckDelay;
  std::optional<Simulation> sim = Simulation::create(machine, sim_options);
  ASSERT_TRUE(sim.has_value());

  ASSERT_TRUE(env.start_service());
  Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--quiet", "--ack-delay", "0.02"},
                        env.path("plc.log")));
  // The PLC sets the basic parameters of each interpolator it finds, which only a standing
  // interpolator takes: let it find all of them before the first program starts.
  const auto found_by = std::chrono::steady_clock::now() + 30s;
  while (test::count_of(plc.log(), ": setup done (") <
             static_cast<int>(machine.interpolators.size()) &&
         std::chrono::steady_clock::now() < found_by) {
    std::this_thread::sleep_for(20ms);
  }
  int normal_total = 0;
  int continuous_total = 0;
  long rss_warm_kb = -1;
  for (std::uint64_t k = 0; k < programs; ++k) {
    const SoakProgram p = soak_program(seed * 1'000'003ull + k);
    const std::string file = env.path("soak-" + std::to_string(k + 1) + ".ngc");
    std::ofstream(file) << p.text;
    CompileResult compiled = compile_gcode(p.text, CompileOptions::from_machine(machine, 0));
    ASSERT_TRUE(compiled.ok()) << "program " << k << ":\n" << p.text;
    const SimulationSummary expected = sim->run(compiled.program);

    Child hmi;
    ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", file, "--config", env.config(), "--quiet"},
                          env.path("hmi.log")));
    const int code = hmi.wait(kHang);
    const std::string log = hmi.log();
    ASSERT_EQ(code, 0) << "program " << k << ":\n"
                       << p.text << "\n--- hmi:\n"
                       << log << "\n--- plc:\n"
                       << plc.log() << "\n--- service:\n"
                       << env.service.log();
    const RunSummary got = parse_summary(log);
    EXPECT_EQ(got.records, static_cast<long>(compiled.program.segments.size())) << log;
    for (int a = 0; a < 3; ++a) {
      // tgm-hmi prints four decimals.
      const auto i = static_cast<std::size_t>(a);
      EXPECT_NEAR(got.end[i], expected.end_position[i], 5.1e-5)
          << "program " << k << " axis " << a << "\n"
          << p.text << log;
    }
    normal_total += p.normal_m;
    continuous_total += p.continuous_m;
    const long rss_kb = test::proc_status_kb(env.service.pid(), "VmRSS");
    if (k == 1) rss_warm_kb = rss_kb;
    std::printf("soak: program %" PRIu64 "/%" PRIu64
                ": %zu records, %.2f s, %d + %d M, service "
                "RSS %ld kB\n",
                k + 1, programs, compiled.program.segments.size(), expected.program_time_s,
                p.normal_m, p.continuous_m, rss_kb);
    std::fflush(stdout);
    if (::testing::Test::HasFailure()) break;
  }
  const long rss_end_kb = test::proc_status_kb(env.service.pid(), "VmRSS");
  EXPECT_EQ(plc.interrupt(), 0);
  const std::string plc_log = plc.log();
  EXPECT_EQ(env.service.interrupt(), 0) << env.service.log();
  // How the requests fared: repeats are requests resent after 0.5 s without a reply (a lost
  // reply, or a slow one on a loaded machine); unmatched ones waited 30 s for a match.
  const std::string stats = test::read_text(env.stats_path());
  const auto field = [&](const char* name) {
    const std::string key = std::string("\"") + name + "\": ";
    const std::size_t at = stats.find(key);
    return at == std::string::npos ? -1LL : std::atoll(stats.c_str() + at + key.size());
  };
  std::printf(
      "soak: %lld requests, %lld repeated, %lld replies held for a match, %lld written "
      "unmatched after 30 s\n",
      field("requests"), field("requests_repeated"), field("replies_held_for_match"),
      field("replies_unmatched"));
  EXPECT_EQ(field("replies_unmatched"), 0) << stats;
  // Each normal M-function acknowledged once (from the event or the main loop), none refused;
  // each continuous one seen and noted once.
  EXPECT_EQ(test::count_of(plc_log, " acknowledged"), normal_total) << plc_log;
  EXPECT_EQ(test::count_of(plc_log, "refused"), 0) << plc_log;
  EXPECT_EQ(test::count_of(plc_log, " continuous: motion goes on"), continuous_total) << plc_log;
  EXPECT_EQ(test::count_of(plc_log, " noted"), continuous_total) << plc_log;
  // Memory: the service's resident set after the last program against after the second one
  // (the first runs fill Fast DDS's pools). Measured in session 27: about 17 kB more per
  // program over 120 programs, the first touch of the record ring and chunk pool reserved at
  // start, which --no-realtime leaves unlocked (README.md, "Tests and benchmarks"; with
  // mlockall the RSS is flat). The bound allows four times that plus 4 MB, so it catches a
  // leak of a program's records or a chunk per run (tens of kB and more), not that drift.
  ASSERT_GT(rss_warm_kb, 0);
  ASSERT_GT(rss_end_kb, 0);
  const long allowed_kb = 4096 + 64 * static_cast<long>(programs);
  std::printf("soak: service RSS %ld kB after program 2, %ld kB after program %" PRIu64
              " (%+.1f kB per program; allowed growth %ld kB)\n",
              rss_warm_kb, rss_end_kb, programs,
              static_cast<double>(rss_end_kb - rss_warm_kb) / static_cast<double>(programs - 2),
              allowed_kb);
#if defined(TGM_PROCESSES_ASAN)
  // AddressSanitizer keeps freed blocks in its quarantine (up to 256 MB) and adds shadow memory,
  // so the resident set grows with every allocation (+1.9 MB a program, session 48). There
  // LeakSanitizer checks the service at its exit instead: a leak makes its exit status non-zero.
  std::printf("soak: the RSS bound does not apply under AddressSanitizer\n");
#else
  EXPECT_LT(rss_end_kb - rss_warm_kb, allowed_kb) << "the service's memory grew with the programs";
#endif
}

}  // namespace
}  // namespace tgm
