// tgm-hmi run: compile a program, stream it into an interpolator's buffer (flow controlled by
// the free buffer count; a program larger than Buffer_Size streams while it runs), start it and
// follow it to the end with a progress display, M29 messages and a summary.
#include <poll.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "commands.hpp"
#include "dds_common.hpp"
#include "plot_series.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/printable.hpp"
#include "tgm/program_times.hpp"
#include "tgm/registers.hpp"
#include "tgm/resume.hpp"
#include "wait_count.hpp"

namespace tgm::hmi {

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

constexpr const char* kUsage =
    "usage: tgm-hmi run FILE [--interpolator N] [--config YAML] [OPTIONS]\n"
    "\n"
    "Compiles FILE (G-code, or intercode written by `tgm-hmi compile --out`, *.tgmi or known by\n"
    "its first bytes; - reads standard input), streams it into the interpolator's buffer,\n"
    "starts it and follows it to the end. A stop on the trajectory (Command 8, or the\n"
    "emergency stop 4) is followed until `tgm-hmi command start` resumes it. Exit code 0\n"
    "when the program ended, 1 when it was dropped (a stop off the trajectory, 5 or 9) or\n"
    "failed, 2 on bad input. Where the service's config has plc.setup_before_start, it first\n"
    "waits for the PLC to set the interpolator up (up to 10 s, or --timeout).\n"
    "\n"
    "  --interpolator N      interpolator 0 up to the config's interpolators - 1 (at most\n"
    "                        2; default 0)\n"
    "  --config YAML         machine config (default: $TGM_CONFIG, the installed or\n"
    "                        the in-tree config/default.yaml)\n"
    "  --domain N, --profiles FILE, --participant-prefix P, --security DIR   DDS overrides\n"
    "  --plot OUT.svg        draw the executed toolpath (XY) and the path speed over time\n"
    "  --progress-interval S plain progress line every S seconds when not on a terminal (default "
    "1)\n"
    "  --m0-continue S       after an M0 program stop, start again after S seconds (default: on a\n"
    "                        terminal wait for Enter, otherwise 1 s)\n"
    "  --timeout S           give up (stop the interpolator, exit 1) after S seconds (default "
    "none)\n"
    "  --quiet               no progress display, only messages and the summary\n"
    "  --no-estimate         no time estimate (below; none with --quiet either)\n"
    "  --from-here           run a .tgmi file from where the interpolator stands although it\n"
    "                        was compiled from another point (its first move goes from "
    "here)\n" TGM_HMI_RESUME_USAGE
    "  --start X20,Y5        with --from-line and G-code: where the program was started from\n"
    "                        the first time [mm] (default: zero), so that its G91 moves and the\n"
    "                        axes its G90 lines do not name go where they went then\n"
    "  --block-delete W      lines that start with '/' (optional blocks): run (the block\n"
    "                        delete switch off) or skip (on); default: the config's\n"
    "                        compiler.block_delete, error unless set (such a line is refused)\n"
    "  --single-block        stop after each block (a program stop, as an M0: Enter, or\n"
    "                        --m0-continue S, runs the next), to prove out a new program\n"
    "\n"
    "A G-code FILE is compiled from where the interpolator stands. A .tgmi file runs only from\n"
    "the point it was compiled from (tgm-hmi compile --start), unless --from-here.\n"
    "\n"
    "The progress line shows the part done by time and the time left: the program is\n"
    "simulated with this config's machine at the Rel_Speed it starts with, normal\n"
    "M-functions acknowledged after plc.default_m_delay_s / plc.m_delay_s, no operator wait (an\n"
    "M0, a stop), and the moves of the time left scaled to the Rel_Speed now (the waits for\n"
    "M-functions and dwells not); until that is done (a thread at the lowest priority), the\n"
    "part of the records sent. The summary gives the estimate beside the time the program\n"
    "took. A service whose machine is not this config's (its state's machine_digest; tgm-hmi\n"
    "status) gets no estimate, and the run says so.\n"
    "\n"
    "Ctrl-C (or SIGTERM) stops the interpolator (normal stop on the trajectory) and exits with\n"
    "130, also while it waits for the service (its state, or the reply to the clear or the\n"
    "start). The stop (also that of --timeout) is repeated until tgm-service answers it, for up\n"
    "to 60 s (a network outage); a second Ctrl-C gives up, and the run then says that the\n"
    "interpolator was not stopped. A closed terminal or SSH session (SIGHUP), or a reader of its\n"
    "output that goes away, does not end the run: it follows the program to its end.\n";

struct PlotData {
  std::vector<std::pair<double, double>> path;      // Position of the first two axes [mm]
  std::vector<std::pair<double, double>> speed;     // (time [s], Act_Speed [mm/min])
};

// Points kept for the plot while the program runs: every 0.05 mm of the path and every state
// of the speed until a million of each, then thinned (PlotSeries): a run of hours stays bounded.
constexpr std::size_t kMaxPlotPoints = std::size_t{1} << 20;

// A stream that waits this long with the service's buffer empty, or a service silent this
// long, is taken for a link broken one way: the run joins DDS again (Client::rejoin), at most
// once per kRejoinEvery.
constexpr std::chrono::seconds kStallBeforeRejoin{2};
constexpr std::chrono::seconds kSilenceBeforeRejoin{5};
constexpr std::chrono::seconds kRejoinEvery{10};

// How long the clear and the start wait for their reply. Each can be the run's first request,
// and its endpoints are matched only then: on a link losing 10 % of its datagrams the start of
// a fully streamed program found no match within the 3 s of a `tgm-hmi command` and the run
// ended ("no reply ... nothing was sent"; ServiceNetns.ProgramRequestsAndHandshake..., CI of
// session 59). The service holds a reply up to 30 s for the match as well.
constexpr std::chrono::milliseconds kFirstRequestTimeout = 30s;

// How long the stop that ends a run (Ctrl-C, --timeout) is tried until the service answers it.
constexpr auto kStopPersistence = 60s;

// An M-function that has waited this long for the PLC's acknowledgement [s]: the progress line
// asks whether tgm-plc runs (the PLC's own delays are fractions of a second).
constexpr double kLongMWait = 5.0;

bool write_svg(AtomicFile& out, const PlotData& d, const std::string& letters, std::string& error) {
  const double W = 900, H = 420, pad = 40;
  std::string s;
  char b[256];
  std::snprintf(b, sizeof b,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" font-family=\"sans-serif\" "
                "font-size=\"12\">\n<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
                W, H);
  s += b;
  auto polyline = [&](const std::vector<std::pair<double, double>>& pts, double x0, double y0, double w, double h,
                      const char* colour, const char* title, bool equal) {
    double minx = 1e300, maxx = -1e300, miny = 1e300, maxy = -1e300;
    for (auto [x, y] : pts) {
      minx = std::min(minx, x), maxx = std::max(maxx, x), miny = std::min(miny, y), maxy = std::max(maxy, y);
    }
    if (pts.empty()) minx = maxx = miny = maxy = 0;
    double sx = (maxx - minx) > 1e-12 ? w / (maxx - minx) : 1.0;
    double sy = (maxy - miny) > 1e-12 ? h / (maxy - miny) : 1.0;
    if (equal) sx = sy = std::min(sx, sy);
    std::snprintf(b, sizeof b, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"#ccc\"/>\n",
                  x0, y0, w, h);
    s += b;
    std::snprintf(b, sizeof b, "<text x=\"%.1f\" y=\"%.1f\">%s</text>\n", x0, y0 - 8, title);
    s += b;
    std::snprintf(b, sizeof b,
                  "<text x=\"%.1f\" y=\"%.1f\" fill=\"#666\">x %.3g..%.3g, y %.3g..%.3g</text>\n", x0, y0 + h + 16,
                  minx, maxx, miny, maxy);
    s += b;
    s += "<polyline fill=\"none\" stroke=\"";
    s += colour;
    s += "\" stroke-width=\"1.2\" points=\"";
    for (auto [x, y] : pts) {
      std::snprintf(b, sizeof b, "%.2f,%.2f ", x0 + (x - minx) * sx, y0 + h - (y - miny) * sy);
      s += b;
    }
    s += "\"/>\n";
  };
  const std::string t1 = std::string("toolpath ") + (letters.size() > 0 ? letters[0] : 'X') + "/" +
                         (letters.size() > 1 ? letters[1] : 'Y') + " [mm]";
  polyline(d.path, pad, pad, W / 2 - 2 * pad, H - 2 * pad - 10, "#1565c0", t1.c_str(), true);
  polyline(d.speed, W / 2 + pad / 2, pad, W / 2 - 1.5 * pad, H - 2 * pad - 10, "#c62828",
           "path speed Act_Speed [mm/min] over time [s]", false);
  s += "</svg>\n";
  return out.write(s.data(), s.size(), error) && out.commit(error);
}

// What the operator's terminal holds for an M0 wait.
enum class StdinLine { kNone, kLine, kClosed };
StdinLine stdin_line() {
  pollfd p{0, POLLIN, 0};
  if (::poll(&p, 1, 0) <= 0) return StdinLine::kNone;
  char buf[256];
  const ssize_t got = ::read(0, buf, sizeof buf);
  if (got > 0) return StdinLine::kLine;
  if (got < 0 && (errno == EINTR || errno == EAGAIN)) return StdinLine::kNone;
  // End of input (Ctrl-D, or the terminal hung up: EIO) is no operator pressing Enter. It was
  // taken for one: a closed SSH session let the program run on past its M0.
  return StdinLine::kClosed;
}

// The time a running program has left: the program run offline (tgm/program_times.hpp) in a
// thread at the lowest priority while it streams and runs, so that neither waits for it and
// the service, on the same host or not, gives it no cycle.
class TimeEstimate {
 public:
  TimeEstimate(MachineConfig machine, SimulationOptions options, const PackedProgram& program)
      : thread_(
            [this, machine = std::move(machine), options = std::move(options), &program]() mutable {
              // Linux: a thread's id names that thread alone. Nothing to say if refused: it runs
              // at the HMI's priority then.
              (void)::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 19);
              options.on_progress = [this](const SimulationProgress&) {
                return !cancel_.load(std::memory_order_relaxed);
              };
              std::string error;
              if (auto t = program_times(machine, options, program, &error)) {
                times_ = std::move(*t);
              } else {
                error_ = error.empty() ? "the simulation did not end" : error;
              }
              done_.store(true, std::memory_order_release);
            }) {}
  TimeEstimate(const TimeEstimate&) = delete;
  TimeEstimate& operator=(const TimeEstimate&) = delete;
  ~TimeEstimate() {
    cancel_.store(true, std::memory_order_relaxed);
    thread_.join();
  }
  //! The times once the run is done; nullptr before, or when it failed.
  const ProgramTimes* times() const {
    return done_.load(std::memory_order_acquire) && error_.empty() ? &times_ : nullptr;
  }
  //! Why there are none, once the run is done; empty before, or when it succeeded.
  std::string failure() const {
    return done_.load(std::memory_order_acquire) ? error_ : std::string();
  }

