// The three processes in three Linux network namespaces joined by veth pairs to a bridge (in a
// fourth namespace), so that every DDS sample crosses a (virtual) network, as between the
// containers of docker/compose.yaml. Addresses 10.231.0.0/24 exist only inside the namespaces
// this test creates; it removes them even when it fails. Needs root and `ip netns`: skipped
// otherwise.
//
// Transport: config/fastdds_profiles.xml (UDPv4 only) with the three addresses as initial peers
// (docker/make_udp_profiles.sh; unicast discovery, no dependence on multicast routing across the
// bridge).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "../support/env_params.hpp"
#include "service_test_env.hpp"
#include "tgm/gcode.hpp"
#include "tgm/simulation.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {
namespace {

using namespace std::chrono_literals;

std::string ip_binary() {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"}) {
    if (::access(p, X_OK) == 0) return p;
  }
  return {};
}

// Runs a shell command line; true on exit code 0.
bool sh(const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()) == 0; }

// Three namespaces (service, plc, hmi) on a bridge in a fourth; removed by the destructor.
class Namespaces {
 public:
  explicit Namespaces(const std::string& ip) : ip_(ip) {
    const std::string tag = "tgm" + std::to_string(::getpid() % 100000);
    bridge_ = tag + "br";
    names_ = {tag + "svc", tag + "plc", tag + "hmi"};
  }
  ~Namespaces() {
    for (const auto& n : names_) sh(ip_ + " netns del " + n);
    sh(ip_ + " netns del " + bridge_);
  }
  bool create(std::string& error) {
    auto run = [&](const std::string& c) {
      if (sh(ip_ + " " + c)) return true;
      error = "ip " + c + " failed";
      return false;
    };
    if (!run("netns add " + bridge_) || !run("-n " + bridge_ + " link add br0 type bridge") ||
        !run("-n " + bridge_ + " link set br0 type bridge mcast_snooping 0") ||
        !run("-n " + bridge_ + " link set br0 up") || !run("-n " + bridge_ + " link set lo up")) {
      return false;
    }
    for (std::size_t i = 0; i < names_.size(); ++i) {
      const std::string& n = names_[i];
      std::string port = "p";
      port += std::to_string(i);  // not "p" + ...: GCC 12 -O3 warns falsely (-Wrestrict)
      if (!run("netns add " + n) ||
          !run("-n " + bridge_ + " link add " + port + " type veth peer name eth0 netns " + n) ||
          !run("-n " + bridge_ + " link set " + port + " master br0") ||
          !run("-n " + bridge_ + " link set " + port + " up") || !run("-n " + n + " link set lo up") ||
          !run("-n " + n + " addr add " + address(i) + "/24 dev eth0") || !run("-n " + n + " link set eth0 up") ||
          !run("-n " + n + " route add 224.0.0.0/4 dev eth0")) {
        return false;
      }
    }
    return true;
  }
  static std::string address(std::size_t i) { return "10.231.0." + std::to_string(i + 1); }
  const std::string& name(std::size_t i) const { return names_[i]; }
  std::vector<std::string> exec(std::size_t i, std::vector<std::string> args) const {
    std::vector<std::string> out{ip_, "netns", "exec", names_[i]};
    out.insert(out.end(), args.begin(), args.end());
    return out;
  }

 private:
  std::string ip_;
  std::string bridge_;
  std::vector<std::string> names_;
};

// config/fastdds_profiles.xml (the tgm_participant on UDPv4 only) with the three namespace
// addresses as initial peers: made by docker/make_udp_profiles.sh, the same script that makes the
// profiles of docker/compose.yaml.
std::string udp_profiles(const std::string& dir) {
  const std::string path = dir + "/fastdds_profiles_udp.xml";
  std::string cmd = "bash " TGM_SOURCE_DIR "/docker/make_udp_profiles.sh";
  for (std::size_t i = 0; i < 3; ++i) (cmd += ' ') += Namespaces::address(i);
  EXPECT_EQ(std::system((cmd + " > " + path).c_str()), 0) << cmd;
  EXPECT_NE(test::read_text(path).find("<useBuiltinTransports>false</useBuiltinTransports>"), std::string::npos);
  return path;
}

