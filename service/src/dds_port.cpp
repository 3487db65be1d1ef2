#include "dds_port.hpp"

#include <linux/futex.h>
#include <pthread.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <climits>
#include <cstdio>
#include <map>
#include <random>
#include <utility>

#include "tgm/dds/topics.hpp"
#include "tgm/idl_mapping.hpp"
#include "tgm/service/peer_service.hpp"

namespace tgm::service {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

namespace {

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

RequestKind from_msg(msg::RequestKind k) {
  switch (k) {
    case msg::REQUEST_KIND_COMMAND: return RequestKind::kCommand;
    case msg::REQUEST_KIND_WRITE_M_FUNC: return RequestKind::kWriteMFunc;
    case msg::REQUEST_KIND_WRITE_REL_SPEED: return RequestKind::kWriteRelSpeed;
    case msg::REQUEST_KIND_WRITE_OFFSET: return RequestKind::kWriteOffset;
    case msg::REQUEST_KIND_WRITE_RATIO: return RequestKind::kWriteRatio;
    case msg::REQUEST_KIND_WRITE_NUMBER_AXES: return RequestKind::kWriteNumberAxes;
    case msg::REQUEST_KIND_START: return RequestKind::kStart;
    case msg::REQUEST_KIND_STOP: return RequestKind::kStop;
    case msg::REQUEST_KIND_CLEAR: return RequestKind::kClear;
    case msg::REQUEST_KIND_PLC_SETUP_DONE:
      return RequestKind::kPlcSetupDone;
  }
  return RequestKind::kUnknown;
}

msg::ReplyCode to_msg(ReplyCode c) {
  switch (c) {
    case ReplyCode::kAccepted: return msg::REPLY_CODE_ACCEPTED;
    case ReplyCode::kWrongRole: return msg::REPLY_CODE_WRONG_ROLE;
    case ReplyCode::kOutOfRange: return msg::REPLY_CODE_OUT_OF_RANGE;
    case ReplyCode::kWrongState: return msg::REPLY_CODE_WRONG_STATE;
    case ReplyCode::kBadRequest: return msg::REPLY_CODE_BAD_REQUEST;
    case ReplyCode::kUnsupported: return msg::REPLY_CODE_UNSUPPORTED;
    case ReplyCode::kBusy: return msg::REPLY_CODE_BUSY;
  }
  return msg::REPLY_CODE_BAD_REQUEST;
}

bool progress_changed(const Registers& a, const Registers& b) {
  return a.act_part != b.act_part || a.free_slots != b.free_slots || a.act_speed != b.act_speed ||
         a.orig_position != b.orig_position || a.position != b.position;
}

// What a request asks for, apart from its id and client: a repeat of a request (Client::request
// sends an unanswered one again under its id) must ask for the same. FNV-1a over the fields.
std::uint64_t request_digest(const msg::Request& r, Role role) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  const auto mix = [&h](std::uint64_t v) {
    for (int b = 0; b < 8; ++b, v >>= 8) {
      h ^= v & 0xFFU;
      h *= 0x100000001b3ULL;
    }
  };
  mix(static_cast<std::uint64_t>(role));  // as executed: a secured topic's, not the sample's
  mix(r.interpolator());
  mix(static_cast<std::uint64_t>(r.kind()));
  mix(static_cast<std::uint32_t>(r.command()));
  for (const std::int32_t p : r.command_parameter()) mix(static_cast<std::uint32_t>(p));
  mix(r.axis());
  mix(std::bit_cast<std::uint64_t>(r.value()));
  mix(static_cast<std::uint32_t>(r.m_func_acknowledged()));
  mix(r.m_func_count_acknowledged());
  return h;
}

// The reason of every REPLY_CODE_BUSY answer.
constexpr const char* kBusyReason =
    "service busy: the request queue is full (a client sends faster than the interpolation "
    "cycles take requests); not executed, send it again";

}  // namespace

void Doorbell::ring() {
  word_.fetch_add(1, std::memory_order_release);
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word_), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr,
          nullptr, 0);
}

void Doorbell::wait(std::uint32_t seen, std::chrono::nanoseconds timeout) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(timeout.count() / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(timeout.count() % 1'000'000'000);
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word_), FUTEX_WAIT_PRIVATE, seen, &ts,
          nullptr, 0);
}

