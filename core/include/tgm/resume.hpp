// Block search: a program resumed at one of its source lines, as an operator restarts a job
// after a broken tool or a stop off the trajectory (Command 5/9 drops the program).
//
// The program is compiled whole (from the point it was first started from), so every modal
// state at the line (G90/G91, plane, feed, tool, offsets, mirroring, cutter compensation) is
// what it was in the full run: its records hold absolute positions and their own feed, tool
// and plane. The records before the line are dropped; a straight approach move at a feed the
// caller chooses goes from where the machine stands to the point the line starts at; the rest
// runs as compiled. The M-functions dropped with the records before the line never reach the
// PLC: the result names them, so that the operator can bring the machine into their state.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "tgm/intercode.hpp"
#include "tgm/intercode_io.hpp"

namespace tgm {

struct ResumeOptions {
  //! Source line to resume at (1-based): the first record of that line runs first.
  std::int32_t line = 0;
  //! Which run of the line's records (1-based): a subroutine called twice, or a loop, runs a
  //! line more than once. A run is the records of the line one after another, so a one-line
  //! subroutine called twice in a row makes one run.
  std::uint64_t occurrence = 1;
  //! Where the machine stands [mm]: the approach starts here, and so does the program returned.
  std::array<double, kMaxAxes> here{};
  //! Feed of the approach move [mm/min], > 0 and at most kMaxFeedMmPerMin.
  double approach_feed_mm_per_min = 0.0;
};

//! A PLC M-function (normal or continuous) that the block search dropped.
struct SkippedM {
  std::int32_t m = 0;
  std::int32_t line = 0;
  MKind kind = MKind::kNone;
};

struct Resume {
  //! The approach move (if any) and the records from the line on; start_mm is `here`.
  PackedProgram program;
  //! Index in the whole program of its first record kept.
  std::uint64_t first_record = 0;
  //! Runs of the line's records in the whole program.
  std::uint64_t occurrences = 0;
  //! Where the line starts [mm] (the end of the last move before it, or the program's start).
  std::array<double, kMaxAxes> resume_point{};
  //! An approach move was put first (false when the machine stands at the resume point).
  bool approach = false;
  //! Records dropped, and the PLC M-functions among them: how many, and the last few.
  std::uint64_t skipped_records = 0;
  std::uint64_t skipped_m = 0;
  std::vector<SkippedM> last_skipped_m;
  //! How many dropped M-functions last_skipped_m keeps.
  static constexpr std::size_t kSkippedKept = 8;
};

//! The program `in` resumed as `o` says; false, with the reason in `error` ("line 7 makes no
//! record: ..."), when the line or its occurrence does not exist or an option is out of range.
bool resume_from_line(const PackedProgram& in, const ResumeOptions& o, Resume& out,
                      std::string& error);

//! Which run of its line's records (1-based, as ResumeOptions::occurrence counts them) record
//! `index` (0-based) of `p` belongs to; 0 when `p` has no such record.
std::uint64_t occurrence_at(const PackedProgram& p, std::uint64_t index);

//! Single block, the other operator mode that runs a program other than straight through: `in`
//! with a program stop (M0: the motion stops, the start continues) after each block, i.e.
//! after the last record of each run of one source line's records, except a block that ends
//! in a program stop or the program's end already. The stops carry their block's line and a
//! parameter set of their own with every letter unset (appended to the tables). `stops` is
//! how many were put in; `out` may be `in`. False, with the reason, only if the result does not
//! decode (a defect).
bool single_block(const PackedProgram& in, PackedProgram& out, std::uint64_t& stops,
                  std::string& error);

}  // namespace tgm
