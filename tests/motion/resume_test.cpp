// Block search (tgm/resume.hpp): a program resumed at a source line runs the approach from where
// the machine stands and then exactly the records the whole program has from that line on.
// Single block: a program stop after each block, the same end.
// Known values on G-code, the errors, and a seeded sweep (--resume-seed=N, --resume-count=N) of
// random programs resumed at a random line from a random point, run through the interpolator
// with the limit checker on.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "../support/test_params.hpp"
#include "packed_gcode.hpp"
#include "random_program.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/resume.hpp"
#include "tgm/simulation.hpp"

namespace tgm {
namespace {

using test::packed;

std::vector<Segment> records(const PackedProgram& p) {
  std::vector<Segment> out;
  Segment s;
  for (auto c = p.cursor(); c.next(s);) out.push_back(s);
  return out;
}

// The same record as the interpolator sees it (every field the encoding keeps).
void expect_same_record(const Segment& a, const Segment& b, const std::string& ctx) {
  EXPECT_EQ(a.type, b.type) << ctx;
  EXPECT_EQ(a.line, b.line) << ctx;
  EXPECT_EQ(a.plane, b.plane) << ctx;
  EXPECT_EQ(a.m, b.m) << ctx;
  EXPECT_EQ(a.m_kind, b.m_kind) << ctx;
  EXPECT_EQ(a.tool, b.tool) << ctx;
  EXPECT_EQ(a.aux, b.aux) << ctx;
  EXPECT_EQ(a.end, b.end) << ctx;
  EXPECT_EQ(a.center, b.center) << ctx;
  EXPECT_EQ(a.radius, b.radius) << ctx;
  EXPECT_EQ(a.feed_mm_per_min, b.feed_mm_per_min) << ctx;
  EXPECT_EQ(a.dwell_s, b.dwell_s) << ctx;
}

constexpr const char* kProgram =
    "G90\n"                    // 1
    "G1 X10 F600\n"            // 2
    "M3 S1200\n"               // 3
    "G1 Y10\n"                 // 4
    "G2 X20 Y10 I5 J0 F900\n"  // 5
    "M1005\n"                  // 6
    "(a comment)\n"            // 7
    "G1 X30\n"                 // 8
    "M2\n";                    // 9

TEST(Resume, AtAnArcFromElsewhereApproachesItsStartAndKeepsTheRest) {
  const PackedProgram whole = packed(kProgram);
  const std::vector<Segment> all = records(whole);
  ResumeOptions o;
  o.line = 5;
  o.here = {2.0, 3.0, -1.0};
  o.approach_feed_mm_per_min = 1500.0;
  Resume r;
  std::string error;
  ASSERT_TRUE(resume_from_line(whole, o, r, error)) << error;
  EXPECT_EQ(r.first_record, 3u);  // G1 X10, M3, G1 Y10 before it
  EXPECT_EQ(r.occurrences, 1u);
  EXPECT_TRUE(r.approach);
  EXPECT_EQ(r.resume_point[0], 10.0);
  EXPECT_EQ(r.resume_point[1], 10.0);
  EXPECT_EQ(r.resume_point[2], 0.0);
  EXPECT_EQ(r.skipped_records, 3u);
  ASSERT_EQ(r.skipped_m, 1u);
  ASSERT_EQ(r.last_skipped_m.size(), 1u);
  EXPECT_EQ(r.last_skipped_m[0].m, 3);
  EXPECT_EQ(r.last_skipped_m[0].line, 3);
  EXPECT_EQ(r.last_skipped_m[0].kind, MKind::kNormal);
  EXPECT_EQ(r.program.tables().start_mm, o.here);

  const std::vector<Segment> got = records(r.program);
  ASSERT_EQ(got.size(), 1 + all.size() - 3);
  EXPECT_EQ(got[0].type, SegmentType::kLinear);
  EXPECT_EQ(got[0].line, 5);
  EXPECT_EQ(got[0].feed_mm_per_min, 1500.0);
  EXPECT_EQ(got[0].end[0], 10.0);
  EXPECT_EQ(got[0].end[1], 10.0);
  EXPECT_EQ(got[0].end[2], 0.0);
  for (std::size_t k = 1; k < got.size(); ++k) {
    expect_same_record(got[k], all[k + 2], "record " + std::to_string(k));
  }
  // The M3's parameter table entry is still there for a later M record's index: the tables
  // are kept whole.
  EXPECT_EQ(r.program.tables().params.size(), whole.tables().params.size());
}

TEST(Resume, StandingAtTheResumePointNeedsNoApproach) {
  const PackedProgram whole = packed(kProgram);
  ResumeOptions o;
  o.line = 8;
  o.here = {20.0, 10.0, 0.0};  // where the arc of line 5 ends
  o.approach_feed_mm_per_min = 1000.0;
  Resume r;
  std::string error;
  ASSERT_TRUE(resume_from_line(whole, o, r, error)) << error;
  EXPECT_FALSE(r.approach);
  const std::vector<Segment> got = records(r.program);
  ASSERT_EQ(got.size(), 2u);  // G1 X30, M2
  EXPECT_EQ(got[0].line, 8);
  EXPECT_EQ(r.skipped_m, 2u);  // M3 and the continuous M1005
  EXPECT_EQ(r.last_skipped_m.back().m, 1005);
  EXPECT_EQ(r.last_skipped_m.back().kind, MKind::kContinuous);
}

TEST(Resume, TheFirstLineResumesFromTheProgramsStart) {
  const std::array<double, kMaxAxes> start = {1.0, 2.0, 3.0};
  const PackedProgram whole = packed("G91\nG1 X1 F100\nG1 Y1\n", start);
  ResumeOptions o;
  o.line = 2;
  o.here = {0.0, 0.0, 0.0};
  o.approach_feed_mm_per_min = 100.0;
  Resume r;
  std::string error;
  ASSERT_TRUE(resume_from_line(whole, o, r, error)) << error;
  EXPECT_EQ(r.first_record, 0u);
  EXPECT_TRUE(r.approach);
  EXPECT_EQ(r.resume_point, start);
  EXPECT_EQ(records(r.program).size(), 3u);
}

TEST(Resume, ARepeatedLineIsResumedAtTheOccurrenceAsked) {
  // The subroutine's line 7 runs twice, once per call.
  const PackedProgram whole =
      packed("G90\nG1 X1 F600\nG25 L1\nG25 L1\nM2\nG29 L1\nG91 G1 X1\nG1 Y1\nM17\n");
  ResumeOptions o;
  o.line = 7;
  o.occurrence = 2;
  o.approach_feed_mm_per_min = 600.0;
  Resume r;
  std::string error;
  ASSERT_TRUE(resume_from_line(whole, o, r, error)) << error;
  EXPECT_EQ(r.occurrences, 2u);
  EXPECT_EQ(r.resume_point[0], 2.0);  // after X1 and the first call's X+1 Y+1
  EXPECT_EQ(r.resume_point[1], 1.0);
  const std::vector<Segment> got = records(r.program);
  ASSERT_EQ(got.size(), 4u);  // the approach, X+1, Y+1, M2
  EXPECT_EQ(got[1].line, 7);
  EXPECT_EQ(got[1].end[0], 3.0);
  EXPECT_EQ(got[1].end[1], 1.0);

  o.occurrence = 3;
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("line 7 runs 2 times"), std::string::npos) << error;

