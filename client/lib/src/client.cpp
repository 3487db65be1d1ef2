#include "tgm/client/client.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <random>

#include "tgm/dds/topics.hpp"
#include "tgm/idl_mapping.hpp"
#include "tgm/msg/tgmPubSubTypes.h"
#include "tgm/printable.hpp"

namespace tgm::client {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

std::string_view reply_code_name(msg::ReplyCode c) {
  switch (c) {
    case msg::REPLY_CODE_ACCEPTED: return "accepted";
    case msg::REPLY_CODE_WRONG_ROLE: return "wrong role";
    case msg::REPLY_CODE_OUT_OF_RANGE: return "out of range";
    case msg::REPLY_CODE_WRONG_STATE: return "wrong state";
    case msg::REPLY_CODE_BAD_REQUEST: return "bad request";
    case msg::REPLY_CODE_UNSUPPORTED: return "unsupported";
    case msg::REPLY_CODE_BUSY: return "busy";
  }
  return "unknown reply code";
}

static_assert(dds::kMaxClientName == TGM_MAX_NAME, "the participant's USER_DATA carries the name");

std::string unique_client_name(std::string_view participant) {
  char tail[32];
  std::snprintf(tail, sizeof tail, "-%ld-%08x", static_cast<long>(::getpid()),
                static_cast<unsigned>(std::random_device{}()));
  const std::size_t room = TGM_MAX_NAME - std::strlen(tail);
  return std::string(participant.substr(0, room)) + tail;
}

std::string describe(const Reply& r) {
  if (r.timed_out) {
    char waited[32];
    std::snprintf(waited, sizeof waited, "%.1f s", static_cast<double>(r.waited.count()) / 1000.0);
    if (r.cancelled) {
      return std::string("interrupted after ") + waited +
             (r.sent
                  ? " waiting for the reply: the request was sent, whether tgm-service executed it "
                    "is not known (check the registers)"
                  : " waiting for tgm-service to take requests; nothing was sent");
    }
    if (!r.sent) {
      return std::string("no reply: no tgm-service took requests on this domain within ") + waited +
             " (is it running, with the same domain, profiles and security?); nothing was sent";
    }
    return std::string("no reply within ") + waited +
           (r.sends > 1 ? ": the request was sent (" + std::to_string(r.sends) + " times)"
                        : std::string(": the request was sent")) +
           ", but whether tgm-service executed it is not known (it may "
           "still arrive over a slow or lossy network; check the registers)";
  }
  if (r.accepted) return "accepted";
  return "refused (" + std::string(reply_code_name(r.code)) + "): " + printable(r.reason);
}

std::string config_name(const AppConfig& config) {
  return config.source_path.empty() ? "the built-in config" : config.source_path;
}

bool same_machine(const msg::InterpolatorState& s, const MachineConfig& machine, int ip) {
  return s.machine_digest() == 0 ||
         s.machine_digest() == machine_digest(machine, ip, s.number_axes());
}

std::optional<SmoothingConfig> smoothing_in_effect(const msg::InterpolatorState& s) {
  if (s.iir_p_e6() == 0) return std::nullopt;
  SmoothingConfig c;
  c.spline_points = s.spline_points();
  c.spline_jerk_mm_s3 = s.spline_jerk_mm_s3();
  c.iir_p_e6 = s.iir_p_e6();
  c.iir_q_e6 = s.iir_q_e6();
  c.iir_f_e6 = s.iir_f_e6();
  c.iir_axis_mask = s.iir_axis_mask();
  return c;
}

SmoothingConfig smoothing_for_simulation(const SmoothingConfig& own,
                                         const msg::InterpolatorState& s) {
  SmoothingConfig c = own;
  const std::optional<SmoothingConfig> now = smoothing_in_effect(s);
  if (!now) return c;
  c.spline_points = now->spline_points;
  if (now->spline_points != 0) c.spline_jerk_mm_s3 = now->spline_jerk_mm_s3;
  c.iir_axis_mask = now->iir_axis_mask;
  if (now->iir_axis_mask != 0) {
    c.iir_p_e6 = now->iir_p_e6;
    c.iir_q_e6 = now->iir_q_e6;
    c.iir_f_e6 = now->iir_f_e6;
  }
  return c;
}

std::string describe_smoothing(const msg::InterpolatorState& s, std::string_view letters) {
  const std::optional<SmoothingConfig> c = smoothing_in_effect(s);
  if (!c) return "not said (tgm-service before 0.2.2)";
  char buf[160];
  std::string out;
  if (c->spline_points == 0) {
    out = "Spline off";
  } else {
    // The spline delays by its points in calculation steps (a fifth of the cycle). In double:
    // a foreign writer's values may be anything.
    std::snprintf(buf, sizeof buf,
                  "Spline %d points (%.1f ms at %d us cycles), jerk limit %.0f mm/s^3",
                  c->spline_points, c->spline_points * (s.cycle_time_us() / 5000.0),
                  s.cycle_time_us(), c->spline_jerk_mm_s3);
    out = buf;
  }
  if (c->iir_axis_mask == 0) return out + "; IIR off";
  std::snprintf(buf, sizeof buf, "; IIR p %g, q %g, f %g ms on",
                static_cast<double>(c->iir_p_e6) * 1e-6, static_cast<double>(c->iir_q_e6) * 1e-6,
                static_cast<double>(c->iir_f_e6) * 1e-6);
  out += buf;
  for (int i = 0; i < kMaxAxes; ++i) {
    if ((c->iir_axis_mask >> i & 1u) == 0) continue;
    out += ' ';
    if (static_cast<std::size_t>(i) < letters.size()) {
      out += letters[static_cast<std::size_t>(i)];
    } else {
      out += "axis " + std::to_string(i);
    }
  }
  return out;
}

std::string_view status_name(std::int32_t status) {
  switch (status) {
    case 0: return "empty";
    case 1: return "running";
    case 3: return "ended";
    case 4: return "ready";
    case 6: return "emergency ramp";
    case 7: return "emergency stopped";
    case 8: return "underrun";
    default: return "?";
  }
}

Client::Client(const DdsConfig& config, Role role, const ClientOptions& options)
    : role_(role),
      request_timeout_(options.request_timeout),
      default_cancel_(options.cancel),
      config_(config),
      setpoints_(options.setpoints) {
  // Named before the participant exists: it announces the name in its USER_DATA, so that the
  // service can say which client joined or left before its first request (a second tgm-plc was
  // 'tgm-plc', the participant's name, beside 'tgm-plc-12873-f69fb842').
  name_ = unique_client_name(dds::participant_name(config_, participant_role()));
  join(make_participant());
  states_.resize(kMaxInterpolators);
  state_samples_.resize(kMaxInterpolators, 0);
  follow_.resize(kMaxInterpolators);
}

std::unique_ptr<dds::Participant> Client::make_participant() const {
  return std::make_unique<dds::Participant>(config_, participant_role(), dds::kParticipantProfile,
                                            name_);
}

void Client::join(std::unique_ptr<dds::Participant> made) {
  participant_ = std::move(made);
  dds::Participant& p = *participant_;
  state_reader_ = &p.reader<msg::InterpolatorStatePubSubType>(dds::kStateTopic);
  reply_reader_ = &p.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  message_reader_ = &p.reader<msg::MessagePubSubType>(dds::kMessageTopic);
  request_writer_ =
      &p.writer<msg::RequestPubSubType>(config_.security_dir.empty() ? dds::kRequestTopic
                                        : role_ == Role::kPlc        ? dds::kRequestPlcTopic
                                                                     : dds::kRequestHmiTopic);
  if (role_ == Role::kHmi) {
    program_writer_ = &p.writer<msg::ProgramChunkPubSubType>(dds::kProgramTopic);
  }
  if (setpoints_) {
    setpoint_reader_ = &p.reader<msg::SetpointsPubSubType>(dds::kSetpointsTopic);
    waiter_.emplace(std::initializer_list<fdds::DataReader*>{state_reader_, reply_reader_,
                                                             message_reader_, setpoint_reader_});
  } else {
    waiter_.emplace(
        std::initializer_list<fdds::DataReader*>{state_reader_, reply_reader_, message_reader_});
  }
}

std::string Client::rejoin() {
  // Made first: a participant that cannot be made (a port taken meanwhile) used to leave the
  // client without one, and the run ended in an "internal error".
  std::unique_ptr<dds::Participant> fresh;
  try {
    fresh = make_participant();
  } catch (const dds::SetupError& e) {
    return e.what();
  }
  if (event_reader_ != nullptr) event_reader_->set_listener(nullptr);
  waiter_.reset();
  state_reader_ = reply_reader_ = message_reader_ = setpoint_reader_ = event_reader_ = nullptr;
  request_writer_ = program_writer_ = nullptr;
  participant_.reset();  // its entities first, then the participant (a clean leave)
  join(std::move(fresh));
  if (event_listener_) attach_events("rejoin");
  return {};
}

void Client::attach_events(const char* caller) {
  event_reader_ = &participant_->reader<msg::InterpolatorEventPubSubType>(dds::kEventTopic);
  if (event_reader_->set_listener(event_listener_.get(), fdds::StatusMask::data_available()) !=
      eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    throw dds::SetupError(std::string("tgm::client::Client::") + caller +
                          ": cannot attach the listener to the " +
                          std::string(dds::kEventTopic.name) + " reader");
  }
}

fdds::DataWriter& Client::program_writer() {
  if (program_writer_ == nullptr) {
    throw dds::SetupError("tgm::client::Client: only an HMI client writes the program stream");
  }
  return *program_writer_;
}

Client::~Client() {
  if (event_listener_) {
    event_reader_->set_listener(nullptr);
    event_listener_->detach();
  }
}

void Client::EventListener::on_data_available(fdds::DataReader* reader) {
  const auto received = Clock::now();
  const std::lock_guard lock(mutex_);
  if (detached_) return;
  while (dds::take_next(*reader, event_.sample)) {
    event_.received = received;
    const std::size_t i = event_.sample.interpolator();
    if (i < last_counter_.size()) {
      const std::uint64_t c = event_.sample.event_counter();
      // A restarted service counts from 1 again: not a loss.
      if (event_.sample.service_instance() != last_instance_[i]) {
        last_instance_[i] = event_.sample.service_instance();
        last_counter_[i] = 0;
      }
      if (last_counter_[i] == 0 && c > 1) {
        client_.events_before_join_.fetch_add(c - 1, std::memory_order_relaxed);
      }
      if (last_counter_[i] != 0 && c > last_counter_[i] + 1) {
        client_.events_lost_.fetch_add(c - last_counter_[i] - 1, std::memory_order_relaxed);
      }
      last_counter_[i] = c;
    }
    client_.events_received_.fetch_add(1, std::memory_order_relaxed);
    handler_(event_);
  }
}

void Client::EventListener::detach() {
  const std::lock_guard lock(mutex_);
  detached_ = true;
}

void Client::on_event(EventHandler handler) {
  if (event_listener_)
    throw dds::SetupError("tgm::client::Client::on_event: a handler is already set");
  if (!handler) throw dds::SetupError("tgm::client::Client::on_event: empty handler");
  event_listener_ = std::make_unique<EventListener>(*this, std::move(handler));
  attach_events("on_event");
}

bool Client::wait_for_event_match(std::chrono::milliseconds timeout,
                                  const std::atomic<bool>* cancel) {
  if (event_reader_ == nullptr) return false;
  const auto deadline = Clock::now() + timeout;
  while (true) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (dds::wait_for_match(
            *event_reader_, 1,
            std::clamp(left, std::chrono::milliseconds(0), std::chrono::milliseconds(20))))
      return true;
    if (Clock::now() >= deadline || (cancel != nullptr && cancel->load())) return false;
  }
}

