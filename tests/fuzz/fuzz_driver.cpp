// Plain driver for the fuzz targets, for compilers without libFuzzer (and for a short,
// deterministic run in CTest): runs LLVMFuzzerTestOneInput over the seed files, their
// truncations, and a fixed-seed stream of mutated and random inputs.
//
//   DRIVER [--seed N] [--runs N] [--max-len N] [--crash-file PATH] [--write-seeds DIR]
//          FILE_OR_DIR...
//
// On a crash or failed check the input being run is written to --crash-file (default
// ./fuzz-crash-input) by the signal handler; rerun the libFuzzer binary or this driver on it.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "tgm/cli_args.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

namespace fs = std::filesystem;

// The input being run, for the crash handler.
const char* g_input = nullptr;
std::size_t g_input_size = 0;
char g_crash_file[4096] = "fuzz-crash-input";

extern "C" void on_crash(int sig) {
  const int fd = ::open(g_crash_file, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0 && g_input != nullptr) {
    std::size_t done = 0;
    while (done < g_input_size) {
      const ssize_t w = ::write(fd, g_input + done, g_input_size - done);
      if (w <= 0) break;
      done += static_cast<std::size_t>(w);
    }
  }
  if (fd >= 0) ::close(fd);
  static const char msg[] = "fuzz driver: crash; the input was written to the crash file\n";
  (void)!::write(2, msg, sizeof msg - 1);
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

using tgm::fuzz::Rng;

// Pieces of G-code and of trouble, inserted by the mutator (also in gcode.dict for libFuzzer);
// a target may replace them (prepare_tokens: the YAML targets).
constexpr const char* kGcodeTokens[] = {
    "G0 ",
    "G1 ",
    "G2 ",
    "G3 ",
    "G4 P",
    "G17",
    "G18",
    "G19",
    "G21",
    "G20",
    "G25 L",
    "G26 L",
    " K",
    "G27 L",
    "G29 L",
    "G29 (note)",
    "G40",
    "G41 D",
    "G42",
    "G53",
    "G54 X",
    "G90",
    "G91",
    "G92 X",
    "M0",
    "M2",
    "M17",
    "M29 (",
    "M30",
    "M80",
    "M84",
    "M99 F",
    "M1001",
    "M51 A1 B",
    "T1",
    "X",
    "Y",
    "Z",
    "A",
    "B",
    "C",
    "U",
    "V",
    "W",
    "E",
    "I",
    "J",
    "K",
    "R-",
    "F",
    "N",
    "L",
    "P",
    "(",
    ")",
    ";",
    "\n",
    "\r\n",
    " ",
    "-.",
    "+1.",
    "1e308",
    "nan",
    "inf",
    "-0",
    "99999999999999999999",
    "0.00000000000000000001",
    "1.7976931348623157e308",
    "4294967296",
    "-2147483649",
    "\t",
    "\0",
    "\xff",
    "%",
};

std::string random_bytes(Rng& r, std::size_t n, bool printable) {
  static constexpr char kAlphabet[] = "GMXYZIJKRFNLPTD0123456789.-+ ()\n;";
  std::string s(n, ' ');
  for (char& c : s) {
    c = printable ? kAlphabet[r.below(sizeof kAlphabet - 1)] : static_cast<char>(r.next());
  }
  return s;
}

void mutate(Rng& r, std::string& s, const std::vector<std::string>& seeds,
            const std::vector<std::string>& tokens, std::size_t max_len) {
  const int n = 1 + static_cast<int>(r.below(4));
  for (int k = 0; k < n; ++k) {
    const std::size_t at = r.below(s.size() + 1);
    switch (r.below(8)) {
      case 0:  // truncate
        s.resize(at);
        break;
      case 1:  // flip a bit
        if (!s.empty()) s[r.below(s.size())] ^= static_cast<char>(1u << r.below(8));
        break;
      case 2:  // overwrite a byte
        if (!s.empty()) s[r.below(s.size())] = static_cast<char>(r.next());
        break;
      case 3: {  // insert a token
        s.insert(at, tokens[r.below(tokens.size())]);
        break;
      }
      case 4:  // erase a range
        s.erase(at, r.below(16) + 1);
        break;
      case 5: {  // duplicate a range (loops, repeated labels)
        const std::size_t len = std::min(s.size() - std::min(at, s.size()), r.below(64) + 1);
        s.insert(at, s.substr(at, len));
        break;
      }
      case 6: {  // splice in a piece of another seed
        const std::string& o = seeds[r.below(seeds.size())];
        const std::size_t from = r.below(o.size() + 1);
        s.insert(at, o.substr(from, r.below(128) + 1));
        break;
      }
      default:  // random printable run
        s.insert(at, random_bytes(r, r.below(8) + 1, true));
        break;
    }
  }
  if (s.size() > max_len) s.resize(max_len);
}

void run(const std::string& s) {
  g_input = s.data();
  g_input_size = s.size();
  LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(s.data()), s.size());
}