DdsPort::DdsPort(const DdsConfig& config, const DdsPortOptions& options)
    : opt_(options),
      participant_(config, "service"),
      state_writer_(participant_.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic)),
      event_writer_(participant_.writer<msg::InterpolatorEventPubSubType>(dds::kEventTopic)),
      setpoint_writer_(participant_.writer<msg::SetpointsPubSubType>(dds::kSetpointsTopic)),
      reply_writer_(participant_.writer<msg::ReplyPubSubType>(
          dds::kReplyTopic, &reply_match_listener_, fdds::StatusMask::publication_matched())),
      message_writer_(participant_.writer<msg::MessagePubSubType>(dds::kMessageTopic)),
      program_reader_(participant_.reader<msg::ProgramChunkPubSubType>(dds::kProgramTopic)),
      state_reader_(participant_.reader<msg::InterpolatorStatePubSubType>(dds::kStateTopic)),
      waiter_({&program_reader_}),
      free_chunks_(static_cast<std::size_t>(options.interpolators) * 4 *
                   dds::kProgramChunksInFlight) {
  if (config.security_dir.empty()) {
    request_sources_.push_back(
        {&participant_.reader<msg::RequestPubSubType>(dds::kRequestTopic), std::nullopt});
  } else {
    request_sources_.push_back(
        {&participant_.reader<msg::RequestPubSubType>(dds::kRequestPlcTopic), Role::kPlc});
    request_sources_.push_back(
        {&participant_.reader<msg::RequestPubSubType>(dds::kRequestHmiTopic), Role::kHmi});
  }
  const auto n = static_cast<std::size_t>(opt_.interpolators);
  std::random_device entropy;
  while (service_instance_ == 0) {
    service_instance_ = (static_cast<std::uint64_t>(entropy()) << 32) ^ entropy() ^
                        static_cast<std::uint64_t>(steady_ns());
  }
  for (std::size_t i = 0; i < n; ++i) {
    chunks_.push_back(std::make_unique<SpscQueue<ChunkIn*>>(2 * dds::kProgramChunksInFlight));
    m_written_ns_.push_back(std::make_unique<std::atomic<std::int64_t>>(0));
  }
  m_written_.resize(n);
  stream_from_.resize(n);
  // Capacity bounds these (the receiving and the publisher thread push only within it).
  const std::size_t stamps = std::min<std::size_t>(opt_.handshake_samples, 100'000);
  m_applied_.reserve(stamps);
  m_published_.reserve(stamps);
  m_pending_.assign(n, -1);
  last_m_count_.assign(n, 0);
  backlog_.resize(n);
  published_.resize(n);
  queued_setpoints_.resize(n);
  standing_setpoint_cycles_ =
      std::max<std::uint64_t>(1, static_cast<std::uint64_t>(opt_.state_period.count()) * 1000u /
                                     static_cast<std::uint64_t>(std::max(1, opt_.cycle_time_us)));
  // Chunk objects: enough for every queue plus the window of every sender.
  for (std::size_t i = 0; i < free_chunks_.capacity(); ++i) {
    chunk_pool_.push_back(std::make_unique<ChunkIn>());
    chunk_pool_.back()->program.segments.reserve(mapping::kMaxChunkSegments);
    free_chunks_.push(chunk_pool_.back().get());
  }
  // What came before the listener is taken before the listener is set, never after: Fast DDS
  // calls on_data_available holding the reader's lock, and take_states takes the reader's lock
  // under state_watch_mutex_, so a take here while a sample's callback ran was a lock-order
  // deadlock that hung the start for good, deaf to SIGTERM (review of session 80: a service
  // started while another published). A sample between the two is taken with the next one,
  // which another service publishes within its state period.
  take_states();
  state_reader_.set_listener(&state_watch_, fdds::StatusMask::data_available());
  // Discovery only (no status: the readers' and writers' own listeners or WaitSets keep those),
  // from here on: a tgm-plc already running is then seen while the service looks for another.
  participant_.get().set_listener(&peer_watch_, fdds::StatusMask::none());
}

DdsPort::~DdsPort() { stop(); }

void DdsPort::take_states() {
  const std::lock_guard lock(state_watch_mutex_);
  while (dds::take_next(state_reader_, other_state_sample_)) {
    if (other_state_sample_.service_instance() != service_instance_) {
      other_cycles_.store(other_state_sample_.cycle_counter(), std::memory_order_relaxed);
      other_latest_.store(other_state_sample_.service_instance(), std::memory_order_release);
    }
  }
}

std::uint64_t DdsPort::other_service(std::chrono::milliseconds wait) {
  const auto until = Clock::now() + wait;
  while (true) {
    if (const std::uint64_t other = other_latest_.load(std::memory_order_acquire); other != 0) {
      return other;
    }
    const auto now = Clock::now();
    if (now >= until) return 0;
    std::this_thread::sleep_for(
        std::min<Clock::duration>(until - now, std::chrono::milliseconds(10)));
  }
}

void DdsPort::start() {
  receiver_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "tgm-receive");
    receive_loop();
  });
  for (const RequestSource& src : request_sources_) {
    src.reader->set_listener(&request_listener_, fdds::StatusMask::data_available());
  }
  publisher_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "tgm-publish");
    publish_loop();
  });
}

void DdsPort::stop(std::atomic<const char*>* stage) {
  const auto at = [stage](const char* what) {
    if (stage != nullptr) stage->store(what, std::memory_order_release);
  };
  stopping_ = true;
  at("removing the DDS request listener");
  for (const RequestSource& src : request_sources_) src.reader->set_listener(nullptr);
  participant_.get().set_listener(nullptr);
  state_reader_.set_listener(nullptr);
  at("waiting for a DDS request callback in progress");
  { const std::lock_guard lock(request_mutex_); }  // a callback in progress has finished
  { const std::lock_guard lock(state_watch_mutex_); }
  waiter_.wake();
  doorbell_.ring();
  at("joining the DDS receive thread");
  if (receiver_.joinable()) receiver_.join();
  at("joining the DDS publisher thread");
  if (publisher_.joinable()) publisher_.join();
}

// ---- cycle thread ----

bool DdsPort::next_request(RequestIn& out) {
  if (!requests_.pop(out)) return false;
  if (out.kind == RequestKind::kWriteMFunc && out.taken_ns != 0 && m_applied_.size() < m_applied_.capacity()) {
    m_applied_.emplace_back(out.taken_ns, steady_ns());
  }
  return true;
}

