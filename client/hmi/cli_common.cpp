#include "cli_common.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>

#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/printable.hpp"
#include "tgm/resume.hpp"
#include "tgm/soft_limits.hpp"

namespace tgm::hmi {

Args::Args(int argc, char** argv, const char* command, const char* usage)
    : ArgReader(argc, argv, std::string("tgm-hmi ") + command), usage_(usage) {}

bool Args::common() {
  return help_flag() || flag("--config", config_path_) ||
         flag("--interpolator", interpolator_text_);
}

bool Args::compile_flag() {
  return flag("--block-delete", block_delete_);
}

bool Args::compile_flags_fit(const std::string& file, bool intercode) const {
  if (!intercode || block_delete_.empty()) return true;
  std::fprintf(stderr,
               "%s: error: --block-delete: the file is intercode, compiled already (its optional "
               "blocks were run or skipped then: tgm-hmi compile --block-delete)\n",
               file.c_str());
  return false;
}

bool Args::help() const {
  if (help_given()) std::fputs(usage_, stdout);
  return help_given();
}

std::optional<AppConfig> Args::load_app() {
  std::optional<AppConfig> config = load_config_or_report(config_path_, program());
  if (!config) return std::nullopt;
  const int count = static_cast<int>(config->machine.interpolators.size());
  if (!interpolator_text_.empty()) {
    if (!parse_integer(interpolator_text_, 0, count - 1, interpolator_)) {
      usage_error("--interpolator must be 0.." + std::to_string(count - 1) + " (the config has " +
                  std::to_string(count) + "), not '" + interpolator_text_ + "'");
      return std::nullopt;
    }
  }
  if (!block_delete_.empty() &&
      (block_delete_ == "error" ||
       !parse_block_delete(block_delete_, config->machine.compiler.block_delete))) {
    usage_error("--block-delete takes run or skip, not '" + block_delete_ + "'");
    return std::nullopt;
  }
  return config;
}

std::optional<MachineConfig> Args::load_machine() {
  auto app = load_app();
  if (!app) return std::nullopt;
  return app->machine;
}

bool parse_start(const std::string& text, const std::string& letters,
                 std::array<double, kMaxAxes>& out, std::string& why) {
  out = {};
  std::string named;
  for (const std::string& item : comma_items(text)) {
    if (item.empty()) {
      why = "an empty item in '" + text + "' (AXIS<mm> items, comma-separated)";
      return false;
    }
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(item[0])));
    const std::size_t axis = letters.find(letter);
    if (axis == std::string::npos) {
      why = "'" + item + "' does not start with an axis letter of " + letters;
      return false;
    }
    if (named.find(letter) != std::string::npos) {
      why = std::string(1, letter) + " is given twice";
      return false;
    }
    named.push_back(letter);
    double v = 0.0;
    if (!parse_finite(item.substr(1), v) || std::fabs(v) > kMaxCoordinateMm) {
      why = "'" + item + "': " + std::string(1, letter) + " takes a number of mm within +-1e9";
      return false;
    }
    out[axis] = v;
  }
  return true;
}

std::string point_text(const std::array<double, kMaxAxes>& p, const std::string& letters,
                       char sep) {
  std::string out;
  for (std::size_t i = 0; i < letters.size() && i < p.size(); ++i) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.6f", p[i]);
    std::string v = buf;
    v.erase(v.find_last_not_of('0') + 1);
    if (v.back() == '.') v.pop_back();
    if (v == "-0") v = "0";
    if (i > 0) out.push_back(sep);
    out.push_back(letters[i]);
    out += v;
  }
  return out;
}

bool same_point(const std::array<double, kMaxAxes>& a, const std::array<double, kMaxAxes>& b,
                int n) {
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!(std::fabs(a[k] - b[k]) <= kSamePointMm)) return false;
  }
  return true;
}

bool is_intercode(const std::string& file, std::string_view bytes) {
  return has_intercode_magic(bytes) ||
         (file.size() > 5 && file.compare(file.size() - 5, 5, ".tgmi") == 0);
}

