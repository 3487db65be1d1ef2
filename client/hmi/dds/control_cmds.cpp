// tgm-hmi status / watch / stop / start / clear / command: one-shot views and requests.
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include "commands.hpp"
#include "dds_common.hpp"
#include "tgm/client/silence_watch.hpp"
#include "tgm/printable.hpp"

namespace tgm::hmi {

namespace {

using namespace std::chrono_literals;

constexpr const char* kStatusUsage =
    "usage: tgm-hmi status [--interpolator N | --all] [--json] [--wait S] [--config YAML]\n"
    "                      [DDS overrides]\n"
    "\n"
    "Prints every register of the interpolator once (the state is TRANSIENT_LOCAL: a new reader\n"
    "gets the current one at once).\n"
    "  --all    every interpolator the service hosts\n"
    "  --json   one line of JSON per interpolator (JSON Lines): the IDL's field names, units in\n"
    "           the key where the register has one, per-axis values keyed by axis letter,\n"
    "           numbers that are not finite as null; for scripts and monitoring\n"
    "  --wait S wait up to S seconds for the service's state (default 10, at most 3600);\n"
    "           none by then: exit code 1\n"
    "A warning follows (with --json on standard error) when the service's machine digest is\n"
    "not this config's: its axis limits, cycle time, smoothing or buffer size differ.\n";
constexpr const char* kWatchUsage =
    "usage: tgm-hmi watch [--interpolator N] [--interval S] [--count K] [--json] [--wait S]\n"
    "                     [--config YAML] [DDS overrides]\n"
    "\n"
    "Follows the registers: prints them every S seconds (default 0.5) until Ctrl-C, or K times.\n"
    "Messages (M29 texts, warnings, errors) follow the registers; those written before watch\n"
    "began (the service keeps the last 32) are marked 'earlier', with their age. On a terminal\n"
    "the newest 5 stay on every screen.\n"
    "  --json   one line of JSON per sample (see tgm-hmi status --help), nothing else on\n"
    "           standard output, with state_age_s: the seconds since that state arrived (it\n"
    "           grows when the service stops publishing); warnings go to standard error\n"
    "  --wait S wait up to S seconds for the service's first state (default 10, at most 3600)\n"
    "Under the registers: a warning when the service's machine digest is not this config's\n"
    "(see tgm-hmi status --help).\n";
constexpr const char* kStopUsage =
    "usage: tgm-hmi stop [--interpolator N] [--timeout S] [--config YAML] [DDS overrides]\n"
    "\n"
    "Normal stop on the trajectory (Command 8); `tgm-hmi command start` resumes.\n"
    "  --timeout S   wait up to S seconds for the reply (default 3, at most 3600)\n";
constexpr const char* kCommandUsage =
    "usage: tgm-hmi command WHAT [P0 P1 ...] [--interpolator N] [--config YAML] [DDS overrides]\n"
    "\n"
    "Sends one request as the HMI and prints the reply. WHAT is one of\n"
    "  start, stop, clear             program control\n"
    "  estop                          Command 4, emergency stop on the trajectory\n"
    "  estop-off                      Command 5, emergency stop, off the trajectory\n"
    "  stop-off                       Command 9, normal stop, off the trajectory\n"
    "  CODE [P0 .. P11]               the Command register with its parameters (the service\n"
    "                                 refuses what the HMI may not do, e.g. 1024)\n"
    "  --timeout S   wait up to S seconds for the reply (default 3, at most 3600): a lossy\n"
    "                network can take seconds to find tgm-service and to repair a lost sample\n"
    "Exit code 0 when accepted, 1 when refused or unanswered. Unanswered says whether the\n"
    "request was sent at all: one that was may still be executed after the timeout.\n";

struct Common {
  DdsOverrides overrides;
  std::optional<AppConfig> config;
  std::optional<client::Client> client;
  double timeout_s = 3.0;  // reply timeout of the requests (stop, command)
};

// --wait S of status and watch: how long to wait for the service's state.
bool wait_flag(Args& args, double& out) {
  return args.number_flag("--wait", out, "seconds in (0, 3600]",
                          [](double v) { return v > 0.0 && v <= 3600.0; });
}

// --timeout S of stop and command.
bool timeout_flag(Args& args, double& out) {
  return args.number_flag("--timeout", out, "seconds in (0, 3600]",
                          [](double v) { return v > 0.0 && v <= 3600.0; });
}

int connect(Args& args, Common& c) {
  // Ctrl-C while waiting for the service or a reply is said (whether the request was sent),
  // not a silent death with code 130.
  install_signal_flag(Hangup::kInterrupt);
  client::ClientOptions options;
  options.request_timeout =
      std::chrono::milliseconds(static_cast<long long>(std::ceil(c.timeout_s * 1000.0)));
  options.cancel = &g_interrupted;
  return make_client(args, c.overrides, c.config, c.client, options);
}

// "WHAT: accepted" on standard output (exit code 0), or why not on standard error (1).
int report(const char* command, const std::string& what, const client::Reply& r) {
  if (r.accepted) {
    std::printf("%s: accepted\n", what.c_str());
    return 0;
  }
  std::fprintf(stderr, "tgm-hmi %s: %s: %s\n", command, what.c_str(), client::describe(r).c_str());
  return r.cancelled ? 130 : 1;
}

// Flushes what watch wrote: -1 while standard output takes it, else the exit code: 0 when its
// reader has gone (`watch --json | head -n 1`; SIGPIPE is ignored, and watch died of it), 1 on
// any other write error, which is said.
int flush_watch_output() {
  if (std::fflush(stdout) == 0 && !std::ferror(stdout)) return -1;
  const int err = errno;
  stdout_failure_handled();
  if (err == EPIPE) return 0;
  std::fprintf(stderr, "tgm-hmi watch: cannot write to standard output: %s\n", std::strerror(err));
  return 1;
}

}  // namespace

int run_status(int argc, char** argv) {
  Args args(argc, argv, "status", kStatusUsage);
  Common c;
  bool all = false;
  bool json = false;
  double wait_s = kServiceWaitS;
  while (args.more()) {
    if (args.dds_flag(c.overrides)) continue;
    if (args.boolean("--all", all) || args.boolean("--json", json)) continue;
    if (wait_flag(args, wait_s)) continue;
    if (args.common()) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (all && args.interpolator_given()) {
    return args.usage_error("--all shows every interpolator: give it or --interpolator N");
  }
  if (const int rc = connect(args, c); rc != 0) return rc;
  const int first = all ? 0 : args.interpolator();
  const int last = all ? static_cast<int>(c.config->machine.interpolators.size()) - 1 : first;
  if (const int rc = wait_for_service(*c.client, *c.config, first, "status", wait_s); rc != 0)
    return rc;
  if (all) c.client->poll(200ms);  // the other instances arrive together
  for (int i = first; i <= last; ++i) {
    // The service publishes every interpolator it hosts at least every 50 ms: with the first
    // one's state here, one without a state in 2 s is not hosted (its config has fewer). It
    // said "no state", which read like a fault.
    if (i != first && !c.client->wait_for_state(i, 2s)) {
      const char* why =
          "not hosted by tgm-service (no state within 2 s; its config has fewer "
          "interpolators than this one)";
      if (json) {
        std::fprintf(stderr, "tgm-hmi status: interpolator %d: %s\n", i, why);
      } else {
        std::printf("Interpolator %d: %s\n", i, why);
      }
      continue;
    }
    const std::string letters = c.config->machine.axis_letters(i);
    std::fputs((json ? format_state_json(*c.client->state(i), letters)
                     : format_state(*c.client->state(i), letters))
                   .c_str(),
               stdout);
    // Said, not an error: the service's config is the one that moves the machine. What this
    // config would compute for it (an estimate, a simulation) does not hold.
    if (const std::string why = machine_mismatch(*c.client->state(i), *c.config, i); !why.empty()) {
      if (json) {
        std::fprintf(stderr, "tgm-hmi status: %s\n", why.c_str());
      } else {
        std::printf("warning: %s\n", why.c_str());
      }
    }
  }
  return 0;
}

// "message (line 2): text", or for one written before `began_cycle` "earlier message (line 2,
// 12.5 s before watch began): text". Warnings and errors are named as such.
static std::string message_line(const msg::Message& m, std::uint64_t began_cycle,
                                std::int32_t cycle_time_us) {
  const char* kind = m.severity() == msg::SEVERITY_ERROR     ? "error"
                     : m.severity() == msg::SEVERITY_WARNING ? "warning"
                                                             : "message";
  char head[160];
  if (m.cycle() < began_cycle) {
    const double ago_s =
        static_cast<double>(began_cycle - m.cycle()) * static_cast<double>(cycle_time_us) * 1e-6;
    std::snprintf(head, sizeof head, "earlier %s (line %d, %.1f s before watch began)", kind,
                  m.source_line(), ago_s);
  } else {
    std::snprintf(head, sizeof head, "%s (line %d)", kind, m.source_line());
  }
  return std::string(head) + ": " + printable(m.text().c_str());
}

int run_watch(int argc, char** argv) {
  Args args(argc, argv, "watch", kWatchUsage);
  Common c;
  double interval = 0.5;
  long long count = 0;
  bool json = false;
  double wait_s = kServiceWaitS;
  while (args.more()) {
    if (args.dds_flag(c.overrides)) continue;
    if (args.boolean("--json", json)) continue;
    if (wait_flag(args, wait_s)) continue;
    if (args.number_flag("--interval", interval, "seconds > 0", [](double v) { return v > 0.0; }))
      continue;
    if (args.whole_flag("--count", 1, 1'000'000'000, count)) continue;
    if (args.common()) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  // connect() takes the signals before the client exists: a Ctrl-C once its readers match is
  // taken as the end of the watch (the test that waits for that match to interrupt found it
  // killed, with no word).
  if (const int rc = connect(args, c); rc != 0) return rc;
  const int ip = args.interpolator();
  if (const int rc = wait_for_service(*c.client, *c.config, ip, "watch", wait_s); rc != 0)
    return rc;
  const bool tty = !json && ::isatty(1) != 0;
  std::uint64_t malformed_said = 0, other_said = 0;
  std::string mismatch_said;  // machine_mismatch() said last on standard error (--json)
  // The message topic keeps the last 32 messages for late readers: those written before the
  // first state seen here are history, and said so (they used to look like news).
  const std::uint64_t began_cycle = c.client->state(ip)->cycle_counter();
  const std::int32_t cycle_time_us = c.client->state(ip)->cycle_time_us();
  constexpr std::size_t kMessagesShown = 5;
  std::deque<std::string> recent;  // on a terminal: shown on every screen, newest last
  // A service that stops publishing leaves its last state here: watch kept showing it, "running"
  // at a standstill, without a word.
  client::SilenceWatch silence(3s);
  // The service instance followed: another one (a restarted service) is said once, since its
  // registers start afresh (Status 0) and what ran before is gone; they switched silently.
  std::uint64_t followed = c.client->service_followed(ip);
  for (long long k = 0; !g_interrupted && (count == 0 || k < count); ++k) {
    if (k > 0) {
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(interval);
      while (!g_interrupted && std::chrono::steady_clock::now() < until) c.client->poll(10ms);
    }
    std::string restarted;
    if (const std::uint64_t now_followed = c.client->service_followed(ip);
        now_followed != followed && now_followed != 0) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "tgm-service restarted (instance %016llx, was %016llx): its registers start "
                    "afresh, and the program it ran before is gone",
                    static_cast<unsigned long long>(now_followed),
                    static_cast<unsigned long long>(followed));
      restarted = text;
      followed = now_followed;
    }
    const auto now = std::chrono::steady_clock::now();
    const auto change = silence.update(c.client->state_samples(ip), now);
    // Once per silence of 5 s, a new participant: after this process stood still for seconds
    // the link can break one way for good (Client::rejoin; `run` does the same).
    if (silence.lasted(std::chrono::seconds(5), now)) {
      std::fprintf(stderr,
                   "tgm-hmi watch: no state from tgm-service for 5 s: joining DDS again as a new "
                   "participant (the link may have broken one way, as after this process stood "
                   "still for seconds)\n");
      if (const std::string why = c.client->rejoin(); !why.empty()) {
        std::fprintf(stderr,
                     "tgm-hmi watch: warning: could not join DDS again (%s): going on as before\n",
                     why.c_str());
      }
    }
    const std::string stale =
        silence.silent()
            ? "no state from tgm-service for " + std::to_string(silence.seconds_since_last(now)) +
                  " s (stopped, or the network is down): the registers shown are the last received"
            : std::string();
    if (json) {
      if (!restarted.empty()) std::fprintf(stderr, "tgm-hmi watch: %s\n", restarted.c_str());
      if (change == client::SilenceWatch::Change::kSilent) {
        std::fprintf(stderr, "tgm-hmi watch: %s\n", stale.c_str());
      } else if (change == client::SilenceWatch::Change::kBack) {
        std::fprintf(stderr, "tgm-hmi watch: tgm-service is back\n");
      }
      // Standard output stays JSON Lines: the rest goes to standard error, once per change.
      std::fputs(
          format_state_json(*c.client->state(ip), c.config->machine.axis_letters(ip),
                            std::chrono::duration<double>(now - c.client->state_taken(ip)).count())
              .c_str(),
          stdout);
      if (const int rc = flush_watch_output(); rc >= 0) return rc;
      if (const std::uint64_t bad = dds::malformed_samples(); bad != malformed_said) {
        malformed_said = bad;
        std::fprintf(stderr,
                     "tgm-hmi watch: DDS samples that cannot be read were dropped (%llu failed "
                     "reads) on domain %d\n",
                     static_cast<unsigned long long>(bad), c.config->dds.domain_id);
      }
      if (std::string why = machine_mismatch(*c.client->state(ip), *c.config, ip);
          why != mismatch_said) {
        mismatch_said = std::move(why);
        if (!mismatch_said.empty())
          std::fprintf(stderr, "tgm-hmi watch: %s\n", mismatch_said.c_str());
      }
      if (const std::uint64_t other = c.client->other_service(ip); other != other_said) {
        other_said = other;
        if (other != 0) {
          std::fprintf(stderr,
                       "tgm-hmi watch: another tgm-service (instance %016llx) publishes on DDS "
                       "domain %d too; shown: %016llx. Stop one of them.\n",
                       static_cast<unsigned long long>(other), c.config->dds.domain_id,
                       static_cast<unsigned long long>(c.client->service_followed(ip)));
        }
      }
      // Messages: the newest is in the state (message_text, message_counter).
      continue;
    }
    if (tty) std::printf("\033[H\033[2J");
    std::fputs(format_state(*c.client->state(ip), c.config->machine.axis_letters(ip)).c_str(), stdout);
    if (!stale.empty()) std::printf("%s\n", stale.c_str());
    if (const std::string why = machine_mismatch(*c.client->state(ip), *c.config, ip);
        !why.empty()) {
      std::printf("warning: %s\n", why.c_str());
    }
    if (const std::uint64_t other = c.client->other_service(ip); other != 0) {
      std::printf(
          "warning: another tgm-service (instance %016llx) publishes on DDS domain %d too; "
          "shown: %016llx. Stop one of them.\n",
          static_cast<unsigned long long>(other), c.config->dds.domain_id,
          static_cast<unsigned long long>(c.client->service_followed(ip)));
    }
    if (!restarted.empty()) {
      if (tty) {
        recent.push_back(restarted);
        if (recent.size() > kMessagesShown) recent.pop_front();
      } else {
        std::printf("%s\n", restarted.c_str());
      }
    }
    for (const auto& m : c.client->take_messages()) {
      if (m.interpolator() != ip) continue;
      std::string line = message_line(m, began_cycle, cycle_time_us);
      if (!tty) {
        std::printf("%s\n", line.c_str());
        continue;
      }
      recent.push_back(std::move(line));
      if (recent.size() > kMessagesShown) recent.pop_front();
    }
    for (const std::string& line : recent) std::printf("%s\n", line.c_str());
    // Shown on every screen: a line printed once would be cleared by the next.
    if (const std::uint64_t bad = dds::malformed_samples(); bad != 0) {
      std::printf(
          "DDS samples that cannot be read were dropped (%llu failed reads): a participant on "
          "domain %d writes tgm topics in a form this version does not know\n",
          static_cast<unsigned long long>(bad), c.config->dds.domain_id);
    }
    if (!tty) std::printf("\n");
    if (const int rc = flush_watch_output(); rc >= 0) return rc;
  }
  return 0;
}

int run_stop(int argc, char** argv) {
  Args args(argc, argv, "stop", kStopUsage);
  Common c;
  while (args.more()) {
    if (args.dds_flag(c.overrides)) continue;
    if (timeout_flag(args, c.timeout_s)) continue;
    if (args.common()) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (const int rc = connect(args, c); rc != 0) return rc;
  return report("stop", "stop", c.client->stop(args.interpolator()));
}

int run_command(int argc, char** argv) {
  Args args(argc, argv, "command", kCommandUsage);
  Common c;
  std::vector<std::string> words;
  while (args.more()) {
    if (args.dds_flag(c.overrides)) continue;
    if (timeout_flag(args, c.timeout_s)) continue;
    if (args.common()) continue;
    // Negative numbers (Command -1 / -2, parameters) are words, not options.
    if (std::string w; args.positional(w) || args.negative_number(w)) {
      words.push_back(w);
      continue;
    }
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (words.empty()) return args.usage_error("say WHAT to send (start, stop, clear, estop, ... or a Command code)");
  const std::string what = words[0];
  std::vector<std::int32_t> params;
  long long code = 0;
  bool is_code = false;
  if (what == "start" || what == "stop" || what == "clear" || what == "estop" || what == "estop-off" ||
      what == "stop-off") {
    if (words.size() > 1) return args.usage_error("'" + what + "' takes no parameters");
  } else if (parse_integer(what, LLONG_MIN, LLONG_MAX, code)) {
    if (code < -1'000'000 || code > 1'000'000)
      // Codes within the bound go to the service, which names the codes it knows: the
      // message claimed -2..2049 here and sent 2050.
      return args.usage_error("Command code " + what +
                              " is out of range -1000000..1000000 (the known codes lie in "
                              "-2..2049; tgm-service names them)");
    is_code = true;
    if (words.size() > 13) return args.usage_error("at most 12 Command parameters");
    for (std::size_t k = 1; k < words.size(); ++k) {
      long long v = 0;
      if (!parse_integer(words[k], INT32_MIN, INT32_MAX, v)) {
        const std::string where =
            "Command_Parameter[" + std::to_string(k - 1) + "] '" + words[k] + "'";
        return args.usage_error(
            parse_integer(words[k], LLONG_MIN, LLONG_MAX, v)
                ? where + " does not fit its 32-bit register (-2147483648..2147483647)"
                : where + " is not a whole number");
      }
      params.push_back(static_cast<std::int32_t>(v));
    }
  } else {
    return args.usage_error("unknown command '" + what + "'");
  }
  if (const int rc = connect(args, c); rc != 0) return rc;
  const int ip = args.interpolator();
  client::Client& cl = *c.client;
  if (what == "start") return report("command", "start", cl.start(ip));
  if (what == "stop") return report("command", "stop", cl.stop(ip));
  if (what == "clear") return report("command", "clear", cl.clear(ip));
  if (what == "estop") return report("command", "Command 4", cl.command(ip, 4));
  if (what == "estop-off") return report("command", "Command 5", cl.command(ip, 5));
  if (what == "stop-off") return report("command", "Command 9", cl.command(ip, 9));
  (void)is_code;
  return report("command", "Command " + what,
                cl.command(ip, static_cast<std::int32_t>(code), params));
}

}  // namespace tgm::hmi
