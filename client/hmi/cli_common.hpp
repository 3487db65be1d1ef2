// Command-line plumbing shared by the tgm-hmi subcommands: flags, config loading, file I/O.
#pragma once

#include <algorithm>
#include <array>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "tgm/atomic_file.hpp"
#include "tgm/cli_args.hpp"
#include "tgm/cli_numbers.hpp"
#include "tgm/config.hpp"
#include "tgm/file_text.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm::hmi {

//! The argument reader of a tgm-hmi subcommand (tgm::cli::ArgReader, messages prefixed
//! "tgm-hmi CMD") with the flags every subcommand shares: --config, --interpolator, --help.
class Args : public cli::ArgReader {
 public:
  Args(int argc, char** argv, const char* command, const char* usage);

  //! Consumes --config, --interpolator, --help.
  bool common();
  //! Consumes the flags of the commands that compile G-code: --block-delete run|skip (applied
  //! to the config's compiler.block_delete by load_app()).
  bool compile_flag();
  //! False, saying why, when --block-delete was given for FILE that is intercode (compiled
  //! already, its optional blocks run or skipped then).
  bool compile_flags_fit(const std::string& file, bool intercode) const;
  //! True (after printing the usage to stdout) when --help was given.
  bool help() const;

  //! Loads and validates the config (printing every problem); nullopt on failure.
  std::optional<MachineConfig> load_machine();
  std::optional<AppConfig> load_app();
  //! The --interpolator value (0 when not given); valid after load_machine().
  int interpolator() const { return interpolator_; }
  //! True when --interpolator was given.
  bool interpolator_given() const { return !interpolator_text_.empty(); }
  const std::string& config_path() const { return config_path_; }
  //! The config file that load_app() reads, named for distinct_files().
  NamedFile config_file() const { return ArgReader::config_file(config_path_); }

 private:
  const char* usage_;
  std::string config_path_;
  std::string interpolator_text_;
  int interpolator_ = 0;
  std::string block_delete_;
};

//! What FileView reads from a pipe or a device (regular files are mapped, of any size): 1 GiB,
//! several times the longest program the compiler expands (compiler.max_program_segments).
inline constexpr std::size_t kMaxStreamedInput = std::size_t{1} << 30;

//! Reads a start point as "X20,Y5,Z-2" into `out`: axis letters of `letters` (either case),
//! each at most once, numbers within +-1e9 mm; the axes not named stand at 0. False with the
//! reason in `why`.
bool parse_start(const std::string& text, const std::string& letters,
                 std::array<double, kMaxAxes>& out, std::string& why);

//! A point as "X20 Y5.25 Z-2" (`sep` ' ') or as parse_start reads it, "X20,Y5.25,Z-2" (`sep`
//! ','): the first letters.size() axes, at most 6 decimals, trailing zeros dropped, so that
//! what is printed reads back within kSamePointMm.
std::string point_text(const std::array<double, kMaxAxes>& p, const std::string& letters,
                       char sep = ' ');

//! How far two start points may lie apart and still be one [mm]: the rounding of point_text.
inline constexpr double kSamePointMm = 1e-6;

//! True when the first `n` axes of `a` and `b` lie within kSamePointMm of each other.
bool same_point(const std::array<double, kMaxAxes>& a, const std::array<double, kMaxAxes>& b,
                int n);

//! True when FILE, whose content is `bytes`, is read as intercode rather than compiled: it
//! begins with intercode's magic (whatever its name), or it is named *.tgmi (and is then refused
//! if it is not intercode).
bool is_intercode(const std::string& file, std::string_view bytes);

