#include <cstdio>

#include "commands.hpp"

namespace tgm::hmi {

int run_simulate(int /*argc*/, char** /*argv*/) {
  std::fprintf(stderr, "tgm-hmi simulate: not built yet\n");
  return 1;
}

}  // namespace tgm::hmi