 private:
  std::atomic<bool> cancel_{false}, done_{false};
  ProgramTimes times_;
  std::string error_;
  std::thread thread_;  // last: it starts once the members it writes exist
};

// A time of up to 999 hours as m:ss or h:mm:ss.
std::string clock_text(double s) {
  const auto t = static_cast<long long>(s > 0.0 ? std::round(std::min(s, 999.0 * 3600.0)) : 0.0);
  char b[32];
  if (t >= 3600) {
    std::snprintf(b, sizeof b, "%lld:%02lld:%02lld", t / 3600, t / 60 % 60, t % 60);
  } else {
    std::snprintf(b, sizeof b, "%lld:%02lld", t / 60, t % 60);
  }
  return b;
}

}  // namespace

int run_run(int argc, char** argv) {
  Args args(argc, argv, "run", kUsage);
  DdsOverrides overrides;
  std::string file, plot_path, error;
  bool quiet = false, from_here = false, single = false, no_estimate = false;
  ResumeFlags resume;
  std::string start_text;
  double interval_s = 1.0, m0_s = -1.0, timeout_s = 0.0;
  while (args.more()) {
    if (args.dds_flag(overrides)) continue;
    if (args.boolean("--from-here", from_here)) continue;
    if (resume.read(args)) continue;
    if (args.flag("--start", start_text)) continue;
    if (args.boolean("--single-block", single)) continue;
    if (args.flag("--plot", plot_path)) continue;
    if (progress_interval_flag(args, interval_s)) continue;
    // Bounded as simulate's --max-time: 1e300 s printed "continuing shortly" and waited for
    // ever (a wait of that many seconds never ends on a steady clock counted in nanoseconds).
    if (args.number_flag("--m0-continue", m0_s, "seconds, >= 0 and at most 1e9",
                         [](double v) { return v >= 0.0 && v <= 1e9; }))
      continue;
    if (args.number_flag("--timeout", timeout_s, "seconds, > 0 and at most 1e9",
                         [](double v) { return v > 0.0 && v <= 1e9; }))
      continue;
    if (args.boolean("--quiet", quiet)) continue;
    if (args.boolean("--no-estimate", no_estimate)) continue;
    if (args.common()) continue;
    if (args.compile_flag()) continue;
    if (args.positional(file)) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (file.empty()) return args.usage_error("a program FILE is required");
  if (!resume.check(args)) return 2;
  if (!start_text.empty() && !resume.given()) {
    return args.usage_error(
        "--start needs --from-line N (without it a program runs from where the interpolator "
        "stands)");
  }
  if (from_here && resume.given()) {
    return args.usage_error(
        "--from-here and --from-line: the block search approaches line N "
        "from where the interpolator stands already; leave --from-here out");
  }
  if (!args.distinct_files({{"FILE", file}, args.config_file()}, {{"--plot", plot_path}})) {
    return 2;
  }
  // Written at the end: a path that cannot be written fails now, not after the run.
  AtomicFile plot_file;
  if (!plot_path.empty() && !plot_file.open(plot_path, error)) {
    return args.usage_error("--plot " + plot_path + ": " + error);
  }

  // Config and program first: bad input never touches the service.
  std::optional<AppConfig> config = args.load_app();
  if (!config) return 2;
  overrides.apply(config->dds);
  if (std::string why = dds::config_problem(config->dds, "hmi"); !why.empty())
    return args.usage_error(why);
  const int ip = args.interpolator();
  const std::string letters = config->machine.axis_letters(ip);
  // Block search: the G-code is compiled from where it first started, not from here.
  std::array<double, kMaxAxes> resume_start{};
  if (std::string why;
      !start_text.empty() && !parse_start(start_text, letters, resume_start, why)) {
    return args.usage_error("--start: " + why);
  }
  // Held as intercode: a program of millions of lines took 152 bytes a record as Segments.
  PackedProgram program;
  bool intercode = false;
  ProgramNotes note(config->machine.tools);
  std::int32_t last_line = 0;
  const auto observe = [&](const Segment& s) {
    note.observe(s);
    last_line = std::max(last_line, s.line);
  };
  // Read once and held for the run: from a pipe, the second compile (from where the
  // interpolator stands, below) read nothing, and the run cleared the interpolator for an empty
  // program (review of session 77).
  // Let go after the last compile (a piped program of up to 1 GiB is not held for hours).
  std::optional<FileView> source_holder;
  FileView& source = source_holder.emplace();
  if (!source.open_or_report(file)) return 2;
  if (std::size_t errors = 0; !load_packed(file, source, config->machine, ip, program, nullptr,
                                           &intercode, observe, &errors)) {
    if (errors > 0)
      std::fprintf(stderr, "%s: %zu error%s, nothing sent\n", file.c_str(), errors,
                   errors == 1 ? "" : "s");
    return 2;
  }
  if (!args.compile_flags_fit(file, intercode)) return 2;
  if (program.size() == 0) {
    std::fprintf(stderr, "%s: error: the program has no records (no move, dwell or M-function)\n", file.c_str());
    return 2;
  }
  // Said once the program is compiled for the tool in the spindle (below).

  install_signal_flag(Hangup::kIgnore);
  // M-function waits are counted from the event topic (RELIABLE, every change of the handshake
  // registers): a wait the PLC acknowledges at once lasts a cycle or two, which the state
  // (KEEP_LAST 1, taken every 2 ms) often does not show. The event callback only queues what
  // the main loop needs. Declared before the client, which detaches the callback when destroyed.
  struct MEvent {
    std::uint64_t cycle;
    std::uint32_t program;
    std::int32_t part;
    bool waiting;  // for the PLC's acknowledgement of an M-function
  };
  std::mutex events_mutex;
  std::vector<MEvent> events_in, events;
  std::optional<client::Client> hmi;
  client::ClientOptions copt;
  copt.setpoints = !plot_path.empty();
  try {
    hmi.emplace(config->dds, client::Role::kHmi, copt);
  } catch (const dds::SetupError& e) {
    std::fprintf(stderr, "tgm-hmi run: %s\n", e.what());
    return 1;
  }
  // --timeout bounds the whole run, the wait for the service too (it waited 10 s regardless).
  const auto began = std::chrono::steady_clock::now();
  if (const int rc =
          wait_for_service(*hmi, *config, ip, "run",
                           timeout_s > 0.0 ? std::min(timeout_s, kServiceWaitS) : kServiceWaitS);
      rc != 0) {
    return rc;
  }
  try {
    hmi->on_event([&](const client::Event& ev) {
      const msg::InterpolatorEvent& e = ev.sample;
      if (e.interpolator() != ip) return;
      const std::lock_guard lock(events_mutex);
      events_in.push_back(
          {e.cycle_counter(), e.program_id(), e.act_part(),
           run_flag_waits_for_m(static_cast<std::uint32_t>(e.run_flag())) && e.m_func() != 0});
    });
  } catch (const dds::SetupError& e) {
    std::fprintf(stderr, "tgm-hmi run: %s\n", e.what());
    return 1;
  }
  // The service's writer is known (its state arrived); the new reader matches it within
  // milliseconds. Events written before the match would be missing from the count.
  const bool events_matched = hmi->wait_for_event_match(std::chrono::seconds(5), &g_interrupted);
  if (!events_matched && g_interrupted) {
    std::fprintf(stderr, "tgm-hmi run: interrupted while waiting for the event topic to match\n");
    return 130;
  }
  if (!events_matched) {
    std::fprintf(stderr,
                 "tgm-hmi run: warning: the event topic did not match within 5 s; M-function waits "
                 "are counted from the state and may miss short ones\n");
  }

  // A service that wants the PLC's setup first (plc.setup_before_start) stands at 0 after a
  // restart until tgm-plc restores the drives' position: compiled from that 0, the program
  // would run from the wrong point, and its start was refused anyway (review of session 80).
  // --timeout is the bound here too, what is left of it (a PLC bringing its fieldbus up may
  // need longer than the 10 s that were the bound whatever --timeout said: review of session 81).
  const double setup_wait_s =
      timeout_s > 0.0
          ? std::max(
                0.0,
                timeout_s -
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count())
          : kServiceWaitS;
  if (const int rc = wait_for_plc_setup(*hmi, ip, "run", setup_wait_s); rc != 0) {
    return rc;
  }
  // Take the interpolator over: clear what it holds (only while it stands).
  const msg::InterpolatorState* st = hmi->state(ip);
  // Positions go by axis index: a program compiled with a config whose letters differ from the
  // service's would drive the wrong axes (the service refuses it too; this says why up front).
  // Fewer axes of the same config: the PLC wrote Number_Axes. G-code is compiled again for the
  // axes the interpolator runs with (below; every program was refused, also one that names only
  // those axes); intercode holds positions for all its axes and is refused.
  const std::string service_letters = st->axis_letters().to_string();
  const bool fewer_axes =
      !service_letters.empty() && service_letters.size() < program.tables().axis_letters.size() &&
      program.tables().axis_letters.compare(0, service_letters.size(), service_letters) == 0;
  if (!service_letters.empty() && service_letters != program.tables().axis_letters &&
      !(fewer_axes && !intercode)) {
    if (fewer_axes) {
      std::fprintf(stderr,
                   "%s: error: compiled for the axes %s, interpolator %d runs with Number_Axes %d "
                   "(%s: written by a PLC, or the service's config has fewer axes than this one): "
                   "run the G-code itself, or compile it with a config of those axes\n",
                   file.c_str(), program.tables().axis_letters.c_str(), ip, st->number_axes(),
                   service_letters.c_str());
    } else {
      std::fprintf(stderr,
                   "%s: error: compiled for the axes %s (config %s), the service's interpolator %d "
                   "drives %s: use the service's config\n",
                   file.c_str(), program.tables().axis_letters.c_str(),
                   args.config_file().path.c_str(), ip, service_letters.c_str());
    }
    return 2;
  }
  // The service this run talks to: a restarted one has lost the program.
  const std::uint64_t instance = st->service_instance();
  // Messages about the service written before this run (the topic keeps the last ones for late
  // readers) are not this run's.
  const std::uint64_t run_from_cycle = st->cycle_counter();
  if (st->status() == 1 || st->status() == 6) {
    std::fprintf(stderr, "tgm-hmi run: interpolator %d is busy (status %d %s); stop it first (tgm-hmi stop)\n", ip,
                 st->status(), std::string(client::status_name(st->status())).c_str());
    return 1;
  }
  // A G-code program runs from where the interpolator stands, as on any CNC: G91 moves are
  // relative to that point and the axes a G90 line does not name stay where they are. It was
  // compiled from machine zero above, so that bad input is reported before any DDS traffic; from
  // any other point it is compiled again (before the clear: an error there leaves the service
  // untouched). Intercode holds absolute positions compiled from the point its file records
  // (`tgm-hmi compile --start`; machine zero before format version 4): from anywhere else its
  // first move and the axes its first G90 lines do not name go elsewhere than compiled (a note
  // said so, and the run went on), so it runs from there only, or with --from-here.
  std::array<double, kMaxAxes> here{};
  bool away = false;
  const std::string& run_letters = fewer_axes ? service_letters : program.tables().axis_letters;
  for (std::size_t k = 0; k < run_letters.size(); ++k) {
    here[k] = st->orig_position()[k];
    away = away || here[k] != 0.0;
  }
  const std::string here_text = point_text(here, run_letters);
  if (intercode) {
    if (resume.given()) {
      // The block search approaches line N from here.
      if (!start_text.empty() &&
          !same_point(resume_start, program.tables().start_mm, program.tables().number_axes)) {
        std::fprintf(stderr,
                     "%s: error: compiled from %s, not from --start %s: leave --start out\n",
                     file.c_str(),
                     point_text(program.tables().start_mm, program.tables().axis_letters).c_str(),
                     point_text(resume_start, program.tables().axis_letters).c_str());
        return 2;
      }
    } else if (same_point(here, program.tables().start_mm, program.tables().number_axes)) {
      // Runs as compiled.
    } else if (!from_here) {
      std::fprintf(stderr,
                   "%s: error: compiled from %s, interpolator %d stands at %s: the program would "
                   "not run as compiled (its moves were planned from %s). Compile the G-code "
                   "from here (tgm-hmi compile FILE --start %s --out ...), run the G-code itself, "
                   "or pass --from-here\n",
                   file.c_str(),
                   point_text(program.tables().start_mm, program.tables().axis_letters).c_str(), ip,
                   here_text.c_str(),
                   point_text(program.tables().start_mm, program.tables().axis_letters).c_str(),
                   point_text(here, program.tables().axis_letters, ',').c_str());
      return 2;
    } else if (!quiet) {
      std::fprintf(stderr,
                   "%s: note: compiled from %s, runs from where interpolator %d stands (%s): its "
                   "first move starts here\n",
                   file.c_str(),
                   point_text(program.tables().start_mm, program.tables().axis_letters).c_str(), ip,
                   here_text.c_str());
    }
  } else {
    // The tool in the spindle is the one the last program left there (Tool_Number, which a clear
    // keeps); the config's initial_tool only while the service shows none. Compiled from the
    // config's alone, a program without a T word set Tool_Number back to 0 and ran G41/G42 at
    // radius 0.
    MachineConfig machine = config->machine;
    const std::int32_t spindle = st->tool_number();
    const bool other_tool =
        spindle > 0 && spindle <= kMaxTool && spindle != machine.compiler.initial_tool;
    if (other_tool) machine.compiler.initial_tool = spindle;
    if (fewer_axes) {
      machine.interpolators[static_cast<std::size_t>(ip)].axes.resize(service_letters.size());
    }
    // A block search compiles from where the program first started (--start), the whole
    // program, and approaches line N from here (resume_program, below).
    const bool resume_away = resume.given() && !same_point(resume_start, {}, kMaxAxes);
    const bool from_point = resume.given() ? resume_away : away;
    const std::array<double, kMaxAxes>& compile_start = resume.given() ? resume_start : here;
    if (from_point || other_tool || fewer_axes) {
      program = PackedProgram{};  // a long program is not held twice
      note = ProgramNotes{config->machine.tools};
      if (std::size_t errors = 0; !load_packed(
              file, source, machine, ip, program, from_point ? &compile_start : nullptr, nullptr,
              [&](const Segment& s) { note.observe(s); }, &errors)) {
        if (errors > 0) {
          std::string how;
          if (resume_away)
            how = "from --start " + point_text(resume_start, letters);
          else if (from_point)
            how = "from where interpolator " + std::to_string(ip) + " stands (" + here_text + ")";
          if (fewer_axes) {
            how += std::string(how.empty() ? "" : ", ") + "for the axes " + service_letters +
                   " (Number_Axes " + std::to_string(st->number_axes()) +
                   ": written by a PLC, or the service's config has fewer axes than this one)";
          }
          if (how.empty()) how = "for tool T" + std::to_string(spindle);
          std::fprintf(stderr, "%s: %zu error%s compiled %s, nothing sent\n", file.c_str(), errors,
                       errors == 1 ? "" : "s", how.c_str());
        }
        return 2;
      }
      if (program.size() == 0) {  // the same text from another point: records all the same
        std::fprintf(stderr, "%s: error: the program has no records compiled from here\n",
                     file.c_str());
        return 2;
      }
      if (!quiet && fewer_axes) {
        std::fprintf(stderr,
                     "%s: compiled for the axes %s: interpolator %d runs with Number_Axes %d "
                     "(written by a PLC, or the service's config has fewer axes than this one)\n",
                     file.c_str(), service_letters.c_str(), ip, st->number_axes());
      }
      if (!quiet && from_point && !resume.given()) {
        std::fprintf(stderr, "%s: compiled from where interpolator %d stands: %s\n", file.c_str(),
                     ip, here_text.c_str());
      }
      if (!quiet && other_tool) {
        std::fprintf(stderr,
                     "%s: compiled for tool T%d, in interpolator %d's spindle since its last "
                     "program (the config's initial_tool is %d)\n",
                     file.c_str(), spindle, ip, config->machine.compiler.initial_tool);
      }
    }
  }
  source_holder.reset();  // compiled for the last time
  note.print(file, intercode);
  // Where the program starts as compiled (a G91 program's moves depend on it): the --start of
  // a later block search, said at the start of the run.
  const std::array<double, kMaxAxes> origin =
      resume.given() && !intercode ? resume_start : program.tables().start_mm;
  if (resume.given() && !resume_program(file, program, resume, here,
                                        config->machine.compiler.default_feed_mm_per_min)) {
    return 2;
  }
  if (single) {
    std::uint64_t stops = 0;
    if (std::string why; !single_block(program, program, stops, why)) {
      std::fprintf(stderr, "%s: error: --single-block: %s\n", file.c_str(), why.c_str());
      return 2;
    }
    std::fprintf(stderr, "%s: single block: a program stop after each of %llu blocks\n",
                 file.c_str(), static_cast<unsigned long long>(stops));
  }
  // What the program stream cannot carry is found before the clear (the sender checks the
  // whole program when it is made): one that found it later left a half-sent program running
  // (a 300-byte M29 text at line 19,970 stopped the stream with the machine moving).
  const std::uint32_t program_id = client::new_program_id();
  client::ProgramSender sender(*hmi, program, ip, program_id);
  if (!sender.error().empty()) {
    std::fprintf(stderr, "%s: error: %s; nothing sent\n", file.c_str(), sender.error().c_str());
    return 2;
  }
  // The time the program takes, simulated while it runs (declared after the program, which it
  // reads: it ends first).
  std::optional<TimeEstimate> estimate;
  double est_rel = 1.0;  // the Rel_Speed it is simulated at
  if (!quiet && !no_estimate) {
    MachineConfig machine = config->machine;
    auto& axes = machine.interpolators[static_cast<std::size_t>(ip)].axes;
    if (fewer_axes) axes.resize(service_letters.size());
    // The service's cycle: times are counted in its cycles (a config's may differ).
    if (st->cycle_time_us() > 0) machine.cycle_time_us = st->cycle_time_us();
    SimulationOptions so;
    so.interpolator = ip;
    const double rel = st->rel_speed();
    so.rel_speed = std::isfinite(rel) ? std::clamp(rel, 0.01, 2.0) : 1.0;
    est_rel = so.rel_speed;
    so.m_ack_s = config->plc.default_m_delay_s;
    for (const auto& [m, delay] : config->plc.m_delay_s) so.m_ack_by_number[m] = delay;
    so.m0_restart_s = 0.0;
    so.start_mm = here;
    so.max_time_s = SimulationOptions::kMaxTimeS;
    if (client::same_machine(*st, machine, ip)) {
      // The smoothing the service applies now: the PLC may have set another than the config's
      // (Command -2 / -1), which the digest does not follow.
      machine.smoothing = client::smoothing_for_simulation(machine.smoothing, *st);
      estimate.emplace(std::move(machine), std::move(so), program);
    } else {
      // Simulated by other limits, the times would be wrong without a sign of it.
      std::fprintf(stderr,
                   "tgm-hmi run: no time estimate (progress by records): the service moves "
                   "interpolator %d by another machine config than %s (axis limits, smoothing or "
                   "buffer size differ)\n",
                   ip, client::config_name(*config).c_str());
    }
  }
  bool estimate_said = false;
  if (st->status() != 0) {
    // A program that did not end (stopped, in an underrun, after an emergency stop) is
    // dropped by the clear: said, with where it stood, since another HMI may still follow it
    // or its sender may have died half-way (the clear dropped it without a word).
    const bool unfinished = st->status() != 3 && st->program_id() != 0;
    const std::uint32_t held = st->program_id();
    const int held_line = st->act_line();
    const std::string held_status(client::status_name(st->status()));
    const client::Reply r = hmi->clear(ip, kFirstRequestTimeout, &g_interrupted);
    if (!r.accepted) {
      std::fprintf(stderr, "tgm-hmi run: clearing interpolator %d: %s\n", ip, client::describe(r).c_str());
      return r.cancelled ? 130 : 1;
    }
    if (unfinished) {
      std::fprintf(stderr,
                   "tgm-hmi run: interpolator %d held program %u, not finished (%s at line %d): "
                   "cleared for this one\n",
                   ip, held, held_status.c_str(), held_line);
    }
  }

  PlotSeries plot_path_points(PlotSeries::Spacing::kDistance, 0.05, kMaxPlotPoints);
  PlotSeries plot_speed_points(PlotSeries::Spacing::kFirst, 0.0, kMaxPlotPoints);
  std::uint64_t first_cycle = 0;
  // Times are the service's cycles at the service's cycle time (this config's may differ).
  const double cycle_s =
      (st->cycle_time_us() > 0 ? st->cycle_time_us() : config->machine.cycle_time_us) * 1e-6;
  if (!plot_path.empty()) {
    hmi->on_setpoints = [&](const msg::Setpoints& s) {
      if (s.interpolator() != ip) return;
      plot_path_points.add({s.position()[0], s.position()[1]});
    };
    hmi->on_state = [&](const msg::InterpolatorState& s) {
      if (s.interpolator() != ip || first_cycle == 0) return;
      plot_speed_points.add(
          {static_cast<double>(s.cycle_counter() - first_cycle) * cycle_s, s.act_speed()});
    };
  }

  const bool tty = ::isatty(1) != 0;
  // Taken once: a terminal that hangs up is no terminal any more for isatty(), and an M0 wait
  // then ran out after the 1 s meant for runs without one.
  const bool stdin_tty = ::isatty(0) != 0;
  bool stdin_closed = false;
  const auto t0 = Clock::now();
  auto last_line_at = t0;
  bool started = false, m0_wait = false, stop_reported = false;
  Clock::time_point m0_since{};
  std::uint32_t m_wait_count = 0;  // m_func_count of the M-function waiting now; 0 = none
  Clock::time_point m_wait_since{};
  std::uint64_t start_cycle = 0;
  std::uint64_t missed_before = 0;  // the service's missed cycles when this run started
  std::uint64_t fresh_after = 0;  // ignore states from before our last start request
  // From the state (the fall-back), and from the events (used when the event topic matched).
  WaitCount state_waits, event_waits;
  auto count_events = [&] {
    {
      const std::lock_guard lock(events_mutex);
      events.swap(events_in);
    }
    for (const MEvent& e : events) {
      if (e.program != program_id || !started || e.cycle <= start_cycle) continue;
      event_waits.see(e.waiting, e.part, e.cycle);
    }
    events.clear();
  };
  std::size_t messages = 0;
  // The source line where the program last stood: a program that is dropped takes its section
  // registers with it (Act_Line 0), and the run says where it was.
  int line_seen = 0;
  std::int32_t part_seen = 0;  // its record (Act_Part, 1-based)
  // The record running (Act_Part), the cycle it was first seen in and Move_Distance then.
  std::int32_t est_part = 0;
  std::uint64_t est_part_since = 0;
  double est_part_mm = 0.0;
  // After the program was dropped: the block search that goes on from the line it stood at
  // (that line again from its start, after an approach).
  const auto say_resume = [&]() {
    if (line_seen <= 0 || part_seen <= 0) return;
    // Which run of the line's records that was, among the records sent.
    std::uint64_t runs = occurrence_at(program, static_cast<std::uint64_t>(part_seen) - 1);
    std::string cmd =
        "tgm-hmi run " + shell_word(file) + " --from-line " + std::to_string(line_seen);
    bool occurrence_known = true;
    if (resume.given()) {
      // The approach and the first records kept are one run of the line resumed at; of
      // another line the runs before the cut are not known here.
      if (line_seen == resume.line) {
        runs += static_cast<std::uint64_t>(std::max(resume.occurrence, 1LL)) - 1;
      } else {
        occurrence_known = false;
      }
    }
    if (occurrence_known && runs > 1) cmd += " --occurrence " + std::to_string(runs);
    if (!intercode && !same_point(origin, {}, kMaxAxes)) {
      cmd += " --start " + point_text(origin, program.tables().axis_letters, ',');
    }
    if (ip != 0) cmd += " --interpolator " + std::to_string(ip);
    if (!args.config_file().path.empty()) cmd += " --config " + shell_word(args.config_file().path);
    std::fprintf(stderr, "tgm-hmi run: to go on from line %d once the path is clear: %s%s\n",
                 line_seen, cmd.c_str(),
                 occurrence_known ? ""
                                  : " (and --occurrence K if the line's records ran more than "
                                    "once before: count from the program's start)");
  };
  int exit_code = 0;
  bool progress_shown = false;
  // Said once; the run goes on if the service comes back.
  client::SilenceWatch silence(3s);
  dds::MalformedWatch malformed;
  // Flushed: what follows goes to standard error, and a terminal's line-buffered standard
  // output held the "\r\033[K" back, so the message was appended to the progress line.
  auto clear_progress = [&] {
    if (tty && progress_shown) {
      std::printf("\r\033[K");
      std::fflush(stdout);
    }
    progress_shown = false;
  };
  // The normal stop that ends the run, repeated until the service answers it. Tried once, a
  // stop during a network outage of a second or more was never written (the service's request
  // reader had gone with the participant lease): the run exited and the program ran on, 767 mm
  // after the Ctrl-C, while the run said it stayed loaded. A second Ctrl-C, or
  // kStopPersistence, gives up, and then the run says plainly that nothing was stopped.
  const auto stop_the_run = [&](const char* why, const std::string& left) {
    g_interrupted = false;  // from here on a Ctrl-C means "give up the stop"
    const auto until = Clock::now() + kStopPersistence;
    client::Reply stop;
    bool said = false;
    while (true) {
      stop = hmi->stop(ip, 3s, &g_interrupted);
      if (!stop.timed_out || stop.cancelled || Clock::now() >= until) break;
      if (!said) {
        std::printf(
            "tgm-hmi run: %s: normal stop: %s; trying again for up to %lld s (Ctrl-C "
            "again gives up)\n",
            why, client::describe(stop).c_str(),
            static_cast<long long>(
                std::chrono::duration_cast<std::chrono::seconds>(kStopPersistence).count()));
        std::fflush(stdout);
        said = true;
      }
    }
    if (!stop.timed_out) {
      std::printf("tgm-hmi run: %s: normal stop: %s; %s\n", why, client::describe(stop).c_str(),
                  left.c_str());
      return;
    }
    const msg::InterpolatorState* last = hmi->state(ip);
    std::printf(
        "tgm-hmi run: %s: normal stop: %s; the interpolator was NOT stopped: it may still be "
        "executing program %u (last seen at Status %d, line %d); stop it with `tgm-hmi command "
        "stop --interpolator %d` once tgm-service answers, or at the machine\n",
        why, client::describe(stop).c_str(), program_id,
        last ? static_cast<int>(last->status()) : 0, last ? static_cast<int>(last->act_line()) : 0,
        ip);
  };
  std::printf(
      "tgm-hmi run: %s: %zu record%s for interpolator %d (program %u), DDS domain %d, "
      "program start %s\n",
      file.c_str(), static_cast<std::size_t>(program.size()), program.size() == 1 ? "" : "s", ip,
      program_id, config->dds.domain_id, point_text(origin, program.tables().axis_letters).c_str());
  std::fflush(stdout);

  bool service_stopping = false;  // it announced its shutdown
  Clock::time_point starving_since{};  // the stream waits with the service's buffer empty
  Clock::time_point rejoined_at{};     // the last Client::rejoin ({}: none yet)
  bool rewrite_after_rejoin = false;
  while (true) {
    hmi->poll(2ms);
    if (!sender.pump()) {
      clear_progress();
      std::fprintf(stderr, "tgm-hmi run: %s\n", sender.error().c_str());
      exit_code = 1;
      break;
    }
    st = hmi->state(ip);
    if (st->service_instance() != instance) {
      clear_progress();
      std::fprintf(stderr,
                   "tgm-hmi run: tgm-service restarted during the run (instance %016llx, now "
                   "%016llx): the program is gone from its buffer; run it again from a known "
                   "position\n",
                   static_cast<unsigned long long>(instance),
                   static_cast<unsigned long long>(st->service_instance()));
      exit_code = 1;
      break;
    }
    const auto change = silence.update(hmi->state_samples(ip), Clock::now());
    if (change == client::SilenceWatch::Change::kSilent && service_stopping) {
      clear_progress();
      const msg::InterpolatorState* last = hmi->state(ip);
      std::fprintf(stderr,
                   "tgm-hmi run: tgm-service shut down during the run (it said so, then went "
                   "silent; last seen at Status %d, line %d): the program is gone with it; run it "
                   "again from a known position\n",
                   last ? static_cast<int>(last->status()) : 0,
                   last ? static_cast<int>(last->act_line()) : 0);
      exit_code = 1;
      break;
    }
    if (change == client::SilenceWatch::Change::kSilent) {
      clear_progress();
      std::printf(
          "tgm-hmi run: no state from tgm-service for 3 s (stopped, or the network is "
          "down): waiting; Ctrl-C stops the run\n");
      std::fflush(stdout);
    } else if (change == client::SilenceWatch::Change::kBack) {
      clear_progress();
      std::printf("tgm-hmi run: tgm-service is back\n");
    }
    if (const std::string bad = malformed.update(config->dds.domain_id, Clock::now());
        !bad.empty()) {
      clear_progress();
      std::printf("tgm-hmi run: %s\n", bad.c_str());
    }
    // A link broken one way (Client::rejoin): the service takes none of the records in flight
    // although its buffer ran empty, or nothing comes from it at all. Seen after this process
    // stood still for seconds (SIGSTOP, a stalled PC): the service had dropped it, Fast DDS
    // never matched it again, and the program stood half-executed in an underrun while the
    // run waited for good (3 of 5 freezes, live review of session 80). A new participant is
    // discovered afresh; the records in flight are written again, which the service takes
    // from where it stands. At most every 10 s; after a silence the rewrite waits for the
    // first state that shows the underrun.
    {
      const auto now = Clock::now();
      const bool starving = st->program_id() == program_id &&
                            st->status() == static_cast<int>(InterpolatorStatus::kUnderrun) &&
                            st->buffered_segments() == 0 && sender.written() > sender.confirmed();
      if (!starving) {
        starving_since = {};
      } else if (starving_since == Clock::time_point{}) {
        starving_since = now;
      }
      if (starving && rewrite_after_rejoin) {
        sender.rewrite();
        rewrite_after_rejoin = false;
        starving_since = {};
      }
      const bool stalled =
          starving_since != Clock::time_point{} && now - starving_since >= kStallBeforeRejoin;
      // Once per silence: a service that is down stays silent, and a new participant every
      // 10 s would only fill the output.
      const bool may_rejoin = now - rejoined_at >= kRejoinEvery;
      const bool silent = may_rejoin && silence.lasted(kSilenceBeforeRejoin, now);
      if (may_rejoin && (stalled || silent)) {
        // A rejoin for a stall within a silence is that silence's rejoin too.
        if (stalled) silence.lasted(std::chrono::seconds(0), now);
        clear_progress();
        std::printf(
            "tgm-hmi run: %s: joining DDS again as a new participant (the link may have broken "
            "one way, as after this process stood still for seconds)\n",
            stalled ? "tgm-service has taken none of the records in flight although its buffer "
                      "ran empty"
                    : "no state from tgm-service for 5 s");
        std::fflush(stdout);
        if (const std::string why = hmi->rejoin(); !why.empty()) {
          std::fprintf(stderr,
                       "tgm-hmi run: warning: could not join DDS again (%s): going on as before\n",
                       why.c_str());
        }
        rejoined_at = now;
        starving_since = {};
        if (stalled) {
          sender.rewrite();
        } else {
          rewrite_after_rejoin = true;
        }
      }
    }
    count_events();
    for (const msg::Message& m : hmi->take_messages()) {
      if (m.interpolator() != ip) continue;
      // After a rejoin, the service's words on this run as a sender: they concern its former
      // participant (lost, then ended at the rejoin), whose stream goes on from the new one
      // under the same client name.
      if (rejoined_at != Clock::time_point{} &&
          std::string_view(m.text().c_str()).find("its sender '" + hmi->name() + "'") !=
              std::string_view::npos)
        continue;
      // Another program's messages (an earlier run's M29 texts and warnings) are not shown.
      if (m.program_id() != 0 ? m.program_id() != program_id : m.cycle() < run_from_cycle) continue;
      clear_progress();
      const bool err = m.severity() == msg::SEVERITY_ERROR;
      // A message about the program as a whole (a refused chunk) has no line: "(line 0)" was
      // printed for it.
      const std::string where =
          m.source_line() > 0 ? " (line " + std::to_string(m.source_line()) + ")" : "";
      // An informational message without a line is the service's own (a PLC that is back),
      // not an M29 text of the program.
      // The service's announcement that it shuts down (Engine::wind_down): its silence after
      // it ends the run instead of a wait without end (session 75).
      if (m.severity() == msg::SEVERITY_WARNING &&
          std::string_view(m.text().c_str()).rfind("tgm-service is stopping", 0) == 0)
        service_stopping = true;
      std::printf("%s%s: %s\n",
                  err                                     ? "ERROR"
                  : m.severity() == msg::SEVERITY_WARNING ? "warning"
                  : m.source_line() > 0                   ? "M29"
                                                          : "note",
                  where.c_str(), printable(m.text().c_str()).c_str());
      ++messages;
      if (err && m.program_id() == program_id) exit_code = 1;
    }
    if (exit_code != 0) break;
    // What a run that ends here leaves on the interpolator: the program stays loaded, and a
    // part of it when the stream was cut (a start from another HMI ran that part and stood in
    // underrun for good, with nothing said).
    const auto left_loaded = [&] {
      if (sender.all_confirmed())
        return std::string("the program stays loaded: `tgm-hmi command start` resumes it");
      // Chunks written and not yet confirmed still arrive after the stop (the buffer held up
      // to 128 records more than the count said: review of session 77).
      std::string more;
      if (sender.written() > sender.confirmed())
        more =
            " (up to " + std::to_string(sender.written()) + " once the chunks on their way arrive)";
      return "only " + std::to_string(sender.confirmed()) + " of its " +
             std::to_string(sender.total()) + " records reached the buffer" + more +
             " and stay loaded: a start runs only those and then stands in underrun; `tgm-hmi "
             "command clear` drops them";
    };
    if (g_interrupted) {
      clear_progress();
      stop_the_run("interrupted", left_loaded());
      exit_code = 130;
      break;
    }
    if (timeout_s > 0 && Clock::now() - t0 > std::chrono::duration<double>(timeout_s)) {
      clear_progress();
      char why[64];
      std::snprintf(why, sizeof why, "timeout after %.1f s", timeout_s);
      stop_the_run(why, left_loaded());
      exit_code = 1;
      break;
    }
    const bool ours = st->program_id() == program_id;
    // Start once everything is in the buffer, or once the buffer is half full.
    if (!started && ours &&
        (sender.all_confirmed() || sender.confirmed() >= static_cast<std::uint64_t>(st->buffer_size() / 2) ||
         st->free_buffer_slots() == 0)) {
      const client::Reply r = hmi->start(ip, kFirstRequestTimeout, &g_interrupted);
      if (r.cancelled) {
        // A start that was sent may still be carried out: stop as at any Ctrl-C.
        clear_progress();
        stop_the_run(("interrupted: start: " + client::describe(r)).c_str(), left_loaded());
        exit_code = 130;
        break;
      }
      if (!r.accepted) {
        std::fprintf(stderr, "tgm-hmi run: start: %s\n", client::describe(r).c_str());
        exit_code = 1;
        break;
      }
      started = true;
      start_cycle = r.cycle;
      missed_before = st->missed_cycles();
      fresh_after = r.cycle;
      first_cycle = r.cycle;
      continue;
    }
    if (!started || st->cycle_counter() <= fresh_after) continue;
    if (!ours) {
      // A clear (by another HMI, after a stop) sets the state's program to 0; another program
      // can only be loaded after that. Either way this one is gone: waiting on for it hung.
      clear_progress();
      if (st->program_id() == 0) {
        std::fprintf(stderr, "tgm-hmi run: the program was cleared by someone else at line %d\n",
                     line_seen);
      } else {
        std::fprintf(stderr, "tgm-hmi run: the program was replaced by program %u\n",
                     static_cast<unsigned>(st->program_id()));
      }
      exit_code = 1;
      break;
    }
    const bool m_waiting = run_flag_waits_for_m(static_cast<std::uint32_t>(st->run_flag()));
    state_waits.see(m_waiting, st->act_part(), st->cycle_counter());
    // How long this M-function has waited, for the operator: the PLC acknowledges it.
    if (!m_waiting) {
      m_wait_count = 0;
    } else if (st->m_func_count() != m_wait_count) {
      m_wait_count = st->m_func_count();
      m_wait_since = Clock::now();
    }
    const auto status = static_cast<InterpolatorStatus>(st->status());
    // (A stop off the trajectory clears Act_Line with the program: the line it stopped at is
    // the last one seen.)
    if (status != InterpolatorStatus::kEmpty && st->act_line() != 0) {
      line_seen = st->act_line();
      part_seen = st->act_part();
    }
    // Since when the record runs, for the time estimate.
    if (st->act_part() != est_part) {
      est_part = st->act_part();
      est_part_since = st->cycle_counter();
      est_part_mm = st->move_distance();
    }
    if (status == InterpolatorStatus::kEnded && sender.all_confirmed()) break;
    if (status == InterpolatorStatus::kEmpty) {
      clear_progress();
      // Command 9 drops the program and leaves the state's program id: off the trajectory.
      if (st->off_trajectory()) {
        std::fprintf(stderr,
                     "tgm-hmi run: normal stop off the trajectory (Command 9) at line %d: the "
                     "program was dropped\n",
                     line_seen);
      } else {
        // The state still names this program: a position set (Command 2048/2049, the PLC's)
        // dropped it; a clear would have set the state's program to 0 (handled above).
        std::fprintf(stderr,
                     "tgm-hmi run: a position set (Command 2048/2049, by the PLC) at line %d "
                     "dropped the program\n",
                     line_seen);
      }
      say_resume();
      exit_code = 1;
      break;
    }
    // An emergency stop on the trajectory holds the program (start resumes it): the run goes
    // on showing its progress, "emergency stopped" (the display froze for the whole hold).
    const bool estop_hold = status == InterpolatorStatus::kEmergencyRamp ||
                            status == InterpolatorStatus::kEmergencyStopped;
    if (status == InterpolatorStatus::kEmergencyStopped) {
      // The Command register is back at 0 once the ramp has ended: the trajectory tells 4 from 5.
      if (st->off_trajectory()) {
        clear_progress();
        if (stop_reported) {
          // Stopped on the trajectory (Command 4) first: Command 9 (or 5) then drops the
          // program and the status stays 7. It was named Command 5 whichever it was.
          std::fprintf(stderr,
                       "tgm-hmi run: after the emergency stop, a stop off the trajectory (Command "
                       "9 or 5) at line %d dropped the program\n",
                       line_seen);
        } else {
          std::fprintf(stderr,
                       "tgm-hmi run: emergency stop (Command 5), off trajectory at line %d: the "
                       "program was dropped\n",
                       line_seen);
        }
        say_resume();
        exit_code = 1;
        break;
      }
      // Command 4 stops on the trajectory and start resumes it, so the run follows on and keeps
      // streaming, as after a normal stop. It used to end here: a program longer than the buffer
      // then resumed into an underrun, its records beyond the buffer never sent.
      if (!stop_reported) {
        stop_reported = true;
        clear_progress();
        std::printf(
            "emergency stop (Command 4) at line %d, on the trajectory; `tgm-hmi command start` "
            "resumes, Ctrl-C ends the run\n",
            st->act_line());
        std::fflush(stdout);
      }
    }
    if (status == InterpolatorStatus::kUnderrun && st->buffered_segments() > 0) {
      fresh_after = hmi->start(ip).cycle;  // the buffer ran empty and got more: go on
      continue;
    }
    if (estop_hold) {
      // (stop_reported stays: the hold was said once)
    } else if (status == InterpolatorStatus::kReady) {
      // Standing at an M0 (program_stop), not stopped by a stop command: start continues it.
      const bool at_m0 = st->program_stop();
      if (at_m0) {
        if (!m0_wait) {
          m0_wait = true;
          m0_since = Clock::now();
          clear_progress();
          char in[64];
          std::snprintf(in, sizeof in, "continuing in %.0f s", m0_s);
          std::printf(single ? "stopped after line %d (single block): %s\n"
                             : "M0 program stop at line %d: %s\n",
                      st->act_line(),
                      m0_s > 10.0               ? in
                      : m0_s >= 0 || !stdin_tty ? "continuing shortly"
                      : stdin_closed            ? "`tgm-hmi command start` continues"
                                                : "press Enter to continue");
          std::fflush(stdout);
        }
        const double wait = m0_s >= 0 ? m0_s : stdin_tty ? -1.0 : 1.0;
        bool go = false;
        if (wait >= 0) {
          go = Clock::now() - m0_since >= std::chrono::duration<double>(wait);
        } else if (!stdin_closed) {
          const StdinLine line = stdin_line();
          go = line == StdinLine::kLine;
          if (line == StdinLine::kClosed) {
            stdin_closed = true;
            clear_progress();
            std::printf(
                "tgm-hmi run: the terminal's input ended (Ctrl-D, or the terminal closed): the "
                "M0 program stop at line %d waits for `tgm-hmi command start`\n",
                st->act_line());
            std::fflush(stdout);
          }
        }
        if (go) {
          m0_wait = false;
          fresh_after = hmi->start(ip).cycle;
        }
      } else {
        m0_wait = false;
        if (!stop_reported) {
          stop_reported = true;
          clear_progress();
          std::printf("stopped by a stop command at line %d; `tgm-hmi command start` resumes\n",
                      st->act_line());
        }
      }
    } else {
      stop_reported = false;
      // Resumed by another HMI's start: the next M0 is a new wait, with its own time and words
      // (the next one went on at once after a timed wait, or without a word on a terminal).
      m0_wait = false;
    }
    if (estimate && !estimate_said) {
      if (const std::string why = estimate->failure(); !why.empty()) {
        clear_progress();
        std::fprintf(stderr, "tgm-hmi run: no time estimate (progress by records): %s\n",
                     why.c_str());
        estimate_said = true;
      }
    }
    // Progress.
    const auto now = Clock::now();
    // While the service is silent the registers are stale: a log gets no more lines of them
    // (it got the same "running" line every interval for as long as the service was gone), a
    // terminal says for how long nothing came in place of the status.
    const bool stale = silence.silent();
    if (!quiet && !(stale && !tty) &&
        (tty ? now - last_line_at >= 100ms
             : now - last_line_at >= std::chrono::duration<double>(interval_s))) {
      last_line_at = now;
      double pct = 100.0 * static_cast<double>(std::max(st->act_part(), 0)) /
                   static_cast<double>(program.size());
      // By time once the estimate is there: what the records before this one take, and as
      // much of this one's own as it has run. The time left at the Rel_Speed now: the moves
      // take longer at a lower override (not exactly, where a limit, not the feed, sets the
      // speed), the waits (M-functions, dwells) as long; none while it is below 1 %.
      std::string left;
      if (const ProgramTimes* times = estimate ? estimate->times() : nullptr) {
        const double in_record =
            static_cast<double>(st->cycle_counter() -
                                std::min(est_part_since, st->cycle_counter())) *
            cycle_s;
        const double in_mm = st->move_distance() - est_part_mm;
        const double elapsed = times->elapsed_s(st->act_part(), in_record, in_mm);
        if (times->total_s > 0.0) pct = 100.0 * elapsed / times->total_s;
        const double rel = st->rel_speed();
        left =
            rel >= 0.01
                ? " " + clock_text(times->left_s(st->act_part(), in_record, in_mm, est_rel / rel)) +
                      " left"
                : " --:-- left";
      }
      char bar[21];
      const int filled = std::clamp(static_cast<int>(pct / 5.0), 0, 20);
      for (int k = 0; k < 20; ++k) bar[k] = k < filled ? '#' : '.';
      bar[20] = '\0';
      std::string dro;
      for (int a = 0; a < std::min<int>(st->number_axes(), 3); ++a) {
        char b[40];
        std::snprintf(b, sizeof b, " %c%.3f", letters.size() > static_cast<std::size_t>(a) ? letters[static_cast<std::size_t>(a)] : '?',
                      st->position()[static_cast<std::size_t>(a)]);
        dro += b;
      }
      std::string wait;
      if (m_waiting) {
        wait = " waiting for M" + std::to_string(st->m_func());
        const double waited = std::chrono::duration<double>(now - m_wait_since).count();
        if (waited >= kLongMWait)
          wait += " for " + std::to_string(static_cast<int>(waited)) + " s (is tgm-plc running?)";
      }
      std::string shown(client::status_name(st->status()));
      if (stale) {
        shown = "no state for " + std::to_string(silence.seconds_since_last(now)) + " s";
        wait.clear();
      }
      std::printf("%s[%s] %5.1f%% line %d/%d%s%s F%.0f %s%s%s", tty ? "\r\033[K" : "", bar, pct,
                  st->act_line(), last_line, left.c_str(), dro.c_str(), st->act_speed(),
                  shown.c_str(), wait.c_str(), tty ? "" : "\n");
      std::fflush(stdout);
      progress_shown = true;
    }
  }
  clear_progress();
  for (int k = 0; k < 50 && !plot_path.empty(); ++k) hmi->poll(1ms);  // last samples for the plot
  // The event that ends the last wait was written before the end state; it may still be on
  // its way (the state and event topics are separate readers).
  for (int k = 0; k < 250 && exit_code == 0 && events_matched && event_waits.from != 0; ++k) {
    hmi->poll(2ms);
    count_events();
  }
  const WaitCount& waits = events_matched ? event_waits : state_waits;
  st = hmi->state(ip);
  const double program_s = static_cast<double>(st->cycle_counter() - start_cycle) * cycle_s;
  if (exit_code == 0) {
    std::string dro;
    for (int a = 0; a < st->number_axes(); ++a) {
      char b[40];
      std::snprintf(b, sizeof b, " %c%.4f", letters.size() > static_cast<std::size_t>(a) ? letters[static_cast<std::size_t>(a)] : '?',
                    st->position()[static_cast<std::size_t>(a)]);
      dro += b;
    }
    std::string estimated;
    if (const ProgramTimes* times = estimate ? estimate->times() : nullptr) {
      char b[64];
      std::snprintf(b, sizeof b, ", estimated %.3f s", times->total_s);
      estimated = b;
    }
    std::printf(
        "done: %llu record%s, %d line%s in %.3f s of program time (%llu cycles%s; %.3f s by the "
        "clock), distance %.3f mm, "
        "%llu M-function wait%s (%.3f s)%s, %zu message%s\n"
        "  end position%s\n"
        "  service cycle lateness since it started: max %.1f us, p99.9 %.1f us, missed cycles "
        "%llu (%llu during this run)\n",
        static_cast<unsigned long long>(sender.total()), sender.total() == 1 ? "" : "s", last_line,
        last_line == 1 ? "" : "s", program_s,
        static_cast<unsigned long long>(st->cycle_counter() - start_cycle), estimated.c_str(),
        std::chrono::duration<double>(Clock::now() - t0).count(), st->move_distance(),
        static_cast<unsigned long long>(waits.waits), waits.waits == 1 ? "" : "s",
        static_cast<double>(waits.cycles) * cycle_s,
        !events_matched          ? " seen in the state"
        : hmi->events_lost() > 0 ? " (events lost: the count may be short)"
                                 : "",
        messages, messages == 1 ? "" : "s", dro.c_str(),
        static_cast<double>(st->lateness_max_ns()) / 1e3,
        static_cast<double>(st->lateness_p999_ns()) / 1e3,
        static_cast<unsigned long long>(st->missed_cycles()),
        static_cast<unsigned long long>(st->missed_cycles() -
                                        std::min(missed_before, st->missed_cycles())));
  }
  if (!plot_path.empty()) {
    const PlotData plot{plot_path_points.points(), plot_speed_points.points()};
    if (!write_svg(plot_file, plot, letters, error)) {
      std::fprintf(stderr, "%s: error: %s\n", plot_path.c_str(), error.c_str());
      if (exit_code == 0) exit_code = 1;
    } else {
      std::printf("plot: %s (%zu path points, %zu speed samples)\n", plot_path.c_str(), plot.path.size(),
                  plot.speed.size());
    }
  }
  std::fflush(stdout);
  return exit_code;
}

}  // namespace tgm::hmi