//! Notes on a compiled program that is not wrong but may not be what its author meant,
//! printed to standard error by compile, simulate and run:
//! - G41/G42 at radius 0 (no D on the line and tool T0, or a table radius of 0) leaves the tool
//!   centre on the programmed contour: one note names the first record that moves so, so the
//!   user who asked for compensation is not misled;
//! - a program without M2 or M30 just stops after its last record, which is also how a file
//!   cut short by a post-processor that died reads: one note names that record's line.
class ProgramNotes {
 public:
  //! `tools`: the config's tool table, to tell a D0 on the G41/G42 line from a tool without a
  //! radius (empty for intercode of unknown origin).
  explicit ProgramNotes(std::vector<ToolConfig> tools = {}) : tools_(std::move(tools)) {}
  void observe(const Segment& s) {
    if (!compensation_seen_ && s.compensation != Compensation::kOff &&
        s.compensation_radius_mm == 0.0 && s.is_motion()) {
      compensation_seen_ = true;
      compensation_ = s;
    }
    if (s.type == SegmentType::kMFunction && s.m_kind == MKind::kProgramEnd) ends_ = true;
    records_ = true;
    last_line_ = std::max(last_line_, s.line);
  }
  //! Nothing a later record could change is left to observe.
  bool complete() const { return compensation_seen_ && ends_; }
  //! Prints the notes to standard error (nothing when there is nothing to note), at FILE:LINE,
  //! or for an `intercode` FILE at "FILE (source line LINE)": the line is one of the G-code it
  //! was compiled from, not of the binary file.
  void print(const std::string& file, bool intercode = false) const;

 private:
  std::vector<ToolConfig> tools_;
  bool compensation_seen_ = false;
  Segment compensation_{};
  bool ends_ = false;
  bool records_ = false;
  std::int32_t last_line_ = 0;
};

//! FILE as the program of interpolator `ip` of `machine`, held as intercode (PackedProgram,
//! about 20 bytes a record where a Segment takes 152): intercode (is_intercode: written by
//! `tgm-hmi compile --out`) checked and kept as it is, refused when it was compiled for other
//! axis letters (positions go by axis index: a C where this interpolator has Z would move Z),
//! or G-code compiled straight into intercode. Prints every problem ("FILE: error: ..." or the
//! compiler's diagnostics) and returns false; `compile_errors` (when given) receives the number
//! of compiler diagnostics. G-code is compiled from `start_mm` (machine mm; default machine
//! zero), the point the program starts at: G91 moves are relative to it, axes a G90 line does
//! not name stay there. `intercode` (when given) says which of the two FILE was; `observe`
//! (when given) sees every record in order as it is read: what it gathers is the program's when
//! load_packed returns true (on false it may have seen a part of it).
bool load_packed(const std::string& file, const MachineConfig& machine, int ip, PackedProgram& out,
                 const std::array<double, kMaxAxes>* start_mm = nullptr, bool* intercode = nullptr,
                 const SegmentSink& observe = {}, std::size_t* compile_errors = nullptr);

class FileView;

//! load_packed from `input`, FILE opened by the caller: a program loaded twice (`run` compiles
//! it again from where the interpolator stands) reads FILE once, as a pipe can be read only
//! once (the second compile of a piped program was empty, and `run` cleared the interpolator
//! for it).
bool load_packed(const std::string& file, const FileView& input, const MachineConfig& machine,
                 int ip, PackedProgram& out, const std::array<double, kMaxAxes>* start_mm,
                 bool* intercode, const SegmentSink& observe, std::size_t* compile_errors);

//! Every diagnostic of a failed compile on standard error, as `FILE:LINE:COL: error: reason`.
void print_compile_errors(const std::string& file, const CompileResult& result);

//! Intercode checked against the soft limits of `axes` (tgm/soft_limits.hpp) from the point it
//! was compiled from: each record beyond them on standard error as "FILE (source line N):
//! error: reason" (the first 20), then their number. Returns the number; 0 without soft limits.
//! The compiler checks G-code itself; load_packed calls this for intercode.
std::size_t print_soft_limit_errors(const std::string& file, const PackedProgram& program,
                                    const InterpolatorConfig& axes);

//! load_packed's intercode half: `input` (FILE, open, intercode) copied, checked to be the file
//! as it was opened (FileView::check) and decoded into `out`, which `observe` sees record by
//! record. Prints why not ("FILE: error: ...") and returns false.
bool open_intercode(const std::string& file, const FileView& input, PackedProgram& out,
                    const SegmentSink& observe = {});

//! load_packed's G-code half: `input` (FILE, open) compiled with `options` straight into
//! intercode held by `out`. Prints the compiler's diagnostics (their number goes to
//! `compile_errors` when given), an internal error, or that FILE changed while it was read
//! (FileView::check; then no diagnostics), and returns false.
bool compile_packed(const std::string& file, const FileView& input, const CompileOptions& options,
                    PackedProgram& out, const SegmentSink& observe = {},
                    std::size_t* compile_errors = nullptr);

