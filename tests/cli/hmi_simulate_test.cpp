// tgm-hmi simulate as a user runs it (issue 3, "Command line"): the CSV's columns and rows, the
// summary, the exit codes for bad input, the override, the progress display, and Ctrl-C in the
// middle of a long run keeping every cycle written so far.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli_fixture.hpp"
#include "tgm/registers.hpp"

namespace tgm {
namespace {

using test::ProcessResult;
using test::slurp;
namespace fs = std::filesystem;
using HmiSimulate = test::CliTest;
using namespace std::chrono_literals;

const std::string kConfig = test::kDefaultConfig;
const std::string kExample = test::kManualExample;

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string f; std::getline(ss, f, sep);) out.push_back(f);
  return out;
}

std::vector<std::string> lines(const std::string& text) { return split(text, '\n'); }

// "NAME: ... <number> WORD" from the summary, e.g. number_before(out, " s program time").
double number_before(const std::string& text, const std::string& word) {
  const std::size_t at = text.find(word);
  if (at == std::string::npos) return NAN;
  std::size_t b = at;
  while (b > 0 && (std::isdigit(static_cast<unsigned char>(text[b - 1])) || text[b - 1] == '.')) --b;
  return std::atof(text.substr(b, at - b).c_str());
}

TEST_F(HmiSimulate, ManualExampleWritesEveryColumnAndEndsCleanUnderTheChecker) {
  const fs::path csv = dir_ / "run.csv", blocks = dir_ / "blocks.csv";
  const ProcessResult r = run("simulate " + kExample + " --config " + kConfig + " --check-limits --csv " +
                              csv.string() + " --blocks " + blocks.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("result:    finished\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("violations: 0\n"), std::string::npos) << r.out;
  for (const char* axis : {"\nX ", "\nY ", "\nZ "}) EXPECT_NE(r.out.find(axis), std::string::npos) << axis;

  const auto rows = lines(slurp(csv));
  ASSERT_GT(rows.size(), 100u);
  EXPECT_EQ(rows[0],
            "time_s,line,act_part,status,run_flag,m_func,act_speed_mm_min,move_distance_mm,"
            "orig_X,orig_Y,orig_Z,pos_X,pos_Y,pos_Z,inc_X,inc_Y,inc_Z,backlash_X,backlash_Y,"
            "backlash_Z,speed_X,speed_Y,speed_Z,limit_factor");
  // One row per cycle, every column filled, factors by name, the last row where the program ends.
  const double cycles = number_before(r.out, " cycles");
  EXPECT_EQ(static_cast<double>(rows.size() - 1), cycles);
  std::set<std::string> names;
  for (int f = 0; f <= static_cast<int>(LimitFactor::kStopCommand); ++f) {
    names.insert(limit_factor_name(static_cast<LimitFactor>(f)));
  }
  double last_t = 0.0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const auto f = split(rows[i], ',');
    ASSERT_EQ(f.size(), 24u) << rows[i];
    // Each number as printf's %.6f / %d / %.9f writes it (the writer formats with to_chars).
    for (std::size_t k = 0; k < 23; ++k) {
      const bool integer = (k >= 1 && k <= 5) || (k >= 14 && k <= 19);
      const int decimals = (k == 0 || k == 6 || k >= 20) ? 6 : 9;
      char expect[64];
      if (integer) {
        std::snprintf(expect, sizeof expect, "%lld", std::atoll(f[k].c_str()));
      } else {
        std::snprintf(expect, sizeof expect, "%.*f", decimals, std::atof(f[k].c_str()));
      }
      ASSERT_EQ(f[k], expect) << "row " << i << " column " << k;
    }
    const double t = std::atof(f[0].c_str());
    ASSERT_NEAR(t - last_t, 0.0005, 1e-9) << "row " << i;
    last_t = t;
    ASSERT_TRUE(names.count(f[23])) << f[23];
    for (std::size_t k = 17; k < 20; ++k) ASSERT_EQ(f[k], "0") << "no backlash configured";
  }
  const auto last = split(rows.back(), ',');
  EXPECT_EQ(last[3], "3");  // Status: ended
  const std::size_t end_at = r.out.find("end:");
  ASSERT_NE(end_at, std::string::npos);
  for (int i = 0; i < 3; ++i) {
    const std::string key = std::string(1, "XYZ"[i]) + "=";
    const double summary = std::atof(r.out.c_str() + r.out.find(key, end_at) + 2);
    EXPECT_NEAR(std::atof(last[8 + i].c_str()), summary, 1e-6) << key;
  }
  EXPECT_NEAR(std::atof(last[0].c_str()), number_before(r.out, " s program time"), 1e-4);

  const auto brows = lines(slurp(blocks));
  ASSERT_GT(brows.size(), 1u);
  EXPECT_EQ(brows[0], "line,act_part,g,length_mm,programmed_mm_min,peak_mm_min,duration_s,limit_factor");
  for (std::size_t i = 1; i < brows.size(); ++i) {
    const auto f = split(brows[i], ',');
    ASSERT_EQ(f.size(), 8u) << brows[i];
    EXPECT_TRUE(names.count(f[7])) << brows[i];
  }
}

// "limited by (time)": per factor the time of the cycles the CSV files under it (to a cycle,
// printed to a millisecond) and its share of their sum; the cycles filed under "none" (the
// motion stands) are not listed.
TEST_F(HmiSimulate, TimeByLimitFactorAddsUpTheCsvsCycles) {
  const fs::path csv = dir_ / "run.csv";
  const ProcessResult r =
      run("simulate " + kExample + " --config " + kConfig + " --csv " + csv.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  std::map<std::string, double> from_csv;
  const auto rows = lines(slurp(csv));
  ASSERT_GT(rows.size(), 1000u);
  for (std::size_t i = 1; i < rows.size(); ++i) from_csv[split(rows[i], ',').back()] += 0.0005;
  const std::size_t at = r.out.find("limited by (time):");
  ASSERT_NE(at, std::string::npos) << r.out;
  std::stringstream line(r.out.substr(at + 18, r.out.find('\n', at) - (at + 18)));
  std::map<std::string, std::pair<double, int>> summary;  // seconds, percent
  for (std::string name, s_word, pct, pct_word; line >> name;) {
    double t = 0.0;
    ASSERT_TRUE(line >> t >> s_word >> pct >> pct_word) << r.out;
    EXPECT_EQ(s_word, "s");
    EXPECT_EQ(pct_word, "%)");
    ASSERT_EQ(pct.front(), '(') << pct;
    summary[name] = {t, std::atoi(pct.c_str() + 1)};
  }
  double total = 0.0;
  for (const auto& [name, seconds] : from_csv) {
    if (name == "none") continue;
    ASSERT_TRUE(summary.count(name)) << name << " is in the CSV, not in: " << r.out;
    EXPECT_NEAR(summary[name].first, seconds, 0.0005 + 1e-9) << name;
    total += seconds;
  }
  EXPECT_EQ(summary.size(), from_csv.size() - from_csv.count("none")) << r.out;
  EXPECT_GE(summary.size(), 3u) << r.out;
  for (const auto& [name, sp] : summary) {
    EXPECT_NEAR(sp.second, 100.0 * from_csv[name] / total, 0.5 + 1e-6) << name;
  }
  EXPECT_GE(summary["feed"].second, 90) << r.out;  // the example's long moves run at their feed
}

// --csv-every N: the rows of the full CSV (the same text) at every N-th cycle, at each cycle
// where status, run_flag or m_func changes, and at the last cycle; nothing else.
TEST_F(HmiSimulate, CsvEveryKeepsTheNthCyclesTheEventsAndTheLast) {
  const fs::path full = dir_ / "full.csv", part = dir_ / "part.csv";
  const std::string base = "simulate " + kExample + " --config " + kConfig + " --csv ";
  ASSERT_EQ(run(base + full.string()).exit_code, 0);
  const ProcessResult r = run(base + part.string() + " --csv-every 250");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto all = lines(slurp(full)), some = lines(slurp(part));
  ASSERT_GT(all.size(), 10000u);
  EXPECT_EQ(some[0], all[0]);  // the header
  std::vector<std::string> expect;
  std::vector<std::string> prev;
  int events = 0;
  for (std::size_t i = 1; i < all.size(); ++i) {
    const auto f = split(all[i], ',');
    const bool event = prev.empty() || f[3] != prev[3] || f[4] != prev[4] || f[5] != prev[5];
    events += event ? 1 : 0;
    if (i % 250 == 0 || event || i + 1 == all.size()) expect.push_back(all[i]);
    prev = f;
  }
  EXPECT_GT(events, 6);  // start, the M-function handshakes, the end
  ASSERT_EQ(some.size() - 1, expect.size());
  for (std::size_t k = 0; k < expect.size(); ++k)
    ASSERT_EQ(some[k + 1], expect[k]) << "row " << k + 1;
  EXPECT_EQ(split(some.back(), ',')[3], "3");  // the program's end
}

// `--csv -` wrote a file named "-" and the summary to standard output. "-" is standard output
// now, for any one of the outputs, and the summary goes to standard error.
TEST_F(HmiSimulate, AnOutputNamedDashIsStandardOutputAndTheSummaryMovesToStandardError) {
  const fs::path file = dir_ / "file.csv";
  const std::string base = "simulate " + kExample + " --config " + kConfig;
  const ProcessResult to_file =
      run(base + " --csv " + file.string() + " --blocks " + (dir_ / "b.csv").string());
  ASSERT_EQ(to_file.exit_code, 0) << to_file.err;
  const ProcessResult csv = run(base + " --csv -");
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  EXPECT_EQ(csv.out, slurp(file));
  EXPECT_FALSE(fs::exists(fs::current_path() / "-"));
  EXPECT_NE(csv.err.find("result:    finished"), std::string::npos) << csv.err;
  const ProcessResult blocks = run(base + " --blocks -");
  ASSERT_EQ(blocks.exit_code, 0) << blocks.err;
  EXPECT_EQ(blocks.out, slurp(dir_ / "b.csv"));
  EXPECT_NE(blocks.err.find("result:    finished"), std::string::npos) << blocks.err;
  // The summary stays on standard output without a "-".
  EXPECT_NE(to_file.out.find("result:    finished"), std::string::npos) << to_file.out;
  const ProcessResult both = run(base + " --csv - --blocks -");
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_NE(both.err.find("both outputs would be written into it"), std::string::npos) << both.err;
  // The program from standard input and the CSV to standard output, for a pipe: "-" as FILE
  // and "-" as an output are two streams (it was refused as the same file).
  for (const char* out : {" --csv -", " --blocks -"}) {
    const ProcessResult piped =
        run("simulate - --config " + std::string(kConfig) + out, "", kExample);
    ASSERT_EQ(piped.exit_code, 0) << out << piped.err;
    EXPECT_EQ(piped.out, out == std::string(" --csv -") ? csv.out : blocks.out) << out;
  }
  const ProcessResult piped_both =
      run("simulate - --config " + std::string(kConfig) + " --csv - --blocks -", "", kExample);
  EXPECT_EQ(piped_both.exit_code, 2);
  EXPECT_NE(piped_both.err.find("both outputs would be written into it"), std::string::npos)
      << piped_both.err;
}

TEST_F(HmiSimulate, OverrideStretchesAFeedLimitedLine) {
  // 100 mm at F600: 10 s plus the S-curve's ramps; at Rel_Speed 0.5 twice the cruise.
  const fs::path prog = write("line.ngc", "G90 G1 X100 F600\nM2\n");
  const ProcessResult full = run("simulate " + prog.string() + " --config " + kConfig);
  const ProcessResult half = run("simulate " + prog.string() + " --config " + kConfig + " --rel-speed 0.5");
  ASSERT_EQ(full.exit_code, 0) << full.out << full.err;
  ASSERT_EQ(half.exit_code, 0) << half.out << half.err;
  const double t1 = number_before(full.out, " s program time");
  const double t2 = number_before(half.out, " s program time");
  EXPECT_GT(t1, 10.0);
  EXPECT_LT(t1, 10.1);
  EXPECT_GT(t2, 20.0);
  EXPECT_LT(t2, 20.1);
  EXPECT_NE(full.out.find("X=100.000000 Y=0.000000 Z=0.000000"), std::string::npos) << full.out;
  EXPECT_NE(full.out.find("distance:  100.0000 mm"), std::string::npos) << full.out;
}

// Rows of a CSV as numbers, with the column index of each header name.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  std::size_t col(const std::string& name) const {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  }
  // The first row whose column `name` reaches `at` or more (rows.size() when none does).
  std::size_t first_reaching(const std::string& name, double at) const {
    const std::size_t c = col(name);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (rows[i][c] >= at) return i;
    }
    return rows.size();
  }
};

