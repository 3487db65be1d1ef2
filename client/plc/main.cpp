// tgm-plc: the PLC emulator (DESIGN.md section 1, the manual's "PLC competence"). It sets the
// basic parameters from the config, acknowledges normal M-functions after the per-M delay of the
// config, notes continuous ones, logs every M-function and every acknowledgement, and can be
// told (flags or a small YAML script) to change Rel_Speed, issue stops or refuse to acknowledge.
// It cannot start the interpolator: the service refuses (--try-start shows it).
//
// Two threads see M-functions: the event callback (tgm_event, in Fast DDS's receive thread)
// and the main loop (tgm_state). Whichever sees an M-function first claims it (MTracker, under
// one mutex), so each is handled and logged once. An acknowledgement due at once (delay 0,
// continuous M-functions, not refused) is written from the callback itself; everything else
// (delayed acknowledgements, refusals, every log line) happens in the main loop. Neither waits
// for a reply: the main loop collects the replies to every acknowledgement as they come, so a
// reply lost on the network for one interpolator holds up no other's handshake.
#include <pthread.h>
#include <sched.h>
#include <signal.h>

#include <cstring>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "handshake_trace.hpp"
#include "m_tracker.hpp"
#include "params_text.hpp"
#include "tgm/atomic_file.hpp"
#include "tgm/cli_args.hpp"
#include "tgm/cli_numbers.hpp"
#include "tgm/client/client.hpp"
#include "tgm/command_stage.hpp"
#include "tgm/dds_overrides.hpp"
#include "tgm/log_time.hpp"
#include "tgm/plc_script.hpp"
#include "tgm/printable.hpp"
#include "tgm/registers.hpp"
#include "tgm/smoothing.hpp"
#include "tgm/systemd_notify.hpp"
#include "tgm/yaml_config.hpp"

namespace {

using Clock = std::chrono::steady_clock;

// Appends one log line, "tgm-plc [t s] " and printf's format (checked by the compiler against
// the arguments), to `out`; a line longer than 1 KiB is cut.
[[gnu::format(printf, 3, 4)]] void append_log(std::string& out, double t_s, const char* fmt, ...) {
  char line[1024];
  const int head = std::snprintf(line, sizeof line, "tgm-plc [%8.3f s] ", t_s);
  std::va_list args;
  va_start(args, fmt);
  const int body =
      std::vsnprintf(line + head, sizeof line - static_cast<std::size_t>(head), fmt, args);
  va_end(args);
  const int n = std::min<int>(head + std::max(body, 0), static_cast<int>(sizeof line) - 1);
  out.append(line, static_cast<std::size_t>(n));
  out += '\n';
}
using namespace std::chrono_literals;

constexpr const char* kUsage =
    "usage: tgm-plc [--config YAML] [OPTIONS]\n"
    "\n"
    "PLC emulator: sets the basic parameters, acknowledges normal M-functions after the delay\n"
    "of plc.m_delay_s (or plc.default_m_delay_s), notes continuous M-functions, logs both.\n"
    "It sees M-functions on the small event topic first: an acknowledgement due at once\n"
    "(delay 0, continuous) is written from the event callback, the rest from the main loop.\n"
    "The basic parameters go by axis index: when the config's axis letters are not those the\n"
    "service publishes, none are sent and the log says why. A restarted tgm-service starts at\n"
    "0; with its basic parameters it gets where the emulated drives stand, the last\n"
    "PositionInc seen (Command 2048). Where the service's config has plc.setup_before_start\n"
    "(its state shows plc_setup 1), it then reports the setup, which a start waits for; not\n"
    "when a setup request was refused or not sent (--no-basic-params, other axes): the log\n"
    "says so. Stops cleanly on SIGINT / SIGTERM (SIGHUP, a closed terminal, is ignored).\n"
    "\n"
    "  --config YAML        machine config (default: $TGM_CONFIG, the installed or the in-tree\n"
    "                       config/default.yaml)\n"
    "%s"
    "  --interpolator N     serve only interpolator N (default: every configured one)\n"
    "  --rel-speed R        write Rel_Speed = R (0.01..2) at start\n"
    "  --refuse-ack M[,M]   never acknowledge these normal M-functions (1..999; the interpolator\n"
    "                       keeps waiting), on every interpolator served\n"
    "  --ack-delay S        acknowledge every normal M-function after S seconds (overrides "
    "config)\n"
    "  --script YAML        timed actions, a list of maps:\n"
    "                         - {at_s: 1.5, rel_speed: 0.5}       Rel_Speed write\n"
    "                         - {at_s: 0, number_axes: 2}         Number_Axes write\n"
    "                         - {at_s: 0, ratio: {X: 2000}}       Ratio writes [inc/mm]\n"
    "                         - {at_s: 0, offset: {X: 500}}       Offset writes [inc]\n"
    "                         - {at_s: 3, command: 8}             Command: 4/5/8/9 stops, or\n"
    "                                                             1024 2048 2049 -1 -2 with\n"
    "                           parameters: [0, 2000, 1]          Command_Parameter[0..] (the\n"
    "                                                             rest 0)\n"
    "                         - {at_s: 4, start: true}            try to start (refused)\n"
    "                         - {at_s: 0, refuse_ack: [51]}       stop acknowledging M51 (an\n"
    "                                                             M51 that waits already too)\n"
    "                       each may name `interpolator: N` (default 0), the only one its\n"
    "                       actions apply to (with --interpolator, it must be that one), and\n"
    "                       needs at least one action (several run in the order above); at_s\n"
    "                       counts from the moment the service was found (default 0).\n"
    "                       Ratio and offset go to the service's axis of that letter (the\n"
    "                       letters its state publishes; such a step waits for that state):\n"
    "                       a letter the config's interpolator lacks is an error before\n"
    "                       anything is sent (exit code 2), one the service does not drive\n"
    "                       is not written, an error (exit code 3)\n"
    "  --try-start          send a start request as the PLC to each interpolator served, when\n"
    "                       it is found (the service refuses each one)\n"
    "  --no-basic-params    do not send the basic parameters at start\n"
    "  --duration S         stop by itself S seconds after the start (at most 1e9). A script's\n"
    "                       at_s counts from when the service was found, so it must be below\n"
    "                       S; steps not run by the end are named on standard error (exit\n"
    "                       code 3; after a signal too, with exit code 0)\n"
    "  --quiet              leave out the lines of the basic parameters the service accepted;\n"
    "                       the rest stays: M-functions, acknowledgements, refusals and errors,\n"
    "                       script actions, and the run's own lines (the start, each\n"
    "                       interpolator found and its setup done, the service restarted or\n"
    "                       silent, the summary at exit)\n"
    "  --no-events          do not subscribe to tgm_event: see M-functions on the state only\n"
    "                       (the main loop acknowledges them all)\n"
    "  --handshake-trace F  write the time stamps of every acknowledgement and note as CSV to F\n"
    "                       at exit, a row each with the M number, m_func_count, normal or\n"
    "                       continuous and the reply (code; accepted, refused or none)\n"
    "  --rt-priority N      run the emulator (all its threads) SCHED_FIFO at N, 1..98, when\n"
    "                       permitted (a real PLC task is real-time; default: normal)\n"
    "  --log-time WHEN      local date and time (ms) before each log line: auto (default:\n"
    "                       unless the output goes to systemd's journal, which stamps it),\n"
    "                       on or off\n"
    "  --help               this text\n"
    "  --version            print tgm-plc's version\n"
    "\n"
    "Exit codes: 0 stopped (signal or --duration), 1 DDS could not be set up or a report file\n"
    "could not be written, 2 a bad flag, config or script, 3 the script did not run as written\n"
    "(an axis write not sent, or steps not run when --duration ended the run).\n"
    "\n"
    "Under systemd (Type=notify: the installed lib/systemd/system/tgm-plc.service) it says\n"
    "READY=1 once its DDS entities exist, what it serves in STATUS=, and STOPPING=1; with\n"
    "WatchdogSec= it pings the watchdog from its main loop.\n";

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

using MParams = std::array<double, TGM_M_FUNCTION_PARAMETERS>;

// The reply to the note (M_Func = 0) of a continuous M-function. The service refuses it with
// WRONG_STATE when M_Func shows the next M-function already: that one is left to be handled,
// which is what should happen, not an error.
// A repeat whose first copy arrived is refused as acknowledged already: said as such.
std::string note_reply(const tgm::client::Reply& r) {
  if (r.code == tgm::msg::REPLY_CODE_WRONG_STATE) {
    if (r.reason.find("was acknowledged already") != std::string::npos)
      return "acknowledged already (the first acknowledgement arrived)";
    return "M_Func shows the next M-function already";
  }
  return tgm::client::describe(r);
}

// The source line of the M-function a state or event sample hands over: m_func_line, or when it
// is 0 (none recorded) the executing record's.
template <typename Sample>
std::int32_t m_func_line_of(const Sample& s) {
  return s.m_func_line() != 0 ? s.m_func_line() : s.act_line();
}

// An M-function the event callback claimed, for the main loop to log and, unless it was
// acknowledged from the callback, to acknowledge or refuse.
struct EventSeen {
  enum class Action { kAcked, kRefused, kScheduled };
  int interpolator = 0;
  std::int32_t m = 0, line = 0, part = 0;
  std::uint32_t count = 0;  // m_func_count: the acknowledgement names the M-function by it
  bool normal = false;
  MParams params{};
  Action action = Action::kScheduled;
  //! kAcked: the request id of the acknowledgement written from the callback.
  std::uint64_t request_id = 0;
  Clock::time_point woke{}, seen{}, ack_call{}, ack_written{};
  //! The service instance that showed the M-function.
  std::uint64_t instance = 0;
  //! Who wrote the acknowledgement (or note): the event callback, the main loop when due, or
  //! the main loop again after one was left unanswered.
  enum class Via { kEvent, kLoop, kRepeat };
  Via via = Via::kEvent;
};

// A request of the PLC's own (Rel_Speed, the basic parameters, --try-start, a script action),
// written without waiting for its reply so that the main loop keeps serving M-functions and
// signals meanwhile. One at a time per interpolator, in order (main loop only).
struct SetupRequest {
  tgm::msg::Request request;
  std::string what;           // the log line before ": <reply>"
  bool quiet_ok = false;      // under --quiet, logged only when refused or unanswered
  int attempts = 1;           // written this often at most while unanswered (basic parameters: 3)
  bool report = false;        // the setup report: not counted in total / accepted
  int attempt = 0;            // the attempt written last
  std::uint64_t id = 0;       // request_id once written
  Clock::time_point since{};  // when this attempt was first tried, or written
};
struct SetupQueue {
  std::deque<SetupRequest> items;
  int total = 0, accepted = 0;
  int failed = 0;       // counted items refused or given up unanswered
  bool report = false;  // "setup done" is due once the items are answered
  const char* withheld = nullptr;  // why the basic parameters were not sent, if they were not
  const char* unrestored = nullptr;  // why the drives' position was not restored, if it was not
};

// One interpolator as the PLC sees it (main loop only).
struct Served {
  int number = 0;
  bool found = false;
  std::uint64_t instance = 0;  // InterpolatorState.service_instance when found
  std::uint64_t other = 0;     // another service publishing for it, when told
  std::int32_t m_part = -1;
  // A pending acknowledgement.
  std::int32_t ack_m = 0;
  std::uint32_t ack_count = 0;
  std::uint64_t ack_instance = 0;  // the service instance that showed it
  Clock::time_point ack_at{};
  Clock::time_point seen_at{};
  Clock::time_point woke_at{};
  // An acknowledgement left unanswered: sent again while the state still shows that M-function.
  std::int32_t unanswered_m = 0;
  std::uint32_t unanswered_count = 0;
  Clock::time_point unanswered_at{};
  // The drives' position as this PLC last saw it (PositionInc of the service followed): a
  // restarted service starts at 0, and the PLC tells it where the axes stand (Command 2048).
  std::array<long long, tgm::kMaxAxes> last_inc{};
  std::size_t last_axes = 0;
  std::string last_letters;  // the axes of last_inc, by letter (a restart may change them)
  bool restore = false;  // a restarted service gets last_inc once its basic parameters are set
  void left_unanswered(std::int32_t m, std::uint32_t count, Clock::time_point at) {
    unanswered_m = m;
    unanswered_count = count;
    unanswered_at = at;
  }
};

// The axes a state's interpolator drives (Number_Axes, within 0..kMaxAxes).
std::size_t driven_axes(const tgm::msg::InterpolatorState& s) {
  return static_cast<std::size_t>(std::clamp<std::int32_t>(s.number_axes(), 0, tgm::kMaxAxes));
}

int plc_main(int argc, char** argv);

}  // namespace

