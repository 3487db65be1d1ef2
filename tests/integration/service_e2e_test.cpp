// tgm-service, tgm-plc and tgm-hmi as real processes over DDS on this machine (loopback / shared
// memory): the manual's example end to end, the M-function handshake, a late-joining HMI, role
// enforcement, and a 100,000-record program streamed into a 1,000-record buffer while it runs.
// Time bounds only guard against hangs; what is checked is counted in interpolation cycles.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "hand_request.hpp"
#include "raw_sample.hpp"
#include "service_test_env.hpp"
#include "tgm/cli_args.hpp"
#include "tgm/client/client.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/dds/topics.hpp"
#include "tgm/gcode.hpp"
#include "tgm/registers.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {
namespace {

using namespace std::chrono_literals;
using test::ServiceEnv;
namespace fdds = eprosima::fastdds::dds;

constexpr auto kHang = 60s;

// A G-code program of `records` collinear G1 X0.1 moves (G91, the default config's) at `feed`
// mm/min, then M2.
void write_tenth_steps(const std::string& path, int records, int feed) {
  std::ofstream g(path);
  g << "F" << feed << "\n";
  for (int i = 0; i < records; ++i) g << "G1 X0.1\n";
  g << "M2\n";
}

Program compile(const std::string& gcode, const std::string& config_path) {
  const ConfigLoad load = load_config_file(config_path);
  EXPECT_TRUE(load.config.has_value());
  CompileResult r = compile_gcode(gcode, CompileOptions::from_machine(load.config->machine, 0));
  EXPECT_TRUE(r.ok());
  return r.program;
}

// The reply of a stand-in service that accepts `q` in `cycle`.
msg::Reply accepted_reply(const msg::Request& q, std::uint64_t cycle) {
  msg::Reply r;
  r.request_id(q.request_id());
  r.client_name(q.client_name());
  r.interpolator(q.interpolator());
  r.accepted(true);
  r.code(msg::REPLY_CODE_ACCEPTED);
  r.cycle_counter(cycle);
  return r;
}

// Starts the service and a PLC client whose request and reply topics have matched both ways
// (one request answered), for tests that then write requests without waiting for each reply.
::testing::AssertionResult start_with_matched_plc(ServiceEnv& env, std::optional<client::Client>& plc) {
  if (!env.start_service()) return ::testing::AssertionFailure() << "the service did not start";
  plc.emplace(env.dds(), client::Role::kPlc);
  if (!plc->wait_for_state(0, kHang)) return ::testing::AssertionFailure() << "no state from the service";
  if (!plc->set_rel_speed(0, 1.0).accepted) return ::testing::AssertionFailure() << "the first request was refused";
  return ::testing::AssertionSuccess();
}

// Streams and starts `program` on interpolator 0 and runs until Status 3 (restarting after an
// underrun, as tgm-hmi run does). Returns false on a hang or an error message.
bool run_program(client::Client& hmi, const Program& program, std::string& why,
                 std::uint64_t* underruns = nullptr) {
  client::ProgramSender sender(hmi, program, 0, client::new_program_id());
  bool started = false;
  std::uint64_t fresh_after = 0;
  const auto deadline = std::chrono::steady_clock::now() + 5 * kHang;
  while (std::chrono::steady_clock::now() < deadline) {
    hmi.poll(2ms);
    if (!sender.pump()) {
      why = sender.error();
      return false;
    }
    for (const auto& m : hmi.take_messages()) {
      if (m.severity() == msg::SEVERITY_ERROR) {
        why = "service: " + std::string(m.text().c_str());
        return false;
      }
    }
    const auto* s = hmi.state(0);
    if (s == nullptr || s->program_id() != sender.program_id()) continue;
    if (!started && (sender.all_confirmed() || sender.confirmed() >= static_cast<std::uint64_t>(s->buffer_size() / 2))) {
      const auto r = hmi.start(0);
      if (!r.accepted) {
        why = "start: " + client::describe(r);
        return false;
      }
      started = true;
      fresh_after = r.cycle;
    }
    if (!started || s->cycle_counter() <= fresh_after) continue;
    if (s->status() == 3 && sender.all_confirmed()) return true;
    if (s->status() == 8 && s->buffered_segments() > 0) {
      if (underruns) ++*underruns;
      fresh_after = hmi.start(0).cycle;
    }
    if (s->status() == 7 || s->status() == 0) {
      why = "status " + std::to_string(s->status());
      return false;
    }
  }
  why = "timeout";
  return false;
}

// Starts `tgm-hmi run FILE` as `run` (log run.log) and waits, through `hmi`, until the state of
// interpolator 0 satisfies `reached`.
::testing::AssertionResult start_run_until(
    ServiceEnv& env, const std::string& file, test::Child& run, client::Client& hmi,
    const std::function<bool(const msg::InterpolatorState&)>& reached) {
  if (!run.start({TGM_HMI_BIN, "run", file, "--config", env.config()}, env.path("run.log")))
    return ::testing::AssertionFailure() << "tgm-hmi run did not start";
  if (!hmi.wait_until(0, reached, kHang))
    return ::testing::AssertionFailure() << "the state never came:\n" << run.log();
  return ::testing::AssertionSuccess();
}

TEST(ServiceProcesses, ManualExampleEndToEndWithPlcAndHmiProcesses) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", TGM_SOURCE_DIR "/tests/programs/manual_example.ngc", "--config",
                         env.config(), "--plot", env.path("plot.svg")},
                        env.path("hmi.log")));
  const int hmi_code = hmi.wait(kHang);
  EXPECT_EQ(hmi_code, 0) << hmi.log() << "\n--- plc:\n" << plc.log() << "\n--- service:\n" << env.service.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(env.service.interrupt(), 0) << env.service.log();
  const std::string out = hmi.log();
  EXPECT_NE(out.find("done: 13 records"), std::string::npos) << out;
  // G42 with no tool (T0) and no D compensates by nothing: the operator is told so before the
  // program runs.
  EXPECT_NE(out.find("manual_example.ngc:4: note: the first move under G42 (tool radius "
                     "compensation) with radius 0"),
            std::string::npos)
      << out;
  // Counted from the event topic (a wait acknowledged at once can be shorter than the state's
  // sampling shows; the state-based count is only the fall-back when events did not match).
  EXPECT_NE(out.find("3 M-function waits"), std::string::npos) << out;
  EXPECT_EQ(out.find("seen in the state"), std::string::npos) << out;
  const std::string plc_log = plc.log();
  EXPECT_EQ(test::count_of(plc_log, "M51 acknowledged"), 2) << plc_log;
  EXPECT_EQ(test::count_of(plc_log, "M50 acknowledged"), 1) << plc_log;
  EXPECT_EQ(test::count_of(plc_log, "M51 normal"), 2) << plc_log;
  // Every event the service wrote reached the PLC, but those of the service's first cycle (one
  // per interpolator, "the first cycle always has one"), which can come before the PLC joined:
  // it counts them for the interpolators it later had an event from (the first event_counter
  // it saw, less one); of the others it cannot know. Before session 41 the demo's PLC said
  // "16 received" to the service's 19 events with no word on the 3.
  std::smatch written;
  std::smatch received;
  std::smatch interpolators;
  const std::string service_log = env.service.log();
  ASSERT_TRUE(std::regex_search(service_log, written, std::regex(R"(, (\d+) events \(0 lost\))")))
      << service_log;
  ASSERT_TRUE(std::regex_search(service_log, interpolators,
                                std::regex(R"(tgm-service: (\d+) interpolators)")))
      << service_log;
  ASSERT_TRUE(std::regex_search(
      plc_log, received,
      std::regex(R"(events: (\d+) received, 0 lost, (\d+) written before the PLC joined)")))
      << plc_log;
  const int seen = std::stoi(received[1].str()) + std::stoi(received[2].str());
  EXPECT_LE(seen, std::stoi(written[1].str())) << plc_log << "\n--- service:\n" << service_log;
  EXPECT_GE(seen, std::stoi(written[1].str()) - std::stoi(interpolators[1].str()))
      << plc_log << "\n--- service:\n"
      << service_log;
  EXPECT_LE(std::stoi(received[2].str()), 1) << plc_log;  // interpolator 0's first, at most
  EXPECT_NE(test::read_text(env.path("plot.svg")).find("<polyline"), std::string::npos);
  EXPECT_NE(env.service.log().find("stopping (Interrupt)"), std::string::npos) << env.service.log();
}

// One DDS participant per test process: Fast DDS 2.9 can deadlock two participants of one process
// on its intra-process liveliness path, so the HMI side runs as `tgm-hmi run`, as in production.
TEST(ServiceProcesses, MFunctionWaitsUntilThePlcAcksAndNotLonger) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client plc(env.dds(), client::Role::kPlc);
  ASSERT_TRUE(plc.wait_for_state(0, kHang));
  std::ofstream(env.path("m51.ngc")) << "G1 X5\nM51 A7\nG1 X5\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("m51.ngc"), "--config", env.config()}, env.path("hmi.log")));

  // The PLC sees M51 (normal: the section state says it waits) with its parameter.
  auto waiting = [](const msg::InterpolatorState& s) {
    const auto sec = run_flag_section(static_cast<std::uint32_t>(s.run_flag()));
    return s.m_func() == 51 && (sec == SectionState::kWaitMFunc || sec == SectionState::kWaitMFuncEnd);
  };
  ASSERT_TRUE(plc.wait_until(0, waiting, kHang)) << hmi.log();
  const std::uint64_t m_cycle = plc.state(0)->cycle_counter();
  const std::int32_t m_part = plc.state(0)->act_part();
  EXPECT_DOUBLE_EQ(plc.state(0)->m_function_parameter()[0], 7.0);

  // Without an ack the interpolator keeps waiting: 0.5 s of cycles later it still stands at M51.
  const double cycle_s = 500e-6;
  const auto hold = static_cast<std::uint64_t>(0.5 / cycle_s);
  bool left_early = false;
  ASSERT_TRUE(plc.wait_until(0, [&](const msg::InterpolatorState& s) {
    left_early = left_early || !waiting(s) || s.act_part() != m_part;
    return s.cycle_counter() >= m_cycle + hold;
  }, kHang));
  EXPECT_FALSE(left_early) << "the interpolator went on without the PLC's acknowledgement";

  const auto ack = plc.ack_m_func(0);
  ASSERT_TRUE(ack.accepted) << client::describe(ack);
  EXPECT_GE(ack.cycle, m_cycle + hold);
  // It resumes in the cycle the ack is applied in: the first state published after that cycle no
  // longer waits and is past the M record. Publishing may lag a little behind the cycle; 200
  // cycles (0.1 s) is a generous bound for that lag.
  ASSERT_TRUE(plc.wait_until(0, [&](const msg::InterpolatorState& s) { return s.cycle_counter() > ack.cycle; }, kHang));
  const msg::InterpolatorState s = *plc.state(0);
  EXPECT_FALSE(waiting(s));
  EXPECT_EQ(s.m_func(), 0);
  EXPECT_GT(s.act_part(), m_part);
  EXPECT_LE(s.cycle_counter() - ack.cycle, 200u) << "state published late";
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  EXPECT_NE(hmi.log().find("done: 4 records"), std::string::npos) << hmi.log();
  EXPECT_NE(hmi.log().find("end position X10.0000"), std::string::npos) << hmi.log();
  std::printf("M51: waited %llu cycles, acknowledged in cycle %llu, first state after it: cycle %llu\n",
              static_cast<unsigned long long>(ack.cycle - m_cycle), static_cast<unsigned long long>(ack.cycle),
              static_cast<unsigned long long>(s.cycle_counter()));
}

// A streaming tgm-hmi and a tgm-plc killed (SIGKILL) are noticed by the service from their
// writers' liveliness, said in its log and to the HMIs (a `tgm-hmi watch` shows it). Nothing
// read the liveliness before: the program ran dry in an underrun, and an M-function waited for
// a dead PLC, without a word.
// Block search over DDS: `tgm-hmi run --from-line` compiles the whole program from --start,
// approaches line N from where the interpolator stands and runs the rest; the PLC M-function
// before it is named and never reaches M_Func. A line without records is refused before
// anything reaches the service.
TEST(ServiceProcesses, ABlockSearchRunsFromALineAfterAnApproach) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  // G91 from X20: line 4 starts at X25, the program ends at X30 Y5.
  std::ofstream(env.path("inc.ngc")) << "G91\nG1 X5 F3000\nM51 S7\nG1 X5\nG1 Y5\nM2\n";
  test::Child bad;
  ASSERT_TRUE(bad.start(
      {TGM_HMI_BIN, "run", env.path("inc.ngc"), "--config", env.config(), "--from-line", "1"},
      env.path("bad.log")));
  EXPECT_EQ(bad.wait(kHang), 2) << bad.log();
  EXPECT_NE(bad.log().find("error: --from-line: line 1 makes no record"), std::string::npos)
      << bad.log();
  EXPECT_EQ(bad.log().find("records for interpolator"), std::string::npos) << bad.log();

  test::Child hmi;
  ASSERT_TRUE(
      hmi.start({TGM_HMI_BIN, "run", env.path("inc.ngc"), "--config", env.config(), "--from-line",
                 "4", "--start", "X20", "--approach-feed", "2400", "--quiet"},
                env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << env.service.log();
  const std::string log = hmi.log();
  EXPECT_NE(log.find("resuming at line 4 (record 3 of 5): approach from X0 Y0 Z0 to X25 Y0 Z0 at "
                     "2400 mm/min"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("1 PLC M-function before line 4 never reaches the PLC: M51 (line 3)"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("done: 4 records"), std::string::npos) << log;
  EXPECT_NE(log.find("program start X20 Y0 Z0"), std::string::npos) << log;
  EXPECT_NE(log.find("0 M-function waits"), std::string::npos) << log;
  const auto end = test::run_end_position(log);
  EXPECT_NEAR(end[0], 30.0, 1e-4) << log;
  EXPECT_NEAR(end[1], 5.0, 1e-4) << log;
  EXPECT_NEAR(end[2], 0.0, 1e-4) << log;
}

// A program dropped off the trajectory (Command 9) ends the run with the block search that goes
// on from the line it stood at, with the point the program started from; that command, run as
// printed, approaches the line's start and finishes the program at its end point.
TEST(ServiceProcesses, ADroppedProgramSaysTheBlockSearchThatGoesOnAndItDoes) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("to5.ngc")) << "G90 G1 X5 F6000\nM2\n";
  test::Child first;
  ASSERT_TRUE(
      first.start({TGM_HMI_BIN, "run", env.path("to5.ngc"), "--config", env.config(), "--quiet"},
                  env.path("first.log")));
  ASSERT_EQ(first.wait(kHang), 0) << first.log();
  // G91 from X5: 20 mm lines at 10 mm/s; line 3 runs from X25 Y20 to X5 Y20.
  std::ofstream(env.path("square.ngc")) << "G91 G1 X20 F600\nG1 Y20\nG1 X-20\nG1 Y-20\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("square.ngc"), "--config", env.config()},
                        env.path("hmi.log")));
  client::Client watch(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 1 && s.act_line() == 3; },
      kHang))
      << hmi.log();
  const client::Reply off = watch.command(0, 9);
  ASSERT_TRUE(off.accepted) << client::describe(off);
  EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
  const std::string log = hmi.log();
  const std::string said = "to go on from line 3 once the path is clear: tgm-hmi run ";
  const auto at = log.find(said);
  ASSERT_NE(at, std::string::npos) << log;
  const std::string cmd = log.substr(at + said.size(), log.find('\n', at) - at - said.size());
  EXPECT_EQ(cmd,
            env.path("square.ngc") + " --from-line 3 --start X5,Y0,Z0 --config " + env.config())
      << log;

  // Run as printed (its words: the paths hold no spaces here); the approach at the config's
  // default feed (ServiceEnv: 6000 mm/min).
  std::vector<std::string> argv{TGM_HMI_BIN, "run"};
  std::istringstream words(cmd);
  for (std::string w; words >> w;) argv.push_back(w);
  argv.push_back("--quiet");
  test::Child again;
  ASSERT_TRUE(again.start(argv, env.path("again.log")));
  EXPECT_EQ(again.wait(kHang), 0) << again.log();
  const std::string again_log = again.log();
  EXPECT_NE(again_log.find("resuming at line 3 (record 3 of 5): approach from "), std::string::npos)
      << again_log;
  EXPECT_NE(again_log.find(" to X25 Y20 Z0 at 6000 mm/min"), std::string::npos) << again_log;
  const auto end = test::run_end_position(again_log);
  EXPECT_NEAR(end[0], 5.0, 1e-4) << again_log;
  EXPECT_NEAR(end[1], 0.0, 1e-4) << again_log;
}

// Single block: the run stops after each block (a program stop the run continues, here after
// --m0-continue) and ends where the program does.
TEST(ServiceProcesses, SingleBlockStopsAfterEachBlock) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("sb.ngc")) << "G90\nG1 X5 F3000\nG1 Y5\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("sb.ngc"), "--config", env.config(),
                         "--single-block", "--m0-continue", "0.2", "--quiet"},
                        env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  const std::string log = hmi.log();
  EXPECT_NE(log.find("single block: a program stop after each of 2 blocks"), std::string::npos)
      << log;
  const auto first = log.find("stopped after line 2 (single block): continuing shortly");
  const auto second = log.find("stopped after line 3 (single block): continuing shortly");
  EXPECT_NE(first, std::string::npos) << log;
  EXPECT_NE(second, std::string::npos) << log;
  EXPECT_LT(first, second) << log;
  EXPECT_NE(log.find("done: 5 records"), std::string::npos) << log;  // 3 and the 2 stops
  const auto end = test::run_end_position(log);
  EXPECT_NEAR(end[0], 5.0, 1e-4) << log;
  EXPECT_NEAR(end[1], 5.0, 1e-4) << log;
}

// The progress line goes by the program's time, simulated while it runs: a long move first,
// then a hundred short ones, is far more than 1 % done (the part of the records) while the
// long move runs; it says the time left, and the summary the estimate beside the time taken.
TEST(ServiceProcesses, ARunShowsTheTimeLeftByTheProgramsTimeAndItsEstimate) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  {
    std::ofstream f(env.path("long_short.ngc"));
    f << "G90\nG1 X40 F600\n";  // 4 s
    for (int k = 1; k <= 100; ++k) f << "G1 Y" << 0.01 * k << "\n";
  }
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("long_short.ngc"), "--config", env.config(),
                         "--progress-interval", "0.1"},
                        env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  const std::string log = hmi.log();
  // Progress lines of the long move by time ("[###.......]  35.2% line 2/102 0:03 left X..").
  double most = 0.0;
  std::size_t lines = 0;
  for (std::size_t at = log.find("% line 2/102 "); at != std::string::npos;
       at = log.find("% line 2/102 ", at + 1)) {
    if (log.compare(log.find(' ', at + 13), 6, " left ") != 0) continue;  // not estimated yet
    const std::size_t open = log.rfind(']', at);
    ASSERT_NE(open, std::string::npos) << log;
    most = std::max(most, std::strtod(log.c_str() + open + 1, nullptr));
    ++lines;
  }
  EXPECT_GT(lines, 3u) << log;
  EXPECT_GT(most, 50.0) << log;  // by records at most 1 %
  // "in 4.523 s of program time (9046 cycles, estimated 4.521 s; ...": no M-function, so the
  // service's run and the simulation's agree to a few cycles.
  const std::size_t in = log.find("done: 101 records, 102 lines in ");
  const std::size_t est = log.find(", estimated ");
  ASSERT_NE(in, std::string::npos) << log;
  ASSERT_NE(est, std::string::npos) << log;
  const double took = std::strtod(log.c_str() + in + 32, nullptr);
  const double estimated = std::strtod(log.c_str() + est + 12, nullptr);
  EXPECT_GT(took, 4.0) << log;
  EXPECT_NEAR(estimated, took, 0.01) << log;

  // Without it: the part of the records, no estimate.
  test::Child plain;
  ASSERT_TRUE(plain.start({TGM_HMI_BIN, "run", env.path("long_short.ngc"), "--config", env.config(),
                           "--progress-interval", "0.1", "--no-estimate"},
                          env.path("plain.log")));
  EXPECT_EQ(plain.wait(kHang), 0) << plain.log();
  EXPECT_EQ(plain.log().find(" left "), std::string::npos) << plain.log();
  EXPECT_EQ(plain.log().find("estimated"), std::string::npos) << plain.log();
  EXPECT_NE(plain.log().find("% line "), std::string::npos) << plain.log();

  // The override halved during a move (the PLC's script, a second after it starts): the part
  // done goes by the part of its length moved, not by the time it has run.
  std::ofstream(env.path("half.yaml")) << "- {at_s: 1.5, rel_speed: 0.5}\n";
  std::ofstream(env.path("one.ngc")) << "G91\nG1 X40 F1200\nM2\n";  // from X40
  test::Child plc, half;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--script", env.path("half.yaml")},
                        env.path("plc.log")));
  ASSERT_TRUE(half.start({TGM_HMI_BIN, "run", env.path("one.ngc"), "--config", env.config(),
                          "--progress-interval", "0.1"},
                         env.path("half.log")));
  EXPECT_EQ(half.wait(kHang), 0) << half.log();
  const std::string h = half.log();
  bool slowed = false;
  std::size_t seen = 0;
  for (std::size_t at = h.find("% line 2/3 "); at != std::string::npos;
       at = h.find("% line 2/3 ", at + 1)) {
    if (h.compare(h.find(' ', at + 11), 6, " left ") != 0) continue;  // not estimated yet
    const double pct = std::strtod(h.c_str() + h.rfind(']', at) + 1, nullptr);
    const std::size_t x = h.find(" X", at);
    ASSERT_NE(x, std::string::npos) << h;
    const double moved = std::strtod(h.c_str() + x + 2, nullptr) - 40.0;
    // One record: its part of the time is its part of the length (the state's Move_Distance
    // and Position come in the same sample).
    EXPECT_NEAR(pct, 100.0 * moved / 40.0, 0.5) << h;
    slowed = slowed || h.compare(h.find(" F", x), 6, " F600 ") == 0;
    ++seen;
  }
  EXPECT_GT(seen, 5u) << h;
  EXPECT_TRUE(slowed) << h << plc.log();
  EXPECT_EQ(plc.interrupt(), 0) << plc.log();
}

TEST(ServiceProcesses, AKilledStreamingHmiAndAKilledPlcAreSaid) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  write_tenth_steps(env.path("long.ngc"), 40'000, 3000);  // 4 m at 50 mm/s
  test::Child plc, hmi, watch;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  ASSERT_TRUE(watch.start({TGM_HMI_BIN, "watch", "--config", env.config()}, env.path("watch.log")));
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config(),
                         "--progress-interval", "0.2"},
                        env.path("hmi.log")));
  hmi.wait_for_log("% line ", kHang, 20ms);
  ASSERT_NE(hmi.log().find("% line "), std::string::npos) << hmi.log() << env.service.log();
  plc.wait_for_log("setup done", kHang, 20ms);
  EXPECT_EQ(hmi.interrupt(10s, SIGKILL), 128 + SIGKILL);
  env.service.wait_for_log("gave no sign of life", 30s, 20ms);
  EXPECT_NE(env.service.log().find("the sender 'tgm-hmi-"), std::string::npos) << env.service.log();
  EXPECT_NE(env.service.log().find("gave no sign of life (it stopped, or the network is down)"),
            std::string::npos)
      << env.service.log();
  EXPECT_EQ(plc.interrupt(10s, SIGKILL), 128 + SIGKILL);
  env.service.wait_for_log(
      "gave no sign of life (it stopped, or the network is down)\n"
      "tgm-service: tgm-plc",
      30s, 20ms);
  const std::string log = env.service.log();
  const std::size_t plc_lost = log.find("tgm-service: tgm-plc 'tgm-plc-");
  ASSERT_NE(plc_lost, std::string::npos) << log;
  EXPECT_NE(log.find("gave no sign of life (it stopped, or the network is down)", plc_lost),
            std::string::npos)
      << log;
  watch.wait_for_log("no sign of life from tgm-plc", 10s, 20ms);
  const std::string w = watch.log();
  EXPECT_NE(w.find("its sender 'tgm-hmi-"), std::string::npos) << w;
  EXPECT_NE(w.find("unless it returns, the motion stops at the buffer's end"), std::string::npos)
      << w;
  EXPECT_NE(w.find("no sign of life from tgm-plc"), std::string::npos) << w;
  EXPECT_EQ(watch.interrupt(), 0) << w;
}

// A second tgm-plc (a script run beside the machine's PLC) is said when it joins, as both
// acknowledge the M-functions; when it ends, it is no lost PLC: the HMIs were warned that
// M-functions "wait until a PLC answers" while the first acknowledged them.
TEST(ServiceProcesses, ASecondPlcThatEndsIsNoLostPlc) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc, second, watch;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  plc.wait_for_log("setup done", kHang, 20ms);
  ASSERT_TRUE(watch.start({TGM_HMI_BIN, "watch", "--config", env.config()}, env.path("watch.log")));
  watch.wait_for_log("Status", kHang, 20ms);
  ASSERT_TRUE(
      second.start({TGM_PLC_BIN, "--config", env.config(), "--no-basic-params", "--duration", "1"},
                   env.path("second.log")));
  EXPECT_EQ(second.wait(kHang), 0) << second.log();
  watch.wait_for_log("is there and acknowledges the M-functions", 30s, 20ms);
  const std::string w = watch.log();
  // Both named as their requests name them, the second from its discovery on (it announces
  // its name in its participant's USER_DATA; it was 'tgm-plc', the participant's name).
  const std::string slog = second.log();
  const std::size_t as = slog.find(" as 'tgm-plc-");
  ASSERT_NE(as, std::string::npos) << slog;
  const std::string name = slog.substr(as + 5, slog.find('\'', as + 5) - (as + 5));
  EXPECT_NE(w.find("tgm-plc '" + name + "' joined beside tgm-plc 'tgm-plc-"), std::string::npos)
      << name << "\n"
      << w;
  EXPECT_NE(env.service.log().find("tgm-plc '" + name + "' joined beside tgm-plc 'tgm-plc-"),
            std::string::npos)
      << env.service.log();
  EXPECT_NE(w.find("tgm-plc '" + name + "' ended; tgm-plc 'tgm-plc-"), std::string::npos)
      << w << env.service.log();
  EXPECT_EQ(w.find("wait for an acknowledgement until a PLC answers"), std::string::npos) << w;
  // The machine's PLC ends too: now the M-functions wait.
  EXPECT_EQ(plc.interrupt(kHang), 0) << plc.log();
  watch.wait_for_log("wait for an acknowledgement until a PLC answers", 30s, 20ms);
  EXPECT_NE(watch.log().find("wait for an acknowledgement until a PLC answers"), std::string::npos)
      << watch.log() << env.service.log();
  EXPECT_EQ(watch.interrupt(), 0) << watch.log();
}

// Two clients of one PID (each PID 1 in a container of its own) get different names: named
// "tgm-hmi-1" both, each took the other's replies (a start "accepted" that the service refused).
TEST(ClientName, IsUniquePerClientAndFitsTheTopicsBound) {
  const std::string a = client::unique_client_name("tgm-hmi");
  const std::string b = client::unique_client_name("tgm-hmi");
  EXPECT_NE(a, b);
  // Appended, not `"-" + std::to_string(...)`: GCC 12 at -O3 took that for an overlapping
  // memcpy (-Werror=restrict in a Release build of the tests).
  std::string pid = "-";
  pid += std::to_string(::getpid());
  pid += '-';
  std::string prefix = "tgm-hmi";
  prefix += pid;
  for (const std::string& n : {a, b}) {
    EXPECT_EQ(n.rfind(prefix, 0), 0u) << n;
    EXPECT_EQ(n.size(), 7 + pid.size() + 8) << n;
    EXPECT_EQ(n.find_first_not_of("0123456789abcdef", 7 + pid.size()), std::string::npos) << n;
  }
  // A long participant name is cut, the tail kept: the name stays at 64 characters.
  const std::string long_name = client::unique_client_name(std::string(100, 'p'));
  EXPECT_EQ(long_name.size(), 64u);
  EXPECT_NE(long_name.find(pid), std::string::npos) << long_name;
}

// Replies are keyed by interpolator. A request to one the service does not host is refused, and
// its reply goes out under one key for all of them: each key is a reply writer instance for
// good, and after ten bad indices (Fast DDS's default limit) no client got another reply, while
// its requests still executed.
TEST(ServiceProcesses, RequestsToInterpolatorsThatDoNotExistLeaveTheRepliesWorking) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client plc(env.dds(), client::Role::kPlc);
  ASSERT_TRUE(plc.wait_for_state(0, kHang));
  for (int i = 3; i < 13; ++i) {
    msg::Request r;
    r.interpolator(static_cast<std::uint16_t>(i));
    r.kind(msg::REQUEST_KIND_WRITE_REL_SPEED);
    r.value(1.0);
    const client::Reply reply = plc.request(r);
    ASSERT_FALSE(reply.timed_out) << "interpolator " << i;
    EXPECT_EQ(reply.code, msg::REPLY_CODE_BAD_REQUEST) << client::describe(reply);
    EXPECT_NE(reply.reason.find("interpolator " + std::to_string(i) + " does not exist"),
              std::string::npos)
        << reply.reason;
  }
  // Another client (a process of its own: one participant per test process) is answered.
  test::Child stop;
  ASSERT_TRUE(
      stop.start({TGM_HMI_BIN, "command", "stop", "--config", env.config()}, env.path("stop.log")));
  EXPECT_EQ(stop.wait(kHang), 0) << stop.log();
  EXPECT_NE(stop.log().find("accepted"), std::string::npos) << stop.log();
}

