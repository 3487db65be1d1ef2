#include <cstdio>

#include "commands.hpp"

namespace tgm::hmi {

int run_compile(int, char**) { return 1; }

}  // namespace tgm::hmi
