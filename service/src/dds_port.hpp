// The DDS side of tgm-service: implements CyclePort with lock-free queues and a latest-value
// buffer, and owns the two DDS threads (STYLE.md "DDS application shape", DESIGN.md section 3):
// - requests (small: commands, register writes such as the PLC's M_Func = 0) are taken by a light
//   DataReaderListener in Fast DDS's receive thread, converted and queued at once: one thread
//   wake-up less on the M-function handshake than a WaitSet thread (BENCHMARKS.md "Service");
// - the receiver thread waits on the program reader (WaitSet), converts chunks to plain structs
//   and queues them for the cycle thread; it also retries requests when their queue was full;
// - the publisher thread wakes after each cycle, writes replies and messages, then the event
//   sample of every interpolator whose event registers changed (small, first: the PLC reacts to
//   it), then the state (on such a change, at most every `progress_period` for progress-only
//   changes, at least every `state_period`) and the setpoints (every cycle it sees).
// The cycle thread only touches the queues and the latest-value buffer.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>

#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/rtps/common/GuidPrefix_t.hpp>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"
#include "tgm/service/latest_value.hpp"
#include "tgm/service/port.hpp"
#include "tgm/service/spsc_queue.hpp"

namespace tgm::service {

struct DdsPortOptions {
  int interpolators = 3;
  std::chrono::milliseconds state_period{20};
  std::chrono::microseconds progress_period{2000};
  //! Publish setpoints every Nth snapshot the publisher sees (1 = every cycle).
  int setpoint_decimation = 1;
  //! The interpolation cycle [us], published in every state (InterpolatorState.cycle_time_us).
  int cycle_time_us = 500;
  //! Two services that started within each other's look (DdsPort::other_service) both serve.
  //! In its first `yield_window_cycles` cycles a service that sees another one gives way to it
  //! (yielded_to()) when the other has run a fifth of the window longer or, closer in age, has
  //! the lower instance: of two that see each other one gives way. 0: never (tgm-service
  //! --service-check-ms 0).
  std::uint64_t yield_window_cycles = 0;
  //! M-function handshakes whose time stamps are kept for handshakes() (--stats,
  //! --handshake-trace); 0 keeps none. Kept without either, a week's run held 80 bytes a
  //! handshake up to a million of them (session 74's soak: +55 MB after 120,000).
  std::size_t handshake_samples = 0;
};

//! Publisher-side stamps of one event write that showed a new M_Func (and of the state write
//! after it), steady clock [ns]: hand-off of the cycle's event that first shows the M-function,
//! publisher wake-up, event write() begin / end, state write() begin / end. The receiver sees
//! act_part and the stamps up to event_write_begin_ns (published by an atomic); the rest is
//! joined in after stop(). A stamp is 0 when that step did not happen.
struct MWritten {
  int interpolator = 0;
  std::int32_t act_part = 0;
  std::int64_t handoff_ns = 0;
  std::int64_t publisher_woke_ns = 0;
  std::int64_t event_write_begin_ns = 0;
  std::int64_t event_write_end_ns = 0;
  std::int64_t state_write_begin_ns = 0;
  std::int64_t state_write_end_ns = 0;
};

//! M-function handshake measurement: from just before the write() of the event sample that shows
//! a new M_Func until the acknowledging request is taken (request listener) [ns] (round_trip_ns),
//! with the publisher's stamps of that write, the ack taken and the ack applied by a cycle
//! (steady clock, ns; 0 when that step did not happen, e.g. no cycle applied the ack before the
//! stop).
struct HandshakeSample {
  MWritten written;
  std::int64_t round_trip_ns = 0;
  std::int64_t taken_ns = 0;
  std::int64_t applied_ns = 0;
};

//! A futex-backed doorbell: ring() never blocks; wait() sleeps until rung or timeout.
class Doorbell {
 public:
  void ring();
  void wait(std::uint32_t seen, std::chrono::nanoseconds timeout);
  std::uint32_t value() const { return word_.load(std::memory_order_acquire); }

 private:
  std::atomic<std::uint32_t> word_{0};
};

class DdsPort final : public CyclePort {
 public:
  DdsPort(const DdsConfig& config, const DdsPortOptions& options);
  ~DdsPort() override;

  //! Starts the receiver and publisher threads.
  void start();
  //! Stops and joins them (idempotent). `stage`, when given, is told what it is doing at each
  //! point where it can wait (for a watchdog that reports a slow stop).
  void stop(std::atomic<const char*>* stage = nullptr);

