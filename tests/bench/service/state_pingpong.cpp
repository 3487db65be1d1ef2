// tgm_bench_state_pingpong: the raw Fast DDS reference for the M-function handshake. The ping
// side writes the sample that carries a new M_Func with its topic's QoS profile; the pong side
// answers each with a tgm::msg::Request (the PLC's M_Func = 0) with the request profile. Same
// types, sizes and QoS as the real handshake, without the service's cycle. --sample request
// pings the request itself and answers with a tgm::msg::Reply (the request / reply round trip
// of every HMI and PLC request; BENCHMARKS.md, section DDS).
//
//   tgm_bench_state_pingpong [--role both|ping|pong|sink] [--sample state|event|request]
//                            [--mode waitset|listener|both] [--count N] [--warmup N] [--block N]
//                            [--domain D] [--profiles FILE] [--sinks N] [--interval-us N]
//
// --sample state: tgm::msg::InterpolatorState with the tgm_state profiles (3,836 B with three
//   axis letters, the sample the service wrote first before the event topic existed); event:
//   tgm::msg::InterpolatorEvent with the tgm_event profiles (what the service writes first
//   now); request: tgm::msg::Request with the tgm_request profiles, answered by a
//   tgm::msg::Reply with the tgm_reply ones.
// --mode waitset: the pong waits on a WaitSet in its main thread, takes, writes the Request; the
//   ping waits on a WaitSet for it and stops the clock after the take.
// --mode listener: the pong answers from its DataReaderListener (Fast DDS's receive thread), as
//   tgm-plc does from its event callback; the ping takes the Request in a listener and stops the
//   clock there, as tgm-service does (its request listener).
// --mode both: the two modes on separate topics, alternating in blocks of --block round trips,
//   so that both see the same load over the run; each mode is reported on its own.
// The clock starts just before write() and stops when the Request is taken, as the service's
// "DDS part" of the handshake does. The pong puts the time it began its write() into
// Request.value (Reply.cycle_counter for --sample request; same clock, same host), so the
// return hop (pong write() begins -> answer taken) is reported too: it compares with the
// handshake's "ack request call -> service took it".
// --sinks N starts N more processes that only read the pinged samples (like tgm-hmi next to
// tgm-plc on the state): the ping side then writes every sample to N + 1 readers.
// --interval-us N pauses N us between round trips (not timed), as sporadic as the handshake
// (one M-function every few cycles); 0 = back to back.
//
// Output: one line per mode beginning with "RESULT" (parsed by handshake_trace.py --raw).
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <fastdds/dds/subscriber/DataReaderListener.hpp>

#include "tgm/cli_args.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

extern char** environ;

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
namespace fdds = eprosima::fastdds::dds;

struct Options {
  std::string role = "both";
  std::string sample = "state";
  std::string mode = "waitset";
  int count = 5000;
  int warmup = 500;
  int block = 500;
  int domain = 78;
  int sinks = 0;
  int interval_us = 0;
  std::string profiles = TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
};

enum Mode { kWaitSet = 0, kListener = 1 };
const char* mode_name(int m) {
  return m == kWaitSet ? "waitset" : "listener";
}

// The pinged topic of a mode: the sample's own profiles under a bench name.
tgm::dds::TopicSpec ping_topic(const Options& o, int mode) {
  tgm::dds::TopicSpec s = o.sample == "event"     ? tgm::dds::kEventTopic
                          : o.sample == "request" ? tgm::dds::kRequestTopic
                                                  : tgm::dds::kStateTopic;
  static const std::string names[2][3] = {
      {"tgm_bench_state", "tgm_bench_event_w", "tgm_bench_request_w"},
      {"tgm_bench_state_l", "tgm_bench_event_l", "tgm_bench_request_l"}};
  s.name = names[mode][o.sample == "event" ? 1 : o.sample == "request" ? 2 : 0];
  return s;
}
// The answer's topic: the request profiles, or the reply ones when the request is pinged.
tgm::dds::TopicSpec ack_topic(const Options& o, int mode) {
  tgm::dds::TopicSpec s = o.sample == "request" ? tgm::dds::kReplyTopic : tgm::dds::kRequestTopic;
  s.name = mode == kWaitSet ? "tgm_bench_ack" : "tgm_bench_ack_l";
  return s;
}
tgm::DdsConfig config(const Options& o) {
  tgm::DdsConfig c;
  c.domain_id = o.domain;
  c.profiles_file = o.profiles;
  c.participant_prefix = "tgm-bench";
  return c;
}
bool uses(const Options& o, int mode) {
  return o.mode == "both" || o.mode == mode_name(mode);
}

