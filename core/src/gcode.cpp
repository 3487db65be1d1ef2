#include "tgm/gcode.hpp"

namespace tgm {

std::string format_diagnostic(std::string_view file, const Diagnostic& d) {
  return std::string(file) + ":" + std::to_string(d.line) + ":" + std::to_string(d.column) +
         ": error: " + d.reason;
}

CompileOptions CompileOptions::from_machine(const MachineConfig& m, int n) {
  CompileOptions o;
  o.axis_letters = m.axis_letters(n);
  o.compiler = m.compiler;
  o.tools = m.tools;
  return o;
}

CompileResult compile_gcode(std::string_view, const CompileOptions&) {
  CompileResult r;
  r.errors.push_back({1, 1, "compiler not written yet"});
  return r;
}

}  // namespace tgm
