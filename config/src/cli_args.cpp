#include "tgm/cli_args.hpp"

#include "tgm/cli_numbers.hpp"
#include "tgm/yaml_config.hpp"

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <new>
#include <system_error>
#include <utility>
#include <vector>

namespace tgm::cli {

namespace {

namespace fs = std::filesystem;

// `a` and `b` would be one file once written: the same existing regular file (through links,
// hard links or different spellings), or the same path where nothing exists yet. An existing
// device, pipe or directory never counts: the first may be shared, the last fails on its own.
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::file_status sa = fs::status(a, ea), sb = fs::status(b, eb);
  const bool has_a = fs::exists(sa), has_b = fs::exists(sb);
  if (has_a && has_b) {
    if (!fs::is_regular_file(sa) || !fs::is_regular_file(sb)) return false;
    std::error_code e;
    return fs::equivalent(a, b, e) && !e;
  }
  if (has_a || has_b) return false;
  const fs::path ca = fs::weakly_canonical(fs::absolute(a, ea), ea);
  const fs::path cb = fs::weakly_canonical(fs::absolute(b, eb), eb);
  return !ea && !eb && ca == cb;
}

}  // namespace

ArgReader::ArgReader(int argc, char** argv, std::string program)
    : argc_(argc), argv_(argv), program_(std::move(program)) {}

bool ArgReader::more() {
  if (!options_ended_ && i_ < argc_ && std::strcmp(argv_[i_], "--") == 0) {
    options_ended_ = true;
    ++i_;
  }
  return i_ < argc_ && !failed_ && !help_;
}

bool ArgReader::flag(const char* name, std::string& value) {
  if (options_ended_) return false;
  const char* arg = argv_[i_];
  const std::size_t n = std::strlen(name);
  if (std::strcmp(arg, name) == 0) {
    if (i_ + 1 >= argc_) {
      ++i_;
      value.clear();
      usage_error(std::string(name) + " needs a value");
      return true;
    }
    value = argv_[i_ + 1];
    i_ += 2;
    // The next flag, the value forgotten: `--handshake-trace --no-events` wrote a file named
    // "--no-events" and left the events on, `--participant-prefix --quiet` joined as
    // "--quiet-plc". A value that does start with "--" is given as NAME=VALUE.
    if (value.rfind("--", 0) == 0) {
      usage_error(std::string(name) + " needs a value, not the flag '" + value +
                  "' (a value that starts with -- is given as " + name + "=VALUE)");
      value.clear();
      return true;
    }
  } else if (std::strncmp(arg, name, n) == 0 && arg[n] == '=') {
    value = arg + n + 1;
    ++i_;
  } else {
    return false;
  }
  // An empty value would read as the flag not given (its default), silently.
  if (value.empty()) usage_error(std::string(name) + " needs a value, not an empty string");
  if (std::find(given_.begin(), given_.end(), name) == given_.end()) {
    given_.emplace_back(name);
  } else if (std::find(repeatable_.begin(), repeatable_.end(), name) == repeatable_.end()) {
    usage_error(std::string(name) + " is given more than once; give it once");
  }
  return true;
}

bool ArgReader::distinct_files(const std::vector<NamedFile>& inputs,
                               const std::vector<NamedFile>& outputs) {
  std::vector<const NamedFile*> seen;  // the inputs, then the outputs checked so far
  for (const NamedFile& f : inputs) {
    if (!f.path.empty()) seen.push_back(&f);
  }
  const std::size_t input_count = seen.size();
  for (const NamedFile& out : outputs) {
    if (out.path.empty()) continue;
    for (std::size_t k = 0; k < seen.size(); ++k) {
      const NamedFile& other = *seen[k];
      // "-" is standard input as an input and standard output as an output: two different
      // streams (`post | tgm-hmi simulate - --csv - | plot` was refused), but one stream for
      // two outputs.
      const bool dash = out.path == "-" || other.path == "-";
      if (dash ? !(out.path == other.path && k >= input_count) : !same_file(out.path, other.path))
        continue;
      usage_error(std::string(out.what) + " '" + out.path + "' is the same file as " + other.what +
                  " '" + other.path + "'" +
                  (k < input_count ? ": writing it would destroy the input"
                                   : ": both outputs would be written into it"));
      return false;
    }
    seen.push_back(&out);
  }
  return true;
}