  bool next_request(RequestIn& out) override;
  ChunkIn* front_chunk(int interpolator) override;
  void pop_chunk(int interpolator) override;
  bool reply(const ReplyOut& r) override;
  bool message(const MessageOut& m) override;
  bool event(const EventOut& e) override;
  void publish(const Snapshot& s) override;
  bool next_peer_notice(PeerNotice& out) override;

  //! Valid after stop(); applied_ns filled in from the cycle thread's stamps.
  const std::vector<HandshakeSample>& handshakes();
  std::uint64_t states_published() const { return states_published_; }
  std::uint64_t events_published() const { return events_published_; }
  std::uint64_t setpoints_published() const { return setpoints_published_; }
  //! Setpoints due that the queue to the publisher had no room for (0 unless the publisher
  //! stalled for about 2 s).
  std::uint64_t setpoints_lost() const { return setpoints_lost_.load(std::memory_order_relaxed); }
  //! Requests answered REPLY_CODE_BUSY because the request queue was full (valid after stop()).
  std::uint64_t busy_requests() const { return busy_requests_; }
  //! Replies held back until the reply writer had matched the client's reply reader, and those
  //! of them written after kReplyMatchWait without that match (valid after stop()).
  std::uint64_t replies_held() const { return replies_held_; }
  std::uint64_t replies_unmatched() const { return replies_unmatched_; }
  //! Requests that came again (the same client, request_id and content: a client that heard
  //! no reply sends its request again) and were answered with the first reply, or left to it
  //! when that was not written yet, instead of being executed twice (valid after stop()).
  std::uint64_t requests_repeated() const { return requests_repeated_; }
  //! Repeats of requests first sent to another service instance (the one this service
  //! replaced, or another service on the domain) that this one had not seen: answered
  //! REPLY_CODE_WRONG_STATE, not executed (valid after stop()).
  std::uint64_t stale_repeats() const { return stale_repeats_; }
  //! Replies whose write() failed (valid after stop()).
  std::uint64_t replies_not_written() const { return replies_not_written_; }
  //! The reply key of a request to an interpolator the service does not host: one instance for
  //! all of them (each new key is a writer instance for good, and at Fast DDS's default of 10
  //! every later reply, to every client, failed while its request still executed).
  static constexpr std::uint16_t kForeignInterpolatorKey = 0xFFFF;
  //! How long a reply waits for the reply writer to match its client's reply reader. On a
  //! network that loses packets that match can take seconds (a lost discovery sample is
  //! repaired at the builtin writers' heartbeat): with 2 s, one in a few fresh `tgm-hmi
  //! command` processes on a 20 % lossy link never got its reply (session 50). Held replies
  //! are bounded (1024); a client that is gone only keeps its replies this long.
  static constexpr std::chrono::seconds kReplyMatchWait{30};
  const std::string& participant_name() const { return participant_.name(); }
  //! Drawn at construction, never 0: InterpolatorState / InterpolatorEvent.service_instance.
  std::uint64_t service_instance() const { return service_instance_; }
  //! Before start(), while nothing of this service is published: waits up to `wait` for the
  //! state of another tgm-service on the domain (a tgm_state sample of another instance; a
  //! live service publishes one every state period, a dead one nothing). Returns its instance,
  //! 0 when none came.
  //! After start(), another instance seen on tgm_state (two services started within each
  //! other's wait) is said by the publisher thread on standard error and as an error message to
  //! the HMIs, once per instance.
  std::uint64_t other_service(std::chrono::milliseconds wait);
  //! The instance this service gave way to (DdsPortOptions::yield_window_cycles), 0 = none: the
  //! caller stops the service. Any thread.
  std::uint64_t yielded_to() const { return yielded_to_.load(std::memory_order_acquire); }

 private:
  void receive_loop();
  void publish_loop();
  //! Takes every request sample: into the queue, or answered busy when it is full (any thread;
  //! never blocks: see .cpp).
  void take_requests();
  void take_requests_locked();

  void take_chunks();
  //! Takes every tgm_state sample (the watch listener, any thread); another instance's is
  //! kept in other_latest_.
  void take_states();
  //! Writes the replies the cycle thread handed over, each once its client's reply reader is
  //! matched (publisher thread; see .cpp).
  void publish_replies();
  void publish_event(const EventOut& ev);
  void publish_state(int i, const InterpolatorSnapshot& s, const Snapshot& all);