bool load_packed(const std::string& file, const MachineConfig& machine, int ip, PackedProgram& out,
                 const std::array<double, kMaxAxes>* start_mm, bool* intercode,
                 const SegmentSink& observe, std::size_t* compile_errors) {
  if (intercode) *intercode = false;
  if (compile_errors) *compile_errors = 0;
  FileView input;
  if (!input.open_or_report(file)) return false;
  return load_packed(file, input, machine, ip, out, start_mm, intercode, observe, compile_errors);
}

bool load_packed(const std::string& file, const FileView& input, const MachineConfig& machine,
                 int ip, PackedProgram& out, const std::array<double, kMaxAxes>* start_mm,
                 bool* intercode, const SegmentSink& observe, std::size_t* compile_errors) {
  if (intercode) *intercode = false;
  if (compile_errors) *compile_errors = 0;
  const std::string letters = machine.axis_letters(ip);
  if (is_intercode(file, input.text())) {
    if (intercode) *intercode = true;
    if (!open_intercode(file, input, out, observe)) return false;
    if (out.tables().axis_letters != letters) {
      std::fprintf(stderr,
                   "%s: error: compiled for the axes %s, interpolator %d has %s: compile the "
                   "G-code for it (tgm-hmi compile --interpolator %d with this config)\n",
                   file.c_str(), out.tables().axis_letters.c_str(), ip, letters.c_str(), ip);
      return false;
    }
    // Said with their count here: `compile_errors` counts the compiler's diagnostics.
    return print_soft_limit_errors(file, out,
                                   machine.interpolators[static_cast<std::size_t>(ip)]) == 0;
  }
  CompileOptions options = CompileOptions::from_machine(machine, ip);
  if (start_mm) options.start_mm = *start_mm;
  return compile_packed(file, input, options, out, observe, compile_errors);
}

std::size_t print_soft_limit_errors(const std::string& file, const PackedProgram& program,
                                    const InterpolatorConfig& axes) {
  if (!has_soft_limits(axes)) return 0;
  // Every record from the point the program was compiled from, as the compiler checks G-code
  // (a record's start is where the motion record before it ends).
  std::array<double, kMaxAxes> at = program.tables().start_mm;
  std::size_t beyond = 0;
  constexpr std::size_t kListed = 20;
  auto cursor = program.cursor();
  for (Segment s; cursor.next(s);) {
    if (!s.is_motion()) continue;
    if (const std::string why = soft_limit_problem(s, at.data(), axes); !why.empty()) {
      if (++beyond <= kListed) {
        std::fprintf(stderr, "%s (source line %d): error: %s\n", file.c_str(), s.line, why.c_str());
      }
    }
    at = s.end;
  }
  if (beyond > kListed) {
    std::fprintf(stderr, "%s: ... and %zu more\n", file.c_str(), beyond - kListed);
  }
  if (beyond > 0) {
    std::fprintf(stderr, "%s: %zu record%s beyond the soft limits\n", file.c_str(), beyond,
                 beyond == 1 ? "" : "s");
  }
  return beyond;
}

bool open_intercode(const std::string& file, const FileView& input, PackedProgram& out,
                    const SegmentSink& observe) {
  // Copied before the check: the copy is what is checked to be the file as it was opened.
  std::string bytes(input.text());
  if (!input.check_or_report(file)) return false;
  // `observe` sees the records as open() checks them: one pass less.
  if (std::string error; !PackedProgram::open(std::move(bytes), out, error, observe)) {
    std::fprintf(stderr, "%s: error: %s\n", file.c_str(), error.c_str());
    return false;
  }
  // Version 2 has no checksum: a flipped bit ran as another program without a word (X10 as
  // X10.5, session 75). Read as before, and said.
  if (const std::string_view f = out.file();
      f.size() >= 6 && static_cast<unsigned char>(f[4]) == 2 && f[5] == 0) {
    std::fprintf(stderr,
                 "%s: note: version 2 intercode carries no checksum, so damage to it cannot be "
                 "found; `tgm-hmi compile %s --out NEW` writes it as the current version\n",
                 file.c_str(), file.c_str());
  }
  return true;
}

