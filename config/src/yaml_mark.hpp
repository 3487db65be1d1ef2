// Where yaml-cpp says a problem is, for the messages of the config and PLC script readers.
#pragma once

#include <yaml-cpp/mark.h>

#include <string>

namespace tgm {

//! ":LINE:COLUMN" (1-based) of a yaml-cpp mark; "" for a mark that points nowhere (yaml-cpp's
//! null mark would read as line 0, column 0).
inline std::string yaml_place(const YAML::Mark& m) {
  if (m.is_null()) return {};
  // Appended piece by piece: GCC 12 at -O3 warns (-Wrestrict, falsely) on ":" + to_string().
  std::string out(1, ':');
  out += std::to_string(m.line + 1);
  out += ':';
  out += std::to_string(m.column + 1);
  return out;
}

}  // namespace tgm
