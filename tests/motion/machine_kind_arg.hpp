// `--machines=random|wide|box` (or `--machines wide`) on the command line of a sweep's test binary:
// which machines its cases draw (test::random_machine, wide_machine, box_machine; default random).
// Any other value stops the binary with a message, as a mistyped seed does (test_params.hpp).
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "../support/test_params.hpp"
#include "random_program.hpp"

namespace tgm::test {

inline MachineKind machine_kind_arg() {
  read_flags().insert("--machines");
  const std::vector<std::string> args = ::testing::internal::GetArgvs();
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string value;
    if (args[i].rfind("--machines=", 0) == 0) {
      value = args[i].substr(11);
    } else if (args[i] == "--machines") {  // the spaced form, as test_params.hpp takes it
      value = i + 1 < args.size() ? args[i + 1] : "";
    } else {
      continue;
    }
    MachineKind kind;
    if (machine_kind_from_name(value, kind)) return kind;
    std::fprintf(stderr, "--machines must be wide, box or random, not '%s'\n", value.c_str());
    std::exit(2);
  }
  return MachineKind::kRandom;
}

}  // namespace tgm::test
