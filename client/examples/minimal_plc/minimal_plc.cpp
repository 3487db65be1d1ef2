// tgm-minimal-plc: the smallest useful PLC, written against the installed tgm SDK only
// (find_package(tgm COMPONENTS client); tgm::client::Client). It shows the handshake a PLC of
// your own has to keep with tgm-service (the manual's M-functions, DESIGN section 1):
//
//   1. report the setup of each interpolator when the config asks for it
//      (plc.setup_before_start): until then the service refuses to start the interpolator,
//      and a restarted service (a new service_instance in the state) asks for it again;
//   2. see every M-function the service hands to M_Func: the event topic delivers each one as
//      it happens; the state, read once at the start, shows one that was pending before;
//   3. acknowledge it by writing M_Func = 0, naming it by number and m_func_count: a normal one
//      (below 1000) after the machine has done it (here: after --ack-delay), a continuous one
//      at once, as a note (the motion did not stop for it).
//
// tgm-plc is the full emulator (per-M delays, scripts, refusals, Rel_Speed changes); this
// program is the starting point for a real PLC: replace the delay with your machine's I/O.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "tgm/client/client.hpp"
#include "tgm/yaml_config.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

constexpr const char* kUsage =
    "usage: tgm-minimal-plc [--config YAML] [--ack-delay S] [--wait S]\n"
    "A minimal PLC for tgm-service, an example of the tgm SDK (client/examples/minimal_plc):\n"
    "reports each interpolator's setup, acknowledges normal M-functions after --ack-delay and\n"
    "notes continuous ones at once, logging each. Runs until SIGINT or SIGTERM.\n"
    "  --config YAML   the tgm config (default: the installed config/default.yaml)\n"
    "  --ack-delay S   seconds a normal M-function takes, 0..3600 (default 0.1)\n"
    "  --wait S        seconds to wait for tgm-service at the start, 1..3600 (default 10)\n"
    "Exit codes: 0 stopped by a signal, 1 no tgm-service, 2 bad usage.\n";

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop = true;
}

// A number in [lo, hi] from a flag's value; false (and a message) when it is none.
bool parse_seconds(std::string_view flag, const char* text, double lo, double hi, double& out) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(v >= lo && v <= hi)) {
    std::fprintf(stderr, "tgm-minimal-plc: %.*s '%s' is not a number of seconds %g..%g\n",
                 static_cast<int>(flag.size()), flag.data(), text, lo, hi);
    return false;
  }
  out = v;
  return true;
}

// What the event callback saw, handed to the main thread (the callback must not block or call
// anything but send(): tgm/client/client.hpp, on_event()).
struct Seen {
  int interpolator = 0;
  std::uint64_t instance = 0;  // service instance: a restarted service counts afresh
  std::uint32_t count = 0;     // m_func_count: names this M-function
  std::int32_t m = 0, line = 0;
  std::string params;  // "S=1000 T=3": the M line's other words (M_Function_Parameter)
};

