#include "tgm/plc_script.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <set>

#include "tgm/cli_numbers.hpp"
#include "tgm/command_stage.hpp"
#include "tgm/config.hpp"
#include "tgm/file_text.hpp"
#include "tgm/intercode.hpp"
#include "tgm/output_stage.hpp"
#include "tgm/printable.hpp"
#include "tgm/yaml_config.hpp"
#include "yaml_document.hpp"
#include "yaml_mark.hpp"

namespace tgm {

namespace {

// What a node holds, for a message: a scalar as written, else its kind.
std::string shown(const YAML::Node& n) {
  if (n.IsScalar()) return n.Scalar();
  if (n.IsSequence()) return "[list]";
  if (n.IsMap()) return "{map}";
  return "null";
}

// One step's keys; "" or the reason (without the place).
// `key_line` receives the line of the key being read (1-based; of the one that is wrong when
// this returns a reason): a step over several lines is named where its bad key stands.
std::string read_step(const YAML::Node& n, PlcScriptStep& s, int& key_line) {
  std::set<std::string> seen;
  for (const auto& kv : n) {
    key_line = kv.first.Mark().line + 1;
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "(not a name)";
    if (!seen.insert(key).second) return "'" + key + "' is given twice";  // yaml-cpp keeps both
    const YAML::Node& v = kv.second;
    const auto bad = [&](const std::string& what) {
      return key + " must be " + what + ", not '" + shown(v) + "'";
    };
    // Values are read as the command line reads numbers (cli_numbers.hpp: the whole text,
    // base 10, finite) and checked against their range: yaml-cpp's conversion said only "bad
    // conversion", and a Rel_Speed the service refuses is an error here, not in the run.
    const auto number = [&](double lo, double hi, double& out) {
      return v.IsScalar() && parse_finite(v.Scalar(), out) && out >= lo && out <= hi;
    };
    long long k = 0;
    double x = 0.0;
    if (key == "at_s") {
      if (!number(0.0, 1e9, s.at_s)) return bad("a number of seconds 0..1e9");
    } else if (key == "interpolator") {
      if (!v.IsScalar() || !parse_integer(v.Scalar(), 0LL, kMaxInterpolators - 1LL, k)) {
        return bad("an interpolator 0.." + std::to_string(kMaxInterpolators - 1));
      }
      s.interpolator = static_cast<int>(k);
    } else if (key == "rel_speed") {
      if (!number(0.01, 2.0, x)) return bad("an override 0.01..2");
      s.rel_speed = x;
    } else if (key == "command") {
      if (!v.IsScalar() || !parse_integer(v.Scalar(), INT32_MIN + 0LL, INT32_MAX + 0LL, k) ||
          !plc_script_command(k)) {
        return bad("a Command: 4, 5, 8, 9 (stops), 1024, 2048, 2049, -1 or -2");
      }
      s.command = static_cast<int>(k);
    } else if (key == "parameters") {
      if (!v.IsSequence()) return bad("a list of Command parameters");
      if (v.size() > s.parameters.size()) {
        return "parameters takes at most " + std::to_string(s.parameters.size()) +
               " values (Command_Parameter[0..11]), not " + std::to_string(v.size());
      }
      std::size_t i = 0;
      for (const YAML::Node& p : v) {
        if (!p.IsScalar() || !parse_integer(p.Scalar(), INT32_MIN + 0LL, INT32_MAX + 0LL, k)) {
          return "parameters must list 32-bit integers, not '" + shown(p) + "'";
        }
        s.parameters[i++] = static_cast<std::int32_t>(k);
      }
    } else if (key == "number_axes") {
      if (!v.IsScalar() || !parse_integer(v.Scalar(), 1LL, kMaxAxes + 0LL, k)) {
        return bad("a number of axes 1.." + std::to_string(kMaxAxes));
      }
      s.number_axes = static_cast<int>(k);
    } else if (key == "ratio" || key == "offset") {
      const bool ratio = key == "ratio";
      const char* what = ratio ? "Ratio [inc/mm] by axis letter, e.g. {X: 2000}"
                               : "Offset [inc] by axis letter, e.g. {X: 500, Z: -20}";
      if (!v.IsMap() || v.size() == 0) return bad(std::string("a map of ") + what);
      std::set<char> axes;
      for (const auto& av : v) {
        std::string letter = av.first.IsScalar() ? av.first.Scalar() : "";
        // Case-insensitive, as the config's axis letters (yaml_config.cpp) and G-code's words are.
        if (letter.size() == 1)
          letter[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(letter[0])));
        const std::string in = key + " of '" + letter + "'";
        if (letter.size() != 1 || letter[0] < 'A' || letter[0] > 'Z') {
          return key + " takes axis letters A..Z as keys, not '" + shown(av.first) + "'";
        }
        if (!axes.insert(letter[0]).second) return in + " is given twice";
        const YAML::Node& a = av.second;
        if (ratio) {
          if (!a.IsScalar() || !parse_finite(a.Scalar(), x) || !(std::fabs(x) >= kMinRatio) ||
              !(std::fabs(x) <= kMaxRatio)) {
            return in + " must be inc/mm with |ratio| 1e-06..1e+09, not '" + shown(a) + "'";
          }
          s.ratio.emplace_back(letter[0], x);
        } else {
          if (!a.IsScalar() || !parse_integer(a.Scalar(), -kMaxOffsetInc, kMaxOffsetInc, k)) {
            return in + " must be whole increments, |offset| <= 1e15, not '" + shown(a) + "'";
          }
          s.offset_inc.emplace_back(letter[0], k);
        }
      }
    } else if (key == "start") {
      const std::string t = v.IsScalar() ? v.Scalar() : "";
      if (t == "true" || t == "yes" || t == "on") {
        s.start = true;
      } else if (t != "false" && t != "no" && t != "off") {
        return bad("true or false");
      }
    } else if (key == "refuse_ack") {
      if (!v.IsSequence()) return bad("a list of M numbers");
      // Refusing a continuous M-function would do nothing: the interpolator does not wait for it.
      for (const YAML::Node& m : v) {
        if (!m.IsScalar() || !parse_integer(m.Scalar(), 1LL, kMaxNormalM + 0LL, k)) {
          return "refuse_ack must list normal M-functions 1.." + std::to_string(kMaxNormalM) +
                 " (the interpolator waits only for those), not '" + shown(m) + "'";
        }
        s.refuse_ack.push_back(static_cast<int>(k));
      }
    } else {
      return "unknown key '" + key + "' (known: at_s, interpolator, rel_speed, number_axes, " +
             "ratio, offset, command, parameters, start, refuse_ack)";
    }
  }
  if (seen.count("parameters") != 0 && !s.command)
    return "parameters belong to a command: give command too";
  return {};
}

}  // namespace

