// tgm-service: hosts the configured interpolators, runs the interpolation cycle in real time and
// serves them over DDS (DESIGN.md sections 1, 3, 6). SIGINT / SIGTERM stop it cleanly.
#include <pthread.h>
#include <sched.h>
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "dds_port.hpp"
#include "tgm/atomic_file.hpp"
#include "tgm/cli_args.hpp"
#include "tgm/cli_numbers.hpp"
#include "tgm/dds_overrides.hpp"
#include "tgm/log_time.hpp"
#include "tgm/service/engine.hpp"
#include "tgm/service/rt_loop.hpp"
#include "tgm/systemd_notify.hpp"
#include "tgm/yaml_config.hpp"

namespace {

// "0-3,6" for the CPUs in `set`.
std::string cpu_list(const cpu_set_t& set) {
  std::string out;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (!CPU_ISSET(static_cast<unsigned>(c), &set)) continue;
    int last = c;
    while (last + 1 < CPU_SETSIZE && CPU_ISSET(static_cast<unsigned>(last + 1), &set)) ++last;
    // Appended piece by piece: GCC 12 at -O3 warns (-Wrestrict, falsely) on "-" + to_string().
    if (!out.empty()) out += ',';
    out += std::to_string(c);
    if (last > c) {
      out += '-';
      out += std::to_string(last);
    }
    c = last;
  }
  return out.empty() ? "(none)" : out;
}

constexpr const char* kUsage =
    "usage: tgm-service [--config YAML] [OPTIONS]\n"
    "\n"
    "Hosts the configured interpolators (1..3), runs their cycle every cycle_time_us with\n"
    "absolute deadlines and serves state, setpoints, requests and the program stream over DDS.\n"
    "Stops cleanly on SIGINT / SIGTERM (exit code 0; SIGHUP, a closed terminal, is ignored),\n"
    "bringing axes that still move to rest on the trajectory first (normal stop, at most 30 s;\n"
    "exit code 1 when they still moved then);\n"
    "a stop that takes longer than 5 s says what it waits for, and a second SIGINT / SIGTERM\n"
    "while stopping exits at once (code 1).\n"
    "\n"
    "  --config YAML          machine config (default: $TGM_CONFIG, the installed or the\n"
    "                         in-tree config/default.yaml)\n"
    "%s"
    "  --no-realtime          do not try SCHED_FIFO / mlockall\n"
    "  --rt-priority N        SCHED_FIFO priority of the cycle thread, 1..99 (default 80)\n"
    "  --cpu N                pin the cycle thread to CPU N, one this process may run on\n"
    "                         (default: not pinned)\n"

    "  --dds-priority N       SCHED_FIFO priority of every DDS thread (Fast DDS's, receiver,\n"
    "                         publisher), 1..98 and below --rt-priority; default 0 = normal\n"
    "  --chunk-budget N       program records appended per cycle, all interpolators together\n"
    "                         (default 1024, 1..1000000)\n"
    "  --request-budget N     requests executed per cycle, all interpolators together\n"
    "                         (default 32, 1..1024); up to 256 more wait, beyond that a\n"
    "                         request is answered \"busy\"\n"
    "  --state-period-ms N    publish each state at least every N ms (default 20, 1..50)\n"
    "  --setpoint-decimation N  publish setpoints every Nth cycle (default 1, 1..10000)\n"
    "  --check-limits         check every axis' velocity, acceleration, jerk and corner steps\n"
    "                         (of velocity, and of acceleration where the curvature changes)\n"
    "                         on the interpolated positions each cycle; each excess goes to\n"
    "                         the HMI as a warning (axis, size, limit, line, cycle)\n"
    "  --limit-share F        with --check-limits (implied): check against F (0..1] of each\n"
    "                         limit (the motion is unchanged), e.g. 0.8 reports where a\n"
    "                         program uses over 80 %%\n"
    "  --service-check-ms N   before serving, wait up to N ms for the state of another\n"
    "                         tgm-service on the domain and exit (code 1) if one is live\n"
    "                         (default 500, 0..10000). Of two started together, one gives\n"
    "                         way (exit code 1) in its first 10,000 cycles. 0 = do not look,\n"
    "                         and never give way: two services may then both serve\n"
    "  --duration S           stop by itself after S seconds (at most 1e9)\n"
    "  --stats FILE           write lateness, handshake (the first 100,000) and counter\n"
    "                         figures as JSON at exit\n"
    "  --handshake-trace FILE write the time stamps of every M-function handshake (up to a\n"
    "                         million) as CSV at exit\n"
    "  --log-time WHEN        local date and time (ms) before each log line: auto (default:\n"
    "                         unless the output goes to systemd's journal, which stamps it),\n"
    "                         on or off\n"
    "  --check-config         check the config (its values, the interpolators it builds, the\n"
    "                         DDS settings and profiles file), print what it sets up with\n"
    "                         each interpolator's machine digest, and exit: 0 when it is\n"
    "                         usable, 2 with every problem found; DDS is not joined\n"
    "  --help                 this text\n"
    "  --version              print tgm-service's version\n"
    "\n"
    "Under systemd (Type=notify: the installed lib/systemd/system/tgm-service.service) it says\n"
    "READY=1 once its cycle runs, its state in STATUS=, and STOPPING=1; with WatchdogSec= it\n"
    "pings the watchdog only while the cycle thread makes progress.\n";

