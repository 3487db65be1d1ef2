// G-code compiler: the dialect of core/GCODE.md, pinned known values and the exact text of
// every error class.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/printable.hpp"
#include "tgm/soft_limits.hpp"

namespace tgm {
namespace {

CompileOptions options(bool incremental = false) {
  CompileOptions o;
  o.axis_letters = "XYZ";
  o.compiler.start_incremental = incremental;
  o.tools = {{1, 3.0, 50.0}, {2, 5.0, 60.0}};
  return o;
}

Program compile_ok(const std::string& text, const CompileOptions& o = options()) {
  CompileResult r = compile_gcode(text, o);
  std::string all;
  for (const auto& e : r.errors) all += format_diagnostic("t.ngc", e) + "\n";
  EXPECT_TRUE(r.ok()) << all;
  return r.program;
}

// Errors as "LINE:COL: reason", one per entry.
std::vector<std::string> errors_of(const std::string& text, const CompileOptions& o = options()) {
  CompileResult r = compile_gcode(text, o);
  std::vector<std::string> out;
  for (const auto& e : r.errors) {
    out.push_back(std::to_string(e.line) + ":" + std::to_string(e.column) + ": " + e.reason);
  }
  if (!r.ok()) {
    EXPECT_TRUE(r.program.segments.empty()) << "a program with errors must yield no records";
  }
  return out;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

constexpr double kTol = 1e-9;

// --- The manual's example program ------------------------------------------------------------

TEST(GcodeExample, CompilesWithTheDefaultG91Start) {
  const std::string text = read_text(TGM_SOURCE_DIR "/tests/programs/manual_example.ngc");
  ASSERT_FALSE(text.empty());
  const Program p = compile_ok(text, options(/*incremental=*/true));
  // 2 rapids, 7 arcs, M51 twice, M50 once, M2.
  ASSERT_EQ(p.segments.size(), 13u);
  const Segment& rapid = p.segments[0];
  EXPECT_EQ(rapid.type, SegmentType::kRapid);
  EXPECT_NEAR(rapid.end[0], 60.6051, kTol);
  EXPECT_NEAR(rapid.end[1], 40.7723, kTol);

  const Segment& m51 = p.segments[1];
  EXPECT_EQ(m51.type, SegmentType::kMFunction);
  EXPECT_EQ(m51.m, 51);
  EXPECT_EQ(m51.m_kind, MKind::kNormal);
  EXPECT_EQ(m51.line, 3);
  EXPECT_EQ(m51.compensation, Compensation::kRight);
  // No tool (T0, the default initial tool) and no D: radius 0, the contour as programmed.
  EXPECT_DOUBLE_EQ(m51.compensation_radius_mm, 0.0);
  EXPECT_EQ(m51.tool, 0);

  // First arc: centre = start + (I, J) and the end radius equals the start radius.
  const Segment& a1 = p.segments[2];
  EXPECT_EQ(a1.type, SegmentType::kArcCw);
  EXPECT_EQ(a1.line, 4);
  EXPECT_NEAR(a1.center[0], 60.6051 + 3.0336, kTol);
  EXPECT_NEAR(a1.center[1], 40.7723 - 1.2601, kTol);
  EXPECT_NEAR(a1.end[0], 60.6051, kTol);
  EXPECT_NEAR(a1.end[1], 40.7723 - 2.5202, kTol);
  EXPECT_NEAR(a1.radius, std::hypot(3.0336, 1.2601), kTol);
  // Every arc closes: |end - centre| == radius within the compiler's tolerance.
  for (const Segment& s : p.segments) {
    if (!s.is_arc()) continue;
    const double r1 = std::hypot(s.end[0] - s.center[0], s.end[1] - s.center[1]);
    EXPECT_NEAR(r1, s.radius, std::max(0.005, 0.001 * s.radius)) << "line " << s.line;
  }
  // The last arc ends at X 60.6051 + sum of the X increments.
  const double x_end = 60.6051 + 0 + 0.922 + 1.079 + 2.2624 + 1.9856 + 3.015 + 6.2889;
  EXPECT_NEAR(p.segments[8].end[0], x_end, kTol);
  EXPECT_EQ(p.segments[9].m, 50);
  EXPECT_EQ(p.segments[9].compensation, Compensation::kRight);
  EXPECT_EQ(p.segments[10].type, SegmentType::kRapid);
  EXPECT_EQ(p.segments[10].compensation, Compensation::kOff);
  EXPECT_NEAR(p.segments[10].end[0], x_end - 28.9085, kTol);
  EXPECT_EQ(p.segments[12].m_kind, MKind::kProgramEnd);
  EXPECT_EQ(p.segments[12].line, 17);
}

TEST(GcodeExample, DumpMatchesTheCheckedInGoldenFile) {
  const std::string text = read_text(TGM_SOURCE_DIR "/tests/programs/manual_example.ngc");
  const Program p = compile_ok(text, options(true));
  std::string dump;
  dump_jsonl(p, dump);
  const std::string golden = read_text(TGM_SOURCE_DIR "/tests/programs/manual_example.jsonl");
  EXPECT_EQ(dump, golden) << "regenerate with: tgm-hmi compile "
                             "tests/programs/manual_example.ngc --dump jsonl";
}

TEST(GcodeExample, ReadAbsoluteTheArcsDoNotClose) {
  // DESIGN section 4: the example only closes its arcs read incrementally.
  const std::string text = read_text(TGM_SOURCE_DIR "/tests/programs/manual_example.ngc");
  const auto errs = errors_of(text, options(false));
  ASSERT_FALSE(errs.empty());
  EXPECT_NE(errs[0].find("4:"), std::string::npos);
  EXPECT_NE(errs[0].find("arc end radius"), std::string::npos);
}

// --- Dialect ---------------------------------------------------------------------------------

TEST(Gcode, WordsAreCaseInsensitiveWithBlanksAndLeadingZeros) {
  const Program p = compile_ok("g90\nn10 g01 x 1 0 . 5 y-.5 z+1. f 600\n");
  ASSERT_EQ(p.segments.size(), 1u);
  EXPECT_EQ(p.segments[0].type, SegmentType::kLinear);
  EXPECT_DOUBLE_EQ(p.segments[0].end[0], 10.5);
  EXPECT_DOUBLE_EQ(p.segments[0].end[1], -0.5);
  EXPECT_DOUBLE_EQ(p.segments[0].end[2], 1.0);
  EXPECT_DOUBLE_EQ(p.segments[0].feed_mm_per_min, 600.0);
}

TEST(Gcode, CommentsAndTapeMarkersAreIgnored) {
  const Program p = compile_ok("%\n(header)\nG90 ; absolute\nG1 X1 (move) Y2 F100\n%\n");
  ASSERT_EQ(p.segments.size(), 1u);
  EXPECT_DOUBLE_EQ(p.segments[0].end[1], 2.0);
}

// Line ends of every kind: LF, CR LF (Windows), CR alone (old Mac; it was read as a blank, and
// a CR file as one line of contradicting words) and a mix; a UTF-8 byte-order mark before the
// first line is skipped (it was "unexpected byte 0xEF"). Lines are numbered as editors do.
TEST(Gcode, EveryKindOfLineEndAndAByteOrderMark) {
  const std::string lf = "G90 G1 X1 F100\nG1 X2\n\nG1 X3\nM30\n";
  for (const std::string& text :
       {lf, std::string("G90 G1 X1 F100\r\nG1 X2\r\n\r\nG1 X3\r\nM30\r\n"),
        std::string("G90 G1 X1 F100\rG1 X2\r\rG1 X3\rM30\r"),
        std::string("G90 G1 X1 F100\r\nG1 X2\r\rG1 X3\nM30"), std::string("\xEF\xBB\xBF") + lf}) {
    const Program p = compile_ok(text);
    ASSERT_EQ(p.segments.size(), 4u);
    for (std::size_t k = 0; k < 3; ++k) {
      EXPECT_DOUBLE_EQ(p.segments[k].end[0], static_cast<double>(k + 1));
    }
    EXPECT_EQ(p.segments[0].line, 1);
    EXPECT_EQ(p.segments[1].line, 2);
    EXPECT_EQ(p.segments[2].line, 4);
    EXPECT_EQ(p.segments[3].line, 5);
  }
  // Errors keep their columns: the mark is not one, nor is the CR of a CR LF.
  EXPECT_THAT(errors_of("\xEF\xBB\xBFG1 X1 Q2\r\n"),
              ::testing::ElementsAre("1:7: unknown word 'Q2'"));
  EXPECT_THAT(errors_of("G90\rG1 X1 Q2\r"), ::testing::ElementsAre("2:7: unknown word 'Q2'"));
  // A mark anywhere else is a byte like any other.
  EXPECT_THAT(errors_of("G90\n\xEF\xBB\xBFG1 X1\n"),
              ::testing::ElementsAre("2:1: unexpected invisible character U+FEFF"));
}

TEST(Gcode, DistanceModesAndModalMotion) {
  const Program p = compile_ok("G90 G1 X10 Y10 F100\nX20\nG91 X5 Y-5\nG0 Z3\n");
  ASSERT_EQ(p.segments.size(), 4u);
  EXPECT_DOUBLE_EQ(p.segments[1].end[0], 20.0);
  EXPECT_EQ(p.segments[1].type, SegmentType::kLinear);
  EXPECT_DOUBLE_EQ(p.segments[2].end[0], 25.0);
  EXPECT_DOUBLE_EQ(p.segments[2].end[1], 5.0);
  EXPECT_EQ(p.segments[3].type, SegmentType::kRapid);
  EXPECT_DOUBLE_EQ(p.segments[3].feed_mm_per_min, 0.0);
  EXPECT_DOUBLE_EQ(p.segments[3].end[2], 3.0);
}

TEST(Gcode, FeedIsModalAndM99SetsTheDefault) {
  CompileOptions o = options();
  o.compiler.default_feed_mm_per_min = 700;
  const Program p = compile_ok("G90 G1 X1\nF300 X2\nX3\nM99 F900\nX4\nF100 X5\n", o);
  ASSERT_EQ(p.segments.size(), 5u);
  EXPECT_DOUBLE_EQ(p.segments[0].feed_mm_per_min, 700.0);
  EXPECT_DOUBLE_EQ(p.segments[1].feed_mm_per_min, 300.0);
  EXPECT_DOUBLE_EQ(p.segments[2].feed_mm_per_min, 300.0);
  EXPECT_DOUBLE_EQ(p.segments[3].feed_mm_per_min, 900.0);
  EXPECT_DOUBLE_EQ(p.segments[4].feed_mm_per_min, 100.0);
}

TEST(Gcode, ZeroPointShiftAndG92) {
  // machine = program + G54 shift + G92 offset
  const Program p = compile_ok(
      "G90 G54 X100 Y50\nG1 X1 Y1 F100\nG92 X0 Y0\nG1 X2\nG53\nG1 X3\nG91 G92 X10\nG1 X1\n");
  ASSERT_EQ(p.segments.size(), 4u);
  EXPECT_DOUBLE_EQ(p.segments[0].end[0], 101.0);
  EXPECT_DOUBLE_EQ(p.segments[0].end[1], 51.0);
  // G92 X0 at machine 101: offset 1 - ... the point (101, 51) now reads (0, 0).
  EXPECT_DOUBLE_EQ(p.segments[1].end[0], 103.0);
  EXPECT_DOUBLE_EQ(p.segments[1].end[1], 51.0);
  // G53 drops the shift, the G92 offset (1, 1) stays.
  EXPECT_DOUBLE_EQ(p.segments[2].end[0], 4.0);
  // G92 X10 while incremental still sets a coordinate; G91 X1 moves by 1.
  EXPECT_DOUBLE_EQ(p.segments[3].end[0], 5.0);
}

TEST(Gcode, ArcsByIjkAndR) {
  const Program p = compile_ok(
      "G90 G17 G1 X10 Y0 F100\n"
      "G3 X0 Y10 I-10 J0\n"   // quarter circle CCW about the origin
      "G2 X10 Y0 R10\n"       // back CW, short way: centre at the origin
      "G2 X0 Y-10 R-10\n");   // 270 deg CW: centre at the origin again
  ASSERT_EQ(p.segments.size(), 4u);
  const Segment& a = p.segments[1];
  EXPECT_EQ(a.type, SegmentType::kArcCcw);
  EXPECT_NEAR(a.center[0], 0.0, kTol);
  EXPECT_NEAR(a.center[1], 0.0, kTol);
  EXPECT_NEAR(a.radius, 10.0, kTol);
  const Segment& b = p.segments[2];
  EXPECT_NEAR(b.center[0], 0.0, 1e-9);
  EXPECT_NEAR(b.center[1], 0.0, 1e-9);
  const Segment& c = p.segments[3];
  // The short CW arc from (10,0) to (0,-10) has its centre at the origin; R<0 takes the other one.
  EXPECT_NEAR(c.center[0], 10.0, 1e-9);
  EXPECT_NEAR(c.center[1], -10.0, 1e-9);
}

TEST(Gcode, FullCircleAndHelixInEveryPlane) {
  const Program p = compile_ok(
      "G90 G17 G2 I5 F100\n"            // full circle, start == end
      "G2 I5 Z-3\n"                      // helix: one turn, 3 mm down
      "G18 G3 X5 Z-8 I0 K-5\n"           // XZ plane (K is the Z offset)
      "G19 G2 Y5 Z-3 J0 K5 X7\n");       // YZ plane with X as the linear axis
  ASSERT_EQ(p.segments.size(), 4u);
  EXPECT_DOUBLE_EQ(p.segments[0].end[0], 0.0);
  EXPECT_NEAR(p.segments[0].center[0], 5.0, kTol);
  EXPECT_EQ(p.segments[0].turns, 0);
  EXPECT_DOUBLE_EQ(p.segments[1].end[2], -3.0);
  EXPECT_EQ(p.segments[2].plane, Plane::kXZ);
  // G18 centre is stored as (Z, X) (plane_axes: first = Z, second = X).
  EXPECT_NEAR(p.segments[2].center[0], -8.0, kTol);
  EXPECT_NEAR(p.segments[2].center[1], 0.0, kTol);
  EXPECT_EQ(p.segments[3].plane, Plane::kYZ);
  EXPECT_DOUBLE_EQ(p.segments[3].end[0], 7.0);
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  return buf;
}

// A mirrored R arc is the mirror image of the unmirrored one, as its I/J twin is: G2 X10 Y10
// R10 under M81 took its centre on the wrong side (0, 10), a 270 degree arc, where the I/J
// form and rs274's unmirrored centre (10, 0) mirrored give (-10, 0) and 90 degrees.
TEST(Gcode, AMirroredRArcIsTheMirrorImageOfItsIjTwin) {
  const Program r = compile_ok("G90 G0 X0 Y0\nM81\nG2 X10 Y10 R10 F100\nM2\n");
  const Program ij = compile_ok("G90 G0 X0 Y0\nM81\nG2 X10 Y10 I10 J0 F100\nM2\n");
  ASSERT_EQ(r.segments.size(), 3u);
  ASSERT_EQ(ij.segments.size(), 3u);
  for (const Program* p : {&r, &ij}) {
    const Segment& a = p->segments[1];
    EXPECT_EQ(a.type, SegmentType::kArcCcw);
    EXPECT_NEAR(a.center[0], -10.0, kTol);
    EXPECT_NEAR(a.center[1], 0.0, kTol);
    EXPECT_DOUBLE_EQ(a.end[0], -10.0);
    EXPECT_DOUBLE_EQ(a.end[1], 10.0);
  }
  // G18 (centre as Z, X), mirrored in X: the R arc and its I/J twin agree.
  const Program g18 = compile_ok("G90 G18 G0 X0 Z0\nM81\nG2 X10 Z10 R10 F100\nM2\n");
  const Program g18ij = compile_ok("G90 G18 G0 X0 Z0\nM81\nG2 X10 Z10 I0 K10 F100\nM2\n");
  EXPECT_EQ(g18.segments[1].type, g18ij.segments[1].type);
  EXPECT_NEAR(g18.segments[1].center[0], g18ij.segments[1].center[0], kTol);
  EXPECT_NEAR(g18.segments[1].center[1], g18ij.segments[1].center[1], kTol);
  // Seeded: R arcs of both signs, both directions and every mirror agree with their I/J twins.
  std::mt19937 rng(6501);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (int k = 0; k < 200; ++k) {
    const double ex = u(rng), ey = u(rng);
    const double d = std::hypot(ex, ey);
    if (d < 1.0) continue;
    const double rad = 0.5 * d * (1.0 + std::fabs(u(rng)) / 10.0);
    const bool cw = k % 2 == 0, long_way = k % 4 >= 2;
    const char* mirror = k % 3 == 0 ? "M81" : k % 3 == 1 ? "M82" : "M80";
    const std::string head = std::string("G90 G0 X0 Y0\n") + mirror + "\nG" + (cw ? "2" : "3") +
                             " X" + fmt(ex) + " Y" + fmt(ey);
    const Program pr = compile_ok(head + " R" + fmt(long_way ? -rad : rad) + " F100\n");
    // The unmirrored R arc's centre, from the same formula the compiler applies before
    // mirroring, gives the offsets of the I/J twin.
    const Program plain =
        compile_ok(std::string("G90 G0 X0 Y0\nG") + (cw ? "2" : "3") + " X" + fmt(ex) + " Y" +
                   fmt(ey) + " R" + fmt(long_way ? -rad : rad) + " F100\n");
    const double i = plain.segments[1].center[0], j = plain.segments[1].center[1];
    const Program pij = compile_ok(head + " I" + fmt(i) + " J" + fmt(j) + " F100\n");
    ASSERT_EQ(pr.segments.size(), 2u) << head;
    EXPECT_EQ(pr.segments[1].type, pij.segments[1].type) << head;
    EXPECT_NEAR(pr.segments[1].center[0], pij.segments[1].center[0], 1e-6) << head;
    EXPECT_NEAR(pr.segments[1].center[1], pij.segments[1].center[1], 1e-6) << head;
  }
}

// In G2/G3 a line of centre offsets alone is another full circle, as a line of axis words
// alone is another arc (rs274 runs it); it was "I is only used by an arc move (G2/G3)".
TEST(Gcode, ALineOfCentreOffsetsAloneIsAModalFullCircle) {
  const Program p = compile_ok("G90 G17 F100\nG0 X10\nG2 X10 I5\nI-5\nM51 I3\nM2\n");
  ASSERT_EQ(p.segments.size(), 5u);
  EXPECT_EQ(p.segments[2].type, SegmentType::kArcCw);
  EXPECT_EQ(p.segments[2].line, 4);
  EXPECT_NEAR(p.segments[2].center[0], 5.0, kTol);
  EXPECT_DOUBLE_EQ(p.segments[2].end[0], 10.0);
  // On an M line I stays a parameter of the M-function.
  EXPECT_EQ(p.segments[3].type, SegmentType::kMFunction);
  EXPECT_EQ(p.segments[3].m, 51);
  EXPECT_THAT(errors_of("G1 X1 F100\nI2\n"),
              testing::ElementsAre("2:1: I is only used by an arc move (G2/G3)"));
}

TEST(Gcode, MirroringFlipsCoordinatesArcsAndCompensation) {
  const Program p =
      compile_ok("G90 M81\nG1 X10 Y5 F100\nG2 X20 Y5 I5\nM84\nG41 D0\nG1 X1 Y1\nM80\nG1 X1 Y1\n");
  ASSERT_EQ(p.segments.size(), 4u);
  EXPECT_DOUBLE_EQ(p.segments[0].end[0], -10.0);
  EXPECT_DOUBLE_EQ(p.segments[0].end[1], 5.0);
  // X mirrored: the CW arc runs CCW, centre offset mirrored.
  EXPECT_EQ(p.segments[1].type, SegmentType::kArcCcw);
  EXPECT_NEAR(p.segments[1].center[0], -15.0, kTol);
  EXPECT_DOUBLE_EQ(p.segments[1].end[0], -20.0);
  // Both plane axes mirrored: G41 stays left.
  EXPECT_EQ(p.segments[2].compensation, Compensation::kLeft);
  EXPECT_DOUBLE_EQ(p.segments[2].end[0], -1.0);
  EXPECT_DOUBLE_EQ(p.segments[2].end[1], -1.0);
  EXPECT_DOUBLE_EQ(p.segments[3].end[0], 1.0);

  const Program q = compile_ok("G90 M82\nG42 D1\nG1 X1 Y1 F100\n");
  EXPECT_EQ(q.segments[0].compensation, Compensation::kLeft);  // one plane axis mirrored: swap
}

TEST(Gcode, CompensationRadiusFromDOrTheToolTable) {
  // G41 with T2's 5 mm, G40, G42 with D's 0.5 mm: the second entry starts where the first
  // offset left the tool.
  const Program p = compile_ok("G90 T2\nG41\nG1 X10 F100\nG40\nG42 D0.5\nX20\nG40\nX30\n");
  ASSERT_EQ(p.segments.size(), 3u);
  EXPECT_DOUBLE_EQ(p.segments[0].end[1], 5.0);
  // From (10, 5) to X20 Y0: 0.5 mm to the right of that direction, (10, -5) / sqrt(125).
  EXPECT_NEAR(p.segments[1].end[0], 20.0 - 0.5 * 5 / std::sqrt(125.0), 1e-12);
  EXPECT_NEAR(p.segments[1].end[1], -0.5 * 10 / std::sqrt(125.0), 1e-12);
  EXPECT_DOUBLE_EQ(p.segments[2].end[1], 0.0);
  EXPECT_EQ(p.segments[0].compensation, Compensation::kLeft);
  EXPECT_DOUBLE_EQ(p.segments[0].compensation_radius_mm, 5.0);
  EXPECT_EQ(p.segments[0].tool, 2);
  EXPECT_EQ(p.segments[1].compensation, Compensation::kRight);
  EXPECT_DOUBLE_EQ(p.segments[1].compensation_radius_mm, 0.5);
  EXPECT_EQ(p.segments[2].compensation, Compensation::kOff);
}

TEST(Gcode, MFunctionsKindsAndParameters) {
  const Program p = compile_ok("G90\nM3 S12000 T2\nM1005 A1 Z-2.5\nM0\nM29 (hello world)\nM30\nG1 X5\n");
  ASSERT_EQ(p.segments.size(), 5u);  // nothing after M30
  EXPECT_EQ(p.segments[0].m_kind, MKind::kNormal);
  EXPECT_EQ(p.segments[0].tool, 2);
  const MParams& m3 = p.params[static_cast<std::size_t>(p.segments[0].aux)];
  EXPECT_DOUBLE_EQ(m3['S' - 'A'], 12000.0);
  EXPECT_DOUBLE_EQ(m3['T' - 'A'], 2.0);
  EXPECT_TRUE(is_not_set(m3['A' - 'A']));
  EXPECT_EQ(p.segments[1].m_kind, MKind::kContinuous);
  const MParams& m1005 = p.params[static_cast<std::size_t>(p.segments[1].aux)];
  EXPECT_DOUBLE_EQ(m1005['Z' - 'A'], -2.5);
  EXPECT_EQ(p.segments[2].m_kind, MKind::kProgramStop);
  EXPECT_EQ(p.segments[3].type, SegmentType::kMessage);
  EXPECT_EQ(p.messages.at(static_cast<std::size_t>(p.segments[3].aux)), "hello world");
  EXPECT_EQ(p.segments[4].m_kind, MKind::kProgramEnd);
}

// Records with equal parameters or texts share one side-table entry: a G26 loop of M1005 A1
// stored 208 bytes per pass (3.9 GB to compile 9 million, session 76's review). Each record
// still reads its own values; -0 and 0 are different parameters.
TEST(Gcode, EqualParametersAndTextsShareOneTableEntry) {
  const Program p = compile_ok(
      "G91 G1 F1000\nG26 L1 K1000\nM1005 A-0\nM2\nG29 L1\nM1005 A1\nM51 A1\nM1005 A2\n"
      "M29 (pass)\nM17\n");
  ASSERT_EQ(p.segments.size(), 4u * 1000u + 2u);
  EXPECT_EQ(p.params.size(), 4u);  // A1 (twice per pass), A2, A-0, and the M2's none
  EXPECT_EQ(p.messages.size(), 1u);
  std::size_t m = 0, texts = 0;
  for (std::size_t k = 0; k + 2 < p.segments.size(); k += 4) {
    const Segment* s = &p.segments[k];
    ASSERT_EQ(s[0].m, 1005);
    ASSERT_EQ(s[1].m, 51);
    ASSERT_EQ(s[2].m, 1005);
    ASSERT_EQ(s[3].type, SegmentType::kMessage);
    EXPECT_EQ(p.params.at(static_cast<std::size_t>(s[0].aux))['A' - 'A'], 1.0);
    EXPECT_EQ(s[0].aux, s[1].aux);
    EXPECT_EQ(p.params.at(static_cast<std::size_t>(s[2].aux))['A' - 'A'], 2.0);
    EXPECT_EQ(p.messages.at(static_cast<std::size_t>(s[3].aux)), "pass");
    m += 3;
    ++texts;
  }
  EXPECT_EQ(m, 3000u);
  EXPECT_EQ(texts, 1000u);
  const MParams& minus_zero = p.params.at(static_cast<std::size_t>(p.segments[4000].aux));
  EXPECT_EQ(p.segments[4000].m, 1005);
  EXPECT_TRUE(std::signbit(minus_zero['A' - 'A']));
}

TEST(Gcode, RedefinedMFunctionsGoToThePlc) {
  CompileOptions o = options();
  o.compiler.plc_redefined_m = {2, 29};
  const Program p = compile_ok("M29 X1\nM2\nG90 G1 X1 F10\n", o);
  ASSERT_EQ(p.segments.size(), 3u);
  EXPECT_EQ(p.segments[0].m_kind, MKind::kNormal);
  EXPECT_EQ(p.segments[1].m_kind, MKind::kNormal);  // M2 no longer ends the program
}

TEST(Gcode, DwellRecord) {
  const Program p = compile_ok("G4 P1.5\n");
  ASSERT_EQ(p.segments.size(), 1u);
  EXPECT_EQ(p.segments[0].type, SegmentType::kDwell);
  EXPECT_DOUBLE_EQ(p.segments[0].dwell_s, 1.5);
}

TEST(Gcode, SubroutinesCyclesAndJumpsExpandFlat) {
  const Program p = compile_ok(
      "G90 G1 F100 X0\n"
      "G25 L10\n"          // call once
      "G26 L10 K3\n"       // call three times
      "G29 L5\n"
      "G91 G1 X100\n"
      "G27 L5 K2\n"        // jump back twice: the X100 move runs 3 times
      "M2\n"
      "G29 L10\n"
      "G91 G1 Y1\n"
      "M17\n");
  // X0, 4 subroutine moves, 3 X100 moves, M2
  ASSERT_EQ(p.segments.size(), 9u);
  EXPECT_DOUBLE_EQ(p.segments[4].end[1], 4.0);
  EXPECT_EQ(p.segments[4].line, 9);
  EXPECT_DOUBLE_EQ(p.segments[7].end[0], 300.0);
}

TEST(Gcode, NestedLoopsRearmTheirCounters) {
  // The inner jump (K1: body twice) runs inside an outer loop (K2: three passes).
  const Program p = compile_ok(
      "G91 F100\nG29 L1\nG29 L2\nG1 X1\nG27 L2 K1\nG1 Y1\nG27 L1 K2\nM2\n");
  int x = 0, y = 0;
  for (const Segment& s : p.segments) {
    if (s.line == 4) ++x;
    if (s.line == 6) ++y;
  }
  EXPECT_EQ(x, 6);
  EXPECT_EQ(y, 3);
}

// --- Errors: every class with its exact message ---------------------------------------------

using ::testing::ElementsAre;
using ::testing::IsEmpty;

TEST(GcodeErrors, UnknownWordAndCharacter) {
  EXPECT_THAT(errors_of("G1 X1 Q5\n"), ElementsAre("1:7: unknown word 'Q5'"));
  EXPECT_THAT(errors_of("G1 A5\n"),
              ElementsAre("1:4: unknown word 'A5' (not an axis of this interpolator)"));
  EXPECT_THAT(errors_of("G1 X1 #\n"), ElementsAre("1:7: unexpected character '#'"));
  EXPECT_THAT(errors_of("G1 X1 F100\n  /G1 X2\n"),
              ElementsAre("2:3: block delete '/': whether such lines run or are skipped is not set "
                          "(compiler.block_delete: run or skip; tgm-hmi --block-delete)"));
  EXPECT_THAT(errors_of("G1 X1 /Y2\n"), ElementsAre("1:7: unexpected character '/'"));
  EXPECT_THAT(errors_of("G1 X1 \xff\n"), ElementsAre("1:7: unexpected byte 0xFF"));
}

// Block delete: a '/' first on a line (after blanks) marks an optional block, which the
// operator's switch runs (off) or skips (on). Unset, such a line is refused (above).
TEST(GcodeBlockDelete, RunIgnoresTheSlashAndSkipLeavesTheLineOut) {
  const std::string text =
      "G90 G1 X10 F1000\n"
      "/G1 Y5\n"
      "  / G1 Z-1 (an optional plunge)\n"
      "/\n"
      "G1 X0\n"
      "M2\n";
  CompileOptions run = options();
  run.compiler.block_delete = BlockDelete::kRun;
  const Program with = compile_ok(text, run);
  // The same as the program without the slashes, line for line.
  const Program plain =
      compile_ok("G90 G1 X10 F1000\nG1 Y5\n   G1 Z-1 (an optional plunge)\n\nG1 X0\nM2\n");
  ASSERT_EQ(with.segments.size(), plain.segments.size());
  for (std::size_t k = 0; k < with.segments.size(); ++k) {
    EXPECT_EQ(with.segments[k].line, plain.segments[k].line) << k;
    EXPECT_EQ(with.segments[k].end, plain.segments[k].end) << k;
  }
  ASSERT_EQ(with.segments.size(), 5u);  // four moves and the end
  EXPECT_NEAR(with.segments[2].end[2], -1.0, kTol);

  CompileOptions skip = options();
  skip.compiler.block_delete = BlockDelete::kSkip;
  const Program without = compile_ok(text, skip);
  ASSERT_EQ(without.segments.size(), 3u);
  EXPECT_EQ(without.segments[0].line, 1);
  EXPECT_EQ(without.segments[1].line, 5);
  EXPECT_NEAR(without.segments[1].end[0], 0.0, kTol);
  EXPECT_NEAR(without.segments[1].end[1], 0.0, kTol);  // Y5 left out
  EXPECT_NEAR(without.segments[1].end[2], 0.0, kTol);  // Z-1 left out
}

TEST(GcodeBlockDelete, OnlyTheFirstCharacterMarksABlockAndItsWordsAreCheckedWhenRun) {
  CompileOptions run = options();
  run.compiler.block_delete = BlockDelete::kRun;
  CompileOptions skip = options();
  skip.compiler.block_delete = BlockDelete::kSkip;
  for (const CompileOptions& o : {run, skip}) {
    EXPECT_THAT(errors_of("G1 X1 F100 /Y2\n", o),
                ElementsAre("1:12: block delete '/' must come first on its line"));
    EXPECT_THAT(errors_of("N10 /G1 X1 F100\n", o),
                ElementsAre("1:5: block delete '/' must come first on its line"));
  }
  // Run, an optional block is a block like any other, with its errors where they are.
  EXPECT_THAT(errors_of("G1 X1 F100\n / G1 Q2\n", run), ElementsAre("2:7: unknown word 'Q2'"));
  EXPECT_THAT(errors_of("G1 X1 F100\n//G1 X2\n", run),
              ElementsAre("2:2: block delete '/' must come first on its line"));
  // Skipped, its words are not read: what the switch leaves out does not run.
  EXPECT_THAT(errors_of("G1 X1 F100\n / G1 Q2\n", skip), IsEmpty());
  // A label in a skipped line is no label.
  EXPECT_THAT(errors_of("G25 L7\nM2\n/G29 L7\nG1 X1 F100\nM17\n", skip),
              ElementsAre("1:5: unknown label L7 (define it with G29 L7)"));
  EXPECT_THAT(errors_of("G25 L7\nM2\n/G29 L7\nG1 X1 F100\nM17\n", run), IsEmpty());
}

// A 0x00 byte anywhere makes the text a binary file: one error at the first, where it lies (lines
// counted as the lexer counts them), and nothing else, where every line of binary gave errors.
TEST(GcodeErrors, ABinaryFileIsOneErrorAtItsFirstZeroByte) {
  using namespace std::string_literals;
  EXPECT_THAT(errors_of("G1 X1 F100\nG1 Q2\nG1 X2\0\0\n\x01\x02 G7\n"s),
              ElementsAre("3:6: a 0x00 byte: this is a binary file, not G-code text"));
  EXPECT_THAT(errors_of("G90\rG91\r\n\0"s),
              ElementsAre("3:1: a 0x00 byte: this is a binary file, not G-code text"));
  // Intercode given as G-code.
  std::string bytes;
  encode_intercode(compile_ok("G90 G1 X1 F100\nM2\n"), bytes);
  EXPECT_THAT(errors_of(bytes),
              ElementsAre(::testing::EndsWith(": this is binary intercode, not G-code text")));
}

TEST(GcodeErrors, UnknownGAndMNumbers) {
  EXPECT_THAT(errors_of("G7\n"), ElementsAre("1:1: unknown G-code G7"));
  EXPECT_THAT(errors_of("G91.1\n"), ElementsAre("1:1: unknown G-code G91.1"));
  EXPECT_THAT(errors_of("G20\n"),
              ElementsAre("1:1: G20 (inch units) is not supported: programs are in mm (G21)"));
  EXPECT_THAT(errors_of("M1000\n"),
              ElementsAre("1:1: M1000 is neither a normal (< 1000) nor a continuous (> 1000) "
                          "M-function"));
  EXPECT_THAT(errors_of("M3.5\n"),
              ElementsAre("1:1: M-number must be a whole number 0..999999, not M3.5"));
}

TEST(GcodeErrors, NumbersMissingNotFiniteOrOutOfRange) {
  EXPECT_THAT(errors_of("G1 XNAN\n"), ElementsAre("1:4: word X needs a number, not 'NAN'"));
  EXPECT_THAT(errors_of("G1 X\n"), ElementsAre("1:4: word X needs a number"));
  // Quoted source text never carries control codes or stray UTF-8 bytes into a terminal.
  EXPECT_THAT(errors_of("G1 X\x1b[2J\xe2\x80\n"),
              ElementsAre("1:4: word X needs a number, not '\\x1B[2J\\xE2\\x80'"));
  // The text that is no number is quoted, and skipped as one: no errors follow from it.
  EXPECT_THAT(errors_of("G1 X+-1 Y2\n"), ElementsAre("1:4: word X needs a number, not '+-1'"));
  EXPECT_THAT(errors_of("G1 X - Y2\n"), ElementsAre("1:4: word X needs a number, not '-'"));
  EXPECT_THAT(errors_of("G1 X+-1Y2\n"), ElementsAre("1:4: word X needs a number, not '+-1Y2'"));
  // A word after a blank is a word of its own, and a CR before the line feed is no text.
  EXPECT_THAT(errors_of("G90\nG1 Y X1\n"), ElementsAre("2:4: word Y needs a number, not 'X1'"));
  EXPECT_THAT(errors_of("G90\r\nG1 Y\r\nM2\r\n"), ElementsAre("2:4: word Y needs a number"));
  // A word that cannot be read is not reported missing as well.
  EXPECT_THAT(errors_of("G29 L99999999999\nM2\n"),
              ElementsAre("1:5: value of L is out of range (|value| <= 1e9): 'L99999999999'"));
  // A long word is quoted by its first 40 characters and its length, not echoed whole.
  EXPECT_THAT(errors_of("G1 X1" + std::string(400, '0') + "\n"),
              ElementsAre("1:4: value of X is out of range (|value| <= 1e9): 'X1" +
                          std::string(38, '0') + "... (402 characters)'"));
  EXPECT_THAT(errors_of("G1 X2000000000\n"),
              ElementsAre("1:4: value of X is out of range (|value| <= 1e9): 'X2000000000'"));
  // Each word within range, the point they add up to not (the interpolator would refuse it).
  EXPECT_THAT(errors_of("G91 G1 X900000000 F1000\nX900000000\n"),
              ElementsAre("2:1: end point X1800000000 is beyond +-1e9 mm (after incremental moves and offsets)"));
  EXPECT_THAT(errors_of("G1 X1 F0\n"),
              ElementsAre("1:7: feed F must be > 0 and <= 1000000 mm/min, not 0"));
  EXPECT_THAT(errors_of("G4 P-1\n"), ElementsAre("1:4: dwell P must be 0..100000 s, not -1"));
  EXPECT_THAT(errors_of("T1.5\n"), ElementsAre("1:1: tool T must be a whole number 0..99999, not 1.5"));
  // On an M line T selects the tool too (M6 T2), so the same range holds there: T-1 passed as a
  // parameter and left the tool unchanged without a word, T99999999 became the tool.
  EXPECT_THAT(errors_of("M6 T-1\n"),
              ElementsAre("1:4: tool T must be a whole number 0..99999, not -1"));
  EXPECT_THAT(errors_of("M6 T99999999\n"),
              ElementsAre("1:4: tool T must be a whole number 0..99999, not 99999999"));
  EXPECT_THAT(errors_of("M1006 T2.5\n"),
              ElementsAre("1:7: tool T must be a whole number 0..99999, not 2.5"));
  EXPECT_THAT(errors_of("G26 L1 K0\nM2\nG29 L1\nM17\n"),
              ElementsAre("1:8: count K must be a whole number 1..1000000000, not 0"));
}

TEST(GcodeErrors, RepeatedAndConflictingWords) {
  EXPECT_THAT(errors_of("G1 X1 X2\n"), ElementsAre("1:7: word X appears twice on one line"));
  EXPECT_THAT(errors_of("G90 G91\n"),
              ElementsAre("1:5: G90 and G91 cannot be on one line (same group)"));
  EXPECT_THAT(errors_of("G1 G92 X1\n"),
              ElementsAre("1:1: G1 and G92 both use the axis words: put them on separate lines"));
  EXPECT_THAT(errors_of("G1 X1 M3\n"),
              ElementsAre("1:1: G1 cannot share a line with M3 (the other words of an M line are "
                          "its parameters)"));
  EXPECT_THAT(errors_of("M3 P2\n"),
              ElementsAre("1:4: P is reserved and cannot be an M-function parameter (reserved: G "
                          "M N P)"));
  EXPECT_THAT(errors_of("M2 X1\n"), ElementsAre("1:4: M2 takes no parameters, but X is given"));
}

// Under a modal G2 / G3 a line that does not move took its centre offset for an arc: "G92 X6
// I3" ran a half circle to X16, "G29 L1 K5" a full circle; on G25 / G26 / G27 lines I, J, R (and
// K on G25) were dropped without a word. rs274 refuses them all ("I word with no G2 ... to use
// it").
TEST(GcodeErrors, CentreWordsOnLinesThatDoNotMove) {
  EXPECT_THAT(errors_of("G91 G2 X10 I5 F100\nG92 X6 I3\nM2\n"),
              ElementsAre("2:8: I is not used by G92 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)"));
  EXPECT_THAT(errors_of("G90 G2 X10 Y0 I5 J0 F100\nG54 X8 I3\nM2\n"),
              ElementsAre("2:8: I is not used by G54 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)"));
  EXPECT_THAT(errors_of("G91 G18 G2 X10 I5 F100\nG29 L1 K5\nM2\n"),
              ElementsAre("2:8: K is not used by G29 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)"));
  EXPECT_THAT(errors_of("G2 X10 I5 F100\nG4 P1 R5\nM2\n"),
              ElementsAre("2:7: R is not used by G4 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)"));
  EXPECT_THAT(errors_of("G91 G1 F100\nG25 L1 K3\nM2\nG29 L1\nX1\nM17\n"),
              ElementsAre("2:8: K is not used by G25 (K, the count of calls, belongs to G26 / "
                          "G27)"));
  EXPECT_THAT(errors_of("G26 L1 K2 I5 J2\nM2\nG29 L1\nM17\n"),
              ElementsAre("1:11: I is not used by G26 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)",
                          "1:14: J is not used by G26 (it belongs to an arc move, G2 / G3, on a "
                          "line of its own)"));
  // K stays G26 / G27's count, also under a modal arc.
  EXPECT_THAT(errors_of("G18 G2 X10 I5 F100\nG26 L1 K2\nM2\nG29 L1\nM17\n"), ElementsAre());
}

// A line with a call or jump to a label further down ran its settings twice (once when read,
// once when the labels were known): G41 on it was refused as "on already".
TEST(GcodeErrors, AForwardJumpLineRunsItsSettingsOnce) {
  const std::string fwd =
      "G90 G17 G0 X0 Y0\nG41 D1 G27 L5\nG1 X20 Y0 F500\nG29 L5\n"
      "G1 X20 Y20\nG40 G1 X30 Y30\nM2\n";
  const std::string split =
      "G90 G17 G0 X0 Y0\nG41 D1\nG27 L5\nG1 X20 Y0 F500\nG29 L5\n"
      "G1 X20 Y20\nG40 G1 X30 Y30\nM2\n";
  EXPECT_THAT(errors_of(fwd), ElementsAre());
  const auto a = compile_gcode(fwd, options());
  const auto b = compile_gcode(split, options());
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a.program.segments.size(), b.program.segments.size());
  for (std::size_t i = 0; i < a.program.segments.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.program.segments[i].end[static_cast<std::size_t>(k)],
                b.program.segments[i].end[static_cast<std::size_t>(k)]);
    }
  }
}

