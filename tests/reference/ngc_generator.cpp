#include "ngc_generator.hpp"

#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "tgm/intercode.hpp"

namespace tgm::ref {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr char kAxis[3] = {'X', 'Y', 'Z'};
constexpr char kOffset[3] = {'I', 'J', 'K'};
//! Soft bound of the program coordinates [mm]: moves are steered back inside it.
constexpr double kBox = 80.0;

class Generator {
 public:
  Generator(std::uint64_t seed, int lines) : rng_(seed), target_lines_(lines) {}

  GeneratedProgram run() {
    GeneratedProgram g;
    absolute_ = rng_.chance(0.5);
    g.starts_incremental = !absolute_;
    line(std::string(absolute_ ? "G90" : "G91") + " G17" + (rng_.chance(0.5) ? " G21" : ""));
    set_feed_line();
    while (lines_ < target_lines_ - 1) step();
    line("M2");
    g.text = std::move(text_);
    g.lines = lines_;
    return g;
  }

 private:
  // ---- text helpers ---------------------------------------------------------------------

  //! A number as CAM output writes it: 4 decimals, sometimes without trailing or leading zeros.
  std::string number(double v) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.4f", v);
    std::string s = buf;
    if (s == "-0.0000") s = "0.0000";
    if (rng_.chance(0.3)) {
      while (s.back() == '0') s.pop_back();
      if (s.back() == '.' && rng_.chance(0.5)) s.pop_back();
    }
    if (rng_.chance(0.1)) {
      // "0.5" -> ".5", "-0.5" -> "-.5"; never down to a bare "."
      if (s.rfind("0.", 0) == 0 && s.size() > 2) {
        s.erase(0, 1);
      } else if (s.rfind("-0.", 0) == 0 && s.size() > 3) {
        s.erase(1, 1);
      }
    }
    if (rng_.chance(0.02) && s[0] != '-') s.insert(0, "+");
    return s;
  }

  //! " X1.2345" (sometimes "X 1.2345"); `value` receives what an interpreter reads back.
  std::string word(char letter, double v, double& value) {
    const std::string n = number(v);
    value = std::strtod(n.c_str(), nullptr);
    std::string w(1, ' ');
    w += letter;
    if (rng_.chance(0.02)) w += ' ';
    return w + n;
  }

  //! Axis word for a target in program coordinates; writes the resulting position to `out`.
  std::string axis_word(int axis, double target, double& out) {
    const auto a = static_cast<std::size_t>(axis);
    double v = 0.0;
    std::string w = word(kAxis[a], absolute_ ? target : target - pos_[a], v);
    out = absolute_ ? v : pos_[a] + v;
    return w;
  }

