// SystemdNotifier speaks sd_notify(3)'s datagram protocol; WatchdogGate pings only while the
// watched counter moves. The receiving end here is a plain AF_UNIX datagram socket, as
// systemd's is.
#include "tgm/systemd_notify.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstring>
#include <string>
#include <vector>

namespace {

// A bound datagram socket at `address` ('@' first: abstract namespace).
class Receiver {
 public:
  explicit Receiver(const std::string& address) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::memcpy(sa.sun_path, address.data(), address.size());
    socklen_t len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + address.size());
    if (address[0] == '@') {
      sa.sun_path[0] = '\0';
    } else {
      path_ = address;
      ::unlink(address.c_str());
      ++len;
    }
    bound_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<const sockaddr*>(&sa), len) == 0;
  }
  ~Receiver() {
    if (fd_ >= 0) ::close(fd_);
    if (!path_.empty()) ::unlink(path_.c_str());
  }
  bool bound() const { return bound_; }
  // Every datagram waiting now.
  std::vector<std::string> take() {
    std::vector<std::string> out;
    char buf[4096];
    while (true) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n < 0) break;
      out.emplace_back(buf, static_cast<std::size_t>(n));
    }
    return out;
  }

 private:
  int fd_ = -1;
  bool bound_ = false;
  std::string path_;
};

std::string temp_socket_path() {
  return testing::TempDir() + "tgm-notify-" + std::to_string(::getpid());
}

TEST(SystemdNotify, WithoutNotifySocketEverythingIsANoOp) {
  const auto n = tgm::SystemdNotifier::from_values(nullptr, "2000000", nullptr, 1);
  EXPECT_FALSE(n.enabled());
  EXPECT_EQ(n.watchdog_us(), 0);
  EXPECT_TRUE(n.problem().empty());
  EXPECT_FALSE(n.ready("x"));
  EXPECT_FALSE(n.watchdog());
  EXPECT_FALSE(tgm::SystemdNotifier::from_values("", nullptr, nullptr, 1).enabled());
}

TEST(SystemdNotify, SendsTheProtocolsLinesToAPathSocket) {
  const std::string path = temp_socket_path();
  Receiver rx(path);
  ASSERT_TRUE(rx.bound()) << path;
  const auto n = tgm::SystemdNotifier::from_values(path.c_str(), nullptr, nullptr, 1);
  ASSERT_TRUE(n.enabled()) << n.problem();
  EXPECT_TRUE(n.ready("serving 3 interpolators"));
  EXPECT_TRUE(n.status("looking"));
  EXPECT_TRUE(n.watchdog());
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(rx.take(), (std::vector<std::string>{"READY=1\nSTATUS=serving 3 interpolators",
                                                 "STATUS=looking", "WATCHDOG=1", "STOPPING=1"}));
}

TEST(SystemdNotify, SendsToAnAbstractSocket) {
  const std::string name = "@tgm-notify-test-" + std::to_string(::getpid());
  Receiver rx(name);
  ASSERT_TRUE(rx.bound());
  const auto n = tgm::SystemdNotifier::from_values(name.c_str(), nullptr, nullptr, 1);
  ASSERT_TRUE(n.enabled()) << n.problem();
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(rx.take(), std::vector<std::string>{"STOPPING=1"});
}

TEST(SystemdNotify, ASocketNobodyListensOnIsAnErrorThatSaysWhy) {
  const std::string path = temp_socket_path() + "-gone";
  const auto n = tgm::SystemdNotifier::from_values(path.c_str(), nullptr, nullptr, 1);
  ASSERT_TRUE(n.enabled());
  std::string error;
  EXPECT_FALSE(n.send("READY=1", &error));
  EXPECT_NE(error.find("NOTIFY_SOCKET"), std::string::npos) << error;
  EXPECT_NE(error.find("No such file"), std::string::npos) << error;
}