TEST(GcodeErrors, MissingWords) {
  EXPECT_THAT(errors_of("G4\n"), ElementsAre("1:1: G4 needs P<seconds>"));
  EXPECT_THAT(errors_of("G25\n"), ElementsAre("1:1: G25 needs L<label>"));
  EXPECT_THAT(errors_of("G26 L1\nM2\nG29 L1\nM17\n"),
              ElementsAre("1:1: G26 needs K<count>, the number of calls"));
  EXPECT_THAT(errors_of("G92\n"),
              ElementsAre("1:1: G92 needs axis words: the coordinates the current point gets"));
  EXPECT_THAT(errors_of("G54\n"),
              ElementsAre("1:1: G54 needs axis words: the zero-point shift per axis"));
  EXPECT_THAT(errors_of("M29\n"),
              ElementsAre("1:1: M29 needs its message text in parentheses: M29 (text)"));
  // The text reaches the HMIs through a topic of 255 bytes: a longer one compiled, simulated, and
  // stopped `tgm-hmi run` part-way through the program. Bytes, not characters: "ü" is two.
  EXPECT_THAT(errors_of("M29 (" + std::string(255, 'x') + ")\n"), IsEmpty());
  EXPECT_THAT(errors_of("M29 (" + std::string(128, 'x') + std::string(64, ' ') + "\xc3\xbc" +
                        std::string(62, 'x') + ")\n"),
              ElementsAre("1:1: M29 message is 256 bytes long; at most 255 reach the HMI (split it "
                          "over several M29 lines)"));
  EXPECT_THAT(errors_of("M99\n"), ElementsAre("1:1: M99 needs F<mm/min>, the new default feed"));
  EXPECT_THAT(errors_of("G90 G2 X10\n"), ElementsAre("1:5: arc needs a centre: I/J offsets or R"));
  EXPECT_THAT(errors_of("X5\n"),
              ElementsAre("1:1: axis words without a motion G-code (G0, G1, G2 or G3) before them"));
  CompileOptions no_tool = options();
  no_tool.compiler.initial_tool = 7;
  EXPECT_THAT(errors_of("G41\n", no_tool),
              ElementsAre("1:1: G41 needs a radius: D<mm> on the line, or tool T7 in the tool table"));
}

