// tgm-hmi status --json and watch --json: one JSON object per line on standard output, read
// back here with yaml-cpp (JSON is YAML's flow style), so that scripts and monitoring can
// rely on the keys and on the values matching the registers.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "service_test_env.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/dds/topics.hpp"
#include "tgm/msg/tgm.h"
#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm {
namespace {

using namespace std::chrono_literals;
constexpr auto kHang = 60s;

// Runs tgm-hmi with `args`; its standard output alone (standard error to NAME.err), split
// into lines. The exit code in `code`.
std::vector<std::string> hmi_stdout(test::ServiceEnv& env, const std::string& name,
                                    const std::vector<std::string>& args, int& code) {
  std::string cmd = "'" TGM_HMI_BIN "'";
  for (const auto& a : args) cmd += " '" + a + "'";
  const test::ShellRun run = test::run_shell(cmd, env.path(""), name);
  code = run.exit_code;
  std::vector<std::string> lines;
  std::istringstream in(run.out);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A state as a stand-in service publishes it, with values a real one never has: numbers that
// are not finite and a message with quotes, a backslash and control characters.
TEST(HmiJson, StatusWritesOneObjectPerLineWithEveryValueReadable) {
  test::ServiceEnv env;  // its config and domain only: no tgm-service runs
  dds::Participant fake(env.dds(), "service");
  auto& states = fake.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic);
  msg::InterpolatorState s;
  s.interpolator(0);
  s.number(0);
  s.number_axes(3);
  s.buffer_size(1000);
  s.status(1);
  s.act_part(7);
  s.act_line(12);
  s.m_func(51);
  s.address_external_position(4096);
  s.run_flag(0x00020005);
  s.axis_letters("XYZ");
  s.service_instance(0xfedcba9876543210ULL);
  s.cycle_counter(123456789012ULL);
  s.orig_position()[0] = 12.5;
  s.orig_position()[1] = -3.25;
  s.orig_position()[2] = std::numeric_limits<double>::infinity();
  s.speed()[0] = std::numeric_limits<double>::quiet_NaN();
  s.position_inc()[1] = -9'007'199'254'740'993LL;       // beyond a double's integers
  for (double& p : s.m_function_parameter()) p = 1e39;  // not set
  s.m_function_parameter()[0] = 1.5;                    // A
  s.m_function_parameter()[25] = -2;                    // Z
  auto& e = s.look_ahead_buffer()[0];
  for (double& p : e.all_params()) p = 1e39;
  e.tangent(1e39);  // not set: null
  e.start_angle(90.0);
  e.end_angle(1e39);
  e.movement_type(1);
  e.movement_code(2);
  e.line(12);
  e.plane(17);
  e.end_pos()[0] = 20.0;
  e.radius(5.0);
  const std::string text = "say \"hi\" \\ tab\tend\x01";
  s.message_text(text);
  s.message_counter(4);
  s.m_func_line(11);
  s.program_stop(true);
  s.off_trajectory(true);
  s.program_id(4711);  // a program was loaded: "the program was dropped"
  s.cycle_time_us(500);
  s.spline_points(100);
  s.spline_jerk_mm_s3(2'000'000);
  s.iir_p_e6(3'000'000);
  s.iir_q_e6(2'000'000);
  s.iir_f_e6(8'000'000);
  s.iir_axis_mask(5);  // X and Z
  std::atomic<bool> done{false};
  std::thread writer([&] {
    while (!done) {
      states.write(&s);
      std::this_thread::sleep_for(20ms);
    }
  });
  int code = -1;
  const auto lines =
      hmi_stdout(env, "status", {"status", "--json", "--config", env.config()}, code);
  int text_code = -1;
  const auto text_lines = hmi_stdout(env, "text", {"status", "--config", env.config()}, text_code);
  done = true;
  writer.join();
  ASSERT_EQ(code, 0) << test::read_text(env.path("status.err"));
  ASSERT_EQ(text_code, 0) << test::read_text(env.path("text.err"));
  ASSERT_GE(text_lines.size(), 2u);
  std::string text_all;
  for (const std::string& l : text_lines) text_all += l + "\n";
  // Every axis of an entry by its letter, and Command_Parameter (session 75: three unnamed
  // values, no Command_Parameter).
  EXPECT_NE(text_all.find("    [0] G2 line 12 plane 17 tool 0 end X20.0000 Y0.0000 Z0.0000 "
                          "radius 5.0000 start angle 90.000\n"),
            std::string::npos)
      << text_all;
  EXPECT_NE(text_all.find("  Command_Parameter: 0 0 0"), std::string::npos) << text_all;
  EXPECT_NE(text_all.find("  M_Function_Parameter: A1.5 Z-2\n"), std::string::npos) << text_all;
  EXPECT_NE(text_all.find("  Smoothing: Spline 100 points (10.0 ms at 500 us cycles), jerk limit "
                          "2000000 mm/s^3; IIR p 3, q 2, f 8 ms on X Z\n"),
            std::string::npos)
      << text_all;
  EXPECT_NE(text_lines[0].find("Status 1 (running, at an M0 program stop: start continues, off "
                               "the trajectory: the program was dropped)"),
            std::string::npos)
      << text_lines[0];
  EXPECT_NE(text_lines[1].find("Run_Flag 0x00020005 (section 5 WAIT_MFUNC_WAIT_FOR_END, speed 2 "
                               "accelerating), "
                               "Address_External_Position 4096"),
            std::string::npos)
      << text_lines[1];
  ASSERT_EQ(lines.size(), 1u);
  const YAML::Node j = YAML::Load(lines[0]);
  ASSERT_TRUE(j.IsMap()) << lines[0];
  EXPECT_EQ(j["number"].as<int>(), 0);
  EXPECT_EQ(j["status"].as<int>(), 1);
  EXPECT_EQ(j["status_name"].as<std::string>(), "running");
  EXPECT_EQ(j["axis_letters"].as<std::string>(), "XYZ");
  EXPECT_EQ(j["act_part"].as<int>(), 7);
  EXPECT_EQ(j["act_line"].as<int>(), 12);
  EXPECT_EQ(j["m_func"].as<int>(), 51);
  EXPECT_EQ(j["m_func_line"].as<int>(), 11);
  EXPECT_TRUE(j["program_stop"].as<bool>());
  EXPECT_TRUE(j["off_trajectory"].as<bool>());
  EXPECT_EQ(j["run_flag"].as<std::uint32_t>(), 0x00020005u);
  // Every register of the manual's table is shown (this one was left out of both views).
  EXPECT_EQ(j["address_external_position"].as<int>(), 4096);
  EXPECT_EQ(j["service_instance"].as<std::string>(), "fedcba9876543210");
  EXPECT_EQ(j["cycle_counter"].as<std::uint64_t>(), 123456789012ULL);
  EXPECT_EQ(j["orig_position_mm"]["X"].as<double>(), 12.5);
  EXPECT_EQ(j["orig_position_mm"]["Y"].as<double>(), -3.25);
  EXPECT_TRUE(j["orig_position_mm"]["Z"].IsNull()) << lines[0];
  EXPECT_TRUE(j["speed_mm_s"]["X"].IsNull()) << lines[0];
  EXPECT_EQ(j["position_inc"]["Y"].as<long long>(), -9'007'199'254'740'993LL);
  EXPECT_EQ(j["m_function_parameter"].size(), 2u);
  EXPECT_EQ(j["m_function_parameter"]["A"].as<double>(), 1.5);
  EXPECT_EQ(j["m_function_parameter"]["Z"].as<double>(), -2.0);
  ASSERT_EQ(j["look_ahead_buffer"].size(), 8u);
  EXPECT_EQ(j["look_ahead_buffer"][0]["movement_code"].as<int>(), 2);
  EXPECT_EQ(j["look_ahead_buffer"][0]["end_pos_mm"]["X"].as<double>(), 20.0);
  EXPECT_EQ(j["look_ahead_buffer"][0]["radius_mm"].as<double>(), 5.0);
  EXPECT_EQ(j["look_ahead_buffer"][0]["all_params"].size(), 0u);
  EXPECT_TRUE(j["look_ahead_buffer"][0]["tangent_deg"].IsNull()) << lines[0];
  EXPECT_EQ(j["look_ahead_buffer"][0]["start_angle_deg"].as<double>(), 90.0);
  EXPECT_TRUE(j["look_ahead_buffer"][0]["end_angle_deg"].IsNull()) << lines[0];
  EXPECT_TRUE(j["look_ahead_buffer"][1].IsNull());
  EXPECT_EQ(j["message_counter"].as<int>(), 4);
  EXPECT_EQ(j["message_text"].as<std::string>(), text);
  EXPECT_EQ(j["smoothing"]["spline_points"].as<int>(), 100);
  EXPECT_EQ(j["smoothing"]["spline_jerk_mm_s3"].as<double>(), 2e6);
  EXPECT_EQ(j["smoothing"]["iir_p_e6"].as<long long>(), 3'000'000);
  EXPECT_EQ(j["smoothing"]["iir_q_e6"].as<long long>(), 2'000'000);
  EXPECT_EQ(j["smoothing"]["iir_f_e6"].as<long long>(), 8'000'000);
  EXPECT_EQ(j["smoothing"]["iir_axis_mask"].as<unsigned>(), 5u);
  // No bare NaN or inf: JSON has none, and a strict reader stops at them.
  EXPECT_EQ(lines[0].find("nan"), std::string::npos) << lines[0];
  EXPECT_EQ(lines[0].find("inf"), std::string::npos) << lines[0];
}

// With the real service: the registers after a run, every interpolator, and a watch.
TEST(HmiJson, StatusAndWatchShowTheRealServicesRegisters) {
  test::ServiceEnv env;
  ASSERT_TRUE(env.start_service());
  std::ofstream(env.path("p.ngc")) << "G1 X12.5 Y-3 F3000\nM2\n";
  test::Child run;
  ASSERT_TRUE(run.start({TGM_HMI_BIN, "run", env.path("p.ngc"), "--config", env.config()},
                        env.path("run.log")));
  ASSERT_EQ(run.wait(kHang), 0) << run.log() << env.service.log();
  int code = -1;
  const auto all =
      hmi_stdout(env, "all", {"status", "--json", "--all", "--config", env.config()}, code);
  ASSERT_EQ(code, 0) << test::read_text(env.path("all.err"));
  ASSERT_EQ(all.size(), 3u);
  std::string instance;
  for (int i = 0; i < 3; ++i) {
    const YAML::Node j = YAML::Load(all[static_cast<std::size_t>(i)]);
    EXPECT_EQ(j["number"].as<int>(), i);
    EXPECT_EQ(j["number_axes"].as<int>(), 3);
    EXPECT_EQ(j["cycle_time_us"].as<int>(), 500);
    // The config's smoothing: spline and IIR off, IIR p, q, f the config's.
    EXPECT_EQ(j["smoothing"]["spline_points"].as<int>(), 0);
    EXPECT_EQ(j["smoothing"]["iir_p_e6"].as<long long>(), 2'000'000);
    EXPECT_EQ(j["smoothing"]["iir_axis_mask"].as<unsigned>(), 0u);
    if (i == 0) instance = j["service_instance"].as<std::string>();
    EXPECT_EQ(j["service_instance"].as<std::string>(), instance);
  }
  // --all with --interpolator N showed every interpolator, the N silently ignored.
  const auto both = hmi_stdout(
      env, "both", {"status", "--json", "--all", "--interpolator", "1", "--config", env.config()},
      code);
  EXPECT_EQ(code, 2);
  EXPECT_TRUE(both.empty());
  EXPECT_NE(
      test::read_text(env.path("both.err"))
          .find("tgm-hmi status: --all shows every interpolator: give it or --interpolator N"),
      std::string::npos)
      << test::read_text(env.path("both.err"));
  const YAML::Node j0 = YAML::Load(all[0]);
  EXPECT_EQ(j0["status_name"].as<std::string>(), "ended");
  EXPECT_NEAR(j0["orig_position_mm"]["X"].as<double>(), 12.5, 1e-9);
  EXPECT_NEAR(j0["orig_position_mm"]["Y"].as<double>(), -3.0, 1e-9);
  EXPECT_EQ(j0["act_m_func"].as<int>(), 2);
  // The text view says the same instance.
  test::Child text;
  ASSERT_TRUE(text.start({TGM_HMI_BIN, "status", "--config", env.config()}, env.path("text.log")));
  ASSERT_EQ(text.wait(kHang), 0);
  EXPECT_NE(text.log().find("service instance " + instance), std::string::npos) << text.log();

  const auto watched = hmi_stdout(
      env, "watch",
      {"watch", "--json", "--count", "3", "--interval", "0.1", "--config", env.config()}, code);
  ASSERT_EQ(code, 0) << test::read_text(env.path("watch.err"));
  ASSERT_EQ(watched.size(), 3u);
  std::uint64_t last = 0;
  for (const auto& line : watched) {
    const YAML::Node j = YAML::Load(line);
    const auto cycle = j["cycle_counter"].as<std::uint64_t>();
    EXPECT_GT(cycle, last) << line;
    last = cycle;
    // The service publishes every few milliseconds: each state shown is fresh.
    const double age = j["state_age_s"].as<double>();
    EXPECT_GE(age, 0.0) << line;
    EXPECT_LT(age, 1.0) << line;
  }
}

}  // namespace
}  // namespace tgm
