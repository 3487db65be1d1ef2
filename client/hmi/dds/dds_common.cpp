#include "dds_common.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <optional>
#include <string>
#include <type_traits>

#include "tgm/intercode.hpp"
#include "tgm/printable.hpp"
#include "tgm/registers.hpp"

namespace tgm::hmi {

std::atomic<bool> g_interrupted{false};

namespace {
void on_signal(int) { g_interrupted = true; }
}  // namespace

void install_signal_flag(Hangup hangup) {
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  sigaction(SIGPIPE, &ignore, nullptr);
  sigaction(SIGHUP, hangup == Hangup::kIgnore ? &ignore : &sa, nullptr);
}

int make_client(Args& args, const DdsOverrides& o, std::optional<AppConfig>& config,
                std::optional<client::Client>& c, const client::ClientOptions& options) {
  config = args.load_app();
  if (!config) return 2;
  o.apply(config->dds);
  if (std::string why = dds::config_problem(config->dds, "hmi"); !why.empty())
    return args.usage_error(why);
  try {
    c.emplace(config->dds, client::Role::kHmi, options);
  } catch (const dds::SetupError& e) {
    std::fprintf(stderr, "%s: %s\n", args.program().c_str(), e.what());
    return 1;
  }
  return 0;
}

namespace {
// `from` + `wait_s` seconds, rounded up to whole milliseconds (the waits' bound).
std::chrono::steady_clock::time_point deadline_after(std::chrono::steady_clock::time_point from,
                                                     double wait_s) {
  return from + std::chrono::milliseconds(static_cast<long long>(std::ceil(wait_s * 1000.0)));
}
}  // namespace

int wait_for_service(client::Client& c, const AppConfig& config, int interpolator,
                     const char* command, double wait_s) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = deadline_after(Clock::now(), wait_s);
  // A service publishes the states of all the interpolators it hosts every few milliseconds
  // (--state-period-ms, at most 50): when others arrive for a second and this one does not,
  // the service's config has fewer interpolators than this one's. The wait ran out the whole
  // 10 s and then asked whether a service was running at all.
  std::optional<Clock::time_point> others_since;
  while (true) {
    const auto slice = std::clamp<Clock::duration>(deadline - Clock::now(), Clock::duration(0),
                                                   std::chrono::milliseconds(100));
    if (c.wait_for_state(interpolator, std::chrono::duration_cast<std::chrono::milliseconds>(slice),
                         &g_interrupted)) {
      return 0;
    }
    if (g_interrupted) {
      std::fprintf(stderr,
                   "tgm-hmi %s: interrupted while waiting for the state of interpolator %d\n",
                   command, interpolator);
      return 130;
    }
    std::string hosted;
    int hosted_count = 0;
    for (int i = 0; i < kMaxInterpolators; ++i) {
      if (i != interpolator && c.state(i) != nullptr) {
        hosted += (hosted.empty() ? "" : ", ") + std::to_string(i);
        ++hosted_count;
      }
    }
    const auto now = Clock::now();
    if (!hosted.empty() && !others_since) others_since = now;
    if (others_since && now - *others_since >= std::chrono::seconds(1)) {
      const std::string mine = client::config_name(config);
      std::fprintf(stderr,
                   "tgm-hmi %s: tgm-service on DDS domain %d hosts interpolator%s %s, not %d (its "
                   "config has %d interpolator%s, %s has %zu): choose one with --interpolator, or "
                   "use the service's config\n",
                   command, config.dds.domain_id, hosted_count == 1 ? "" : "s", hosted.c_str(),
                   interpolator, hosted_count, hosted_count == 1 ? "" : "s", mine.c_str(),
                   config.machine.interpolators.size());
      return 1;
    }
    if (now >= deadline) break;
  }
  std::fprintf(
      stderr,
      "tgm-hmi %s: no state of interpolator %d from tgm-service on DDS domain %d within %g s "
      "(is tgm-service running with the same domain, profiles and security?)\n",
      command, interpolator, config.dds.domain_id, wait_s);
  return 1;
}

