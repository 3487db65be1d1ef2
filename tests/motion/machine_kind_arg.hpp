// `--machines=random|wide|box` on the command line of a sweep's test binary: which machines its
// cases draw (test::random_machine, wide_machine, box_machine; default random). Any other value
// stops the binary with a message, as a mistyped seed does (test_params.hpp).
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "random_program.hpp"

namespace tgm::test {

inline MachineKind machine_kind_arg() {
  for (const std::string& a : ::testing::internal::GetArgvs()) {
    if (a.rfind("--machines=", 0) != 0) continue;
    MachineKind kind;
    if (machine_kind_from_name(std::string_view(a).substr(11), kind)) return kind;
    std::fprintf(stderr, "--machines must be wide, box or random, not '%s'\n", a.c_str() + 11);
    std::exit(2);
  }
  return MachineKind::kRandom;
}

}  // namespace tgm::test
