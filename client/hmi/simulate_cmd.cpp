// tgm-hmi simulate: runs a G-code program through the interpolator core offline (no DDS, as fast
// as the machine allows), writes the registers per cycle as CSV and prints a summary.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "cli_common.hpp"
#include "commands.hpp"
#include "fixed_text.hpp"
#include "tgm/gcode.hpp"
#include "tgm/simulation.hpp"
#include "tgm/smoothing.hpp"

namespace tgm::hmi {

namespace {

constexpr const char* kUsage =
    "usage: tgm-hmi simulate FILE [--config YAML] [--interpolator N] [--csv OUT] [--csv-every N]\n"
    "                             [--rel-speed R] [--check-limits] [--limit-share F] [--m-ack S]\n"
    "                             [--blocks OUT] [--spline POINTS,JERK] [--iir P,Q,F,MASK]\n"
    "                             [--lookahead OUT] [--stop-at T[:CODE],...] [--restart-after S]\n"
    "                             [--max-time S]"
    " [--start X..,Y..] [--progress-interval S] [--quiet]\n"
    "                             [--block-delete run|skip]\n"
    "                             [--from-line N [--occurrence K] [--approach-feed F]\n"
    "                              [--here X..,Y..]]\n"
    "\n"
    "Compiles FILE (G-code, or intercode written by `tgm-hmi compile --out`, *.tgmi or known by\n"
    "its first bytes; - reads standard input) and runs it through interpolator N (default 0)\n"
    "offline, cycle by cycle, acknowledging every M-function like the PLC emulator would\n"
    "(plc.default_m_delay_s and plc.m_delay_s of the config, or --m-ack S for all) and\n"
    "restarting after M0 at once.\n"
    "  --csv OUT        one row per cycle: time_s, line, act_part, status, run_flag, m_func,\n"
    "                   act_speed_mm_min, move_distance_mm, orig_<axis> (Orig_Position),\n"
    "                   pos_<axis> (Position, after spline / IIR), inc_<axis> (PositionInc),\n"
    "                   backlash_<axis> (Backlash [inc]), speed_<axis> (after smoothing),\n"
    "                   limit_factor\n"
    "  --csv-every N    only every N-th cycle (1..1000000, default 1) in the CSV, plus each\n"
    "                   cycle where status, run_flag or m_func changes and the last one\n"
    "  --spline POINTS,JERK  Command -2 before the start: points 50..500 (0 = off), jerk limit\n"
    "                   [mm/s^3] (integers, as Command_Parameter[0..1])\n"
    "  --iir P,Q,F,MASK Command -1 before the start: p, q, f x 1e6 (f in ms) and the axis bit\n"
    "                   mask (integers, as Command_Parameter[0..3]), e.g. "
    "2000000,1000000,6000000,7\n"
    "  --lookahead OUT  JSON lines: the LookAheadBuffer each time it shifts (cycle, time_s,\n"
    "                   act_part and the 8 entries; kNotSet values as null)\n"
    "  --blocks OUT     one row per executed motion block: line, length, programmed and peak\n"
    "                   speed, duration and the factor that limited its speed\n"
    "                   (OUT of --csv, --blocks or --lookahead may be - for standard output;\n"
    "                   the summary then goes to standard error)\n"
    "  --start X20,Y5   where the machine stands when the program starts [mm] (default:\n"
    "                   zero): the program is compiled from there, as `tgm-hmi run` compiles\n"
    "                   from where the interpolator stands (axes not named: 0); a .tgmi\n"
    "                   file starts where it was compiled from (tgm-hmi compile --start)\n"
    "  --block-delete W lines that start with '/' (optional blocks): run (the block delete\n"
    "                   switch off) or skip (on); default: the config's compiler.block_delete,\n"
    "                   error unless set (such a line is refused)\n"
    "  --rel-speed R    feed override 0.01..2 (default 1)\n"
    "  --check-limits   differentiate Orig_Position per cycle and fail on any per-axis velocity,\n"
    "                   acceleration, jerk or corner-step excess, on corner steps that add\n"
    "                   up over 10 ms beyond the acceleration limit (mean_acceleration), and on\n"
    "                   acceleration steps from a change of curvature at a junction beyond\n"
    "                   corner_acceleration_tolerance_mm_s2 (corner_acceleration; listed with\n"
    "                   cycle and line)\n"
    "  --limit-share F  with --check-limits (implied): check against F (0..1] of each limit\n"
    "                   (the motion is unchanged), e.g. 0.8 lists where the program uses more\n"
    "                   than 80 % of one\n"
    "  --m-ack S        time the emulated PLC takes per normal M-function [s]\n"
    "  --stop-at T[:CODE],...  stops at program times T [s]: CODE 8 normal stop (default) or 4\n"
    "                   emergency stop, both on the trajectory (a feed hold, an emergency "
    "button);\n"
    "                   the emulated operator restarts once the motion stands\n"
    "  --restart-after S  with --stop-at: seconds from the standstill after a stop to the\n"
    "                   restart (default 0.5)\n"
    "  --max-time S     give up after S seconds of program time (default 86400, up to 1e9)\n"
    "  --progress-interval S  when standard error is not a terminal, a progress line there\n"
    "                   every S seconds (default 10); on a terminal the line is redrawn\n"
    "  --quiet          no progress display\n" TGM_HMI_RESUME_USAGE
    "  --here X5,Y5     with --from-line: where the machine stands [mm] (default: where the\n"
    "                   program starts, --start)\n"
    "\n"
    "The run ends when every axis, delayed or filtered, stands where the program ends.\n"
    "Prints program time, distance, per-axis peaks against the limits, violations and the time\n"
    "spent per limit factor, with its share of the moving time. Ctrl-C (SIGINT) or SIGTERM ends\n"
    "the run where it is: the output files hold every cycle up to there, the summary says so,\n"
    "exit code 128 + the signal.\n"
    "Exit code otherwise: 0 finished, 1 did not finish or limits were exceeded, 2 bad input\n"
    "(usage, config, G-code errors as FILE:LINE:COL: error: reason).\n";

volatile std::sig_atomic_t g_signal = 0;
extern "C" void take_signal(int sig) { g_signal = sig; }

// SIGINT / SIGTERM only set a flag while the run is on (the run loop asks for it every few
// milliseconds); the previous handlers come back afterwards.
class SignalFlag {
 public:
  SignalFlag() {
    struct sigaction sa {};
    sa.sa_handler = take_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~SignalFlag() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  SignalFlag(const SignalFlag&) = delete;
  SignalFlag& operator=(const SignalFlag&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

struct CloseFile {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, CloseFile>;

// CSV text formatted exactly as printf's %.Nf and %d would (fixed_text.hpp for the decimals,
// std::to_chars for the integers) at a fraction of the cost, and written in large pieces: the
// CSV of a long program has millions of rows. printf took 2 us of every row's 2.8 us; then
// std::to_chars(fixed, N) a third of a whole run's time (session 50).
class CsvWriter {
 public:
  explicit CsvWriter(std::FILE* f) : f_(f) {}
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;
  ~CsvWriter() { flush(); }

  void fixed(double v, int precision) {
    room();
    p_ = fixed_chars(p_, buf_.data() + buf_.size(), v, precision);
  }
  void integer(long long v) {
    room();
    p_ = std::to_chars(p_, buf_.data() + buf_.size(), v).ptr;
  }
  void text(const char* t) {
    for (; *t != '\0'; ++t) put(*t);
  }
  //! The next column of a row: the separator, then the value.
  void col(double v, int precision) {
    put(',');
    fixed(v, precision);
  }
  void col(long long v) {
    put(',');
    integer(v);
  }
  void put(char c) {
    room();
    *p_++ = c;
  }
  //! Writes what is buffered (also done when full and at destruction).
  void flush() {
    if (p_ != buf_.data()) std::fwrite(buf_.data(), 1, static_cast<std::size_t>(p_ - buf_.data()), f_);
    p_ = buf_.data();
  }

 private:
  // The longest field, a double of 1e308 in %.9f, takes 320 characters.
  void room() {
    if (buf_.data() + buf_.size() - p_ < 400) flush();
  }
  std::FILE* f_;
  std::array<char, 1 << 16> buf_{};
  char* p_ = buf_.data();
};

// "-" is standard output (a copy of its descriptor, so that closing the file leaves it open).
// Opened before the run: a path that cannot be written is bad input (exit code 2), said with
// its flag, as tgm-service and tgm-plc say theirs.
File open_out(const std::string& path, std::string& why) {
  if (path == "-") {
    std::fflush(stdout);
    const int fd = ::dup(1);
    File f(fd >= 0 ? ::fdopen(fd, "w") : nullptr);
    if (!f) {
      why = std::string("cannot write standard output: ") + std::strerror(errno);
      if (fd >= 0) ::close(fd);
    }
    return f;
  }
  File f(std::fopen(path.c_str(), "w"));
  if (!f) {
    why = errno == EISDIR ? std::string("is a directory")
                          : std::string("cannot create: ") + std::strerror(errno);
  }
  return f;
}

}  // namespace

int run_simulate(int argc, char** argv) {
  Args args(argc, argv, "simulate", kUsage);
  std::string file, csv_path, blocks_path, spline_text, iir_text, la_path, stop_text, start_text,
      here_text;
  ResumeFlags resume;
  bool check_limits = false, quiet = false;
  double rel = 1.0, m_ack = -1.0, interval_s = 10.0, restart_s = -1.0;  // restart: -1 = not given
  double max_time_s = SimulationOptions{}.max_time_s;
  double share = 0.0;       // 0: --limit-share not given (the full limits, checker as asked)
  long long csv_every = 0;  // 0: not given (every cycle)
  while (args.more()) {
    if (args.flag("--csv", csv_path)) continue;
    if (args.whole_flag("--csv-every", 1, 1000000, csv_every)) continue;
    if (args.flag("--blocks", blocks_path)) continue;
    if (args.number_flag("--rel-speed", rel, "0.01..2",
                         [](double v) { return v >= 0.01 && v <= 2.0; })) {
      continue;
    }
    if (args.number_flag("--m-ack", m_ack, "seconds 0..3600",
                         [](double v) { return v >= 0.0 && v <= 3600.0; })) {
      continue;
    }
    if (args.flag("--spline", spline_text)) continue;
    if (args.flag("--iir", iir_text)) continue;
    if (args.flag("--lookahead", la_path)) continue;
    if (progress_interval_flag(args, interval_s)) continue;
    if (args.number_flag("--limit-share", share, "a number in (0, 1]", LimitChecker::valid_share)) {
      continue;
    }
    if (args.flag("--stop-at", stop_text)) continue;
    if (args.flag("--start", start_text)) continue;
    if (args.flag("--here", here_text)) continue;
    if (resume.read(args)) continue;
    if (args.number_flag("--restart-after", restart_s, "seconds 0..3600",
                         [](double v) { return v >= 0.0 && v <= 3600.0; })) {
      continue;
    }
    if (args.number_flag("--max-time", max_time_s, "seconds of program time, > 0 and at most 1e9",
                         [](double v) { return v > 0.0 && v <= SimulationOptions::kMaxTimeS; })) {
      continue;
    }
    if (args.boolean("--check-limits", check_limits)) continue;
    if (args.boolean("--quiet", quiet)) continue;
    if (args.common()) continue;
    if (args.compile_flag()) continue;
    if (args.positional(file)) continue;
    return args.fail();
  }
  if (args.help()) return 0;
  if (args.failed()) return 2;
  if (file.empty()) return args.usage_error("a G-code FILE is required");
  if (csv_every > 0 && csv_path.empty()) return args.usage_error("--csv-every needs --csv OUT");
  if (!resume.check(args)) return 2;
  if (!here_text.empty() && !resume.given()) return args.usage_error("--here needs --from-line N");
  if (restart_s >= 0.0 && stop_text.empty()) {
    return args.usage_error(
        "--restart-after needs --stop-at T (it times the restart after each stop)");
  }
  if (restart_s < 0.0) restart_s = 0.5;
  if (!args.distinct_files(
          {{"FILE", file}, args.config_file()},
          {{"--csv", csv_path}, {"--lookahead", la_path}, {"--blocks", blocks_path}})) {
    return 2;
  }
  if (csv_every == 0) csv_every = 1;
  if (share > 0.0) {
    check_limits = true;
  } else {
    share = 1.0;
  }
  // --stop-at T[:CODE],...: each item a time [s] and optionally :8 or :4.
  std::vector<std::pair<double, std::int32_t>> stops;
  for (const std::string& item :
       stop_text.empty() ? std::vector<std::string>{} : comma_items(stop_text)) {
    const std::size_t colon = item.find(':');
    double t = 0.0;
    const std::string code_text = colon == std::string::npos ? "8" : item.substr(colon + 1);
    if (!parse_finite(item.substr(0, colon), t) || t < 0.0 ||
        (code_text != "8" && code_text != "4")) {
      return args.usage_error(
          "--stop-at takes TIME[:8|:4] items (seconds >= 0, comma-separated), not '" + item + "'");
    }
    stops.emplace_back(t, code_text == "8" ? 8 : 4);
  }
  // Integer lists for the Command_Parameter registers.
  auto int_list = [](const std::string& text, std::size_t count,
                     std::array<std::int32_t, kCommandParameters>& out) {
    const std::vector<std::string> items = comma_items(text);
    if (items.size() != count) return false;
    for (std::size_t k = 0; k < count; ++k) {
      long long v = 0;
      if (!parse_integer(items[k], INT32_MIN, INT32_MAX, v)) return false;
      out[k] = static_cast<std::int32_t>(v);
    }
    return true;
  };
  std::vector<std::pair<std::int32_t, std::array<std::int32_t, kCommandParameters>>> commands;
  if (!spline_text.empty()) {
    std::array<std::int32_t, kCommandParameters> p{};
    if (!int_list(spline_text, 2, p)) {
      return args.usage_error("--spline takes POINTS,JERK (integers), not '" + spline_text + "'");
    }
    commands.push_back({-2, p});
  }
  if (!iir_text.empty()) {
    std::array<std::int32_t, kCommandParameters> p{};
    if (!int_list(iir_text, 4, p)) {
      return args.usage_error("--iir takes P,Q,F,MASK (integers, P Q F x 1e6), not '" + iir_text + "'");
    }
    commands.push_back({-1, p});
  }
  const auto app = args.load_app();
  if (!app) return 2;
  const MachineConfig& machine = app->machine;
  const int ip_index = args.interpolator();

  std::array<double, kMaxAxes> start{};
  if (std::string why;
      !start_text.empty() && !parse_start(start_text, machine.axis_letters(ip_index), start, why)) {
    return args.usage_error("--start: " + why);
  }
  // Held as intercode: a program of millions of lines took 152 bytes a record as Segments.
  PackedProgram program;
  bool intercode = false;
  ProgramNotes note(machine.tools);
  if (!load_packed(file, machine, ip_index, program, &start, &intercode,
                   [&note](const Segment& s) { note.observe(s); }))
    return 2;
  // As `run` says it: a summary of nothing ("NOT finished: empty program", exit 1) looked like
  // a run that went wrong.
  if (program.size() == 0) {
    std::fprintf(stderr, "%s: error: the program has no records (no move, dwell or M-function)\n", file.c_str());
    return 2;
  }
  if (!args.compile_flags_fit(file, intercode)) return 2;
  // Intercode runs from the point it was compiled from, as `tgm-hmi run` runs it.
  if (intercode) {
    if (!start_text.empty() &&
        !same_point(start, program.tables().start_mm, program.tables().number_axes)) {
      std::fprintf(
          stderr,
          "%s: error: compiled from %s, not from --start %s: tgm-hmi run runs it only from "
          "there (or with --from-here from anywhere); leave --start out\n",
          file.c_str(),
          point_text(program.tables().start_mm, program.tables().axis_letters).c_str(),
          point_text(start, program.tables().axis_letters).c_str());
      return 2;
    }
    start = program.tables().start_mm;
  }
  note.print(file, intercode);
  if (resume.given()) {
    // The machine stands at --here (or where the program starts) and approaches line N.
    std::array<double, kMaxAxes> here = start;
    if (std::string why;
        !here_text.empty() && !parse_start(here_text, machine.axis_letters(ip_index), here, why)) {
      return args.usage_error("--here: " + why);
    }
    if (!resume_program(file, program, resume, here, machine.compiler.default_feed_mm_per_min)) {
      return 2;
    }
    start = here;
  }

  SimulationOptions so;
  so.interpolator = ip_index;
  so.rel_speed = rel;
  so.m_ack_s = m_ack >= 0.0 ? m_ack : app->plc.default_m_delay_s;
  if (m_ack < 0.0) {
    for (const auto& [m, s] : app->plc.m_delay_s) so.m_ack_by_number[m] = s;
  }
  // The checker needs every cycle, so it runs only when asked (as does the CSV); otherwise the
  // run skips through cruise, dwells and M waits (Interpolator::advance, same trajectory).
  so.check_limits = check_limits;
  so.limit_share = share;
  so.commands = commands;
  so.stops = stops;
  so.stop_restart_s = restart_s;
  so.max_time_s = max_time_s;
  so.start_mm = start;
  const auto wall0 = std::chrono::steady_clock::now();
  // Progress on standard error (standard output is the summary): redrawn on a terminal from
  // half a second on, a plain line every interval_s otherwise.
  const bool tty = ::isatty(2) != 0;
  bool progress_shown = false;
  auto after = [](std::chrono::steady_clock::time_point t, double s) {
    return t + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
  };
  auto next_progress = after(wall0, tty ? 0.5 : interval_s);
  const SignalFlag signal_flag;
  g_signal = 0;
  // Stream buffers, sized only for the files asked for (a megabyte written out and never used
  // is 256 page faults, 3 ms on a VM, of a run that takes 30 ms), and declared before the files
  // so that they outlive them: a file closed on an early return still flushes from its buffer.
  std::vector<char> csv_buf, blk_buf;
  File csv, blocks, la;
  // An output that can no longer be written (a full disk) ends the run where it is: it ran on
  // to the end of the program, however long, and only then said that the file was incomplete.
  bool output_failed = false;
  so.on_progress = [&](const SimulationProgress& p) {
    if (g_signal != 0) return false;
    for (const File* f : {&csv, &blocks, &la}) {
      if (*f && std::ferror(f->get())) {
        output_failed = true;
        return false;
      }
    }
    if (quiet) return true;
    const auto now = std::chrono::steady_clock::now();
    if (now < next_progress) return true;
    next_progress = after(now, tty ? 0.1 : interval_s);
    const double elapsed = std::chrono::duration<double>(now - wall0).count();
    const double done = p.records > 0 ? static_cast<double>(std::max(p.act_part, 0)) / static_cast<double>(p.records) : 0.0;
    char eta[48] = "";
    if (done > 0.01) std::snprintf(eta, sizeof eta, ", about %.0f s left", elapsed * (1.0 - done) / done);
    std::fprintf(stderr, "%ssimulate: %5.1f %% of the records, line %d, program time %.1f s (%.0fx real time)%s%s",
                 tty ? "\r\033[K" : "", 100.0 * done, p.act_line, p.program_time_s,
                 elapsed > 0.0 ? p.program_time_s / elapsed : 0.0, eta, tty ? "" : "\n");
    std::fflush(stderr);
    progress_shown = tty;
    return true;
  };
  std::string err;
  auto sim = Simulation::create(machine, so, &err);
  if (!sim) {
    std::fprintf(stderr, "tgm-hmi simulate: %s\n", err.c_str());
    return 2;
  }
  const std::string letters = machine.axis_letters(ip_index);
  const int n = static_cast<int>(letters.size());

  for (auto [flag, path, out] :
       {std::tuple{"--csv", &csv_path, &csv}, std::tuple{"--lookahead", &la_path, &la},
        std::tuple{"--blocks", &blocks_path, &blocks}}) {
    std::string why;
    if (!path->empty() && !(*out = open_out(*path, why))) {
      return args.usage_error(std::string(flag) + " " + *path + ": " + why);
    }
  }
  if (csv) {
    csv_buf.resize(1 << 20);
    std::setvbuf(csv.get(), csv_buf.data(), _IOFBF, csv_buf.size());
    std::fputs("time_s,line,act_part,status,run_flag,m_func,act_speed_mm_min,move_distance_mm", csv.get());
    for (char l : letters) std::fprintf(csv.get(), ",orig_%c", l);
    for (char l : letters) std::fprintf(csv.get(), ",pos_%c", l);
    for (char l : letters) std::fprintf(csv.get(), ",inc_%c", l);
    for (char l : letters) std::fprintf(csv.get(), ",backlash_%c", l);
    for (char l : letters) std::fprintf(csv.get(), ",speed_%c", l);
    std::fputs(",limit_factor\n", csv.get());
  }
  std::optional<CsvWriter> csv_out;
  if (csv) csv_out.emplace(csv.get());
  if (blocks) {
    blk_buf.resize(1 << 16);
    std::setvbuf(blocks.get(), blk_buf.data(), _IOFBF, blk_buf.size());
    std::fputs("line,act_part,g,length_mm,programmed_mm_min,peak_mm_min,duration_s,limit_factor\n", blocks.get());
  }
  const double T = machine.cycle_time_us * 1e-6;
  std::function<void(const Registers&)> on_cycle;
  std::array<LookAheadEntry, kLookAheadEntries> la_last{};
  bool la_first = true;
  // The table shifted (or first appeared): compared without the Tangent, which moves on arcs.
  auto la_changed = [&](const Registers& r) {
    if (la_first) return true;
    for (std::size_t e = 0; e < la_last.size(); ++e) {
      const LookAheadEntry& a = la_last[e];
      const LookAheadEntry& b = r.lookahead[e];
      if (a.movement_type != b.movement_type || a.movement_code != b.movement_code || a.line != b.line ||
          a.end_pos_mm != b.end_pos_mm || a.all_params != b.all_params) {
        return true;
      }
    }
    return false;
  };
  auto json_num = [](std::FILE* f, double v) {
    if (is_not_set(v) || !std::isfinite(v)) std::fputs("null", f);
    else std::fprintf(f, "%.9g", v);
  };
  auto write_lookahead = [&](const Registers& r) {
    std::FILE* f = la.get();
    std::fprintf(f, "{\"cycle\":%llu,\"time_s\":%.6f,\"act_part\":%d,\"act_line\":%d,\"entries\":[",
                 static_cast<unsigned long long>(r.cycle), static_cast<double>(r.cycle) * T, r.act_part, r.act_line);
    for (std::size_t e = 0; e < r.lookahead.size(); ++e) {
      const LookAheadEntry& x = r.lookahead[e];
      std::fprintf(f, "%s{\"movement_type\":%d,\"movement_code\":%d,\"line\":%d,\"plane\":%d,\"tool\":%d,",
                   e ? "," : "", x.movement_type, x.movement_code, x.line, x.plane, x.tool);
      std::fputs("\"tangent_deg\":", f);
      json_num(f, x.tangent_deg);
      std::fputs(",\"start_angle_deg\":", f);
      json_num(f, x.start_angle_deg);
      std::fputs(",\"end_angle_deg\":", f);
      json_num(f, x.end_angle_deg);
      std::fprintf(f, ",\"radius_mm\":%.9g,\"end_pos_mm\":[", x.radius_mm);
      for (int i = 0; i < n; ++i) {
        std::fprintf(f, "%s%.9g", i ? "," : "", x.end_pos_mm[static_cast<std::size_t>(i)]);
      }
      std::fputs("],\"all_params\":{", f);
      bool first = true;
      for (int k = 0; k < kParamLetters; ++k) {
        const double v = x.all_params[static_cast<std::size_t>(k)];
        if (is_not_set(v)) continue;
        std::fprintf(f, "%s\"%c\":%.9g", first ? "" : ",", static_cast<char>('A' + k), v);
        first = false;
      }
      std::fputs("}}", f);
    }
    std::fputs("]}\n", f);
    la_last = r.lookahead;
    la_first = false;
  };
  // The CSV's fields of one cycle. With --csv-every the last cycle's are kept until the next
  // one (the last cycle of a run is written whether it is an N-th or not).
  struct CsvRow {
    std::uint64_t cycle = 0;
    long long line = 0, act_part = 0, status = 0, run_flag = 0, m_func = 0;
    double act_speed = 0.0, move_distance = 0.0;
    std::array<double, kMaxAxes> orig{}, pos{}, speed{};
    std::array<std::int64_t, kMaxAxes> inc{}, backlash{};
    LimitFactor factor = LimitFactor::kNone;
  };
  CsvRow row;
  bool row_written = true;  // row is in the file (or there is none yet)
  bool any_row = false;
  auto write_row = [&](const CsvRow& x) {
    CsvWriter& w = *csv_out;
    w.fixed(static_cast<double>(x.cycle) * T, 6);
    for (const long long v : {x.line, x.act_part, x.status, x.run_flag, x.m_func}) w.col(v);
    w.col(x.act_speed, 6);
    w.col(x.move_distance, 9);
    for (int i = 0; i < n; ++i) w.col(x.orig[static_cast<std::size_t>(i)], 9);
    for (int i = 0; i < n; ++i) w.col(x.pos[static_cast<std::size_t>(i)], 9);
    for (int i = 0; i < n; ++i) w.col(static_cast<long long>(x.inc[static_cast<std::size_t>(i)]));
    for (int i = 0; i < n; ++i) {
      w.col(static_cast<long long>(x.backlash[static_cast<std::size_t>(i)]));
    }
    for (int i = 0; i < n; ++i) w.col(x.speed[static_cast<std::size_t>(i)], 6);
    w.put(',');
    w.text(limit_factor_name(x.factor));
    w.put('\n');
  };
  if (csv || la) {
    on_cycle = [&](const Registers& r) {
      if (la && la_changed(r)) write_lookahead(r);
      if (!csv) return;
      // An event: status, run_flag or m_func differ from the cycle before.
      const bool event = !any_row || r.status != row.status || r.run_flag != row.run_flag ||
                         r.m_func != row.m_func;
      row.cycle = r.cycle;
      row.line = r.act_line;
      row.act_part = r.act_part;
      row.status = r.status;
      row.run_flag = r.run_flag;
      row.m_func = r.m_func;
      row.act_speed = r.act_speed;
      row.move_distance = r.move_distance;
      row.orig = r.orig_position;
      row.pos = r.position;
      row.inc = r.position_inc;
      row.backlash = r.backlash;
      row.speed = r.speed;
      row.factor = r.limit_factor;
      any_row = true;
      row_written = csv_every == 1 || event || r.cycle % static_cast<std::uint64_t>(csv_every) == 0;
      if (row_written) write_row(row);
    };
  }
  const SimulationSummary sum = sim->run(program, on_cycle, [&](const BlockReport& b) {
    if (!blocks) return;
    std::fprintf(blocks.get(), "%d,%d,%d,%.9f,%.3f,%.3f,%.6f,%s\n", b.line, b.act_part, b.g, b.length_mm,
                 b.programmed_mm_min, b.peak_mm_min, b.duration_s, limit_factor_name(b.factor));
  });
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (progress_shown) std::fputs("\r\033[K", stderr);
  const int interrupted = sum.result == StepResult::kFinished ? 0 : static_cast<int>(g_signal);
  if (csv_out && !row_written) write_row(row);  // the last cycle
  if (csv_out) csv_out->flush();
  // Which output failed and why, said after the summary (the figures are still right).
  std::string io_error;
  const struct {
    const char* flag;
    const std::string& path;
    const File& file;
  } outputs[] = {
      {"--csv", csv_path, csv}, {"--blocks", blocks_path, blocks}, {"--lookahead", la_path, la}};
  for (const auto& o : outputs) {
    if (!o.file) continue;
    errno = 0;
    const bool flushed = std::fflush(o.file.get()) == 0;
    const int why = errno;
    if (!flushed || std::ferror(o.file.get())) {
      io_error += std::string("tgm-hmi simulate: cannot write ") + o.flag + " " + o.path + ": " +
                  (!flushed && why != 0 ? std::strerror(why) : "a write failed") +
                  " (the file is incomplete)\n";
    }
  }
  const bool io_ok = io_error.empty();

  // With an output on standard output ("-") the summary goes to standard error.
  std::FILE* const report =
      csv_path == "-" || blocks_path == "-" || la_path == "-" ? stderr : stdout;
  const bool finished = sum.result == StepResult::kFinished;
  const auto records = static_cast<std::size_t>(program.size());
  std::fprintf(report, "program:   %s (%zu record%s, interpolator %d, %d us cycle)\n", file.c_str(),
               records, records == 1 ? "" : "s", ip_index, machine.cycle_time_us);
  const std::string why =
      output_failed ? std::string("stopped: an output file could not be written (below)")
      : interrupted != 0
          ? std::string("interrupted by ") + (interrupted == SIGINT ? "SIGINT" : "SIGTERM") +
                (csv_every > 1 ? " (the output files hold the run up to here)"
                               : " (the output files hold every cycle up to here)")
          : sum.error + (sum.time_limit_reached ? " (--max-time S raises it)" : "");
  if (finished && !io_ok) {
    // The run is whole, a file of it is not: said here as well as below (the line said
    // "finished" and nothing else, with exit code 1).
    std::fprintf(report, "result:    finished, but an output file could not be written (below)\n");
  } else {
    std::fprintf(report, "result:    %s%s%s\n", finished ? "finished" : "NOT finished",
                 why.empty() ? "" : ": ", why.c_str());
  }
  // A program of a few cycles takes less time than setting up its run: "simulated 0x faster
  // than real time" read as a fault. Its wall time says more.
  const double speed = wall > 0.0 ? sum.program_time_s / wall : 0.0;
  std::fprintf(report, "time:      %.4f s program time, %llu cycles, ", sum.program_time_s,
               static_cast<unsigned long long>(sum.cycles));
  if (speed >= 10.0) {
    std::fprintf(report, "simulated %.0fx faster than real time\n", speed);
  } else {
    std::fprintf(report, "simulated in %.3f s\n", wall);
  }
  // Below 1 mm/min with three significant digits (F0.001 printed as 0.0).
  std::fprintf(
      report,
      sum.peak_speed_mm_min >= 1.0 || sum.peak_speed_mm_min == 0.0
          ? "distance:  %.4f mm, peak path speed %.1f mm/min, %llu M-functions acknowledged\n"
          : "distance:  %.4f mm, peak path speed %.3g mm/min, %llu M-functions acknowledged\n",
      sum.distance_mm, sum.peak_speed_mm_min, static_cast<unsigned long long>(sum.m_functions));
  if (!stops.empty()) {
    std::fprintf(
        report,
        "stops:     %llu of %zu given before the end, each restarted %.3f s after the standstill\n",
        static_cast<unsigned long long>(sum.stops), stops.size(), restart_s);
  }
  std::fprintf(report, "end:      ");
  for (int i = 0; i < n; ++i)
    std::fprintf(report, " %c=%.6f", letters[static_cast<std::size_t>(i)],
                 sum.end_position[static_cast<std::size_t>(i)]);
  std::fprintf(report, "  (Position after smoothing:");
  for (int i = 0; i < n; ++i) {
    std::fprintf(report, " %c=%.6f", letters[static_cast<std::size_t>(i)],
                 sum.end_position_smoothed[static_cast<std::size_t>(i)]);
  }
  std::fprintf(report, ")\n");
  {
    const SmoothingStage& sm = sim->interpolator().smoothing();
    const SplineStats& ss = sm.spline().stats();
    if (sm.spline().delay_steps() > 0) {
      std::fprintf(report,
                   "spline:    %d points (%.1f ms delay), jerk limit %.0f mm/s^3, %llu flagged "
                   "steps, %llu passes, "
                   "contour deviation max %.6f mm\n",
                   sm.spline().delay_steps(), sm.spline().delay_steps() * sm.calc_step_s() * 1e3,
                   sm.spline().jerk_limit_mm_s3(),
                   static_cast<unsigned long long>(ss.flagged_steps),
                   static_cast<unsigned long long>(ss.passes), ss.max_mm);
      if (const std::uint64_t early = sim->interpolator().early_smoothing_events(); early > 0) {
        std::fprintf(report,
                     "warning:   %llu M-functions and messages reached M_Func before their motion "
                     "(more than %zu inside the spline's delay), in program order\n",
                     static_cast<unsigned long long>(early), SmoothingStage::kEventCapacity);
      }
    }
    if (sm.iir().mask() != 0) {
      std::fprintf(report, "iir:       p %.6g q %.6g f %.6g ms, zeta %.3f, axis mask 0x%x\n",
                   static_cast<double>(sm.iir().params().p_e6) * 1e-6,
                   static_cast<double>(sm.iir().params().q_e6) * 1e-6,
                   static_cast<double>(sm.iir().params().f_e6) * 1e-6, sm.iir().zeta(),
                   sm.iir().mask());
    }
  }
  const auto& axes = machine.interpolators[static_cast<std::size_t>(ip_index)].axes;
  if (!check_limits) {
    std::fprintf(
        report,
        "axis peaks and violations: not checked (--check-limits differentiates every cycle)\n");
  } else {
    if (share < 1.0)
      std::fprintf(report, "limits checked at %g x the configured ones (--limit-share)\n", share);
    std::fprintf(report,
                 "axis   |v| peak / limit [mm/s]   |a| peak / limit [mm/s^2]   |j| peak / limit "
                 "[mm/s^3]   corner step / tol [mm/s]   curvature step / tol [mm/s^2]\n");
    for (int i = 0; i < n; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const AxisConfig& a = axes[ui];
      std::fprintf(
          report,
          "%c      %9.3f / %-9.3f      %10.1f / %-10.1f      %11.0f / %-11.0f      %7.3f / %-7.3f"
          "       %9.1f / %.1f\n",
          a.letter, sum.peaks[ui].velocity_mm_s, a.max_velocity_mm_s,
          sum.peaks[ui].acceleration_mm_s2, a.max_acceleration_mm_s2, sum.peaks[ui].jerk_mm_s3,
          a.max_jerk_mm_s3, sum.peaks[ui].corner_step_mm_s, a.corner_velocity_tolerance_mm_s,
          sum.peaks[ui].corner_acceleration_mm_s2, corner_acceleration_tolerance(a));
    }
    for (int i = 0; i < n; ++i) {
      // Why such an axis peaks below its limits: the planner leaves the ramp its share.
      const AxisConfig& a = axes[static_cast<std::size_t>(i)];
      if (a.backlash_mm > 0.0) {
        std::fprintf(report,
                     "(%c has backlash: its path is planned at %g x the limits above, the "
                     "backlash ramp has the rest)\n",
                     a.letter, planned_limit_share(a));
      }
    }
    if (std::any_of(stops.begin(), stops.end(), [](const auto& st) { return st.second == 4; })) {
      std::fprintf(
          report,
          "(peaks include the emergency ramp, which is held to the emergency deceleration and\n"
          " the jerk scaled by the same ratio, not to the limits above)\n");
    }
    if (sum.smoothed_measured) {
      // What the drives get: the checker holds Orig_Position to the limits, and the smoothing
      // may take Position beyond them (an IIR filter below critical damping overshoots); the
      // backlash ramp adds to that, within the share the planner leaves free.
      bool over = false;
      std::fprintf(report,
                   "to the drives (Position after the spline / IIR, plus the backlash ramp):\n");
      for (int i = 0; i < n; ++i) {
        const auto ui = static_cast<std::size_t>(i);
        const AxisConfig& a = axes[ui];
        const AxisPeaks& pk = sum.smoothed_peaks[ui];
        const bool v_over = pk.velocity_mm_s > a.max_velocity_mm_s * share * (1.0 + 1e-9);
        const bool a_over = pk.acceleration_mm_s2 > a.max_acceleration_mm_s2 * share * (1.0 + 1e-9);
        over = over || v_over || a_over;
        std::fprintf(report, "%c      %9.3f / %-9.3f%s   %10.1f / %-10.1f%s\n", a.letter,
                     pk.velocity_mm_s, a.max_velocity_mm_s, v_over ? " over" : "     ",
                     pk.acceleration_mm_s2, a.max_acceleration_mm_s2, a_over ? " over" : "     ");
      }
      if (over) {
        std::fprintf(report,
                     "warning:   the setpoint goes beyond an axis limit that the interpolated "
                     "path keeps (an IIR filter below critical damping overshoots): the drives "
                     "get that\n");
      }
    }
    std::fprintf(report, "violations: %llu\n",
                 static_cast<unsigned long long>(sum.violation_count));
    constexpr std::size_t kListed = 20;
    std::size_t shown = 0;
    for (const auto& v : sum.violations) {
      if (++shown > kListed) break;
      std::fprintf(report, "  cycle %llu line %d axis %c %s %.6g > %.6g\n",
                   static_cast<unsigned long long>(v.cycle), v.line,
                   letters[static_cast<std::size_t>(v.axis)], limit_quantity_name(v.quantity),
                   v.value, v.limit);
    }
    // The list stopped at 20 without a word: 2,757 violations looked like 20.
    if (sum.violation_count > kListed) {
      std::fprintf(report, "  (the first %zu listed; %llu more)\n", kListed,
                   static_cast<unsigned long long>(sum.violation_count - kListed));
    }
  }
  // Each factor's share too: on a CAM program "corner 3190.680 s" of 5,683 s said more as 56 %.
  double factored_s = 0.0;
  for (std::size_t k = 1; k < sum.factor_time_s.size(); ++k) factored_s += sum.factor_time_s[k];
  std::fprintf(report, "limited by (time):");
  for (std::size_t k = 1; k < sum.factor_time_s.size(); ++k) {
    if (sum.factor_time_s[k] > 0.0) {
      std::fprintf(report, " %s %.3f s (%.0f %%)", limit_factor_name(static_cast<LimitFactor>(k)),
                   sum.factor_time_s[k], 100.0 * sum.factor_time_s[k] / factored_s);
    }
  }
  std::fprintf(report, "\n");
  if (!io_ok) {
    std::fputs(io_error.c_str(), stderr);
    return 1;
  }
  if (interrupted != 0) return 128 + interrupted;
  if (!finished || sum.nan) return 1;
  if (check_limits && sum.violation_count > 0) return 1;
  return 0;
}

}  // namespace tgm::hmi
