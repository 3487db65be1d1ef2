// libtgm-client: what a PLC or an HMI needs to talk to tgm-service over DDS (DESIGN.md
// section 2). tgm-plc and tgm-hmi are built on it; a third-party HMI or PLC can be too.
//
// The client is polled from one application thread: poll() takes whatever arrived (state,
// replies, messages, optionally setpoints) and keeps the newest state of every interpolator;
// request() sends one request and polls until its reply arrives. The one exception is on_event():
// event samples (the M-function handshake registers, tgm_event) are handed to a callback in
// Fast DDS's receive thread as they arrive, so a PLC can acknowledge an M-function without
// waiting for its own thread to wake (see on_event() for what the callback may do).
// Construction and on_event() throw dds::SetupError; nothing else throws.
//
//   tgm::client::Client plc(config.dds, tgm::client::Role::kPlc);
//   plc.wait_for_state(0, 5s);
//   while (running) {
//     plc.poll(10ms);
//     const auto* s = plc.state(0);
//     if (s && s->m_func() != 0) plc.ack_m_func(0);
//   }
//
// or, acknowledging in the receive thread (the reply is taken later by the polling thread):
//
//   plc.on_event([&](const tgm::client::Event& e) {
//     if (e.sample.m_func() != 0 && is_new(e.sample)) plc.send_ack_m_func(e.sample.interpolator());
//   });
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fastdds/dds/subscriber/DataReaderListener.hpp>

#include "tgm/client/silence_watch.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/intercode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/msg/tgm.h"
#include "tgm/yaml_config.hpp"

