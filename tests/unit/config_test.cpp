// Config: core validation and the YAML adapter (key paths, unknown keys, ranges).
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>
#include <utility>
#include <vector>

#include "tgm/dds_overrides.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm {
namespace {

bool has_error(const std::vector<std::string>& errors, const std::string& needle) {
  for (const auto& e : errors) {
    if (e.find(needle) != std::string::npos) return true;
  }
  return false;
}

TEST(Config, DefaultMachineIsValid) {
  EXPECT_TRUE(MachineConfig::default_machine().validate().empty());
}

// The config accepts the ratios a Ratio write accepts, no more: 1e300 inc/mm made PositionInc
// -2^63. A negative ratio turns the axis round and is kept.
TEST(Config, RatioHasTheRangeOfARatioWrite) {
  for (const double bad : {1e300, 2e9, 0.0, 1e-7, -1e10, std::nan("")}) {
    MachineConfig m = MachineConfig::default_machine();
    m.interpolators[0].axes[1].ratio_inc_per_mm = bad;
    const auto problems = m.validate();
    ASSERT_EQ(problems.size(), 1u) << bad;
    EXPECT_NE(problems[0].find("interpolators[0].axes[1].ratio_inc_per_mm: |ratio| must be "
                               "1e-06..1e+09 inc/mm, not "),
              std::string::npos)
        << problems[0];
  }
  for (const double good : {1e9, -1e9, 1e-6, -5.0, 1000.0}) {
    MachineConfig m = MachineConfig::default_machine();
    m.interpolators[0].axes[1].ratio_inc_per_mm = good;
    EXPECT_TRUE(m.validate().empty()) << good;
  }
}

// An axis with backlash is planned at 1 - backlash_ramp_share of its limits: the share has a
// range, and what it leaves must stay within the range the motion core is tested at.
TEST(Config, BacklashRampShareHasARangeAndLeavesTestedLimits) {
  for (const double bad : {0.0, 0.005, 0.51, 1.0, -0.1, std::nan("")}) {
    MachineConfig m = MachineConfig::default_machine();
    m.interpolators[0].axes[2].backlash_ramp_share = bad;
    const auto problems = m.validate();
    ASSERT_EQ(problems.size(), 1u) << bad;
    EXPECT_NE(problems[0].find("interpolators[0].axes[2].backlash_ramp_share: must be 0.01..0.5"),
              std::string::npos)
        << problems[0];
  }
  MachineConfig m = MachineConfig::default_machine();
  AxisConfig& z = m.interpolators[0].axes[2];
  z.backlash_ramp_share = 0.5;
  z.max_acceleration_mm_s2 = 0.15;
  z.emergency_deceleration_mm_s2 = 0.15;
  EXPECT_TRUE(m.validate().empty()) << "no backlash: the motion has the whole limit";
  z.backlash_mm = 0.01;
  const auto problems = m.validate();
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0],
            "interpolators[0].axes[2].backlash_ramp_share: 0.5 leaves max_acceleration_mm_s2 "
            "0.075 to the motion, below 0.1 mm/s^2");
  z.backlash_ramp_share = 0.3;
  EXPECT_TRUE(m.validate().empty());
}

TEST(Config, DefaultYamlLoadsAndMatchesBuiltInDefaults) {
  const auto load = load_config_file(TGM_SOURCE_DIR "/config/default.yaml");
  ASSERT_TRUE(load.errors.empty()) << load.errors.front();
  const auto& m = load.config->machine;
  EXPECT_EQ(m.cycle_time_us, 500);
  ASSERT_EQ(m.interpolators.size(), 3u);
  EXPECT_EQ(m.axis_letters(0), "XYZ");
  EXPECT_DOUBLE_EQ(m.interpolators[1].axes[2].max_jerk_mm_s3, 30000.0);
  EXPECT_TRUE(m.compiler.start_incremental);
  EXPECT_DOUBLE_EQ(load.config->plc.m_delay_s.at(51), 0.2);
  EXPECT_TRUE(load.config->plc.setup_before_start);
}

// A file that is not a config (here 200 "kN: 1" lines, as a log or a program given by mistake)
// has a problem on every line: the first 50 are printed, then how many more, then the count.
TEST(Config, AFileWithAProblemOnEveryLinePrintsTheFirstFiftyAndTheCount) {
  const std::string path =
      (std::filesystem::temp_directory_path() / ("tgm_kv_" + std::to_string(::getpid()) + ".yaml"))
          .string();
  {
    std::ofstream f(path);
    for (int k = 0; k < 200; ++k) f << "k" << k << ": 1\n";
  }
  testing::internal::CaptureStderr();
  EXPECT_FALSE(load_config_or_report(path, "prog"));
  const std::string err = testing::internal::GetCapturedStderr();
  std::remove(path.c_str());
  std::size_t lines = 0;
  for (char c : err) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, kConfigProblemsShown + 2) << err;
  EXPECT_NE(err.find(path + ":50: k49: unknown key"), std::string::npos) << err;
  EXPECT_EQ(err.find(path + ":51:"), std::string::npos) << err;
  EXPECT_NE(err.find(path + ": ... and 150 more not shown\nprog: the config " + path +
                     " has 200 problems\n"),
            std::string::npos)
      << err;
}

// Brackets nested thousands deep (a generated or corrupted file): yaml-cpp stops at its depth
// limit with the words "bad file"; the error says what is wrong. Aliases that would expand
// exponentially are never expanded: a list where a table is expected is one problem per item.
TEST(Config, DeepNestingAndAliasBombsAreOneClearProblem) {
  const std::string deep = "tools: " + std::string(100'000, '[') + std::string(100'000, ']') + "\n";
  auto load = load_config_text(deep, "deep.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0].rfind("deep.yaml:1:", 0), 0u) << load.errors[0];
  EXPECT_NE(load.errors[0].find(": YAML syntax: nested more than "), std::string::npos)
      << load.errors[0];
  EXPECT_NE(load.errors[0].find(" levels deep"), std::string::npos) << load.errors[0];
  std::string bomb = "compiler:\n  plc_redefined_m: &a [2, 3, 4, 5, 6, 7, 8, 9, 17, 29]\n";
  std::string prev = "a";
  for (char c = 'b'; c <= 'l'; ++c) {
    bomb += std::string("x") + c + ": &" + c + " [";
    for (int k = 0; k < 10; ++k) bomb += (k ? ", *" : "*") + prev;
    bomb += "]\n";
    prev = std::string(1, c);
  }
  // 10^12 numbers if it were expanded. Walked alias by alias, looking for empty values, eight
  // levels took 5 s and these twelve would take days (a hang, until session 64).
  bomb += "tools: *l\n";
  load = load_config_text(bomb, "bomb.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_EQ(load.errors.size(), 11u + 10u);  // x.. keys unknown; each of the 10 tools not a table
  EXPECT_NE(load.errors.back().find("tools[9]: must be a mapping"), std::string::npos)
      << load.errors.back();
}

// dds.security names a directory relative to the YAML file, as dds.profiles_file does; unset,
// security is off.
TEST(Config, DdsSecurityIsADirectoryRelativeToTheFile) {
  auto load = load_config_text("dds: {security: sec}\n", "/etc/tgm/cell1.yaml");
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.security_dir, "/etc/tgm/sec");
  load = load_config_text("dds: {security: /opt/sec}\n", "/etc/tgm/cell1.yaml");
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.security_dir, "/opt/sec");
  load = load_config_text("dds: {domain_id: 3}\n", "/etc/tgm/cell1.yaml");
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.security_dir, "");
  load = load_config_text("dds: {security: [a]}\n", "m.yaml");
  EXPECT_FALSE(load.config.has_value());
}

