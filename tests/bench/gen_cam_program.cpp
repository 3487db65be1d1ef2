// tgm_gen_cam_program: writes the CAM-like benchmark program (see gen/cam_program.hpp).
//
//   tgm_gen_cam_program [--lines N] [--seed S] [--incremental] [-o FILE]
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "gen/cam_program.hpp"
#include "tgm/cli_args.hpp"

namespace {
constexpr const char* kUsage =
    "usage: tgm_gen_cam_program [--lines N] [--seed S] [--incremental] [-o FILE]\n"
    "Writes the CAM-like benchmark program (random short G1 chords and arcs) to FILE or stdout.\n"
    "  --lines N       lines, 8..100000000 (default 1000000)\n"
    "  --seed S        random seed, 0..2^63 (default 1); the same seed writes the same program\n"
    "  --incremental   G91 (incremental) coordinates instead of G90\n"
    "  -o FILE         output file (default: standard output)\n";
}  // namespace

int main(int argc, char** argv) {
  long long lines = 1'000'000;
  long long seed = 1;
  bool incremental = false;
  std::string path;
  tgm::cli::ArgReader args(argc, argv, "tgm_gen_cam_program");
  while (args.more()) {
    if (args.help_flag()) {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (args.whole_flag("--lines", 8LL, 100'000'000LL, lines) ||
        args.whole_flag("--seed", 0LL, INT64_MAX, seed) ||
        args.boolean("--incremental", incremental) || args.flag("-o", path)) {
      continue;
    }
    return args.fail();
  }
  if (args.failed()) return 2;
  std::string text;
  tgm::bench::generate_cam_program(text, static_cast<long>(lines), static_cast<std::uint64_t>(seed),
                                   incremental);
  FILE* f = path.empty() ? stdout : std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    std::fprintf(stderr, "tgm_gen_cam_program: cannot write %s: %s\n", path.c_str(),
                 std::strerror(errno));
    return 1;
  }
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (!path.empty() && std::fclose(f) != 0) ok = false;
  if (!ok)
    std::fprintf(stderr, "tgm_gen_cam_program: write error on %s\n",
                 path.empty() ? "stdout" : path.c_str());
  return ok ? 0 : 1;
}