void print_compile_errors(const std::string& file, const CompileResult& result) {
  for (const Diagnostic& d : result.errors)
    std::fprintf(stderr, "%s\n", format_diagnostic(file, d).c_str());
}

bool compile_packed(const std::string& file, const FileView& input, const CompileOptions& options,
                    PackedProgram& out, const SegmentSink& observe, std::size_t* compile_errors) {
  if (compile_errors) *compile_errors = 0;
  const std::string_view text = input.text();
  const std::string& letters = options.axis_letters;
  std::string bytes;
  // Room that is never written costs no memory, and growing the string by doubling holds the
  // old and the new copy at once: twice the source covers a CAM program's records (a planar
  // G1 line of 18 characters is 20 bytes of intercode); loops, arcs and many axes may need more.
  bytes.reserve(2 * text.size() + 4096);
  IntercodeEncoder encoder(bytes, static_cast<int>(letters.size()), letters, options.start_mm);
  CompileResult r = compile_gcode(text, options, [&](const Segment& s) {
    encoder.add(s);
    if (observe) observe(s);
  });
  // A file changed under the compiler: its diagnostics may be about a mix of two versions.
  if (!input.check_or_report(file)) return false;
  if (!r.ok()) {
    print_compile_errors(file, r);
    if (compile_errors) *compile_errors = r.error_count();
    return false;
  }
  encoder.finish(r.program.params, r.program.messages);
  if (std::string error; !PackedProgram::open(std::move(bytes), out, error)) {
    std::fprintf(stderr, "%s: internal error: the compiled program does not read back: %s\n",
                 file.c_str(), error.c_str());
    return false;
  }
  return true;
}

void ProgramNotes::print(const std::string& file, bool intercode) const {
  const auto where = [&](std::int32_t line) {
    return intercode ? file + " (source line " + std::to_string(line) + ")"
                     : file + ":" + std::to_string(line);
  };
  double table_radius = 0.0;
  for (const ToolConfig& t : tools_) {
    if (t.number == compensation_.tool) table_radius = t.radius_mm;
  }
  if (compensation_seen_ && table_radius > 0.0) {
    // The radius is 0 although the tool has one: a D0 on the G41/G42 line (the note said to use
    // a T with a radius, which the program had).
    std::fprintf(stderr,
                 "%s: note: the first move under G%d (tool radius compensation) with radius 0 "
                 "(D0 on the G%d line, where tool T%d has %s mm in the tool table): the tool "
                 "centre follows the programmed contour\n",
                 where(compensation_.line).c_str(), static_cast<int>(compensation_.compensation),
                 static_cast<int>(compensation_.compensation), static_cast<int>(compensation_.tool),
                 shortest_text(table_radius).c_str());
  } else if (compensation_seen_) {
    std::fprintf(stderr,
                 "%s: note: the first move under G%d (tool radius compensation) with radius 0 "
                 "(tool T%d): the tool centre follows the programmed contour; D<mm> on the G%d "
                 "line, or a T with a radius in the tool table, offsets it\n",
                 where(compensation_.line).c_str(), static_cast<int>(compensation_.compensation),
                 static_cast<int>(compensation_.tool),
                 static_cast<int>(compensation_.compensation));
  }
  if (records_ && !ends_) {
    std::fprintf(stderr,
                 "%s: note: the program has no M2 or M30: it ends after this line's record, "
                 "where the motion stops (a file cut short reads the same: is it whole?)\n",
                 where(last_line_).c_str());
  }
}