void Client::poll(std::chrono::nanoseconds timeout) {
  if (timeout.count() > 0) {
    waiter_->wait(timeout);
    last_wake_ = Clock::now();
  }
  // States: all that arrived first, so that a followed service whose state is among them counts
  // as alive however long this client did not poll (its silence is judged by polls).
  batch_.clear();
  std::array<bool, kMaxInterpolators> followed_heard{};
  while (dds::take_next(*state_reader_, state_scratch_)) {
    const std::size_t i = state_scratch_.interpolator();
    if (i >= states_.size()) continue;
    followed_heard[i] =
        followed_heard[i] || state_scratch_.service_instance() == follow_[i].instance;
    batch_.push_back(state_scratch_);
  }
  const auto now = Clock::now();
  for (const msg::InterpolatorState& s : batch_) {
    const std::size_t i = s.interpolator();
    Follow& f = follow_[i];
    if (f.instance != 0 && s.service_instance() != f.instance &&
        (followed_heard[i] || now - f.last < kServiceSwitch)) {
      f.other = s.service_instance();  // two services on the domain: not mixed in
      f.other_at = now;
      continue;
    }
    f.instance = s.service_instance();
    f.last = now;
    states_[i] = s;
    ++state_samples_[i];
    if (on_state) on_state(s);
  }
  msg::Reply reply;
  while (dds::take_next(*reply_reader_, reply)) {
    if (reply.client_name() != name_) continue;
    if (!replied_.insert(reply.request_id()).second) continue;  // a second reply to it
    replied_order_.push_back(reply.request_id());
    if (replied_order_.size() > kMaxKeptReplies) {
      replied_.erase(replied_order_.front());
      replied_order_.pop_front();
    }
    replies_.push_back(reply);
    free_slot();
    window_progress_ns_.store(Clock::now().time_since_epoch().count(), std::memory_order_relaxed);
  }
  if (replies_.size() > kMaxKeptReplies) {
    replies_.erase(replies_.begin(), replies_.end() - static_cast<std::ptrdiff_t>(kMaxKeptReplies));
  }
  msg::Message m;
  while (dds::take_next(*message_reader_, m)) messages_.push_back(m);
  if (setpoint_reader_ != nullptr) {
    while (dds::take_next(*setpoint_reader_, setpoints_scratch_)) {
      if (on_setpoints) on_setpoints(setpoints_scratch_);
    }
  }
}

