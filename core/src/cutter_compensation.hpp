// Tool radius compensation (G41 / G42 / G40) of compiled records.
//
// Internal to the compiler: the records come in program order, flattened, in machine
// coordinates, each with the side and radius in force (`Segment::compensation`,
// `compensation_radius_mm`); the stage passes them on with the tool centre path in the
// compensation plane. The rules are LinuxCNC's (checked against `rs274` in
// tests/reference/compensation_test.cpp):
//  - the first move in the plane after G41/G42 is the entry move: it starts where the tool
//    stands and ends at its programmed end moved by the radius to the side, square to the
//    move's direction there (a straight entry must be longer than the radius; an arc keeps
//    its centre on the radial line through its end);
//  - every later move is offset by the radius (an arc keeps its centre, its radius grows or
//    shrinks by r); where two moves meet at a convex corner an arc of radius r around the
//    programmed corner joins them, at a concave corner both are cut where they intersect (an
//    error when they do not: the tool would cut into the contour); within 0.05 rad of a
//    reversal the corner is cut where the offsets cross, if they do, else it goes round, unless
//    the two moves cross just after it (an error: the tool cannot reach it);
//  - moves that leave the plane coordinates where they are (Z alone, M-functions, dwells)
//    happen at the compensated point;
//  - the first move after G40 leads from the compensated point to the programmed one; an arc
//    there is an error.
// A radius of 0 passes every record through unchanged.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/intercode.hpp"

namespace tgm::detail {

//! A point or direction in the compensation plane (its first and second axis).
struct Vec2 {
  double x = 0;
  double y = 0;
};

class CutterCompensation {
 public:
  using Emit = std::function<void(const Segment&)>;
  //! Reports an error at a source line; the stage passes nothing on after the first.
  using Fail = std::function<void(int line, std::string reason)>;

  CutterCompensation(std::string_view axis_letters, Emit emit, Fail fail);

  //! True when a record may bypass the stage (emitted directly, in order).
  bool idle() const { return !on_ && held_.empty() && !exit_pending_; }

  //! One record in program order; `from` is the programmed point it starts at (all axes).
  void push(const Segment& s, const std::array<double, kMaxAxes>& from);
  //! End of the records: passes on what is held.
  void finish();

 private:
  using V = Vec2;
  //! A move in the plane as the tool centre runs it.
  struct Elem {
    bool arc = false;
    bool cw = false;
    V s;               //!< start
    V e;               //!< end (the nominal offset end until the next move cuts it)
    V c;               //!< arc centre
    double r = 0;      //!< arc radius at the start (the circle the start lies on)
    double r_end = 0;  //!< arc radius at the end (a programmed arc may be a slight spiral)
    V a;               //!< line: a point of the offset line (parameter 0)
    V d;               //!< line: unit direction
    double t0 = 0;     //!< line: parameter of the start
    double t1 = 0;     //!< line: parameter of the nominal end
    double sweep = 0;  //!< arc: angle from the start to the nominal end [rad]
    V t_start;         //!< unit tangent at the programmed start
    V from;            //!< programmed start point
    V corner;          //!< programmed end point (the corner the next move turns at)
    V t_end;           //!< unit tangent at the programmed end
    int line = 0;
  };

  V plane_point(const Segment& s) const { return {s.end[p0_], s.end[p1_]}; }
  void set_plane_point(Segment& s, V p) const {
    s.end[p0_] = p.x;
    s.end[p1_] = p.y;
  }
  bool in_plane_move(const Segment& s, V from) const;
  void fail(int line, std::string reason);
  void flush();
  //! The offset element of move `s` that starts at programmed point `from`; false on error.
  bool offset_element(const Segment& s, V from, Elem& out);
  bool entry_element(const Segment& s, V from, Elem& out);
  //! Joins held_ (ending with element cur_) to `next`: cuts or adds a corner arc.
  //! Returns false on error; sets `corner` when a corner arc goes between them.
  bool join(Elem& next, bool& corner);
  //! Where the lines or circles of `prev` and `next` cross first along `next`, on both moves
  //! (prev between its start and its nominal end, next from its start on): those of the
  //! tool's path, or with `programmed` those of the contour (not at the corner itself).
  //! Returns false when they do not; `along` is the distance along next's path.
  bool first_crossing(const Elem& prev, const Elem& next, bool programmed, V& x,
                      double& along) const;
  //! Where `p` lies along `el` from its start: a length for a line, an angle for an arc.
  static double param(const Elem& el, V p);

  std::string letters_;
  Emit emit_;
  Fail fail_;
  bool failed_ = false;
  std::size_t p0_ = 0, p1_ = 1;  //!< plane axes of the compensation in force
  bool on_ = false;
  bool exit_pending_ = false;
  Compensation side_ = Compensation::kOff;
  Plane plane_ = Plane::kXY;
  double radius_ = 0;
  bool entry_ = false;         //!< no move in the plane yet since G41/G42
  V out_{};                    //!< plane point the tool stands at after what was passed on
  Elem cur_;                   //!< the held move (valid when held_ is not empty)
  std::vector<Segment> held_;  //!< cur_'s record first, then the records at its end
};

}  // namespace tgm::detail
