#include "dds_common.hpp"

#include <signal.h>

#include <cstdarg>
#include <cstdio>
#include <type_traits>

#include "tgm/intercode.hpp"
#include "tgm/printable.hpp"
#include "tgm/registers.hpp"

namespace tgm::hmi {

std::atomic<bool> g_interrupted{false};

namespace {
void on_signal(int) { g_interrupted = true; }
}  // namespace

void install_signal_flag() {
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int make_client(Args& args, const DdsOverrides& o, std::optional<AppConfig>& config,
                std::optional<client::Client>& c, const client::ClientOptions& options) {
  config = args.load_app();
  if (!config) return 2;
  o.apply(config->dds);
  if (std::string why = dds_config_problem(config->dds, "hmi"); !why.empty())
    return args.usage_error(why);
  try {
    c.emplace(config->dds, client::Role::kHmi, options);
  } catch (const dds::SetupError& e) {
    std::fprintf(stderr, "tgm-hmi: %s\n", e.what());
    return 1;
  }
  return 0;
}

bool wait_for_service(client::Client& c, const AppConfig& config, int interpolator, const char* command) {
  if (c.wait_for_state(interpolator, std::chrono::seconds(10))) return true;
  std::fprintf(
      stderr,
      "tgm-hmi %s: no state of interpolator %d from tgm-service on DDS domain %d within 10 s "
      "(is tgm-service running with the same domain, profiles and security?)\n",
      command, interpolator, config.dds.domain_id);
  return false;
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
  append_line(out, "Interpolator %d: Status %d (%s), Number_Axes %d, Buffer_Size %d", s.number(),
              s.status(), std::string(client::status_name(s.status())).c_str(), s.number_axes(),
              s.buffer_size());
  append_line(out, "  Command %d, Command_Status %d, Run_Flag 0x%08x (section %u, speed %u)",
              s.command(), s.command_status(), rf, rf & 0xFFFFu, rf >> 16);
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
  std::string params;
  for (std::size_t k = 0; k < kParamLetters; ++k) {
    if (is_not_set(s.m_function_parameter()[k])) continue;
    std::snprintf(buf, sizeof buf, " %c%g", static_cast<char>('A' + k), s.m_function_parameter()[k]);
    params += buf;
  }
  append_line(out, "  M_Function_Parameter:%s", params.empty() ? " (none)" : params.c_str());
  append_line(out, "  LookAheadBuffer:");
  for (std::size_t e = 0; e < s.look_ahead_buffer().size(); ++e) {
    const auto& l = s.look_ahead_buffer()[e];
    if (l.movement_type() == 0) {
      append_line(out, "    [%zu] invalid", e);
      continue;
    }
    append_line(out, "    [%zu] %s%d line %d plane %d tool %d end (%.4f, %.4f, %.4f) radius %.4f",
                e, l.movement_type() == 1 ? "G" : "M", l.movement_code(), l.line(), l.plane(),
                l.tool(), l.end_pos()[0], l.end_pos()[1], l.end_pos()[2], l.radius());
  }
  append_line(out, "  program %u: next_sequence %llu, buffered %d, free %d", s.program_id(),
              static_cast<unsigned long long>(s.next_sequence()), s.buffered_segments(),
              s.free_buffer_slots());
  append_line(out, "  M-functions handed over %u; service instance %016llx", s.m_func_count(),
              static_cast<unsigned long long>(s.service_instance()));
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