namespace {

// The SIGBUS guard of FileView's mappings: a fault on a guarded page that the file no longer
// has maps zeros over the rest of that mapping and marks it cut, and the reading goes on.
struct GuardedMapping {
  std::atomic<std::uintptr_t> begin{0};
  std::atomic<std::size_t> size{0};
  std::atomic<bool> cut{false};
};
constexpr int kGuardSlots = 8;  // mapped views at once (tgm-hmi holds one)
GuardedMapping g_guarded[kGuardSlots];
std::mutex g_guard_mutex;
bool g_guard_installed = false;  // under g_guard_mutex
struct sigaction g_bus_before {};
std::uintptr_t g_page_size = 4096;

void on_bus_error(int sig, siginfo_t* info, void* /*context*/) {
  const auto at = reinterpret_cast<std::uintptr_t>(info->si_addr);
  for (GuardedMapping& g : g_guarded) {
    const std::uintptr_t begin = g.begin.load(std::memory_order_acquire);
    const std::size_t size = g.size.load(std::memory_order_acquire);
    if (begin == 0 || at < begin || at - begin >= size) continue;
    const std::uintptr_t from = at & ~(g_page_size - 1);
    // mmap is a plain system call here, safe in a handler; the faulting read then reads zeros.
    if (mmap(reinterpret_cast<void*>(from), begin + size - from, PROT_READ,
             MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0) != MAP_FAILED) {
      g.cut.store(true, std::memory_order_release);
      return;
    }
    break;
  }
  // Not a guarded page: the disposition from before the guard takes the fault when the
  // instruction faults again (a SIGBUS sent by another process is raised again for it).
  sigaction(SIGBUS, &g_bus_before, nullptr);
  if (info->si_code <= 0) raise(sig);
}

// The slot guarding [p, p + size), -1 when none is free or the handler cannot be installed.
int guard_mapping(void* p, std::size_t size) {
  const std::lock_guard<std::mutex> lock(g_guard_mutex);
  // Installed once; again when a SIGBUS of another mapping handed the signal back (on_bus_error).
  if (g_guard_installed) {
    struct sigaction now {};
    g_guard_installed = sigaction(SIGBUS, nullptr, &now) == 0 && (now.sa_flags & SA_SIGINFO) != 0 &&
                        now.sa_sigaction == on_bus_error;
  }
  if (!g_guard_installed) {
    const long page = sysconf(_SC_PAGESIZE);
    if (page > 0) g_page_size = static_cast<std::uintptr_t>(page);
    struct sigaction sa {};
    sa.sa_sigaction = on_bus_error;
    sa.sa_flags = SA_SIGINFO;
    sigemptyset(&sa.sa_mask);
    if (sigaction(SIGBUS, &sa, &g_bus_before) != 0) return -1;
    g_guard_installed = true;
  }
  for (int i = 0; i < kGuardSlots; ++i) {
    GuardedMapping& g = g_guarded[i];
    if (g.begin.load(std::memory_order_relaxed) != 0) continue;
    g.cut.store(false, std::memory_order_relaxed);
    g.size.store(size, std::memory_order_release);
    g.begin.store(reinterpret_cast<std::uintptr_t>(p), std::memory_order_release);
    return i;
  }
  return -1;
}

void unguard_mapping(int slot) {
  const std::lock_guard<std::mutex> lock(g_guard_mutex);
  g_guarded[slot].begin.store(0, std::memory_order_release);
  g_guarded[slot].size.store(0, std::memory_order_release);
}

long long mtime_ns(const struct stat& st) {
  return static_cast<long long>(st.st_mtim.tv_sec) * 1'000'000'000LL + st.st_mtim.tv_nsec;
}

}  // namespace

FileView::~FileView() {
  if (guard_ >= 0) unguard_mapping(guard_);
  if (map_) munmap(map_, map_size_);
  if (fd_ >= 0) ::close(fd_);
}

bool FileView::check(std::string& why) const {
  if (guard_ >= 0 && g_guarded[guard_].cut.load(std::memory_order_acquire)) {
    why =
        "the file was cut short while it was read (written again by another program?); "
        "use it once it is complete";
    return false;
  }
  struct stat st {};
  if (fd_ < 0 || fstat(fd_, &st) != 0) return true;  // a pipe, or nothing to compare
  if (st.st_size != size_) {
    why = "the file changed while it was read (" + std::to_string(size_) +
          " bytes when it was opened, " + std::to_string(st.st_size) +
          " now); use it once it is complete";
    return false;
  }
  if (mtime_ns(st) != mtime_ns_) {
    why = "the file was written while it was read; use it once it is complete";
    return false;
  }
  return true;
}

