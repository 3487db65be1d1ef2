// Intercode: the binary program the interpolator executes.
//
// The HMI compiles G-code text into a flat sequence of plain records (`Segment`). Subroutines,
// cycles and jumps are already expanded, every coordinate is absolute machine millimetres, and
// every record keeps the source line it came from. Side tables hold what only a few records
// need (M-function parameters, message texts) so that a record stays small.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tgm {

//! Axes one interpolator can drive (manual: "up to ten actuators").
inline constexpr int kMaxAxes = 10;
//! Interpolators one service hosts (manual: "three independent interpolators").
inline constexpr int kMaxInterpolators = 3;
//! M-function parameter letters A..Z (manual: M_Function_Parameter, AllParams).
inline constexpr int kParamLetters = 26;
//! Largest |coordinate| of an end point or arc centre [mm] (1000 km), and the largest feed
//! [mm/min]: the compiler's bounds for a word, which the interpolator also holds a record to,
//! so lengths, squares and products of any accepted record stay finite.
inline constexpr double kMaxCoordinateMm = 1.0e9;
inline constexpr double kMaxFeedMmPerMin = 1.0e6;
//! Longest M29 message text [bytes of UTF-8]: what the message topic carries to the HMIs.
inline constexpr std::size_t kMaxMessageBytes = 255;
//! Largest tool number a T word may select.
inline constexpr int kMaxTool = 99999;
//! Most full extra turns of one arc record (Segment::turns). The dialect writes 0 (G2/G3 have
//! no P word); a record of 2^31 turns from another writer ran until the time limit.
inline constexpr std::int32_t kMaxArcTurns = 1000;
//! An arc whose end lies closer than this to its start ends at its start [mm]: a full circle
//! with I/J/K, an error with R (the compiler and the interpolator hold to the same rule).
inline constexpr double kFullCircleMm = 1.0e-9;
//! How far the end of an arc of start radius r may lie off its circle [mm]: max(0.005 mm,
//! 0.1 % of r). The compiler refuses an I/J/K arc beyond it; the interpolator refuses an arc
//! record that starts further off the circle through its end (a program compiled to start at
//! another point than the one the interpolator stands at: it would run as a spiral).
inline double arc_radius_tolerance_mm(double r) {
  return std::max(0.005, 0.001 * r);
}
//! Value of a register or parameter that does not apply ("greater than 10^38" in the manual).
inline constexpr double kNotSet = 1.0e39;

//! True when a register value means "not set / does not apply".
inline bool is_not_set(double v) { return v > 1.0e38; }

//! What a record does. The numeric values of the motion types equal their G-numbers.
enum class SegmentType : std::uint8_t {
  kRapid = 0,    //!< G0: straight line at the axes' rapid limits
  kLinear = 1,   //!< G1: straight line at the programmed feed
  kArcCw = 2,    //!< G2: clockwise arc (or helix) in the record's plane
  kArcCcw = 3,   //!< G3: counter-clockwise arc (or helix)
  kDwell = 4,    //!< G4: wait `dwell_s` seconds standing still
  kMFunction = 5,  //!< M-function (see `MKind`)
  kMessage = 6,  //!< M29: publish `Program::messages[aux]`
};

//! How the interpolator treats an M-function record.
enum class MKind : std::uint8_t {
  kNone = 0,        //!< not an M-function record
  kNormal = 1,      //!< M < 1000: stop, set M_Func, wait until the PLC writes it back to 0
  kContinuous = 2,  //!< M > 1000: tell the PLC, keep moving
  kProgramStop = 3,  //!< M0: pause until start
  kProgramEnd = 4,   //!< M2 / M30: end of program (Status 3)
};

//! The largest normal M-function: the interpolator waits for M1..M999 only (M1000 is neither).
inline constexpr int kMaxNormalM = 999;

//! Active plane of circular interpolation; the values are the G-numbers (LookAheadBuffer Plane).
enum class Plane : std::uint8_t { kXY = 17, kXZ = 18, kYZ = 19 };

//! Tool radius compensation state recorded for each record (G40 / G41 / G42).
enum class Compensation : std::uint8_t { kOff = 40, kLeft = 41, kRight = 42 };

