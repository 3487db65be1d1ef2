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

//! Appends `s` as a JSON string: quotes, backslashes and control characters escaped, the rest
//! (UTF-8 included) as it is.
inline void append_json_string(std::string& out, std::string_view s) {
  out.push_back('"');
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out.push_back(ch);
        }
    }
  }
  out.push_back('"');
}

//! A number as a reply or an error message shows it: six significant digits ("1e+21", "-0.5").
inline std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace tgm