//! A read-only view of a whole file (memory-mapped when possible).
//!
//! A mapped file that another program truncates while it is read would kill the process with
//! SIGBUS (a CAM post-processor writing the program again with `>` while `tgm-hmi compile`
//! reads it). The mapping is guarded instead: a page that is no longer there reads as zeros
//! (a process-wide SIGBUS handler maps them in, for the guarded mappings only; any other
//! SIGBUS keeps its disposition), and check() says afterwards whether what was read is the
//! file as it was opened.
class FileView {
 public:
  FileView() = default;
  FileView(const FileView&) = delete;
  FileView& operator=(const FileView&) = delete;
  ~FileView();
  bool open(const std::string& path, std::string& error);
  //! open() with the reason printed as "FILE: error: ...".
  bool open_or_report(const std::string& path);
  std::string_view text() const { return text_; }
  //! True when the file is still the one opened (size and modification time, nothing cut from
  //! the mapping); else false with the reason in `why`. Call it once the text has been used:
  //! a change before then may have mixed two versions of the file, or zeros, into it.
  bool check(std::string& why) const;
  //! check() with the reason printed as "FILE: error: ...".
  bool check_or_report(const std::string& file) const;

 private:
  void* map_ = nullptr;
  std::size_t map_size_ = 0;
  int guard_ = -1;  // the mapping's slot in the SIGBUS guard (-1: none)
  int fd_ = -1;     // a regular file, kept open for check()
  long long size_ = 0;
  long long mtime_ns_ = 0;
  std::string copy_;  // for files that cannot be mapped (pipes, empty files)
  std::string_view text_;
};

//! Consumes --progress-interval S of `run` and `simulate` into `out`: seconds > 0, at most a
//! day (a bad value is reported through `args`).
bool progress_interval_flag(Args& args, double& out);

//! `word` as one word of a POSIX shell command line: as it is when it holds only letters,
//! digits and _ . / , : = + -, else in single quotes.
std::string shell_word(const std::string& word);

//! The block search flags of `run` and `simulate` (tgm/resume.hpp): --from-line N,
//! --occurrence K, --approach-feed F.
struct ResumeFlags {
  long long line = 0;        // 0: not given
  long long occurrence = 0;  // 0: not given (the first)
  double approach_feed = 0;  // 0: not given (the config's default feed)
  //! Consumes one of the flags.
  bool read(Args& args);
  //! The flags that need --from-line without it: a usage error through `args` (returns false).
  bool check(Args& args) const;
  bool given() const { return line > 0; }
};

//! The usage text of the flags (for kUsage of `run` and `simulate`).
#define TGM_HMI_RESUME_USAGE                                                                      \
  "  --from-line N         block search: run the program from source line N on (its first\n"      \
  "                        record; compiled whole, so every modal state is the full run's),\n"    \
  "                        after a straight approach from where the machine stands to where\n"    \
  "                        line N starts. The PLC M-functions before it are skipped and\n"        \
  "                        listed: bring the machine into their state first\n"                    \
  "  --occurrence K        with --from-line: the K-th run of line N's records (a subroutine or\n" \
  "                        a loop repeats a line; default 1)\n"                                   \
  "  --approach-feed F     with --from-line: feed of the approach [mm/min] (default: the\n"       \
  "                        config's compiler.default_feed_mm_per_min)\n"

//! Replaces `program` by its block search from `here` (flags.given() must hold) and says what
//! it did on standard error: where it resumes, the approach, and the PLC M-functions skipped
//! (always: the machine must be brought into their state). False, with "FILE: error: ..." said,
//! when the line cannot be resumed at.
bool resume_program(const std::string& file, PackedProgram& program, const ResumeFlags& flags,
                    const std::array<double, kMaxAxes>& here, double default_feed_mm_per_min);

//! Writes `text` to standard output and flushes it. On failure prints "tgm-hmi CMD: cannot
//! write WHAT: reason" and returns false; main() then does not report standard output again.
bool write_stdout(std::string_view text, const char* command, const char* what);
//! True once write_stdout() has reported a failure, or a command took one as handled.
bool stdout_failure_reported();
//! A command dealt with a failed write to standard output itself (said why, or ended because
//! its reader had gone): main() does not report it again.
void stdout_failure_handled();

}  // namespace tgm::hmi
