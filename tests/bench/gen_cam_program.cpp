// tgm_gen_cam_program: writes the CAM-like benchmark program (see gen/cam_program.hpp).
//
//   tgm_gen_cam_program [--lines N] [--seed S] [--incremental] [-o FILE]
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "gen/cam_program.hpp"

int main(int argc, char** argv) {
  long lines = 1'000'000;
  unsigned long long seed = 1;
  bool incremental = false;
  const char* path = nullptr;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (std::strcmp(argv[i], "--lines") == 0 && has_value) {
      lines = std::strtol(argv[++i], nullptr, 0);
    } else if (std::strcmp(argv[i], "--seed") == 0 && has_value) {
      seed = std::strtoull(argv[++i], nullptr, 0);
    } else if (std::strcmp(argv[i], "--incremental") == 0) {
      incremental = true;
    } else if (std::strcmp(argv[i], "-o") == 0 && has_value) {
      path = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: tgm_gen_cam_program [--lines N] [--seed S] [--incremental] [-o FILE]\n");
      return 2;
    }
  }
  std::string text;
  tgm::bench::generate_cam_program(text, lines, seed, incremental);
  FILE* f = path != nullptr ? std::fopen(path, "wb") : stdout;
  if (f == nullptr) {
    std::perror(path);
    return 1;
  }
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (path != nullptr && std::fclose(f) != 0) return 1;
  return ok ? 0 : 1;
}
