// tgm_dds_pingpong: round-trip latency of a raw Fast DDS ping-pong with the samples and QoS of
// tgm's request / reply path (tgm::msg::Request out, tgm::msg::Reply back, profiles
// tgm_request_* / tgm_reply_*). It is the reference for the M-function handshake round trip,
// which travels the same topics plus one state sample.
//
//   tgm_dds_pingpong [--role both|ping|pong] [--count N] [--warmup N] [--domain D]
//                    [--profiles FILE]
//
// --role both (default) starts the pong side as a second process (this program with --role
// pong) and runs the ping side here. Results: min / median / p99 / p99.9 / max in microseconds.
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "tgm/cli_args.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

extern char** environ;

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr std::uint64_t kQuitId = std::numeric_limits<std::uint64_t>::max();

struct Options {
  std::string role = "both";
  int count = 20000;
  int warmup = 2000;
  int domain = 77;
  std::string profiles = TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
};

tgm::dds::TopicSpec ping_topic() {
  tgm::dds::TopicSpec s = tgm::dds::kRequestTopic;
  s.name = "tgm_bench_ping";
  return s;
}
tgm::dds::TopicSpec pong_topic() {
  tgm::dds::TopicSpec s = tgm::dds::kReplyTopic;
  s.name = "tgm_bench_pong";
  return s;
}

tgm::DdsConfig dds_config(const Options& o) {
  tgm::DdsConfig c;
  c.domain_id = o.domain;
  c.profiles_file = o.profiles;
  c.participant_prefix = "tgm-bench";
  return c;
}

// Set by SIGINT / SIGTERM (only an atomic store is async-signal-safe; the loop polls it).
std::atomic<bool> g_signalled{false};
void on_signal(int) { g_signalled = true; }

// The pong side: answers every request with a reply carrying its id (STYLE.md application
// shape: entities in the constructor, run() / stop(), a WaitSet loop).
class Pong {
 public:
  explicit Pong(const Options& o)
      : participant_(dds_config(o), "pong"),
        requests_(participant_.reader<tgm::msg::RequestPubSubType>(ping_topic())),
        replies_(participant_.writer<tgm::msg::ReplyPubSubType>(pong_topic())),
        waiter_({&requests_}) {}

  int run() {
    tgm::msg::Request req;
    tgm::msg::Reply rep;
    rep.accepted(true);
    rep.code(tgm::msg::REPLY_CODE_ACCEPTED);
    while (!stop_ && !g_signalled) {
      waiter_.wait(200ms);
      while (tgm::dds::take_next(requests_, req)) {
        if (req.request_id() == kQuitId) return 0;
        rep.request_id(req.request_id());
        rep.client_name(req.client_name());
        rep.interpolator(req.interpolator());
        replies_.write(&rep);
      }
    }
    return 0;
  }
  void stop() {
    stop_ = true;
    waiter_.wake();
  }

 private:
  tgm::dds::Participant participant_;
  eprosima::fastdds::dds::DataReader& requests_;
  eprosima::fastdds::dds::DataWriter& replies_;
  tgm::dds::DataWaiter waiter_;
  std::atomic<bool> stop_{false};
};


double percentile(const std::vector<double>& sorted, double p) {
  const auto i = static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1) + 0.5);
  return sorted[std::min(i, sorted.size() - 1)];
}

