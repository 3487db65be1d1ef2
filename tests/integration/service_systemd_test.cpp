// tgm-service and tgm-plc under systemd: their units pass `systemd-analyze verify`, and the
// binaries speak the notification protocol the units rely on (Type=notify, WatchdogSec=). The
// test plays systemd's part: it binds the datagram socket a unit's NOTIFY_SOCKET names, starts
// the binary with NOTIFY_SOCKET and WATCHDOG_USEC set, and reads what arrives.
#include <gtest/gtest.h>
#include <sys/ptrace.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "process_util.hpp"
#include "service_test_env.hpp"

namespace {

using namespace std::chrono_literals;

// systemd's end of NOTIFY_SOCKET: a datagram socket bound to a path.
class NotifySocket {
 public:
  explicit NotifySocket(std::string path) : path_(std::move(path)) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path_.c_str());
    ::unlink(path_.c_str());
    bound_ = fd_ >= 0 && path_.size() < sizeof sa.sun_path &&
             ::bind(fd_, reinterpret_cast<const sockaddr*>(&sa), sizeof sa) == 0;
  }
  ~NotifySocket() {
    if (fd_ >= 0) ::close(fd_);
    ::unlink(path_.c_str());
  }
  bool bound() const { return bound_; }
  std::string env() const { return "NOTIFY_SOCKET=" + path_; }
  //! Every datagram received so far, in order.
  const std::vector<std::string>& received() {
    char buf[4096];
    ssize_t n = 0;
    while ((n = ::recv(fd_, buf, sizeof buf, 0)) >= 0) {
      all_.emplace_back(buf, static_cast<std::size_t>(n));
    }
    return all_;
  }
  //! Waits until a datagram contains `what`; its index, or -1 after `timeout`.
  int wait_for(const std::string& what, std::chrono::milliseconds timeout, std::size_t from = 0) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (true) {
      const auto& all = received();
      for (std::size_t k = from; k < all.size(); ++k) {
        if (all[k].find(what) != std::string::npos) return static_cast<int>(k);
      }
      if (std::chrono::steady_clock::now() >= until) return -1;
      std::this_thread::sleep_for(10ms);
    }
  }
  //! How many datagrams from index `from` on are exactly `what`.
  int count(const std::string& what, std::size_t from = 0) {
    int n = 0;
    const auto& all = received();
    for (std::size_t k = from; k < all.size(); ++k) n += all[k] == what ? 1 : 0;
    return n;
  }
  std::string text() {
    std::string out;
    for (const auto& d : received()) out += "[" + d + "] ";
    return out;
  }

 private:
  std::string path_;
  int fd_ = -1;
  bool bound_ = false;
  std::vector<std::string> all_;
};

// The id of the thread of process `pid` named `name` (/proc/PID/task/TID/comm); -1 if none.
pid_t thread_named(pid_t pid, const std::string& name) {
  const std::filesystem::path tasks = "/proc/" + std::to_string(pid) + "/task";
  std::error_code ec;
  for (const auto& t : std::filesystem::directory_iterator(tasks, ec)) {
    std::string comm;
    std::getline(std::ifstream(t.path() / "comm"), comm);
    if (comm == name) return static_cast<pid_t>(std::stol(t.path().filename().string()));
  }
  return -1;
}

