// Tool radius compensation (G41/G42/G40) in the compiler: pinned values (the same programs run
// through LinuxCNC's rs274 gave them; tests/reference/compensation_test.cpp keeps comparing),
// the errors with their text, the symmetries (mirroring, the G18 plane, the streaming sink)
// and a seeded sweep of random contours checked against geometry alone: every compensated move
// ends at least the tool radius from the programmed moves around it, and lies at the radius
// from its own programmed move (or, a corner arc, from the corner) all along.
//
// The sweep: --comp-seed=N --comp-count=N (or TGM_COMP_UNIT_SEED / TGM_COMP_UNIT_COUNT).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../support/sweep_progress.hpp"
#include "../support/test_params.hpp"
#include "tgm/gcode.hpp"

namespace tgm {
namespace {

using ::testing::ElementsAre;

constexpr double kPi = 3.14159265358979323846;

CompileOptions options() {
  CompileOptions o;
  o.axis_letters = "XYZ";
  o.compiler.start_incremental = false;
  o.tools = {{1, 3.0, 50.0}, {2, 5.0, 60.0}};
  return o;
}

CompileResult compile(const std::string& text, const CompileOptions& o = options()) {
  return compile_gcode(text, o);
}

std::string errors(const CompileResult& r) {
  std::string s;
  for (const auto& e : r.errors) s += format_diagnostic("t.ngc", e) + "\n";
  return s;
}

std::vector<const Segment*> moves(const Program& p) {
  std::vector<const Segment*> m;
  for (const Segment& s : p.segments) {
    if (s.is_motion()) m.push_back(&s);
  }
  return m;
}

//! The motion records of `text`, which must compile.
std::vector<Segment> compiled_moves(const std::string& text) {
  const CompileResult r = compile(text);
  EXPECT_TRUE(r.ok()) << errors(r);
  std::vector<Segment> m;
  for (const Segment& s : r.program.segments) {
    if (s.is_motion()) m.push_back(s);
  }
  return m;
}

void expect_move(const Segment& s, SegmentType type, double x, double y, int line) {
  EXPECT_EQ(s.type, type) << "line " << s.line;
  EXPECT_NEAR(s.end[0], x, 1e-4) << "line " << s.line;
  EXPECT_NEAR(s.end[1], y, 1e-4) << "line " << s.line;
  EXPECT_EQ(s.line, line);
}

TEST(Compensation, SquareOnTheInsideCutsItsCornersAndOnTheOutsideRoundsThem) {
  const std::string body =
      " D1\nG1 X10 Y0 F600\nG1 X10 Y10\nG1 X0 Y10\nG1 X0 Y0\nG40\nG0 X-20 Y-20\nM2\n";
  const auto m = compiled_moves("G90 G17\nG0 X0 Y0\nG41" + body);
  ASSERT_EQ(m.size(), 6u);
  expect_move(m[1], SegmentType::kLinear, 9, 1, 4);  // entry, cut at the first corner
  expect_move(m[2], SegmentType::kLinear, 9, 9, 5);
  expect_move(m[3], SegmentType::kLinear, 1, 9, 6);
  expect_move(m[4], SegmentType::kLinear, 1, 0, 7);     // last move: square to its end
  expect_move(m[5], SegmentType::kRapid, -20, -20, 9);  // G40's move: back to the contour

  const auto o = compiled_moves("G90 G17\nG0 X0 Y0\nG42" + body);
  ASSERT_EQ(o.size(), 9u);
  expect_move(o[1], SegmentType::kLinear, 10, -1, 4);
  expect_move(o[2], SegmentType::kArcCcw, 11, 0, 5);  // around the corner, of the next block
  EXPECT_NEAR(o[2].center[0], 10, 1e-12);
  EXPECT_NEAR(o[2].center[1], 0, 1e-12);
  EXPECT_NEAR(o[2].radius, 1, 1e-12);
  EXPECT_EQ(o[2].feed_mm_per_min, 600);
  expect_move(o[3], SegmentType::kLinear, 11, 10, 5);
  expect_move(o[4], SegmentType::kArcCcw, 10, 11, 6);
  expect_move(o[5], SegmentType::kLinear, 0, 11, 6);
  expect_move(o[6], SegmentType::kArcCcw, -1, 10, 7);
  expect_move(o[7], SegmentType::kLinear, -1, 0, 7);
  for (const Segment& s : o) {
    if (s.line >= 4 && s.line <= 7) {
      EXPECT_EQ(s.compensation, Compensation::kRight);
      EXPECT_EQ(s.compensation_radius_mm, 1.0);
    }
  }
}

TEST(Compensation, ArcsKeepTheirCentresAndChangeTheirRadius) {
  // Outside of a CW arc, inside of a CCW one, then a convex corner into a line.
  const auto m = compiled_moves(
      "G90 G17\nG0 X0 Y0\nG41 D1\nG1 X10 Y0 F600\nG2 X20 Y0 I5 J0\nG3 X30 Y0 I5 J0\n"
      "G1 X40 Y5\nG40\nG0 X50\nM2\n");
  ASSERT_EQ(m.size(), 7u);
  expect_move(m[1], SegmentType::kLinear, 9.0839, 1.0, 4);  // cut where y=1 meets r 6
  expect_move(m[2], SegmentType::kArcCw, 21, 0, 5);
  EXPECT_NEAR(m[2].center[0], 15, 1e-12);
  EXPECT_NEAR(m[2].radius, 6, 1e-9);
  expect_move(m[3], SegmentType::kArcCcw, 29, 0, 6);
  EXPECT_NEAR(m[3].center[0], 25, 1e-12);
  EXPECT_NEAR(m[3].radius, 4, 1e-9);
  expect_move(m[4], SegmentType::kArcCw, 29.5528, 0.8944, 7);  // the corner at X30
  expect_move(m[5], SegmentType::kLinear, 39.5528, 5.8944, 7);
  expect_move(m[6], SegmentType::kRapid, 50, 5, 9);
}

TEST(Compensation, AnEntryArcKeepsItsCentreOnTheRadiusThroughItsEnd) {
  const auto m =
      compiled_moves("G90 G17\nG0 X0 Y0\nG41 D1\nG2 X10 Y0 I5 J0 F600\nG1 X20\nG40\nG0 X30\nM2\n");
  ASSERT_EQ(m.size(), 4u);
  expect_move(m[1], SegmentType::kArcCw, 10.9083, 1.0, 4);
  EXPECT_NEAR(m[1].center[0], 5.5, 1e-12);
  EXPECT_NEAR(m[1].center[1], 0.0, 1e-12);
  expect_move(m[2], SegmentType::kLinear, 20, 1, 5);
}

TEST(Compensation, RecordsThatStayInThePlaneHappenAtTheOffsetPoint) {
  // A plunge, an M-function and a dwell between two moves: at the cut corner (9, 1).
  const CompileResult r = compile(
      "G90 G17\nG0 X0 Y0\nG41 D1\nG1 X10 Y0 F600\nG1 Z-1\nM51\nG4 P0.5\nG0 X10 Y10\n"
      "G40\nG0 X20\nM2\n");
  ASSERT_TRUE(r.ok()) << errors(r);
  const auto& s = r.program.segments;
  ASSERT_EQ(s.size(), 8u);
  for (std::size_t k = 1; k <= 4; ++k) {
    EXPECT_NEAR(s[k].end[0], 9, 1e-12) << k;
    EXPECT_NEAR(s[k].end[1], 1, 1e-12) << k;
  }
  EXPECT_EQ(s[2].end[2], -1.0);
  EXPECT_EQ(s[3].m, 51);
  EXPECT_EQ(s[4].type, SegmentType::kDwell);
  expect_move(s[5], SegmentType::kRapid, 9, 10, 8);
  expect_move(s[6], SegmentType::kRapid, 20, 10, 10);
}

TEST(Compensation, ARapidAroundAConvexCornerGoesStraight) {
  const auto m =
      compiled_moves("G90 G17\nG0 X0 Y0\nG42 D1\nG1 X10 F500\nG0 X10 Y10\nG40\nG0 X20\nM2\n");
  ASSERT_EQ(m.size(), 5u);
  expect_move(m[1], SegmentType::kLinear, 10, -1, 4);
  expect_move(m[2], SegmentType::kRapid, 11, 0, 5);
  expect_move(m[3], SegmentType::kRapid, 11, 10, 5);
}

TEST(Compensation, RadiusZeroAndTZeroLeaveThePathAsProgrammed) {
  const std::string text = "G90 G0 X0 Y0\nG41\nG1 X10 F600\nG1 Y10\nG40\nG0 X20\nM2\n";
  CompileOptions o = options();
  o.compiler.initial_tool = 0;
  const CompileResult r = compile(text, o);
  ASSERT_TRUE(r.ok()) << errors(r);
  const CompileResult plain = compile("G90 G0 X0 Y0\nG1 X10 F600\nG1 Y10\nG0 X20\nM2\n", o);
  ASSERT_EQ(r.program.segments.size(), plain.program.segments.size());
  for (std::size_t k = 0; k < r.program.segments.size(); ++k) {
    EXPECT_EQ(r.program.segments[k].end, plain.program.segments[k].end) << k;
  }
  EXPECT_EQ(r.program.segments[1].compensation, Compensation::kLeft);
  EXPECT_EQ(r.program.segments[1].compensation_radius_mm, 0.0);
  // T1 from the tool table: 3 mm.
  const CompileResult t1 = compile("T1\n" + text, o);
  ASSERT_TRUE(t1.ok()) << errors(t1);
  EXPECT_NEAR(t1.program.segments[1].end[1], 3.0, 1e-12);
}

TEST(Compensation, ErrorsNameTheBlockAndTheReason) {
  const auto first_error = [](const std::string& text) {
    const CompileResult r = compile(text);
    EXPECT_FALSE(r.ok()) << text;
    EXPECT_TRUE(r.program.segments.empty());
    return r.errors.empty() ? std::string() : format_diagnostic("t.ngc", r.errors.front());
  };
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG41 D2\nG1 X1.5 F600\nG1 Y5\nM2\n"),
            "t.ngc:3:1: error: tool radius compensation: the entry move after G41 (1.5000 mm in "
            "the plane) must be longer than the tool radius 2.0000 mm");
  EXPECT_EQ(
      first_error("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nG42 D1\nM2\n"),
      "t.ngc:4:1: error: G42: tool radius compensation is on already; cancel it with G40 first");
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nG18\nM2\n"),
            "t.ngc:4:1: error: G18: the plane cannot change while tool radius compensation is on "
            "(G40 first)");
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nG40\nG2 X20 I5\nM2\n"),
            "t.ngc:5:1: error: tool radius compensation: the move after G40 leads from the "
            "compensated path back to the programmed one and must be straight, not an arc");
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG42 D2\nG1 X10 F600\nG2 X12 Y0 I1\nG1 X20\nM2\n"),
            "t.ngc:4:1: error: tool radius compensation: the tool radius 2.0000 mm is not "
            "smaller than the radius 1.0000 mm of this arc, whose inside it follows");
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG41 D1\nG2 I5 F600\nM2\n"),
            "t.ngc:3:1: error: tool radius compensation: the entry move after G41 cannot be a "
            "full circle (start it with a straight move)");
  EXPECT_EQ(first_error("G90 G0 X-5 Y0\nG41 D2\nG1 X10 F600\nG1 Y1\nG1 X20\nG40\nM2\n"),
            "t.ngc:4:1: error: tool radius compensation: the tool (radius 2.0000 mm) cannot reach "
            "the concave corner at line 3's end without cutting into the contour");
  // A short hook: the move back crosses the arc 0.35 mm from their corner, and the gap the
  // tool stands in narrows to that crossing, which the arc's offset never reaches.
  EXPECT_EQ(first_error("G90 G0 X-20 Y-10\nG42 D1\nG1 X-20 Y0 F600\nG1 X0 Y0\n"
                        "G3 X1.736482 Y0.151922 I0 J10\nG1 X-18.018 Y-2.976\nG40 G1 X-30\nM2\n"),
            "t.ngc:6:1: error: tool radius compensation: this move crosses line 5's move 0.3499 "
            "mm from their corner; the tool (radius 1.0000 mm) cannot reach that corner without "
            "cutting into the contour");
  EXPECT_EQ(first_error("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nM82\nG1 Y10\nM2\n"),
            "t.ngc:4:1: error: M82 mirrors one axis of the plane while tool radius compensation "
            "is on, which would swap its side (G40 first)");
  // Mirroring both plane axes (or Z) keeps the side: a 180 degree turn of the contour.
  EXPECT_TRUE(compile("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nM84\nG1 Y10\nG40\nG1 X0\nM2\n").ok());
  // G40 and a plane change on one line are fine.
  EXPECT_TRUE(compile("G90 G0 X0 Y0\nG41 D2\nG1 X10 F600\nG40 G18 G1 X20\nM2\n").ok());
}