// The event topic: the PLC gets the M-function in a small event sample, in Fast DDS's receive
// thread, and can acknowledge it right there; the reply is taken later by the polling thread.
TEST(ServiceProcesses, EventCallbackSeesTheMFunctionAndCanAcknowledgeIt) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client plc(env.dds(), client::Role::kPlc);
  std::mutex mutex;
  std::vector<msg::InterpolatorEvent> m_events;  // events with M_Func set, as the callback saw them
  std::vector<std::uint64_t> ack_ids;
  std::uint64_t last_counter = 0;
  bool counters_contiguous = true;
  plc.on_event([&](const client::Event& e) {
    if (e.sample.interpolator() != 0) return;
    const std::lock_guard lock(mutex);
    if (last_counter != 0 && e.sample.event_counter() != last_counter + 1)
      counters_contiguous = false;
    last_counter = e.sample.event_counter();
    if (e.sample.m_func() == 0 ||
        (!m_events.empty() && m_events.back().act_part() == e.sample.act_part()))
      return;
    m_events.push_back(e.sample);
    ack_ids.push_back(plc.send_ack_m_func(0));
  });
  ASSERT_THROW(plc.on_event([](const client::Event&) {}), dds::SetupError);
  ASSERT_TRUE(plc.wait_for_state(0, kHang));
  std::ofstream(env.path("m51.ngc")) << "G1 X5\nM51 A7\nG1 X5\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("m51.ngc"), "--config", env.config()},
                        env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  EXPECT_NE(hmi.log().find("done: 4 records"), std::string::npos) << hmi.log();
  EXPECT_NE(hmi.log().find("1 M-function wait"), std::string::npos) << hmi.log();

  const std::lock_guard lock(mutex);
  ASSERT_EQ(m_events.size(), 1u);
  const msg::InterpolatorEvent& e = m_events[0];
  EXPECT_EQ(e.m_func(), 51);
  EXPECT_EQ(e.act_line(), 2);
  EXPECT_DOUBLE_EQ(e.m_function_parameter()[0], 7.0);
  EXPECT_TRUE(is_not_set(e.m_function_parameter()[1]));
  const auto sec = run_flag_section(static_cast<std::uint32_t>(e.run_flag()));
  EXPECT_TRUE(sec == SectionState::kWaitMFunc || sec == SectionState::kWaitMFuncEnd)
      << e.run_flag();
  EXPECT_NE(e.program_id(), 0u);
  EXPECT_GT(e.cycle_counter(), 0u);
  EXPECT_TRUE(counters_contiguous);
  EXPECT_EQ(plc.events_lost(), 0u);
  EXPECT_GE(plc.events_received(), 3u);  // at least: program loaded, running, M51, ended
  ASSERT_EQ(ack_ids.size(), 1u);
  ASSERT_NE(ack_ids[0], 0u) << "the ack could not be written from the callback";
  std::optional<client::Reply> reply;
  for (int i = 0; i < 100 && !reply; ++i) {
    plc.poll(20ms);
    reply = plc.take_reply(ack_ids[0]);
  }
  ASSERT_TRUE(reply.has_value());
  EXPECT_TRUE(reply->accepted) << client::describe(*reply);
  EXPECT_GE(reply->cycle, e.cycle_counter());
}

// tgm-plc with an acknowledgement delay of 0 acknowledges from the event callback; it sees every
// M-function on both topics (event and state) and still logs each, and each acknowledgement, once.
TEST(ServiceProcesses, PlcAcknowledgesFromTheEventAndLogsEachMFunctionOnce) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(
      plc.start({TGM_PLC_BIN, "--config", env.config(), "--ack-delay", "0"}, env.path("plc.log")));
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", TGM_SOURCE_DIR "/tests/programs/manual_example.ngc",
                         "--config", env.config()},
                        env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << "\n--- plc:\n" << plc.log();
  EXPECT_EQ(plc.interrupt(), 0);
  // Each wait lasts a cycle or two here; the HMI counts them from the events, not the state.
  EXPECT_NE(hmi.log().find("3 M-function waits"), std::string::npos) << hmi.log();
  EXPECT_EQ(hmi.log().find("seen in the state"), std::string::npos) << hmi.log();
  const std::string log = plc.log();
  EXPECT_EQ(test::count_of(log, "M51 normal"), 2) << log;
  EXPECT_EQ(test::count_of(log, "M50 normal"), 1) << log;
  EXPECT_EQ(test::count_of(log, "M51 acknowledged from the event"), 2) << log;
  EXPECT_EQ(test::count_of(log, "M50 acknowledged from the event"), 1) << log;
  EXPECT_EQ(test::count_of(log, "acknowledged"), 3) << log;
  EXPECT_EQ(test::count_of(log, ": accepted (cycle"), 3) << log;
  EXPECT_EQ(test::count_of(log, " 0 lost"), 1) << log;
  EXPECT_EQ(test::count_of(log, "M51 normal: the interpolator waits (line 3, part 2)"), 1) << log;
  EXPECT_EQ(test::count_of(log, "M50 normal: the interpolator waits (line 11, part 10)"), 1) << log;
}

// tgm-plc logs a continuous M-function with its own line. It is handed over as the record after
// it starts, and the log named that record's line (the state's act_line).
TEST(ServiceProcesses, PlcLogsAContinuousMFunctionAtItsOwnLine) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(
      plc.start({TGM_PLC_BIN, "--config", env.config(), "--ack-delay", "0"}, env.path("plc.log")));
  std::ofstream(env.path("c.ngc")) << "G90 G1 X1 F600\nM1005\nG4 P0.1\nM51\nG1 X2\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(
      hmi.start({TGM_HMI_BIN, "run", env.path("c.ngc"), "--config", env.config(), "--quiet"},
                env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << "\n--- plc:\n" << plc.log();
  // A hundred in a row: beyond the 64 that wait a cycle each, 35 are overwritten in M_Func
  // within the first cycle (core/MOTION.md). The PLC sees the rest in program order and says
  // how many it could not see, and before which one (it said nothing).
  std::ofstream hundred(env.path("h.ngc"));
  hundred << "G90 G1 X3 F600\n";
  for (int k = 0; k < 100; ++k) hundred << "M" << 2001 + k << "\n";
  hundred << "G1 X4\nM2\n";
  hundred.close();
  test::Child again;
  ASSERT_TRUE(
      again.start({TGM_HMI_BIN, "run", env.path("h.ngc"), "--config", env.config(), "--quiet"},
                  env.path("again.log")));
  EXPECT_EQ(again.wait(kHang), 0) << again.log() << "\n--- plc:\n" << plc.log();
  EXPECT_EQ(plc.interrupt(), 0);
  const std::string log = plc.log();
  EXPECT_EQ(test::count_of(log, "M1005 continuous: motion goes on (line 2, part 3)"), 1) << log;
  EXPECT_EQ(test::count_of(log, "M51 normal: the interpolator waits (line 4, part 4)"), 1) << log;
  EXPECT_EQ(test::count_of(log,
                           "interpolator 0: 35 M-functions before M2036 (line 37) reached "
                           "M_Func in the same cycle and were overwritten"),
            1)
      << log;
  // Each of the rest once (their order is the core's test: the PLC logs an M-function seen on
  // the state and one seen on the event topic as each arrives).
  EXPECT_EQ(test::count_of(log, "M2036 continuous: motion goes on (line 37,"), 1) << log;
  for (int m = 2001; m <= 2100; ++m) {
    // Piece by piece: GCC 12 at -O3 warns (-Wrestrict, falsely) on "M" + to_string().
    std::string says = std::to_string(m);
    says.insert(says.begin(), 'M');
    says += " continuous";
    EXPECT_EQ(test::count_of(log, says), m >= 2036 ? 1 : 0) << says << "\n" << log;
  }
}

// A stand-in service in this process (its config and domain only: no tgm-service runs) for a
// tgm-plc started with `args` after --config: the state, reply and request endpoints, matched
// with the PLC's, and interpolators 0 and 1 of three axes of one service instance, idle.
struct StandInService {
  explicit StandInService(const ServiceEnv& env)
      : fake(env.dds(), "service"),
        states(fake.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic)),
        replies(fake.writer<msg::ReplyPubSubType>(dds::kReplyTopic)),
        requests(fake.reader<msg::RequestPubSubType>(dds::kRequestTopic)) {
    for (std::uint16_t i = 0; i < 2; ++i) {
      st[i].interpolator(i);
      st[i].number(i);
      st[i].number_axes(3);
      st[i].buffer_size(10000);
      st[i].service_instance(0x5eedULL);
      st[i].axis_letters("XYZ");
    }
  }
  void start_plc(ServiceEnv& env, test::Child& plc, const std::vector<std::string>& args) {
    std::vector<std::string> argv = {TGM_PLC_BIN, "--config", env.config(), "--no-events",
                                     "--no-basic-params"};
    argv.insert(argv.end(), args.begin(), args.end());
    ASSERT_TRUE(plc.start(argv, env.path("plc.log")));
    ASSERT_TRUE(dds::wait_for_match(states, 1, kHang)) << plc.log();
    ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang)) << plc.log();
    ASSERT_TRUE(dds::wait_for_match(requests, 1, kHang)) << plc.log();
  }
  // Interpolator i waits for the PLC's acknowledgement of normal M-function m (the first one
  // handed over).
  void wait_for_m(std::size_t i, std::int32_t m) {
    st[i].status(1);
    st[i].m_func(m);
    st[i].m_func_count(1);
    st[i].run_flag(
        static_cast<std::int32_t>(static_cast<std::uint32_t>(SectionState::kWaitMFunc) |
                                  (static_cast<std::uint32_t>(SpeedState::kNoMotion) << 16)));
  }
  // Publishes both states as one more service cycle of 20 (`cycle` counts them).
  bool publish(std::uint64_t& cycle) {
    for (auto& s : st) {
      s.cycle_counter(cycle += 20);
      if (!states.write(&s)) return false;
    }
    return true;
  }
  // Publishes the states and answers every request until `plc` exits (at most kHang); `each`
  // runs first in every pass. Returns the number of requests answered.
  int serve_until_exit(test::Child& plc, const std::function<void()>& each = {}) {
    std::uint64_t cycle = 0;
    int answered = 0;
    const auto deadline = std::chrono::steady_clock::now() + kHang;
    while (plc.running() && std::chrono::steady_clock::now() < deadline) {
      if (each) each();
      if (!publish(cycle)) {
        ADD_FAILURE() << "the stand-in's state was not written";
        break;
      }
      msg::Request rq;
      while (dds::take_next(requests, rq)) {
        ++answered;
        if (!answer(rq, cycle)) ADD_FAILURE() << "the stand-in's reply was not written";
      }
      std::this_thread::sleep_for(10ms);
      plc.wait(0ms);
    }
    return answered;
  }
  // Accepts acknowledgement `q` in `cycle`: the reply, and its interpolator's M-function
  // released.
  bool answer(const msg::Request& q, std::uint64_t cycle) {
    msg::Reply r = accepted_reply(q, cycle);
    st[q.interpolator()].m_func(0);
    st[q.interpolator()].run_flag(static_cast<std::int32_t>(SectionState::kRun));
    return replies.write(&r);
  }
  dds::Participant fake;
  eprosima::fastdds::dds::DataWriter& states;
  eprosima::fastdds::dds::DataWriter& replies;
  eprosima::fastdds::dds::DataReader& requests;
  std::array<msg::InterpolatorState, 2> st;
};

// tgm-plc's handshakes with several interpolators do not wait for one another: a reply lost on
// the network for one does not hold up the acknowledgement of the next. A stand-in service in
// this process shows interpolators 0 and 1 both waiting (M51, M52) and answers neither
// acknowledgement until both have arrived. A PLC that waited for each reply before writing the
// next acknowledgement (as it did until session 51) left its first one unanswered for its 3 s
// timeout and logged it so; this one writes both and takes both replies.
TEST(ServiceProcesses, ThePlcAcknowledgesEachInterpolatorWithoutWaitingForAnothersReply) {
  ServiceEnv env;
  StandInService service(env);
  test::Child plc;
  ASSERT_NO_FATAL_FAILURE(service.start_plc(env, plc, {"--ack-delay", "0.1"}));
  for (std::uint16_t i = 0; i < 2; ++i) {
    service.wait_for_m(i, 51 + i);
    service.st[i].act_part(2);
    service.st[i].act_line(2);
  }
  std::vector<msg::Request> held;
  std::array<int, 2> acks{};
  std::uint64_t cycle = 0;
  int answered = 0;
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  // Until both are answered, and half a second more for the PLC to see them released.
  auto until = deadline;
  while (std::chrono::steady_clock::now() < until) {
    ASSERT_TRUE(service.publish(cycle));
    msg::Request rq;
    while (dds::take_next(service.requests, rq)) {
      ASSERT_EQ(rq.kind(), msg::REQUEST_KIND_WRITE_M_FUNC) << plc.log();
      ASSERT_LT(rq.interpolator(), 2) << plc.log();
      ++acks[rq.interpolator()];
      held.push_back(rq);
    }
    if (acks[0] > 0 && acks[1] > 0) {
      for (const msg::Request& q : held) {
        ASSERT_TRUE(service.answer(q, cycle));
        if (++answered == 2) until = std::chrono::steady_clock::now() + 500ms;
      }
      held.clear();
    }
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(answered, 2) << plc.log();
  EXPECT_EQ(plc.interrupt(), 0);
  const std::string log = plc.log();
  EXPECT_EQ(acks[0], 1) << log;
  EXPECT_EQ(acks[1], 1) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 0: M51 acknowledged after"), 1) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 1: M52 acknowledged after"), 1) << log;
  EXPECT_EQ(test::count_of(log, ": accepted (cycle"), 2) << log;
  EXPECT_EQ(test::count_of(log, "no reply"), 0) << log;
}

// A script's refuse_ack is for the interpolator its step names: with M51 waiting on
// interpolators 0 and 1 after `{interpolator: 1, refuse_ack: [51]}`, 0's is acknowledged and
// 1's is not (one set for all refused M51 on every interpolator). A stand-in service, as above.
TEST(ServiceProcesses, APlcScriptRefusalIsForTheInterpolatorItNames) {
  ServiceEnv env;
  StandInService service(env);
  const std::string script = env.path("refuse.yaml");
  std::ofstream(script) << "- {at_s: 0, interpolator: 1, refuse_ack: [51]}\n";
  test::Child plc;
  ASSERT_NO_FATAL_FAILURE(service.start_plc(env, plc, {"--ack-delay", "0", "--script", script}));
  // Idle until the step ran (it runs once the PLC found the service), then both wait for M51.
  const std::string step_ran = "script line 1: interpolator 1: from now on M51 is not acknowledged";
  std::uint64_t cycle = 0;
  std::array<int, 2> acks{};
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  auto until = deadline;
  bool waiting = false;
  while (std::chrono::steady_clock::now() < until) {
    if (!waiting && plc.log().find(step_ran) != std::string::npos) {
      waiting = true;
      for (std::size_t i = 0; i < 2; ++i) service.wait_for_m(i, 51);
      until = std::min(deadline, std::chrono::steady_clock::now() + 1500ms);
    }
    ASSERT_TRUE(service.publish(cycle));
    msg::Request rq;
    while (dds::take_next(service.requests, rq)) {
      ASSERT_LT(rq.interpolator(), 2) << plc.log();
      ++acks[rq.interpolator()];
      ASSERT_TRUE(service.answer(rq, cycle));
    }
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(waiting) << plc.log();
  EXPECT_EQ(plc.interrupt(), 0);
  const std::string log = plc.log();
  EXPECT_EQ(acks[0], 1) << log;
  EXPECT_EQ(acks[1], 0) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 0: M51 acknowledged after"), 1) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 1: M51: refusing to acknowledge"), 1) << log;
  // At the stop, the M-function left waiting is named (only 1's: 0's was acknowledged).
  EXPECT_EQ(test::count_of(log, "is left waiting, not acknowledged"), 1) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 1: M51 (line 0) is left waiting"), 1) << log;
}

// A script's refuse_ack also holds back the acknowledgement of an M-function that waits already
// and is due later: M51 waits from the first state, due after --ack-delay 0.5 s, and the step
// at 0.1 s refuses it. The PLC logged "from now on M51 is not acknowledged" and acknowledged it
// 0.4 s later (review of session 76, F2); now nothing is sent until its --duration ends.
TEST(ServiceProcesses, APlcScriptRefusalHoldsBackAnAcknowledgementAlreadyDue) {
  ServiceEnv env;
  StandInService service(env);
  service.wait_for_m(0, 51);
  service.st[0].act_part(2);
  const std::string script = env.path("refuse.yaml");
  std::ofstream(script) << "- {at_s: 0.1, refuse_ack: [51]}\n";
  test::Child plc;
  ASSERT_NO_FATAL_FAILURE(service.start_plc(
      env, plc,
      {"--ack-delay", "0.5", "--script", script, "--duration", "2", "--interpolator", "0"}));
  const int acks = service.serve_until_exit(plc);
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  const std::string log = plc.log();
  EXPECT_EQ(acks, 0) << log;
  EXPECT_NE(log.find("script line 1: interpolator 0: from now on M51 is not acknowledged"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("script line 1: interpolator 0: M51 (part 2) waits: its acknowledgement, "
                     "due in 0."),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("M51 acknowledged"), std::string::npos) << log;
  EXPECT_EQ(test::count_of(log, "interpolator 0: M51 (line 0) is left waiting"), 1) << log;
}

// An acknowledgement not yet due is not sent when its M-function goes without it: M51 waits,
// due after --ack-delay 2.5 s, and after 0.3 s the stand-in shows M_Func 0 with the same count
// (its program dropped, as by a Command 5). The PLC sent it all the same, 2.3 s after its own
// Command 5 in the review of session 76, and the service refused it.
TEST(ServiceProcesses, APlcDropsAnAcknowledgementWhoseMFunctionWentBeforeItWasDue) {
  ServiceEnv env;
  StandInService service(env);
  service.wait_for_m(0, 51);
  service.st[0].act_part(2);
  test::Child plc;
  ASSERT_NO_FATAL_FAILURE(service.start_plc(
      env, plc, {"--ack-delay", "2.5", "--duration", "3.5", "--interpolator", "0"}));
  bool dropped = false;
  const int acks = service.serve_until_exit(plc, [&] {
    if (dropped || plc.log().find("M51 normal") == std::string::npos) return;
    std::this_thread::sleep_for(300ms);
    dropped = true;
    service.st[0].status(7);
    service.st[0].m_func(0);
    service.st[0].run_flag(static_cast<std::int32_t>(SectionState::kRun));
  });
  EXPECT_TRUE(dropped) << plc.log();
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  const std::string log = plc.log();
  EXPECT_EQ(acks, 0) << log;
  EXPECT_EQ(test::count_of(log,
                           "interpolator 0: M51 not acknowledged: it went before its "
                           "acknowledgement was due (status 7 "),
            1)
      << log;
  EXPECT_EQ(log.find("M51 acknowledged"), std::string::npos) << log;
  EXPECT_EQ(log.find("is left waiting"), std::string::npos) << log;
}

// A script's write by axis letter goes to the service's axis of that letter: the stand-in
// drives Y, X, C where the PLC's config has X, Y, Z. The ratio for X went to axis 0 (the
// service's Y), and the offset for Z to the service's C, both logged as accepted (review of
// session 76). Now X goes to axis 1, and Z, which the service does not drive, is not written:
// an error in the log naming the line and the service's letters, and exit code 3.
TEST(ServiceProcesses, APlcScriptAxisWriteGoesToTheServicesAxisOfItsLetter) {
  ServiceEnv env;
  StandInService service(env);
  service.st[0].axis_letters("YXC");
  const std::string script = env.path("axes.yaml");
  std::ofstream(script) << "- {at_s: 0, ratio: {X: 2000}, offset: {Z: 7}}\n";
  test::Child plc;
  ASSERT_NO_FATAL_FAILURE(service.start_plc(env, plc, {"--script", script}));
  std::vector<msg::Request> writes;
  std::uint64_t cycle = 0;
  const std::string answered = "script line 1: interpolator 0: Ratio X = 2000 inc/mm: accepted";
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  while (std::chrono::steady_clock::now() < deadline &&
         plc.log().find(answered) == std::string::npos) {
    ASSERT_TRUE(service.publish(cycle));
    msg::Request rq;
    while (dds::take_next(service.requests, rq)) {
      writes.push_back(rq);
      ASSERT_TRUE(service.answer(rq, cycle));
    }
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(plc.interrupt(), 3) << plc.log();
  const std::string log = plc.log();
  ASSERT_EQ(writes.size(), 1u) << log;
  EXPECT_EQ(writes[0].kind(), msg::REQUEST_KIND_WRITE_RATIO) << log;
  EXPECT_EQ(writes[0].axis(), 1) << log;
  EXPECT_EQ(writes[0].value(), 2000.0) << log;
  const std::string why = "Offset Z = 7 inc";
  const std::string service_has = "the service has no axis Z: it drives YXC (Number_Axes 3)";
  EXPECT_NE(log.find("script " + script + ":1: interpolator 0: error: " + why + " not written: " +
                     service_has + "; the script names the axes of this config (XYZ)"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("tgm-plc: 1 axis write of the script was not sent (the first: " + script +
                     ":1: interpolator 0: " + why + ": " + service_has + ")"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("Offset Z = 7 inc: accepted"), std::string::npos) << log;
}

// A tgm-plc (re)started while a program waits for M51 leaves the machine's parameters alone:
// its gear ratios were accepted mid-program (the interpolator stands during the wait), and
// PositionInc jumped by Position x dRatio with the program going on from there.
TEST(ServiceProcesses, APlcStartedInTheMiddleOfAProgramSendsNoBasicParameters) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("m.ngc")) << "G90 G1 X10 F3000\nM51\nG1 X20\nM2\n";
  test::Child run;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(start_run_until(env, env.path("m.ngc"), run, hmi,
                              [](const msg::InterpolatorState& s) { return s.m_func() == 51; }));
  std::string geared = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(geared, "ratio_inc_per_mm: 1000", "ratio_inc_per_mm: 2000"));
  std::ofstream(env.path("geared.yaml")) << geared;
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.path("geared.yaml"), "--refuse-ack", "51",
                         "--interpolator", "0", "--duration", "1.5", "--rel-speed", "0.5"},
                        env.path("plc.log")));
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  // Nor the override (it was written: a restarted PLC reset the operator's Rel_Speed mid-cut).
  EXPECT_NE(plc.log().find("interpolator 0: Rel_Speed not written: a program is under way (status "
                           "1 running); the override stays 1"),
            std::string::npos)
      << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: basic parameters not sent: a program is under way "
                           "(status 1 running)"),
            std::string::npos)
      << plc.log();
  EXPECT_EQ(plc.log().find("Command 1024"), std::string::npos) << plc.log();
  // "setup done (0 of 0 requests accepted)" read as success (review of session 77).
  EXPECT_NE(plc.log().find("interpolator 0: setup done (0 of 0 requests accepted; basic "
                           "parameters not sent: a program is under way)"),
            std::string::npos)
      << plc.log();
  hmi.poll(100ms);
  EXPECT_EQ(hmi.state(0)->ratio()[0], 1000.0);
  EXPECT_EQ(hmi.state(0)->position_inc()[0], 10000);
  EXPECT_EQ(hmi.state(0)->rel_speed(), 1.0);
  EXPECT_EQ(run.interrupt(kHang), 130) << run.log();
}

// The same after an emergency stop on the trajectory (Command 4), whose program a start
// resumes: the ratio was sent there, and refused, leaving Command_Status -1 on the screens
// (review of the HMI, session 75).
TEST(ServiceProcesses, APlcStartedAfterAnEmergencyStopOnTheTrajectorySendsNoBasicParameters) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("long.ngc")) << "G90 G1 X200 F3000\nM2\n";
  test::Child run;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(start_run_until(env, env.path("long.ngc"), run, hmi,
                              [](const msg::InterpolatorState& s) { return s.act_speed() > 0; }));
  EXPECT_TRUE(hmi.command(0, 4).accepted);
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 7; }, kHang));
  std::string geared = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(geared, "ratio_inc_per_mm: 1000", "ratio_inc_per_mm: 2000"));
  std::ofstream(env.path("geared.yaml")) << geared;
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.path("geared.yaml"), "--interpolator", "0",
                         "--duration", "1.5"},
                        env.path("plc.log")));
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: basic parameters not sent: a program is under way "
                           "(status 7 emergency stopped)"),
            std::string::npos)
      << plc.log();
  EXPECT_EQ(plc.log().find("Command 1024"), std::string::npos) << plc.log();
  hmi.poll(100ms);
  EXPECT_EQ(hmi.state(0)->ratio()[0], 1000.0);
  EXPECT_NE(hmi.state(0)->command_status(), -1);
  EXPECT_EQ(run.interrupt(kHang), 130) << run.log();
}

// The tool a program leaves in the spindle stays there for the next one: `run` compiles that for
// Tool_Number (it compiled from the config's initial_tool, 0, so a program without a T word set
// Tool_Number back to 0 and ran G41/G42 at radius 0).
TEST(ServiceProcesses, HmiRunCompilesForTheToolInTheSpindle) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("t2.ngc")) << "G90 T2 G1 X1 F3000\nM2\n";
  std::ofstream(env.path("next.ngc")) << "G90 G1 X2 F3000\nM2\n";
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  test::Child first;
  ASSERT_TRUE(first.start({TGM_HMI_BIN, "run", env.path("t2.ngc"), "--config", env.config()},
                          env.path("first.log")));
  ASSERT_EQ(first.wait(kHang), 0) << first.log();
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.tool_number() == 2; }, kHang));
  test::Child next;
  ASSERT_TRUE(next.start({TGM_HMI_BIN, "run", env.path("next.ngc"), "--config", env.config()},
                         env.path("next.log")));
  ASSERT_EQ(next.wait(kHang), 0) << next.log();
  EXPECT_NE(next.log().find("next.ngc: compiled for tool T2, in interpolator 0's spindle since its "
                            "last program (the config's initial_tool is 0)"),
            std::string::npos)
      << next.log();
  // Ended at X2 (run waited for that), with T2 still in the spindle.
  ASSERT_TRUE(hmi.wait_until(
      0,
      [](const msg::InterpolatorState& s) {
        return s.status() == 3 && s.orig_position()[0] == 2.0;
      },
      kHang));
  EXPECT_EQ(hmi.state(0)->tool_number(), 2);
}

// The PLC's basic parameters set the very gear ratios of its config: Command 1024 with a 32-bit
// numerator and denominator where they carry the value, the Ratio register where not. It sent
// ratio x 1000 + 0.5 over 1000: -1000 became -999.999, 3e6 overflowed into -2147483.648 (the
// axis reversed, "accepted"), 0.0004 became 0 and was refused.
TEST(ServiceProcesses, ThePlcSetsTheConfiguredGearRatiosExactly) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::string geared = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(
      geared, "axes: [{letter: X}, {letter: Y}, {letter: Z}]",
      "axes: [{letter: X, ratio_inc_per_mm: -1000}, {letter: Y, ratio_inc_per_mm: 3e6},\n"
      "           {letter: Z, ratio_inc_per_mm: 0.0004}]"));
  std::ofstream(env.path("geared.yaml")) << geared;
  // No pair of 32-bit whole numbers has this quotient (1 / 3 does: the double nearest to it).
  std::string fine = geared;
  ASSERT_TRUE(
      test::replace_first(fine, "ratio_inc_per_mm: 0.0004", "ratio_inc_per_mm: 1234.56789012345"));
  std::ofstream(env.path("fine.yaml")) << fine;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  for (const char* cfg : {"geared.yaml", "fine.yaml"}) {
    SCOPED_TRACE(cfg);
    const bool is_fine = std::string(cfg) == "fine.yaml";
    const double z = is_fine ? 1234.56789012345 : 0.0004;
    test::Child plc;
    ASSERT_TRUE(plc.start(
        {TGM_PLC_BIN, "--config", env.path(cfg), "--interpolator", "0", "--duration", "1.5"},
        env.path("plc.log")));
    EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
    EXPECT_EQ(test::count_of(plc.log(), "(gear ratio of axis"), is_fine ? 2 : 3) << plc.log();
    EXPECT_EQ(test::count_of(plc.log(), "): accepted"), 5) << plc.log();
    EXPECT_EQ(plc.log().find("refused"), std::string::npos) << plc.log();
    if (is_fine) {
      EXPECT_NE(plc.log().find("basic parameters: Ratio register of axis Z = 1234.56789012345 "
                               "inc/mm, the service had 4e-04 (no 32-bit numerator / "
                               "denominator of Command 1024 carries it): accepted"),
                std::string::npos)
          << plc.log();
    }
    // Each value, and the service's own where it differs: the first PLC replaced the service's
    // 1000, the second finds X and Y as the first left them.
    EXPECT_NE(plc.log().find(is_fine ? "Command 1024 (gear ratio of axis X: -1000 inc/mm): accepted"
                                     : "Command 1024 (gear ratio of axis X: -1000 inc/mm, the "
                                       "service had 1000): accepted"),
              std::string::npos)
        << plc.log();
    EXPECT_NE(plc.log().find(is_fine ? "Command 1024 (gear ratio of axis Y: 3e+06 inc/mm): accepted"
                                     : "Command 1024 (gear ratio of axis Y: 3e+06 inc/mm, the "
                                       "service had 1000): accepted"),
              std::string::npos)
        << plc.log();
    const auto until = std::chrono::steady_clock::now() + 3s;
    while (std::chrono::steady_clock::now() < until) {
      hmi.poll(50ms);
      if (hmi.state(0)->ratio()[2] == z) break;
    }
    EXPECT_EQ(hmi.state(0)->ratio()[0], -1000.0);
    EXPECT_EQ(hmi.state(0)->ratio()[1], 3e6);
    EXPECT_EQ(hmi.state(0)->ratio()[2], z);
  }
}

