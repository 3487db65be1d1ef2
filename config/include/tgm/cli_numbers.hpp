// Numbers given on the command line, read the same way by tgm-service, tgm-plc and tgm-hmi (and
// the numbers of the config and of a PLC script): the whole argument must be a plain base-10
// number (no trailing text, no leading blank or '+', no hex like "0x10" or "0x1p-1", which
// strtod and strtoll took), integers must fit the flag's range (no wrap-around through a
// narrowing cast) and decimals must be finite ("inf", "nan" and overflowing values like
// "1e999" are refused, so `--duration inf` is an error, not a run without end) and not so
// small that they would read as 0 ("1e-400"). Header-only, like dds_overrides.hpp; the
// binaries word their own messages.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

namespace tgm {

namespace detail {

// Length of the run of decimal digits at `at`.
inline std::size_t decimal_digits(const std::string& text, std::size_t at) {
  std::size_t n = 0;
  while (at + n < text.size() && text[at + n] >= '0' && text[at + n] <= '9') ++n;
  return n;
}

// True when `text` is [-]DIGITS, or with `decimal` [-](DIGITS[.[DIGITS]] | .DIGITS)[(e|E)[+|-]
// DIGITS]: what strtod / strtoll then read in full, without their leading blanks, '+', hex,
// "inf" and "nan". `nonzero` says whether a mantissa digit is not 0.
inline bool plain_decimal(const std::string& text, bool decimal, bool& nonzero) {
  std::size_t at = text.empty() || text[0] != '-' ? 0 : 1;
  const std::size_t mantissa = at;
  std::size_t digits = decimal_digits(text, at);
  at += digits;
  if (decimal && at < text.size() && text[at] == '.') {
    const std::size_t fraction = decimal_digits(text, at + 1);
    digits += fraction;
    at += 1 + fraction;
  }
  if (digits == 0) return false;
  nonzero = text.find_first_of("123456789", mantissa) < at;
  if (decimal && at < text.size() && (text[at] == 'e' || text[at] == 'E')) {
    ++at;
    if (at < text.size() && (text[at] == '+' || text[at] == '-')) ++at;
    const std::size_t exponent = decimal_digits(text, at);
    if (exponent == 0) return false;
    at += exponent;
  }
  return at == text.size();
}

}  // namespace detail

//! The whole of `text` as a base-10 integer within [lo, hi]; false (out untouched) otherwise.
inline bool parse_integer(const std::string& text, long long lo, long long hi, long long& out) {
  bool nonzero = false;
  if (!detail::plain_decimal(text, false, nonzero)) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (errno != 0 || *end != '\0' || v < lo || v > hi) return false;
  out = v;
  return true;
}

//! parse_integer for an `int` destination (lo and hi are ints, so the value always fits).
inline bool parse_integer(const std::string& text, int lo, int hi, int& out) {
  long long v = 0;
  if (!parse_integer(text, static_cast<long long>(lo), static_cast<long long>(hi), v)) return false;
  out = static_cast<int>(v);
  return true;
}

//! The whole of `text` as a finite decimal number ("-2.5", "1e-3", ".5"); false (out untouched)
//! otherwise, and for a value too small to be told from 0 ("1e-400"; subnormal ones are kept).
inline bool parse_finite(const std::string& text, double& out) {
  bool nonzero = false;
  if (!detail::plain_decimal(text, true, nonzero)) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (*end != '\0' || !std::isfinite(v) || (nonzero && v == 0.0)) return false;
  out = v;
  return true;
}

//! The comma-separated items of a list argument ("51,50"), empty ones kept so that the caller
//! refuses them: "1,,2" is three items, "" one.
inline std::vector<std::string> comma_items(const std::string& text) {
  std::vector<std::string> items;
  for (std::size_t at = 0; at <= text.size();) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    items.push_back(text.substr(at, comma - at));
    at = comma + 1;
  }
  return items;
}

}  // namespace tgm
