// tgm-plc: the PLC emulator (DESIGN.md section 1, the manual's "PLC competence"). It sets the
// basic parameters from the config, acknowledges normal M-functions after the per-M delay of the
// config, notes continuous ones, logs every M-function and every acknowledgement, and can be
// told (flags or a small YAML script) to change Rel_Speed, issue stops or refuse to acknowledge.
// It cannot start the interpolator: the service refuses (--try-start shows it).
#include <pthread.h>
#include <sched.h>
#include <signal.h>

#include <cstring>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "tgm/client/client.hpp"
#include "tgm/dds_overrides.hpp"
#include "tgm/registers.hpp"
#include "tgm/yaml_config.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

constexpr const char* kUsage =
    "usage: tgm-plc [--config YAML] [OPTIONS]\n"
    "\n"
    "PLC emulator: sets the basic parameters, acknowledges normal M-functions after the delay\n"
    "of plc.m_delay_s (or plc.default_m_delay_s), notes continuous M-functions, logs both.\n"
    "Stops cleanly on SIGINT / SIGTERM.\n"
    "\n"
    "  --config YAML        machine config (default: $TGM_CONFIG, the installed or the in-tree\n"
    "                       config/default.yaml)\n"
    "%s"
    "  --interpolator N     serve only interpolator N (default: every configured one)\n"
    "  --rel-speed R        write Rel_Speed = R (0.01..2) at start\n"
    "  --refuse-ack M[,M]   never acknowledge these M numbers (the interpolator keeps waiting)\n"
    "  --ack-delay S        acknowledge every normal M-function after S seconds (overrides config)\n"
    "  --script YAML        timed actions, a list of maps:\n"
    "                         - {at_s: 1.5, rel_speed: 0.5}       Rel_Speed write\n"
    "                         - {at_s: 3, command: 8}             Command (stop 4/5/8/9, ...)\n"
    "                         - {at_s: 4, start: true}            try to start (refused)\n"
    "                         - {at_s: 0, refuse_ack: [51]}       stop acknowledging M51\n"
    "                       each may name `interpolator: N` (default 0); at_s counts from the\n"
    "                       moment the service was found\n"
    "  --try-start          send a start request as the PLC once (the service refuses it)\n"
    "  --no-basic-params    do not send the basic parameters at start\n"
    "  --duration S         stop by itself after S seconds\n"
    "  --quiet              log only M-functions, acknowledgements and errors\n"
    "  --handshake-trace F  write the time stamps of every acknowledgement as CSV to F at exit\n"
    "  --rt-priority N      run the emulator (all its threads) SCHED_FIFO at N, 1..98, when\n"
    "                       permitted (a real PLC task is real-time; default: normal)\n"
    "  --help               this text\n";

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

int usage_error(const std::string& why) {
  std::fprintf(stderr, "tgm-plc: %s\n(see tgm-plc --help)\n", why.c_str());
  return 2;
}

struct ScriptStep {
  double at_s = 0.0;
  int interpolator = 0;
  std::optional<double> rel_speed;
  std::optional<int> command;
  bool start = false;
  std::vector<int> refuse_ack;
  bool done = false;
};

bool load_script(const std::string& path, std::vector<ScriptStep>& steps, std::string& error) {
  try {
    const YAML::Node root = YAML::LoadFile(path);
    if (!root.IsSequence()) {
      error = path + ": the script must be a list of steps";
      return false;
    }
    for (const YAML::Node& n : root) {
      const int line = n.Mark().line + 1;
      if (!n.IsMap()) {
        error = path + ":" + std::to_string(line) + ": a step must be a map";
        return false;
      }
      ScriptStep s;
      for (const auto& kv : n) {
        const std::string key = kv.first.as<std::string>();
        if (key == "at_s") s.at_s = kv.second.as<double>();
        else if (key == "interpolator") s.interpolator = kv.second.as<int>();
        else if (key == "rel_speed") s.rel_speed = kv.second.as<double>();
        else if (key == "command") s.command = kv.second.as<int>();
        else if (key == "start") s.start = kv.second.as<bool>();
        else if (key == "refuse_ack") s.refuse_ack = kv.second.as<std::vector<int>>();
        else {
          error = path + ":" + std::to_string(line) + ": unknown key '" + key + "'";
          return false;
        }
      }
      if (s.at_s < 0.0) {
        error = path + ":" + std::to_string(line) + ": at_s must be >= 0";
        return false;
      }
      steps.push_back(s);
    }
  } catch (const YAML::Exception& e) {
    error = path + ": " + e.what();
    return false;
  }
  return true;
}

