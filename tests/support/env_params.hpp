// Whole numbers from the environment for test and fuzz binaries: a value that is not a whole
// number stops the binary with a message naming it, so a typo never quietly runs seed 0.
// Header-only, no GoogleTest (the libFuzzer targets use it too; test_params.hpp adds the
// `--name=N` arguments of the GoogleTest binaries).
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace tgm::test {

//! `text` as a base-10 whole number >= 0, or exit(2) with a message naming `what`.
inline std::uint64_t u64_or_exit(const std::string& text, const std::string& what) {
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (text.empty() || text[0] == '-' || errno != 0 || *end != '\0') {
    std::fprintf(stderr, "%s must be a whole number >= 0, not '%s'\n", what.c_str(), text.c_str());
    std::exit(2);
  }
  return v;
}

//! $`env` when set and not empty, else `fallback`.
inline std::uint64_t env_u64(const char* env, std::uint64_t fallback) {
  const char* v = std::getenv(env);
  if (v == nullptr || *v == '\0') return fallback;
  return u64_or_exit(v, env);
}

}  // namespace tgm::test
