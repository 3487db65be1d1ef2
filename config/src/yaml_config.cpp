#include "tgm/yaml_config.hpp"

#include "tgm/cli_numbers.hpp"
#include "tgm/file_text.hpp"
#include "tgm/intercode.hpp"
#include "tgm/printable.hpp"
#include "yaml_document.hpp"
#include "yaml_mark.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace tgm {

namespace {

// Walks a YAML tree, collecting errors instead of throwing, and rejecting unknown keys.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  std::vector<std::string> errors;
  // Line (1-based) of each value read, by key path; and for a value an axis took from
  // axis_defaults, the key path it was written at (validate() names the axis's own path).
  std::map<std::string, int> line_of;
  std::map<std::string, std::string> origin;
  // Key paths already reported: validate() says nothing more about them.
  std::set<std::string> rejected;

  // yaml-cpp marks an empty value ("key:" and nothing) where the next token starts, often
  // lines further down; such a value is placed at its key instead, and an empty list item
  // ("-" and nothing) at its `-` (empty_item_line, from `text`). Called once on the root.
  // Each collection is walked once: an alias is the node of its anchor, and ten lists of ten
  // aliases of the one before, eight deep, took 5 s to walk through every alias (12 deep:
  // hours), for a file of 700 bytes.
  void index_empty_values(const YAML::Node& root, std::string_view text) {
    std::unordered_multimap<int, YAML::Node> walked;  // the collections, by where they start
    std::vector<YAML::Node> todo{root};  // a list, not recursion: depth is yaml-cpp's bound
    while (!todo.empty()) {
      const YAML::Node n = todo.back();
      todo.pop_back();
      if (!n.IsMap() && !n.IsSequence()) continue;
      const int at = n.Mark().pos;
      const auto [from, to] = walked.equal_range(at);
      if (std::any_of(from, to, [&](const auto& w) { return w.second.is(n); })) continue;
      walked.emplace(at, n);
      if (n.IsMap()) {
        for (const auto& kv : n) {
          if (kv.second.IsNull())
            empty_values_.emplace(kv.second.Mark().pos, EmptyValue{kv.second, kv.first.Mark()});
          todo.push_back(kv.second);
        }
      } else {
        for (const auto& v : n) {
          if (v.IsNull()) {
            YAML::Mark dash = v.Mark();
            dash.line = empty_item_line(text, dash);
            empty_values_.emplace(v.Mark().pos, EmptyValue{v, dash});
          }
          todo.push_back(v);
        }
      }
    }
  }

  int line(const YAML::Node& n) const {
    if (!n.IsDefined()) return -1;
    if (n.IsNull()) {
      // By where yaml-cpp marked it: 200,000 empty values, each reported, took 20 s looked up
      // one by one.
      const auto [from, to] = empty_values_.equal_range(n.Mark().pos);
      for (auto it = from; it != to; ++it) {
        if (it->second.value.is(n)) return it->second.key.line;
      }
    }
    return n.Mark().line;
  }

  void note(const YAML::Node& n, const std::string& path) {
    if (const int l = line(n); l >= 0) line_of[path] = l + 1;
  }

  void error(const YAML::Node& n, const std::string& path, const std::string& reason) {
    std::string where = file_;
    if (const int l = line(n); l >= 0) {
      // Appended piece by piece: GCC 12 at -O3 warns (-Wrestrict, falsely) on ":" + to_string().
      where += ':';
      where += std::to_string(l + 1);
    }
    errors.push_back(where + ": " + path + ": " + reason);
    rejected.insert(path);
  }

  // Checks that `n` is a map whose keys are all in `known`, each given once.
  bool map(const YAML::Node& n, const std::string& path, const std::set<std::string>& known) {
    if (!n.IsMap()) {
      error(n, path.empty() ? "(top level)" : path, "must be a mapping of key: value");
      return false;
    }
    unique_keys(n, path);
    for (const auto& kv : n) {
      const std::string key = text(kv.first);  // a list or mapping as a key is named, not ""
      if (!known.count(key)) {
        std::string list;
        for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
        error(kv.first, join(path, key), "unknown key (known: " + list + ")");
      }
    }
    return true;
  }

