// Fixed-point text of a double with 0..9 decimals, exactly as printf's "%.Nf" (and
// std::to_chars with chars_format::fixed) writes it, for the CSV of `tgm-hmi simulate`: a long
// program writes millions of rows of dozens of numbers, and libstdc++'s general fixed-precision
// conversion took a third of such a run (session 50, perf).
//
// Exact, not approximate: the double is m 2^e with an integer m < 2^53, so its value times 10^N
// is m 10^N 2^e, an integer (m 10^N < 2^83) shifted by e. That is done in 128-bit integers and
// rounded to nearest with ties to even, as glibc's printf and the standard's to_chars round the
// exact binary value. Magnitudes of 2^50 (1.1e15) and more, infinities and NaN go to
// std::to_chars.
// Header-only, no DDS (unit-tested against std::to_chars and snprintf).
#pragma once

#include <array>
#include <charconv>
#include <cstdint>
#include <cstring>

namespace tgm::hmi {

__extension__ typedef unsigned __int128 FixedTextU128;  // GCC / Clang: exact 128-bit products

//! Writes `v` with `precision` decimals (0..9) into [first, last) as printf("%.*f") does;
//! returns the end of the text, or `last` with nothing written when the text does not fit
//! (at most 27 characters below 2^50, else up to 320: the to_chars fallback).
inline char* fixed_chars(char* first, char* last, double v, int precision) {
  static constexpr std::array<std::uint64_t, 10> kPow10 = {
      1u, 10u, 100u, 1000u, 10000u, 100000u, 1000000u, 10000000u, 100000000u, 1000000000u};
  std::uint64_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  const int biased = static_cast<int>((bits >> 52) & 0x7ffu);
  // Below 2^50 the scaled value stays under 2^50 10^9 < 2^80.
  if (precision < 0 || precision > 9 || biased >= 1023 + 50) {
    return std::to_chars(first, last, v, std::chars_format::fixed, precision).ptr;
  }
  const bool negative = (bits >> 63) != 0;
  std::uint64_t mant = bits & ((std::uint64_t{1} << 52) - 1u);
  int shift = 1075 - biased;  // |v| = mant 2^-shift, shift >= 3 below 2^50
  if (biased == 0) {
    shift = 1074;  // subnormal
  } else {
    mant |= std::uint64_t{1} << 52;
  }
  // The integer part exactly, then the fraction's bits times 10^N, rounded (no division).
  std::uint64_t int_part = shift < 64 ? mant >> shift : 0u;
  const std::uint64_t frac_bits = shift < 64 ? mant & ((std::uint64_t{1} << shift) - 1u) : mant;
  const std::uint64_t scale = kPow10[static_cast<std::size_t>(precision)];
  const FixedTextU128 scaled = static_cast<FixedTextU128>(frac_bits) * scale;  // < 2^93
  std::uint64_t frac = 0;
  if (shift < 120) {
    frac = static_cast<std::uint64_t>(scaled >> shift);  // < 10^N
    const FixedTextU128 rem = scaled - (static_cast<FixedTextU128>(frac) << shift);
    const FixedTextU128 half = static_cast<FixedTextU128>(1) << (shift - 1);
    // Ties to even: of the last digit written (10^N is even for N >= 1).
    const bool odd = ((precision == 0 ? int_part : frac) & 1u) != 0;
    if (rem > half || (rem == half && odd)) ++frac;
    if (frac == scale) {
      frac = 0;
      ++int_part;
    }
  }  // else below 2^-37 of a unit in the last place: rounds to 0
  // Written in place from the end (a memcpy of a few bytes cost more than the digits).
  std::size_t int_digits = 1;
  for (std::uint64_t x = int_part; x >= 10u; x /= 10u) ++int_digits;
  const std::size_t len = (negative ? 1u : 0u) + int_digits +
                          (precision > 0 ? 1u + static_cast<std::size_t>(precision) : 0u);
  if (static_cast<std::size_t>(last - first) < len) return last;
  char* d = first + len;
  for (int k = 0; k < precision; ++k) {
    *--d = static_cast<char>('0' + frac % 10u);
    frac /= 10u;
  }
  if (precision > 0) *--d = '.';
  do {
    *--d = static_cast<char>('0' + int_part % 10u);
    int_part /= 10u;
  } while (int_part != 0);
  if (negative) *--d = '-';
  return first + len;
}

}  // namespace tgm::hmi