template <class Params>
std::string params_text(const Params& params) {
  std::string out;
  for (std::size_t k = 0; k < tgm::kParamLetters; ++k) {
    const double v = params[k];
    if (tgm::is_not_set(v)) continue;
    char buf[48];
    std::snprintf(buf, sizeof buf, "%s%c%g", out.empty() ? "" : " ", static_cast<char>('A' + k), v);
    out += buf;
  }
  return out.empty() ? "none" : out;
}

// One interpolator as the PLC sees it.
struct Served {
  int number = 0;
  bool found = false;
  // (program_id, Act_Part) of the last M-function handled, so a repeated M number is new.
  std::uint32_t m_program = 0;
  std::int32_t m_part = -1;
  std::int32_t m_func = 0;
  // Continuous M-function noted and not yet seen cleared (M_Func stays set while motion goes on).
  std::int32_t cont_noted = 0;
  // A pending acknowledgement.
  std::int32_t ack_m = 0;
  Clock::time_point ack_at{};
  Clock::time_point seen_at{};
  Clock::time_point woke_at{};
};

// One acknowledgement's time stamps for --handshake-trace (steady clock).
struct AckTrace {
  int interpolator;
  std::int32_t act_part;
  Clock::time_point woke, seen, ack_call, ack_written, reply;
};

}  // namespace