  // map() for a top-level section, which may be empty: "plc:" followed by comments only is
  // null in YAML, and reads as {} (an empty file does too); false then, as nothing is to read.
  bool section(const YAML::Node& n, const std::string& path, const std::set<std::string>& known) {
    return !n.IsNull() && map(n, path, known);
  }

  // A key given twice in one mapping is an error: yaml-cpp keeps both, and a lookup would
  // silently take the first.
  void unique_keys(const YAML::Node& n, const std::string& path) {
    std::set<std::string> seen;
    for (const auto& kv : n) {
      if (!kv.first.IsScalar()) continue;  // never a known key: map() names it
      const std::string& key = kv.first.Scalar();
      if (!seen.insert(key).second) error(kv.first, join(path, key), "given twice");
    }
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

  void number(const YAML::Node& parent, const std::string& path, const char* key, double& out) {
    const auto n = parent[key];
    if (!n) return;
    double v = 0;
    if (!scalar_double(n, v)) {
      error(n, join(path, key), not_a_number(n));
      return;
    }
    note(n, join(path, key));
    out = v;
  }

  template <typename Int>
  void integer(const YAML::Node& parent, const std::string& path, const char* key, Int& out) {
    const auto n = parent[key];
    if (!n) return;
    long long v = 0;
    if (!scalar_int(n, v)) {
      error(n, join(path, key), "must be a whole number, not '" + text(n) + "'");
      return;
    }
    // No wrap-around through the cast: 4294967796 was read as a cycle time of 500 us.
    constexpr auto lo = static_cast<long long>(std::numeric_limits<Int>::min());
    constexpr auto hi = static_cast<long long>(std::min<unsigned long long>(
        std::numeric_limits<Int>::max(), std::numeric_limits<long long>::max()));
    if (v < lo || v > hi) {
      error(n, join(path, key),
            "must be a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) +
                ", not '" + text(n) + "'");
      return;
    }
    note(n, join(path, key));
    out = static_cast<Int>(v);
  }

  void boolean(const YAML::Node& parent, const std::string& path, const char* key, bool& out) {
    const auto n = parent[key];
    if (!n) return;
    if (!n.IsScalar()) {
      error(n, join(path, key), "must be true or false");
      return;
    }
    const auto s = n.Scalar();
    if (s == "true" || s == "yes" || s == "on") {
      out = true;
    } else if (s == "false" || s == "no" || s == "off") {
      out = false;
    } else {
      error(n, join(path, key), "must be true or false (also yes / no, on / off), not '" + s + "'");
    }
  }

  //! False when the key is there but not a string (said).
  bool string(const YAML::Node& parent, const std::string& path, const char* key,
              std::string& out) {
    const auto n = parent[key];
    if (!n) return true;
    if (!n.IsScalar()) {
      error(n, join(path, key), "must be a string");
      return false;
    }
    out = n.Scalar();
    return true;
  }

  static std::string text(const YAML::Node& n) {
    if (n.IsScalar()) return n.Scalar();
    if (n.IsSequence()) return "[list]";
    if (n.IsMap()) return "{mapping}";
    return "null";
  }

  // Numbers are read as the command line reads them (cli_numbers.hpp): the whole scalar,
  // finite; whole numbers in base 10 (with base 0, 0500 was octal 320) and within long long
  // (an overflow was clamped and then narrowed to -1).
  // Why `n` is no number: text that reads as one but not as a finite double is named so
  // ("1e400" was "must be a number", which points at the wrong fix).
  std::string not_a_number(const YAML::Node& n) const {
    if (n.IsScalar()) {
      const std::string& t = n.Scalar();
      char* end = nullptr;
      errno = 0;
      const double d = std::strtod(t.c_str(), &end);
      if (!t.empty() && end == t.c_str() + t.size() && !std::isnan(d)) {
        if (std::isinf(d)) {
          return "must be a finite number, not '" + text(n) + "' (beyond the range of a double)";
        }
        if (errno == ERANGE) {
          return "must be a number, not '" + text(n) +
                 "' (too small for a double: it would read as 0)";
        }
      }
    }
    return "must be a number, not '" + text(n) + "'";
  }

  static bool scalar_double(const YAML::Node& n, double& v) {
    return n.IsScalar() && parse_finite(n.Scalar(), v);
  }

  static bool scalar_int(const YAML::Node& n, long long& v) {
    return n.IsScalar() && parse_integer(n.Scalar(), std::numeric_limits<long long>::min(),
                                         std::numeric_limits<long long>::max(), v);
  }

 private:
  std::string file_;
  struct EmptyValue {
    YAML::Node value;
    YAML::Mark key;  // where it is named: its key, or for a list item its `-`
  };
  std::unordered_multimap<int, EmptyValue> empty_values_;  // by the value's own mark
};

const std::set<std::string> kAxisKeys = {"letter",
                                         "max_velocity_mm_s",
                                         "max_acceleration_mm_s2",
                                         "max_jerk_mm_s3",
                                         "rapid_velocity_mm_s",
                                         "emergency_deceleration_mm_s2",
                                         "corner_velocity_tolerance_mm_s",
                                         "corner_acceleration_tolerance_mm_s2",
                                         "ratio_inc_per_mm",
                                         "backlash_mm",
                                         "backlash_ramp_share",
                                         "min_position_mm",
                                         "max_position_mm"};

void read_axis(Reader& r, const YAML::Node& n, const std::string& path, AxisConfig& a,
               bool letter_allowed) {
  auto keys = kAxisKeys;
  if (!letter_allowed) keys.erase("letter");
  if (!r.map(n, path, keys)) return;
  if (letter_allowed && n["letter"]) {
    std::string s;
    if (!r.string(n, path, "letter", s)) {
      // said
    } else if (s.size() != 1) {
      r.error(n["letter"], path + ".letter", "must be one letter, not '" + s + "'");
    } else {
      a.letter = static_cast<char>(std::toupper(static_cast<unsigned char>(s[0])));
      r.note(n["letter"], path + ".letter");
    }
  }
  r.number(n, path, "max_velocity_mm_s", a.max_velocity_mm_s);
  r.number(n, path, "max_acceleration_mm_s2", a.max_acceleration_mm_s2);
  r.number(n, path, "max_jerk_mm_s3", a.max_jerk_mm_s3);
  r.number(n, path, "rapid_velocity_mm_s", a.rapid_velocity_mm_s);
  r.number(n, path, "emergency_deceleration_mm_s2", a.emergency_deceleration_mm_s2);
  r.number(n, path, "corner_velocity_tolerance_mm_s", a.corner_velocity_tolerance_mm_s);
  r.number(n, path, "corner_acceleration_tolerance_mm_s2", a.corner_acceleration_tolerance_mm_s2);
  r.number(n, path, "ratio_inc_per_mm", a.ratio_inc_per_mm);
  r.number(n, path, "backlash_mm", a.backlash_mm);
  r.number(n, path, "backlash_ramp_share", a.backlash_ramp_share);
  r.number(n, path, "min_position_mm", a.min_position_mm);
  r.number(n, path, "max_position_mm", a.max_position_mm);
}

// Notes the axis_defaults keys that axis `path` (its own node `axis`, maybe undefined) takes.
void from_defaults(Reader& r, const YAML::Node& defaults, const YAML::Node& axis,
                   const std::string& path) {
  if (!defaults || !defaults.IsMap()) return;
  for (const std::string& key : kAxisKeys) {
    if (defaults[key] && !(axis && axis.IsMap() && axis[key])) {
      r.origin[path + "." + key] = "axis_defaults." + key;
    }
  }
}

// validate()'s findings ("key.path: reason") with the file and the line the value was written
// at. A value an axis took from axis_defaults is named there, once for every axis that took it
// with the same finding (a bad default was reported nine times, without a line).
std::vector<std::string> locate(const Reader& r, const std::string& file,
                                const std::vector<std::string>& findings) {
  std::vector<std::string> out;
  std::map<std::string, std::size_t> shared;  // "origin: reason" -> index in out
  std::map<std::string, int> takers;
  // A finding `id` of defaults that several axes take is said once: as `first`, then as
  // "WHERE: ID; N axes take it".
  const auto say_once = [&](const std::string& where, const std::string& id, std::string first) {
    const auto [it, fresh] = shared.emplace(id, out.size());
    if (fresh) out.push_back(std::move(first));
    if (++takers[id] > 1) {
      out[it->second] = where + ": " + id + "; " + std::to_string(takers[id]) + " axes take it";
    }
  };
  for (const std::string& f : findings) {
    const std::size_t colon = f.find(": ");
    const std::string key = colon == std::string::npos ? f : f.substr(0, colon);
    const std::string reason = colon == std::string::npos ? "" : f.substr(colon + 2);
    if (r.rejected.count(key)) continue;  // the reader said what is wrong with it
    const auto o = r.origin.find(key);
    const std::string at = o != r.origin.end() ? o->second : key;
    // A finding about more than one key (the IIR and spline checks of Command -1 / -2, the
    // number of interpolators) has the line of the nearest section above it that was read.
    auto l = r.line_of.find(at);
    for (std::string up = at; l == r.line_of.end();) {
      const std::size_t cut = up.find_last_of(".[");
      if (cut == std::string::npos || cut == 0) break;
      up.resize(cut);
      l = r.line_of.find(up);
    }
    // A finding about a group of keys the file gives (smoothing.iir: the iir_* keys) is at the
    // first of them, not at its section, and is no built-in value: it was said to be "iir is
    // not given: the built-in value" under the very keys that gave it.
    int group_line = -1;
    if (r.line_of.count(at) == 0) {
      const std::string prefix = at + "_";
      for (auto g = r.line_of.lower_bound(prefix);
           g != r.line_of.end() && g->first.compare(0, prefix.size(), prefix) == 0; ++g) {
        if (group_line < 0 || g->second < group_line) group_line = g->second;
      }
    }
    std::string where = file;
    if (group_line >= 0) {
      where.append(":").append(std::to_string(group_line));
    } else if (l != r.line_of.end()) {
      where.append(":").append(std::to_string(l->second));
    }
    if (o == r.origin.end()) {
      // A value the file does not give is the built-in one: say so, or "rapid_velocity_mm_s:
      // 250 exceeds max_velocity_mm_s 100" names a 250 the reader looks for in vain.
      const bool built_in =
          r.line_of.count(key) == 0 && group_line < 0 && key.find('.') != std::string::npos;
      if (built_in) {
        // The other key of the finding, when the axis took it from axis_defaults: the finding
        // is that default's, said once at its line for every axis that takes it (a config of
        // only `axis_defaults: {max_velocity_mm_s: 100}` gave nine findings without a line).
        const std::string name = key.substr(key.rfind('.') + 1);
        const std::string axis = key.substr(0, key.rfind('.'));
        std::string from;
        for (const std::string& other : kAxisKeys) {
          if (other == name || reason.find(other) == std::string::npos) continue;
          if (const auto d = r.origin.find(axis + "." + other); d != r.origin.end()) {
            from = d->second;
            break;
          }
        }
        if (!from.empty()) {
          std::string at_line = file;
          if (const auto fl = r.line_of.find(from); fl != r.line_of.end())
            at_line.append(":").append(std::to_string(fl->second));
          const std::string id = from + ": the built-in " + name + " (not given) " + reason;
          say_once(at_line, id, at_line + ": " + id + " (" + axis + ")");
          continue;
        }
      }
      out.push_back(
          where + ": " + f +
          (built_in ? " (" + key.substr(key.rfind('.') + 1) + " is not given: the built-in value)"
                    : std::string()));
      continue;
    }
    const std::string id = at + ": " + reason;
    say_once(where, id, where + ": " + f + " (from " + at + ")");
  }
  return out;
}

void read_file(Reader& r, const YAML::Node& root, AppConfig& cfg) {
  if (!r.map(root, "",
             {"cycle_time_us", "axis_defaults", "interpolators", "tools", "compiler", "smoothing",
              "dds", "plc"})) {
    return;
  }
  MachineConfig& m = cfg.machine;
  r.integer(root, "", "cycle_time_us", m.cycle_time_us);

  // Every axis starts from the built-in machine's axis (the values config/default.yaml lists),
  // changed by axis_defaults, then by its own keys.
  AxisConfig defaults = MachineConfig::default_machine().interpolators.front().axes.front();
  // A section whose keys are all commented out ("axis_defaults:" and comments) is empty.
  if (root["axis_defaults"] && !root["axis_defaults"].IsNull()) {
    read_axis(r, root["axis_defaults"], "axis_defaults", defaults, false);
  }

  if (const auto ips = root["interpolators"]) {
    r.note(ips, "interpolators");
    if (!ips.IsSequence()) {
      r.error(ips, "interpolators", "must be a list of interpolators");
    } else {
      m.interpolators.clear();
      for (std::size_t k = 0; k < ips.size(); ++k) {
        const std::string path = "interpolators[" + std::to_string(k) + "]";
        const auto n = ips[k];
        InterpolatorConfig ip;
        if (!r.map(n, path, {"buffer_size", "axes"})) continue;
        r.integer(n, path, "buffer_size", ip.buffer_size);
        const auto axes = n["axes"];
        if (!axes || !axes.IsSequence()) {
          r.error(axes ? axes : n, path + ".axes", "a list of 1..10 axes is required");
        } else {
          r.note(axes, path + ".axes");  // an empty list is named at its line
          for (std::size_t i = 0; i < axes.size(); ++i) {
            AxisConfig a = defaults;
            a.letter = default_axis_letter(static_cast<int>(i));
            const std::string ap = path + ".axes[" + std::to_string(i) + "]";
            r.note(axes[i], ap);  // the line of a finding about a value the axis does not give
            read_axis(r, axes[i], ap, a, true);
            from_defaults(r, root["axis_defaults"], axes[i], ap);
            ip.axes.push_back(a);
          }
        }
        m.interpolators.push_back(ip);
      }
    }
  } else if (root["axis_defaults"]) {
    // No interpolators listed: the axis defaults apply to the built-in machine's axes (they were
    // read and then dropped without a word).
    for (std::size_t k = 0; k < m.interpolators.size(); ++k) {
      auto& axes = m.interpolators[k].axes;
      for (std::size_t i = 0; i < axes.size(); ++i) {
        const char letter = axes[i].letter;
        axes[i] = defaults;
        axes[i].letter = letter;
        from_defaults(r, root["axis_defaults"], YAML::Node(),
                      "interpolators[" + std::to_string(k) + "].axes[" + std::to_string(i) + "]");
      }
    }
  }

  if (const auto tools = root["tools"]) {
    if (!tools.IsSequence()) {
      r.error(tools, "tools", "must be a list of {number, radius_mm, length_mm}");
    } else {
      m.tools.clear();
      for (std::size_t i = 0; i < tools.size(); ++i) {
        const std::string path = "tools[" + std::to_string(i) + "]";
        ToolConfig t;
        if (!r.map(tools[i], path, {"number", "radius_mm", "length_mm"})) continue;
        // Without one the entry was tool 1, and two such entries were "tool 1 listed twice".
        if (!tools[i]["number"]) {
          r.error(tools[i], path + ".number", "is required (the T word that selects the tool)");
        }
        r.integer(tools[i], path, "number", t.number);
        r.number(tools[i], path, "radius_mm", t.radius_mm);
        r.number(tools[i], path, "length_mm", t.length_mm);
        m.tools.push_back(t);
      }
    }
  }

  if (const auto c = root["compiler"]) {
    if (r.section(c, "compiler",
                  {"distance_mode", "default_feed_mm_per_min", "initial_tool", "plc_redefined_m",
                   "max_program_segments", "max_call_depth", "block_delete"})) {
      if (c["block_delete"]) {
        std::string mode;
        if (!r.string(c, "compiler", "block_delete", mode)) {
          // said
        } else if (!parse_block_delete(mode, m.compiler.block_delete)) {
          r.error(c["block_delete"], "compiler.block_delete",
                  "must be error, run or skip, not '" + mode + "'");
        }
      }
      if (c["distance_mode"]) {
        std::string mode;
        if (!r.string(c, "compiler", "distance_mode", mode)) {
          // said
        } else if (mode == "G90" || mode == "g90") {
          m.compiler.start_incremental = false;
        } else if (mode == "G91" || mode == "g91") {
          m.compiler.start_incremental = true;
        } else {
          r.error(c["distance_mode"], "compiler.distance_mode", "must be G90 or G91, not '" +
                                                                    mode + "'");
        }
      }
      r.number(c, "compiler", "default_feed_mm_per_min", m.compiler.default_feed_mm_per_min);
      r.integer(c, "compiler", "max_program_segments", m.compiler.max_program_segments);
      r.integer(c, "compiler", "max_call_depth", m.compiler.max_call_depth);
      r.integer(c, "compiler", "initial_tool", m.compiler.initial_tool);
      if (const auto list = c["plc_redefined_m"]) {
        if (!list.IsSequence()) {
          r.error(list, "compiler.plc_redefined_m", "must be a list of M-numbers");
        } else {
          m.compiler.plc_redefined_m.clear();
          for (std::size_t i = 0; i < list.size(); ++i) {
            long long v = 0;
            r.note(list[i], "compiler.plc_redefined_m[" + std::to_string(i) + "]");
            if (!Reader::scalar_int(list[i], v)) {
              r.error(list[i], "compiler.plc_redefined_m[" + std::to_string(i) + "]",
                      "must be a whole number");
            } else if (v < 0 || v > kMaxNormalM) {
              // Not wrapped into an int: 4294967298 was read as M2.
              r.error(list[i], "compiler.plc_redefined_m[" + std::to_string(i) + "]",
                      redefine_m_problem(v));
            } else {
              m.compiler.plc_redefined_m.push_back(static_cast<int>(v));
            }
          }
        }
      }
    }
  }

  if (const auto s = root["smoothing"]) {
    r.note(s, "smoothing");
    if (r.section(s, "smoothing",
                  {"spline_points", "spline_jerk_mm_s3", "iir_p_e6", "iir_q_e6", "iir_f_e6",
                   "iir_axis_mask"})) {
      auto& sm = m.smoothing;
      r.integer(s, "smoothing", "spline_points", sm.spline_points);
      r.number(s, "smoothing", "spline_jerk_mm_s3", sm.spline_jerk_mm_s3);
      r.integer(s, "smoothing", "iir_p_e6", sm.iir_p_e6);
      r.integer(s, "smoothing", "iir_q_e6", sm.iir_q_e6);
      r.integer(s, "smoothing", "iir_f_e6", sm.iir_f_e6);
      r.integer(s, "smoothing", "iir_axis_mask", sm.iir_axis_mask);
    }
  }

  if (const auto d = root["dds"]) {
    if (r.section(d, "dds", {"domain_id", "profiles_file", "participant_prefix", "security"})) {
      r.integer(d, "dds", "domain_id", cfg.dds.domain_id);
      r.string(d, "dds", "profiles_file", cfg.dds.profiles_file);
      r.string(d, "dds", "participant_prefix", cfg.dds.participant_prefix);
      r.string(d, "dds", "security", cfg.dds.security_dir);
      // Both as the flags refuse them: an empty profiles file failed every binary later, in
      // Fast DDS, with exit 1 (a restart every 2 s under systemd) and "not found in ''".
      if (d["profiles_file"] && cfg.dds.profiles_file.empty()) {
        r.error(d["profiles_file"], "dds.profiles_file",
                "must name the Fast DDS profiles file (the shipped one: fastdds_profiles.xml), "
                "not an empty string");
      }
      if (d["participant_prefix"]) {
        if (const std::string why = DdsConfig::prefix_problem(cfg.dds.participant_prefix);
            !why.empty()) {
          r.error(d["participant_prefix"], "dds.participant_prefix", why);
        }
      }
      if (cfg.dds.domain_id < 0 || cfg.dds.domain_id > 232) {
        r.error(d["domain_id"], "dds.domain_id", "must be 0..232");
      }
    }
  }

  if (const auto p = root["plc"]) {
    if (r.section(p, "plc", {"default_m_delay_s", "m_delay_s", "setup_before_start"})) {
      r.boolean(p, "plc", "setup_before_start", cfg.plc.setup_before_start);
      r.number(p, "plc", "default_m_delay_s", cfg.plc.default_m_delay_s);
      if (cfg.plc.default_m_delay_s < 0 || cfg.plc.default_m_delay_s > 3600) {
        r.error(p["default_m_delay_s"], "plc.default_m_delay_s", "must be 0..3600 s");
      }
      if (const auto md = p["m_delay_s"]) {
        if (!md.IsMap()) {
          r.error(md, "plc.m_delay_s", "must map M-numbers to seconds, e.g. {51: 0.2}");
        } else {
          r.unique_keys(md, "plc.m_delay_s");
          // The table replaces the built-in one (default.yaml's), entry by entry it would be
          // a table the file does not show.
          cfg.plc.m_delay_s.clear();
          std::map<long long, std::string> given;  // M-number -> its key as written
          for (const auto& kv : md) {
            long long mnum = 0;
            double sec = 0;
            const std::string key = "plc.m_delay_s." + kv.first.as<std::string>("?");
            // Only a normal M-function waits for the PLC's acknowledgement: a delay for M0
            // (the operator's) or a continuous one did nothing, and a key beyond int wrapped
            // round (4294967347 delayed M51).
            if (!Reader::scalar_int(kv.first, mnum) || mnum < 1 || mnum > kMaxNormalM) {
              r.error(kv.first, key,
                      "key must be a normal M-function 1.." + std::to_string(kMaxNormalM) +
                          " (the ones the PLC acknowledges)");
            } else if (!Reader::scalar_double(kv.second, sec) || sec < 0 || sec > 3600) {
              r.error(kv.second, key, "must be 0..3600 s");
            } else if (const auto [at, fresh] = given.emplace(mnum, kv.first.as<std::string>("?"));
                       !fresh) {
              // 51 and 051 are one M-function: the later entry silently won. The same text
              // twice unique_keys has said.
              if (at->second != kv.first.as<std::string>("?")) {
                r.error(
                    kv.first, key,
                    "M" + std::to_string(mnum) + " is given twice (also as " + at->second + ")");
              }
            } else {
              cfg.plc.m_delay_s[static_cast<int>(mnum)] = sec;
            }
          }
        }
      }
    }
  }
}

}  // namespace