// What escapes plc_main ends with words and exit 1 (run_guarded), not with an abort.
int main(int argc, char** argv) {
  return tgm::cli::run_guarded("tgm-plc", plc_main, argc, argv);
}

namespace {
int plc_main(int argc, char** argv) {
  std::string config_path;
  tgm::DdsOverrides overrides;
  std::optional<double> rel_speed;
  std::optional<double> ack_delay;
  // --refuse-ack's M-functions, refused on every interpolator served (a script's are added
  // per interpolator when their step runs).
  std::set<int> refuse_flag;
  std::vector<tgm::PlcScriptStep> script;
  std::string script_path;
  std::string trace_path;
  int only = -1;
  bool try_start = false;
  bool no_basic = false;
  bool quiet = false;
  bool no_events = false;
  double duration_s = 0.0;
  int rt_priority = 0;
  std::string log_time = "auto";
  tgm::cli::ArgReader args(argc, argv, "tgm-plc");
  args.repeatable("--refuse-ack");  // the lists add up
  while (args.more()) {
    std::string value;
    if (args.help_flag()) {
      std::printf(kUsage, tgm::kDdsOverrideHelp);
      return 0;
    }
    if (args.version_flag()) {
      std::printf("%s\n", args.version_line().c_str());
      return 0;
    }
    if (args.dds_flag(overrides) || args.flag("--config", config_path) ||
        args.flag("--handshake-trace", trace_path) || args.flag("--log-time", log_time) ||
        args.boolean("--try-start", try_start) || args.boolean("--quiet", quiet) ||
        args.boolean("--no-basic-params", no_basic) || args.boolean("--no-events", no_events)) {
      continue;
    }
    if (args.whole_flag("--interpolator", 0, 2, only) ||
        args.whole_flag("--rt-priority", 1, 98, rt_priority) ||
        args.number_flag("--duration", duration_s, "seconds, > 0 and at most 1e9",
                         [](double v) { return v > 0.0 && v <= 1e9; })) {
      continue;
    }
    double v = 0.0;
    if (args.number_flag("--rel-speed", v, "0.01..2",
                         [](double x) { return x >= 0.01 && x <= 2.0; })) {
      rel_speed = v;
    } else if (args.number_flag("--ack-delay", v, "0..3600 s",
                                [](double x) { return x >= 0.0 && x <= 3600.0; })) {
      ack_delay = v;
    } else if (args.flag("--refuse-ack", value)) {
      for (const std::string& item : tgm::comma_items(value)) {
        int m = 0;
        if (!tgm::parse_integer(item, 1, tgm::kMaxNormalM, m))
          return args.usage_error(
              "--refuse-ack takes normal M-functions 1.." + std::to_string(tgm::kMaxNormalM) +
              " like 51,50 (the interpolator waits only for those), not '" + value + "'");
        refuse_flag.insert(m);
      }
    } else if (args.flag("--script", script_path)) {
      if (!args.failed()) {
        tgm::PlcScriptLoad load = tgm::load_plc_script(script_path);
        if (!load.ok()) {
          std::size_t from = 0;
          while (from <= load.error.size()) {  // one problem per line
            const std::size_t end = std::min(load.error.find('\n', from), load.error.size());
            std::fprintf(stderr, "tgm-plc: %.*s\n", static_cast<int>(end - from),
                         load.error.c_str() + from);
            from = end + 1;
          }
          return 2;
        }
        script = std::move(load.steps);
      }
    } else {
      return args.fail();
    }
  }
  if (args.failed()) return 2;
  const std::optional<tgm::LogTime> stamping = tgm::parse_log_time(log_time);
  if (!stamping)
    return args.usage_error("--log-time must be auto, on or off, not '" + log_time + "'");
  if (!args.distinct_files(
          {tgm::cli::ArgReader::config_file(config_path), {"--script", script_path}},
          {{"--handshake-trace", trace_path}})) {
    return 2;
  }
  // Written at exit: a path that cannot be written fails the start, not the end of the run.
  tgm::ReportFile trace_file;
  if (std::string why; !trace_path.empty() && !trace_file.open(trace_path, why)) {
    return args.usage_error("--handshake-trace " + trace_path + ": " + why);
  }
  const bool basic = !no_basic;
  const bool events = !no_events;
  const std::optional<tgm::AppConfig> loaded = tgm::load_config_or_report(config_path, "tgm-plc");
  if (!loaded) return 2;
  tgm::AppConfig config = *loaded;
  overrides.apply(config.dds);
  if (std::string why = tgm::dds::config_problem(config.dds, "plc"); !why.empty())
    return args.usage_error(why);
  const int count = static_cast<int>(config.machine.interpolators.size());
  if (only >= count)
    return args.usage_error("--interpolator " + std::to_string(only) + ": the config has " +
                            std::to_string(count));
  std::vector<bool> script_done(script.size(), false);
  // Script writes by axis letter not sent because the service has no axis of that letter: the
  // count and the first one, said again at exit (exit code 3).
  int held_writes = 0;
  std::string first_held;
  // Every step that cannot run, in line order, before any runs (one per step).
  bool script_bad = false;
  for (const auto& s : script) {
    // A step for an interpolator this PLC does not serve (--interpolator N) was sent anyway.
    if (const std::string why = tgm::plc_script_interpolator_problem(s, count, only);
        !why.empty()) {
      std::fprintf(stderr, "tgm-plc: %s:%d: %s\n", script_path.c_str(), s.line, why.c_str());
      script_bad = true;
      continue;
    }
    // An axis letter the interpolator does not have, more axes than it has.
    if (const std::string why =
            tgm::plc_script_axes_problem(s, config.machine.axis_letters(s.interpolator));
        !why.empty()) {
      std::fprintf(stderr, "tgm-plc: %s:%d: %s\n", script_path.c_str(), s.line, why.c_str());
      script_bad = true;
      continue;
    }
    // What the service would refuse in any state (a ratio of 0 mm, spline points out of
    // range) is said now, not in the middle of the run. A standing, idle interpolator with all
    // its configured axes is the context that allows the most.
    if (s.command) {
      const int axes = static_cast<int>(
          config.machine.interpolators[static_cast<std::size_t>(s.interpolator)].axes.size());
      tgm::CommandContext most;
      most.number_axes = axes;
      most.configured_axes = axes;
      if (const tgm::RequestResult r = tgm::check_command(*s.command, s.parameters, most);
          !r.ok()) {
        const std::string named = r.reason.rfind("Command ", 0) == 0
                                      ? r.reason
                                      : "Command " + std::to_string(*s.command) + ": " + r.reason;
        std::fprintf(stderr, "tgm-plc: %s:%d: interpolator %d: %s\n", script_path.c_str(), s.line,
                     s.interpolator, named.c_str());
        script_bad = true;
      }
    }
  }
  if (script_bad) return 2;
  // --duration counts from the start, at_s from when the service is found: a step at or after
  // the duration could never run (it was left out without a word, exit code 0).
  if (const std::string why = tgm::plc_script_duration_problem(script, duration_s, script_path);
      duration_s > 0.0 && !why.empty()) {
    return args.usage_error(why);
  }
  // The log from here on, the usage errors above not: they go to whoever started the PLC.
  if (std::string why; !tgm::stamp_standard_streams(*stamping, why)) {
    std::fprintf(stderr, "tgm-plc: %s\n", why.c_str());
    return 1;
  }

  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // A log reader that goes away must not end the emulator: the interpolators would wait for
  // their M-function acknowledgements for good. Its writes fail with EPIPE instead. A closed
  // terminal or SSH session (SIGHUP) neither.
  ::signal(SIGPIPE, SIG_IGN);
  ::signal(SIGHUP, SIG_IGN);

  std::string rt_log;
  if (rt_priority > 0) {
    // Before the participant exists, so that Fast DDS's threads inherit the policy too.
    sched_param p{};
    p.sched_priority = rt_priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
    rt_log = rc == 0 ? "SCHED_FIFO priority " + std::to_string(rt_priority)
                     : std::string("SCHED_FIFO not permitted (") + std::strerror(rc) + "), normal priority";
  }
  std::optional<tgm::client::Client> plc;
  try {
    plc.emplace(config.dds, tgm::client::Role::kPlc);
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm-plc: %s\n", e.what());
    return 1;
  }
  const auto t_start = Clock::now();
  auto stamp = [&] { return std::chrono::duration<double>(Clock::now() - t_start).count(); };
  // Log lines are collected and written once per loop iteration, after the acknowledgements of
  // that iteration went out: a write to a pipe or file must not delay the handshake.
  std::string pending_log;
  auto flush_log = [&] {
    if (pending_log.empty()) return;
    std::fwrite(pending_log.data(), 1, pending_log.size(), stdout);
    std::fflush(stdout);
    pending_log.clear();
  };
  auto delay_for = [&](int m) {
    if (ack_delay) return *ack_delay;
    const auto it = config.plc.m_delay_s.find(m);
    return it != config.plc.m_delay_s.end() ? it->second : config.plc.default_m_delay_s;
  };

  std::vector<Served> served;
  for (int i = 0; i < count; ++i) {
    if (only < 0 || only == i) served.emplace_back().number = i;
  }
  append_log(
      pending_log, stamp(), "PLC emulator on DDS domain %d as '%s', serving %zu interpolator%s, version %s",
      config.dds.domain_id, plc->name().c_str(), served.size(), served.size() == 1 ? "" : "s",
      tgm::cli::version());
  if (!rt_log.empty()) append_log(pending_log, stamp(), "%s", rt_log.c_str());

  // The PLC's own requests per interpolator (SetupRequest), pumped once per main-loop pass.
  std::map<int, SetupQueue> setup;
  auto queue_request = [&](int interpolator, tgm::msg::Request request, std::string what,
                           bool quiet_ok, int attempts) {
    SetupQueue& q = setup[interpolator];
    q.items.push_back(SetupRequest{std::move(request), std::move(what), quiet_ok, attempts});
    ++q.total;
  };
  // A restarted service starts every axis at 0, but the drives still stand where the previous
  // one left them: a real PLC reads their actual positions and sets them (Command 2048, on the
  // trajectory), or the first setpoints jump there. The emulated drives stand where the last
  // PositionInc this PLC saw put them. Behind the gear ratios (the service converts the
  // increments with the ratio it has then).
  // `not_sent`: why it may not be sent (nullptr: it may).
  auto restore_position = [&](const Served& sv, const tgm::msg::InterpolatorState& now_state,
                              const char* not_sent) {
    // By letter: a service restarted with another config (XYC corrected to XYZ) would take C's
    // increments as Z's by index. An axis the old service did not drive keeps the new one's
    // position, and one it no longer drives is named.
    const std::size_t axes = driven_axes(now_state);
    const std::string letters = now_state.axis_letters().to_string();
    std::string where, kept, gone;
    std::array<std::int32_t, tgm::kMaxAxes> params{};
    bool differs = false, fits = true;
    for (std::size_t a = 0; a < axes; ++a) {
      const char letter = a < letters.size() ? letters[a] : '?';
      const std::size_t old = sv.last_letters.find(letter);
      const long long now_inc = now_state.position_inc()[a];
      const bool known = old != std::string::npos && old < sv.last_axes;
      const long long inc = known ? sv.last_inc[old] : now_inc;
      if (!known) kept += letter;
      if (inc != now_inc) differs = true;
      if (inc < INT32_MIN || inc > INT32_MAX) fits = false;
      params[a] = static_cast<std::int32_t>(std::clamp<long long>(inc, INT32_MIN, INT32_MAX));
      where += (where.empty() ? "" : " ");
      where += letter;
      where += ' ' + std::to_string(inc);
    }
    for (std::size_t a = 0; a < sv.last_axes && a < sv.last_letters.size(); ++a) {
      if (letters.find(sv.last_letters[a]) == std::string::npos && sv.last_inc[a] != 0)
        gone += sv.last_letters[a];
    }
    if (!gone.empty()) {
      append_log(pending_log, stamp(),
                 "interpolator %d: warning: the restarted service does not drive %s (it drives "
                 "%s): %s's last position is not restored",
                 sv.number, gone.c_str(), letters.c_str(), gone.c_str());
    }
    if (!differs) return;
    if (!fits) {
      append_log(pending_log, stamp(),
                 "interpolator %d: warning: position not restored (an increment beyond "
                 "Command_Parameter's 32 bits): the drives stood at %s inc, the restarted "
                 "service starts from its own position",
                 sv.number, where.c_str());
      setup[sv.number].unrestored = "the drives' position does not fit Command 2048";
      return;
    }
    if (not_sent != nullptr) {
      append_log(pending_log, stamp(),
                 "interpolator %d: warning: position not restored (%s): the drives stood at %s "
                 "inc, the restarted service starts from its own position; set it with Command "
                 "2048",
                 sv.number, not_sent, where.c_str());
      return;
    }
    char what[tgm::kMaxAxes * 24 + 200];
    std::snprintf(what, sizeof what,
                  "interpolator %d: position restore: Command 2048 with the drives' last "
                  "increments (%s%s%s%s)",
                  sv.number, where.c_str(), kept.empty() ? "" : "; ", kept.c_str(),
                  kept.empty() ? "" : " as the service has it");
    queue_request(sv.number,
                  tgm::client::command_request(sv.number, tgm::kCommandSetPositionOn,
                                               std::span<const std::int32_t>(params.data(), axes)),
                  what, false, 3);
  };
  // Writes the next request of each queue, logs the replies that came, and writes an
  // unanswered one again after 3 s (the clients' request timeout) while it has attempts left.
  // A request that cannot be written (no service matched, the request window full) is tried
  // for 3 s. Without `write` nothing is written (nor written again), replies are still
  // taken; `final`: what is left is logged as not answered.
  auto pump_setup = [&](bool write, bool final) {
    for (auto& [number, q] : setup) {
      while (!q.items.empty()) {
        SetupRequest& r = q.items.front();
        const auto now = Clock::now();
        // The report says the machine is set up: not where a setup request was refused or not
        // sent (a loaded program kept the position restore out, another config's axes, no
        // basic parameters), or the service would start programs from the wrong position or
        // with the wrong gear ratios (review of session 81).
        if (r.report && r.id == 0 &&
            (q.failed > 0 || q.withheld != nullptr || q.unrestored != nullptr)) {
          const std::string why = q.withheld != nullptr ? std::string(q.withheld)
                                  : q.unrestored != nullptr
                                      ? std::string(q.unrestored)
                                      : std::to_string(q.failed) + " of " +
                                            std::to_string(q.total) +
                                            " setup requests refused or unanswered";
          append_log(pending_log, stamp(),
                     "interpolator %d: error: setup not reported to tgm-service (%s): it starts "
                     "no program there until a PLC has set it up (plc.setup_before_start)",
                     number, why.c_str());
          q.items.pop_front();
          continue;
        }
        if (r.id == 0 && write) {
          if (r.since == Clock::time_point{}) {
            r.since = now;
            ++r.attempt;
          }
          r.id = plc->send(r.request);
          if (r.id != 0) {
            r.since = now;
            break;
          }
          if (now - r.since < 3s) break;
        } else if (r.id != 0) {
          if (std::optional<tgm::client::Reply> reply = plc->take_reply(r.id)) {
            if (reply->accepted && !r.report) ++q.accepted;
            if (!reply->accepted && !r.report) ++q.failed;
            if (!quiet || !r.quiet_ok || !reply->accepted) {
              append_log(pending_log, stamp(), "%s: %s", r.what.c_str(),
                         tgm::client::describe(*reply).c_str());
            }
            q.items.pop_front();
            continue;
          }
          if (now - r.since < 3s && !final) break;
        }
        // Not written, or unanswered for 3 s: written again, or given up, once writing resumes.
        if (!write && !final) break;
        tgm::client::Reply none;
        none.timed_out = true;
        none.sent = r.id != 0;
        none.waited = std::chrono::duration_cast<std::chrono::milliseconds>(now - r.since);
        if (r.attempt < r.attempts && write) {
          append_log(pending_log, stamp(), "%s: %s; sending it again (%d of %d)", r.what.c_str(),
                     tgm::client::describe(none).c_str(), r.attempt + 1, r.attempts);
          r.id = 0;
          r.since = Clock::time_point{};
          continue;
        }
        if (!r.report) ++q.failed;
        append_log(pending_log, stamp(), "%s: %s", r.what.c_str(),
                   !final      ? tgm::client::describe(none).c_str()
                   : r.id != 0 ? "no reply before the stop"
                               : "not sent before the stop");
        q.items.pop_front();
      }
      if (q.items.empty() && q.report) {
        q.report = false;
        // "setup done (0 of 0 requests accepted)" read as success where nothing was set
        // (review of session 77).
        append_log(pending_log, stamp(),
                   "interpolator %d: setup done (%d of %d requests accepted%s%s)", number,
                   q.accepted, q.total,
                   q.withheld != nullptr ? "; basic parameters not sent: " : "",
                   q.withheld != nullptr ? q.withheld : "");
        q.withheld = nullptr;
        q.unrestored = nullptr;
      }
    }
  };

  std::vector<tgm::plc::AckTrace> traces;
  if (!trace_path.empty()) traces.reserve(100'000);
  auto trace = [&](const tgm::plc::AckTrace& t) {
    if (!trace_path.empty() && traces.size() < 1'000'000) traces.push_back(t);
  };
  auto find_served = [&](int i) -> Served* {
    for (Served& sv : served) {
      if (sv.number == i) return &sv;
    }
    return nullptr;
  };

  // Shared by the event callback and the main loop, under `shared_mutex`.
  std::mutex shared_mutex;
  tgm::plc::MTracker tracker;
  tgm::plc::RefusedM refuse;
  for (int m : refuse_flag) refuse.refuse_everywhere(m);
  // Whether M `m` is refused on interpolator `i` now (the main loop's checks).
  const auto refused_now = [&](int i, std::int32_t m) {
    const std::lock_guard lock(shared_mutex);
    return refuse.refused(i, m);
  };
  std::vector<EventSeen> event_seen;
  event_seen.reserve(256);
  // More than 64 M-functions in a row share cycles in M_Func (core/MOTION.md): between two
  // consecutive events (none lost) m_func_count then rises by more than one, and the ones
  // between were overwritten within a cycle. Noted by the callback, logged by the main loop.
  struct Overwritten {
    int interpolator = 0;
    std::uint32_t unseen = 0;      // how many
    std::int32_t m = 0, line = 0;  // the M-function shown after them
  };
  struct LastEvent {
    std::uint64_t instance = 0, counter = 0;
    std::uint32_t m_count = 0;
  };
  std::array<LastEvent, tgm::kMaxInterpolators> last_event{};
  std::vector<Overwritten> overwritten;
  overwritten.reserve(16);
  if (events) {
    std::array<bool, tgm::kMaxInterpolators> serves{};
    for (const Served& sv : served) serves[static_cast<std::size_t>(sv.number)] = true;
    // Fast DDS receive thread: claim, acknowledge at once when due, hand the rest to the main
    // loop. No logging here (the main loop formats and writes every line).
    tgm::client::Client* client = &*plc;
    auto on_event = [&, serves, client](const tgm::client::Event& ev) {
      const tgm::msg::InterpolatorEvent& e = ev.sample;
      const auto seen = Clock::now();
      const int i = e.interpolator();
      if (i >= tgm::kMaxInterpolators || !serves[static_cast<std::size_t>(i)]) return;
      EventSeen rec;
      rec.interpolator = i;
      rec.m = e.m_func();
      rec.count = e.m_func_count();
      rec.instance = e.service_instance();
      rec.normal = tgm::run_flag_waits_for_m(static_cast<std::uint32_t>(e.run_flag()));
      bool refused = false;
      {
        const std::lock_guard lock(shared_mutex);
        LastEvent& last = last_event[static_cast<std::size_t>(i)];
        if (last.instance == e.service_instance() && last.counter != 0 &&
            e.event_counter() == last.counter + 1 && e.m_func_count() > last.m_count + 1) {
          overwritten.push_back({i, e.m_func_count() - last.m_count - 1, rec.m, m_func_line_of(e)});
        }
        last = {e.service_instance(), e.event_counter(), e.m_func_count()};
        if (!tracker.claim(i, e.service_instance(), e.m_func_count(), rec.m)) return;
        refused = rec.normal && refuse.refused(i, rec.m);
      }
      if (!refused && (!rec.normal || delay_for(rec.m) <= 0.0)) {
        rec.ack_call = Clock::now();
        rec.request_id = client->send_ack_m_func(i, rec.m, rec.count);
        rec.ack_written = Clock::now();
      }
      rec.action = rec.request_id != 0 ? EventSeen::Action::kAcked
                   : refused           ? EventSeen::Action::kRefused
                                       : EventSeen::Action::kScheduled;
      rec.line = m_func_line_of(e);
      rec.part = e.act_part();
      rec.params = e.m_function_parameter();
      rec.woke = ev.received;
      rec.seen = seen;
      const std::lock_guard lock(shared_mutex);
      event_seen.push_back(rec);
    };
    try {
      plc->on_event(on_event);
    } catch (const tgm::dds::SetupError& e) {
      std::fprintf(stderr, "tgm-plc: %s\n", e.what());
      return 1;
    }
  }
  auto log_m = [&](int i, std::int32_t m, bool normal, std::int32_t line, std::int32_t part,
                   const MParams& params) {
    append_log(pending_log, stamp(), "interpolator %d: M%d %s (line %d, part %d), parameters: %s",
               i, m, normal ? "normal: the interpolator waits" : "continuous: motion goes on", line,
               part, tgm::plc::params_text(params).c_str());
  };
  // Acknowledgements (and notes of continuous M-functions) whose reply the main loop still
  // waits for. None is waited for in place: a reply lost for one interpolator must not hold up
  // the handshake of the others (a synchronous request stalled the whole loop for its 3 s).
  std::vector<EventSeen> acked;
  // Writes the acknowledgement of `rec` from the main loop without waiting for its reply;
  // take_acked_replies() logs the reply, or tries the write again while none could be written
  // (no service matched yet, or the request window is full).
  auto send_from_loop = [&](EventSeen rec, EventSeen::Via via) {
    rec.via = via;
    rec.ack_call = Clock::now();
    rec.request_id = plc->send_ack_m_func(rec.interpolator, rec.m, rec.count);
    rec.ack_written = Clock::now();
    acked.push_back(rec);
  };
  // The record of an M-function the main loop acknowledges for `sv`.
  auto loop_seen = [](const Served& sv, std::int32_t m, std::uint32_t m_count, bool normal) {
    EventSeen rec;
    rec.interpolator = sv.number;
    rec.m = m;
    rec.count = m_count;
    rec.normal = normal;
    rec.part = sv.m_part;
    rec.woke = sv.woke_at;
    rec.seen = sv.seen_at;
    rec.instance = sv.instance;
    rec.action = EventSeen::Action::kAcked;
    return rec;
  };
  std::vector<EventSeen> drained;
  drained.reserve(256);
  // Logs what the event callback handed over; returns after scheduling delayed acknowledgements.
  std::vector<Overwritten> overwritten_drained;
  auto take_event_seen = [&] {
    {
      const std::lock_guard lock(shared_mutex);
      drained.swap(event_seen);
      overwritten_drained.swap(overwritten);
    }
    for (const Overwritten& o : overwritten_drained) {
      append_log(pending_log, stamp(),
                 "interpolator %d: %u M-function%s before M%d (line %d) reached M_Func in the "
                 "same cycle and %s overwritten: more than 64 in a row (core/MOTION.md); not "
                 "seen here",
                 o.interpolator, o.unseen, o.unseen == 1 ? "" : "s", o.m, o.line,
                 o.unseen == 1 ? "was" : "were");
    }
    overwritten_drained.clear();
    for (const EventSeen& rec : drained) {
      log_m(rec.interpolator, rec.m, rec.normal, rec.line, rec.part, rec.params);
      Served* sv = find_served(rec.interpolator);
      if (rec.action == EventSeen::Action::kAcked) {
        acked.push_back(rec);
      } else if (rec.action == EventSeen::Action::kRefused) {
        append_log(pending_log, stamp(),
                   "interpolator %d: M%d: refusing to acknowledge (--refuse-ack / script)",
                   rec.interpolator, rec.m);
      } else if (!rec.normal) {  // continuous, and the callback could not write the note
        send_from_loop(rec, EventSeen::Via::kLoop);
      } else if (sv != nullptr) {
        sv->m_part = rec.part;
        sv->ack_m = rec.m;
        sv->ack_count = rec.count;
        sv->ack_instance = rec.instance;
        sv->seen_at = rec.seen;
        sv->woke_at = rec.woke;
        sv->ack_at = rec.seen + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>(delay_for(rec.m)));
      }
    }
    drained.clear();
  };
  // Logs the reply to each acknowledgement and note in `acked` once it came, or that none came
  // within 3 s (then a normal M-function's acknowledgement is sent again while the state still
  // shows it). One not written yet is tried again each pass for those 3 s, as a synchronous
  // request waits for the service to match. `at_stop`: the last call, nothing is waited for.
  auto take_acked_replies = [&](bool at_stop) {
    for (auto it = acked.begin(); it != acked.end();) {
      auto t = Clock::now();
      if (it->request_id == 0 && !at_stop && t - it->ack_call < 3s) {
        it->request_id = plc->send_ack_m_func(it->interpolator, it->m, it->count);
        it->ack_written = Clock::now();
        ++it;
        continue;
      }
      std::optional<tgm::client::Reply> r;
      if (it->request_id != 0) r = plc->take_reply(it->request_id);
      t = Clock::now();
      if (!r && !at_stop && it->request_id != 0 && t - it->ack_written < 3s) {
        ++it;
        continue;
      }
      if (!r) {
        r.emplace();
        r->timed_out = true;
        r->sent = it->request_id != 0;
        r->waited = std::chrono::duration_cast<std::chrono::milliseconds>(
            t - (r->sent ? it->ack_written : it->ack_call));
        // Only for the service that showed it: a restarted one numbers its M-functions anew.
        if (Served* sv = find_served(it->interpolator);
            sv != nullptr && it->normal && !at_stop && sv->instance == it->instance) {
          sv->left_unanswered(it->m, it->count, t);
        }
      }
      const bool from_event = it->via == EventSeen::Via::kEvent;
      // Every acknowledgement and note, whoever wrote it (notes written by the main loop and
      // repeats were left out, so a trace with events had rows that one without lacked).
      tgm::plc::AckTrace row;
      row.interpolator = it->interpolator;
      row.act_part = it->part;
      row.woke = it->woke;
      row.seen = it->seen;
      row.ack_call = it->ack_call;
      row.ack_written = it->ack_written;
      row.reply = t;
      row.path = from_event ? "event" : it->via == EventSeen::Via::kRepeat ? "repeat" : "loop";
      row.m = it->m;
      row.m_func_count = it->count;
      row.normal = it->normal;
      row.reply_code = r->timed_out ? -1 : static_cast<int>(r->code);
      trace(row);
      if (it->via == EventSeen::Via::kRepeat) {
        append_log(pending_log, stamp(),
                   "interpolator %d: M%d still waits after an unanswered acknowledgement: sent "
                   "again: %s",
                   it->interpolator, it->m, note_reply(*r).c_str());
      } else if (it->normal) {
        append_log(pending_log, stamp(),
                   "interpolator %d: M%d acknowledged%s after %.3f s: %s (cycle %llu)",
                   it->interpolator, it->m, from_event ? " from the event" : "",
                   std::chrono::duration<double>(t - it->seen).count(),
                   tgm::client::describe(*r).c_str(), static_cast<unsigned long long>(r->cycle));
      } else {
        append_log(pending_log, stamp(), "interpolator %d: M%d noted%s: %s", it->interpolator,
                   it->m, from_event ? " from the event" : "", note_reply(*r).c_str());
      }
      it = acked.erase(it);
    }
  };

  std::optional<Clock::time_point> found_at;
  bool events_matched = false;
  // The first requests wait for the event topic's match until then (see the find).
  bool awaiting_match = false;
  Clock::time_point event_match_by{};
  auto last_wait_log = Clock::now();
  // Served interpolators the service does not host (its config has fewer): said once, a second
  // after the first state of another (every hosted one publishes every few ms). The PLC went on
  // saying "waiting for tgm-service" beside a running service, or nothing at all.
  std::optional<Clock::time_point> others_seen_at;
  bool unhosted_said = false;
  tgm::client::SilenceWatch silence(3s);
  tgm::dds::MalformedWatch malformed;
  // systemd (Type=notify): ready once the DDS entities exist; the watchdog is pinged while the
  // main loop turns (a hung loop acknowledges nothing and is restarted).
  const tgm::SystemdNotifier notifier = tgm::SystemdNotifier::from_environment();
  if (!notifier.problem().empty())
    append_log(pending_log, stamp(), "%s", notifier.problem().c_str());
  notifier.ready("waiting for tgm-service on DDS domain " + std::to_string(config.dds.domain_id));
  tgm::WatchdogGate gate(notifier.watchdog_us());
  std::uint64_t passes = 0;
  auto say_serving = [&] {
    std::string text = "serving interpolator";
    if (served.size() != 1) text += 's';
    for (std::size_t k = 0; k < served.size(); ++k) {
      text += (k == 0 ? " " : ", ") + std::to_string(served[k].number);
    }
    notifier.status(text + " on DDS domain " + std::to_string(config.dds.domain_id));
  };
  flush_log();
  bool duration_ended = false;
  while (!g_stop) {
    flush_log();
    if (gate.due(++passes)) notifier.watchdog();
    if (duration_s > 0.0 && stamp() >= duration_s) {
      duration_ended = true;
      break;
    }
    plc->poll(5ms);
    take_event_seen();
    take_acked_replies(false);
    // The first requests wait for the event topic's match (at most 2 s after the find, see
    // there), without holding up the loop.
    bool hold_writes = false;
    if (awaiting_match) {
      events_matched = plc->wait_for_event_match(std::chrono::milliseconds(0));
      if (events_matched) {
        awaiting_match = false;
      } else if (Clock::now() >= event_match_by) {
        append_log(pending_log, stamp(),
                   "the event topic has not matched 2 s after tgm-service was found: "
                   "M-functions are seen in the state until it does");
        awaiting_match = false;
      } else {
        hold_writes = true;
      }
    }
    pump_setup(!hold_writes, false);
    const auto now = Clock::now();
    for (Served& sv : served) {
      const tgm::msg::InterpolatorState* s = plc->state(sv.number);
      if (s == nullptr) continue;
      if (const std::uint64_t other = plc->other_service(sv.number); other != sv.other) {
        sv.other = other;
        if (other != 0) {
          append_log(pending_log, stamp(),
                     "interpolator %d: another tgm-service (instance %016llx) publishes too: "
                     "serving %016llx only; stop one of them",
                     sv.number, static_cast<unsigned long long>(other),
                     static_cast<unsigned long long>(plc->service_followed(sv.number)));
        }
      }
      if (sv.found && s->service_instance() != sv.instance) {
        // A restarted service: its interpolators start from the defaults, and an acknowledgement
        // still due belongs to a program that is gone.
        append_log(pending_log, stamp(),
                   "interpolator %d: tgm-service restarted (instance %016llx)", sv.number,
                   static_cast<unsigned long long>(s->service_instance()));
        sv.found = false;
        sv.ack_m = 0;
        sv.unanswered_m = 0;
        sv.restore = sv.last_axes > 0;
        events_matched = false;
        SetupQueue& q = setup[sv.number];
        if (!q.items.empty()) {
          append_log(pending_log, stamp(),
                     "interpolator %d: %zu requests of the PLC's own dropped: they were for the "
                     "service before its restart",
                     sv.number, q.items.size());
        }
        q = SetupQueue{};
      }
      if (!sv.found) {
        sv.instance = s->service_instance();
        sv.found = true;
        append_log(pending_log, stamp(), "interpolator %d: found (status %d %s)", sv.number,
                   s->status(), std::string(tgm::client::status_name(s->status())).c_str());
        say_serving();
        // Events are VOLATILE: those written before the event reader matched never arrive.
        // Match before the first request, so that whatever this PLC causes from here on is seen
        // as an event (the state carries it either way: the fall-back when no match comes).
        if (events && !events_matched && !awaiting_match) {
          awaiting_match = true;
          event_match_by = Clock::now() + 2s;
        }
        // Basic parameters (the manual: the PLC sets them): Rel_Speed and the Command
        // structure with the config's smoothing and gear ratios.
        // Queued behind what a script queued for it before it was found, if anything.
        setup[sv.number].report = true;
        setup[sv.number].withheld = basic ? nullptr : "--no-basic-params";
        char what[320];
        // The basic parameters go by axis index (gear ratios, the IIR axis mask): from a config
        // whose axes are not the service's they would set the wrong axes.
        const std::string mine = config.machine.axis_letters(sv.number);
        const std::string theirs = s->axis_letters().to_string();
        const bool same_axes = theirs.empty() || mine.compare(0, theirs.size(), theirs) == 0;
        if (basic && !same_axes) {
          setup[sv.number].withheld = "this config's axes are not the service's";
          append_log(pending_log, stamp(),
                     "interpolator %d: error: basic parameters not sent: the service drives the "
                     "axes %s, this config (%s) has %s: give tgm-plc the service's config",
                     sv.number, theirs.c_str(),
                     tgm::cli::ArgReader::config_file(config_path).path.c_str(), mine.c_str());
        } else if (!tgm::client::same_machine(*s, config.machine, sv.number)) {
          // Said, not refused: the service's config moves the machine, and the smoothing this
          // PLC sets is its own config's. A mix of two configs is rarely meant.
          append_log(pending_log, stamp(),
                     "interpolator %d: warning: the service's machine config is not %s (axis "
                     "limits, cycle time, smoothing or buffer size differ; its machine digest "
                     "%016llx, this config's %016llx): give tgm-plc the service's config",
                     sv.number, tgm::cli::ArgReader::config_file(config_path).path.c_str(),
                     static_cast<unsigned long long>(s->machine_digest()),
                     static_cast<unsigned long long>(
                         tgm::machine_digest(config.machine, sv.number, s->number_axes())));
        }
        // A PLC started while a program is under way (a restart after a crash) leaves the
        // machine as it is: the service keeps the parameters set before, and new ones would
        // change it mid-program (a gear ratio written while M51 waited made PositionInc jump by
        // Position x dRatio, and the program went on).
        const int status = s->status();
        // Ready (4) counts once the loaded program has moved or paused at M0 (a stop in its
        // middle); a program loaded and not yet started is not under way.
        using Status = tgm::InterpolatorStatus;
        const auto is = [status](Status x) { return status == static_cast<int>(x); };
        // And an emergency stop on the trajectory (Command 4) with its program loaded, which a
        // start resumes: the ratio was sent there, and refused (review of the HMI, session 75).
        const bool under_way =
            is(Status::kRunning) || is(Status::kEmergencyRamp) || is(Status::kUnderrun) ||
            (is(Status::kReady) && s->buffered_segments() > 0 &&
             (s->move_distance() > 0.0 || s->program_stop())) ||
            (is(Status::kEmergencyStopped) && s->buffered_segments() > 0 && !s->off_trajectory());
        // Rel_Speed too: a PLC restarted mid-cut reset the operator's override (it was written
        // before this check).
        if (rel_speed && !under_way) {
          std::snprintf(what, sizeof what, "interpolator %d: Rel_Speed = %g", sv.number,
                        *rel_speed);
          queue_request(sv.number, tgm::client::rel_speed_request(sv.number, *rel_speed), what,
                        false, 1);
        } else if (rel_speed) {
          append_log(pending_log, stamp(),
                     "interpolator %d: Rel_Speed not written: a program is under way (status %d "
                     "%s); the override stays %g",
                     sv.number, status, std::string(tgm::client::status_name(status)).c_str(),
                     s->rel_speed());
        }
        if (basic && same_axes && under_way) {
          setup[sv.number].withheld = "a program is under way";
          append_log(pending_log, stamp(),
                     "interpolator %d: basic parameters not sent: a program is under way "
                     "(status %d %s), and they would change the machine in its middle; the "
                     "service keeps the ones set before (restart tgm-plc while it is idle to "
                     "send them)",
                     sv.number, status, std::string(tgm::client::status_name(status)).c_str());
        }
        if (basic && same_axes && !under_way) {
          const auto& sm = config.machine.smoothing;
          // Rounded as the loader checked it (at most INT32_MAX there: Command_Parameter is
          // 32-bit); a cast truncated 0.7 to 0, which the service refused.
          const std::int32_t spline[] = {
              sm.spline_points, static_cast<std::int32_t>(std::llround(sm.spline_jerk_mm_s3))};
          const auto& axes = config.machine.interpolators[static_cast<std::size_t>(sv.number)].axes;
          // Only the axes the service drives (its letters are the first of ours, same_axes: a
          // lower Number_Axes, or a config without the others): gear ratios for the rest were
          // refused one by one, and the IIR mask gets only their bits (the service refuses a
          // mask that names none of them; the config's mask is shared by interpolators of
          // different sizes).
          const std::size_t driven = theirs.empty() ? axes.size() : theirs.size();
          const std::uint32_t iir_mask =
              tgm::IirFilter::mask_of_axes(sm.iir_axis_mask, static_cast<int>(driven));
          const std::int32_t iir[] = {
              static_cast<std::int32_t>(sm.iir_p_e6), static_cast<std::int32_t>(sm.iir_q_e6),
              static_cast<std::int32_t>(sm.iir_f_e6), static_cast<std::int32_t>(iir_mask)};
          // A request left unanswered is sent again, twice at most: setting the same
          // parameters twice is harmless, and a lossy network can lose the request or its reply
          // for longer than the timeout (30 % loss left one interpolator without them).
          // --quiet still logs a refusal: it is an error (e.g. the interpolator was already
          // running a program when the PLC came up).
          std::snprintf(what, sizeof what,
                        "interpolator %d: basic parameters: Command -2 (spline %d points)",
                        sv.number, sm.spline_points);
          queue_request(sv.number, tgm::client::command_request(sv.number, -2, spline), what, true,
                        3);
          std::snprintf(what, sizeof what,
                        "interpolator %d: basic parameters: Command -1 (IIR mask 0x%x)", sv.number,
                        iir_mask);
          queue_request(sv.number, tgm::client::command_request(sv.number, -1, iir), what, true, 3);
          if (driven < axes.size()) {
            append_log(pending_log, stamp(),
                       "interpolator %d: gear ratios of %s not sent: the service drives %s "
                       "(Number_Axes %zu)",
                       sv.number, mine.substr(driven).c_str(), theirs.c_str(), driven);
          }
          for (std::size_t a = 0; a < driven; ++a) {
            // Ratio as counter [inc] / denominator [mm], both 32-bit, exactly the configured
            // double (x 1000 + 0.5 over 1000 made -1000 into -999.999 and 3e6 into
            // -2147483.648). A ratio no such pair carries goes to the Ratio register.
            const double want = axes[a].ratio_inc_per_mm;
            const auto f = tgm::OutputStage::ratio_as_fraction(want);
            const char letter = config.machine.axis_letters(sv.number)[a];
            // The value, and the service's own where it differs: a PLC config whose ratio is
            // not the service's replaced it without a word (review of session 77).
            std::string value = tgm::shortest_text(want) + " inc/mm";
            if (const double had = s->ratio()[a]; had != want)
              value += ", the service had " + tgm::shortest_text(had);
            if (f.exact) {
              const std::int32_t ratio[] = {static_cast<std::int32_t>(a), f.numerator_inc,
                                            f.denominator_mm};
              std::snprintf(what, sizeof what,
                            "interpolator %d: basic parameters: Command 1024 (gear ratio of axis "
                            "%c: %s)",
                            sv.number, letter, value.c_str());
              queue_request(sv.number, tgm::client::command_request(sv.number, 1024, ratio), what,
                            true, 3);
            } else {
              std::snprintf(what, sizeof what,
                            "interpolator %d: basic parameters: Ratio register of axis %c = %s "
                            "(no 32-bit numerator / denominator of Command 1024 carries it)",
                            sv.number, letter, value.c_str());
              queue_request(sv.number,
                            tgm::client::ratio_request(sv.number, static_cast<int>(a), want), what,
                            true, 3);
            }
          }
        }
        if (sv.restore) {
          sv.restore = false;
          restore_position(sv, *s,
                           !basic       ? "--no-basic-params"
                           : !same_axes ? "this config's axes are not the service's"
                           : under_way  ? "a program is under way"
                                        : nullptr);
        }
        // Last, where the service waits for it (plc.setup_before_start: its state shows
        // plc_setup 1): it starts no program before this report, so a program waiting for a
        // restarted service does not start from 0 before the position restore above (review
        // of session 80). Sent only when every request before it was accepted (pump_setup).
        if (s->plc_setup() == 1) {
          std::snprintf(what, sizeof what, "interpolator %d: setup reported to tgm-service",
                        sv.number);
          SetupQueue& sq = setup[sv.number];
          sq.items.push_back(
              SetupRequest{tgm::client::plc_setup_done_request(sv.number), what, true, 3});
          sq.items.back().report = true;
        }
        if (try_start) {
          std::snprintf(what, sizeof what, "interpolator %d: trying to start as the PLC",
                        sv.number);
          queue_request(sv.number, tgm::client::start_request(sv.number), what, false, 1);
        }
        if (!found_at) found_at = Clock::now();
      }
      // Not while the PLC's own requests are on their way (a restore among them): a service
      // restarted again before its Command 2048 was answered showed 0 here, and the position
      // was lost without a word.
      if (setup[sv.number].items.empty()) {
        sv.last_axes = driven_axes(*s);
        for (std::size_t a = 0; a < sv.last_axes; ++a) sv.last_inc[a] = s->position_inc()[a];
        sv.last_letters = s->axis_letters().to_string();
      }
      // A new M-function: M_Func set with an m_func_count that neither this loop nor the event
      // callback has claimed (with events, the callback usually sees it first).
      // (The line logs a copy of the fields: it is written at the end of the pass.)
      bool seen_new = false;
      bool seen_normal = false;
      std::int32_t seen_m = 0, seen_line = 0, seen_part = 0;
      auto seen_params = s->m_function_parameter();
      auto log_seen = [&] {
        if (!seen_new) return;
        seen_new = false;
        log_m(sv.number, seen_m, seen_normal, seen_line, seen_part, seen_params);
      };
      const bool normal = tgm::run_flag_waits_for_m(static_cast<std::uint32_t>(s->run_flag()));
      bool claimed = false;
      bool refused = false;
      {
        const std::lock_guard lock(shared_mutex);
        claimed = tracker.claim(sv.number, s->service_instance(), s->m_func_count(), s->m_func());
        refused = claimed && normal && refuse.refused(sv.number, s->m_func());
      }
      if (claimed) {
        sv.m_part = s->act_part();
        // An acknowledgement due at once goes out before this line is formatted (below).
        seen_new = true;
        seen_normal = normal;
        seen_m = s->m_func();
        seen_line = m_func_line_of(*s);
        seen_part = s->act_part();
        seen_params = s->m_function_parameter();
        sv.seen_at = now;
        sv.woke_at = plc->last_wake();
        if (!normal) {
          log_seen();
          send_from_loop(loop_seen(sv, s->m_func(), s->m_func_count(), false),
                         EventSeen::Via::kLoop);
        } else if (refused) {
          log_seen();
          append_log(pending_log, stamp(),
                     "interpolator %d: M%d: refusing to acknowledge (--refuse-ack / script)",
                     sv.number, s->m_func());
        } else {
          sv.ack_m = s->m_func();
          sv.ack_count = s->m_func_count();
          sv.ack_instance = s->service_instance();
          sv.ack_at = now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(delay_for(s->m_func())));
        }
      }
      // An acknowledgement not yet due whose M-function went without it: its program dropped
      // (a stop off the trajectory, a clear) or another client acknowledged it. The state shows
      // its count with M_Func 0, or a later count. It used to be sent all the same, and refused
      // ("went with its program") seconds after the PLC's own Command 5.
      // Only on the state of the instance that showed it: in the moments after a restart the
      // event of the new one's M-function can come before its first state.
      if (sv.ack_m != 0 && s->service_instance() == sv.ack_instance &&
          (s->m_func_count() > sv.ack_count ||
           (s->m_func_count() == sv.ack_count && s->m_func() == 0))) {
        log_seen();
        append_log(pending_log, stamp(),
                   "interpolator %d: M%d not acknowledged: it went before its acknowledgement "
                   "was due (status %d %s, M_Func %d)",
                   sv.number, sv.ack_m, s->status(),
                   std::string(tgm::client::status_name(s->status())).c_str(), s->m_func());
        sv.ack_m = 0;
      }
      if (sv.ack_m != 0 && now >= sv.ack_at) {
        log_seen();
        // Refused after it was scheduled (a script step that raced the event callback's
        // hand-over): not written either.
        if (refused_now(sv.number, sv.ack_m)) {
          append_log(pending_log, stamp(),
                     "interpolator %d: M%d: refusing to acknowledge (--refuse-ack / script)",
                     sv.number, sv.ack_m);
        } else {
          send_from_loop(loop_seen(sv, sv.ack_m, sv.ack_count, true), EventSeen::Via::kLoop);
        }
        sv.ack_m = 0;
      }
      // An unanswered acknowledgement (lost on a lossy network, or its reply was): while the
      // state still shows that M-function (same m_func_count) a second after, it is sent again.
      // One that arrived meanwhile makes the service refuse the repeat (it names the count).
      // While the repeat waits for its reply none is sent; unanswered, it arms the next.
      if (sv.unanswered_m != 0) {
        if (s->m_func() != sv.unanswered_m || s->m_func_count() != sv.unanswered_count ||
            refused_now(sv.number, sv.unanswered_m)) {
          sv.unanswered_m = 0;
        } else if (Clock::now() - sv.unanswered_at >= 1s) {
          send_from_loop(loop_seen(sv, sv.unanswered_m, sv.unanswered_count, true),
                         EventSeen::Via::kRepeat);
          sv.unanswered_m = 0;
        }
      }
      log_seen();
    }
    std::string hosted;
    for (int i = 0; i < tgm::kMaxInterpolators; ++i) {
      if (plc->state(i) != nullptr) hosted += (hosted.empty() ? "" : ", ") + std::to_string(i);
    }
    if (!hosted.empty() && !others_seen_at) others_seen_at = now;
    if (!unhosted_said && others_seen_at && now - *others_seen_at >= 1s) {
      unhosted_said = true;
      std::string missing;
      int unhosted = 0;
      for (const Served& sv : served) {
        if (sv.found || plc->state(sv.number) != nullptr) continue;
        missing += (missing.empty() ? "" : ", ") + std::to_string(sv.number);
        ++unhosted;
      }
      if (unhosted > 0) {
        append_log(pending_log, stamp(),
                   "interpolator%s %s: tgm-service on DDS domain %d hosts %s only (its config has "
                   "fewer interpolators than %s): not served until a service hosts %s",
                   unhosted == 1 ? "" : "s", missing.c_str(), config.dds.domain_id, hosted.c_str(),
                   tgm::client::config_name(config).c_str(), unhosted == 1 ? "it" : "them");
      }
    }
    if (!found_at && hosted.empty() && now - last_wait_log > 5s) {
      last_wait_log = now;
      append_log(pending_log, stamp(), "waiting for tgm-service on DDS domain %d ...",
                 config.dds.domain_id);
    }
    if (const std::string bad = malformed.update(config.dds.domain_id, now); !bad.empty()) {
      append_log(pending_log, stamp(), "%s", bad.c_str());
    }
    if (found_at) {
      std::uint64_t n = 0;
      for (const Served& sv : served) n += plc->state_samples(sv.number);
      const auto change = silence.update(n, now);
      if (change == tgm::client::SilenceWatch::Change::kSilent) {
        append_log(pending_log, stamp(),
                   "no state from tgm-service for 3 s (stopped, or the network is down): waiting");
        notifier.status("no state from tgm-service for 3 s: waiting");
      } else if (change == tgm::client::SilenceWatch::Change::kBack) {
        append_log(pending_log, stamp(), "tgm-service is back");
        say_serving();
      }
      const double t = std::chrono::duration<double>(now - *found_at).count();
      for (std::size_t k = 0; k < script.size(); ++k) {
        const tgm::PlcScriptStep& st = script[k];
        if (script_done[k] || t < st.at_s) continue;
        // Writes by axis letter go to the service's axis of that letter, which its state names:
        // such a step waits for the state of its interpolator.
        const tgm::msg::InterpolatorState* ist = plc->state(st.interpolator);
        if (ist == nullptr && (!st.ratio.empty() || !st.offset_inc.empty())) continue;
        script_done[k] = true;
        char what[320];
        if (st.rel_speed) {
          std::snprintf(what, sizeof what, "script line %d: interpolator %d: Rel_Speed = %g",
                        st.line, st.interpolator, *st.rel_speed);
          queue_request(st.interpolator,
                        tgm::client::rel_speed_request(st.interpolator, *st.rel_speed), what, false,
                        1);
        }
        if (st.number_axes) {
          std::snprintf(what, sizeof what, "script line %d: interpolator %d: Number_Axes = %d",
                        st.line, st.interpolator, *st.number_axes);
          queue_request(st.interpolator,
                        tgm::client::number_axes_request(st.interpolator, *st.number_axes), what,
                        false, 1);
        }
        // Register writes by axis letter, to the index of that letter among the axes the service
        // drives (its state's letters). The index in this PLC's config set another axis when
        // the two differ (a ratio for C went to the service's Z): a letter the service does not
        // drive is not written at all, said as an error and in the exit code.
        const std::string theirs = ist != nullptr ? ist->axis_letters().to_string() : "";
        for (const tgm::PlcAxisWrite& w : tgm::plc_script_axis_writes(st, theirs)) {
          const bool ratio = w.reg == tgm::PlcAxisWrite::Register::kRatio;
          char value[64];
          if (ratio) {
            // Every digit (%g's six showed a ratio of 1234.5678 as 1234.57).
            std::snprintf(value, sizeof value, "Ratio %c = %s inc/mm", w.letter,
                          tgm::shortest_text(w.ratio_inc_per_mm).c_str());
          } else {
            std::snprintf(value, sizeof value, "Offset %c = %lld inc", w.letter,
                          static_cast<long long>(w.offset_inc));
          }
          if (w.axis < 0) {
            const std::string why =
                theirs.empty()
                    ? std::string("the service publishes no axis letters for it")
                    : "the service has no axis " + std::string(1, w.letter) + ": it drives " +
                          theirs + " (Number_Axes " + std::to_string(ist->number_axes()) + ")";
            append_log(pending_log, stamp(),
                       "script %s:%d: interpolator %d: error: %s not written: %s; the script "
                       "names the axes of this config (%s)",
                       script_path.c_str(), st.line, st.interpolator, value, why.c_str(),
                       config.machine.axis_letters(st.interpolator).c_str());
            if (held_writes++ == 0) {
              first_held = script_path + ":" + std::to_string(st.line) + ": interpolator " +
                           std::to_string(st.interpolator) + ": " + value + ": " + why;
            }
            continue;
          }
          std::snprintf(what, sizeof what, "script line %d: interpolator %d: %s", st.line,
                        st.interpolator, value);
          queue_request(
              st.interpolator,
              ratio ? tgm::client::ratio_request(st.interpolator, w.axis, w.ratio_inc_per_mm)
                    : tgm::client::offset_request(st.interpolator, w.axis, w.offset_inc),
              what, false, 1);
        }
        if (st.command) {
          // The parameters up to the last one that is not 0, as the script gave them.
          std::size_t shown = st.parameters.size();
          while (shown > 0 && st.parameters[shown - 1] == 0) --shown;
          std::string params;
          for (std::size_t i = 0; i < shown; ++i) {
            params += (i == 0 ? " [" : ", ") + std::to_string(st.parameters[i]);
          }
          if (shown > 0) params += "]";
          std::snprintf(what, sizeof what, "script line %d: interpolator %d: Command %d%s", st.line,
                        st.interpolator, *st.command, params.c_str());
          queue_request(st.interpolator,
                        tgm::client::command_request(st.interpolator, *st.command, st.parameters),
                        what, false, 1);
        }
        if (st.start) {
          std::snprintf(what, sizeof what, "script line %d: interpolator %d: start as the PLC",
                        st.line, st.interpolator);
          queue_request(st.interpolator, tgm::client::start_request(st.interpolator), what, false,
                        1);
        }
        for (int m : st.refuse_ack) {
          {
            const std::lock_guard lock(shared_mutex);
            refuse.refuse(st.interpolator, m);
          }
          append_log(pending_log, stamp(),
                     "script line %d: interpolator %d: from now on M%d is not acknowledged",
                     st.line, st.interpolator, m);
          // "From now on" includes the M-function that already waits: its acknowledgement, due
          // later (--ack-delay, plc.m_delay_s), is not written, nor is an unanswered one sent
          // again. It was: the interpolator went on at M51 seconds after this line.
          Served* sv = find_served(st.interpolator);
          if (sv != nullptr && sv->ack_m == m) {
            append_log(pending_log, stamp(),
                       "script line %d: interpolator %d: M%d (part %d) waits: its "
                       "acknowledgement, due in %.3f s, is not sent",
                       st.line, st.interpolator, m, sv->m_part,
                       std::max(0.0, std::chrono::duration<double>(sv->ack_at - now).count()));
            sv->ack_m = 0;
          }
          if (sv != nullptr && sv->unanswered_m == m) sv->unanswered_m = 0;
        }
      }
    }
  }
  const auto loop_ended = Clock::now();
  notifier.stopping();
  // Every M-function seen and every acknowledgement is logged, even when the stop came first.
  // Replies still on their way get a moment (a stop right after an acknowledgement).
  plc->poll(std::chrono::nanoseconds(0));
  take_event_seen();
  auto setup_written = [&] {
    for (const auto& [number, q] : setup) {
      if (!q.items.empty() && q.items.front().id != 0) return true;
    }
    return false;
  };
  for (const auto until = Clock::now() + 1s;
       (!acked.empty() || setup_written()) && Clock::now() < until;) {
    take_acked_replies(false);
    pump_setup(false, false);
    if (!acked.empty() || setup_written()) plc->poll(5ms);
  }
  take_acked_replies(true);
  pump_setup(false, true);
  if (events) {
    append_log(pending_log, stamp(),
               "events: %llu received, %llu lost, %llu written before the PLC joined",
               static_cast<unsigned long long>(plc->events_received()),
               static_cast<unsigned long long>(plc->events_lost()),
               static_cast<unsigned long long>(plc->events_before_join()));
  }
  if (const std::uint64_t bad = tgm::dds::malformed_samples(); bad != 0) {
    append_log(pending_log, stamp(), "malformed DDS samples were dropped (%llu failed reads)",
               static_cast<unsigned long long>(bad));
  }
  // A normal M-function still waiting is left to the next PLC: said, since the interpolator
  // stands until one acknowledges it (the log ended with "stopping" alone).
  for (const Served& sv : served) {
    const auto* st = plc->state(sv.number);
    if (st == nullptr || st->m_func() == 0 || st->m_func() >= 1000) continue;
    const auto section = tgm::run_flag_section(static_cast<std::uint32_t>(st->run_flag()));
    if (section != tgm::SectionState::kWaitMFunc && section != tgm::SectionState::kWaitMFuncEnd)
      continue;
    append_log(pending_log, stamp(),
               "interpolator %d: M%d (line %d) is left waiting, not acknowledged: the "
               "interpolator stands until a PLC acknowledges it",
               sv.number, st->m_func(), m_func_line_of(*st));
  }
  append_log(pending_log, stamp(), "stopping");
  flush_log();
  int exit_code = 0;
  if (std::FILE* f = trace_file.stream()) {
    std::fputs(tgm::plc::kAckTraceHeader, f);
    for (const tgm::plc::AckTrace& t : traces) std::fputs(tgm::plc::ack_trace_row(t).c_str(), f);
  }
  if (held_writes > 0) {
    std::fprintf(stderr,
                 "tgm-plc: %d axis write%s of the script %s not sent (the first: %s): give "
                 "tgm-plc the service's config, or name the service's axes in the script\n",
                 held_writes, held_writes == 1 ? "" : "s", held_writes == 1 ? "was" : "were",
                 first_held.c_str());
    exit_code = 3;
  }
  // Steps not due yet (or waiting for their interpolator's state) when the run ended: said,
  // and after a --duration end the exit code says the script did not run whole (it said 0 with
  // a stop step left out). A signal is the operator's stop: said, exit code 0.
  if (const std::string unrun = tgm::plc_script_unrun(script, script_done, script_path);
      !unrun.empty()) {
    char when[160];
    if (found_at) {
      std::snprintf(when, sizeof when, "%.3f s after tgm-service was found",
                    std::chrono::duration<double>(loop_ended - *found_at).count());
    } else {
      std::snprintf(when, sizeof when, "before tgm-service was found");
    }
    if (duration_ended) {
      std::fprintf(stderr,
                   "tgm-plc: %s: --duration %g s ended the run %s (at_s counts from then)\n",
                   unrun.c_str(), duration_s, when);
      exit_code = 3;
    } else {
      std::fprintf(stderr, "tgm-plc: %s: the PLC was stopped by a signal %s\n", unrun.c_str(),
                   when);
    }
  }
  if (std::string why; trace_file.is_open() && !trace_file.finish(why)) {
    std::fprintf(stderr, "tgm-plc: %s: %s\n", trace_path.c_str(), why.c_str());
    exit_code = 1;
  }
  // Before the locals the event callback uses go out of scope: ~Client detaches the callback.
  plc.reset();
  return exit_code;
}

}  // namespace