  // A listener that calls `take` of the port when its reader has data.
  template <void (DdsPort::*take)()>
  class TakeListener final : public eprosima::fastdds::dds::DataReaderListener {
   public:
    explicit TakeListener(DdsPort& port) : port_(port) {}
    void on_data_available(eprosima::fastdds::dds::DataReader*) override { (port_.*take)(); }

   private:
    DdsPort& port_;
  };
  using GuidPrefix = eprosima::fastrtps::rtps::GuidPrefix_t;
  // The clients' participants as discovery sees them: one whose lease lapsed (the process
  // died, or the network to it is down: DROPPED) or that left (its process ended: REMOVED),
  // and one that is back. A PLC (named <prefix>-plc, or that sent requests as the PLC) or the
  // sender of a program stream becomes a PeerNotice for the cycle thread, and a log line.
  // `announced`: the client name in its USER_DATA (dds::participant_client_name; empty if none),
  // the peer's name from discovery on, as its requests will carry it.
  void participant_changed(const GuidPrefix& participant, std::string_view name,
                           std::string_view announced, bool gone, bool dropped);
  class PeerWatch final : public eprosima::fastdds::dds::DomainParticipantListener {
   public:
    explicit PeerWatch(DdsPort& port) : port_(port) {}
    void on_participant_discovery(
        eprosima::fastdds::dds::DomainParticipant*,
        eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override;

   private:
    DdsPort& port_;
  };
  // Declared before the participant so they outlive the participant's receive threads.
  TakeListener<&DdsPort::take_requests> request_listener_{*this};
  PeerWatch peer_watch_{*this};
  // tgm_state as read back: every sample is taken as it comes (this service's own are delivered
  // too, within the process); a deeper look than the reader's KEEP_LAST 1 per interpolator,
  // where this service's next write would hide another's sample.
  TakeListener<&DdsPort::take_states> state_watch_{*this};
  // Counts the reply readers the reply writer matched, per participant (Fast DDS's threads).
  class ReplyMatchListener final : public eprosima::fastdds::dds::DataWriterListener {
   public:
    explicit ReplyMatchListener(DdsPort& port) : port_(port) {}
    void on_publication_matched(eprosima::fastdds::dds::DataWriter*,
                                const eprosima::fastdds::dds::PublicationMatchedStatus& s) override;

   private:
    DdsPort& port_;
  };
  ReplyMatchListener reply_match_listener_{*this};
  // Under reply_match_mutex_ (request taking, the reply writer's listener, the publisher): the
  // matched reply readers per participant, and the participant each client's requests came
  // from (by client name; an entry goes when its participant's last reply reader unmatches).
  // Before the participant: the listener runs inside the reply writer's creation when the
  // participant already knows reply readers (a crash at start while they came after it).
  std::mutex reply_match_mutex_;
  std::map<GuidPrefix, int> reply_readers_;
  std::map<std::string, GuidPrefix, std::less<>> client_participants_;
  // Also under reply_match_mutex_: each client's latest requests (by client name, at most
  // kRecentRequests each), with the participant they came from and, once the publisher had it,
  // their reply. A request that comes again (same name, participant, id and content) is
  // answered from here, at once and past the hold of publish_replies: its client heard
  // nothing, so the first reply was lost or is held, as when the match listener's status merged
  // two readers' matches (the count of one participant then never rose) and the reply waited
  // out kReplyMatchWait. A client's log is kept kRecentFor after its last request, whatever
  // its participant's matches say (a lossy link's participant that was dropped and found again
  // still resends); kRecentClients bounds the whole, the longest unheard going first.
  struct RecentRequest {
    std::uint64_t id = 0;
    std::uint64_t digest = 0;
    std::uint64_t tag = 0;
    GuidPrefix participant;
    std::optional<msg::Reply> reply;
  };
  struct RecentLog {
    std::deque<RecentRequest> requests;
    std::chrono::steady_clock::time_point last{};
  };
  static constexpr std::size_t kRecentRequests = 64;
  static constexpr std::size_t kRecentClients = 256;
  static constexpr std::chrono::seconds kRecentFor{120};
  void log_request_locked(std::string_view client, RecentRequest q);
  //! The reply sample of `r` (every reply the port writes is made here).
  void fill_reply(msg::Reply& out, const ReplyOut& r) const;
  std::map<std::string, RecentLog, std::less<>> recent_requests_;
  std::vector<msg::Reply> repeat_replies_;  // at most kMaxRepeatReplies
  static constexpr std::size_t kMaxRepeatReplies = 1024;
  std::atomic<bool> repeats_pending_{false};
  std::uint64_t requests_repeated_ = 0;
  std::uint64_t next_tag_ = 0;  // take_requests_locked()
  // Under peers_mutex_ (never held across a DDS call): who each client participant is, from its
  // requests; the participant that sent each interpolator's last program chunk, and its
  // program; the participants whose loss was said (so that a flapping link says it once).
  struct Peer {
    std::string name;
    bool plc = false;
  };
  struct StreamFrom {
    GuidPrefix participant;
    std::uint32_t program_id = 0;
    bool known = false;
  };
  std::mutex peers_mutex_;
  std::map<GuidPrefix, Peer> peers_;
  std::vector<StreamFrom> stream_from_;
  std::set<GuidPrefix> lost_;
  SpscQueue<PeerNotice> peer_notices_{64};  // pushed under peers_mutex_
  // A tgm-plc other than `participant` that is there (not lost), or null; under peers_mutex_.
  const Peer* live_plc_other_than(const GuidPrefix& participant) const;