bool plc_script_command(long long code) {
  if (code < INT32_MIN || code > INT32_MAX) return false;
  const auto c = static_cast<std::int32_t>(code);
  return c == 4 || c == 5 || c == 8 || c == 9 || is_stage_command(c);
}

std::string plc_script_interpolator_problem(const PlcScriptStep& step, int count, int only) {
  const std::string named = "interpolator " + std::to_string(step.interpolator);
  if (step.interpolator < 0 || step.interpolator >= count) {
    return named + " does not exist (the config has " + std::to_string(count) + ")";
  }
  if (only >= 0 && step.interpolator != only) {
    // A step without `interpolator:` is for interpolator 0: said, since that is easy to miss.
    return named + " is not served: tgm-plc runs with --interpolator " + std::to_string(only) +
           (step.interpolator == 0 ? " (a step without `interpolator: N` is for interpolator 0)"
                                   : "");
  }
  return {};
}

std::string plc_script_axes_problem(const PlcScriptStep& step, const std::string& letters) {
  const std::string named = "interpolator " + std::to_string(step.interpolator);
  const auto axes = static_cast<int>(letters.size());
  if (step.number_axes && *step.number_axes > axes) {
    return named + ": number_axes " + std::to_string(*step.number_axes) + " is more than its " +
           std::to_string(axes) + " configured axes (" + letters + ")";
  }
  const auto unknown = [&](char letter, const char* key) -> std::string {
    if (letters.find(letter) != std::string::npos) return {};
    return named + ": " + key + " of '" + std::string(1, letter) + "': it has no such axis (" +
           letters + ")";
  };
  for (const auto& [letter, value] : step.ratio) {
    if (std::string why = unknown(letter, "ratio"); !why.empty()) return why;
  }
  for (const auto& [letter, value] : step.offset_inc) {
    if (std::string why = unknown(letter, "offset"); !why.empty()) return why;
  }
  return {};
}

std::vector<PlcAxisWrite> plc_script_axis_writes(const PlcScriptStep& step,
                                                 std::string_view service_letters) {
  const auto axis_of = [&](char letter) {
    const std::size_t at = service_letters.find(letter);
    return at == std::string_view::npos ? -1 : static_cast<int>(at);
  };
  std::vector<PlcAxisWrite> out;
  const auto add = [&](PlcAxisWrite::Register reg, char letter) -> PlcAxisWrite& {
    PlcAxisWrite& w = out.emplace_back();
    w.reg = reg;
    w.letter = letter;
    w.axis = axis_of(letter);
    return w;
  };
  for (const auto& [letter, ratio] : step.ratio) {
    add(PlcAxisWrite::Register::kRatio, letter).ratio_inc_per_mm = ratio;
  }
  for (const auto& [letter, offset] : step.offset_inc) {
    add(PlcAxisWrite::Register::kOffset, letter).offset_inc = offset;
  }
  return out;
}

std::string plc_script_duration_problem(const std::vector<PlcScriptStep>& steps, double duration_s,
                                        const std::string& path) {
  const PlcScriptStep* late = nullptr;
  for (const PlcScriptStep& s : steps) {
    if (s.at_s >= duration_s && (late == nullptr || s.at_s > late->at_s)) late = &s;
  }
  if (late == nullptr) return {};
  return printable("--duration " + shortest_text(duration_s) + " (seconds from the start) ends " +
                   "the run before the step at " + path + ":" + std::to_string(late->line) +
                   " (at_s " + shortest_text(late->at_s) +
                   ", seconds from when tgm-service is found) could run: give a --duration " +
                   "longer than the script's last at_s");
}

