// Text from a program or from the network, made safe to print on a terminal: an M29 message
// or a reply's reason may hold control characters (a tab, a stray carriage return, an escape
// sequence that would recolour or clear the operator's screen). And numbers for messages.
#pragma once

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <system_error>

namespace tgm {

//! Appends the shortest text that reads back as the same double ("0.1", "1e-06", "4000.125"):
//! every digit a message, a log or a dump needs, where printf's %g kept six.
inline void append_shortest(std::string& out, double v) {
  char buf[32];  // the longest, "-2.2250738585072014e-308", takes 24
  out.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

//! append_shortest() as a string of its own.
inline std::string shortest_text(double v) {
  std::string out;
  append_shortest(out, v);
  return out;
}

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

//! Length of the well-formed UTF-8 sequence at the start of `s` (1..4 bytes), 0 when it is not
//! one (a stray continuation byte, an overlong form, a surrogate, beyond U+10FFFF, cut short).
inline std::size_t utf8_sequence_length(std::string_view s) {
  if (s.empty()) return 0;
  const auto b = [&](std::size_t i) { return static_cast<unsigned char>(s[i]); };
  const unsigned char c = b(0);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // the range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;  // no overlong form
    if (c == 0xED) hi = 0x9F;  // no surrogate
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;
    if (c == 0xF4) hi = 0x8F;  // at most U+10FFFF
  } else {
    return 0;
  }
  if (s.size() < n || b(1) < lo || b(1) > hi) return 0;
  for (std::size_t i = 2; i < n; ++i) {
    if (b(i) < 0x80 || b(i) > 0xBF) return 0;
  }
  return n;
}

//! The code point of `s`, a whole well-formed UTF-8 sequence (utf8_sequence_length(s) ==
//! s.size()).
inline unsigned utf8_code_point(std::string_view s) {
  const auto b = [&](std::size_t i) {
    return static_cast<unsigned>(static_cast<unsigned char>(s[i]));
  };
  switch (s.size()) {
    case 1:
      return b(0);
    case 2:
      return ((b(0) & 0x1Fu) << 6) | (b(1) & 0x3Fu);
    case 3:
      return ((b(0) & 0x0Fu) << 12) | ((b(1) & 0x3Fu) << 6) | (b(2) & 0x3Fu);
    case 4:
      return ((b(0) & 0x07u) << 18) | ((b(1) & 0x3Fu) << 12) | ((b(2) & 0x3Fu) << 6) |
             (b(3) & 0x3Fu);
    default:
      return 0xFFFDu;
  }
}

//! Offset of the first byte of `s` that is not well-formed UTF-8; npos when all of it is.
inline std::size_t utf8_invalid_at(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = utf8_sequence_length(s.substr(i));
    if (n == 0) return i;
    i += n;
  }
  return std::string_view::npos;
}

//! Offset of the first control character of `s` (a byte below 0x20 other than a tab, or DEL);
//! npos when it has none. Message texts are shown on terminals and panels: an escape sequence
//! or a bell in an M29 text reached every HMI as it was.
inline std::size_t control_char_at(std::string_view s) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && c != '\t') || c == 0x7f) return i;
  }
  return std::string_view::npos;
}

//! Appends `s` as a JSON string: quotes, backslashes and control characters escaped, UTF-8 as
//! it is, and each byte that is not well-formed UTF-8 as U+FFFD (JSON is UTF-8: a raw 0xFF made
//! a line no JSON parser reads).
inline void append_json_string(std::string& out, std::string_view s) {
  out.push_back('"');
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x80) {
      const std::size_t n = utf8_sequence_length(s.substr(i));
      if (n == 0) {
        out += "\\ufffd";
        ++i;
      } else {
        out.append(s.data() + i, n);
        i += n;
      }
      continue;
    }
    ++i;
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
        if (c < 0x20 || c == 0x7f) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out.push_back(static_cast<char>(c));
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

//! number_text when its six digits read back as `v`, else the shortest text that does: a value
//! just outside a range is not printed as the bound ("must be 0.01..100000, not 100000" for
//! 100000.0001).
inline std::string exact_number_text(double v) {
  std::string six = number_text(v);
  if (std::strtod(six.c_str(), nullptr) == v) return six;
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : six;
}

}  // namespace tgm
