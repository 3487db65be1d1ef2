// `--machines=random|wide|box` (or `--machines wide`) on the command line of a sweep's test binary:
// which machines its cases draw (test::random_machine, wide_machine, box_machine; default random).
// Any other value stops the binary with a message, as a mistyped seed does (test_params.hpp).
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>

#include "../support/test_params.hpp"
#include "random_program.hpp"

namespace tgm::test {

inline MachineKind machine_kind_arg() {
  const std::optional<std::string> value = flag_value("machines");
  if (!value) return MachineKind::kRandom;
  MachineKind kind;
  if (machine_kind_from_name(*value, kind)) return kind;
  std::fprintf(stderr, "--machines must be wide, box or random, not '%s'\n", value->c_str());
  std::exit(2);
}

}  // namespace tgm::test
