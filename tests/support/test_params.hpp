// Seeds and counts of the seeded tests: `--NAME=N` or `--NAME N` among the test binary's
// arguments (GoogleTest's own `--gtest_*` flags do not collide), else the environment variable,
// else the default. A value that is not a whole number stops the test binary with a message
// naming it: a typo must not quietly run seed 0 or zero programs and pass (env_params.hpp).
// An argument that no test read (a misspelt name, or its test filtered out) is named at the end
// of the run, for the same reason. Header-only; needs GoogleTest.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "env_params.hpp"

namespace tgm::test {

//! The `--name` flags some test has looked up in this run.
inline std::set<std::string>& read_flags() {
  static std::set<std::string> flags;
  return flags;
}

//! At the end of the run: every `--name[=N]` argument no test looked up, named on stderr.
class UnreadFlagsReport : public ::testing::EmptyTestEventListener {
 public:
  void OnTestProgramEnd(const ::testing::UnitTest&) override {
    const std::vector<std::string> args = ::testing::internal::GetArgvs();
    for (std::size_t i = 1; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a.rfind("--", 0) != 0 || a.rfind("--gtest_", 0) == 0) continue;
      const std::string flag = a.substr(0, a.find('='));
      if (read_flags().count(flag) != 0) continue;
      std::fprintf(stderr,
                   "note: no test that ran read %s (a misspelt name, or its test filtered out): "
                   "it changed nothing\n",
                   flag.c_str());
    }
  }
};

inline const bool kUnreadFlagsReportInstalled = [] {
  ::testing::UnitTest::GetInstance()->listeners().Append(new UnreadFlagsReport);
  return true;
}();

//! The value of `--name=V` or `--name V` among the test binary's arguments ("" when the spaced
//! form ends the line), or nothing when the flag is absent. Marks the flag as read.
inline std::optional<std::string> flag_value(const std::string& name) {
  const std::string flag = "--" + name;
  read_flags().insert(flag);
  const std::string prefix = flag + "=";
  const std::vector<std::string> args = ::testing::internal::GetArgvs();
  for (std::size_t i = 0; i < args.size(); ++i) {
    if (args[i].rfind(prefix, 0) == 0) return args[i].substr(prefix.size());
    // The spaced form: without it `--comp-seed 2` ran the default seed and passed.
    if (args[i] == flag) return i + 1 < args.size() ? args[i + 1] : "";
  }
  return std::nullopt;
}

//! `--name=N` or `--name N` among the test binary's arguments, else env_u64(env, fallback).
inline std::uint64_t param_u64(const std::string& name, const char* env, std::uint64_t fallback) {
  if (const std::optional<std::string> v = flag_value(name)) return u64_or_exit(*v, "--" + name);
  return env_u64(env, fallback);
}

}  // namespace tgm::test