  DdsPortOptions opt_;
  std::uint64_t service_instance_ = 0;
  dds::Participant participant_;
  eprosima::fastdds::dds::DataWriter& state_writer_;
  eprosima::fastdds::dds::DataWriter& event_writer_;
  eprosima::fastdds::dds::DataWriter& setpoint_writer_;
  eprosima::fastdds::dds::DataWriter& reply_writer_;
  eprosima::fastdds::dds::DataWriter& message_writer_;
  // Where requests come from: tgm_request, whose samples name their role, or with DDS Security
  // one topic per role, which only that role's permissions let write (`role` set: the request's
  // role is the topic's, whatever the sample says).
  struct RequestSource {
    eprosima::fastdds::dds::DataReader* reader = nullptr;
    std::optional<Role> role;
  };
  std::vector<RequestSource> request_sources_;
  eprosima::fastdds::dds::DataReader& program_reader_;
  // tgm_state as another service publishes it (this service's own samples are skipped).
  eprosima::fastdds::dds::DataReader& state_reader_;
  dds::DataWaiter waiter_;

  // cycle <- receiver
  SpscQueue<RequestIn> requests_{256};
  std::vector<std::unique_ptr<SpscQueue<ChunkIn*>>> chunks_;
  // cycle -> receiver: chunk objects to reuse
  SpscQueue<ChunkIn*> free_chunks_;
  std::vector<std::unique_ptr<ChunkIn>> chunk_pool_;
  // cycle -> publisher
  // 32 cycles of the engine's largest request batch: a publisher woken late (the VM stalls
  // threads for milliseconds) must not make the cycle thread drop answers.
  SpscQueue<ReplyOut> replies_{1024};
  SpscQueue<MessageOut> messages_{256};
  // request taking (under request_mutex_) -> publisher: the answers given there, not executed
  // (REPLY_CODE_BUSY, and the stale repeats' REPLY_CODE_WRONG_STATE)
  SpscQueue<ReplyOut> busy_replies_{256};
  // Every cycle with an event-register change, of all interpolators: 4 s of the busiest
  // program seen (a change in every other cycle) at a 1 ms cycle.
  SpscQueue<EventOut> events_{2048};
  LatestValue<Snapshot> latest_;
  Doorbell doorbell_;

