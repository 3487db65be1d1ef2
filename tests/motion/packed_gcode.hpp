// G-code compiled and held as intercode (PackedProgram), for the tests of what takes a program
// that way (block search, program times). A compile error fails the test that asked.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <string>

#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"

namespace tgm::test {

//! `gcode` compiled with the default options from `start` [mm], as intercode.
inline PackedProgram packed(const std::string& gcode,
                            const std::array<double, kMaxAxes>& start = {}) {
  CompileOptions o;
  o.start_mm = start;
  const CompileResult r = compile_gcode(gcode, o);
  EXPECT_TRUE(r.errors.empty()) << (r.errors.empty()
                                        ? ""
                                        : format_diagnostic("program", r.errors.front()));
  PackedProgram p;
  std::string error;
  EXPECT_TRUE(PackedProgram::from_program(r.program, p, error)) << error;
  return p;
}

}  // namespace tgm::test