// How long a stop waits for moving axes to come to rest before the process exits regardless.
constexpr auto kWindDownLimit = std::chrono::seconds(30);

std::int64_t percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(k, v.size() - 1)];
}

int service_main(int argc, char** argv);

// What --check-config prints for a usable config: what the service would set up with it.
std::string config_summary(const tgm::AppConfig& config, const std::string& path) {
  const tgm::MachineConfig& m = config.machine;
  std::string out = "tgm-service: config " + path + " is usable\n";
  // Paths and names of any length: appended, not formatted into a fixed buffer.
  out += "  cycle " + std::to_string(m.cycle_time_us) + " us; DDS domain " +
         std::to_string(config.dds.domain_id) + ", participant prefix '" +
         config.dds.participant_prefix + "', profiles " +
         (config.dds.profiles_file.empty() ? "(Fast DDS defaults)" : config.dds.profiles_file) +
         "\n";
  char b[160];
  for (int i = 0; i < static_cast<int>(m.interpolators.size()); ++i) {
    const tgm::InterpolatorConfig& ip = m.interpolators[static_cast<std::size_t>(i)];
    const int axes = static_cast<int>(ip.axes.size());
    std::snprintf(b, sizeof b,
                  "  interpolator %d: axes %s, Buffer_Size %d, machine digest %016llx\n", i,
                  m.axis_letters(i).c_str(), ip.buffer_size,
                  static_cast<unsigned long long>(tgm::machine_digest(m, i, axes)));
    out += b;
  }
  std::snprintf(b, sizeof b, "  a start waits for the PLC's setup report: %s\n",
                config.plc.setup_before_start ? "yes (plc.setup_before_start)" : "no");
  out += b;
  out +=
      "The machine digest of a running service is in tgm-hmi status: the same digest, the same "
      "limits.\n";
  return out;
}

}  // namespace

// What escapes the setup ends with words and exit 1 (run_guarded). Once the cycle thread runs,
// an exception is a defect that terminates the process.
int main(int argc, char** argv) {
  return tgm::cli::run_guarded("tgm-service", service_main, argc, argv);
}