// Each installed unit, with its ExecStart pointed at the binary of this build, passes
// `systemd-analyze verify` without a word (an unknown key or a bad value is a warning there).
TEST(ServiceSystemd, TheUnitsPassSystemdAnalyzeVerify) {
  const std::string dir = testing::TempDir() + "tgm-units-" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  const tgm::test::ShellRun version =
      tgm::test::run_shell("systemd-analyze --version", dir, "version");
  ASSERT_EQ(version.exit_code, 0) << "systemd-analyze is missing (.ci/deps installs systemd): "
                                  << version.out << version.err;
  const std::string build_bins[] = {TGM_SERVICE_BIN, TGM_PLC_BIN};
  const char* units[] = {"tgm-service", "tgm-plc"};
  for (int k = 0; k < 2; ++k) {
    std::string unit =
        tgm::test::read_text(std::string(TGM_UNIT_DIR) + "/" + units[k] + ".service");
    const std::string installed =
        std::string("ExecStart=") + TGM_INSTALL_BINDIR + "/" + units[k] + " ";
    ASSERT_TRUE(tgm::test::replace_first(unit, installed, "ExecStart=" + build_bins[k] + " "))
        << units[k] << ": its ExecStart is not the installed binary:\n"
        << unit;
    EXPECT_NE(unit.find("Type=notify"), std::string::npos) << unit;
    EXPECT_NE(unit.find("WatchdogSec="), std::string::npos) << unit;
    const std::string path = dir + "/" + units[k] + ".service";
    std::ofstream(path) << unit;
    const tgm::test::ShellRun verify =
        tgm::test::run_shell("systemd-analyze verify --man=no " + path, dir, units[k]);
    EXPECT_EQ(verify.exit_code, 0) << verify.out << verify.err;
    EXPECT_EQ(verify.out + verify.err, "") << units[k] << ":\n" << verify.out << verify.err;
  }
  std::filesystem::remove_all(dir);
}

// `cmake --install --prefix P` to a prefix other than the configured one makes a self-contained
// installation: the units start P/bin's binaries, and a binary there reads P/share/tgm's default
// config (it ran /usr/local's, or the source tree's, and the units named the configured prefix).
TEST(ServiceSystemd, AnInstallationToAnotherPrefixUsesItsOwnFiles) {
  const std::string prefix = testing::TempDir() + "tgm-prefix-" + std::to_string(::getpid());
  std::filesystem::remove_all(prefix);
  const tgm::test::ShellRun install = tgm::test::run_shell(
      std::string(TGM_CMAKE) + " --install " + TGM_BUILD_DIR + " --prefix " + prefix,
      testing::TempDir(), "install");
  ASSERT_EQ(install.exit_code, 0) << install.out << install.err;
  for (const char* unit : {"tgm-service", "tgm-plc"}) {
    const std::string text =
        tgm::test::read_text(prefix + "/lib/systemd/system/" + unit + ".service");
    EXPECT_NE(text.find("ExecStart=" + prefix + "/bin/" + unit + " "), std::string::npos) << text;
  }
  // The installed default config, changed so that its use shows.
  const std::string config = prefix + "/share/tgm/default.yaml";
  std::string yaml = tgm::test::read_text(config);
  ASSERT_TRUE(tgm::test::replace_first(yaml, "cycle_time_us: 500", "cycle_time_us: 1000")) << yaml;
  std::ofstream(config) << yaml;
  std::ofstream(prefix + "/p.ngc") << "G1 X1 F600\nM2\n";
  const tgm::test::ShellRun run = tgm::test::run_shell(
      "env -u TGM_CONFIG " + prefix + "/bin/tgm-hmi simulate " + prefix + "/p.ngc", prefix,
      "simulate");
  EXPECT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("interpolator 0, 1000 us cycle"), std::string::npos) << run.out << run.err;
  std::filesystem::remove_all(prefix);
}

// READY=1 once the cycle runs, with what it serves in STATUS=; watchdog pings while it runs;
// STOPPING=1 last, at the clean stop.
TEST(ServiceSystemd, TheServiceSaysReadyPingsTheWatchdogAndSaysStopping) {
  tgm::test::ServiceEnv env;
  NotifySocket sock(env.path("notify"));
  ASSERT_TRUE(sock.bound());
  ASSERT_TRUE(env.start_service({}, {sock.env(), "WATCHDOG_USEC=2000000"}));
  const int ready = sock.wait_for("READY=1", 20s);
  ASSERT_GE(ready, 0) << sock.text() << env.service.log();
  EXPECT_EQ(sock.received()[static_cast<std::size_t>(ready)],
            "READY=1\nSTATUS=serving 3 interpolators, cycle 500 us, DDS domain " +
                std::to_string(env.domain()));
  EXPECT_NE(sock.received()[0].find("STATUS=looking for another tgm-service"), std::string::npos)
      << sock.text();
  std::this_thread::sleep_for(3s);
  // One every second (half the interval); a busy machine may delay a few.
  EXPECT_GE(sock.count("WATCHDOG=1", static_cast<std::size_t>(ready)), 2) << sock.text();
  EXPECT_EQ(env.service.interrupt(), 0) << env.service.log();
  EXPECT_EQ(sock.received().back(), "STOPPING=1") << sock.text();
}