// Two arcs that meet 1 degree short of a reversal, the tool outside both: by their tangents a
// convex corner, but they cross 0.17 mm on and the tool stands in the cusp between them. It stops
// where the offset circles cross (rs274: -4.6705, 0.0407); round the tip, on the second arc's
// offset it cut up to 0.2 mm into the first arc's contour.
TEST(Compensation, ACuspJustShortOfAReversalIsCutWhereTheOffsetsCross) {
  const std::vector<Segment> m = compiled_moves(
      "G90 G17 G0 X-10 Y20\nG42 D1\nG1 X-10 Y10 F500\nG3 X0 Y0 I10 J0\n"
      "G3 X-10.1745 Y-9.9985 I-0.1745 J-9.9985\nG1 X-10.1745 Y-30\nG40 G1 X-30 Y-30\nM2\n");
  ASSERT_EQ(m.size(), 6u);  // rapid, entry, two arcs, line, exit: no corner arc
  // The crossing of the circles (0, 10) and (-0.1745, -9.9985) of radius 11 (the second arc
  // ends at radius 10; it starts 2.3e-5 mm further out), left of the corner.
  expect_move(m[2], SegmentType::kArcCcw, m[2].end[0], m[2].end[1], 4);
  EXPECT_NEAR(std::hypot(m[2].end[0], m[2].end[1] - 10), 11, 1e-9);
  EXPECT_NEAR(std::hypot(m[2].end[0] + 0.1745, m[2].end[1] + 9.9985), 11, 1e-9);
  EXPECT_NEAR(m[2].end[0], -4.6705, 1e-4);
  EXPECT_NEAR(m[2].end[1], 0.0407, 1e-4);
  expect_move(m[3], SegmentType::kArcCcw, -11.1745, -9.9985, 5);
  EXPECT_NEAR(m[3].center[0], -0.1745, 1e-12);
  EXPECT_NEAR(m[3].center[1], -9.9985, 1e-12);
}

