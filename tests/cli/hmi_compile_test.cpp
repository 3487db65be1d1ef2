// tgm-hmi compile as a user runs it: exit codes, the error format, nothing written on error, and
// the streamed binary output equal to the in-process encoding.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_fixture.hpp"

#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {
namespace {

using test::ProcessResult;
using test::slurp;
namespace fs = std::filesystem;
using HmiCompile = test::CliTest;

const char* const kConfig = test::kDefaultConfig;

// Temporary outputs (AtomicFile's "<path>.tmp-<pid>") left in `dir`.
int temporaries(const fs::path& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    n += e.path().filename().string().find(".tmp-") != std::string::npos ? 1 : 0;
  }
  return n;
}

TEST_F(HmiCompile, ExampleProgramWritesIntercodeEqualToTheInProcessEncoding) {
  const fs::path prog = test::kManualExample;
  const fs::path out = dir_ / "ex.tgmi";
  const ProcessResult r = run("compile " + prog.string() + " --config " + kConfig + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("13 records"), std::string::npos) << r.err;

  const auto cfg = load_config_file(kConfig);
  ASSERT_TRUE(cfg.config);
  const CompileResult c =
      compile_gcode(slurp(prog), CompileOptions::from_machine(cfg.config->machine, 0));
  ASSERT_TRUE(c.ok());
  std::string expected;
  encode_intercode(c.program, expected);
  EXPECT_EQ(slurp(out), expected);
  EXPECT_EQ(temporaries(dir_), 0) << "a temporary file was left";
  // '-' is standard output, as simulate's --csv - (it wrote a file named '-'); not with --dump.
  const ProcessResult piped = run("compile " + prog.string() + " --config " + kConfig + " --out -");
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  EXPECT_EQ(piped.out, expected);
  const ProcessResult both =
      run("compile " + prog.string() + " --config " + kConfig + " --out - --dump text");
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_NE(both.err.find("--out - and --dump both write standard output"), std::string::npos)
      << both.err;
}

// G41/G42 offset the path by the radius of D, else of the active tool's table entry; with no
// tool (T0, the default config's initial tool) and no D the radius is 0: compile, --dump and
// simulate say so once, naming the first record that moves so; a program with a radius gets
// no note.
// --block-delete run|skip: the operator's switch over the lines that start with '/'; unset,
// such a line is an error that says how to set it. Intercode was compiled with its choice made.
TEST_F(HmiCompile, BlockDeleteRunsOrSkipsTheOptionalBlocks) {
  const fs::path prog = dir_ / "optional.ngc";
  std::ofstream(prog) << "G90 G1 X10 F1000\n/G1 Y5\nG1 X0\nM2\n";
  const std::string base = "compile " + prog.string() + " --config " + kConfig;
  const ProcessResult unset = run(base);
  EXPECT_EQ(unset.exit_code, 2);
  EXPECT_NE(unset.err.find("optional.ngc:2:1: error: block delete '/': whether such lines run or "
                           "are skipped is not set"),
            std::string::npos)
      << unset.err;
  const ProcessResult on = run(base + " --block-delete run --dump text");
  ASSERT_EQ(on.exit_code, 0) << on.err;
  EXPECT_NE(on.out.find("Y5.0000"), std::string::npos) << on.out;
  EXPECT_EQ(std::count(on.out.begin(), on.out.end(), '\n'), 4) << on.out;  // a line a record
  const fs::path out = dir_ / "optional.tgmi";
  const ProcessResult off = run(base + " --block-delete skip --out " + out.string());
  ASSERT_EQ(off.exit_code, 0) << off.err;
  EXPECT_NE(off.err.find("3 records"), std::string::npos) << off.err;
  const ProcessResult bad = run(base + " --block-delete yes");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--block-delete takes run or skip, not 'yes'"), std::string::npos)
      << bad.err;
  const ProcessResult again =
      run("compile " + out.string() + " --config " + kConfig + " --block-delete run");
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_NE(again.err.find("--block-delete: the file is intercode, compiled already"),
            std::string::npos)
      << again.err;
  // simulate takes the same switch.
  const ProcessResult sim =
      run("simulate " + prog.string() + " --config " + kConfig + " --block-delete skip --quiet");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  EXPECT_NE(sim.out.find("distance:  20.0000 mm"), std::string::npos) << sim.out;
}

