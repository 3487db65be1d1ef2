// tgm-plc --script: the reader of the timed steps (config/src/plc_script.cpp). The PLC process
// itself is tested with a script in tests/integration (PlcScriptErrorsNameTheLineAndTheReason).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <climits>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <future>
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

// The PLC's register writes (DESIGN section 1): Number_Axes, and Ratio and Offset by axis
// letter, in the order given; whether the letters exist is a question of the interpolator.
TEST(PlcScript, RegisterWritesByAxisLetter) {
  const PlcScriptLoad load = parse_plc_script(
      "- {at_s: 0, offset: {Z: -20, X: 1000000000000000}, ratio: {Y: 2000.5, X: -1e-6}}\n"
      "- {at_s: 1, number_axes: 2, interpolator: 1}\n",
      "s.yaml");
  ASSERT_TRUE(load.ok()) << load.error;
  ASSERT_EQ(load.steps.size(), 2u);
  using Offsets = std::vector<std::pair<char, std::int64_t>>;
  using Ratios = std::vector<std::pair<char, double>>;
  EXPECT_EQ(load.steps[0].offset_inc, (Offsets{{'Z', -20}, {'X', 1'000'000'000'000'000}}));
  EXPECT_EQ(load.steps[0].ratio, (Ratios{{'Y', 2000.5}, {'X', -1e-6}}));
  EXPECT_FALSE(load.steps[0].number_axes);
  EXPECT_EQ(load.steps[1].number_axes, 2);
  EXPECT_TRUE(load.steps[1].offset_inc.empty() && load.steps[1].ratio.empty());
  // Letters in lower case, as the config takes them (`letter: x`).
  const PlcScriptLoad lower =
      parse_plc_script("- {at_s: 0, offset: {z: -20}, ratio: {y: 2000.5}}\n", "s.yaml");
  ASSERT_TRUE(lower.ok()) << lower.error;
  EXPECT_EQ(lower.steps[0].offset_inc, (Offsets{{'Z', -20}}));
  EXPECT_EQ(lower.steps[0].ratio, (Ratios{{'Y', 2000.5}}));
  EXPECT_EQ(plc_script_axes_problem(load.steps[0], "XYZ"), "");
  EXPECT_EQ(plc_script_axes_problem(load.steps[0], "XY"),
            "interpolator 0: offset of 'Z': it has no such axis (XY)");
  EXPECT_EQ(plc_script_axes_problem(load.steps[1], "XY"), "");
  EXPECT_EQ(plc_script_axes_problem(load.steps[1], "X"),
            "interpolator 1: number_axes 2 is more than its 1 configured axes (X)");
  PlcScriptStep ratio_only;
  ratio_only.ratio = {{'C', 1.0}};
  EXPECT_EQ(plc_script_axes_problem(ratio_only, "XYZ"),
            "interpolator 0: ratio of 'C': it has no such axis (XYZ)");
}

// A write by axis letter goes to the index of that letter among the axes the service drives,
// not to its place in tgm-plc's config: with a config of Y, X, Z the ratio for X set the
// service's Y, and with X, Y, C the one for C its Z (review of session 76). A letter the
// service does not drive has no index (-1): nothing is written.
TEST(PlcScript, AxisWritesGoToTheServicesAxisOfTheLetter) {
  const PlcScriptLoad load = parse_plc_script(
      "- {at_s: 0, offset: {C: 77, X: -5}, ratio: {C: 5000, X: 2000}}\n", "s.yaml");
  ASSERT_TRUE(load.ok()) << load.error;
  using R = PlcAxisWrite::Register;
  const auto shown = [](const std::vector<PlcAxisWrite>& writes) {
    std::string out;
    for (const PlcAxisWrite& w : writes) {
      out += (w.reg == R::kRatio ? "ratio " : "offset ") + std::string(1, w.letter) + "->" +
             std::to_string(w.axis) + " ";
    }
    return out;
  };
  // Ratios first, then offsets, each in the order given.
  EXPECT_EQ(shown(plc_script_axis_writes(load.steps[0], "XYC")),
            "ratio C->2 ratio X->0 offset C->2 offset X->0 ");
  EXPECT_EQ(shown(plc_script_axis_writes(load.steps[0], "YXC")),
            "ratio C->2 ratio X->1 offset C->2 offset X->1 ");
  EXPECT_EQ(shown(plc_script_axis_writes(load.steps[0], "XYZ")),
            "ratio C->-1 ratio X->0 offset C->-1 offset X->0 ");
  // A lower Number_Axes: the service drives only the first letters.
  EXPECT_EQ(shown(plc_script_axis_writes(load.steps[0], "X")),
            "ratio C->-1 ratio X->0 offset C->-1 offset X->0 ");
  // A service that publishes no letters: nothing can be addressed.
  EXPECT_EQ(shown(plc_script_axis_writes(load.steps[0], "")),
            "ratio C->-1 ratio X->-1 offset C->-1 offset X->-1 ");
  const std::vector<PlcAxisWrite> w = plc_script_axis_writes(load.steps[0], "YXC");
  ASSERT_EQ(w.size(), 4u);
  EXPECT_EQ(w[0].ratio_inc_per_mm, 5000.0);
  EXPECT_EQ(w[1].ratio_inc_per_mm, 2000.0);
  EXPECT_EQ(w[2].offset_inc, 77);
  EXPECT_EQ(w[3].offset_inc, -5);
}

// at_s counts from when the service is found, --duration from the PLC's start: a step at or
// after the duration never runs, and is refused at the start (it was left out without a word).
TEST(PlcScript, ADurationThatEndsBeforeAStepIsNamed) {
  const PlcScriptLoad load = parse_plc_script(
      "- {at_s: 0.2, rel_speed: 0.9}\n- {at_s: 5, command: 8}\n- {at_s: 3, command: 9}\n",
      "s.yaml");
  ASSERT_TRUE(load.ok()) << load.error;
  EXPECT_EQ(plc_script_duration_problem(load.steps, 5.5, "s.yaml"), "");
  EXPECT_EQ(plc_script_duration_problem(load.steps, 5, "s.yaml"),
            "--duration 5 (seconds from the start) ends the run before the step at s.yaml:2 "
            "(at_s 5, seconds from when tgm-service is found) could run: give a --duration "
            "longer than the script's last at_s");
  // The latest step is named: the one the duration must exceed.
  EXPECT_EQ(
      plc_script_duration_problem(load.steps, 1, "s.yaml")
          .rfind("--duration 1 (seconds from the start) ends the run before the step at s.yaml:2 "
                 "(at_s 5,",
                 0),
      0u);
}

// What of a script did not run when the PLC stopped: how many, and the first one's place.
TEST(PlcScript, StepsThatNeverRanAreCountedAndTheFirstNamed) {
  const PlcScriptLoad load = parse_plc_script(
      "- {at_s: 0.2, rel_speed: 0.9}\n- {at_s: 5, command: 8}\n- {at_s: 3.25, command: 9}\n",
      "s.yaml");
  ASSERT_TRUE(load.ok()) << load.error;
  EXPECT_EQ(plc_script_unrun(load.steps, {true, true, true}, "s.yaml"), "");
  EXPECT_EQ(plc_script_unrun(load.steps, {true, false, true}, "s.yaml"),
            "1 of 3 script steps never ran (the first: s.yaml:2, at_s 5)");
  EXPECT_EQ(plc_script_unrun(load.steps, {true, false, false}, "s.yaml"),
            "2 of 3 script steps never ran (the first: s.yaml:2, at_s 5)");
  EXPECT_EQ(plc_script_unrun(load.steps, {false, false, false}, "s.yaml"),
            "3 of 3 script steps never ran (the first: s.yaml:1, at_s 0.2)");
  const std::vector<PlcScriptStep> one(load.steps.begin() + 2, load.steps.end());
  EXPECT_EQ(plc_script_unrun(one, {false}, "s.yaml"),
            "1 of 1 script step never ran (the first: s.yaml:3, at_s 3.25)");
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
       "s.yaml:2: the step does nothing: give it rel_speed, number_axes, ratio, offset, command, "
       "start: true or refuse_ack"},
      // Register writes: whole axes, letters as keys, values in the registers' ranges.
      {"- {at_s: 1, number_axes: 11}\n",
       "s.yaml:1: number_axes must be a number of axes 1..10, not '11'"},
      {"- {at_s: 1, number_axes: 1.5}\n", "s.yaml:1: number_axes must be a number of axes 1..10"},
      {"- {at_s: 1, offset: 5}\n",
       "s.yaml:1: offset must be a map of Offset [inc] by axis letter, e.g. {X: 500, Z: -20}, not "
       "'5'"},
      {"- {at_s: 1, offset: {}}\n", "s.yaml:1: offset must be a map of Offset [inc]"},
      {"- {at_s: 1, offset: {1: 5}}\n",
       "s.yaml:1: offset takes axis letters A..Z as keys, not '1'"},
      // Lower case is the same letter (as in the config): given twice.
      {"- {at_s: 1, offset: {x: 5, X: 6}}\n", "s.yaml:1: offset of 'X' is given twice"},
      {"- {at_s: 1, offset: {XY: 5}}\n",
       "s.yaml:1: offset takes axis letters A..Z as keys, not 'XY'"},
      {"- {at_s: 1, offset: {X: 0.5}}\n",
       "s.yaml:1: offset of 'X' must be whole increments, |offset| <= 1e15, not '0.5'"},
      {"- {at_s: 1, offset: {X: 1000000000000001}}\n",
       "s.yaml:1: offset of 'X' must be whole increments, |offset| <= 1e15, not "
       "'1000000000000001'"},
      {"- {at_s: 1, offset: {X: 1, X: 2}}\n", "s.yaml:1: offset of 'X' is given twice"},
      {"- {at_s: 1, ratio: {X: 0}}\n",
       "s.yaml:1: ratio of 'X' must be inc/mm with |ratio| 1e-06..1e+09, not '0'"},
      {"- {at_s: 1, ratio: {X: 2e9}}\n", "s.yaml:1: ratio of 'X' must be inc/mm"},
      {"- {at_s: 1, ratio: {X: nan}}\n", "s.yaml:1: ratio of 'X' must be inc/mm"},
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
      // A second document was ignored (YAML::Load reads the first), and so was anything after
      // `...`, YAML or not.
      {"- {at_s: 1, command: 8}\n---\n- {at_s: 2, command: 9}\n",
       "s.yaml:2:1: YAML syntax: a second YAML document starts here; the file must hold one"},
      {"- {at_s: 1, command: 8}\n---\n", "s.yaml:2:1: YAML syntax: a second YAML document"},
      {"---\n- {at_s: 1, command: 8}\n...\n\n# more\n: : not yaml [ {\n",
       "s.yaml:6:1: YAML syntax: a second YAML document starts here"},
      {"- {at_s: 1, command: 8}\n...\n- {at_s: 2, command: 9}\n",
       "s.yaml:3:1: YAML syntax: a second YAML document starts here"},
      {"- {at_s: 1, command: 8}\n...\n%YAML 1.2\n---\n[]\n",
       "s.yaml:4:1: YAML syntax: a second YAML document starts here"},
      // yaml-cpp starts one without `---` where the list ends and more follows.
      {"- {at_s: 1, command: 8}\ncommand: 9\n",
       "s.yaml:2:1: YAML syntax: a second YAML document starts here"},
      // Numbers are plain decimal, as on the command line: strtod took hex, '+' and blanks, and
      // read 1e-400 as 0.
      {"- {at_s: 0x2, command: 8}\n",
       "s.yaml:1: at_s must be a number of seconds 0..1e9, not '0x2'"},
      {"- {at_s: 0x1p-1, command: 8}\n", "s.yaml:1: at_s must be a number of seconds 0..1e9"},
      {"- {at_s: +1, command: 8}\n", "s.yaml:1: at_s must be a number of seconds 0..1e9, not '+1'"},
      {"- {at_s: \" 1\", command: 8}\n", "s.yaml:1: at_s must be a number of seconds"},
      {"- {at_s: 1, rel_speed: 1e-400}\n",
       "s.yaml:1: rel_speed must be an override 0.01..2, not '1e-400'"},
      {"- {at_s: 1, interpolator: +1, command: 8}\n",
       "s.yaml:1: interpolator must be an interpolator 0..2, not '+1'"},
      {"- {at_s: 1, command: 0x8}\n", "s.yaml:1: command must be a Command"},
      {"- {at_s: 1, command: -2, parameters: [0x10]}\n",
       "s.yaml:1: parameters must list 32-bit integers, not '0x10'"},
      {"- {at_s: 1, refuse_ack: [+51]}\n", "s.yaml:1: refuse_ack must list normal M-functions"},
  };
  for (const auto& [text, says] : cases) {
    const PlcScriptLoad load = parse_plc_script(text, "s.yaml");
    EXPECT_FALSE(load.ok()) << text;
    EXPECT_TRUE(load.steps.empty()) << text;
    EXPECT_EQ(load.error.rfind(says, 0), 0u) << text.substr(0, 80) << "\n" << load.error;
  }
}

// A script may end its one document with `...` and comments.
TEST(PlcScript, ADocumentEndAndCommentsAfterTheStepsAreFine) {
  for (const char* text : {"- {at_s: 1, command: 8}\n...\n", "---\n- {at_s: 1, command: 8}\n...\n",
                           "- {at_s: 1, command: 8}\n...\n# the end\n\n...\n"}) {
    const PlcScriptLoad load = parse_plc_script(text, "s.yaml");
    ASSERT_TRUE(load.ok()) << text << load.error;
    EXPECT_EQ(load.steps.size(), 1u) << text;
  }
}

// An empty step ("-" alone) is named at its `-`: yaml-cpp marks it where the next token starts,
// past blank lines and comments (the message named the line of the next step, or one past the
// end of the file).
// Every bad step is named at once, in line order, and none is kept: a script with five
// mistakes took five edits and runs, each naming the next.
TEST(PlcScript, EveryBadStepIsNamedAtOnce) {
  const std::string text =
      "- {at_s: 1, command: 8}\n"
      "- {at_s: 2, rel_speed: 5}\n"
      "-\n"
      "- {at_s: 3, comand: 9}\n"
      "- {at_s: 4, command: 9}\n"
      "- {at_s: 5}\n";
  const PlcScriptLoad load = parse_plc_script(text, "s.yaml");
  EXPECT_TRUE(load.steps.empty());
  EXPECT_EQ(load.error,
            "s.yaml:2: rel_speed must be an override 0.01..2, not '5'\n"
            "s.yaml:3: a step must be a map, e.g. {at_s: 3, command: 8}\n"
            "s.yaml:4: unknown key 'comand' (known: at_s, interpolator, rel_speed, number_axes, "
            "ratio, offset, command, parameters, start, refuse_ack)\n"
            "s.yaml:6: the step does nothing: give it rel_speed, number_axes, ratio, offset, "
            "command, start: true or refuse_ack [M, ...]");
  // At most 20 are listed, the rest counted.
  std::string many;
  for (int i = 0; i < 25; ++i) many += "- {at_s: 1}\n";
  const PlcScriptLoad lots = parse_plc_script(many, "m.yaml");
  EXPECT_EQ(std::count(lots.error.begin(), lots.error.end(), '\n'), 20) << lots.error;
  EXPECT_NE(lots.error.find("\nm.yaml: ... and 5 more not shown"), std::string::npos) << lots.error;
}

TEST(PlcScript, AnEmptyStepIsNamedAtItsDash) {
  const std::string says = ": a step must be a map, e.g. {at_s: 3, command: 8}";
  const std::pair<std::string, int> cases[] = {
      {"- {at_s: 1, command: 8}\n-\n- {at_s: 2, command: 9}\n", 2},
      {"- {at_s: 1, command: 8}\n-\n\n# a comment\n   # another - with a dash\n\n"
       "- {at_s: 2, command: 9}\n",
       2},
      {"- {at_s: 1, command: 8}\n-   # nothing here\n  \n- {at_s: 2, command: 9}\n", 2},
      {"- {at_s: 1, command: 8}\n-\n", 2},  // the last step: marked past the end
      {"- {at_s: 1, command: 8}\n-\n\n\n", 2},
      {"-\n- {at_s: 2, command: 9}\n", 1},                  // the first
      {"# head\n\n  -\n\n  - {at_s: 2, command: 9}\n", 3},  // an indented list
      {"- {at_s: 1, command: 8}\r\n-\r\n\r\n- {at_s: 2, command: 9}\r\n", 2},
      {"- {at_s: 1, command: 8}\n- ~\n\n- {at_s: 2, command: 9}\n", 2},  // a null written
      {"- {at_s: 1, command: 8}\n-\n  # indented\n- {at_s: 2, command: 9}\n", 2},
      // A flow list has no `-`: its null item is where yaml-cpp marks it.
      {"[{at_s: 1, command: 8},\n\n ~]\n", 3},
  };
  for (const auto& [text, line] : cases) {
    const PlcScriptLoad load = parse_plc_script(text, "s.yaml");
    EXPECT_EQ(load.error, "s.yaml:" + std::to_string(line) + says) << text;
  }
}

// tgm-plc checks each step's interpolator against its config and --interpolator at the start:
// a step for an interpolator it does not serve was sent anyway.
TEST(PlcScript, AStepMustNameAnInterpolatorThePlcServes) {
  PlcScriptStep s;
  s.interpolator = 1;
  EXPECT_EQ(plc_script_interpolator_problem(s, 3, -1), "");
  EXPECT_EQ(plc_script_interpolator_problem(s, 3, 1), "");
  EXPECT_EQ(plc_script_interpolator_problem(s, 3, 2),
            "interpolator 1 is not served: tgm-plc runs with --interpolator 2");
  EXPECT_EQ(plc_script_interpolator_problem(s, 1, -1),
            "interpolator 1 does not exist (the config has 1)");
  s.interpolator = 0;  // also what a step without `interpolator:` names
  EXPECT_EQ(plc_script_interpolator_problem(s, 3, 1),
            "interpolator 0 is not served: tgm-plc runs with --interpolator 1 (a step without "
            "`interpolator: N` is for interpolator 0)");
  EXPECT_EQ(plc_script_interpolator_problem(s, 3, 0), "");
}

// A step over several lines is named at the line of its bad key (it was the step's first).
TEST(PlcScript, AnErrorInAStepNamesTheLineOfItsKey) {
  EXPECT_EQ(parse_plc_script("- at_s: 1\n  rel_speed: 0.5\n  bogus: 3\n", "s.yaml")
                .error.rfind("s.yaml:3: unknown key 'bogus'", 0),
            0u);
  EXPECT_EQ(parse_plc_script("- at_s: 1\n\n  rel_speed: 5\n", "s.yaml").error,
            "s.yaml:3: rel_speed must be an override 0.01..2, not '5'");
}

TEST(PlcScript, AnEmptyScriptIsRefused) {
  // An empty file (or comments only) is a null document, not a list: said as empty (it read
  // "must be a list of steps"), since a script given on purpose that does nothing is a mistake
  // more often than not. So is an empty list (it used to load and
  // run as no script at all).
  for (const char* text : {"", "# nothing yet\n\n"}) {
    EXPECT_EQ(parse_plc_script(text, "s.yaml").error,
              "s.yaml: the script is empty; give at least one step, e.g. - {at_s: 3, command: 8}")
        << text;
  }
  for (const char* text : {"[]\n", "# steps to come\n[ ]\n"}) {
    const PlcScriptLoad none = parse_plc_script(text, "s.yaml");
    EXPECT_EQ(none.error,
              "s.yaml: the script has no steps; give at least one, e.g. - {at_s: 3, command: 8}")
        << text;
    EXPECT_TRUE(none.steps.empty());
  }
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
// not there, a device without end (read up to the config bound).
TEST(PlcScript, FilesThatAreNoScriptAreNamed) {
  const std::string dir = ::testing::TempDir() + "plc_script_test_" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  EXPECT_EQ(load_plc_script(dir).error, dir + ": is a directory, not a script file");
  EXPECT_EQ(load_plc_script(dir + "/none.yaml").error,
            dir + "/none.yaml: cannot open the script file: No such file or directory");
  EXPECT_EQ(load_plc_script("/dev/zero").error,
            "/dev/zero: is a character device, not a script file");
  // A FIFO without a writer blocked the PLC's start in open() for good. Read on another thread:
  // should it block again, a writer frees it and the test fails instead of hanging.
  const std::string fifo = dir + "/s.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto read = std::async(std::launch::async, [&] { return load_plc_script(fifo).error; });
  if (read.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    ADD_FAILURE() << "load_plc_script blocked on a FIFO";
    std::ofstream(fifo) << "[]\n";
  }
  EXPECT_EQ(read.get(), fifo + ": is a named pipe (FIFO), not a script file");
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