// The three namespaces, a directory and a service environment with the UDP-only profiles
// for one test; skipped without root, `ip netns` or the right to create namespaces.
class ServiceNetns : public ::testing::Test {
 protected:
  void SetUp() override {
    if (::geteuid() != 0) GTEST_SKIP() << "needs root to create network namespaces";
    ip_ = ip_binary();
    if (ip_.empty() || !sh(ip_ + " netns list")) GTEST_SKIP() << "`ip netns` is not available";
    ns_.emplace(ip_);
    std::string error;
    if (!ns_->create(error)) GTEST_SKIP() << "cannot create network namespaces here: " << error;
    dir_ = (std::filesystem::temp_directory_path() /
            ("tgm_netns_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name()))
               .string();
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty() && !HasFailure()) std::filesystem::remove_all(dir_, ec);
  }
  //! Service environment (config) with the UDP-only profiles of the three namespaces.
  test::ConfigEdits edits() const {
    test::ConfigEdits e;
    e.profiles = udp_profiles(dir_);
    return e;
  }
  //! `iptables ARGS` in namespace i (0 service, 1 plc, 2 hmi); true on success.
  bool iptables(std::size_t i, const std::string& args) const {
    return sh(ip_ + " netns exec " + ns_->name(i) + " iptables " + args);
  }
  //! Drops every datagram in and out of namespace i (block), or lets them through (unblock).
  bool block(std::size_t i) const {
    return iptables(i, "-I INPUT -j DROP") && iptables(i, "-I OUTPUT -j DROP");
  }
  bool unblock(std::size_t i) const {
    return iptables(i, "-D INPUT -j DROP") && iptables(i, "-D OUTPUT -j DROP");
  }
  //! Drops every datagram in and out of namespace i for `outage`, then lets them through again.
  void cut(std::size_t i, std::chrono::seconds outage) const {
    ASSERT_TRUE(block(i));
    std::this_thread::sleep_for(outage);
    ASSERT_TRUE(unblock(i));
  }
  //! tgm-service (with --stats) in the service's namespace and `tgm-hmi run PROGRAM` (a progress
  //! line every 0.2 s) in the HMI's; succeeds once the run streams (its first progress line).
  ::testing::AssertionResult start_run(const test::ServiceEnv& env, const std::string& program,
                                       test::Child& service, test::Child& hmi) const {
    if (!service.start(ns_->exec(0, {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime",
                                     "--stats", env.stats_path()}),
                       env.path("service.log")) ||
        !hmi.start(ns_->exec(2, {TGM_HMI_BIN, "run", program, "--config", env.config(),
                                 "--progress-interval", "0.2"}),
                   env.path("hmi.log"))) {
      return ::testing::AssertionFailure() << "cannot start tgm-service or tgm-hmi";
    }
    if (!hmi.wait_for_log("% line ", 60s, 20ms)) {
      return ::testing::AssertionFailure() << hmi.log() << service.log();
    }
    return ::testing::AssertionSuccess();
  }
  const Namespaces& ns() const { return *ns_; }

  std::string ip_;
  std::optional<Namespaces> ns_;
  std::string dir_;
};

constexpr const char* kManualExample = TGM_SOURCE_DIR "/tests/programs/manual_example.ngc";

// Where the offline simulation of `program_path` ends, with the machine of `config_path`.
std::array<double, kMaxAxes> simulated_end(const std::string& config_path,
                                           const std::string& program_path) {
  const ConfigLoad load = load_config_file(config_path);
  EXPECT_TRUE(load.config.has_value());
  if (!load.config) return {};
  const MachineConfig& machine = load.config->machine;
  const CompileResult compiled =
      compile_gcode(test::read_text(program_path), CompileOptions::from_machine(machine, 0));
  EXPECT_TRUE(compiled.ok());
  std::optional<Simulation> sim = Simulation::create(machine, SimulationOptions{});
  EXPECT_TRUE(sim.has_value());
  if (!sim) return {};
  const SimulationSummary s = sim->run(compiled.program);
  EXPECT_EQ(s.result, StepResult::kFinished);
  return s.end_position;
}

// The end position of `tgm-hmi run`'s summary against `want`, to its four decimals.
void expect_run_ended_at(const std::string& log, const std::array<double, kMaxAxes>& want) {
  const std::array<double, 3> end = test::run_end_position(log);
  for (std::size_t a = 0; a < 3; ++a) {
    EXPECT_NEAR(end[a], want[a], 5.1e-5) << "axis " << a << "\n" << log;
  }
}

TEST_F(ServiceNetns, ManualExampleAcrossThreeNetworkNamespaces) {
  test::ServiceEnv env(edits());
  test::Child service, plc, hmi;
  ASSERT_TRUE(
      service.start(ns().exec(0, {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime"}),
                    env.path("service.log")));
  ASSERT_TRUE(
      plc.start(ns().exec(1, {TGM_PLC_BIN, "--config", env.config()}), env.path("plc.log")));
  ASSERT_TRUE(
      hmi.start(ns().exec(2, {TGM_HMI_BIN, "run", kManualExample, "--config", env.config()}),
                env.path("hmi.log")));
  const int code = hmi.wait(120s);
  EXPECT_EQ(code, 0) << hmi.log() << "\n--- plc:\n" << plc.log() << "\n--- service:\n" << service.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  EXPECT_NE(hmi.log().find("done: 13 records"), std::string::npos) << hmi.log();
  EXPECT_EQ(test::count_of(plc.log(), "acknowledged after"), 3) << plc.log();
}

// The same with DDS Security, each namespace holding only its own role's material (ca.pem,
// governance.p7s and the role's certificate, key and permissions), as each machine of a cell
// would: authentication, access control and encryption across hosts (README, "DDS Security").
TEST_F(ServiceNetns, ManualExampleAcrossThreeNamespacesWithDdsSecurity) {
  if (!test::have_openssl()) GTEST_SKIP() << "no openssl";
  test::ServiceEnv env(edits());
  const std::string all = env.path("security");
  ASSERT_TRUE(test::make_security_material(all));
  auto role_dir = [&](const std::string& role) {
    const std::string dir = env.path(role + "-security");
    std::filesystem::create_directories(dir);
    for (const std::string& f : {std::string("ca.pem"), std::string("governance.p7s"),
                                 role + ".pem", role + ".key", role + ".permissions.p7s"}) {
      std::filesystem::copy_file(all + "/" + f, dir + "/" + f);
    }
    return dir;
  };
  test::Child service, plc, hmi;
  ASSERT_TRUE(service.start(ns().exec(0, {TGM_SERVICE_BIN, "--config", env.config(),
                                          "--no-realtime", "--security", role_dir("service")}),
                            env.path("service.log")));
  ASSERT_TRUE(plc.start(
      ns().exec(1, {TGM_PLC_BIN, "--config", env.config(), "--security", role_dir("plc")}),
      env.path("plc.log")));
  ASSERT_TRUE(hmi.start(ns().exec(2, {TGM_HMI_BIN, "run", kManualExample, "--config", env.config(),
                                      "--security", role_dir("hmi")}),
                        env.path("hmi.log")));
  const int code = hmi.wait(120s);
  EXPECT_EQ(code, 0) << hmi.log() << "\n--- plc:\n"
                     << plc.log() << "\n--- service:\n"
                     << service.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  EXPECT_NE(hmi.log().find("done: 13 records"), std::string::npos) << hmi.log();
  EXPECT_EQ(test::count_of(plc.log(), "acknowledged after"), 3) << plc.log();
  expect_run_ended_at(hmi.log(), simulated_end(env.config(), kManualExample));
}

// The same three namespaces on a network that loses packets: every process drops a share of
// the UDP datagrams it receives at random (iptables' statistic match, in its own namespace;
// the kernel here has no netem), 10 % by default, TGM_NETNS_LOSS_PERCENT=30 for a harder run. DDS's
// reliable topics must carry the program, the requests and their replies, and the M-function
// handshake through it: the manual's example ends where the offline simulation ends with every
// M-function acknowledged once, each of a series of operator commands is answered, a second
// run works as the first, and the service counts no lost or unmatched reply.
TEST_F(ServiceNetns, ProgramRequestsAndHandshakeSurviveALossyNetwork) {
  const std::uint64_t loss_percent = test::env_u64("TGM_NETNS_LOSS_PERCENT", 10);
  ASSERT_LE(loss_percent, 90u) << "TGM_NETNS_LOSS_PERCENT: 0..90";
  const std::string loss_text = std::to_string(static_cast<double>(loss_percent) / 100.0);
  for (std::size_t i = 0; i < 3; ++i) {
    const std::string rule =
        "-A INPUT -p udp -m statistic --mode random --probability " + loss_text + " -j DROP";
    if (!iptables(i, rule)) GTEST_SKIP() << "iptables cannot drop packets at random here: " << rule;
  }
  test::ServiceEnv env(edits());
  const auto expected = simulated_end(env.config(), kManualExample);

  test::Child service, plc;
  ASSERT_TRUE(service.start(ns().exec(0, {TGM_SERVICE_BIN, "--config", env.config(),
                                          "--no-realtime", "--stats", env.stats_path()}),
                            env.path("service.log")));
  ASSERT_TRUE(
      plc.start(ns().exec(1, {TGM_PLC_BIN, "--config", env.config()}), env.path("plc.log")));
  auto logs = [&] { return "\n--- plc:\n" + plc.log() + "\n--- service:\n" + service.log(); };
  auto run_program = [&](const std::string& name, const std::array<double, kMaxAxes>& want) {
    test::Child hmi;
    ASSERT_TRUE(hmi.start(
        ns().exec(2, {TGM_HMI_BIN, "run", kManualExample, "--config", env.config(), "--quiet"}),
        env.path(name)));
    ASSERT_EQ(hmi.wait(180s), 0) << hmi.log() << logs();
    EXPECT_NE(hmi.log().find("done: 13 records"), std::string::npos) << hmi.log();
    expect_run_ended_at(hmi.log(), want);
  };
  run_program("hmi-1.log", expected);
  // Operator commands, each a new HMI process (participant, discovery, request, reply).
  constexpr int kCommands = 8;
  for (int k = 0; k < kCommands && !::testing::Test::HasFailure(); ++k) {
    test::Child cmd;
    const std::string log_name = "command-" + std::to_string(k) + ".log";
    // The timeout only bounds a hang: what is checked is that each is answered, once.
    ASSERT_TRUE(cmd.start(ns().exec(2, {TGM_HMI_BIN, "command", "clear", "--timeout", "30",
                                        "--config", env.config()}),
                          env.path(log_name)));
    EXPECT_EQ(cmd.wait(60s), 0) << cmd.log() << logs();
    EXPECT_EQ(test::count_of(cmd.log(), "accepted"), 1) << cmd.log();
  }
  // The second run starts where the first ended: the example is incremental (G91) throughout,
  // so it ends twice as far from zero.
  std::array<double, kMaxAxes> twice{};
  for (std::size_t a = 0; a < twice.size(); ++a) twice[a] = 2.0 * expected[a];
  run_program("hmi-2.log", twice);
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  // Three normal M-functions per run, each acknowledged once.
  EXPECT_EQ(test::count_of(plc.log(), "acknowledged after"), 6) << plc.log();
  const std::string stats = test::read_text(env.stats_path());
  for (const char* zero : {"\"lost_replies\": 0,", "\"replies_unmatched\": 0,"}) {
    EXPECT_NE(stats.find(zero), std::string::npos) << stats;
  }
  std::printf("lossy network (%llu %% of the UDP datagrams dropped on receipt):\n%s",
              static_cast<unsigned long long>(loss_percent), stats.c_str());
}

// The HMI's network goes down for 4 s (every datagram in and out of its namespace dropped)
// while it streams a 40,000-record program into a 1,000-record buffer: longer than the 1 s
// participant lease, so both sides forget each other and discover each other again. The
// interpolator runs dry (underrun) and must go on once the link is back: every record executed
// once, in order, ending at the programmed end point, with no refused chunk.
TEST_F(ServiceNetns, AProgramStreamGoesOnAfterANetworkOutage) {
  if (!iptables(2, "-L -n")) GTEST_SKIP() << "iptables is not usable here";
  test::ConfigEdits e = edits();
  e.buffer_size0 = 1000;
  test::ServiceEnv env(e);
  // 40,000 collinear 0.025 mm moves at the rapid-limit feed, then M2: 1 m in about 4 s.
  constexpr int kRecords = 40'000;
  std::string gcode = "F15000\n";
  gcode.reserve(kRecords * 10);
  for (int i = 0; i < kRecords; ++i) gcode += "G1 X0.025\n";
  gcode += "M2\n";
  const std::string program_path = env.path("long.ngc");
  std::ofstream(program_path) << gcode;

  test::Child service, hmi;
  // Cut once the stream runs (the first progress line), well before its end.
  ASSERT_TRUE(start_run(env, program_path, service, hmi));
  cut(2, 4s);
  const int code = hmi.wait(120s);
  const std::string log = hmi.log();
  EXPECT_EQ(code, 0) << log << "\n--- service:\n" << service.log();
  EXPECT_NE(log.find("done: " + std::to_string(kRecords + 1) + " records"), std::string::npos)
      << log;
  expect_run_ended_at(log, {1000.0});
  // The outage was one: the HMI heard nothing for 3 s and then heard the service again.
  EXPECT_NE(log.find("no state from tgm-service for 3 s"), std::string::npos) << log;
  EXPECT_NE(log.find("tgm-service is back"), std::string::npos) << log;
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"segments\": " + std::to_string(kRecords + 1) + ","), std::string::npos)
      << stats;
  EXPECT_NE(stats.find("\"refused_chunks\": 0,"), std::string::npos) << stats;
  std::printf("%s\n%s", log.c_str(), stats.c_str());
}

// The PLC's network goes down for 4 s right when the interpolator starts waiting for M51: the
// acknowledgement, due 0.5 s later, is written into the outage and left unanswered. Once the link
// is back it must arrive (DDS repairs it, or tgm-plc sends it again while the state still shows
// M51), and the manual's example must end where the offline simulation ends, with each of its
// three M-functions acknowledged once.
TEST_F(ServiceNetns, AnAcknowledgementCutOffByAnOutageArrivesAfterIt) {
  if (!iptables(1, "-L -n")) GTEST_SKIP() << "iptables is not usable here";
  test::ServiceEnv env(edits());
  const auto expected = simulated_end(env.config(), kManualExample);

  test::Child service, plc, hmi;
  ASSERT_TRUE(service.start(ns().exec(0, {TGM_SERVICE_BIN, "--config", env.config(),
                                          "--no-realtime", "--stats", env.stats_path()}),
                            env.path("service.log")));
  ASSERT_TRUE(plc.start(ns().exec(1, {TGM_PLC_BIN, "--config", env.config(), "--ack-delay", "0.5"}),
                        env.path("plc.log")));
  ASSERT_TRUE(hmi.start(
      ns().exec(2, {TGM_HMI_BIN, "run", kManualExample, "--config", env.config(), "--quiet"}),
      env.path("hmi.log")));
  plc.wait_for_log("M51 normal: the interpolator waits", 60s, 5ms);
  ASSERT_NE(plc.log().find("M51 normal: the interpolator waits"), std::string::npos)
      << plc.log() << hmi.log();
  cut(1, 4s);
  const int code = hmi.wait(120s);
  const std::string log = hmi.log();
  EXPECT_EQ(code, 0) << log << "\n--- plc:\n" << plc.log() << "\n--- service:\n" << service.log();
  EXPECT_NE(log.find("done: 13 records"), std::string::npos) << log;
  expect_run_ended_at(log, expected);
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  // Three acknowledgements applied by the service: one per M-function, none twice.
  const std::string stats = test::read_text(env.stats_path());
  EXPECT_NE(stats.find("\"handshake_ns\": {\"count\": 3,"), std::string::npos)
      << stats << "\n--- plc:\n"
      << plc.log();
  std::printf("--- plc:\n%s\n%s", plc.log().c_str(), stats.c_str());
}

// The operator presses Ctrl-C on `tgm-hmi run` while the HMI's network is down. The stop must
// reach the service once the link is back, and the interpolator stand. Tried once, the stop
// was never written (the service's request reader had gone with the 1 s participant lease),
// the run exited and the program ran on through everything buffered: 767 mm after the Ctrl-C.
TEST_F(ServiceNetns, ACtrlCDuringAnOutageStopsTheMachineOnceTheLinkIsBack) {
  if (!iptables(2, "-L -n")) GTEST_SKIP() << "iptables is not usable here";
  test::ConfigEdits e = edits();
  test::ServiceEnv env(e);
  // 400 collinear 2.5 mm moves at F3000: 1 m in 20 s, far longer than the test, and all in
  // the buffer, so that the outage does not starve the motion (it runs on without a stop).
  constexpr int kRecords = 400;
  std::string gcode = "G91 F3000\n";
  for (int i = 0; i < kRecords; ++i) gcode += "G1 X2.5\n";
  gcode += "M2\n";
  const std::string program_path = env.path("long.ngc");
  std::ofstream(program_path) << gcode;

  test::Child service, hmi;
  ASSERT_TRUE(start_run(env, program_path, service, hmi));
  ASSERT_TRUE(block(2));
  std::this_thread::sleep_for(1500ms);  // longer than the participant lease
  ASSERT_GT(hmi.pid(), 0);
  ::kill(hmi.pid(), SIGINT);
  hmi.wait_for_log("trying again", 10s, 20ms);
  std::this_thread::sleep_for(3s);
  ASSERT_TRUE(unblock(2));
  const int code = hmi.wait(90s);
  const std::string log = hmi.log();
  EXPECT_EQ(code, 130) << log << "\n--- service:\n" << service.log();
  EXPECT_NE(log.find("trying again for up to 60 s"), std::string::npos) << log;
  EXPECT_NE(log.find("interrupted: normal stop: accepted"), std::string::npos) << log;
  EXPECT_EQ(log.find("NOT stopped"), std::string::npos) << log;
  // The interpolator stands on the program's trajectory (Status 4), not in underrun (8) at
  // the end of what was buffered, nor running.
  std::this_thread::sleep_for(1s);
  test::Child status;
  ASSERT_TRUE(
      status.start(ns().exec(2, {TGM_HMI_BIN, "status", "--json", "--config", env.config()}),
                   env.path("status.log")));
  EXPECT_EQ(status.wait(30s), 0) << status.log();
  EXPECT_NE(status.log().find("\"status\":4,"), std::string::npos) << status.log();
  EXPECT_EQ(service.interrupt(), 0) << service.log();
}

}  // namespace
}  // namespace tgm
