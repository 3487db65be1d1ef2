// Shared by the tgm-hmi subcommands that talk to tgm-service over DDS.
#pragma once

#include <atomic>
#include <optional>
#include <string>

#include "cli_common.hpp"
#include "tgm/client/client.hpp"
#include "tgm/dds_overrides.hpp"

namespace tgm::hmi {

//! Set by SIGINT / SIGTERM once install_signal_flag() ran.
extern std::atomic<bool> g_interrupted;
//! What SIGHUP (the terminal or the SSH session closed) does: end the command as SIGINT does,
//! or nothing.
enum class Hangup { kInterrupt, kIgnore };
//! For the commands that follow a running interpolator (run, watch): SIGINT and SIGTERM set
//! g_interrupted, and SIGPIPE is ignored, so that a reader of standard output that goes away
//! (`tgm-hmi run prog.ngc | head`) no longer kills the process: `run` then follows and streams on
//! (it died and left the program to run dry in an underrun), `watch` ends cleanly. `run` ignores
//! SIGHUP for the same reason: a dropped SSH session killed it half-way through the program.
void install_signal_flag(Hangup hangup);

//! Loads the config, applies the overrides and creates an HMI client; prints why not.
//! Returns the exit code on failure (2 config, 1 DDS), 0 on success.
int make_client(Args& args, const DdsOverrides& o, std::optional<AppConfig>& config,
                std::optional<client::Client>& c, const client::ClientOptions& options = {});

//! How long status, watch and run wait for the service's state by default [s].
inline constexpr double kServiceWaitS = 10.0;

//! Waits for the state of `interpolator`; prints a clear error when there is none. Returns the
//! exit code: 0 with the state, 1 without it, 130 when interrupted (g_interrupted) first.
int wait_for_service(client::Client& c, const AppConfig& config, int interpolator,
                     const char* command, double wait_s = kServiceWaitS);
//! Waits while the state of `interpolator` shows that the service wants the PLC's setup
//! first (InterpolatorState.plc_setup 1): 0 once it does not, 1 after `wait_s` with the
//! reason printed, 130 on Ctrl-C.
int wait_for_plc_setup(client::Client& c, int interpolator, const char* command, double wait_s);

//! What status and watch say when !client::same_machine(s, config.machine, ip) ("interpolator 0:
//! the service's machine config is not FILE (...)"); empty when it is the same.
std::string machine_mismatch(const msg::InterpolatorState& s, const AppConfig& config, int ip);

//! The registers of one interpolator as readable lines, the axes named by the service's
//! letters (`config_letters` when the state has none).
std::string format_state(const msg::InterpolatorState& s, const std::string& config_letters);
//! The same as one line of JSON (JSON Lines): the IDL's field names, units in the key where
//! the register has one, per-axis values keyed by letter, not-finite numbers as null.
//! `age_s` >= 0: written as "state_age_s", the time since the state arrived [s] (watch: a
//! service that stopped publishing leaves its last state, and a script sees it age).
std::string format_state_json(const msg::InterpolatorState& s, const std::string& config_letters,
                              double age_s = -1.0);

}  // namespace tgm::hmi
