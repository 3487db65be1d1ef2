// The cycle logic of tgm-service without clocks or DDS: once per cycle it applies the queued
// requests (with a budget), moves program chunks into the ring buffers (in bounded pieces),
// steps every interpolator and hands a snapshot to the port. The real-time loop (rt_loop.hpp)
// calls cycle() at absolute deadlines; tests call it as fast as they like with a mock port.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/limit_checker.hpp"
#include "tgm/service/port.hpp"

namespace tgm::service {

//! Budgets that bound the work of one cycle.
struct EngineOptions {
  //! Requests applied per cycle at most; the rest wait for the next cycle.
  int max_requests_per_cycle = 32;
  //! Program records appended per cycle at most, all interpolators together (a 128-record
  //! chunk may take several cycles when the budget is small). Appending plans each record on
  //! the cycle thread (about 0.2 us a record), so this bounds that work however many
  //! interpolators stream at once; the interpolator served first rotates every cycle.
  std::size_t max_segments_per_cycle = 1024;
  //! Options for every interpolator.
  InterpolatorOptions interpolator;
  //! Runs a limit checker on every interpolator's output (Orig_Position differentiated per
  //! cycle, core/MOTION.md "Limit checker"; `tgm-service --check-limits`). Each excess goes to
  //! the HMI as a warning message naming axis, quantity, size, limit, line and cycle: the first
  //! `max_limit_messages` of each program, then one message that the rest are only counted.
  bool check_limits = false;
  int max_limit_messages = 16;
  //! The part of each limit the checker holds the motion to (`--limit-share`,
  //! LimitChecker::create).
  double limit_share = 1.0;
  //! A start is refused until a PLC has reported its setup of the interpolator
  //! (RequestKind::kPlcSetupDone) since the engine was made: config plc.setup_before_start.
  //! A restarted service stands at 0 where the drives stand elsewhere, and without the PLC's
  //! gear ratios; the PLC sets both, and a program started before it would run from the wrong
  //! point.
  bool require_plc_setup = false;
};

//! What the engine counted (for the log at shutdown and for tests).
struct EngineCounters {
  std::uint64_t requests = 0;
  std::uint64_t refused_requests = 0;
  std::uint64_t chunks = 0;
  std::uint64_t segments = 0;
  std::uint64_t duplicate_chunks = 0;
  std::uint64_t refused_chunks = 0;
  std::uint64_t lost_replies = 0;
  std::uint64_t lost_messages = 0;
  //! Events the port's queue could not take (the publisher fell that far behind).
  std::uint64_t lost_events = 0;
  //! Limit excesses found by the checker (EngineOptions::check_limits), all interpolators.
  std::uint64_t limit_violations = 0;
};

//! Role rule of a request (DESIGN.md section 1), exposed for tests and documentation.
//! Empty when `role` may send it, else the reason.
std::string role_violation(Role role, RequestKind kind, std::int32_t command);

class Engine {
 public:
  static std::optional<Engine> create(const MachineConfig& machine, const EngineOptions& options,
                                      std::string* error = nullptr);

  //! One interpolation cycle. `lateness` goes into the snapshot unchanged.
  void cycle(CyclePort& port, const LatenessStats& lateness);

  //! Shutdown (SIGINT / SIGTERM): call after each cycle() once the service is to stop. The
  //! first call brings every interpolator still in motion to a normal stop on the trajectory
  //! (Command 8); an emergency ramp already under way runs on. Every interpolator that holds
  //! a program not yet ended, moving or standing, gets a warning "tgm-service is stopping: ..."
  //! for its HMIs. True once every interpolator stands with its smoothing settled, so the
  //! last setpoints the drives get are at rest (leaving the cycle at once froze them at full
  //! speed).
  bool wind_down(CyclePort& port);
  //! Interpolators wind_down() stopped (for the log).
  int wound_down() const { return wound_down_; }
  //! Warnings wind_down() sent (the service waits for them to be published).
  int announced() const { return announced_; }