ConfigLoad load_config_text(const std::string& text, const std::string& path) {
  ConfigLoad out;
  AppConfig cfg;
  cfg.machine = MachineConfig::default_machine();
  cfg.source_path = path;
  Reader r(path);
  YAML::Node root;
  try {
    root = load_one_document(text);
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's own message for this is "bad file".
    out.errors.push_back(printable(path + yaml_place(e.mark) + ": YAML syntax: nested more than " +
                                   std::to_string(e.depth() - 1) + " levels deep"));
    return out;
  } catch (const YAML::Exception& e) {
    out.errors.push_back(printable(path + yaml_place(e.mark) + ": YAML syntax: " + e.msg));
    return out;
  }
  try {
    if (root.IsNull()) {
      // An empty file means: all defaults.
    } else {
      r.index_empty_values(root, text);
      read_file(r, root, cfg);
    }
  } catch (const YAML::Exception& e) {
    r.errors.push_back(path + yaml_place(e.mark) + ": " + e.msg);
  }
  for (auto& e : locate(r, path, cfg.machine.validate())) r.errors.push_back(std::move(e));
  if (!r.errors.empty()) {
    // Keys and values are quoted from the file: a control character in them (an escape in a
    // quoted scalar) is shown, not sent to the terminal.
    for (std::string& e : r.errors) out.errors.push_back(printable(e));
    return out;
  }
  // The profiles file and the security directory are relative to the YAML file.
  namespace fs = std::filesystem;
  // A config that names no profiles file takes the one beside it, or else the one shipped with
  // tgm: a machine config written elsewhere (/etc/tgm/mill.yaml) was refused for a missing
  // fastdds_profiles.xml it never asked for.
  if (!(root.IsMap() && root["dds"].IsMap() && root["dds"]["profiles_file"])) {
    std::error_code ec;
    const fs::path beside = fs::path(path).parent_path() / cfg.dds.profiles_file;
    if (path.empty() || !fs::exists(beside, ec))
      cfg.dds.profiles_file = shipped_config_file(cfg.dds.profiles_file);
  }
  for (std::string* p : {&cfg.dds.profiles_file, &cfg.dds.security_dir}) {
    if (!p->empty() && fs::path(*p).is_relative() && !path.empty()) {
      *p = (fs::path(path).parent_path() / *p).string();
    }
  }
  out.config = std::move(cfg);
  return out;
}