  // request taking (listener or receiver thread), under request_mutex_: the producer side of
  // requests_ and the handshake records
  std::mutex request_mutex_;
  std::atomic<bool> requests_pending_{false};
  std::vector<HandshakeSample> handshakes_;
  msg::Request request_sample_;
  std::uint64_t busy_requests_ = 0;
  std::uint64_t stale_repeats_ = 0;
  // publisher thread only: replies waiting for their client's reply reader, in order
  struct HeldReply {
    msg::Reply reply;
    GuidPrefix participant;
    std::chrono::steady_clock::time_point until;
  };
  std::deque<HeldReply> held_replies_;
  std::vector<msg::Reply> replies_to_write_;
  std::uint64_t replies_held_ = 0;
  std::uint64_t replies_unmatched_ = 0;
  std::uint64_t replies_not_written_ = 0;
  //! The key a reply to a request for `interpolator` is written under.
  std::uint16_t reply_key(std::int64_t interpolator) const {
    return interpolator >= 0 && interpolator < opt_.interpolators
               ? static_cast<std::uint16_t>(interpolator)
               : kForeignInterpolatorKey;
  }
  // receiver thread only
  std::vector<std::deque<ChunkIn*>> backlog_;
  ChunkIn* spare_ = nullptr;
  // Chunks for an interpolator this service does not host: counted, said at most every 10 s.
  std::uint64_t foreign_chunks_ = 0;
  std::chrono::steady_clock::time_point foreign_note_at_{};
  tgm::msg::ProgramChunk chunk_sample_;
  // publisher -> receiver: when the event with a new M_Func was written [steady ns], 0 = none;
  // the other stamps of that write are in m_written_ (guarded by the atomic: written before the
  // release store, read after the acquire exchange).
  std::vector<std::unique_ptr<std::atomic<std::int64_t>>> m_written_ns_;
  std::vector<MWritten> m_written_;
  // cycle thread only: (taken_ns, applied_ns) of M_Func writes, preallocated (no allocation in
  // the cycle; stamps beyond the capacity are dropped).
  std::vector<std::pair<std::int64_t, std::int64_t>> m_applied_;
  std::int64_t publisher_woke_ns_ = 0;  // publisher thread only

  // publisher thread only
  struct Published {
    bool any = false;
    Registers reg;
    std::uint32_t program_id = 0;
    std::uint64_t next_sequence = 0;
    std::uint32_t message_counter = 0;
    std::uint8_t plc_setup = 0;
    std::chrono::steady_clock::time_point at{};
  };
  std::vector<Published> published_;
  // Setpoints, queued by the cycle thread (publish()) for every cycle due and written by the
  // publisher, all of them in order: it used to write only the newest snapshot it saw, so a
  // publisher woken late (normal priority under load) left a quarter of the moving cycles
  // without a setpoint, gaps of up to 40 cycles, and nothing counted them (session 75).
  struct SetpointOut {
    std::uint16_t interpolator = 0;
    std::uint64_t cycle = 0;
    std::array<double, kMaxAxes> position{};
    std::array<std::int64_t, kMaxAxes> position_inc{};
  };
  // Cycle thread only: what it queued last per interpolator (every cycle in which Position or
  // PositionInc changed is queued, a standing position with the state period).
  struct QueuedSetpoint {
    bool any = false;
    SetpointOut last;
  };
  std::vector<QueuedSetpoint> queued_setpoints_;
  std::uint64_t standing_setpoint_cycles_ = 1;  // the state period in cycles
  // 2 s of three interpolators at a 250 us cycle.
  SpscQueue<SetpointOut> setpoints_{24576};
  std::atomic<std::uint64_t> setpoints_lost_{0};  // a full queue: counted, never silent
  // m_func_count of the last event written per interpolator: a new value with M_Func set is a
  // new M-function (for the handshake records).
  std::vector<std::uint32_t> last_m_count_;
  // Every new-M_Func event write with the stamps of the state write after it (preallocated;
  // joined into handshakes_ after stop()). m_pending_[i]: index of the record of interpolator i
  // whose state write is still to come, -1 = none.
  std::vector<MWritten> m_published_;
  std::vector<std::ptrdiff_t> m_pending_;
  tgm::msg::InterpolatorEvent event_sample_;
  tgm::msg::InterpolatorState state_sample_;
  tgm::msg::Setpoints setpoint_sample_;
  std::uint64_t states_published_ = 0;
  std::uint64_t events_published_ = 0;
  std::uint64_t setpoints_published_ = 0;
  // take_states (under state_watch_mutex_), then read by other_service and the publisher
  std::mutex state_watch_mutex_;
  tgm::msg::InterpolatorState other_state_sample_;
  std::atomic<std::uint64_t> other_latest_{0};
  std::atomic<std::uint64_t> other_cycles_{0};  // cycle_counter of other_latest_'s last sample
  std::uint64_t other_reported_ = 0;  // publisher thread: the last instance said
  std::atomic<std::uint64_t> yielded_to_{0};

  std::atomic<bool> stopping_{false};
  std::thread receiver_;
  std::thread publisher_;
};

}  // namespace tgm::service