// With --interpolator N the PLC serves N alone: a script step for another interpolator was
// sent all the same. It is an error at the start, with the step's line.
TEST(ServiceProcesses, APlcScriptStepForAnInterpolatorNotServedIsAnError) {
  ServiceEnv env;
  const std::string script = env.path("other.yaml");
  std::ofstream(script) << "- {at_s: 0, interpolator: 1, rel_speed: 0.5}\n"
                           "- {at_s: 1, refuse_ack: [51]}\n";
  test::Child plc;
  ASSERT_TRUE(
      plc.start({TGM_PLC_BIN, "--config", env.config(), "--interpolator", "1", "--script", script},
                env.path("plc.log")));
  EXPECT_EQ(plc.wait(kHang), 2) << plc.log();
  EXPECT_EQ(plc.log(), "tgm-plc: " + script +
                           ":2: interpolator 0 is not served: tgm-plc runs with --interpolator 1 "
                           "(a step without `interpolator: N` is for interpolator 0)\n");
}

// A service restarted under a running tgm-plc: the PLC sees the new instance, sets the basic
// parameters again and handles M-functions at once. It used to ignore every sample until the new
// service's cycle counter passed the old one's (a service that had run an hour made the PLC deaf
// for an hour), and never set the parameters again. Two equal continuous M-functions in a row
// are two M-functions to the PLC (told apart by m_func_count), in both runs. The new service
// starts at 0, where the emulated drives are not: the PLC sets their last increments (Command
// 2048), so its first setpoints are where the first service left the axes.
TEST(ServiceProcesses, PlcServesARestartedServiceAtOnceAndSeesEqualMFunctionsApart) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  std::ofstream(env.path("m.ngc")) << "G1 X5 F3000\nM1001\nM1001\nG1 X10\nM50\nG1 X15\nM2\n";
  // The PLC sets the basic parameters of each interpolator as it finds it: a program started
  // before that would have them refused.
  auto wait_found = [&](int n) {
    for (int i = 0; i < 200 && test::count_of(plc.log(), ": setup done (") < n; ++i) {
      std::this_thread::sleep_for(50ms);
    }
    return test::count_of(plc.log(), ": setup done (");
  };
  ASSERT_EQ(wait_found(3), 3) << plc.log();
  auto run = [&](const char* log) {
    test::Child hmi;
    EXPECT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config()},
                          env.path(log)));
    EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << "\n--- plc:\n" << plc.log();
    EXPECT_NE(hmi.log().find("done: 7 records"), std::string::npos) << hmi.log();
  };
  run("hmi1.log");
  // Let the first service count well ahead of where the second will show M50.
  std::this_thread::sleep_for(4s);
  ASSERT_EQ(env.service.interrupt(), 0);
  const std::string first_log = env.service.log();
  const auto at = first_log.find(" after ", first_log.find("stopping ("));
  ASSERT_NE(at, std::string::npos) << first_log;
  const unsigned long long first_cycles = std::stoull(first_log.substr(at + 7));
  ASSERT_TRUE(env.start_service());
  ASSERT_EQ(wait_found(6), 6) << plc.log();
  test::Child look;
  ASSERT_TRUE(look.start({TGM_HMI_BIN, "status", "--json", "--config", env.config()},
                         env.path("status.log")));
  ASSERT_EQ(look.wait(kHang), 0) << look.log();
  EXPECT_NE(look.log().find("\"position_inc\":{\"X\":30000,\"Y\":0,\"Z\":0}"), std::string::npos)
      << look.log();
  EXPECT_NE(look.log().find("\"orig_position_mm\":{\"X\":30,\"Y\":0,\"Z\":0}"), std::string::npos)
      << look.log();
  run("hmi2.log");
  EXPECT_EQ(plc.interrupt(), 0);
  const std::string log = plc.log();
  EXPECT_EQ(test::count_of(log, "tgm-service restarted (instance"), 3) << log;
  // Commands -2, -1 and 1024 for each of the 3 axes, each accepted, from both services; for
  // the restarted one's interpolator 0, whose axes stood at X 30 (the default config starts in
  // G91), Command 2048 too.
  EXPECT_EQ(test::count_of(log, "Command 1024 (gear ratio of axis Z: 1000 inc/mm): accepted"), 6)
      << log;
  EXPECT_EQ(test::count_of(log, ": setup done (5 of 5 requests accepted)"), 5) << log;
  EXPECT_EQ(test::count_of(log,
                           "interpolator 0: position restore: Command 2048 with the "
                           "drives' last increments (X 30000 Y 0 Z 0): accepted"),
            1)
      << log;
  EXPECT_EQ(test::count_of(log, "interpolator 0: setup done (6 of 6 requests accepted)"), 1) << log;
  EXPECT_EQ(test::count_of(log, "M1001 continuous"), 4) << log;
  EXPECT_EQ(test::count_of(log, "M1001 noted"), 4) << log;
  EXPECT_EQ(test::count_of(log, "M50 acknowledged"), 2) << log;
  // The second service's M50 was acknowledged in a cycle before the first service's count.
  const auto last = log.rfind("M50 acknowledged");
  ASSERT_NE(last, std::string::npos);
  const auto cycle_at = log.find("(cycle ", last);
  ASSERT_NE(cycle_at, std::string::npos) << log;
  EXPECT_LT(std::stoull(log.substr(cycle_at + 7)), first_cycles) << log;
}

// plc.setup_before_start: without a PLC the service starts no program, and every HMI command
// says why (run after its wait, status, command start); a tgm-plc that sets nothing up
// (--no-basic-params) does not report a setup and says so (review of session 81); once tgm-plc
// has set the interpolator up (its report follows its basic parameters), the same run runs.
TEST(ServiceProcesses, WithSetupBeforeStartAProgramWaitsForThePlc) {
  test::ConfigEdits edits;
  edits.plc_setup_before_start = true;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("p.ngc")) << "G1 X5 F3000\nM2\n";
  const std::vector<std::string> run_args{
      TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config(), "--timeout", "2"};
  test::Child early;
  ASSERT_TRUE(early.start(run_args, env.path("early.log")));
  EXPECT_EQ(early.wait(kHang), 1) << early.log();
  EXPECT_NE(early.log().find("tgm-hmi run: waiting for the PLC to set interpolator 0 up"),
            std::string::npos)
      << early.log();
  EXPECT_NE(early.log().find("tgm-hmi run: the PLC has not set interpolator 0 up in the "),
            std::string::npos)
      << early.log();
  EXPECT_NE(early.log().find(" s waited, and the service starts no program before "
                             "(plc.setup_before_start in its config): start tgm-plc (its log says "
                             "why it did not report the setup, if it runs), use a PLC that sends "
                             "the report (REQUEST_KIND_PLC_SETUP_DONE; tgm-plc before version 0.2 "
                             "does not), or on a machine without a PLC set "
                             "plc.setup_before_start: false\n"),
            std::string::npos)
      << early.log();
  // On a terminal (script(1) gives it one) the waiting line counts down in place, once a
  // second (at most 4 lines in 3 s: waits truncated to 0 ms in the last millisecond spun,
  // each rewriting it, in one of two runs by hand).
  std::string line;
  for (const std::string& a : run_args) line += (line.empty() ? "" : " ") + a;
  line.replace(line.rfind("--timeout 2"), std::string::npos, "--timeout 3");
  test::Child tty;
  ASSERT_TRUE(tty.start({"/usr/bin/script", "-qec", line, "/dev/null"}, env.path("tty.log")));
  EXPECT_EQ(tty.wait(kHang), 1) << tty.log();
  EXPECT_NE(tty.log().find("\rtgm-hmi run: waiting for the PLC to set interpolator 0 up: 1 s "
                           "left\x1b[K"),
            std::string::npos)
      << tty.log();
  EXPECT_GE(test::count_of(tty.log(), " s left\x1b[K"), 2) << tty.log();
  EXPECT_LE(test::count_of(tty.log(), " s left\x1b[K"), 4) << tty.log();
  EXPECT_NE(tty.log().find("\x1b[K\r\ntgm-hmi run: the PLC has not set interpolator 0 up in the "),
            std::string::npos)
      << tty.log();
  test::Child look;
  ASSERT_TRUE(look.start({TGM_HMI_BIN, "status", "--config", env.config()}, env.path("st.log")));
  EXPECT_EQ(look.wait(kHang), 0) << look.log();
  EXPECT_NE(look.log().find("Status 0 (empty, not yet set up by the PLC: a start waits for it)"),
            std::string::npos)
      << look.log();
  test::Child start;
  ASSERT_TRUE(start.start({TGM_HMI_BIN, "command", "start", "--config", env.config()},
                          env.path("start.log")));
  EXPECT_EQ(start.wait(kHang), 1) << start.log();
  EXPECT_NE(start.log().find("the PLC has not set interpolator 0 up since tgm-service started "
                             "(position, gear ratios): start tgm-plc"),
            std::string::npos)
      << start.log();
  test::Child bare;
  ASSERT_TRUE(bare.start({TGM_PLC_BIN, "--config", env.config(), "--interpolator", "0",
                          "--no-basic-params", "--duration", "2"},
                         env.path("bare.log")));
  EXPECT_EQ(bare.wait(kHang), 0) << bare.log();
  EXPECT_NE(bare.log().find("interpolator 0: error: setup not reported to tgm-service "
                            "(--no-basic-params): it starts no program there until a PLC has "
                            "set it up (plc.setup_before_start)"),
            std::string::npos)
      << bare.log();
  test::Child still;
  ASSERT_TRUE(
      still.start({TGM_HMI_BIN, "status", "--config", env.config()}, env.path("still.log")));
  EXPECT_EQ(still.wait(kHang), 0) << still.log();
  EXPECT_NE(still.log().find("not yet set up by the PLC"), std::string::npos) << still.log();
  // tgm-plc reports the setup once it has set the interpolator up.
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--interpolator", "0"},
                        env.path("plc.log")));
  test::Child later;
  ASSERT_TRUE(later.start(
      {TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config(), "--timeout", "30"},
      env.path("later.log")));
  EXPECT_EQ(later.wait(kHang), 0) << later.log() << "\n--- plc:\n" << plc.log();
  EXPECT_NEAR(test::run_end_position(later.log())[0], 5.0, 1e-9) << later.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_NE(plc.log().find("interpolator 0: setup done (5 of 5 requests accepted)"),
            std::string::npos)
      << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: setup reported to tgm-service: accepted"),
            std::string::npos)
      << plc.log();
}

// A service that crashed and comes back while a `run` waits for it stands at 0, where the
// drives stand at X 5: the run compiles and starts only after tgm-plc's position restore, so
// the program's G91 move goes from X 5 to X 8 (review of session 80: the run could start before
// the restore, Command 2048 was then refused as "a program is loaded", and the program ran from
// X 0 while the drives stood at X 5).
TEST(ServiceProcesses, ARunWaitingForACrashedServiceStartsAfterThePlcRestoresThePosition) {
  test::ConfigEdits edits;
  edits.plc_setup_before_start = true;
  edits.interpolators = 1;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  std::ofstream(env.path("a.ngc")) << "G1 X5 F3000\nM2\n";
  std::ofstream(env.path("b.ngc")) << "G91 G1 X3 F3000\nM2\n";
  test::Child first;
  ASSERT_TRUE(first.start({TGM_HMI_BIN, "run", env.path("a.ngc"), "--config", env.config()},
                          env.path("first.log")));
  ASSERT_EQ(first.wait(kHang), 0) << first.log() << "\n--- plc:\n" << plc.log();
  ASSERT_EQ(env.service.interrupt(std::chrono::seconds(10), SIGKILL), 128 + SIGKILL)
      << env.service.log();
  for (int round = 0; round < 3; ++round) {
    test::Child second;
    ASSERT_TRUE(second.start({TGM_HMI_BIN, "run", env.path("b.ngc"), "--config", env.config()},
                             env.path("second" + std::to_string(round) + ".log")));
    std::this_thread::sleep_for(300ms);
    ASSERT_TRUE(env.start_service());
    ASSERT_EQ(second.wait(kHang), 0) << second.log() << "\n--- plc:\n" << plc.log();
    EXPECT_NEAR(test::run_end_position(second.log())[0], 8.0 + 3.0 * round, 1e-9)
        << second.log() << "\n--- plc:\n"
        << plc.log();
    ASSERT_EQ(env.service.interrupt(std::chrono::seconds(10), SIGKILL), 128 + SIGKILL);
  }
  EXPECT_EQ(plc.interrupt(), 0);
}

// The position goes to a restarted service by axis letter: the service ran XYZ (a PLC config of
// XYC sends it no basic parameters) and comes back with XYC. X and Y get their increments, C
// keeps the new service's 0, and Z, which it no longer drives, is named. By index, Z's 1000
// increments went to C.
TEST(ServiceProcesses, APlcRestoresARestartedServicesPositionByAxisLetter) {
  ServiceEnv env;
  std::string xyc = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(xyc, "axes: [{letter: X}, {letter: Y}, {letter: Z}]",
                                  "axes: [{letter: X}, {letter: Y}, {letter: C}]"));
  std::ofstream(env.path("xyc.yaml")) << xyc;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.path("xyc.yaml"), "--interpolator", "0"},
                        env.path("plc.log")));
  ASSERT_TRUE(plc.wait_for_log(": setup done (")) << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: setup done (0 of 0 requests accepted; basic "
                           "parameters not sent: this config's axes are not the service's)"),
            std::string::npos)
      << plc.log();
  std::ofstream(env.path("p.ngc")) << "G1 X5 Y2 Z1 F3000\nM2\n";
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config()},
                        env.path("run.log")));
  ASSERT_EQ(run.wait(kHang), 0) << run.log();
  std::this_thread::sleep_for(500ms);  // the PLC takes the last state (every 20 ms at most)
  ASSERT_EQ(env.service.interrupt(), 0);
  ASSERT_TRUE(env.start_service({"--config", env.path("xyc.yaml")}));
  for (int i = 0; i < 300 && test::count_of(plc.log(), ": setup done (") < 2; ++i)
    std::this_thread::sleep_for(50ms);
  ASSERT_EQ(test::count_of(plc.log(), ": setup done ("), 2) << plc.log();
  const std::string log = plc.log();
  EXPECT_NE(log.find("interpolator 0: warning: the restarted service does not drive Z (it drives "
                     "XYC): Z's last position is not restored"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("interpolator 0: position restore: Command 2048 with the drives' last "
                     "increments (X 5000 Y 2000 C 0; C as the service has it): accepted"),
            std::string::npos)
      << log;
  test::Child look;
  ASSERT_TRUE(look.start({TGM_HMI_BIN, "status", "--json", "--config", env.path("xyc.yaml")},
                         env.path("status.log")));
  ASSERT_EQ(look.wait(kHang), 0) << look.log();
  EXPECT_NE(look.log().find("\"position_inc\":{\"X\":5000,\"Y\":2000,\"C\":0}"), std::string::npos)
      << look.log();
  EXPECT_EQ(plc.interrupt(), 0);
}

// A tgm-plc that outlives a stopped and a killed tgm-service serves the one after both: it
// sets the basic parameters of each and acknowledges the next program's M50, with no request
// left unanswered. Over Fast DDS's shared memory, 3 of 9 trials of a longer form of this
// sequence (a run streaming and a watch beside it, 8 s between the kill and the restart) left
// the PLC cut off for good or the last service unseen (session 76's soak review), and tgm is
// on UDPv4 only since (config/fastdds_profiles.xml). This short form did not show that fault
// in 8 trials with shared memory (TGM_TEST_PROFILES=tests/bench/service/shm.xml): it checks
// the PLC's side of the restarts, not the transport.
TEST(ServiceProcesses, APlcOutlivesAStoppedAndAKilledServiceAndServesTheNext) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  auto wait_found = [&](int n) {
    for (int i = 0; i < 300 && test::count_of(plc.log(), ": setup done (") < n; ++i) {
      std::this_thread::sleep_for(50ms);
    }
    return test::count_of(plc.log(), ": setup done (");
  };
  ASSERT_EQ(wait_found(3), 3) << plc.log();
  ASSERT_EQ(env.service.interrupt(), 0);
  test::Child look;  // an HMI while no service runs
  ASSERT_TRUE(look.start({TGM_HMI_BIN, "status", "--wait", "1", "--config", env.config()},
                         env.path("status.log")));
  EXPECT_EQ(look.wait(kHang), 1) << look.log();
  ASSERT_TRUE(env.start_service());
  ASSERT_EQ(wait_found(6), 6) << plc.log();
  ASSERT_EQ(env.service.interrupt(kHang, SIGKILL), 128 + SIGKILL);
  ASSERT_TRUE(env.start_service());
  ASSERT_EQ(wait_found(9), 9) << plc.log();
  std::ofstream(env.path("m.ngc")) << "G1 X5 F3000\nM50\nG1 X10\nM2\n";
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config()},
                        env.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << "\n--- plc:\n" << plc.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(test::count_of(plc.log(), "M50 acknowledged"), 1) << plc.log();
  EXPECT_EQ(test::count_of(plc.log(), "no reply within"), 0) << plc.log();
}

// `tgm-hmi run` under a service that stops mid-program and comes back: it says when the state
// falls silent, and used to wait for ever after the restart (the new service's state is not its
// program's); it ends with exit code 1 and says why. While the state is silent its log gets no
// more progress lines (it got the last "running" one every second). `tgm-hmi watch` beside it
// says the same silence and the return (it showed the last state as if it were news).
TEST(ServiceProcesses, HmiRunEndsWithAClearErrorWhenTheServiceRestarts) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("long.ngc")) << "G1 X200 F1000\nM2\n";  // 12 s
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config(),
                         "--progress-interval", "0.2"},
                        env.path("hmi.log")));
  test::Child watcher;
  ASSERT_TRUE(
      watcher.start({TGM_HMI_BIN, "watch", "--json", "--interval", "0.2", "--config", env.config()},
                    env.path("watch.log")));
  {
    client::Client watch(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(watch.wait_until(
        0, [](const msg::InterpolatorState& s) { return s.status() == 1; }, kHang))
        << hmi.log();
  }
  // Killed (a crash, a power cut of its host): a service stopped by a signal says it shuts
  // down, and the run then ends at its silence (ARunEndsWhenTheServiceShutsDownDuringIt).
  ASSERT_EQ(env.service.interrupt(kHang, SIGKILL), 128 + SIGKILL);
  hmi.wait_for_log("no state from tgm-service");
  EXPECT_NE(hmi.log().find("no state from tgm-service for 3 s"), std::string::npos) << hmi.log();
  std::this_thread::sleep_for(1500ms);  // 7 progress intervals
  {
    const std::string log = hmi.log();
    const auto notice = log.find("no state from tgm-service");
    ASSERT_NE(notice, std::string::npos) << log;
    EXPECT_EQ(log.find("% line ", notice), std::string::npos) << log;
  }
  ASSERT_TRUE(env.start_service());
  EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
  EXPECT_NE(hmi.log().find("tgm-service restarted during the run"), std::string::npos) << hmi.log();
  watcher.wait_for_log("tgm-service is back");
  EXPECT_EQ(watcher.interrupt(), 0);
  const std::string watched = watcher.log();
  const auto silent = watched.find(
      "tgm-hmi watch: no state from tgm-service for 3 s (stopped, or the network is down)");
  EXPECT_NE(silent, std::string::npos) << watched;
  EXPECT_NE(watched.find("tgm-hmi watch: tgm-service is back", silent), std::string::npos)
      << watched;
  // And that it is another service, whose registers start afresh (they switched silently).
  EXPECT_NE(watched.find("tgm-hmi watch: tgm-service restarted (instance ", silent),
            std::string::npos)
      << watched;
  // Standard output says it too: each JSON line's state_age_s, the time since that state
  // arrived, grew through the silence (3 s and more) and fell again with the new service.
  std::vector<double> ages;
  for (std::size_t at = watched.find("\"state_age_s\":"); at != std::string::npos;
       at = watched.find("\"state_age_s\":", at + 1)) {
    ages.push_back(std::strtod(watched.c_str() + at + 14, nullptr));
  }
  ASSERT_GE(ages.size(), 10u) << watched;
  EXPECT_LT(ages.front(), 1.0) << watched;
  EXPECT_GE(*std::max_element(ages.begin(), ages.end()), 3.0) << watched;
  EXPECT_LT(ages.back(), 1.0) << watched;
}

// An emergency stop off the trajectory (Command 5) drops the program: the run ends with exit
// code 1 and names it. The Command register is back at 0 when the ramp has ended, and the run
// once said "Command 0".
TEST(ServiceProcesses, HmiRunEndsAtAnEmergencyStopOffTheTrajectory) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("long.ngc")) << "G1 X200 F1000\nM2\n";  // 12 s
  test::Child hmi;
  ASSERT_TRUE(
      hmi.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config(), "--quiet"},
                env.path("hmi.log")));
  {
    client::Client watch(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(watch.wait_until(
        0, [](const msg::InterpolatorState& s) { return s.status() == 1; }, kHang))
        << hmi.log();
  }
  test::Child estop;
  ASSERT_TRUE(estop.start({TGM_HMI_BIN, "command", "estop-off", "--config", env.config()},
                          env.path("estop.log")));
  EXPECT_EQ(estop.wait(kHang), 0) << estop.log();
  EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
  EXPECT_NE(hmi.log().find("tgm-hmi run: emergency stop (Command 5), off trajectory at line 1: "
                           "the program was dropped\n"),
            std::string::npos)
      << hmi.log();
}

// `tgm-hmi run` of `records` tenth steps at F3000 (hmi), stopped by Command 4 on the trajectory
// once it runs past part 100. From this process (watch): a `tgm-hmi command` under
// AddressSanitizer may take seconds to start, and the stream could be complete by then.
void run_into_an_emergency_stop(ServiceEnv& env, int records, test::Child& hmi,
                                client::Client& watch, bool quiet = true) {
  write_tenth_steps(env.path("long.ngc"), records, 3000);
  std::vector<std::string> args{TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config()};
  if (quiet) {
    args.emplace_back("--quiet");
  } else {
    args.insert(args.end(), {"--progress-interval", "0.1"});
  }
  ASSERT_TRUE(hmi.start(args, env.path("hmi.log")));
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 1 && s.act_part() > 100; },
      kHang))
      << hmi.log();
  const client::Reply estop = watch.command(0, 4);
  EXPECT_TRUE(estop.accepted) << client::describe(estop);
  ASSERT_TRUE(hmi.wait_for_log("emergency stop (Command 4) at line ", kHang)) << hmi.log();
}

// An emergency stop on the trajectory (Command 4) is resumed by start, so `run` follows on and
// streams the rest. It used to end there with exit code 1: a program longer than the buffer
// then resumed into an underrun, the records beyond the buffer never sent.
TEST(ServiceProcesses, HmiRunStreamsOnAfterAnEmergencyStopOnTheTrajectory) {
  test::ConfigEdits edits;
  edits.buffer_size0 = 1000;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  // 500 mm in about 10 s, five buffers' worth.
  constexpr int kRecords = 5000;
  test::Child hmi;
  client::Client watch(env.dds(), client::Role::kHmi);
  ASSERT_NO_FATAL_FAILURE(run_into_an_emergency_stop(env, kRecords, hmi, watch, false));
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 7; }, kHang));
  // The progress display goes on through the hold, saying so (it froze until the start).
  ASSERT_TRUE(hmi.wait_for_log(" F0 emergency stopped\n", kHang)) << hmi.log();
  // Records are still to be sent, and the run is still there to send them.
  EXPECT_LT(watch.state(0)->next_sequence(), static_cast<std::uint64_t>(kRecords));
  EXPECT_EQ(watch.state(0)->off_trajectory(), false);
  EXPECT_EQ(hmi.wait(std::chrono::milliseconds(0)), -1) << hmi.log();  // not ended
  const client::Reply start = watch.start(0);
  EXPECT_TRUE(start.accepted) << client::describe(start);
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 3; }, kHang));
  // Every record executed once: the count and the end point.
  EXPECT_EQ(watch.state(0)->next_sequence(), static_cast<std::uint64_t>(kRecords + 1));
  EXPECT_NEAR(watch.state(0)->orig_position()[0], 0.1 * kRecords, 1e-6);
}

// Command 9 after Command 4: the status stays 7 and the program is dropped off the trajectory.
// The run said "emergency stop (Command 5)", which nobody had sent.
TEST(ServiceProcesses, HmiRunNamesAStopOffTheTrajectoryAfterAnEmergencyStop) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child hmi;
  client::Client watch(env.dds(), client::Role::kHmi);
  ASSERT_NO_FATAL_FAILURE(run_into_an_emergency_stop(env, 5000, hmi, watch));
  const client::Reply off = watch.command(0, 9);
  EXPECT_TRUE(off.accepted) << client::describe(off);
  EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
  EXPECT_NE(hmi.log().find("after the emergency stop, a stop off the trajectory (Command 9 or 5) "
                           "at line "),
            std::string::npos)
      << hmi.log();
  EXPECT_EQ(hmi.log().find("Command 5)"), std::string::npos) << hmi.log();
}

// On a terminal, an M0 waits for Enter. The end of the terminal's input (Ctrl-D, or a closed
// SSH session, which no longer ends the run) was taken for Enter and the program ran on past
// its M0 at once; now the M0 waits for a start, here from another HMI, and the run follows on.
TEST(ServiceProcesses, HmiRunKeepsAnM0WhenTheTerminalInputEnds) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("m0.ngc")) << "G91 G1 X10 F3000\nM0\nG1 X10\nM2\n";
  // script(1) gives the run a terminal whose input ends at once (its own is /dev/null).
  test::Child hmi;
  ASSERT_TRUE(hmi.start(
      {"/usr/bin/script", "-qfc",
       "'" TGM_HMI_BIN "' run '" + env.path("m0.ngc") + "' --config '" + env.config() + "'",
       "/dev/null"},
      env.path("hmi.log")));
  client::Client watch(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 4 && s.program_stop(); },
      kHang))
      << hmi.log();
  ASSERT_TRUE(hmi.wait_for_log("waits for `tgm-hmi command start`", kHang)) << hmi.log();
  std::this_thread::sleep_for(1500ms);
  watch.poll(50ms);
  EXPECT_EQ(watch.state(0)->status(), 4) << hmi.log();
  EXPECT_NEAR(watch.state(0)->orig_position()[0], 10.0, 1e-9);
  const client::Reply start = watch.start(0);
  EXPECT_TRUE(start.accepted) << client::describe(start);
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log();
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 3; }, kHang));
  EXPECT_NEAR(watch.state(0)->orig_position()[0], 20.0, 1e-9);
}

// A stand-in for tgm-service on the test's domain: the endpoints a client matches (state,
// event, request, reply, program), one interpolator's state as the test sets it, and requests
// taken but answered only when the test says so. What a frozen service or one cut off after
// its state arrived looks like to a client.
// `pred` polled every 10 ms until it holds; false after `limit`.
template <class Pred>
bool eventually(Pred pred, std::chrono::milliseconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (!pred()) {
    if (std::chrono::steady_clock::now() >= until) return false;
    std::this_thread::sleep_for(10ms);
  }
  return true;
}

struct SilentService {
  // Without `events` it has no event writer, so a client's event reader never matches.
  explicit SilentService(const DdsConfig& c, bool events = true)
      : p(c, "silent"),
        state_w(p.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic)),
        event_w(events ? &p.writer<msg::InterpolatorEventPubSubType>(dds::kEventTopic) : nullptr),
        reply_w(p.writer<msg::ReplyPubSubType>(dds::kReplyTopic)),
        request_r(p.reader<msg::RequestPubSubType>(dds::kRequestTopic)),
        program_r(p.reader<msg::ProgramChunkPubSubType>(dds::kProgramTopic)) {
    state.interpolator(0);
    state.service_instance(0x5117E47);
    state.number_axes(3);
    state.buffer_size(1000);
    state.free_buffer_slots(1000);
    state.cycle_time_us(500);
    state.rel_speed(1.0);
  }
  void publish() {
    state.cycle_counter(state.cycle_counter() + 1);
    state_w.write(&state);
  }
  // The next request, publishing the state every 10 ms meanwhile; nullopt after `limit`.
  // The next request not taken before: a client that heard no reply writes its request again
  // under the same id (Client::request), and those repeats are skipped.
  std::optional<msg::Request> next_request(std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    msg::Request r;
    while (std::chrono::steady_clock::now() < until) {
      if (dds::take_next(request_r, r)) {
        if (!taken.emplace(r.client_name(), r.request_id()).second) continue;
        return r;
      }
      publish();
      std::this_thread::sleep_for(10ms);
    }
    return std::nullopt;
  }
  void accept(const msg::Request& r) {
    msg::Reply rep = accepted_reply(r, state.cycle_counter());
    reply_w.write(&rep);
  }
  std::set<std::pair<std::string, std::uint64_t>> taken;

  dds::Participant p;
  fdds::DataWriter& state_w;
  fdds::DataWriter* event_w;
  fdds::DataWriter& reply_w;
  fdds::DataReader& request_r;
  fdds::DataReader& program_r;
  msg::InterpolatorState state;
};