namespace tgm::client {

using namespace std::chrono_literals;

//! Who the client is (DESIGN.md section 1); the service checks it on every request.
enum class Role { kPlc, kHmi };

//! The service's answer to a request.
struct Reply {
  bool accepted = false;
  //! msg::REPLY_CODE_*; meaningless when `timed_out`.
  msg::ReplyCode code = msg::REPLY_CODE_BAD_REQUEST;
  std::string reason;
  //! Cycle in which the service handled the request (InterpolatorState.cycle_counter numbering).
  std::uint64_t cycle = 0;
  //! No reply within the timeout.
  bool timed_out = false;
  //! With `timed_out`: the request was written (tgm-service's request reader had matched). It
  //! may still arrive and be executed after the timeout: a lossy network repairs late.
  bool sent = false;
  //! How often the request was written: again, under the same request_id, when its reply did
  //! not come (Client::request; tgm-service executes it once and answers each repeat).
  int sends = 0;
  //! With `timed_out`: how long the reply was waited for.
  std::chrono::milliseconds waited{0};
  //! With `timed_out`: the wait was given up because the caller's cancel flag was set (Ctrl-C),
  //! not because the time ran out. `sent` says whether the request went out.
  bool cancelled = false;
};

//! "accepted", "wrong role", "out of range", ...
std::string_view reply_code_name(msg::ReplyCode c);
//! A one-line description of a reply: "accepted" or "refused (wrong role): reason".
std::string describe(const Reply& r);

//! The name a client puts on its requests and the service on their replies:
//! "<participant>-<pid>-<8 random hex digits>", at most 64 characters (the participant's name is
//! cut first). The random part tells apart clients that share a PID, each PID 1 in a container
//! of its own: named by PID alone, two HMIs took each other's replies.
std::string unique_client_name(std::string_view participant);
//! "empty", "running", "ended", "ready", "emergency ramp", "emergency stopped", "underrun".
std::string_view status_name(std::int32_t status);

//! The config's file for messages, "the built-in config" when it was none.
std::string config_name(const AppConfig& config);
//! Whether the service moves interpolator `ip` by `machine`: its InterpolatorState.machine_digest
//! against tgm::machine_digest() of `machine` over the state's Number_Axes. True when the service
//! does not say (a digest of 0: a service before 0.2.1).
bool same_machine(const msg::InterpolatorState& s, const MachineConfig& machine, int ip);
//! The smoothing the service applies to interpolator s.interpolator() (its config's, or what
//! the PLC set with Command -2 / -1 since); nullopt when the state does not say (a service
//! before 0.2.2: iir_p_e6 0).
std::optional<SmoothingConfig> smoothing_in_effect(const msg::InterpolatorState& s);
//! `own` (a config's smoothing) with what the state says is in effect, for a simulation of what
//! the service will do: the spline and the IIR as the service has them; where one is off, its
//! parameters stay `own`'s (an off spline's jerk reads 0, which a config refuses). `own` alone
//! from a service that does not say.
SmoothingConfig smoothing_for_simulation(const SmoothingConfig& own,
                                         const msg::InterpolatorState& s);
//! smoothing_in_effect() for a person: "Spline 100 points (10.0 ms at 500 us cycles), jerk
//! limit 1000000 mm/s^3; IIR off", the IIR as "IIR p 2, q 1, f 6 ms on X Z" (`letters`: the
//! axes' letters); "not said (tgm-service before 0.2.2)".
std::string describe_smoothing(const msg::InterpolatorState& s, std::string_view letters);

//! Requests as start(), command() and set_rel_speed() send them, for Client::send() (which
//! does not wait for the reply).
msg::Request start_request(int interpolator);
msg::Request command_request(int interpolator, std::int32_t code,
                             std::span<const std::int32_t> params = {});
msg::Request rel_speed_request(int interpolator, double rel_speed);
//! The PLC's register writes (DESIGN section 1): Number_Axes, Ratio[axis] [inc/mm] and
//! Offset[axis] [inc].
msg::Request number_axes_request(int interpolator, int number_axes);
msg::Request ratio_request(int interpolator, int axis, double ratio_inc_per_mm);
msg::Request offset_request(int interpolator, int axis, std::int64_t offset_inc);
//! The PLC's report that it has set the interpolator up (InterpolatorState.plc_setup).
msg::Request plc_setup_done_request(int interpolator);

//! One event sample as the event callback gets it.
struct Event {
  msg::InterpolatorEvent sample;
  //! When Fast DDS called the listener that took it (steady clock): the wake-up of the receive
  //! thread, before the sample was taken and copied.
  std::chrono::steady_clock::time_point received{};
};

//! Callback for event samples; see Client::on_event() for its threading contract.
using EventHandler = std::function<void(const Event&)>;

struct ClientOptions {
  //! Also take the setpoints topic (every cycle; only for plotting or drives).
  bool setpoints = false;
  //! How long start(), stop(), clear(), command(), ack_m_func() and set_rel_speed() wait for
  //! their reply (matching included).
  std::chrono::milliseconds request_timeout = 3s;
  //! A flag that ends the wait of every request made without a cancel flag of its own, as
  //! request()'s `cancel` does (a command-line tool's Ctrl-C flag); null: none.
  const std::atomic<bool>* cancel = nullptr;
};

class Client {
 public:
  Client(const DdsConfig& config, Role role, const ClientOptions& options = {});
  //! Detaches the event callback first: it waits for a running call to return, and no call
  //! starts afterwards.
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  //! Takes every sample that arrived; waits up to `timeout` when nothing has.
  void poll(std::chrono::nanoseconds timeout);
  //! When the last poll() with a timeout returned from its wait (before taking anything).
  std::chrono::steady_clock::time_point last_wake() const { return last_wake_; }
  //! When the last request() returned from the write() of its request.
  std::chrono::steady_clock::time_point last_request_written() const { return last_written_; }
  //! Polls until the state of `interpolator` is known; false on timeout, or within 20 ms of a
  //! `cancel` flag becoming true.
  bool wait_for_state(int interpolator, std::chrono::milliseconds timeout,
                      const std::atomic<bool>* cancel = nullptr);
  //! Polls until `pred(state)` holds for the state of `interpolator`; false on timeout or
  //! cancel, as wait_for_state.
  bool wait_until(int interpolator, const std::function<bool(const msg::InterpolatorState&)>& pred,
                  std::chrono::milliseconds timeout, const std::atomic<bool>* cancel = nullptr);
  //! Newest state of `interpolator`, null when none has arrived. Of the service instance
  //! followed (service_followed()): with two services on one domain (a mistake the services
  //! report, see README) the states of the other are not mixed in.
  const msg::InterpolatorState* state(int interpolator) const;
  //! The tgm-service instance whose states state() shows for `interpolator`: the first one
  //! heard, kept while it publishes. Another instance's states are taken instead once the
  //! followed one has published nothing for kServiceSwitch (a restarted service, or the one of
  //! two that gave way). 0: no state yet.
  std::uint64_t service_followed(int interpolator) const;
  //! Another instance whose states for `interpolator` arrived in the last 3 s while the followed
  //! one published (two services on one domain); 0: none.
  std::uint64_t other_service(int interpolator) const;
  static constexpr std::chrono::milliseconds kServiceSwitch{1000};
  //! State samples received for `interpolator` so far.
  std::uint64_t state_samples(int interpolator) const;
  //! When poll() took the newest state of `interpolator` (of the service followed); the epoch
  //! when none came. poll() waits on the readers, so this is when it arrived.
  std::chrono::steady_clock::time_point state_taken(int interpolator) const;
  //! Messages (M29 texts, errors) received since the last call.
  std::vector<msg::Message> take_messages();

