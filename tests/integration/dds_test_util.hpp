// Shared setup of the DDS integration tests: a config on a domain and with topic names of this
// test process only, so that concurrently running tests (ctest -j) and a running tgm never
// see each other's samples.
#pragma once

#include <fcntl.h>
#include <netinet/in.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "tgm/dds/topics.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm::test {

//! config/fastdds_profiles.xml, or $TGM_TEST_PROFILES (to try QoS variants without editing it).
inline std::string profiles_path() {
  const char* env = std::getenv("TGM_TEST_PROFILES");
  return env != nullptr && *env != '\0' ? env : TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
}

//! A DDS domain in 10..99 that no other test process on this machine holds. Each process
//! takes an exclusive lock on /tmp/tgm-test-domain-D.lock, trying its pid's slot first, and
//! keeps it until it exits (the kernel drops the lock with the process, also on a crash; the
//! descriptor is close-on-exec, so the service and clients a test starts do not hold it).
//! Concurrent tests (ctest -j) used to take 100 + pid % 100 and met on one domain when their
//! pids differed by a multiple of 100: another test's clear then reached this test's service
//! ("chunk ... of a program that is not loaded", CI, session 27). The domains were 100..199
//! until session 70; from domain 102 on their ports (7400 + 250 x domain and up) lie in Linux's
//! default range for outgoing sockets (32768-60999): another program's socket took a test's
//! discovery port and its participants never matched (CI, session 69). 10..99 stay below it and
//! clear of domain 0, which tgm uses by default. $TGM_TEST_DOMAIN (0..232) pins the domain
//! instead, without a lock: for a run beside other work on this machine that keeps to a domain
//! of its own (one test binary at a time then).
inline int test_domain() {
  static const int domain = [] {
    if (const char* pinned = std::getenv("TGM_TEST_DOMAIN"); pinned != nullptr && *pinned != '\0') {
      char* end = nullptr;
      const long d = std::strtol(pinned, &end, 10);
      if (*end == '\0' && d >= 0 && d <= 232) return static_cast<int>(d);
      std::fprintf(stderr, "TGM_TEST_DOMAIN must be a DDS domain 0..232, not '%s'\n", pinned);
      std::exit(2);
    }
    constexpr int kFirst = 10;
    constexpr int kCount = 90;
    const int start = static_cast<int>(::getpid() % kCount);
    for (int k = 0; k < kCount; ++k) {
      const int d = kFirst + (start + k) % kCount;
      const std::string path = "/tmp/tgm-test-domain-" + std::to_string(d) + ".lock";
      const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
      if (fd < 0) continue;
      if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return d;  // fd stays open: the lock is held
      ::close(fd);
    }
    return kFirst + start;  // every slot held: the pid's, as before
  }();
  return domain;
}

inline DdsConfig test_config() {
  DdsConfig c;
  c.domain_id = test_domain();
  c.profiles_file = profiles_path();
  c.participant_prefix = "tgmtest";
  return c;
}

//! The spec of a tgm topic, renamed to "<name>_<pid>" (same profiles).
struct TestTopic {
  std::string name;
  dds::TopicSpec spec;
};
inline TestTopic test_topic(const dds::TopicSpec& spec) {
  TestTopic t{std::string(spec.name) + "_" + std::to_string(::getpid()), spec};
  t.spec.name = t.name;
  return t;
}

//! The UDP port on which simple discovery listens for `domain` (Fast DDS's default port
//! parameters, which config/fastdds_profiles.xml keeps).
inline int discovery_port(int domain) {
  return 7400 + 250 * domain;
}

//! A UDP port on all addresses held as another program's socket holds it (no SO_REUSEADDR),
//! so a DDS participant cannot share it. Released when destroyed or by release().
class HeldUdpPort {
 public:
  explicit HeldUdpPort(int port) : fd_(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0)) {
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_ANY);
    addr.sin_port = htons(static_cast<std::uint16_t>(port));
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
      const int err = errno;
      error_ = "cannot hold UDP port " + std::to_string(port) + ": " + std::strerror(err);
      release();
    }
  }
  ~HeldUdpPort() { release(); }
  HeldUdpPort(const HeldUdpPort&) = delete;
  HeldUdpPort& operator=(const HeldUdpPort&) = delete;
  //! "" while the port is held, else why not.
  const std::string& error() const { return error_; }
  void release() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_;
  std::string error_;
};

}  // namespace tgm::test
