// Reference test of tool radius compensation (G41/G42/G40): our compiler against LinuxCNC's
// interpreter (`rs274 -g`), motion by motion with the comparison of reference_test.cpp.
//
// Dialects: our `G41 D<r>` / `G42 D<r>` give the RADIUS r [mm]; LinuxCNC's `G41.1 D<d>` /
// `G42.1 D<d>` give the DIAMETER. Every program here is written in our dialect and translated
// line by line (`to_rs274_dialect`) for rs274, so line numbers are the same in both files.
//
// - programs_comp/*.ngc: hand-written contours; `err_*.ngc` must be rejected by both, and our
//   first error must name the block rs274 names.
// - CompensationSweep: seeded random G17 G90 contours of lines and I/J arcs. Where rs274 rejects
//   a program ours must reject it too and vice versa; otherwise the motions must agree.
// - CompensationErrors: the line our diagnostics name.
//
// Environment: TGM_COMP_SEED (default 20240612), TGM_COMP_COUNT (programs, default 100),
// TGM_COMP_FIRST (index of the first program, default 0: TGM_COMP_FIRST=i TGM_COMP_COUNT=1
// reruns program i of a sweep), TGM_COMP_SHRINK (default 1: cut failing programs down to a
// smaller one that fails the same way, kept next to them as *_min.ngc), TGM_COMP_TANGENT
// (percentage of tangent joins, default 35), TGM_REF_KEEP=1 (keep
// programs that pass), TGM_RS274, TGM_REQUIRE_RS274 (as for reference_test.cpp). Failing
// programs are kept in build/tests/reference/work/ with their rs274 translation
// (*.rs274.ngc) and rs274's output (*.rs274.out).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "../support/sweep_progress.hpp"
#include "../support/test_params.hpp"
#include "ngc_generator.hpp"
#include "reference_compare.hpp"
#include "rs274_canon.hpp"
#include "tgm/gcode.hpp"

namespace fs = std::filesystem;