//! `text` with X and Y negated and G2/G3, G41/G42 swapped: what mirroring X must give.
TEST(Compensation, MirroringOneAxisOfThePlaneSwapsTheSide) {
  const std::string mirrored =
      "G90 G0 X0 Y0\nM81\nG41 D1\nG1 X10 F600\nG3 X20 Y0 I5 J0\nG1 X20 Y10\nG40\nG0 X0\nM2\n";
  const std::string by_hand =
      "G90 G0 X0 Y0\nG42 D1\nG1 X-10 F600\nG2 X-20 Y0 I-5 J0\nG1 X-20 Y10\nG40\nG0 X0\nM2\n";
  const CompileResult a = compile(mirrored);
  const CompileResult b = compile(by_hand);
  ASSERT_TRUE(a.ok()) << errors(a);
  ASSERT_TRUE(b.ok()) << errors(b);
  const auto ma = moves(a.program), mb = moves(b.program);
  ASSERT_EQ(ma.size(), mb.size());
  ASSERT_GT(ma.size(), 4u);
  for (std::size_t k = 0; k < ma.size(); ++k) {
    EXPECT_EQ(ma[k]->type, mb[k]->type) << k;
    EXPECT_NEAR(ma[k]->end[0], mb[k]->end[0], 1e-12) << k;
    EXPECT_NEAR(ma[k]->end[1], mb[k]->end[1], 1e-12) << k;
  }
}

