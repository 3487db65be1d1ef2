// Where yaml-cpp says a problem is, for the messages of the config and PLC script readers.
#pragma once

#include <yaml-cpp/mark.h>

#include <algorithm>
#include <string>
#include <string_view>

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

//! The line (0-based) of an empty block sequence item ("-" and nothing) marked at `mark`:
//! yaml-cpp marks one where the next token starts, often lines further down. Only blank space
//! and comments lie between the `-` and that mark, so the item's line is the nearest one at or
//! before the mark (on the mark's own line, the part before it) that holds anything else. When
//! that line does not start with `-` (an empty item of a flow list, `[a, ~]`), or the mark
//! does not fit `text`, the mark's own line is kept. It looks back from the mark only: the
//! cost is the distance to the `-`, so that every empty item of a large file can be placed.
inline int empty_item_line(std::string_view text, const YAML::Mark& mark) {
  if (mark.is_null() || mark.line < 0 || mark.column < 0 || mark.pos < mark.column)
    return mark.line;
  // yaml-cpp counts the bytes of UTF-8 after a byte order mark (it skips one).
  const std::size_t bom = text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
  std::size_t end = static_cast<std::size_t>(mark.pos) + bom;
  std::size_t begin = end - static_cast<std::size_t>(mark.column);  // start of the mark's line
  if (end > text.size() || begin < bom || (begin == bom) != (mark.line == 0) ||
      (begin > bom && text[begin - 1] != '\n')) {
    return mark.line;
  }
  for (int line = mark.line; line >= 0; --line) {
    const std::string_view part = text.substr(begin, end - begin);
    if (const std::size_t first = part.find_first_not_of(" \t\r");
        first != std::string_view::npos && part[first] != '#') {
      return part[first] == '-' ? line : mark.line;
    }
    if (begin <= bom) break;
    end = begin - 1;  // the newline that ends the line before
    const std::size_t nl = end == 0 ? std::string_view::npos : text.rfind('\n', end - 1);
    begin = nl == std::string_view::npos ? bom : nl + 1;
  }
  return mark.line;
}

}  // namespace tgm
