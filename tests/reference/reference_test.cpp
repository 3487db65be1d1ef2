// Reference test: our G-code compiler against LinuxCNC's interpreter (`rs274 -g`).
//
// For every program (hand-written ones in programs/*.ngc and seeded generated ones) rs274's
// canonical motions are compared with our intercode, motion by motion: type (G0/G1/G2/G3),
// plane, end point of X/Y/Z, arc centre and full turns to 1e-4 mm (plus the 5e-5 by which
// rs274 rounds its 4-decimal output), and the feed in force.
//
// Coordinates: rs274 prints program coordinates; machine = program + G5x + G92 offsets (it
// prints those offsets as SET_G5X_OFFSET / SET_G92_OFFSET), which is what our intercode holds.
//
// Environment: TGM_REF_SEED (default 20240611), TGM_REF_COUNT (default 20 programs; read when
// the tests are listed), TGM_REF_MIN_LINES / TGM_REF_MAX_LINES (2000 / 20000),
// TGM_REF_LONG_LINES (200000), TGM_REF_CAM_LINES (100000), TGM_REF_KEEP=1 (keep generated programs that pass), TGM_RS274 (path of rs274), TGM_REQUIRE_RS274=1 (a missing rs274
// fails instead of skipping; CI sets it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../support/test_params.hpp"
#include "gen/cam_program.hpp"  // tests/bench/gen: the compile benchmark's program
#include "ngc_generator.hpp"
#include "reference_compare.hpp"
#include "rs274_canon.hpp"
#include "tgm/gcode.hpp"

namespace fs = std::filesystem;