int main(int argc, char** argv) {
  std::string config_path;
  tgm::DdsOverrides overrides;
  std::optional<double> rel_speed;
  std::optional<double> ack_delay;
  std::set<int> refuse;
  std::vector<ScriptStep> script;
  std::string script_path;
  std::string trace_path;
  int only = -1;
  bool try_start = false;
  bool basic = true;
  bool quiet = false;
  double duration_s = 0.0;
  int rt_priority = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf(kUsage, tgm::kDdsOverrideHelp);
      return 0;
    }
    if (arg == "--try-start") { try_start = true; continue; }
    if (arg == "--no-basic-params") { basic = false; continue; }
    if (arg == "--quiet") { quiet = true; continue; }
    if (arg.rfind("--", 0) != 0) return usage_error("unexpected argument '" + arg + "'");
    std::string flag = arg;
    std::string value;
    if (const auto eq = arg.find('='); eq != std::string::npos) {
      flag = arg.substr(0, eq);
      value = arg.substr(eq + 1);
    } else {
      if (i + 1 >= argc) return usage_error(arg + " needs a value, or is unknown");
      value = argv[++i];
    }
    std::string error;
    char* end = nullptr;
    if (overrides.take(flag, value, error)) {
      if (!error.empty()) return usage_error(error);
    } else if (flag == "--config") {
      config_path = value;
    } else if (flag == "--interpolator") {
      only = static_cast<int>(std::strtol(value.c_str(), &end, 10));
      if (value.empty() || *end != '\0' || only < 0 || only > 2) return usage_error("--interpolator must be 0..2");
    } else if (flag == "--rel-speed") {
      const double v = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !(v >= 0.01 && v <= 2.0)) return usage_error("--rel-speed must be 0.01..2");
      rel_speed = v;
    } else if (flag == "--ack-delay") {
      const double v = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !(v >= 0.0 && v <= 3600.0)) return usage_error("--ack-delay must be 0..3600 s");
      ack_delay = v;
    } else if (flag == "--refuse-ack") {
      std::size_t p = 0;
      while (p <= value.size()) {
        const std::size_t q = std::min(value.find(',', p), value.size());
        const std::string m = value.substr(p, q - p);
        const long v = std::strtol(m.c_str(), &end, 10);
        if (m.empty() || *end != '\0' || v <= 0) return usage_error("--refuse-ack takes M numbers like 51,50");
        refuse.insert(static_cast<int>(v));
        p = q + 1;
      }
    } else if (flag == "--handshake-trace") {
      trace_path = value;
    } else if (flag == "--script") {
      script_path = value;
      if (!load_script(value, script, error)) {
        std::fprintf(stderr, "tgm-plc: %s\n", error.c_str());
        return 2;
      }
    } else if (flag == "--rt-priority") {
      rt_priority = static_cast<int>(std::strtol(value.c_str(), &end, 10));
      if (value.empty() || *end != '\0' || rt_priority < 1 || rt_priority > 98) {
        return usage_error("--rt-priority must be 1..98");
      }
    } else if (flag == "--duration") {
      duration_s = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !(duration_s > 0.0)) return usage_error("--duration must be > 0 s");
    } else {
      return usage_error("unknown option '" + flag + "'");
    }
  }
  const std::optional<tgm::AppConfig> loaded = tgm::load_config_or_report(config_path, "tgm-plc");
  if (!loaded) return 2;
  tgm::AppConfig config = *loaded;
  overrides.apply(config.dds);
  if (std::string why = tgm::dds_profiles_problem(config.dds); !why.empty()) return usage_error(why);
  const int count = static_cast<int>(config.machine.interpolators.size());
  if (only >= count) return usage_error("--interpolator " + std::to_string(only) + ": the config has " + std::to_string(count));
  for (const auto& s : script) {
    if (s.interpolator < 0 || s.interpolator >= count) {
      std::fprintf(stderr, "tgm-plc: %s: interpolator %d does not exist\n", script_path.c_str(), s.interpolator);
      return 2;
    }
  }

  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

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
  auto log = [&](const char* fmt, auto... args) {
    char line[1024];
    int n = std::snprintf(line, sizeof line, "tgm-plc [%8.3f s] ", stamp());
    n += std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n), fmt, args...);
    pending_log.append(line, static_cast<std::size_t>(std::min<int>(n, static_cast<int>(sizeof line) - 1)));
    pending_log += '\n';
  };
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
    if (only < 0 || only == i) served.push_back(Served{i});
  }
  log("PLC emulator on DDS domain %d as '%s', serving %zu interpolator%s", config.dds.domain_id,
      plc->name().c_str(), served.size(), served.size() == 1 ? "" : "s");
  if (!rt_log.empty()) log("%s", rt_log.c_str());

  std::vector<AckTrace> traces;
  if (!trace_path.empty()) traces.reserve(100'000);
  std::optional<Clock::time_point> found_at;
  auto last_wait_log = Clock::now();
  flush_log();
  while (!g_stop) {
    flush_log();
    if (duration_s > 0.0 && stamp() >= duration_s) break;
    plc->poll(5ms);
    const auto now = Clock::now();
    for (Served& sv : served) {
      const tgm::msg::InterpolatorState* s = plc->state(sv.number);
      if (s == nullptr) continue;
      if (!sv.found) {
        sv.found = true;
        log("interpolator %d: found (status %d %s)", sv.number, s->status(),
            std::string(tgm::client::status_name(s->status())).c_str());
        // Basic parameters (the manual: the PLC sets them): Rel_Speed and the Command
        // structure with the config's smoothing and gear ratios.
        if (rel_speed) {
          log("interpolator %d: Rel_Speed = %g: %s", sv.number, *rel_speed,
              tgm::client::describe(plc->set_rel_speed(sv.number, *rel_speed)).c_str());
        }
        if (basic) {
          const auto& sm = config.machine.smoothing;
          const std::int32_t spline[] = {sm.spline_points, static_cast<std::int32_t>(sm.spline_jerk_mm_s3)};
          const std::int32_t iir[] = {static_cast<std::int32_t>(sm.iir_p_e6), static_cast<std::int32_t>(sm.iir_q_e6),
                                      static_cast<std::int32_t>(sm.iir_f_e6), static_cast<std::int32_t>(sm.iir_axis_mask)};
          const auto r2 = plc->command(sv.number, -2, spline);
          const auto r1 = plc->command(sv.number, -1, iir);
          std::string ratio_log;
          const auto& axes = config.machine.interpolators[static_cast<std::size_t>(sv.number)].axes;
          tgm::client::Reply r1024;
          for (std::size_t a = 0; a < axes.size(); ++a) {
            // Ratio as counter [inc] / denominator [mm] with 1e-3 mm resolution.
            const std::int32_t ratio[] = {static_cast<std::int32_t>(a),
                                          static_cast<std::int32_t>(axes[a].ratio_inc_per_mm * 1000.0 + 0.5), 1000};
            const auto r = plc->command(sv.number, 1024, ratio);
            if (a == 0 || (r1024.accepted && !r.accepted)) r1024 = r;  // report the first refusal
          }
          if (!quiet) {
            log("interpolator %d: basic parameters: Command -2 (spline %d points): %s", sv.number, sm.spline_points,
                tgm::client::describe(r2).c_str());
            log("interpolator %d: basic parameters: Command -1 (IIR mask 0x%x): %s", sv.number, sm.iir_axis_mask,
                tgm::client::describe(r1).c_str());
            log("interpolator %d: basic parameters: Command 1024 (gear ratio, %zu axes): %s", sv.number, axes.size(),
                tgm::client::describe(r1024).c_str());
          }
        }
        if (try_start) {
          log("interpolator %d: trying to start as the PLC: %s", sv.number,
              tgm::client::describe(plc->start(sv.number)).c_str());
        }
        if (!found_at) found_at = Clock::now();
      }
      // A new M-function: M_Func set at a record (program, Act_Part) not handled yet.
      // (ack_m_func() polls, so *s may be newer afterwards: the line logs a copy of the fields.)
      bool seen_new = false;
      bool seen_normal = false;
      std::int32_t seen_m = 0, seen_line = 0, seen_part = 0;
      auto seen_params = s->m_function_parameter();
      auto log_seen = [&] {
        if (!seen_new) return;
        seen_new = false;
        log("interpolator %d: M%d %s (line %d, part %d), parameters: %s", sv.number, seen_m,
            seen_normal ? "normal: the interpolator waits" : "continuous: motion goes on", seen_line,
            seen_part, params_text(seen_params).c_str());
      };
      const auto section = static_cast<tgm::SectionState>(static_cast<std::uint32_t>(s->run_flag()) & 0xFFFFu);
      const bool normal = section == tgm::SectionState::kWaitMFunc || section == tgm::SectionState::kWaitMFuncEnd;
      if (s->m_func() != sv.cont_noted) sv.cont_noted = 0;
      if (s->m_func() != 0 && (s->program_id() != sv.m_program || s->act_part() != sv.m_part) &&
          (normal || s->m_func() != sv.cont_noted)) {
        sv.m_program = s->program_id();
        sv.m_part = s->act_part();
        sv.m_func = s->m_func();
        if (!normal) sv.cont_noted = s->m_func();
        // An acknowledgement due at once goes out before this line is formatted (below).
        seen_new = true;
        seen_normal = normal;
        seen_m = s->m_func();
        seen_line = s->act_line();
        seen_part = s->act_part();
        seen_params = s->m_function_parameter();
        sv.seen_at = now;
        sv.woke_at = plc->last_wake();
        if (!normal) {
          log_seen();
          log("interpolator %d: M%d noted: %s", sv.number, s->m_func(),
              tgm::client::describe(plc->ack_m_func(sv.number)).c_str());
        } else if (refuse.count(s->m_func()) != 0) {
          log_seen();
          log("interpolator %d: M%d: refusing to acknowledge (--refuse-ack / script)", sv.number, s->m_func());
        } else {
          sv.ack_m = s->m_func();
          sv.ack_at = now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(delay_for(s->m_func())));
        }
      }
      if (sv.ack_m != 0 && now >= sv.ack_at) {
        const int m = sv.ack_m;
        sv.ack_m = 0;
        const auto ack_call = Clock::now();
        const auto r = plc->ack_m_func(sv.number);
        if (!trace_path.empty() && traces.size() < 1'000'000) {
          traces.push_back({sv.number, sv.m_part, sv.woke_at, sv.seen_at, ack_call, plc->last_request_written(), Clock::now()});
        }
        log_seen();
        log("interpolator %d: M%d acknowledged after %.3f s: %s (cycle %llu)", sv.number, m,
            std::chrono::duration<double>(Clock::now() - sv.seen_at).count(), tgm::client::describe(r).c_str(),
            static_cast<unsigned long long>(r.cycle));
      }
      log_seen();
    }
    if (!found_at && now - last_wait_log > 5s) {
      last_wait_log = now;
      log("waiting for tgm-service on DDS domain %d ...", config.dds.domain_id);
    }
    if (found_at) {
      const double t = std::chrono::duration<double>(now - *found_at).count();
      for (ScriptStep& st : script) {
        if (st.done || t < st.at_s) continue;
        st.done = true;
        if (st.rel_speed) {
          log("script: interpolator %d: Rel_Speed = %g: %s", st.interpolator, *st.rel_speed,
              tgm::client::describe(plc->set_rel_speed(st.interpolator, *st.rel_speed)).c_str());
        }
        if (st.command) {
          log("script: interpolator %d: Command %d: %s", st.interpolator, *st.command,
              tgm::client::describe(plc->command(st.interpolator, *st.command)).c_str());
        }
        if (st.start) {
          log("script: interpolator %d: start as the PLC: %s", st.interpolator,
              tgm::client::describe(plc->start(st.interpolator)).c_str());
        }
        for (int m : st.refuse_ack) {
          refuse.insert(m);
          log("script: from now on M%d is not acknowledged", m);
        }
      }
    }
  }
  log("stopping");
  flush_log();
  if (!trace_path.empty()) {
    if (std::FILE* f = std::fopen(trace_path.c_str(), "w")) {
      auto ns = [](Clock::time_point t) {
        return static_cast<long long>(std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count());
      };
      std::fprintf(f, "interpolator,act_part,woke_ns,seen_ns,ack_call_ns,ack_written_ns,reply_ns\n");
      for (const AckTrace& t : traces) {
        std::fprintf(f, "%d,%d,%lld,%lld,%lld,%lld,%lld\n", t.interpolator, t.act_part, ns(t.woke), ns(t.seen),
                     ns(t.ack_call), ns(t.ack_written), ns(t.reply));
      }
      std::fclose(f);
    } else {
      std::fprintf(stderr, "tgm-plc: cannot write %s\n", trace_path.c_str());
    }
  }
  return 0;
}
