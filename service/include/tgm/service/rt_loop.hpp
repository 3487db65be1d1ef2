// The real-time cycle loop: absolute deadlines on CLOCK_MONOTONIC (clock_nanosleep with
// TIMER_ABSTIME), optional SCHED_FIFO and mlockall when permitted, lateness measured per cycle.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "tgm/service/engine.hpp"
#include "tgm/service/lateness.hpp"
#include "tgm/service/port.hpp"

namespace tgm::service {

struct RtOptions {
  //! Try SCHED_FIFO at `priority` and mlockall; without permission the loop runs as a normal
  //! thread (one log line says so).
  bool realtime = true;
  int priority = 80;
  //! Pin the cycle thread to this CPU (-1: not pinned).
  int cpu = -1;
};

//! Tries mlockall (then touches the stack so the loop takes no page fault), SCHED_FIFO, the
//! CPU affinity and a 1 ns timer slack for the calling thread; returns a log line saying what
//! worked.
std::string make_realtime(const RtOptions& o);

//! Why SCHED_FIFO at `priority` is refused to this process, with the limit to raise; empty when
//! it is permitted (tried on a thread of its own, which then ends).
std::string sched_fifo_refusal(int priority);

//! Runs `engine` against `port` every `period_ns` until `stop` becomes true. Call from the
//! thread that is to be the cycle thread. A cycle that starts a whole period or more late counts
//! the periods it missed as missed cycles; their deadlines are skipped (no catch-up burst).
class RtLoop {
 public:
  RtLoop(Engine& engine, CyclePort& port, std::int64_t period_ns)
      : engine_(engine), port_(port), period_ns_(period_ns) {}
  void run(const std::atomic<bool>& stop);
  //! Asks the running loop to bring the motion to rest (Engine::wind_down) before `stop`; any
  //! thread may call it. at_rest() says when every interpolator stands.
  void wind_down() { wind_down_.store(true, std::memory_order_release); }
  bool at_rest() const { return at_rest_.load(std::memory_order_acquire); }
  //! Valid after run() returned.
  const LatenessHistogram& histogram() const { return hist_; }
  //! Time the engine's cycle() took (the work of a cycle, without the wake-up) [ns].
  const LatenessHistogram& work_histogram() const { return work_; }
  const LatenessStats& stats() const { return stats_; }
  //! Cycles run so far; any thread may read it while run() runs (the systemd watchdog does).
  std::uint64_t heartbeat() const { return heartbeat_.load(std::memory_order_relaxed); }
  //! Deadlines missed so far (cycles skipped), and the latest start lateness of a cycle that
  //! missed one [ns]; any thread may read them while run() runs (the main thread reports them).
  std::uint64_t missed() const { return missed_.load(std::memory_order_relaxed); }
  std::int64_t last_miss_ns() const { return last_miss_ns_.load(std::memory_order_relaxed); }

 private:
  Engine& engine_;
  CyclePort& port_;
  std::int64_t period_ns_;
  LatenessHistogram hist_;
  LatenessHistogram work_;
  LatenessStats stats_;
  std::atomic<std::uint64_t> heartbeat_{0};
  std::atomic<std::uint64_t> missed_{0};
  std::atomic<std::int64_t> last_miss_ns_{0};
  std::atomic<bool> wind_down_{false};
  std::atomic<bool> at_rest_{false};
};

}  // namespace tgm::service
