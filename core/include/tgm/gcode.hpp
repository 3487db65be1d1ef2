// The G-code compiler: G-code text -> intercode (the dialect: core/GCODE.md).
#pragma once

#include <array>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/config.hpp"
#include "tgm/intercode.hpp"

namespace tgm {

//! One compile error at a place in the source.
struct Diagnostic {
  int line = 0;    //!< 1-based source line; 0: at no place (the options, the count of the rest)
  int column = 0;  //!< 1-based column of the offending text, in characters as editors count
                   //!< them (a UTF-8 sequence is one, a byte that is not UTF-8 one)
  std::string reason;
};

//! "FILE:LINE:COL: error: reason"; "FILE: error: reason" at line 0.
std::string format_diagnostic(std::string_view file, const Diagnostic& d);

//! What the compiler needs to know about the machine.
struct CompileOptions {
  //! Letters of the configured axes, one per axis (1..kMaxAxes), e.g. "XYZ".
  std::string axis_letters = "XYZ";
  CompilerConfig compiler;
  std::vector<ToolConfig> tools;
  //! Machine position the program starts from [mm] (G91 moves and arcs are relative to it).
  std::array<double, kMaxAxes> start_mm{};
  //! The interpolator's axes, for their soft limits (tgm/soft_limits.hpp): a record that
  //! leaves them is an error at its line. No axes: not checked.
  InterpolatorConfig machine_axes;

  //! Options for interpolator `n` of a machine.
  static CompileOptions from_machine(const MachineConfig& m, int n);
};

//! Result of a compilation: a program when `errors` is empty, otherwise no records at all.
struct CompileResult {
  Program program;
  std::vector<Diagnostic> errors;
  //! Errors beyond the first 10,000: `errors` then ends with one saying how many.
  std::size_t errors_not_shown = 0;
  bool ok() const { return errors.empty(); }
  //! Every error found, those not shown included.
  std::size_t error_count() const {
    return errors_not_shown > 0 ? errors.size() - 1 + errors_not_shown : errors.size();
  }
};

//! Receives each record as the compiler makes it, in program order.
using SegmentSink = std::function<void(const Segment&)>;

//! Compiles a whole program. Never throws on bad input; every error is reported with its place,
//! and a program with errors yields no records.
CompileResult compile_gcode(std::string_view source, const CompileOptions& options);

//! Compiles a whole program, handing the records to `sink` instead of keeping them (for very
//! long programs: `result.program` then holds only the side tables). When the result has errors,
//! whatever the sink received must be discarded.
CompileResult compile_gcode(std::string_view source, const CompileOptions& options,
                            const SegmentSink& sink);

}  // namespace tgm