TEST_F(HmiCompile, CompensationIsAppliedAndRadiusZeroIsNotedOnce) {
  const std::string note =
      "note: the first move under G42 (tool radius compensation) with radius 0 (tool T0): the tool "
      "centre follows the "
      "programmed contour; D<mm> on the G42 line, or a T with a radius in the tool table, "
      "offsets it";
  const ProcessResult ex =
      run("compile " + std::string(test::kManualExample) + " --config " + kConfig);
  ASSERT_EQ(ex.exit_code, 0) << ex.err;
  EXPECT_NE(ex.err.find(std::string("manual_example.ngc:4: ") + note), std::string::npos) << ex.err;
  EXPECT_EQ(ex.err.find("note:"), ex.err.rfind("note:")) << ex.err;

  const fs::path zero =
      write("zero.ngc", "G90 G1 X1 F600\nG41\nM51\nG1 X5\nG1 Y5\nG40\nG1 X0\nM2\n");
  // From its intercode too (the records are seen as the load checks them).
  const fs::path tgmi = dir_ / "zero.tgmi";
  ASSERT_EQ(run("compile " + zero.string() + " --config " + kConfig + " --out " + tgmi.string())
                .exit_code,
            0);
  for (const fs::path& prog : {zero, tgmi}) {
    for (const char* cmd : {"compile ", "simulate "}) {
      const ProcessResult r = run(cmd + prog.string() + " --config " + kConfig);
      ASSERT_EQ(r.exit_code, 0) << cmd << r.err;
      // The line is the G-code's: at a .tgmi it is named as the source line, not as one of
      // the binary file's.
      const std::string where = prog == tgmi ? " (source line 4)" : ":4";
      EXPECT_NE(r.err.find(prog.filename().string() + where +
                           ": note: the first move under G41 (tool radius compensation) with "
                           "radius 0 (tool T0)"),
                std::string::npos)
          << cmd << r.err;
    }
  }

  // D0 with a tool that has a radius: the note names the D0 (it advised a T with a radius,
  // which the program had).
  const fs::path d0 = write("d0.ngc", "T1\nG90 G1 X1 F600\nG41 D0\nG1 X5\nM2\n");
  const ProcessResult d0_run = run("compile " + d0.string() + " --config " + kConfig);
  ASSERT_EQ(d0_run.exit_code, 0) << d0_run.err;
  EXPECT_NE(d0_run.err.find("d0.ngc:4: note: the first move under G41 (tool radius compensation) "
                            "with radius 0 (D0 on the G41 line, where tool T1 has 3 mm in the "
                            "tool table): the tool centre follows the programmed contour\n"),
            std::string::npos)
      << d0_run.err;

  // D 2.5 on the left: the entry from X1 ends where the offset lines of X5 and Y5 meet
  // (concave corner), the rise runs at X2.5, G40's move leads back to the contour.
  const fs::path left =
      write("left.ngc", "G90 G1 X1 F600\nG41 D2.5\nM51\nG1 X5\nG1 Y5\nG40\nG1 X0\nM2\n");
  const ProcessResult dump =
      run("compile " + left.string() + " --config " + kConfig + " --dump text");
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  EXPECT_EQ(dump.err.find("note:"), std::string::npos) << dump.err;
  EXPECT_NE(dump.out.find("4  G1  X2.5000 Y2.5000 Z0.0000  F600\n"), std::string::npos) << dump.out;
  EXPECT_NE(dump.out.find("5  G1  X2.5000 Y5.0000 Z0.0000  F600\n"), std::string::npos) << dump.out;
  EXPECT_NE(dump.out.find("7  G1  X0.0000 Y5.0000 Z0.0000  F600\n"), std::string::npos) << dump.out;
  // T3's radius from the default tool table (1.5 mm), on the right: a convex corner gets an
  // arc around it.
  const fs::path tool =
      write("tool.ngc", "G90 G1 X-10 F600\nT3 G42\nG1 X0\nG1 Y10\nG40\nG0 X20 Y20\nM2\n");
  const ProcessResult td =
      run("compile " + tool.string() + " --config " + kConfig + " --dump text");
  ASSERT_EQ(td.exit_code, 0) << td.err;
  EXPECT_NE(td.out.find("3  G1  X0.0000 Y-1.5000 Z0.0000  F600\n"), std::string::npos) << td.out;
  EXPECT_NE(td.out.find("4  G3  X1.5000 Y0.0000 Z0.0000  centre(X0.0000 Y0.0000) R1.5000"),
            std::string::npos)
      << td.out;
  EXPECT_NE(td.out.find("4  G1  X1.5000 Y10.0000 Z0.0000  F600\n"), std::string::npos) << td.out;

  // A concave corner the tool cannot reach is an error at its line, and nothing is written.
  const fs::path gouge =
      write("gouge.ngc", "G90 G1 X-5 F600\nG41 D2\nG1 X10\nG1 Y1\nG1 X20\nG40\nG0 X30\nM2\n");
  const ProcessResult g = run("compile " + gouge.string() + " --config " + kConfig);
  EXPECT_EQ(g.exit_code, 2) << g.err;
  EXPECT_NE(g.err.find("gouge.ngc:4:1: error: tool radius compensation: the tool (radius 2.0000 "
                       "mm) cannot reach the concave corner at line 3's end"),
            std::string::npos)
      << g.err;
}

