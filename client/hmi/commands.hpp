// Subcommands of tgm-hmi. Each returns the process exit code: 0 success, 1 runtime failure,
// 2 bad input (usage, config, G-code).
#pragma once

namespace tgm::hmi {

//! `tgm-hmi compile FILE [--config YAML] [--dump jsonl|text] [--out FILE]`
int run_compile(int argc, char** argv);

//! `tgm-hmi simulate FILE [--config YAML] [--interpolator N] [--csv OUT] [--rel-speed R]
//! [--check-limits]`
int run_simulate(int argc, char** argv);

#ifdef TGM_HMI_DDS
//! DDS subcommands (hmi/dds/): `run FILE`, `status`, `watch`, `stop`, `command WHAT`.
int run_run(int argc, char** argv);
int run_status(int argc, char** argv);
int run_watch(int argc, char** argv);
int run_stop(int argc, char** argv);
int run_command(int argc, char** argv);
#endif

}  // namespace tgm::hmi