// Ctrl-C is taken while `run` and `watch` wait for the service: they ignored it until their
// wait ran out (10 s for the first state, 30 s for the reply to run's clear or start), then
// said "no state" or "no reply" and exited 1, with the run's start possibly still carried out.
TEST(ServiceProcesses, RunAndWatchTakeCtrlCWhileTheyWaitForTheService) {
  ServiceEnv env;
  std::ofstream(env.path("p.ngc")) << "G91 G1 X10 F3000\nM2\n";
  const std::vector<std::string> run = {TGM_HMI_BIN, "run", env.path("p.ngc"), "--config",
                                        env.config()};
  SilentService service(env.dds());
  // No state yet: the client's state reader matching means the signal flag is set up.
  for (const std::vector<std::string>& args :
       {run, std::vector<std::string>{TGM_HMI_BIN, "watch", "--config", env.config()}}) {
    test::Child hmi;
    ASSERT_TRUE(hmi.start(args, env.path("wait.log")));
    ASSERT_TRUE(dds::wait_for_match(service.state_w, 1, kHang)) << hmi.log();
    EXPECT_EQ(hmi.interrupt(kHang), 130) << hmi.log();
    EXPECT_NE(hmi.log().find("interrupted while waiting for the state of interpolator 0"),
              std::string::npos)
        << hmi.log();
    ASSERT_TRUE(eventually([&] { return !dds::wait_for_match(service.state_w, 1, 0ms); }, kHang));
  }

  // A state that needs a clear (an ended program); the clear is taken and not answered.
  service.state.status(3);
  {
    test::Child hmi;
    ASSERT_TRUE(hmi.start(run, env.path("clear.log")));
    const std::optional<msg::Request> clear = service.next_request(kHang);
    ASSERT_TRUE(clear.has_value()) << hmi.log();
    EXPECT_EQ(clear->kind(), msg::REQUEST_KIND_CLEAR);
    EXPECT_EQ(hmi.interrupt(kHang), 130) << hmi.log();
    EXPECT_NE(hmi.log().find("clearing interpolator 0: interrupted after"), std::string::npos)
        << hmi.log();
    EXPECT_NE(hmi.log().find("the request was sent"), std::string::npos) << hmi.log();
  }

  // The clear answered, the program taken whole: the start is taken and not answered. A start
  // that was sent may still be carried out, so the run stops as at any Ctrl-C.
  test::Child hmi;
  ASSERT_TRUE(hmi.start(run, env.path("start.log")));
  std::optional<msg::Request> r = service.next_request(kHang);
  ASSERT_TRUE(r.has_value() && r->kind() == msg::REQUEST_KIND_CLEAR) << hmi.log();
  service.state.status(0);
  service.publish();
  service.accept(*r);
  msg::ProgramChunk chunk;
  ASSERT_TRUE(eventually([&] { return dds::take_next(service.program_r, chunk); }, kHang))
      << hmi.log();
  service.state.program_id(chunk.program_id());
  service.state.next_sequence(1000);
  service.state.status(4);
  r = service.next_request(kHang);
  ASSERT_TRUE(r.has_value()) << hmi.log();
  EXPECT_EQ(r->kind(), msg::REQUEST_KIND_START);
  ASSERT_GT(hmi.pid(), 0);
  ::kill(hmi.pid(), SIGINT);
  r = service.next_request(kHang);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->kind(), msg::REQUEST_KIND_STOP);
  // The stop is not answered either: the run repeats it until a second Ctrl-C gives up, and
  // then says that nothing was stopped.
  hmi.wait_for_log("trying again", kHang, 20ms);
  EXPECT_EQ(hmi.interrupt(kHang), 130) << hmi.log();
  EXPECT_NE(hmi.log().find("interrupted: start: interrupted after"), std::string::npos)
      << hmi.log();
  EXPECT_NE(hmi.log().find("normal stop:"), std::string::npos) << hmi.log();
  EXPECT_NE(hmi.log().find("the interpolator was NOT stopped: it may still be executing program"),
            std::string::npos)
      << hmi.log();

  // `command` waiting for its reply: the Ctrl-C is said with what is known of the request. It
  // died of the signal without a word, which left open whether the start had been sent.
  test::Child command;
  ASSERT_TRUE(
      command.start({TGM_HMI_BIN, "command", "start", "--config", env.config(), "--timeout", "60"},
                    env.path("command.log")));
  do {  // (the run's repeated stops may still come first)
    r = service.next_request(kHang);
  } while (r.has_value() && r->kind() == msg::REQUEST_KIND_STOP);
  ASSERT_TRUE(r.has_value()) << command.log();
  EXPECT_EQ(r->kind(), msg::REQUEST_KIND_START);
  EXPECT_EQ(command.interrupt(kHang), 130) << command.log();
  EXPECT_NE(command.log().find("tgm-hmi command: start: interrupted after"), std::string::npos)
      << command.log();
  EXPECT_NE(command.log().find("the request was sent, whether tgm-service executed it is not "
                               "known"),
            std::string::npos)
      << command.log();
}

// Ctrl-C is taken while `run` waits for its event reader to match the service's event writer
// (up to 5 s; a service that has none, here): run went on to its warning that M-function
// waits are counted from the state, and only then saw the Ctrl-C.
TEST(ServiceProcesses, RunTakesCtrlCWhileItWaitsForTheEventTopic) {
  ServiceEnv env;
  std::ofstream(env.path("p.ngc")) << "G91 G1 X10 F3000\nM2\n";
  SilentService service(env.dds(), /*events=*/false);
  test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config()},
                        env.path("run.log")));
  ASSERT_TRUE(dds::wait_for_match(service.state_w, 1, kHang)) << hmi.log();
  // The state goes out every 10 ms; a second of it is far more than run needs to take one
  // and reach the event wait, and far less than the wait's 5 s.
  EXPECT_FALSE(service.next_request(1s).has_value()) << hmi.log();
  EXPECT_EQ(hmi.interrupt(kHang), 130) << hmi.log();
  EXPECT_NE(hmi.log().find("interrupted while waiting for the event topic to match"),
            std::string::npos)
      << hmi.log();
  EXPECT_EQ(hmi.log().find("did not match within 5 s"), std::string::npos) << hmi.log();
}

// Ctrl-C while a program larger than the buffer streams: the run stops the interpolator and
// says how much of the program stays loaded and what a start would do with it. It said only
// "normal stop: accepted", and a start from another HMI ran the part and stood in underrun.
TEST(ServiceProcesses, AnInterruptedRunSaysWhatOfItsProgramStaysLoaded) {
  test::ConfigEdits edits;
  edits.buffer_size0 = 1000;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  write_tenth_steps(env.path("long.ngc"), 5000, 600);  // 500 mm at 10 mm/s: minutes
  test::Child run;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(start_run_until(env, env.path("long.ngc"), run, hmi,
                              [](const msg::InterpolatorState& s) { return s.status() == 1; }));
  EXPECT_EQ(run.interrupt(kHang), 130) << run.log();
  const std::string log = run.log();
  // The chunks written and not yet confirmed arrive after the stop: the count says how many
  // records that can be (the service held up to 128 more than it said: review of session 77).
  const std::regex said(
      "interrupted: normal stop: accepted; only ([0-9]+) of its 5001 records reached the buffer( "
      "\\(up to ([0-9]+) once the chunks on their way arrive\\))? and stay loaded: a start runs "
      "only those and then stands in underrun; `tgm-hmi command clear` drops them");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(log, m, said)) << log;
  const int loaded = std::stoi(m[1].str());
  const int up_to = m[3].matched ? std::stoi(m[3].str()) : loaded;
  EXPECT_GE(loaded, 500);  // run starts the program once half the buffer is filled
  EXPECT_LT(loaded, 5001);
  EXPECT_GE(up_to, loaded);
  // What the service holds once the stream settled (its state every 20 ms at most).
  std::this_thread::sleep_for(500ms);
  const std::uint64_t from = hmi.state(0)->cycle_counter();
  ASSERT_TRUE(hmi.wait_until(
      0, [&](const msg::InterpolatorState& s) { return s.cycle_counter() > from + 100; }, kHang));
  const std::uint64_t held = hmi.state(0)->next_sequence();
  EXPECT_GE(held, static_cast<std::uint64_t>(loaded)) << log;
  EXPECT_LE(held, static_cast<std::uint64_t>(up_to)) << log;
}

// An interpolator the service does not host (its config has fewer) is named as such within a
// second or so of the others' states: status, watch and run waited out their 10 s and asked
// whether a service was running at all.
TEST(ServiceProcesses, AnInterpolatorTheServiceDoesNotHostIsNamed) {
  test::ConfigEdits one;
  one.interpolators = 1;
  ServiceEnv service_env(one), hmi_env;  // the HMI's config has the default three
  ASSERT_TRUE(service_env.start_service());
  std::ofstream(hmi_env.path("p.ngc")) << "G91 G1 X10 F3000\nM2\n";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{TGM_HMI_BIN, "status", "--interpolator", "2"},
        std::vector<std::string>{TGM_HMI_BIN, "watch", "--interpolator", "1"},
        std::vector<std::string>{TGM_HMI_BIN, "run", hmi_env.path("p.ngc"), "--interpolator",
                                 "1"}}) {
    std::vector<std::string> a = args;
    a.insert(a.end(),
             {"--config", hmi_env.config(), "--domain", std::to_string(service_env.domain())});
    test::Child hmi;
    ASSERT_TRUE(hmi.start(a, hmi_env.path("hmi.log")));
    EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
    const std::string expect = "tgm-service on DDS domain " + std::to_string(service_env.domain()) +
                               " hosts interpolator 0, not " + args[args.size() - 1] +
                               " (its config has 1 interpolator, " + hmi_env.config() + " has 3)";
    EXPECT_NE(hmi.log().find(expect), std::string::npos) << hmi.log();
  }
  client::Client watch(service_env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watch.wait_for_state(0, kHang));
  EXPECT_EQ(watch.state(0)->status(), 0);  // the run sent nothing
  // `status --all` lists the HMI config's three: the two the service lacks as not hosted (it
  // said "no state", which read like a fault).
  {
    test::Child all;
    ASSERT_TRUE(all.start({TGM_HMI_BIN, "status", "--all", "--config", hmi_env.config(), "--domain",
                           std::to_string(service_env.domain())},
                          hmi_env.path("all.log")));
    EXPECT_EQ(all.wait(kHang), 0) << all.log();
    EXPECT_NE(all.log().find("Interpolator 0: Status 0"), std::string::npos) << all.log();
    for (const char* i : {"1", "2"}) {
      EXPECT_NE(all.log().find(std::string("Interpolator ") + i +
                               ": not hosted by tgm-service (no state within 2 s; its config has "
                               "fewer interpolators than this one)"),
                std::string::npos)
          << all.log();
    }
  }

  // The PLC serves interpolator 0 and says once that the others are not hosted (it said
  // "waiting for tgm-service" every 5 s beside the running service, or nothing).
  test::Child plc;
  ASSERT_TRUE(plc.start(
      {TGM_PLC_BIN, "--config", hmi_env.config(), "--domain", std::to_string(service_env.domain())},
      hmi_env.path("plc.log")));
  EXPECT_TRUE(plc.wait_for_log("interpolators 1, 2: tgm-service on DDS domain " +
                                   std::to_string(service_env.domain()) +
                                   " hosts 0 only (its config has fewer interpolators than " +
                                   hmi_env.config() + "): not served until a service hosts them",
                               kHang))
      << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: found"), std::string::npos) << plc.log();
  EXPECT_EQ(plc.interrupt(kHang), 0) << plc.log();
}

// A reader of standard output that goes away (`| head`) no longer kills `run` by SIGPIPE: it
// died and left a program longer than the buffer to run dry in an underrun. It follows and
// streams on to the end, and says at exit that its output was lost (exit code 1). SIGHUP, the
// same. `watch` ends cleanly when its reader has gone (it died by SIGPIPE too, exit code 141).
TEST(ServiceProcesses, RunAndWatchOutliveTheReaderOfTheirOutput) {
  test::ConfigEdits edits;
  edits.buffer_size0 = 1000;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  constexpr int kRecords = 5000;  // about 5 s, five buffers' worth
  write_tenth_steps(env.path("long.ngc"), kRecords, 6000);
  const std::string hmi = "'" TGM_HMI_BIN "'", cfg = " --config '" + env.config() + "'";
  const test::ShellRun run = test::run_shell(
      "((" + hmi + " run '" + env.path("long.ngc") + "'" + cfg + " --progress-interval 0.1 2>'" +
          env.path("run.err") + "'; echo $? >'" + env.path("run.rc") +
          "') | head -n 2)",  // (run_shell's redirections go to the whole)
      env.path(""), "run_head");
  EXPECT_EQ(std::count(run.out.begin(), run.out.end(), '\n'), 2) << run.out;
  const std::string run_err = test::read_text(env.path("run.err"));
  EXPECT_EQ(test::read_text(env.path("run.rc")), "1\n") << run_err;
  EXPECT_NE(run_err.find("tgm-hmi: cannot write standard output"), std::string::npos) << run_err;
  client::Client watch(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 3; }, kHang))
      << run_err;
  EXPECT_EQ(watch.state(0)->next_sequence(), static_cast<std::uint64_t>(kRecords + 1));
  EXPECT_NEAR(watch.state(0)->orig_position()[0], 0.1 * kRecords, 1e-6);

  // A closed terminal or SSH session (SIGHUP) killed it the same way (exit code 129).
  test::Child hup;
  ASSERT_TRUE(hup.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config()},
                        env.path("hup.log")));
  ASSERT_TRUE(watch.wait_until(
      0,
      [](const msg::InterpolatorState& s) {
        return s.status() == 1 && s.act_part() > 100 && s.next_sequence() < kRecords;
      },
      kHang))
      << hup.log();
  EXPECT_EQ(hup.interrupt(kHang, SIGHUP), 0) << hup.log();
  ASSERT_TRUE(watch.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 3; }, kHang));
  EXPECT_EQ(watch.state(0)->next_sequence(), static_cast<std::uint64_t>(kRecords + 1));
  EXPECT_NEAR(watch.state(0)->orig_position()[0], 0.2 * kRecords, 1e-6);  // G91: from 500 mm on

  for (const char* json : {" --json", ""}) {
    const test::ShellRun w = test::run_shell("((" + hmi + " watch --interval 0.05" + json + cfg +
                                                 " 2>'" + env.path("watch.err") + "'; echo $? >'" +
                                                 env.path("watch.rc") + "') | head -n 1)",
                                             env.path(""), "watch_head");
    EXPECT_EQ(std::count(w.out.begin(), w.out.end(), '\n'), 1) << w.out;
    EXPECT_EQ(test::read_text(env.path("watch.rc")), "0\n")
        << json << test::read_text(env.path("watch.err"));
    EXPECT_EQ(test::read_text(env.path("watch.err")), "") << json;
  }
}

// A second tgm-service on a live service's domain would take the same requests and programs:
// it looks for another service's state before serving and exits 1 naming its instance, and the
// first goes on. Two that started within each other's wait (here: --service-check-ms 0) both
// say so, on standard error and as an error message to the HMIs. A service that is gone (its
// participant still within its lease after SIGKILL) publishes nothing and holds up no restart.
TEST(ServiceProcesses, ASecondServiceOnTheDomainIsRefusedOrReported) {
  ServiceEnv env;
  // Not looking, the first service also never gives way (OfTwoServicesStartedTogetherOneGivesWay):
  // the unchecked one below starts within its first cycles.
  ASSERT_TRUE(env.start_service({"--service-check-ms", "0"}));
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  const std::uint64_t first = hmi.state(0)->service_instance();
  char first_hex[17];
  std::snprintf(first_hex, sizeof first_hex, "%016llx", static_cast<unsigned long long>(first));

  test::Child second;
  ASSERT_TRUE(second.start({TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime"},
                           env.path("second.log")));
  EXPECT_EQ(second.wait(kHang), 1) << second.log();
  EXPECT_NE(second.log().find(std::string("another tgm-service (instance ") + first_hex +
                              ") already serves DDS domain " + std::to_string(env.domain())),
            std::string::npos)
      << second.log();
  EXPECT_EQ(hmi.state(0)->service_instance(), first);  // the first one goes on

  test::Child unchecked;
  ASSERT_TRUE(unchecked.start(
      {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime", "--service-check-ms", "0"},
      env.path("unchecked.log")));
  // Up to 20 s: under ASan, with the tests beside it starting services of their own, the
  // unchecked one took more than the 5 s this allowed to find the first (CI, session 58).
  bool said = false;
  for (int i = 0; i < 400 && !said; ++i) {
    hmi.poll(50ms);
    for (const msg::Message& m : hmi.take_messages()) {
      said = said || (m.severity() == msg::SEVERITY_ERROR &&
                      std::string(m.text().to_string()).find("another tgm-service (instance ") !=
                          std::string::npos);
    }
  }
  EXPECT_TRUE(said);
  for (int i = 0;
       i < 100 && (env.service.log().find("serves this DDS domain") == std::string::npos ||
                   unchecked.log().find("serves this DDS domain") == std::string::npos);
       ++i) {
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_NE(env.service.log().find("another tgm-service (instance "), std::string::npos)
      << env.service.log();
  EXPECT_NE(unchecked.log().find(std::string("another tgm-service (instance ") + first_hex +
                                 ") serves this DDS domain"),
            std::string::npos)
      << unchecked.log();
  EXPECT_EQ(unchecked.interrupt(10s, SIGTERM), 0) << unchecked.log();

  // Killed without a word, the first service leaves its participant behind for the lease; a
  // new service starts at once all the same.
  EXPECT_EQ(env.service.interrupt(10s, SIGKILL), 128 + SIGKILL);
  ASSERT_TRUE(env.start_service());
  ASSERT_TRUE(hmi.wait_until(
      0, [&](const msg::InterpolatorState& s) { return s.service_instance() != first; }, kHang))
      << env.service.log();
  EXPECT_EQ(env.service.log().find("already serves"), std::string::npos) << env.service.log();
}

// SIGTERM during the look for another service (--service-check-ms) ends the service there:
// the signals were blocked for the main loop's sigtimedwait, so it looked on for up to 10 s
// and then served the domain before it stopped (session 75).
TEST(ServiceProcesses, ASignalDuringTheLookForAnotherServiceEndsItThere) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service({"--service-check-ms", "8000"}));
  env.service.wait_for_log("looking 8000 ms for another tgm-service");
  const auto sent = std::chrono::steady_clock::now();
  EXPECT_EQ(env.service.interrupt(kHang, SIGTERM), 0) << env.service.log();
  EXPECT_LT(std::chrono::steady_clock::now() - sent, 5s) << "it looked on";
  const std::string log = env.service.log();
  EXPECT_NE(log.find("tgm-service: Terminated while looking for another tgm-service: exiting, "
                     "nothing served"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("interpolators, cycle"), std::string::npos) << log;
}

// A service stopped during a run brings the motion to rest, says so, and goes: the run then
// waited for it without end ("no state for 3 s ... waiting"), and on Ctrl-C said the
// interpolator "was NOT stopped" (session 75). It ends, exit 1, naming what happened.
TEST(ServiceProcesses, ARunEndsWhenTheServiceShutsDownDuringIt) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("long.ngc")) << "G90 G1 X200 F3000\nM2\n";  // 4 s
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config()},
                        env.path("run.log")));
  ASSERT_TRUE(run.wait_for_log("records for interpolator 0")) << run.log();
  std::this_thread::sleep_for(1s);
  EXPECT_EQ(env.service.interrupt(kHang, SIGTERM), 0) << env.service.log();
  EXPECT_EQ(run.wait(20s), 1) << run.log();
  const std::string log = run.log();
  EXPECT_NE(log.find("warning (line 1): tgm-service is stopping: normal stop on the trajectory"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("tgm-hmi run: tgm-service shut down during the run (it said so, then went "
                     "silent; last seen at Status 4"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("NOT stopped"), std::string::npos) << log;
}

// A SCHED_FIFO priority asked for (--rt-priority, --dds-priority) that the kernel refuses is an
// error naming the limit to raise: it was a line on standard output and a service at normal
// priority, exit 0 (session 75). Run as nobody (RLIMIT_RTPRIO 0 there), which needs root here.
TEST(ServiceProcesses, ARefusedRealTimePriorityThatWasAskedForIsAnError) {
  const char* setpriv = "/usr/bin/setpriv";  // util-linux
  if (::geteuid() != 0 || ::access(setpriv, X_OK) != 0) {
    GTEST_SKIP() << "needs root and setpriv to run the service as another user";
  }
  ServiceEnv env;
  {
    // A build under a directory nobody may enter (/root) cannot be run so.
    test::Child probe;
    ASSERT_TRUE(probe.start(
        {setpriv, "--reuid=65534", "--regid=65534", "--clear-groups", TGM_SERVICE_BIN, "--version"},
        env.path("probe.log")));
    if (probe.wait(kHang) != 0) GTEST_SKIP() << "nobody cannot run " << TGM_SERVICE_BIN;
  }
  for (const char* flag : {"--rt-priority", "--dds-priority"}) {
    test::Child service;
    ASSERT_TRUE(service.start(
        {setpriv, "--reuid=65534", "--regid=65534", "--clear-groups", TGM_SERVICE_BIN, "--config",
         env.config(), flag, "40", "--service-check-ms", "0", "--duration", "1"},
        env.path("nobody.log")));
    EXPECT_EQ(service.wait(kHang), 2) << service.log();
    EXPECT_NE(service.log().find(std::string("tgm-service: ") + flag +
                                 " 40: SCHED_FIFO priority 40 not permitted (Operation not "
                                 "permitted; RLIMIT_RTPRIO is 0: raise it with LimitRTPRIO="),
              std::string::npos)
        << service.log();
  }
}

// Two services on one domain that neither gives way (both started with --service-check-ms 0):
// a client follows the first it heard and never mixes in the other's states (tgm-hmi run said
// "tgm-service restarted" at every flip, tgm-plc logged a restart at each), and says that there
// is another. Once the followed one stops, the other's states are taken after kServiceSwitch.
TEST(ServiceProcesses, AClientFollowsOneOfTwoServicesAndTakesTheOtherWhenItStops) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service({"--service-check-ms", "0"}));
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  const std::uint64_t first = hmi.state(0)->service_instance();
  EXPECT_EQ(hmi.service_followed(0), first);
  std::set<std::uint64_t> shown;
  hmi.on_state = [&](const msg::InterpolatorState& s) {
    if (s.interpolator() == 0) shown.insert(s.service_instance());
  };
  test::Child second;
  ASSERT_TRUE(second.start(
      {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime", "--service-check-ms", "0"},
      env.path("second.log")));
  const auto heard_by = std::chrono::steady_clock::now() + kHang;
  while (hmi.other_service(0) == 0 && std::chrono::steady_clock::now() < heard_by) hmi.poll(5ms);
  const std::uint64_t other = hmi.other_service(0);
  ASSERT_NE(other, 0u) << second.log();
  EXPECT_NE(other, first);
  for (const auto until = std::chrono::steady_clock::now() + 1500ms;
       std::chrono::steady_clock::now() < until;) {
    hmi.poll(5ms);
  }
  EXPECT_EQ(shown, std::set<std::uint64_t>{first});
  EXPECT_EQ(hmi.service_followed(0), first);

  test::Child watch;
  ASSERT_TRUE(watch.start(
      {TGM_HMI_BIN, "watch", "--count", "4", "--interval", "0.3", "--config", env.config()},
      env.path("watch.log")));
  EXPECT_EQ(watch.wait(kHang), 0) << watch.log();
  EXPECT_NE(watch.log().find("warning: another tgm-service (instance "), std::string::npos)
      << watch.log();

  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  EXPECT_TRUE(hmi.wait_until(
      0, [&](const msg::InterpolatorState& s) { return s.service_instance() == other; }, kHang));
  EXPECT_EQ(hmi.service_followed(0), other);
  EXPECT_EQ(second.interrupt(kHang), 0) << second.log();
}

// Two services started at the same moment each look (50 ms here, shorter than discovery), see
// nothing (neither publishes while it looks) and serve. In their first cycles one gives way to
// the other and exits with code 1 (or, started far enough apart, the later one finds the first
// in its look and exits): one service is left, and every state an HMI sees afterwards is its.
TEST(ServiceProcesses, OfTwoServicesStartedTogetherOneGivesWay) {
  ServiceEnv env;
  test::Child a, b;
  for (test::Child* c : {&a, &b}) {
    ASSERT_TRUE(c->start(
        {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime", "--service-check-ms", "50"},
        env.path(c == &a ? "a.log" : "b.log")));
  }
  const auto until = std::chrono::steady_clock::now() + kHang;
  int code_a = -1, code_b = -1;
  while (code_a == -1 && code_b == -1 && std::chrono::steady_clock::now() < until) {
    code_a = a.wait(50ms);
    if (code_a == -1) code_b = b.wait(50ms);
  }
  ASSERT_TRUE(code_a != -1 || code_b != -1) << a.log() << "\n----\n" << b.log();
  test::Child& gone = code_a != -1 ? a : b;
  test::Child& left = code_a != -1 ? b : a;
  EXPECT_EQ(code_a != -1 ? code_a : code_b, 1) << gone.log();
  const std::string why = gone.log();
  EXPECT_TRUE(why.find("gives way and exits") != std::string::npos ||
              why.find("already serves DDS domain") != std::string::npos)
      << why;
  if (why.find("gives way") != std::string::npos) {
    EXPECT_NE(why.find("stopping (gave way to another service)"), std::string::npos) << why;
  }
  // The one left serves on, alone: after its peer's last samples it is the only instance.
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  std::this_thread::sleep_for(1s);
  hmi.poll(100ms);
  const std::uint64_t instance = hmi.state(0)->service_instance();
  bool other_seen = false;
  for (int i = 0; i < 20; ++i) {
    hmi.poll(50ms);
    other_seen = other_seen || hmi.state(0)->service_instance() != instance;
  }
  EXPECT_FALSE(other_seen);
  EXPECT_TRUE(left.running()) << left.log();
  EXPECT_EQ(left.wait(1s), -1) << left.log();
  EXPECT_EQ(left.interrupt(10s, SIGTERM), 0) << left.log();
  EXPECT_EQ(left.log().find("gives way and exits"), std::string::npos) << left.log();
}

// tgm-hmi command and stop as an operator types them: "WHAT: accepted" and exit code 0, or the
// service's reason and exit code 1; negative Command codes are words, bad lines exit 2.
// One malformed sample from any participant on the domain terminated tgm-service (a program
// chunk whose end_of_program byte is 2: fastcdr throws, the generated type support let it
// through Fast DDS's take). It is dropped and said, and the service goes on serving.
TEST(ServiceProcesses, AMalformedSampleIsDroppedAndTheServiceGoesOn) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  dds::Participant rogue(env.dds(), "rogue");
  auto& w = rogue.writer(
      rogue.topic<test::RawBytesType<msg::ProgramChunkPubSubType>>(dds::kProgramTopic.name),
      dds::kProgramTopic.writer_profile);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  std::string bad = test::chunk_with_a_bool_of_2(0, 9);
  ASSERT_FALSE(bad.empty()) << "the generated layout of ProgramChunk changed";
  ASSERT_TRUE(w.write(&bad));
  const std::string says = "tgm-service: DDS samples that cannot be read arrive and are dropped (";
  const std::string who = "so far): a participant on domain " + std::to_string(env.domain()) +
                          " writes tgm topics in a form this version does not know";
  env.service.wait_for_log(who);
  EXPECT_NE(env.service.log().find(says), std::string::npos) << env.service.log();
  EXPECT_NE(env.service.log().find(who), std::string::npos) << env.service.log();
  const client::Reply r = hmi.clear(0);
  EXPECT_TRUE(r.accepted) << client::describe(r);

  // The clients drop such samples too; tgm-hmi watch says so on every screen. A state whose
  // first encapsulation byte is not 0 (fastcdr throws there as well), kept by the rogue's
  // writer for late joiners as the service's states are.
  auto& sw = rogue.writer(
      rogue.topic<test::RawBytesType<msg::InterpolatorStatePubSubType>>(dds::kStateTopic.name),
      dds::kStateTopic.writer_profile);
  msg::InterpolatorState state;
  state.interpolator(0);
  std::string bad_state = test::serialized<msg::InterpolatorStatePubSubType>(state);
  ASSERT_GT(bad_state.size(), 6u);
  bad_state[0] = 1;
  ASSERT_TRUE(sw.write(&bad_state));
  test::Child watch;
  ASSERT_TRUE(watch.start(
      {TGM_HMI_BIN, "watch", "--count", "4", "--interval", "0.3", "--config", env.config()},
      env.path("watch.log")));
  EXPECT_EQ(watch.wait(kHang), 0) << watch.log();
  EXPECT_NE(watch.log().find("DDS samples that cannot be read were dropped ("), std::string::npos)
      << watch.log();
  EXPECT_NE(watch.log().find("Status"), std::string::npos) << watch.log();  // and it showed states

  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  EXPECT_NE(env.service.log().find("; malformed DDS samples dropped ("), std::string::npos)
      << env.service.log();
}

// A reply written before the service's reply writer has matched the client's reply reader
// never reaches it (the topic is VOLATILE). Discovery is not symmetric: the client's reader can
// see the service's writer before the service sees the reader, so a client that waited for its
// own matches could still be answered into the void, and said "no reply" for a request the
// service had executed (sanitizer build, session 48). The service now holds such a reply until
// the match. Here the reply reader is made only after the request was answered.
TEST(ServiceProcesses, AReplyWaitsUntilTheClientsReplyReaderIsMatched) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  {
    client::Client hmi(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  }
  dds::Participant late(env.dds(), "hmi");
  auto& w = late.writer<msg::RequestPubSubType>(dds::kRequestTopic);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  msg::Request req =
      test::hand_request(7, msg::CLIENT_ROLE_HMI, "late-reader", msg::REQUEST_KIND_CLEAR);
  ASSERT_TRUE(w.write(&req));
  std::this_thread::sleep_for(300ms);  // answered within a cycle or two
  auto& r = late.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  msg::Reply reply;
  bool got = false;
  for (int i = 0; i < 100 && !got; ++i) {
    while (!got && dds::take_next(r, reply)) {
      got = reply.client_name() == "late-reader" && reply.request_id() == 7;
    }
    if (!got) std::this_thread::sleep_for(30ms);
  }
  ASSERT_TRUE(got) << "the reply to a request sent before the reply reader existed was lost";
  EXPECT_TRUE(reply.accepted()) << reply.reason();
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  // It was held, and written on the match rather than after the wait.
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"replies_held_for_match\": 1,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"replies_unmatched\": 0,"), std::string::npos) << stats;
}