  // Records: X1 (line 2), X+1 (7), Y+1 (8), X+1 (7), Y+1 (8), M2 (5).
  EXPECT_EQ(occurrence_at(whole, 0), 1u);
  EXPECT_EQ(occurrence_at(whole, 1), 1u);
  EXPECT_EQ(occurrence_at(whole, 2), 1u);
  EXPECT_EQ(occurrence_at(whole, 3), 2u);
  EXPECT_EQ(occurrence_at(whole, 4), 2u);
  EXPECT_EQ(occurrence_at(whole, 5), 1u);
  EXPECT_EQ(occurrence_at(whole, 6), 0u);  // no such record
}

TEST(Resume, LinesWithoutRecordsAndBadOptionsAreRefusedWithTheReason) {
  const PackedProgram whole = packed(kProgram);
  Resume r;
  std::string error;
  ResumeOptions o;
  o.approach_feed_mm_per_min = 1000.0;
  o.line = 7;
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("line 7 makes no record"), std::string::npos) << error;
  o.line = 1;  // G90 alone
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("line 1 makes no record"), std::string::npos) << error;
  o.line = 40;
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("line 40 lies after the program's last record (line 9)"), std::string::npos)
      << error;
  o.line = 0;
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("1 or more"), std::string::npos) << error;
  o.line = 4;
  o.approach_feed_mm_per_min = 0.0;
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("approach feed"), std::string::npos) << error;
  o.approach_feed_mm_per_min = 1000.0;
  o.here[1] = std::nan("");
  EXPECT_FALSE(resume_from_line(whole, o, r, error));
  EXPECT_NE(error.find("axis Y"), std::string::npos) << error;
}

