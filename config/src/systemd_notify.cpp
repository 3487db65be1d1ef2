#include "tgm/systemd_notify.hpp"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace tgm {

namespace {

// A decimal without sign, spaces or trailing text that fits in int64; false otherwise.
bool parse_positive(const char* text, std::int64_t& out) {
  if (text == nullptr || *text < '0' || *text > '9') return false;
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || v <= 0) return false;
  out = v;
  return true;
}

}  // namespace

SystemdNotifier SystemdNotifier::from_environment() {
  return from_values(std::getenv("NOTIFY_SOCKET"), std::getenv("WATCHDOG_USEC"),
                     std::getenv("WATCHDOG_PID"), static_cast<std::int64_t>(::getpid()));
}

SystemdNotifier SystemdNotifier::from_values(const char* notify_socket, const char* watchdog_usec,
                                             const char* watchdog_pid, std::int64_t pid) {
  SystemdNotifier n;
  if (notify_socket == nullptr || *notify_socket == '\0') return n;
  const std::string text = notify_socket;
  if (text[0] != '/' && text[0] != '@') {
    n.problem_ =
        "NOTIFY_SOCKET '" + text +
        "' is neither an absolute path nor an abstract socket (@name): not notifying systemd";
    return n;
  }
  if (text.size() >= sizeof(sockaddr_un::sun_path)) {
    n.problem_ = "NOTIFY_SOCKET is longer than a socket address (" +
                 std::to_string(sizeof(sockaddr_un::sun_path) - 1) +
                 " bytes): not notifying systemd";
    return n;
  }
  n.address_ = text;
  if (text[0] == '@') n.address_[0] = '\0';
  n.fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (n.fd_ < 0) {
    n.problem_ = std::string("cannot create a socket for NOTIFY_SOCKET: ") + std::strerror(errno);
    return n;
  }
  if (watchdog_usec != nullptr && *watchdog_usec != '\0') {
    std::int64_t us = 0, owner = 0;
    if (!parse_positive(watchdog_usec, us)) {
      n.problem_ = std::string("WATCHDOG_USEC '") + watchdog_usec +
                   "' is not a positive number of microseconds: no watchdog pings";
    } else if (watchdog_pid != nullptr && *watchdog_pid != '\0' &&
               (!parse_positive(watchdog_pid, owner) || owner != pid)) {
      // The watchdog belongs to another process (a parent that passed its environment on).
    } else {
      n.watchdog_us_ = us;
    }
  }
  return n;
}

SystemdNotifier::SystemdNotifier(SystemdNotifier&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      address_(std::move(other.address_)),
      watchdog_us_(other.watchdog_us_),
      problem_(std::move(other.problem_)) {}

SystemdNotifier& SystemdNotifier::operator=(SystemdNotifier&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    address_ = std::move(other.address_);
    watchdog_us_ = other.watchdog_us_;
    problem_ = std::move(other.problem_);
  }
  return *this;
}

SystemdNotifier::~SystemdNotifier() {
  if (fd_ >= 0) ::close(fd_);
}

bool SystemdNotifier::send(std::string_view state, std::string* error) const {
  if (fd_ < 0) return false;
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, address_.data(), address_.size());
  // An abstract address is exactly its bytes; a path ends at its terminating zero.
  const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + address_.size() +
                                          (address_[0] == '\0' ? 0 : 1));
  const ssize_t sent = ::sendto(fd_, state.data(), state.size(), MSG_NOSIGNAL,
                                reinterpret_cast<const sockaddr*>(&sa), len);
  if (sent == static_cast<ssize_t>(state.size())) return true;
  if (error != nullptr) {
    *error = std::string("cannot notify systemd through NOTIFY_SOCKET: ") +
             (sent < 0 ? std::strerror(errno) : "short write");
  }
  return false;
}

bool SystemdNotifier::ready(std::string_view status) const {
  return send("READY=1\nSTATUS=" + std::string(status));
}

bool SystemdNotifier::status(std::string_view status) const {
  return send("STATUS=" + std::string(status));
}

bool SystemdNotifier::stopping() const {
  return send("STOPPING=1");
}

bool SystemdNotifier::watchdog() const {
  return send("WATCHDOG=1");
}

bool WatchdogGate::due(std::uint64_t counter, std::int64_t now_us) {
  if (last_change_us_ < 0 || counter != last_counter_) {
    last_counter_ = counter;
    last_change_us_ = now_us;
  }
  stalled_us_ = now_us - last_change_us_;
  if (interval_us_ <= 0 || stalled()) return false;
  if (last_ping_us_ >= 0 && now_us - last_ping_us_ < interval_us_ / 2) return false;
  last_ping_us_ = now_us;
  return true;
}

bool WatchdogGate::due(std::uint64_t counter) {
  return due(counter, std::chrono::duration_cast<std::chrono::microseconds>(
                          std::chrono::steady_clock::now().time_since_epoch())
                          .count());
}

}  // namespace tgm
