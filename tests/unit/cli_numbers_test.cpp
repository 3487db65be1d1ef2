// The command-line number readers shared by tgm-service, tgm-plc and tgm-hmi.
#include "tgm/cli_numbers.hpp"

#include <gtest/gtest.h>

#include <climits>
#include <string>

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
                          "99999999999999999999", "-99999999999999999999"}) {
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
  for (const char* bad : {"", "inf", "-inf", "Infinity", "nan", "NAN(1)", "1e999", "-1e999", "0.5s",
                          "s0.5", "1,5", "--1"}) {
    EXPECT_FALSE(parse_finite(bad, v)) << "'" << bad << "'";
    EXPECT_EQ(v, 7.0) << "a refused text must leave the value alone: '" << bad << "'";
  }
}

}  // namespace
}  // namespace tgm
