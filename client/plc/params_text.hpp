// How tgm-plc's log shows an M-function's parameters (M_Function_Parameter). Header-only, no
// DDS (unit-tested).
#pragma once

#include <cstddef>
#include <string>

#include "tgm/intercode.hpp"
#include "tgm/printable.hpp"

namespace tgm::plc {

//! "A-1e-06 B123456789.123": each parameter that is set, by its letter, as the shortest text
//! that reads back as the same double (printf's %g kept 6 digits: "B1.23457e+08" for a
//! spindle speed or position the PLC got whole); "none" when none is set.
template <class Params>
std::string params_text(const Params& params) {
  std::string out;
  for (std::size_t k = 0; k < kParamLetters; ++k) {
    const double v = params[k];
    if (is_not_set(v)) continue;
    if (!out.empty()) out += ' ';
    out += static_cast<char>('A' + k);
    append_shortest(out, v);
  }
  return out.empty() ? "none" : out;
}

}  // namespace tgm::plc