namespace tgm::ref {
namespace {

constexpr double kPi = 3.14159265358979323846;

// ---- dialect ---------------------------------------------------------------------------------

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

//! Our program in RS274/NGC: on a line with G41/G42, those become G41.1/G42.1 and the D word
//! (our radius) becomes twice its value (LinuxCNC's diameter). Words must be separated by blanks
//! (as in every program of this file); comments are copied as they are.
std::string to_rs274_dialect(const std::string& ours) {
  std::string out;
  for (const std::string& line : split_lines(ours)) {
    const std::size_t comment = std::min(line.find('('), line.find(';'));
    const std::string code = line.substr(0, comment);
    std::vector<std::string> words;
    std::istringstream ws(code);
    for (std::string w; ws >> w;) words.push_back(w);
    bool comp_on = false;
    for (std::string& w : words) {
      const std::string u = upper(w);
      if (u == "G41" || u == "G42") {
        w = u + ".1";
        comp_on = true;
      }
    }
    if (comp_on) {
      for (std::string& w : words) {
        if (w.size() > 1 && std::toupper(static_cast<unsigned char>(w[0])) == 'D') {
          char buf[48];
          std::snprintf(buf, sizeof buf, "D%.6f", 2.0 * std::strtod(w.c_str() + 1, nullptr));
          w = buf;
        }
      }
    }
    std::string rebuilt;
    for (const std::string& w : words) rebuilt += (rebuilt.empty() ? "" : " ") + w;
    if (comment != std::string::npos) {
      rebuilt += (rebuilt.empty() ? "" : " ") + line.substr(comment);
    }
    out += rebuilt + "\n";
  }
  return out;
}

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

// ---- running both ----------------------------------------------------------------------------

//! Both interpreters' view of one program.
struct Outcome {
  // rs274
  bool rs_ok = false;
  std::string rs_message;     //!< rs274's error text (stderr without "executing")
  std::string rs_block;       //!< the block rs274 names with its error (last stderr line)
  std::vector<int> rs_lines;  //!< lines of the program holding that block (1-based)
  std::string rs_out;         //!< canonical output
  std::string parse_error;    //!< set when rs274's output could not be read
  CanonProgram canon;
  // ours
  CompileResult ours;
};

//! Runs rs274 on the translation of `text` (kept as `base`.rs274.ngc; `text` itself is written
//! to `base`.ngc) and our compiler on `text`.
Outcome run_both(const std::string& rs274, const fs::path& base, const std::string& text) {
  Outcome o;
  const std::string rs_text = to_rs274_dialect(text);
  const fs::path ours_file = fs::path(base.string() + ".ngc");
  const fs::path rs_file = fs::path(base.string() + ".rs274.ngc");
  {
    std::ofstream f(ours_file, std::ios::binary);
    f << text;
  }
  {
    std::ofstream f(rs_file, std::ios::binary);
    f << rs_text;
  }
  const Rs274Run run = run_rs274(rs274, rs_file.string());
  o.rs_out = run.out;
  std::vector<std::string> msg;
  for (const std::string& l : split_lines(run.err)) {
    const std::string t = trimmed(l);
    if (!t.empty() && t != "executing") msg.push_back(t);
  }
  for (const std::string& m : msg) o.rs_message += (o.rs_message.empty() ? "" : " / ") + m;
  if (const auto perr = parse_canon(run.out, o.canon)) o.parse_error = *perr;
  o.rs_ok = run.exit_code == 0 && o.canon.ended && o.parse_error.empty();
  if (!o.rs_ok && !msg.empty()) {
    o.rs_block = msg.back();
    const std::vector<std::string> lines = split_lines(rs_text);
    for (std::size_t i = 0; i < lines.size(); ++i) {
      if (trimmed(lines[i]) == o.rs_block) o.rs_lines.push_back(static_cast<int>(i + 1));
    }
  }
  if (!o.rs_ok && o.rs_message.empty()) {
    o.rs_message = "exit code " + std::to_string(run.exit_code) +
                   (o.canon.ended ? "" : ", no PROGRAM_END") +
                   (o.parse_error.empty() ? "" : ", " + o.parse_error);
  }
  CompileOptions opt;
  opt.axis_letters = "XYZ";
  opt.compiler.start_incremental = first_line_incremental(text);
  o.ours = compile_gcode(text, opt);
  return o;
}

void remove_files(const fs::path& base) {
  std::error_code ec;
  for (const char* ext : {".ngc", ".rs274.ngc", ".rs274.out"}) fs::remove(base.string() + ext, ec);
}

std::string describe(const Segment& s) {
  std::ostringstream o;
  o << "G" << static_cast<int>(s.type) << " X" << fmt(s.end[0]) << " Y" << fmt(s.end[1]) << " Z"
    << fmt(s.end[2]);
  if (s.is_arc()) o << " centre(" << fmt(s.center[0]) << ", " << fmt(s.center[1]) << ")";
  if (s.type != SegmentType::kRapid) o << " F" << s.feed_mm_per_min;
  o << "  [line " << s.line << "]";
  return o.str();
}

std::string describe(const CanonMotion& m) {
  std::ostringstream o;
  o << "G" << m.type << " X" << fmt(m.end[0]) << " Y" << fmt(m.end[1]) << " Z" << fmt(m.end[2]);
  if (m.type >= 2) o << " centre(" << fmt(m.center[0]) << ", " << fmt(m.center[1]) << ")";
  if (m.type != 0) o << " F" << m.feed_mm_per_min;
  o << "  [output line " << m.output_line << "]";
  return o.str();
}

//! Both motion lists, one motion a line (for reports on programs of up to `max` motions).
std::string motion_listing(const Outcome& o, std::size_t max = 80) {
  std::vector<const Segment*> ours;
  for (const Segment& s : o.ours.program.segments) {
    if (s.is_motion()) ours.push_back(&s);
  }
  const std::size_t n = std::max(ours.size(), o.canon.motions.size());
  if (n > max) return "";
  std::ostringstream r;
  r << "  motions (ours | rs274):\n";
  for (std::size_t k = 0; k < n; ++k) {
    r << "   #" << k << "  " << (k < ours.size() ? describe(*ours[k]) : std::string("-"))
      << "\n        " << (k < o.canon.motions.size() ? describe(o.canon.motions[k]) : "-") << "\n";
  }
  return r.str();
}

std::string our_errors(const CompileResult& r, const std::string& file, std::size_t max = 3) {
  std::string s;
  for (std::size_t i = 0; i < r.errors.size() && i < max; ++i) {
    s += "    " + format_diagnostic(file, r.errors[i]) + "\n";
  }
  return s;
}

std::string rs_lines_text(const Outcome& o) {
  if (o.rs_lines.empty()) return "?";
  std::string s;
  for (int l : o.rs_lines) s += (s.empty() ? "" : "/") + std::to_string(l);
  return s;
}

//! How the two interpreters relate on one program.
enum class Verdict { kAgree, kBothRejected, kOnlyRs274Rejected, kOnlyOursRejected, kDiffer };

Verdict judge(const Outcome& o, const std::string& text, std::string& report,
              const std::string& file) {
  report.clear();
  if (!o.parse_error.empty()) {
    report = "  rs274 output unreadable: " + o.parse_error + "\n";
    return Verdict::kDiffer;
  }
  if (!o.rs_ok && !o.ours.ok()) return Verdict::kBothRejected;
  if (!o.rs_ok) {
    report = "  rs274 rejected it (line " + rs_lines_text(o) + "): " + o.rs_message +
             "\n  ours accepted it (" + std::to_string(o.ours.program.segments.size()) +
             " records)\n" + motion_listing(o);
    return Verdict::kOnlyRs274Rejected;
  }
  if (!o.ours.ok()) {
    report = "  ours rejected it:\n" + our_errors(o.ours, file) + "  rs274 accepted it (" +
             std::to_string(o.canon.motions.size()) + " motions)\n";
    return Verdict::kOnlyOursRejected;
  }
  const std::string diff = compare(o.canon, o.ours.program, text);
  if (diff.empty()) return Verdict::kAgree;
  report = diff + motion_listing(o);
  return Verdict::kDiffer;
}

//! Marks the test skipped, or failed under TGM_REQUIRE_RS274.
void skip_without_rs274() {
  if (rs274_required()) {
    ADD_FAILURE() << "rs274 not found (PATH or $TGM_RS274) but TGM_REQUIRE_RS274 is set; "
                     "install the Debian package linuxcnc-uspace";
  } else {
    GTEST_SKIP() << "rs274 not found on PATH (Debian package linuxcnc-uspace); set "
                    "TGM_REQUIRE_RS274=1 to make this a failure";
  }
}

//! rs274's path, or empty after skip_without_rs274().
std::string rs274_or_skip() {
  std::string rs274 = find_rs274();
  if (rs274.empty()) skip_without_rs274();
  return rs274;
}

fs::path comp_work_dir() {
  fs::path d = work_dir() / "comp";
  fs::create_directories(d);
  return d;
}

bool keep_passing() {
  return test::env_u64("TGM_REF_KEEP", 0) != 0;
}

// ---- the translation itself (runs without rs274) ---------------------------------------------

TEST(CompDialect, TranslatesRadiusToDiameterOnG41G42LinesOnly) {
  const std::string ours =
      "G90 G17\n"
      "G41 D1.25\n"
      "g42 d0.5 G1 X1 Y2 (D9 G41)\n"
      "G40 G0 X0 Y0\n"
      "G1 X3 D7\n";
  EXPECT_EQ(to_rs274_dialect(ours),
            "G90 G17\n"
            "G41.1 D2.500000\n"
            "G42.1 D1.000000 G1 X1 Y2 (D9 G41)\n"
            "G40 G0 X0 Y0\n"
            "G1 X3 D7\n");
}

// ---- hand-written programs -------------------------------------------------------------------

fs::path hand_dir() {
  return fs::path(TGM_SOURCE_DIR) / "tests" / "reference" / "programs_comp";
}

std::vector<std::string> hand_comp_programs() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(hand_dir(), ec)) {
    if (e.path().extension() == ".ngc") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

class CompHandProgram : public ::testing::TestWithParam<std::string> {};

TEST_P(CompHandProgram, AgreesWithRs274) {
  const std::string rs274 = rs274_or_skip();
  if (rs274.empty()) return;
  const fs::path src = hand_dir() / (GetParam() + ".ngc");
  const std::string text = read_file(src);
  ASSERT_FALSE(text.empty()) << src;
  const fs::path base = comp_work_dir() / ("hand_" + GetParam());
  const Outcome o = run_both(rs274, base, text);
  ASSERT_TRUE(o.parse_error.empty()) << o.parse_error;
  const bool meant_to_fail = GetParam().rfind("err_", 0) == 0;
  bool ok = true;
  if (meant_to_fail) {
    // The program exists to show an error: rs274 must reject it, on one line we can find.
    ASSERT_FALSE(o.rs_ok) << src << " is meant to be rejected, but rs274 accepted it";
    ASSERT_EQ(o.rs_lines.size(), 1u)
        << "rs274's error block `" << o.rs_block << "` is not on exactly one line of " << src;
    const int rs_line = o.rs_lines.front();
    // Where ours names another block, the program says so: "(ours: line N ...".
    int our_line = rs_line;
    if (const std::size_t at = text.find("(ours: line "); at != std::string::npos) {
      our_line = std::atoi(text.c_str() + at + 12);
    }
    if (o.ours.ok()) {
      ok = false;
      ADD_FAILURE() << src << ": rs274 rejected line " << rs_line << " (" << o.rs_message
                    << "), ours accepted it\n"
                    << motion_listing(o);
    } else if (o.ours.errors.front().line != our_line) {
      ok = false;
      ADD_FAILURE() << src << ": our first error is on line " << o.ours.errors.front().line
                    << " (expected " << our_line << "), rs274 names line " << rs_line << " (`"
                    << o.rs_block << "`: " << o.rs_message << ")\n"
                    << our_errors(o.ours, src.string());
    }
  } else {
    ASSERT_TRUE(o.rs_ok) << src << " is meant to be valid, but rs274 rejected line "
                         << rs_lines_text(o) << ": " << o.rs_message;
    std::string report;
    const Verdict v = judge(o, text, report, src.string());
    ok = v == Verdict::kAgree;
    EXPECT_TRUE(ok) << "disagreement with rs274 on " << src << " (rs274 input " << base.string()
                    << ".rs274.ngc):\n"
                    << report;
  }
  if (ok && !keep_passing()) {
    remove_files(base);
  } else {
    std::ofstream(base.string() + ".rs274.out", std::ios::binary) << o.rs_out;
  }
}

INSTANTIATE_TEST_SUITE_P(Programs, CompHandProgram, ::testing::ValuesIn(hand_comp_programs()),
                         [](const ::testing::TestParamInfo<std::string>& i) {
                           std::string n = i.param;
                           for (char& c : n) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return n;
                         });

TEST(CompHandPrograms, Exist) {
  // A renamed directory must not quietly turn the hand-written tests into none.
  EXPECT_GE(hand_comp_programs().size(), 10u) << hand_dir();
}

// ---- the lines our diagnostics name ----------------------------------------------------------

struct LineCase {
  const char* name;
  const char* text;
  int line;  //!< the block rs274 names
  int ours;  //!< the block ours names (0: the same)
};

// Line numbers are pinned (so this runs without rs274) and checked against rs274's when it is
// there.
const LineCase kLineCases[] = {
    // A step 0.5 mm high in a contour cut with a 1 mm tool on the left (inside the step): the
    // rise, line 7, is too short for the tool to reach into the concave corner at its start
    // (ours names it); rs274 finds it one move later, at line 8, where the rise would run
    // backwards.
    {"gouge_step",
     "G90 G17\n"
     "G0 X-5 Y-5\n"
     "F500\n"
     "G41 D1\n"
     "G1 X0 Y0\n"
     "G1 X10 Y0\n"
     "G1 X10 Y0.5\n"
     "G1 X11 Y0.5\n"
     "G1 X11 Y0\n"
     "G1 X20 Y0\n"
     "G40\n"
     "G0 X-5 Y-5\n"
     "M2\n",
     8, 7},
    // A slot 0.8 mm wide, reached through a quarter arc, cut with a 0.6 mm tool on the right
    // (inside the slot): the move up out of the slot, line 10, cannot reach its concave corner.
    {"gouge_slot_after_arc",
     "G90 G17\n"
     "G0 X-5 Y5\n"
     "F400\n"
     "G42 D0.6\n"
     "G1 X0 Y0\n"
     "G1 X8 Y0\n"
     "G2 X10 Y-2 I0 J-2\n"
     "G1 X10 Y-6\n"
     "G1 X9.2 Y-6\n"
     "G1 X9.2 Y-3\n"
     "G1 X0 Y-3\n"
     "G40\n"
     "G0 X-5 Y5\n"
     "M2\n",
     10, 0},
    {"entry_too_short",
     "G90 G17\n"
     "G0 X-0.5 Y0\n"
     "F500\n"
     "G41 D1\n"
     "G1 X0 Y0\n"
     "G1 X10 Y0\n"
     "G40\n"
     "G0 X-5 Y-5\n"
     "M2\n",
     5, 0},
};

TEST(CompensationErrors, NameTheOffendingLine) {
  const std::string rs274 = find_rs274();
  for (const LineCase& c : kLineCases) {
    SCOPED_TRACE(c.name);
    if (!rs274.empty()) {
      const Outcome o = run_both(rs274, comp_work_dir() / (std::string("line_") + c.name), c.text);
      ASSERT_FALSE(o.rs_ok) << "rs274 accepted " << c.name << "; the case is wrong";
      EXPECT_EQ(o.rs_lines, std::vector<int>{c.line})
          << "rs274 names `" << o.rs_block << "` (" << o.rs_message << "); the case is wrong";
      if (!keep_passing()) remove_files(comp_work_dir() / (std::string("line_") + c.name));
    }
    CompileOptions opt;
    opt.axis_letters = "XYZ";
    opt.compiler.start_incremental = false;
    const CompileResult r = compile_gcode(c.text, opt);
    ASSERT_FALSE(r.ok()) << "our compiler accepted " << c.name << ":\n" << c.text;
    EXPECT_EQ(r.errors.front().line, c.ours != 0 ? c.ours : c.line)
        << "first error: " << format_diagnostic(c.name, r.errors.front());
  }
}

// ---- seeded random contours --------------------------------------------------------------------

// Six decimals: a programmed arc's end then lies within about 1e-6 mm of the circle through its
// start. With four (a CAM post's usual), the two radii differ by up to 7e-5 mm, and where an
// offset line meets the circle at a grazing angle the two interpreters' choices of radius put
// the cut up to 7e-4 mm apart (seeds 15, 16 and 22 of 300 each): rounding of the input, not a
// difference of the rules.
double round6(double v) {
  return std::round(v * 1e6) / 1e6 + 0.0;
}  // + 0.0: no "-0.000000"

std::string num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6f", round6(v));
  return buf;
}

//! A G17 G90 program: rapid to a start point, G41/G42 with a random radius, entry line to the
//! contour, 5-40 lines and I/J arcs joined tangentially or at a corner of 0.15-2.8 rad either
//! way, G40, a move away, M2. Corners near LinuxCNC's 0.05 rad "tangent" threshold are left out,
//! so a rounding difference cannot flip a join. One program in ten is "tight" (elements and
//! radii of the order of the tool radius), which gives programs both must reject.
std::string generate_comp_program(std::uint64_t seed, double tangent_share = 0.35) {
  Rng rng(seed);
  const bool tight = rng.chance(0.1);
  const double r = round6(rng.uniform(0.1, 2.0));
  const int elements = rng.range(5, 40);
  std::ostringstream o;
  o << "G90 G17\n";
  double px = round6(rng.uniform(-50, 50));
  double py = round6(rng.uniform(-50, 50));
  const double away = rng.uniform(std::max(5.0, 3 * r), 30.0);
  const double entry_angle = rng.uniform(-kPi, kPi);
  const double sx = round6(px - away * std::cos(entry_angle));
  const double sy = round6(py - away * std::sin(entry_angle));
  o << "G0 X" << num(sx) << " Y" << num(sy) << "\n";
  o << "F" << 100 * rng.range(1, 30) << "\n";
  const std::string comp = std::string(rng.chance(0.5) ? "G41" : "G42") + " D" + num(r);
  if (rng.chance(0.25)) {
    o << comp << " G1 X" << num(px) << " Y" << num(py) << "\n";
  } else {
    o << comp << "\n"
      << "G1 X" << num(px) << " Y" << num(py) << "\n";
  }
  double dir = std::atan2(py - sy, px - sx);
  for (int k = 0; k < elements; ++k) {
    if (rng.chance(0.04)) o << "G1 Z" << num(-rng.uniform(0.1, 3.0)) << "\n";
    double turn = 0.0;
    if (!rng.chance(tangent_share)) turn = (rng.chance(0.5) ? 1 : -1) * rng.uniform(0.15, 2.8);
    const double d0 = dir + turn;
    const std::string feed = rng.chance(0.1) ? " F" + std::to_string(100 * rng.range(1, 30)) : "";
    if (rng.chance(0.5)) {
      const double len =
          tight ? rng.uniform(0.3, 4 * r + 0.5) : rng.uniform(std::max(1.0, 6 * r), 6 * r + 15);
      const double qx = round6(px + len * std::cos(d0));
      const double qy = round6(py + len * std::sin(d0));
      o << "G1 X" << num(qx) << " Y" << num(qy) << feed << "\n";
      dir = std::atan2(qy - py, qx - px);
      px = qx;
      py = qy;
    } else {
      const bool ccw = rng.chance(0.5);
      const double rad =
          tight ? rng.uniform(0.5 * r, 4 * r) + 0.1 : rng.uniform(3 * r + 0.5, 3 * r + 15);
      const double min_len = tight ? 0.3 : std::max(1.0, 4 * r);
      const double sweep = rng.uniform(std::min(3.0, std::max(0.2, min_len / rad)), 3.5);
      const double side = ccw ? 1.0 : -1.0;
      const double i = round6(-side * rad * std::sin(d0));
      const double j = round6(side * rad * std::cos(d0));
      const double cx = px + i;
      const double cy = py + j;
      const double a1 = std::atan2(py - cy, px - cx) + side * sweep;
      const double rr = std::hypot(i, j);
      const double qx = round6(cx + rr * std::cos(a1));
      const double qy = round6(cy + rr * std::sin(a1));
      o << (ccw ? "G3" : "G2") << " X" << num(qx) << " Y" << num(qy) << " I" << num(i) << " J"
        << num(j) << feed << "\n";
      dir = std::atan2(qy - cy, qx - cx) + side * kPi / 2;
      px = qx;
      py = qy;
    }
  }
  const double leave = rng.uniform(-kPi, kPi);
  const double ex = px + rng.uniform(5, 20) * std::cos(leave);
  const double ey = py + rng.uniform(5, 20) * std::sin(leave);
  const std::string exit_move =
      std::string(rng.chance(0.3) ? "G1" : "G0") + " X" + num(ex) + " Y" + num(ey);
  if (rng.chance(0.3)) {
    o << "G40 " << exit_move << "\n";
  } else {
    o << "G40\n" << exit_move << "\n";
  }
  o << "M2\n";
  return o.str();
}

TEST(CompGenerator, SameSeedSameText) {
  EXPECT_EQ(generate_comp_program(5), generate_comp_program(5));
  EXPECT_NE(generate_comp_program(5), generate_comp_program(6));
  const std::string t = generate_comp_program(5);
  EXPECT_NE(t.find("G4"), std::string::npos);
  EXPECT_NE(t.find("\nG40"), std::string::npos);
}

//! Cuts `text` down, one line at a time (never the first four lines or the last three), as long
//! as the result still gets `want` from the two interpreters. Returns the smallest found.
std::string shrink(const std::string& rs274, const std::string& text, Verdict want,
                   const fs::path& base, int max_runs = 400) {
  std::vector<std::string> lines = split_lines(text);
  int runs = 0;
  bool progress = true;
  while (progress && runs < max_runs) {
    progress = false;
    // From the end: most disagreements are local, so the tail goes first.
    for (std::size_t i = lines.size() >= 4 ? lines.size() - 4 : 0; i >= 4 && runs < max_runs; --i) {
      std::vector<std::string> cand = lines;
      cand.erase(cand.begin() + static_cast<std::ptrdiff_t>(i));
      std::string t;
      for (const std::string& l : cand) t += l + "\n";
      ++runs;
      const Outcome o = run_both(rs274, base, t);
      std::string report;
      if (judge(o, t, report, base.string() + ".ngc") == want) {
        lines = cand;
        progress = true;
      }
    }
  }
  std::string t;
  for (const std::string& l : lines) t += l + "\n";
  return t;
}

// ---- an independent look at rs274's path ----------------------------------------------------

struct P2 {
  double x = 0, y = 0;
};

double distance_to_segment(P2 p, P2 a, P2 b) {
  const double dx = b.x - a.x, dy = b.y - a.y;
  const double l2 = dx * dx + dy * dy;
  double t = l2 > 0 ? ((p.x - a.x) * dx + (p.y - a.y) * dy) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return std::hypot(p.x - (a.x + t * dx), p.y - (a.y + t * dy));
}

//! Distance from `p` to the arc from `a` to `b` around `c` (cw or not), full circle when a == b.
double distance_to_arc(P2 p, P2 a, P2 b, P2 c, bool cw) {
  const auto angle = [&](P2 q) { return std::atan2(q.y - c.y, q.x - c.x); };
  const auto ccw_from_a = [&](double th) {
    double d = cw ? angle(a) - th : th - angle(a);
    d = std::fmod(d, 2 * kPi);
    return d < 0 ? d + 2 * kPi : d;
  };
  const double r = std::hypot(a.x - c.x, a.y - c.y);
  const bool full = std::hypot(b.x - a.x, b.y - a.y) < 1e-9;
  const double sweep = full ? 2 * kPi : ccw_from_a(angle(b));
  if (ccw_from_a(angle(p)) <= sweep) return std::fabs(std::hypot(p.x - c.x, p.y - c.y) - r);
  return std::min(std::hypot(p.x - a.x, p.y - a.y), std::hypot(p.x - b.x, p.y - b.y));
}

//! How close rs274's tool centre comes to the programmed contour of `text` (a generated
//! program: initial G0, entry, contour, exit move, M2), at the ends of its moves between the
//! entry and the exit move; `radius` receives the program's compensation radius. Where rs274
//! runs a program ours refuses, an approach closer than the radius says rs274's path cuts into
//! the contour, so the refusal is right.
double closest_approach(const Outcome& o, const std::string& text, double& radius) {
  radius = 0.0;
  std::string zero;  // the program with radius 0: its records are the programmed contour
  for (const std::string& line : split_lines(text)) {
    std::string out;
    std::istringstream ws(line);
    const bool comp = upper(line).find("G41") != std::string::npos ||
                      upper(line).find("G42") != std::string::npos;
    for (std::string w; ws >> w;) {
      if (comp && w.size() > 1 && std::toupper(static_cast<unsigned char>(w[0])) == 'D') {
        radius = std::strtod(w.c_str() + 1, nullptr);
        w = "D0";
      }
      out += (out.empty() ? "" : " ") + w;
    }
    zero += out + "\n";
  }
  CompileOptions opt;
  opt.axis_letters = "XYZ";
  opt.compiler.start_incremental = first_line_incremental(text);
  const CompileResult programmed = compile_gcode(zero, opt);
  std::vector<const Segment*> moves;
  for (const Segment& s : programmed.program.segments) {
    if (s.is_motion()) moves.push_back(&s);
  }
  double closest = 1e300;
  if (moves.size() < 3 || o.canon.motions.size() < 3) return closest;
  for (std::size_t k = 1; k + 1 < o.canon.motions.size(); ++k) {
    const P2 v{o.canon.motions[k].end[0], o.canon.motions[k].end[1]};
    for (std::size_t m = 1; m + 1 < moves.size(); ++m) {
      const P2 a{moves[m - 1]->end[0], moves[m - 1]->end[1]};
      const P2 b{moves[m]->end[0], moves[m]->end[1]};
      const double d = moves[m]->is_arc()
                           ? distance_to_arc(v, a, b, {moves[m]->center[0], moves[m]->center[1]},
                                             moves[m]->type == SegmentType::kArcCw)
                           : distance_to_segment(v, a, b);
      closest = std::min(closest, d);
    }
  }
  return closest;
}

TEST(CompensationCheck, ClosestApproachSeesACutIntoTheContour) {
  // rs274's path for a square of side 10 at radius 1 keeps 1 mm; one vertex moved inside by
  // 0.4 mm comes within 0.6.
  Outcome o;
  const std::string text =
      "G90 G17\nG0 X-5 Y-5\nF500\nG41 D1\nG1 X0 Y0\nG1 X10 Y0\nG1 X10 Y10\nG40\nG0 X20 "
      "Y20\nM2\n";
  for (const auto& e : std::vector<std::array<double, 2>>{{-5, -5}, {9, 1}, {9, 10}, {20, 20}}) {
    CanonMotion m;
    m.end = {e[0], e[1], 0};
    o.canon.motions.push_back(m);
  }
  double r = 0;
  EXPECT_NEAR(closest_approach(o, text, r), 1.0, 1e-12);
  EXPECT_EQ(r, 1.0);
  o.canon.motions[1].end = {9, 0.6, 0};
  EXPECT_NEAR(closest_approach(o, text, r), 0.6, 1e-12);
}

const char* verdict_name(Verdict v) {
  switch (v) {
    case Verdict::kAgree:
      return "agree";
    case Verdict::kBothRejected:
      return "both rejected";
    case Verdict::kOnlyRs274Rejected:
      return "only rs274 rejected";
    case Verdict::kOnlyOursRejected:
      return "only ours rejected";
    case Verdict::kDiffer:
      return "motions differ";
  }
  return "?";
}

TEST(CompensationSweep, AgreesWithRs274) {
  const std::string rs274 = rs274_or_skip();
  if (rs274.empty()) return;
  const std::uint64_t seed = test::param_u64("comp-seed", "TGM_COMP_SEED", 20240612);
  const std::uint64_t count = test::param_u64("comp-count", "TGM_COMP_COUNT", 100);
  const std::uint64_t first = test::param_u64("comp-first", "TGM_COMP_FIRST", 0);
  const bool shrink_failures = test::env_u64("TGM_COMP_SHRINK", 1) != 0;
  const double tangent_share =
      static_cast<double>(std::min<std::uint64_t>(test::env_u64("TGM_COMP_TANGENT", 35), 100)) /
      100.0;
  std::size_t agreed = 0;
  std::size_t rs274_accepted = 0;
  std::size_t both_rejected = 0;
  std::size_t same_line = 0;
  std::size_t failed = 0;
  std::size_t shrunk = 0;
  std::size_t rs274_cuts_in = 0;  //!< refused by ours only, and rs274's path cuts in
  std::ostringstream failures;
  test::SweepProgress progress("CompensationSweep (rs274) seed " + std::to_string(seed), count);
  for (std::uint64_t index = first; index < first + count; ++index) {
    progress.update(index - first);
    const std::uint64_t program_seed = seed * 1000003u + index;
    const std::string text = generate_comp_program(program_seed, tangent_share);
    const fs::path base =
        work_dir() / ("comp_" + std::to_string(seed) + "_" + std::to_string(index));
    const Outcome o = run_both(rs274, base, text);
    std::string report;
    Verdict v = judge(o, text, report, base.string() + ".ngc");
    if (v == Verdict::kAgree) ++agreed;
    if (o.rs_ok) ++rs274_accepted;
    if (v == Verdict::kBothRejected) {
      ++both_rejected;
      if (o.rs_lines.size() == 1 && o.ours.errors.front().line == o.rs_lines.front()) ++same_line;
    }
    if (v == Verdict::kOnlyOursRejected) {
      double r = 0;
      if (closest_approach(o, text, r) < r - 1e-3) {
        ++rs274_cuts_in;
        v = Verdict::kBothRejected;
      }
    }
    if (v == Verdict::kAgree || v == Verdict::kBothRejected) {
      if (!keep_passing()) remove_files(base);
      continue;
    }
    ++failed;
    std::ofstream(base.string() + ".rs274.out", std::ios::binary) << o.rs_out;
    if (failed <= 5) {
      failures << "seed " << seed << " program " << index << " (TGM_COMP_SEED=" << seed
               << " TGM_COMP_FIRST=" << index << " TGM_COMP_COUNT=1): " << verdict_name(v)
               << "\n  program: " << base.string() << ".ngc (rs274 input " << base.string()
               << ".rs274.ngc)\n"
               << report;
      if (shrink_failures && shrunk < 3) {
        ++shrunk;
        const fs::path min_base = fs::path(base.string() + "_min");
        const std::string small = shrink(rs274, text, v, min_base);
        const Outcome m = run_both(rs274, min_base, small);
        std::string min_report;
        judge(m, small, min_report, min_base.string() + ".ngc");
        std::ofstream(min_base.string() + ".rs274.out", std::ios::binary) << m.rs_out;
        failures << "  smallest program failing the same way (" << min_base.string() << ".ngc):\n"
                 << small << min_report;
      }
    } else {
      failures << "seed " << seed << " program " << index << ": " << verdict_name(v) << ", "
               << base.string() << ".ngc\n";
    }
  }
  std::cout << "[ compensation sweep ] seed " << seed << ", programs " << first << ".."
            << first + count - 1 << ": " << agreed << " agreed, " << both_rejected
            << " rejected by both (" << same_line << " on the same line), " << rs274_cuts_in
            << " rejected by ours only where rs274's path cuts into the contour, " << failed
            << " failed\n";
  EXPECT_EQ(failed, 0u) << failures.str();
  // The generator must mostly make programs rs274 runs, or the sweep compares little.
  EXPECT_GE(rs274_accepted, (count * 6) / 10)
      << "fewer than 60% of the programs were accepted by rs274: the generator is off";
}

}  // namespace
}  // namespace tgm::ref