std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

int main(int argc, char** argv) {
  // Whole numbers only: '--runs 1e5' must not quietly run one input, '--seed x' seed 0.
  long long seed = 1;
  long long runs = 10000;
  long long max_len = 4096;
  std::string crash_file, write_seeds;
  std::vector<fs::path> files;
  tgm::cli::ArgReader args(argc, argv, fs::path(argv[0]).filename().string());
  while (args.more()) {
    if (args.help_flag()) {
      std::puts(
          "usage: DRIVER [--seed N] [--runs N] [--max-len N] [--crash-file PATH]\n"
          "              [--write-seeds DIR] FILE_OR_DIR...");
      return 0;
    }
    if (args.whole_flag("--seed", 0LL, INT64_MAX, seed) ||
        args.whole_flag("--runs", 0LL, 1'000'000'000'000LL, runs) ||
        args.whole_flag("--max-len", 1LL, 1LL << 30, max_len) ||
        args.flag("--crash-file", crash_file) || args.flag("--write-seeds", write_seeds)) {
      continue;
    }
    std::string arg;
    if (!args.positional(arg)) return args.fail();
    const fs::path p(arg);
    if (fs::is_directory(p)) {
      std::vector<fs::path> in;
      for (const auto& e : fs::directory_iterator(p)) {
        if (e.is_regular_file()) in.push_back(e.path());
      }
      std::sort(in.begin(), in.end());
      files.insert(files.end(), in.begin(), in.end());
    } else if (fs::is_regular_file(p)) {
      files.push_back(p);
    } else {
      return args.usage_error("no such file or directory: " + arg);
    }
  }
  if (args.failed()) return 2;
  if (!crash_file.empty())
    std::snprintf(g_crash_file, sizeof g_crash_file, "%s", crash_file.c_str());
  for (int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL}) std::signal(sig, on_crash);

  std::vector<std::string> seeds;
  for (const fs::path& f : files) seeds.push_back(read_file(f));
  tgm::fuzz::prepare_seeds(seeds);
  std::vector<std::string> tokens;
  for (const char* t : kGcodeTokens) tokens.push_back(t[0] == '\0' ? std::string(1, '\0') : t);
  tgm::fuzz::prepare_tokens(tokens);
  if (tokens.empty()) tokens.emplace_back(" ");
  if (seeds.empty()) seeds.emplace_back();
  if (!write_seeds.empty()) {
    fs::create_directories(write_seeds);
    for (std::size_t k = 0; k < seeds.size(); ++k) {
      std::ofstream(fs::path(write_seeds) / ("seed-" + std::to_string(k)), std::ios::binary)
          << seeds[k];
    }
  }

  long executed = 0;
  std::size_t bytes = 0;
  const auto go = [&](const std::string& s) {
    run(s);
    ++executed;
    bytes += s.size();
  };
  // 1. Seeds as they are, and cut at 32 places each plus the last 8 bytes one by one.
  for (const std::string& s : seeds) {
    go(s);
    for (std::size_t k = 1; k < 32; ++k) go(s.substr(0, s.size() * k / 32));
    for (std::size_t k = 1; k <= 8 && k <= s.size(); ++k) go(s.substr(0, s.size() - k));
  }
  // 2. Mutated seeds and random strings from a fixed seed.
  Rng r{{static_cast<std::uint64_t>(seed)}};
  for (long long k = 0; k < runs; ++k) {
    std::string s;
    switch (r.below(10)) {
      case 0:
        s = random_bytes(r, r.below(256), false);
        break;
      case 1:
        s = random_bytes(r, r.below(512), true);
        break;
      default:
        s = seeds[r.below(seeds.size())];
        mutate(r, s, seeds, tokens, static_cast<std::size_t>(max_len));
        break;
    }
    go(s);
  }
  std::printf("fuzz driver: %ld inputs (%zu seeds, seed %llu), %zu bytes, no crash\n", executed,
              seeds.size(), static_cast<unsigned long long>(seed), bytes);
  return 0;
}