  //! Called for every state / setpoints sample as it is taken (optional).
  std::function<void(const msg::InterpolatorState&)> on_state;
  std::function<void(const msg::Setpoints&)> on_setpoints;

  //! Subscribes to the event topic (tgm_event) and calls `handler` for every event sample, in the
  //! order the service wrote them per interpolator. Call once, after construction; throws
  //! dds::SetupError when the reader cannot be created or a handler is already set.
  //!
  //! Threading contract:
  //! - `handler` runs in a Fast DDS receive thread (a DataReaderListener), concurrently with the
  //!   thread that calls poll() / request(). Calls are serialized: never two at once.
  //! - In `handler`, call only send() / send_ack_m_func() (thread-safe, they write at once and do
  //!   not wait for the reply) and your own synchronized code. Never poll(), request() and its
  //!   shorthands, wait_*(), state(), take_*(): they are not thread-safe, and request() would
  //!   block the receive thread that has to deliver its reply.
  //! - Keep it short and never block: other samples for this process wait behind it. Format and
  //!   write log lines elsewhere (hand them to your polling thread).
  //! - Everything `handler` uses must live until this Client is destroyed (~Client() detaches it).
  //! Events are VOLATILE: those written before the subscription matched are not replayed; the
  //! state (poll(), state()) is the source of truth for a late joiner.
  void on_event(EventHandler handler);
  //! Waits until the event reader of on_event() has matched the service's event writer (events
  //! written before the match never arrive). False on timeout, when on_event() was not called,
  //! or when the `cancel` flag became true (checked every 20 ms).
  bool wait_for_event_match(std::chrono::milliseconds timeout,
                            const std::atomic<bool>* cancel = nullptr);
  //! Event samples handed to the callback so far, and events the service wrote that this
  //! client never got (gaps in InterpolatorEvent.event_counter). Thread-safe.
  std::uint64_t events_received() const { return events_received_.load(std::memory_order_relaxed); }
  std::uint64_t events_lost() const { return events_lost_.load(std::memory_order_relaxed); }
  //! Events the service wrote before this client's first one from it (per interpolator and
  //! service instance: the first event_counter seen, less one). Not lost: written before the
  //! match, which a VOLATILE topic does not replay. Thread-safe.
  std::uint64_t events_before_join() const {
    return events_before_join_.load(std::memory_order_relaxed);
  }