TEST(GcodeErrors, WordsOutOfPlace) {
  EXPECT_THAT(errors_of("G1 X1 I2\n"), ElementsAre("1:7: I is only used by an arc move (G2/G3)"));
  // R0 off an arc is out of place too, not a radius of 0 (a closing-note item for long).
  EXPECT_THAT(errors_of("G1 X1 R0\n"), ElementsAre("1:7: R is only used by an arc move (G2/G3)"));
  EXPECT_THAT(errors_of("G2 X1 R1\nG1 X2 R0\n"),
              ElementsAre("2:7: R is only used by an arc move (G2/G3)"));
  EXPECT_THAT(errors_of("G3 X1 R1\nX2 R0\n"), ElementsAre("2:4: arc radius R must not be 0"));
  EXPECT_THAT(errors_of("G1 X1 P2\n"), ElementsAre("1:7: P (dwell seconds) is only used with G4"));
  EXPECT_THAT(errors_of("G1 X1 L2\n"),
              ElementsAre("1:7: L (label) is only used by G25, G26, G27 and G29"));
  EXPECT_THAT(errors_of("G1 X1 D2\n"),
              ElementsAre("1:7: D (compensation radius) is only used with G41/G42"));
  EXPECT_THAT(errors_of("G17 G2 X2 I1 K2\n"),
              ElementsAre("1:14: K is not a centre offset in plane G17 (use I and J)"));
  EXPECT_THAT(errors_of("G2 X1 R1 I1\n"),
              ElementsAre("1:7: an arc takes either R or centre offsets, not both"));
}