//! One intercode record. Plain data, trivially copyable.
struct Segment {
  SegmentType type = SegmentType::kLinear;
  Plane plane = Plane::kXY;
  Compensation compensation = Compensation::kOff;
  MKind m_kind = MKind::kNone;
  //! Source line (1-based) of the G-code block this record came from.
  std::int32_t line = 0;
  //! M-function number (M records), otherwise -1.
  std::int32_t m = -1;
  //! Active tool number (T word), 0 when none was selected.
  std::int32_t tool = 0;
  //! Full extra turns of an arc beyond the first (0 for an ordinary arc or one full circle).
  std::int32_t turns = 0;
  //! Index into `Program::params` (M records) or `Program::messages` (message records); -1 if none.
  std::int32_t aux = -1;
  //! End point of every axis in absolute machine coordinates [mm]; unconfigured axes hold 0.
  std::array<double, kMaxAxes> end{};
  //! Arc centre in absolute machine coordinates [mm] on the plane's first and second axis
  //! (see `plane_axes`).
  std::array<double, 2> center{};
  //! Arc radius [mm]; 0 for non-arcs.
  double radius = 0.0;
  //! Programmed path feed [mm/min] (G1-G3); 0 for rapid (the axes' rapid limits apply).
  double feed_mm_per_min = 0.0;
  //! Dwell time [s] (G4 records).
  double dwell_s = 0.0;
  //! Compensation radius [mm] for G41/G42 (from D or the tool table), 0 otherwise.
  double compensation_radius_mm = 0.0;

  bool is_motion() const { return static_cast<int>(type) <= 3; }
  bool is_arc() const { return type == SegmentType::kArcCw || type == SegmentType::kArcCcw; }
};

//! The 26 M-function parameters A..Z; letters not given hold `kNotSet`.
using MParams = std::array<double, kParamLetters>;

//! Parameters with every letter unset.
constexpr MParams unset_params() {
  MParams p{};
  p.fill(kNotSet);
  return p;
}

//! The two axes of an arc's plane (first, second) and the normal axis. (first, second, normal)
//! is right-handed, so an arc is CCW when it turns from `first` towards `second`.
struct PlaneAxes {
  int first;
  int second;
  int normal;
};

//! The plane's axes as X, Y, Z = 0, 1, 2 (their centre offsets are I, J, K).
inline PlaneAxes plane_xyz(Plane p) {
  switch (p) {
    case Plane::kXZ:
      // G18 is the Z-X plane: (Z, X, Y) is right-handed, so CW/CCW are seen from +Y as in
      // RS274/NGC.
      return {2, 0, 1};
    case Plane::kYZ:
      return {1, 2, 0};
    case Plane::kXY:
    default:
      return {0, 1, 2};
  }
}

//! The plane's axes as indices of an interpolator whose axes have the letters `letters` (axis
//! 0 first): G17 is the plane of the axes lettered X and Y wherever they stand, so a lathe of
//! axes X, Z turns G18 arcs, and one whose axis 0 is Y still turns G17 arcs in X-Y. An axis
//! whose letter the interpolator does not have is kMaxAxes (no axis). Arc records hold their
//! centre on `first` and `second` of this.
inline PlaneAxes plane_axes(Plane p, std::string_view letters) {
  const PlaneAxes xyz = plane_xyz(p);
  const auto index = [&](int k) {
    const std::size_t at = letters.find("XYZ"[k]);
    return at == std::string_view::npos || at >= kMaxAxes ? kMaxAxes : static_cast<int>(at);
  };
  return {index(xyz.first), index(xyz.second), index(xyz.normal)};
}

//! A compiled program: records plus their side tables.
struct Program {
  std::vector<Segment> segments;
  std::vector<MParams> params;
  std::vector<std::string> messages;
  //! Number of configured axes the records were compiled for (1..kMaxAxes).
  int number_axes = 3;
  //! Axis letters, one per configured axis.
  std::string axis_letters = "XYZ";
  //! Machine position the program was compiled from [mm] (CompileOptions::start_mm): its G91
  //! moves, arcs and the axes its first G90 moves do not name start there, so it runs as
  //! compiled only from there.
  std::array<double, kMaxAxes> start_mm{};
};

}  // namespace tgm