bool FileView::check_or_report(const std::string& file) const {
  std::string why;
  if (check(why)) return true;
  std::fprintf(stderr, "%s: error: %s\n", file.c_str(), why.c_str());
  return false;
}

bool FileView::open_or_report(const std::string& path) {
  std::string error;
  if (open(path, error)) return true;
  std::fprintf(stderr, "%s: error: %s\n", path.c_str(), error.c_str());
  return false;
}

bool FileView::open(const std::string& name, std::string& error) {
  // A named pipe opens once a writer opens it, and is read as a pipe is: said first, as the
  // command would otherwise wait without a word (a closing-note item since the early sessions).
  if (struct stat pst{}; name != "-" && ::stat(name.c_str(), &pst) == 0 && S_ISFIFO(pst.st_mode)) {
    std::fprintf(stderr, "%s: a named pipe: waiting for a writer to open it (Ctrl-C stops)\n",
                 name.c_str());
  }
  // "-" is standard input (a CAM post-processor's pipe), as for most Unix tools. Its own
  // descriptor, not /dev/stdin: a socket (ssh, inetd, systemd) cannot be opened by a path.
  const int fd =
      name == "-" ? ::fcntl(0, F_DUPFD_CLOEXEC, 0) : ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = std::string(name == "-" ? "cannot read standard input: " : "cannot open: ") +
            std::strerror(errno);
    return false;
  }
  struct stat st {};
  const bool have_stat = fstat(fd, &st) == 0;
  if (have_stat && S_ISDIR(st.st_mode)) {
    ::close(fd);
    error = "is a directory";
    return false;
  }
  // A device other than a terminal (/dev/zero, /dev/urandom) is no program: its bytes never
  // end. A pipe and a terminal are read (up to kMaxStreamedInput).
  if (have_stat && S_ISCHR(st.st_mode) && ::isatty(fd) == 0) {
    ::close(fd);
    error = "is a device, not a file";
    return false;
  }
  if (have_stat && S_ISREG(st.st_mode)) {
    // Kept open: check() compares the file with what was opened.
    fd_ = fd;
    size_ = static_cast<long long>(st.st_size);
    mtime_ns_ = mtime_ns(st);
  }
  if (have_stat && S_ISREG(st.st_mode) && st.st_size > 0) {
    const auto size = static_cast<std::size_t>(st.st_size);
    void* p = mmap(nullptr, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (p != MAP_FAILED) {
      guard_ = guard_mapping(p, size);
      if (guard_ >= 0) {
        map_ = p;
        map_size_ = size;
        text_ = std::string_view(static_cast<const char*>(p), map_size_);
        return true;
      }
      munmap(p, size);  // unguarded it could kill the process: read it instead
    }
  }
  // Read from what was opened (a path opened again can name something else by now); a file
  // kept open for check() through a second descriptor.
  const int read_fd = fd_ < 0 ? fd : ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
  if (read_fd < 0) {
    error = std::string("cannot read: ") + std::strerror(errno);
    return false;
  }
  switch (read_whole_fd(read_fd, kMaxStreamedInput, copy_)) {
    case ReadResult::kRead:
      break;
    case ReadResult::kCannotOpen:
      error = std::string("cannot open: ") + std::strerror(errno);
      return false;
    case ReadResult::kReadError:
      error = "read error";
      return false;
    case ReadResult::kTooLarge:
      error = "more than " + std::to_string(kMaxStreamedInput >> 20) +
              " MiB to read (an input without end?)";
      return false;
  }
  text_ = copy_;
  return true;
}

bool progress_interval_flag(Args& args, double& out) {
  return args.number_flag("--progress-interval", out, "seconds in (0, 86400]",
                          [](double v) { return v > 0.0 && v <= 86400.0; });
}

std::string shell_word(const std::string& word) {
  const bool plain = !word.empty() && std::all_of(word.begin(), word.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 ||
           std::strchr("_./,:=+-", c) != nullptr;
  });
  if (plain) return word;
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

