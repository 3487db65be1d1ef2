#include "tgm/soft_limits.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "tgm/printable.hpp"

namespace tgm {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Rounding of an end point computed from offsets, incremental moves or an arc's crossing
// (a point programmed on the limit itself is within it).
constexpr double kSlackMm = 1e-6;

std::string axis_name(const InterpolatorConfig& ip, int a) {
  return std::string(1, ip.axes[static_cast<std::size_t>(a)].letter);
}

// Empty when `value` of axis a lies within its limits.
std::string beyond(const InterpolatorConfig& ip, int a, double value, const char* lead,
                   const char* verb) {
  const AxisConfig& ax = ip.axes[static_cast<std::size_t>(a)];
  const bool above = value > ax.max_position_mm + kSlackMm;
  if (!above && !(value < ax.min_position_mm - kSlackMm)) return {};
  const std::string letter = axis_name(ip, a);
  return std::string(lead) + letter + shortest_text(value) + verb + " the soft limit of axis " +
         letter + " (" +
         (above ? "max_position_mm " + shortest_text(ax.max_position_mm)
                : "min_position_mm " + shortest_text(ax.min_position_mm)) +
         " in the config)";
}

}  // namespace

bool has_soft_limits(const InterpolatorConfig& ip) {
  return std::any_of(ip.axes.begin(), ip.axes.end(), [](const AxisConfig& a) {
    return a.min_position_mm > -kMaxCoordinateMm || a.max_position_mm < kMaxCoordinateMm;
  });
}

std::string soft_limit_problem(const Segment& s, const double* start,
                               const InterpolatorConfig& ip) {
  if (!s.is_motion()) return {};
  const int n = static_cast<int>(ip.axes.size());
  for (int a = 0; a < n; ++a) {
    if (std::string why =
            beyond(ip, a, s.end[static_cast<std::size_t>(a)], "end point ", " is beyond");
        !why.empty()) {
      return why;
    }
  }
  if (!s.is_arc()) return {};
  std::string letters;
  for (const AxisConfig& ax : ip.axes) letters.push_back(ax.letter);
  const PlaneAxes pa = plane_axes(s.plane, letters);
  if (pa.first >= n || pa.second >= n) return {};
  const auto f = static_cast<std::size_t>(pa.first), g = static_cast<std::size_t>(pa.second);
  const double sx = start[f] - s.center[0], sy = start[g] - s.center[1];
  const double ex = s.end[f] - s.center[0], ey = s.end[g] - s.center[1];
  const double r = std::max(std::hypot(sx, sy), std::hypot(ex, ey));
  const bool ccw = s.type == SegmentType::kArcCcw;
  const double th0 = std::atan2(sy, sx), th1 = std::atan2(ey, ex);
  double sweep = ccw ? th1 - th0 : th0 - th1;
  while (sweep <= 0.0) sweep += 2.0 * kPi;
  if (std::hypot(ex - sx, ey - sy) < 1e-9) sweep = 2.0 * kPi;  // a full circle
  sweep += 2.0 * kPi * std::max(0, s.turns);
  // The rays along +first, +second, -first, -second the sweep passes (each reached within a
  // full turn, so four at most).
  for (int k = 0; k < 4; ++k) {
    const double ray = k * 0.5 * kPi;
    double to = ccw ? ray - th0 : th0 - ray;
    while (to < 0.0) to += 2.0 * kPi;
    while (to >= 2.0 * kPi) to -= 2.0 * kPi;
    if (to > sweep || to < 1e-12) continue;  // not passed, or the start (a line's too is free)
    const int axis = (k % 2 == 0) ? pa.first : pa.second;
    const double centre = (k % 2 == 0) ? s.center[0] : s.center[1];
    const double value = centre + (k < 2 ? r : -r);
    if (std::string why = beyond(ip, axis, value, "the arc passes ", ", beyond"); !why.empty())
      return why;
  }
  return {};
}

}  // namespace tgm
