// Command-line overrides of the DDS settings of the YAML config (DESIGN.md section 6: domain id,
// participant names and the profile file come from the config and can be overridden on the
// command line). Shared by tgm-service, tgm-plc and tgm-hmi so the flags mean the same
// everywhere. Header-only: the binaries parse their own arguments and call these.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "tgm/cli_numbers.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {

//! The flags below, for --help texts.
inline constexpr const char* kDdsOverrideHelp =
    "  --domain N            DDS domain id 0..232 (overrides dds.domain_id; 0..100 keep\n"
    "                        their ports below Linux's range for outgoing sockets)\n"
    "  --profiles FILE       Fast DDS XML profiles (overrides dds.profiles_file)\n"
    "  --participant-prefix P  participant names P-service, P-plc, P-hmi\n"
    "  --security DIR        DDS Security material of config/security/tgm-security\n"
    "                        (overrides dds.security; 'off' runs without)\n";

//! DDS settings given on the command line (empty / -1 = not given).
struct DdsOverrides {
  int domain_id = -1;
  std::string profiles_file;
  std::string participant_prefix;
  std::optional<std::string> security_dir;  // "" = off

  //! Takes `flag` with `value` when it is one of the DDS flags; false otherwise. A bad value
  //! sets `error` (and returns true).
  bool take(std::string_view flag, const std::string& value, std::string& error) {
    if (flag == "--domain") {
      if (!parse_integer(value, 0, 232, domain_id))
        error = "--domain must be 0..232, not '" + value + "'";
      return true;
    }
    if (flag == "--profiles") {
      profiles_file = value;
      return true;
    }
    if (flag == "--security") {
      if (value.empty()) error = "--security needs a directory (or 'off'), not an empty string";
      security_dir = value == "off" ? std::string() : value;
      return true;
    }
    if (flag == "--participant-prefix") {
      if (const std::string why = DdsConfig::prefix_problem(value); !why.empty()) {
        error = "--participant-prefix " + why;
      }
      participant_prefix = value;
      return true;
    }
    return false;
  }
  //! Applies what was given to `c`.
  void apply(DdsConfig& c) const {
    if (domain_id >= 0) c.domain_id = domain_id;
    if (!profiles_file.empty()) c.profiles_file = profiles_file;
    if (!participant_prefix.empty()) c.participant_prefix = participant_prefix;
    if (security_dir) c.security_dir = *security_dir;
  }
};

//! Empty when the profiles file of `c` exists (or none is set), else a reason (a config error:
//! the binaries exit with 2 instead of failing later in Fast DDS).
inline std::string dds_profiles_problem(const DdsConfig& c) {
  std::error_code ec;
  if (c.profiles_file.empty() || std::filesystem::is_regular_file(c.profiles_file, ec)) return {};
  const bool exists = std::filesystem::exists(c.profiles_file, ec);
  return "the DDS profiles file '" + c.profiles_file + "' " +
         (exists ? "is not a regular file" : "does not exist") +
         " (dds.profiles_file or --profiles)";
}

//! The files of DDS Security for participant `role` (service, plc, hmi) in `dir`, in the order
//! ca, governance, identity certificate, private key, permissions.
inline std::array<std::string, 5> dds_security_files(const std::string& dir,
                                                     std::string_view role) {
  namespace fs = std::filesystem;
  const fs::path d(dir);
  const std::string r(role);
  return {(d / "ca.pem").string(), (d / "governance.p7s").string(), (d / (r + ".pem")).string(),
          (d / (r + ".key")).string(), (d / (r + ".permissions.p7s")).string()};
}

//! Empty when security is off or every file participant `role` needs is there, else a reason
//! naming the file (a config error: the binaries exit with 2 before Fast DDS refuses).
inline std::string dds_security_problem(const DdsConfig& c, std::string_view role) {
  if (c.security_dir.empty()) return {};
  std::error_code ec;
  if (!std::filesystem::is_directory(c.security_dir, ec)) {
    return "the DDS Security directory '" + c.security_dir +
           "' does not exist (dds.security or "
           "--security; config/security/tgm-security --out DIR makes one)";
  }
  for (const std::string& f : dds_security_files(c.security_dir, role)) {
    if (!std::filesystem::is_regular_file(f, ec)) {
      return "DDS Security: '" + f + "' is missing (the " + std::string(role) +
             " identity of config/security/tgm-security; dds.security or --security)";
    }
  }
  return {};
}

//! dds_profiles_problem, then dds_security_problem for the participant of `role`: what the
//! binaries check before any DDS entity exists (a problem is a config error, exit 2).
inline std::string dds_config_problem(const DdsConfig& c, std::string_view role) {
  if (std::string why = dds_profiles_problem(c); !why.empty()) return why;
  return dds_security_problem(c, role);
}

}  // namespace tgm
