// Seeds and counts of the seeded tests: `--NAME=N` among the arguments GoogleTest left (it
// removes its own flags), else the environment variable, else the default. A value that is not
// a whole number stops the test binary with a message naming it: a typo must not quietly run
// seed 0 or zero programs and pass. Header-only; needs GoogleTest.
#pragma once

#include <gtest/gtest.h>

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

//! `--name=N` among the test binary's arguments, else env_u64(env, fallback).
inline std::uint64_t param_u64(const std::string& name, const char* env, std::uint64_t fallback) {
  const std::string prefix = "--" + name + "=";
  for (const std::string& a : ::testing::internal::GetArgvs()) {
    if (a.rfind(prefix, 0) == 0) return u64_or_exit(a.substr(prefix.size()), "--" + name);
  }
  return env_u64(env, fallback);
}

}  // namespace tgm::test
