// Checks the YAML targets share: where a message says a problem is, and that it is printable.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"

namespace tgm::fuzz {

inline std::size_t line_count(std::string_view text) {
  std::size_t lines = 1;
  for (char c : text) lines += c == '\n' ? 1 : 0;
  return lines;
}

//! `e` reads "PATH: reason", "PATH:LINE: reason" or "PATH:LINE:COLUMN: reason", with LINE
//! within the text (yaml-cpp counts a lone '\r' as a line end too: at most twice the '\n'
//! lines), a reason, and no control character (text quoted from the input is escaped).
inline void check_message(const std::string& e, const std::string& path, std::string_view text) {
  TGM_FUZZ_CHECK(e.compare(0, path.size(), path) == 0, "message without the path: " + e);
  std::size_t at = path.size();
  for (int field = 0; field < 2 && at < e.size() && e[at] == ':' && at + 1 < e.size() &&
                      e[at + 1] >= '0' && e[at + 1] <= '9';
       ++field) {
    std::size_t end = at + 1;
    long long v = 0;
    while (end < e.size() && e[end] >= '0' && e[end] <= '9' && v < 1'000'000'000) {
      v = v * 10 + (e[end] - '0');
      ++end;
    }
    TGM_FUZZ_CHECK(v >= 1, "line or column 0: " + e);
    if (field == 0) {
      std::size_t limit = line_count(text);
      for (char c : text) limit += c == '\r' ? 1 : 0;
      TGM_FUZZ_CHECK(static_cast<std::size_t>(v) <= limit + 1, "line beyond the text: " + e);
    }
    at = end;
  }
  TGM_FUZZ_CHECK(e.compare(at, 2, ": ") == 0 && e.size() > at + 2,
                 "no ': reason' after the place: " + e);
  for (const char ch : e) {
    const auto c = static_cast<unsigned char>(ch);
    TGM_FUZZ_CHECK(c >= 0x20 && c != 0x7f, "control character in a message: " + e);
  }
}

}  // namespace tgm::fuzz