// A config that does not name a profiles file takes fastdds_profiles.xml beside it, or else the
// one shipped with tgm. A machine config kept elsewhere was refused for a missing
// fastdds_profiles.xml it never asked for. One that names a file gets that file.
TEST(Config, AnUnnamedProfilesFileIsTheOneBesideOrTheShippedOne) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("tgm_profiles_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string yaml = (dir / "mill.yaml").string();
  auto load = load_config_text("cycle_time_us: 500\n", yaml);
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.profiles_file, shipped_config_file("fastdds_profiles.xml"));
  EXPECT_TRUE(fs::is_regular_file(load.config->dds.profiles_file))
      << load.config->dds.profiles_file;
  EXPECT_TRUE(dds_profiles_problem(load.config->dds).empty());
  std::ofstream(dir / "fastdds_profiles.xml") << "<profiles/>\n";
  load = load_config_text("dds: {domain_id: 3}\n", yaml);
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.profiles_file, (dir / "fastdds_profiles.xml").string());
  load = load_config_text("dds: {profiles_file: qos.xml}\n", yaml);
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.profiles_file, (dir / "qos.xml").string());
  EXPECT_NE(dds_profiles_problem(load.config->dds).find("qos.xml' does not exist"),
            std::string::npos);
  // A copy of config/default.yaml kept elsewhere (/etc/tgm/machine.yaml, as
  // config/systemd/tgm.default suggests): it named fastdds_profiles.xml, which was then looked
  // for beside the copy, and every binary refused to start.
  fs::remove(dir / "fastdds_profiles.xml");
  fs::copy_file(TGM_SOURCE_DIR "/config/default.yaml", dir / "machine.yaml");
  load = load_config_file((dir / "machine.yaml").string());
  ASSERT_TRUE(load.config.has_value());
  EXPECT_EQ(load.config->dds.profiles_file, shipped_config_file("fastdds_profiles.xml"));
  EXPECT_TRUE(dds_profiles_problem(load.config->dds).empty());
  fs::remove_all(dir);
}