double now_ns() {
  return static_cast<double>(Clock::now().time_since_epoch().count());
}

constexpr std::uint64_t kQuitId = std::numeric_limits<std::uint64_t>::max();

// The pinged samples: a round trip's id, and the quit sample that ends the pong and the sinks.
template <class Sample>
std::uint64_t ping_id(const Sample& s) {
  return s.cycle_counter();
}
template <class Sample>
void set_ping_id(Sample& s, std::uint64_t id) {
  s.cycle_counter(id);
}
template <class Sample>
bool is_quit(const Sample& s) {
  return s.m_func() < 0;
}
template <class Sample>
void make_quit(Sample& s) {
  s.m_func(-1);
}
template <class Sample>
void init_ping(Sample& s, const std::string&) {
  s.m_func(51);
}
template <>
std::uint64_t ping_id(const tgm::msg::Request& s) {
  return s.request_id();
}
template <>
void set_ping_id(tgm::msg::Request& s, std::uint64_t id) {
  s.request_id(id);
}
template <>
bool is_quit(const tgm::msg::Request& s) {
  return s.request_id() == kQuitId;
}
template <>
void make_quit(tgm::msg::Request& s) {
  s.request_id(kQuitId);
}
template <>
void init_ping(tgm::msg::Request& s, const std::string& name) {
  s.role(tgm::msg::CLIENT_ROLE_PLC);
  s.kind(tgm::msg::REQUEST_KIND_WRITE_M_FUNC);
  s.client_name(name);
}

// The pong's answer: an M_Func = 0 request as tgm-plc writes it; to a pinged request, the
// service's accepting reply.
template <class Sample>
struct AnswerOf {
  using Type = tgm::msg::Request;
  using PubSub = tgm::msg::RequestPubSubType;
};
template <>
struct AnswerOf<tgm::msg::Request> {
  using Type = tgm::msg::Reply;
  using PubSub = tgm::msg::ReplyPubSubType;
};
template <class Answer>
Answer pong_answer(const std::string& name) {
  Answer r;
  if constexpr (std::is_same_v<Answer, tgm::msg::Reply>) {
    r.client_name(name);
    r.accepted(true);
    r.code(tgm::msg::REPLY_CODE_ACCEPTED);
  } else {
    init_ping(r, name);  // the PLC's M_Func = 0 request
  }
  return r;
}
// The answer carries the id and the time the pong began its write() (ns, steady clock).
void stamp(tgm::msg::Request& a, std::uint64_t id) {
  a.request_id(id);
  a.value(now_ns());
}
void stamp(tgm::msg::Reply& a, std::uint64_t id) {
  a.request_id(id);
  a.cycle_counter(static_cast<std::uint64_t>(now_ns()));
}
double pong_write_ns(const tgm::msg::Request& a) {
  return a.value();
}
double pong_write_ns(const tgm::msg::Reply& a) {
  return static_cast<double>(a.cycle_counter());
}

