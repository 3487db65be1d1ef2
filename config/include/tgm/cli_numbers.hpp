// Numbers given on the command line, read the same way by tgm-service, tgm-plc and tgm-hmi: the
// whole argument must be the number (no trailing text), integers must fit the flag's range
// (no wrap-around through a narrowing cast) and decimals must be finite ("inf", "nan" and
// overflowing values like "1e999" are refused, so `--duration inf` is an error, not a run
// without end). Header-only, like dds_overrides.hpp; the binaries word their own messages.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

namespace tgm {

//! The whole of `text` as a base-10 integer within [lo, hi]; false (out untouched) otherwise.
inline bool parse_integer(const std::string& text, long long lo, long long hi, long long& out) {
  if (text.empty()) return false;
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

//! The whole of `text` as a finite number (strtod's syntax); false (out untouched) otherwise.
inline bool parse_finite(const std::string& text, double& out) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (*end != '\0' || !std::isfinite(v)) return false;
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
