// tgm-plc --script: the reader of the timed steps (config/src/plc_script.cpp). The PLC process
// itself is tested with a script in tests/integration (PlcScriptErrorsNameTheLineAndTheReason).
#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <climits>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "tgm/plc_script.hpp"

namespace tgm {
namespace {

TEST(PlcScript, EveryKindOfStepIsRead) {
  const PlcScriptLoad load = parse_plc_script(
      "# comment\n"
      "- {at_s: 0, refuse_ack: [51, 999]}\n"
      "- {at_s: 1.5, rel_speed: 0.5, interpolator: 2}\n"
      "- at_s: 3\n"
      "  command: 8\n"
      "- {at_s: 4, start: yes, command: -2}\n"
      "- {at_s: 5, command: 1024, parameters: [1, -2147483648, 2147483647]}\n"
      "- {at_s: 6, command: 2048, parameters: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]}\n",
      "s.yaml");
  ASSERT_TRUE(load.ok()) << load.error;
  ASSERT_EQ(load.steps.size(), 6u);
  const PlcScriptStep& a = load.steps[0];
  EXPECT_EQ(a.line, 2);
  EXPECT_EQ(a.at_s, 0.0);
  EXPECT_EQ(a.refuse_ack, (std::vector<int>{51, 999}));
  EXPECT_FALSE(a.rel_speed || a.command || a.start);
  EXPECT_EQ(load.steps[1].line, 3);
  EXPECT_EQ(load.steps[1].interpolator, 2);
  EXPECT_EQ(load.steps[1].rel_speed, 0.5);
  EXPECT_EQ(load.steps[2].line, 4);
  EXPECT_EQ(load.steps[2].at_s, 3.0);
  EXPECT_EQ(load.steps[2].command, 8);
  EXPECT_EQ(load.steps[2].interpolator, 0);
  EXPECT_TRUE(load.steps[3].start);
  EXPECT_EQ(load.steps[3].command, -2);
  EXPECT_EQ(load.steps[3].parameters, (std::array<std::int32_t, 12>{}));  // none given: all 0
  EXPECT_EQ(load.steps[4].command, 1024);
  EXPECT_EQ(load.steps[4].parameters,
            (std::array<std::int32_t, 12>{1, INT32_MIN, INT32_MAX, 0, 0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(load.steps[5].parameters,
            (std::array<std::int32_t, 12>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}));
}

// A bad step is named by its line and the reason, and nothing of the script is kept: a script
// is not run in part (the fuzz target found the steps before a bad one kept).
TEST(PlcScript, AProblemNamesTheLineAndKeepsNoStep) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{at_s: 1, command: 8}\n", "s.yaml: the script must be a list of steps"},
      {"- {at_s: 1, command: 8}\n- {at_s: 2, comand: 9}\n", "s.yaml:2: unknown key 'comand'"},
      {"- {at_s: 1, command: 8}\n- {at_s: 2, at_s: 3, command: 9}\n",
       "s.yaml:2: 'at_s' is given twice"},
      {"- {at_s: -1, command: 8}\n", "s.yaml:1: at_s must be a number of seconds 0..1e9, not '-1'"},
      {"- {at_s: 1, command: 8}\n- 8\n", "s.yaml:2: a step must be a map"},
      // A step without an action did nothing, silently.
      {"- {at_s: 1, command: 8}\n- {at_s: 2}\n",
       "s.yaml:2: the step does nothing: give it rel_speed, command, start: true or refuse_ack"},
      {"- {at_s: 2, start: false}\n", "s.yaml:1: the step does nothing"},
      {"- {at_s: 2, refuse_ack: []}\n", "s.yaml:1: the step does nothing"},
      {"- {}\n", "s.yaml:1: the step does nothing"},
      // Values are read as the command line reads numbers and checked against their range
      // (yaml-cpp said "bad conversion"; a Rel_Speed of 5 was refused only in the run).
      {"- {at_s: abc}\n", "s.yaml:1: at_s must be a number of seconds 0..1e9, not 'abc'"},
      {"- {at_s: 1, rel_speed: 5}\n", "s.yaml:1: rel_speed must be an override 0.01..2, not '5'"},
      {"- {at_s: 1, rel_speed: [1]}\n",
       "s.yaml:1: rel_speed must be an override 0.01..2, not '[list]'"},
      {"- {at_s: 1, start: on}\n- {at_s: 2, command: 3}\n",
       "s.yaml:2: command must be a Command: 4, 5, 8, 9"},
      {"- {at_s: 1, command: 4294967304}\n", "s.yaml:1: command must be a Command"},
      {"- {at_s: 1, interpolator: 3}\n", "s.yaml:1: interpolator must be an interpolator 0..2"},
      {"- {at_s: 1, refuse_ack: [51, x]}\n",
       "s.yaml:1: refuse_ack must list normal M-functions 1..999 (the interpolator waits only for "
       "those), not 'x'"},
      {"- {at_s: 1, refuse_ack: [0]}\n",
       "s.yaml:1: refuse_ack must list normal M-functions 1..999"},
      {"- {at_s: 1, refuse_ack: [1001]}\n",
       "s.yaml:1: refuse_ack must list normal M-functions 1..999 (the interpolator waits only for "
       "those), not '1001'"},
      {"- {at_s: 1, refuse_ack: 51}\n", "s.yaml:1: refuse_ack must be a list of M numbers"},
      {"- {at_s: 1, start: maybe}\n", "s.yaml:1: start must be true or false, not 'maybe'"},
      // Command parameters: with a command, at most twelve, each a 32-bit integer.
      {"- {at_s: 1, parameters: [1, 2, 3]}\n",
       "s.yaml:1: parameters belong to a command: give command too"},
      {"- {at_s: 1, command: -2, parameters: 200}\n",
       "s.yaml:1: parameters must be a list of Command parameters, not '200'"},
      {"- {at_s: 1, command: -2, parameters: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13]}\n",
       "s.yaml:1: parameters takes at most 12 values (Command_Parameter[0..11]), not 13"},
      {"- {at_s: 1, command: -2, parameters: [200, 1e6]}\n",
       "s.yaml:1: parameters must list 32-bit integers, not '1e6'"},
      {"- {at_s: 1, command: -2, parameters: [2147483648]}\n",
       "s.yaml:1: parameters must list 32-bit integers, not '2147483648'"},
      {"- {at_s: 1, [a]: 2}\n", "s.yaml:1: unknown key '(not a name)'"},
      // Text from the script is quoted with its control characters shown.
      {"- {at_s: \"1\\e[2J\"}\n",
       "s.yaml:1: at_s must be a number of seconds 0..1e9, not '1\\x1b[2J'"},
      {"- {\"a\\x07\": 1}\n", "s.yaml:1: unknown key 'a\\x07'"},
      // yaml-cpp's "bad file" for brackets nested past its depth limit.
      {"- " + std::string(3000, '[') + std::string(3000, ']') + "\n",
       "s.yaml:2:1: YAML syntax: nested more than "},
      {"- {at_s: 1\n", "s.yaml:2:1: YAML syntax: "},
  };
  for (const auto& [text, says] : cases) {
    const PlcScriptLoad load = parse_plc_script(text, "s.yaml");
    EXPECT_FALSE(load.ok()) << text;
    EXPECT_TRUE(load.steps.empty()) << text;
    EXPECT_EQ(load.error.rfind(says, 0), 0u) << text.substr(0, 80) << "\n" << load.error;
  }
}

TEST(PlcScript, AnEmptyScriptHasNoSteps) {
  // An empty file is a null document, not a list: said, since a script given on purpose that
  // does nothing is a mistake more often than not.
  EXPECT_EQ(parse_plc_script("", "s.yaml").error,
            "s.yaml: the script must be a list of steps, e.g. - {at_s: 3, command: 8}");
  const PlcScriptLoad none = parse_plc_script("[]\n", "s.yaml");
  EXPECT_TRUE(none.ok()) << none.error;
  EXPECT_TRUE(none.steps.empty());
}

TEST(PlcScript, OnlyTheStopsAndTheStageCommandsMayBeSent) {
  for (const long long c : {4LL, 5LL, 8LL, 9LL, 1024LL, 2048LL, 2049LL, -1LL, -2LL}) {
    EXPECT_TRUE(plc_script_command(c)) << c;
  }
  for (const long long c :
       {0LL, 1LL, 3LL, 6LL, 7LL, 10LL, 1023LL, -3LL, 4294967304LL, -4294967292LL}) {
    EXPECT_FALSE(plc_script_command(c)) << c;
  }
}

// Files that are no script: a directory (an uncaught exception aborted the PLC), one that is
// not there, a device without end (read up to the config bound, 16 MiB).
TEST(PlcScript, FilesThatAreNoScriptAreNamed) {
  const std::string dir = ::testing::TempDir() + "plc_script_test_" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  EXPECT_EQ(load_plc_script(dir).error, dir + ": is a directory, not a script file");
  EXPECT_EQ(load_plc_script(dir + "/none.yaml").error,
            dir + "/none.yaml: cannot open the script file: No such file or directory");
  EXPECT_EQ(load_plc_script("/dev/zero").error, "/dev/zero: more than 16 MiB: not a script file");
  const std::string file = dir + "/s.yaml";
  std::ofstream(file) << "- {at_s: 2, command: 9}\n";
  const PlcScriptLoad load = load_plc_script(file);
  ASSERT_TRUE(load.ok()) << load.error;
  ASSERT_EQ(load.steps.size(), 1u);
  EXPECT_EQ(load.steps[0].command, 9);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace tgm
