// Fuzz target: arbitrary bytes as a machine config (the YAML file all three binaries read).
//
// Invariants (DESIGN.md section 7): loading never crashes, hangs or throws; it gives a config
// or problems, never both or neither; every problem names the file, a line within the text
// when it has one, and a reason, with no control character; a config it gives passes core's
// validation, builds every interpolator, compiles a line of G-code for each, and has DDS and
// PLC settings within their ranges; the same text loads the same way twice.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "tgm/gcode.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/yaml_config.hpp"
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
  const tgm::ConfigLoad load = tgm::load_config_text(text, path);
  TGM_FUZZ_CHECK(load.config.has_value() == load.errors.empty(),
                 load.config ? "a config with problems" : "neither a config nor a problem");
  for (const std::string& e : load.errors) tgm::fuzz::check_message(e, path, text);

  if (load.config) {
    const tgm::AppConfig& c = *load.config;
    const tgm::MachineConfig& m = c.machine;
    const std::vector<std::string> problems = m.validate();
    TGM_FUZZ_CHECK(problems.empty(), "a loaded config fails validate(): " + problems.front());
    TGM_FUZZ_CHECK(!m.interpolators.empty() &&
                       m.interpolators.size() <= static_cast<std::size_t>(tgm::kMaxInterpolators),
                   "interpolator count " + std::to_string(m.interpolators.size()));
    for (int i = 0; i < static_cast<int>(m.interpolators.size()); ++i) {
      std::string error;
      TGM_FUZZ_CHECK(tgm::Interpolator::create(m, i, {}, &error).has_value(),
                     "interpolator " + std::to_string(i) + " of a loaded config: " + error);
      const tgm::CompileResult r =
          tgm::compile_gcode("G1 F100\nM30\n", tgm::CompileOptions::from_machine(m, i));
      TGM_FUZZ_CHECK(r.ok(), "a line of G-code for interpolator " + std::to_string(i) + ": " +
                                 (r.errors.empty() ? std::string() : r.errors.front().reason));
    }
    TGM_FUZZ_CHECK(c.dds.domain_id >= 0 && c.dds.domain_id <= 232,
                   "domain_id " + std::to_string(c.dds.domain_id));
    TGM_FUZZ_CHECK(std::isfinite(c.plc.default_m_delay_s) && c.plc.default_m_delay_s >= 0.0 &&
                       c.plc.default_m_delay_s <= 3600.0,
                   "plc.default_m_delay_s");
    for (const auto& [mnum, s] : c.plc.m_delay_s) {
      TGM_FUZZ_CHECK(
          mnum >= 1 && mnum <= tgm::kMaxNormalM && std::isfinite(s) && s >= 0.0 && s <= 3600.0,
          "plc.m_delay_s." + std::to_string(mnum));
    }
  }

  const tgm::ConfigLoad again = tgm::load_config_text(text, path);
  TGM_FUZZ_CHECK(again.errors == load.errors && again.config.has_value() == load.config.has_value(),
                 "the same text loads differently");
  return 0;
}