int run_ping(const Options& o) {
  tgm::dds::Participant participant(dds_config(o), "ping");
  auto& requests = participant.writer<tgm::msg::RequestPubSubType>(ping_topic());
  auto& replies = participant.reader<tgm::msg::ReplyPubSubType>(pong_topic());
  // Writing before the match loses samples on a VOLATILE topic: wait both ways.
  if (!tgm::dds::wait_for_match(requests, 1, 30s) || !tgm::dds::wait_for_match(replies, 1, 30s)) {
    std::fprintf(stderr, "tgm_dds_pingpong: no pong on domain %d within 30 s\n", o.domain);
    return 1;
  }
  tgm::dds::DataWaiter waiter({&replies});
  tgm::msg::Request req;
  req.role(tgm::msg::CLIENT_ROLE_PLC);
  req.client_name(participant.name());
  req.kind(tgm::msg::REQUEST_KIND_WRITE_M_FUNC);
  tgm::msg::Reply rep;
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(o.count));
  int timeouts = 0;
  for (int i = 0; i < o.warmup + o.count; ++i) {
    req.request_id(static_cast<std::uint64_t>(i));
    const auto t0 = Clock::now();
    requests.write(&req);
    bool got = false;
    while (!got) {
      if (!waiter.wait(2s)) break;
      while (tgm::dds::take_next(replies, rep)) got = got || rep.request_id() == req.request_id();
    }
    const auto t1 = Clock::now();
    if (!got) {
      ++timeouts;
      continue;
    }
    if (i >= o.warmup) us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
  }
  req.request_id(kQuitId);
  requests.write(&req);
  requests.wait_for_acknowledgments(eprosima::fastrtps::Duration_t(2, 0));
  if (us.empty()) {
    std::fprintf(stderr, "tgm_dds_pingpong: no round trip completed\n");
    return 1;
  }
  std::sort(us.begin(), us.end());
  tgm::msg::RequestPubSubType req_type;
  tgm::msg::ReplyPubSubType rep_type;
  std::printf("DDS ping-pong (Request %u B -> Reply %u B serialized, RELIABLE VOLATILE, domain %d)\n",
              req_type.getSerializedSizeProvider(&req)(), rep_type.getSerializedSizeProvider(&rep)(),
              o.domain);
  std::printf("round trips %zu (warm-up %d, timeouts %d)\n", us.size(), o.warmup, timeouts);
  std::printf("min %.1f us  median %.1f us  p99 %.1f us  p99.9 %.1f us  max %.1f us\n", us.front(),
              percentile(us, 0.5), percentile(us, 0.99), percentile(us, 0.999), us.back());
  return timeouts == 0 ? 0 : 1;
}

constexpr const char* kUsage =
    "usage: tgm_dds_pingpong [--role both|ping|pong] [--count N] [--warmup N] [--domain D]\n"
    "                        [--profiles FILE]\n"
    "Round-trip latency of a raw Fast DDS ping-pong: Request out, Reply back, with tgm's request "
    "/\n"
    "reply QoS profiles. Prints min / median / p99 / p99.9 / max in microseconds.\n"
    "  --role R       both (default: the pong side in a second process), ping or pong\n"
    "  --count N      measured round trips, 1..100000000 (default 20000)\n"
    "  --warmup N     round trips not counted, 0..100000000 (default 2000)\n"
    "  --domain D     DDS domain, 0..232 (default 77)\n"
    "  --profiles F   Fast DDS profiles XML (default: config/fastdds_profiles.xml)\n";

// 0: go on; otherwise the exit code (--help printed, or a usage error reported).
int parse(int argc, char** argv, Options& o) {
  tgm::cli::ArgReader args(argc, argv, "tgm_dds_pingpong");
  while (args.more()) {
    if (args.help_flag()) {
      std::fputs(kUsage, stdout);
      return -1;
    }
    if (args.flag("--role", o.role) || args.whole_flag("--count", 1, 100'000'000, o.count) ||
        args.whole_flag("--warmup", 0, 100'000'000, o.warmup) ||
        args.whole_flag("--domain", 0, 232, o.domain) || args.flag("--profiles", o.profiles)) {
      continue;
    }
    return args.fail();
  }
  if (args.failed()) return 2;
  if (o.role != "both" && o.role != "ping" && o.role != "pong")
    return args.usage_error("--role must be both, ping or pong, not '" + o.role + "'");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const int rc = parse(argc, argv, o); rc != 0) return rc < 0 ? 0 : rc;
  try {
    if (o.role == "pong") {
      Pong pong(o);
      std::signal(SIGINT, on_signal);
      std::signal(SIGTERM, on_signal);
      return pong.run();
    }
    if (o.role == "ping") return run_ping(o);
    // both: the pong side in a second process.
    const std::string domain = std::to_string(o.domain);
    const char* child_argv[] = {"/proc/self/exe", "--role",     "pong",
                                "--domain",       domain.c_str(), "--profiles",
                                o.profiles.c_str(), nullptr};
    pid_t pid = 0;
    if (posix_spawn(&pid, "/proc/self/exe", nullptr, nullptr, const_cast<char**>(child_argv),
                    environ) != 0) {
      std::perror("tgm_dds_pingpong: cannot start the pong process");
      return 1;
    }
    const int rc = run_ping(o);
    int status = 0;
    if (rc != 0) ::kill(pid, SIGTERM);
    ::waitpid(pid, &status, 0);
    return rc;
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm_dds_pingpong: %s\n", e.what());
    return 1;
  }
}
