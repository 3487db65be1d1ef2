// What the cycle loop exchanges with the outside world, and the abstract port it talks through
// (STYLE.md "Transport behind an interface"): the DDS adapter implements the port in
// service/src, a mock implements it in tests/service. Every type here is plain data with fixed
// capacity, so handing it between threads never allocates.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "tgm/config.hpp"
#include "tgm/intercode.hpp"
#include "tgm/registers.hpp"
#include "tgm/service/lateness.hpp"

namespace tgm::service {

//! Who sent a request (DESIGN.md section 1).
enum class Role : std::uint8_t { kPlc = 0, kHmi = 1 };

//! What a request asks for; mirrors tgm::msg::RequestKind.
enum class RequestKind : std::uint8_t {
  kCommand = 0,
  kWriteMFunc = 1,
  kWriteRelSpeed = 2,
  kWriteOffset = 3,
  kWriteRatio = 4,
  kWriteNumberAxes = 5,
  kStart = 6,
  kStop = 7,
  kClear = 8,
  kPlcSetupDone = 9,
  kUnknown = 255,
};

//! Outcome of a request; mirrors tgm::msg::ReplyCode.
enum class ReplyCode : std::uint8_t {
  kAccepted = 0,
  kWrongRole = 1,
  kOutOfRange = 2,
  kWrongState = 3,
  kBadRequest = 4,
  kUnsupported = 5,
  kBusy = 6,
};

//! A fixed-capacity, always NUL-terminated text.
template <std::size_t N>
struct FixedText {
  std::array<char, N> chars{};
  void set(std::string_view s) {
    const std::size_t n = s.size() < N - 1 ? s.size() : N - 1;
    // An empty view may have a null data(): memcpy from null is undefined even for 0 bytes
    // (UBSan stopped the service at every accepted reply, whose reason is empty).
    if (n > 0) std::memcpy(chars.data(), s.data(), n);
    chars[n] = '\0';
  }
  std::string_view view() const { return {chars.data(), std::strlen(chars.data())}; }
};

//! A request as the cycle thread sees it.
struct RequestIn {
  std::uint64_t request_id = 0;
  //! The port's own number for the request (never 0), echoed in its ReplyOut.
  std::uint64_t tag = 0;
  Role role = Role::kHmi;
  FixedText<65> client;
  int interpolator = 0;
  RequestKind kind = RequestKind::kUnknown;
  std::int32_t command = 0;
  std::array<std::int32_t, kCommandParameters> command_parameter{};
  int axis = 0;
  double value = 0.0;
  //! WRITE_M_FUNC: the M-function acknowledged (0: whichever M_Func shows).
  std::int32_t m_func_acknowledged = 0;
  //! WRITE_M_FUNC: its m_func_count (0: not checked).
  std::uint32_t m_func_count_acknowledged = 0;
  //! When the receiver thread took the sample (steady clock) [ns]; for the handshake trace.
  std::int64_t taken_ns = 0;
};

//! The answer to one request.
struct ReplyOut {
  std::uint64_t request_id = 0;
  //! RequestIn::tag of the request answered (0: none, a reply of the port's own).
  std::uint64_t tag = 0;
  FixedText<65> client;
  int interpolator = 0;
  ReplyCode code = ReplyCode::kAccepted;
  FixedText<256> reason;
  //! Cycle (Registers::cycle numbering) in which the request was handled.
  std::uint64_t cycle = 0;
};

//! A message for the HMI (M29 text, a refused program chunk, ...).
struct MessageOut {
  enum class Severity : std::uint8_t { kInfo = 0, kWarning = 1, kError = 2 };
  int interpolator = 0;
  Severity severity = Severity::kInfo;
  FixedText<256> text;
  std::int32_t source_line = 0;
  std::uint32_t program_id = 0;  //!< the program it belongs to; 0 = none
  std::uint64_t cycle = 0;       //!< the service cycle it was sent in
};

//! A program chunk, already decoded on the receiving thread. The cycle thread applies it in
//! pieces (`applied` records so far) and gives it back with pop_chunk().
struct ChunkIn {
  int interpolator = 0;
  std::uint32_t program_id = 0;
  std::uint64_t sequence_number = 0;
  bool end_of_program = false;
  //! 0 when decoding worked; otherwise `error` says why the chunk is unusable.
  int decode_status = 0;
  FixedText<200> error;
  //! The records with their side tables (number_axes set from the chunk).
  Program program;
  //! Records of `program` already in the ring buffer (cycle thread only).
  std::size_t applied = 0;
};

//! A client that DDS discovery dropped (its participant lease lapsed: the process died, or the
//! network between it and the service is down) or that left (its process ended), or that came
//! back.
struct PeerNotice {
  enum class Kind : std::uint8_t {
    kPlcLost =
        0,  //!< a tgm-plc (a participant named <prefix>-plc, or that sent requests as the PLC)
    kPlcBack = 1,
    kStreamLost = 2,  //!< the sender of `interpolator`'s program stream
    kStreamBack = 3,
    //! a tgm-plc (a participant named <prefix>-plc) joined while `other_plc` is there: both
    //! acknowledge the M-functions
    kPlcJoined = 4,
  };
  Kind kind = Kind::kPlcLost;
  //! *Lost: the client's process ended (it left the domain), not a lapse of its lease.
  bool ended = false;
  FixedText<65> client;          //!< its client (or participant) name; empty when unknown
  //! kPlcLost: another tgm-plc that is still there (empty when none is known); kPlcJoined:
  //! the one that was there first.
  FixedText<65> other_plc;
  int interpolator = 0;          //!< kStream*: the interpolator its last chunk was for
  std::uint32_t program_id = 0;  //!< kStream*: the program of that chunk
};

//! The event registers of one interpolator after a cycle in which one of them changed (or the
//! program, or the M-function moved to another record): the cycle thread queues every such
//! cycle, so the event topic shows each change, also those the newest-value snapshot merges
//! (two M-functions in successive cycles, two equal continuous ones in a row).
struct EventOut {
  int interpolator = 0;
  //! Events of this interpolator queued so far, 1, 2, ...; a gap is an event the port dropped.
  std::uint64_t counter = 0;
  std::uint32_t program_id = 0;
  EventRegisters reg;
  //! When the cycle thread queued it (steady clock) [ns]; set by the port.
  std::int64_t queued_ns = 0;
};

//! True when the change from `before` to `now` (registers and program of one interpolator in
//! two cycles) is an event the clients must see at once (M-function handshake, status,
//! commands); progress (positions, next_sequence, Act_Part alone) is not.
inline bool event_due(const Registers& now, std::uint32_t program_now, const Registers& before,
                      std::uint32_t program_before) {
  return now.status != before.status || now.m_func != before.m_func ||
         now.m_func_count != before.m_func_count || now.act_m_func != before.act_m_func ||
         now.last_cont_m_func != before.last_cont_m_func || now.run_flag != before.run_flag ||
         now.command != before.command || now.command_status != before.command_status ||
         now.off_trajectory != before.off_trajectory || now.rel_speed != before.rel_speed ||
         now.tool_number != before.tool_number || now.number_axes != before.number_axes ||
         program_now != program_before || (now.m_func != 0 && now.act_part != before.act_part);
}

//! One interpolator's part of a snapshot: its registers and what the service adds.
struct InterpolatorSnapshot {
  Registers reg;
  std::uint32_t program_id = 0;
  std::uint64_t next_sequence = 0;
  std::int32_t buffered_segments = 0;
  std::uint32_t message_counter = 0;
  FixedText<256> message_text;
  //! Letters of the Number_Axes axes ("XYZ").
  FixedText<kMaxAxes + 1> axis_letters;
  //! InterpolatorState.plc_setup: 0 not required, 1 not yet reported, 2 reported.
  std::uint8_t plc_setup = 0;
  //! machine_digest() of the config over the Number_Axes axes (InterpolatorState.machine_digest).
  std::uint64_t machine_digest = 0;
  //! The smoothing in effect (InterpolatorState.spline_points ... iir_axis_mask).
  SmoothingConfig smoothing;
};

//! Everything the publisher needs after one cycle.
struct Snapshot {
  std::uint64_t cycle = 0;
  int count = 0;
  std::array<InterpolatorSnapshot, kMaxInterpolators> ip{};
  LatenessStats lateness;
};

//! The cycle loop's window to the world. Called only from the cycle thread; no call may block,
//! allocate in the steady state, or wait for a DDS thread.
class CyclePort {
 public:
  virtual ~CyclePort() = default;
  //! Next request, oldest first; false when there is none.
  virtual bool next_request(RequestIn& out) = 0;
  //! Oldest program chunk of `interpolator` not yet given back, or null.
  virtual ChunkIn* front_chunk(int interpolator) = 0;
  //! Gives back the chunk front_chunk() returned (fully applied or dropped).
  virtual void pop_chunk(int interpolator) = 0;
  //! Queues a reply; false when the outgoing queue is full (the reply is lost and counted).
  virtual bool reply(const ReplyOut& r) = 0;
  //! Queues a message; false when the outgoing queue is full.
  virtual bool message(const MessageOut& m) = 0;
  //! Queues an event (before the cycle's publish()); false when the queue is full (the event is
  //! dropped; its counter leaves a gap the clients count as lost).
  virtual bool event(const EventOut& e) = 0;
  //! Hands the newest snapshot over (latest value wins).
  virtual void publish(const Snapshot& s) = 0;
  //! Next client that lost or regained its liveliness, oldest first; false when none.
  virtual bool next_peer_notice(PeerNotice& out) {
    (void)out;
    return false;
  }
};

}  // namespace tgm::service