bool Client::wait_for_state(int interpolator, std::chrono::milliseconds timeout,
                            const std::atomic<bool>* cancel) {
  return wait_until(
      interpolator, [](const msg::InterpolatorState&) { return true; }, timeout, cancel);
}

bool Client::wait_until(int interpolator,
                        const std::function<bool(const msg::InterpolatorState&)>& pred,
                        std::chrono::milliseconds timeout, const std::atomic<bool>* cancel) {
  const auto deadline = Clock::now() + timeout;
  while (true) {
    poll(std::chrono::nanoseconds(0));
    if (const auto* s = state(interpolator); s != nullptr && pred(*s)) return true;
    const auto now = Clock::now();
    if (now >= deadline || (cancel != nullptr && cancel->load())) return false;
    poll(std::min<std::chrono::nanoseconds>(deadline - now, 20ms));
  }
}

const msg::InterpolatorState* Client::state(int interpolator) const {
  if (interpolator < 0 || static_cast<std::size_t>(interpolator) >= states_.size()) return nullptr;
  const auto& s = states_[static_cast<std::size_t>(interpolator)];
  return s ? &*s : nullptr;
}

std::uint64_t Client::service_followed(int interpolator) const {
  if (interpolator < 0 || static_cast<std::size_t>(interpolator) >= follow_.size()) return 0;
  return follow_[static_cast<std::size_t>(interpolator)].instance;
}

