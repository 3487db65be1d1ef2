// The argument reader shared by tgm-service, tgm-plc and the tgm-hmi subcommands.
#include "tgm/cli_args.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace tgm::cli {
namespace {

// argv for ArgReader: program name first, then `args` (kept alive by the struct).
struct Argv {
  std::vector<std::string> words;
  std::vector<char*> ptrs;
  explicit Argv(std::initializer_list<const char*> args) {
    words.emplace_back("prog");
    for (const char* a : args) words.emplace_back(a);
    for (std::string& w : words) ptrs.push_back(w.data());
  }
  int argc() const { return static_cast<int>(ptrs.size()); }
  char** argv() { return ptrs.data(); }
};

// Reads the arguments the way the binaries do: --out VALUE, --quiet, the DDS overrides, one
// positional FILE. Returns what was printed on standard error.
struct Parsed {
  std::string out, file, stderr_text;
  bool quiet = false, help = false, failed = false;
  DdsOverrides dds;
};
Parsed parse(std::initializer_list<const char*> args) {
  Argv a(args);
  ArgReader r(a.argc(), a.argv(), "prog sub");
  Parsed p;
  testing::internal::CaptureStderr();
  while (r.more()) {
    if (r.help_flag() || r.dds_flag(p.dds) || r.flag("--out", p.out) ||
        r.boolean("--quiet", p.quiet) || r.positional(p.file)) {
      continue;
    }
    EXPECT_EQ(r.fail(), 2);
  }
  p.stderr_text = testing::internal::GetCapturedStderr();
  p.help = r.help_given();
  p.failed = r.failed();
  return p;
}

TEST(CliArgs, ValuesWithASpaceOrAnEqualsSign) {
  Parsed p = parse({"--out", "a.csv", "--quiet", "prog.ngc"});
  EXPECT_FALSE(p.failed) << p.stderr_text;
  EXPECT_EQ(p.out, "a.csv");
  EXPECT_TRUE(p.quiet);
  EXPECT_EQ(p.file, "prog.ngc");
  EXPECT_EQ(p.stderr_text, "");
  p = parse({"--out=b=c.csv", "--domain=7", "--profiles", "x.xml", "--participant-prefix=cell2"});
  EXPECT_FALSE(p.failed) << p.stderr_text;
  EXPECT_EQ(p.out, "b=c.csv");  // only the first '=' separates
  EXPECT_EQ(p.dds.domain_id, 7);
  EXPECT_EQ(p.dds.profiles_file, "x.xml");
  EXPECT_EQ(p.dds.participant_prefix, "cell2");
  // A value may look like an option ("-5"); a lone "-" is a positional (standard input).
  p = parse({"--out", "-5", "-"});
  EXPECT_FALSE(p.failed) << p.stderr_text;
  EXPECT_EQ(p.out, "-5");
  EXPECT_EQ(p.file, "-");
}

// --help ends the reading, in whatever order: "SUB --help --domain 999" printed the error and
// the help and exited 0, "SUB --domain 999 --help" exited 2 without the help.
TEST(CliArgs, HelpEndsTheReading) {
  Parsed p = parse({"--help", "--domain", "999", "--bogus"});
  EXPECT_TRUE(p.help);
  EXPECT_FALSE(p.failed);
  EXPECT_EQ(p.stderr_text, "");
  p = parse({"--domain", "999", "--help"});
  EXPECT_TRUE(p.failed);
  EXPECT_FALSE(p.help);
  EXPECT_EQ(p.stderr_text, "prog sub: --domain must be 0..232, not '999'\n(see prog sub --help)\n");
}

TEST(CliArgs, EveryProblemIsNamedWithTheProgramAndAHintToHelp) {
  struct Case {
    std::initializer_list<const char*> args;
    const char* message;
  };
  const Case cases[] = {
      {{"--out"}, "prog sub: --out needs a value\n(see prog sub --help)\n"},
      {{"--out="}, "prog sub: --out needs a value, not an empty string\n(see prog sub --help)\n"},
      {{"--quiet=1"}, "prog sub: --quiet takes no value\n(see prog sub --help)\n"},
      {{"--bogus", "1"}, "prog sub: unknown option '--bogus'\n(see prog sub --help)\n"},
      {{"-x"}, "prog sub: unknown option '-x'\n(see prog sub --help)\n"},
      {{"a.ngc", "b.ngc"}, "prog sub: unexpected argument 'b.ngc'\n(see prog sub --help)\n"},
      {{"--domain", "233"},
       "prog sub: --domain must be 0..232, not '233'\n(see prog sub --help)\n"},
      {{"--domain"}, "prog sub: --domain needs a value\n(see prog sub --help)\n"},
      {{"--outfile", "x"}, "prog sub: unknown option '--outfile'\n(see prog sub --help)\n"},
      // A second value would silently replace the first (either spelling, DDS overrides too).
      {{"--out", "a.csv", "--out=b.csv"},
       "prog sub: --out is given more than once; give it once\n(see prog sub --help)\n"},
      {{"--domain", "3", "x.ngc", "--domain", "3"},
       "prog sub: --domain is given more than once; give it once\n(see prog sub --help)\n"},
  };
  for (const Case& c : cases) {
    const Parsed p = parse(c.args);
    EXPECT_TRUE(p.failed) << c.message;
    EXPECT_EQ(p.stderr_text, c.message);
  }
}

TEST(CliArgs, OnlyTheFirstProblemIsPrintedAndReadingStops) {
  Argv a({"--out", "a.csv", "stray", "--bogus"});
  ArgReader r(a.argc(), a.argv(), "prog");
  std::string out;
  bool quiet = false;
  ASSERT_TRUE(r.flag("--out", out));
  EXPECT_EQ(out, "a.csv");
  testing::internal::CaptureStderr();
  EXPECT_FALSE(r.boolean("--quiet", quiet));
  EXPECT_EQ(r.fail(), 2);
  EXPECT_FALSE(r.more());
  // A check after the loop (a value out of range) adds nothing to the first message.
  EXPECT_EQ(r.usage_error("--out must be a file name"), 2);
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "prog: unexpected argument 'stray'\n(see prog --help)\n");
  EXPECT_TRUE(r.failed());