TEST(GcodeErrors, ArcGeometry) {
  EXPECT_THAT(errors_of("G90 G2 X10 Y0 I3\n"),
              ElementsAre("1:15: arc end radius 7.0000 differs from start radius 3.0000 by 4.0000 "
                          "mm (allowed: max(0.005 mm, 0.1 % of the radius))"));
  // Within tolerance: 0.004 mm off on a 3 mm radius is accepted.
  EXPECT_TRUE(errors_of("G90 G2 X6.004 Y0 I3\n").empty());
  EXPECT_THAT(errors_of("G90 G2 X10 R2\n"),
              ElementsAre("1:12: radius R2 is too small for the distance 10.0000 mm between start "
                          "and end"));
  // R short of half the chord within max(0.005 mm, 0.1 %): the half circle over the chord.
  const Program half = compile_ok("G90 G2 X10 R4.996\n");
  EXPECT_NEAR(half.segments[0].center[0], 5.0, kTol);
  EXPECT_NEAR(half.segments[0].center[1], 0.0, kTol);
  EXPECT_NEAR(half.segments[0].radius, 5.0, kTol);
  EXPECT_THAT(errors_of("G90 G2 X10 R4.99\n"),
              ElementsAre("1:12: radius R4.99 is too small for the distance 10.0000 mm between "
                          "start and end"));
  EXPECT_THAT(errors_of("G90 G2 X0 R2\n"),
              ElementsAre("1:11: an R arc cannot have its end at its start (use I/J/K for a full "
                          "circle)"));
  EXPECT_THAT(errors_of("G2 X1 R0\n"), ElementsAre("1:7: arc radius R must not be 0"));
  CompileOptions two = options();
  two.axis_letters = "XY";
  EXPECT_THAT(errors_of("G18 G2 X1 I1\n", two),
              ElementsAre("1:5: arc in plane G18 needs the axes X and Z, but this "
                          "interpolator's axes are XY"));
  CompileOptions one = options();
  one.axis_letters = "X";
  EXPECT_THAT(errors_of("G2 X1 I1\n", one),
              ElementsAre("1:1: arc in plane G17 needs the axes X and Y, but this "
                          "interpolator's axes are X"));
  CompileOptions lathe = options();
  lathe.axis_letters = "XZ";
  EXPECT_THAT(errors_of("G17 G2 X10 Z0 I5 J0\n", lathe),
              ElementsAre("1:5: arc in plane G17 needs the axes X and Y, but this "
                          "interpolator's axes are XZ"));
}