// Answers every sample waiting in `reader` with `ack` (stamped with the sample's id and the time
// it was written); true when the quit sample was among them.
template <class Sample, class Answer>
bool answer_all(fdds::DataReader& reader, Sample& s, Answer& ack, fdds::DataWriter& acks) {
  bool quit = false;
  while (tgm::dds::take_next(reader, s)) {
    if (is_quit(s)) {
      quit = true;
      continue;
    }
    stamp(ack, ping_id(s));
    acks.write(&ack);
  }
  return quit;
}

// Pong side of the listener mode: answers every sample from Fast DDS's receive thread.
template <class Sample>
class PongListener final : public fdds::DataReaderListener {
 public:
  using Answer = typename AnswerOf<Sample>::Type;
  PongListener(fdds::DataWriter& acks, const std::string& name)
      : acks_(acks), r_(pong_answer<Answer>(name)) {}
  void on_data_available(fdds::DataReader* reader) override {
    const std::lock_guard lock(mutex_);
    if (detached_) return;
    if (answer_all(*reader, s_, r_, acks_)) quit = true;
  }
  void detach() {
    const std::lock_guard lock(mutex_);
    detached_ = true;
  }
  std::atomic<bool> quit{false};

 private:
  fdds::DataWriter& acks_;
  std::mutex mutex_;
  bool detached_ = false;
  Sample s_;
  Answer r_;
};

// Ping side of the listener mode: takes the answer in Fast DDS's receive thread, stops the
// clock there and tells the ping thread.
template <class Answer>
class AckListener final : public fdds::DataReaderListener {
 public:
  void on_data_available(fdds::DataReader* reader) override {
    const std::lock_guard lock(mutex_);
    if (detached_) return;
    while (tgm::dds::take_next(*reader, r_)) {
      if (r_.request_id() == expected_) {
        taken_ = Clock::now();
        pong_write_ns_ = pong_write_ns(r_);
        got_ = true;
        cv_.notify_one();
      }
    }
  }
  void expect(std::uint64_t id) {
    const std::lock_guard lock(mutex_);
    expected_ = id;
    got_ = false;
  }
  //! Time the expected Request was taken; false on timeout.
  bool wait(Clock::time_point& taken, double& pong_write_ns, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [&] { return got_; })) return false;
    taken = taken_;
    pong_write_ns = pong_write_ns_;
    return true;
  }
  void detach() {
    const std::lock_guard lock(mutex_);
    detached_ = true;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool detached_ = false;
  bool got_ = false;
  std::uint64_t expected_ = 0;
  Clock::time_point taken_{};
  double pong_write_ns_ = 0;
  Answer r_;
};

template <class Sample, class SampleType>
int run_pong(const Options& o) {
  std::unique_ptr<PongListener<Sample>> listener;  // outlives the participant's threads
  tgm::dds::Participant p(config(o), "pong");
  fdds::DataReader* ws_reader = nullptr;
  fdds::DataWriter* ws_acks = nullptr;
  fdds::DataReader* l_reader = nullptr;
  if (uses(o, kWaitSet)) {
    ws_reader = &p.reader<SampleType>(ping_topic(o, kWaitSet));
    ws_acks = &p.writer<typename AnswerOf<Sample>::PubSub>(ack_topic(o, kWaitSet));
  }
  if (uses(o, kListener)) {
    l_reader = &p.reader<SampleType>(ping_topic(o, kListener));
    auto& acks = p.writer<typename AnswerOf<Sample>::PubSub>(ack_topic(o, kListener));
    listener = std::make_unique<PongListener<Sample>>(acks, p.name());
    l_reader->set_listener(listener.get(), fdds::StatusMask::data_available());
  }
  std::optional<tgm::dds::DataWaiter> waiter;
  if (ws_reader != nullptr) waiter.emplace(std::initializer_list<fdds::DataReader*>{ws_reader});
  Sample s;
  auto r = pong_answer<typename AnswerOf<Sample>::Type>(p.name());
  const auto give_up = Clock::now() + 600s;
  bool ws_quit = ws_reader == nullptr;
  while (Clock::now() < give_up && !(ws_quit && (!listener || listener->quit))) {
    if (waiter) {
      waiter->wait(100ms);
      if (answer_all(*ws_reader, s, r, *ws_acks)) ws_quit = true;
    } else {
      std::this_thread::sleep_for(10ms);
    }
  }
  if (listener) {
    l_reader->set_listener(nullptr);
    listener->detach();
  }
  return 0;
}