template <typename Sample>
Seen seen_of(const Sample& s) {
  Seen e{s.interpolator(),
         s.service_instance(),
         s.m_func_count(),
         s.m_func(),
         s.m_func_line() != 0 ? s.m_func_line() : s.act_line(),
         {}};
  for (std::size_t k = 0; k < 26; ++k) {
    const double p = s.m_function_parameter()[k];
    if (p < 1e38) {
      char word[64];
      std::snprintf(word, sizeof word, "%s%c=%g", e.params.empty() ? "" : " ",
                    static_cast<char>('A' + k), p);
      e.params += word;
    }
  }
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_path;
  double ack_delay_s = 0.1, wait_s = 10.0;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    const bool takes_value = a == "--config" || a == "--ack-delay" || a == "--wait";
    if (!takes_value) {
      std::fprintf(stderr, "tgm-minimal-plc: unknown argument '%s'\n%s", argv[i], kUsage);
      return 2;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "tgm-minimal-plc: %s needs a value\n%s", argv[i], kUsage);
      return 2;
    }
    const char* value = argv[++i];
    if (a == "--config") {
      config_path = value;
    } else if (!parse_seconds(a, value, a == "--wait" ? 1.0 : 0.0, 3600.0,
                              a == "--wait" ? wait_s : ack_delay_s)) {
      return 2;
    }
  }
  const auto config = tgm::load_config_or_report(config_path, "tgm-minimal-plc");
  if (!config) return 2;
  const int interpolators = static_cast<int>(config->machine.interpolators.size());

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);

  try {
    tgm::client::Client plc(config->dds, tgm::client::Role::kPlc);
    std::mutex mutex;
    std::vector<Seen> events;  // guarded by mutex
    plc.on_event([&](const tgm::client::Event& e) {
      if (e.sample.m_func() == 0) return;
      const std::lock_guard<std::mutex> lock(mutex);
      events.push_back(seen_of(e.sample));
    });

    const auto wait = std::chrono::milliseconds(static_cast<long long>(wait_s * 1000.0));
    for (int i = 0; i < interpolators; ++i) {
      if (!plc.wait_for_state(i, wait, &g_stop)) {
        if (g_stop) return 0;
        std::fprintf(stderr,
                     "tgm-minimal-plc: no state of interpolator %d from tgm-service on "
                     "DDS domain %d within %g s: is it running with this config?\n",
                     i, config->dds.domain_id, wait_s);
        return 1;
      }
    }
    // Events written before the event reader matched are not replayed; the state, read in
    // every round below, shows an M-function that was waiting before (or whose event was lost).
    if (!plc.wait_for_event_match(wait, &g_stop) && !g_stop) {
      std::fprintf(stderr, "tgm-minimal-plc: the event topic did not match within %g s\n", wait_s);
      return 1;
    }
    std::printf("serving %d interpolator(s) on DDS domain %d; normal M-functions take %g s\n",
                interpolators, config->dds.domain_id, ack_delay_s);
    // The service instance each interpolator's setup was reported to: a restarted service
    // (a new instance) waits for the report again.
    std::vector<std::uint64_t> set_up(static_cast<std::size_t>(interpolators), 0);
    const auto report_setup = [&](int i, std::uint64_t instance) {
      if (!config->plc.setup_before_start || set_up[static_cast<std::size_t>(i)] == instance)
        return;
      set_up[static_cast<std::size_t>(i)] = instance;
      // A real PLC sets the interpolator up first (ratios, Number_Axes, the drives' position:
      // ratio_request(), number_axes_request(), offset_request()), then reports it.
      const tgm::client::Reply r = plc.request(tgm::client::plc_setup_done_request(i));
      std::printf("interpolator %d: setup reported: %s\n", i, tgm::client::describe(r).c_str());
    };

    // Per interpolator: the service instance followed and the highest m_func_count handled.
    std::map<int, std::pair<std::uint64_t, std::uint32_t>> handled;
    struct Due {
      Seen m;
      Clock::time_point at;
    };
    std::vector<Due> due;
    const auto handle = [&](const Seen& e) {
      auto& [instance, newest] = handled[e.interpolator];
      if (e.instance != instance) {  // first sample, or a restarted service: counts begin again
        instance = e.instance;
        newest = 0;
      }
      if (e.count <= newest) return;  // seen already (event and state both show it)
      newest = e.count;
      const bool normal = e.m < 1000;
      std::printf("interpolator %d: M%d (line %d%s%s) %s\n", e.interpolator, e.m, e.line,
                  e.params.empty() ? "" : ", ", e.params.c_str(),
                  normal ? "normal: the interpolator waits" : "continuous: motion goes on");
      const double delay = normal ? ack_delay_s : 0.0;
      due.push_back(
          {e, Clock::now() + std::chrono::microseconds(static_cast<long long>(delay * 1e6))});
    };

    while (!g_stop) {
      plc.poll(20ms);
      std::vector<Seen> taken;
      {
        const std::lock_guard<std::mutex> lock(mutex);
        taken.swap(events);
      }
      for (const Seen& e : taken) handle(e);
      for (int i = 0; i < interpolators; ++i) {
        const auto* s = plc.state(i);
        if (s == nullptr) continue;
        report_setup(i, s->service_instance());
        if (s->m_func() != 0) handle(seen_of(*s));
      }
      const auto now = Clock::now();
      for (std::size_t k = 0; k < due.size();) {
        if (due[k].at > now) {
          ++k;
          continue;
        }
        const Seen m = due[k].m;
        due.erase(due.begin() + static_cast<std::ptrdiff_t>(k));
        // Named by number and count: the service refuses it (WRONG_STATE) when M_Func already
        // shows a later M-function, so a late note never releases the wrong one.
        const tgm::client::Reply r = plc.ack_m_func(m.interpolator, m.m, m.count);
        std::printf("interpolator %d: M%d acknowledged: %s\n", m.interpolator, m.m,
                    tgm::client::describe(r).c_str());
      }
    }
    std::printf("stopped\n");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tgm-minimal-plc: %s\n", e.what());
    return 1;
  }
}
