// Comparing what two limit checks found (a stepped and a fast-forwarded run, a trace and the
// same cycles one by one).
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "tgm/limit_checker.hpp"

namespace tgm::test {

// Expects the same violations, field for field and in the same order, and the same peaks of
// the first `axes` axes, bit for bit. Call it inside ASSERT_NO_FATAL_FAILURE: lists of
// different lengths are a fatal failure.
inline void expect_same_findings(const std::vector<LimitViolation>& a,
                                 const std::vector<LimitViolation>& b,
                                 const std::array<AxisPeaks, kMaxAxes>& peaks_a,
                                 const std::array<AxisPeaks, kMaxAxes>& peaks_b, int axes,
                                 const std::string& ctx) {
  ASSERT_EQ(a.size(), b.size()) << ctx;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const std::string at = ctx + " violation " + std::to_string(i);
    EXPECT_EQ(a[i].cycle, b[i].cycle) << at;
    EXPECT_EQ(a[i].line, b[i].line) << at;
    EXPECT_EQ(a[i].axis, b[i].axis) << at;
    EXPECT_EQ(a[i].quantity, b[i].quantity) << at;
    EXPECT_EQ(a[i].value, b[i].value) << at;
    EXPECT_EQ(a[i].limit, b[i].limit) << at;
  }
  for (int i = 0; i < axes; ++i) {
    const AxisPeaks& pa = peaks_a[static_cast<std::size_t>(i)];
    const AxisPeaks& pb = peaks_b[static_cast<std::size_t>(i)];
    const std::string at = ctx + " axis " + std::to_string(i);
    EXPECT_EQ(pa.velocity_mm_s, pb.velocity_mm_s) << at;
    EXPECT_EQ(pa.acceleration_mm_s2, pb.acceleration_mm_s2) << at;
    EXPECT_EQ(pa.jerk_mm_s3, pb.jerk_mm_s3) << at;
    EXPECT_EQ(pa.corner_step_mm_s, pb.corner_step_mm_s) << at;
  }
}

}  // namespace tgm::test
