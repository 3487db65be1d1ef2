// tgm-hmi simulate's fixed-point CSV numbers (fixed_text.hpp) against two references: the
// standard's std::to_chars(fixed, N) and C's snprintf("%.*f"), which must agree with each other
// too. Pinned values for the cases that decide correctness (exact ties, signs of zero, carries
// into the integer part, subnormals, the fallback above 2^50), then a seeded sweep:
//   build/tests/unit/tgm_unit_tests --gtest_filter='FixedText.*' --seed=N --count=N
// (default seed 1, 400,000 values per kind).
#include "fixed_text.hpp"

#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include "../support/splitmix64.hpp"
#include "../support/test_params.hpp"

namespace tgm::hmi {
namespace {

std::string ours(double v, int precision) {
  char buf[400];
  char* end = fixed_chars(buf, buf + sizeof buf, v, precision);
  return {buf, end};
}

std::string standard(double v, int precision) {
  char buf[400];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, precision);
  return {buf, r.ptr};
}

std::string c_printf(double v, int precision) {
  char buf[400];
  const int n = std::snprintf(buf, sizeof buf, "%.*f", precision, v);
  return {buf, static_cast<std::size_t>(n)};
}

TEST(FixedText, PinnedValuesAsPrintfWritesThem) {
  struct Case {
    double v;
    int precision;
    const char* text;
  };
  const Case cases[] = {
      {0.0, 9, "0.000000000"},
      {-0.0, 6, "-0.000000"},
      {-1e-12, 9, "-0.000000000"},  // negative, rounded to zero: the sign stays
      {0.5, 0, "0"},                // exact ties go to the even last digit
      {1.5, 0, "2"},
      {2.5, 0, "2"},
      {-2.5, 0, "-2"},
      {0.0078125, 6, "0.007812"},  // 1/128: a tie at the 7th decimal, 2 is even
      {0.0234375, 6, "0.023438"},  // 3/128: 7 is odd, up
      {0.125, 2, "0.12"},
      {0.375, 2, "0.38"},
      {0.1, 9, "0.100000000"},
      {123.456, 3, "123.456"},
      {0.0005, 3, "0.001"},               // 0.0005000000000000000104...: above the tie
      {0.0015, 3, "0.002"},               // 0.00150000000000000003...
      {0.0025, 3, "0.003"},               // 0.00250000000000000005...
      {9.9999999996, 9, "10.000000000"},  // carries into the integer part
      {-999999999.9999999995, 9, "-1000000000.000000000"},
      {4.9406564584124654e-324, 9, "0.000000000"},     // the smallest subnormal
      {1125899906842623.75, 1, "1125899906842623.8"},  // just below 2^50: 0.75 -> .8
      {1125899906842624.0, 2, "1125899906842624.00"},  // 2^50: to_chars
      {1e15, 0, "1000000000000000"},                   // to_chars
  };
  for (const Case& c : cases) {
    EXPECT_EQ(ours(c.v, c.precision), c.text) << "%.*f of " << c.v << " with " << c.precision;
    EXPECT_EQ(c_printf(c.v, c.precision), c.text) << "the reference itself, " << c.v;
  }
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(ours(inf, 6), standard(inf, 6));
  EXPECT_EQ(ours(-inf, 6), standard(-inf, 6));
  EXPECT_EQ(ours(std::nan(""), 6), standard(std::nan(""), 6));
  EXPECT_EQ(ours(1e300, 3), standard(1e300, 3));
  EXPECT_EQ(ours(-1e300, 3), c_printf(-1e300, 3));
}

TEST(FixedText, TextThatDoesNotFitWritesNothing) {
  char buf[8];
  std::memset(buf, 'x', sizeof buf);
  EXPECT_EQ(fixed_chars(buf, buf + 8, 12345.678, 3), buf + 8);  // needs 9
  EXPECT_EQ(std::string(buf, 8), "xxxxxxxx");
  EXPECT_EQ(fixed_chars(buf, buf + 8, -1234.56, 2), buf + 8);  // needs 8 with the sign: fits
  EXPECT_EQ(std::string(buf, 8), "-1234.56");
}

// Random values of every kind a CSV column can hold, each against both references.
TEST(FixedText, SeededSweepEqualsToCharsAndPrintf) {
  const std::uint64_t seed = test::param_u64("seed", "TGM_SEED", 1);
  const std::uint64_t count = test::param_u64("count", "TGM_COUNT", 400'000);
  test::SplitMix64 rng{seed};
  std::uint64_t checked = 0, failures = 0;
  auto check = [&](double v, int precision, const char* kind) {
    const std::string want = standard(v, precision);
    const std::string got = ours(v, precision);
    ++checked;
    if (got != want || want != c_printf(v, precision)) {
      if (++failures <= 20) {
        ADD_FAILURE() << kind << " value " << std::hexfloat << v << std::defaultfloat << " (" << v
                      << ") with " << precision << " decimals: ours '" << got << "', to_chars '"
                      << want << "', printf '" << c_printf(v, precision) << "' (seed " << seed
                      << ")";
      }
    }
  };
  for (std::uint64_t i = 0; i < count; ++i) {
    const int p = static_cast<int>(rng.next() % 10);
    // Any bit pattern below 2^52 (about 4.5e15; the fallback above 2^50 included), any sign.
    std::uint64_t bits = rng.next() & 0x800f'ffff'ffff'ffffULL;
    bits |= (rng.next() % (1023 + 52)) << 52;
    double v = 0.0;
    std::memcpy(&v, &bits, sizeof v);
    check(v, p, "bit pattern");
    // Coordinates as programs and motion make them: decimals with a few places, scaled.
    const double decimal = std::round(rng.uniform(-2e6, 2e6)) / std::pow(10.0, rng.next() % 10);
    check(decimal * std::pow(10.0, static_cast<double>(rng.next() % 7) - 3.0), p, "decimal");
    // Binary fractions, multiples of 2^-(p + 1 .. p + 4): the odd multiples of 2^-(p + 1) are
    // exact ties at the last decimal written ((2k + 1) 5^p / 2 units of 10^-p).
    const double tie = static_cast<double>(rng.next() % 2'000'001) *
                       std::ldexp(1.0, -static_cast<int>(p + 1 + rng.next() % 4));
    check(rng.next() % 2 ? tie : -tie, p, "binary fraction");
    // Next to the rounding boundaries of the decimal written, a few units in the last place off.
    const double boundary = (std::round(rng.uniform(-1e7, 1e7)) + 0.5) / std::pow(10.0, p);
    double near = boundary;
    const int ulps = static_cast<int>(rng.next() % 7) - 3;
    for (int u = 0; u < std::abs(ulps); ++u) near = std::nextafter(near, ulps > 0 ? 1e300 : -1e300);
    check(near, p, "boundary");
  }
  EXPECT_EQ(failures, 0u) << "of " << checked << " values";
}

}  // namespace
}  // namespace tgm::hmi