// The cycle thread alone stands still (the test stops that one thread with ptrace): the main
// thread goes on but pings the watchdog no more, and says why in the log, so systemd restarts
// a service whose machines get no setpoints. Once the cycle runs again, so do the pings.
TEST(ServiceSystemd, AStalledCycleThreadGetsNoWatchdogPings) {
  tgm::test::ServiceEnv env;
  NotifySocket sock(env.path("notify"));
  ASSERT_TRUE(sock.bound());
  ASSERT_TRUE(env.start_service({}, {sock.env(), "WATCHDOG_USEC=1000000"}));
  const int ready = sock.wait_for("READY=1", 20s);
  ASSERT_GE(ready, 0) << sock.text() << env.service.log();
  ASSERT_GE(sock.wait_for("WATCHDOG=1", 5s, static_cast<std::size_t>(ready)), 0) << sock.text();
  const pid_t cycle = thread_named(env.service.pid(), "tgm-cycle");
  ASSERT_GT(cycle, 0) << "no thread named tgm-cycle in tgm-service";
  ASSERT_EQ(::ptrace(PTRACE_SEIZE, cycle, nullptr, nullptr), 0) << std::strerror(errno);
  ASSERT_EQ(::ptrace(PTRACE_INTERRUPT, cycle, nullptr, nullptr), 0) << std::strerror(errno);
  int st = 0;
  ASSERT_EQ(::waitpid(cycle, &st, __WALL), cycle);
  const std::size_t stalled_from = sock.received().size();
  std::this_thread::sleep_for(3s);
  // Running, it would have pinged 6 times; stalled, at most the one due in the first half
  // interval, before the stall shows.
  const int during = sock.count("WATCHDOG=1", stalled_from);
  const std::size_t resumed_from = sock.received().size();
  ASSERT_EQ(::ptrace(PTRACE_DETACH, cycle, nullptr, nullptr), 0) << std::strerror(errno);
  EXPECT_LE(during, 1) << sock.text();
  EXPECT_NE(env.service.log().find("the cycle thread has not run for"), std::string::npos)
      << env.service.log();
  EXPECT_GE(sock.wait_for("WATCHDOG=1", 5s, resumed_from), 0) << sock.text();
  EXPECT_EQ(env.service.interrupt(), 0) << env.service.log();
}

// tgm-plc: READY=1 while it waits for the service, STATUS= when it serves and when the service
// goes silent, watchdog pings from its main loop, STOPPING=1 at the end.
TEST(ServiceSystemd, ThePlcSaysWhatItServes) {
  tgm::test::ServiceEnv env;
  NotifySocket sock(env.path("notify"));
  ASSERT_TRUE(sock.bound());
  tgm::test::Child plc;
  ASSERT_TRUE(plc.start({TGM_PLC_BIN, "--config", env.config()}, env.path("plc.log"),
                        {sock.env(), "WATCHDOG_USEC=1000000"}));
  const std::string domain = std::to_string(env.domain());
  const int ready = sock.wait_for("READY=1", 20s);
  ASSERT_GE(ready, 0) << sock.text() << plc.log();
  EXPECT_EQ(sock.received()[static_cast<std::size_t>(ready)],
            "READY=1\nSTATUS=waiting for tgm-service on DDS domain " + domain);
  ASSERT_TRUE(env.start_service());
  EXPECT_GE(sock.wait_for("STATUS=serving interpolators 0, 1, 2 on DDS domain " + domain, 30s), 0)
      << sock.text() << plc.log();
  EXPECT_EQ(env.service.interrupt(), 0);
  EXPECT_GE(sock.wait_for("STATUS=no state from tgm-service for 3 s: waiting", 15s), 0)
      << sock.text() << plc.log();
  EXPECT_GE(sock.count("WATCHDOG=1"), 2) << sock.text();
  EXPECT_EQ(plc.interrupt(), 0) << plc.log();
  EXPECT_EQ(sock.received().back(), "STOPPING=1") << sock.text();
}

}  // namespace
