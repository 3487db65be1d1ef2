// Seeds and counts of the seeded tests: `--NAME=N` among the arguments GoogleTest left (it
// removes its own flags), else the environment variable, else the default. A value that is not
// a whole number stops the test binary with a message naming it: a typo must not quietly run
// seed 0 or zero programs and pass (env_params.hpp). Header-only; needs GoogleTest.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "env_params.hpp"

namespace tgm::test {

//! `--name=N` among the test binary's arguments, else env_u64(env, fallback).
inline std::uint64_t param_u64(const std::string& name, const char* env, std::uint64_t fallback) {
  const std::string prefix = "--" + name + "=";
  for (const std::string& a : ::testing::internal::GetArgvs()) {
    if (a.rfind(prefix, 0) == 0) return u64_or_exit(a.substr(prefix.size()), "--" + name);
  }
  return env_u64(env, fallback);
}

}  // namespace tgm::test
