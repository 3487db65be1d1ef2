// Builds intercode programs directly (absolute machine mm), for motion tests and benchmarks.
#pragma once

#include <array>
#include <cmath>
#include <initializer_list>
#include <string>

#include "tgm/intercode.hpp"

namespace tgm::test {

class ProgramBuilder {
 public:
  explicit ProgramBuilder(int axes = 3, std::array<double, kMaxAxes> start = {}) : pos_(start) {
    p_.number_axes = axes;
    p_.axis_letters = std::string("XYZABCUVWE").substr(0, static_cast<std::size_t>(axes));
  }

  ProgramBuilder& rapid(std::initializer_list<double> end) { return move(SegmentType::kRapid, end, 0.0); }
  ProgramBuilder& line(std::initializer_list<double> end, double feed) {
    return move(SegmentType::kLinear, end, feed);
  }
  ProgramBuilder& line_to(const std::array<double, kMaxAxes>& end, double feed) {
    Segment s = base(SegmentType::kLinear);
    s.end = end;
    s.feed_mm_per_min = feed;
    return push(s);
  }
  //! Arc to `end` (absolute) around `center` (absolute, plane coordinates), any other axes in
  //! `end` move linearly (helix).
  ProgramBuilder& arc(bool ccw, const std::array<double, kMaxAxes>& end, std::array<double, 2> center,
                      double feed, Plane plane = Plane::kXY, int turns = 0) {
    Segment s = base(ccw ? SegmentType::kArcCcw : SegmentType::kArcCw);
    s.plane = plane;
    s.end = end;
    s.center = center;
    const PlaneAxes pa = plane_xyz(plane);
    const double dx = pos_[static_cast<std::size_t>(pa.first)] - center[0];
    const double dy = pos_[static_cast<std::size_t>(pa.second)] - center[1];
    s.radius = std::sqrt(dx * dx + dy * dy);
    s.turns = turns;
    s.feed_mm_per_min = feed;
    return push(s);
  }
  ProgramBuilder& m(int number, MKind kind, const MParams* params = nullptr) {
    Segment s = base(SegmentType::kMFunction);
    s.end = pos_;
    s.m = number;
    s.m_kind = kind;
    if (params) {
      s.aux = static_cast<std::int32_t>(p_.params.size());
      p_.params.push_back(*params);
    }
    return push(s);
  }
  ProgramBuilder& dwell(double seconds) {
    Segment s = base(SegmentType::kDwell);
    s.end = pos_;
    s.dwell_s = seconds;
    return push(s);
  }
  ProgramBuilder& message(const std::string& text) {
    Segment s = base(SegmentType::kMessage);
    s.end = pos_;
    s.aux = static_cast<std::int32_t>(p_.messages.size());
    p_.messages.push_back(text);
    return push(s);
  }
  ProgramBuilder& end() { return m(2, MKind::kProgramEnd); }

  const std::array<double, kMaxAxes>& position() const { return pos_; }
  Program& program() { return p_; }

 private:
  Segment base(SegmentType t) {
    Segment s;
    s.type = t;
    s.line = line_++;
    return s;
  }
  ProgramBuilder& move(SegmentType t, std::initializer_list<double> end, double feed) {
    Segment s = base(t);
    s.end = pos_;
    std::size_t i = 0;
    for (double v : end) s.end[i++] = v;
    s.feed_mm_per_min = feed;
    return push(s);
  }
  ProgramBuilder& push(const Segment& s) {
    p_.segments.push_back(s);
    pos_ = s.end;
    return *this;
  }
  Program p_;
  std::array<double, kMaxAxes> pos_{};
  int line_ = 1;
};

}  // namespace tgm::test
