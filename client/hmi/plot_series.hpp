// The points of `tgm-hmi run --plot`, bounded however long the run: a point is kept when it is
// at least the spacing away from the last one kept (distance for the toolpath, time for the
// speed trace); once `capacity` points are kept, every other one is dropped and the spacing
// doubles, so a run of hours keeps its whole extent at a coarser resolution instead of growing
// without end. Header-only, no DDS (unit-tested).
#pragma once

#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace tgm::hmi {

class PlotSeries {
 public:
  using Point = std::pair<double, double>;
  enum class Spacing {
    kDistance,  //!< Euclidean distance of the points (a toolpath)
    kFirst,     //!< difference of the first coordinates (time of a trace)
  };

  //! `spacing` >= 0 (0: every point until the first thinning), `capacity` >= 2.
  PlotSeries(Spacing kind, double spacing, std::size_t capacity)
      : kind_(kind), spacing_(spacing), capacity_(capacity < 2 ? 2 : capacity) {
    points_.reserve(capacity_);
  }

  void add(const Point& p) {
    latest_ = p;
    have_latest_ = true;
    if (!points_.empty() && gap(points_.back(), p) < spacing_) return;
    if (points_.size() >= capacity_) thin();
    if (!points_.empty() && gap(points_.back(), p) < spacing_) return;
    points_.push_back(p);
  }

  //! The kept points and, last, the newest point added if it was skipped (the plot ends where
  //! the run ended).
  std::vector<Point> points() const {
    std::vector<Point> out = points_;
    if (have_latest_ && (out.empty() || out.back() != latest_)) out.push_back(latest_);
    return out;
  }
  double spacing() const { return spacing_; }

 private:
  double gap(const Point& a, const Point& b) const {
    return kind_ == Spacing::kDistance ? std::hypot(b.first - a.first, b.second - a.second)
                                       : b.first - a.first;
  }
  void thin() {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < points_.size(); i += 2) points_[kept++] = points_[i];
    points_.resize(kept);
    // The new spacing: twice the old, or (from 0) the mean gap of the points kept.
    double mean = 0.0;
    for (std::size_t i = 1; i < points_.size(); ++i) mean += gap(points_[i - 1], points_[i]);
    if (points_.size() > 1) mean /= static_cast<double>(points_.size() - 1);
    spacing_ = spacing_ > 0.0 ? 2.0 * spacing_ : mean;
  }

  Spacing kind_;
  double spacing_;
  std::size_t capacity_;
  std::vector<Point> points_;
  Point latest_{};
  bool have_latest_ = false;
};

}  // namespace tgm::hmi
