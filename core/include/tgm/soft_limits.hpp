// Software travel limits: the range [min_position_mm, max_position_mm] each axis may be
// commanded to (config `axes`). The compiler refuses a block that leaves it, with its line;
// the interpolator refuses such a record as it is appended to the ring (the service's safety
// net for programs that did not come through the compiler with this config: for a record
// beyond the first buffer_size, mid-run, where the motion stops at the buffer's end).
#pragma once

#include <string>

#include "tgm/config.hpp"
#include "tgm/intercode.hpp"

namespace tgm {

//! Empty when motion record `s`, starting at `start` (absolute machine coordinates of every
//! axis), stays within the soft limits of `ip`'s axes; otherwise which axis leaves them, where
//! and which limit ("end point X612.5 is beyond the soft limit of axis X (max_position_mm 500
//! in the config)"; for an arc "the arc passes X612.5 ..." where its sweep goes beyond one).
//! Lines are checked at their end point (a move that starts outside the range may come back
//! into it), arcs over their sweep after the start in their plane and at the end point on the
//! other axes. Not a motion: empty.
std::string soft_limit_problem(const Segment& s, const double* start, const InterpolatorConfig& ip);

//! True when some axis of `ip` has a soft limit inside +-kMaxCoordinateMm.
bool has_soft_limits(const InterpolatorConfig& ip);

}  // namespace tgm