Table read_table(const fs::path& csv) {
  Table t;
  const auto all = lines(slurp(csv));
  if (all.empty()) return t;
  t.header = split(all[0], ',');
  for (std::size_t i = 1; i < all.size(); ++i) {
    std::vector<double> row;
    for (const std::string& f : split(all[i], ',')) row.push_back(std::atof(f.c_str()));
    t.rows.push_back(std::move(row));
  }
  return t;
}

// --start: the program is compiled and run from that point, as tgm-hmi run does from where the
// interpolator stands. An incremental program run from X20 Y5 Z-2 takes the same path as its
// absolute twin written for that point: the same time to the cycle and the same end; a G90
// line leaves the axes it does not name where they stand.
TEST_F(HmiSimulate, StartRunsTheProgramFromThatPoint) {
  const fs::path inc = write("inc.ngc", "G91 G1 X10 F6000\nG2 X10 I5\nM2\n");
  const fs::path abs =
      write("abs.ngc", "G90 G0 X20 Y5 Z-2\nG4 P0.1\nG1 X30 F6000\nG2 X40 Y5 I5 J0\nM2\n");
  const ProcessResult from = run("simulate " + inc.string() + " --config " + kConfig +
                                 " --start X20,y5,Z-2 --blocks " + (dir_ / "inc.csv").string());
  const ProcessResult twin = run("simulate " + abs.string() + " --config " + kConfig +
                                 " --blocks " + (dir_ / "abs.csv").string());
  ASSERT_EQ(from.exit_code, 0) << from.out << from.err;
  ASSERT_EQ(twin.exit_code, 0) << twin.out << twin.err;
  EXPECT_NE(from.out.find("X=40.000000 Y=5.000000 Z=-2.000000"), std::string::npos) << from.out;
  // The twin's first block is the rapid to the start point, which ends in a dwell; the rest
  // are the same blocks.
  const Table a = read_table(dir_ / "inc.csv"), b = read_table(dir_ / "abs.csv");
  ASSERT_EQ(a.rows.size(), 2u) << slurp(dir_ / "inc.csv");
  ASSERT_EQ(b.rows.size(), 3u) << slurp(dir_ / "abs.csv");
  // A block's duration counts whole calculation steps (100 us here): the twin's first one
  // starts after the dwell, one step later in its cycle.
  for (const auto& [column, within] : {std::pair<const char*, double>{"length_mm", 1e-9},
                                       {"peak_mm_min", 1e-9},
                                       {"duration_s", 1e-4 + 1e-9}}) {
    for (std::size_t k = 0; k < 2; ++k) {
      EXPECT_NEAR(a.rows[k][a.col(column)], b.rows[k + 1][b.col(column)], within) << column << k;
    }
  }
  const fs::path g90 = write("g90.ngc", "G90 G0 X1 Y2\nM2\n");
  const ProcessResult held =
      run("simulate " + g90.string() + " --config " + kConfig + " --start Z-7.5");
  ASSERT_EQ(held.exit_code, 0) << held.out << held.err;
  EXPECT_NE(held.out.find("X=1.000000 Y=2.000000 Z=-7.500000"), std::string::npos) << held.out;
}