namespace {

int service_main(int argc, char** argv) {
  std::string config_path;
  std::string stats_path;
  std::string trace_path;
  tgm::DdsOverrides overrides;
  tgm::service::RtOptions rt;
  tgm::service::EngineOptions engine_options;
  tgm::service::DdsPortOptions port_options;
  double duration_s = 0.0;
  int dds_priority = 0;
  long long service_check_ms = 500;
  tgm::cli::ArgReader args(argc, argv, "tgm-service");
  bool no_realtime = false;
  bool check_config = false;
  bool rt_priority_given = false;
  std::string log_time = "auto";
  while (args.more()) {
    long long n = 0;
    if (args.help_flag()) {
      std::printf(kUsage, tgm::kDdsOverrideHelp);
      return 0;
    }
    if (args.version_flag()) {
      std::printf("%s\n", args.version_line().c_str());
      return 0;
    }
    if (args.dds_flag(overrides) || args.flag("--config", config_path) ||
        args.flag("--stats", stats_path) || args.flag("--handshake-trace", trace_path) ||
        args.flag("--log-time", log_time) || args.boolean("--no-realtime", no_realtime) ||
        args.boolean("--check-config", check_config) ||
        args.boolean("--check-limits", engine_options.check_limits)) {
      continue;
    }
    if (args.whole_flag("--cpu", 0, 1023, rt.cpu) ||
        args.whole_flag("--dds-priority", 0, 98, dds_priority) ||
        args.whole_flag("--service-check-ms", 0, 10000, service_check_ms) ||
        args.whole_flag("--setpoint-decimation", 1, 10000, port_options.setpoint_decimation) ||
        args.number_flag("--duration", duration_s, "seconds, > 0 and at most 1e9",
                         [](double v) { return v > 0.0 && v <= 1e9; })) {
      continue;
    }
    if (args.whole_flag("--rt-priority", 1, 99, rt.priority)) {
      rt_priority_given = true;
    } else if (args.whole_flag("--chunk-budget", 1, 1'000'000, n)) {
      engine_options.max_segments_per_cycle = static_cast<std::size_t>(n);
    } else if (args.whole_flag("--request-budget", 1, 1024,
                               engine_options.max_requests_per_cycle)) {
    } else if (args.whole_flag("--state-period-ms", 1, 50, n)) {
      port_options.state_period = std::chrono::milliseconds(n);
    } else if (args.number_flag("--limit-share", engine_options.limit_share, "a number in (0, 1]",
                                tgm::LimitChecker::valid_share)) {
      engine_options.check_limits = true;
    } else {
      return args.fail();
    }
  }
  if (args.failed()) return 2;
  const std::optional<tgm::LogTime> stamping = tgm::parse_log_time(log_time);
  if (!stamping)
    return args.usage_error("--log-time must be auto, on or off, not '" + log_time + "'");
  if (!args.distinct_files({tgm::cli::ArgReader::config_file(config_path)},
                           {{"--stats", stats_path}, {"--handshake-trace", trace_path}})) {
    return 2;
  }
  // Written at exit: a path that cannot be written fails the start, not the end of a long run.
  tgm::ReportFile stats_file, trace_file;
  for (auto [flag, path, file] : {std::tuple{"--stats", &stats_path, &stats_file},
                                  std::tuple{"--handshake-trace", &trace_path, &trace_file}}) {
    if (std::string why; !path->empty() && !file->open(*path, why)) {
      return args.usage_error(std::string(flag) + " " + *path + ": " + why);
    }
  }
  if (no_realtime) rt.realtime = false;

  const std::optional<tgm::AppConfig> loaded = tgm::load_config_or_report(config_path, "tgm-service");
  if (!loaded) return 2;
  tgm::AppConfig config = *loaded;
  overrides.apply(config.dds);
  if (std::string why = tgm::dds::config_problem(config.dds, "service"); !why.empty())
    return args.usage_error(why);

  engine_options.require_plc_setup = config.plc.setup_before_start;
  std::string error;
  auto engine = tgm::service::Engine::create(config.machine, engine_options, &error);
  if (!engine) {
    std::fprintf(stderr, "tgm-service: %s\n", error.c_str());
    return 2;
  }
  if (check_config) {
    std::fputs(config_summary(config, tgm::cli::ArgReader::config_file(config_path).path).c_str(),
               stdout);
    return 0;
  }
  // The handshake figures of --stats come from the first 100,000 handshakes; a trace keeps up
  // to a million. Without either none are kept.
  port_options.handshake_samples = !trace_path.empty()   ? 1'000'000
                                   : !stats_path.empty() ? 100'000
                                                         : 0;
  port_options.interpolators = engine->count();
  port_options.cycle_time_us = config.machine.cycle_time_us;
  // Two services started within each other's look both serve; in its first cycles one gives
  // way to the other (DdsPortOptions::yield_window_cycles): 5 s at 500 us, long enough for
  // discovery on a loaded host, short enough that no program has been sent yet.
  if (service_check_ms > 0) port_options.yield_window_cycles = 10'000;

  // SIGINT / SIGTERM are taken by sigwait in this thread only: block them before any other
  // thread (Fast DDS's included) exists, so no other thread is interrupted.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  // A log reader that goes away (a closed pipe, a restarted journal) must not end the service
  // and stop the machines with it: its writes fail with EPIPE and the log is lost, nothing more.
  ::signal(SIGPIPE, SIG_IGN);
  // Nor must a closed terminal or SSH session it was started from (SIGHUP killed it, and the
  // machines stood still with it). It rereads nothing: SIGINT / SIGTERM stop it.
  ::signal(SIGHUP, SIG_IGN);

  // Both set SCHED_FIFO priorities, which --no-realtime turns off: together they are a
  // contradiction, not a priority to compare (a --dds-priority of 80 under --no-realtime used to
  // be refused as "must be below --rt-priority", a check of values that were not used).
  if (no_realtime && (rt_priority_given || dds_priority > 0)) {
    return args.usage_error(std::string(rt_priority_given ? "--rt-priority" : "--dds-priority") +
                            " sets a SCHED_FIFO priority, which --no-realtime turns off: give "
                            "one or the other");
  }
  if (dds_priority >= rt.priority)
    return args.usage_error("--dds-priority must be below --rt-priority");
  // A pin the kernel would refuse (a CPU the machine does not have, or one outside this
  // process's affinity: isolcpus, a cgroup's cpuset) is an error now; the cycle thread used to
  // log the refusal and run unpinned, a real-time setup that silently was not one.
  if (rt.cpu >= 0) {
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    if (sched_getaffinity(0, sizeof allowed, &allowed) == 0 &&
        (rt.cpu >= CPU_SETSIZE || !CPU_ISSET(static_cast<unsigned>(rt.cpu), &allowed))) {
      return args.usage_error("--cpu " + std::to_string(rt.cpu) + ": this process may run on " +
                              (CPU_COUNT(&allowed) == 1 ? "CPU " : "CPUs ") + cpu_list(allowed) +
                              " only");
    }
  }
  // A priority asked for that the kernel refuses is an error, as an unusable --cpu is: it used
  // to be a line on standard output and a service at normal priority (session 75). The default
  // (80, not given) stays a try: a development machine runs without the limits.
  if (rt.realtime) {
    for (const auto& [flag, priority, given] :
         {std::tuple{"--rt-priority", rt.priority, rt_priority_given},
          std::tuple{"--dds-priority", dds_priority, dds_priority > 0}}) {
      if (!given) continue;
      if (const std::string why = tgm::service::sched_fifo_refusal(priority); !why.empty())
        return args.usage_error(std::string(flag) + " " + std::to_string(priority) + ": " + why);
    }
  }
  // The log from here on, the usage errors above not: they go to whoever started the service.
  if (std::string why; !tgm::stamp_standard_streams(*stamping, why)) {
    std::fprintf(stderr, "tgm-service: %s\n", why.c_str());
    return 1;
  }
  if (dds_priority > 0 && rt.realtime) {
    // Threads inherit the policy of their creator: set it here, before the participant and the
    // port's threads exist, so Fast DDS's receive / event threads and ours run at it.
    sched_param p{};
    p.sched_priority = dds_priority;
    if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); rc == 0) {
      std::printf("tgm-service: DDS threads SCHED_FIFO priority %d\n", dds_priority);
    } else {
      std::printf("tgm-service: DDS threads: SCHED_FIFO not permitted (%s), normal priority\n", std::strerror(rc));
    }
  }
  if (rt.cpu >= 0) {
    // The cycle thread gets CPU rt.cpu; the threads created from here on (Fast DDS's, the
    // port's) inherit the other CPUs, so a spinning cycle thread never starves them.
    cpu_set_t others;
    CPU_ZERO(&others);
    if (sched_getaffinity(0, sizeof others, &others) == 0 && CPU_ISSET(rt.cpu, &others) &&
        CPU_COUNT(&others) > 1) {
      CPU_CLR(rt.cpu, &others);
      if (pthread_setaffinity_np(pthread_self(), sizeof others, &others) == 0) {
        std::printf("tgm-service: DDS threads kept off CPU %d\n", rt.cpu);
      }
    }
  }
  // systemd (Type=notify): a set but unusable $NOTIFY_SOCKET is said, not fatal.
  const tgm::SystemdNotifier notifier = tgm::SystemdNotifier::from_environment();
  if (!notifier.problem().empty()) {
    std::fprintf(stderr, "tgm-service: %s\n", notifier.problem().c_str());
  }
  std::unique_ptr<tgm::service::DdsPort> port;
  try {
    port = std::make_unique<tgm::service::DdsPort>(config.dds, port_options);
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm-service: %s\n", e.what());
    return 1;
  }
  // A second service on the domain would take the same requests and programs and drive the
  // same axes: refuse to start next to a live one (a dead one publishes nothing, so a restart
  // after a crash is not held up by its participant lease).
  if (service_check_ms > 0) {
    notifier.status("looking for another tgm-service on DDS domain " +
                    std::to_string(config.dds.domain_id));
    std::printf("tgm-service: looking %lld ms for another tgm-service on DDS domain %d\n",
                service_check_ms, config.dds.domain_id);
    std::fflush(stdout);
    // In slices, asking for SIGINT / SIGTERM between them: the signals are blocked for
    // sigtimedwait, and a service told to stop during its look (up to 10 s) ignored it and
    // then served the domain before it stopped (session 75).
    std::uint64_t other = 0;
    for (long long waited = 0; other == 0 && waited < service_check_ms; waited += 10) {
      other = port->other_service(
          std::chrono::milliseconds(std::min<long long>(10, service_check_ms - waited)));
      const timespec none{};
      if (const int sig = sigtimedwait(&signals, nullptr, &none); sig > 0 && other == 0) {
        std::printf(
            "tgm-service: %s while looking for another tgm-service: exiting, nothing "
            "served\n",
            strsignal(sig));
        return 0;
      }
    }
    if (other != 0) {
      std::fprintf(
          stderr,
          "tgm-service: another tgm-service (instance %016llx) already serves DDS domain %d: "
          "two would both take every request and program and drive the same axes. Stop "
          "it, or give this one another domain (--domain)\n",
          static_cast<unsigned long long>(other), config.dds.domain_id);
      return 1;
    }
  }
  port->start();

  const auto period_ns = static_cast<std::int64_t>(config.machine.cycle_time_us) * 1000;
  std::printf(
      "tgm-service: %d interpolator%s, cycle %d us, DDS domain %d as '%s', instance %016llx,"
      " version %s, config %s\n",
      engine->count(), engine->count() == 1 ? "" : "s", config.machine.cycle_time_us,
      config.dds.domain_id, port->participant_name().c_str(),
      static_cast<unsigned long long>(port->service_instance()), tgm::cli::version(),
      // Which file it read: a binary copied away from its share/ read the build tree's
      // default.yaml without a word (review of the installation, session 75).
      tgm::cli::ArgReader::config_file(config_path).path.c_str());
  std::fflush(stdout);

  std::atomic<bool> stop{false};
  tgm::service::RtLoop loop(*engine, *port, period_ns);
  std::thread cycle_thread([&] {
    // Named for top -H, perf and gdb (and found by that name in the watchdog test).
    pthread_setname_np(pthread_self(), "tgm-cycle");
    const std::string rt_log = tgm::service::make_realtime(rt);
    std::printf("tgm-service: %s\n", rt_log.c_str());
    std::fflush(stdout);
    loop.run(stop);
  });

  // Runs until a signal, the --duration or, in the first cycles, another service this one gives
  // way to (DdsPortOptions::yield_window_cycles); looked at every 100 ms, or four times per
  // systemd watchdog interval when that is shorter.
  int sig = 0;
  tgm::dds::MalformedWatch malformed;  // samples a participant wrote that cannot be read
  {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(duration_s);
    const std::string serving = std::to_string(engine->count()) + " interpolator" +
                                (engine->count() == 1 ? "" : "s") + ", cycle " +
                                std::to_string(config.machine.cycle_time_us) + " us, DDS domain " +
                                std::to_string(config.dds.domain_id);
    bool ready = false;
    tgm::WatchdogGate gate(notifier.watchdog_us());
    long slice_ns = 100'000'000;
    if (notifier.watchdog_us() > 0) {
      slice_ns =
          std::clamp<long>(static_cast<long>(notifier.watchdog_us() * 250), 1'000'000, slice_ns);
    }
    bool said_stall = false;
    // Missed deadlines, said while they happen (at most once a minute, so that a shared host's
    // journal is not filled with them): they were only counted, and a service without
    // real-time priority under load missed 40 % of its cycles without a line until its exit
    // (session 75).
    std::uint64_t missed_said = 0;
    auto missed_next = std::chrono::steady_clock::now();
    while (port->yielded_to() == 0 &&
           (duration_s <= 0.0 || std::chrono::steady_clock::now() < until)) {
      if (const std::uint64_t missed = loop.missed();
          missed > missed_said && std::chrono::steady_clock::now() >= missed_next) {
        std::fprintf(
            stderr,
            "tgm-service: %llu cycle%s missed %s (%llu in all; the latest started %.1f ms "
            "late): the axes ran that much slower than programmed, and the drives got no "
            "setpoint for %s%s\n",
            static_cast<unsigned long long>(missed - missed_said),
            missed - missed_said == 1 ? "" : "s",
            missed_said == 0 ? "since the start" : "since the last report",
            static_cast<unsigned long long>(missed), static_cast<double>(loop.last_miss_ns()) / 1e6,
            missed - missed_said == 1 ? "it" : "them",
            no_realtime ? " (--no-realtime: the cycle thread has no real-time priority)" : "");
        std::fflush(stderr);
        missed_said = missed;
        missed_next = std::chrono::steady_clock::now() + std::chrono::seconds(60);
      }
      if (notifier.enabled()) {
        const std::uint64_t cycles = loop.heartbeat();
        // Ready once the cycle has run: the interpolators answer and publish from then on.
        if (!ready && cycles > 0) ready = notifier.ready("serving " + serving);
        if (ready && gate.due(cycles)) notifier.watchdog();
        // A stalled cycle thread is restarted by systemd: say so while it can still be read.
        if (gate.stalled()) {
          if (!said_stall) {
            std::fprintf(stderr,
                         "tgm-service: the cycle thread has not run for %.1f s: no watchdog "
                         "ping to systemd (WatchdogSec=%.1f s)\n",
                         static_cast<double>(gate.stalled_us()) / 1e6,
                         static_cast<double>(notifier.watchdog_us()) / 1e6);
            std::fflush(stderr);
            said_stall = true;
          }
        } else {
          said_stall = false;
        }
      }
      timespec slice{};
      slice.tv_nsec = slice_ns;
      if (duration_s > 0.0) {
        const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
            until - std::chrono::steady_clock::now());
        if (left.count() < slice.tv_nsec)
          slice.tv_nsec = std::max<long>(0, static_cast<long>(left.count()));
      }
      sig = sigtimedwait(&signals, nullptr, &slice);
      if (sig > 0) break;
      sig = 0;
      if (const std::string bad =
              malformed.update(config.dds.domain_id, std::chrono::steady_clock::now());
          !bad.empty()) {
        std::fprintf(stderr, "tgm-service: %s\n", bad.c_str());
        std::fflush(stderr);
      }
    }
  }
  const std::uint64_t yielded_to = port->yielded_to();
  notifier.stopping();
  // The stop can wait on other threads (the cycle, Fast DDS callbacks, the participant's
  // shutdown). A watchdog says where it is when that takes long, and a second signal ends the
  // process at once: an operator is never left with a service that ignores Ctrl-C.
  std::atomic<const char*> stage{"joining the cycle thread"};
  std::atomic<bool> stopped{false};
  std::thread watchdog([&] {
    pthread_setname_np(pthread_self(), "tgm-stopping");
    const auto begin = std::chrono::steady_clock::now();
    auto report = begin + std::chrono::seconds(5);
    while (!stopped.load(std::memory_order_acquire)) {
      timespec slice{};
      slice.tv_nsec = 50'000'000;
      const int again = sigtimedwait(&signals, nullptr, &slice);
      // A repeat within 250 ms is the same request delivered twice, not an operator insisting:
      // `timeout` signals its child and then its own process group, the child among them.
      if (again > 0 && std::chrono::steady_clock::now() - begin < std::chrono::milliseconds(250))
        continue;
      if (again > 0) {
        std::fprintf(stderr, "tgm-service: %s while stopping (%s): exiting at once\n", strsignal(again),
                     stage.load(std::memory_order_acquire));
        std::fflush(stderr);
        std::_Exit(1);
      }
      if (std::chrono::steady_clock::now() >= report) {
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
        std::fprintf(stderr, "tgm-service: still stopping after %.0f s: %s (send the signal again to exit at once)\n",
                     s, stage.load(std::memory_order_acquire));
        std::fflush(stderr);
        report += std::chrono::seconds(5);
      }
    }
  });
  // Axes in motion are brought to rest on the trajectory before the cycle ends (Engine::
  // wind_down): leaving at once froze the drives' setpoints at full speed. Bounded, and a second
  // signal still exits at once (the watchdog above).
  bool moving_at_exit = false;
  stage.store("bringing the motion to rest (normal stop on the trajectory)",
              std::memory_order_release);
  loop.wind_down();
  {
    const auto give_up = std::chrono::steady_clock::now() + kWindDownLimit;
    while (!loop.at_rest() && std::chrono::steady_clock::now() < give_up)
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    // wound_down() is read only once at_rest() said the cycle thread is done with it (its
    // acquire pairs with the loop's release); without the rest the count is not needed.
    const bool rest = loop.at_rest();
    const int brought = rest ? engine->wound_down() : 0;
    // The cycle runs on a little at rest, so that the warnings and the states and setpoints of
    // the standstill are published (the last cycles of the ramp were still in the port's
    // queue); every interpolator stopped was announced.
    if (rest && engine->announced() > 0)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (brought > 0) {
      std::printf(
          "tgm-service: stopped the motion of %d interpolator%s on the trajectory before "
          "exiting\n",
          brought, brought == 1 ? "" : "s");
    } else if (!rest) {
      std::printf(
          "tgm-service: the motion did not come to rest within 30 s: exiting with it "
          "moving (exit code 1)\n");
      // Not a clean stop: systemd and scripts saw exit code 0 while the last setpoint was a
      // moving one (session 75).
      moving_at_exit = true;
    }
    std::fflush(stdout);
  }
  stage.store("joining the cycle thread", std::memory_order_release);
  stop = true;
  cycle_thread.join();
  port->stop(&stage);
  stage.store("writing the statistics", std::memory_order_release);

  const auto& st = loop.stats();
  const auto& hist = loop.histogram();
  const auto& c = engine->counters();
  std::vector<std::int64_t> rt_ns;
  for (const auto& h : port->handshakes()) rt_ns.push_back(h.round_trip_ns);
  std::printf(
      "tgm-service: stopping (%s) after %llu cycles: lateness p50 %.1f us, p99 %.1f us,"
      " p99.9 %.1f us, max %.1f us, missed %llu; cycle work p99.9 %.1f us, max %.1f us;"
      " %llu requests (%llu refused, %llu busy), %llu chunks, %llu segments,"
      " %llu events (%llu lost), %llu states, %llu setpoints published (%llu lost)%s%s%s\n",
      sig > 0           ? strsignal(sig)
      : yielded_to != 0 ? "gave way to another service"
                        : "time is up",
      static_cast<unsigned long long>(st.cycles), static_cast<double>(hist.quantile_ns(0.5)) / 1e3,
      static_cast<double>(hist.quantile_ns(0.99)) / 1e3,
      static_cast<double>(hist.quantile_ns(0.999)) / 1e3, static_cast<double>(hist.max_ns()) / 1e3,
      static_cast<unsigned long long>(st.missed_cycles),
      static_cast<double>(loop.work_histogram().quantile_ns(0.999)) / 1e3,
      static_cast<double>(loop.work_histogram().max_ns()) / 1e3,
      static_cast<unsigned long long>(c.requests),
      static_cast<unsigned long long>(c.refused_requests),
      static_cast<unsigned long long>(port->busy_requests()),
      static_cast<unsigned long long>(c.chunks), static_cast<unsigned long long>(c.segments),
      static_cast<unsigned long long>(port->events_published()),
      static_cast<unsigned long long>(c.lost_events),
      static_cast<unsigned long long>(port->states_published()),
      static_cast<unsigned long long>(port->setpoints_published()),
      static_cast<unsigned long long>(port->setpoints_lost()),
      engine_options.check_limits
          ? ("; limit excesses " + std::to_string(c.limit_violations)).c_str()
          : "",
      tgm::dds::malformed_samples() != 0
          ? ("; malformed DDS samples dropped (" + std::to_string(tgm::dds::malformed_samples()) +
             " failed reads)")
                .c_str()
          : "",
      port->replies_not_written() != 0
          ? ("; replies DDS did not take: " + std::to_string(port->replies_not_written())).c_str()
          : "");
  int exit_code = yielded_to != 0 ? 1 : 0;
  if (std::FILE* f = stats_file.stream()) {
    std::fprintf(
        f,
        "{\"cycles\": %llu, \"cycle_time_us\": %d, \"interpolators\": %d,\n"
        " \"lateness_ns\": {\"p50\": %lld, \"p99\": %lld, \"p999\": %lld, \"max\": %lld},\n"
        " \"missed_cycles\": %llu,\n"
        " \"cycle_work_ns\": {\"p50\": %lld, \"p999\": %lld, \"max\": %lld},\n"
        " \"handshake_ns\": {\"count\": %zu, \"min\": %lld, \"p50\": %lld, \"p99\": %lld,"
        " \"max\": %lld},\n"
        " \"requests\": %llu, \"busy_requests\": %llu, \"requests_repeated\": %llu,"
        " \"stale_repeats\": %llu, \"chunks\": %llu, \"segments\": %llu,"
        " \"duplicate_chunks\": %llu,"
        " \"refused_chunks\": %llu, \"lost_replies\": %llu, \"lost_messages\": %llu,\n"
        " \"replies_held_for_match\": %llu, \"replies_unmatched\": %llu,"
        " \"replies_not_written\": %llu,\n"
        " \"events_published\": %llu, \"lost_events\": %llu, \"states_published\": %llu,"
        " \"setpoints_published\": %llu, \"setpoints_lost\": %llu,\n"
        " \"limits_checked\": %s, \"limit_violations\": %llu}\n",
        static_cast<unsigned long long>(st.cycles), config.machine.cycle_time_us, engine->count(),
        static_cast<long long>(hist.quantile_ns(0.5)),
        static_cast<long long>(hist.quantile_ns(0.99)),
        static_cast<long long>(hist.quantile_ns(0.999)), static_cast<long long>(hist.max_ns()),
        static_cast<unsigned long long>(st.missed_cycles),
        static_cast<long long>(loop.work_histogram().quantile_ns(0.5)),
        static_cast<long long>(loop.work_histogram().quantile_ns(0.999)),
        static_cast<long long>(loop.work_histogram().max_ns()), rt_ns.size(),
        static_cast<long long>(percentile(rt_ns, 0.0)),
        static_cast<long long>(percentile(rt_ns, 0.5)),
        static_cast<long long>(percentile(rt_ns, 0.99)),
        static_cast<long long>(percentile(rt_ns, 1.0)), static_cast<unsigned long long>(c.requests),
        static_cast<unsigned long long>(port->busy_requests()),
        static_cast<unsigned long long>(port->requests_repeated()),
        static_cast<unsigned long long>(port->stale_repeats()),
        static_cast<unsigned long long>(c.chunks), static_cast<unsigned long long>(c.segments),
        static_cast<unsigned long long>(c.duplicate_chunks),
        static_cast<unsigned long long>(c.refused_chunks),
        static_cast<unsigned long long>(c.lost_replies),
        static_cast<unsigned long long>(c.lost_messages),
        static_cast<unsigned long long>(port->replies_held()),
        static_cast<unsigned long long>(port->replies_unmatched()),
        static_cast<unsigned long long>(port->replies_not_written()),
        static_cast<unsigned long long>(port->events_published()),
        static_cast<unsigned long long>(c.lost_events),
        static_cast<unsigned long long>(port->states_published()),
        static_cast<unsigned long long>(port->setpoints_published()),
        static_cast<unsigned long long>(port->setpoints_lost()),
        engine_options.check_limits ? "true" : "false",
        static_cast<unsigned long long>(c.limit_violations));
  }
  if (std::FILE* f = trace_file.stream()) {
    std::fprintf(
        f,
        "interpolator,act_part,handoff_ns,publisher_woke_ns,event_write_begin_ns,"
        "event_write_end_ns,state_write_begin_ns,state_write_end_ns,taken_ns,applied_ns\n");
    for (const auto& h : port->handshakes()) {
      const auto& w = h.written;
      std::fprintf(f, "%d,%d,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%lld\n", w.interpolator, w.act_part,
                   static_cast<long long>(w.handoff_ns),
                   static_cast<long long>(w.publisher_woke_ns),
                   static_cast<long long>(w.event_write_begin_ns),
                   static_cast<long long>(w.event_write_end_ns),
                   static_cast<long long>(w.state_write_begin_ns),
                   static_cast<long long>(w.state_write_end_ns), static_cast<long long>(h.taken_ns),
                   static_cast<long long>(h.applied_ns));
    }
  }
  for (auto [path, file] :
       {std::pair{&stats_path, &stats_file}, std::pair{&trace_path, &trace_file}}) {
    if (std::string why; file->is_open() && !file->finish(why)) {
      std::fprintf(stderr, "tgm-service: %s: %s\n", path->c_str(), why.c_str());
      exit_code = 1;
    }
  }
  stage.store("closing the DDS participant", std::memory_order_release);
  port.reset();
  stopped.store(true, std::memory_order_release);
  watchdog.join();
  return moving_at_exit ? 1 : exit_code;
}

}  // namespace