  void line(std::string l) {
    if (rng_.chance(0.04)) l = "N" + std::to_string(10 * (lines_ + 1)) + " " + l;
    if (rng_.chance(0.03)) {
      for (char& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    if (rng_.chance(0.03)) l += rng_.chance(0.5) ? " (cut)" : " ; note";
    text_ += l;
    text_ += '\n';
    ++lines_;
  }

  std::string g(int n) {
    if (n < 4 && rng_.chance(0.2)) return "G0" + std::to_string(n);
    return "G" + std::to_string(n);
  }

  //! Sometimes a distance-mode switch in front of a motion; it applies to that line's words.
  std::string mode_prefix() {
    if (!rng_.chance(0.03)) return {};
    absolute_ = !absolute_;
    return absolute_ ? "G90 " : "G91 ";
  }

  //! Emits modal words chosen for a block that was then not generated.
  void abandon(const std::string& prefix) {
    if (!prefix.empty()) line(trim_back(prefix));
  }

  static std::string trim_back(std::string s) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
  }

  std::string feed_word() {
    double f = 0.0;
    const double want = std::round(rng_.uniform(50.0, 5000.0) * 10.0) / 10.0;
    std::string w = word('F', want, f);
    return w;
  }

  void set_feed_line() { line(feed_word().substr(1)); }

  //! Direction [rad] in the plane (a, b): random, or back towards the origin when far out.
  double heading(int a, int b) {
    const double pa = pos_[static_cast<std::size_t>(a)];
    const double pb = pos_[static_cast<std::size_t>(b)];
    if (std::hypot(pa, pb) > kBox * 0.75) return std::atan2(-pb, -pa) + rng_.uniform(-1.0, 1.0);
    return rng_.uniform(-kPi, kPi);
  }

  double bounded_delta(int axis, double span) {
    const double p = pos_[static_cast<std::size_t>(axis)];
    double d = rng_.uniform(-span, span);
    if (std::fabs(p + d) > kBox) d = -d;
    return d;
  }

  // ---- blocks ---------------------------------------------------------------------------

  void step() {
    const double r = rng_.unit();
    if (r < 0.36) {
      linear(1);
    } else if (r < 0.42) {
      linear(0);
    } else if (r < 0.62) {
      arc_ijk();
    } else if (r < 0.76) {
      arc_r();
    } else if (r < 0.80) {
      plane_switch();
    } else if (r < 0.83) {
      absolute_ = !absolute_;
      line(absolute_ ? "G90" : "G91");
    } else if (r < 0.84) {
      g92();
    } else if (r < 0.87) {
      set_feed_line();
    } else if (r < 0.875) {
      line("(comment " + std::to_string(lines_) + ")");
    } else {
      linear(1);
    }
  }

  void linear(int type) {
    const std::string pre = mode_prefix();
    std::array<double, 3> next = pos_;
    std::string words;
    const bool far = rng_.chance(type == 0 ? 0.5 : 0.1);
    bool moved = false;
    for (int i = 0; i < 3; ++i) {
      const auto a = static_cast<std::size_t>(i);
      if (!rng_.chance(far ? 0.8 : 0.6)) continue;
      const double target = far ? rng_.uniform(-kBox, kBox) : pos_[a] + bounded_delta(i, 2.0);
      words += axis_word(i, target, next[a]);
      moved = moved || next[a] != pos_[a];
    }
    if (!moved) return abandon(pre);  // no zero-length moves: our compiler may drop them
    const bool modal = type == 1 && last_motion_ == 1 && pre.empty() && rng_.chance(0.1);
    if (type == 1 && rng_.chance(0.05)) words += feed_word();
    line(pre + (modal ? trim_front(words) : g(type) + words));
    pos_ = next;
    last_motion_ = type;
  }

  static std::string trim_front(std::string s) {
    while (!s.empty() && s.front() == ' ') s.erase(0, 1);
    return s;
  }

  void plane_switch() {
    const int p = rng_.range(17, 19);
    plane_ = static_cast<Plane>(p);
    line("G" + std::to_string(p));
  }

  void g92() {
    std::string words;
    std::array<double, 3> next = pos_;
    for (int i = 0; i < 3; ++i) {
      if (!rng_.chance(0.6) && !(i == 2 && words.empty())) continue;
      words += word(kAxis[i], rng_.uniform(-50.0, 50.0), next[static_cast<std::size_t>(i)]);
    }
    line("G92" + words);
    pos_ = next;
  }

  //! Optional plane change in front of an arc.
  std::string arc_plane_prefix() {
    if (!rng_.chance(0.1)) return {};
    const int p = rng_.range(17, 19);
    plane_ = static_cast<Plane>(p);
    return "G" + std::to_string(p) + " ";
  }

  std::string helix_word(int normal, std::array<double, 3>& next) {
    if (!rng_.chance(0.25)) return {};
    const auto n = static_cast<std::size_t>(normal);
    return axis_word(normal, pos_[n] + bounded_delta(normal, 3.0), next[n]);
  }

  void arc_ijk() {
    const std::string pp = arc_plane_prefix() + mode_prefix();
    const PlaneAxes pa = plane_xyz(plane_);
    const auto a = static_cast<std::size_t>(pa.first);
    const auto b = static_cast<std::size_t>(pa.second);
    const double radius = rng_.chance(0.6) ? rng_.uniform(0.2, 5.0) : rng_.uniform(5.0, 40.0);
    const double h = heading(pa.first, pa.second);
    double ci = 0.0, cj = 0.0;
    std::string offsets = word(kOffset[a], radius * std::cos(h), ci) +
                          word(kOffset[b], radius * std::sin(h), cj);
    const double ca = pos_[a] + ci;
    const double cb = pos_[b] + cj;
    const double r0 = std::hypot(pos_[a] - ca, pos_[b] - cb);
    if (r0 < 0.1) return abandon(pp);
    const bool ccw = rng_.chance(0.5);
    std::array<double, 3> next = pos_;
    std::string ends;
    if (rng_.chance(0.1)) {
      // Full circle: start == end. G91 says so with zero increments; G90 leaves the plane
      // words out (the current position may not be a 4-decimal number after G91 moves).
      if (!absolute_ && rng_.chance(0.7)) {
        double unused = 0.0;
        ends = word(kAxis[a], 0.0, unused) + word(kAxis[b], 0.0, unused);
      }
    } else {
      const double phi0 = std::atan2(pos_[b] - cb, pos_[a] - ca);
      const double sweep = rng_.uniform(5.0, 355.0) * kPi / 180.0;
      const double phi1 = ccw ? phi0 + sweep : phi0 - sweep;
      ends = axis_word(pa.first, ca + r0 * std::cos(phi1), next[a]) +
             axis_word(pa.second, cb + r0 * std::sin(phi1), next[b]);
      const double r1 = std::hypot(next[a] - ca, next[b] - cb);
      if (std::fabs(r1 - r0) > 1e-3) return abandon(pp);  // not with 4-decimal rounding
    }
    ends += helix_word(pa.normal, next);
    std::string words = ends + offsets;
    if (rng_.chance(0.05)) words += feed_word();
    line(pp + g(ccw ? 3 : 2) + words);
    pos_ = next;
    last_motion_ = ccw ? 3 : 2;
  }

  void arc_r() {
    const std::string pp = arc_plane_prefix() + mode_prefix();
    const PlaneAxes pa = plane_xyz(plane_);
    const auto a = static_cast<std::size_t>(pa.first);
    const auto b = static_cast<std::size_t>(pa.second);
    const double chord = rng_.chance(0.6) ? rng_.uniform(0.5, 5.0) : rng_.uniform(5.0, 40.0);
    const double theta = rng_.uniform(10.0, 170.0) * kPi / 180.0;
    const double radius = chord / (2.0 * std::sin(theta / 2.0));
    const double h = heading(pa.first, pa.second);
    std::array<double, 3> next = pos_;
    std::string ends = axis_word(pa.first, pos_[a] + chord * std::cos(h), next[a]) +
                       axis_word(pa.second, pos_[b] + chord * std::sin(h), next[b]);
    const bool large = rng_.chance(0.3);
    double r = 0.0;
    std::string rw = word('R', large ? -radius : radius, r);
    const double real_chord = std::hypot(next[a] - pos_[a], next[b] - pos_[b]);
    if (std::fabs(r) < real_chord / 2.0 * 1.002) return abandon(pp);  // near a half circle
    ends += helix_word(pa.normal, next);
    const bool ccw = rng_.chance(0.5);
    std::string words = ends + rw;
    if (rng_.chance(0.05)) words += feed_word();
    line(pp + g(ccw ? 3 : 2) + words);
    pos_ = next;
    last_motion_ = ccw ? 3 : 2;
  }

  Rng rng_;
  int target_lines_;
  int lines_ = 0;
  std::string text_;
  //! Current point in program coordinates, computed the way an interpreter reads the text.
  std::array<double, 3> pos_{};
  bool absolute_ = true;
  Plane plane_ = Plane::kXY;
  int last_motion_ = -1;
};

}  // namespace

GeneratedProgram generate_reference_program(std::uint64_t seed, int lines) {
  return Generator(seed, lines).run();
}

}  // namespace tgm::ref