TEST_F(HmiCompile, LongProgramStreamsInPiecesAndDecodes) {
  // More than 1 MiB of records, with a subroutine so both execution modes run.
  std::string text = "G91 G1 F1000\nG25 L1\n";
  for (int i = 0; i < 40000; ++i) text += (i % 2) ? "G1 X0.1 Y-0.05\n" : "G2 X0.2 I0.1\n";
  text += "M30\nG29 L1\nG1 Z1\nG1 Z-1\nM17\n";
  const fs::path prog = write("long.ngc", text);
  const fs::path out = dir_ / "long.tgmi";
  const ProcessResult r = run("compile " + prog.string() + " --config " + kConfig + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  Program p;
  std::string err;
  ASSERT_TRUE(decode_intercode(slurp(out), p, err)) << err;
  ASSERT_EQ(p.segments.size(), 40003u);
  EXPECT_DOUBLE_EQ(p.segments[1].end[2], 0.0);  // subroutine: Z up and down
  EXPECT_EQ(p.segments.back().m_kind, MKind::kProgramEnd);
  EXPECT_NEAR(p.segments[40001].end[0], 20000 * 0.2 + 20000 * 0.1, 1e-6);
}

// A dump is written a piece at a time as the records are read back: it was built whole first
// (2 GB for 6 million lines, and nothing for `| head` to read before all of it was made). The
// pieces join into the dump of the whole program made in-process, from G-code and from its
// intercode; --out beside --dump writes what --out alone writes.
TEST_F(HmiCompile, ALongDumpIsWrittenInPiecesThatMakeTheWholeDump) {
  std::string text = "G91 G1 F1000\nG25 L1\n";
  for (int i = 0; i < 40000; ++i) text += (i % 2) ? "G1 X0.1 Y-0.05\n" : "G2 X0.2 I0.1\n";
  text += "M7 Q1\nM29 (half way)\nM30\nG29 L1\nG1 Z1\nG1 Z-1\nM17\n";
  const fs::path prog = write("long.ngc", text);
  const fs::path alone = dir_ / "alone.tgmi", beside = dir_ / "beside.tgmi";
  ProcessResult r =
      run("compile " + prog.string() + " --config " + kConfig + " --out " + alone.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  Program p;
  std::string err;
  ASSERT_TRUE(decode_intercode(slurp(alone), p, err)) << err;
  ASSERT_EQ(p.segments.size(), 40005u);
  for (const std::string kind : {"jsonl", "text"}) {
    std::string whole;
    if (kind == "jsonl") {
      dump_jsonl(p, whole);
    } else {
      dump_text(p, whole);
    }
    ASSERT_GT(whole.size(), 2u << 20);  // three pieces at least
    r = run("compile " + prog.string() + " --config " + kConfig + " --dump " + kind + " --out " +
            beside.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.out == whole) << kind << ": " << r.out.size() << " bytes, not " << whole.size();
    EXPECT_TRUE(slurp(beside) == slurp(alone)) << kind;
    r = run("compile " + alone.string() + " --config " + kConfig + " --dump " + kind);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.out == whole) << kind << ", from intercode: " << r.out.size() << " bytes";
  }
#if !defined(__SANITIZE_ADDRESS__)  // AddressSanitizer reserves far more address space
  // A million records dump in 150 MB of address space; held whole as Segments (152 bytes a
  // record) beside their dump, they ran out of memory there.
  std::string million = "G91 F6000\n";
  for (int k = 0; k < 1'000'000; ++k) million += "G1 X0.01\n";
  const fs::path big = write("million.ngc", million + "M2\n");
  r = run("compile " + big.string() + " --config " + kConfig + " --dump text",
          "ulimit -v 150000; ");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1'000'001);
  EXPECT_TRUE(r.out.ends_with("1000002  M   M2 (program_end)\n"))
      << r.out.substr(r.out.size() - 80);
#endif
}