// The plane is that of the axes with its letters, wherever they stand: a lathe of axes X, Z
// turns G18 arcs (it refused them as needing "axes 2 and 0"), and an interpolator whose axis 0
// is Y takes I as the X offset (it took I for axis 0, Y, and ran another circle silently).
TEST(Gcode, ArcPlanesFollowTheAxisLettersNotTheirPositions) {
  CompileOptions lathe = options();
  lathe.axis_letters = "XZ";
  const Program l = compile_ok("G90 G18 G2 X10 Z0 I5 K0 F100\nG3 X0 Z0 R5\n", lathe);
  ASSERT_EQ(l.segments.size(), 2u);
  EXPECT_EQ(l.segments[0].plane, Plane::kXZ);
  EXPECT_EQ(l.segments[0].type, SegmentType::kArcCw);
  // G18's first axis is Z (axis 1 here), its second X (axis 0).
  EXPECT_EQ(plane_axes(Plane::kXZ, "XZ").first, 1);
  EXPECT_EQ(plane_axes(Plane::kXZ, "XZ").second, 0);
  EXPECT_EQ(plane_axes(Plane::kXZ, "XZ").normal, kMaxAxes);
  EXPECT_NEAR(l.segments[0].center[0], 0.0, kTol);  // Z
  EXPECT_NEAR(l.segments[0].center[1], 5.0, kTol);  // X
  EXPECT_DOUBLE_EQ(l.segments[0].end[0], 10.0);
  EXPECT_DOUBLE_EQ(l.segments[0].end[1], 0.0);
  EXPECT_NEAR(l.segments[1].radius, 5.0, kTol);

  CompileOptions swapped = options();
  swapped.axis_letters = "YXZ";
  const Program y = compile_ok("G90 G1 X10 Y0 F100\nG2 X20 Y0 I5 J0\n", swapped);
  ASSERT_EQ(y.segments.size(), 2u);
  EXPECT_DOUBLE_EQ(y.segments[0].end[1], 10.0);      // X is axis 1
  EXPECT_NEAR(y.segments[1].center[0], 15.0, kTol);  // G17's first axis: X
  EXPECT_NEAR(y.segments[1].center[1], 0.0, kTol);
  EXPECT_EQ(y.segments[1].type, SegmentType::kArcCw);
  // The same program on X, Y, Z: the same centre, the same end point with its axes swapped.
  const Program x = compile_ok("G90 G1 X10 Y0 F100\nG2 X20 Y0 I5 J0\n");
  EXPECT_EQ(x.segments[1].center, y.segments[1].center);
  EXPECT_EQ(x.segments[1].end[0], y.segments[1].end[1]);
  EXPECT_EQ(x.segments[1].end[1], y.segments[1].end[0]);
}

TEST(GcodeErrors, LabelsAndFlowControl) {
  EXPECT_THAT(errors_of("G25 L9\n"),
              ElementsAre("1:5: unknown label L9 (define it with G29 L9)"));
  EXPECT_THAT(errors_of("G29 L1\nG29 L1\n"),
              ElementsAre("2:5: label 1 is defined twice (first on line 1)"));
  EXPECT_THAT(errors_of("M17\n"), ElementsAre("1:1: M17 (return) outside a subroutine"));
  EXPECT_THAT(errors_of("G29 L1\nG27 L1\n"),
              ElementsAre("2:5: backward jump to L1 without K would loop forever (give K<count>)"));
  EXPECT_THAT(errors_of("G25 L1\nG29 L1\nG91 G1 X1 F1\n"),
              ElementsAre("1:1: subroutine called here runs to the end of the program without M17"));
  EXPECT_THAT(errors_of("G29\n"), ElementsAre("1:1: G29 needs L<label> or a text note in parentheses"));
  EXPECT_TRUE(errors_of("G29 (a text note)\n").empty());
}

TEST(GcodeErrors, NestingAndSizeLimits) {
  // Endless recursion stops at the nesting limit.
  EXPECT_THAT(errors_of("G29 L1\nG25 L1\n"),
              ElementsAre("2:5: subroutine calls nested deeper than 16"));
  CompileOptions small = options();
  small.compiler.max_program_segments = 5;
  EXPECT_THAT(errors_of("G91 G1 F1\nG29 L1\nX1\nG27 L1 K10\n", small),
              ElementsAre("3:1: program expands to more than 5 segments "
                          "(compiler.max_program_segments)"));
  // Records the tool radius compensation still holds at the end count too (a square of five
  // moves with its entry came out as 7 records under a limit of 6; session 76's review).
  small.compiler.max_program_segments = 6;
  const std::string square = "G90 G0 X-10 Y-10\nG41 D1\nG1 X0 Y0 F100\nX20\nY20\nX0\nY0\n";
  EXPECT_THAT(errors_of(square, small),
              ElementsAre(::testing::HasSubstr("program expands to more than 6 segments")));
  small.compiler.max_program_segments = 7;
  EXPECT_EQ(compile_ok(square, small).segments.size(), 7u);
  // A loop that makes nothing still ends with an error, not a hang.
  small.compiler.max_program_segments = 10;
  EXPECT_THAT(errors_of("G26 L1 K1000000000\nM2\nG29 L1\nM17\n", small),
              ElementsAre(::testing::HasSubstr(
                  "executes more than 1000100 blocks (10 x max_program_segments + 1,000,000) "
                  "without ending, here in the subroutine called on line 1: an endless loop")));
  // Comment-only lines are no blocks and do not count: 200,000 passes of three blocks
  // (label, F, M17) and six comment lines stay under the 1,000,100 (nine a pass did not).
  EXPECT_TRUE(
      errors_of("G26 L1 K200000\nM2\nG29 L1\n(a)\n(b)\n; c\n(d)\n(e)\n(f)\nF100\nM17\n", small)
          .empty());
}

TEST(GcodeErrors, CommentsAndMirroring) {
  EXPECT_THAT(errors_of("G1 X1 (open\n"), ElementsAre("1:7: comment '(' is not closed on this line"));
  // The comment ends where its parentheses balance: its rest is not read as words.
  EXPECT_THAT(errors_of("(a (b) c)\n"),
              ElementsAre("1:4: '(' inside a comment: comments do not nest"));
  EXPECT_THAT(errors_of("G1 X1 ((nested) still)\n"),
              ElementsAre("1:8: '(' inside a comment: comments do not nest"));
  CompileOptions two = options();
  two.axis_letters = "XY";
  EXPECT_THAT(errors_of("M83\n", two),
              ElementsAre("1:1: M83 mirrors Z, which this interpolator has no axis for"));
}

TEST(GcodeErrors, AllErrorsAreReportedInLineOrder) {
  const auto errs = errors_of("G7\nG1 X1 Q1\nG25 L3\nG1 X\n");
  ASSERT_EQ(errs.size(), 4u);
  EXPECT_EQ(errs[0].substr(0, 2), "1:");
  EXPECT_EQ(errs[1].substr(0, 2), "2:");
  EXPECT_EQ(errs[2].substr(0, 2), "3:");
  EXPECT_EQ(errs[3].substr(0, 2), "4:");
}

// The reasons no other test gave (line coverage, session 44), each with its line and column.
TEST(GcodeErrors, TheRemainingReasonsNameTheirWord) {
  EXPECT_THAT(errors_of("N-5 G1 X1 F100\n"),
              ElementsAre("1:1: line number N must be a whole number >= 0, not -5"));
  EXPECT_THAT(errors_of("N1.5 G1 X1 F100\n"),
              ElementsAre("1:1: line number N must be a whole number >= 0, not 1.5"));
  EXPECT_THAT(errors_of("M99 F100 X1\n"), ElementsAre("1:10: M99 takes only F, not X"));
  EXPECT_THAT(errors_of("M99 F-3\n"),
              ElementsAre("1:5: feed F must be > 0 and <= 1000000 mm/min, not -3"));
  EXPECT_THAT(errors_of("G41 D-1\n"),
              ElementsAre("1:5: compensation radius D must be >= 0, not -1"));
  EXPECT_THAT(errors_of("G41 D1\nG40 D1\n"),
              ElementsAre("2:5: D (compensation radius) belongs to G41/G42, not G40"));
  EXPECT_THAT(errors_of("G25 L-2\n"),
              ElementsAre("1:5: label L must be a whole number >= 0, not -2"));
  EXPECT_THAT(errors_of("G29 L1\nG1 G25 L1\n"),
              ElementsAre("2:1: G25 cannot share a line with motion or axis words"));
  EXPECT_THAT(errors_of("G29 L1 X2\n"),
              ElementsAre("1:1: G29 cannot share a line with motion or axis words"));
  EXPECT_THAT(errors_of("G90 G2 X0 I0 J0 F100\n"),
              ElementsAre("1:11: arc centre is at the start point (radius 0)"));
  EXPECT_THAT(errors_of("G90 G1 X900000000 F1000\nG2 X900000001 I200000000\n"),
              ElementsAre("2:1: arc centre is beyond +-1e9 mm"));
  // What the compiler is given to compile for.
  CompileOptions none = options();
  none.axis_letters = "";
  EXPECT_THAT(errors_of("G1 X1\n", none),
              ElementsAre("0:0: the interpolator must have 1..10 axes, not 0"));
  CompileOptions word_letter = options();
  word_letter.axis_letters = "XYF";
  EXPECT_THAT(errors_of("G1 X1\n", word_letter), ElementsAre("0:0: bad axis letter 'F'"));
  CompileOptions twice = options();
  twice.axis_letters = "XyY";
  EXPECT_THAT(errors_of("G1 X1\n", twice), ElementsAre("0:0: bad axis letter 'Y'"));
}