// Intercode compiled from a point (`compile --start`) simulates from there, as the G-code does
// with the same --start; a --start elsewhere is refused (the file would not run as compiled), and
// the same point given again is taken.
TEST_F(HmiSimulate, IntercodeStartsWhereItWasCompiledFrom) {
  const fs::path inc = write("inc.ngc", "G91 G1 X10 F6000\nG2 X10 I5\nM2\n");
  const fs::path tgmi = dir_ / "inc.tgmi";
  ProcessResult r = run("compile " + inc.string() + " --config " + kConfig +
                        " --start X20,Y5,Z-2 --out " + tgmi.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(
      r.err.find("3 records (1 M-function, 0 messages, compiled from X20 Y5 Z-2) written to "),
      std::string::npos)
      << r.err;
  const ProcessResult gcode =
      run("simulate " + inc.string() + " --config " + kConfig + " --start X20,Y5,Z-2");
  const ProcessResult intercode = run("simulate " + tgmi.string() + " --config " + kConfig);
  ASSERT_EQ(gcode.exit_code, 0) << gcode.out << gcode.err;
  ASSERT_EQ(intercode.exit_code, 0) << intercode.out << intercode.err;
  EXPECT_NE(intercode.out.find("X=40.000000 Y=5.000000 Z=-2.000000"), std::string::npos)
      << intercode.out;
  EXPECT_EQ(number_before(intercode.out, " s program time"),
            number_before(gcode.out, " s program time"));
  r = run("simulate " + tgmi.string() + " --config " + kConfig + " --start X20");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, tgmi.string() +
                       ": error: compiled from X20 Y5 Z-2, not from --start X20 Y0 Z0: tgm-hmi run "
                       "runs it only from there (or with --from-here from anywhere); leave "
                       "--start out\n");
  r = run("simulate " + tgmi.string() + " --config " + kConfig + " --start z-2,X20,Y5");
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

// Intercode compiled without the config's soft limits is checked against them when it is
// read, as the compiler checks G-code: every record beyond one named with its source line,
// nothing run. Before session 83 only the interpolator's check at append caught it, a
// buffer's worth at a time: "record 2 (line 4): ..." and, in tgm-hmi run, a record beyond the
// first buffer_size stopped the motion mid-program.
TEST_F(HmiSimulate, IntercodeBeyondTheSoftLimitsIsRefusedWithItsLines) {
  const fs::path src =
      write("far.ngc", "G90 G1 X50 F6000\nG1 X120\nG1 X50\nG2 X50 Y0 I-30 J0\nG1 Z-5\nM2\n");
  const fs::path tgmi = dir_ / "far.tgmi";
  ProcessResult r =
      run("compile " + src.string() + " --config " + kConfig + " --out " + tgmi.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const fs::path limited = write("limited.yaml",
                                 "interpolators:\n  - axes: [{letter: X, max_position_mm: 100}, "
                                 "{letter: Y, min_position_mm: -20}, {letter: Z}]\n");
  r = run("simulate " + tgmi.string() + " --config " + limited.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, tgmi.string() +
                       " (source line 2): error: end point X120 is beyond the soft limit of axis "
                       "X (max_position_mm 100 in the config)\n" +
                       tgmi.string() +
                       " (source line 4): error: the arc passes Y-30, beyond the soft limit of "
                       "axis Y (min_position_mm -20 in the config)\n" +
                       tgmi.string() + ": 2 records beyond the soft limits\n")
      << r.err;
  // The compiler says the same of the G-code (line 3 comes back from beyond: allowed).
  r = run("compile " + src.string() + " --config " + limited.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(src.string() +
                       ":2:1: error: end point X120 is beyond the soft limit of axis X "
                       "(max_position_mm 100 in the config)\n" +
                       src.string() +
                       ":4:1: error: the arc passes Y-30, beyond the soft limit of axis Y "
                       "(min_position_mm -20 in the config)\n"),
            std::string::npos)
      << r.err;
  // Within them it runs.
  r = run("simulate " + tgmi.string() + " --config " + kConfig);
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

// The Backlash register is in the CSV (backlash_<axis>): LinuxCNC's convention, half the
// configured backlash towards the last direction of motion, 0 before the first, ramped at a
// reversal; in every row PositionInc = round(Position x Ratio) + Backlash (no Offset here).
// Y turns round (ratio -2000), so its increments run against its millimetres.
TEST_F(HmiSimulate, TheCsvShowsTheBacklashOfEveryAxis) {
  const fs::path cfg = write("backlash.yaml",
                             "axis_defaults: {backlash_mm: 0.05}\n"
                             "interpolators:\n"
                             "  - axes: [{letter: X}, {letter: Y, ratio_inc_per_mm: -2000}, "
                             "{letter: Z}]\n");
  const fs::path prog = write("zigzag.ngc", "G90 G1 X1 Y1 F600\nG1 X0 Y0\nG1 X0.5 Y-0.5\nM2\n");
  const fs::path csv = dir_ / "backlash.csv";
  const ProcessResult r =
      run("simulate " + prog.string() + " --config " + cfg.string() + " --csv " + csv.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const Table t = read_table(csv);
  ASSERT_GT(t.rows.size(), 100u);
  const std::array<double, 3> ratio = {1000.0, -2000.0, 1000.0};
  std::set<double> seen_x, seen_y;
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) {
      const std::string l(1, "XYZ"[a]);
      const double pos = t.rows[i][t.col("pos_" + l)];
      const double inc = t.rows[i][t.col("inc_" + l)];
      const double backlash = t.rows[i][t.col("backlash_" + l)];
      ASSERT_EQ(inc, std::round(pos * ratio[a]) + backlash) << "row " << i << " axis " << l;
    }
    seen_x.insert(t.rows[i][t.col("backlash_X")]);
    seen_y.insert(t.rows[i][t.col("backlash_Y")]);
    ASSERT_EQ(t.rows[i][t.col("backlash_Z")], 0.0) << "Z never moves";
  }
  // Both signs of half the backlash, 0.025 mm: 25 inc on X, 50 inc the other way on Y.
  EXPECT_TRUE(seen_x.count(25.0) && seen_x.count(-25.0));
  EXPECT_TRUE(seen_y.count(-50.0) && seen_y.count(50.0));
  EXPECT_EQ(t.rows.back()[t.col("backlash_X")], 25.0);  // last moved in +X
  EXPECT_EQ(t.rows.back()[t.col("backlash_Y")], 50.0);  // last moved in -Y: -0.025 x -2000
  // With the checker, the summary says why these axes peak below their limits, and gives
  // the setpoint's peaks with the ramp (Z's share set to 0.2).
  const fs::path shared = write("shared.yaml",
                                "axis_defaults: {backlash_mm: 0.05}\n"
                                "interpolators:\n"
                                "  - axes: [{letter: X}, {letter: Y, backlash_mm: 0}, "
                                "{letter: Z, backlash_ramp_share: 0.2}]\n");
  const ProcessResult c =
      run("simulate " + prog.string() + " --config " + shared.string() + " --check-limits");
  ASSERT_EQ(c.exit_code, 0) << c.out << c.err;
  EXPECT_NE(c.out.find("(X has backlash: its path is planned at 0.9 x the limits above, the "
                       "backlash ramp has the rest)\n(Z has backlash: its path is planned at "
                       "0.8 x the limits above, the backlash ramp has the rest)\n"),
            std::string::npos)
      << c.out;
  EXPECT_EQ(c.out.find("(Y has backlash"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("to the drives (Position after the spline / IIR, plus the backlash "
                       "ramp):\nX "),
            std::string::npos)
      << c.out;
}

// --spline and --iir as the README gives them reach the interpolator as Command -2 and -1
// before the start: the summary names both, Position (pos_<axis>) follows Orig_Position by the
// spline's delay (200 points of 100 us: 40 cycles of 500 us, exactly, as the spline is
// symmetric) and, on the axes in the IIR's mask only, by the filter's lag on top (p 2, q 1,
// f 6 ms: 2 ms on a ramp); the run ends with Position on the end point. Without either option
// Position is Orig_Position in every cycle.
TEST_F(HmiSimulate, SplineAndIirFromTheCommandLineDelayThePositionAsConfigured) {
  const std::string base =
      "simulate " + kExample + " --config " + kConfig + " --rel-speed 0.8 --csv ";
  const fs::path plain = dir_ / "plain.csv", spline = dir_ / "spline.csv", both = dir_ / "both.csv";
  const ProcessResult p = run(base + plain.string());
  const ProcessResult s = run(base + spline.string() + " --spline 200,1000000");
  const ProcessResult b =
      run(base + both.string() + " --spline 200,1000000 --iir 2000000,1000000,6000000,1");
  ASSERT_EQ(p.exit_code, 0) << p.out << p.err;
  ASSERT_EQ(s.exit_code, 0) << s.out << s.err;
  ASSERT_EQ(b.exit_code, 0) << b.out << b.err;
  EXPECT_EQ(p.out.find("spline:"), std::string::npos) << p.out;
  EXPECT_EQ(p.out.find("iir:"), std::string::npos) << p.out;
  EXPECT_NE(s.out.find("spline:    200 points (20.0 ms delay), jerk limit 1000000 mm/s^3"),
            std::string::npos)
      << s.out;
  EXPECT_EQ(s.out.find("iir:"), std::string::npos) << s.out;
  EXPECT_NE(b.out.find("iir:       p 2 q 1 f 6 ms, zeta 1.000, axis mask 0x1\n"), std::string::npos)
      << b.out;

  const Table tp = read_table(plain), ts = read_table(spline), tb = read_table(both);
  ASSERT_GT(tp.rows.size(), 1000u);
  for (const std::string axis : {"X", "Y"}) {
    for (const auto& row : tp.rows)
      ASSERT_EQ(row[tp.col("pos_" + axis)], row[tp.col("orig_" + axis)]);
    // The rapid to (60.6051, 40.7723) takes X and Y through 10, 20 and 40 mm.
    for (double at : {10.0, 20.0, 40.0}) {
      const std::size_t o = ts.first_reaching("orig_" + axis, at);
      ASSERT_LT(o, ts.rows.size()) << axis << " " << at;
      EXPECT_EQ(ts.first_reaching("pos_" + axis, at), o + 40) << axis << " " << at;
      ASSERT_EQ(tb.first_reaching("orig_" + axis, at), o) << axis << " " << at;
      // The IIR's mask 0x1 holds X only: Y keeps the spline's 40 cycles.
      EXPECT_EQ(tb.first_reaching("pos_" + axis, at), o + (axis == "X" ? 44 : 40))
          << axis << " " << at;
    }
    for (const Table* t : {&ts, &tb}) {
      EXPECT_EQ(t->rows.back()[t->col("pos_" + axis)], t->rows.back()[t->col("orig_" + axis)])
          << axis;
    }
  }
  EXPECT_EQ(tb.rows.back()[tb.col("status")], 3.0);
}

// --lookahead writes the LookAheadBuffer each time it shifts, one JSON object a line: the first
// holds the program's first eight sections (the G42 and G40 lines make none; M51 is a normal
// M-function), each later one the same entries moved up by one with the next section appended
// (the current arc's tangent aside, which turns with the motion), and the last, at the end,
// only invalid entries, which give no addresses.
TEST_F(HmiSimulate, LookAheadFileIsTheShiftBufferOfTheProgram) {
  const fs::path la = dir_ / "la.jsonl";
  const ProcessResult r =
      run("simulate " + kExample + " --config " + kConfig + " --lookahead " + la.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto shifts = lines(slurp(la));
  ASSERT_EQ(shifts.size(), 13u);  // the first table, then one shift for each of the 12 sections
  const std::string kEntry = "{\"movement_type\":";
  // An entry without its "tangent_deg":VALUE, field (std::regex would do, but GCC 12 warns
  // inside it under the sanitizer build's -Werror).
  const auto without_tangent = [](std::string e) {
    const std::size_t at = e.find("\"tangent_deg\":");
    if (at != std::string::npos) e.erase(at, e.find(',', at) + 1 - at);
    return e;
  };
  std::vector<std::vector<std::string>> tables;
  long last_cycle = 0;
  for (const std::string& line : shifts) {
    ASSERT_EQ(line.rfind("{\"cycle\":", 0), 0u) << line;
    ASSERT_TRUE(line.ends_with("]}")) << line;
    const long cycle = std::atol(line.c_str() + 9);
    EXPECT_GT(cycle, last_cycle) << line;
    last_cycle = cycle;
    std::vector<std::string> entries;
    for (std::size_t at = line.find(kEntry); at != std::string::npos;) {
      const std::size_t next = line.find(kEntry, at + 1);
      // Up to the next entry's comma, or the line's closing "]}".
      const std::size_t end = next == std::string::npos ? line.size() - 2 : next - 1;
      entries.push_back(without_tangent(line.substr(at, end - at)));
      at = next;
    }
    ASSERT_EQ(entries.size(), 8u) << line;
    tables.push_back(entries);
  }
  const auto field = [](const std::string& entry, const std::string& name) {
    const std::size_t at = entry.find("\"" + name + "\":");
    return at == std::string::npos ? std::string("?")
                                   : entry.substr(at + name.size() + 3,
                                                  entry.find_first_of(",}", at + name.size() + 3) -
                                                      at - name.size() - 3);
  };
  const std::vector<std::string> first_lines = {"1", "3", "4", "5", "6", "7", "8", "9"};
  for (std::size_t e = 0; e < 8; ++e) {
    EXPECT_EQ(field(tables[0][e], "line"), first_lines[e]) << tables[0][e];
    EXPECT_EQ(field(tables[0][e], "movement_type"), e == 1 ? "2" : "1") << tables[0][e];
    EXPECT_EQ(field(tables[0][e], "movement_code"), e == 0   ? "0"
                                                    : e == 1 ? "51"
                                                             : "2")
        << tables[0][e];
  }
  EXPECT_NE(tables[0][0].find("\"end_pos_mm\":[60.6051,40.7723,0]"), std::string::npos)
      << tables[0][0];
  // The first arc: I3.0336 J-1.2601 from (60.6051, 40.7723).
  EXPECT_EQ(field(tables[0][2], "radius_mm"), "3.28490197") << tables[0][2];
  EXPECT_EQ(field(tables[0][2], "plane"), "17") << tables[0][2];
  for (std::size_t t = 1; t < tables.size(); ++t) {
    for (std::size_t e = 0; e + 1 < 8; ++e)
      ASSERT_EQ(tables[t][e], tables[t - 1][e + 1]) << "shift " << t;
  }
  const std::string invalid =
      "{\"movement_type\":0,\"movement_code\":0,\"line\":0,\"plane\":17,\"tool\":0,\"start_angle_"
      "deg\":null,"
      "\"end_angle_deg\":null,\"radius_mm\":0,\"end_pos_mm\":[0,0,0],\"all_params\":{}}";
  for (const std::string& e : tables.back()) EXPECT_EQ(e, invalid);
  EXPECT_EQ(field(tables[tables.size() - 2][0], "line"), "15");  // the last section: M51
}

// A continuous M-function is no section: its number and its other addresses are the AllParams
// of the section after it (M1005 S3 Q7 before line 3), a normal M-function's are its own. Only
// the M letter used to reach the table.
TEST_F(HmiSimulate, AContinuousMsAddressesAreTheNextSectionsAllParams) {
  const fs::path prog =
      write("cont.ngc", "G91 G1 X1 F600\nM1005 S3 Q7\nG1 X1\nM51 S9\nG1 X1\nM2\n");
  const fs::path la = dir_ / "cont.jsonl";
  const ProcessResult r =
      run("simulate " + prog.string() + " --config " + kConfig + " --lookahead " + la.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto shifts = lines(slurp(la));
  ASSERT_FALSE(shifts.empty());
  const std::string& first = shifts[0];
  const auto entry_of_line = [&](const std::string& line) {
    const std::size_t at = first.find("\"line\":" + line + ",");
    EXPECT_NE(at, std::string::npos) << first;
    return at == std::string::npos ? std::string() : first.substr(at, first.find("}}", at) - at);
  };
  EXPECT_TRUE(entry_of_line("1").ends_with("\"all_params\":{")) << entry_of_line("1");
  EXPECT_TRUE(entry_of_line("3").ends_with("\"all_params\":{\"M\":1005,\"Q\":7,\"S\":3"))
      << entry_of_line("3");
  // M51's number is its MovementCode (2 / 51); its addresses stay its own.
  EXPECT_TRUE(entry_of_line("4").ends_with("\"all_params\":{\"S\":9")) << entry_of_line("4");
  EXPECT_TRUE(entry_of_line("5").ends_with("\"all_params\":{")) << entry_of_line("5");
}

// --stop-at: a normal stop at 2 s on a 100 mm line at F600 (10 s): the motion stands, is
// restarted 1.5 s later and still ends at X100, 1.5 s plus the extra ramps later, without a
// limit excess; the summary says how many stops were given.
TEST_F(HmiSimulate, StopAtGivesAStopAndTheRestartGoesOn) {
  const fs::path prog = write("line.ngc", "G90 G1 X100 F600\nM2\n");
  const ProcessResult plain = run("simulate " + prog.string() + " --config " + kConfig);
  const ProcessResult held = run("simulate " + prog.string() + " --config " + kConfig +
                                 " --check-limits --stop-at 2,4:4 --restart-after 1.5");
  ASSERT_EQ(plain.exit_code, 0) << plain.out << plain.err;
  ASSERT_EQ(held.exit_code, 0) << held.out << held.err;
  const double t0 = number_before(plain.out, " s program time");
  const double t1 = number_before(held.out, " s program time");
  EXPECT_GT(t1, t0 + 3.0);
  EXPECT_LT(t1, t0 + 3.0 + 1.0);
  EXPECT_NE(
      held.out.find(
          "stops:     2 of 2 given before the end, each restarted 1.500 s after the standstill"),
      std::string::npos)
      << held.out;
  EXPECT_NE(held.out.find("violations: 0"), std::string::npos) << held.out;
  EXPECT_NE(held.out.find("X=100.000000 Y=0.000000 Z=0.000000"), std::string::npos) << held.out;
}

// A program longer than the time limit ends there with exit code 1, says which limit and how
// to raise it, and still reports the peak path speed of the block it was cut in (it printed
// 0.0 mm/min: the peak came only from the reports of finished blocks). --max-time raises it.
TEST_F(HmiSimulate, TimeLimitIsNamedAndMaxTimeRaisesIt) {
  // 60 mm at F600 (10 mm/s): about 6 s.
  const fs::path prog = write("line.ngc", "G90 G1 X60 F600\nM2\n");
  ProcessResult r = run("simulate " + prog.string() + " --config " + kConfig + " --max-time 2");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("result:    NOT finished: program time limit of 2 s reached (--max-time S "
                       "raises it)\n"),
            std::string::npos)
      << r.out;
  EXPECT_NEAR(number_before(r.out, " mm/min, "), 600.0, 1e-6) << r.out;
  EXPECT_NEAR(number_before(r.out, " s program time"), 2.0, 0.001) << r.out;
  r = run("simulate " + prog.string() + " --config " + kConfig + " --max-time 7");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("result:    finished\n"), std::string::npos) << r.out;
  EXPECT_NEAR(number_before(r.out, " mm/min, "), 600.0, 1e-6) << r.out;
}

// An output path that cannot be opened is bad input, said with its flag before the run (it
// said "DIR: error: cannot write: Is a directory" and exited 1, like a failed run).
TEST_F(HmiSimulate, AnOutputPathThatCannotBeOpenedIsAUsageError) {
  const fs::path prog = write("line.ngc", "G90 G1 X6 F600\nM2\n");
  ProcessResult r =
      run("simulate " + prog.string() + " --config " + kConfig + " --csv " + dir_.string());
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "tgm-hmi simulate: --csv " + dir_.string() +
                       ": is a directory\n(see tgm-hmi simulate --help)\n");
  const std::string missing = (dir_ / "no" / "la.jsonl").string();
  r = run("simulate " + prog.string() + " --config " + kConfig + " --lookahead " + missing);
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_EQ(r.err, "tgm-hmi simulate: --lookahead " + missing +
                       ": cannot create: No such file or directory\n(see tgm-hmi simulate "
                       "--help)\n");
}

// An output file the disk does not take: the summary is still printed, its result line says
// that a file failed, each file that failed is named with the reason below it, and the exit
// code is 1 (it said "error writing the output files", naming none; then "finished" alone).
TEST_F(HmiSimulate, AnOutputThatCannotBeWrittenIsNamedWithTheReason) {
  const fs::path prog = write("line.ngc", "G90 G1 X6 F600\nM2\n");
  const fs::path csv = dir_ / "ok.csv";
  const ProcessResult r = run("simulate " + prog.string() + " --config " + kConfig + " --csv " +
                              csv.string() + " --blocks /dev/full --quiet");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("result:    finished, but an output file could not be written (below)\n"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.err,
            "tgm-hmi simulate: cannot write --blocks /dev/full: No space left on device (the file "
            "is incomplete)\n");
  // The CSV is written whole: as a run without the failing output writes it.
  const fs::path again = dir_ / "again.csv";
  ASSERT_EQ(run("simulate " + prog.string() + " --config " + kConfig + " --csv " + again.string() +
                " --quiet")
                .exit_code,
            0);
  EXPECT_GT(lines(slurp(csv)).size(), 1000u);
  EXPECT_EQ(slurp(csv), slurp(again));

  // An output that fails while the run goes on (a disk that fills up) ends the run there: it
  // ran to the program's end first, an hour of program for a file that was lost after a
  // minute. 600 s of program time here, about 120 MB of CSV; the first megabyte fails.
  const fs::path long_prog = write("long.ngc", "G90 G1 X100 F10\nM2\n");
  const ProcessResult full =
      run("simulate " + long_prog.string() + " --config " + kConfig + " --csv /dev/full --quiet");
  EXPECT_EQ(full.exit_code, 1) << full.out << full.err;
  EXPECT_NE(full.out.find("result:    NOT finished: stopped: an output file could not be written"),
            std::string::npos)
      << full.out;
  EXPECT_EQ(full.err,
            "tgm-hmi simulate: cannot write --csv /dev/full: No space left on device (the file "
            "is incomplete)\n");
  const std::size_t at = full.out.find("s program time, ");
  ASSERT_NE(at, std::string::npos) << full.out;
  EXPECT_LT(std::stoull(full.out.substr(at + 16)), 100000u) << full.out;  // of 1,200,000 cycles
}

// A feed of 0.001 mm/min: 0.001 mm take 60 s, and the summary prints the peak with its digits
// (it printed 0.0 mm/min).
TEST_F(HmiSimulate, ASlowFeedFinishesAndItsPeakIsPrinted) {
  const fs::path prog = write("slow.ngc", "G90 G1 X0.001 F0.001\nM2\n");
  const ProcessResult r = run("simulate " + prog.string() + " --config " + kConfig);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("peak path speed 0.001 mm/min"), std::string::npos) << r.out;
  EXPECT_NEAR(number_before(r.out, " s program time"), 60.0, 0.01) << r.out;
  EXPECT_NE(r.out.find("X=0.001000 Y=0.000000 Z=0.000000"), std::string::npos) << r.out;
}

// A program of one cycle is over before its run is set up: the summary gives the wall time
// instead of a speed of "0x" real time, which read as a fault.
TEST_F(HmiSimulate, AProgramOfOneCycleSaysItsWallTimeNotASpeed) {
  const fs::path prog = write("tiny.ngc", "G90 G1 X0.0000000001 F1000\nM2\n");
  const ProcessResult r = run("simulate " + prog.string() + " --config " + kConfig);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("0.0005 s program time, 1 cycles, simulated in "), std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("faster than real time"), std::string::npos) << r.out;
}

