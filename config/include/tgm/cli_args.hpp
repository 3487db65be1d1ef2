// Strict command-line reading shared by tgm-service, tgm-plc and every tgm-hmi subcommand:
// `--flag VALUE` or `--flag=VALUE`, flags without a value, positionals, the DDS overrides.
// A problem is printed as "PROGRAM: reason" with a pointer to --help, the first one only, so
// the three binaries word their errors alike and never print a follow-on error.
#pragma once

#include <string>
#include <vector>

#include "tgm/dds_overrides.hpp"

namespace tgm::cli {

//! tgm's version (the project version of the top-level CMakeLists.txt), as every binary's
//! --version prints it: "tgm-service 0.2.2".
const char* version();

class ArgReader {
 public:
  //! `program` is the prefix of every message and names the --help to see ("tgm-plc",
  //! "tgm-hmi simulate").
  ArgReader(int argc, char** argv, std::string program);

  //! Arguments are left, none was malformed and --help was not given (what follows --help is
  //! not read: `SUB --help --domain 999` printed the error and the help, then exited 0). The
  //! first `--` is passed over and ends the options: what follows it is read as positionals
  //! only, so a file named "-x.ngc" can be given as `-- -x.ngc`.
  bool more();
  //! Consumes `name VALUE` or `name=VALUE`; true when the current argument was `name`. A
  //! missing or empty value is reported (failed() becomes true, `value` is left empty), as is a
  //! VALUE after a space that starts with "--" (the next flag: `--out --quiet`; such a value
  //! goes as `name=--x`), and so is a second `name` unless repeatable(name) was called: one of
  //! the two values would be lost without a word (`--rel-speed 0.5 ... --rel-speed 2`).
  bool flag(const char* name, std::string& value);
  //! Lets `name` be given more than once; the caller combines the values (tgm-plc's
  //! --refuse-ack 51 --refuse-ack 52).
  void repeatable(const char* name) { repeatable_.emplace_back(name); }
  //! Consumes a flag without a value; `name=...` is reported as a malformed flag.
  bool boolean(const char* name, bool& value);
  //! Consumes `name N` with N a whole number lo..hi into `out`; a bad value is reported as
  //! "NAME must be LO..HI, not 'TEXT'" (`out` untouched).
  bool whole_flag(const char* name, long long lo, long long hi, long long& out);
  bool whole_flag(const char* name, int lo, int hi, int& out);
  //! Consumes `name X` with X a finite number that `ok` accepts into `out`; a bad value is
  //! reported as "NAME must be WHAT, not 'TEXT'" (`out` untouched). `what` words the range
  //! for a user: "0.01..2", "seconds > 0", "a number in (0, 1]".
  bool number_flag(const char* name, double& out, const char* what, bool (*ok)(double));
  //! Consumes --help or -h.
  bool help_flag();
  //! Consumes --version; the caller prints version_line() and exits 0.
  bool version_flag();
  std::string version_line() const { return program_ + " " + version(); }
  bool help_given() const { return help_; }
  //! Consumes a positional argument if `value` is still empty.
  bool positional(std::string& value);
  //! Consumes a negative whole number ("-2") as a word, not an option (Command codes and
  //! parameters). Flags read before it keep theirs: `--domain -1` is still --domain's value.
  bool negative_number(std::string& value);
  //! Consumes --domain, --profiles and --participant-prefix into `o` (a bad value is reported).
  bool dds_flag(DdsOverrides& o);
  //! Reports the current argument as an unknown option or an unexpected argument; returns 2.
  int fail();
  //! Prints "PROGRAM: reason" and the hint to --help unless a problem was reported already;
  //! returns the exit code 2.
  int usage_error(const std::string& reason);
  //! A file named on the command line: what named it ("FILE", "--csv") and the path ("" when
  //! not given).
  struct NamedFile {
    const char* what;
    std::string path;
  };
  //! Refuses, as a usage error, an output that would overwrite an input or another output: the
  //! same regular file under any name (a link, "./", another directory's path to it), or the
  //! same path not created yet. Devices and pipes (/dev/null, a FIFO) may be named more than
  //! once. Checked before anything is opened, so a typo such as `--out prog.ngc` cannot
  //! destroy the program. Returns false after reporting.
  bool distinct_files(const std::vector<NamedFile>& inputs, const std::vector<NamedFile>& outputs);
  //! The config file a program loads for `--config VALUE` (empty: not given, the default of
  //! default_config_path()), named for distinct_files().
  static NamedFile config_file(const std::string& config_flag);
  //! A problem was reported.
  bool failed() const { return failed_; }
  const std::string& program() const { return program_; }

 private:
  int argc_;
  char** argv_;
  int i_ = 1;
  std::string program_;
  bool help_ = false;
  bool failed_ = false;
  bool options_ended_ = false;           // `--` was read
  std::vector<std::string> given_;       // value flags read so far
  std::vector<std::string> repeatable_;  // repeatable(): may be given more than once
};

//! Runs a binary's main body so that what escapes it (memory running out, a thread that cannot
//! start, a library's exception nobody foresaw) ends with "PROGRAM: ..." on standard error and
//! exit code 1, not with an abort and a core dump. Expected problems are reported where they
//! happen; this is the last resort of tgm-hmi, tgm-plc and tgm-service.
int run_guarded(const char* program, int (*body)(int, char**), int argc, char** argv);

//! Has glibc take blocks up to 32 MiB from the heap and keep freed memory there, instead of
//! mapping each block over 128 kB afresh and unmapping it when freed. A block taken again then
//! reuses pages already touched: on a virtual machine a page fault costs microseconds, and
//! `tgm-hmi simulate` of 63,000 short chords spent 40 % of its time faulting in its record
//! ring (tests/bench/BENCHMARKS.md, session 54). For offline tools: a process that must not
//! fault on its cycle (tgm-service) locks and pre-faults its memory instead.
void prefer_heap_for_large_blocks();

}  // namespace tgm::cli
