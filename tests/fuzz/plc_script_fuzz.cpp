// Fuzz target: arbitrary bytes as a tgm-plc script (--script: a YAML list of timed steps).
//
// Invariants: parsing never crashes, hangs or throws; it gives steps or one problem; the
// problem names the file, a line within the text when it has one, and a reason, with no
// control character; every step it gives is within the ranges the PLC sends (an override the
// service would refuse, a Command it does not know, are problems here); the same text parses
// the same way twice.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "tgm/intercode.hpp"
#include "tgm/plc_script.hpp"
#include "yaml_checks.hpp"
#include "yaml_tokens.hpp"

namespace tgm::fuzz {
void prepare_seeds(std::vector<std::string>&) {}
void prepare_tokens(std::vector<std::string>& tokens) {
  tokens = yaml_tokens();
}
}  // namespace tgm::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::string path = "fuzz.yaml";
  const tgm::PlcScriptLoad load = tgm::parse_plc_script(text, path);
  if (!load.ok()) {
    TGM_FUZZ_CHECK(load.steps.empty(), "steps with a problem: " + load.error);
    // One problem per line (every bad step is named), each a message of its own.
    std::size_t from = 0;
    while (from <= load.error.size()) {
      const std::size_t end = std::min(load.error.find('\n', from), load.error.size());
      tgm::fuzz::check_message(load.error.substr(from, end - from), path, text);
      from = end + 1;
    }
  }
  for (const tgm::PlcScriptStep& s : load.steps) {
    const std::string at = "step of line " + std::to_string(s.line) + ": ";
    TGM_FUZZ_CHECK(s.line >= 1 && static_cast<std::size_t>(s.line) <= size + 1, at + "line");
    TGM_FUZZ_CHECK(std::isfinite(s.at_s) && s.at_s >= 0.0 && s.at_s <= 1e9, at + "at_s");
    TGM_FUZZ_CHECK(s.interpolator >= 0 && s.interpolator < tgm::kMaxInterpolators,
                   at + "interpolator");
    TGM_FUZZ_CHECK(!s.rel_speed || (*s.rel_speed >= 0.01 && *s.rel_speed <= 2.0), at + "rel_speed");
    TGM_FUZZ_CHECK(!s.command || tgm::plc_script_command(*s.command), at + "command");
    for (int m : s.refuse_ack) TGM_FUZZ_CHECK(m >= 1 && m <= 999, at + "refuse_ack");
    TGM_FUZZ_CHECK(!s.number_axes || (*s.number_axes >= 1 && *s.number_axes <= tgm::kMaxAxes),
                   at + "number_axes");
    for (const auto& [letter, r] : s.ratio) {
      TGM_FUZZ_CHECK(letter >= 'A' && letter <= 'Z' && std::fabs(r) >= 1e-6 && std::fabs(r) <= 1e9,
                     at + "ratio");
    }
    for (const auto& [letter, o] : s.offset_inc) {
      TGM_FUZZ_CHECK(letter >= 'A' && letter <= 'Z' && o >= -1'000'000'000'000'000 &&
                         o <= 1'000'000'000'000'000,
                     at + "offset");
    }
    TGM_FUZZ_CHECK(s.rel_speed || s.number_axes || !s.ratio.empty() || !s.offset_inc.empty() ||
                       s.command || s.start || !s.refuse_ack.empty(),
                   at + "a step without an action");
  }
  const tgm::PlcScriptLoad again = tgm::parse_plc_script(text, path);
  TGM_FUZZ_CHECK(again.error == load.error && again.steps.size() == load.steps.size(),
                 "the same text parses differently");
  return 0;
}