// The summary counts in words that agree with the counts ("1 M-functions" before).
TEST_F(HmiCompile, TheSummaryCountsRecordsMFunctionsAndMessages) {
  const fs::path one = write("one.ngc", "M2\n");
  ProcessResult r = run("compile " + one.string() + " --config " + kConfig);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, one.string() + ": 1 record (1 M-function, 0 messages)\n");
  const fs::path more = write("more.ngc", "G1 X1 F100\nM29 (a)\nM29 (b)\nM3\nM2\n");
  r = run("compile " + more.string() + " --config " + kConfig);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, more.string() + ": 5 records (2 M-functions, 2 messages)\n");
}

TEST_F(HmiCompile, ErrorsAreAllListedWithFileLineColumnAndNothingIsWritten) {
  const fs::path prog = write("bad.ngc", "G90\nG1 X1 Q2\nG7\nG25 L4\n");
  const fs::path out = dir_ / "bad.tgmi";
  std::ofstream(out) << "previous";
  const ProcessResult r = run("compile " + prog.string() + " --config " + kConfig + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  const std::string f = prog.string();
  EXPECT_EQ(r.err, f + ":2:7: error: unknown word 'Q2'\n" + f +
                       ":3:1: error: unknown G-code G7\n" + f +
                       ":4:5: error: unknown label L4 (define it with G29 L4)\n" + f +
                       ": 3 errors, no intercode written\n");
  EXPECT_EQ(slurp(out), "previous");
  EXPECT_EQ(temporaries(dir_), 0) << "a temporary file was left";
  EXPECT_TRUE(r.out.empty());
}

// A program of comments and settings alone compiled to "0 records", which simulate and run
// then refused: compile refuses it as they do, with and without a dump, and writes nothing.
TEST_F(HmiCompile, AProgramWithoutRecordsIsAnErrorAndNothingIsWritten) {
  const fs::path prog = write("comments.ngc", "(only a comment)\nG90 G17\n");
  const fs::path out = dir_ / "comments.tgmi";
  const std::string says = prog.string() +
                           ": error: the program has no records (no move, dwell or M-function): "
                           "no intercode written\n";
  for (const std::string& extra : {" --out " + out.string(), std::string(" --dump jsonl")}) {
    const ProcessResult r = run("compile " + prog.string() + " --config " + kConfig + extra);
    EXPECT_EQ(r.exit_code, 2) << extra;
    EXPECT_EQ(r.err, says) << extra;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(temporaries(dir_), 0) << "a temporary file was left";
}

TEST_F(HmiCompile, DumpJsonlMatchesTheGoldenFile) {
  const ProcessResult r = run("compile " + std::string(test::kManualExample) + " --config " + kConfig +
                              " --dump jsonl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, slurp(TGM_SOURCE_DIR "/tests/programs/manual_example.jsonl"));
}

// --out is written into place by a rename: through a symbolic link that must replace the file the
// link names, not the link, and a pipe or device (a FIFO, /dev/stdout, /dev/full) must be written
// into, not renamed over (as root, /dev/full became a regular file). The test uses a FIFO of its
// own: run against a broken tgm-hmi it must not replace a device of the machine.
TEST_F(HmiCompile, OutputThroughALinkOrIntoAPipeKeepsTheLinkAndThePipe) {
  const std::string compile =
      "compile " + std::string(test::kManualExample) + " --config " + kConfig + " --out ";
  const fs::path plain = dir_ / "plain.tgmi";
  ASSERT_EQ(run(compile + plain.string()).exit_code, 0);
  const std::string expected = slurp(plain);
  ASSERT_FALSE(expected.empty());
  // Binary: compared whole, reported by size.
  auto same = [&](const std::string& got) {
    return got == expected ? ::testing::AssertionSuccess()
                           : ::testing::AssertionFailure() << got.size() << " bytes, not the "
                                                           << expected.size() << " expected";
  };

  const fs::path link = dir_ / "link.tgmi";
  fs::create_symlink("real.tgmi", link);  // dangling until the first write
  for (int i = 0; i < 2; ++i) {
    const ProcessResult r = run(compile + link.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::is_symlink(link));
    EXPECT_TRUE(same(slurp(dir_ / "real.tgmi")));
  }
  const fs::path bad = write("bad.ngc", "G1 X1 F600\nG7\n");
  EXPECT_EQ(
      run("compile " + bad.string() + " --config " + kConfig + " --out " + link.string()).exit_code,
      2);
  EXPECT_TRUE(same(slurp(dir_ / "real.tgmi")));  // an error leaves the file as it was

  // A FIFO read by a background cat (ended by timeout if the pipe were replaced: no hang).
  const fs::path fifo = dir_ / "fifo", got = dir_ / "got", done = dir_ / "done";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string reader = "(timeout 20 cat " + fifo.string() + " > " + got.string() +
                             "; touch " + done.string() + ") &";
  ASSERT_EQ(std::system(reader.c_str()), 0);
  const ProcessResult r = run(compile + fifo.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_fifo(fifo));
  for (int i = 0; i < 250 && !fs::exists(done); ++i) ::usleep(100'000);
  EXPECT_TRUE(same(slurp(got)));
}

TEST_F(HmiCompile, BadCommandLinesAndFilesAreUsageErrors) {
  ProcessResult r = run("compile");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("a G-code FILE is required"), std::string::npos);
  r = run("compile x.ngc --frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown option '--frobnicate'"), std::string::npos);
  r = run("compile x.ngc --dump xml");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--dump takes jsonl or text, not 'xml'"), std::string::npos);
  r = run("compile /nonexistent.ngc --config " + std::string(kConfig));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "/nonexistent.ngc: error: cannot open: No such file or directory\n");
  r = run("compile x.ngc --config " + std::string(kConfig) + " --interpolator 5");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--interpolator must be 0..2 (the config has 3), not '5'"),
            std::string::npos);
  r = run("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown command 'frobnicate'"), std::string::npos);
  // Inputs without end are refused at once, not read until the memory runs out.
  r = run("compile /dev/zero --config " + std::string(kConfig));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "/dev/zero: error: is a device, not a file\n");
  // A named pipe is read as a pipe once a writer opens it; until then the wait is said.
  const fs::path fifo = dir_ / "post.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  r = run(
      "compile " + fifo.string() + " --config " + kConfig,
      "(timeout 20 sh -c 'sleep 0.3; printf \"G1 X1 F100\\nM30\\n\" >" + fifo.string() + "' &) ; ");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, fifo.string() +
                       ": a named pipe: waiting for a writer to open it (Ctrl-C stops)\n" +
                       fifo.string() + ": 2 records (1 M-function, 0 messages)\n");
  const fs::path prog = write("p.ngc", "G1 X1 F100\n");
  r = run("compile " + prog.string() + " --config /dev/zero");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err,
            "/dev/zero: is a character device, not a config file\n"
            "tgm-hmi compile: the config /dev/zero has 1 problem\n");
  // A config path taken from $TGM_CONFIG is said to come from there.
  r = run("compile " + prog.string(), "TGM_CONFIG=/nonexistent/machine.yaml ");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("tgm-hmi compile: the config /nonexistent/machine.yaml (from $TGM_CONFIG) "
                       "has 1 problem\n"),
            std::string::npos)
      << r.err;
  // An --out that cannot be written is named with its flag, before anything is compiled, and
  // is bad input like the rest (it said "DIR: error: is a directory", exit code 1).
  r = run("compile " + prog.string() + " --config " + kConfig + " --out " + dir_.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "tgm-hmi compile: --out " + dir_.string() +
                       ": is a directory\n(see tgm-hmi compile --help)\n");
  r = run("compile " + prog.string() + " --config " + kConfig + " --out " +
          (dir_ / "no" / "p.tgi").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err,
            "tgm-hmi compile: --out " + (dir_ / "no" / "p.tgi").string() +
                ": cannot create: No such file or directory\n(see tgm-hmi compile --help)\n");
}