// Errors past the first 10,000 are counted, not listed: the last entry says how many more.
TEST(GcodeErrors, ErrorsPastTheLimitAreCountedInOneLastEntry) {
  std::string text;
  for (int i = 0; i < 10'003; ++i) text += "Q1\n";
  const auto errs = errors_of(text);
  ASSERT_EQ(errs.size(), 10'001u);
  EXPECT_EQ(errs[9'999], "10000:1: unknown word 'Q1'");
  // At no place: it was given the last error's, which read as a location.
  EXPECT_EQ(errs.back(), "0:0: 3 further errors not shown");
  // The count says all of them (tgm-hmi compile's "10001 errors" counted the note as one).
  const CompileResult r = compile_gcode(text, options());
  EXPECT_EQ(r.errors_not_shown, 3u);
  EXPECT_EQ(r.error_count(), 10'003u);
  EXPECT_EQ(compile_gcode("Q1\nQ2\n", options()).error_count(), 2u);
}

// An error of a line that runs again (a loop pass, another call) is reported once, with the
// count of its repeats: each pass of a K100000 loop was one more line of 10,000.
TEST(GcodeErrors, AnErrorOfALineThatRunsAgainIsReportedOnceWithItsCount) {
  EXPECT_THAT(errors_of("G91\nG29 L1\nG0 X600000000\nG27 L1 K5\nM2\n"),
              ElementsAre("3:4: end point X1200000000 is beyond +-1e9 mm (after incremental moves "
                          "and offsets) (4 more times, as the line ran again)"));
  const CompileResult r =
      compile_gcode("G91\nG29 L1\nG0 X600000000\nG27 L1 K100000\nM2\n", options());
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors_not_shown, 0u);
  EXPECT_NE(r.errors[0].reason.find("(99999 more times, as the line ran again)"), std::string::npos)
      << r.errors[0].reason;
  // A subroutine called three times: beyond the bound in the second and third call.
  EXPECT_THAT(errors_of("G26 L1 K3\nM2\nG29 L1\nG91 G0 X600000000\nM17\n"),
              ElementsAre("4:8: end point X1200000000 is beyond +-1e9 mm (after incremental "
                          "moves and offsets) (1 more time, as the line ran again)"));
}

TEST(GcodeErrors, UncalledSubroutinesAreCheckedToo) {
  EXPECT_THAT(errors_of("M2\nG29 L1\nG1 X1 Q2\nM17\n"), ElementsAre("3:7: unknown word 'Q2'"));
  // Labels too: a call or jump to a missing label, and a backward jump without K, in code that
  // never runs (session 76's review: both compiled).
  EXPECT_THAT(errors_of("G91 G1 F100 X1\nM2\nG29 L1\nG25 L99\nG27 L98\nG27 L1\nM17\n"),
              ElementsAre("4:5: unknown label L99 (define it with G29 L99)",
                          "5:5: unknown label L98 (define it with G29 L98)",
                          "6:5: backward jump to L1 without K would loop forever (give K<count>)"));
  // Said once where the code runs as well; a forward jump without K and calls of labels
  // further down stay fine.
  EXPECT_THAT(errors_of("G25 L7\nM2\n"),
              ElementsAre("1:5: unknown label L7 (define it with G29 L7)"));
  EXPECT_TRUE(errors_of("G27 L2\nG29 L1\nG25 L3\nG29 L2\nG26 L3 K2\nM2\nG29 L3\nM17\n").empty());
}

TEST(Gcode, DiagnosticFormat) {
  EXPECT_EQ(format_diagnostic("a.ngc", {3, 7, "unknown word 'Q5'"}),
            "a.ngc:3:7: error: unknown word 'Q5'");
}

// --- Intercode encoding ------------------------------------------------------------------------

TEST(Intercode, RoundTripKeepsEveryField) {
  const Program p = compile_ok(
      "G90 T2 G41 G1 X10 Y20 Z3 F100\nG40 G1 X11\nG18 G3 X19 Z3 I4 K0\nM3 S100\nM29 (msg)\nG4 "
      "P2\nM2\n");
  std::string bytes;
  encode_intercode(p, bytes);
  Program q;
  std::string err;
  ASSERT_TRUE(decode_intercode(bytes, q, err)) << err;
  std::string a, b;
  dump_jsonl(p, a);
  dump_jsonl(q, b);
  EXPECT_EQ(a, b);
  EXPECT_EQ(q.messages, p.messages);
}

// A PackedProgram holds the intercode bytes and reads back every record of a seeded random
// program as decode_intercode does; it refuses what decode_intercode refuses, with its words.
TEST(Intercode, APackedProgramReadsTheRecordsDecodeReads) {
  std::string text = "G90 T2 G41 D0 G1 X1 Y2 Z3 F100\nM3 S100\nM29 (msg)\nG4 P2\n";
  std::uint64_t seed = 0x5EED;
  auto next = [&seed] {
    seed += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = seed;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<double>((z ^ (z >> 31)) >> 11) / 9007199254740992.0;
  };
  for (int i = 0; i < 2000; ++i) {
    const double u = next();
    char line[160];
    if (u < 0.6) {
      std::snprintf(line, sizeof line, "G1 X%.4f Y%.4f F%d\n", 100 * next(), 100 * next(),
                    100 + static_cast<int>(1000 * next()));
    } else if (u < 0.8) {
      std::snprintf(line, sizeof line, "G91 G2 X0 Y0 I%.3f J0 Z%.3f\nG90\n", 1 + next(), next());
    } else if (u < 0.9) {
      std::snprintf(line, sizeof line, "M%d Q%.2f\n", 51 + static_cast<int>(10 * next()), next());
    } else {
      std::snprintf(line, sizeof line, "G18 G0 Z%.3f X%.3f\nG17\n", next(), 50 * next());
    }
    text += line;
  }
  text += "M2\n";
  const Program p = compile_ok(text);
  ASSERT_GT(p.segments.size(), 2000u);
  std::string bytes;
  encode_intercode(p, bytes);
  PackedProgram packed;
  std::string err;
  ASSERT_TRUE(PackedProgram::open(bytes, packed, err)) << err;
  EXPECT_EQ(packed.size(), p.segments.size());
  EXPECT_EQ(packed.bytes(), bytes.size());
  EXPECT_LT(packed.bytes(), p.segments.size() * sizeof(Segment) / 3);
  Program read = packed.tables();
  EXPECT_TRUE(read.segments.empty());
  auto cursor = packed.cursor();
  Segment s;
  while (cursor.next(s)) read.segments.push_back(s);
  EXPECT_EQ(cursor.read(), p.segments.size());
  EXPECT_FALSE(cursor.next(s));
  std::string a, b;
  dump_jsonl(p, a);
  dump_jsonl(read, b);
  EXPECT_EQ(a, b);
  EXPECT_EQ(read.params, p.params);
  EXPECT_EQ(read.messages, p.messages);
  EXPECT_EQ(read.start_mm, p.start_mm);
  EXPECT_EQ(read.axis_letters, p.axis_letters);
  PackedProgram again;
  ASSERT_TRUE(PackedProgram::from_program(p, again, err)) << err;
  EXPECT_EQ(again.size(), packed.size());

  // Refused as decode_intercode refuses: a damaged byte, a cut file.
  for (std::string bad : {bytes.substr(0, bytes.size() / 2), bytes}) {
    if (bad.size() == bytes.size())
      bad[bad.size() / 2] = static_cast<char>(bad[bad.size() / 2] ^ 0x10);
    Program q;
    std::string decode_err, packed_err;
    EXPECT_FALSE(decode_intercode(bad, q, decode_err));
    EXPECT_FALSE(PackedProgram::open(bad, packed, packed_err));
    EXPECT_EQ(packed_err, decode_err);
    EXPECT_FALSE(packed_err.empty());
  }
}

// A PackedProgram::Window holds the records asked for, in place, as a consumer that takes some
// or all of them each time sees them: seeded calls ask for 0..700 records from where the last
// taking ended (0..all of them taken), now and then skipping ahead over records never asked
// for, and every record returned is the program's own; the calls past the end hold fewer.
TEST(Intercode, AWindowHoldsTheRecordsAskedForWhereverTheyStart) {
  std::string text = "G90\n";
  for (int i = 0; i < 3000; ++i) {
    text += "G1 X" + std::to_string(i % 97) + " Y" + std::to_string(i % 89) + " F" +
            std::to_string(100 + i) + "\n";
  }
  text += "M2\n";
  const Program p = compile_ok(text);
  PackedProgram packed;
  std::string err;
  ASSERT_TRUE(PackedProgram::from_program(p, packed, err)) << err;
  const std::uint64_t total = packed.size();
  std::mt19937_64 rng(62);
  for (int round = 0; round < 20; ++round) {
    PackedProgram::Window window(packed);
    std::uint64_t first = 0;
    std::uint64_t calls = 0;
    while (first < total + 10) {
      const std::uint64_t count = rng() % 701;
      const Program& held = window.from(first, count);
      ++calls;
      ASSERT_LE(window.base(), first);
      const std::uint64_t have = std::min(count, first < total ? total - first : 0);
      if (have > 0) {
        ASSERT_GE(held.segments.size(), first - window.base() + have)
            << "call " << calls << ": records from " << first << ", held from " << window.base();
      }
      for (std::uint64_t k = 0; k < have; ++k) {
        const Segment& got = held.segments[static_cast<std::size_t>(first - window.base() + k)];
        const Segment& want = p.segments[static_cast<std::size_t>(first + k)];
        ASSERT_EQ(got.line, want.line) << "record " << first + k << ", call " << calls;
        ASSERT_EQ(got.feed_mm_per_min, want.feed_mm_per_min) << "record " << first + k;
        ASSERT_EQ(got.end, want.end) << "record " << first + k;
      }
      // Taken: all, some or none of them; or a jump past records never asked for.
      const std::uint64_t way = rng() % 8;
      first += way == 0 ? 0 : (way == 1 ? 1 + rng() % 2000 : (way < 4 ? have / 2 : have));
      if (have == 0 && way != 1) ++first;
    }
  }
}

// Both dumps of every record kind the example program lacks: a continuous M-function, M0, an
// M-function with parameters, a message whose comment holds a quote, a backslash, a tab and a
// control character (JSON-escaped in the jsonl dump, as written in the text dump) and a dwell.
// The compiler and the intercode reader refuse a control character in a message: it is put in
// by hand, as a program made in memory could hold it.
TEST(Intercode, DumpsShowEveryRecordKind) {
  Program p = compile_ok(
      "G90 T1 G1 X1 F100\nM1003\nM0\nM3 S1200 Q2.5\nM29 (say \"hi\" \\ back\ttab)\nG4 "
      "P0.25\nM2\n");
  ASSERT_EQ(p.messages.size(), 1u);
  p.messages[0] += "\001x";
  std::string jsonl, text;
  dump_jsonl(p, jsonl);
  dump_text(p, text);
  const std::string at = R"("end":{"X":1,"Y":0,"Z":0},)";
  EXPECT_EQ(jsonl, R"({"line":1,"type":"G1",)" + at +
                       R"("feed_mm_per_min":100,"plane":17,"tool":1})"
                       "\n" +
                       R"({"line":2,"type":"M",)" + at +
                       R"("m":1003,"kind":"continuous","params":{},"tool":1})"
                       "\n" +
                       R"({"line":3,"type":"M",)" + at +
                       R"("m":0,"kind":"program_stop","params":{},"tool":1})"
                       "\n" +
                       R"({"line":4,"type":"M",)" + at +
                       R"("m":3,"kind":"normal","params":{"Q":2.5,"S":1200},"tool":1})"
                       "\n" +
                       R"({"line":5,"type":"MSG",)" + at +
                       R"("text":"say \"hi\" \\ back\ttab\u0001x","tool":1})"
                       "\n" +
                       R"({"line":6,"type":"G4",)" + at +
                       R"("seconds":0.25,"tool":1})"
                       "\n" +
                       R"({"line":7,"type":"M",)" + at +
                       R"("m":2,"kind":"program_end","params":{},"tool":1})"
                       "\n");
  EXPECT_EQ(text,
            "     1  G1  X1.0000 Y0.0000 Z0.0000  F100\n"
            "     2  M   M1003 (continuous)\n"
            "     3  M   M0 (program_stop)\n"
            "     4  M   M3 (normal) Q2.5 S1200\n"
            "     5  MSG \"say \"hi\" \\ back\\ttab\\x01x\"\n"
            "     6  G4  0.25 s\n"
            "     7  M   M2 (program_end)\n");
}

// A message or a reply's reason printed on an operator's terminal: control characters (an
// escape sequence would clear or recolour the screen) are shown as escapes, UTF-8 as it is.
TEST(Printable, ControlCharactersAreEscapedAndTheRestKept) {
  EXPECT_EQ(printable("plain text, 100 %"), "plain text, 100 %");
  EXPECT_EQ(printable("tab\tcr\rlf\n"), "tab\\tcr\\rlf\\n");
  EXPECT_EQ(printable("\x1b[2Jgone"), "\\x1b[2Jgone");
  EXPECT_EQ(printable(std::string_view("nul\0del\x7f", 8)), "nul\\x00del\\x7f");
  EXPECT_EQ(printable("Spindel gekühlt"), "Spindel gekühlt");
  EXPECT_EQ(printable("back\\slash \"quoted\""), "back\\slash \"quoted\"");
}

// JSON is UTF-8: a byte that is not (a cp1252 comment, a reason from a client of another
// encoding) is U+FFFD, and the rest of the text as it was.
TEST(Printable, JsonStringsAreAlwaysUtf8) {
  const auto json = [](std::string_view s) {
    std::string out;
    append_json_string(out, s);
    return out;
  };
  EXPECT_EQ(json("gek\xc3\xbchlt"), "\"gek\xc3\xbchlt\"");
  EXPECT_EQ(json("caf\xe9 \xff\xfe!"), "\"caf\\ufffd \\ufffd\\ufffd!\"");
  EXPECT_EQ(json("\xe2\x82"), "\"\\ufffd\\ufffd\"");           // cut short
  EXPECT_EQ(json("\xc0\xaf"), "\"\\ufffd\\ufffd\"");           // overlong '/'
  EXPECT_EQ(json("\xed\xa0\x80"), "\"\\ufffd\\ufffd\\ufffd\"");  // a surrogate
  EXPECT_EQ(json("\xf0\x9f\x94\xa7 del\x7f"), "\"\xf0\x9f\x94\xa7 del\\u007f\"");
  EXPECT_EQ(utf8_invalid_at("ok \xe2\x82\xac"), std::string_view::npos);
  EXPECT_EQ(utf8_invalid_at("ok \xf4\x90\x80\x80"), 3u);  // beyond U+10FFFF
}

// An M29 text that is not UTF-8 is an error at the byte, with what to do.
TEST(GcodeErrors, AnM29TextThatIsNotUtf8IsRefusedAtItsByte) {
  EXPECT_THAT(errors_of("G90\nM29 (caf\xe9 au lait)\nM2\n"),
              ElementsAre("2:9: M29 message is not UTF-8 text (byte 0xE9): save the program as "
                          "UTF-8"));
  EXPECT_THAT(errors_of("M29 (caf\xc3\xa9 au lait)\nM2\n"), ElementsAre());
}

// Columns count characters, as editors do (they counted bytes: an error after "(äöü)" was
// three columns further right than an editor shows it), also after a byte-order mark, with
// CR LF line ends, in the second pass and on the lines after; a byte that is not UTF-8 counts
// one. A letter of another alphabet is named, not its first byte.
TEST(GcodeErrors, ColumnsCountCharactersAndForeignLettersAreNamed) {
  EXPECT_THAT(errors_of("G90\n(\xc3\xa4\xc3\xb6\xc3\xbc) G1 X\nM2\n"),
              ElementsAre("2:10: word X needs a number"));
  EXPECT_THAT(errors_of("G90\nG1 X1 \xc3\xa4\nM2\n"),
              ElementsAre("2:7: unexpected character '\xc3\xa4' (U+00E4)"));
  EXPECT_THAT(errors_of("G90\nG1 X1\xc2\xa0Y1\nM2\n"),  // a no-break space
              ElementsAre("2:6: unexpected invisible character U+00A0"));
  EXPECT_THAT(errors_of("\xef\xbb\xbf(\xe2\x82\xac\xf0\x9f\x98\x80) G1 X\xe9 Y1 \xe2\x82\xac\r\n"
                        "(\xc3\xa4) G1 Y\r\nM2\r\n"),
              ElementsAre("1:9: word X needs a number, not '\\xE9'",
                          "1:15: unexpected character '\xe2\x82\xac' (U+20AC)",
                          "2:8: word Y needs a number"));
  // Quoted text shows a visible character as the editor does, and an invisible one or a
  // stray byte as \xNN (it showed every byte of 'ä' so).
  EXPECT_THAT(errors_of("G1 X\xc3\xa4"
                        "1 Y\xc2\xa0"
                        "2 Z\xe9\n"),
              ElementsAre("1:4: word X needs a number, not '\xc3\xa4"
                          "1'",
                          "1:8: word Y needs a number, not '\\xC2\\xA0"
                          "2'",
                          "1:12: word Z needs a number, not '\\xE9'"));
  // Pass 2: a subroutine's error on a line with a multi-byte comment.
  EXPECT_THAT(errors_of("G91\nG26 L5 K1\nM2\nG29 L5\n(\xc3\xa4) G0 X600000000\n"
                        "(\xc3\xa4\xc3\xa4) G0 X600000000\nM17\n"),
              ElementsAre(testing::StartsWith("6:9: end point X1200000000 is beyond")));
}

// Control characters in an M29 text reached every HMI's terminal as they were: an escape
// sequence, a bell. Refused at the byte; a tab is text.
TEST(GcodeErrors, AnM29TextWithAControlCharacterIsRefusedAtIt) {
  EXPECT_THAT(errors_of("G90\nM29 (tool \x1b[2Jchange)\nM2\n"),
              ElementsAre("2:11: M29 message holds the control character 0x1B: an HMI shows the "
                          "text as it is, so only printable text (and tabs) may be in it"));
  EXPECT_THAT(
      errors_of("M29 (ring\x07)\nM2\n"),
      ElementsAre(testing::StartsWith("1:10: M29 message holds the control character 0x07")));
  EXPECT_THAT(
      errors_of("M29 (del\x7f)\nM2\n"),
      ElementsAre(testing::StartsWith("1:9: M29 message holds the control character 0x7F")));
  EXPECT_THAT(errors_of("M29 (tool\tchange)\nM2\n"), ElementsAre());
  EXPECT_EQ(control_char_at("a\tb \xe2\x82\xac"), std::string_view::npos);
  EXPECT_EQ(control_char_at("ab\r"), 2u);
}

// Intercode that encodes but does not describe a program is refused with the record and the
// reason: negative sizes, and M or message records whose side-table entry is not there.
TEST(Intercode, DecodeRefusesOutOfRangeValuesAndMissingSideTableEntries) {
  struct Case {
    const char* what;
    void (*spoil)(Program&);
    const char* error;
  };
  const Case cases[] = {
      {"negative dwell", [](Program& p) { p.segments[1].dwell_s = -1.0; },
       "value out of range in record 1"},
      {"negative feed", [](Program& p) { p.segments[0].feed_mm_per_min = -5.0; },
       "value out of range in record 0"},
      {"negative radius", [](Program& p) { p.segments[3].radius = -2.0; },
       "value out of range in record 3"},
      {"negative turns", [](Program& p) { p.segments[3].turns = -1; },
       "value out of range in record 3"},
      {"negative tool", [](Program& p) { p.segments[2].tool = -1; },
       "value out of range in record 2"},
      {"tool beyond the T range", [](Program& p) { p.segments[0].tool = kMaxTool + 1; },
       "value out of range in record 0"},
      {"message beyond the topic's bound",
       [](Program& p) { p.messages[0].assign(kMaxMessageBytes + 1, 'm'); },
       "a message is longer than 255 bytes"},
      {"M without parameters", [](Program& p) { p.params.clear(); },
       "an M record at line 3 names a missing parameter set"},
      {"message without text", [](Program& p) { p.segments[4].aux = 7; },
       "a message record at line 5 names a missing text"},
      // Session 75: what a writer other than the compiler could put into a file whose
      // checksum it computed, and the reader took.
      {"arc of 2^31 - 1 turns", [](Program& p) { p.segments[3].turns = 2147483647; },
       "value out of range in record 3"},
      {"negative line", [](Program& p) { p.segments[0].line = -5; },
       "value out of range in record 0"},
      {"M3 as a program end", [](Program& p) { p.segments[2].m_kind = MKind::kProgramEnd; },
       "M-function kind does not match its number in record 2"},
      {"M3 as a continuous M-function",
       [](Program& p) { p.segments[2].m_kind = MKind::kContinuous; },
       "M-function kind does not match its number in record 2"},
      {"a parameter of -infinity",
       [](Program& p) { p.params[0][0] = -std::numeric_limits<double>::infinity(); },
       "a parameter that is not a finite number"},
      {"a message in cp1252", [](Program& p) { p.messages[0] = "caf\xe9"; },
       "a message that is not UTF-8 text"},
      {"a message with an escape sequence", [](Program& p) { p.messages[0] = "\x1b[31mred"; },
       "a message with a control character"},
      {"control characters for letters", [](Program& p) { p.axis_letters = "X\x01\""; },
       "axis letters must be distinct letters A..Z, not 'X\\x01\"'"},
      {"a letter twice", [](Program& p) { p.axis_letters = "XYX"; },
       "axis letters must be distinct letters A..Z, not 'XYX'"},
  };
  for (const Case& c : cases) {
    Program p = compile_ok("G90 G1 X1 F100\nG4 P1\nM3 S5\nG2 X3 I1\nM29 (hello)\n");
    ASSERT_EQ(p.segments.size(), 5u);
    c.spoil(p);
    std::string bytes;
    encode_intercode(p, bytes);
    Program q;
    std::string err;
    EXPECT_FALSE(decode_intercode(bytes, q, err)) << c.what;
    EXPECT_NE(err.find(c.error), std::string::npos) << c.what << ": " << err;
  }
}

TEST(Intercode, RecordsStoreOnlyWhatChanged) {
  // Header 25 bytes and the start point 3 x 8; first move: type, flags, axis mask, tool
  // (T1), X, feed = 24; then X only = 12 each; the table counts 8; the checksum 4.
  const Program p = compile_ok("G90 T1 G1 X1 F100\nX2\nX3\n");
  std::string bytes;
  encode_intercode(p, bytes);
  EXPECT_EQ(bytes.size(), 25u + 24u + 24u + 12u + 12u + 8u + 4u);
}

TEST(Intercode, LineNumberOverflowIsAnErrorNotUndefinedBehaviour) {
  // Found by libFuzzer: a record without its own line after one at INT32_MAX.
  Program p;
  p.number_axes = 3;
  p.axis_letters = "XYZ";
  Segment s;
  s.line = std::numeric_limits<std::int32_t>::max();
  p.segments = {s, s};
  std::string bytes;
  encode_intercode(p, bytes);
  ASSERT_EQ(bytes.size(), 25u + 24u + 8u + 8u + 8u + 4u);  // each record: type, flags, mask, line
  Program q;
  std::string err;
  ASSERT_TRUE(decode_intercode(bytes, q, err)) << err;
  EXPECT_EQ(q.segments[1].line, std::numeric_limits<std::int32_t>::max());
  bytes[58] = static_cast<char>(bytes[58] & ~0x08);  // second record: "line = previous + 1"
  bytes.erase(61, 4);
  ASSERT_TRUE(reseal_intercode(bytes));
  EXPECT_FALSE(decode_intercode(bytes, q, err));
  EXPECT_NE(err.find("line number overflows in record 1"), std::string::npos) << err;
}

TEST(Intercode, DecodeRejectsEveryTruncation) {
  const Program p = compile_ok("G90 G1 X1 F100\nG2 X3 I1\nM3 S1\nM29 (x)\n");
  std::string bytes;
  encode_intercode(p, bytes);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    Program q;
    std::string err;
    EXPECT_FALSE(decode_intercode(std::string_view(bytes).substr(0, n), q, err)) << n;
    EXPECT_FALSE(err.empty());
  }
  Program q;
  std::string err;
  EXPECT_FALSE(decode_intercode(bytes + "x", q, err));
  EXPECT_NE(err.find("checksum mismatch"), std::string::npos) << err;
  // With a checksum that fits, the extra byte itself is named.
  std::string longer = bytes;
  longer.insert(longer.size() - 4, "x");
  ASSERT_TRUE(reseal_intercode(longer));
  EXPECT_FALSE(decode_intercode(longer, q, err));
  EXPECT_NE(err.find("trailing bytes"), std::string::npos) << err;
}

// The checksum is the CRC-32 of IEEE 802.3 (zlib's crc32): its check value, and the values of
// random strings computed bit by bit here, the polynomial straight from the standard. The
// strings cover every length up to 40 from every start offset up to 8, so that each split
// between the eight-byte steps and the bytes left over is compared; and a long one.
TEST(Intercode, ChecksumIsTheStandardCrc32) {
  EXPECT_EQ(crc32("123456789"), 0xCBF43926u);
  EXPECT_EQ(crc32(""), 0u);
  const auto bitwise = [](std::string_view text) {
    std::uint32_t c = 0xFFFFFFFFu;
    for (const char ch : text) {
      c ^= static_cast<unsigned char>(ch);
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    }
    return ~c;
  };
  std::mt19937 rng(5);
  std::string text(100'003, '\0');
  for (char& c : text) c = static_cast<char>(rng());
  const std::string_view all(text);
  EXPECT_EQ(crc32(all), bitwise(all));
  for (std::size_t from = 0; from <= 8; ++from) {
    for (std::size_t len = 0; len <= 40; ++len) {
      EXPECT_EQ(crc32(all.substr(from, len)), bitwise(all.substr(from, len)))
          << "from " << from << ", " << len << " bytes";
    }
  }
}

// A file with any byte changed is refused as damaged, never run as another program: a byte of
// the first record's X flipped used to make a 100 mm move one of -0.0015 mm.
TEST(Intercode, EveryChangedByteIsRefusedAsDamaged) {
  const Program p = compile_ok("G90 G1 X100 F1000\nG2 X102 I1\nM3 S1\nM29 (x)\nM30\n");
  std::string bytes;
  encode_intercode(p, bytes);
  Program q;
  std::string err;
  ASSERT_TRUE(decode_intercode(bytes, q, err)) << err;
  std::mt19937 rng(11);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::string bad = bytes;
    bad[i] = static_cast<char>(bad[i] ^ static_cast<char>(1 + rng() % 255));
    EXPECT_FALSE(decode_intercode(bad, q, err)) << "byte " << i;
    if (i >= 6) {
      EXPECT_NE(err.find("checksum mismatch: the file is damaged"), std::string::npos)
          << i << ": " << err;
    }
  }
}

// The streaming writer of `tgm-hmi compile` (the buffer emptied as it goes, the record count
// written at the end) makes the same bytes as encode_intercode, the checksum included.
TEST(Intercode, StreamingEncoderMakesTheSameFile) {
  const Program p = compile_ok("G90 G1 X1 F100\nG2 X3 I1\nM3 S1\nM29 (x)\nG4 P1\nG0 Z5\nM30\n");
  std::string whole;
  encode_intercode(p, whole);
  std::string buffer, file;
  IntercodeEncoder enc(buffer, p.number_axes, p.axis_letters, p.start_mm, /*streaming=*/true);
  for (const Segment& sg : p.segments) {
    enc.add(sg);
    file += buffer;
    buffer.clear();
  }
  const std::uint64_t count = enc.records();
  enc.finish(p.params, p.messages);
  file += buffer;
  std::memcpy(file.data() + IntercodeEncoder::kCountOffset, &count, sizeof count);
  EXPECT_EQ(file, whole);
  // Appended behind other bytes, the header is where the encoder put it.
  std::string behind = "xyz";
  encode_intercode(p, behind);
  EXPECT_EQ(behind.substr(3), whole);
}

// The point a program was compiled from is in the file (version 4), the G91 records' ends
// relative to it; the streaming writer of `tgm-hmi compile` writes it too.
TEST(Intercode, TheStartPointTravelsWithTheFile) {
  CompileOptions o;
  o.start_mm = {20.0, 5.25, -2.0};
  const CompileResult r = compile_gcode("G91 G1 X10 F100\nG2 X10 I5\nM2\n", o);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.program.start_mm, o.start_mm);
  EXPECT_EQ(r.program.segments[0].end[0], 30.0);
  std::string bytes;
  encode_intercode(r.program, bytes);
  Program q;
  std::string err;
  ASSERT_TRUE(decode_intercode(bytes, q, err)) << err;
  EXPECT_EQ(q.start_mm, o.start_mm);
  std::string streamed;
  IntercodeEncoder enc(streamed, 3, "XYZ", o.start_mm, /*streaming=*/true);
  for (const Segment& sg : r.program.segments) enc.add(sg);
  const std::uint64_t count = enc.records();
  enc.finish(r.program.params, r.program.messages);
  std::memcpy(streamed.data() + IntercodeEncoder::kCountOffset, &count, sizeof count);
  EXPECT_EQ(streamed, bytes);
  // A start point that is not a number is refused, as a coordinate is.
  std::string bad = bytes;
  const double nan = std::nan("");
  std::memcpy(bad.data() + IntercodeEncoder::kCountOffset + 8 + 8, &nan, sizeof nan);
  ASSERT_TRUE(reseal_intercode(bad));
  EXPECT_FALSE(decode_intercode(bad, q, err));
  EXPECT_NE(err.find("non-finite start point"), std::string::npos) << err;
}