  // A malformed value: the caller's own range check (on the empty value) prints nothing more.
  Argv b({"--count"});
  ArgReader s(b.argc(), b.argv(), "prog");
  std::string count = "unchanged";
  testing::internal::CaptureStderr();
  ASSERT_TRUE(s.flag("--count", count));
  EXPECT_EQ(count, "");
  EXPECT_EQ(s.usage_error("--count must be 1..10, not ''"), 2);
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "prog: --count needs a value\n(see prog --help)\n");
}

TEST(CliArgs, ARepeatableFlagMayBeGivenAgainAndOthersStayOnce) {
  Argv a({"--refuse", "51", "--refuse=52", "--quiet", "--quiet", "--rate", "1", "--rate", "2"});
  ArgReader r(a.argc(), a.argv(), "prog");
  r.repeatable("--refuse");
  std::vector<std::string> refused;
  std::string rate;
  bool quiet = false;
  testing::internal::CaptureStderr();
  while (r.more()) {
    if (std::string v; r.flag("--refuse", v)) {
      refused.push_back(v);
    } else if (!r.flag("--rate", rate) && !r.boolean("--quiet", quiet)) {
      r.fail();
    }
  }
  EXPECT_EQ(testing::internal::GetCapturedStderr(),
            "prog: --rate is given more than once; give it once\n(see prog --help)\n");
  EXPECT_TRUE(r.failed());
  EXPECT_EQ(refused, (std::vector<std::string>{"51", "52"}));
  EXPECT_TRUE(quiet);  // a switch given twice loses nothing
}

