// Reading LinuxCNC's `rs274 -g` canonical output, and running the `rs274` binary.
//
// rs274 prints one canonical call per line, e.g.
//   "   14 N..... ARC_FEED(30.0000, 5.0000, 25.0000, 5.0000, -1, 1.0000, 0.0000, 0.0000, 0.0000)"
// Positions in STRAIGHT_TRAVERSE / STRAIGHT_FEED / ARC_FEED are program coordinates; the canon
// layer of LinuxCNC adds the active G5x and G92 offsets (printed as SET_G5X_OFFSET /
// SET_G92_OFFSET) to get machine coordinates. Our intercode holds machine coordinates, so the
// parser adds those offsets: machine = canonical + g5x + g92, per axis.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/intercode.hpp"

namespace tgm::ref {

//! One motion as rs274 reports it, mapped into our intercode's conventions.
struct CanonMotion {
  //! 0 STRAIGHT_TRAVERSE, 1 STRAIGHT_FEED, 2 ARC_FEED clockwise, 3 ARC_FEED counter-clockwise.
  int type = 1;
  Plane plane = Plane::kXY;
  //! End point X, Y, Z in machine coordinates [mm].
  std::array<double, 3> end{};
  //! Arc centre on the plane's first and second axis (see `plane_axes`: X, Y, Z are axes 0, 1, 2
  //! here), machine coords [mm].
  std::array<double, 2> center{};
  //! Extra full turns beyond the first: |rotation| - 1 (arcs only).
  int turns = 0;
  //! Feed rate in force [mm/min] (SET_FEED_RATE).
  double feed_mm_per_min = 0.0;
  //! 1-based line of the rs274 output this motion was read from.
  int output_line = 0;
};

//! Everything the comparison needs from one rs274 run.
struct CanonProgram {
  std::vector<CanonMotion> motions;
  //! PROGRAM_END() was seen.
  bool ended = false;
};

//! Parses rs274's canonical output. Returns an error text on a line it cannot read.
std::optional<std::string> parse_canon(std::string_view output, CanonProgram& out);

//! Path of the rs274 binary: $TGM_RS274 if set, else the first `rs274` on PATH; empty if none.
std::string find_rs274();

//! Output and exit status of one rs274 run.
struct Rs274Run {
  int exit_code = -1;
  std::string out;  //!< canonical calls (stdout)
  std::string err;  //!< rs274's messages (stderr)
};

//! Runs `rs274 -g FILE`, capturing stdout and stderr.
Rs274Run run_rs274(const std::string& rs274, const std::string& file);

}  // namespace tgm::ref