const std::vector<HandshakeSample>& DdsPort::handshakes() {
  std::size_t k = 0;
  for (auto& h : handshakes_) {
    while (k < m_applied_.size() && m_applied_[k].first < h.taken_ns) ++k;
    if (k < m_applied_.size() && m_applied_[k].first == h.taken_ns) h.applied_ns = m_applied_[k].second;
  }
  // The publisher's records, in the order it wrote them, by (interpolator, event write begin).
  std::map<std::pair<int, std::int64_t>, const MWritten*> by_write;
  for (const MWritten& w : m_published_) by_write[{w.interpolator, w.event_write_begin_ns}] = &w;
  for (auto& h : handshakes_) {
    const auto it = by_write.find({h.written.interpolator, h.written.event_write_begin_ns});
    if (it != by_write.end()) h.written = *it->second;
  }
  return handshakes_;
}

ChunkIn* DdsPort::front_chunk(int i) {
  ChunkIn** c = chunks_[static_cast<std::size_t>(i)]->front();
  return c != nullptr ? *c : nullptr;
}

void DdsPort::pop_chunk(int i) {
  auto& q = *chunks_[static_cast<std::size_t>(i)];
  ChunkIn** c = q.front();
  if (c == nullptr) return;
  ChunkIn* chunk = *c;
  q.pop_front();
  free_chunks_.push(chunk);  // never full: it holds every pool object
}

bool DdsPort::reply(const ReplyOut& r) { return replies_.push(r); }
bool DdsPort::message(const MessageOut& m) { return messages_.push(m); }

bool DdsPort::event(const EventOut& e) {
  EventOut q = e;
  q.queued_ns = steady_ns();
  return events_.push(q);
}

void DdsPort::publish(const Snapshot& s) {
  Snapshot& slot = latest_.write_slot();
  slot = s;
  latest_.publish();
  // Setpoints: every cycle the positions change (every --setpoint-decimation'th), and with the
  // state period while they stand.
  const auto decimation = static_cast<std::uint64_t>(std::max(1, opt_.setpoint_decimation));
  for (int i = 0; i < s.count && i < static_cast<int>(queued_setpoints_.size()); ++i) {
    const Registers& reg = s.ip[static_cast<std::size_t>(i)].reg;
    QueuedSetpoint& q = queued_setpoints_[static_cast<std::size_t>(i)];
    // Position as well as PositionInc: at the start of a motion the axes move less than an
    // increment a cycle, and a drive that interpolates between setpoints needs those cycles.
    const bool moved =
        !q.any || reg.position != q.last.position || reg.position_inc != q.last.position_inc;
    const bool due =
        moved ? s.cycle % decimation == 0 : s.cycle - q.last.cycle >= standing_setpoint_cycles_;
    if (!due) continue;
    SetpointOut out;
    out.interpolator = static_cast<std::uint16_t>(i);
    out.cycle = s.cycle;
    out.position = reg.position;
    out.position_inc = reg.position_inc;
    if (!setpoints_.push(out)) {
      setpoints_lost_.fetch_add(1, std::memory_order_relaxed);
      continue;  // queued again next cycle: q is not moved on
    }
    q.any = true;
    q.last = out;
  }
  doorbell_.ring();
}

// ---- receiver thread ----

