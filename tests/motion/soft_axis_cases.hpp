// Two-axis machines whose jerk limits differ by orders of magnitude, with a few moves each that
// made the planner exceed the soft axis' jerk (found by the wide-envelope sweep; see
// core/MOTION_LOG.md, "Junctions into a lower jerk"). The motion tests keep them as regression
// cases.
#pragma once

#include <array>
#include <vector>

#include "program_builder.hpp"
#include "tgm/config.hpp"
#include "tgm/intercode.hpp"

namespace tgm::test {

struct AxisLimits {
  double v, a, j, tol;  // [mm/s], [mm/s^2], [mm/s^3], corner tolerance [mm/s]
};

struct SoftAxisCase {
  int cycle_us;
  AxisLimits stiff, soft;                    // X, Y
  std::vector<std::array<double, 3>> moves;  // x, y, F [mm/min]

  MachineConfig machine() const {
    MachineConfig m = MachineConfig::default_machine();
    m.cycle_time_us = cycle_us;
    auto& axes = m.interpolators[0].axes;
    axes.resize(2);
    const AxisLimits lim[2] = {stiff, soft};
    for (std::size_t i = 0; i < 2; ++i) {
      axes[i].letter = i == 0 ? 'X' : 'Y';
      axes[i].max_velocity_mm_s = axes[i].rapid_velocity_mm_s = lim[i].v;
      axes[i].max_acceleration_mm_s2 = lim[i].a;
      axes[i].emergency_deceleration_mm_s2 = 2.0 * lim[i].a;
      axes[i].max_jerk_mm_s3 = lim[i].j;
      axes[i].corner_velocity_tolerance_mm_s = lim[i].tol;
    }
    return m;
  }

  //! The moves from the origin, then M2.
  Program program() const {
    ProgramBuilder b(2);
    for (const auto& mv : moves) b.line({mv[0], mv[1]}, mv[2]);
    b.end();
    return b.program();
  }
};

inline std::vector<SoftAxisCase> soft_axis_cases() {
  return {
      // Wide sweep seed 1 program 60: Y jerk 23,000 > 347 at the final stop.
      {250, {61.7, 8333.0, 2.408e5, 7.822}, {40.0, 173.7, 347.4, 0.127},
       {{0.9459, 0.0, 211.0}, {2.3396, 2.2001, 81.4}, {4.4766, -2.0658, 81.4}}},
      // Wide sweep seed 1 program 115: a 0.26 mm/s corner from X onto a Y-led line, stall at
      // v = 0 with -880 mm/s^2, Y jerk 3.9e5 > 823. The calculation step that could reach the
      // junction already had Y's jerk limit: the braking has to be done before it.
      {500, {41.8, 8360.0, 4.18e6, 0.7192}, {2057.0, 411.3, 822.7, 0.1923},
       {{-4.66325, 0.01271, 5650.0}, {3.16951, 0.01271, 13050.0}, {7.24153, 4.62242, 13610.0}}},
      // The same with two more moves: the corner braking left -134 mm/s^2, and the landing on
      // the feed behind it limited taking that back to Y's jerk (stall, Y jerk 1.5e5).
      {500, {41.8, 8360.0, 4.18e6, 0.7192}, {2057.0, 411.3, 822.7, 0.1923},
       {{-4.66325, 0.01271, 5650.0}, {3.16951, 0.01271, 13050.0}, {7.24153, 4.62242, 13610.0},
        {3.40833, 6.95940, 13610.0}, {2.56256, 10.70280, 13610.0}}},
  };
}

}  // namespace tgm::test