bool ResumeFlags::read(Args& args) {
  return args.whole_flag("--from-line", 1LL, static_cast<long long>(INT32_MAX), line) ||
         args.whole_flag("--occurrence", 1LL, static_cast<long long>(INT32_MAX), occurrence) ||
         args.number_flag("--approach-feed", approach_feed, "mm/min, > 0 and at most 1e6",
                          [](double v) { return v > 0.0 && v <= kMaxFeedMmPerMin; });
}

bool ResumeFlags::check(Args& args) const {
  if (given()) return true;
  const char* alone =
      occurrence > 0 ? "--occurrence" : (approach_feed > 0.0 ? "--approach-feed" : nullptr);
  if (alone == nullptr) return true;
  args.usage_error(std::string(alone) + " needs --from-line N");
  return false;
}

bool resume_program(const std::string& file, PackedProgram& program, const ResumeFlags& flags,
                    const std::array<double, kMaxAxes>& here, double default_feed_mm_per_min) {
  ResumeOptions o;
  o.line = static_cast<std::int32_t>(flags.line);
  o.occurrence = flags.occurrence > 0 ? static_cast<std::uint64_t>(flags.occurrence) : 1;
  o.here = here;
  o.approach_feed_mm_per_min =
      flags.approach_feed > 0.0 ? flags.approach_feed : default_feed_mm_per_min;
  Resume r;
  std::string error;
  if (!resume_from_line(program, o, r, error)) {
    std::fprintf(stderr, "%s: error: --from-line: %s\n", file.c_str(), error.c_str());
    return false;
  }
  const std::string& letters = program.tables().axis_letters;
  std::string where =
      "record " + std::to_string(r.first_record + 1) + " of " + std::to_string(program.size());
  if (r.occurrences > 1) {
    where += ", the run " + std::to_string(o.occurrence) + " of " + std::to_string(r.occurrences) +
             " of this line (--occurrence picks another)";
  }
  if (r.approach) {
    std::fprintf(stderr, "%s: resuming at line %d (%s): approach from %s to %s at %g mm/min\n",
                 file.c_str(), o.line, where.c_str(), point_text(here, letters).c_str(),
                 point_text(r.resume_point, letters).c_str(), o.approach_feed_mm_per_min);
  } else {
    std::fprintf(stderr, "%s: resuming at line %d (%s): the machine stands where it starts (%s)\n",
                 file.c_str(), o.line, where.c_str(), point_text(here, letters).c_str());
  }
  if (r.skipped_m > 0) {
    std::string list;
    for (const SkippedM& m : r.last_skipped_m) {
      list += (list.empty() ? "" : ", ") + std::string("M") + std::to_string(m.m) + " (line " +
              std::to_string(m.line) + ")";
    }
    std::fprintf(stderr,
                 "%s: note: %llu PLC M-function%s before line %d never reach%s the PLC%s: %s. "
                 "Bring the machine into the state %s leave%s (spindle, coolant, clamps) before "
                 "the start\n",
                 file.c_str(), static_cast<unsigned long long>(r.skipped_m),
                 r.skipped_m == 1 ? "" : "s", o.line, r.skipped_m == 1 ? "es" : "",
                 r.skipped_m > r.last_skipped_m.size() ? ", the last of them" : "", list.c_str(),
                 r.skipped_m == 1 ? "it" : "they", r.skipped_m == 1 ? "s" : "");
  }
  program = std::move(r.program);
  return true;
}

namespace {
bool g_stdout_reported = false;
}  // namespace

bool write_stdout(std::string_view text, const char* command, const char* what) {
  if (std::fwrite(text.data(), 1, text.size(), stdout) == text.size() && std::fflush(stdout) == 0) {
    return true;
  }
  std::fprintf(stderr, "tgm-hmi %s: cannot write %s: %s\n", command, what, std::strerror(errno));
  g_stdout_reported = true;
  return false;
}

bool stdout_failure_reported() {
  return g_stdout_reported;
}

void stdout_failure_handled() {
  g_stdout_reported = true;
}

}  // namespace tgm::hmi
