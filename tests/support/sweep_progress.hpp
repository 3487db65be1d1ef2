// Progress of a long seeded sweep on stderr: a seed of 1,000 box-machine programs runs for twenty
// minutes, and without a word in between it cannot be told from a hang. A line at most every
// `interval` of wall time, none for a sweep that ends sooner (CTest's short sweeps stay quiet):
//
//   RandomSweep seed 6901: 140 of 1000 programs (14 %), 3.1 min, about 19.0 min left
//
// Display only: no test reads the clock. Header-only.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>

namespace tgm::test {

class SweepProgress {
 public:
  using Clock = std::chrono::steady_clock;

  //! `what` names the sweep and its seed; `total` cases, counted in `unit`.
  SweepProgress(std::string what, std::uint64_t total, std::string unit = "programs",
                Clock::duration interval = std::chrono::seconds(30))
      : what_(std::move(what)),
        unit_(std::move(unit)),
        total_(total),
        interval_(interval),
        start_(Clock::now()),
        next_(start_ + interval) {}

  //! `done` cases are finished: prints a line when the interval has passed since the last.
  void update(std::uint64_t done) {
    const Clock::time_point now = Clock::now();
    if (now < next_) return;
    next_ = now + interval_;
    std::fprintf(stderr, "%s\n",
                 line(done, std::chrono::duration<double>(now - start_).count()).c_str());
  }

  //! The progress line after `done` cases in `elapsed_s` seconds.
  std::string line(std::uint64_t done, double elapsed_s) const {
    std::string out =
        what_ + ": " + std::to_string(done) + " of " + std::to_string(total_) + " " + unit_;
    if (total_ > 0) out += " (" + std::to_string(done * 100 / total_) + " %)";
    out += ", " + duration_text(elapsed_s);
    if (done > 0 && done < total_) {
      const double left =
          elapsed_s * static_cast<double>(total_ - done) / static_cast<double>(done);
      out += ", about " + duration_text(left) + " left";
    }
    return out;
  }

  //! "42 s", "3.1 min", "2.4 h".
  static std::string duration_text(double s) {
    char buf[32];
    if (s < 100.0) {
      std::snprintf(buf, sizeof buf, "%.0f s", s);
    } else if (s < 6000.0) {
      std::snprintf(buf, sizeof buf, "%.1f min", s / 60.0);
    } else {
      std::snprintf(buf, sizeof buf, "%.1f h", s / 3600.0);
    }
    return buf;
  }

 private:
  std::string what_, unit_;
  std::uint64_t total_;
  Clock::duration interval_;
  Clock::time_point start_, next_;
};

}  // namespace tgm::test