// A reply can be lost (the service held one for a match of its client's reply reader that it
// never saw, and a soak session waited 30 s for the reply to its clear). The client sends an
// unanswered request again under the same request_id, after 0.5 s and then at twice the last
// interval, until a reply comes: a stand-in service here leaves the first two writes
// unanswered and answers the third.
TEST(ServiceProcesses, AClientSendsAnUnansweredRequestAgainUnderItsId) {
  ServiceEnv env;
  dds::Participant fake(env.dds(), "service");
  auto& requests = fake.reader<msg::RequestPubSubType>(dds::kRequestTopic);
  auto& replies = fake.writer<msg::ReplyPubSubType>(dds::kReplyTopic);
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(requests, 1, kHang));
  std::vector<msg::Request> seen;
  bool answered = false;
  std::thread stand_in([&] {
    const auto deadline = std::chrono::steady_clock::now() + kHang;
    msg::Request q;
    while (seen.size() < 3 && std::chrono::steady_clock::now() < deadline) {
      while (seen.size() < 3 && dds::take_next(requests, q)) seen.push_back(q);
      std::this_thread::sleep_for(5ms);
    }
    if (seen.size() < 3) return;
    msg::Reply r = accepted_reply(seen.back(), 4242);
    answered = replies.write(&r);
  });
  const client::Reply r = hmi.clear(0, 20s);
  stand_in.join();
  ASSERT_TRUE(answered) << seen.size() << " requests seen";
  EXPECT_TRUE(r.accepted) << client::describe(r);
  EXPECT_EQ(r.cycle, 4242u);
  EXPECT_GE(r.sends, 3);  // a 4th write when the stand-in stalled for 2 s
  for (const msg::Request& q : seen) {
    EXPECT_EQ(q.request_id(), seen.front().request_id());
    EXPECT_EQ(q.kind(), msg::REQUEST_KIND_CLEAR);
    EXPECT_EQ(q.client_name(), seen.front().client_name());
  }
  // A request left unanswered for good says how often it went out.
  client::Reply lost;
  lost.timed_out = true;
  lost.sent = true;
  lost.sends = 4;
  lost.waited = 8000ms;
  EXPECT_EQ(client::describe(lost),
            "no reply within 8.0 s: the request was sent (4 times), but whether tgm-service "
            "executed it is not known (it may still arrive over a slow or lossy network; check "
            "the registers)");
}

// The service executes a request once: the same request again (same client, request_id and
// content: a client that heard no reply) is answered at once with the first reply, handled in
// the same cycle; the same id asking for something else is a new request and executed.
TEST(ServiceProcesses, ARepeatedRequestIsAnsweredWithItsFirstReplyAndNotExecutedAgain) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  dds::Participant plc(env.dds(), "plc");
  auto& replies = plc.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  auto& w = plc.writer<msg::RequestPubSubType>(dds::kRequestTopic);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  msg::Request req = test::hand_request(7, msg::CLIENT_ROLE_PLC, "repeating-plc",
                                        msg::REQUEST_KIND_WRITE_REL_SPEED);
  req.value(0.5);
  // Writes `q` and waits for one reply to request 7.
  const auto ask = [&](msg::Request q) -> std::optional<msg::Reply> {
    if (!w.write(&q)) return std::nullopt;
    return test::await_reply(replies, "repeating-plc", 7, 20s);
  };
  const auto first = ask(req);
  ASSERT_TRUE(first) << env.service.log();
  ASSERT_TRUE(first->accepted()) << first->reason();
  // Later cycles run before the repeat: a repeat executed again would be handled in one.
  std::this_thread::sleep_for(100ms);
  const auto again = ask(req);
  ASSERT_TRUE(again) << "a repeated request was not answered\n" << env.service.log();
  EXPECT_TRUE(again->accepted()) << again->reason();
  EXPECT_EQ(again->cycle_counter(), first->cycle_counter());
  req.value(0.7);  // the same id for another value: a request of its own
  const auto other = ask(req);
  ASSERT_TRUE(other) << env.service.log();
  EXPECT_TRUE(other->accepted()) << other->reason();
  EXPECT_GT(other->cycle_counter(), first->cycle_counter());
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"requests\": 2, \"busy_requests\": 0, \"requests_repeated\": 1,"),
            std::string::npos)
      << stats;
}

// A repeat (Request.attempt > 1) first sent to another service instance, which this one has
// not seen, may have been executed by that instance before it went (a restarted service has
// lost its log of requests): it is answered "not executed", and its own repeat the same way. A
// repeat for this instance that it has not seen (the first write was lost) is executed, and so
// is a first write that names another instance.
TEST(ServiceProcesses, ARepeatFirstSentToAReplacedServiceIsNotExecuted) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client watcher(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watcher.wait_for_state(0, kHang));
  const std::uint64_t own = watcher.state(0)->service_instance();
  const std::uint64_t gone = own ^ 0x5a5a5a5a5a5a5a5aULL;
  dds::Participant plc(env.dds(), "plc");
  auto& replies = plc.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  auto& w = plc.writer<msg::RequestPubSubType>(dds::kRequestTopic);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  const auto ask = [&](std::uint64_t id, double value, std::uint64_t instance,
                       std::uint32_t attempt) -> std::optional<msg::Reply> {
    msg::Request q =
        test::hand_request(id, msg::CLIENT_ROLE_PLC, "late-plc", msg::REQUEST_KIND_WRITE_REL_SPEED);
    q.value(value);
    q.service_instance(instance);
    q.attempt(attempt);
    if (!w.write(&q)) return std::nullopt;
    return test::await_reply(replies, "late-plc", id, 20s);
  };
  const auto stale = ask(11, 0.3, gone, 2);
  ASSERT_TRUE(stale) << env.service.log();
  EXPECT_FALSE(stale->accepted());
  EXPECT_EQ(stale->code(), msg::REPLY_CODE_WRONG_STATE);
  char gone_hex[17];
  std::snprintf(gone_hex, sizeof gone_hex, "%016llx", static_cast<unsigned long long>(gone));
  EXPECT_NE(stale->reason().to_string().find(std::string("first sent to tgm-service instance ") +
                                             gone_hex + " (since restarted"),
            std::string::npos)
      << stale->reason().to_string();
  const auto stale_again = ask(11, 0.3, gone, 3);
  ASSERT_TRUE(stale_again) << env.service.log();
  EXPECT_EQ(stale_again->code(), msg::REPLY_CODE_WRONG_STATE);
  const auto lost_first = ask(12, 0.4, own, 2);
  ASSERT_TRUE(lost_first) << env.service.log();
  EXPECT_TRUE(lost_first->accepted()) << lost_first->reason();
  ASSERT_TRUE(watcher.wait_until(
      0, [](const msg::InterpolatorState& st) { return st.rel_speed() == 0.4; }, kHang));
  const auto first_write = ask(13, 0.6, gone, 1);
  ASSERT_TRUE(first_write) << env.service.log();
  EXPECT_TRUE(first_write->accepted()) << first_write->reason();
  ASSERT_TRUE(watcher.wait_until(
      0, [](const msg::InterpolatorState& st) { return st.rel_speed() == 0.6; }, kHang));
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"requests\": 2, \"busy_requests\": 0, \"requests_repeated\": 1, "
                       "\"stale_repeats\": 1,"),
            std::string::npos)
      << stats;
}

// The case it is for: tgm::client::Client writes a request to a service that stops answering
// (SIGSTOP, every thread stopped before the request is written) and is killed; a new service
// comes up on the domain, and the client's repeat reaches it. The new one does not execute it
// and says why; the client has its answer instead of a timeout.
TEST(ServiceProcesses, AClientsRepeatToARestartedServiceIsAnsweredNotExecuted) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client plc(env.dds(), client::Role::kPlc);
  ASSERT_TRUE(plc.wait_for_state(0, kHang));
  const std::uint64_t first = plc.state(0)->service_instance();
  ASSERT_TRUE(test::stop_process(env.service.pid()));
  std::thread restart([&] {
    std::this_thread::sleep_for(300ms);
    env.service.interrupt(kHang, SIGKILL);
    env.start_service();
  });
  const client::Reply reply = plc.request(client::rel_speed_request(0, 0.3), 40s);
  restart.join();
  ASSERT_FALSE(reply.timed_out) << env.service.log();
  EXPECT_GE(reply.sends, 2);
  EXPECT_EQ(reply.code, msg::REPLY_CODE_WRONG_STATE) << reply.reason;
  char first_hex[17];
  std::snprintf(first_hex, sizeof first_hex, "%016llx", static_cast<unsigned long long>(first));
  EXPECT_NE(reply.reason.find(std::string("first sent to tgm-service instance ") + first_hex),
            std::string::npos)
      << reply.reason;
  ASSERT_TRUE(plc.wait_until(
      0, [&](const msg::InterpolatorState& st) { return st.service_instance() != first; }, kHang));
  EXPECT_EQ(plc.state(0)->rel_speed(), 1.0);  // the new service's own
  // A request written now goes to the new service and is executed.
  const client::Reply next = plc.request(client::rel_speed_request(0, 0.3), 20s);
  EXPECT_TRUE(next.accepted) << next.reason;
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
}

// The case repeats are for: a reply held for its client's reply reader (here the requesting
// participant has none, so the service holds the reply up to 30 s). The repeat is answered at
// once, past the hold: another participant's reply reader sees it long before the 30 s.
TEST(ServiceProcesses, ARepeatOfARequestWhoseReplyIsHeldIsAnsweredAtOnce) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  dds::Participant sender(env.dds(), "hmi");
  auto& w = sender.writer<msg::RequestPubSubType>(dds::kRequestTopic);
  dds::Participant listener(env.dds(), "listener");
  auto& replies = listener.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  msg::Request req = test::hand_request(9, msg::CLIENT_ROLE_HMI, "held", msg::REQUEST_KIND_CLEAR);
  ASSERT_TRUE(w.write(&req));
  EXPECT_FALSE(test::await_reply(replies, "held", 9, 1s)) << "the reply was not held";
  ASSERT_TRUE(w.write(&req));
  const auto reply = test::await_reply(replies, "held", 9, 10s);
  ASSERT_TRUE(reply) << "the repeat was not answered at once\n" << env.service.log();
  EXPECT_TRUE(reply->accepted()) << reply->reason();
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"requests\": 1, \"busy_requests\": 0, \"requests_repeated\": 1,"),
            std::string::npos)
      << stats;
  EXPECT_NE(stats.find("\"replies_held_for_match\": 1,"), std::string::npos) << stats;
}

// A request answered "busy" (the queue to the cycles full) is logged with that answer: its
// repeat is answered "busy" again and not executed, since its client may have taken the first
// "busy" already and given up. The cycles take one request each here (--request-budget 1), so
// a burst of 400 fills the queue of 256 and the last requests written are answered "busy".
TEST(ServiceProcesses, ARepeatOfARequestAnsweredBusyIsAnsweredBusyAgain) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service({"--request-budget", "1"}));
  dds::Participant plc(env.dds(), "plc");
  auto& replies = plc.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  auto& w = plc.writer<msg::RequestPubSubType>(dds::kRequestTopic);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  const std::string name = "flooding-plc";
  const auto request = [&](std::uint64_t id) {
    msg::Request r =
        test::hand_request(id, msg::CLIENT_ROLE_PLC, name, msg::REQUEST_KIND_WRITE_REL_SPEED);
    r.value(0.5);
    return r;
  };
  std::uint64_t id = 0;
  std::optional<msg::Reply> busy;
  // The busy answer to the latest request: taken between the writes, as the reader keeps only
  // the last 100 replies.
  msg::Reply got;
  const auto take_replies = [&] {
    while (dds::take_next(replies, got)) {
      if (got.client_name() == name && got.code() == msg::REPLY_CODE_BUSY &&
          (!busy || got.request_id() > busy->request_id())) {
        busy = got;
      }
    }
  };
  int bursts = 0;
  for (const auto give_up = std::chrono::steady_clock::now() + 30s;
       !busy && std::chrono::steady_clock::now() < give_up;) {
    ++bursts;
    for (int k = 0; k < 400; ++k) {
      msg::Request r = request(++id);
      w.write(&r);
      take_replies();
    }
    for (const auto until = std::chrono::steady_clock::now() + 200ms;
         std::chrono::steady_clock::now() < until; std::this_thread::sleep_for(5ms)) {
      take_replies();
    }
    // Fewer than 64 requests written after it: still in its client's log.
    if (busy && busy->request_id() + 64 <= id) busy.reset();
  }
  ASSERT_TRUE(busy) << bursts << " bursts of 400 requests left no late request answered busy\n"
                    << env.service.log();
  EXPECT_FALSE(busy->accepted());
  msg::Request again = request(busy->request_id());
  ASSERT_TRUE(w.write(&again));
  const auto reply = test::await_reply(replies, name, busy->request_id(), 20s);
  ASSERT_TRUE(reply) << "the repeat was not answered\n" << env.service.log();
  EXPECT_EQ(reply->code(), msg::REPLY_CODE_BUSY) << reply->reason();
  EXPECT_EQ(reply->reason(), busy->reason());
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"requests_repeated\": 1,"), std::string::npos) << stats;
  std::printf("%d bursts; request %llu of %llu answered busy twice\n", bursts,
              static_cast<unsigned long long>(busy->request_id()),
              static_cast<unsigned long long>(id));
}

// The setpoint topic carries every cycle of a motion (DESIGN.md: "PositionInc/Position per
// cycle, for drives"). The publisher used to write only the newest snapshot it saw: woken late
// (normal priority), it left 5 % of the moving cycles without a setpoint on an idle machine and
// 27 % under load, in gaps of up to 40 cycles, and nothing counted them (session 75's review).
// Now the cycle thread queues each one; the service counts those it could not queue (0), and a
// reader with room for all of them finds every cycle of the motion (BEST_EFFORT: a sample the
// transport drops is allowed for, one in 200).
TEST(ServiceProcesses, EveryMovingCycleHasItsSetpoint) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  dds::Participant drive(env.dds(), "drive");
  fdds::Subscriber* sub = drive.get().create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  ASSERT_NE(sub, nullptr);
  fdds::DataReaderQos qos;
  ASSERT_EQ(
      sub->get_datareader_qos_from_profile(std::string(dds::kSetpointsTopic.reader_profile), qos),
      eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK);
  qos.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
  qos.resource_limits().max_samples = 800000;
  qos.resource_limits().max_instances = 4;
  qos.resource_limits().max_samples_per_instance = 200000;
  fdds::DataReader* reader = sub->create_datareader(
      &drive.topic<msg::SetpointsPubSubType>(dds::kSetpointsTopic.name), qos);
  ASSERT_NE(reader, nullptr);
  ASSERT_TRUE(dds::wait_for_match(*reader, 1, kHang));
  std::ofstream(env.path("line.ngc")) << "G90 G1 X60 F6000\nM2\n";
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("line.ngc"), "--config", env.config()},
                        env.path("run.log")));
  std::map<std::uint64_t, std::int64_t> x_inc;  // interpolator 0: cycle -> PositionInc X
  msg::Setpoints sp;
  const auto take = [&] {
    while (dds::take_next(*reader, sp)) {
      if (sp.interpolator() == 0) x_inc[sp.cycle_counter()] = sp.position_inc()[0];
    }
  };
  int code = -1;
  for (const auto until = std::chrono::steady_clock::now() + kHang;
       (code = run.wait(0ms)) == -1 && std::chrono::steady_clock::now() < until;) {
    take();
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(code, 0) << run.log();
  std::this_thread::sleep_for(200ms);
  take();
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
  EXPECT_NE(env.service.log().find(" setpoints published (0 lost)"), std::string::npos)
      << env.service.log();
  // The motion: from the last cycle at X 0 to the first at X 60 mm (60,000 inc).
  std::uint64_t first = 0, last = 0;
  for (const auto& [cycle, inc] : x_inc) {
    if (inc == 0) first = cycle;
    if (inc == 60000 && last == 0) last = cycle;
  }
  ASSERT_GT(first, 0u);
  ASSERT_GT(last, first + 1000) << "a motion of 0.6 s at least";
  std::uint64_t missing = 0;
  std::string gaps;
  for (std::uint64_t c = first; c <= last; ++c) {
    if (x_inc.count(c) == 0) {
      ++missing;
      if (gaps.size() < 400) gaps += " " + std::to_string(c - first);
    }
  }
  EXPECT_LE(missing * 200, last - first)
      << missing << " of " << (last - first + 1) << " moving cycles had no setpoint, at:" << gaps;
}

// An HMI of the service in `env` and a program writer on a participant of its own: for chunks
// the client library never writes (another interpolator, a NaN in a record).
struct RawChunkWriter {
  explicit RawChunkWriter(const ServiceEnv& env)
      : hmi(env.dds(), client::Role::kHmi),
        other(env.dds(), "other"),
        writer(other.writer<msg::ProgramChunkPubSubType>(dds::kProgramTopic)) {}
  //! The HMI has the service's state and the writer has matched its reader.
  bool ready() { return hmi.wait_for_state(0, kHang) && dds::wait_for_match(writer, 1, kHang); }

  client::Client hmi;
  dds::Participant other;
  fdds::DataWriter& writer;
};

// Chunks for an interpolator the service does not host (a client configured for more, or a
// flood) are dropped and said at once, then at most every 10 s: one line per chunk let a
// sender fill the service's log as fast as it wrote.
TEST(ServiceProcesses, ChunksForAnInterpolatorNotHostedAreSaidOnceNotPerChunk) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  RawChunkWriter raw(env);
  ASSERT_TRUE(raw.ready());
  fdds::DataWriter& w = raw.writer;
  msg::ProgramChunk chunk;
  chunk.interpolator(7);
  chunk.end_of_program(true);
  for (std::uint32_t k = 1; k <= 200; ++k) {
    chunk.program_id(k);
    ASSERT_TRUE(w.write(&chunk));
  }
  const std::string says =
      "tgm-service: program chunk for interpolator 7 dropped (the service "
      "hosts 0..2; 1 such chunks so far)";
  env.service.wait_for_log(says);
  std::this_thread::sleep_for(300ms);
  const std::string log = env.service.log();
  EXPECT_NE(log.find(says), std::string::npos) << log;
  EXPECT_EQ(log.find("interpolator 7 dropped"), log.rfind("interpolator 7 dropped")) << log;
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
}

// A chunk with a NaN in it is refused, and the refusal names the record, its source line and
// the field: "NaN or infinity in a record" alone left a sender of 100,000 records searching.
TEST(ServiceProcesses, ARefusedChunkNamesTheRecordAndTheField) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  RawChunkWriter raw(env);
  ASSERT_TRUE(raw.ready());
  fdds::DataWriter& w = raw.writer;
  client::Client& hmi = raw.hmi;
  msg::ProgramChunk chunk;
  chunk.interpolator(0);
  chunk.program_id(5);
  chunk.number_axes(3);
  chunk.axis_letters("XYZ");
  chunk.sequence_number(0);
  chunk.end_of_program(true);
  for (int k = 0; k < 3; ++k) {
    msg::Segment& seg = chunk.segments().emplace_back();
    seg.type(static_cast<std::uint8_t>(SegmentType::kLinear));
    seg.plane(static_cast<std::uint8_t>(Plane::kXY));
    seg.compensation(static_cast<std::uint8_t>(Compensation::kOff));
    seg.line(10 + k);
    seg.feed_mm_per_min(600.0);
    seg.end()[0] = k + 1.0;
  }
  chunk.segments()[2].end()[1] = std::nan("");
  ASSERT_TRUE(w.write(&chunk));
  const std::string want =
      "program 5 refused: NaN or infinity in a record: record 2 of the program (record 2 of its "
      "chunk, source line 12), field end[1]";
  std::string got;
  for (const auto until = std::chrono::steady_clock::now() + kHang;
       got.empty() && std::chrono::steady_clock::now() < until;) {
    hmi.poll(20ms);
    for (const msg::Message& m : hmi.take_messages()) {
      if (m.text().to_string().find("refused") != std::string::npos) got = m.text().to_string();
    }
  }
  EXPECT_EQ(got, want);
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
}

// Chunks lost on the way (a sender the service's reader dropped while it stood still, then
// matched again: 1 run in 8 of the freeze test) leave a gap. It is said once, as a warning
// over DDS, the program stays where it stands, and the sender's chunks written again from
// there complete it; the program then runs to its end. Until 0.2.2 the gap was an error that
// ended tgm-hmi run with the machine in underrun.
TEST(ServiceProcesses, AGapInAStreamIsSaidAndHealsWhenTheSenderWritesFromWhereItStands) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  RawChunkWriter raw(env);
  ASSERT_TRUE(raw.ready());
  client::Client& hmi = raw.hmi;
  // Records 0..5: G1 to X 1..6.
  const auto chunk = [](std::uint64_t first, std::uint64_t count, bool end) {
    msg::ProgramChunk c;
    c.interpolator(0);
    c.program_id(5);
    c.number_axes(3);
    c.axis_letters("XYZ");
    c.sequence_number(first);
    c.end_of_program(end);
    for (std::uint64_t k = first; k < first + count; ++k) {
      msg::Segment& seg = c.segments().emplace_back();
      seg.type(static_cast<std::uint8_t>(SegmentType::kLinear));
      seg.plane(static_cast<std::uint8_t>(Plane::kXY));
      seg.compensation(static_cast<std::uint8_t>(Compensation::kOff));
      seg.line(static_cast<std::int32_t>(10 + k));
      seg.feed_mm_per_min(6000.0);
      seg.end()[0] = static_cast<double>(k + 1);
    }
    return c;
  };
  msg::ProgramChunk c = chunk(0, 2, false);
  ASSERT_TRUE(raw.writer.write(&c));
  c = chunk(4, 2, true);  // records 2..3 lost
  ASSERT_TRUE(raw.writer.write(&c));
  const std::string want =
      "program 5: chunk 4 skips records 2..3 (lost on the way): dropped; the sender must write "
      "from record 2 again";
  std::optional<msg::Message> said;
  for (const auto until = std::chrono::steady_clock::now() + kHang;
       !said && std::chrono::steady_clock::now() < until;) {
    hmi.poll(20ms);
    for (const msg::Message& m : hmi.take_messages()) {
      if (m.text().to_string().find("skips") != std::string::npos) said = m;
    }
  }
  ASSERT_TRUE(said.has_value());
  EXPECT_EQ(said->text().to_string(), want);
  EXPECT_EQ(said->severity(), msg::SEVERITY_WARNING);
  EXPECT_EQ(said->program_id(), 5u);
  ASSERT_TRUE(hmi.wait_until(
      0,
      [](const msg::InterpolatorState& s) { return s.program_id() == 5 && s.next_sequence() == 2; },
      kHang));

  c = chunk(2, 2, false);
  ASSERT_TRUE(raw.writer.write(&c));
  c = chunk(4, 2, true);
  ASSERT_TRUE(raw.writer.write(&c));
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.next_sequence() == 6; }, kHang));
  const client::Reply start = hmi.start(0);
  ASSERT_TRUE(start.accepted) << client::describe(start);
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 3; }, kHang));
  EXPECT_DOUBLE_EQ(hmi.state(0)->orig_position()[0], 6.0);
  EXPECT_EQ(env.service.interrupt(kHang), 0) << env.service.log();
}

TEST(ServiceProcesses, HmiCommandAndStopSayAcceptedOrWhyNot) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  {
    client::Client hmi(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  }
  struct Case {
    std::vector<std::string> words;
    int code;
    std::string says;
  };
  const Case cases[] = {
      {{"command", "clear"}, 0, "clear: accepted\n"},
      {{"command", "start"}, 1, "tgm-hmi command: start: refused (wrong state): nothing loaded\n"},
      {{"command", "1024", "1", "1", "1"},
       1,
       "tgm-hmi command: Command 1024: refused (wrong role): the HMI may not send Command 1024 "
       "(gear ratio)\n"},
      {{"command", "-2", "100", "1000000"},
       1,
       "tgm-hmi command: Command -2: refused (wrong role): the HMI may not send Command -2 (spline "
       "parameters)\n"},
      {{"command", "7"}, 1, "tgm-hmi command: Command 7: refused (bad request): unknown Command 7"},
      {{"stop"}, 0, "stop: accepted\n"},
      {{"command", "estop"}, 0, "Command 4: accepted\n"},
      {{"command", "frob"}, 2, "tgm-hmi command: unknown command 'frob'\n"},
      {{"command", "start", "1"}, 2, "tgm-hmi command: 'start' takes no parameters\n"},
      {{"command", "2048", "0", "1.5"},
       2,
       "tgm-hmi command: Command_Parameter[1] '1.5' is not a whole number\n"},
      {{"command", "2048", "0", "99999999999"},
       2,
       "tgm-hmi command: Command_Parameter[1] '99999999999' does not fit its 32-bit register "
       "(-2147483648..2147483647)\n"},
      {{"command", "20000000"},
       2,
       "tgm-hmi command: Command code 20000000 is out of range -1000000..1000000 (the known "
       "codes lie in -2..2049; tgm-service names them)\n"},
      {{"command", "clear", "--timeout", "0"},
       2,
       "tgm-hmi command: --timeout must be seconds in (0, 3600], not '0'\n"},
      {{"stop", "--timeout", "x"},
       2,
       "tgm-hmi stop: --timeout must be seconds in (0, 3600], not 'x'\n"},
      {{"status", "--wait", "0"},
       2,
       "tgm-hmi status: --wait must be seconds in (0, 3600], not '0'\n"},
      {{"watch", "--wait", "4000"},
       2,
       "tgm-hmi watch: --wait must be seconds in (0, 3600], not '4000'\n"},
      {{"command", "clear", "--timeout", "20"}, 0, "clear: accepted\n"},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args{TGM_HMI_BIN};
    args.insert(args.end(), c.words.begin(), c.words.end());
    args.insert(args.end(), {"--config", env.config()});
    test::Child hmi;
    ASSERT_TRUE(hmi.start(args, env.path("cmd" + std::to_string(k++) + ".log")));
    EXPECT_EQ(hmi.wait(kHang), c.code) << c.words[0] << " " << c.words.back() << "\n" << hmi.log();
    EXPECT_EQ(hmi.log().rfind(c.says, 0), 0u) << hmi.log();
  }
  // No service on the domain: unanswered within --timeout, and it says that nothing was sent
  // (a request that was sent but not answered may still be executed later: it says so instead).
  env.service.interrupt();
  test::Child hmi;
  ASSERT_TRUE(
      hmi.start({TGM_HMI_BIN, "command", "clear", "--timeout", "0.5", "--config", env.config()},
                env.path("cmd-none.log")));
  EXPECT_EQ(hmi.wait(kHang), 1) << hmi.log();
  EXPECT_EQ(
      hmi.log(),
      "tgm-hmi command: clear: no reply: no tgm-service took requests on this domain within "
      "0.5 s (is it running, with the same domain, profiles and security?); nothing was sent\n");
  // status and watch wait --wait S for the service's state (default 10 s), then exit 1.
  for (const char* what : {"status", "watch"}) {
    test::Child view;
    ASSERT_TRUE(view.start({TGM_HMI_BIN, what, "--wait", "0.5", "--config", env.config()},
                           env.path(std::string(what) + "-none.log")));
    EXPECT_EQ(view.wait(kHang), 1) << view.log();
    EXPECT_EQ(view.log(), "tgm-hmi " + std::string(what) +
                              ": no state of interpolator 0 from tgm-service on DDS domain " +
                              std::to_string(env.domain()) +
                              " within 0.5 s (is tgm-service running with the same domain, "
                              "profiles and security?)\n");
  }
}