namespace tgm::ref {
namespace {

//! Runs both interpreters on `text` (saved as `file`) and checks that they agree.
void check_program(const fs::path& file, const std::string& text) {
  const std::string rs274 = find_rs274();
  if (rs274.empty()) {
    if (rs274_required()) {
      FAIL() << "rs274 not found (PATH or $TGM_RS274) but TGM_REQUIRE_RS274 is set; install "
                "the Debian package linuxcnc-uspace";
    }
    GTEST_SKIP() << "rs274 not found on PATH (Debian package linuxcnc-uspace); set "
                    "TGM_REQUIRE_RS274=1 to make this a failure";
  }
  const Rs274Run run = run_rs274(rs274, file.string());
  ASSERT_EQ(run.exit_code, 0) << "rs274 rejected " << file << ":\n" << run.err;
  CanonProgram ref;
  const auto perr = parse_canon(run.out, ref);
  ASSERT_FALSE(perr.has_value()) << *perr;
  ASSERT_TRUE(ref.ended) << "rs274 output has no PROGRAM_END for " << file;

  CompileOptions opt;
  opt.axis_letters = "XYZ";
  opt.compiler.start_incremental = first_line_incremental(text);
  const CompileResult res = compile_gcode(text, opt);
  if (!res.ok()) {
    std::ostringstream os;
    for (std::size_t i = 0; i < res.errors.size() && i < 5; ++i) {
      os << "  " << format_diagnostic(file.string(), res.errors[i]) << "\n";
    }
    FAIL() << "our compiler rejected a program rs274 accepts (" << res.errors.size()
           << " errors):\n"
           << os.str();
  }
  const std::string diff = compare(ref, res.program, text);
  EXPECT_TRUE(diff.empty()) << "disagreement with rs274 on " << file << " ("
                            << ref.motions.size() << " rs274 motions):\n"
                            << diff;
  if (diff.empty() && file.parent_path() == work_dir() && test::env_u64("TGM_REF_KEEP", 0) == 0) {
    fs::remove(file);
  }
}

// ---- the parser itself, on pinned rs274 output (runs without rs274) ------------------------

TEST(Rs274Canon, ParsesPinnedOutputWithOffsetsAndPlanes) {
  // Output of rs274 -g on: G90 G17 / G0 X10 Y5 / F600 / G2 X30 Y5 I5 J0 / G2 X20 Y5 I5 J0 Z3
  // P3 / G18 / G2 X25 Z3 I2.5 K0 / G19 / G3 Y10 Z3 J2.5 K0 / G92 X0 Y0 / G1 X1 Y1 / M2
  const std::string out =
      "    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)\n"
      "    2 N..... SET_G5X_OFFSET(1, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
      "    3 N..... SET_G92_OFFSET(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
      "    7 N..... SELECT_PLANE(CANON_PLANE_XY)\n"
      "    8 N..... STRAIGHT_TRAVERSE(10.0000, 5.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
      "    9 N10    SET_FEED_RATE(600.0000)\n"
      "   10 N..... COMMENT(\"a, (b)\")\n"
      "   11 N..... ARC_FEED(30.0000, 5.0000, 25.0000, 5.0000, -1, 0.0000, 0.0000, 0.0000, "
      "0.0000)\n"
      "   14 N..... ARC_FEED(20.0000, 5.0000, 25.0000, 5.0000, -3, 3.0000, 0.0000, 0.0000, "
      "0.0000)\n"
      "   15 N..... SELECT_PLANE(CANON_PLANE_XZ)\n"
      "   16 N..... ARC_FEED(3.0000, 25.0000, 3.0000, 22.5000, -1, 5.0000, 0.0000, 0.0000, "
      "0.0000)\n"
      "   17 N..... SELECT_PLANE(CANON_PLANE_YZ)\n"
      "   18 N..... ARC_FEED(10.0000, 3.0000, 7.5000, 3.0000, 1, 25.0000, 0.0000, 0.0000, "
      "0.0000)\n"
      "   19 N..... SET_G92_OFFSET(25.0000, 10.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
      "   20 N100000STRAIGHT_FEED(1.0000, 1.0000, 3.0000, 0.0000, 0.0000, 0.0000)\n"
      "   30 N..... PROGRAM_END()\n"
      "   31 N..... STRAIGHT_FEED(9.0000, 9.0000, 9.0000, 0.0000, 0.0000, 0.0000)\n";
  CanonProgram p;
  ASSERT_FALSE(parse_canon(out, p).has_value());
  EXPECT_TRUE(p.ended);
  ASSERT_EQ(p.motions.size(), 6u);  // nothing after PROGRAM_END
  EXPECT_EQ(p.motions[0].type, 0);
  EXPECT_EQ(p.motions[0].end, (std::array<double, 3>{10, 5, 0}));
  EXPECT_EQ(p.motions[1].type, 2);
  EXPECT_EQ(p.motions[1].turns, 0);
  EXPECT_EQ(p.motions[1].feed_mm_per_min, 600.0);
  EXPECT_EQ(p.motions[1].center, (std::array<double, 2>{25, 5}));
  EXPECT_EQ(p.motions[2].turns, 2);
  EXPECT_EQ(p.motions[2].end, (std::array<double, 3>{20, 5, 3}));
  // G18: first axis Z, second X, normal Y.
  EXPECT_EQ(p.motions[3].plane, Plane::kXZ);
  EXPECT_EQ(p.motions[3].end, (std::array<double, 3>{25, 5, 3}));
  EXPECT_EQ(p.motions[3].center, (std::array<double, 2>{3, 22.5}));
  // G19: first axis Y, second Z, normal X; rotation +1 is G3.
  EXPECT_EQ(p.motions[4].type, 3);
  EXPECT_EQ(p.motions[4].end, (std::array<double, 3>{25, 10, 3}));
  EXPECT_EQ(p.motions[4].center, (std::array<double, 2>{7.5, 3}));
  // After G92 the canonical point (1, 1, 3) is machine (26, 11, 3).
  EXPECT_EQ(p.motions[5].end, (std::array<double, 3>{26, 11, 3}));
  EXPECT_EQ(p.motions[5].output_line, 15);
}

TEST(Rs274Canon, RejectsUnreadableMotion) {
  CanonProgram p;
  EXPECT_TRUE(parse_canon("    1 N..... STRAIGHT_FEED(1.0, x, 2.0)\n", p).has_value());
  EXPECT_TRUE(parse_canon("    1 N..... ARC_FEED(1, 2, 3, 4, 0, 5)\n", p).has_value());
}

TEST(ReferenceGenerator, SameSeedSameText) {
  const GeneratedProgram a = generate_reference_program(42, 500);
  const GeneratedProgram b = generate_reference_program(42, 500);
  const GeneratedProgram c = generate_reference_program(43, 500);
  EXPECT_EQ(a.text, b.text);
  EXPECT_NE(a.text, c.text);
  EXPECT_EQ(a.lines, 500);
  EXPECT_EQ(first_line_incremental(a.text), a.starts_incremental);
}

//! rs274's view of one of our programs, as if rs274 had printed it (for testing `compare`).
CanonProgram canon_of(const Program& p) {
  CanonProgram c;
  for (const Segment& s : p.segments) {
    if (!s.is_motion()) continue;
    CanonMotion m;
    m.type = static_cast<int>(s.type);
    m.plane = s.plane;
    for (std::size_t i = 0; i < 3; ++i) m.end[i] = s.end[i];
    m.center = s.center;
    m.turns = s.turns;
    m.feed_mm_per_min = s.feed_mm_per_min;
    c.motions.push_back(m);
  }
  c.ended = true;
  return c;
}

TEST(ReferenceCompare, FlagsEveryKindOfDifference) {
  const std::string text = "G90 G17\nF500\nG1 X1 Y2\nG18 G2 X3 Z0 I1 K0\nM2\n";
  CompileOptions opt;
  opt.compiler.start_incremental = false;
  const CompileResult res = compile_gcode(text, opt);
  ASSERT_TRUE(res.ok()) << res.errors.front().reason;
  const CanonProgram same = canon_of(res.program);
  ASSERT_EQ(same.motions.size(), 2u);
  EXPECT_EQ(compare(same, res.program, text), "");
  const auto differs = [&](auto&& change) {
    CanonProgram c = same;
    change(c);
    return !compare(c, res.program, text).empty();
  };
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[0].end[1] += 2e-4; }));
  EXPECT_FALSE(differs([](CanonProgram& c) { c.motions[0].end[1] += 1e-4; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[1].center[0] -= 2e-4; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[1].center[1] += 2e-4; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[1].turns = 1; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[1].type = 3; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[1].plane = Plane::kYZ; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions[0].feed_mm_per_min = 501; }));
  EXPECT_TRUE(differs([](CanonProgram& c) { c.motions.pop_back(); }));
}