std::uint64_t Client::other_service(int interpolator) const {
  if (interpolator < 0 || static_cast<std::size_t>(interpolator) >= follow_.size()) return 0;
  const Follow& f = follow_[static_cast<std::size_t>(interpolator)];
  return f.other != 0 && Clock::now() - f.other_at < 3s ? f.other : 0;
}

std::chrono::steady_clock::time_point Client::state_taken(int interpolator) const {
  if (interpolator < 0 || static_cast<std::size_t>(interpolator) >= follow_.size()) return {};
  return follow_[static_cast<std::size_t>(interpolator)].last;
}

std::uint64_t Client::state_samples(int interpolator) const {
  if (interpolator < 0 || static_cast<std::size_t>(interpolator) >= states_.size()) return 0;
  return state_samples_[static_cast<std::size_t>(interpolator)];
}

std::vector<msg::Message> Client::take_messages() {
  std::vector<msg::Message> out;
  out.swap(messages_);
  return out;
}

Reply Client::request(msg::Request r, std::chrono::milliseconds timeout,
                      const std::atomic<bool>* cancel) {
  if (cancel == nullptr) cancel = default_cancel_;
  Reply out;
  out.waited = timeout;
  const auto start = Clock::now();
  const auto deadline = start + timeout;
  // Ends the wait when the time is up or the caller cancels (then `waited` is the time spent).
  const auto give_up = [&] {
    if (cancel != nullptr && cancel->load()) {
      out.cancelled = true;
      out.waited = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start);
    } else if (Clock::now() < deadline) {
      return false;
    }
    out.timed_out = true;
    return true;
  };
  // The request topic is VOLATILE: a request written before the service's reader matched is
  // lost. Matched in slices of 20 ms, so that a cancel is seen.
  const auto matched = [&](auto& endpoint) {
    while (!dds::wait_for_match(
        endpoint, 1,
        std::chrono::duration_cast<std::chrono::milliseconds>(
            std::clamp<Clock::duration>(deadline - Clock::now(), Clock::duration(0), 20ms)))) {
      if (give_up()) return false;
    }
    return true;
  };
  if (!matched(*request_writer_) || !matched(*reply_reader_)) return out;
  // A free place in the window (kRequestsInFlight), waiting for replies to earlier send()s.
  while (!take_slot()) {
    if (give_up()) return out;
    poll(std::min<std::chrono::nanoseconds>(
        std::max<Clock::duration>(deadline - Clock::now(), Clock::duration(0)), 20ms));
  }
  fill(r);
  if (!request_writer_->write(&r)) {
    free_slot();
    out.timed_out = true;
    return out;
  }
  last_written_ = Clock::now();
  out.sent = true;
  out.sends = 1;
  // No reply yet: the same request again (the service executes it once and answers a repeat
  // with the first reply), after kFirstResend, then at twice the last interval. A repeat that
  // reaches a service that replaced the one this client followed at the first write is
  // answered "not executed" (Request.attempt).
  Clock::duration resend_after = kFirstResend;
  Clock::time_point resend_at = last_written_ + resend_after;
  while (true) {
    poll(std::chrono::nanoseconds(0));
    if (std::optional<Reply> reply = take_reply(r.request_id())) {
      reply->sent = true;
      reply->sends = out.sends;
      return *reply;
    }
    if (give_up()) return out;
    auto now = Clock::now();
    if (now >= resend_at) {
      r.attempt(static_cast<std::uint32_t>(out.sends + 1));
      if (request_writer_->write(&r)) {
        ++out.sends;
        last_written_ = now;
      }
      resend_after = std::min<Clock::duration>(resend_after * 2, kLongestResend);
      resend_at = now + resend_after;
    }
    now = Clock::now();
    poll(std::clamp<Clock::duration>(std::min(deadline, resend_at) - now, Clock::duration(0),
                                     Clock::duration(20ms)));
  }
}