TEST(Compensation, TheXzPlaneIsTheXyPlaneRelabelled) {
  // G18's first and second axes are Z and X (centre offsets K and I).
  const CompileResult xy = compile(
      "G90 G17 G0 X0 Y0\nG41 D1\nG1 X10 F600\nG3 X15 Y5 I0 J5\nG1 Y12\nG40\nG0 X0 Y0\nM2\n");
  const CompileResult zx = compile(
      "G90 G18 G0 Z0 X0\nG41 D1\nG1 Z10 F600\nG3 Z15 X5 K0 I5\nG1 X12\nG40\nG0 Z0 X0\nM2\n");
  ASSERT_TRUE(xy.ok()) << errors(xy);
  ASSERT_TRUE(zx.ok()) << errors(zx);
  const auto a = moves(xy.program), b = moves(zx.program);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k]->type, b[k]->type) << k;
    EXPECT_NEAR(a[k]->end[0], b[k]->end[2], 1e-12) << k;
    EXPECT_NEAR(a[k]->end[1], b[k]->end[0], 1e-12) << k;
    EXPECT_NEAR(a[k]->center[0], b[k]->center[0], 1e-12) << k;
    EXPECT_NEAR(a[k]->center[1], b[k]->center[1], 1e-12) << k;
  }
}