ConfigLoad load_config_file(const std::string& path) {
  // Up to a bound: a config is a few KB, and a device without end (/dev/zero) or a large file
  // given by mistake must not be read for minutes.
  std::string text;
  if (std::string error = read_settings_file(path, "config", kMaxConfigBytes, text);
      !error.empty()) {
    ConfigLoad out;
    out.errors.push_back(std::move(error));
    return out;
  }
  return load_config_text(text, path);
}

std::optional<AppConfig> load_config_or_report(const std::string& path,
                                               const std::string& program) {
  const std::string file = path.empty() ? default_config_path() : path;
  ConfigLoad load = load_config_file(file);
  if (!load.config) {
    // A file that is not a config at all (a G-code program, a log given by mistake) has a
    // problem on every line: the first ones say what is wrong, the count says the rest.
    const std::size_t shown = std::min(load.errors.size(), kConfigProblemsShown);
    for (std::size_t k = 0; k < shown; ++k) std::fprintf(stderr, "%s\n", load.errors[k].c_str());
    if (shown < load.errors.size()) {
      std::fprintf(stderr, "%s: ... and %zu more not shown\n", file.c_str(),
                   load.errors.size() - shown);
    }
    // A path the user never typed is said to come from the environment (a stale TGM_CONFIG
    // of /etc/default/tgm or a container image looked like a path from nowhere).
    const char* env = std::getenv("TGM_CONFIG");
    const bool from_env = path.empty() && env != nullptr && *env != '\0';
    std::fprintf(stderr, "%s: the config %s%s has %zu problem%s\n", program.c_str(), file.c_str(),
                 from_env ? " (from $TGM_CONFIG)" : "", load.errors.size(),
                 load.errors.size() == 1 ? "" : "s");
  }
  return std::move(load.config);
}