// Intercode compiled for other axis letters (XYC, where interpolator 0 has XYZ) is refused
// before anything is sent: by index, its C positions would move Z. Compiled for the right
// letters it runs to its end.
// Intercode holds positions by axis index. A .tgmi built for XYC is refused against the
// HMI's own config; G-code compiled with an HMI config of other letters than the service's is
// refused against the letters the service publishes (the service refuses such a stream too:
// Engine.AProgramCompiledForOtherAxisLettersIsRefused), and `status` names the service's axes.
TEST(ServiceProcesses, HmiRunRefusesProgramsOfOtherAxisLetters) {
  ServiceEnv env;
  std::string rotary = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(rotary, "{letter: Z}]", "{letter: C}]"));
  std::ofstream(env.path("rotary.yaml")) << rotary;
  std::ofstream(env.path("p.ngc")) << "G90 G1 X5 F3000\nM2\n";
  for (const char* cfg : {"rotary.yaml", "config.yaml"}) {
    test::Child compile;
    ASSERT_TRUE(compile.start({TGM_HMI_BIN, "compile", env.path("p.ngc"), "--config", env.path(cfg),
                               "--out", env.path(std::string(cfg) + ".tgmi")},
                              env.path("compile.log")));
    ASSERT_EQ(compile.wait(kHang), 0) << compile.log();
  }
  ASSERT_TRUE(env.start_service());
  test::Child wrong;
  ASSERT_TRUE(wrong.start(
      {TGM_HMI_BIN, "run", env.path("rotary.yaml.tgmi"), "--config", env.config(), "--quiet"},
      env.path("wrong.log")));
  EXPECT_EQ(wrong.wait(kHang), 2) << wrong.log();
  EXPECT_NE(wrong.log().find("compiled for the axes XYC, interpolator 0 has XYZ"),
            std::string::npos)
      << wrong.log();
  test::Child other;
  ASSERT_TRUE(other.start(
      {TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.path("rotary.yaml"), "--quiet"},
      env.path("other.log")));
  EXPECT_EQ(other.wait(kHang), 2) << other.log();
  EXPECT_NE(other.log().find(
                "p.ngc: error: compiled for the axes XYC (config " + env.path("rotary.yaml") +
                "), the service's interpolator 0 drives XYZ: use the service's config"),
            std::string::npos)
      << other.log();
  test::Child status;
  ASSERT_TRUE(status.start({TGM_HMI_BIN, "status", "--config", env.path("rotary.yaml")},
                           env.path("status.log")));
  EXPECT_EQ(status.wait(kHang), 0) << status.log();
  EXPECT_NE(status.log().find("  Orig_Position [mm]    X 0.0000 Y 0.0000 Z 0.0000"),
            std::string::npos)
      << status.log();
  // tgm-plc with that config sends no basic parameters (gear ratios by axis index); with the
  // service's own it does.
  for (const char* cfg : {"rotary.yaml", "config.yaml"}) {
    test::Child plc;
    ASSERT_TRUE(plc.start(
        {TGM_PLC_BIN, "--config", env.path(cfg), "--interpolator", "0", "--duration", "1.5"},
        env.path("plc.log")));
    EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
    const bool rotary_plc = std::string(cfg) == "rotary.yaml";
    EXPECT_EQ(
        plc.log().find(
            "interpolator 0: error: basic parameters not sent: the service drives the axes XYZ, "
            "this config (" +
            env.path(cfg) + ") has XYC: give tgm-plc the service's config") != std::string::npos,
        rotary_plc)
        << plc.log();
    EXPECT_EQ(plc.log().find("Command 1024 (gear ratio of axis Z: 1000 inc/mm): accepted") !=
                  std::string::npos,
              !rotary_plc)
        << plc.log();
  }
  // Number_Axes 2, written by a PLC: the letters are the first two. G-code is compiled for
  // them (every program was refused, also one of X alone); one that names Z is refused by the
  // compiler, and intercode of XYZ is refused, each saying who cut the axes.
  {
    client::Client plc(env.dds(), client::Role::kPlc);
    ASSERT_TRUE(plc.wait_for_state(0, kHang));
    msg::Request r;
    r.interpolator(0);
    r.kind(msg::REQUEST_KIND_WRITE_NUMBER_AXES);
    r.value(2);
    ASSERT_TRUE(plc.request(r).accepted);
    // There and back: the intercode below runs from machine zero.
    std::ofstream(env.path("xy.ngc")) << "G90 G1 X5 Y1 F3000\nG1 X0 Y0\nM2\n";
    test::Child fewer;
    ASSERT_TRUE(fewer.start({TGM_HMI_BIN, "run", env.path("xy.ngc"), "--config", env.config()},
                            env.path("fewer.log")));
    EXPECT_EQ(fewer.wait(kHang), 0) << fewer.log();
    EXPECT_NE(fewer.log().find("xy.ngc: compiled for the axes XY: interpolator 0 runs with "
                               "Number_Axes 2 (written by a PLC, or the service's config has fewer "
                               "axes than this one)\n"),
              std::string::npos)
        << fewer.log();
    EXPECT_NE(fewer.log().find("end position X0.0000 Y0.0000\n"), std::string::npos) << fewer.log();
    std::ofstream(env.path("z.ngc")) << "G90 G1 X6 Z1 F3000\nM2\n";
    test::Child with_z;
    ASSERT_TRUE(
        with_z.start({TGM_HMI_BIN, "run", env.path("z.ngc"), "--config", env.config(), "--quiet"},
                     env.path("with_z.log")));
    EXPECT_EQ(with_z.wait(kHang), 2) << with_z.log();
    EXPECT_NE(
        with_z.log().find("for the axes XY (Number_Axes 2: written by a PLC, or the service's "
                          "config has fewer axes than this one), nothing sent"),
        std::string::npos)
        << with_z.log();
    test::Child tgmi;
    ASSERT_TRUE(tgmi.start(
        {TGM_HMI_BIN, "run", env.path("config.yaml.tgmi"), "--config", env.config(), "--quiet"},
        env.path("tgmi.log")));
    EXPECT_EQ(tgmi.wait(kHang), 2) << tgmi.log();
    EXPECT_NE(tgmi.log().find("config.yaml.tgmi: error: compiled for the axes XYZ, interpolator 0 "
                              "runs with Number_Axes 2 (XY: written by a PLC, or the service's "
                              "config has fewer axes than this one): run the G-code itself, or "
                              "compile it with a config of those axes"),
              std::string::npos)
        << tgmi.log();
    // A tgm-plc of the XYZ config sets the ratios of X and Y and says why not Z (Z's Command
    // 1024 was sent and refused: "must be 0..1").
    test::Child second;
    ASSERT_TRUE(second.start({TGM_PLC_BIN, "--config", env.config(), "--duration", "1.5"},
                             env.path("second_plc.log")));
    EXPECT_EQ(second.wait(kHang), 0) << second.log();
    EXPECT_NE(second.log().find("interpolator 0: gear ratios of Z not sent: the service drives XY "
                                "(Number_Axes 2)"),
              std::string::npos)
        << second.log();
    EXPECT_NE(second.log().find("Command 1024 (gear ratio of axis Y: 1000 inc/mm): accepted"),
              std::string::npos)
        << second.log();
    EXPECT_EQ(second.log().find("refused"), std::string::npos) << second.log();
    r.value(3);
    ASSERT_TRUE(plc.request(r).accepted);
  }
  test::Child right;
  ASSERT_TRUE(right.start(
      {TGM_HMI_BIN, "run", env.path("config.yaml.tgmi"), "--config", env.config(), "--quiet"},
      env.path("right.log")));
  EXPECT_EQ(right.wait(kHang), 0) << right.log();
  EXPECT_NE(right.log().find("end position X5.0000 Y0.0000 Z0.0000"), std::string::npos)
      << right.log();
}

// `run --timeout S` bounds the whole run, the wait for the service too (it waited 10 s
// whatever S was), and the waits of --timeout and --m0-continue are bounded (1e300 s printed
// "continuing shortly" and waited for ever).
TEST(ServiceProcesses, RunTimeoutBoundsTheWaitForTheServiceAndItsWaitsAreBounded) {
  const std::string dir = ::testing::TempDir();
  std::ofstream(dir + "/timeout.ngc") << "G90 G1 X1 F600\nM2\n";
  const std::string run = std::string(TGM_HMI_BIN) + " run " + dir + "/timeout.ngc --domain " +
                          std::to_string(test::test_domain()) + " --quiet";
  const test::ShellRun none = test::run_shell(run + " --timeout 1.5", dir, "run-timeout");
  EXPECT_EQ(none.exit_code, 1) << none.err;
  EXPECT_NE(none.err.find("no state of interpolator 0 from tgm-service on DDS domain " +
                          std::to_string(test::test_domain()) + " within 1.5 s"),
            std::string::npos)
      << none.err;
  for (const char* flag : {"--timeout 2e9", "--m0-continue 1e300"}) {
    const test::ShellRun bad = test::run_shell(run + " " + flag, dir, "run-bounds");
    EXPECT_EQ(bad.exit_code, 2) << flag << ": " << bad.err;
    EXPECT_NE(bad.err.find("at most 1e9"), std::string::npos) << flag << ": " << bad.err;
  }
}

// The state carries the service's cycle time: tgm-hmi run times the program by it, not by its
// own config's (an HMI with the default 500 us config against a service at 1 ms printed half
// the program time), and status shows it.
TEST(ServiceProcesses, HmiTimesTheProgramByTheServicesCycle) {
  ServiceEnv env;
  std::string slow = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(slow, "cycle_time_us: 500", "cycle_time_us: 1000"));
  std::ofstream(env.path("slow.yaml")) << slow;
  ASSERT_TRUE(env.start_service({"--config", env.path("slow.yaml")}));
  std::ofstream(env.path("p.ngc")) << "G90 G1 X10 F600\nM2\n";  // 1 s at the feed, plus the ramps
  test::Child run;
  ASSERT_TRUE(
      run.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config(), "--quiet"},
                env.path("run.log")));
  ASSERT_EQ(run.wait(kHang), 0) << run.log();
  const std::string log = run.log();
  const auto at = log.find(" lines in ");
  ASSERT_NE(at, std::string::npos) << log;
  const double seconds = std::strtod(log.c_str() + at + 10, nullptr);
  EXPECT_GT(seconds, 1.0) << log;
  EXPECT_LT(seconds, 1.3) << log;
  test::Child status;
  ASSERT_TRUE(
      status.start({TGM_HMI_BIN, "status", "--config", env.config()}, env.path("status.log")));
  EXPECT_EQ(status.wait(kHang), 0) << status.log();
  EXPECT_NE(status.log().find(" of 1000 us, lateness"), std::string::npos) << status.log();
  // Another config, by its cycle time: status says so. The estimate of a run simulates at the
  // service's cycle, so it has one.
  EXPECT_NE(status.log().find("warning: interpolator 0: the service's machine config is not " +
                              env.config() + " ("),
            std::string::npos)
      << status.log();
  std::ofstream(env.path("back.ngc")) << "G90 G1 X0 F600\nM2\n";
  test::Child timed;
  ASSERT_TRUE(timed.start({TGM_HMI_BIN, "run", env.path("back.ngc"), "--config", env.config()},
                          env.path("timed.log")));
  ASSERT_EQ(timed.wait(kHang), 0) << timed.log();
  EXPECT_NE(timed.log().find(", estimated "), std::string::npos) << timed.log();
}

// A service whose axes have other limits than the HMI's config moves the program in another
// time: the run leaves the estimate out and says why (it simulated by the HMI's limits and
// said nothing), and status says whose config differs. The state carries the digest.
TEST(ServiceProcesses, ARunAgainstOtherAxisLimitsLeavesTheEstimateOut) {
  ServiceEnv env;
  std::string soft = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(soft, "max_jerk_mm_s3: 30000", "max_jerk_mm_s3: 20000"));
  std::ofstream(env.path("soft.yaml")) << soft;
  ASSERT_TRUE(env.start_service({"--config", env.path("soft.yaml")}));
  std::ofstream(env.path("p.ngc")) << "G91 G1 X10 F600\nM2\n";  // each run from where it stands
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config(),
                         "--progress-interval", "0.1"},
                        env.path("run.log")));
  ASSERT_EQ(run.wait(kHang), 0) << run.log();
  const std::string log = run.log();
  EXPECT_NE(log.find("tgm-hmi run: no time estimate (progress by records): the service moves "
                     "interpolator 0 by another machine config than " +
                     env.config() + " (axis limits"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find(", estimated "), std::string::npos) << log;
  EXPECT_EQ(log.find(" left "), std::string::npos) << log;
  EXPECT_NE(log.find("done: "), std::string::npos) << log;

  test::Child status;
  ASSERT_TRUE(status.start({TGM_HMI_BIN, "status", "--json", "--config", env.config()},
                           env.path("status.log")));
  EXPECT_EQ(status.wait(kHang), 0) << status.log();
  const std::string s = status.log();
  EXPECT_NE(s.find("tgm-hmi status: interpolator 0: the service's machine config is not "),
            std::string::npos)
      << s;
  const std::size_t at = s.find("\"machine_digest\":\"");
  ASSERT_NE(at, std::string::npos) << s;
  const std::string digest = s.substr(at + 18, 16);
  EXPECT_EQ(digest.find_first_not_of("0123456789abcdef"), std::string::npos) << s;
  EXPECT_NE(digest, "0000000000000000") << s;

  // watch: under every screen, or once on standard error with --json.
  test::Child watch, watch_json;
  ASSERT_TRUE(watch.start(
      {TGM_HMI_BIN, "watch", "--count", "2", "--interval", "0.1", "--config", env.config()},
      env.path("watch.log")));
  ASSERT_TRUE(watch_json.start({TGM_HMI_BIN, "watch", "--json", "--count", "3", "--interval", "0.1",
                                "--config", env.config()},
                               env.path("watch_json.log")));
  EXPECT_EQ(watch.wait(kHang), 0) << watch.log();
  EXPECT_EQ(watch_json.wait(kHang), 0) << watch_json.log();
  const auto count = [](const std::string& text, const std::string& what) {
    std::size_t n = 0;
    for (std::size_t k = text.find(what); k != std::string::npos; k = text.find(what, k + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count(watch.log(), "warning: interpolator 0: the service's machine config is not "), 2u)
      << watch.log();
  EXPECT_EQ(count(watch_json.log(),
                  "tgm-hmi watch: interpolator 0: the service's machine config is not "),
            1u)
      << watch_json.log();

  // A PLC with the HMI's config says so at its setup (the smoothing it sets is its config's).
  test::Child plc;
  ASSERT_TRUE(
      plc.start({TGM_PLC_BIN, "--config", env.config(), "--duration", "3"}, env.path("plc.log")));
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  EXPECT_NE(plc.log().find("interpolator 0: warning: the service's machine config is not " +
                           env.config() + " (axis limits"),
            std::string::npos)
      << plc.log();

  // With the service's own config: no warning, and the estimate.
  test::Child same;
  ASSERT_TRUE(
      same.start({TGM_HMI_BIN, "status", "--config", env.path("soft.yaml")}, env.path("same.log")));
  EXPECT_EQ(same.wait(kHang), 0) << same.log();
  EXPECT_EQ(same.log().find("warning:"), std::string::npos) << same.log();
  EXPECT_NE(same.log().find("machine digest " + digest), std::string::npos) << same.log();
  test::Child timed;
  ASSERT_TRUE(
      timed.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.path("soft.yaml")},
                  env.path("timed.log")));
  ASSERT_EQ(timed.wait(kHang), 0) << timed.log();
  EXPECT_NE(timed.log().find(", estimated "), std::string::npos) << timed.log();
}

// tgm-hmi run of a program that waits for M51 at line 2 (no PLC here), until it waits.
void run_until_m51(ServiceEnv& env, test::Child& run, client::Client& hmi) {
  std::ofstream(env.path("m.ngc")) << "G90 G1 X1 F600\nM51\nG1 X2\nM2\n";
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config(), "--quiet",
                         "--timeout", "60"},
                        env.path("run.log")));
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.m_func() == 51; }, kHang))
      << run.log();
}

// A normal stop, until the interpolator stands with its program (Status 4).
void stop_until_standing(client::Client& hmi) {
  ASSERT_TRUE(hmi.stop(0).accepted);
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() == 4; }, kHang));
}

// A program that another HMI stops and clears is gone: tgm-hmi run said nothing and waited on
// for good (the state's program id goes to 0, and run looked only at states of its own
// program). It says so now and exits 1. A clear while the program waits for its M-function
// (no PLC here) is refused: stop first.
TEST(ServiceProcesses, HmiRunEndsWhenAnotherHmiClearsItsProgram) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child run;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_NO_FATAL_FAILURE(run_until_m51(env, run, hmi));
  const client::Reply refused = hmi.clear(0);
  EXPECT_FALSE(refused.accepted);
  EXPECT_EQ(refused.reason, "cannot clear while waiting for an M-function: stop first")
      << client::describe(refused);
  ASSERT_NO_FATAL_FAILURE(stop_until_standing(hmi));
  const client::Reply cleared = hmi.clear(0);
  ASSERT_TRUE(cleared.accepted) << client::describe(cleared);
  EXPECT_EQ(run.wait(kHang), 1) << run.log();
  EXPECT_NE(run.log().find("tgm-hmi run: the program was cleared by someone else at line 2\n"),
            std::string::npos)
      << run.log();
}

// A new run clears a program that stands unfinished (here: stopped at its M51): it says so,
// with the program and where it stood (it dropped it without a word), and the run that
// followed it hears that it was cleared.
TEST(ServiceProcesses, HmiRunSaysItClearsAnUnfinishedProgram) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child first;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_NO_FATAL_FAILURE(run_until_m51(env, first, hmi));
  const std::uint32_t held = hmi.state(0)->program_id();
  ASSERT_NO_FATAL_FAILURE(stop_until_standing(hmi));
  std::ofstream(env.path("next.ngc")) << "G90 G1 X0 F600\nM2\n";
  test::Child second;
  ASSERT_TRUE(second.start({TGM_HMI_BIN, "run", env.path("next.ngc"), "--config", env.config(),
                            "--quiet", "--timeout", "60"},
                           env.path("second.log")));
  EXPECT_EQ(second.wait(kHang), 0) << second.log();
  EXPECT_NE(second.log().find("tgm-hmi run: interpolator 0 held program " + std::to_string(held) +
                              ", not finished (ready at line 2): cleared for this one\n"),
            std::string::npos)
      << second.log();
  EXPECT_EQ(first.wait(kHang), 1) << first.log();
  EXPECT_NE(first.log().find("cleared by someone else"), std::string::npos) << first.log();
}

// A streaming `tgm-hmi run` that stops for seconds (SIGSTOP: a stalled or suspended operator
// PC) is dropped by the service's discovery after the 1 s participant lease; resumed, it may
// find the service at once again and never be dropped itself, and then Fast DDS did not match
// its endpoints again: no chunk arrived, the program stood half-executed in an underrun and the
// run waited for good (3 of 5 freezes of 3-5 s, live review of session 80). Three freezes.
TEST(ServiceProcesses, AStreamingRunThatFreezesForSecondsStreamsOnAfterwards) {
  test::ConfigEdits edits;
  edits.buffer_size0 = 1000;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  constexpr int kRecords = 4000;  // 400 mm at F6000: 4 s of motion, four buffers' worth
  write_tenth_steps(env.path("long.ngc"), kRecords, 6000);
  client::Client watch(env.dds(), client::Role::kHmi);
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE("freeze " + std::to_string(k));
    test::Child run;
    ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("long.ngc"), "--config", env.config(),
                           "--timeout", "60", "--progress-interval", "0.5"},
                          env.path("freeze" + std::to_string(k) + ".log")));
    ASSERT_TRUE(watch.wait_until(
        0,
        [](const msg::InterpolatorState& s) {
          return s.status() == 1 && s.next_sequence() > 200 && s.next_sequence() < 2000;
        },
        kHang))
        << run.log();
    ::kill(run.pid(), SIGSTOP);
    std::this_thread::sleep_for(std::chrono::seconds(4));
    ::kill(run.pid(), SIGCONT);
    EXPECT_EQ(run.wait(std::chrono::seconds(40)), 0) << run.log();
    // The service's word that the former participant ended is not this run's end.
    EXPECT_EQ(run.log().find("the rest will not come"), std::string::npos) << run.log();
    EXPECT_TRUE(watch.wait_until(
        0,
        [](const msg::InterpolatorState& s) {
          return s.status() == 3 && s.next_sequence() == kRecords + 1;
        },
        kHang))
        << run.log();
  }
}

// `status` after a stop off the trajectory: "the program was dropped" only where one was
// loaded; on an empty interpolator it said so too, of a program that never was.
TEST(ServiceProcesses, StatusSaysAProgramWasDroppedOnlyWhenOneWas) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.command(0, 9).accepted);
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.off_trajectory(); }, kHang));
  const std::string status = "'" TGM_HMI_BIN "' status --config '" + env.config() + "'";
  const test::ShellRun empty = test::run_shell(status, env.path(""), "status-empty");
  EXPECT_EQ(empty.exit_code, 0) << empty.err;
  EXPECT_NE(empty.out.find("Status 0 (empty, off the trajectory: no program; load one or set the "
                           "position)"),
            std::string::npos)
      << empty.out;
  test::Child run;
  ASSERT_NO_FATAL_FAILURE(run_until_m51(env, run, hmi));
  ASSERT_NO_FATAL_FAILURE(stop_until_standing(hmi));
  ASSERT_TRUE(hmi.command(0, 9).accepted);
  EXPECT_EQ(run.wait(kHang), 1) << run.log();
  const test::ShellRun dropped = test::run_shell(status, env.path(""), "status-dropped");
  EXPECT_NE(dropped.out.find("off the trajectory: the program was dropped)"), std::string::npos)
      << dropped.out;
}

// A position set (Command 2048, the PLC's) while the program stands after a stop dropped the
// program behind an "accepted" (the run then said so and exited 1). It is refused now, with
// what to do, and the run's program stays loaded: a start resumes it
// (Engine.APositionSetIsRefusedWhileAProgramIsLoaded).
TEST(ServiceProcesses, APositionSetIsRefusedWhileARunsProgramStands) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  test::Child run;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_NO_FATAL_FAILURE(run_until_m51(env, run, hmi));
  ASSERT_NO_FATAL_FAILURE(stop_until_standing(hmi));
  client::Client plc(env.dds(), client::Role::kPlc);
  ASSERT_TRUE(plc.wait_for_state(0, kHang));
  const std::int32_t x_inc[] = {5000};  // X = 5 mm at the default 1000 inc/mm
  const client::Reply set = plc.command(0, 2048, x_inc);
  EXPECT_FALSE(set.accepted);
  EXPECT_EQ(set.reason,
            "Command 2048: a program is loaded, which a start would run from the new position "
            "(stop it off the trajectory, Command 9 or 5, or clear it first)")
      << client::describe(set);
  EXPECT_EQ(run.wait(500ms), -1) << run.log();  // the run goes on
  const client::Reply start = hmi.start(0);
  EXPECT_TRUE(start.accepted) << client::describe(start);
  EXPECT_EQ(run.interrupt(kHang, SIGINT), 130) << run.log();  // as after any Ctrl-C
  EXPECT_EQ(run.log().find("dropped the program"), std::string::npos) << run.log();
}

// A program runs from where the interpolator stands. tgm-hmi run compiled every program from
// machine zero: a G91 program's moves were not relative to the machine's position, a G90 line
// drove the axes it does not name to 0 (Z down after a retract: the G0 below went to Z0), and a
// first arc ran as a spiral. Intercode runs only from the point it was compiled from, unless
// --from-here; one that starts with an arc off its circle from here is then refused by the
// interpolator, with the reason, and nothing runs.
TEST(ServiceProcesses, HmiRunStartsTheProgramWhereTheInterpolatorStands) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("to.ngc")) << "G90 G1 X20 Y5 Z-2 F6000\nM2\n";
  std::ofstream(env.path("inc.ngc")) << "G91 G1 X10 F6000\nG2 X10 I5\nM2\n";
  std::ofstream(env.path("abs.ngc")) << "G90 G0 X0 Y0\nM2\n";
  std::ofstream(env.path("arc.ngc")) << "G91 G2 X10 I5 F2000\nM2\n";
  auto run = [&](const std::string& file, int code, const std::string& flag = "") {
    test::Child c;
    std::vector<std::string> argv{
        TGM_HMI_BIN, "run", env.path(file), "--config", env.config(), "--progress-interval", "100"};
    if (!flag.empty()) argv.push_back(flag);
    EXPECT_TRUE(c.start(argv, env.path(file + ".log")));
    EXPECT_EQ(c.wait(kHang), code) << file << ": " << c.log();
    return c.log();
  };
  auto ends_at = [](const std::string& log, std::array<double, 3> want) {
    const std::array<double, 3> got = test::run_end_position(log);
    for (std::size_t a = 0; a < 3; ++a) EXPECT_NEAR(got[a], want[a], 1e-4) << a << ": " << log;
  };
  ends_at(run("to.ngc", 0), {20.0, 5.0, -2.0});
  std::string log = run("inc.ngc", 0);
  EXPECT_NE(log.find("inc.ngc: compiled from where interpolator 0 stands: X20 Y5 Z-2\n"),
            std::string::npos)
      << log;
  ends_at(log, {40.0, 5.0, -2.0});
  ends_at(run("abs.ngc", 0), {0.0, 0.0, -2.0});
  ends_at(run("to.ngc", 0), {20.0, 5.0, -2.0});

  test::Child compile;
  ASSERT_TRUE(compile.start({TGM_HMI_BIN, "compile", env.path("arc.ngc"), "--config", env.config(),
                             "--out", env.path("arc.tgmi")},
                            env.path("compile.log")));
  ASSERT_EQ(compile.wait(kHang), 0) << compile.log();
  // Intercode compiled from zero is refused where the interpolator stands elsewhere (a note said
  // where its first move would start, and the run went on), with what to do.
  log = run("arc.tgmi", 2);
  EXPECT_NE(log.find("arc.tgmi: error: compiled from X0 Y0 Z0, interpolator 0 stands at X20 Y5 "
                     "Z-2: the program would not run as compiled"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("tgm-hmi compile FILE --start X20,Y5,Z-2 --out ...), run the G-code "
                     "itself, or pass --from-here\n"),
            std::string::npos)
      << log;
  // --from-here runs it from there: the interpolator refuses the arc, which would be a spiral.
  log = run("arc.tgmi", 1, "--from-here");
  EXPECT_NE(log.find("ERROR: program "), std::string::npos) << log;  // no "(line 0)"
  EXPECT_NE(log.find("refused: record 0 (line 1): arc does not start on its circle (radius "
                     "15.8114 mm at the start, 5 mm at the end): compiled to start elsewhere "
                     "than X20 Y5, where the interpolator stands\n"),
            std::string::npos)
      << log;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  EXPECT_EQ(hmi.state(0)->orig_position()[0], 20.0);  // it did not move
  EXPECT_EQ(hmi.state(0)->status(), 0);
  // Compiled from where the interpolator stands, the file runs, as the G-code does.
  test::Child here;
  ASSERT_TRUE(here.start({TGM_HMI_BIN, "compile", env.path("arc.ngc"), "--config", env.config(),
                          "--start", "X20,Y5,Z-2", "--out", env.path("here.tgmi")},
                         env.path("here.log")));
  ASSERT_EQ(here.wait(kHang), 0) << here.log();
  EXPECT_NE(here.log().find("compiled from X20 Y5 Z-2) written to "), std::string::npos)
      << here.log();
  ends_at(run("here.tgmi", 0), {30.0, 5.0, -2.0});
}

// Without a PLC an M-function waits for ever: the progress line says for how long and asks
// for tgm-plc, and --timeout stops the interpolator and exits 1.
TEST(ServiceProcesses, HmiRunSaysWhenAnMFunctionWaitsLongAndTimesOut) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("m.ngc")) << "G90 G1 X1 F600\nM51\nG1 X2\nM2\n";
  // A plot path that cannot be written is refused before anything is sent (it used to be said
  // after the run).
  test::Child no_plot;
  ASSERT_TRUE(no_plot.start(
      {TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config(), "--plot", env.path("")},
      env.path("no_plot.log")));
  EXPECT_EQ(no_plot.wait(kHang), 2) << no_plot.log();
  EXPECT_EQ(no_plot.log(),
            "tgm-hmi run: --plot " + env.path("") + ": is a directory\n(see tgm-hmi run --help)\n");
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config(),
                         "--progress-interval", "0.5", "--timeout", "7"},
                        env.path("run.log")));
  EXPECT_EQ(run.wait(kHang), 1) << run.log();
  const std::string log = run.log();
  EXPECT_NE(log.find(" running waiting for M51\n"), std::string::npos) << log;
  EXPECT_NE(log.find(" running waiting for M51 for 5 s (is tgm-plc running?)\n"), std::string::npos)
      << log;
  EXPECT_NE(log.find("tgm-hmi run: timeout after 7.0 s: normal stop: accepted; the program "
                     "stays loaded: `tgm-hmi command start` resumes it"),
            std::string::npos)
      << log;
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.status() != 1; }, kHang));
  EXPECT_NEAR(hmi.state(0)->orig_position()[0], 1.0, 1e-9);  // stopped at the M-function
}

// An M0 program stop pauses the program (Status 4) until the operator starts it again:
// tgm-hmi run says so and, with --m0-continue or when standard input is not a terminal,
// starts it again itself. The M0 is not a LookAheadBuffer section, and tgm-hmi run looked for
// it there: it waited at every M0 for ever.
TEST(ServiceProcesses, HmiRunContinuesAfterAnM0ProgramStop) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  // With an M29 between: its message names its own line, not that of the record after it.
  std::ofstream(env.path("m0.ngc")) << "M0\nG90 G1 X1 F600\nM29 (half way)\nM0\nG1 X2\nM2\n";
  const std::vector<std::vector<std::string>> flags = {{"--m0-continue", "0.2"}, {}};
  for (const auto& extra : flags) {
    std::vector<std::string> args = {TGM_HMI_BIN,  "run",     env.path("m0.ngc"), "--config",
                                     env.config(), "--quiet", "--timeout",        "30"};
    args.insert(args.end(), extra.begin(), extra.end());
    const std::string ctx = extra.empty() ? "no flag" : "--m0-continue 0.2";
    test::Child run;
    ASSERT_TRUE(run.start(args, env.path("run.log"))) << ctx;
    ASSERT_EQ(run.wait(kHang), 0) << ctx << ": " << run.log();
    const std::string log = run.log();
    EXPECT_NE(log.find("M0 program stop at line 1: continuing shortly\n"), std::string::npos)
        << ctx << ": " << log;
    EXPECT_NE(log.find("M0 program stop at line 4: continuing shortly\n"), std::string::npos)
        << ctx << ": " << log;
    // Once: the second run does not show the first one's message, which the topic keeps for
    // late readers.
    const auto m29 = log.find("M29 (line 3): half way\n");
    EXPECT_NE(m29, std::string::npos) << ctx << ": " << log;
    EXPECT_EQ(log.find("M29 (line 3)", m29 + 1), std::string::npos) << ctx << ": " << log;
    EXPECT_EQ(log.find("stopped by a stop command"), std::string::npos) << ctx << ": " << log;
    EXPECT_NE(log.find("end position X2.0000"), std::string::npos) << ctx << ": " << log;
    // The lateness is the service's since it started; the missed cycles also this run's own.
    const auto missed = log.find("missed cycles ");
    ASSERT_NE(missed, std::string::npos) << log;
    unsigned long long total = 0, during = 0;
    ASSERT_EQ(std::sscanf(log.c_str() + missed, "missed cycles %llu (%llu during this run)", &total,
                          &during),
              2)
        << log;
    EXPECT_LE(during, total) << log;
  }
  // While the program stands at an M0, tgm-hmi status says so: the register program_stop tells
  // that Status 4 from a stop command's.
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("m0.ngc"), "--config", env.config(),
                         "--quiet", "--m0-continue", "3"},
                        env.path("run.log")));
  {
    client::Client watch(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(watch.wait_until(
        0, [](const msg::InterpolatorState& s) { return s.program_stop() && s.status() == 4; },
        kHang))
        << run.log();
  }
  test::Child status;
  ASSERT_TRUE(
      status.start({TGM_HMI_BIN, "status", "--config", env.config()}, env.path("status.log")));
  EXPECT_EQ(status.wait(kHang), 0) << status.log();
  EXPECT_NE(status.log().find("Status 4 (ready, at an M0 program stop: start continues)"),
            std::string::npos)
      << status.log();
  EXPECT_EQ(run.wait(kHang), 0) << run.log();
}