int run_guarded(const char* program, int (*body)(int, char**), int argc, char** argv) {
  try {
    return body(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: out of memory\n", program);
  } catch (const std::system_error& e) {
    // A thread that cannot start (EAGAIN: memory or the thread limit), a clock, a lock.
    std::fprintf(stderr, "%s: the system refused: %s\n", program, e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: internal error: %s\n", program, e.what());
  }
  return 1;
}

void prefer_heap_for_large_blocks() {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest on 64-bit
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
}

ArgReader::NamedFile ArgReader::config_file(const std::string& config_flag) {
  return config_flag.empty() ? NamedFile{"the default config", default_config_path()}
                             : NamedFile{"--config", config_flag};
}

bool ArgReader::boolean(const char* name, bool& value) {
  if (options_ended_) return false;
  const char* arg = argv_[i_];
  const std::size_t n = std::strlen(name);
  if (std::strncmp(arg, name, n) != 0 || (arg[n] != '\0' && arg[n] != '=')) return false;
  ++i_;
  if (arg[n] == '=') {
    usage_error(std::string(name) + " takes no value");
    return true;
  }
  value = true;
  return true;
}

bool ArgReader::whole_flag(const char* name, long long lo, long long hi, long long& out) {
  std::string text;
  if (!flag(name, text)) return false;
  if (!failed_ && !parse_integer(text, lo, hi, out)) {
    usage_error(std::string(name) + " must be " + std::to_string(lo) + ".." + std::to_string(hi) +
                ", not '" + text + "'");
  }
  return true;
}

bool ArgReader::whole_flag(const char* name, int lo, int hi, int& out) {
  long long v = out;
  if (!whole_flag(name, static_cast<long long>(lo), static_cast<long long>(hi), v)) return false;
  if (!failed_) out = static_cast<int>(v);
  return true;
}

bool ArgReader::number_flag(const char* name, double& out, const char* what, bool (*ok)(double)) {
  std::string text;
  if (!flag(name, text)) return false;
  double v = 0.0;
  if (failed_) return true;
  if (!parse_finite(text, v) || !ok(v)) {
    usage_error(std::string(name) + " must be " + what + ", not '" + text + "'");
  } else {
    out = v;
  }
  return true;
}

const char* version() {
  return TGM_VERSION;
}

bool ArgReader::version_flag() {
  if (options_ended_) return false;
  if (std::strcmp(argv_[i_], "--version") != 0) return false;
  ++i_;
  return true;
}

bool ArgReader::help_flag() {
  if (options_ended_) return false;
  const char* arg = argv_[i_];
  if (std::strcmp(arg, "--help") != 0 && std::strcmp(arg, "-h") != 0) return false;
  help_ = true;
  ++i_;
  return true;
}

bool ArgReader::positional(std::string& value) {
  const char* arg = argv_[i_];
  if (!value.empty() || (!options_ended_ && arg[0] == '-' && arg[1] != '\0')) return false;
  value = arg;
  ++i_;
  return true;
}

bool ArgReader::negative_number(std::string& value) {
  const char* arg = argv_[i_];
  if (arg[0] != '-' || arg[1] == '\0' ||
      std::strspn(arg + 1, "0123456789") != std::strlen(arg + 1)) {
    return false;
  }
  value = arg;
  ++i_;
  return true;
}

bool ArgReader::dds_flag(DdsOverrides& o) {
  for (const char* name : {"--domain", "--profiles", "--participant-prefix", "--security"}) {
    std::string v;
    if (!flag(name, v)) continue;
    if (std::string error; !failed_ && o.take(name, v, error) && !error.empty()) usage_error(error);
    return true;
  }
  return false;
}

int ArgReader::fail() {
  const char* arg = argv_[i_];
  ++i_;
  if (!options_ended_ && arg[0] == '-' && arg[1] != '\0')
    return usage_error(std::string("unknown option '") + arg + "'");
  return usage_error(std::string("unexpected argument '") + arg + "'");
}

int ArgReader::usage_error(const std::string& reason) {
  if (!failed_) {
    std::fprintf(stderr, "%s: %s\n(see %s --help)\n", program_.c_str(), reason.c_str(),
                 program_.c_str());
  }
  failed_ = true;
  return 2;
}

}  // namespace tgm::cli