TEST(Config, UnknownKeyIsAnErrorWithPathAndLine) {
  const auto load = load_config_text("cycle_time_us: 500\ncompiler:\n  defualt_feed: 3\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "m.yaml:3: compiler.defualt_feed: unknown key"));
}

TEST(Config, AKeyThatIsAListIsNamed) {
  const auto load = load_config_text("? [a, b]\n: 1\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "m.yaml:1: [list]: unknown key")) << load.errors.front();
}

TEST(Config, OutOfRangeValuesAreAllReported) {
  const auto load = load_config_text(
      "cycle_time_us: 300\n"
      "interpolators:\n"
      "  - buffer_size: 10\n"
      "    axes: [{letter: X, max_jerk_mm_s3: -1}, {letter: X}]\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "cycle_time_us: must be 250, 500 or 1000, not 300"));
  EXPECT_TRUE(has_error(load.errors, "interpolators[0].buffer_size: must be 1000..100000"));
  EXPECT_TRUE(has_error(load.errors, "interpolators[0].axes[0].max_jerk_mm_s3: must be > 0"));
  EXPECT_TRUE(has_error(load.errors, "interpolators[0].axes[1].letter: 'X' is used by two axes"));
}

// Axis limits outside the range the motion core is tested over are errors that name the range
// (1e-300 mm/s^2 never got a line going; 1e300 mm/s was accepted and printed with 300 digits),
// and an emergency deceleration below the axis's acceleration is one (the interpolator raised
// it to the acceleration without a word). A finding in a value an axis takes from
// axis_defaults is reported once, at the line of axis_defaults that sets it.
TEST(Config, AxisLimitsOutsideTheTestedRangeAreErrorsWithTheirLine) {
  auto load = load_config_text(
      "axis_defaults:\n"
      "  max_acceleration_mm_s2: 2000\n"
      "  max_jerk_mm_s3: 5\n"
      "interpolators:\n"
      "  - axes: [{letter: X, max_jerk_mm_s3: 100}, {letter: Y}, {letter: Z}]\n"
      "  - axes:\n"
      "      - {letter: X, max_velocity_mm_s: 1e300, rapid_velocity_mm_s: 0.001}\n"
      "      - {letter: Y, max_jerk_mm_s3: 50, corner_velocity_tolerance_mm_s: 2e4}\n"
      "      - {letter: Z, max_jerk_mm_s3: 50, emergency_deceleration_mm_s2: 1999}\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 5u);
  EXPECT_EQ(
      load.errors[0],
      "m.yaml:3: axis_defaults.max_jerk_mm_s3: must be 10..1e+10 mm/s^3, not 5; 3 axes take it");
  EXPECT_EQ(load.errors[1],
            "m.yaml:7: interpolators[1].axes[0].max_velocity_mm_s: must be 0.01..100000 mm/s, "
            "not 1e+300");
  EXPECT_EQ(load.errors[2],
            "m.yaml:7: interpolators[1].axes[0].rapid_velocity_mm_s: must be 0.01..100000 mm/s, "
            "not 0.001");
  EXPECT_EQ(load.errors[3],
            "m.yaml:8: interpolators[1].axes[1].corner_velocity_tolerance_mm_s: must be "
            "0.001..10000 mm/s, not 20000");
  EXPECT_EQ(load.errors[4],
            "m.yaml:9: interpolators[1].axes[2].emergency_deceleration_mm_s2: 1999 is below "
            "max_acceleration_mm_s2 2000 (an emergency stop brakes at least as hard as a normal "
            "one)");
  // One axis taking a bad default is named with the default's line.
  load = load_config_text(
      "axis_defaults: {max_acceleration_mm_s2: 0.01}\n"
      "interpolators: [{axes: [{letter: X}, {letter: Y, max_acceleration_mm_s2: 100}]}]\n",
      "m.yaml");
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "m.yaml:1: interpolators[0].axes[0].max_acceleration_mm_s2: must be 0.1..1e+06 "
            "mm/s^2, not 0.01 (from axis_defaults.max_acceleration_mm_s2)");
  // The ends of the ranges are accepted.
  load = load_config_text(
      "axis_defaults: {max_velocity_mm_s: 0.01, rapid_velocity_mm_s: 0.01,\n"
      "  max_acceleration_mm_s2: 1e6, emergency_deceleration_mm_s2: 1e6, max_jerk_mm_s3: 1e10,\n"
      "  corner_velocity_tolerance_mm_s: 0.001}\n"
      "interpolators:\n"
      "  - axes: [{letter: X, max_velocity_mm_s: 1e5, rapid_velocity_mm_s: 1e5,\n"
      "            max_acceleration_mm_s2: 0.1, emergency_deceleration_mm_s2: 0.1,\n"
      "            max_jerk_mm_s3: 10, corner_velocity_tolerance_mm_s: 1e4}]\n",
      "m.yaml");
  EXPECT_TRUE(load.config) << (load.errors.empty() ? "" : load.errors.front());
}

// corner_acceleration_tolerance_mm_s2: left out or 0, derived from the jerk limit and the
// corner tolerance (config.hpp); set, within the acceleration range.
TEST(Config, CornerAccelerationToleranceIsDerivedUnlessSet) {
  auto load = load_config_text(
      "axis_defaults: {max_jerk_mm_s3: 50000, corner_velocity_tolerance_mm_s: 1}\n"
      "interpolators:\n"
      "  - axes: [{letter: X}, {letter: Y, corner_acceleration_tolerance_mm_s2: 500},\n"
      "           {letter: Z, corner_acceleration_tolerance_mm_s2: 0}]\n",
      "m.yaml");
  ASSERT_TRUE(load.config) << (load.errors.empty() ? "" : load.errors.front());
  const auto& axes = load.config->machine.interpolators[0].axes;
  EXPECT_DOUBLE_EQ(corner_acceleration_tolerance(axes[0]), std::sqrt(2.0 * 50000.0 * 1.0));
  EXPECT_DOUBLE_EQ(corner_acceleration_tolerance(axes[1]), 500.0);
  EXPECT_DOUBLE_EQ(corner_acceleration_tolerance(axes[2]), corner_acceleration_tolerance(axes[0]));
  load = load_config_text(
      "interpolators:\n"
      "  - axes: [{letter: X, corner_acceleration_tolerance_mm_s2: 2e6},\n"
      "           {letter: Y, corner_acceleration_tolerance_mm_s2: -3}]\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 2u);
  EXPECT_EQ(load.errors[0],
            "m.yaml:2: interpolators[0].axes[0].corner_acceleration_tolerance_mm_s2: must be "
            "0.1..1e+06 mm/s^2, not 2e+06");
  EXPECT_EQ(load.errors[1],
            "m.yaml:3: interpolators[0].axes[1].corner_acceleration_tolerance_mm_s2: must be > 0, "
            "not -3");
}

TEST(Config, NonNumbersAndBadSyntaxAreErrors) {
  auto load = load_config_text("cycle_time_us: fast\n", "m.yaml");
  EXPECT_TRUE(has_error(load.errors, "m.yaml:1: cycle_time_us: must be a whole number, not 'fast'"));
  load = load_config_text("a: [1, 2\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "YAML syntax"));
  load = load_config_text("compiler: {plc_redefined_m: [80]}\n", "m.yaml");
  EXPECT_TRUE(has_error(load.errors, "compiler.plc_redefined_m[0]: M80 cannot be redefined"));
}

// Whole numbers are base 10, and one that does not fit its field is an error, not wrapped round.
TEST(Config, WholeNumbersAreDecimalAndNeverWrapRound) {
  // M-numbers as keys and list items too: 2^32 + 2 redefined M2, 2^32 + 51 delayed M51.
  // A delay for one that never waits for the PLC (M0, the operator's; continuous ones) is
  // refused as well.
  const std::pair<std::string, std::string> refused[] = {
      {"cycle_time_us: 4294967796\n",  // 2^32 + 500
       "m.yaml:1: cycle_time_us: must be a whole number from -2147483648 to 2147483647, not "
       "'4294967796'"},
      {"smoothing: {iir_axis_mask: -1}\n",
       "smoothing.iir_axis_mask: must be a whole number from 0 to 4294967295"},
      {"cycle_time_us: 99999999999999999999\n",
       "cycle_time_us: must be a whole number, not '99999999999999999999'"},
      {"cycle_time_us: 0x1F4\n", "cycle_time_us: must be a whole number, not '0x1F4'"},
      // Plain decimal only, as on the command line: strtoll took '+' and leading blanks.
      {"cycle_time_us: +500\n", "m.yaml:1: cycle_time_us: must be a whole number, not '+500'"},
      {"cycle_time_us: \" 500\"\n", "cycle_time_us: must be a whole number, not ' 500'"},
      {"compiler: {plc_redefined_m: [4294967298]}\n",
       "m.yaml:1: compiler.plc_redefined_m[0]: M4294967298 cannot be redefined (only M2-M9, M17, "
       "M29, M30, M99)"},
      {"plc:\n  m_delay_s: {4294967347: 1}\n",
       "m.yaml:2: plc.m_delay_s.4294967347: key must be a normal M-function 1..999 (the ones the "
       "PLC acknowledges)"},
      {"plc:\n  m_delay_s: {0: 1}\n", "plc.m_delay_s.0: key must be a normal M-function 1..999"},
      {"plc:\n  m_delay_s: {1001: 1}\n",
       "plc.m_delay_s.1001: key must be a normal M-function 1..999"},
      {"plc:\n  m_delay_s: {-3: 1}\n", "plc.m_delay_s.-3: key must be a normal M-function 1..999"},
      {"plc:\n  setup_before_start: later\n",
       "m.yaml:2: plc.setup_before_start: must be true or false (also yes / no, on / off), not "
       "'later'"},
  };
  for (const auto& [text, error] : refused) {
    const ConfigLoad refusal = load_config_text(text, "m.yaml");
    EXPECT_FALSE(refusal.config) << text;
    EXPECT_TRUE(has_error(refusal.errors, error)) << text;
  }
  ConfigLoad load = load_config_text("plc:\n  m_delay_s: {1: 1, 999: 2}\n", "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  EXPECT_TRUE(load.config->plc.setup_before_start);  // the default where the key is left out
  const ConfigLoad off = load_config_text("plc:\n  setup_before_start: false\n", "m.yaml");
  ASSERT_TRUE(off.config) << off.errors.front();
  EXPECT_FALSE(off.config->plc.setup_before_start);
  EXPECT_DOUBLE_EQ(load.config->plc.m_delay_s.at(999), 2.0);
  // The file's table replaces default.yaml's whole; left out, default.yaml's holds (it was
  // empty, and M51 got default_m_delay_s's 0.1 s where default.yaml shows 0.2 s).
  EXPECT_EQ(load.config->plc.m_delay_s.size(), 2u);
  const ConfigLoad shipped = load_config_file(TGM_SOURCE_DIR "/config/default.yaml");
  ASSERT_TRUE(shipped.config);
  load = load_config_text("cycle_time_us: 500\n", "m.yaml");
  ASSERT_TRUE(load.config);
  EXPECT_EQ(load.config->plc.m_delay_s, shipped.config->plc.m_delay_s);
  EXPECT_DOUBLE_EQ(load.config->plc.m_delay_s.at(51), 0.2);
  // Empty DDS names are refused as the flags refuse them.
  load = load_config_text("dds:\n  profiles_file: \"\"\n  participant_prefix: ''\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors,
                        "m.yaml:2: dds.profiles_file: must name the Fast DDS profiles file (the "
                        "shipped one: fastdds_profiles.xml), not an empty string"));
  EXPECT_TRUE(has_error(load.errors, "m.yaml:3: dds.participant_prefix: must not be empty"));
  // A prefix Fast DDS would cut (participant names end at 255 bytes, and a PLC is known by its
  // name's "-plc"), or one with control characters, is refused; 200 bytes are taken.
  load = load_config_text("dds:\n  participant_prefix: " + std::string(201, 'a') + "\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors,
                        "m.yaml:2: dds.participant_prefix: is 201 bytes long: at most 200 (Fast "
                        "DDS cuts participant names at 255)"));
  load = load_config_text("dds:\n  participant_prefix: \"a\\tb\"\n", "m.yaml");
  EXPECT_TRUE(
      has_error(load.errors, "m.yaml:2: dds.participant_prefix: must not hold control characters"));
  load = load_config_text("dds:\n  participant_prefix: " + std::string(200, 'a') + "\n", "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  // A section whose keys are all commented out is empty, as an empty file is: the defaults.
  // (Not the tools: "tools:" alone is an error, as it could mean none or default.yaml's.)
  load = load_config_text(
      "axis_defaults:\n  # backlash_mm: 0\n"
      "compiler:\n  # initial_tool: 1\nsmoothing:\n# spline_points: 0\ndds:\nplc:\n"
      "  # default_m_delay_s: 0.1\ncycle_time_us: 1000\n",
      "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  EXPECT_EQ(load.config->machine.cycle_time_us, 1000);
  EXPECT_EQ(load.config->plc.m_delay_s, shipped.config->plc.m_delay_s);
  // One M-function written two ways is given twice (the later entry won).
  load = load_config_text("plc:\n  m_delay_s: {51: 0.2, 051: 5}\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(
      has_error(load.errors, "m.yaml:2: plc.m_delay_s.051: M51 is given twice (also as 51)"))
      << load.errors.front();
  load = load_config_text("compiler: {max_call_depth: 010}\n", "m.yaml");  // not octal 8
  ASSERT_TRUE(load.config) << load.errors.front();
  EXPECT_EQ(load.config->machine.compiler.max_call_depth, 10);
}

// Decimal numbers too are plain base 10 (strtod took hexadecimal floats, '+' and leading
// blanks), and one too small to be told from 0 is refused, not read as 0.
TEST(Config, DecimalNumbersArePlainBaseTenAndNeverReadAsZero) {
  for (const char* bad : {"0x10", "0x1p4", "+16", "\" 16\"", "1e-400"}) {
    const std::string text = std::string("axis_defaults: {max_jerk_mm_s3: ") + bad + "}\n";
    const ConfigLoad load = load_config_text(text, "m.yaml");
    EXPECT_FALSE(load.config) << text;
    EXPECT_TRUE(has_error(load.errors, "m.yaml:1: axis_defaults.max_jerk_mm_s3: must be a number"))
        << text << (load.errors.empty() ? "" : load.errors.front());
  }
  // Text that reads as a number but not as a finite double says why.
  EXPECT_TRUE(has_error(
      load_config_text("axis_defaults: {max_jerk_mm_s3: 1e-400}\n", "m.yaml").errors,
      "m.yaml:1: axis_defaults.max_jerk_mm_s3: must be a number, not '1e-400' (too small for a "
      "double: it would read as 0)"));
  EXPECT_TRUE(has_error(
      load_config_text("axis_defaults: {max_jerk_mm_s3: 1e400}\n", "m.yaml").errors,
      "m.yaml:1: axis_defaults.max_jerk_mm_s3: must be a finite number, not '1e400' (beyond the "
      "range of a double)"));
  const ConfigLoad load = load_config_text("axis_defaults: {max_jerk_mm_s3: 2.5E+4}\n", "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  EXPECT_EQ(load.config->machine.interpolators[0].axes[0].max_jerk_mm_s3, 25000.0);
}

// A config is one YAML document: YAML::Load read the first and ignored the rest, so a second
// document (or anything after `...`) was silently left out.
TEST(Config, ASecondDocumentIsAnError) {
  const std::pair<std::string, std::string> refused[] = {
      {"cycle_time_us: 500\n---\ncycle_time_us: 250\n",
       "m.yaml:2:1: YAML syntax: a second YAML document starts here; the file must hold one"},
      {"cycle_time_us: 500\n...\n\n# junk follows\n}}} not: [yaml\n",
       "m.yaml:5:1: YAML syntax: a second YAML document starts here; the file must hold one"},
      {"cycle_time_us: 500\n...\ncycle_time_us: 250\n",
       "m.yaml:3:1: YAML syntax: a second YAML document starts here; the file must hold one"},
      {"---\ncycle_time_us: 500\n---\n",
       "m.yaml:3:1: YAML syntax: a second YAML document starts here; the file must hold one"},
  };
  for (const auto& [text, error] : refused) {
    const ConfigLoad load = load_config_text(text, "m.yaml");
    EXPECT_FALSE(load.config) << text;
    ASSERT_EQ(load.errors.size(), 1u) << text;
    EXPECT_EQ(load.errors[0], error) << text;
  }
  for (const char* fine : {"---\ncycle_time_us: 500\n...\n", "cycle_time_us: 500\n...\n# end\n",
                           "# nothing but a comment\n...\n"}) {
    const ConfigLoad load = load_config_text(fine, "m.yaml");
    EXPECT_TRUE(load.config) << fine << (load.errors.empty() ? "" : load.errors.front());
  }
}

// axis_defaults reach the axes whether or not the interpolators are listed, and an axis listed
// without axis_defaults has the built-in machine's limits (those of config/default.yaml).
TEST(Config, AxisDefaultsApplyToTheBuiltInAxesToo) {
  auto load = load_config_text(
      "axis_defaults: {max_jerk_mm_s3: 1234, backlash_mm: 0.01, backlash_ramp_share: 0.25}\n",
      "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  const MachineConfig builtin = MachineConfig::default_machine();
  ASSERT_EQ(load.config->machine.interpolators.size(), builtin.interpolators.size());
  for (std::size_t k = 0; k < builtin.interpolators.size(); ++k) {
    const auto& axes = load.config->machine.interpolators[k].axes;
    ASSERT_EQ(axes.size(), builtin.interpolators[k].axes.size());
    for (std::size_t i = 0; i < axes.size(); ++i) {
      EXPECT_EQ(axes[i].letter, builtin.interpolators[k].axes[i].letter);
      EXPECT_DOUBLE_EQ(axes[i].max_jerk_mm_s3, 1234.0);
      EXPECT_DOUBLE_EQ(axes[i].backlash_mm, 0.01);
      EXPECT_DOUBLE_EQ(axes[i].backlash_ramp_share, 0.25);
      EXPECT_DOUBLE_EQ(axes[i].max_velocity_mm_s,
                       builtin.interpolators[k].axes[i].max_velocity_mm_s);
    }
  }
  load = load_config_text(
      "interpolators:\n  - axes: [{letter: X}, {letter: Y, max_velocity_mm_s: 100, "
      "rapid_velocity_mm_s: 90}]\n",
      "m.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  const AxisConfig& x = load.config->machine.interpolators[0].axes[0];
  const AxisConfig& base = builtin.interpolators[0].axes[0];
  EXPECT_DOUBLE_EQ(x.max_velocity_mm_s, base.max_velocity_mm_s);
  EXPECT_DOUBLE_EQ(x.max_acceleration_mm_s2, base.max_acceleration_mm_s2);
  EXPECT_DOUBLE_EQ(x.max_jerk_mm_s3, base.max_jerk_mm_s3);
  EXPECT_DOUBLE_EQ(x.emergency_deceleration_mm_s2, base.emergency_deceleration_mm_s2);
  EXPECT_DOUBLE_EQ(load.config->machine.interpolators[0].axes[1].max_velocity_mm_s, 100.0);
}

TEST(Config, MissingFileIsAnError) {
  const auto load = load_config_file("/nonexistent/tgm.yaml");
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "/nonexistent/tgm.yaml: cannot open the config file: No such file or directory");
}

// A directory opens as a stream that reads nothing, which loaded every default silently.
// A key or a value written with an escape (a quoted scalar may hold any byte) is quoted in the
// message with the control characters shown, never sent to the operator's terminal raw.
TEST(Config, ControlCharactersFromTheFileAreShownEscaped) {
  const auto load = load_config_text(
      "cycle_time_us: \"5\\e[2J00\"\n\"dds\\tx\": 1\naxis_defaults: {backlash_mm: \"\\x07\"}\n",
      "t.yaml");
  ASSERT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 3u);
  EXPECT_NE(load.errors[0].find("t.yaml:2: dds\\tx: unknown key"), std::string::npos)
      << load.errors[0];
  EXPECT_EQ(load.errors[1], "t.yaml:1: cycle_time_us: must be a whole number, not '5\\x1b[2J00'");
  EXPECT_EQ(load.errors[2], "t.yaml:3: axis_defaults.backlash_mm: must be a number, not '\\x07'");
  for (const std::string& e : load.errors) {
    for (const char c : e) EXPECT_GE(static_cast<unsigned char>(c), 0x20) << e;
  }
}

// A finding about a value the file does not give says that it is the built-in one: lowering
// an axis's max_velocity_mm_s below the built-in rapid speed named a "250" nowhere in the file.
TEST(Config, AFindingAboutABuiltInValueSaysSo) {
  const auto load = load_config_text(
      "interpolators:\n  - axes:\n      - {letter: X, max_velocity_mm_s: 100}\n", "t.yaml");
  ASSERT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "t.yaml:3: interpolators[0].axes[0].rapid_velocity_mm_s: 250 exceeds max_velocity_mm_s "
            "100 (rapid_velocity_mm_s is not given: the built-in value)");
  // Given in the file, the value is named without the remark.
  const auto given = load_config_text(
      "interpolators:\n  - axes:\n      - {letter: X, max_velocity_mm_s: 100,\n"
      "         rapid_velocity_mm_s: 120}\n",
      "t.yaml");
  ASSERT_EQ(given.errors.size(), 1u);
  EXPECT_EQ(
      given.errors[0],
      "t.yaml:4: interpolators[0].axes[0].rapid_velocity_mm_s: 120 exceeds max_velocity_mm_s 100");
}

TEST(Config, DirectoryIsAnErrorNotAnEmptyConfig) {
  const auto load = load_config_file(TGM_SOURCE_DIR "/config");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0], TGM_SOURCE_DIR "/config: is a directory, not a config file");
}

// A config larger than 1 MiB is refused before yaml-cpp reads it: at about 500 bytes a node,
// a 16 MB list of zeros (under the 16 MiB bound it had) took 4.3 GB and 39 s.
TEST(Config, AConfigOverOneMibIsRefusedUnread) {
  const std::string path =
      ::testing::TempDir() + "big_config_" + std::to_string(::getpid()) + ".yaml";
  std::string text = "cycle_time_us: 500\n";
  while (text.size() <= kMaxConfigBytes) text += "# padding, as a long comment block would be\n";
  std::ofstream(path) << text;
  const ConfigLoad load = load_config_file(path);
  EXPECT_FALSE(load.config);
  EXPECT_EQ(load.errors, std::vector<std::string>{path + ": more than 1 MiB: not a config file"});
  text.resize(kMaxConfigBytes);
  text.back() = '\n';
  std::ofstream(path) << text;
  const ConfigLoad whole = load_config_file(path);
  EXPECT_TRUE(whole.config) << whole.errors.front();
  std::remove(path.c_str());
}

// Only a regular file is read as a config: a FIFO without a writer blocked the start in open()
// for good, and a device is said as what it is (it was read up to the bound). Read on
// another thread: should it block again, a writer frees it and the test fails, not hangs.
TEST(Config, AFifoOrADeviceIsAnErrorAndNeverBlocks) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("tgm_fifo_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string fifo = (dir / "c.fifo").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto read = std::async(std::launch::async, [&] { return load_config_file(fifo).errors; });
  if (read.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    ADD_FAILURE() << "load_config_file blocked on a FIFO";
    std::ofstream(fifo) << "cycle_time_us: 500\n";
  }
  EXPECT_EQ(read.get(),
            std::vector<std::string>{fifo + ": is a named pipe (FIFO), not a config file"});
  EXPECT_EQ(load_config_file("/dev/null").errors,
            std::vector<std::string>{"/dev/null: is a character device, not a config file"});
  // A link to a regular file is read as the file.
  std::ofstream(dir / "real.yaml") << "cycle_time_us: 250\n";
  fs::create_symlink(dir / "real.yaml", dir / "link.yaml");
  const ConfigLoad linked = load_config_file((dir / "link.yaml").string());
  ASSERT_TRUE(linked.config) << linked.errors.front();
  EXPECT_EQ(linked.config->machine.cycle_time_us, 250);
  fs::remove_all(dir);
}

// yaml-cpp keeps both entries of a repeated key and a lookup takes the first: the second value
// was dropped without a word.
TEST(Config, KeyGivenTwiceIsAnErrorWithItsLine) {
  auto load = load_config_text("cycle_time_us: 500\ncycle_time_us: 250\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "m.yaml:2: cycle_time_us: given twice"));
  load =
      load_config_text("interpolators:\n  - buffer_size: 2000\n    buffer_size: 3000\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "m.yaml:3: interpolators[0].buffer_size: given twice"));
  load = load_config_text("plc:\n  m_delay_s: {51: 0.2, 51: 0.5}\n", "m.yaml");
  EXPECT_FALSE(load.config);
  EXPECT_TRUE(has_error(load.errors, "plc.m_delay_s.51: given twice"));
  EXPECT_EQ(load.errors.size(), 1u);  // said once, not again as "M51 is given twice"
  load = load_config_text("plc:\n  m_delay_s: {51: 0.2, 50: 0.5}\n", "m.yaml");
  EXPECT_TRUE(load.config) << load.errors.front();
}

// machine_digest is a format that services and clients of other versions share: pinned by a
// value computed outside (FNV-1a 64 by hand in Python over the fields in the documented order).
TEST(MachineDigest, IsPinnedForOneAxisOfDefaults) {
  MachineConfig m;
  m.cycle_time_us = 500;
  m.interpolators.push_back({{AxisConfig{}}, 10000});
  EXPECT_EQ(machine_digest(m, 0, 1), 0x9e8234af6b47351eull);
  EXPECT_EQ(machine_digest(m, 0, 10), 0x9e8234af6b47351eull);  // it has one axis
  EXPECT_EQ(machine_digest(m, 1, 1), 0u);                      // no interpolator 1
  EXPECT_EQ(machine_digest(m, -1, 1), 0u);
  m.interpolators[0].axes[0].backlash_mm = -0.0;  // -0 is 0
  EXPECT_EQ(machine_digest(m, 0, 1), 0x9e8234af6b47351eull);
}

// Every value that shapes the motion changes it; what does not (compiler, tools, gear ratio,
// other interpolators, axes beyond the count) leaves it.
TEST(MachineDigest, FollowsWhatShapesTheMotionAndNothingElse) {
  const MachineConfig base = MachineConfig::default_machine();
  const std::uint64_t d = machine_digest(base, 0, 3);
  ASSERT_NE(d, 0u);
  EXPECT_EQ(machine_digest(base, 0, 3), d);
  using Edit = void (*)(MachineConfig&);
  const std::vector<std::pair<const char*, Edit>> shaping = {
      {"cycle_time_us", [](MachineConfig& m) { m.cycle_time_us = 250; }},
      {"spline_points", [](MachineConfig& m) { m.smoothing.spline_points = 50; }},
      {"spline_jerk", [](MachineConfig& m) { m.smoothing.spline_jerk_mm_s3 *= 2; }},
      {"iir_p", [](MachineConfig& m) { m.smoothing.iir_p_e6 += 1; }},
      {"iir_q", [](MachineConfig& m) { m.smoothing.iir_q_e6 += 1; }},
      {"iir_f", [](MachineConfig& m) { m.smoothing.iir_f_e6 += 1; }},
      {"iir_mask", [](MachineConfig& m) { m.smoothing.iir_axis_mask = 1; }},
      {"buffer_size", [](MachineConfig& m) { m.interpolators[0].buffer_size += 1; }},
      {"letter", [](MachineConfig& m) { m.interpolators[0].axes[2].letter = 'W'; }},
      {"velocity", [](MachineConfig& m) { m.interpolators[0].axes[2].max_velocity_mm_s += 1; }},
      {"acceleration",
       [](MachineConfig& m) { m.interpolators[0].axes[0].max_acceleration_mm_s2 += 1; }},
      {"jerk", [](MachineConfig& m) { m.interpolators[0].axes[1].max_jerk_mm_s3 += 1; }},
      {"rapid", [](MachineConfig& m) { m.interpolators[0].axes[1].rapid_velocity_mm_s -= 1; }},
      {"emergency",
       [](MachineConfig& m) { m.interpolators[0].axes[0].emergency_deceleration_mm_s2 += 1; }},
      {"corner",
       [](MachineConfig& m) { m.interpolators[0].axes[0].corner_velocity_tolerance_mm_s += 1; }},
      {"corner_acceleration",
       [](MachineConfig& m) {
         m.interpolators[0].axes[1].corner_acceleration_tolerance_mm_s2 = 500.0;
       }},
      {"backlash", [](MachineConfig& m) { m.interpolators[0].axes[0].backlash_mm = 0.01; }},
      {"backlash_share",
       [](MachineConfig& m) { m.interpolators[0].axes[0].backlash_ramp_share = 0.2; }},
      {"min_position", [](MachineConfig& m) { m.interpolators[0].axes[0].min_position_mm = -5; }},
      {"max_position", [](MachineConfig& m) { m.interpolators[0].axes[2].max_position_mm = 5; }},
      {"an axis fewer", [](MachineConfig& m) { m.interpolators[0].axes.pop_back(); }},
  };
  for (const auto& [name, edit] : shaping) {
    MachineConfig m = base;
    edit(m);
    EXPECT_NE(machine_digest(m, 0, 3), d) << name;
  }
  const std::vector<std::pair<const char*, Edit>> other = {
      {"ratio", [](MachineConfig& m) { m.interpolators[0].axes[0].ratio_inc_per_mm = 7; }},
      {"feed", [](MachineConfig& m) { m.compiler.default_feed_mm_per_min = 77; }},
      {"tools", [](MachineConfig& m) { m.tools.clear(); }},
      {"interpolator 1", [](MachineConfig& m) { m.interpolators[1].buffer_size += 1; }},
      {"an axis beyond",
       [](MachineConfig& m) {
         m.interpolators[0].axes.push_back(AxisConfig{});
         m.interpolators[0].axes.back().letter = 'A';
       }},
  };
  for (const auto& [name, edit] : other) {
    MachineConfig m = base;
    edit(m);
    EXPECT_EQ(machine_digest(m, 0, 3), d) << name;
  }
  // Two axes of three: the third does not count.
  MachineConfig two = base;
  two.interpolators[0].axes[2].max_jerk_mm_s3 += 1;
  EXPECT_EQ(machine_digest(two, 0, 2), machine_digest(base, 0, 2));
  EXPECT_NE(machine_digest(base, 0, 2), d);
}

// compiler.block_delete: what a line starting with '/' does (error by default, the built-in
// machine's too).
TEST(Config, BlockDeleteIsErrorRunOrSkip) {
  EXPECT_EQ(MachineConfig::default_machine().compiler.block_delete, BlockDelete::kRefuse);
  for (const auto& [word, mode] :
       {std::pair{"error", BlockDelete::kRefuse}, std::pair{"run", BlockDelete::kRun},
        std::pair{"skip", BlockDelete::kSkip}}) {
    const auto load =
        load_config_text(std::string("compiler:\n  block_delete: ") + word + "\n", "m.yaml");
    ASSERT_TRUE(load.config) << word << ": " << load.errors.front();
    EXPECT_EQ(load.config->machine.compiler.block_delete, mode) << word;
  }
  const auto load = load_config_text("compiler:\n  block_delete: on\n", "m.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "m.yaml:2: compiler.block_delete: must be error, run or skip, not 'on'");
}

// A key with no value ("key:" and nothing after it) is named at its own line. yaml-cpp marks
// such a value where the next token starts, which may be lines further down: the line after a
// comment block, or the next section. And a value the reader rejected is said once: validate()
// used to add its own finding about the built-in value left in its place.
TEST(Config, AnEmptyValueIsNamedAtItsKeysLineAndOnce) {
  struct Case {
    const char* text;
    std::string error;
  };
  const std::vector<Case> cases = {
      {"cycle_time_us:\n\n# a comment\n\nsmoothing:\n  spline_points: 0\n",
       "m.yaml:1: cycle_time_us: must be a whole number, not 'null'"},
      {"compiler:\n  initial_tool: 1\n  distance_mode:\n# more\n  max_call_depth: 16\n",
       "m.yaml:3: compiler.distance_mode: must be a string"},
      {"interpolators:\n  - buffer_size: 2000\n    axes:\n\ntools: []\n",
       "m.yaml:3: interpolators[0].axes: a list of 1..10 axes is required"},
      {"interpolators:\n  - axes:\n      - {letter: X, backlash_mm: }\n      - {letter: }\n",
       "m.yaml:3: interpolators[0].axes[0].backlash_mm: must be a number, not 'null'"},
      {"tools:\n\ncompiler:\n  initial_tool: 1\n",
       "m.yaml:1: tools: must be a list of {number, radius_mm, length_mm}"},
  };
  for (const Case& c : cases) {
    const auto load = load_config_text(c.text, "m.yaml");
    EXPECT_FALSE(load.config) << c.text;
    ASSERT_FALSE(load.errors.empty()) << c.text;
    EXPECT_EQ(load.errors[0], c.error) << c.text;
    if (std::string(c.text).find("letter: }") != std::string::npos) {
      ASSERT_EQ(load.errors.size(), 2u) << c.text;
      EXPECT_EQ(load.errors[1], "m.yaml:4: interpolators[0].axes[1].letter: must be a string");
    } else {
      EXPECT_EQ(load.errors.size(), 1u) << c.text << load.errors.back();
    }
  }
}

// Empty values are looked up by where yaml-cpp marked them (one by one, 200,000 reported
// empty values took 20 s): each of thousands is still named at its own key's line, and one in
// an anchored table at the anchor's key, however often an alias repeats it.
TEST(Config, EmptyValuesAmongThousandsAndBehindAliasesAreNamedAtTheirKeys) {
  constexpr int kTools = 3000;
  std::string text = "defs:\n  t: &t {number: 7, radius_mm: , length_mm: 2}\ntools:\n  - *t\n";
  for (int i = 1; i < kTools; ++i) text += "  - {number: , radius_mm: 1, length_mm: 1}\n";
  text += "  - *t\n";
  const auto load = load_config_text(text, "m.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 1u + kTools + 2u);
  EXPECT_EQ(load.errors[0].rfind("m.yaml:1: defs: unknown key", 0), 0u) << load.errors[0];
  EXPECT_EQ(load.errors[1], "m.yaml:2: tools[0].radius_mm: must be a number, not 'null'");
  for (int i = 1; i < kTools; ++i) {
    EXPECT_EQ(load.errors[static_cast<std::size_t>(i) + 1],
              "m.yaml:" + std::to_string(i + 4) + ": tools[" + std::to_string(i) +
                  "].number: must be a whole number, not 'null'");
  }
  const std::string last = "m.yaml:2: tools[" + std::to_string(kTools) + "].";
  EXPECT_EQ(load.errors[kTools + 1], last + "radius_mm: must be a number, not 'null'");
  EXPECT_EQ(load.errors[kTools + 2], last + "number: tool 7 is listed twice");
}

// An empty list item ("-" and nothing) is named at its `-`, past blank lines and comments
// (yaml-cpp marks it where the next token starts: the line of the next item, or of the next
// section); and so is each of thousands, looked up without a pass over the file for each.
TEST(Config, AnEmptyListItemIsNamedAtItsDash) {
  const std::pair<std::string, std::string> cases[] = {
      {"interpolators:\n  -\n\n  # a comment - with a dash\n  - {axes: [{letter: X}]}\n",
       "m.yaml:2: interpolators[0]: must be a mapping of key: value"},
      {"interpolators:\n  - axes:\n    -   # nothing here\n\n    - {letter: Y}\n",
       "m.yaml:3: interpolators[0].axes[0]: must be a mapping of key: value"},
      {"tools:\n  - {number: 1, radius_mm: 1, length_mm: 1}\n  -\n\n\ncycle_time_us: 500\n",
       "m.yaml:3: tools[1]: must be a mapping"},
      {"\xEF\xBB\xBFtools:\n  -\n\n  - {number: 1, radius_mm: 1, length_mm: 1}\n",
       "m.yaml:2: tools[0]: must be a mapping"},  // after a byte order mark
      {"tools: [{number: 1, radius_mm: 1, length_mm: 1},\n\n  ~]\n",
       "m.yaml:3: tools[1]: must be a mapping"},  // a flow list: where yaml-cpp marks it
  };
  for (const auto& [text, error] : cases) {
    const ConfigLoad load = load_config_text(text, "m.yaml");
    EXPECT_FALSE(load.config) << text;
    ASSERT_FALSE(load.errors.empty()) << text;
    EXPECT_EQ(load.errors[0].rfind(error, 0), 0u) << text << "\n" << load.errors[0];
  }
  constexpr int kTools = 20000;
  std::string text = "tools:\n";
  for (int i = 0; i < kTools; ++i) text += "  -\n  # tool " + std::to_string(i) + " left out\n";
  const ConfigLoad load = load_config_text(text, "m.yaml");
  ASSERT_EQ(load.errors.size(), static_cast<std::size_t>(kTools));
  for (int i = 0; i < kTools; i += 997) {
    const std::string& e = load.errors[static_cast<std::size_t>(i)];
    const std::string at = "m.yaml:" + std::to_string(2 * i + 2) + ": tools[" + std::to_string(i);
    EXPECT_EQ(e.rfind(at + "]: ", 0), 0u) << e;
  }
}

// A value just outside its range is printed with the digits that show it: six significant
// digits said "must be 0.01..100000 mm/s, not 100000".
TEST(Config, AValueJustOutsideItsRangeIsPrintedWithItsDigits) {
  auto load = load_config_text(
      "interpolators:\n"
      "  - axes:\n"
      "      - {letter: X, max_velocity_mm_s: 250, rapid_velocity_mm_s: 250.0000001}\n"
      "      - {letter: Y, max_velocity_mm_s: 100000.0001}\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  for (const char* want :
       {"m.yaml:3: interpolators[0].axes[0].rapid_velocity_mm_s: 250.0000001 exceeds "
        "max_velocity_mm_s 250",
        "m.yaml:4: interpolators[0].axes[1].max_velocity_mm_s: must be 0.01..100000 mm/s, not "
        "100000.0001"}) {
    EXPECT_TRUE(has_error(load.errors, want)) << "missing: " << want;
  }
}

// Every other check of MachineConfig::validate, each named with its key, its value and the
// reason, and with the line of the YAML that set it. Line coverage (session 44) showed that no
// test had given any of these values.
TEST(Config, EveryOtherBadValueIsNamedWithItsKeyAndLine) {
  auto load = load_config_text(
      "interpolators:\n"
      "  - axes:\n"
      "      - {letter: G}\n"
      "      - {letter: Y, backlash_mm: 11, backlash_ramp_share: 0.6}\n"
      "      - {letter: Z, max_velocity_mm_s: 100, rapid_velocity_mm_s: 200}\n"
      "tools:\n"
      "  - {number: 4, radius_mm: -1, length_mm: 1}\n"
      "  - {number: 4, radius_mm: 1, length_mm: -2e9}\n"
      "  - {number: 0, radius_mm: 1e308}\n"
      "  - {radius_mm: 2}\n"
      "compiler:\n"
      "  default_feed_mm_per_min: 0\n"
      "  initial_tool: -2\n"
      "  max_program_segments: 0\n"
      "  max_call_depth: 17\n"
      "smoothing:\n"
      "  spline_points: 20\n"
      "  spline_jerk_mm_s3: -5\n"
      "  iir_axis_mask: 8\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  for (const char* want :
       {"m.yaml:3: interpolators[0].axes[0].letter: 'G' is not an axis letter (D F G I J K L M N P "
        "R "
        "T are G-code words)",
        "m.yaml:4: interpolators[0].axes[1].backlash_mm: must be 0..10 mm, not 11",
        "m.yaml:4: interpolators[0].axes[1].backlash_ramp_share: must be 0.01..0.5 (a share of "
        "the axis limits), not 0.6",
        "m.yaml:5: interpolators[0].axes[2].rapid_velocity_mm_s: 200 exceeds max_velocity_mm_s 100",
        "m.yaml:7: tools[0].radius_mm: must be 0..1e9 mm, not -1",
        "m.yaml:8: tools[1].number: tool 4 is listed twice",
        // As a D word and a coordinate: 1e308 was taken.
        "m.yaml:8: tools[1].length_mm: must be -1e9..1e9 mm, not -2e+09",
        "m.yaml:9: tools[2].radius_mm: must be 0..1e9 mm, not 1e+308",
        "m.yaml:9: tools[2].number: must be 1..99999 (what a T word selects; T0 is no tool), not "
        "0",
        "m.yaml:10: tools[3].number: is required (the T word that selects the tool)",
        "m.yaml:12: compiler.default_feed_mm_per_min: must be > 0 and at most 1000000 mm/min, "
        "not 0",
        "m.yaml:13: compiler.initial_tool: must be 0..99999, not -2",
        "m.yaml:14: compiler.max_program_segments: must be 1..1000000000, not 0",
        "m.yaml:15: compiler.max_call_depth: must be 1..16, not 17",
        "m.yaml:17: smoothing.spline_points: must be 0 (off) or 50..500, not 20",
        "m.yaml:18: smoothing.spline_jerk_mm_s3: must be > 0, not -5",
        // Axes counted from 1 (8 for Z): no axis was filtered, without a word.
        "m.yaml:19: smoothing.iir_axis_mask: 8 selects no axis of any interpolator (bit 0 is axis "
        "0; the largest has 3 axes)"}) {
    EXPECT_TRUE(has_error(load.errors, want)) << "missing: " << want;
  }
  EXPECT_EQ(load.errors.size(), 17u);
  // The F word's range: 1e308 loaded, and each record without an F was refused mid-program.
  const auto fast = load_config_text("compiler:\n  default_feed_mm_per_min: 1e308\n", "f.yaml");
  EXPECT_FALSE(fast.config);
  ASSERT_EQ(fast.errors.size(), 1u);
  EXPECT_EQ(fast.errors[0],
            "f.yaml:2: compiler.default_feed_mm_per_min: must be > 0 and at most 1000000 mm/min, "
            "not 1e+308");
  EXPECT_TRUE(load_config_text("compiler:\n  default_feed_mm_per_min: 1000000\n", "f.yaml").config);

  // Tools a T word cannot select (T is 0..99999), and an M-number redefined twice.
  load = load_config_text(
      "tools:\n"
      "  - {number: 100000, radius_mm: 1, length_mm: 1}\n"
      "compiler:\n"
      "  initial_tool: 123456\n"
      "  plc_redefined_m: [6, 7, 6]\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  for (const char* want :
       {"m.yaml:2: tools[0].number: must be 1..99999 (what a T word selects; T0 is no tool), not "
        "100000",
        "m.yaml:4: compiler.initial_tool: must be 0..99999, not 123456",
        "m.yaml:5: compiler.plc_redefined_m[2]: M6 is listed twice"}) {
    EXPECT_TRUE(has_error(load.errors, want)) << "missing: " << want;
  }
  EXPECT_EQ(load.errors.size(), 3u);

  // Four interpolators; smoothing defaults that Command -1 / -2 would refuse.
  load = load_config_text(
      "interpolators: [{axes: [{letter: X}]}, {axes: [{letter: X}]}, {axes: [{letter: X}]},\n"
      "                {axes: [{letter: X}]}]\n"
      "smoothing: {spline_points: 100, spline_jerk_mm_s3: 0.2, iir_axis_mask: 1,\n"
      "            iir_p_e6: 1000, iir_q_e6: 1000000}\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  // A finding about several keys has the line of its section.
  for (const char* want :
       {"m.yaml:1: interpolators: between 1 and 3 interpolators are needed, not 4",
        "m.yaml:3: smoothing.iir: IIR damping p / (2 sqrt q) = 0.0005 (p 0.001, q 1) "
        "must be 0.2..10",
        "m.yaml:3: smoothing.spline_jerk_mm_s3: must be at least 0.5 (Command -2 takes it rounded "
        "to whole mm/s^3), not 0.2"}) {
    EXPECT_TRUE(has_error(load.errors, want)) << "missing: " << want;
  }
  EXPECT_EQ(load.errors.size(), 3u);
  // Command -2 carries the jerk in 32 bits: tgm-plc sent 3e9 as -2147483648.
  load = load_config_text("smoothing: {spline_jerk_mm_s3: 3e9}\n", "m.yaml");
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "m.yaml:1: smoothing.spline_jerk_mm_s3: must be at most 2147483647 (Command -2 "
            "carries it as a 32-bit parameter), not 3e+09");
  EXPECT_TRUE(load_config_text("smoothing: {spline_jerk_mm_s3: 2147483647}\n", "m.yaml").config);
  // One parameter out of range is said at its own key and line (it was said as smoothing.iir
  // at the group's first line, session 75), also with the filter off (mask 0): a typo stayed
  // hidden until the filter was turned on.
  for (const char* mask : {"7", "0"}) {
    load = load_config_text(std::string("smoothing:\n  iir_axis_mask: ") + mask +
                                "\n  iir_p_e6: 2000000\n  iir_f_e6: 2001000000\n",
                            "m.yaml");
    ASSERT_EQ(load.errors.size(), 1u) << mask;
    EXPECT_EQ(load.errors[0],
              "m.yaml:4: smoothing.iir_f_e6: IIR f (Command_Parameter[2]) must be "
              "1000000..2000000000 (1..2000 ms x 1e6), not 2001000000")
        << mask;
  }

  // A default that makes a built-in value of the same axes wrong is said once, at the
  // default's line (nine findings without a line when the config lists no interpolators).
  load =
      load_config_text("cycle_time_us: 500\naxis_defaults: {max_velocity_mm_s: 100}\n", "d.yaml");
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "d.yaml:2: axis_defaults.max_velocity_mm_s: the built-in rapid_velocity_mm_s (not "
            "given) 250 exceeds max_velocity_mm_s 100; 9 axes take it");
  load = load_config_text(
      "axis_defaults: {max_velocity_mm_s: 100}\ninterpolators: [{axes: [{letter: X}]}]\n",
      "d.yaml");
  ASSERT_EQ(load.errors.size(), 1u);
  EXPECT_EQ(load.errors[0],
            "d.yaml:1: axis_defaults.max_velocity_mm_s: the built-in rapid_velocity_mm_s (not "
            "given) 250 exceeds max_velocity_mm_s 100 (interpolators[0].axes[0])");

  // An empty list of axes is named at its own line, as given (it was said to be "not given:
  // the built-in value", without a line); a letter that is not one of A..Z says what is.
  load = load_config_text(
      "interpolators:\n"
      "  - axes: [{letter: X}]\n"
      "  - buffer_size: 1000\n"
      "    axes: []\n"
      "  - axes: [{letter: 1}]\n",
      "m.yaml");
  EXPECT_FALSE(load.config);
  for (const char* want :
       {"m.yaml:4: interpolators[1].axes: between 1 and 10 axes are needed, not 0",
        "m.yaml:5: interpolators[2].axes[0].letter: '1' is not an axis letter (A..Z, except the "
        "G-code words D F G I J K L M N P R T)"}) {
    EXPECT_TRUE(has_error(load.errors, want)) << "missing: " << want;
  }
  EXPECT_EQ(load.errors.size(), 2u);
  for (const std::string& e : load.errors) {
    EXPECT_EQ(e.find("not given"), std::string::npos) << e;
  }

  // Eleven or twelve axes without letters: the count is the one error. The axes past the tenth
  // have no built-in letter, and each was also said to have the letter '?' (review of session
  // 77); a letter given to one is still checked.
  for (const char* extra : {"{}", "{}, {}"}) {
    load = load_config_text(std::string("interpolators:\n  - axes: [{}, {}, {}, {}, {}, {}, {}, "
                                        "{}, {}, {}, ") +
                                extra + "]\n",
                            "a.yaml");
    EXPECT_FALSE(load.config);
    ASSERT_EQ(load.errors.size(), 1u) << (load.errors.empty() ? "" : load.errors.back());
    EXPECT_EQ(load.errors[0], std::string("a.yaml:2: interpolators[0].axes: between 1 and 10 axes "
                                          "are needed, not ") +
                                  (std::string(extra) == "{}" ? "11" : "12"));
  }
  load = load_config_text(
      "interpolators:\n  - axes: [{}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {letter: D}]\n",
      "a.yaml");
  ASSERT_EQ(load.errors.size(), 2u);
  EXPECT_TRUE(has_error(load.errors,
                        "a.yaml:2: interpolators[0].axes[10].letter: 'D' is not an "
                        "axis letter (D F G I J K L M N P R T are G-code words)"));
}

}  // namespace
}  // namespace tgm

namespace tgm {
namespace {

// Soft limits per axis: read, defaulting to +-1e9 (none), and refused where they make no
// range.
TEST(Config, SoftLimitsAreReadAndMustMakeARange) {
  auto load = load_config_text(
      "interpolators:\n  - axes: [{letter: X, min_position_mm: -5, max_position_mm: 400}, "
      "{letter: Y}]\n",
      "s.yaml");
  ASSERT_TRUE(load.config) << load.errors.front();
  const auto& axes = load.config->machine.interpolators[0].axes;
  EXPECT_EQ(axes[0].min_position_mm, -5.0);
  EXPECT_EQ(axes[0].max_position_mm, 400.0);
  EXPECT_EQ(axes[1].min_position_mm, -1e9);
  EXPECT_EQ(axes[1].max_position_mm, 1e9);
  load = load_config_text(
      "interpolators:\n  - axes: [{letter: X, min_position_mm: 10, max_position_mm: 10}, "
      "{letter: Y, max_position_mm: 2e9}]\n",
      "s.yaml");
  EXPECT_FALSE(load.config);
  ASSERT_EQ(load.errors.size(), 2u);  // and no summary line: the caller counts them
  EXPECT_EQ(load.errors[0],
            "s.yaml:2: interpolators[0].axes[0].max_position_mm: 10 is not above "
            "min_position_mm 10");
  EXPECT_EQ(load.errors[1],
            "s.yaml:2: interpolators[0].axes[1].max_position_mm: must be -1e9..1e9 mm, not "
            "2e+09");
}

}  // namespace
}  // namespace tgm