  //! Writes `r` at once (request_id, role and client_name are filled in) without waiting for the
  //! reply; returns its request_id, 0 when it could not be written (no service matched, the
  //! write failed, or kRequestsInFlight requests still wait for their replies). Thread-safe:
  //! callable from the event callback. The polling thread gets the reply with take_reply().
  std::uint64_t send(msg::Request r);
  //! Requests written and not answered yet that send() allows. The request topic's histories
  //! hold 100 samples; a client that wrote faster than the service takes them lost requests
  //! without any answer (Fast DDS drops what a full history cannot keep). Within this window
  //! every request is answered (executed, refused, or busy). Replies that do not come for a
  //! second while the window is full (a service restarted meanwhile) free it again.
  static constexpr int kRequestsInFlight = 64;
  int requests_in_flight() const { return in_flight_.load(std::memory_order_relaxed); }
  //! send() of M_Func = 0 (acknowledge the pending M-function of `interpolator`). `m` names
  //! the M-function acknowledged, as seen in M_Func: the service refuses the write
  //! (REPLY_CODE_WRONG_STATE) when M_Func shows another one by then, so a late note of a
  //! continuous M-function never releases the normal one after it. 0: whichever is shown.
  //! `count` != 0 names it exactly, by the m_func_count seen with it: refused once a later
  //! M-function was handed over, also one with the same number.
  std::uint64_t send_ack_m_func(int interpolator, std::int32_t m = 0, std::uint32_t count = 0);
  //! The reply to a send() if it has arrived (taken by poll()); polling thread only. Replies
  //! nobody takes are dropped after the newest kMaxKeptReplies.
  std::optional<Reply> take_reply(std::uint64_t request_id);
  static constexpr std::size_t kMaxKeptReplies = 1000;