// Two threads take requests: the reader's listener (a Fast DDS receive thread, which calls it
// while holding the reader's internal mutex) and the receiver thread (retrying after a full
// queue). Blocking on request_mutex_ in the listener would be lock-order inversion: the receiver
// holds request_mutex_ and then needs the reader's mutex inside take(). So nobody blocks: a
// caller announces itself in requests_pending_ and tries the lock; the holder re-checks the flag
// after unlocking and takes again, so no sample is left behind when a try fails.
void DdsPort::take_requests() {
  requests_pending_.store(true, std::memory_order_seq_cst);
  while (requests_pending_.load(std::memory_order_seq_cst)) {
    std::unique_lock lock(request_mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;  // the holder sees the flag after it unlocks
    requests_pending_.store(false, std::memory_order_seq_cst);
    if (stopping_) return;
    take_requests_locked();
  }
}

void DdsPort::take_requests_locked() {
  msg::Request& r = request_sample_;
  // Stopping: what is still in the reader is neither executed nor answered (the service is
  // going away); a flood must not keep a callback, and so stop(), busy here.
  fdds::SampleInfo info;
  for (const RequestSource& src : request_sources_) {
    while (!stopping_.load(std::memory_order_relaxed) && dds::take_next(*src.reader, r, info)) {
      const std::string_view name(r.client_name().c_str(), r.client_name().size());
      // The participant this client's requests come from, and its role.
      const GuidPrefix from =
          eprosima::fastrtps::rtps::iHandle2GUID(info.publication_handle).guidPrefix;
      const Role role = src.role                           ? *src.role
                        : r.role() == msg::CLIENT_ROLE_PLC ? Role::kPlc
                                                           : Role::kHmi;
      const std::uint64_t digest = request_digest(r, role);
      // A client that sends faster than the cycles take requests is answered "busy" at once.
      // Leaving the sample in the reader would lose it unseen (the reader's history is
      // KEEP_LAST: newer requests push it out; Fast DDS 2.9 also drops samples a full KEEP_ALL
      // reader rejects). requests_.full() is checked here, under request_mutex_, where the
      // cycles can only make room.
      const bool busy = requests_.full();
      // A repeat first sent to another instance (Request.attempt: the one this one replaced,
      // or another service on the domain): that one may have executed it, and nothing here
      // can tell. Unless this instance saw the request (a repeat of it below), it is answered
      // without being executed, as a "busy" is.
      const bool stale =
          r.attempt() > 1 && r.service_instance() != 0 && r.service_instance() != service_instance_;
      ReplyOut door_answer;  // busy or stale: answered here, not executed
      msg::Reply door_reply;
      if (busy || stale) {
        door_answer.request_id = r.request_id();
        door_answer.client.set(name);
        door_answer.interpolator = static_cast<int>(r.interpolator());
        if (stale) {
          door_answer.code = ReplyCode::kWrongState;
          char why[256];
          std::snprintf(why, sizeof why,
                        "a repeat of a request first sent to tgm-service instance %016llx (since "
                        "restarted, or another service on the domain): not executed by this one "
                        "(%016llx), as that one may have; read the registers and send it again "
                        "if needed",
                        static_cast<unsigned long long>(r.service_instance()),
                        static_cast<unsigned long long>(service_instance_));
          door_answer.reason.set(why);
        } else {
          door_answer.code = ReplyCode::kBusy;
          door_answer.reason.set(kBusyReason);
        }
        fill_reply(door_reply, door_answer);
      }
      const bool at_door = busy || stale;
      const std::uint64_t tag = at_door ? 0 : ++next_tag_;
      bool repeat = false;
      {
        // One critical section per request: the publisher (publish_replies) finds a request's
        // participant and its log entry before the cycles can answer it.
        const std::lock_guard lock(reply_match_mutex_);
        // Bounded: a participant that never has a reply reader leaves its entries behind.
        if (client_participants_.size() >= 4096 &&
            client_participants_.find(name) == client_participants_.end()) {
          client_participants_.clear();
        }
        client_participants_.insert_or_assign(std::string(name), from);
        // A request that came before: not executed again. Its reply goes out again at once
        // when the publisher had it; otherwise it is still on its way from the cycles.
        if (const auto log = recent_requests_.find(name); log != recent_requests_.end()) {
          for (const RecentRequest& q : log->second.requests) {
            if (q.id != r.request_id() || q.digest != digest || q.participant != from) continue;
            repeat = true;
            ++requests_repeated_;
            log->second.last = Clock::now();
            // Bounded: a client that is not answered sends again.
            if (q.reply && repeat_replies_.size() < kMaxRepeatReplies) {
              repeat_replies_.push_back(*q.reply);
              repeats_pending_.store(true, std::memory_order_release);
            }
            break;
          }
        }
        // A "busy" is logged with its answer: a repeat gets "busy" again, never an execution
        // after a "busy" that its client may already have taken (a stale repeat's answer
        // likewise).
        if (!repeat) {
          log_request_locked(name,
                             {r.request_id(), digest, tag, from,
                              at_door ? std::optional<msg::Reply>(door_reply) : std::nullopt});
        }
      }
      if (repeat) continue;
      {
        const std::lock_guard lock(peers_mutex_);
        if (peers_.size() >= 4096 && peers_.find(from) == peers_.end()) peers_.clear();
        Peer& peer = peers_[from];
        if (peer.name != name) peer.name.assign(name);
        peer.plc = peer.plc || role == Role::kPlc;
      }
      if (at_door) {
        // Through the publisher like every reply (publish_replies: held until the client's
        // reply reader is matched); only when that queue is full too, at once from here.
        if (!busy_replies_.push(door_answer) && !reply_writer_.write(&door_reply)) {
          ++replies_not_written_;
        }
        ++(stale ? stale_repeats_ : busy_requests_);
        continue;
      }
      RequestIn in;
      in.request_id = r.request_id();
      in.tag = tag;
      in.role = role;
      in.client.set(r.client_name().c_str());
      in.interpolator = r.interpolator();
      in.kind = from_msg(r.kind());
      in.command = r.command();
      for (std::size_t k = 0; k < in.command_parameter.size(); ++k) {
        in.command_parameter[k] = r.command_parameter()[k];
      }
      in.axis = r.axis();
      in.value = r.value();
      in.m_func_acknowledged = r.m_func_acknowledged();
      in.m_func_count_acknowledged = r.m_func_count_acknowledged();
      if (in.kind == RequestKind::kWriteMFunc && in.interpolator >= 0 &&
          in.interpolator < opt_.interpolators) {
        in.taken_ns = steady_ns();
        auto& written = *m_written_ns_[static_cast<std::size_t>(in.interpolator)];
        const std::int64_t t0 = written.exchange(0, std::memory_order_acq_rel);
        if (t0 != 0 && handshakes_.size() < opt_.handshake_samples) {
          const MWritten& w = m_written_[static_cast<std::size_t>(in.interpolator)];
          // Only the stamps the atomic published: the publisher may still be writing the rest.
          HandshakeSample h;
          h.written.interpolator = in.interpolator;
          h.written.act_part = w.act_part;
          h.written.handoff_ns = w.handoff_ns;
          h.written.publisher_woke_ns = w.publisher_woke_ns;
          h.written.event_write_begin_ns = w.event_write_begin_ns;
          h.round_trip_ns = in.taken_ns - t0;
          h.taken_ns = in.taken_ns;
          handshakes_.push_back(h);
        }
      }
      requests_.push(in);  // not full: checked above, under request_mutex_
    }
  }
}

void DdsPort::fill_reply(msg::Reply& out, const ReplyOut& r) const {
  out.request_id(r.request_id);
  out.client_name(std::string(r.client.view()));
  out.interpolator(reply_key(r.interpolator));
  out.accepted(r.code == ReplyCode::kAccepted);
  out.code(to_msg(r.code));
  out.reason(std::string(r.reason.view()));
  out.cycle_counter(r.cycle);
}

void DdsPort::log_request_locked(std::string_view client, RecentRequest q) {
  const auto now = Clock::now();
  auto log = recent_requests_.find(client);
  if (log == recent_requests_.end()) {
    if (recent_requests_.size() >= kRecentClients) {
      std::erase_if(recent_requests_,
                    [&](const auto& kv) { return now - kv.second.last > kRecentFor; });
    }
    if (recent_requests_.size() >= kRecentClients) {
      recent_requests_.erase(std::min_element(
          recent_requests_.begin(), recent_requests_.end(),
          [](const auto& a, const auto& b) { return a.second.last < b.second.last; }));
    }
    log = recent_requests_.emplace(std::string(client), RecentLog{}).first;
  }
  log->second.last = now;
  if (log->second.requests.size() >= kRecentRequests) log->second.requests.pop_front();
  log->second.requests.push_back(std::move(q));
}

void DdsPort::take_chunks() {
  // Hand queued chunks to the cycle thread first (keeps the order per interpolator).
  for (std::size_t i = 0; i < backlog_.size(); ++i) {
    while (!backlog_[i].empty() && chunks_[i]->push(backlog_[i].front())) backlog_[i].pop_front();
  }
  while (true) {
    if (spare_ == nullptr && !free_chunks_.pop(spare_)) return;  // all in use: later
    fdds::SampleInfo info;
    if (!dds::take_next(program_reader_, chunk_sample_, info)) return;
    const int i = chunk_sample_.interpolator();
    if (i < 0 || i >= opt_.interpolators) {
      // A client configured for more interpolators, or a flood: said at once, then at most
      // every 10 s (one line per chunk let a sender fill the log as fast as it wrote).
      ++foreign_chunks_;
      if (const auto now = Clock::now(); now >= foreign_note_at_) {
        foreign_note_at_ = now + std::chrono::seconds(10);
        std::fprintf(stderr,
                     "tgm-service: program chunk for interpolator %d dropped (the service hosts "
                     "0..%d; %llu such chunks so far)\n",
                     i, opt_.interpolators - 1, static_cast<unsigned long long>(foreign_chunks_));
      }
      continue;
    }
    {
      const std::lock_guard lock(peers_mutex_);
      StreamFrom& from = stream_from_[static_cast<std::size_t>(i)];
      from.participant = eprosima::fastrtps::rtps::iHandle2GUID(info.publication_handle).guidPrefix;
      from.program_id = chunk_sample_.program_id();
      from.known = true;
    }
    ChunkIn* c = spare_;
    spare_ = nullptr;
    c->interpolator = i;
    c->program_id = chunk_sample_.program_id();
    c->sequence_number = chunk_sample_.sequence_number();
    c->end_of_program = chunk_sample_.end_of_program();
    c->applied = 0;
    c->program.segments.clear();
    c->program.params.clear();
    c->program.messages.clear();
    mapping::WireProblem where;
    const mapping::MapStatus st = mapping::append_chunk(chunk_sample_, c->program, where);
    c->decode_status = static_cast<int>(st);
    c->error.set(st == mapping::MapStatus::kOk
                     ? std::string{}
                     : mapping::describe(st, where, chunk_sample_.sequence_number()));
    auto& backlog = backlog_[static_cast<std::size_t>(i)];
    if (backlog.empty() && chunks_[static_cast<std::size_t>(i)]->push(c)) continue;
    backlog.push_back(c);
  }
}

bool DdsPort::next_peer_notice(PeerNotice& out) {
  return peer_notices_.pop(out);
}

void DdsPort::PeerWatch::on_participant_discovery(
    fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) {
  using Info = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
  const bool dropped = info.status == Info::DROPPED_PARTICIPANT;
  const bool gone = dropped || info.status == Info::REMOVED_PARTICIPANT;
  if (gone || info.status == Info::DISCOVERED_PARTICIPANT) {
    const std::string announced = dds::participant_client_name(info.info.m_userData.data_vec());
    port_.participant_changed(info.info.m_guid.guidPrefix, info.info.m_participantName.c_str(),
                              announced, gone, dropped);
  }
}

const DdsPort::Peer* DdsPort::live_plc_other_than(const GuidPrefix& participant) const {
  for (const auto& [guid, peer] : peers_) {
    if (guid != participant && peer.plc && lost_.count(guid) == 0) return &peer;
  }
  return nullptr;
}

// A Fast DDS thread. Until session 73 nothing watched the clients: a killed tgm-plc or a
// streaming tgm-hmi was never noticed, and the program ran dry in an underrun without a word.
// A participant that dies is dropped when its lease (1 s, config/fastdds_profiles.xml) lapses;
// DESIGN.md section 6 asks for about 100 ms, which the writers' 100 ms liveliness lease was to
// give, but Fast DDS 2.9 reported those lapses only sometimes (a killed tgm-hmi was never
// reported in one of two set-ups), where discovery drops every dead participant.
void DdsPort::participant_changed(const GuidPrefix& participant, std::string_view name_seen,
                                  std::string_view announced, bool gone, bool dropped) {
  if (stopping_) return;
  const std::lock_guard lock(peers_mutex_);
  // A tgm-plc's participant is named <prefix>-plc: known as a PLC before its first request (one
  // started in the middle of a program sends none until the next M-function).
  constexpr std::string_view kPlcSuffix = "-plc";
  if (!gone && name_seen.size() > kPlcSuffix.size() &&
      name_seen.substr(name_seen.size() - kPlcSuffix.size()) == kPlcSuffix &&
      peers_.find(participant) == peers_.end()) {
    if (peers_.size() >= 4096) peers_.clear();
    // Named as its requests will name it when it announced that (tgm::client does), else by
    // its participant's name.
    const std::string_view name = announced.empty() ? name_seen : announced;
    // A second tgm-plc beside one that is there: both acknowledge the M-functions. Meant for a
    // script run beside the machine's PLC; by mistake (a PLC on another host with the same
    // domain and prefix) it is said, as nothing else would show it.
    if (const Peer* other = live_plc_other_than(participant)) {
      PeerNotice n;
      n.kind = PeerNotice::Kind::kPlcJoined;
      n.client.set(name);
      n.other_plc.set(other->name);
      if (peer_notices_.push(n)) {
        std::fprintf(stderr, "tgm-service: tgm-plc '%.*s' joined beside tgm-plc '%s'\n",
                     static_cast<int>(name.size()), name.data(), other->name.c_str());
      }
    }
    peers_[participant] = Peer{std::string(name), true};
  }
  // Said once per loss: a dropped participant (its lease lapsed) is kept in lost_ until it is
  // back or ends; one that ended is forgotten (its GUID never comes back), so that every run of
  // an HMI does not leave an entry behind.
  if (!gone) {
    if (lost_.erase(participant) == 0) return;
  } else if (dropped) {
    if (lost_.size() >= 4096) lost_.clear();
    if (!lost_.insert(participant).second) return;
  } else if (lost_.erase(participant) != 0) {
    peers_.erase(participant);  // its loss was said when it was dropped
    return;
  }
  const auto peer = peers_.find(participant);
  const std::string name = peer != peers_.end() ? peer->second.name : std::string();
  const std::string who = name.empty() ? std::string("a client") : "'" + name + "'";
  const char* why = !gone     ? "is back"
                    : dropped ? "gave no sign of life (it stopped, or the network is down)"
                              : "ended";
  if (peer != peers_.end() && peer->second.plc) {
    PeerNotice n;
    n.kind = gone ? PeerNotice::Kind::kPlcLost : PeerNotice::Kind::kPlcBack;
    n.ended = gone && !dropped;
    n.client.set(name);
    // Another PLC that is there still acknowledges the M-functions (a tgm-plc --script run
    // beside the machine's PLC ends, the machine's goes on).
    if (const Peer* other = live_plc_other_than(participant)) n.other_plc.set(other->name);
    if (peer_notices_.push(n))
      std::fprintf(stderr, "tgm-service: tgm-plc %s %s\n", who.c_str(), why);
  }
  for (std::size_t i = 0; i < stream_from_.size(); ++i) {
    const StreamFrom& s = stream_from_[i];
    if (!s.known || s.participant != participant) continue;
    PeerNotice n;
    n.kind = gone ? PeerNotice::Kind::kStreamLost : PeerNotice::Kind::kStreamBack;
    n.ended = gone && !dropped;
    n.client.set(name);
    n.interpolator = static_cast<int>(i);
    n.program_id = s.program_id;
    if (!peer_notices_.push(n) || n.ended) continue;  // every run's HMI ends so: not logged
    std::fprintf(stderr, "tgm-service: interpolator %zu: the sender %s of program %u %s\n", i,
                 who.c_str(), s.program_id, why);
  }
  if (gone && !dropped && peer != peers_.end()) peers_.erase(peer);
}

void DdsPort::receive_loop() {
  while (!stopping_) {
    bool pending = spare_ == nullptr;
    for (const auto& b : backlog_) pending = pending || !b.empty();
    pending = pending || requests_.full();
    waiter_.wait(pending ? std::chrono::nanoseconds(std::chrono::milliseconds(1))
                         : std::chrono::nanoseconds(std::chrono::milliseconds(100)));
    if (stopping_) break;
    take_requests();
    take_chunks();
  }
}

// ---- publisher thread ----

void DdsPort::publish_event(const EventOut& ev) {
  const auto n = static_cast<std::size_t>(ev.interpolator);
  mapping::to_event(ev.reg, static_cast<std::uint16_t>(ev.interpolator), event_sample_);
  event_sample_.service_instance(service_instance_);
  event_sample_.program_id(ev.program_id);
  event_sample_.event_counter(ev.counter);
  const bool new_m = ev.reg.m_func != 0 && ev.reg.m_func_count != last_m_count_[n];
  last_m_count_[n] = ev.reg.m_func_count;
  // The handshake clock starts before write(), as in the raw ping-pong it is compared with.
  auto& written = *m_written_ns_[n];
  MWritten* rec = nullptr;
  if (new_m) {
    // The receiver reads m_written_ only after exchanging a non-zero stamp (acquire).
    written.store(0, std::memory_order_relaxed);
    MWritten& w = m_written_[n];
    w.interpolator = ev.interpolator;
    w.act_part = ev.reg.act_part;
    w.handoff_ns = ev.queued_ns;
    w.publisher_woke_ns = publisher_woke_ns_;
    w.event_write_begin_ns = steady_ns();
    if (m_published_.size() < m_published_.capacity()) {
      m_pending_[n] = static_cast<std::ptrdiff_t>(m_published_.size());
      m_published_.push_back(w);
      rec = &m_published_.back();
    }
    written.store(w.event_write_begin_ns, std::memory_order_release);
  }
  event_writer_.write(&event_sample_);
  if (rec != nullptr) rec->event_write_end_ns = steady_ns();
  ++events_published_;
}

void DdsPort::publish_state(int i, const InterpolatorSnapshot& s, const Snapshot& all) {
  mapping::to_idl(s.reg, static_cast<std::uint16_t>(i), state_sample_);
  state_sample_.service_instance(service_instance_);
  state_sample_.program_id(s.program_id);
  state_sample_.next_sequence(s.next_sequence);
  state_sample_.buffered_segments(s.buffered_segments);
  state_sample_.message_counter(s.message_counter);
  state_sample_.message_text(std::string(s.message_text.view()));
  state_sample_.axis_letters(std::string(s.axis_letters.view()));
  state_sample_.plc_setup(s.plc_setup);
  state_sample_.machine_digest(s.machine_digest);
  state_sample_.spline_points(s.smoothing.spline_points);
  state_sample_.spline_jerk_mm_s3(s.smoothing.spline_jerk_mm_s3);
  state_sample_.iir_p_e6(s.smoothing.iir_p_e6);
  state_sample_.iir_q_e6(s.smoothing.iir_q_e6);
  state_sample_.iir_f_e6(s.smoothing.iir_f_e6);
  state_sample_.iir_axis_mask(s.smoothing.iir_axis_mask);
  state_sample_.cycle_counter(all.cycle);
  state_sample_.cycle_time_us(opt_.cycle_time_us);
  state_sample_.lateness_last_ns(all.lateness.last_ns);
  state_sample_.lateness_max_ns(all.lateness.max_ns);
  state_sample_.lateness_p999_ns(all.lateness.p999_ns);
  state_sample_.missed_cycles(all.lateness.missed_cycles);
  Published& p = published_[static_cast<std::size_t>(i)];
  std::ptrdiff_t& pending = m_pending_[static_cast<std::size_t>(i)];
  if (pending >= 0)
    m_published_[static_cast<std::size_t>(pending)].state_write_begin_ns = steady_ns();
  state_writer_.write(&state_sample_);
  if (pending >= 0) {
    m_published_[static_cast<std::size_t>(pending)].state_write_end_ns = steady_ns();
    pending = -1;
  }
  ++states_published_;
  p.any = true;
  p.reg = s.reg;
  p.program_id = s.program_id;
  p.next_sequence = s.next_sequence;
  p.message_counter = s.message_counter;
  p.plc_setup = s.plc_setup;
  p.at = Clock::now();
}

void DdsPort::ReplyMatchListener::on_publication_matched(fdds::DataWriter*,
                                                         const fdds::PublicationMatchedStatus& s) {
  const GuidPrefix p =
      eprosima::fastrtps::rtps::iHandle2GUID(s.last_subscription_handle).guidPrefix;
  const std::lock_guard lock(port_.reply_match_mutex_);
  int& readers = port_.reply_readers_[p];
  readers += s.current_count_change;
  if (readers > 0) return;
  port_.reply_readers_.erase(p);
  std::erase_if(port_.client_participants_, [&](const auto& kv) { return kv.second == p; });
}

// The reply topic is VOLATILE: a reply written before the reply writer has matched the
// client's reply reader never reaches it. The client waits until *its* reader has matched the
// service's writer before it sends, but discovery is not symmetric: the service can learn of
// that reader later (tens of milliseconds under load) and answer first. The client then said
// "no reply" for a request the service had executed (found in the sanitizer build, session
// 48). So a reply waits here, in order behind the earlier ones of its client, until the writer
// has matched a reply reader of the participant the request came from, at most
// kReplyMatchWait; the cycle thread never waits for it.
void DdsPort::publish_replies() {
  // The publisher wakes every cycle; most cycles have no reply to write or to hold.
  if (held_replies_.empty() && replies_.front() == nullptr && busy_replies_.front() == nullptr &&
      !repeats_pending_.load(std::memory_order_acquire)) {
    return;
  }
  const auto now = std::chrono::steady_clock::now();
  replies_to_write_.clear();
  {
    // Decided under the lock, written after it: Fast DDS may call the match listener while it
    // holds the writer's own lock, which write() takes.
    const std::lock_guard lock(reply_match_mutex_);
    auto matched = [&](const GuidPrefix& p) { return reply_readers_.count(p) != 0; };
    const bool stopping = stopping_.load(std::memory_order_relaxed);  // the last chance
    for (auto it = held_replies_.begin(); it != held_replies_.end();) {
      const bool ready = matched(it->participant);
      if (!ready && now < it->until && !stopping) {
        ++it;
        continue;
      }
      if (!ready) ++replies_unmatched_;
      replies_to_write_.push_back(std::move(it->reply));
      it = held_replies_.erase(it);
    }
    ReplyOut r;
    msg::Reply reply;
    while (replies_.pop(r) || busy_replies_.pop(r)) {
      fill_reply(reply, r);
      if (const auto log = recent_requests_.find(r.client.view());
          r.tag != 0 && log != recent_requests_.end()) {
        for (RecentRequest& q : log->second.requests) {
          if (q.tag == r.tag) q.reply = reply;
        }
      }
      const auto from = client_participants_.find(r.client.view());
      const bool hold =
          from != client_participants_.end() && held_replies_.size() < 1024 &&
          (!matched(from->second) ||
           std::any_of(held_replies_.begin(), held_replies_.end(),
                       [&](const HeldReply& h) { return h.participant == from->second; }));
      if (hold) {
        held_replies_.push_back({reply, from->second, now + kReplyMatchWait});
        ++replies_held_;
      } else {
        replies_to_write_.push_back(reply);
      }
    }
    // Repeats: not held (their client has waited already), after the replies above, which
    // they may repeat.
    repeats_pending_.store(false, std::memory_order_relaxed);
    for (msg::Reply& again : repeat_replies_) replies_to_write_.push_back(std::move(again));
    repeat_replies_.clear();
  }
  for (msg::Reply& w : replies_to_write_) {
    if (!reply_writer_.write(&w)) ++replies_not_written_;
  }
}

void DdsPort::publish_loop() {
  const Snapshot* snap = nullptr;
  std::uint32_t seen = doorbell_.value();
  while (true) {
    doorbell_.wait(seen, std::chrono::milliseconds(10));
    publisher_woke_ns_ = steady_ns();
    seen = doorbell_.value();
    publish_replies();
    MessageOut m;
    msg::Message message;
    while (messages_.pop(m)) {
      message.interpolator(static_cast<std::uint16_t>(m.interpolator));
      message.severity(m.severity == MessageOut::Severity::kError     ? msg::SEVERITY_ERROR
                       : m.severity == MessageOut::Severity::kWarning ? msg::SEVERITY_WARNING
                                                                      : msg::SEVERITY_INFO);
      message.text(std::string(m.text.view()));
      message.source_line(m.source_line);
      message.program_id(m.program_id);
      message.cycle(m.cycle);
      message_writer_.write(&message);
    }
    if (stopping_) break;
    // Another service on the domain (two started within each other's wait, see
    // other_service()): said once per instance, on standard error and to the HMIs. In its
    // first cycles a service gives way to it (gives_way(), DdsPortOptions::yield_window_cycles);
    // after them it does not (one that drives a machine is not stopped by a newcomer).
    if (const std::uint64_t other = other_latest_.load(std::memory_order_acquire);
        other != 0 && other != other_reported_) {
      other_reported_ = other;
      const std::uint64_t mine = snap != nullptr ? snap->cycle : 0;
      const bool young = in_yield_window(mine, opt_.yield_window_cycles);
      const bool give_way =
          gives_way(mine, service_instance_, other_cycles_.load(std::memory_order_relaxed), other,
                    opt_.yield_window_cycles);
      char text[256];
      if (give_way) {
        std::snprintf(text, sizeof text,
                      "another tgm-service (instance %016llx) serves this DDS domain: this one "
                      "(instance %016llx, started with it or after it) gives way and exits",
                      static_cast<unsigned long long>(other),
                      static_cast<unsigned long long>(service_instance_));
      } else if (young) {
        std::snprintf(text, sizeof text,
                      "another tgm-service (instance %016llx) started on this DDS domain with "
                      "this one; it should give way and exit: if it does not, stop one of them",
                      static_cast<unsigned long long>(other));
      } else {
        std::snprintf(text, sizeof text,
                      "another tgm-service (instance %016llx) serves this DDS domain: both take "
                      "every request and program sent to it; stop one of them",
                      static_cast<unsigned long long>(other));
      }
      std::fprintf(stderr, "tgm-service: %s\n", text);
      if (give_way) yielded_to_.store(other, std::memory_order_release);
      message.interpolator(0);
      message.severity(msg::SEVERITY_ERROR);
      message.text(text);
      message.source_line(0);
      message.program_id(0);
      message.cycle(mine);
      message_writer_.write(&message);
    }
    // Events first, every one queued, in order: they are small and the PLC acts on them
    // (M-function handshake). The snapshot is read after them, so the state that follows them
    // is at least as new; it stays the source of truth.
    std::array<bool, kMaxInterpolators> evented{};
    EventOut ev;
    while (events_.pop(ev)) {
      publish_event(ev);
      evented[static_cast<std::size_t>(ev.interpolator)] = true;
    }
    const bool fresh = latest_.read(snap);
    if (snap == nullptr) continue;
    const auto now = Clock::now();
    for (int i = 0; i < snap->count; ++i) {
      const InterpolatorSnapshot& s = snap->ip[static_cast<std::size_t>(i)];
      const Published& p = published_[static_cast<std::size_t>(i)];
      bool send = !p.any || now - p.at >= opt_.state_period || evented[static_cast<std::size_t>(i)];
      if (!send && fresh) {
        send = event_due(s.reg, s.program_id, p.reg, p.program_id) ||
               s.message_counter != p.message_counter || s.plc_setup != p.plc_setup ||
               ((s.next_sequence != p.next_sequence || progress_changed(s.reg, p.reg)) &&
                now - p.at >= opt_.progress_period);
      }
      if (send) publish_state(i, s, *snap);
    }
    // Every setpoint the cycle thread queued, in order (after the states: a drive's new
    // program shows in the state before its first setpoint, as before).
    for (SetpointOut sp; setpoints_.pop(sp);) {
      setpoint_sample_.interpolator(sp.interpolator);
      setpoint_sample_.cycle_counter(sp.cycle);
      setpoint_sample_.position() = sp.position;
      setpoint_sample_.position_inc() = sp.position_inc;
      setpoint_writer_.write(&setpoint_sample_);
      ++setpoints_published_;
    }
  }
}

}  // namespace tgm::service