// ---- hand-written programs ------------------------------------------------------------------

std::vector<std::string> hand_programs() {
  std::vector<std::string> names;
  const fs::path dir = fs::path(TGM_SOURCE_DIR) / "tests" / "reference" / "programs";
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().extension() == ".ngc") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

class HandProgram : public ::testing::TestWithParam<std::string> {};

TEST_P(HandProgram, AgreesWithRs274) {
  const fs::path file =
      fs::path(TGM_SOURCE_DIR) / "tests" / "reference" / "programs" / (GetParam() + ".ngc");
  check_program(file, read_file(file));
}

INSTANTIATE_TEST_SUITE_P(Programs, HandProgram, ::testing::ValuesIn(hand_programs()),
                         [](const ::testing::TestParamInfo<std::string>& i) {
                           std::string n = i.param;
                           for (char& c : n) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return n;
                         });

// ---- generated programs -----------------------------------------------------------------------

std::uint64_t base_seed() {
  return test::env_u64("TGM_REF_SEED", 20240611);
}

void check_generated(std::uint64_t seed, int lines, const std::string& name) {
  const GeneratedProgram g = generate_reference_program(seed, lines);
  const fs::path file = work_dir() / (name + ".ngc");
  {
    std::ofstream f(file, std::ios::binary);
    f << g.text;
  }
  SCOPED_TRACE("seed " + std::to_string(seed) + ", " + std::to_string(g.lines) +
               " lines, program kept at " + file.string() + " if the test fails");
  check_program(file, g.text);
}

class Generated : public ::testing::TestWithParam<int> {};

TEST_P(Generated, AgreesWithRs274) {
  const auto index = static_cast<std::uint64_t>(GetParam());
  const std::uint64_t seed = base_seed() * 1000003u + index;
  const auto lo = static_cast<int>(test::env_u64("TGM_REF_MIN_LINES", 2000));
  const auto hi = std::max(lo, static_cast<int>(test::env_u64("TGM_REF_MAX_LINES", 20000)));
  Rng rng(seed ^ 0x5eedu);
  const int lines = rng.range(lo, hi);
  check_generated(seed, lines, "generated_" + std::to_string(base_seed()) + "_" +
                                   std::to_string(index));
}

INSTANTIATE_TEST_SUITE_P(Seeded, Generated,
                         ::testing::Range(0, static_cast<int>(test::env_u64("TGM_REF_COUNT", 20))));

TEST(GeneratedLong, AgreesWithRs274) {
  const auto lines = static_cast<int>(test::env_u64("TGM_REF_LONG_LINES", 200000));
  check_generated(base_seed() * 7919u + 1u, lines, "generated_long_" + std::to_string(base_seed()));
}

//! CAM output rounds R to 4 decimals, so a half circle's R can come out 5e-5 short of half the
//! chord; rs274 runs it as a half circle and so do we (within the arc tolerance of DESIGN.md).
TEST(RArc, RoundedBelowHalfChordRunsAsAHalfCircle) {
  const std::string text = "G90 G17\nF100\nG2 X10 Y0 R4.9999\nG3 X0 Y0 R-4.99995\nM2\n";
  const fs::path file = work_dir() / "r_below_half_chord.ngc";
  {
    std::ofstream f(file, std::ios::binary);
    f << text;
  }
  check_program(file, text);
}

//! The CAM-like program of the compile benchmark (short G1 moves, small tangent arcs).
class CamProgram : public ::testing::TestWithParam<bool> {};

TEST_P(CamProgram, AgreesWithRs274) {
  const bool incremental = GetParam();
  std::string text;
  tgm::bench::generate_cam_program(text,
                                   static_cast<long>(test::env_u64("TGM_REF_CAM_LINES", 100000)),
                                   base_seed(), incremental);
  const fs::path file = work_dir() / (std::string("cam_") + (incremental ? "g91" : "g90") + "_" +
                                      std::to_string(base_seed()) + ".ngc");
  {
    std::ofstream f(file, std::ios::binary);
    f << text;
  }
  check_program(file, text);
}

INSTANTIATE_TEST_SUITE_P(Bench, CamProgram, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& i) {
                           return std::string(i.param ? "G91" : "G90");
                         });

}  // namespace
}  // namespace tgm::ref
