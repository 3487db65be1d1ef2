// YAML adapter: builds core's plain config structs plus the settings of the processes around
// core (DDS, PLC emulator) from one YAML file (DESIGN.md section 7).
#pragma once

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/config.hpp"

namespace tgm {

//! DDS settings shared by every process.
struct DdsConfig {
  int domain_id = 0;
  //! Fast DDS XML profiles file; a relative path is taken relative to the YAML file. Not given
  //! in the file: fastdds_profiles.xml beside it, or else the one shipped with tgm.
  std::string profiles_file = "fastdds_profiles.xml";
  //! Prefix of participant names ("<prefix>-service", "<prefix>-plc", "<prefix>-hmi").
  std::string participant_prefix = "tgm";
  //! Longest participant_prefix [bytes]: Fast DDS cuts participant names at 255 without a word,
  //! and a PLC is known by its name's "-plc".
  static constexpr std::size_t kMaxPrefix = 200;
  //! Why `prefix` cannot be a participant_prefix ("" when it can).
  static std::string prefix_problem(std::string_view prefix);
  //! DDS Security: the directory config/security/tgm-security wrote (CA, governance, each
  //! role's identity and permissions); a relative path is taken relative to the YAML file.
  //! Empty: no security (anyone on the network may join the domain).
  std::string security_dir;
};

//! Behaviour of the PLC emulator (tgm-plc).
struct PlcConfig {
  //! Time the emulated PLC takes for an M-function without its own entry [s].
  double default_m_delay_s = 0.1;
  //! Time per M-number [s] (default.yaml's table; a table in the file replaces it whole).
  std::map<int, double> m_delay_s{{50, 0.2}, {51, 0.2}};
  //! tgm-service refuses a start until a PLC has reported its setup of the interpolator since
  //! the service started (tgm-plc reports it once it has set the basic parameters, the gear
  //! ratios and, after a restart, the drives' position). Off for a machine without a PLC.
  bool setup_before_start = true;
};

//! The whole YAML file.
struct AppConfig {
  MachineConfig machine;
  DdsConfig dds;
  PlcConfig plc;
  //! The file it was read from ("" for built-in defaults).
  std::string source_path;
};

//! load_config_file (and a tgm-plc script) reads at most this much: a config is a few KB.
//! yaml-cpp holds about 500 bytes a node, so this bounds the memory too: a 16 MB list of
//! zeros under the 16 MiB that it was took 4.3 GB and 39 s before its error.
inline constexpr std::size_t kMaxConfigBytes = std::size_t{1} << 20;

//! load_config_or_report prints at most this many problems, then how many more there are.
inline constexpr std::size_t kConfigProblemsShown = 50;

//! Outcome of loading: a config, or every problem found as "FILE:LINE: key.path: reason".
struct ConfigLoad {
  std::optional<AppConfig> config;
  std::vector<std::string> errors;
};

//! Parses YAML text. `path` is used in messages and to resolve relative file names.
ConfigLoad load_config_text(const std::string& text, const std::string& path);

//! Reads and parses a file.
ConfigLoad load_config_file(const std::string& path);

//! Loads `path` (default_config_path() when empty) for a command-line program: on failure prints
//! the problems (the first kConfigProblemsShown, then how many more) and "<program>: the config
//! <path> has N problems" to stderr, returns nullopt.
std::optional<AppConfig> load_config_or_report(const std::string& path, const std::string& program);

//! The config file used when none is given: $TGM_CONFIG, then shipped_config_file("default.yaml").
std::string default_config_path();

//! A file shipped with tgm's configs (default.yaml, fastdds_profiles.xml): share/tgm/NAME of
//! the installation the running binary belongs to (BIN/../share/tgm), else of the configured
//! <prefix>, else config/NAME of the source tree.
std::string shipped_config_file(const std::string& name);

}  // namespace tgm