int wait_for_plc_setup(client::Client& c, int interpolator, const char* command, double wait_s) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const auto deadline = deadline_after(t0, wait_s);
  const auto set_up = [](const msg::InterpolatorState& s) { return s.plc_setup() != 1; };
  // On a terminal the waiting line counts down, rewritten in place each second (review of
  // session 81: one line and then silence until the give-up looked like a hang); into a file
  // or a pipe it is written once.
  const bool tty = ::isatty(2) != 0;
  bool said = false;
  const auto end_line = [&] {
    if (said && tty) std::fputc('\n', stderr);
  };
  const std::string what = "tgm-hmi " + std::string(command) +
                           ": waiting for the PLC to set interpolator " +
                           std::to_string(interpolator) + " up";
  while (true) {
    // tgm-plc sets a service up within a second of finding it: said only when it takes longer.
    const auto until =
        said ? (tty ? std::min(deadline, Clock::now() + std::chrono::seconds(1)) : deadline)
             : std::min(deadline, t0 + std::chrono::seconds(1));
    const auto slice = std::max<Clock::duration>(until - Clock::now(), Clock::duration(0));
    // Rounded up: truncated, the last fraction of a millisecond spun through waits of 0 ms.
    if (c.wait_until(interpolator, set_up, std::chrono::ceil<std::chrono::milliseconds>(slice),
                     &g_interrupted)) {
      // The wait is over: its countdown goes, rather than stay behind with seconds left.
      if (said && tty) std::fputs("\r\033[K", stderr);
      return 0;
    }
    if (g_interrupted) {
      end_line();
      std::fprintf(stderr,
                   "tgm-hmi %s: interrupted while waiting for the PLC's setup of interpolator %d\n",
                   command, interpolator);
      return 130;
    }
    const auto now = Clock::now();
    if (now >= deadline) break;
    if (tty) {
      // Short enough for an 80-column line, which \r can rewrite; the give-up says the rest.
      const double left = std::chrono::duration<double>(deadline - now).count();
      std::fprintf(stderr, "\r%s: %.0f s left\033[K", what.c_str(), std::ceil(left));
      std::fflush(stderr);
    } else if (!said) {
      std::fprintf(stderr, "%s (the service's config has plc.setup_before_start)\n", what.c_str());
    }
    said = true;
  }
  end_line();
  std::fprintf(stderr,
               "tgm-hmi %s: the PLC has not set interpolator %d up in the %.3g s waited, and the "
               "service starts no program before (plc.setup_before_start in its config): start "
               "tgm-plc (its log says why it did not report the setup, if it runs), use a PLC "
               "that sends the report (REQUEST_KIND_PLC_SETUP_DONE; tgm-plc before version "
               "0.2 does not), or on a machine without a PLC set plc.setup_before_start: false\n",
               command, interpolator, wait_s);
  return 1;
}

namespace {
// One line of format_state: printf's format, checked by the compiler against the arguments
// (a lambda forwarding its format could not be), then a newline.
[[gnu::format(printf, 2, 3)]] void append_line(std::string& out, const char* fmt, ...) {
  char buf[512];
  std::va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  out += buf;
  out += '\n';
}
}  // namespace

std::string machine_mismatch(const msg::InterpolatorState& s, const AppConfig& config, int ip) {
  if (client::same_machine(s, config.machine, ip)) return {};
  return "interpolator " + std::to_string(ip) + ": the service's machine config is not " +
         client::config_name(config) +
         " (axis limits, cycle time, smoothing or buffer size differ)";
}