std::string plc_script_unrun(const std::vector<PlcScriptStep>& steps, const std::vector<bool>& ran,
                             const std::string& path) {
  std::size_t unrun = 0;
  const PlcScriptStep* first = nullptr;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    if (k < ran.size() && ran[k]) continue;
    ++unrun;
    if (first == nullptr) first = &steps[k];
  }
  if (first == nullptr) return {};
  return printable(std::to_string(unrun) + " of " + std::to_string(steps.size()) + " script step" +
                   (steps.size() == 1 ? "" : "s") + " never ran" + " (the first: " + path + ":" +
                   std::to_string(first->line) + ", at_s " + shortest_text(first->at_s) + ")");
}

namespace {

// A script's problems shown at most (the rest are counted).
constexpr std::size_t kScriptProblemsShown = 20;

// parse_plc_script before its one exit: every step's problem, in line order (one per step; a
// script with five mistakes took five edits and runs, each naming the next). A problem of the
// script as a whole (empty, not a list, YAML syntax) is the only one.
PlcScriptLoad read_script(std::string_view text, const std::string& path) {
  PlcScriptLoad out;
  std::vector<std::string> problems;
  const auto finish = [&] {
    for (std::size_t k = 0; k < problems.size() && k < kScriptProblemsShown; ++k) {
      if (k > 0) out.error += '\n';
      out.error += problems[k];
    }
    if (problems.size() > kScriptProblemsShown) {
      out.error += "\n" + printable(path) + ": ... and " +
                   std::to_string(problems.size() - kScriptProblemsShown) + " more not shown";
    }
  };
  try {
    const YAML::Node root = load_one_document(std::string(text));
    // Nothing but blanks and comments: said as such (it read "must be a list of steps").
    if (!root.IsDefined() || root.IsNull()) {
      out.error = printable(
          path + ": the script is empty; give at least one step, e.g. - {at_s: 3, command: 8}");
      return out;
    }
    if (!root.IsSequence()) {
      out.error =
          printable(path + ": the script must be a list of steps, e.g. - {at_s: 3, command: 8}");
      return out;
    }
    // As a step that does nothing (below): `[]` is a script left unwritten or cut, not a run.
    if (root.size() == 0) {
      out.error = printable(
          path + ": the script has no steps; give at least one, e.g. - {at_s: 3, command: 8}");
      return out;
    }
    for (const YAML::Node& n : root) {
      PlcScriptStep s;
      // An empty step ("-" alone) is marked where the next token starts: named at its `-`.
      s.line = (n.IsNull() ? empty_item_line(text, n.Mark()) : n.Mark().line) + 1;
      const std::string at = path + ":" + std::to_string(s.line) + ": ";
      if (!n.IsMap()) {
        problems.push_back(printable(at + "a step must be a map, e.g. {at_s: 3, command: 8}"));
        continue;
      }
      int key_line = 0;
      if (std::string why = read_step(n, s, key_line); !why.empty()) {
        problems.push_back(
            printable(path + ":" + std::to_string(key_line > 0 ? key_line : s.line) + ": " + why));
        continue;
      }
      // A step that does nothing is a mistake (an action left out, `start: false`, an empty
      // refuse_ack list): said rather than run as a silent no-op.
      if (!s.rel_speed && !s.number_axes && s.ratio.empty() && s.offset_inc.empty() && !s.command &&
          !s.start && s.refuse_ack.empty()) {
        problems.push_back(printable(at +
                                     "the step does nothing: give it rel_speed, number_axes, "
                                     "ratio, offset, command, start: true or refuse_ack [M, ...]"));
        continue;
      }
      out.steps.push_back(std::move(s));
    }
    finish();
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's own message for this is "bad file".
    out.error = printable(path + yaml_place(e.mark) + ": YAML syntax: nested more than " +
                          std::to_string(e.depth() - 1) + " levels deep");
  } catch (const YAML::Exception& e) {
    out.error = printable(path + yaml_place(e.mark) + ": YAML syntax: " + e.msg);
  }
  return out;
}

}  // namespace

PlcScriptLoad parse_plc_script(std::string_view text, const std::string& path) {
  PlcScriptLoad out = read_script(text, path);
  if (!out.ok()) {
    out.steps.clear();  // all or nothing: a script is not run in part
    // Keys and values are quoted from the script: control characters are shown, not sent to
    // the terminal (as the config loader does). read_script made each problem printable, so
    // that the line breaks between them stay.
  }
  return out;
}

PlcScriptLoad load_plc_script(const std::string& path) {
  std::string text;
  if (std::string error = read_settings_file(path, "script", kMaxConfigBytes, text);
      !error.empty()) {
    PlcScriptLoad out;
    out.error = std::move(error);
    return out;
  }
  return parse_plc_script(text, path);
}

}  // namespace tgm