// Intercode is known by its content: `compile` checks it and dumps it, copies it or sums it up
// (it was parsed as G-code: 277 errors of binary garbage for the manual's example), and
// `simulate` runs it under any name. A damaged file is refused; --start is the G-code's.
// A version 2 file (no checksum) is read as before, with a note that damage to it cannot be
// found and how to rewrite it: a flipped bit ran as another program without a word.
TEST_F(HmiCompile, AVersionTwoFileIsReadWithANoteThatItHasNoChecksum) {
  const CompileResult c = compile_gcode("G90 G1 X10 F1000\nM2\n", {});
  ASSERT_TRUE(c.ok());
  std::string bytes;
  encode_intercode(c.program, bytes);
  // Version 2: version 4 without the start point after the header and without the checksum.
  bytes.erase(IntercodeEncoder::kCountOffset + 8, 3 * sizeof(double));
  bytes.resize(bytes.size() - 4);
  bytes[4] = 2;
  const fs::path v2 = write("old.tgmi", bytes);
  const ProcessResult r = run("compile " + v2.string() + " --config " + kConfig + " --dump text");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("G1  X10.0000"), std::string::npos) << r.out;
  EXPECT_EQ(r.err, v2.string() +
                       ": note: version 2 intercode carries no checksum, so damage to "
                       "it cannot be found; `tgm-hmi compile " +
                       v2.string() + " --out NEW` writes it as the current version\n");
}