// ---- seeded sweep ----------------------------------------------------------------------------

struct P {
  double x = 0, y = 0;
};
P operator-(P a, P b) {
  return {a.x - b.x, a.y - b.y};
}
double len(P a) {
  return std::hypot(a.x, a.y);
}

//! A programmed or compensated move in the XY plane.
struct Move {
  bool arc = false;
  bool cw = false;
  P a, b, c;  //!< start, end, centre
  int line = 0;
};

//! Distance from p to the move (the segment; the arc's part of its circle).
double distance(P p, const Move& m) {
  if (!m.arc) {
    const P d = m.b - m.a;
    const double l2 = d.x * d.x + d.y * d.y;
    const double t =
        l2 > 0 ? std::clamp(((p.x - m.a.x) * d.x + (p.y - m.a.y) * d.y) / l2, 0.0, 1.0) : 0.0;
    return len(p - P{m.a.x + t * d.x, m.a.y + t * d.y});
  }
  const auto ang = [&](P q) { return std::atan2(q.y - m.c.y, q.x - m.c.x); };
  const auto from_a = [&](double th) {
    double d = m.cw ? ang(m.a) - th : th - ang(m.a);
    d = std::fmod(d, 2 * kPi);
    return d < 0 ? d + 2 * kPi : d;
  };
  const double sweep = len(m.b - m.a) < 1e-9 ? 2 * kPi : from_a(ang(m.b));
  if (from_a(ang(p)) <= sweep) return std::fabs(len(p - m.c) - len(m.a - m.c));
  return std::min(len(p - m.a), len(p - m.b));
}

//! Distance from p to the whole line or circle of the move.
double distance_to_carrier(P p, const Move& m) {
  if (m.arc) return std::fabs(len(p - m.c) - len(m.a - m.c));
  const P d = m.b - m.a;
  return std::fabs(d.x * (p.y - m.a.y) - d.y * (p.x - m.a.x)) / len(d);
}

P point_on(const Move& m, double f) {
  if (!m.arc) return {m.a.x + f * (m.b.x - m.a.x), m.a.y + f * (m.b.y - m.a.y)};
  const double a0 = std::atan2(m.a.y - m.c.y, m.a.x - m.c.x);
  double sweep = std::atan2(m.b.y - m.c.y, m.b.x - m.c.x) - a0;
  if (m.cw) sweep = -sweep;
  sweep = std::fmod(sweep, 2 * kPi);
  if (sweep <= 0) sweep += 2 * kPi;
  const double r0 = len(m.a - m.c), r1 = len(m.b - m.c);
  const double th = a0 + (m.cw ? -1 : 1) * f * sweep;
  const double r = r0 + f * (r1 - r0);
  return {m.c.x + r * std::cos(th), m.c.y + r * std::sin(th)};
}

std::vector<Move> plane_moves(const Program& p) {
  std::vector<Move> out;
  P at{p.start_mm[0], p.start_mm[1]};
  for (const Segment& s : p.segments) {
    if (!s.is_motion()) continue;
    Move m;
    m.arc = s.is_arc();
    m.cw = s.type == SegmentType::kArcCw;
    m.a = at;
    m.b = {s.end[0], s.end[1]};
    m.c = {s.center[0], s.center[1]};
    m.line = s.line;
    at = m.b;
    if (m.arc || len(m.b - m.a) > 1e-9) out.push_back(m);
  }
  return out;
}

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9f", v);
  return buf;
}

