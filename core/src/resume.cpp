// Block search (tgm/resume.hpp).
#include "tgm/resume.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace tgm {

namespace {

std::string line_text(std::int32_t line) {
  return "line " + std::to_string(line);
}

// A record of `line` after one of `prev_line` starts a run of that line's records (the first
// record's prev_line is 0, which no source line is).
bool starts_run(const Segment& s, std::int32_t prev_line, std::int32_t line) {
  return s.line == line && prev_line != line;
}

}  // namespace

bool resume_from_line(const PackedProgram& in, const ResumeOptions& o, Resume& out,
                      std::string& error) {
  const Program& tables = in.tables();
  const int n = tables.number_axes;
  if (o.line < 1) {
    error = "the line to resume at must be 1 or more, not " + std::to_string(o.line);
    return false;
  }
  if (o.occurrence < 1) {
    error = "the occurrence of the line must be 1 or more";
    return false;
  }
  if (!(o.approach_feed_mm_per_min > 0.0 && o.approach_feed_mm_per_min <= kMaxFeedMmPerMin)) {
    error = "the approach feed must be above 0 and at most " +
            std::to_string(static_cast<long long>(kMaxFeedMmPerMin)) + " mm/min";
    return false;
  }
  for (int k = 0; k < n; ++k) {
    const double h = o.here[static_cast<std::size_t>(k)];
    if (!(std::fabs(h) <= kMaxCoordinateMm)) {
      error = "the position of axis " +
              std::string(1, tables.axis_letters[static_cast<std::size_t>(k)]) +
              " is not a coordinate the program can start from";
      return false;
    }
  }

  Resume r;
  std::string file;
  std::array<double, kMaxAxes> here{};
  for (int k = 0; k < n; ++k)
    here[static_cast<std::size_t>(k)] = o.here[static_cast<std::size_t>(k)];
  IntercodeEncoder encoder(file, n, tables.axis_letters, here);
  std::array<double, kMaxAxes> at = tables.start_mm;  // end of the last move read
  std::int32_t prev_line = 0, last_line = 0;
  bool keeping = false;
  std::uint64_t index = 0;
  Segment s;
  for (auto cursor = in.cursor(); cursor.next(s); ++index) {
    last_line = std::max(last_line, s.line);
    const bool run_starts = starts_run(s, prev_line, o.line);
    prev_line = s.line;
    if (run_starts && ++r.occurrences == o.occurrence) {
      keeping = true;
      r.first_record = index;
      r.resume_point = at;
      double d2 = 0.0;
      for (int k = 0; k < n; ++k) {
        const double d = at[static_cast<std::size_t>(k)] - here[static_cast<std::size_t>(k)];
        d2 += d * d;
      }
      if (d2 > kFullCircleMm * kFullCircleMm) {
        Segment approach;
        approach.type = SegmentType::kLinear;
        approach.plane = s.plane;
        approach.line = o.line;
        approach.tool = s.tool;
        for (int k = 0; k < n; ++k)
          approach.end[static_cast<std::size_t>(k)] = at[static_cast<std::size_t>(k)];
        approach.feed_mm_per_min = o.approach_feed_mm_per_min;
        encoder.add(approach);
        r.approach = true;
      }
    }
    if (keeping) {
      encoder.add(s);
    } else {
      ++r.skipped_records;
      if (s.type == SegmentType::kMFunction &&
          (s.m_kind == MKind::kNormal || s.m_kind == MKind::kContinuous)) {
        ++r.skipped_m;
        if (r.last_skipped_m.size() == Resume::kSkippedKept)
          r.last_skipped_m.erase(r.last_skipped_m.begin());
        r.last_skipped_m.push_back({s.m, s.line, s.m_kind});
      }
    }
    if (s.is_motion()) at = s.end;
  }
  if (r.occurrences == 0) {
    error = o.line > last_line
                ? line_text(o.line) + " lies after the program's last record (line " +
                      std::to_string(last_line) + ")"
                : line_text(o.line) +
                      " makes no record (a blank line, a comment, or modal words only such as "
                      "G90 or F): resume at a line with a move, a dwell or an M-function";
    return false;
  }
  if (!keeping) {
    error = line_text(o.line) + " runs " + std::to_string(r.occurrences) +
            (r.occurrences == 1 ? " time" : " times") +
            " in the program (a subroutine or a loop repeats a line); occurrence " +
            std::to_string(o.occurrence) + " is none of them";
    return false;
  }
  encoder.finish(tables.params, tables.messages);
  if (!PackedProgram::open(std::move(file), r.program, error)) {
    error = "the resumed program does not decode (" + error + "): a defect, please report it";
    return false;
  }
  out = std::move(r);
  return true;
}

std::uint64_t occurrence_at(const PackedProgram& p, std::uint64_t index) {
  if (index >= p.size()) return 0;
  Segment s;
  auto find = p.cursor();
  while (find.read() <= index) find.next(s);
  const std::int32_t line = s.line;
  std::uint64_t runs = 0;
  std::int32_t prev_line = 0;
  auto cursor = p.cursor();
  for (std::uint64_t k = 0; k <= index && cursor.next(s); ++k) {
    if (starts_run(s, prev_line, line)) ++runs;
    prev_line = s.line;
  }
  return runs;
}

bool single_block(const PackedProgram& in, PackedProgram& out, std::uint64_t& stops,
                  std::string& error) {
  const Program& tables = in.tables();
  const int n = tables.number_axes;
  std::string file;
  IntercodeEncoder encoder(file, n, tables.axis_letters, tables.start_mm);
  const auto stop_params = static_cast<std::int32_t>(tables.params.size());
  std::array<double, kMaxAxes> at = tables.start_mm;  // end of the last move
  std::uint64_t count = 0;
  Segment s, held;
  bool holding = false;
  // After `held`, the last record of its block (the next record's line differs, or the
  // program ends there).
  const auto stop_after_held = [&]() {
    const bool stops_already =
        held.type == SegmentType::kMFunction &&
        (held.m_kind == MKind::kProgramStop || held.m_kind == MKind::kProgramEnd);
    if (stops_already) return;
    Segment m0;
    m0.type = SegmentType::kMFunction;
    m0.m_kind = MKind::kProgramStop;
    m0.m = 0;
    m0.line = held.line;
    m0.plane = held.plane;
    m0.tool = held.tool;
    m0.aux = stop_params;
    m0.end = at;
    encoder.add(m0);
    ++count;
  };
  for (auto cursor = in.cursor(); cursor.next(s);) {
    if (holding && s.line != held.line) stop_after_held();
    encoder.add(s);
    if (s.is_motion()) at = s.end;
    held = s;
    holding = true;
  }
  if (holding) stop_after_held();
  std::vector<MParams> params = tables.params;
  params.push_back(unset_params());
  encoder.finish(params, tables.messages);
  PackedProgram result;
  if (!PackedProgram::open(std::move(file), result, error)) {
    error = "the single-block program does not decode (" + error + "): a defect, please report it";
    return false;
  }
  out = std::move(result);
  stops = count;
  return true;
}

}  // namespace tgm