template <class Sample, class SampleType>
int run_sink(const Options& o) {
  tgm::dds::Participant p(config(o), "sink");
  std::vector<fdds::DataReader*> readers;
  for (int m : {kWaitSet, kListener}) {
    if (uses(o, m)) readers.push_back(&p.reader<SampleType>(ping_topic(o, m)));
  }
  tgm::dds::DataWaiter waiter(readers.size() == 2
                                  ? std::initializer_list<fdds::DataReader*>{readers[0], readers[1]}
                                  : std::initializer_list<fdds::DataReader*>{readers[0]});
  Sample s;
  int quits = 0;
  const auto give_up = Clock::now() + 600s;
  while (Clock::now() < give_up && quits < static_cast<int>(readers.size())) {
    waiter.wait(500ms);
    for (auto* r : readers) {
      while (tgm::dds::take_next(*r, s)) {
        if (is_quit(s)) ++quits;
      }
    }
  }
  return 0;
}

double pct(const std::vector<double>& us, double q) {
  return us[std::min(us.size() - 1,
                     static_cast<std::size_t>(q * static_cast<double>(us.size() - 1) + 0.5))];
}

template <class Sample, class SampleType>
int run_ping(const Options& o) {
  using Answer = typename AnswerOf<Sample>::Type;
  AckListener<Answer> ack_listener;  // outlives the participant's threads
  tgm::dds::Participant p(config(o), "ping");
  struct Side {
    bool on = false;
    fdds::DataWriter* writer = nullptr;
    fdds::DataReader* acks = nullptr;
    std::vector<double> us;
    std::vector<double> back_us;  // pong write() begins -> Request taken
    int timeouts = 0;
  };
  Side side[2];
  for (int m : {kWaitSet, kListener}) {
    if (!uses(o, m)) continue;
    side[m].on = true;
    side[m].writer = &p.writer<SampleType>(ping_topic(o, m));
    side[m].acks = &p.reader<typename AnswerOf<Sample>::PubSub>(ack_topic(o, m));
    if (!tgm::dds::wait_for_match(*side[m].writer, 1 + o.sinks, 30s) ||
        !tgm::dds::wait_for_match(*side[m].acks, 1, 30s)) {
      std::fprintf(stderr, "tgm_bench_state_pingpong: no pong on domain %d (%s)\n", o.domain,
                   mode_name(m));
      return 1;
    }
  }
  if (side[kListener].on)
    side[kListener].acks->set_listener(&ack_listener, fdds::StatusMask::data_available());
  // The pong attaches its listener just after its reader exists: give it that moment.
  std::this_thread::sleep_for(200ms);
  std::optional<tgm::dds::DataWaiter> waiter;
  if (side[kWaitSet].on)
    waiter.emplace(std::initializer_list<fdds::DataReader*>{side[kWaitSet].acks});
  Sample s;
  init_ping(s, p.name());
  Answer r;
  const int modes = side[0].on && side[1].on ? 2 : 1;
  const int first = side[0].on ? 0 : 1;
  // Warm-up rounds of every mode first, then the measured ones in alternating blocks.
  const int total = modes * o.warmup + o.count;
  for (int i = 0; i < total; ++i) {
    const bool warm = i < modes * o.warmup;
    const int k = warm ? i / std::max(1, o.warmup) : (i - modes * o.warmup) / std::max(1, o.block);
    const int m = modes == 1 ? first : k % 2;
    Side& sd = side[m];
    set_ping_id(s, static_cast<std::uint64_t>(i) + 1);
    bool got = false;
    Clock::time_point t1{};
    double pong_write_ns = 0;
    if (m == kListener) ack_listener.expect(ping_id(s));
    const auto t0 = Clock::now();
    sd.writer->write(&s);
    if (m == kListener) {
      got = ack_listener.wait(t1, pong_write_ns, 2000ms);
    } else {
      while (!got) {
        if (!waiter->wait(2s)) break;
        while (tgm::dds::take_next(*sd.acks, r)) {
          if (r.request_id() != ping_id(s)) continue;
          got = true;
          pong_write_ns = ::pong_write_ns(r);
        }
      }
      t1 = Clock::now();
    }
    if (!got) {
      ++sd.timeouts;
      continue;
    }
    if (!warm) {
      sd.us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      sd.back_us.push_back((static_cast<double>(t1.time_since_epoch().count()) - pong_write_ns) /
                           1e3);
    }
    if (o.interval_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(o.interval_us));
  }
  make_quit(s);
  for (Side& sd : side) {
    if (!sd.on) continue;
    sd.writer->write(&s);
    sd.writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(2, 0));
  }
  if (side[kListener].on) {
    side[kListener].acks->set_listener(nullptr);
    ack_listener.detach();
  }
  SampleType st;
  typename AnswerOf<Sample>::PubSub rt;
  r = pong_answer<Answer>(p.name());  // as the pong's (about as long as tgm-plc's "tgm-plc-PID")
  const bool request = o.sample == "request";
  std::printf(
      "raw %s->%s ping-pong (%s %u B -> %s %u B serialized, %s QoS, domain %d), sample "
      "readers %d\n",
      o.sample.c_str(), request ? "reply" : "request",
      o.sample == "event" ? "InterpolatorEvent"
      : request           ? "Request"
                          : "InterpolatorState",
      st.getSerializedSizeProvider(&s)(), request ? "Reply" : "Request",
      rt.getSerializedSizeProvider(&r)(), std::string(ping_topic(o, first).writer_profile).c_str(),
      o.domain, 1 + o.sinks);
  int rc = 0;
  for (int m : {kWaitSet, kListener}) {
    Side& sd = side[m];
    if (!sd.on) continue;
    if (sd.us.empty() || sd.timeouts != 0) rc = 1;
    if (sd.us.empty()) {
      std::printf("RESULT sample=%s mode=%s n=0 timeouts=%d\n", o.sample.c_str(), mode_name(m),
                  sd.timeouts);
      continue;
    }
    std::sort(sd.us.begin(), sd.us.end());
    std::sort(sd.back_us.begin(), sd.back_us.end());
    std::printf(
        "RESULT sample=%s mode=%s interval_us=%d n=%zu timeouts=%d min_us=%.1f median_us=%.1f "
        "p99_us=%.1f p999_us=%.1f "
        "max_us=%.1f return_median_us=%.1f\n",
        o.sample.c_str(), mode_name(m), o.interval_us, sd.us.size(), sd.timeouts, sd.us.front(),
        pct(sd.us, 0.5), pct(sd.us, 0.99), pct(sd.us, 0.999), sd.us.back(), pct(sd.back_us, 0.5));
  }
  return rc;
}