//! A contour of lines and I/J arcs, every join tangent or a corner of 0.1..2.6 rad; with
//! `reversal_share`, that share of the joins turns back by pi less 0.0005..0.045 rad instead,
//! away from the tool (tangents that say convex; on the tool's side only long moves would reach).
std::string random_contour(std::mt19937_64& rng, double r, bool left, double reversal_share = 0) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto uni = [&](double a, double b) { return a + (b - a) * u(rng); };
  std::ostringstream o;
  double px = 0, py = 0, dir = uni(-kPi, kPi);
  o << "G90 G17 G0 X" << fmt(px - 20 * std::cos(dir)) << " Y" << fmt(py - 20 * std::sin(dir))
    << "\n";
  o << "F1200\n" << (left ? "G41" : "G42") << " D" << fmt(r) << "\n";
  o << "G1 X" << fmt(px) << " Y" << fmt(py) << "\n";
  const int n = 3 + static_cast<int>(u(rng) * 20);
  for (int k = 0; k < n; ++k) {
    if (reversal_share > 0 && u(rng) < reversal_share) {
      dir += (left ? -1 : 1) * (kPi - uni(0.0005, 0.045));
    } else if (u(rng) > 0.4) {
      dir += (u(rng) < 0.5 ? -1 : 1) * uni(0.1, 2.6);
    }
    if (u(rng) < 0.1) o << "G1 Z" << fmt(-uni(0.1, 2)) << "\n";
    if (u(rng) < 0.5) {
      const double l = uni(4 * r + 1, 4 * r + 20);
      px += l * std::cos(dir);
      py += l * std::sin(dir);
      o << "G1 X" << fmt(px) << " Y" << fmt(py) << "\n";
    } else {
      const bool ccw = u(rng) < 0.5;
      const double side = ccw ? 1 : -1;
      const double rad = uni(2 * r + 0.5, 2 * r + 20);
      const double i = -side * rad * std::sin(dir), j = side * rad * std::cos(dir);
      const double cx = px + i, cy = py + j;
      const double sweep = uni(0.2, 3.0);
      const double a1 = std::atan2(py - cy, px - cx) + side * sweep;
      px = cx + rad * std::cos(a1);
      py = cy + rad * std::sin(a1);
      o << (ccw ? "G3" : "G2") << " X" << fmt(px) << " Y" << fmt(py) << " I" << fmt(i) << " J"
        << fmt(j) << "\n";
      dir = a1 + side * kPi / 2;
    }
  }
  o << "G40\nG0 X" << fmt(px + 30) << " Y" << fmt(py + 30) << "\nM2\n";
  return o.str();
}

//! Unit tangent of a move at its start (or end).
P tangent(const Move& m, bool at_end) {
  if (!m.arc) {
    const P d = m.b - m.a;
    return {d.x / len(d), d.y / len(d)};
  }
  const P r = (at_end ? m.b : m.a) - m.c;
  const double l = len(r);
  return m.cw ? P{r.y / l, -r.x / l} : P{-r.y / l, r.x / l};
}

//! Whether moves k - 1 and k of `pm` meet within 0.05 rad of a reversal.
bool reverses(const std::vector<Move>& pm, std::size_t k) {
  if (k == 0 || k >= pm.size()) return false;
  const P t0 = tangent(pm[k - 1], true), t1 = tangent(pm[k], false);
  return std::atan2(std::fabs(t0.x * t1.y - t0.y * t1.x), t0.x * t1.x + t0.y * t1.y) > kPi - 0.05;
}

