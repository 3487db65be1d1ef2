// libtgm-client: what a PLC or an HMI needs to talk to tgm-service over DDS (DESIGN.md
// section 2). tgm-plc and tgm-hmi are built on it; a third-party HMI or PLC can be too.
//
// The client is single-threaded and polled: poll() takes whatever arrived (state, replies,
// messages, optionally setpoints) and keeps the newest state of every interpolator; request()
// sends one request and polls until its reply arrives. Construction throws dds::SetupError;
// nothing else throws.
//
//   tgm::client::Client plc(config.dds, tgm::client::Role::kPlc);
//   plc.wait_for_state(0, 5s);
//   while (running) {
//     plc.poll(10ms);
//     const auto* s = plc.state(0);
//     if (s && s->m_func() != 0) plc.ack_m_func(0);
//   }
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/dds/participant.hpp"
#include "tgm/intercode.hpp"
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
  //! No reply within the timeout (no service, or it is overloaded).
  bool timed_out = false;
};

//! "accepted", "wrong role", "out of range", ...
std::string_view reply_code_name(msg::ReplyCode c);
//! A one-line description of a reply: "accepted" or "refused (wrong role): reason".
std::string describe(const Reply& r);
//! "empty", "running", "ended", "ready", "emergency ramp", "emergency stopped", "underrun".
std::string_view status_name(std::int32_t status);

struct ClientOptions {
  //! Also take the setpoints topic (every cycle; only for plotting or drives).
  bool setpoints = false;
};

class Client {
 public:
  Client(const DdsConfig& config, Role role, const ClientOptions& options = {});
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  //! Takes every sample that arrived; waits up to `timeout` when nothing has.
  void poll(std::chrono::nanoseconds timeout);
  //! When the last poll() with a timeout returned from its wait (before taking anything).
  std::chrono::steady_clock::time_point last_wake() const { return last_wake_; }
  //! When the last request() returned from the write() of its request.
  std::chrono::steady_clock::time_point last_request_written() const { return last_written_; }
  //! Polls until the state of `interpolator` is known; false on timeout.
  bool wait_for_state(int interpolator, std::chrono::milliseconds timeout);
  //! Polls until `pred(state)` holds for the state of `interpolator`; false on timeout.
  bool wait_until(int interpolator, const std::function<bool(const msg::InterpolatorState&)>& pred,
                  std::chrono::milliseconds timeout);
  //! Newest state of `interpolator`, null when none has arrived.
  const msg::InterpolatorState* state(int interpolator) const;
  //! State samples received for `interpolator` so far.
  std::uint64_t state_samples(int interpolator) const;
  //! Messages (M29 texts, errors) received since the last call.
  std::vector<msg::Message> take_messages();

  //! Called for every state / setpoints sample as it is taken (optional).
  std::function<void(const msg::InterpolatorState&)> on_state;
  std::function<void(const msg::Setpoints&)> on_setpoints;

  //! Sends `r` (request_id, role and client_name are filled in) and polls until its reply.
  Reply request(msg::Request r, std::chrono::milliseconds timeout = 3s);
  Reply start(int interpolator);
  Reply stop(int interpolator);
  Reply clear(int interpolator);
  //! Command register with Command_Parameter[0..11] (missing parameters are 0).
  Reply command(int interpolator, std::int32_t code, std::span<const std::int32_t> params = {});
  //! M_Func = 0.
  Reply ack_m_func(int interpolator);
  Reply set_rel_speed(int interpolator, double rel_speed);

  Role role() const { return role_; }
  const std::string& name() const { return name_; }
  dds::Participant& participant() { return participant_; }
  eprosima::fastdds::dds::DataWriter& program_writer() { return program_writer_; }

 private:
  Role role_;
  dds::Participant participant_;
  std::string name_;
  eprosima::fastdds::dds::DataReader& state_reader_;
  eprosima::fastdds::dds::DataReader& reply_reader_;
  eprosima::fastdds::dds::DataReader& message_reader_;
  eprosima::fastdds::dds::DataReader* setpoint_reader_ = nullptr;
  eprosima::fastdds::dds::DataWriter& request_writer_;
  eprosima::fastdds::dds::DataWriter& program_writer_;
  std::chrono::steady_clock::time_point last_wake_{};
  std::chrono::steady_clock::time_point last_written_{};
  std::optional<dds::DataWaiter> waiter_;
  std::vector<std::optional<msg::InterpolatorState>> states_;
  std::vector<std::uint64_t> state_samples_;
  std::vector<msg::Message> messages_;
  std::vector<msg::Reply> replies_;
  std::uint64_t next_request_id_ = 1;
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
  ProgramSender(Client& client, const Program& program, int interpolator, std::uint32_t program_id);
  //! Writes what the window allows. False (with `error()`) when a chunk cannot be built or written.
  bool pump();
  //! Records written / confirmed (accepted into the ring buffer) so far.
  std::uint64_t written() const { return next_; }
  std::uint64_t confirmed() const { return confirmed_; }
  std::uint64_t total() const { return total_; }
  bool all_confirmed() const { return confirmed_ >= total_; }
  const std::string& error() const { return error_; }
  std::uint32_t program_id() const { return program_id_; }

 private:
  Client& client_;
  const Program& program_;
  int interpolator_;
  std::uint32_t program_id_;
  std::uint64_t total_;
  std::uint64_t next_ = 0;
  std::uint64_t confirmed_ = 0;
  bool end_written_ = false;
  bool matched_ = false;
  std::vector<std::uint64_t> chunk_ends_;  // end index of each chunk in flight
  msg::ProgramChunk chunk_;
  std::string error_;
};

//! A fresh non-zero program id (time and process based).
std::uint32_t new_program_id();

}  // namespace tgm::client