// The message topic hands a late reader the last 32 messages. tgm-hmi watch printed them as if
// they had just been written ("message (line 2): ..." at every start); it marks them as earlier
// now, and shows a message written while it watches as news.
TEST(ServiceProcesses, WatchMarksMessagesFromBeforeItBegan) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("m29.ngc")) << "G90 G1 X1 F3000\nM29 (first text)\nM2\n";
  test::Child run;
  ASSERT_TRUE(
      run.start({TGM_HMI_BIN, "run", env.path("m29.ngc"), "--config", env.config(), "--quiet"},
                env.path("run.log")));
  ASSERT_EQ(run.wait(kHang), 0) << run.log();
  test::Child watch;
  ASSERT_TRUE(watch.start({TGM_HMI_BIN, "watch", "--interval", "0.25", "--config", env.config()},
                          env.path("watch.log")));
  // A second program while watch runs: its text is news.
  std::ofstream(env.path("m29b.ngc")) << "G90 G1 X2 F3000\nG1 X3\nM29 (second text)\nM2\n";
  std::this_thread::sleep_for(1s);
  test::Child again;
  ASSERT_TRUE(
      again.start({TGM_HMI_BIN, "run", env.path("m29b.ngc"), "--config", env.config(), "--quiet"},
                  env.path("again.log")));
  ASSERT_EQ(again.wait(kHang), 0) << again.log();
  std::this_thread::sleep_for(1s);  // a few more screens, then Ctrl-C
  ASSERT_EQ(watch.interrupt(kHang), 0) << watch.log();
  const std::string log = watch.log();
  EXPECT_NE(log.find("earlier message (line 2, "), std::string::npos) << log;
  EXPECT_NE(log.find(" s before watch began): first text\n"), std::string::npos) << log;
  EXPECT_EQ(log.find("\nmessage (line 2)"), std::string::npos) << log;
  EXPECT_NE(log.find("\nmessage (line 3): second text\n"), std::string::npos) << log;
  EXPECT_EQ(log.find("earlier message (line 3"), std::string::npos) << log;
}

TEST(ServiceProcesses, LateJoiningHmiSeesTheCurrentStateAtOnce) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  {
    client::Client plc(env.dds(), client::Role::kPlc);
    ASSERT_TRUE(plc.wait_for_state(1, kHang));
    ASSERT_TRUE(plc.set_rel_speed(1, 0.37).accepted);
    ASSERT_TRUE(plc.wait_until(1, [](const msg::InterpolatorState& s) { return s.rel_speed() == 0.37; }, kHang));
  }
  // A new HMI process-equivalent joins now: TRANSIENT_LOCAL hands it the current sample of every
  // interpolator as soon as it matches, without waiting for the next publication.
  client::Client late(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(late.wait_for_state(1, kHang));
  EXPECT_DOUBLE_EQ(late.state(1)->rel_speed(), 0.37);
  EXPECT_GT(late.state(1)->cycle_counter(), 0u);
  ASSERT_TRUE(late.wait_for_state(0, 5s));
  ASSERT_TRUE(late.wait_for_state(2, 5s));

  // The same with `tgm-hmi status` as a process.
  test::Child status;
  ASSERT_TRUE(status.start({TGM_HMI_BIN, "status", "--interpolator", "1", "--config", env.config()},
                           env.path("status.log")));
  EXPECT_EQ(status.wait(kHang), 0) << status.log();
  EXPECT_NE(status.log().find("Rel_Speed 0.370"), std::string::npos) << status.log();
  // The per-axis rows: each axis' letter and value in its row's format.
  for (const char* row : {R"(  Orig_Position \[mm\]   ( [A-Z] -?\d+\.\d{4})+)",
                          R"(  Position \[mm\]        ( [A-Z] -?\d+\.\d{4})+)",
                          R"(  PositionInc \[inc\]    ( [A-Z] -?\d+)+)",
                          R"(  Speed \[mm/s\]         ( [A-Z] -?\d+\.\d{3})+)",
                          R"(  Ratio \[inc/mm\]       ( [A-Z] [-+.e\d]+)+)",
                          R"(  Offset \[inc\]         ( [A-Z] -?\d+)+)",
                          R"(  Backlash \[inc\]       ( [A-Z] -?\d+)+)"}) {
    EXPECT_TRUE(std::regex_search(status.log(), std::regex(std::string("(^|\n)") + row + "\n")))
        << row << "\n"
        << status.log();
  }
}

TEST(ServiceProcesses, ThePlcCannotStartAndOtherRolesAreEnforced) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  {
    client::Client plc(env.dds(), client::Role::kPlc);
    ASSERT_TRUE(plc.wait_for_state(0, kHang));
    const auto start = plc.start(0);
    EXPECT_FALSE(start.accepted);
    EXPECT_EQ(start.code, msg::REPLY_CODE_WRONG_ROLE);
    EXPECT_NE(start.reason.find("only the HMI starts"), std::string::npos) << start.reason;
    EXPECT_EQ(plc.clear(0).code, msg::REPLY_CODE_WRONG_ROLE);
    EXPECT_EQ(plc.set_rel_speed(0, 3.0).code, msg::REPLY_CODE_OUT_OF_RANGE);
    EXPECT_EQ(plc.command(0, 77).code, msg::REPLY_CODE_BAD_REQUEST);
    const std::int32_t ratio_params[] = {0, 1000, 1};
    const auto ratio = plc.command(0, 1024, ratio_params);
    EXPECT_TRUE(ratio.accepted) << client::describe(ratio);
    EXPECT_TRUE(plc.command(0, 8).accepted);
  }
  {
    client::Client hmi(env.dds(), client::Role::kHmi);
    ASSERT_TRUE(hmi.wait_for_state(0, kHang));
    EXPECT_EQ(hmi.ack_m_func(0).code, msg::REPLY_CODE_WRONG_ROLE);
    EXPECT_EQ(hmi.set_rel_speed(0, 0.5).code, msg::REPLY_CODE_WRONG_ROLE);
    EXPECT_EQ(hmi.command(0, 1024).code, msg::REPLY_CODE_WRONG_ROLE);
    EXPECT_EQ(hmi.start(0).code, msg::REPLY_CODE_WRONG_STATE) << "the HMI may start; nothing is loaded";
  }
  // A loaded program, and tgm-plc --try-start as a process: the refusal is logged and the
  // interpolator is still ready, not running.
  std::ofstream(env.path("short.ngc")) << "G1 X1\nM2\n";
  test::Child plc_process;
  ASSERT_TRUE(plc_process.start({TGM_PLC_BIN, "--config", env.config(), "--try-start", "--interpolator", "0",
                                 "--no-basic-params", "--duration", "3"},
                                env.path("plc.log")));
  EXPECT_EQ(plc_process.wait(kHang), 0);
  EXPECT_NE(plc_process.log().find("trying to start as the PLC: refused (wrong role)"), std::string::npos)
      << plc_process.log();
  client::Client watcher(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(watcher.wait_for_state(0, kHang));
  EXPECT_EQ(watcher.state(0)->status(), 0);
}

// tgm-plc --handshake-trace has a row for each acknowledgement and each note of a continuous
// M-function, alike with and without events, naming the M-function and the answer. Without
// events the notes were missing (only the event callback's were traced), and no row said
// which M-function it was or whether the service accepted it (review of session 76, F6).
TEST(ServiceProcesses, PlcTracesEveryAcknowledgementAndNoteAlikeWithAndWithoutEvents) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("m.ngc")) << "G90 G1 X1 F3000\nM51\nG1 X2\nM1234\nG1 X20\nM2\n";
  for (const bool events : {true, false}) {
    const std::string mode = events ? "events" : "no_events";
    const std::string csv = env.path("trace_" + mode + ".csv");
    std::vector<std::string> args{
        TGM_PLC_BIN,         "--config",       env.config(), "--ack-delay",       "0",
        "--no-basic-params", "--interpolator", "0",          "--handshake-trace", csv};
    if (!events) args.push_back("--no-events");
    test::Child plc;
    ASSERT_TRUE(plc.start(args, env.path("plc_" + mode + ".log")));
    ASSERT_TRUE(plc.wait_for_log("setup done", kHang)) << plc.log();
    test::Child run;
    ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config()},
                          env.path("run_" + mode + ".log")));
    EXPECT_EQ(run.wait(kHang), 0) << run.log() << plc.log();
    EXPECT_EQ(plc.interrupt(), 0) << plc.log();
    const std::string text = test::read_text(csv);
    std::vector<std::vector<std::string>> rows;
    std::size_t from = 0;
    while (from < text.size()) {
      const std::size_t end = text.find('\n', from);
      std::vector<std::string> fields;
      std::size_t f = from;
      while (true) {
        const std::size_t comma = text.find(',', f);
        if (comma == std::string::npos || comma > end) {
          fields.push_back(text.substr(f, end - f));
          break;
        }
        fields.push_back(text.substr(f, comma - f));
        f = comma + 1;
      }
      rows.push_back(fields);
      from = end + 1;
    }
    ASSERT_EQ(rows.size(), 3u) << mode << "\n" << text << plc.log();
    EXPECT_EQ(rows[0],
              (std::vector<std::string>{"interpolator", "act_part", "woke_ns", "seen_ns",
                                        "ack_call_ns", "ack_written_ns", "reply_ns", "path", "m",
                                        "m_func_count", "kind", "reply_code", "reply"}));
    std::map<std::string, std::vector<std::string>> by_m;
    for (std::size_t k = 1; k < rows.size(); ++k) {
      ASSERT_EQ(rows[k].size(), 13u) << text;
      by_m[rows[k][8]] = rows[k];
    }
    ASSERT_EQ(by_m.count("51"), 1u) << mode << "\n" << text;
    ASSERT_EQ(by_m.count("1234"), 1u) << mode << "\n" << text;
    const std::vector<std::string>& ack = by_m["51"];
    const std::vector<std::string>& note = by_m["1234"];
    EXPECT_EQ(ack[10], "normal") << text;
    EXPECT_EQ(ack[11], "0") << text;
    EXPECT_EQ(ack[12], "accepted") << text;
    // The service numbers the M-functions it hands over: the note's is the next after M51's.
    EXPECT_EQ(std::stoul(note[9]), std::stoul(ack[9]) + 1) << text;
    EXPECT_EQ(note[10], "continuous") << text;
    // The note is accepted unless the service moved on to the next M-function first: the
    // answer is said either way, and matches its code.
    EXPECT_EQ(note[12], note[11] == "0" ? "accepted" : "refused") << text;
    if (!events) {
      EXPECT_EQ(ack[7], "loop") << text;
      EXPECT_EQ(note[7], "loop") << text;
    }
  }
}

// tgm-plc's --help says what --quiet leaves out and how many starts --try-start sends, and the
// PLC does that: the help said "log only M-functions, acknowledgements and errors", yet the
// start line, each interpolator found and its setup done stay (they should: "setup done" is
// the line to start a program after), and "send a start request once" sent one per
// interpolator (review of session 76, F5).
TEST(ServiceProcesses, PlcQuietAndTryStartDoWhatTheHelpSays) {
  ServiceEnv env;
  test::Child help;
  ASSERT_TRUE(help.start({TGM_PLC_BIN, "--help"}, env.path("help.log")));
  EXPECT_EQ(help.wait(kHang), 0);
  const std::string text = help.log();
  EXPECT_NE(text.find("  --quiet              leave out the lines of the basic parameters the "
                      "service accepted;\n"
                      "                       the rest stays: M-functions, acknowledgements, "
                      "refusals and errors,\n"
                      "                       script actions, and the run's own lines (the "
                      "start, each\n"
                      "                       interpolator found and its setup done, the "
                      "service restarted or\n"
                      "                       silent, the summary at exit)\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("  --try-start          send a start request as the PLC to each "
                      "interpolator served, when\n"
                      "                       it is found (the service refuses each one)\n"),
            std::string::npos)
      << text;
  ASSERT_TRUE(env.start_service());
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--quiet", "--try-start"},
                        env.path("plc.log")));
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  while (test::count_of(plc.log(), "setup done") < 3 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(25ms);
  EXPECT_EQ(plc.interrupt(), 0) << plc.log();
  const std::string log = plc.log();
  for (int i = 0; i < 3; ++i) {
    const std::string ip = "interpolator " + std::to_string(i) + ": ";
    EXPECT_EQ(test::count_of(log, ip + "trying to start as the PLC: refused (wrong role)"), 1)
        << log;
    EXPECT_EQ(test::count_of(log, ip + "found (status"), 1) << log;
    // Spline, IIR and three gear ratios accepted, the start refused.
    EXPECT_EQ(test::count_of(log, ip + "setup done (5 of 6 requests accepted)"), 1) << log;
  }
  EXPECT_EQ(test::count_of(log, "basic parameters:"), 0) << log;
  EXPECT_EQ(test::count_of(log, "PLC emulator on DDS domain"), 1) << log;
  EXPECT_EQ(test::count_of(log, "stopping"), 1) << log;
}

TEST(ServiceProcesses, HundredThousandRecordsStreamIntoAThousandRecordBufferWhileRunning) {
  test::ConfigEdits edits;
  edits.buffer_size0 = 1000;
  ServiceEnv env(edits);
  ASSERT_TRUE(env.start_service());
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  ASSERT_EQ(hmi.state(0)->buffer_size(), 1000);

  // 100,000 collinear 0.025 mm moves at the rapid-limit feed, then M2: 2.5 m in about 10 s.
  constexpr std::size_t kRecords = 100'000;
  std::string gcode = "F15000\n";
  gcode.reserve(kRecords * 10);
  for (std::size_t i = 0; i < kRecords; ++i) gcode += "G1 X0.025\n";
  gcode += "M2\n";
  const Program program = compile(gcode, env.config());
  ASSERT_EQ(program.segments.size(), kRecords + 1);

  std::uint64_t max_buffered = 0;
  hmi.on_state = [&](const msg::InterpolatorState& s) {
    if (s.interpolator() == 0) max_buffered = std::max<std::uint64_t>(max_buffered, s.buffered_segments());
  };
  std::string why;
  std::uint64_t underruns = 0;
  ASSERT_TRUE(run_program(hmi, program, why, &underruns)) << why << "\n" << env.service.log();
  const auto* s = hmi.state(0);
  // Every record executed once and in order: the count, the distance (a reordered or repeated
  // record would add a backward move) and the end point.
  EXPECT_EQ(s->next_sequence(), kRecords + 1);
  // Act_Part counts records from 1; at the end it stands on the last motion or on M2.
  EXPECT_GE(static_cast<std::size_t>(s->act_part()), kRecords);
  EXPECT_NEAR(s->move_distance(), 2500.0, 1e-6);
  EXPECT_NEAR(s->orig_position()[0], 2500.0, 1e-6);
  EXPECT_LE(max_buffered, 1000u);
  EXPECT_EQ(env.service.interrupt(), 0);
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"segments\": 100001,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"duplicate_chunks\": 0,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"refused_chunks\": 0,"), std::string::npos) << stats;
  std::printf("streamed %zu records through a 1000-record buffer, %llu underrun restarts\n", kRecords + 1,
              static_cast<unsigned long long>(underruns));
}

// Requests are taken by two threads of the service (the reader's listener in a Fast DDS receive
// thread, and the receiver thread when the request queue was full). A flood that keeps the queue
// full makes both take at once, over and over; the service must keep answering and stop cleanly
// (it used to deadlock: the listener holds the reader's lock and waited for the service's, the
// receiver thread the other way round).
TEST(ServiceProcesses, RequestFloodNeverStallsTheService) {
  ServiceEnv env;
  std::optional<client::Client> plc_slot;
  ASSERT_TRUE(start_with_matched_plc(env, plc_slot));
  client::Client& plc = *plc_slot;
  const auto until = std::chrono::steady_clock::now() + 3s;
  std::uint64_t sent = 0;
  while (std::chrono::steady_clock::now() < until) {
    for (int k = 0; k < 200; ++k) {
      msg::Request r;
      r.interpolator(static_cast<std::uint16_t>(k % 3));
      r.kind(msg::REQUEST_KIND_WRITE_REL_SPEED);
      r.value(0.5 + 0.001 * (k % 100));
      if (plc.send(r) != 0) ++sent;
    }
    plc.poll(std::chrono::nanoseconds(0));
  }
  EXPECT_GT(sent, 1000u);
  // Still answering (each interpolator), and a clean stop (a stuck DDS thread never joins).
  for (int i = 0; i < 3; ++i) {
    msg::Request q;
    q.interpolator(static_cast<std::uint16_t>(i));
    q.kind(msg::REQUEST_KIND_WRITE_REL_SPEED);
    q.value(0.75);
    const auto r = plc.request(q, 10s);
    EXPECT_TRUE(r.accepted) << "interpolator " << i << ": " << client::describe(r);
  }
  EXPECT_EQ(env.service.interrupt(20s), 0) << env.service.log();
  // Nothing lost unseen: every request written (the flood, the first Rel_Speed and the three
  // above) was executed or answered busy (the queue to the cycle full); it used to be that
  // half of a flood vanished from the reader's KEEP_LAST history without an answer.
  const std::string stats = test::read_text(env.stats_path());
  const auto field = [&](const std::string& name) {
    const std::size_t at = stats.find("\"" + name + "\": ");
    return at == std::string::npos ? -1LL : std::atoll(stats.c_str() + at + name.size() + 4);
  };
  EXPECT_EQ(field("requests") + field("busy_requests"), static_cast<long long>(sent + 4)) << stats;
  std::printf("%llu requests sent in 3 s\n", static_cast<unsigned long long>(sent));
}

// The client's window of unanswered requests: send() refuses the 65th while no reply has been
// taken, request() makes room by polling, and a window without any reply for a second is freed.
TEST(ServiceProcesses, ClientKeepsAtMost64RequestsUnanswered) {
  ServiceEnv env;
  std::optional<client::Client> plc_slot;
  ASSERT_TRUE(start_with_matched_plc(env, plc_slot));
  client::Client& plc = *plc_slot;
  EXPECT_EQ(plc.requests_in_flight(), 0);
  msg::Request r;
  r.interpolator(0);
  r.kind(msg::REQUEST_KIND_WRITE_REL_SPEED);
  r.value(0.9);
  for (int k = 0; k < client::Client::kRequestsInFlight; ++k) ASSERT_NE(plc.send(r), 0u) << k;
  EXPECT_EQ(plc.send(r), 0u);  // no poll() has taken a reply yet
  EXPECT_EQ(plc.requests_in_flight(), client::Client::kRequestsInFlight);
  // request() waits for room: its polls take the 64 replies.
  EXPECT_TRUE(plc.set_rel_speed(0, 0.8).accepted);
  EXPECT_EQ(plc.requests_in_flight(), 0);
  // Replies never taken (this client stops polling): the full window is freed after a second.
  for (int k = 0; k < client::Client::kRequestsInFlight; ++k) ASSERT_NE(plc.send(r), 0u) << k;
  EXPECT_EQ(plc.send(r), 0u);
  std::this_thread::sleep_for(1100ms);
  EXPECT_NE(plc.send(r), 0u);
  EXPECT_EQ(env.service.interrupt(20s), 0) << env.service.log();
}

// The service and the PLC emulator log to standard output. When whatever reads it goes away (a
// closed pipe, a restarted log collector), their writes fail with EPIPE and they carry on:
// SIGPIPE used to end them, and the machines with them.
TEST(ServiceProcesses, ServiceAndPlcOutliveTheReaderOfTheirLog) {
  ServiceEnv env;
  const std::string fifo = env.path("log.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);  // children open it
  ASSERT_GE(reader, 0);
  test::Child service, plc;
  ASSERT_TRUE(service.start({TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime"}, fifo));
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, fifo));
  std::this_thread::sleep_for(1s);
  ::close(reader);  // from here on every write to the log fails
  std::this_thread::sleep_for(1s);
  EXPECT_TRUE(service.running());
  EXPECT_TRUE(plc.running());
  // Both still write (the PLC and the service say that they stop) and still exit cleanly.
  EXPECT_EQ(plc.interrupt(kHang), 0);
  EXPECT_EQ(service.interrupt(kHang), 0);
}

// tgm-plc --script: a bad step is named by its line and the reason, before anything is sent
// (every case of the reader: tests/unit/plc_script_test.cpp; fuzzed: tests/fuzz).
TEST(ServiceProcesses, PlcScriptErrorsNameTheLineAndTheReason) {
  ServiceEnv env;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"- {at_s: 1, command: 8}\n- {at_s: 2, comand: 9}\n", ":2: unknown key 'comand'"},
      {"- {at_s: 1, rel_speed: 5}\n", ":1: rel_speed must be an override 0.01..2, not '5'"},
      // What the service refuses in any state is said at the start, with the config's axes
      // (the default machine has three), not refused in the middle of the run.
      {"- {at_s: 1, command: 1024}\n",
       ":1: interpolator 0: Command 1024: numerator (Command_Parameter[1]) must not be 0 inc"},
      {"- {at_s: 1, command: 1024, parameters: [3, 2000, 1]}\n",
       ":1: interpolator 0: Command 1024: axis (Command_Parameter[0]) must be 0..2, not 3"},
      // A ratio out of range passed this check and was refused only when it ran.
      {"- {at_s: 1, command: 1024, parameters: [0, 1, 2000000000]}\n",
       ":1: interpolator 0: Command 1024: |numerator / denominator| must be 1e-06..1e+09 inc/mm, "
       "not 1 / 2000000000 = 5e-10"},
      {"- {at_s: 1, command: -2, parameters: [20, 1000000], interpolator: 2}\n",
       ":1: interpolator 2: Command -2: Spline points (Command_Parameter[0]) must be 0 (off) or "
       "50..500, not 20"},
      // An axis the interpolator does not have: said before anything is sent.
      {"- {at_s: 1, offset: {X: 5, W: 1}}\n",
       ":1: interpolator 0: offset of 'W': it has no such axis (XYZ)"},
      // A directory aborted the PLC (an uncaught exception from yaml-cpp).
      {"", ": is a directory, not a script file"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string script =
        cases[i].first.empty() ? env.path("") : env.path("script" + std::to_string(i) + ".yaml");
    if (!cases[i].first.empty()) std::ofstream(script) << cases[i].first;
    test::Child plc;
    ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--script", script},
                          env.path("plc" + std::to_string(i) + ".log")));
    EXPECT_EQ(plc.wait(kHang), 2) << cases[i].first;
    EXPECT_NE(plc.log().find("tgm-plc: " + script + cases[i].second), std::string::npos)
        << cases[i].first << plc.log();
  }
}

// The smoothing in effect is in the state: the config's at the start, then what the PLC set
// with Command -2 / -1 (before 0.2.2 an HMI could not see it; the machine digest keeps the
// config's). tgm-hmi status shows it, on the interpolator the PLC set only.
TEST(ServiceProcesses, StatusShowsTheSmoothingThePlcSet) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client plc(env.dds(), client::Role::kPlc);
  ASSERT_TRUE(plc.wait_for_state(1, kHang));
  EXPECT_EQ(plc.state(1)->spline_points(), 0);
  EXPECT_EQ(plc.state(1)->iir_p_e6(), 2'000'000);
  const std::uint64_t digest = plc.state(1)->machine_digest();
  const std::array<std::int32_t, 2> spline{120, 3'000'000};
  const std::array<std::int32_t, 4> iir{3'000'000, 2'000'000, 8'000'000, 0b110};
  const client::Reply a = plc.command(1, -2, spline);
  ASSERT_TRUE(a.accepted) << client::describe(a);
  const client::Reply b = plc.command(1, -1, iir);
  ASSERT_TRUE(b.accepted) << client::describe(b);
  ASSERT_TRUE(plc.wait_until(
      1, [](const msg::InterpolatorState& s) { return s.iir_axis_mask() == 0b110; }, kHang));
  const msg::InterpolatorState now = *plc.state(1);
  EXPECT_EQ(now.spline_points(), 120);
  EXPECT_EQ(now.spline_jerk_mm_s3(), 3e6);
  EXPECT_EQ(now.iir_p_e6(), 3'000'000);
  EXPECT_EQ(now.iir_q_e6(), 2'000'000);
  EXPECT_EQ(now.iir_f_e6(), 8'000'000);
  EXPECT_EQ(now.machine_digest(), digest);

  test::Child status;
  ASSERT_TRUE(status.start({TGM_HMI_BIN, "status", "--interpolator", "1", "--config", env.config()},
                           env.path("status.log")));
  ASSERT_EQ(status.wait(kHang), 0) << status.log();
  EXPECT_NE(status.log().find("  Smoothing: Spline 120 points (12.0 ms at 500 us cycles), jerk "
                              "limit 3000000 mm/s^3; IIR p 3, q 2, f 8 ms on Y Z\n"),
            std::string::npos)
      << status.log();
  test::Child other;
  ASSERT_TRUE(other.start({TGM_HMI_BIN, "status", "--interpolator", "0", "--config", env.config()},
                          env.path("other.log")));
  ASSERT_EQ(other.wait(kHang), 0) << other.log();
  EXPECT_NE(other.log().find("  Smoothing: Spline off; IIR off\n"), std::string::npos)
      << other.log();

  // tgm-hmi run simulates its estimate with that smoothing (with the spline off, as on
  // interpolator 0, it keeps its config's jerk: the state's 0 is no config's value).
  std::ofstream(env.path("p.ngc")) << "G1 Y4 F1200\nM2\n";
  for (const char* ip : {"1", "0"}) {
    test::Child run;
    ASSERT_TRUE(run.start(
        {TGM_HMI_BIN, "run", env.path("p.ngc"), "--interpolator", ip, "--config", env.config()},
        env.path(std::string("run") + ip + ".log")));
    ASSERT_EQ(run.wait(kHang), 0) << run.log();
    EXPECT_NE(run.log().find(", estimated "), std::string::npos) << ip << "\n" << run.log();
    EXPECT_EQ(run.log().find("no time estimate"), std::string::npos) << ip << "\n" << run.log();
  }
}

// tgm-plc --script runs each step once, at its time after the service was found, and logs it
// with its line and the service's answer.
TEST(ServiceProcesses, PlcScriptStepsRunAtTheirTimesAndAreLoggedWithTheirLine) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(2, kHang));
  const std::string script = env.path("script.yaml");
  std::ofstream(script) << "# set the override, then refuse M51\n"
                           "- {at_s: 0.2, rel_speed: 0.45, interpolator: 2}\n"
                           "- {at_s: 0.4, refuse_ack: [51]}\n"
                           "- {at_s: 0.4, command: 7}\n";
  test::Child bad;  // Command 7 is not one a script may send: refused before anything is sent
  ASSERT_TRUE(bad.start({TGM_PLC_BIN, "--config", env.config(), "--script", script},
                        env.path("plc_bad.log")));
  EXPECT_EQ(bad.wait(kHang), 2);
  EXPECT_NE(bad.log().find(script + ":4: command must be a Command"), std::string::npos)
      << bad.log();
  std::ofstream(script) << "# set the override, then refuse M51\n"
                           "- {at_s: 0.2, rel_speed: 0.45, interpolator: 2}\n"
                           "- {at_s: 0.4, refuse_ack: [51]}\n"
                           "- {at_s: 0.4, command: 8, interpolator: 1}\n"
                           "- {at_s: 0.5, command: 1024, parameters: [1, 2500, 2]}\n"
                           "- {at_s: 0.5, offset: {Z: -20, X: 500}, ratio: {Z: 4000.125}}\n"
                           "- {at_s: 0.6, number_axes: 2, interpolator: 1}\n";
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config(), "--script", script,
                         "--no-basic-params", "--duration", "1.5"},
                        env.path("plc.log")));
  EXPECT_TRUE(hmi.wait_until(
      2, [](const msg::InterpolatorState& s) { return s.rel_speed() == 0.45; }, kHang));
  EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
  const std::string log = plc.log();
  for (const char* says : {"script line 2: interpolator 2: Rel_Speed = 0.45: accepted",
                           "script line 3: interpolator 0: from now on M51 is not acknowledged",
                           "script line 4: interpolator 1: Command 8: ",
                           "script line 5: interpolator 0: Command 1024 [1, 2500, 2]: accepted",
                           "script line 6: interpolator 0: Ratio Z = 4000.125 inc/mm: accepted",
                           "script line 6: interpolator 0: Offset Z = -20 inc: accepted",
                           "script line 6: interpolator 0: Offset X = 500 inc: accepted",
                           "script line 7: interpolator 1: Number_Axes = 2: accepted"}) {
    EXPECT_NE(log.find(says), std::string::npos) << says << "\n" << log;
    EXPECT_EQ(log.find(says), log.rfind(says)) << "run twice: " << says;
  }
  EXPECT_EQ(hmi.state(0)->rel_speed(), 1.0);  // only the interpolator the step names
  // The Command went with its parameters: Y's ratio is 2500 inc / 2 mm.
  EXPECT_TRUE(hmi.wait_until(
      0, [](const msg::InterpolatorState& s) { return s.ratio()[1] == 1250.0; }, kHang))
      << hmi.state(0)->ratio()[1];
  // The register writes reached their axes (by letter) and interpolator; PositionInc at the
  // origin is the offset.
  EXPECT_TRUE(hmi.wait_until(
      0,
      [](const msg::InterpolatorState& s) {
        return s.offset()[0] == 500 && s.offset()[2] == -20 && s.ratio()[2] == 4000.125 &&
               s.position_inc()[0] == 500 && s.position_inc()[2] == -20;
      },
      kHang));
  EXPECT_EQ(hmi.state(0)->offset()[1], 0);
  EXPECT_TRUE(hmi.wait_until(
      1, [](const msg::InterpolatorState& s) { return s.number_axes() == 2; }, kHang));
  EXPECT_EQ(hmi.state(0)->number_axes(), 3);
}

