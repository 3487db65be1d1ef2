// tgm-hmi run --plot's point series: every point at its spacing until the capacity, then
// thinned by half with the spacing doubled; the whole extent and the last point are kept.
#include "plot_series.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace tgm::hmi {
namespace {

TEST(PlotSeries, APathKeepsPointsAtItsSpacingAndItsEnd) {
  PlotSeries s(PlotSeries::Spacing::kDistance, 0.05, 1000);
  for (int k = 0; k <= 100; ++k) s.add({0.01 * k, 0.0});  // 1 mm in 0.01 mm steps
  const auto p = s.points();
  // 0, 0.05, ..., 1.0 (rounding may put a point a step later), and the end.
  EXPECT_GE(p.size(), 18u);
  EXPECT_LE(p.size(), 22u);
  EXPECT_EQ(p.front().first, 0.0);
  EXPECT_DOUBLE_EQ(p.back().first, 1.0);
  for (std::size_t i = 1; i + 1 < p.size(); ++i)
    EXPECT_GE(p[i].first - p[i - 1].first, 0.05 - 1e-12);
}

TEST(PlotSeries, ALongRunStaysWithinItsCapacityAndKeepsItsWholeExtent) {
  constexpr std::size_t kCap = 1000;
  PlotSeries path(PlotSeries::Spacing::kDistance, 0.05, kCap);
  PlotSeries trace(PlotSeries::Spacing::kFirst, 0.0, kCap);
  // 3 million points along a circle of r 100 mm, 10 laps (0.02 mm apart), and a speed trace
  // of as many samples 500 us apart.
  constexpr int kPoints = 3'000'000;
  std::size_t most = 0;  // the largest size seen along the way
  for (int k = 0; k < kPoints; ++k) {
    const double a = 2.0 * 3.141592653589793 * 10.0 * k / kPoints;
    path.add({100.0 * std::cos(a), 100.0 * std::sin(a)});
    trace.add({0.0005 * k, 1000.0 + (k % 7)});
    if (k % 10'000 == 0) most = std::max({most, path.points().size(), trace.points().size()});
  }
  const auto p = path.points(), t = trace.points();
  EXPECT_LE(p.size(), kCap + 1);  // the kept points and the last one
  EXPECT_LE(t.size(), kCap + 1);
  EXPECT_GT(p.size(), kCap / 2);  // thinned by half at most once past the capacity
  EXPECT_GT(t.size(), kCap / 2);
  EXPECT_GT(path.spacing(), 0.05);  // doubled at each thinning
  EXPECT_GT(trace.spacing(), 0.0);
  // The whole run: the trace from its first to its last sample, the path all around.
  EXPECT_EQ(t.front().first, 0.0);
  EXPECT_DOUBLE_EQ(t.back().first, 0.0005 * (kPoints - 1));
  for (std::size_t i = 1; i < t.size(); ++i) ASSERT_GT(t[i].first, t[i - 1].first);
  double lo_x = 1e9, hi_x = -1e9;
  for (const auto& q : p) {
    lo_x = std::min(lo_x, q.first);
    hi_x = std::max(hi_x, q.first);
  }
  EXPECT_LT(lo_x, -99.0);
  EXPECT_GT(hi_x, 99.0);
  EXPECT_LE(most, kCap + 1);
}

}  // namespace
}  // namespace tgm::hmi
