// tgm-hmi: the operator client of the tgm motion service.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "cli_common.hpp"
#include "commands.hpp"
#include "tgm/cli_args.hpp"

namespace {

constexpr const char* kUsage =
    "usage: tgm-hmi COMMAND [ARGS]\n"
    "\n"
    "Commands:\n"
    "  compile FILE   compile G-code to intercode (--dump jsonl|text, --out FILE)\n"
    "  simulate FILE  run a program offline through the interpolator (--csv writes a CSV)\n"
#ifdef TGM_HMI_DDS
    "  run FILE       stream a program to tgm-service, start it, follow it (--plot OUT.svg)\n"
    "  status         print the registers of an interpolator once\n"
    "  watch          follow the registers\n"
    "  stop           normal stop on the trajectory\n"
    "  command WHAT   start, stop, clear, estop, ... or a Command code with parameters\n"
    "\n"
    "The commands over DDS take the DDS overrides of the config's dds section:\n"
    "  --domain N, --profiles FILE, --participant-prefix P, --security DIR (DDS Security\n"
    "  material of tgm-security; 'off' runs without)\n"
#endif
    "\n"
    "Every command takes --config YAML (default: $TGM_CONFIG, the installed or the in-tree\n"
    "config/default.yaml) and --help (or: tgm-hmi help COMMAND); -- ends the options, so\n"
    "a file whose name starts with - can follow it;\n"
    "tgm-hmi --version prints the version.\n";

}  // namespace

namespace {

using Subcommand = int (*)(int, char**);

// The subcommand named `cmd`, or nullptr.
Subcommand subcommand(std::string_view cmd) {
  if (cmd == "compile") return tgm::hmi::run_compile;
  if (cmd == "simulate") return tgm::hmi::run_simulate;
#ifdef TGM_HMI_DDS
  if (cmd == "run") return tgm::hmi::run_run;
  if (cmd == "status") return tgm::hmi::run_status;
  if (cmd == "watch") return tgm::hmi::run_watch;
  if (cmd == "stop") return tgm::hmi::run_stop;
  if (cmd == "command") return tgm::hmi::run_command;
#endif
  return nullptr;
}

int run_command(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  const std::string_view cmd = argv[1];
  // `help COMMAND` is `COMMAND --help`, as in git.
  if (cmd == "help" && argc == 3) {
    const Subcommand sub = subcommand(argv[2]);
    if (sub == nullptr) {
      std::fprintf(stderr, "tgm-hmi help: unknown command '%s'\n\n%s", argv[2], kUsage);
      return 2;
    }
    char help[] = "--help";
    char* sub_argv[] = {argv[2], help, nullptr};
    return sub(2, sub_argv);
  }
  if (cmd == "help" && argc > 3) {
    std::fprintf(stderr, "tgm-hmi help: takes one command, not '%s' after '%s'\n", argv[3],
                 argv[2]);
    return 2;
  }
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (cmd == "--version") {
    std::printf("tgm-hmi %s\n", tgm::cli::version());
    return 0;
  }
  // Subcommands see argv starting at their own name.
  if (const Subcommand sub = subcommand(cmd)) return sub(argc - 1, argv + 1);
  std::fprintf(stderr, "tgm-hmi: unknown command '%s'\n\n%s", argv[1], kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // compile and simulate: a few large blocks (the program, the record ring) that reuse the
  // pages of each other rather than fault in fresh ones.
  tgm::cli::prefer_heap_for_large_blocks();
  // What escapes a subcommand (memory running out on a huge input) ends with words and exit 1.
  const int code = tgm::cli::run_guarded("tgm-hmi", run_command, argc, argv);
  // What went to standard output (a summary, a dump, a CSV on stdout) must have arrived: a full
  // disk or a closed pipe is an error, not exit code 0 with the output lost.
  // errno names the cause only when this flush failed; an earlier write's errno is gone.
  // A subcommand that reported its own failed write (with what it was writing) is not repeated.
  const bool flush_failed = std::fflush(stdout) != 0;
  if ((flush_failed || std::ferror(stdout)) && !tgm::hmi::stdout_failure_reported()) {
    std::fprintf(stderr, "tgm-hmi: cannot write standard output%s%s\n", flush_failed ? ": " : "",
                 flush_failed ? std::strerror(errno) : "");
    return code != 0 ? code : 1;
  }
  return code;
}