// Intercode written by `compile --out` simulates as its G-code does (the summary is the same to
// the last digit); one compiled for other axis letters is refused (it was read as G-code and
// gave a screen of errors about its bytes).
TEST_F(HmiSimulate, IntercodeRunsAsItsGcodeAndOtherAxesAreRefused) {
  const fs::path tgmi = dir_ / "example.tgmi";
  ProcessResult r = run("compile " + kExample + " --config " + kConfig + " --out " + tgmi.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ProcessResult from_gcode = run("simulate " + kExample + " --config " + kConfig);
  const ProcessResult from_intercode = run("simulate " + tgmi.string() + " --config " + kConfig);
  ASSERT_EQ(from_gcode.exit_code, 0) << from_gcode.err;
  ASSERT_EQ(from_intercode.exit_code, 0) << from_intercode.err;
  // The summary names the input file on its first line and the wall-clock speed on the
  // second; the rest is the run.
  const auto body = [](std::string out) {
    out.erase(0, out.find('\n'));
    const auto at = out.find(", simulated ");
    if (at != std::string::npos) out.erase(at, out.find('\n', at) - at);
    return out;
  };
  EXPECT_EQ(body(from_intercode.out), body(from_gcode.out));
  EXPECT_NE(from_intercode.out.find(" s program time"), std::string::npos) << from_intercode.out;

  std::string rotary = slurp(kConfig);
  const auto at = rotary.find("{letter: Z}]");
  ASSERT_NE(at, std::string::npos);
  rotary.replace(at, 12, "{letter: C}]");
  const fs::path rot_cfg = write("rotary.yaml", rotary);
  const fs::path rot = dir_ / "rotary.tgmi";
  r = run("compile " + write("p.ngc", "G90 G1 X5 F3000\nM2\n").string() + " --config " +
          rot_cfg.string() + " --out " + rot.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run("simulate " + rot.string() + " --config " + kConfig);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(
      r.err,
      rot.string() +
          ": error: compiled for the axes XYC, interpolator 0 has XYZ: compile the G-code for it "
          "(tgm-hmi compile --interpolator 0 with this config)\n");
}

// Memory running out (here a 150 MB address-space limit and a million-line program) ends with
// words and exit code 1; it used to abort with an uncaught std::bad_alloc and a core dump.
// Under a limit of 150 MB of address space (ulimit -v): a million-record program runs, four
// million records of three axes each do not, and that is said (exit code 1), not a crash.
TEST_F(HmiSimulate, RunningOutOfMemoryIsSaidAndExitsOne) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer reserves far more address space than the limit";
#else
  // A million records fit in the limit: the program is held as intercode, 12 bytes a record
  // here (152 as Segments: 1 M records ran out of memory at this limit before).
  // `count` lines of `line` between G91 F6000 and M2.
  auto repeated = [this](const std::string& name, const std::string& line, int count) {
    std::string text = "G91 F6000\n";
    text.reserve(line.size() * static_cast<std::size_t>(count) + 16);
    for (int k = 0; k < count; ++k) text += line;
    return write(name, text + "M2\n");
  };
  const fs::path fits_prog = repeated("fits.ngc", "G1 X0.01\n", 1'000'000);
  const ProcessResult ok =
      run("simulate " + fits_prog.string() + " --config " + kConfig + " --max-time 1 --quiet",
          "ulimit -v 150000; ");
  EXPECT_NE(ok.out.find("program:   " + fits_prog.string() + " (1000001 records"),
            std::string::npos)
      << ok.out << ok.err;
  EXPECT_NE(ok.out.find("program time limit of 1 s reached"), std::string::npos)
      << ok.out << ok.err;
  fs::remove(fits_prog);

  // 4 M records of 28 bytes of intercode each (all three axes move): over 100 MB held, where
  // the limit leaves about 80 MB beyond what the process needs to start.
  const fs::path prog = repeated("big.ngc", "G1 X1 Y1 Z1\n", 4'000'000);
  const ProcessResult r =
      run("simulate " + prog.string() + " --config " + kConfig + " --csv /dev/null",
          "ulimit -v 150000; ");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_EQ(r.err, "tgm-hmi: out of memory\n") << r.out;
#endif
}

TEST_F(HmiSimulate, BadInputIsAUsageErrorAndWritesNothing) {
  const fs::path bad = write("bad.ngc", "G90\nG1 X1 Q2\n");
  const fs::path csv = dir_ / "out.csv";
  ProcessResult r = run("simulate " + bad.string() + " --config " + kConfig + " --csv " + csv.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(bad.string() + ":2:7: error: unknown word 'Q2'"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(csv));
  const fs::path empty = write("empty.ngc", "(nothing but a comment)\n");
  r = run("simulate " + empty.string() + " --config " + kConfig + " --csv " + csv.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, empty.string() + ": error: the program has no records (no move, dwell or M-function)\n");
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_FALSE(fs::exists(csv));
  const std::string ok = kExample + " --config " + kConfig;
  const std::pair<std::string, std::string> cases[] = {
      {"simulate", "a G-code FILE is required"},
      {"simulate " + ok + " --rel-speed 3", "--rel-speed must be 0.01..2, not '3'"},
      {"simulate " + ok + " --m-ack -1", "--m-ack must be seconds 0..3600, not '-1'"},
      {"simulate " + ok + " --spline 1,2,3", "--spline takes POINTS,JERK (integers), not '1,2,3'"},
      {"simulate " + ok + " --iir 1,2", "--iir takes P,Q,F,MASK"},
      {"simulate " + ok + " --progress-interval 0",
       "--progress-interval must be seconds in (0, 86400], not '0'"},
      {"simulate " + ok + " --limit-share 0", "--limit-share must be a number in (0, 1], not '0'"},
      {"simulate " + ok + " --limit-share 1.5",
       "--limit-share must be a number in (0, 1], not '1.5'"},
      {"simulate " + ok + " --interpolator 3", "--interpolator must be 0..2"},
      {"simulate " + ok + " --stop-at 3:5", "--stop-at takes TIME[:8|:4] items"},
      {"simulate " + ok + " --stop-at 1,x",
       "--stop-at takes TIME[:8|:4] items (seconds >= 0, comma-separated), not 'x'"},
      {"simulate " + ok + " --stop-at -1", "not '-1'"},
      {"simulate " + ok + " --restart-after -2",
       "--restart-after must be seconds 0..3600, not '-2'"},
      {"simulate " + ok + " --max-time 0",
       "--max-time must be seconds of program time, > 0 and at most 1e9, not '0'"},
      {"simulate " + ok + " --max-time 2e9", "not '2e9'"},
      {"simulate " + ok + " --frobnicate", "unknown option '--frobnicate'"},
      {"simulate " + ok + " --csv out.csv --csv-every 0",
       "--csv-every must be 1..1000000, not '0'"},
      {"simulate " + ok + " --csv out.csv --csv-every 1000001", "not '1000001'"},
      {"simulate " + ok + " --csv out.csv --csv-every x", "not 'x'"},
      {"simulate " + ok + " --csv-every 10", "--csv-every needs --csv OUT"},
      {"simulate " + ok + " --restart-after 2", "--restart-after needs --stop-at T"},
      // An empty value is not the flag left out.
      {"simulate " + ok + " --csv out.csv --csv-every ''",
       "--csv-every needs a value, not an empty string"},
      {"simulate " + ok + " --rel-speed=", "--rel-speed needs a value, not an empty string"},
      {"simulate /nonexistent.ngc --config " + kConfig, "/nonexistent.ngc: error: cannot open"},
      {"simulate " + ok + " --start Q5", "--start: 'Q5' does not start with an axis letter of XYZ"},
      {"simulate " + ok + " --start X1,x2", "--start: X is given twice"},
      {"simulate " + ok + " --start Y", "--start: 'Y': Y takes a number of mm within +-1e9"},
      {"simulate " + ok + " --start Z2e9", "--start: 'Z2e9': Z takes a number of mm within +-1e9"},
      {"simulate " + ok + " --start X1,,Y2", "--start: an empty item in 'X1,,Y2'"},
  };
  for (const auto& [args, message] : cases) {
    r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << "\n" << r.err;
    EXPECT_TRUE(r.out.empty()) << args;
  }
  r = run("simulate --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("usage: tgm-hmi simulate FILE"), std::string::npos);
}

// --limit-share F checks against F of each limit (and implies --check-limits): the manual's
// example keeps the full limits and uses more than half of some, so at 0.5 it fails with the
// excesses listed against the halved limits.
TEST_F(HmiSimulate, LimitShareChecksAgainstThatPartOfEachLimit) {
  const ProcessResult full =
      run("simulate " + kExample + " --config " + kConfig + " --limit-share 1");
  ASSERT_EQ(full.exit_code, 0) << full.out << full.err;
  EXPECT_NE(full.out.find("violations: 0\n"), std::string::npos) << full.out;
  const ProcessResult half =
      run("simulate " + kExample + " --config " + kConfig + " --limit-share 0.5");
  EXPECT_EQ(half.exit_code, 1) << half.out << half.err;
  EXPECT_NE(half.out.find("limits checked at 0.5 x the configured ones"), std::string::npos)
      << half.out;
  EXPECT_NE(half.out.find("violations: "), std::string::npos) << half.out;
  EXPECT_EQ(half.out.find("violations: 0\n"), std::string::npos) << half.out;
  // Only the check changes, not the motion (the help said it held the motion to F): the same
  // program time to the last digit.
  const auto program_time = [](const std::string& out) {
    const std::size_t at = out.find("time:");
    return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
  };
  EXPECT_FALSE(program_time(full.out).empty()) << full.out;
  EXPECT_EQ(program_time(half.out).substr(0, program_time(half.out).find(',')),
            program_time(full.out).substr(0, program_time(full.out).find(',')));
  // More than 20 are counted, 20 listed, and the rest said (they were left out without a word).
  const std::size_t v = half.out.find("violations: ");
  const unsigned long long count = std::stoull(half.out.substr(v + 12));
  ASSERT_GT(count, 20u) << half.out;
  EXPECT_NE(half.out.find("  (the first 20 listed; " + std::to_string(count - 20) + " more)\n"),
            std::string::npos)
      << half.out;
}

TEST_F(HmiSimulate, ProgressGoesToStandardErrorUnlessQuiet) {
  // 20,000 cycles with the CSV (every cycle stepped): some progress lines at a tiny interval.
  const fs::path prog = write("line.ngc", "G90 G1 X100 F600\nM2\n");
  const std::string args = "simulate " + prog.string() + " --config " + kConfig + " --csv " +
                           (dir_ / "o.csv").string() + " --progress-interval 0.000001";
  ProcessResult r = run(args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto progress = lines(r.err);
  ASSERT_GE(progress.size(), 2u) << r.err;
  for (const auto& l : progress) EXPECT_EQ(l.rfind("simulate: ", 0), 0u) << l;
  EXPECT_NE(r.err.find("% of the records, line 1, program time"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("simulate: "), std::string::npos);  // the summary stays clean
  r = run(args + " --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
}

// 6,000 s of program time: stepped cycle by cycle into a CSV, far longer than a test waits.
const std::string kLongProgram = "G90 G1 X1000 F10\nM2\n";

// Runs `prog` with `extra` flags and its CSV in `dir`, and interrupts it with SIGINT once it is
// well under way. Returns the exit code (-1: killed or hung, after a test failure), the summary
// and the CSV.
struct Interrupted {
  int exit_code = -1;
  std::string summary, csv;
};
Interrupted run_and_interrupt(const fs::path& dir, const fs::path& prog,
                              const std::vector<std::string>& extra) {
  const fs::path csv = dir / "long.csv", out = dir / "stdout", err = dir / "stderr";
  std::vector<std::string> argv = {TGM_HMI, "simulate", prog.string(), "--config",
                                   kConfig, "--csv",    csv.string(),  "--progress-interval",
                                   "0.05"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  std::vector<char*> args;
  for (std::string& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  Interrupted r;
  const pid_t pid = ::fork();
  if (pid < 0) {
    ADD_FAILURE() << "fork failed";
    return r;
  }
  if (pid == 0) {
    std::freopen(out.c_str(), "w", stdout);
    std::freopen(err.c_str(), "w", stderr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  // Interrupt once it is well under way (it says so on standard error).
  const auto give_up = std::chrono::steady_clock::now() + 60s;
  while (slurp(err).find("simulate: ") == std::string::npos && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(20ms);
  }
  ::kill(pid, SIGINT);
  int status = 0;
  pid_t done = 0;
  while ((done = ::waitpid(pid, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < give_up + 30s) {
    std::this_thread::sleep_for(20ms);
  }
  if (done == 0) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    ADD_FAILURE() << "tgm-hmi simulate did not stop on SIGINT";
    return r;
  }
  if (!WIFEXITED(status)) {
    ADD_FAILURE() << "killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    return r;
  }
  r.exit_code = WEXITSTATUS(status);
  r.summary = slurp(out);
  r.csv = slurp(csv);
  return r;
}

TEST_F(HmiSimulate, InterruptKeepsEveryCycleWrittenAndSaysSo) {
  const Interrupted r = run_and_interrupt(dir_, write("long.ngc", kLongProgram), {});
  EXPECT_EQ(r.exit_code, 130);
  EXPECT_NE(r.summary.find("result:    NOT finished: interrupted by SIGINT"), std::string::npos)
      << r.summary;
  ASSERT_FALSE(r.csv.empty());
  EXPECT_EQ(r.csv.back(), '\n');
  const auto rows = lines(r.csv);
  const double cycles = number_before(r.summary, " cycles");
  EXPECT_GT(cycles, 0.0);
  EXPECT_LT(cycles, 12e6);  // stopped long before the end
  EXPECT_EQ(static_cast<double>(rows.size() - 1), cycles);
  EXPECT_NEAR(std::atof(rows.back().c_str()), cycles * 0.0005, 1e-6);
}

// With --csv-every the cycle the interrupt ended on is the last row, an N-th or not.
TEST_F(HmiSimulate, InterruptWithCsvEveryStillWritesTheLastCycle) {
  const Interrupted r =
      run_and_interrupt(dir_, write("long.ngc", kLongProgram), {"--csv-every", "997"});
  EXPECT_EQ(r.exit_code, 130);
  EXPECT_NE(r.summary.find("interrupted by SIGINT (the output files hold the run up to here)"),
            std::string::npos)
      << r.summary;
  const auto rows = lines(r.csv);
  const double cycles = number_before(r.summary, " cycles");
  ASSERT_GT(cycles, 997.0 * 3);
  // Every 997th cycle, a few events (the start, run_flag's section changes) and the last cycle.
  std::vector<long long> at;
  for (std::size_t i = 1; i < rows.size(); ++i)
    at.push_back(std::llround(std::atof(rows[i].c_str()) / 0.0005));
  ASSERT_TRUE(std::is_sorted(at.begin(), at.end()));
  const auto n = static_cast<long long>(cycles);
  for (long long c = 997; c <= n; c += 997) {
    EXPECT_TRUE(std::binary_search(at.begin(), at.end(), c)) << "cycle " << c;
  }
  EXPECT_LE(at.size(), static_cast<std::size_t>(n / 997 + 8));
  EXPECT_EQ(at.back(), n);
}

// Block search: --from-line compiles the whole program from --start and runs it from line N on,
// after an approach from --here; it names the PLC M-functions it skips. The end point is the
// whole program's, and bad lines and flags are refused with the reason.
TEST_F(HmiSimulate, FromLineApproachesTheLineAndRunsTheRestOfTheProgram) {
  // G91 from X20: line 4 starts at X25 (after line 2's X+5 and the M51) and ends at X30.
  const fs::path prog = write("inc.ngc", "G91\nG1 X5 F3000\nM51 S7\nG1 X5\nG1 Y5\nM2\n");
  const std::string base = "simulate " + prog.string() + " --config " + kConfig + " --quiet";
  const ProcessResult r =
      run(base + " --start X20 --from-line 4 --here X0,Y-3 --approach-feed 1200 --check-limits");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.err.find("resuming at line 4 (record 3 of 5): approach from X0 Y-3 Z0 to X25 Y0 Z0 "
                       "at 1200 mm/min"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("1 PLC M-function before line 4 never reaches the PLC: M51 (line 3)"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.out.find("(4 records, interpolator 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("end:       X=30.000000 Y=5.000000 Z=0.000000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0 M-functions acknowledged"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("violations: 0"), std::string::npos) << r.out;
  // The approach is a move of its own at its feed: 25.18 mm at 20 mm/s, then 10 mm at 50 mm/s.
  EXPECT_GT(number_before(r.out, " s program time"), 25.179 / 20.0 + 10.0 / 50.0) << r.out;

  // Standing where the line starts: no approach.
  const ProcessResult at = run(base + " --start X20 --from-line 4 --here X25");
  ASSERT_EQ(at.exit_code, 0) << at.out << at.err;
  EXPECT_NE(at.err.find("the machine stands where it starts (X25 Y0 Z0)"), std::string::npos)
      << at.err;
  EXPECT_NE(at.out.find("(3 records"), std::string::npos) << at.out;

  const struct {
    std::string flags, says;
  } bad[] = {
      {" --from-line 1", "error: --from-line: line 1 makes no record"},
      {" --from-line 7",
       "error: --from-line: line 7 lies after the program's last record (line 6)"},
      {" --from-line 4 --occurrence 2", "line 4 runs 1 time in the program"},
      {" --from-line 0", "--from-line must be 1..2147483647, not '0'"},
      {" --occurrence 2", "--occurrence needs --from-line N"},
      {" --approach-feed 100", "--approach-feed needs --from-line N"},
      {" --here X1", "--here needs --from-line N"},
      {" --from-line 4 --approach-feed 0", "--approach-feed must be mm/min, > 0"},
      {" --from-line 4 --here Q1", "--here: "},
  };
  for (const auto& b : bad) {
    const ProcessResult e = run(base + b.flags);
    EXPECT_EQ(e.exit_code, 2) << b.flags << "\n" << e.out << e.err;
    EXPECT_NE(e.err.find(b.says), std::string::npos) << b.flags << "\n" << e.err;
    EXPECT_EQ(e.out.find("result:"), std::string::npos) << b.flags << ": it ran\n" << e.out;
  }
}

}  // namespace
}  // namespace tgm