TEST_F(HmiCompile, IntercodeGivenAsTheProgramIsReadAsIntercode) {
  const fs::path tgmi = dir_ / "ex.tgmi";
  ProcessResult r = run("compile " + std::string(test::kManualExample) + " --config " + kConfig +
                        " --out " + tgmi.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string bytes = slurp(tgmi);
  const fs::path renamed = write("ex.bin", bytes);
  const std::string note =
      " (source line 4): note: the first move under G42 (tool radius compensation) with radius 0 "
      "(tool T0): the tool "
      "centre follows the programmed contour; D<mm> on the G42 line, or a T with a radius in the "
      "tool table, offsets it\n";
  r = run("compile " + renamed.string() + " --config " + kConfig);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, renamed.string() +
                       ": intercode for the axes XYZ, compiled from X0 Y0 Z0: 13 records (4 "
                       "M-functions, 0 messages)\n" +
                       renamed.string() + note);
  // The dump is the one of the G-code it came from.
  const ProcessResult from_gcode = run("compile " + std::string(test::kManualExample) +
                                       " --config " + kConfig + " --dump jsonl");
  r = run("compile " + renamed.string() + " --config " + kConfig + " --dump jsonl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(r.out.empty());
  EXPECT_EQ(r.out, from_gcode.out);
  // --out writes a checked copy.
  const fs::path copy = dir_ / "copy.tgmi";
  r = run("compile " + renamed.string() + " --config " + kConfig + " --out " + copy.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(slurp(copy), bytes);
  // Simulated under the other name, it ends where the G-code does.
  const ProcessResult sim_bin = run("simulate " + renamed.string() + " --config " + kConfig);
  const ProcessResult sim_ngc =
      run("simulate " + std::string(test::kManualExample) + " --config " + kConfig);
  ASSERT_EQ(sim_bin.exit_code, 0) << sim_bin.err;
  const auto end_line = [](const std::string& out) {
    const auto at = out.find("end:");
    return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
  };
  EXPECT_NE(end_line(sim_ngc.out), "");
  EXPECT_EQ(end_line(sim_bin.out), end_line(sim_ngc.out));
  // Damaged, and with --start.
  std::string damaged = bytes;
  damaged[40] = static_cast<char>(damaged[40] ^ 0x5A);
  const fs::path bad = write("bad.bin", damaged);
  r = run("compile " + bad.string() + " --config " + kConfig);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.find(bad.string() + ": error: checksum mismatch"), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  r = run("compile " + renamed.string() + " --config " + kConfig + " --start X1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--start applies to G-code; " + renamed.string() + " is intercode"),
            std::string::npos)
      << r.err;
}

// Any other binary file is one error, at its first 0x00 byte.
TEST_F(HmiCompile, ABinaryFileIsOneError) {
  std::string blob = "G1 X1 F100\n";
  for (int i = 0; i < 4096; ++i) blob.push_back(static_cast<char>((i * 37) & 0xFF));
  const fs::path prog = write("blob.ngc", blob);
  const ProcessResult r = run("compile " + prog.string() + " --config " + kConfig);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, prog.string() +
                       ":2:1: error: a 0x00 byte: this is a binary file, not G-code text\n" +
                       prog.string() + ": 1 error, no intercode written\n");
}