//! Compiles `count` random contours and checks every offset move against the programmed moves
//! at its ends. Contours may be refused only at a corner the tool cannot reach.
void sweep_contours(std::uint64_t seed, std::uint64_t count, double reversal_share) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t compiled = 0, refused = 0, checked_moves = 0;
  test::SweepProgress progress("CompensationSweep seed " + std::to_string(seed), count, "contours");
  for (std::uint64_t k = 0; k < count; ++k) {
    progress.update(k);
    const double r = 0.1 + 2.0 * u(rng);
    const bool left = u(rng) < 0.5;
    const std::string text = random_contour(rng, r, left, reversal_share);
    std::string zero = text;
    zero.replace(zero.find(" D") + 2, fmt(r).size(), "0");
    const CompileResult comp = compile(text);
    const CompileResult prog = compile(zero);
    ASSERT_TRUE(prog.ok()) << errors(prog) << zero;
    if (!comp.ok()) {
      // Only the concave corner a move is too short or too curved for may refuse these, or
      // the tip of a reversal the moves cross just after.
      const std::string& why = comp.errors.front().reason;
      ASSERT_TRUE(why.find("cannot reach the concave corner") != std::string::npos ||
                  (reversal_share > 0 && why.find("cannot reach that corner") != std::string::npos))
          << "seed " << seed << " program " << k << ": " << errors(comp) << text;
      ++refused;
      continue;
    }
    ++compiled;
    const std::vector<Move> pm = plane_moves(prog.program);
    const std::vector<Move> cm = plane_moves(comp.program);
    const int entry_line = pm[1].line;
    const int exit_line = pm.back().line;
    for (std::size_t c = 0; c < cm.size(); ++c) {
      const Move& m = cm[c];
      if (m.line <= entry_line || m.line >= exit_line) continue;  // entry, exit, rapid start
      // Its programmed move and the ones before and after it.
      std::size_t at = 0;
      while (at < pm.size() && pm[at].line != m.line) ++at;
      ASSERT_LT(at, pm.size());
      const bool corner_arc = m.arc && (!pm[at].arc || len(m.c - pm[at].c) > 1e-9);
      for (int f = 0; f <= 16; ++f) {
        const P p = point_on(m, f / 16.0);
        // Its ends against the programmed moves that meet there: the corners are where the
        // compensation decides (a contour that folds back onto itself within a radius elsewhere
        // is beyond a corner-by-corner offset, rs274's as ours).
        // (A corner arc lies at the start of its move: between the move before and its own.)
        // Where they meet near a reversal, the move runs alongside its neighbour: checked
        // against it along its length.
        const std::size_t q0 = f == 0 || corner_arc || reverses(pm, at) ? at - 1 : at;
        const std::size_t q1 = (f == 16 || reverses(pm, at + 1)) && !corner_arc ? at + 1 : at;
        for (std::size_t q = q0; q <= q1 && q < pm.size() && pm[q].line < exit_line; ++q) {
          EXPECT_GE(distance(p, pm[q]), r - 1e-6)
              << "seed " << seed << " program " << k << ": move " << c << " (line " << m.line
              << ") at " << f << "/16 cuts into line " << pm[q].line << "\n"
              << text;
        }
        // On its own programmed move's line or circle at the radius, or, a corner arc, around
        // the corner the programmed move starts at.
        const double off = corner_arc ? len(p - pm[at].a) : distance_to_carrier(p, pm[at]);
        EXPECT_NEAR(off, r, 1e-6) << "seed " << seed << " program " << k << ": move " << c
                                  << " (line " << m.line << ") at " << f << "/16\n"
                                  << text;
      }
      ++checked_moves;
      if (::testing::Test::HasFailure()) return;
    }
  }
  std::printf(
      "[ compensation sweep ] seed %llu: %zu programs compiled (%zu moves checked), %zu "
      "refused at a corner the tool cannot reach\n",
      static_cast<unsigned long long>(seed), compiled, checked_moves, refused);
  EXPECT_GT(compiled, count / 2) << "the generator makes too few programs that compile";
}

TEST(CompensationSweep, OffsetMovesKeepTheRadiusFromTheContour) {
  sweep_contours(test::param_u64("comp-seed", "TGM_COMP_UNIT_SEED", 20261203),
                 test::param_u64("comp-count", "TGM_COMP_UNIT_COUNT", 400), 0.0);
}

// A fifth of the joins turn back within 0.045 rad of a reversal: the cusps where an arc bends
// back across the move before must be cut, the tips where the material narrows gone round.
TEST(CompensationSweep, NearReversalsKeepTheRadiusFromTheContour) {
  sweep_contours(test::param_u64("comp-seed", "TGM_COMP_UNIT_SEED", 20261204),
                 test::param_u64("comp-count", "TGM_COMP_UNIT_COUNT", 400), 0.2);
}

TEST(Compensation, TheStreamingSinkGetsTheSameRecords) {
  const std::string text =
      "G90 G0 X0 Y0\nG42 D1\nG1 X10 F600\nG1 Z-1\nG1 Y10\nG2 X20 Y10 I5 J0\nG1 Y0\nG40\nG0 "
      "X0\nM2\n";
  const CompileResult whole = compile(text);
  ASSERT_TRUE(whole.ok()) << errors(whole);
  std::vector<Segment> streamed;
  const CompileResult r =
      compile_gcode(text, options(), [&](const Segment& s) { streamed.push_back(s); });
  ASSERT_TRUE(r.ok()) << errors(r);
  ASSERT_EQ(streamed.size(), whole.program.segments.size());
  for (std::size_t k = 0; k < streamed.size(); ++k) {
    EXPECT_EQ(streamed[k].end, whole.program.segments[k].end) << k;
    EXPECT_EQ(streamed[k].type, whole.program.segments[k].type) << k;
  }
}

}  // namespace
}  // namespace tgm