std::string DdsConfig::prefix_problem(std::string_view prefix) {
  if (prefix.empty()) return "must not be empty";
  if (prefix.size() > kMaxPrefix) {
    return "is " + std::to_string(prefix.size()) + " bytes long: at most " +
           std::to_string(kMaxPrefix) + " (Fast DDS cuts participant names at 255)";
  }
  for (const char c : prefix) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      return "must not hold control characters";
    }
  }
  return {};
}

std::string default_config_path() {
  if (const char* env = std::getenv("TGM_CONFIG"); env && *env) return env;
  return shipped_config_file("default.yaml");
}

std::string shipped_config_file(const std::string& name) {
  namespace fs = std::filesystem;
  std::error_code ec;
  // Beside the running binary first (P/bin/../share/tgm): an installation made with
  // `cmake --install --prefix P`, or moved, finds its own files, not the configured prefix's.
  if (const fs::path exe = fs::read_symlink("/proc/self/exe", ec); !ec && exe.has_parent_path()) {
    const fs::path beside = exe.parent_path().parent_path() / "share" / "tgm" / name;
    if (fs::exists(beside, ec)) return beside.string();
  }
  const fs::path installed = fs::path(TGM_INSTALL_CONFIG_DIR) / name;
  if (fs::exists(installed, ec)) return installed.string();
  return (fs::path(TGM_SOURCE_CONFIG_DIR) / name).string();
}

}  // namespace tgm