  //! Sends `r` (request_id, role and client_name are filled in) and polls until its reply,
  //! at most `timeout` (ClientOptions::request_timeout when not given). A `cancel` flag that
  //! becomes true ends the wait within one poll (20 ms): the reply is then `timed_out` and
  //! `cancelled`; without one, ClientOptions::cancel is the flag. A request without a reply
  //! after kFirstResend is written again (the same request_id), then after twice the last
  //! interval (at most kLongestResend), until the reply or the timeout: tgm-service executes it
  //! once and answers a repeat with its first reply. A repeat that reaches a service that
  //! replaced (restarted after) the one this client followed at the first write is answered
  //! REPLY_CODE_WRONG_STATE and not executed: the one it replaced may have executed it.
  //! send() never writes a request again.
  Reply request(msg::Request r, std::chrono::milliseconds timeout,
                const std::atomic<bool>* cancel = nullptr);
  Reply request(msg::Request r) { return request(std::move(r), request_timeout_); }
  static constexpr std::chrono::milliseconds kFirstResend{500};
  //! Below the 120 s that tgm-service keeps a client's requests after its last one.
  static constexpr std::chrono::milliseconds kLongestResend{60'000};
  Reply start(int interpolator);
  Reply stop(int interpolator);
  Reply clear(int interpolator);
  //! start / clear waiting at most `timeout` for the reply (a first request on a lossy network
  //! waits for the discovery of the request and reply endpoints as well), or until `cancel`.
  Reply start(int interpolator, std::chrono::milliseconds timeout,
              const std::atomic<bool>* cancel = nullptr);
  Reply clear(int interpolator, std::chrono::milliseconds timeout,
              const std::atomic<bool>* cancel = nullptr);
  Reply stop(int interpolator, std::chrono::milliseconds timeout,
             const std::atomic<bool>* cancel = nullptr);
  //! Command register with Command_Parameter[0..11] (missing parameters are 0).
  Reply command(int interpolator, std::int32_t code, std::span<const std::int32_t> params = {});
  //! M_Func = 0, acknowledging M-function `m` (0: whichever is shown) with m_func_count `count`
  //! (0: not checked); see send_ack_m_func.
  Reply ack_m_func(int interpolator, std::int32_t m = 0, std::uint32_t count = 0);
  Reply set_rel_speed(int interpolator, double rel_speed);

  //! Leaves DDS and joins it again as a new participant (a new GUID), with the same name, the
  //! states, replies and event callback kept. For a link that broke one way: after this process
  //! stood still for longer than the participant lease (SIGSTOP, a stalled PC), the service
  //! dropped it, and when this process did not drop the service in turn, Fast DDS 2.9 never
  //! matched its endpoints again (it holds the service's acknowledgements of the old session).
  //! A new participant is discovered afresh on both sides. Requests in flight are not lost:
  //! request() writes again what has no reply. The new participant is made before the old one
  //! leaves: when it cannot be made (its ports taken meanwhile), the client stays as it was and
  //! the reason is returned; empty when it rejoined.
  std::string rejoin();

  Role role() const { return role_; }
  const std::string& name() const { return name_; }
  dds::Participant& participant() { return *participant_; }
  //! The program stream's writer. Only an HMI client has one (DESIGN.md section 1: the PLC does
  //! not fill the buffer; with DDS Security its permissions do not allow it either): throws
  //! dds::SetupError for a PLC client.
  eprosima::fastdds::dds::DataWriter& program_writer();

 private:
  // Takes event samples in the receive thread and calls the handler (under `mutex`).
  class EventListener final : public eprosima::fastdds::dds::DataReaderListener {
   public:
    EventListener(Client& client, EventHandler handler)
        : client_(client), handler_(std::move(handler)) {}
    void on_data_available(eprosima::fastdds::dds::DataReader* reader) override;
    //! Waits for a running call and makes later calls return at once.
    void detach();

   private:
    Client& client_;
    EventHandler handler_;
    std::mutex mutex_;
    bool detached_ = false;
    Event event_;
    std::array<std::uint64_t, kMaxInterpolators> last_counter_{};
    std::array<std::uint64_t, kMaxInterpolators> last_instance_{};
  };
  void fill(msg::Request& r);

  // Declared before the participant so that it outlives the participant's receive threads.
  std::unique_ptr<EventListener> event_listener_;
  Role role_;
  std::chrono::milliseconds request_timeout_;
  const std::atomic<bool>* default_cancel_ = nullptr;  // ClientOptions::cancel
  // A new participant of this client's role (SetupError when it cannot be made).
  std::unique_ptr<dds::Participant> make_participant() const;
  // The role its participant is named and authenticated as: "plc" or "hmi".
  const char* participant_role() const { return role_ == Role::kPlc ? "plc" : "hmi"; }
  // Takes `made` with its readers and writers (not the event reader).
  void join(std::unique_ptr<dds::Participant> made);
  // Creates the event reader and attaches event_listener_ to it; `caller` names the method in
  // the SetupError.
  void attach_events(const char* caller);
  DdsConfig config_;
  bool setpoints_;
  std::unique_ptr<dds::Participant> participant_;
  std::string name_;
  eprosima::fastdds::dds::DataReader* state_reader_ = nullptr;
  eprosima::fastdds::dds::DataReader* reply_reader_ = nullptr;
  eprosima::fastdds::dds::DataReader* message_reader_ = nullptr;
  eprosima::fastdds::dds::DataReader* setpoint_reader_ = nullptr;
  eprosima::fastdds::dds::DataReader* event_reader_ = nullptr;
  eprosima::fastdds::dds::DataWriter* request_writer_ = nullptr;
  eprosima::fastdds::dds::DataWriter* program_writer_ = nullptr;  // HMI only
  std::chrono::steady_clock::time_point last_wake_{};
  std::chrono::steady_clock::time_point last_written_{};
  std::optional<dds::DataWaiter> waiter_;
  std::vector<std::optional<msg::InterpolatorState>> states_;
  // The instance followed per interpolator (state()), and another one heard meanwhile.
  struct Follow {
    std::uint64_t instance = 0;
    std::chrono::steady_clock::time_point last{};  // poll that last took a state of it
    std::uint64_t other = 0;
    std::chrono::steady_clock::time_point other_at{};
  };
  std::vector<Follow> follow_;
  std::vector<msg::InterpolatorState> batch_;  // the states one poll() took, in order
  std::vector<std::uint64_t> state_samples_;
  std::vector<msg::Message> messages_;
  std::vector<msg::Reply> replies_;
  // The ids of the latest replies taken in (kMaxKeptReplies): a second reply to one request
  // (a repeat's, and the first one released later) is dropped, and frees no second slot.
  std::deque<std::uint64_t> replied_order_;
  std::set<std::uint64_t> replied_;
  std::atomic<std::uint64_t> next_request_id_{1};
  // send() / request() take a slot, poll() frees one per reply to this client.
  std::atomic<int> in_flight_{0};
  std::atomic<std::int64_t> window_progress_ns_{0};  // last reply taken, or the window's first send
  bool take_slot();
  void free_slot();
  std::atomic<std::uint64_t> events_received_{0};
  std::atomic<std::uint64_t> events_lost_{0};
  std::atomic<std::uint64_t> events_before_join_{0};
  msg::InterpolatorState state_scratch_;
  msg::Setpoints setpoints_scratch_;
};

//! Streams a compiled program into an interpolator's buffer (DDS program stream) with flow
//! control: a chunk is written only while the records in flight (written, not yet confirmed by
//! InterpolatorState.next_sequence) fit into the free buffer slots and at most
//! dds::kProgramChunksInFlight chunks are in flight. Call pump() after each poll().
class ProgramSender {
 public:
  //! `program` must outlive the sender. `program_id` must be non-zero and new for the service.
  //! A program that cannot be sent whole (`mapping::program_problem`) is not sent at all:
  //! `error()` says why from the start ("record 12 (line 14): message text longer than 255
  //! characters"), and pump() returns false before writing anything.
  ProgramSender(Client& client, const Program& program, int interpolator, std::uint32_t program_id);
  //! The same for a program held as intercode: records are decoded as they are sent, a window
  //! of them at a time (a run holds about 20 bytes a record instead of 152).
  ProgramSender(Client& client, const PackedProgram& program, int interpolator,
                std::uint32_t program_id);
  //! Writes what the window allows. False (with `error()`) when a chunk cannot be built or written.
  bool pump();
  //! Records written / confirmed (accepted into the ring buffer) so far.
  std::uint64_t written() const { return next_; }
  std::uint64_t confirmed() const { return confirmed_; }
  std::uint64_t total() const { return total_; }
  bool all_confirmed() const { return confirmed_ >= total_; }
  const std::string& error() const { return error_; }
  std::uint32_t program_id() const { return program_id_; }
  //! Writes the chunks from the one the service has taken only in part (or the next one) again,
  //! once the writer has matched: after Client::rejoin(), whose new writer the service has not
  //! heard from. The service drops what it applied already. Only while its buffer is empty
  //! (an underrun): a chunk it holds in part, waiting for room, would make the rewritten one
  //! a gap.
  void rewrite();

 private:
  // The records from `first` on as a Program, `first` at index first - base(): the whole
  // program, or a window of a packed one.
  const Program& records_from(std::uint64_t first);
  std::uint64_t base() const { return window_ ? window_->base() : 0; }

  Client& client_;
  const Program* program_ = nullptr;             // a whole program
  std::optional<PackedProgram::Window> window_;  // or a packed one
  const PackedProgram* packed_ = nullptr;        // (its program, for rewrite())
  int interpolator_;
  std::uint32_t program_id_;
  std::uint64_t total_;
  std::uint64_t next_ = 0;
  std::uint64_t confirmed_ = 0;
  bool end_written_ = false;
  bool matched_ = false;
  std::vector<std::uint64_t> chunk_ends_;  // end index of each chunk in flight
  std::uint64_t taken_end_ = 0;            // end of the last chunk taken whole
  msg::ProgramChunk chunk_;
  std::string error_;
};

//! A fresh non-zero program id (time and process based).
std::uint32_t new_program_id();

}  // namespace tgm::client
