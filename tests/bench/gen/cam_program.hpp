// A CAM-like G-code program for compiler benchmarks: a smooth tool path made of short G1 moves
// (0.05..0.5 mm) and small tangent G2/G3 arcs by IJK (radius 0.5..5 mm), in G90 or G91 as the
// first line says, with F words now and then and an occasional retract/plunge. Every arc is
// consistent to ~1e-4 mm, so LinuxCNC's rs274 accepts the program too. Deterministic for a seed
// on every platform (tests/support/splitmix64.hpp).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "../../support/splitmix64.hpp"

namespace tgm::bench {

//! Appends a program of exactly `lines` lines (at least 8) to `out`.
inline void generate_cam_program(std::string& out, long lines, std::uint64_t seed,
                                 bool incremental) {
  tgm::test::SplitMix64 rng{seed};
  constexpr double kPi = 3.14159265358979323846;
  constexpr double kBox = 100.0;  // the path stays within +-kBox mm in X and Y
  if (lines < 8) lines = 8;
  out.reserve(out.size() + static_cast<std::size_t>(lines) * 28);

  char buf[160];
  long written = 0;
  const auto put = [&](const char* s) {
    out += s;
    out += '\n';
    ++written;
  };
  // Positions as an interpreter reads them back from the 4-decimal text.
  double x = 0, y = 0, z = 0;
  const auto q = [](double v) { return std::round(v * 1e4) / 1e4; };
  // Prints a coordinate word pair for a move to (nx, ny[, nz]) and updates the position.
  const auto coords = [&](char* p, std::size_t n, double nx, double ny) {
    nx = q(nx);
    ny = q(ny);
    const int k = incremental ? std::snprintf(p, n, "X%.4f Y%.4f", nx - x, ny - y)
                              : std::snprintf(p, n, "X%.4f Y%.4f", nx, ny);
    x = nx;
    y = ny;
    return k;
  };

  put(incremental ? "G91 G17 G21" : "G90 G17 G21");
  put("F1500");
  put(incremental ? "G0 Z5" : "G0 Z5");
  z = 5;
  double depth = -0.5;
  std::snprintf(buf, sizeof buf, "G1 Z%.4f F300", incremental ? depth - z : depth);
  put(buf);
  z = depth;
  put("F1800");

  double heading = 0.0;
  double curvature = 0.0;  // [1/mm]
  while (written < lines - 1) {
    const long left = lines - 1 - written;
    const double r = rng.unit();
    // Steer back towards the middle when near the edge of the box.
    if (std::hypot(x, y) > kBox) {
      const double to_centre = std::atan2(-y, -x);
      double d = std::remainder(to_centre - heading, 2 * kPi);
      curvature = d > 0 ? 0.5 : -0.5;
    } else {
      curvature += rng.uniform(-0.05, 0.05);
      curvature = std::fmax(-0.8, std::fmin(0.8, curvature));
    }
    if (r < 0.0005 && left >= 4) {
      // Retract, rapid to a new start, plunge.
      std::snprintf(buf, sizeof buf, "G0 Z%.4f", incremental ? 5.0 - z : 5.0);
      put(buf);
      z = 5.0;
      char c[96];
      coords(c, sizeof c, rng.uniform(-kBox / 2, kBox / 2), rng.uniform(-kBox / 2, kBox / 2));
      std::snprintf(buf, sizeof buf, "G0 %s", c);
      put(buf);
      depth = q(rng.uniform(-3.0, -0.2));
      std::snprintf(buf, sizeof buf, "G1 Z%.4f F300", incremental ? depth - z : depth);
      put(buf);
      z = depth;
      put("F1800");
    } else if (r < 0.15) {
      // Small tangent arc: the centre is on the side the path curves to.
      const bool ccw = curvature > 0 ? rng.unit() < 0.8 : rng.unit() < 0.2;
      const double radius = rng.uniform(0.5, 5.0);
      const double side = heading + (ccw ? kPi / 2 : -kPi / 2);
      const double i = q(radius * std::cos(side));
      const double j = q(radius * std::sin(side));
      const double cx = x + i, cy = y + j;
      const double r0 = std::hypot(i, j);
      const double a0 = std::atan2(y - cy, x - cx);
      const double sweep = rng.uniform(5.0, 60.0) * kPi / 180.0;
      const double a1 = ccw ? a0 + sweep : a0 - sweep;
      char c[96];
      coords(c, sizeof c, cx + r0 * std::cos(a1), cy + r0 * std::sin(a1));
      std::snprintf(buf, sizeof buf, "%s %s I%.4f J%.4f", ccw ? "G3" : "G2", c, i, j);
      put(buf);
      heading += ccw ? sweep : -sweep;
    } else {
      const double len = rng.uniform(0.05, 0.5);
      heading += curvature * len;
      char c[96];
      coords(c, sizeof c, x + len * std::cos(heading), y + len * std::sin(heading));
      if (rng.unit() < 0.002) {
        std::snprintf(buf, sizeof buf, "G1 %s F%d", c, 600 + 100 * static_cast<int>(rng.unit() * 30));
      } else if (rng.unit() < 0.1) {
        const double nz = q(z + rng.uniform(-0.02, 0.02));
        std::snprintf(buf, sizeof buf, "G1 %s Z%.4f", c, incremental ? nz - z : nz);
        z = nz;
      } else {
        std::snprintf(buf, sizeof buf, "G1 %s", c);
      }
      put(buf);
    }
  }
  put("M30");
}

}  // namespace tgm::bench
