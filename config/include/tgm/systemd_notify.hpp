// The systemd notification protocol (sd_notify(3)) without libsystemd: a binary started by a
// unit of Type=notify says when it is ready, what it is doing, that it is stopping, and, under
// WatchdogSec=, that it is still alive. Outside systemd (no $NOTIFY_SOCKET) every call is a no-op.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace tgm {

//! A connection to the service manager's notification socket.
class SystemdNotifier {
 public:
  //! Reads $NOTIFY_SOCKET, $WATCHDOG_USEC and $WATCHDOG_PID. A variable that is set but cannot
  //! be used leaves the notifier disabled (or the watchdog off) and says why in problem().
  static SystemdNotifier from_environment();
  //! The same from given values (tests); `pid` is this process's id.
  static SystemdNotifier from_values(const char* notify_socket, const char* watchdog_usec,
                                     const char* watchdog_pid, std::int64_t pid);

  SystemdNotifier() = default;
  SystemdNotifier(const SystemdNotifier&) = delete;
  SystemdNotifier& operator=(const SystemdNotifier&) = delete;
  SystemdNotifier(SystemdNotifier&& other) noexcept;
  SystemdNotifier& operator=(SystemdNotifier&& other) noexcept;
  ~SystemdNotifier();

  //! True when a notification socket was given and opened.
  bool enabled() const { return fd_ >= 0; }
  //! The watchdog interval systemd expects pings within [us]; 0 when there is no watchdog.
  std::int64_t watchdog_us() const { return watchdog_us_; }
  //! Why a variable that was set is not used; empty when all is well.
  const std::string& problem() const { return problem_; }
  //! Sends one datagram of "KEY=VALUE" lines. False (with `error`) when it could not be sent.
  bool send(std::string_view state, std::string* error = nullptr) const;
  bool ready(std::string_view status) const;
  bool status(std::string_view status) const;
  bool stopping() const;
  bool watchdog() const;

 private:
  int fd_ = -1;
  std::string address_;  // the socket's path; a leading '\0' for the abstract namespace
  std::int64_t watchdog_us_ = 0;
  std::string problem_;
};

//! Decides when to ping the watchdog: only while the watched work makes progress. Fed the
//! work's counter (cycles run) at any rate; pings at most every half interval, and never once
//! the counter has stood still for half an interval, so a stalled cycle thread is restarted
//! by systemd while a slow DDS thread or a busy main thread is not mistaken for one.
class WatchdogGate {
 public:
  explicit WatchdogGate(std::int64_t interval_us) : interval_us_(interval_us) {}
  //! True when a ping is due now (`now_us` on any monotonic clock).
  bool due(std::uint64_t counter, std::int64_t now_us);
  //! The same at the steady clock's now.
  bool due(std::uint64_t counter);
  //! How long the counter has stood still at the last due() [us].
  std::int64_t stalled_us() const { return stalled_us_; }
  //! The counter had stood still for half an interval at the last due(): no more pings.
  bool stalled() const { return interval_us_ > 0 && stalled_us_ >= interval_us_ / 2; }

 private:
  std::int64_t interval_us_;
  std::uint64_t last_counter_ = 0;
  std::int64_t last_change_us_ = -1;
  std::int64_t last_ping_us_ = -1;
  std::int64_t stalled_us_ = 0;
};

}  // namespace tgm
