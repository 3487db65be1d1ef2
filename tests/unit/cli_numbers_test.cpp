// The command-line number readers shared by tgm-service, tgm-plc and tgm-hmi.
#include "tgm/cli_numbers.hpp"

#include <gtest/gtest.h>

#include <climits>
#include <string>
#include <utility>

namespace tgm {
namespace {

TEST(CliNumbers, IntegersMustBeWholeAndInRange) {
  long long v = -7;
  EXPECT_TRUE(parse_integer("0", 0LL, 10LL, v));
  EXPECT_EQ(v, 0);
  EXPECT_TRUE(parse_integer("-3", -5LL, 5LL, v));
  EXPECT_EQ(v, -3);
  EXPECT_TRUE(parse_integer("9223372036854775807", 0LL, LLONG_MAX, v));
  EXPECT_EQ(v, LLONG_MAX);
  v = 42;
  for (const char* bad : {"", " ", "11", "-6", "1.5", "3x", "x3", "0x10", "1e3",
                          "99999999999999999999", "-99999999999999999999",
                          // Only plain decimal: strtoll took a leading blank and '+'.
                          " 3", "\t3", "\n3", "+3", "3 ", "-", "--3", "+-3", "-+3", "0X3"}) {
    EXPECT_FALSE(parse_integer(bad, -5LL, 10LL, v)) << "'" << bad << "'";
    EXPECT_EQ(v, 42) << "a refused text must leave the value alone: '" << bad << "'";
  }
}

TEST(CliNumbers, IntDestinationsNeverWrapAround) {
  int v = 5;
  EXPECT_TRUE(parse_integer("2", 0, 2, v));
  EXPECT_EQ(v, 2);
  // 2^32 would be 0 after a cast to int; 2^31 would be INT_MIN.
  EXPECT_FALSE(parse_integer("4294967296", 0, 2, v));
  EXPECT_FALSE(parse_integer("2147483648", INT_MIN, INT_MAX, v));
  EXPECT_EQ(v, 2);
  EXPECT_TRUE(parse_integer("-2147483648", INT_MIN, INT_MAX, v));
  EXPECT_EQ(v, INT_MIN);
}

TEST(CliNumbers, DecimalsMustBeFinite) {
  double v = 1.25;
  EXPECT_TRUE(parse_finite("0.5", v));
  EXPECT_EQ(v, 0.5);
  EXPECT_TRUE(parse_finite("-2e-3", v));
  EXPECT_EQ(v, -2e-3);
  EXPECT_TRUE(parse_finite("1e308", v));
  EXPECT_EQ(v, 1e308);
  v = 7.0;
  for (const char* bad :
       {"", "inf", "-inf", "Infinity", "nan", "NAN(1)", "1e999", "-1e999", "0.5s", "s0.5", "1,5",
        "--1",
        // strtod read hexadecimal, leading blanks and '+' too: the comments
        // (and the messages) say a base-10 number.
        "0x10", "0x1p-1", "-0x1p-1", "0X1P3", " 1", "\t1", "\n1", "+1", "+0.5", "1 ", ".", "-",
        "-.", "e5", ".e5", "1e", "1e+", "1e-", "1e5.0", "1.5.0", "1..5", "1_000",
        // A non-zero value that would read as 0 (strtod gave 0 for it).
        "1e-400", "-1e-400", "0.0001e-320", "123e-999999999999"}) {
    EXPECT_FALSE(parse_finite(bad, v)) << "'" << bad << "'";
    EXPECT_EQ(v, 7.0) << "a refused text must leave the value alone: '" << bad << "'";
  }
  // An embedded NUL ended strtod's reading: "1" and the rest was never looked at.
  long long n = 4;
  EXPECT_FALSE(parse_finite(std::string("1\0x", 3), v));
  EXPECT_FALSE(parse_integer(std::string("1\0x", 3), 0LL, 10LL, n));
  EXPECT_EQ(n, 4);
}

// The plain forms of a decimal number are all read: a fraction without a digit on one side,
// an exponent with or without sign, a zero however written, a subnormal (not 0) value.
TEST(CliNumbers, EveryPlainDecimalFormIsRead) {
  const std::pair<const char*, double> cases[] = {
      {"7", 7.0},     {"-7", -7.0},       {"007", 7.0},          {"1.", 1.0},
      {".5", 0.5},    {"-.5", -0.5},      {"2.5e3", 2500.0},     {"2.5E+3", 2500.0},
      {"25e-1", 2.5}, {"0", 0.0},         {"-0", -0.0},          {"0e-999", 0.0},
      {"0.000", 0.0}, {"1e-310", 1e-310}, {"4.9e-324", 4.9e-324}};
  for (const auto& [text, want] : cases) {
    double v = 99.0;
    EXPECT_TRUE(parse_finite(text, v)) << text;
    EXPECT_EQ(v, want) << text;
  }
  long long n = 0;
  EXPECT_TRUE(parse_integer("-0", -1LL, 1LL, n));
  EXPECT_EQ(n, 0);
  EXPECT_TRUE(parse_integer("0010", 0LL, 100LL, n));  // base 10, not octal 8
  EXPECT_EQ(n, 10);
}

}  // namespace
}  // namespace tgm
