// Shared by the fuzz targets and the plain driver that runs them without libFuzzer.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "../support/splitmix64.hpp"
#include "tgm/intercode.hpp"

//! A broken invariant: say which and abort (libFuzzer and the driver both save the input).
#define TGM_FUZZ_CHECK(cond, what)                                                        \
  do {                                                                                    \
    if (!(cond)) {                                                                        \
      std::fprintf(stderr, "fuzz check failed at %s:%d: %s (%s)\n", __FILE__, __LINE__,   \
                   #cond, std::string(what).c_str());                                     \
      std::abort();                                                                       \
    }                                                                                     \
  } while (0)

namespace tgm::fuzz {

//! The driver's mutations and a target's choices (tests/support/splitmix64.hpp: the same stream
//! on every platform).
struct Rng : tgm::test::SplitMix64 {
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(next() % n); }
};

//! Lets a target turn the driver's seed files into its own input format (the intercode target
//! compiles the G-code seeds and encodes them). Every target defines it; libFuzzer builds
//! never call it.
void prepare_seeds(std::vector<std::string>& seeds);

//! Lets a target replace or extend the pieces the plain driver's mutator inserts (G-code words
//! and troublesome numbers by default; the YAML targets insert YAML syntax and their keys).
//! Every target defines it; libFuzzer builds never call it (they take a -dict file).
void prepare_tokens(std::vector<std::string>& tokens);

//! Every field `encode_intercode` stores is equal in `a` and `b`; `why` names the first that
//! is not.
inline bool same_program(const Program& a, const Program& b, std::string& why) {
  if (a.number_axes != b.number_axes) return why = "number_axes", false;
  if (a.segments.size() != b.segments.size()) return why = "segment count", false;
  const auto n = static_cast<std::size_t>(a.number_axes);
  for (std::size_t i = 0; i < n; ++i) {
    if (a.start_mm[i] != b.start_mm[i]) return why = "start_mm[" + std::to_string(i) + "]", false;
  }
  for (std::size_t k = 0; k < a.segments.size(); ++k) {
    const Segment& x = a.segments[k];
    const Segment& y = b.segments[k];
    why = "segment " + std::to_string(k) + ": ";
    if (x.type != y.type || x.plane != y.plane || x.compensation != y.compensation ||
        x.m_kind != y.m_kind || x.line != y.line || x.tool != y.tool) {
      return why += "type/plane/compensation/m_kind/line/tool", false;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (x.end[i] != y.end[i]) return why += "end[" + std::to_string(i) + "]", false;
    }
    if (x.compensation != Compensation::kOff &&
        x.compensation_radius_mm != y.compensation_radius_mm) {
      return why += "compensation_radius_mm", false;
    }
    if (x.is_motion() && x.feed_mm_per_min != y.feed_mm_per_min) return why += "feed", false;
    if (x.is_arc() && (x.center != y.center || x.radius != y.radius || x.turns != y.turns)) {
      return why += "centre/radius/turns", false;
    }
    if (x.type == SegmentType::kDwell && x.dwell_s != y.dwell_s) return why += "dwell", false;
    if (x.type == SegmentType::kMFunction && (x.m != y.m || x.aux != y.aux)) {
      return why += "m/aux", false;
    }
    if (x.type == SegmentType::kMessage && x.aux != y.aux) return why += "aux", false;
  }
  why.clear();
  if (a.params.size() != b.params.size()) return why = "params count", false;
  for (std::size_t k = 0; k < a.params.size(); ++k) {
    for (std::size_t i = 0; i < a.params[k].size(); ++i) {
      // Bit-for-bit except that any NaN would already be a failure elsewhere.
      if (!(a.params[k][i] == b.params[k][i])) return why = "params " + std::to_string(k), false;
    }
  }
  if (a.messages != b.messages) return why = "messages", false;
  return true;
}

//! The decoder's promise: no NaN anywhere, finite numbers in the records.
inline bool all_finite(const Program& p, std::string& why) {
  for (int i = 0; i < p.number_axes; ++i) {
    if (!std::isfinite(p.start_mm[static_cast<std::size_t>(i)]))
      return why = "non-finite start", false;
  }
  for (std::size_t k = 0; k < p.segments.size(); ++k) {
    const Segment& s = p.segments[k];
    bool ok = std::isfinite(s.center[0]) && std::isfinite(s.center[1]) &&
              std::isfinite(s.radius) && std::isfinite(s.feed_mm_per_min) &&
              std::isfinite(s.dwell_s) && std::isfinite(s.compensation_radius_mm);
    for (int i = 0; i < p.number_axes; ++i) {
      ok = ok && std::isfinite(s.end[static_cast<std::size_t>(i)]);
    }
    if (!ok) return why = "non-finite value in segment " + std::to_string(k), false;
  }
  for (const MParams& mp : p.params) {
    for (double v : mp) {
      if (std::isnan(v)) return why = "NaN in params", false;
    }
  }
  return true;
}

}  // namespace tgm::fuzz
