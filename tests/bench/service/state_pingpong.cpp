// tgm_bench_state_pingpong: the raw Fast DDS reference for the M-function handshake. The ping
// side writes a tgm::msg::InterpolatorState (the sample that carries a new M_Func) with the state
// QoS profile; the pong side answers each with a tgm::msg::Request (the PLC's M_Func = 0) with the
// request profile. Same types, sizes and QoS as the real handshake, without the service's cycle.
//
//   tgm_bench_state_pingpong [--role both|ping|pong|sink] [--count N] [--warmup N] [--domain D]
//                            [--profiles FILE] [--sinks N]
//
// --sinks N starts N more processes that only read the states (like tgm-hmi next to tgm-plc): the
// ping side then writes every state to N + 1 readers.
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

extern char** environ;

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string role = "both";
  int count = 5000;
  int warmup = 500;
  int domain = 78;
  int sinks = 0;
  std::string profiles = TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
};

tgm::dds::TopicSpec state_topic() {
  tgm::dds::TopicSpec s = tgm::dds::kStateTopic;
  s.name = "tgm_bench_state";
  return s;
}
tgm::dds::TopicSpec ack_topic() {
  tgm::dds::TopicSpec s = tgm::dds::kRequestTopic;
  s.name = "tgm_bench_ack";
  return s;
}
tgm::DdsConfig config(const Options& o) {
  tgm::DdsConfig c;
  c.domain_id = o.domain;
  c.profiles_file = o.profiles;
  c.participant_prefix = "tgm-bench";
  return c;
}

int run_pong(const Options& o) {
  tgm::dds::Participant p(config(o), "pong");
  auto& states = p.reader<tgm::msg::InterpolatorStatePubSubType>(state_topic());
  auto& acks = p.writer<tgm::msg::RequestPubSubType>(ack_topic());
  tgm::dds::DataWaiter waiter({&states});
  tgm::msg::InterpolatorState s;
  tgm::msg::Request r;
  r.role(tgm::msg::CLIENT_ROLE_PLC);
  r.kind(tgm::msg::REQUEST_KIND_WRITE_M_FUNC);
  r.client_name(p.name());
  const auto give_up = Clock::now() + 600s;
  while (Clock::now() < give_up) {
    waiter.wait(500ms);
    while (tgm::dds::take_next(states, s)) {
      if (s.m_func() < 0) return 0;  // quit
      r.request_id(s.cycle_counter());
      acks.write(&r);
    }
  }
  return 0;
}

int run_sink(const Options& o) {
  tgm::dds::Participant p(config(o), "sink");
  auto& states = p.reader<tgm::msg::InterpolatorStatePubSubType>(state_topic());
  tgm::dds::DataWaiter waiter({&states});
  tgm::msg::InterpolatorState s;
  const auto give_up = Clock::now() + 600s;
  while (Clock::now() < give_up) {
    waiter.wait(500ms);
    while (tgm::dds::take_next(states, s)) {
      if (s.m_func() < 0) return 0;  // quit
    }
  }
  return 0;
}

int run_ping(const Options& o) {
  tgm::dds::Participant p(config(o), "ping");
  auto& states = p.writer<tgm::msg::InterpolatorStatePubSubType>(state_topic());
  auto& acks = p.reader<tgm::msg::RequestPubSubType>(ack_topic());
  if (!tgm::dds::wait_for_match(states, 1 + o.sinks, 30s) || !tgm::dds::wait_for_match(acks, 1, 30s)) {
    std::fprintf(stderr, "tgm_bench_state_pingpong: no pong on domain %d\n", o.domain);
    return 1;
  }
  tgm::dds::DataWaiter waiter({&acks});
  tgm::msg::InterpolatorState s;
  s.m_func(51);
  s.message_text("");
  tgm::msg::Request r;
  std::vector<double> us;
  int timeouts = 0;
  for (int i = 0; i < o.warmup + o.count; ++i) {
    s.cycle_counter(static_cast<std::uint64_t>(i) + 1);
    const auto t0 = Clock::now();
    states.write(&s);
    bool got = false;
    while (!got) {
      if (!waiter.wait(2s)) break;
      while (tgm::dds::take_next(acks, r)) got = got || r.request_id() == s.cycle_counter();
    }
    const auto t1 = Clock::now();
    if (!got) {
      ++timeouts;
      continue;
    }
    if (i >= o.warmup) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  s.m_func(-1);
  states.write(&s);
  states.wait_for_acknowledgments(eprosima::fastrtps::Duration_t(2, 0));
  if (us.empty()) return 1;
  std::sort(us.begin(), us.end());
  auto pct = [&](double q) { return us[std::min(us.size() - 1, static_cast<std::size_t>(q * static_cast<double>(us.size() - 1) + 0.5))]; };
  tgm::msg::InterpolatorStatePubSubType st;
  tgm::msg::RequestPubSubType rt;
  std::printf("raw state->request ping-pong (InterpolatorState %u B -> Request %u B serialized, domain %d)\n",
              st.getSerializedSizeProvider(&s)(), rt.getSerializedSizeProvider(&r)(), o.domain);
  std::printf("round trips %zu (warm-up %d, timeouts %d), state readers %d\n", us.size(), o.warmup, timeouts,
              1 + o.sinks);
  std::printf("min %.1f us  median %.1f us  p99 %.1f us  p99.9 %.1f us  max %.1f us\n", us.front(), pct(0.5),
              pct(0.99), pct(0.999), us.back());
  return timeouts == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "usage: %s [--role both|ping|pong|sink] [--count N] [--warmup N] [--domain D] [--profiles F] [--sinks N]\n",
                   argv[0]);
      return 2;
    }
    if (a == "--role") o.role = argv[++i];
    else if (a == "--count") o.count = std::atoi(argv[++i]);
    else if (a == "--warmup") o.warmup = std::atoi(argv[++i]);
    else if (a == "--domain") o.domain = std::atoi(argv[++i]);
    else if (a == "--profiles") o.profiles = argv[++i];
    else if (a == "--sinks") o.sinks = std::atoi(argv[++i]);
    else return 2;
  }
  try {
    if (o.role == "pong") return run_pong(o);
    if (o.role == "ping") return run_ping(o);
    if (o.role == "sink") return run_sink(o);
    const std::string dom = std::to_string(o.domain);
    std::vector<pid_t> pids;
    for (int k = 0; k <= o.sinks; ++k) {
      std::vector<std::string> args{argv[0], "--role", k == 0 ? "pong" : "sink", "--domain", dom, "--profiles",
                                    o.profiles};
      std::vector<char*> cargs;
      for (auto& s : args) cargs.push_back(s.data());
      cargs.push_back(nullptr);
      pid_t pid = 0;
      if (posix_spawn(&pid, argv[0], nullptr, nullptr, cargs.data(), environ) != 0) return 1;
      pids.push_back(pid);
    }
    const int rc = run_ping(o);
    for (pid_t pid : pids) {
      int st = 0;
      waitpid(pid, &st, 0);
    }
    return rc;
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm_bench_state_pingpong: %s\n", e.what());
    return 1;
  }
}