bool Client::take_slot() {
  int n = in_flight_.load(std::memory_order_relaxed);
  while (true) {
    const std::int64_t now = Clock::now().time_since_epoch().count();
    if (n >= kRequestsInFlight) {
      const std::int64_t since = now - window_progress_ns_.load(std::memory_order_relaxed);
      if (since < std::chrono::nanoseconds(1s).count()) return false;
      // No reply for a second with the window full: those replies are lost (the service
      // restarted, or this client stopped polling). Start a new window.
      in_flight_.store(0, std::memory_order_relaxed);
      n = 0;
    }
    if (in_flight_.compare_exchange_weak(n, n + 1, std::memory_order_relaxed)) {
      if (n == 0) window_progress_ns_.store(now, std::memory_order_relaxed);
      return true;
    }
  }
}

void Client::free_slot() {
  int n = in_flight_.load(std::memory_order_relaxed);
  while (n > 0 && !in_flight_.compare_exchange_weak(n, n - 1, std::memory_order_relaxed)) {
  }
}

void Client::fill(msg::Request& r) {
  r.request_id(next_request_id_.fetch_add(1, std::memory_order_relaxed));
  r.role(role_ == Role::kPlc ? msg::CLIENT_ROLE_PLC : msg::CLIENT_ROLE_HMI);
  r.client_name(name_);
  // The service a repeat is meant for: one that replaced it does not execute the repeat.
  r.service_instance(service_followed(static_cast<int>(r.interpolator())));
  r.attempt(1);
}

std::uint64_t Client::send(msg::Request r) {
  // The request topic is VOLATILE: written before the service's reader matched, it is lost.
  fdds::PublicationMatchedStatus matched;
  if (request_writer_->get_publication_matched_status(matched) !=
          eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK ||
      matched.current_count < 1) {
    return 0;
  }
  if (!take_slot()) return 0;
  fill(r);
  if (request_writer_->write(&r)) return r.request_id();
  free_slot();
  return 0;
}