// A typo that names the program as an output (`--out prog.ngc`, `--csv prog.ngc`, through a
// link) is a usage error before anything is opened: the program is still there, unchanged.
TEST_F(HmiCompile, AnOutputNamingTheProgramIsRefusedAndTheProgramKept) {
  const std::string text = "G90 G1 X10 F600\nM2\n";
  const fs::path prog = write("prog.ngc", text);
  fs::create_symlink(prog, dir_ / "link.ngc");
  const std::string cfg = " --config " + std::string(kConfig);
  const std::string cases[] = {
      "compile " + prog.string() + cfg + " --out " + prog.string(),
      "compile " + (dir_ / "link.ngc").string() + cfg + " --out " + prog.string(),
      "simulate " + prog.string() + cfg + " --csv " + (dir_ / "link.ngc").string(),
      "simulate " + prog.string() + cfg + " --blocks " + prog.string(),
      "simulate " + prog.string() + cfg + " --csv " + (dir_ / "a.csv").string() + " --lookahead " +
          (dir_ / "sub" / ".." / "a.csv").string(),
  };
  fs::create_directories(dir_ / "sub");
  for (const std::string& c : cases) {
    const ProcessResult r = run(c);
    EXPECT_EQ(r.exit_code, 2) << c;
    EXPECT_NE(r.err.find("is the same file as"), std::string::npos) << c << "\n" << r.err;
    EXPECT_EQ(r.out, "") << c;
    EXPECT_EQ(slurp(prog), text) << c;
    EXPECT_FALSE(fs::exists(dir_ / "a.csv")) << c;
  }
  // /dev/null may take several outputs.
  const ProcessResult r =
      run("simulate " + prog.string() + cfg + " --csv /dev/null --blocks /dev/null --quiet");
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

// The temporary output never touches a file of the user's: "<out>.tmp" next to --out keeps
// its content through a compile that writes --out and one that fails.
TEST_F(HmiCompile, AUsersTmpFileNextToTheOutputIsLeftAlone) {
  const fs::path good = write("good.ngc", "G90 G1 X1 F100\nM2\n"), bad = write("bad.ngc", "G7\n");
  const fs::path out = dir_ / "prog.tgmi", mine = dir_ / "prog.tgmi.tmp";
  std::ofstream(mine) << "my notes";
  EXPECT_EQ(
      run("compile " + good.string() + " --config " + kConfig + " --out " + out.string()).exit_code,
      0);
  EXPECT_EQ(
      run("compile " + bad.string() + " --config " + kConfig + " --out " + out.string()).exit_code,
      2);
  EXPECT_EQ(slurp(mine), "my notes");
  EXPECT_GT(fs::file_size(out), 0u);
  EXPECT_EQ(temporaries(dir_), 0);
}

TEST_F(HmiCompile, BadConfigNamesTheKey) {
  const fs::path cfg = write("bad.yaml", "cycle_time_us: 400\ncompiler: {distance_mode: G92}\n");
  const ProcessResult r = run("compile x.ngc --config " + cfg.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(cfg.string() + ":2: compiler.distance_mode: must be G90 or G91, not 'G92'"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("cycle_time_us: must be 250, 500 or 1000, not 400"), std::string::npos);
}

// Standard output that cannot be written (a full disk: /dev/full) fails the command, whatever it
// printed there: a summary, a dump, the help. The failure is said once, with its reason (the
// dump's used to be followed by a second, reasonless "cannot write standard output").
TEST_F(HmiCompile, StandardOutputThatIsLostIsAnError) {
  const fs::path err = dir_ / "err";
  for (const std::string& args :
       {std::string("--help"),
        "simulate " + std::string(test::kManualExample) + " --config " + kConfig,
        "compile " + std::string(test::kManualExample) + " --config " + kConfig + " --dump text",
        "compile " + std::string(test::kManualExample) + " --config " + kConfig +
            " --dump jsonl"}) {
    const std::string cmd =
        std::string(TGM_HMI) + " " + args + " >/dev/full 2>" + err.string() + " </dev/null";
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << args;
    EXPECT_EQ(WEXITSTATUS(status), 1) << args;
    const std::string said = slurp(err);
    const std::size_t at = said.find("No space left on device");
    EXPECT_NE(at, std::string::npos) << args << said;
    EXPECT_EQ(said.find("cannot write", said.find("cannot write") + 1), std::string::npos)
        << args << said;
    if (args.rfind("compile", 0) == 0) {
      EXPECT_NE(said.find("tgm-hmi compile: cannot write the dump: No space left on device\n"),
                std::string::npos)
          << said;
    }
  }
}

TEST_F(HmiCompile, HelpIsPrintedAndSucceeds) {
  ProcessResult r = run("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("usage: tgm-hmi COMMAND"), std::string::npos);
  r = run("compile --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("usage: tgm-hmi compile FILE"), std::string::npos);
  // `help COMMAND` is `COMMAND --help` (it printed the general usage).
  for (const char* cmd : {"compile", "simulate"}) {
    r = run(std::string("help ") + cmd);
    EXPECT_EQ(r.exit_code, 0) << cmd << r.err;
    EXPECT_EQ(r.out.rfind(std::string("usage: tgm-hmi ") + cmd + " FILE", 0), 0u) << r.out;
  }
  r = run("help compyle");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("tgm-hmi help: unknown command 'compyle'", 0), 0u) << r.err;
  r = run("help compile simulate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("takes one command, not 'simulate'"), std::string::npos) << r.err;
}

// `--` ends the options: a program named "-x.ngc" follows it (it was "unknown option '--'"),
// and a flag after it is a file name, not a flag.
TEST_F(HmiCompile, DoubleDashEndsTheOptions) {
  write("-x.ngc", "G90 G1 X1 F600\nM2\n");
  ProcessResult r = run("compile --config " + std::string(kConfig) + " -- -x.ngc",
                        "cd " + dir_.string() + " && ");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("-x.ngc: 2 records"), std::string::npos) << r.err;
  r = run("simulate -- -x.ngc --config " + std::string(kConfig), "cd " + dir_.string() + " && ");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unexpected argument '--config'"), std::string::npos) << r.err;
  r = run("compile -- --help");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--help: error: cannot open"), std::string::npos) << r.err;
  // Without it, a name that starts with - is still an option.
  r = run("compile -x.ngc", "cd " + dir_.string() + " && ");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown option '-x.ngc'"), std::string::npos) << r.err;
}

// A program without M2 or M30 stops after its last record, as a file that a post-processor
// left cut short at a line does: compile, simulate and a .tgmi of it note the line; a program
// with an end does not get the note.
TEST_F(HmiCompile, AProgramWithoutM2OrM30IsNoted) {
  const fs::path cut = write("cut.ngc", "G90\nG1 X10 F600\n\nG1 Y10\n(rest lost)\n");
  const fs::path tgmi = dir_ / "cut.tgmi";
  ASSERT_EQ(
      run("compile " + cut.string() + " --config " + kConfig + " --out " + tgmi.string()).exit_code,
      0);
  const std::string note =
      ": note: the program has no M2 or M30: it ends after this line's record, where the motion "
      "stops (a file cut short reads the same: is it whole?)";
  for (const fs::path& prog : {cut, tgmi}) {
    for (const char* cmd : {"compile ", "simulate ", "compile --dump text "}) {
      const ProcessResult r = run(cmd + prog.string() + " --config " + kConfig);
      ASSERT_EQ(r.exit_code, 0) << cmd << r.err;
      const std::string where = prog == tgmi ? " (source line 4)" : ":4";
      EXPECT_NE(r.err.find(prog.filename().string() + where + note), std::string::npos)
          << cmd << prog << r.err;
    }
  }
  for (const char* end : {"M2", "M30"}) {
    const fs::path whole = write("whole.ngc", std::string("G90\nG1 X10 F600\n") + end + "\n");
    for (const char* cmd : {"compile ", "simulate "}) {
      const ProcessResult r = run(cmd + whole.string() + " --config " + kConfig);
      ASSERT_EQ(r.exit_code, 0) << cmd << r.err;
      EXPECT_EQ(r.err.find("note:"), std::string::npos) << cmd << end << r.err;
    }
  }
  // One record: "1 record" (it said "1 records").
  const fs::path one = write("one.ngc", "G1 X1 F600\n");
  const ProcessResult r = run("simulate " + one.string() + " --config " + kConfig);
  EXPECT_NE(r.out.find("(1 record, interpolator 0"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace tgm