TEST(SingleBlock, EveryBlockEndsInAProgramStopButOneThatStopsOrEndsAlready) {
  const PackedProgram whole = packed(kProgram);
  const std::vector<Segment> all = records(whole);
  PackedProgram sb;
  std::uint64_t stops = 0;
  std::string error;
  ASSERT_TRUE(single_block(whole, sb, stops, error)) << error;
  EXPECT_EQ(stops, 6u);  // after lines 2, 3, 4, 5, 6 and 8; line 9 is the M2
  const std::vector<Segment> got = records(sb);
  ASSERT_EQ(got.size(), all.size() + 6);
  for (std::size_t k = 0; k + 1 < all.size(); ++k) {
    expect_same_record(got[2 * k], all[k], "record " + std::to_string(k));
    const Segment& m0 = got[2 * k + 1];
    EXPECT_EQ(m0.type, SegmentType::kMFunction);
    EXPECT_EQ(m0.m_kind, MKind::kProgramStop);
    EXPECT_EQ(m0.m, 0);
    EXPECT_EQ(m0.line, all[k].line);
    EXPECT_EQ(m0.aux, static_cast<std::int32_t>(whole.tables().params.size()));
  }
  expect_same_record(got.back(), all.back(), "the M2");
  ASSERT_EQ(sb.tables().params.size(), whole.tables().params.size() + 1);
  for (double p : sb.tables().params.back()) EXPECT_TRUE(is_not_set(p));

  // A program stop already there (line 2's M0): no second one after it.
  const PackedProgram with_m0 = packed("G90 G1 X1 F600\nM0\nG1 X2\nM2\n");
  ASSERT_TRUE(single_block(with_m0, sb, stops, error)) << error;
  EXPECT_EQ(stops, 2u);  // after lines 1 and 3
  EXPECT_EQ(records(sb).size(), 6u);
}

TEST(SingleBlock, RunsToTheSameEndStoppingAfterEachBlock) {
  const PackedProgram whole = packed(kProgram);
  PackedProgram sb;
  std::uint64_t stops = 0;
  std::string error;
  ASSERT_TRUE(single_block(whole, sb, stops, error)) << error;
  SimulationOptions so;
  so.check_limits = true;
  so.m_ack_s = 0.0;
  auto a = Simulation::create(MachineConfig::default_machine(), so);
  auto b = Simulation::create(MachineConfig::default_machine(), so);
  ASSERT_TRUE(a && b);
  const SimulationSummary straight = a->run(whole), stepped = b->run(sb);
  ASSERT_EQ(straight.result, StepResult::kFinished) << straight.error;
  ASSERT_EQ(stepped.result, StepResult::kFinished) << stepped.error;
  EXPECT_EQ(stepped.end_position, straight.end_position);
  EXPECT_EQ(stepped.violation_count, 0u);
  // Each stop brings the motion to rest (the simulation's operator starts again at once): the
  // corners the straight run crossed at speed cost time.
  EXPECT_GT(stepped.program_time_s, straight.program_time_s + 0.01);
}

