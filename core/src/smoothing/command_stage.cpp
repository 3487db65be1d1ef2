// Commands 1024, 2048, 2049, -1, -2 and Number_Axes (core/SMOOTHING.md, "Commands").
#include <algorithm>
#include <cmath>
#include <string>

#include "tgm/command_stage.hpp"
#include "tgm/printable.hpp"

namespace tgm {

namespace {

RequestResult refuse(RequestCode c, std::string why) { return {c, std::move(why)}; }

}  // namespace

bool is_stage_command(std::int32_t code) {
  return code == kCommandSetRatio || code == kCommandSetPositionOn ||
         code == kCommandSetPositionOff || code == kCommandIir || code == kCommandSpline;
}

RequestResult check_command(std::int32_t code,
                            const std::array<std::int32_t, kCommandParameters>& p,
                            const CommandContext& c) {
  switch (code) {
    case 4:
    case 5:
    case 8:
    case 9:
      return {};
    case kCommandSetRatio: {
      // The checks OutputStage::set_ratio makes, against Number_Axes: a ratio out of range
      // passed here (and tgm-plc's check of a script) and was refused only when executed.
      if (RequestResult r = OutputStage::check_ratio(p[0], p[1], p[2], c.number_axes); !r.ok())
        return r;
      if (!ratio_may_change(c)) {
        return refuse(RequestCode::kWrongState,
                      "Command 1024: the ratio can only be set while no program is executing "
                      "(PositionInc jumps by Position x the change)");
      }
      return {};
    }
    case kCommandSetPositionOn:
    case kCommandSetPositionOff:
      if (!c.idle || !c.standing) {
        return refuse(RequestCode::kWrongState,
                      "Command " + std::to_string(code) +
                          ": the position can only be set while no program is executing");
      }
      // A set drops the loaded records (a program stopped on its trajectory, starved, or not
      // yet started): it was accepted and the program went without a word, so that the PLC's
      // next start found nothing loaded (session 74). As Number_Axes and the ratio, it is
      // refused, with what to do.
      if (c.holds_program) {
        return refuse(RequestCode::kWrongState,
                      "Command " + std::to_string(code) +
                          ": a program is loaded, which a start would run from the new position "
                          "(stop it off the trajectory, Command 9 or 5, or clear it first)");
      }
      return {};
    case kCommandIir: {
      const std::uint32_t mask = static_cast<std::uint32_t>(p[3]) & 0x3FFu;
      // 0 switches the filter off. Any other mask must select an axis: one of axes the
      // interpolator does not have was done, and filtered nothing (an axis counted from 1: mask
      // 8 for Z of three), as was one of bits above 9 only (1024), which the manual ignores.
      if (p[3] != 0) {
        RequestResult r = IirFilter::check(p[0], p[1], p[2]);
        if (!r.ok()) return r;
        const int axes = std::clamp(c.configured_axes, 1, kMaxAxes);
        if (IirFilter::mask_of_axes(mask, axes) == 0) {
          return refuse(RequestCode::kOutOfRange,
                        "Command -1: the axis mask (Command_Parameter[3]) " + std::to_string(p[3]) +
                            " selects none of axes 0.." + std::to_string(axes - 1) +
                            " (bit 0 is axis 0; bits above 9 are ignored)");
        }
      }
      if (!c.standing) {
        return refuse(RequestCode::kWrongState, "Command -1: IIR parameters can only be set while standing");
      }
      return {};
    }
    case kCommandSpline: {
      RequestResult r = SplineSmoother::check(p[0], p[1]);
      if (!r.ok()) return r;
      if (!c.standing) {
        return refuse(RequestCode::kWrongState, "Command -2: Spline parameters can only be set while standing");
      }
      return {};
    }
    default:
      return refuse(RequestCode::kOutOfRange,
                    "unknown Command " + std::to_string(code) +
                        " (valid: 4, 5, 8, 9, 1024, 2048, 2049, -1, -2)");
  }
}

RequestResult check_number_axes(std::int64_t value, const CommandContext& c) {
  if (value < 1 || value > kMaxAxes) {
    return refuse(RequestCode::kOutOfRange, "Number_Axes must be 1..10, not " + std::to_string(value));
  }
  if (value > c.configured_axes) {
    return refuse(RequestCode::kOutOfRange, "Number_Axes " + std::to_string(value) + ": only " +
                                                std::to_string(c.configured_axes) +
                                                " axes are configured");
  }
  if (!c.idle || !c.standing) {
    return refuse(RequestCode::kWrongState, "Number_Axes can only be written while no program is executing");
  }
  // A change drops the records planned for the old axes: a program stopped, starved or not yet
  // started lost them without a word, and the rest of its stream then ran as a program of its
  // own from where the axes stood.
  if (value != c.number_axes && c.holds_program) {
    return refuse(RequestCode::kWrongState,
                  "Number_Axes " + std::to_string(value) +
                      ": a program is loaded, whose records are planned for " +
                      std::to_string(c.number_axes) + " axes (clear it first)");
  }
  return {};
}

RequestResult execute_command(std::int32_t code,
                              const std::array<std::int32_t, kCommandParameters>& p,
                              const CommandContext& c, SmoothingStage& smoothing,
                              OutputStage& output, std::array<double, kMaxAxes>* position_mm) {
  if (!is_stage_command(code)) {
    return refuse(RequestCode::kUnsupported,
                  "Command " + std::to_string(code) + " is not executed by the command stage");
  }
  RequestResult r = check_command(code, p, c);
  if (!r.ok()) return r;
  switch (code) {
    case kCommandSetRatio:
      if (!smoothing.settled()) {
        return refuse(RequestCode::kWrongState,
                      "Command 1024: the axes are still moving behind the spline / IIR filter");
      }
      return output.set_ratio(p[0], p[1], p[2]);
    case kCommandSetPositionOn:
    case kCommandSetPositionOff: {
      if (!smoothing.settled()) {
        return refuse(RequestCode::kWrongState,
                      "Command " + std::to_string(code) +
                          ": the axes are still moving behind the spline / IIR filter");
      }
      std::array<double, kMaxAxes> pos{};
      for (int i = 0; i < output.axes(); ++i) {
        const double x = output.position_from_inc(i, p[static_cast<std::size_t>(i)]);
        // Checked before anything changes: (inc - Offset - Backlash) / Ratio reaches 1e21 mm
        // with an Offset of 1e15 inc and a Ratio of 1e-6 inc/mm, where every record's end point
        // is held to +-1e9 mm (a first move from there would run for ever).
        if (!(std::fabs(x) <= kMaxCoordinateMm)) {
          return refuse(RequestCode::kOutOfRange,
                        "Command " + std::to_string(code) + ": axis " + std::to_string(i) +
                            " would be at " + number_text(x) +
                            " mm ((inc - Offset - Backlash) / Ratio), outside +-1e9 mm");
        }
        pos[static_cast<std::size_t>(i)] = x;
      }
      smoothing.reset(pos.data());
      output.reset(pos.data());
      output.update(pos.data(), 0.0);
      if (position_mm) *position_mm = pos;
      return {};
    }
    case kCommandIir: {
      IirParams ip;
      ip.p_e6 = p[0];
      ip.q_e6 = p[1];
      ip.f_e6 = p[2];
      ip.axis_mask = static_cast<std::uint32_t>(p[3]);
      return smoothing.configure_iir(ip);
    }
    case kCommandSpline:
      return smoothing.configure_spline(p[0], p[1]);
    default:
      return {};
  }
}

void command_begin(Registers& r, std::int32_t code) {
  r.command = code;
  r.command_status = 1;
}

void command_end(Registers& r, const RequestResult& result) {
  r.command = 0;
  r.command_status = result.ok() ? 0 : -1;
}

}  // namespace tgm