std::optional<Reply> Client::take_reply(std::uint64_t request_id) {
  for (auto it = replies_.begin(); it != replies_.end(); ++it) {
    if (it->request_id() != request_id) continue;
    Reply out;
    out.accepted = it->accepted();
    out.code = it->code();
    out.reason = it->reason();
    out.cycle = it->cycle_counter();
    replies_.erase(it);
    return out;
  }
  return std::nullopt;
}

namespace {
msg::Request make(int interpolator, msg::RequestKind kind) {
  msg::Request r;
  r.interpolator(static_cast<std::uint16_t>(interpolator));
  r.kind(kind);
  return r;
}

// M_Func = 0, naming the M-function acknowledged by number and m_func_count.
msg::Request m_func_ack(int interpolator, std::int32_t m, std::uint32_t count) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_WRITE_M_FUNC);
  r.value(0.0);
  r.m_func_acknowledged(m);
  r.m_func_count_acknowledged(count);
  return r;
}
}  // namespace

msg::Request start_request(int interpolator) {
  return make(interpolator, msg::REQUEST_KIND_START);
}

msg::Request plc_setup_done_request(int interpolator) {
  return make(interpolator, msg::REQUEST_KIND_PLC_SETUP_DONE);
}

msg::Request command_request(int interpolator, std::int32_t code,
                             std::span<const std::int32_t> params) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_COMMAND);
  r.command(code);
  for (std::size_t k = 0; k < params.size() && k < r.command_parameter().size(); ++k) {
    r.command_parameter()[k] = params[k];
  }
  return r;
}

msg::Request rel_speed_request(int interpolator, double rel_speed) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_WRITE_REL_SPEED);
  r.value(rel_speed);
  return r;
}

msg::Request number_axes_request(int interpolator, int number_axes) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_WRITE_NUMBER_AXES);
  r.value(number_axes);
  return r;
}

msg::Request ratio_request(int interpolator, int axis, double ratio_inc_per_mm) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_WRITE_RATIO);
  r.axis(static_cast<std::uint16_t>(axis));
  r.value(ratio_inc_per_mm);
  return r;
}

msg::Request offset_request(int interpolator, int axis, std::int64_t offset_inc) {
  msg::Request r = make(interpolator, msg::REQUEST_KIND_WRITE_OFFSET);
  r.axis(static_cast<std::uint16_t>(axis));
  r.value(static_cast<double>(offset_inc));  // exact: |offset| <= 1e15 < 2^53
  return r;
}

Reply Client::start(int i) {
  return start(i, request_timeout_);
}
Reply Client::stop(int i) {
  return request(make(i, msg::REQUEST_KIND_STOP));
}
Reply Client::clear(int i) {
  return clear(i, request_timeout_);
}
Reply Client::start(int i, std::chrono::milliseconds timeout, const std::atomic<bool>* cancel) {
  return request(start_request(i), timeout, cancel);
}
Reply Client::stop(int i, std::chrono::milliseconds timeout, const std::atomic<bool>* cancel) {
  return request(make(i, msg::REQUEST_KIND_STOP), timeout, cancel);
}
Reply Client::clear(int i, std::chrono::milliseconds timeout, const std::atomic<bool>* cancel) {
  return request(make(i, msg::REQUEST_KIND_CLEAR), timeout, cancel);
}

Reply Client::command(int i, std::int32_t code, std::span<const std::int32_t> params) {
  return request(command_request(i, code, params));
}

Reply Client::ack_m_func(int i, std::int32_t m, std::uint32_t count) {
  return request(m_func_ack(i, m, count));
}

std::uint64_t Client::send_ack_m_func(int i, std::int32_t m, std::uint32_t count) {
  return send(m_func_ack(i, m, count));
}

Reply Client::set_rel_speed(int i, double rel_speed) {
  return request(rel_speed_request(i, rel_speed));
}

// ---- ProgramSender ----

namespace {

// "record 12 (line 14): " for a record of `program`, "" past its end.
// "record 12 (line 14): " for record `index` of the program, held at `index - base` of `records`.
std::string record_text(const Program& records, std::uint64_t index, std::uint64_t base = 0) {
  if (index < base || index - base >= records.segments.size()) return {};
  return "record " + std::to_string(index) + " (line " +
         std::to_string(records.segments[static_cast<std::size_t>(index - base)].line) + "): ";
}

}  // namespace

