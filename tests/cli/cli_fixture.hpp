// Runs tgm-hmi as a user does: a fresh directory per test, the command through the shell with
// standard output and error captured in files, the exit code.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace tgm::test {

namespace fs = std::filesystem;

struct ProcessResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tgm_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

  //! `tgm-hmi ARGS`, waited for; `shell_before` runs first in the same shell (e.g. a ulimit);
  //! standard input is `stdin_from` (default: /dev/null).
  ProcessResult run(const std::string& args, const std::string& shell_before = "",
                    const std::string& stdin_from = "/dev/null") {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string cmd = shell_before + std::string(TGM_HMI) + " " + args + " >" + out.string() +
                            " 2>" + err.string() + " <" + stdin_from;
    const int status = std::system(cmd.c_str());
    ProcessResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  fs::path dir_;
};

inline const char* const kDefaultConfig = TGM_SOURCE_DIR "/config/default.yaml";
inline const char* const kManualExample = TGM_SOURCE_DIR "/tests/programs/manual_example.ngc";

}  // namespace tgm::test