std::string format_state(const msg::InterpolatorState& s, const std::string& config_letters) {
  // The service's letters, where it sends them: they are what its positions mean.
  const std::string letters =
      s.axis_letters().size() == 0 ? config_letters : s.axis_letters().to_string();
  std::string out;
  char buf[512];
  const int n = std::max(1, std::min<int>(s.number_axes(), kMaxAxes));
  // One row of per-axis values: integers as they are, reals with `decimals` (-1: %g). The
  // formats are literals, so the compiler checks them against the values.
  auto axes = [&](const char* name, int decimals, auto get) {
    std::string t = name;
    for (int i = 0; i < n; ++i) {
      char b[64];
      const char letter =
          i < static_cast<int>(letters.size()) ? letters[static_cast<std::size_t>(i)] : '?';
      const auto value = get(static_cast<std::size_t>(i));
      if constexpr (std::is_integral_v<decltype(value)>) {
        std::snprintf(b, sizeof b, " %c %lld", letter, static_cast<long long>(value));
      } else if (decimals < 0) {
        std::snprintf(b, sizeof b, " %c %g", letter, value);
      } else {
        std::snprintf(b, sizeof b, " %c %.*f", letter, decimals, value);
      }
      t += b;
    }
    out += t + '\n';
  };
  const auto rf = static_cast<std::uint32_t>(s.run_flag());
  // Off the trajectory (Command 5, 9 or 2049) the screen looked the same as after Command 4,
  // whose program a start resumes (review of the HMI, session 75).
  append_line(out, "Interpolator %d: Status %d (%s%s%s%s), Number_Axes %d, Buffer_Size %d",
              s.number(), s.status(), std::string(client::status_name(s.status())).c_str(),
              s.plc_setup() == 1 ? ", not yet set up by the PLC: a start waits for it" : "",
              s.program_stop() ? ", at an M0 program stop: start continues" : "",
              !s.off_trajectory()   ? ""
              : s.program_id() != 0 ? ", off the trajectory: the program was dropped"
                                    // A stop off the trajectory with nothing loaded (it said
                                    // "the program was dropped" where none had been).
                                    : ", off the trajectory: no program; load one or set the "
                                      "position",
              s.number_axes(), s.buffer_size());
  // The manual's names of Run_Flag's two halves, after the numbers.
  static constexpr const char* kSection[] = {"STOP",       "RUN",        "WAIT_WINDOW",
                                             "WAIT_PULSE", "WAIT_MFUNC", "WAIT_MFUNC_WAIT_FOR_END"};
  static constexpr const char* kSpeed[] = {"",
                                           "no motion",
                                           "accelerating",
                                           "speed reached",
                                           "decelerating",
                                           "next speed section",
                                           "decelerating on the last section",
                                           "emergency ramp"};
  const std::uint32_t section = rf & 0xFFFFu, speed = rf >> 16;
  append_line(out,
              "  Command %d, Command_Status %d, Run_Flag 0x%08x (section %u %s, speed %u %s), "
              "Address_External_Position %d",
              s.command(), s.command_status(), rf, section, section < 6 ? kSection[section] : "?",
              speed, speed >= 1 && speed < 8 ? kSpeed[speed] : "?", s.address_external_position());
  append_line(out,
              "  Act_Part %d, line %d, Act_G_Func %d, Act_M_Func %d, M_Func %d, Last_Cont_M_Func "
              "%d, Tool_Number %d",
              s.act_part(), s.act_line(), s.act_g_func(), s.act_m_func(), s.m_func(),
              s.last_cont_m_func(), s.tool_number());
  append_line(
      out, "  Rel_Speed %.3f, Set_Speed %.1f mm/min, Act_Speed %.1f mm/min, Move_Distance %.3f mm",
      s.rel_speed(), s.set_speed(), s.act_speed(), s.move_distance());
  axes("  Orig_Position [mm]   ", 4, [&](std::size_t i) { return s.orig_position()[i]; });
  axes("  Position [mm]        ", 4, [&](std::size_t i) { return s.position()[i]; });
  axes("  PositionInc [inc]    ", 0, [&](std::size_t i) { return s.position_inc()[i]; });
  axes("  Speed [mm/s]         ", 3, [&](std::size_t i) { return s.speed()[i]; });
  axes("  Ratio [inc/mm]       ", -1, [&](std::size_t i) { return s.ratio()[i]; });
  axes("  Offset [inc]         ", 0, [&](std::size_t i) { return s.offset()[i]; });
  axes("  Backlash [inc]       ", 0, [&](std::size_t i) { return s.backlash()[i]; });
  // The letters that are set, each value with all its digits (%g showed H99999999 as H1e+08).
  const auto letters_set = [&](const auto& values) {
    std::string text;
    for (std::size_t k = 0; k < kParamLetters; ++k) {
      if (is_not_set(values[k])) continue;
      std::snprintf(buf, sizeof buf, " %c%.15g", static_cast<char>('A' + k), values[k]);
      text += buf;
    }
    return text;
  };
  const std::string params = letters_set(s.m_function_parameter());
  append_line(out, "  M_Function_Parameter:%s", params.empty() ? " (none)" : params.c_str());
  std::string command_parameter;
  // Appended piece by piece: GCC 12 at -O3 warns of an overlapping memcpy inside
  // `" " + std::to_string(p)` (a false -Wrestrict).
  for (const std::int32_t p : s.command_parameter()) {
    command_parameter += ' ';
    command_parameter += std::to_string(p);
  }
  append_line(out, "  Command_Parameter:%s", command_parameter.c_str());
  // Every axis by its letter (three unnamed values dropped A..E of a 10-axis interpolator), the
  // angles where they apply and AllParams (review of the HMI, session 75).
  append_line(out, "  LookAheadBuffer:");
  for (std::size_t e = 0; e < s.look_ahead_buffer().size(); ++e) {
    const auto& l = s.look_ahead_buffer()[e];
    if (l.movement_type() == 0) {
      append_line(out, "    [%zu] invalid", e);
      continue;
    }
    std::string end;
    for (int a = 0; a < n; ++a) {
      const auto ua = static_cast<std::size_t>(a);
      std::snprintf(buf, sizeof buf, " %c%.4f", ua < letters.size() ? letters[ua] : '?',
                    l.end_pos()[ua]);
      end += buf;
    }
    std::string angles;
    for (const auto& [name, v] :
         {std::pair{"tangent", l.tangent()}, std::pair{"start angle", l.start_angle()},
          std::pair{"end angle", l.end_angle()}}) {
      if (is_not_set(v)) continue;
      std::snprintf(buf, sizeof buf, " %s %.3f", name, v);
      angles += buf;
    }
    const std::string all = letters_set(l.all_params());
    append_line(out, "    [%zu] %s%d line %d plane %d tool %d end%s radius %.4f%s%s%s", e,
                l.movement_type() == 1 ? "G" : "M", l.movement_code(), l.line(), l.plane(),
                l.tool(), end.c_str(), l.radius(), angles.c_str(), all.empty() ? "" : " AllParams",
                all.c_str());
  }
  append_line(out, "  program %u: next_sequence %llu, buffered %d, free %d", s.program_id(),
              static_cast<unsigned long long>(s.next_sequence()), s.buffered_segments(),
              s.free_buffer_slots());
  // 0: a service before 0.2.1, whose state has no digest (read as an older layout).
  char digest[48] = "not said (tgm-service before 0.2.1)";
  if (s.machine_digest() != 0) {
    std::snprintf(digest, sizeof digest, "%016llx",
                  static_cast<unsigned long long>(s.machine_digest()));
  }
  append_line(out,
              "  M-functions handed over %u (the last from line %d); service instance %016llx, "
              "machine digest %s",
              s.m_func_count(), s.m_func_line(),
              static_cast<unsigned long long>(s.service_instance()), digest);
  append_line(out, "  Smoothing: %s", client::describe_smoothing(s, letters).c_str());
  append_line(out,
              "  cycle %llu of %d us, lateness last %.1f us, max %.1f us, p99.9 %.1f us, missed "
              "cycles %llu",
              static_cast<unsigned long long>(s.cycle_counter()), s.cycle_time_us(),
              static_cast<double>(s.lateness_last_ns()) / 1e3,
              static_cast<double>(s.lateness_max_ns()) / 1e3,
              static_cast<double>(s.lateness_p999_ns()) / 1e3,
              static_cast<unsigned long long>(s.missed_cycles()));
  if (s.message_counter() > 0)
    append_line(out, "  last message (%u): %s", s.message_counter(),
                printable(s.message_text().c_str()).c_str());
  return out;
}

}  // namespace tgm::hmi