// Script steps still to come when tgm-plc stops are named on standard error, with the first
// one's line and at_s: with no service on the domain none runs. A --duration end then exits
// with code 3, a signal (the operator's stop) with 0; both exited 0 without a word about the
// script (review of session 76, F3). A --duration that ends before a step's at_s could come
// is refused at the start.
TEST(ServiceProcesses, PlcScriptStepsThatNeverRanAreNamedAtTheExit) {
  ServiceEnv env;  // no service started
  const std::string script = env.path("script.yaml");
  std::ofstream(script) << "- {at_s: 0, rel_speed: 0.9}\n- {at_s: 0.3, command: 8}\n";
  test::Child timed;
  ASSERT_TRUE(timed.start({TGM_PLC_BIN, "--config", env.config(), "--script", script,
                           "--no-basic-params", "--duration", "0.5"},
                          env.path("plc_timed.log")));
  EXPECT_EQ(timed.wait(kHang), 3) << timed.log();
  EXPECT_NE(timed.log().find("tgm-plc: 2 of 2 script steps never ran (the first: " + script +
                             ":1, at_s 0): --duration 0.5 s ended the run before tgm-service "
                             "was found (at_s counts from then)\n"),
            std::string::npos)
      << timed.log();
  test::Child stopped;
  ASSERT_TRUE(stopped.start(
      {TGM_PLC_BIN, "--config", env.config(), "--script", script, "--no-basic-params"},
      env.path("plc_stopped.log")));
  ASSERT_TRUE(stopped.wait_for_log("PLC emulator on DDS domain", kHang)) << stopped.log();
  EXPECT_EQ(stopped.interrupt(kHang), 0) << stopped.log();
  EXPECT_NE(stopped.log().find("tgm-plc: 2 of 2 script steps never ran (the first: " + script +
                               ":1, at_s 0): the PLC was stopped by a signal before tgm-service "
                               "was found\n"),
            std::string::npos)
      << stopped.log();
  test::Child short_run;
  ASSERT_TRUE(short_run.start(
      {TGM_PLC_BIN, "--config", env.config(), "--script", script, "--duration", "0.3"},
      env.path("plc_short.log")));
  EXPECT_EQ(short_run.wait(kHang), 2) << short_run.log();
  EXPECT_EQ(short_run.log(),
            "tgm-plc: --duration 0.3 (seconds from the start) ends the run before the step at " +
                script +
                ":2 (at_s 0.3, seconds from when tgm-service is found) could run: give a "
                "--duration longer than the script's last at_s\n(see tgm-plc --help)\n");
}

// tgm-plc refuses flags that could not do what they say, before it joins DDS: refusing to
// acknowledge a continuous M-function (the interpolator does not wait for one) did nothing.
TEST(ServiceProcesses, PlcFlagsThatCannotWorkAreUsageErrors) {
  const std::string cfg = std::string(TGM_SOURCE_DIR) + "/config/default.yaml";
  const std::string refuse =
      "tgm-plc: --refuse-ack takes normal M-functions 1..999 like 51,50 (the interpolator waits "
      "only for those), not '";
  const std::pair<std::vector<std::string>, std::string> cases[] = {
      {{"--refuse-ack", "51,1001"}, refuse + "51,1001'\n"},
      {{"--refuse-ack", "0"}, refuse + "0'\n"},
      {{"--refuse-ack", "51,"}, refuse + "51,'\n"},
      {{"--ack-delay", "-1"}, "tgm-plc: --ack-delay must be 0..3600 s, not '-1'\n"},
      // The next flag is no value: it wrote a trace file "--no-events" and left the events on,
      // or joined DDS as "--quiet-plc" (review of session 76, F4).
      {{"--handshake-trace", "--no-events", "--duration", "0.5"},
       "tgm-plc: --handshake-trace needs a value, not the flag '--no-events' (a value that "
       "starts with -- is given as --handshake-trace=VALUE)\n"},
      {{"--participant-prefix", "--quiet", "--duration", "0.5"},
       "tgm-plc: --participant-prefix needs a value, not the flag '--quiet' (a value that "
       "starts with -- is given as --participant-prefix=VALUE)\n"},
  };
  const std::string dir = ::testing::TempDir();
  int k = 0;
  for (const auto& [flags, says] : cases) {
    std::vector<std::string> args{TGM_PLC_BIN, "--config", cfg};
    args.insert(args.end(), flags.begin(), flags.end());
    test::Child plc;
    ASSERT_TRUE(plc.start(args, dir + "/plc-flags" + std::to_string(k++) + ".log"));
    EXPECT_EQ(plc.wait(kHang), 2) << plc.log();
    EXPECT_EQ(plc.log(), says + "(see tgm-plc --help)\n");
  }
  EXPECT_FALSE(std::filesystem::exists("--no-events"));
}

// Runs tgm-service, tgm-plc, tgm-hmi status and tgm-hmi run with the default config and
// `extra` flags, each of which must fail its start with exit code `code` and say `says` as
// `PROGRAM: says` (logs in `stem`N.log under the test's temporary directory).
void expect_every_binary_fails_its_start(const std::vector<std::string>& extra, int code,
                                         const std::string& says, const std::string& stem) {
  const std::string cfg = std::string(TGM_SOURCE_DIR) + "/config/default.yaml";
  const std::pair<std::vector<std::string>, std::string> cases[] = {
      {{TGM_SERVICE_BIN, "--no-realtime", "--duration", "5"}, "tgm-service: "},
      {{TGM_PLC_BIN, "--duration", "5"}, "tgm-plc: "},
      {{TGM_HMI_BIN, "status", "--wait", "1"}, "tgm-hmi status: "},
      {{TGM_HMI_BIN, "run", std::string(TGM_SOURCE_DIR) + "/tests/programs/manual_example.ngc"},
       "tgm-hmi run: "},
  };
  int k = 0;
  for (const auto& [head, who] : cases) {
    std::vector<std::string> args = head;
    args.push_back("--config");
    args.push_back(cfg);
    args.insert(args.end(), extra.begin(), extra.end());
    test::Child c;
    ASSERT_TRUE(c.start(args, ::testing::TempDir() + "/" + stem + std::to_string(k++) + ".log"));
    EXPECT_EQ(c.wait(kHang), code) << who << c.log();
    EXPECT_NE(c.log().find(who + says), std::string::npos) << c.log();
  }
}

// A profiles file that Fast DDS rejects is a bad config like a missing one: every binary says
// so with exit code 2 before it joins DDS (it was exit code 1, as if DDS could not be set up).
TEST(ServiceProcesses, AProfilesFileFastDdsRejectsIsAConfigError) {
  const std::string bad = ::testing::TempDir() + "/rejected-profiles.xml";
  std::ofstream(bad) << "<dds><profiles>\n";  // not closed
  expect_every_binary_fails_its_start(
      {"--profiles", bad}, 2,
      "DDS profiles file '" + bad + "' was rejected by Fast DDS (Fast DDS return code 1)",
      "profiles");
  // Fast DDS's own reason goes to standard error, plain: its default log wrote it to standard
  // output with terminal colours, into the JSON of `status --json`.
  const test::ShellRun status =
      test::run_shell(std::string(TGM_HMI_BIN) + " status --json --wait 1 --profiles '" + bad +
                          "' --domain " + std::to_string(test::test_domain()),
                      ::testing::TempDir(), "rejected-profiles-status");
  EXPECT_EQ(status.exit_code, 2) << status.err;
  EXPECT_EQ(status.out, "");
  EXPECT_NE(status.err.find("Fast DDS error [XMLPARSER]: Error parsing '" + bad + "'"),
            std::string::npos)
      << status.err;
  EXPECT_EQ(status.err.find('\x1b'), std::string::npos) << status.err;
}

// A well-formed profiles file without tgm's profiles is a bad config too (exit code 2, named
// before DDS is joined; it was exit code 1 at the participant's creation), and the message
// lists what is missing: here the shipped file less its message reader profile.
TEST(ServiceProcesses, AProfilesFileWithoutTgmsProfilesIsAConfigError) {
  std::ifstream in(std::string(TGM_SOURCE_DIR) + "/config/fastdds_profiles.xml");
  std::stringstream text;
  text << in.rdbuf();
  std::string xml = text.str();
  const std::string from = "profile_name=\"tgm_message_reader\"";
  const std::size_t at = xml.find(from);
  ASSERT_NE(at, std::string::npos);
  xml.replace(at, from.size(), "profile_name=\"someone_elses_reader\"");
  const std::string partial = ::testing::TempDir() + "/partial-profiles.xml";
  std::ofstream(partial) << xml;
  expect_every_binary_fails_its_start({"--profiles", partial}, 2,
                                      "DDS profiles file '" + partial +
                                          "' lacks the profile 'tgm_message_reader' that tgm "
                                          "creates its participant and topics from",
                                      "partial-profiles");
}

// Another program's socket on the domain's discovery port left every binary running deaf
// (Fast DDS goes on without the port): each now exits with code 1 at its start, naming the
// port, as `PROGRAM: reason`.
TEST(ServiceProcesses, ADiscoveryPortHeldByAnotherProgramFailsTheStart) {
  const int domain = test::test_domain();
  test::HeldUdpPort held(test::discovery_port(domain));
  ASSERT_EQ(held.error(), "");
  expect_every_binary_fails_its_start(
      {"--domain", std::to_string(domain)}, 1,
      "DDS domain " + std::to_string(domain) + ": its discovery port, UDP " +
          std::to_string(test::discovery_port(domain)) + ", is held by another program",
      "held-port");
}

// --stats and --handshake-trace are written at exit. A path that cannot be written fails the
// start (it used to be said at the end of the run, exit code 0, the figures lost); a device
// that refuses the bytes (/dev/full) fails the exit with code 1 (it was not noticed at all).
TEST(ServiceProcesses, ReportFilesThatCannotBeWrittenFailTheStartOrTheExit) {
  ServiceEnv env;
  struct Case {
    std::vector<std::string> args;
    int code;
    std::string says;
  };
  const std::string dir = env.path("");
  const std::string cfg = env.config();
  const Case cases[] = {
      {{TGM_SERVICE_BIN, "--config", cfg, "--stats", dir},
       2,
       "tgm-service: --stats " + dir + ": is a directory"},
      {{TGM_SERVICE_BIN, "--config", cfg, "--handshake-trace", env.path("no/such/dir.csv")},
       2,
       "tgm-service: --handshake-trace " + env.path("no/such/dir.csv") +
           ": cannot create: No such file"},
      {{TGM_SERVICE_BIN, "--config", cfg, "--no-realtime", "--duration", "0.5", "--stats",
        "/dev/full"},
       1,
       "tgm-service: /dev/full: cannot write: No space left on device"},
      {{TGM_PLC_BIN, "--config", cfg, "--handshake-trace", dir},
       2,
       "tgm-plc: --handshake-trace " + dir + ": is a directory"},
      {{TGM_PLC_BIN, "--config", cfg, "--duration", "0.5", "--handshake-trace", "/dev/full"},
       1,
       "tgm-plc: /dev/full: cannot write: No space left on device"},
  };
  for (const Case& k : cases) {
    test::Child c;
    ASSERT_TRUE(c.start(k.args, env.path("report.log")));
    EXPECT_EQ(c.wait(kHang), k.code) << k.args.back() << c.log();
    EXPECT_NE(c.log().find(k.says), std::string::npos) << c.log();
  }
  // A good path: written whole at exit, and no temporary file left next to it.
  test::Child ok;
  ASSERT_TRUE(ok.start({TGM_SERVICE_BIN, "--config", cfg, "--no-realtime", "--duration", "0.5",
                        "--stats", env.path("stats.json")},
                       env.path("ok.log")));
  EXPECT_EQ(ok.wait(kHang), 0) << ok.log();
  const std::string json = test::read_text(env.path("stats.json"));
  EXPECT_EQ(json.rfind("{\"cycles\": ", 0), 0u) << json;
  EXPECT_NE(json.find("\"limit_violations\": 0}\n"), std::string::npos) << json;
  for (const auto& e : std::filesystem::directory_iterator(env.path(""))) {
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
  }
}

// SIGTERM while an axis runs at its programmed feed: the service brings it to rest on the
// trajectory (the Command 8 ramp) before it exits, says so in its log and to the HMIs, and the
// last setpoints the drives get are at rest. It used to leave the cycle at once, and the
// setpoints froze at 6000 mm/min.
TEST(ServiceProcesses, AStopSignalBringsMovingAxesToRestBeforeTheExit) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  client::ClientOptions options;
  options.setpoints = true;
  client::Client hmi(env.dds(), client::Role::kHmi, options);
  std::vector<double> x;  // setpoint Position of X, cycle by cycle as they arrive
  hmi.on_setpoints = [&](const msg::Setpoints& sp) {
    if (sp.interpolator() == 0) x.push_back(sp.position()[0]);
  };
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  const Program program = compile("G90 G1 X300 F6000\nM2\n", env.config());
  client::ProgramSender sender(hmi, program, 0, client::new_program_id());
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  bool started = false, at_feed = false;
  while (!at_feed && std::chrono::steady_clock::now() < deadline) {
    hmi.poll(2ms);
    ASSERT_TRUE(sender.pump()) << sender.error();
    const auto* s = hmi.state(0);
    if (!started && sender.all_confirmed()) started = hmi.start(0).accepted;
    at_feed = started && s != nullptr && s->act_speed() == 6000.0;
  }
  ASSERT_TRUE(at_feed);
  const double x_at_signal = hmi.state(0)->orig_position()[0];
  ASSERT_LT(x_at_signal, 200.0);  // far from the end: the stop is the signal's
  ASSERT_EQ(::kill(env.service.pid(), SIGTERM), 0);
  int code = -1;
  std::vector<std::string> messages;
  while ((code = env.service.wait(0ms)) == -1 &&
         std::chrono::steady_clock::now() < deadline + kHang) {
    hmi.poll(5ms);
    for (const auto& m : hmi.take_messages()) messages.emplace_back(m.text().c_str());
  }
  for (int i = 0; i < 40; ++i) hmi.poll(5ms);  // what is still on its way
  for (const auto& m : hmi.take_messages()) messages.emplace_back(m.text().c_str());
  EXPECT_EQ(code, 0) << env.service.log();
  EXPECT_NE(env.service.log().find(
                "stopped the motion of 1 interpolator on the trajectory before exiting"),
            std::string::npos)
      << env.service.log();
  EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [](const std::string& m) {
    return m.find(
               "tgm-service is stopping: normal stop on the trajectory (Command 8) at 6000 "
               "mm/min on line 1") != std::string::npos;
  }));
  // The last setpoints stand, past where the signal came and short of the program's end.
  ASSERT_GE(x.size(), 3u);
  EXPECT_EQ(x[x.size() - 1], x[x.size() - 2]);
  EXPECT_EQ(x[x.size() - 2], x[x.size() - 3]);
  EXPECT_GT(x.back(), x_at_signal);
  EXPECT_LT(x.back(), 300.0);
}

// The log of tgm-service and tgm-plc carries the local date and time of each line (--log-time
// on; auto does the same unless the output is systemd's journal, which stamps it itself); the
// lines had no time at all. Usage errors are not log lines and stay unstamped.
TEST(ServiceProcesses, ServiceAndPlcLogLinesCarryTheirTime) {
  ServiceEnv env;
  const std::regex stamped(R"(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}[+-]\d{4} .*)");
  const auto lines = [](const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
  };
  for (const char* when : {"on", "off"}) {
    test::Child service, plc;
    ASSERT_TRUE(service.start({TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime",
                               "--service-check-ms", "0", "--duration", "1", "--log-time", when},
                              env.path(std::string("service-") + when + ".log")));
    ASSERT_TRUE(
        plc.start({TGM_PLC_BIN, "--config", env.config(), "--duration", "1", "--log-time", when},
                  env.path(std::string("plc-") + when + ".log")));
    EXPECT_EQ(service.wait(kHang), 0) << service.log();
    EXPECT_EQ(plc.wait(kHang), 0) << plc.log();
    for (const test::Child* c : {&service, &plc}) {
      const std::vector<std::string> all = lines(c->log());
      EXPECT_GE(all.size(), 2u) << c->log();
      for (const std::string& line : all) {
        EXPECT_EQ(std::regex_match(line, stamped), std::string(when) == "on") << line;
      }
    }
  }
  test::Child bad;
  ASSERT_TRUE(
      bad.start({TGM_PLC_BIN, "--config", env.config(), "--log-time", "yes"}, env.path("bad.log")));
  EXPECT_EQ(bad.wait(kHang), 2);
  EXPECT_EQ(bad.log(),
            "tgm-plc: --log-time must be auto, on or off, not 'yes'\n(see tgm-plc --help)\n");
}

// `tgm-service --check-config` checks a config as the start does, without DDS: usable, it says
// what the service would set up (with each interpolator's machine digest, which `tgm-hmi
// status` shows of the running service) and exits 0; not, every problem and exit code 2.
TEST(ServiceProcesses, CheckConfigSaysWhatTheServiceWouldSetUpOrEveryProblem) {
  ServiceEnv env;
  test::Child good;
  ASSERT_TRUE(good.start({TGM_SERVICE_BIN, "--config", env.config(), "--check-config"},
                         env.path("good.log")));
  ASSERT_EQ(good.wait(kHang), 0) << good.log();
  const std::string g = good.log();
  EXPECT_EQ(g.rfind("tgm-service: config " + env.config() + " is usable\n", 0), 0u) << g;
  EXPECT_NE(g.find("  cycle 500 us; DDS domain " + std::to_string(test::test_domain())),
            std::string::npos)
      << g;
  const std::optional<AppConfig> config = load_config_file(env.config()).config;
  ASSERT_TRUE(config.has_value());
  for (int i = 0; i < 3; ++i) {
    char line[160];
    std::snprintf(line, sizeof line,
                  "  interpolator %d: axes XYZ, Buffer_Size 10000, machine digest %016llx\n", i,
                  static_cast<unsigned long long>(machine_digest(config->machine, i, 3)));
    EXPECT_NE(g.find(line), std::string::npos) << line << "\n" << g;
  }
  EXPECT_EQ(g.find("looking"), std::string::npos) << g;  // DDS not joined

  std::string yaml = test::read_text(env.config());
  ASSERT_TRUE(test::replace_first(yaml, "max_jerk_mm_s3: 30000", "max_jerk_mm_s3: 3"));
  ASSERT_TRUE(test::replace_first(yaml, "cycle_time_us: 500", "cycle_time_us: 400"));
  std::ofstream(env.path("bad.yaml")) << yaml;
  test::Child bad;
  ASSERT_TRUE(bad.start({TGM_SERVICE_BIN, "--config", env.path("bad.yaml"), "--check-config"},
                        env.path("bad.log")));
  EXPECT_EQ(bad.wait(kHang), 2) << bad.log();
  EXPECT_NE(bad.log().find("max_jerk_mm_s3"), std::string::npos) << bad.log();
  EXPECT_NE(bad.log().find("cycle_time_us"), std::string::npos) << bad.log();
  EXPECT_EQ(bad.log().find("usable"), std::string::npos) << bad.log();
}

TEST(ServiceProcesses, ServiceStopsCleanlyOnSigtermAndRejectsBadFlags) {
  ServiceEnv env;
  test::Child bad;
  ASSERT_TRUE(bad.start({TGM_SERVICE_BIN, "--config", env.config(), "--bogus", "1"}, env.path("bad.log")));
  EXPECT_EQ(bad.wait(kHang), 2);
  EXPECT_NE(bad.log().find("unknown option '--bogus'"), std::string::npos) << bad.log();
  // A CPU the process may not run on (1023: no test machine has it; the kernel refuses the pin)
  // is refused at the start. The cycle thread used to log the refusal and run unpinned.
  test::Child unpinned;
  ASSERT_TRUE(unpinned.start({TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime", "--cpu",
                              "1023", "--duration", "5"},
                             env.path("unpinned.log")));
  EXPECT_EQ(unpinned.wait(kHang), 2) << unpinned.log();
  EXPECT_NE(unpinned.log().find("tgm-service: --cpu 1023: this process may run on CPU"),
            std::string::npos)
      << unpinned.log();
  // Numbers: the whole text, within range, finite (one reader for every binary, cli_numbers.hpp).
  // `--duration inf` used to be a run without end; 2^32 used to wrap to interpolator 0.
  test::Child endless;
  ASSERT_TRUE(endless.start({TGM_SERVICE_BIN, "--config", env.config(), "--duration", "inf"},
                            env.path("endless.log")));
  EXPECT_EQ(endless.wait(kHang), 2);
  EXPECT_NE(endless.log().find("--duration must be seconds, > 0 and at most 1e9, not 'inf'"),
            std::string::npos)
      << endless.log();
  // 1e12 s passed, and its end in nanoseconds overflowed the cast to the clock's integer: the
  // main thread's wait became 0 and it spun on a core next to the cycle thread.
  test::Child spinning;
  ASSERT_TRUE(spinning.start({TGM_SERVICE_BIN, "--config", env.config(), "--duration", "1e12"},
                             env.path("spinning.log")));
  EXPECT_EQ(spinning.wait(kHang), 2);
  EXPECT_NE(spinning.log().find("--duration must be seconds, > 0 and at most 1e9, not '1e12'"),
            std::string::npos)
      << spinning.log();
  test::Child wrapped;
  ASSERT_TRUE(wrapped.start({TGM_PLC_BIN, "--config", env.config(), "--interpolator", "4294967296"},
                            env.path("wrapped.log")));
  EXPECT_EQ(wrapped.wait(kHang), 2);
  EXPECT_NE(wrapped.log().find("--interpolator must be 0..2, not '4294967296'"), std::string::npos)
      << wrapped.log();
  test::Child plc_endless;
  ASSERT_TRUE(plc_endless.start({TGM_PLC_BIN, "--config", env.config(), "--duration", "1e999"},
                                env.path("plc_endless.log")));
  EXPECT_EQ(plc_endless.wait(kHang), 2);
  EXPECT_NE(plc_endless.log().find("--duration must be"), std::string::npos) << plc_endless.log();
  // Priorities with --no-realtime contradict it; a value given twice would lose one of them.
  test::Child not_realtime;
  ASSERT_TRUE(not_realtime.start({TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime",
                                  "--dds-priority", "90", "--duration", "5"},
                                 env.path("not_realtime.log")));
  EXPECT_EQ(not_realtime.wait(kHang), 2);
  EXPECT_NE(not_realtime.log().find("--dds-priority sets a SCHED_FIFO priority, which "
                                    "--no-realtime turns off"),
            std::string::npos)
      << not_realtime.log();
  test::Child twice;
  ASSERT_TRUE(twice.start({TGM_PLC_BIN, "--config", env.config(), "--ack-delay", "0.5",
                           "--ack-delay", "0", "--duration", "5"},
                          env.path("twice.log")));
  EXPECT_EQ(twice.wait(kHang), 2);
  EXPECT_NE(twice.log().find("tgm-plc: --ack-delay is given more than once"), std::string::npos)
      << twice.log();
  // An empty value is not the flag left out: `--config=` used to run with the default config.
  test::Child empty_config;
  ASSERT_TRUE(empty_config.start({TGM_SERVICE_BIN, "--config="}, env.path("empty_config.log")));
  EXPECT_EQ(empty_config.wait(kHang), 2);
  EXPECT_NE(empty_config.log().find("--config needs a value, not an empty string"),
            std::string::npos)
      << empty_config.log();
  test::Child empty_profiles;
  ASSERT_TRUE(empty_profiles.start({TGM_PLC_BIN, "--config", env.config(), "--profiles", ""},
                                   env.path("empty_profiles.log")));
  EXPECT_EQ(empty_profiles.wait(kHang), 2);
  EXPECT_NE(empty_profiles.log().find("--profiles needs a value, not an empty string"),
            std::string::npos)
      << empty_profiles.log();
  test::Child bad_config;
  ASSERT_TRUE(bad_config.start({TGM_PLC_BIN, "--config", env.path("missing.yaml")}, env.path("bad_config.log")));
  EXPECT_EQ(bad_config.wait(kHang), 2);
  test::Child no_profiles;
  ASSERT_TRUE(no_profiles.start({TGM_HMI_BIN, "status", "--config", env.config(), "--profiles", env.path("none.xml")},
                                env.path("no_profiles.log")));
  EXPECT_EQ(no_profiles.wait(kHang), 2);
  EXPECT_NE(no_profiles.log().find("does not exist"), std::string::npos) << no_profiles.log();
  test::Child help;
  ASSERT_TRUE(help.start({TGM_PLC_BIN, "--help"}, env.path("help.log")));
  EXPECT_EQ(help.wait(kHang), 0);
  EXPECT_NE(help.log().find("--refuse-ack"), std::string::npos);
  for (const char* bin : {TGM_PLC_BIN, TGM_SERVICE_BIN, TGM_HMI_BIN}) {
    test::Child version;
    ASSERT_TRUE(version.start({bin, "--version"}, env.path("version.log")));
    EXPECT_EQ(version.wait(kHang), 0) << bin;
    const std::string name = std::filesystem::path(bin).filename().string();
    EXPECT_EQ(version.log(), name + " " + cli::version() + "\n") << bin;
  }

  ASSERT_TRUE(env.start_service());
  client::Client hmi(env.dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log")));
  // Running, its handlers in place (a fixed 300 ms was too short under AddressSanitizer: the
  // SIGTERM came before the handler and the PLC died of it, exit 143).
  ASSERT_TRUE(plc.wait_for_log(": setup done (")) << plc.log();
  // A closed terminal (SIGHUP) ends neither: both died of it, and the machines with the service.
  const std::uint64_t before = hmi.state(0)->cycle_counter();
  ::kill(plc.pid(), SIGHUP);
  ::kill(env.service.pid(), SIGHUP);
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(plc.wait(0ms), -1) << plc.log();
  EXPECT_EQ(env.service.wait(0ms), -1) << env.service.log();
  EXPECT_TRUE(hmi.wait_until(
      0, [&](const msg::InterpolatorState& s) { return s.cycle_counter() > before + 1000; },
      kHang));
  // SIGTERM as from systemd or docker stop: both exit 0 and say so.
  EXPECT_EQ(plc.interrupt(10s, SIGTERM), 0) << plc.log();
  EXPECT_EQ(env.service.interrupt(10s, SIGTERM), 0) << env.service.log();
  EXPECT_NE(env.service.log().find("stopping (Terminated)"), std::string::npos) << env.service.log();
}

// A program piped into `run` is read once: away from machine zero `run` compiles it a second
// time from where the interpolator stands, and from a pipe that second compile read nothing.
// The run then cleared the interpolator, sent 0 records and failed with "nothing loaded"
// (review of session 77). Both runs from the pipe ("-" is standard input) now run it: from X5
// to X10 and on to X15 (the default config starts in G91).
TEST(ServiceProcesses, RunReadsAPipedProgramOnceAlsoAwayFromMachineZero) {
  ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  const std::string program = env.path("x5.ngc");
  std::ofstream(program) << "G1 X5 F3000\nM2\n";
  test::Child first;
  ASSERT_TRUE(
      first.start({TGM_HMI_BIN, "run", program, "--config", env.config()}, env.path("first.log")));
  ASSERT_EQ(first.wait(kHang), 0) << first.log();
  for (const char* input : {"-", "/dev/stdin"}) {
    test::Child piped;
    const std::string line = std::string("cat '") + program + "' | '" + TGM_HMI_BIN + "' run " +
                             input + " --config '" + env.config() + "'";
    ASSERT_TRUE(piped.start({"/bin/sh", "-c", line}, env.path("piped.log")));
    EXPECT_EQ(piped.wait(kHang), 0) << piped.log();
    EXPECT_NE(
        piped.log().find(std::string(input) + ": compiled from where interpolator 0 stands: X"),
        std::string::npos)
        << piped.log();
    EXPECT_NE(piped.log().find(input == std::string("-") ? "end position X10.0000"
                                                         : "end position X15.0000"),
              std::string::npos)
        << piped.log();
  }
}

}  // namespace
}  // namespace tgm