template <class Sample, class SampleType>
int run(const Options& o, char** argv) {
  if (o.role == "pong") return run_pong<Sample, SampleType>(o);
  if (o.role == "ping") return run_ping<Sample, SampleType>(o);
  if (o.role == "sink") return run_sink<Sample, SampleType>(o);
  const std::string dom = std::to_string(o.domain);
  std::vector<pid_t> pids;
  for (int k = 0; k <= o.sinks; ++k) {
    std::vector<std::string> args{argv[0],    "--role",   k == 0 ? "pong" : "sink",
                                  "--domain", dom,        "--profiles",
                                  o.profiles, "--sample", o.sample,
                                  "--mode",   o.mode};
    std::vector<char*> cargs;
    for (auto& s : args) cargs.push_back(s.data());
    cargs.push_back(nullptr);
    pid_t pid = 0;
    if (posix_spawn(&pid, argv[0], nullptr, nullptr, cargs.data(), environ) != 0) return 1;
    pids.push_back(pid);
  }
  const int rc = run_ping<Sample, SampleType>(o);
  for (pid_t pid : pids) {
    int st = 0;
    waitpid(pid, &st, 0);
  }
  return rc;
}

constexpr const char* kUsage =
    "usage: tgm_bench_state_pingpong [--role both|ping|pong|sink] [--sample state|event|request]\n"
    "                                [--mode waitset|listener|both] [--count N] [--warmup N]\n"
    "                                [--block N] [--domain D] [--profiles F] [--sinks N]\n"
    "                                [--interval-us N]\n"
    "The raw Fast DDS reference for the M-function handshake: the pinged sample (state or event,\n"
    "with its topic's QoS) is answered with the PLC's Request; a pinged Request with the\n"
    "service's Reply. One RESULT line per mode.\n"
    "  --role R         both (default: pong and sinks as child processes), ping, pong or sink\n"
    "  --sample S       state (InterpolatorState), event (InterpolatorEvent) or request\n"
    "                   (Request -> Reply); default state\n"
    "  --mode M         waitset, listener or both (alternating blocks); default waitset\n"
    "  --count N        measured round trips, 1..100000000 (default 5000)\n"
    "  --warmup N       round trips per mode not counted, 0..100000000 (default 500)\n"
    "  --block N        round trips per block with --mode both, 1..100000000 (default 500)\n"
    "  --domain D       DDS domain, 0..232 (default 78)\n"
    "  --profiles F     Fast DDS profiles XML (default: config/fastdds_profiles.xml)\n"
    "  --sinks N        extra processes that only read the pinged samples, 0..16 (default 0)\n"
    "  --interval-us N  pause between round trips, 0..10000000 us (default 0: back to back)\n";

}  // namespace