namespace tgm::hmi {

namespace {
// JSON pieces of format_state_json. A number that is not finite (a state from a foreign or
// broken writer) is null: JSON has no NaN.
void json_key(std::string& out, const char* key) {
  if (out.back() != '{') out += ',';
  append_json_string(out, key);
  out += ':';
}
void json_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  append_shortest(out, v);
}
void json_number(std::string& out, long long v) {
  out += std::to_string(v);
}
void json_number(std::string& out, unsigned long long v) {
  out += std::to_string(v);
}
template <class T>
void json_field(std::string& out, const char* key, T v) {
  json_key(out, key);
  if constexpr (std::is_floating_point_v<T>) {
    json_number(out, static_cast<double>(v));
  } else if constexpr (std::is_same_v<T, bool>) {
    out += v ? "true" : "false";
  } else if constexpr (std::is_signed_v<T>) {
    json_number(out, static_cast<long long>(v));
  } else {
    json_number(out, static_cast<unsigned long long>(v));
  }
}
// {"A": 1.5, ...}: the M-function addresses that are set.
template <class Params>
void json_params(std::string& out, const char* key, const Params& p) {
  json_key(out, key);
  out += '{';
  for (std::size_t k = 0; k < kParamLetters && k < p.size(); ++k) {
    if (is_not_set(p[k])) continue;
    const char letter[2] = {static_cast<char>('A' + k), '\0'};
    json_field(out, letter, p[k]);
  }
  out += '}';
}
}  // namespace

