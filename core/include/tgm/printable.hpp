// Text from a program or from the network, made safe to print on a terminal: an M29 message
// or a reply's reason may hold control characters (a tab, a stray carriage return, an escape
// sequence that would recolour or clear the operator's screen). And numbers for messages.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace tgm {

//! `s` with every control character (C0 and DEL) written as \t, \n, \r or \xHH; everything
//! else, UTF-8 included, as it is.
inline std::string printable(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c != 0x7f) {
      out.push_back(ch);
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  return out;
}

//! A number as a reply or an error message shows it: six significant digits ("1e+21", "-0.5").
inline std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace tgm