// Random programs (the sweeps' generator) on random machines, resumed at a random record's line
// from a random point near the program: the run finishes at the program's end point, within
// every limit, and after the approach runs exactly the whole program's records from there. The
// whole program in single block finishes at the same end, within every limit.
TEST(ResumeSweep, ResumedProgramsRunTheirTailFromAnywhere) {
  const std::uint64_t seed = test::param_u64("resume-seed", "TGM_RESUME_SEED", 1);
  const std::uint64_t count = test::param_u64("resume-count", "TGM_RESUME_COUNT", 40);
  for (std::uint64_t k = 0; k < count; ++k) {
    std::mt19937_64 rng(seed * 7919u + k);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const test::RandomCase c = test::random_case(rng, 12);
    const int axes = c.axes;
    const MachineConfig& m = c.machine;
    const test::Generated& g = c.generated;
    const std::string ctx = "resume seed " + std::to_string(seed) + " program " + std::to_string(k);
    PackedProgram whole;
    std::string error;
    ASSERT_TRUE(PackedProgram::from_program(g.program, whole, error)) << ctx << ": " << error;
    const std::vector<Segment>& all = g.program.segments;
    const auto at = static_cast<std::size_t>(u(rng) * static_cast<double>(all.size()));
    ResumeOptions o;
    o.line = all[at].line;
    o.approach_feed_mm_per_min = 100.0 + u(rng) * 5000.0;
    // Near the program's own points (a lead of up to 20 mm from its start).
    for (int i = 0; i < axes; ++i) {
      o.here[static_cast<std::size_t>(i)] =
          g.program.start_mm[static_cast<std::size_t>(i)] + (u(rng) - 0.5) * 40.0;
    }
    Resume r;
    ASSERT_TRUE(resume_from_line(whole, o, r, error)) << ctx << ": " << error;
    ASSERT_EQ(r.first_record, at) << ctx << " (each record has a line of its own)";
    const std::vector<Segment> got = records(r.program);
    const std::size_t lead = r.approach ? 1 : 0;
    ASSERT_EQ(got.size(), lead + all.size() - at) << ctx;
    for (std::size_t j = at; j < all.size(); ++j) {
      expect_same_record(got[lead + j - at], all[j], ctx + " record " + std::to_string(j));
    }
    SimulationOptions so;
    so.start_mm = o.here;
    so.check_limits = true;
    so.m_ack_s = 0.0;
    so.max_time_s = 1e5;
    auto sim = Simulation::create(m, so);
    ASSERT_TRUE(sim) << ctx;
    const SimulationSummary s = sim->run(r.program);
    ASSERT_EQ(s.result, StepResult::kFinished) << ctx << ": " << s.error;
    EXPECT_FALSE(s.nan) << ctx;
    EXPECT_EQ(s.violation_count, 0u) << ctx;
    for (int i = 0; i < axes; ++i) {
      EXPECT_NEAR(s.end_position[static_cast<std::size_t>(i)], g.end[static_cast<std::size_t>(i)],
                  1e-9)
          << ctx << " axis " << i;
    }
    // Single block on the whole program: the same end, within every limit.
    PackedProgram sb;
    std::uint64_t stops = 0;
    ASSERT_TRUE(single_block(whole, sb, stops, error)) << ctx << ": " << error;
    SimulationOptions sbo = so;
    sbo.start_mm = g.program.start_mm;
    auto sbs = Simulation::create(m, sbo);
    ASSERT_TRUE(sbs) << ctx;
    const SimulationSummary t = sbs->run(sb);
    ASSERT_EQ(t.result, StepResult::kFinished) << ctx << " single block: " << t.error;
    EXPECT_EQ(t.violation_count, 0u) << ctx << " single block";
    for (int i = 0; i < axes; ++i) {
      EXPECT_NEAR(t.end_position[static_cast<std::size_t>(i)], g.end[static_cast<std::size_t>(i)],
                  1e-9)
          << ctx << " single block, axis " << i;
    }
    if (::testing::Test::HasFailure()) break;
  }
}

}  // namespace
}  // namespace tgm
