#include "tgm/service/rt_loop.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <time.h>

#include <cerrno>
#include <cstring>
#include <thread>

namespace tgm::service {

namespace {

std::int64_t to_ns(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}
timespec to_timespec(std::int64_t ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  t.tv_nsec = static_cast<long>(ns % 1'000'000'000);
  return t;
}
std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return to_ns(t);
}

// Touches `bytes` of stack below the caller so those pages are resident (with mlockall they stay).
[[gnu::noinline]] void prefault_stack(std::size_t bytes) {
  volatile unsigned char buf[256 * 1024];
  for (std::size_t i = 0; i < bytes && i < sizeof buf; i += 4096) buf[i] = 0;
}

// The soft limit `resource` as text ("unlimited", or the number in `unit` of `scale`).
std::string limit_text(int resource, unsigned long long scale, const char* unit) {
  rlimit r{};
  if (getrlimit(resource, &r) != 0) return "unknown";
  if (r.rlim_cur == RLIM_INFINITY) return "unlimited";
  return std::to_string(static_cast<unsigned long long>(r.rlim_cur) / scale) + unit;
}

// What a refused SCHED_FIFO or mlockall needs: the limits by name, and how to raise them. The
// messages said only "Operation not permitted" or "Cannot allocate memory" (session 75).
std::string rtprio_hint() {
  return std::string("RLIMIT_RTPRIO is ") + limit_text(RLIMIT_RTPRIO, 1, "") +
         ": raise it with LimitRTPRIO= in the systemd unit or ulimit -r, or run as root";
}

}  // namespace

std::string sched_fifo_refusal(int priority) {
  int rc = 0;
  std::thread probe([&] {
    sched_param p{};
    p.sched_priority = priority;
    rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
  });
  probe.join();
  if (rc == 0) return {};
  return std::string("SCHED_FIFO priority ") + std::to_string(priority) + " not permitted (" +
         std::strerror(rc) + "; " + rtprio_hint() + ")";
}

std::string make_realtime(const RtOptions& o) {
  std::string log;
  // clock_nanosleep may wake up to the timer slack late (default 50 us for normal threads;
  // SCHED_FIFO threads have none): 1 ns, also for --no-realtime.
  const bool slack = prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL) == 0;
  if (o.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(o.cpu), &set);
    if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set); rc == 0) {
      log = "pinned to CPU " + std::to_string(o.cpu) + ", ";
    } else {
      log = "CPU " + std::to_string(o.cpu) + " refused (" + std::strerror(rc) + "), ";
    }
  }
  log += slack ? "timer slack 1 ns, " : "timer slack unchanged, ";
  if (!o.realtime) return log + "real-time scheduling off (--no-realtime): normal thread";
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    prefault_stack(256 * 1024);
    log += "memory locked";
  } else {
    log += std::string("mlockall not permitted (") + std::strerror(errno) + "; RLIMIT_MEMLOCK is " +
           limit_text(RLIMIT_MEMLOCK, 1024, " KiB") +
           ": LimitMEMLOCK=infinity in the systemd unit or ulimit -l), memory not locked";
  }
  sched_param p{};
  p.sched_priority = o.priority;
  if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); rc == 0) {
    log += ", cycle thread SCHED_FIFO priority " + std::to_string(o.priority);
  } else {
    log += std::string(", SCHED_FIFO not permitted (") + std::strerror(rc) + "; " + rtprio_hint() +
           "): cycle thread runs with normal priority";
  }
  return log;
}

void RtLoop::run(const std::atomic<bool>& stop) {
  std::int64_t deadline = now_ns() + period_ns_;
  while (!stop.load(std::memory_order_relaxed)) {
    const timespec ts = to_timespec(deadline);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const std::int64_t woke = now_ns();
    const std::int64_t late = woke - deadline;
    hist_.record(late);
    stats_.last_ns = late;
    stats_.max_ns = hist_.max_ns();
    ++stats_.cycles;
    if (late >= period_ns_) {
      const std::int64_t skipped = late / period_ns_;
      stats_.missed_cycles += static_cast<std::uint64_t>(skipped);
      deadline += skipped * period_ns_;
      last_miss_ns_.store(late, std::memory_order_relaxed);
      missed_.store(stats_.missed_cycles, std::memory_order_relaxed);
    }
    // The percentile walks the histogram: every 64 cycles is plenty for a published value.
    if ((stats_.cycles & 63u) == 1u) stats_.p999_ns = hist_.quantile_ns(0.999);
    engine_.cycle(port_, stats_);
    if (wind_down_.load(std::memory_order_acquire) && !at_rest_.load(std::memory_order_relaxed) &&
        engine_.wind_down(port_)) {
      at_rest_.store(true, std::memory_order_release);
    }
    heartbeat_.store(stats_.cycles, std::memory_order_relaxed);
    work_.record(now_ns() - woke);
    deadline += period_ns_;
  }
  stats_.p999_ns = hist_.quantile_ns(0.999);
}

}  // namespace tgm::service