  int count() const { return static_cast<int>(ips_.size()); }
  const Interpolator& interpolator(int i) const { return ips_[static_cast<std::size_t>(i)].ip; }
  const EngineCounters& counters() const { return counters_; }
  std::uint64_t cycles() const { return cycles_; }
  double cycle_time_s() const;

 private:
  static constexpr std::uint64_t kNoProgram = ~std::uint64_t{0};
  struct Slot {
    explicit Slot(Interpolator i) : ip(std::move(i)) {}
    Interpolator ip;
    std::optional<LimitChecker> checker;  // EngineOptions::check_limits
    int limit_messages = 0;               // excesses reported for the current program
    std::uint64_t position_sets = 0;      // Interpolator::position_sets() the checker has seen
    std::uint64_t sets_at_load = 0;       // Interpolator::position_sets() when program_id loaded
    std::uint32_t program_id = 0;
    std::uint64_t next_sequence = 0;
    bool stream_complete = false;  // the chunk that ends program_id's stream is applied
    // Last program id a refusal message was sent for (kNoProgram: none; 0 is an id a bad
    // client may send, whose refusals it used to swallow).
    std::uint64_t refused_program = kNoProgram;
    // next_sequence + 1 where the loaded program's stream last had a gap said (0: none): one
    // warning per place the stream stands at, not one per chunk behind the gap.
    std::uint64_t gap_said_at = 0;
    std::uint32_t message_seen = 0;
    std::uint64_t unexecuted_seen = 0;  // Interpolator::unexecuted_commands() already said
    std::uint32_t message_counter = 0;
    FixedText<256> message_text;
    std::uint64_t events = 0;  // EventOut::counter of the last event queued
    std::string letters;       // the config's axis letters (Number_Axes takes the first ones)
    bool plc_setup_done = false;  // a PLC reported its setup (EngineOptions::require_plc_setup)
    // machine_digest() of the config by Number_Axes (made once: the cycle does not hash).
    std::array<std::uint64_t, kMaxAxes + 1> digests{};
    //! The letters of the Number_Axes axes in use.
    std::string_view active_letters() const {
      return std::string_view(letters).substr(0,
                                              static_cast<std::size_t>(ip.registers().number_axes));
    }
  };
  Engine(std::vector<Slot> ips, const EngineOptions& o) : ips_(std::move(ips)), opt_(o) {}
  //! True while `s` waits for the PLC's setup report (EngineOptions::require_plc_setup): its
  //! starts and programs are refused.
  bool awaits_plc_setup(const Slot& s) const { return opt_.require_plc_setup && !s.plc_setup_done; }
  ReplyOut apply(const RequestIn& r);
  //! Appends what interpolator i's queued chunks allow within `budget`, which it lowers.
  void apply_chunks(CyclePort& port, int i, std::size_t& budget);
  void refuse_chunk(CyclePort& port, int i, const ChunkIn& c, std::string_view why);
  //! Says to the HMIs that a PLC or the sender of a stream is gone (or back).
  void peer_notice(CyclePort& port, const PeerNotice& n);
  //! Sends a message of interpolator i to the HMIs (counted as lost when the port drops it).
  //! `program_id`: the program the message belongs to (0: none).
  void send_message(CyclePort& port, int i, MessageOut::Severity severity, std::string_view text,
                    std::int32_t line, std::uint32_t program_id);
  //! Warns when a Ratio or Offset change stepped an axis's PositionInc (the drive follows a
  //! step unless it is disabled): `before` is the previous cycle's registers.
  void report_output_steps(CyclePort& port, int i, const Registers& before, const Registers& now);
  //! Feeds interpolator i's cycle to its limit checker and reports new excesses.
  void check_limits(CyclePort& port, int i);

  std::vector<Slot> ips_;
  EngineOptions opt_;
  EngineCounters counters_;
  std::uint64_t cycles_ = 0;
  bool winding_down_ = false;  // wind_down() has sent its stops
  int wound_down_ = 0;
  int announced_ = 0;
  Snapshot snapshot_;
};

}  // namespace tgm::service