std::string format_state_json(const msg::InterpolatorState& s, const std::string& config_letters,
                              double age_s) {
  const std::string letters =
      s.axis_letters().size() == 0 ? config_letters : s.axis_letters().to_string();
  const int n = std::max(1, std::min<int>(s.number_axes(), kMaxAxes));
  std::string out = "{";
  // {"X": v, "Y": v, ...} over the axes in use.
  auto axes = [&](const char* key, const auto& values) {
    json_key(out, key);
    out += '{';
    for (int i = 0; i < n; ++i) {
      const char letter[2] = {
          i < static_cast<int>(letters.size()) ? letters[static_cast<std::size_t>(i)] : '?', '\0'};
      json_field(out, letter, values[static_cast<std::size_t>(i)]);
    }
    out += '}';
  };
  json_field(out, "number", s.number());
  json_field(out, "status", s.status());
  json_key(out, "status_name");
  append_json_string(out, client::status_name(s.status()));
  json_field(out, "number_axes", s.number_axes());
  json_key(out, "axis_letters");
  append_json_string(out, letters.substr(0, static_cast<std::size_t>(n)));
  json_field(out, "buffer_size", s.buffer_size());
  json_field(out, "command", s.command());
  json_key(out, "command_parameter");
  out += '[';
  for (std::size_t k = 0; k < s.command_parameter().size(); ++k) {
    if (k > 0) out += ',';
    json_number(out, static_cast<long long>(s.command_parameter()[k]));
  }
  out += ']';
  json_field(out, "command_status", s.command_status());
  json_field(out, "address_external_position", s.address_external_position());
  json_field(out, "run_flag", static_cast<std::uint32_t>(s.run_flag()));
  json_field(out, "act_part", s.act_part());
  json_field(out, "act_line", s.act_line());
  json_field(out, "act_g_func", s.act_g_func());
  json_field(out, "act_m_func", s.act_m_func());
  json_field(out, "m_func", s.m_func());
  json_field(out, "last_cont_m_func", s.last_cont_m_func());
  json_field(out, "m_func_count", s.m_func_count());
  json_field(out, "m_func_line", s.m_func_line());
  json_field(out, "tool_number", s.tool_number());
  json_field(out, "rel_speed", s.rel_speed());
  json_field(out, "set_speed_mm_min", s.set_speed());
  json_field(out, "act_speed_mm_min", s.act_speed());
  json_field(out, "act_acceleration_mm_s2", s.act_acceleration_mm_s2());
  json_field(out, "move_distance_mm", s.move_distance());
  json_field(out, "limit_factor", static_cast<int>(s.limit_factor()));
  json_field(out, "off_trajectory", static_cast<bool>(s.off_trajectory()));
  json_field(out, "program_stop", static_cast<bool>(s.program_stop()));
  json_field(out, "plc_setup", static_cast<int>(s.plc_setup()));
  axes("orig_position_mm", s.orig_position());
  axes("position_mm", s.position());
  axes("position_inc", s.position_inc());
  axes("backlash_inc", s.backlash());
  axes("offset_inc", s.offset());
  axes("speed_mm_s", s.speed());
  axes("ratio_inc_per_mm", s.ratio());
  json_params(out, "m_function_parameter", s.m_function_parameter());
  json_key(out, "look_ahead_buffer");
  out += '[';
  for (std::size_t e = 0; e < s.look_ahead_buffer().size(); ++e) {
    const auto& l = s.look_ahead_buffer()[e];
    if (e > 0) out += ',';
    if (l.movement_type() == 0) {
      out += "null";
      continue;
    }
    out += '{';
    json_field(out, "movement_type", l.movement_type());
    json_field(out, "movement_code", l.movement_code());
    json_field(out, "line", l.line());
    json_field(out, "plane", l.plane());
    json_field(out, "tool", l.tool());
    axes("end_pos_mm", l.end_pos());
    json_field(out, "radius_mm", l.radius());
    // "Does not apply" (> 1e38 in the register) is null, as simulate --lookahead writes it: it
    // was 1e+39 here (review of the HMI, session 75).
    for (const auto& [key, v] :
         {std::pair{"tangent_deg", l.tangent()}, std::pair{"start_angle_deg", l.start_angle()},
          std::pair{"end_angle_deg", l.end_angle()}}) {
      json_key(out, key);
      if (is_not_set(v)) {
        out += "null";
      } else {
        json_number(out, v);
      }
    }
    json_params(out, "all_params", l.all_params());
    out += '}';
  }
  out += ']';
  json_field(out, "program_id", s.program_id());
  json_field(out, "next_sequence", s.next_sequence());
  json_field(out, "buffered_segments", s.buffered_segments());
  json_field(out, "free_buffer_slots", s.free_buffer_slots());
  // 64 random bits: a string, so that no JSON reader rounds it to a double.
  char instance[20];
  std::snprintf(instance, sizeof instance, "%016llx",
                static_cast<unsigned long long>(s.service_instance()));
  json_key(out, "service_instance");
  append_json_string(out, instance);
  std::snprintf(instance, sizeof instance, "%016llx",
                static_cast<unsigned long long>(s.machine_digest()));
  json_key(out, "machine_digest");
  append_json_string(out, instance);
  // The smoothing in effect; null where the service does not say (before 0.2.2).
  const std::optional<SmoothingConfig> smoothing = client::smoothing_in_effect(s);
  json_key(out, "smoothing");
  if (!smoothing) {
    out += "null";
  } else {
    out += '{';
    json_field(out, "spline_points", smoothing->spline_points);
    json_field(out, "spline_jerk_mm_s3", smoothing->spline_jerk_mm_s3);
    json_field(out, "iir_p_e6", smoothing->iir_p_e6);
    json_field(out, "iir_q_e6", smoothing->iir_q_e6);
    json_field(out, "iir_f_e6", smoothing->iir_f_e6);
    json_field(out, "iir_axis_mask", smoothing->iir_axis_mask);
    out += '}';
  }
  json_field(out, "cycle_counter", s.cycle_counter());
  json_field(out, "cycle_time_us", s.cycle_time_us());
  json_field(out, "lateness_last_ns", s.lateness_last_ns());
  json_field(out, "lateness_max_ns", s.lateness_max_ns());
  json_field(out, "lateness_p999_ns", s.lateness_p999_ns());
  json_field(out, "missed_cycles", s.missed_cycles());
  json_field(out, "message_counter", s.message_counter());
  json_key(out, "message_text");
  append_json_string(out, s.message_text().to_string());
  if (age_s >= 0.0) json_field(out, "state_age_s", std::round(age_s * 1000.0) / 1000.0);
  out += "}\n";
  return out;
}

}  // namespace tgm::hmi