// Version 3 files (before the start point) and version 2 files (before the checksum) are still
// read, as compiled from machine zero, the only point `tgm-hmi compile` compiled from then.
TEST(Intercode, VersionTwoAndThreeFilesAreReadAsCompiledFromZero) {
  const Program p = compile_ok("G90 G1 X1 F100\nG2 X3 I1\nM3 S1\n");
  std::string bytes;
  encode_intercode(p, bytes);
  ASSERT_EQ(bytes[4], 4);
  // Version 3: the same without the start point's 3 doubles after the header.
  std::string v3 = bytes;
  v3.erase(IntercodeEncoder::kCountOffset + 8, 3 * sizeof(double));
  v3[4] = 3;
  ASSERT_TRUE(reseal_intercode(v3));
  Program q;
  q.start_mm[0] = 7.0;
  std::string err;
  ASSERT_TRUE(decode_intercode(v3, q, err)) << err;
  EXPECT_EQ(q.segments.size(), p.segments.size());
  EXPECT_EQ(q.segments[1].end, p.segments[1].end);
  EXPECT_EQ(q.start_mm, (std::array<double, kMaxAxes>{}));
  // Version 2: version 3 without the checksum.
  std::string v2 = v3.substr(0, v3.size() - 4);
  v2[4] = 2;
  ASSERT_TRUE(decode_intercode(v2, q, err)) << err;
  EXPECT_EQ(q.segments.size(), p.segments.size());
  EXPECT_EQ(q.segments[1].end, p.segments[1].end);
  v2[4] = 5;
  EXPECT_FALSE(decode_intercode(v2, q, err));
  EXPECT_NE(err.find("unsupported version 5 (this build reads 2 to 4)"), std::string::npos) << err;
}

}  // namespace
}  // namespace tgm