int main(int argc, char** argv) {
  Options o;
  tgm::cli::ArgReader args(argc, argv, "tgm_bench_state_pingpong");
  while (args.more()) {
    if (args.help_flag()) {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (args.flag("--role", o.role) || args.flag("--sample", o.sample) ||
        args.flag("--mode", o.mode) || args.whole_flag("--count", 1, 100'000'000, o.count) ||
        args.whole_flag("--warmup", 0, 100'000'000, o.warmup) ||
        args.whole_flag("--block", 1, 100'000'000, o.block) ||
        args.whole_flag("--domain", 0, 232, o.domain) || args.flag("--profiles", o.profiles) ||
        args.whole_flag("--sinks", 0, 16, o.sinks) ||
        args.whole_flag("--interval-us", 0, 10'000'000, o.interval_us)) {
      continue;
    }
    return args.fail();
  }
  if (args.failed()) return 2;
  if (o.role != "both" && o.role != "ping" && o.role != "pong" && o.role != "sink")
    return args.usage_error("--role must be both, ping, pong or sink, not '" + o.role + "'");
  if (o.sample != "state" && o.sample != "event" && o.sample != "request")
    return args.usage_error("--sample must be state, event or request, not '" + o.sample + "'");
  if (o.mode != "waitset" && o.mode != "listener" && o.mode != "both")
    return args.usage_error("--mode must be waitset, listener or both, not '" + o.mode + "'");
  try {
    if (o.sample == "event")
      return run<tgm::msg::InterpolatorEvent, tgm::msg::InterpolatorEventPubSubType>(o, argv);
    if (o.sample == "request") return run<tgm::msg::Request, tgm::msg::RequestPubSubType>(o, argv);
    return run<tgm::msg::InterpolatorState, tgm::msg::InterpolatorStatePubSubType>(o, argv);
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm_bench_state_pingpong: %s\n", e.what());
    return 1;
  }
}
