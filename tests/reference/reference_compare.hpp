// Helpers the reference tests share: where they keep their programs, reading files, and the
// motion-by-motion comparison of rs274's canonical motions with our intercode.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "rs274_canon.hpp"
#include "tgm/intercode.hpp"

namespace tgm::ref {

//! Agreement asked for [mm], plus the rounding of rs274's "%.4f" output.
inline constexpr double kTolerance = 1e-4 + 5e-5 + 1e-9;

//! True when a missing rs274 is a failure (TGM_REQUIRE_RS274 at configure time or =1 in the
//! environment), not a skip.
bool rs274_required();

//! build/tests/reference/work (created on first use): generated and failing programs.
std::filesystem::path work_dir();

std::string read_file(const std::filesystem::path& p);

std::vector<std::string> split_lines(const std::string& text);

//! True when the first line of the program states G91 (every reference program states G90 or
//! G91 there, because our default distance mode is a config value).
bool first_line_incremental(const std::string& text);

//! "%.6f".
std::string fmt(double v);

//! Compares and returns a readable report of the first mismatches (empty when they agree).
//! `source` is our program text (its lines are quoted in the report).
std::string compare(const CanonProgram& ref, const Program& ours, const std::string& source,
                    std::size_t max_reports = 10);

}  // namespace tgm::ref