// Numbers read by whole_flag / number_flag: the value lands only when all of it is a number
// in range; otherwise one message names the flag, the range and the text given.
struct Numbers {
  int small = 7;
  long long big = 7;
  double seconds = 7.0;
  bool failed = false;
  std::string stderr_text;
};
Numbers parse_numbers(std::initializer_list<const char*> args) {
  Argv a(args);
  ArgReader r(a.argc(), a.argv(), "prog");
  Numbers n;
  testing::internal::CaptureStderr();
  while (r.more()) {
    if (r.whole_flag("--small", 0, 2, n.small) ||
        r.whole_flag("--big", 1LL, 5'000'000'000LL, n.big) ||
        r.number_flag("--seconds", n.seconds, "seconds > 0", [](double v) { return v > 0.0; })) {
      continue;
    }
    r.fail();
  }
  n.stderr_text = testing::internal::GetCapturedStderr();
  n.failed = r.failed();
  return n;
}

TEST(CliArgs, NumbersAreWholeInRangeAndFinite) {
  Numbers n = parse_numbers({"--small", "2", "--big=5000000000", "--seconds", "0.25"});
  EXPECT_FALSE(n.failed) << n.stderr_text;
  EXPECT_EQ(n.small, 2);
  EXPECT_EQ(n.big, 5'000'000'000LL);
  EXPECT_EQ(n.seconds, 0.25);
  struct Case {
    std::initializer_list<const char*> args;
    const char* message;
  };
  const Case cases[] = {
      {{"--small", "3"}, "prog: --small must be 0..2, not '3'\n(see prog --help)\n"},
      {{"--small", "-1"}, "prog: --small must be 0..2, not '-1'\n(see prog --help)\n"},
      // 2^32 + 1 must not wrap to 1 through a narrowing cast.
      {{"--small=4294967297"}, "prog: --small must be 0..2, not '4294967297'\n(see prog --help)\n"},
      {{"--small", "1x"}, "prog: --small must be 0..2, not '1x'\n(see prog --help)\n"},
      {{"--big", "1.5"}, "prog: --big must be 1..5000000000, not '1.5'\n(see prog --help)\n"},
      {{"--seconds", "0"}, "prog: --seconds must be seconds > 0, not '0'\n(see prog --help)\n"},
      {{"--seconds", "inf"}, "prog: --seconds must be seconds > 0, not 'inf'\n(see prog --help)\n"},
      {{"--seconds", "nan"}, "prog: --seconds must be seconds > 0, not 'nan'\n(see prog --help)\n"},
      {{"--seconds", "1e999"},
       "prog: --seconds must be seconds > 0, not '1e999'\n(see prog --help)\n"},
      {{"--seconds"}, "prog: --seconds needs a value\n(see prog --help)\n"},
      {{"--seconds="}, "prog: --seconds needs a value, not an empty string\n(see prog --help)\n"},
  };
  for (const Case& c : cases) {
    n = parse_numbers(c.args);
    EXPECT_TRUE(n.failed) << c.message;
    EXPECT_EQ(n.stderr_text, c.message);
    EXPECT_EQ(n.small, 7) << c.message;  // a bad value leaves the default
    EXPECT_EQ(n.big, 7) << c.message;
    EXPECT_EQ(n.seconds, 7.0) << c.message;
  }
}

// A value flag followed by another flag has lost its value: the next flag was taken as it
// (`tgm-plc --handshake-trace --no-events` wrote a file "--no-events" and left the events on,
// `--participant-prefix --quiet` joined DDS as "--quiet-plc"). Refused as a missing value,
// naming both; the reading stops there, so the flag is not read a second time. A value that
// starts with "--" on purpose goes after '='; one that starts with a single '-' is a value.
TEST(CliArgs, AFlagIsNoValueOfTheFlagBeforeIt) {
  struct Case {
    std::initializer_list<const char*> args;
    const char* message;
  };
  const Case cases[] = {
      {{"--out", "--quiet"},
       "prog sub: --out needs a value, not the flag '--quiet' (a value that starts with -- is "
       "given as --out=VALUE)\n(see prog sub --help)\n"},
      {{"--participant-prefix", "--quiet", "x.ngc"},
       "prog sub: --participant-prefix needs a value, not the flag '--quiet' (a value that "
       "starts with -- is given as --participant-prefix=VALUE)\n(see prog sub --help)\n"},
      {{"--domain", "--out", "a.csv"},
       "prog sub: --domain needs a value, not the flag '--out' (a value that starts with -- is "
       "given as --domain=VALUE)\n(see prog sub --help)\n"},
      {{"--out", "--"},
       "prog sub: --out needs a value, not the flag '--' (a value that starts with -- is given "
       "as --out=VALUE)\n(see prog sub --help)\n"},
  };
  for (const Case& c : cases) {
    const Parsed p = parse(c.args);
    EXPECT_TRUE(p.failed) << c.message;
    EXPECT_EQ(p.stderr_text, c.message);
    EXPECT_EQ(p.out, "") << c.message;
    EXPECT_FALSE(p.quiet) << c.message;
    EXPECT_EQ(p.dds.participant_prefix, "") << c.message;
  }
  Parsed p = parse({"--out=--quiet", "--participant-prefix=--cell", "--quiet"});
  EXPECT_FALSE(p.failed) << p.stderr_text;
  EXPECT_EQ(p.out, "--quiet");
  EXPECT_EQ(p.dds.participant_prefix, "--cell");
  EXPECT_TRUE(p.quiet);
  p = parse({"--out", "-", "--quiet"});
  EXPECT_FALSE(p.failed) << p.stderr_text;
  EXPECT_EQ(p.out, "-");
  // The numeric flags say the same (they said "must be 0..232, not '--out'").
  Numbers n = parse_numbers({"--small", "--seconds", "1"});
  EXPECT_EQ(n.stderr_text,
            "prog: --small needs a value, not the flag '--seconds' (a value that starts with -- "
            "is given as --small=VALUE)\n(see prog --help)\n");
  EXPECT_EQ(n.seconds, 7.0);
}

TEST(CliArgs, HelpIsConsumedAnywhere) {
  Parsed p = parse({"prog.ngc", "--help", "--out", "x"});
  EXPECT_TRUE(p.help);
  EXPECT_FALSE(p.failed);
  EXPECT_EQ(p.out, "");  // not read: see HelpEndsTheReading
  p = parse({"-h"});
  EXPECT_TRUE(p.help);
}

// --version is its own word (every binary prints "PROGRAM VERSION" and exits 0); a value or a
// prefix of it is not taken for it.
TEST(CliArgs, VersionIsAWordAndNamesTheProgram) {
  const std::string v = version();
  ASSERT_FALSE(v.empty());
  int dots = 0;
  for (char c : v) {
    EXPECT_TRUE((c >= '0' && c <= '9') || c == '.') << v;
    dots += c == '.';
  }
  EXPECT_EQ(dots, 2) << v;
  for (const char* word : {"--version", "--version=1", "--versio", "-v"}) {
    Argv a({word});
    ArgReader r(a.argc(), a.argv(), "tgm-plc");
    EXPECT_EQ(r.version_flag(), std::string(word) == "--version") << word;
    EXPECT_EQ(r.more(), std::string(word) != "--version") << word;
  }
  Argv a({"--version"});
  EXPECT_EQ(ArgReader(a.argc(), a.argv(), "tgm-plc").version_line(), "tgm-plc " + v);
}

// Negative numbers are words where a command takes them (Command -2, its parameters); a flag
// read first keeps its value, so `--domain -1` is still refused as a domain, with its text.
TEST(CliArgs, NegativeNumbersAreWordsButFlagValuesStayTheFlags) {
  Argv a({"-2", "100", "-7", "--domain", "-1", "-x", "--5"});
  ArgReader r(a.argc(), a.argv(), "prog sub");
  std::vector<std::string> words;
  DdsOverrides dds;
  testing::internal::CaptureStderr();
  while (r.more()) {
    if (r.dds_flag(dds)) continue;
    if (std::string w; r.positional(w) || r.negative_number(w)) {
      words.push_back(w);
      continue;
    }
    r.fail();
  }
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(words, (std::vector<std::string>{"-2", "100", "-7"}));
  EXPECT_EQ(err, "prog sub: --domain must be 0..232, not '-1'\n(see prog sub --help)\n");
  for (const char* bad : {"-x", "--5", "-", "-5a"}) {
    Argv b({bad});
    ArgReader rb(b.argc(), b.argv(), "prog sub");
    std::string w;
    EXPECT_FALSE(rb.negative_number(w)) << bad;
    EXPECT_TRUE(w.empty()) << bad;
  }
}

// The profiles file is checked before Fast DDS sees it: missing, or not a file (a directory,
// /dev/zero, which Fast DDS would read without end), each said as it is.
TEST(CliArgs, TheProfilesFileMustBeARegularFile) {
  DdsConfig c;
  c.profiles_file = "";
  EXPECT_EQ(dds_profiles_problem(c), "");  // none set: Fast DDS's defaults
  c.profiles_file = TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
  EXPECT_EQ(dds_profiles_problem(c), "");
  c.profiles_file = "/nonexistent/profiles.xml";
  EXPECT_EQ(dds_profiles_problem(c),
            "the DDS profiles file '/nonexistent/profiles.xml' does not exist (dds.profiles_file "
            "or --profiles)");
  for (const char* odd : {"/dev/zero", "/tmp"}) {
    c.profiles_file = odd;
    EXPECT_EQ(dds_profiles_problem(c),
              std::string("the DDS profiles file '") + odd +
                  "' is not a regular file (dds.profiles_file or --profiles)");
  }
}

// --security overrides dds.security ('off' turns it off); the files of a role are checked
// before Fast DDS sees them, and a missing one is named.
// --participant-prefix is checked as dds.participant_prefix is (DdsConfig::prefix_problem).
TEST(CliArgs, AParticipantPrefixFastDdsWouldCutIsRefused) {
  DdsOverrides o;
  std::string error;
  EXPECT_TRUE(o.take("--participant-prefix", std::string(201, 'p'), error));
  EXPECT_EQ(error,
            "--participant-prefix is 201 bytes long: at most 200 (Fast DDS cuts participant "
            "names at 255)");
  error.clear();
  EXPECT_TRUE(o.take("--participant-prefix", "", error));
  EXPECT_EQ(error, "--participant-prefix must not be empty");
  error.clear();
  EXPECT_TRUE(o.take("--participant-prefix", "cell-2", error));
  EXPECT_EQ(error, "");
  EXPECT_EQ(o.participant_prefix, "cell-2");
}

TEST(CliArgs, SecurityOverrideAndItsFiles) {
  DdsConfig c;
  c.security_dir = "/etc/tgm/sec";
  DdsOverrides o;
  std::string error;
  EXPECT_TRUE(o.take("--security", "off", error));
  EXPECT_EQ(error, "");
  o.apply(c);
  EXPECT_EQ(c.security_dir, "");
  EXPECT_EQ(dds_security_problem(c, "plc"), "");  // off: nothing to check
  EXPECT_TRUE(o.take("--security", "/nonexistent/sec", error));
  o.apply(c);
  EXPECT_EQ(c.security_dir, "/nonexistent/sec");
  EXPECT_EQ(dds_security_problem(c, "plc"),
            "the DDS Security directory '/nonexistent/sec' does not exist (dds.security or "
            "--security; config/security/tgm-security --out DIR makes one)");
  c.security_dir = TGM_SOURCE_DIR "/config";  // a directory without the files
  EXPECT_EQ(dds_security_problem(c, "hmi"),
            "DDS Security: '" TGM_SOURCE_DIR
            "/config/ca.pem' is missing (the hmi identity of "
            "config/security/tgm-security; dds.security or --security)");
  const auto files = dds_security_files("/s", "service");
  EXPECT_EQ(files[0], "/s/ca.pem");
  EXPECT_EQ(files[1], "/s/governance.p7s");
  EXPECT_EQ(files[2], "/s/service.pem");
  EXPECT_EQ(files[3], "/s/service.key");
  EXPECT_EQ(files[4], "/s/service.permissions.p7s");
  // Not a DDS flag: left to the binary.
  EXPECT_FALSE(o.take("--secure", "x", error));
}

// An output that names an input or another output, under any spelling, is refused before
// anything is opened; distinct files, paths not given and shared devices or pipes are not.
TEST(CliArgs, AnOutputMayNotBeAnInputOrAnotherOutput) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("tgm_cli_args_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "prog.ngc") << "G1 X1 F100\n";
  std::ofstream(dir / "cfg.yaml") << "cycle_time_us: 500\n";
  fs::create_symlink(dir / "prog.ngc", dir / "link.ngc");
  fs::create_hard_link(dir / "prog.ngc", dir / "hard.ngc");
  const std::string fifo = (dir / "pipe").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string prog = (dir / "prog.ngc").string(), cfg = (dir / "cfg.yaml").string();
  const std::string fresh = (dir / "new.csv").string();
  const std::string fresh_other = (dir / "sub" / ".." / "new.csv").string();

  struct Case {
    std::vector<ArgReader::NamedFile> outputs;
    std::string message;  // "" when accepted
  };
  const std::string destroy = ": writing it would destroy the input\n(see prog sub --help)\n";
  const std::string both = ": both outputs would be written into it\n(see prog sub --help)\n";
  const Case cases[] = {
      {{{"--out", prog}},
       "prog sub: --out '" + prog + "' is the same file as FILE '" + prog + "'" + destroy},
      {{{"--out", (dir / "link.ngc").string()}},
       "prog sub: --out '" + (dir / "link.ngc").string() + "' is the same file as FILE '" + prog +
           "'" + destroy},
      {{{"--out", (dir / "hard.ngc").string()}},
       "prog sub: --out '" + (dir / "hard.ngc").string() + "' is the same file as FILE '" + prog +
           "'" + destroy},
      {{{"--csv", fresh}, {"--blocks", cfg}},
       "prog sub: --blocks '" + cfg + "' is the same file as --config '" + cfg + "'" + destroy},
      {{{"--csv", fresh}, {"--blocks", fresh_other}},
       "prog sub: --blocks '" + fresh_other + "' is the same file as --csv '" + fresh + "'" + both},
      {{{"--csv", fresh}, {"--blocks", (dir / "other.csv").string()}, {"--lookahead", ""}}, ""},
      {{{"--csv", "/dev/null"}, {"--blocks", "/dev/null"}}, ""},
      {{{"--csv", fifo}, {"--blocks", fifo}}, ""},
      {{{"--out", (dir / "sub").string()}}, ""},  // a directory: opening it fails on its own
  };
  for (const Case& c : cases) {
    Argv a({});
    ArgReader r(a.argc(), a.argv(), "prog sub");
    testing::internal::CaptureStderr();
    const bool ok = r.distinct_files({{"FILE", prog}, {"--config", cfg}}, c.outputs);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(ok, c.message.empty()) << c.outputs[0].path;
    EXPECT_EQ(r.failed(), !c.message.empty()) << c.outputs[0].path;
    EXPECT_EQ(err, c.message);
  }
  // Nothing was created or changed by the check.
  EXPECT_FALSE(fs::exists(fresh));
  std::ifstream in(prog);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "G1 X1 F100\n");
  fs::remove_all(dir);
}

// The last resort of every binary's main: what escapes ends with words and exit code 1.
TEST(RunGuarded, WhatEscapesEndsWithWordsAndExitOne) {
  const auto run = [](int (*body)(int, char**), std::string& err) {
    testing::internal::CaptureStderr();
    const int code = run_guarded("prog", body, 0, nullptr);
    err = testing::internal::GetCapturedStderr();
    return code;
  };
  std::string err;
  EXPECT_EQ(run([](int, char**) { return 7; }, err), 7);
  EXPECT_EQ(err, "");
  EXPECT_EQ(run([](int, char**) -> int { throw std::bad_alloc(); }, err), 1);
  EXPECT_EQ(err, "prog: out of memory\n");
  EXPECT_EQ(
      run([](int, char**) -> int { throw std::system_error(EAGAIN, std::generic_category()); },
          err),
      1);
  EXPECT_EQ(err, "prog: the system refused: Resource temporarily unavailable\n");
  EXPECT_EQ(run([](int, char**) -> int { throw std::runtime_error("odd"); }, err), 1);
  EXPECT_EQ(err, "prog: internal error: odd\n");
}

}  // namespace
}  // namespace tgm::cli
