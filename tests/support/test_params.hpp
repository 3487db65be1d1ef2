// Seeds and counts of the seeded tests: `--NAME=N` or `--NAME N` among the arguments GoogleTest
// left (it removes its own flags), else the environment variable, else the default. A value that is
// not a whole number stops the test binary with a message naming it: a typo must not quietly run
// seed 0 or zero programs and pass (env_params.hpp). Header-only; needs GoogleTest.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "env_params.hpp"

namespace tgm::test {

//! `--name=N` or `--name N` among the test binary's arguments, else env_u64(env, fallback).
inline std::uint64_t param_u64(const std::string& name, const char* env, std::uint64_t fallback) {
  const std::string flag = "--" + name;
  const std::string prefix = flag + "=";
  const std::vector<std::string> args = ::testing::internal::GetArgvs();
  for (std::size_t i = 0; i < args.size(); ++i) {
    if (args[i].rfind(prefix, 0) == 0) return u64_or_exit(args[i].substr(prefix.size()), flag);
    // The spaced form: without it `--comp-seed 2` ran the default seed and passed.
    if (args[i] == flag) return u64_or_exit(i + 1 < args.size() ? args[i + 1] : "", flag);
  }
  return env_u64(env, fallback);
}

}  // namespace tgm::test