ProgramSender::ProgramSender(Client& client, const Program& program, int interpolator,
                             std::uint32_t program_id)
    : client_(client),
      program_(&program),
      interpolator_(interpolator),
      program_id_(program_id),
      total_(program.segments.size()) {
  std::size_t index = 0;
  if (const mapping::MapStatus st = mapping::program_problem(program, index);
      st != mapping::MapStatus::kOk)
    error_ = record_text(program, index) + std::string(mapping::to_string(st));
}

ProgramSender::ProgramSender(Client& client, const PackedProgram& program, int interpolator,
                             std::uint32_t program_id)
    : client_(client),
      window_(program),
      packed_(&program),
      interpolator_(interpolator),
      program_id_(program_id),
      total_(program.size()) {
  // The whole program is checked first, a window at a time, as the other constructor does.
  PackedProgram::Cursor check = program.cursor();
  Program part = program.tables();
  std::uint64_t first = 0;
  while (true) {
    part.segments.clear();
    Segment s;
    while (part.segments.size() < 4096 && check.next(s)) part.segments.push_back(s);
    std::size_t index = 0;
    if (const mapping::MapStatus st = mapping::program_problem(part, index);
        st != mapping::MapStatus::kOk) {
      error_ = record_text(part, first + index, first) + std::string(mapping::to_string(st));
      return;
    }
    if (part.segments.size() < 4096) break;
    first += part.segments.size();
  }
}

const Program& ProgramSender::records_from(std::uint64_t first) {
  return program_ != nullptr ? *program_ : window_->from(first, mapping::kMaxChunkSegments);
}

bool ProgramSender::pump() {
  if (!error_.empty()) return false;  // nothing of a program that cannot be sent whole
  const msg::InterpolatorState* s = client_.state(interpolator_);
  if (s == nullptr) return true;
  if (s->program_id() == program_id_) confirmed_ = std::max<std::uint64_t>(confirmed_, s->next_sequence());
  while (!chunk_ends_.empty() && chunk_ends_.front() <= confirmed_) {
    taken_end_ = chunk_ends_.front();
    chunk_ends_.erase(chunk_ends_.begin());
  }
  if (!matched_) {
    fdds::PublicationMatchedStatus st;
    client_.program_writer().get_publication_matched_status(st);
    if (st.current_count < 1) return true;
    matched_ = true;
  }
  const std::uint64_t free_slots = static_cast<std::uint64_t>(std::max(0, s->free_buffer_slots()));
  while (!end_written_ && chunk_ends_.size() < static_cast<std::size_t>(dds::kProgramChunksInFlight)) {
    const Program& records = records_from(next_);
    const std::uint64_t base = this->base();
    std::size_t end_in = 0;
    const mapping::MapStatus st = mapping::fill_chunk(
        records, static_cast<std::size_t>(next_ - base),
        {static_cast<std::uint16_t>(interpolator_), program_id_}, chunk_, end_in);
    if (st != mapping::MapStatus::kOk) {
      error_ = record_text(records, base + end_in, base) + std::string(mapping::to_string(st));
      return false;
    }
    // Numbered in the whole program (a window starts at base), ended by its last record.
    const std::uint64_t end = base + end_in;
    chunk_.sequence_number(next_);
    chunk_.end_of_program(end == total_);
    const std::uint64_t in_flight = next_ > confirmed_ ? next_ - confirmed_ : 0;
    const std::uint64_t n = end - next_;
    if (in_flight > 0 && in_flight + n > free_slots) break;
    if (!client_.program_writer().write(&chunk_)) {
      error_ = "writing program chunk " + std::to_string(next_) + " failed";
      return false;
    }
    next_ = end;
    chunk_ends_.push_back(end);
    if (chunk_.end_of_program()) end_written_ = true;
  }
  return true;
}

void ProgramSender::rewrite() {
  if (confirmed_ >= next_) return;  // nothing in flight
  next_ = taken_end_;
  chunk_ends_.clear();
  end_written_ = false;
  matched_ = false;
  if (packed_ != nullptr) window_.emplace(*packed_);  // a window does not move back
}

std::uint32_t new_program_id() {
  const auto t = static_cast<std::uint64_t>(Clock::now().time_since_epoch().count());
  std::uint32_t id = static_cast<std::uint32_t>(t ^ (t >> 32) ^ (static_cast<std::uint64_t>(::getpid()) << 16));
  return id == 0 ? 1 : id;
}

}  // namespace tgm::client
