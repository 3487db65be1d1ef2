#include "tgm/config.hpp"
#include "tgm/intercode.hpp"
#include "tgm/printable.hpp"
#include "tgm/smoothing.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <set>
#include <string>

namespace tgm {

namespace {

// Largest tool radius and |length| [mm]: a D word's bound.
constexpr double kMaxToolMm = 1e9;

bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

// Spline jerks [mm/s^3] below this round into Command -2's 32-bit Command_Parameter (2^31 - 1).
constexpr double kCarriedJerkBound = 2147483647.5;

}  // namespace

std::string redefine_m_problem(long long m) {
  // The M-numbers the manual marks "can be redefined".
  if (m == 2 || (m >= 3 && m <= 9) || m == 17 || m == 29 || m == 30 || m == 99) return {};
  std::string why = "M";  // appended, not "M" + ...: GCC 12 warns falsely (-Wrestrict)
  why += std::to_string(m);
  return why + " cannot be redefined (only M2-M9, M17, M29, M30, M99)";
}

bool parse_block_delete(std::string_view word, BlockDelete& out) {
  if (word == "error") {
    out = BlockDelete::kRefuse;
  } else if (word == "run") {
    out = BlockDelete::kRun;
  } else if (word == "skip") {
    out = BlockDelete::kSkip;
  } else {
    return false;
  }
  return true;
}

namespace {

// FNV-1a, 64 bits, over little-endian values.
class Fnv1a {
 public:
  void add(std::uint64_t v) {
    for (int k = 0; k < 8; ++k) {
      h_ = (h_ ^ ((v >> (8 * k)) & 0xffu)) * 0x100000001b3ull;
    }
  }
  void add(double v) { add(std::bit_cast<std::uint64_t>(v == 0.0 ? 0.0 : v)); }
  std::uint64_t value() const { return h_ != 0 ? h_ : 1; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ull;
};

}  // namespace

std::uint64_t machine_digest(const MachineConfig& machine, int n, int axes) {
  if (n < 0 || n >= static_cast<int>(machine.interpolators.size())) return 0;
  const InterpolatorConfig& ip = machine.interpolators[static_cast<std::size_t>(n)];
  const std::size_t count = std::min(ip.axes.size(), static_cast<std::size_t>(std::max(axes, 0)));
  Fnv1a h;
  h.add(std::uint64_t{1});  // the format's version
  h.add(static_cast<std::uint64_t>(machine.cycle_time_us));
  const SmoothingConfig& s = machine.smoothing;
  h.add(static_cast<std::uint64_t>(s.spline_points));
  h.add(s.spline_jerk_mm_s3);
  h.add(static_cast<std::uint64_t>(s.iir_p_e6));
  h.add(static_cast<std::uint64_t>(s.iir_q_e6));
  h.add(static_cast<std::uint64_t>(s.iir_f_e6));
  h.add(static_cast<std::uint64_t>(s.iir_axis_mask));
  h.add(static_cast<std::uint64_t>(ip.buffer_size));
  h.add(static_cast<std::uint64_t>(count));
  for (std::size_t i = 0; i < count; ++i) {
    const AxisConfig& a = ip.axes[i];
    h.add(static_cast<std::uint64_t>(static_cast<unsigned char>(a.letter)));
    for (const double v :
         {a.max_velocity_mm_s, a.max_acceleration_mm_s2, a.max_jerk_mm_s3, a.rapid_velocity_mm_s,
          a.emergency_deceleration_mm_s2, a.corner_velocity_tolerance_mm_s, a.backlash_mm,
          a.backlash_ramp_share, a.min_position_mm, a.max_position_mm}) {
      h.add(v);
    }
    // Only when set: left at 0 it follows from the jerk and the corner tolerance above, and
    // the fingerprints of the configs written before the key existed stay what they were.
    if (a.corner_acceleration_tolerance_mm_s2 != 0.0) h.add(a.corner_acceleration_tolerance_mm_s2);
  }
  return h.value();
}

char default_axis_letter(int i) {
  static constexpr char kLetters[kMaxAxes + 1] = "XYZABCUVWE";
  return (i >= 0 && i < kMaxAxes) ? kLetters[i] : '?';
}

std::string MachineConfig::axis_letters(int n) const {
  std::string s;
  if (n < 0 || n >= static_cast<int>(interpolators.size())) return s;
  for (const auto& a : interpolators[static_cast<std::size_t>(n)].axes) s.push_back(a.letter);
  return s;
}

std::vector<std::string> MachineConfig::validate() const {
  std::vector<std::string> e;
  if (cycle_time_us != 250 && cycle_time_us != 500 && cycle_time_us != 1000) {
    e.push_back("cycle_time_us: must be 250, 500 or 1000, not " + std::to_string(cycle_time_us));
  }
  if (interpolators.empty() || interpolators.size() > static_cast<std::size_t>(kMaxInterpolators)) {
    e.push_back("interpolators: between 1 and 3 interpolators are needed, not " +
                std::to_string(interpolators.size()));
  }
  for (std::size_t n = 0; n < interpolators.size(); ++n) {
    const auto& ip = interpolators[n];
    const std::string base = "interpolators[" + std::to_string(n) + "]";
    if (ip.buffer_size < 1000 || ip.buffer_size > 100000) {
      e.push_back(base + ".buffer_size: must be 1000..100000 segments, not " +
                  std::to_string(ip.buffer_size));
    }
    if (ip.axes.empty() || ip.axes.size() > static_cast<std::size_t>(kMaxAxes)) {
      e.push_back(base + ".axes: between 1 and 10 axes are needed, not " +
                  std::to_string(ip.axes.size()));
    }
    std::set<char> seen;
    for (std::size_t i = 0; i < ip.axes.size(); ++i) {
      const auto& a = ip.axes[i];
      const std::string ab = base + ".axes[" + std::to_string(i) + "]";
      const char L = a.letter;
      const bool letter_ok = L >= 'A' && L <= 'Z' && L != 'D' && L != 'F' && L != 'G' &&
                             L != 'I' && L != 'J' && L != 'K' && L != 'L' && L != 'M' &&
                             L != 'N' && L != 'P' && L != 'R' && L != 'T';
      // An axis past the tenth has no built-in letter ('?'): the axis count is the error, said
      // above (a second, made-up one about '?' followed from it: review of session 77).
      const bool past_the_tenth =
          i >= static_cast<std::size_t>(kMaxAxes) && L == default_axis_letter(static_cast<int>(i));
      if (past_the_tenth) {
        // no letter of its own to check
      } else if (!letter_ok) {
        e.push_back(ab + ".letter: '" + std::string(1, L) + "' is not an axis letter " +
                    (L >= 'A' && L <= 'Z'
                         ? "(D F G I J K L M N P R T are G-code words)"
                         : "(A..Z, except the G-code words D F G I J K L M N P R T)"));
      } else if (!seen.insert(L).second) {
        e.push_back(ab + ".letter: '" + std::string(1, L) + "' is used by two axes");
      }
      auto in_range = [&](const char* key, double v, double lo, double hi, const char* unit) {
        if (!finite_positive(v)) {
          e.push_back(ab + "." + key + ": must be > 0, not " + exact_number_text(v));
        } else if (v < lo || v > hi) {
          e.push_back(ab + "." + key + ": must be " + exact_number_text(lo) + ".." +
                      exact_number_text(hi) + " " + unit + ", not " + exact_number_text(v));
        }
      };
      in_range("max_velocity_mm_s", a.max_velocity_mm_s, kMinVelocity, kMaxVelocity, "mm/s");
      in_range("max_acceleration_mm_s2", a.max_acceleration_mm_s2, kMinAcceleration,
               kMaxAcceleration, "mm/s^2");
      in_range("max_jerk_mm_s3", a.max_jerk_mm_s3, kMinJerk, kMaxJerk, "mm/s^3");
      in_range("rapid_velocity_mm_s", a.rapid_velocity_mm_s, kMinVelocity, kMaxVelocity, "mm/s");
      in_range("emergency_deceleration_mm_s2", a.emergency_deceleration_mm_s2, kMinAcceleration,
               kMaxAcceleration, "mm/s^2");
      in_range("corner_velocity_tolerance_mm_s", a.corner_velocity_tolerance_mm_s,
               kMinCornerTolerance, kMaxCornerTolerance, "mm/s");
      if (a.corner_acceleration_tolerance_mm_s2 != 0.0) {  // 0: derived (config.hpp)
        in_range("corner_acceleration_tolerance_mm_s2", a.corner_acceleration_tolerance_mm_s2,
                 kMinAcceleration, kMaxAcceleration, "mm/s^2");
      }
      // The interpolator used to raise a lower one to max_acceleration_mm_s2 without a word.
      if (finite_positive(a.emergency_deceleration_mm_s2) &&
          finite_positive(a.max_acceleration_mm_s2) &&
          a.emergency_deceleration_mm_s2 < a.max_acceleration_mm_s2) {
        e.push_back(
            ab +
            ".emergency_deceleration_mm_s2: " + exact_number_text(a.emergency_deceleration_mm_s2) +
            " is below max_acceleration_mm_s2 " + exact_number_text(a.max_acceleration_mm_s2) +
            " (an emergency stop brakes at least as hard as a normal one)");
      }
      // The range a Ratio write accepts (1e300 gave PositionInc values of -2^63).
      if (!(std::fabs(a.ratio_inc_per_mm) >= kMinRatio &&
            std::fabs(a.ratio_inc_per_mm) <= kMaxRatio)) {
        e.push_back(ab + ".ratio_inc_per_mm: |ratio| must be 1e-06..1e+09 inc/mm, not " +
                    exact_number_text(a.ratio_inc_per_mm));
      }
      if (!std::isfinite(a.backlash_mm) || a.backlash_mm < 0.0 || a.backlash_mm > 10.0) {
        e.push_back(ab + ".backlash_mm: must be 0..10 mm, not " + exact_number_text(a.backlash_mm));
      }
      if (!(a.backlash_ramp_share >= 0.01 && a.backlash_ramp_share <= 0.5)) {  // NaN too
        e.push_back(ab +
                    ".backlash_ramp_share: must be 0.01..0.5 (a share of the axis limits), not " +
                    exact_number_text(a.backlash_ramp_share));
      } else if (a.backlash_mm > 0.0) {
        // The planner moves the axis at the rest of its limits: that too within the range the
        // motion core is tested at (MOTION.md, Accepted machine limits).
        const double rest = planned_limit_share(a);
        const auto planned = [&](const char* key, double limit, double lo, const char* unit) {
          if (finite_positive(limit) && rest * limit < lo) {
            e.push_back(ab + ".backlash_ramp_share: " + exact_number_text(a.backlash_ramp_share) +
                        " leaves " + key + " " + exact_number_text(rest * limit) +
                        " to the motion, below " + exact_number_text(lo) + " " + unit);
          }
        };
        planned("max_velocity_mm_s", a.max_velocity_mm_s, kMinVelocity, "mm/s");
        planned("max_acceleration_mm_s2", a.max_acceleration_mm_s2, kMinAcceleration, "mm/s^2");
        planned("max_jerk_mm_s3", a.max_jerk_mm_s3, kMinJerk, "mm/s^3");
      }
      const bool min_ok = std::fabs(a.min_position_mm) <= 1.0e9;  // false for NaN
      const bool max_ok = std::fabs(a.max_position_mm) <= 1.0e9;
      if (!min_ok) {
        e.push_back(ab + ".min_position_mm: must be -1e9..1e9 mm, not " +
                    exact_number_text(a.min_position_mm));
      }
      if (!max_ok) {
        e.push_back(ab + ".max_position_mm: must be -1e9..1e9 mm, not " +
                    exact_number_text(a.max_position_mm));
      }
      if (min_ok && max_ok && !(a.min_position_mm < a.max_position_mm)) {
        e.push_back(ab + ".max_position_mm: " + exact_number_text(a.max_position_mm) +
                    " is not above min_position_mm " + exact_number_text(a.min_position_mm));
      }
      if (finite_positive(a.rapid_velocity_mm_s) && finite_positive(a.max_velocity_mm_s) &&
          a.rapid_velocity_mm_s > a.max_velocity_mm_s) {
        e.push_back(ab + ".rapid_velocity_mm_s: " + exact_number_text(a.rapid_velocity_mm_s) +
                    " exceeds max_velocity_mm_s " + exact_number_text(a.max_velocity_mm_s));
      }
    }
  }
  std::set<int> tool_numbers;
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const auto& t = tools[i];
    const std::string tb = "tools[" + std::to_string(i) + "]";
    // T0 is no tool in the spindle, whose radius is 0: an entry for it was never used.
    if (t.number < 1 || t.number > kMaxTool) {
      e.push_back(tb + ".number: must be 1.." + std::to_string(kMaxTool) +
                  " (what a T word selects; T0 is no tool), not " + std::to_string(t.number));
    }
    if (!tool_numbers.insert(t.number).second) {
      e.push_back(tb + ".number: tool " + std::to_string(t.number) + " is listed twice");
    }
    // Bounded as a D word and a coordinate are (1e308 was taken, and every compensated move
    // was then refused).
    if (!std::isfinite(t.radius_mm) || t.radius_mm < 0.0 || t.radius_mm > kMaxToolMm) {
      e.push_back(tb + ".radius_mm: must be 0..1e9 mm, not " + exact_number_text(t.radius_mm));
    }
    if (!std::isfinite(t.length_mm) || std::fabs(t.length_mm) > kMaxToolMm) {
      e.push_back(tb + ".length_mm: must be -1e9..1e9 mm, not " + exact_number_text(t.length_mm));
    }
  }
  const auto& c = compiler;
  // The range of an F word: 1e308 compiled and then every record without an F was refused by
  // the interpolator when it was appended, mid-program.
  if (!finite_positive(c.default_feed_mm_per_min) || c.default_feed_mm_per_min > kMaxFeedMmPerMin) {
    e.push_back("compiler.default_feed_mm_per_min: must be > 0 and at most " +
                std::to_string(static_cast<long long>(kMaxFeedMmPerMin)) + " mm/min, not " +
                exact_number_text(c.default_feed_mm_per_min));
  }
  if (c.initial_tool < 0 || c.initial_tool > kMaxTool) {
    e.push_back("compiler.initial_tool: must be 0.." + std::to_string(kMaxTool) + ", not " +
                std::to_string(c.initial_tool));
  }
  std::set<int> redefined;
  for (std::size_t i = 0; i < c.plc_redefined_m.size(); ++i) {
    if (std::string why = redefine_m_problem(c.plc_redefined_m[i]); !why.empty()) {
      e.push_back("compiler.plc_redefined_m[" + std::to_string(i) + "]: " + why);
    } else if (!redefined.insert(c.plc_redefined_m[i]).second) {
      e.push_back("compiler.plc_redefined_m[" + std::to_string(i) + "]: M" +
                  std::to_string(c.plc_redefined_m[i]) + " is listed twice");
    }
  }
  if (c.max_program_segments < 1 || c.max_program_segments > 1'000'000'000) {
    e.push_back("compiler.max_program_segments: must be 1..1000000000, not " +
                std::to_string(c.max_program_segments));
  }
  if (c.max_call_depth < 1 || c.max_call_depth > 16) {
    e.push_back("compiler.max_call_depth: must be 1..16, not " + std::to_string(c.max_call_depth));
  }
  const auto& s = smoothing;
  if (s.spline_points != 0 && (s.spline_points < 50 || s.spline_points > 500)) {
    e.push_back("smoothing.spline_points: must be 0 (off) or 50..500, not " +
                std::to_string(s.spline_points));
  }
  if (!finite_positive(s.spline_jerk_mm_s3)) {
    e.push_back("smoothing.spline_jerk_mm_s3: must be > 0, not " +
                exact_number_text(s.spline_jerk_mm_s3));
  } else if (s.spline_jerk_mm_s3 >= kCarriedJerkBound) {
    // Command -2 carries it in a 32-bit Command_Parameter, whether or not the spline is on:
    // tgm-plc sent 3e9 as -2147483648.
    e.push_back(
        "smoothing.spline_jerk_mm_s3: must be at most 2147483647 (Command -2 carries it as a "
        "32-bit parameter), not " +
        exact_number_text(s.spline_jerk_mm_s3));
  }
  if (s.iir_p_e6 <= 0) e.push_back("smoothing.iir_p_e6: must be > 0");
  if (s.iir_q_e6 <= 0) e.push_back("smoothing.iir_q_e6: must be > 0");
  if (s.iir_f_e6 <= 0) e.push_back("smoothing.iir_f_e6: must be > 0");
  if (s.iir_axis_mask > 0x3FFu) e.push_back("smoothing.iir_axis_mask: only 10 bits (0..1023)");
  // Bit 0 is axis 0: a mask of axes no interpolator has filtered nothing, without a word.
  std::size_t most_axes = 0;
  for (const auto& ip : interpolators) most_axes = std::max(most_axes, ip.axes.size());
  if (s.iir_axis_mask != 0 && most_axes >= 1 && most_axes <= kMaxAxes &&
      IirFilter::mask_of_axes(s.iir_axis_mask, static_cast<int>(most_axes)) == 0) {
    e.push_back("smoothing.iir_axis_mask: " + std::to_string(s.iir_axis_mask) +
                " selects no axis of any interpolator (bit 0 is axis 0; the largest has " +
                std::to_string(most_axes) + " axes)");
  }
  // The checks of Command -1 / -2 (core/SMOOTHING.md), so a bad default is reported at load:
  // with the mask 0 too (a typo stayed hidden until the filter was turned on, session 75), and
  // under the key at fault (an f out of range was said at iir_p_e6's line, as smoothing.iir).
  if (s.iir_p_e6 > 0 && s.iir_q_e6 > 0 && s.iir_f_e6 > 0) {
    if (const RequestResult r = IirFilter::check(s.iir_p_e6, s.iir_q_e6, s.iir_f_e6); !r.ok()) {
      const std::string& w = r.reason;
      const char* key = w.rfind("IIR p ", 0) == 0   ? "smoothing.iir_p_e6"
                        : w.rfind("IIR q ", 0) == 0 ? "smoothing.iir_q_e6"
                        : w.rfind("IIR f ", 0) == 0 ? "smoothing.iir_f_e6"
                                                    : "smoothing.iir";
      e.push_back(std::string(key) + ": " + w);
    }
  }
  if (s.spline_points >= 50 && s.spline_points <= 500 && finite_positive(s.spline_jerk_mm_s3) &&
      s.spline_jerk_mm_s3 < kCarriedJerkBound) {
    if (std::llround(s.spline_jerk_mm_s3) < 1) {
      // Command -2 takes the jerk rounded to whole mm/s^3: 0.2 became 0, and the message said
      // "must be > 0 mm/s^3, not 0" of a value the file gives as 0.2.
      e.push_back(
          "smoothing.spline_jerk_mm_s3: must be at least 0.5 (Command -2 takes it rounded "
          "to whole mm/s^3), not " +
          exact_number_text(s.spline_jerk_mm_s3));
    } else if (const RequestResult r =
                   SplineSmoother::check(s.spline_points, std::llround(s.spline_jerk_mm_s3));
               !r.ok()) {
      e.push_back("smoothing.spline: " + r.reason);
    }
  }
  return e;
}

MachineConfig MachineConfig::default_machine() {
  // A small gantry mill: 15 m/min rapids, 1.5 m/s^2 acceleration with a jerk that lets a
  // 50 mm circle at 6 m/min run at feed (centripetal 0.2 m/s^2).
  MachineConfig m;
  InterpolatorConfig ip;
  ip.buffer_size = 10000;
  for (int i = 0; i < 3; ++i) {
    AxisConfig a;
    a.letter = default_axis_letter(i);
    a.max_velocity_mm_s = 250.0;
    a.rapid_velocity_mm_s = 250.0;
    a.max_acceleration_mm_s2 = 1500.0;
    a.max_jerk_mm_s3 = 30000.0;
    a.emergency_deceleration_mm_s2 = 4000.0;
    a.corner_velocity_tolerance_mm_s = 2.0;
    a.ratio_inc_per_mm = 1000.0;
    ip.axes.push_back(a);
  }
  m.interpolators.assign(3, ip);
  m.tools = {{1, 3.0, 50.0}, {2, 5.0, 60.0}, {3, 1.5, 40.0}};
  return m;
}

}  // namespace tgm
