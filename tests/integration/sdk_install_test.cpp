// The SDK as a third party gets it: `cmake --install` to a prefix of its own, then the example
// PLC (client/examples/minimal_plc) configured and built outside tgm's tree with
// find_package(tgm COMPONENTS client) alone, and run as the PLC of a real tgm-service while
// tgm-hmi runs a program with a normal and a continuous M-function.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "service_test_env.hpp"

namespace {

using namespace std::chrono_literals;

// Flags the external project needs to link this build's static libraries: a sanitizer build's
// objects call the sanitizers' runtime.
std::string sanitizer_flags() {
  const std::string s = TGM_SANITIZE;
  if (s.empty()) return "";
  const std::string f = "-fsanitize=" + s;
  return " '-DCMAKE_CXX_FLAGS=" + f + "' '-DCMAKE_EXE_LINKER_FLAGS=" + f + "'";
}

TEST(SdkInstall, AnExternalProjectBuildsAPlcThatHandlesTheHandshake) {
  const std::string dir = testing::TempDir() + "tgm-sdk-" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string prefix = dir + "/prefix", build = dir + "/build";
  const tgm::test::ShellRun install = tgm::test::run_shell(
      std::string(TGM_CMAKE) + " --install " + TGM_BUILD_DIR + " --prefix " + prefix, dir,
      "install");
  ASSERT_EQ(install.exit_code, 0) << install.out << install.err;
  for (const char* f :
       {"lib/cmake/tgm/tgmConfig.cmake", "lib/cmake/tgm/tgmConfigVersion.cmake",
        "lib/libtgm_client.a", "include/tgm/client/client.hpp", "include/tgm/msg/tgm.h"}) {
    EXPECT_TRUE(std::filesystem::exists(prefix + "/" + f)) << f << " is not installed";
  }

  // Configured with the prefix only: nothing of tgm's source or build tree is on any path.
  const tgm::test::ShellRun configure = tgm::test::run_shell(
      std::string(TGM_CMAKE) + " -S " + TGM_SOURCE_DIR "/client/examples/minimal_plc -B " + build +
          " -DCMAKE_PREFIX_PATH=" + prefix + sanitizer_flags(),
      dir, "configure");
  ASSERT_EQ(configure.exit_code, 0) << configure.out << configure.err;
  const tgm::test::ShellRun compile =
      tgm::test::run_shell(std::string(TGM_CMAKE) + " --build " + build + " -j2", dir, "build");
  ASSERT_EQ(compile.exit_code, 0) << compile.out << compile.err;
  const std::string plc_bin = build + "/tgm-minimal-plc";

  // The service's start waits for the PLC's setup report, as on a machine.
  tgm::test::ConfigEdits edits;
  edits.plc_setup_before_start = true;
  tgm::test::ServiceEnv env(edits);

  // No service yet: said, and exit code 1 (not a hang).
  tgm::test::Child lonely;
  ASSERT_TRUE(
      lonely.start({plc_bin, "--config", env.config(), "--wait", "1"}, env.path("lonely.log")));
  EXPECT_EQ(lonely.wait(30s), 1) << lonely.log();
  EXPECT_NE(lonely.log().find("no state of interpolator 0"), std::string::npos) << lonely.log();

  ASSERT_TRUE(env.start_service());
  tgm::test::Child plc;
  ASSERT_TRUE(
      plc.start({plc_bin, "--config", env.config(), "--ack-delay", "0.3"}, env.path("plc.log")));
  ASSERT_TRUE(plc.wait_for_log("interpolator 2: setup reported", 30s))
      << plc.log() << env.service.log();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NE(plc.log().find("interpolator " + std::to_string(i) + ": setup reported: accepted"),
              std::string::npos)
        << plc.log();
  }

  std::ofstream(env.path("m.ngc")) << "G90\nG1 X5 F3000\nM7 S1200 T3\nG1 X10\nM1005\nG1 X15\nM2\n";
  tgm::test::Child hmi;
  ASSERT_TRUE(hmi.start({TGM_HMI_BIN, "run", env.path("m.ngc"), "--config", env.config()},
                        env.path("hmi.log")));
  ASSERT_EQ(hmi.wait(60s), 0) << hmi.log() << plc.log() << env.service.log();
  EXPECT_NE(hmi.log().find("end position X15.0000"), std::string::npos) << hmi.log();
  // One wait (M7): the continuous M1005 does not stop the motion. It lasted the PLC's delay.
  // (No <regex>: GCC 12 warns inside it in the AddressSanitizer build.)
  const std::string hmi_log = hmi.log();
  const std::string waits = "1 M-function wait (";
  const auto w = hmi_log.find(waits);
  ASSERT_NE(w, std::string::npos) << hmi_log;
  const double waited = std::strtod(hmi_log.c_str() + w + waits.size(), nullptr);
  EXPECT_GE(waited, 0.28) << hmi_log;
  EXPECT_LT(waited, 3.0) << hmi_log;

  ASSERT_TRUE(plc.wait_for_log("M1005 acknowledged", 10s)) << plc.log();
  // A restarted service (a new instance) gets the setup report again.
  ASSERT_EQ(env.service.interrupt(), 0) << env.service.log();
  ASSERT_TRUE(env.start_service());
  const auto reports = [&] {
    return tgm::test::count_of(plc.log(), "interpolator 0: setup reported: accepted");
  };
  for (int k = 0; k < 600 && reports() < 2; ++k) std::this_thread::sleep_for(50ms);
  EXPECT_EQ(reports(), 2) << plc.log() << env.service.log();
  EXPECT_EQ(plc.interrupt(10s, SIGTERM), 0) << plc.log();
  const std::string log = plc.log();
  const auto at = [&](const std::string& text) {
    const auto p = log.find(text);
    EXPECT_NE(p, std::string::npos) << "'" << text << "' missing:\n" << log;
    return p;
  };
  const auto m7 = at("interpolator 0: M7 (line 3, S=1200 T=3) normal: the interpolator waits");
  const auto m7_ack = at("interpolator 0: M7 acknowledged: accepted");
  const auto m1005 = at("interpolator 0: M1005 (line 5) continuous: motion goes on");
  const auto m1005_ack = at("interpolator 0: M1005 acknowledged: accepted");
  EXPECT_LT(m7, m7_ack);
  EXPECT_LT(m7_ack, m1005);
  EXPECT_LT(m1005, m1005_ack);
  // Each once, though the event topic and the state both show them.
  EXPECT_EQ(log.find(": M7 (", m7_ack), std::string::npos) << log;
  EXPECT_EQ(log.find(": M1005 (", m1005_ack), std::string::npos) << log;
  EXPECT_NE(log.find("stopped"), std::string::npos) << log;
  if (!testing::Test::HasFailure()) std::filesystem::remove_all(dir);
}

}  // namespace