TEST(SystemdNotify, UnusableVariablesAreNamed) {
  auto relative = tgm::SystemdNotifier::from_values("run/notify", nullptr, nullptr, 1);
  EXPECT_FALSE(relative.enabled());
  EXPECT_NE(relative.problem().find("NOTIFY_SOCKET 'run/notify'"), std::string::npos)
      << relative.problem();
  const std::string long_path = "/" + std::string(200, 'x');
  auto too_long = tgm::SystemdNotifier::from_values(long_path.c_str(), nullptr, nullptr, 1);
  EXPECT_FALSE(too_long.enabled());
  EXPECT_NE(too_long.problem().find("longer than a socket address"), std::string::npos);
  for (const char* bad : {"abc", "-5", "0", "12s", " 5", "99999999999999999999999"}) {
    auto n = tgm::SystemdNotifier::from_values("/run/x", bad, nullptr, 1);
    EXPECT_TRUE(n.enabled());
    EXPECT_EQ(n.watchdog_us(), 0) << bad;
    EXPECT_NE(n.problem().find(std::string("WATCHDOG_USEC '") + bad + "'"), std::string::npos)
        << n.problem();
  }
}

TEST(SystemdNotify, TheWatchdogIsOnlyThisProcesssWhenWatchdogPidSaysSo) {
  EXPECT_EQ(tgm::SystemdNotifier::from_values("/run/x", "2000000", nullptr, 42).watchdog_us(),
            2'000'000);
  EXPECT_EQ(tgm::SystemdNotifier::from_values("/run/x", "2000000", "42", 42).watchdog_us(),
            2'000'000);
  // A parent's watchdog passed on in the environment: not this process's to ping.
  const auto other = tgm::SystemdNotifier::from_values("/run/x", "2000000", "41", 42);
  EXPECT_EQ(other.watchdog_us(), 0);
  EXPECT_TRUE(other.problem().empty());
}

TEST(WatchdogGate, PingsEveryHalfIntervalWhileTheCounterMoves) {
  tgm::WatchdogGate gate(1'000'000);
  std::vector<std::int64_t> pings;
  // Checked every 100 ms, the counter moving by 200 each time (cycles of 500 us).
  for (std::int64_t t = 0; t <= 3'000'000; t += 100'000) {
    if (gate.due(static_cast<std::uint64_t>(t / 500), t)) pings.push_back(t);
  }
  EXPECT_EQ(pings, (std::vector<std::int64_t>{0, 500'000, 1'000'000, 1'500'000, 2'000'000,
                                              2'500'000, 3'000'000}));
  EXPECT_EQ(gate.stalled_us(), 0);
}

TEST(WatchdogGate, StopsPingingOnceTheCounterStandsStillForHalfAnInterval) {
  tgm::WatchdogGate gate(1'000'000);
  std::vector<std::int64_t> pings;
  std::uint64_t counter = 0;
  for (std::int64_t t = 0; t <= 4'000'000; t += 100'000) {
    // The counter moves until 1.0 s, stands still until 3.0 s, then moves again.
    if (t <= 1'000'000 || t >= 3'000'000) counter += 200;
    if (gate.due(counter, t)) pings.push_back(t);
    if (t == 1'400'000) {
      EXPECT_EQ(gate.stalled_us(), 400'000);
      EXPECT_FALSE(gate.stalled());
    }
    if (t == 2'900'000) {
      EXPECT_EQ(gate.stalled_us(), 1'900'000);
      EXPECT_TRUE(gate.stalled());
    }
  }
  // 1.0 s is the last move: a ping at 1.0 s, none from 1.5 s (stalled half the interval) until
  // the counter moves again at 3.0 s.
  EXPECT_EQ(pings,
            (std::vector<std::int64_t>{0, 500'000, 1'000'000, 3'000'000, 3'500'000, 4'000'000}));
}

TEST(WatchdogGate, NoIntervalNeverPings) {
  tgm::WatchdogGate gate(0);
  for (std::int64_t t = 0; t < 1'000'000; t += 100'000) {
    EXPECT_FALSE(gate.due(static_cast<std::uint64_t>(t), t));
  }
}

}  // namespace