namespace tgm {
namespace {

// Soft limits (config axes[].min_position_mm / max_position_mm): every record that leaves
// them is an error at its line, lines at their end point, arcs wherever their sweep goes; a
// move that starts outside and comes back is free, and so is an arc's start.
TEST(GcodeSoftLimits, ABlockBeyondASoftLimitIsAnErrorAtItsLine) {
  CompileOptions o = options();
  MachineConfig m = MachineConfig::default_machine();
  o.machine_axes = m.interpolators[0];
  o.machine_axes.axes[0].min_position_mm = -1.0;
  o.machine_axes.axes[0].max_position_mm = 100.0;
  o.machine_axes.axes[1].max_position_mm = 50.0;
  EXPECT_THAT(errors_of("G90 F3000\nG1 X50 Y10\nG1 X120\nG2 X80 Y10 I-20 J0\nG1 X-5\nM2\n", o),
              ::testing::ElementsAre(
                  "3:1: end point X120 is beyond the soft limit of axis X (max_position_mm 100 "
                  "in the config)",
                  "5:1: end point X-5 is beyond the soft limit of axis X (min_position_mm -1 "
                  "in the config)"));
  // A half circle about X 80 Y 10 of radius 25 (CW from its top) passes X 105; on its end
  // points it stays within every limit. Its CCW twin passes X 55 only.
  EXPECT_THAT(errors_of("G90 F3000\nG1 X80 Y35\nG2 X80 Y-15 I0 J-25\nM2\n", o),
              ::testing::ElementsAre("3:1: the arc passes X105, beyond the soft limit of axis "
                                     "X (max_position_mm 100 in the config)"));
  compile_ok("G90 F3000\nG1 X80 Y35\nG3 X80 Y-15 I0 J-25\nM2\n", o);
  // A program that starts outside may come back; one on the limit itself is within it.
  o.start_mm = {150.0, 0.0, 0.0};
  compile_ok("G90 F3000\nG1 X100 Y50\nG1 X-1\nM2\n", o);
  // Without axes (tests, and configs without soft limits) nothing is checked.
  EXPECT_TRUE(errors_of("G90 G1 X1000 F3000\nM2\n").empty());
  EXPECT_FALSE(has_soft_limits(m.interpolators[0]));
  EXPECT_TRUE(has_soft_limits(o.machine_axes));
  EXPECT_TRUE(CompileOptions::from_machine(m, 0).machine_axes.axes.empty());
}

}  // namespace
}  // namespace tgm
