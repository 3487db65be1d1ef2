#include "tgm/service/engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "tgm/printable.hpp"
#include "tgm/smoothing.hpp"

namespace tgm::service {

namespace {

constexpr unsigned kPlc = 1u << static_cast<unsigned>(Role::kPlc);
constexpr unsigned kHmi = 1u << static_cast<unsigned>(Role::kHmi);
constexpr unsigned kBoth = kPlc | kHmi;

const char* role_name(Role r) { return r == Role::kPlc ? "PLC" : "HMI"; }

using Handler = RequestResult (*)(Interpolator&, const RequestIn&);

RequestResult whole(double v, double lo, double hi, const char* name, std::int64_t& out) {
  if (!std::isfinite(v) || v != std::floor(v) || v < lo || v > hi) {
    // With the range and the value: "Number_Axes must be a whole number" was all of it for 0.
    return {RequestCode::kOutOfRange, std::string(name) + " must be a whole number " +
                                          number_text(lo) + ".." + number_text(hi) + ", not " +
                                          number_text(v)};
  }
  out = static_cast<std::int64_t>(v);
  return {};
}

// ---- The request table (DESIGN.md section 1). A new register write or command is one line. ----

struct KindRule {
  RequestKind kind;
  unsigned roles;
  const char* name;
  Handler handler;  // null for kCommand (see kCommands)
};

const KindRule kKinds[] = {
    {RequestKind::kCommand, kBoth, "Command", nullptr},
    {RequestKind::kWriteMFunc, kPlc, "M_Func write",
     [](Interpolator& ip, const RequestIn& r) {
       std::int64_t v = 0;
       if (auto bad = whole(r.value, -2e9, 2e9, "M_Func", v); !bad.ok()) return bad;
       return ip.write_m_func(static_cast<std::int32_t>(v), r.m_func_acknowledged,
                              r.m_func_count_acknowledged);
     }},
    {RequestKind::kWriteRelSpeed, kPlc, "Rel_Speed write",
     [](Interpolator& ip, const RequestIn& r) { return ip.set_rel_speed(r.value); }},
    {RequestKind::kWriteOffset, kPlc, "Offset write",
     [](Interpolator& ip, const RequestIn& r) {
       // Offset is whole increments: the IDL says the value is rounded.
       if (!std::isfinite(r.value) || std::abs(r.value) > 1e15) {
         return RequestResult{
             RequestCode::kOutOfRange,
             "Offset must be finite, |Offset| <= 1e15 inc, not " + number_text(r.value)};
       }
       return ip.write_offset(r.axis, std::llround(r.value));
     }},
    {RequestKind::kWriteRatio, kPlc, "Ratio write",
     [](Interpolator& ip, const RequestIn& r) { return ip.write_ratio(r.axis, r.value); }},
    {RequestKind::kWriteNumberAxes, kPlc, "Number_Axes write",
     [](Interpolator& ip, const RequestIn& r) {
       std::int64_t v = 0;
       if (auto bad = whole(r.value, 1, kMaxAxes, "Number_Axes", v); !bad.ok()) return bad;
       return ip.write_number_axes(static_cast<int>(v));
     }},
    {RequestKind::kStart, kHmi, "start",
     [](Interpolator& ip, const RequestIn&) { return ip.start(); }},
    {RequestKind::kStop, kBoth, "stop",
     [](Interpolator& ip, const RequestIn&) { return ip.command(8); }},
    {RequestKind::kClear, kHmi, "clear",
     [](Interpolator& ip, const RequestIn&) { return ip.clear(); }},
    // Recorded by Engine::apply (EngineOptions::require_plc_setup).
    {RequestKind::kPlcSetupDone, kPlc, "setup report",
     [](Interpolator&, const RequestIn&) { return RequestResult{}; }},
};

struct CommandRule {
  std::int32_t code;
  unsigned roles;
  const char* name;
};

// Every Command goes to core's command(code, Command_Parameter); a code core does not implement
// comes back as kUnsupported, which becomes REPLY_CODE_UNSUPPORTED.
const CommandRule kCommands[] = {
    {4, kBoth, "emergency stop on trajectory"},
    {5, kBoth, "emergency stop off trajectory"},
    {8, kBoth, "normal stop on trajectory"},
    {9, kBoth, "normal stop off trajectory"},
    {1024, kPlc, "gear ratio"},
    {2048, kPlc, "set position on trajectory"},
    {2049, kPlc, "set position off trajectory"},
    {-1, kPlc, "IIR filter parameters"},
    {-2, kPlc, "spline parameters"},
};

const KindRule* find_kind(RequestKind k) {
  for (const KindRule& r : kKinds) {
    if (r.kind == k) return &r;
  }
  return nullptr;
}
const CommandRule* find_command(std::int32_t code) {
  for (const CommandRule& r : kCommands) {
    if (r.code == code) return &r;
  }
  return nullptr;
}

ReplyCode to_reply(RequestCode c) {
  switch (c) {
    case RequestCode::kAccepted:
      return ReplyCode::kAccepted;
    case RequestCode::kOutOfRange:
      return ReplyCode::kOutOfRange;
    case RequestCode::kWrongState:
    case RequestCode::kBufferFull:
      return ReplyCode::kWrongState;
    case RequestCode::kInvalid:
      return ReplyCode::kBadRequest;
    case RequestCode::kUnsupported:
      return ReplyCode::kUnsupported;
  }
  return ReplyCode::kBadRequest;
}

// The start of both refusals while an interpolator waits for the PLC's setup report.
std::string no_plc_setup_yet(int interpolator) {
  return "the PLC has not set interpolator " + std::to_string(interpolator) +
         " up since tgm-service started (position, gear ratios)";
}

bool standing_without_program(const Registers& r) {
  const auto s = static_cast<InterpolatorStatus>(r.status);
  return s == InterpolatorStatus::kEmpty || s == InterpolatorStatus::kEnded ||
         (s == InterpolatorStatus::kEmergencyStopped && r.off_trajectory != 0);
}

}  // namespace

std::string role_violation(Role role, RequestKind kind, std::int32_t command) {
  const KindRule* k = find_kind(kind);
  if (k == nullptr) return {};
  unsigned roles = k->roles;
  const CommandRule* c = nullptr;
  if (kind == RequestKind::kCommand) {
    c = find_command(command);
    if (c == nullptr) return {};
    roles = c->roles;
  }
  if ((roles & (1u << static_cast<unsigned>(role))) != 0) return {};
  // Worded only for a refusal: an allowed request must not allocate on the cycle thread.
  const std::string what =
      c != nullptr ? "Command " + std::to_string(command) + " (" + c->name + ")" : std::string(k->name);
  std::string why = std::string("the ") + role_name(role) + " may not send " + what;
  if (kind == RequestKind::kStart) why += ": only the HMI starts the interpolator";
  return why;
}

std::optional<Engine> Engine::create(const MachineConfig& machine, const EngineOptions& options,
                                     std::string* error) {
  std::vector<Slot> ips;
  InterpolatorOptions io = options.interpolator;
  // Appends on the cycle thread never grow a ring (InterpolatorOptions::preallocate_ring).
  io.preallocate_ring = true;
  if (options.check_limits) io.record_corner_events = true;  // the checker removes the corners
  for (int i = 0; i < static_cast<int>(machine.interpolators.size()); ++i) {
    std::string why;
    auto ip = Interpolator::create(machine, i, io, &why);
    if (!ip) {
      if (error) *error = "interpolator " + std::to_string(i) + ": " + why;
      return std::nullopt;
    }
    Slot slot(std::move(*ip));
    slot.letters = machine.axis_letters(i);
    for (int k = 0; k <= kMaxAxes; ++k) {
      slot.digests[static_cast<std::size_t>(k)] = machine_digest(machine, i, k);
    }
    if (options.check_limits) {
      slot.checker = LimitChecker::create(machine.interpolators[static_cast<std::size_t>(i)],
                                          machine.cycle_time_us, &why, options.limit_share);
      if (!slot.checker) {
        if (error) *error = "interpolator " + std::to_string(i) + ": limit checker: " + why;
        return std::nullopt;
      }
    }
    ips.push_back(std::move(slot));
  }
  if (ips.empty() || ips.size() > static_cast<std::size_t>(kMaxInterpolators)) {
    if (error) *error = "the config must have 1.." + std::to_string(kMaxInterpolators) + " interpolators";
    return std::nullopt;
  }
  return Engine(std::move(ips), options);
}

double Engine::cycle_time_s() const { return ips_.front().ip.cycle_time_s(); }

ReplyOut Engine::apply(const RequestIn& r) {
  ReplyOut out;
  out.request_id = r.request_id;
  out.tag = r.tag;
  out.client = r.client;
  out.interpolator = r.interpolator;
  out.cycle = cycles_;
  ++counters_.requests;
  auto refuse = [&](ReplyCode c, std::string_view why) {
    out.code = c;
    out.reason.set(why);
    ++counters_.refused_requests;
    return out;
  };
  if (r.interpolator < 0 || r.interpolator >= count()) {
    return refuse(ReplyCode::kBadRequest, "interpolator " + std::to_string(r.interpolator) +
                                              " does not exist (the service hosts 0.." +
                                              std::to_string(count() - 1) + ")");
  }
  const KindRule* k = find_kind(r.kind);
  if (k == nullptr) return refuse(ReplyCode::kBadRequest, "unknown request kind");
  if (r.kind == RequestKind::kCommand && find_command(r.command) == nullptr) {
    return refuse(ReplyCode::kBadRequest, "unknown Command " + std::to_string(r.command) +
                                              " (known: 4, 5, 8, 9, 1024, 2048, 2049, -1, -2)");
  }
  if (std::string why = role_violation(r.role, r.kind, r.command); !why.empty()) {
    return refuse(ReplyCode::kWrongRole, why);
  }
  Slot& slot = ips_[static_cast<std::size_t>(r.interpolator)];
  if (r.kind == RequestKind::kStart && awaits_plc_setup(slot)) {
    return refuse(ReplyCode::kWrongState,
                  no_plc_setup_yet(r.interpolator) +
                      ": start tgm-plc or wait for its setup; a PLC of your own reports it with "
                      "REQUEST_KIND_PLC_SETUP_DONE (plc.setup_before_start)");
  }
  Interpolator& ip = slot.ip;
  const RequestResult res =
      k->handler != nullptr ? k->handler(ip, r) : ip.command(r.command, r.command_parameter);
  if (!res.ok()) return refuse(to_reply(res.code), res.reason);
  if (r.kind == RequestKind::kClear) {
    slot.program_id = 0;
    slot.next_sequence = 0;
  }
  if (r.kind == RequestKind::kPlcSetupDone) slot.plc_setup_done = true;
  return out;
}

void Engine::refuse_chunk(CyclePort& port, int i, const ChunkIn& c, std::string_view why) {
  Slot& s = ips_[static_cast<std::size_t>(i)];
  ++counters_.refused_chunks;
  if (s.refused_program == c.program_id) return;  // one message per refused program
  s.refused_program = c.program_id;
  send_message(port, i, MessageOut::Severity::kError,
               "program " + std::to_string(c.program_id) + " refused: " + std::string(why), 0,
               c.program_id);
}

void Engine::send_message(CyclePort& port, int i, MessageOut::Severity severity,
                          std::string_view text, std::int32_t line, std::uint32_t program_id) {
  MessageOut m;
  m.interpolator = i;
  m.severity = severity;
  m.text.set(text);
  m.source_line = line;
  m.program_id = program_id;
  m.cycle = cycles_;
  if (!port.message(m)) ++counters_.lost_messages;
}

void Engine::apply_chunks(CyclePort& port, int i, std::size_t& budget) {
  Slot& s = ips_[static_cast<std::size_t>(i)];
  while (budget > 0) {
    ChunkIn* c = port.front_chunk(i);
    if (c == nullptr) return;
    if (c->decode_status != 0) {
      refuse_chunk(port, i, *c, c->error.view());
      port.pop_chunk(i);
      continue;
    }
    // 0 is no program (the IDL): it also turned off the check for a program a position set
    // dropped.
    if (c->program_id == 0) {
      refuse_chunk(port, i, *c, "program id 0 is no program (number programs from 1)");
      port.pop_chunk(i);
      continue;
    }
    // Before the PLC's setup (EngineOptions::require_plc_setup) a loaded program would keep the
    // PLC from setting the position (Command 2048 is refused while one is loaded), and a start
    // once the report came would run it from 0 where the drives stand elsewhere (review of
    // session 81).
    if (awaits_plc_setup(s)) {
      refuse_chunk(port, i, *c,
                   no_plc_setup_yet(i) +
                       ": send it once the state shows plc_setup 2 (plc.setup_before_start)");
      port.pop_chunk(i);
      continue;
    }
    // Records hold positions by axis index: a program compiled for other letters (XYC) would
    // drive this interpolator's axes (XYZ) as if they were those. The axis count is checked
    // by the interpolator; letters only when the chunk names them.
    const std::string_view letters = s.active_letters();
    if (!c->program.axis_letters.empty() && c->program.axis_letters != letters) {
      refuse_chunk(port, i, *c,
                   "compiled for axes " + c->program.axis_letters + ", interpolator " +
                       std::to_string(i) + " drives " + std::string(letters) +
                       " (the service's config): compile with that config");
      port.pop_chunk(i);
      continue;
    }
    // A chunk that must start a program: one of another program than the loaded one, or of the
    // loaded one after an off-trajectory stop (Command 5/9) dropped it. The rest of a dropped
    // program's stream must not become a program of its own, which would start where the axes
    // stand; streamed again from its first record, it loads again.
    // A position set (Command 2048/2049) since the program loaded dropped it the same way: the
    // rest of its stream loaded behind the set, and a start ran that tail from the new
    // position (session 55).
    const bool other = c->program_id != s.program_id;
    const bool set_dropped = s.program_id != 0 && s.ip.position_sets() != s.sets_at_load;
    if (other || s.ip.registers().off_trajectory != 0 || set_dropped) {
      if (c->sequence_number != 0 || c->applied != 0) {
        const char* by = set_dropped ? " was dropped by a position set (Command 2048/2049)"
                                     : " was dropped by an off-trajectory stop (Command 5/9)";
        refuse_chunk(port, i, *c,
                     other ? "chunk " + std::to_string(c->sequence_number) +
                                 " of a program that is not loaded (cleared?)"
                           : "program " + std::to_string(s.program_id) + by + ": stream it again");
        port.pop_chunk(i);
        continue;
      }
      if (!standing_without_program(s.ip.registers())) {
        refuse_chunk(port, i, *c,
                     "interpolator " + std::to_string(i) + " still holds program " +
                         std::to_string(s.program_id) + " (status " +
                         std::to_string(s.ip.registers().status) +
                         "), another sender's (an HMI may have loaded it just "
                         "now): clear it first only if it is not wanted");
        port.pop_chunk(i);
        continue;
      }
      s.program_id = c->program_id;
      s.next_sequence = 0;
      s.stream_complete = false;
      s.sets_at_load = s.ip.position_sets();
      s.refused_program = kNoProgram;
      s.gap_said_at = 0;
      s.limit_messages = 0;
    }
    const std::size_t total = c->program.segments.size();
    const std::uint64_t at = c->sequence_number + c->applied;
    if (at != s.next_sequence && c->sequence_number < s.next_sequence &&
        c->sequence_number + total > s.next_sequence) {
      // A copy of a chunk taken in part (a sender writing again from where it stood): its rest.
      c->applied = static_cast<std::size_t>(s.next_sequence - c->sequence_number);
    } else if (at != s.next_sequence) {
      if (c->sequence_number + total <= s.next_sequence) {
        ++counters_.duplicate_chunks;  // already applied (a resent chunk): drop quietly
      } else {
        // A gap: chunks between were lost on the way. Reliable delivery loses them only when
        // the service's reader dropped the sender and matched it again (a sender that stood
        // still for seconds: 1 run in 8 of the freeze test, session 92). The program stays,
        // where it stands; the sender writes from there again (tgm-hmi does when the buffer
        // runs empty with records in flight). An error here ended such runs half-executed.
        ++counters_.refused_chunks;
        if (s.gap_said_at != s.next_sequence + 1) {
          s.gap_said_at = s.next_sequence + 1;
          send_message(port, i, MessageOut::Severity::kWarning,
                       "program " + std::to_string(c->program_id) + ": chunk " +
                           std::to_string(c->sequence_number) + " skips records " +
                           std::to_string(s.next_sequence) + ".." +
                           std::to_string(c->sequence_number - 1) +
                           " (lost on the way): dropped; the sender must write from record " +
                           std::to_string(s.next_sequence) + " again",
                       0, c->program_id);
        }
      }
      port.pop_chunk(i);
      continue;
    }
    // The interpolator takes no records during an emergency ramp (Command 4/5): the chunk
    // waits for its end, like one that finds the buffer full, instead of being refused. A
    // refusal broke the stream (every later chunk a gap), so a program streamed while an
    // emergency stop on the trajectory was given could not be resumed.
    if (!s.ip.takes_records()) return;
    // Only what fits: append() formats the reason of a full ring (kBufferFull) as a string,
    // which allocated on the cycle thread in every cycle a stream waited for room (session
    // 41, tests/service/cycle_alloc_test.cpp).
    const std::size_t rest = total - c->applied;
    const std::size_t piece = std::min({rest, budget, s.ip.free_slots()});
    if (piece == 0 && rest > 0) return;  // (an empty chunk still passes: it may end the program)
    const bool last_piece = piece == rest;
    std::size_t accepted = 0;
    const RequestResult res =
        s.ip.append(c->program, c->applied, piece, last_piece && c->end_of_program, &accepted);
    c->applied += accepted;
    s.next_sequence += accepted;
    if (res.ok() && last_piece && c->end_of_program) s.stream_complete = true;
    counters_.segments += accepted;
    budget -= std::min(budget, accepted);
    if (!res.ok() && res.code != RequestCode::kBufferFull) {
      refuse_chunk(port, i, *c, res.reason);
      port.pop_chunk(i);
      continue;
    }
    if (c->applied == total) {
      ++counters_.chunks;
      port.pop_chunk(i);
      continue;
    }
    return;  // buffer full or budget spent: the rest waits for the next cycle
  }
}

void Engine::check_limits(CyclePort& port, int i) {
  Slot& s = ips_[static_cast<std::size_t>(i)];
  const Registers& reg = s.ip.registers();
  // A position set (Command 2048 / 2049, executed with the request or in a later cycle while
  // the smoothing settles) moves Orig_Position by design: the differences across it are no
  // motion. (Watching the Command register missed a set executed with its request: the
  // register is back at 0 when the cycle ends.)
  if (s.ip.position_sets() != s.position_sets) {
    s.position_sets = s.ip.position_sets();
    s.checker->reset();
  }
  const std::size_t stored_before = s.checker->violations().size();
  const std::uint64_t counted_before = s.checker->violation_count();
  s.checker->add_cycle(reg, s.ip.corner_events());
  const std::uint64_t found = s.checker->violation_count() - counted_before;
  counters_.limit_violations += found;
  auto send = [&](std::string_view text, std::int32_t line) {
    send_message(port, i, MessageOut::Severity::kWarning, text, line, s.program_id);
  };
  // The checker keeps the first LimitChecker::kMaxStored excesses in detail.
  const auto& stored = s.checker->violations();
  const InterpolatorConfig& cfg = s.ip.config();
  for (std::uint64_t k = 0; k < found && s.limit_messages <= opt_.max_limit_messages; ++k) {
    if (s.limit_messages == opt_.max_limit_messages || stored_before + k >= stored.size()) {
      send("limit excess: more in this program are counted, not reported (tgm-service --stats)", reg.act_line);
      s.limit_messages = opt_.max_limit_messages + 1;  // nothing more for this program
      break;
    }
    const LimitViolation& v = stored[stored_before + k];
    static constexpr const char* kUnit[] = {"mm/s", "mm/s^2", "mm/s^3", "mm/s", "mm/s^2", "mm/s^2"};
    const auto q = static_cast<std::size_t>(v.quantity);
    char text[200];
    std::snprintf(text, sizeof text, "limit excess: axis %c %s %.6g > %.6g %s (cycle %llu)",
                  cfg.axes[static_cast<std::size_t>(v.axis)].letter,
                  limit_quantity_name(v.quantity), v.value, v.limit,
                  q < std::size(kUnit) ? kUnit[q] : "", static_cast<unsigned long long>(v.cycle));
    send(text, v.line);
    ++s.limit_messages;
  }
}

void Engine::peer_notice(CyclePort& port, const PeerNotice& n) {
  // A name of up to 64 characters (a long --participant-prefix) made the warnings below longer
  // than a message carries (255 bytes), and they lost their advice at the end: at most 40 here.
  const auto shortened = [](std::string_view s) {
    return s.size() > 40 ? std::string(s.substr(0, 37)) + "..." : std::string(s);
  };
  const std::string name = shortened(n.client.view());
  const std::string who = name.empty() ? std::string("a client") : "'" + name + "'";
  switch (n.kind) {
    case PeerNotice::Kind::kPlcLost:
    case PeerNotice::Kind::kPlcBack:
      for (int i = 0; i < count(); ++i) {
        const Slot& s = ips_[static_cast<std::size_t>(i)];
        if (n.kind == PeerNotice::Kind::kPlcBack) {
          send_message(port, i, MessageOut::Severity::kInfo, "tgm-plc " + who + " is back", 0,
                       s.program_id);
          continue;
        }
        std::string text = n.ended ? "tgm-plc " + who + " ended"
                                   : "no sign of life from tgm-plc " + who +
                                         " (it stopped, or the network is down)";
        if (!n.other_plc.view().empty()) {
          // Not a warning: the M-functions are still acknowledged.
          send_message(port, i, MessageOut::Severity::kInfo,
                       text + "; tgm-plc '" + shortened(n.other_plc.view()) +
                           "' is there and acknowledges the M-functions",
                       0, s.program_id);
          continue;
        }
        text += ": M-functions wait for an acknowledgement until a PLC answers";
        if (const std::int32_t m = s.ip.registers().m_func; m != 0) {
          text += " (M" + std::to_string(m) + " waits now)";
        }
        send_message(port, i, MessageOut::Severity::kWarning, text, 0, s.program_id);
      }
      return;
    case PeerNotice::Kind::kPlcJoined: {
      const std::string other = shortened(n.other_plc.view());
      // A warning: two PLCs answer every M-function, and each may set what the other did not
      // mean to (a script beside the machine's PLC is the case it is meant for).
      for (int i = 0; i < count(); ++i) {
        send_message(port, i, MessageOut::Severity::kWarning,
                     "tgm-plc " + who + " joined beside tgm-plc '" + other +
                         "': both acknowledge the M-functions (stop one unless that is meant)",
                     0, ips_[static_cast<std::size_t>(i)].program_id);
      }
      return;
    }
    case PeerNotice::Kind::kStreamLost:
    case PeerNotice::Kind::kStreamBack: {
      if (n.interpolator < 0 || n.interpolator >= count()) return;
      const Slot& s = ips_[static_cast<std::size_t>(n.interpolator)];
      // Only while the program it sent is loaded and waits for more of it.
      if (s.program_id != n.program_id || s.stream_complete ||
          s.ip.registers().status == static_cast<std::int32_t>(InterpolatorStatus::kEmpty)) {
        return;
      }
      const std::string program = "program " + std::to_string(n.program_id);
      if (n.kind == PeerNotice::Kind::kStreamBack) {
        send_message(port, n.interpolator, MessageOut::Severity::kInfo,
                     program + ": its sender " + who + " is back", 0, n.program_id);
        return;
      }
      const std::string records = std::to_string(s.next_sequence) + " records";
      send_message(port, n.interpolator, MessageOut::Severity::kWarning,
                   n.ended ? program + ": its sender " + who + " ended after " + records +
                                 ": the rest will not come, and the motion stops at the buffer's "
                                 "end (Status 8); `tgm-hmi command clear` drops it"
                           : program + ": its sender " + who + " gave no sign of life after " +
                                 records +
                                 " (stopped, or network down): unless it returns, the motion "
                                 "stops at the buffer's end (Status 8); `tgm-hmi command clear` "
                                 "drops the rest",
                   0, n.program_id);
      return;
    }
  }
}

void Engine::cycle(CyclePort& port, const LatenessStats& lateness) {
  for (PeerNotice n; port.next_peer_notice(n);) peer_notice(port, n);
  for (int n = 0; n < opt_.max_requests_per_cycle; ++n) {
    RequestIn r;
    if (!port.next_request(r)) break;
    const bool awaited = r.kind == RequestKind::kPlcSetupDone && r.interpolator >= 0 &&
                         r.interpolator < count() &&
                         awaits_plc_setup(ips_[static_cast<std::size_t>(r.interpolator)]);
    const ReplyOut reply = apply(r);
    if (!port.reply(reply)) ++counters_.lost_replies;
    // The gate opens once per service run: said where the HMIs read (`tgm-hmi watch`), so that
    // whoever waited for a start can see why it is accepted now (review of session 81).
    if (awaited && reply.code == ReplyCode::kAccepted) {
      const std::string who(r.client.view());
      send_message(port, r.interpolator, MessageOut::Severity::kInfo,
                   "set up by the PLC" +
                       (who.empty() ? std::string() : " '" + who.substr(0, 64) + "'") +
                       ": starts and programs are accepted",
                   0, 0);
    }
  }
  std::size_t budget = opt_.max_segments_per_cycle;
  const int first = static_cast<int>(cycles_ % static_cast<std::uint64_t>(count()));
  for (int k = 0; k < count() && budget > 0; ++k) apply_chunks(port, (first + k) % count(), budget);
  ++cycles_;
  snapshot_.cycle = cycles_;
  snapshot_.count = count();
  snapshot_.lateness = lateness;
  for (int i = 0; i < count(); ++i) {
    Slot& s = ips_[static_cast<std::size_t>(i)];
    s.ip.step();
    if (s.checker) check_limits(port, i);
    const Registers& reg = s.ip.registers();
    // Every message that came out since the last cycle, in order: M29 lines in a row come out
    // in one cycle, and only the last was sent (session 75).
    // (Unsigned: a count that wrapped is still the difference; the ring keeps the last ones.)
    constexpr std::uint32_t kRing = Interpolator::kMessageRing;
    const std::uint32_t fresh = reg.message_count - s.message_seen;
    for (std::uint32_t k = fresh > kRing ? fresh - kRing + 1u : 1u; k <= fresh; ++k) {
      const std::int32_t slot = s.ip.message_slot_of(s.message_seen + k);
      if (slot < 0) continue;  // more than the ring in one cycle: it kept the newest
      const std::string_view text = s.ip.message_text(slot);
      ++s.message_counter;
      s.message_text.set(text);
      send_message(port, i, MessageOut::Severity::kInfo, text, s.ip.message_line(slot),
                   s.program_id);
    }
    s.message_seen = reg.message_count;
    InterpolatorSnapshot& o = snapshot_.ip[static_cast<std::size_t>(i)];
    if (s.events != 0) report_output_steps(port, i, o.reg, reg);
    // A command that waited at Command_Status 1 (its reply said accepted) and then ended
    // unexecuted, cancelled by a stop or no longer allowed: the reason was only in
    // command_error(), which nobody read, and the PLC believed its position set done.
    if (s.ip.unexecuted_commands() != s.unexecuted_seen) {
      s.unexecuted_seen = s.ip.unexecuted_commands();
      send_message(
          port, i, MessageOut::Severity::kError,
          "a command that waited for the smoothing was not executed: " + s.ip.unexecuted_reason(),
          0, s.program_id);
    }
    // o still holds the previous cycle: queue the event (the first cycle always has one).
    if (s.events == 0 || event_due(reg, s.program_id, o.reg, o.program_id)) {
      EventOut e;
      e.interpolator = i;
      e.counter = ++s.events;
      e.program_id = s.program_id;
      e.reg = event_registers(reg);
      if (!port.event(e)) ++counters_.lost_events;
    }
    o.reg = reg;
    o.program_id = s.program_id;
    o.next_sequence = s.next_sequence;
    o.buffered_segments = reg.buffer_size - static_cast<std::int32_t>(s.ip.free_slots());
    o.message_counter = s.message_counter;
    o.message_text = s.message_text;
    o.axis_letters.set(s.active_letters());
    o.machine_digest = s.digests[static_cast<std::size_t>(
        std::clamp(static_cast<int>(reg.number_axes), 0, kMaxAxes))];
    o.plc_setup = !opt_.require_plc_setup ? 0 : awaits_plc_setup(s) ? 1 : 2;
    o.smoothing = s.ip.smoothing().in_effect();
  }
  port.publish(snapshot_);
}

void Engine::report_output_steps(CyclePort& port, int i, const Registers& before,
                                 const Registers& now) {
  // A ratio set at standstill was only "accepted", and PositionInc jumped by Position x the
  // change: a drive that is enabled follows that jump (session 75). The usual setup, a ratio
  // at Position 0 before the position is set, steps nothing and says nothing. An Offset
  // written at standstill is how a PLC references its axes (PositionInc made to match the
  // drive): only one written while the axes move, a step in the middle of a motion, is said.
  const Slot& s = ips_[static_cast<std::size_t>(i)];
  const bool moving = now.act_speed != 0.0;
  for (int a = 0; a < now.number_axes && a < kMaxAxes; ++a) {
    const auto u = static_cast<std::size_t>(a);
    const bool ratio = now.ratio[u] != before.ratio[u];
    const bool offset = moving && now.offset[u] != before.offset[u];
    if (!ratio && !offset) continue;
    const double step = now.position[u] * (now.ratio[u] - before.ratio[u]) +
                        (offset ? static_cast<double>(now.offset[u] - before.offset[u]) : 0.0);
    if (!(std::fabs(step) >= 0.5)) continue;
    // Formatted into a buffer: the cycle thread does not allocate (cycle_alloc_test).
    char text[256];
    std::size_t n = 0;
    const auto put = [&](const char* fmt, auto... v) {
      const int k = std::snprintf(text + n, sizeof text - n, fmt, v...);
      if (k > 0) n = std::min(sizeof text - 1, n + static_cast<std::size_t>(k));
    };
    put("axis %c: PositionInc stepped by %.10g inc (", u < s.letters.size() ? s.letters[u] : '?',
        step);
    if (ratio) {
      put("Ratio %.6g -> %.6g inc/mm at Position %.6g mm", before.ratio[u], now.ratio[u],
          now.position[u]);
    }
    if (offset) {
      put("%sOffset %lld -> %lld inc", ratio ? ", " : "", static_cast<long long>(before.offset[u]),
          static_cast<long long>(now.offset[u]));
    }
    if (moving) put(", while moving at %.6g mm/min", now.act_speed);
    put("): an enabled drive jumps with it (change them with the drive off, or set the position "
        "after, Command 2049)");
    send_message(port, i, MessageOut::Severity::kWarning, text, now.act_line, s.program_id);
  }
}

bool Engine::wind_down(CyclePort& port) {
  const auto moving = [](const Slot& s) {
    const Registers& r = s.ip.registers();
    return r.act_speed != 0.0 ||
           r.status == static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp) ||
           !s.ip.smoothing().settled();
  };
  if (!winding_down_) {
    winding_down_ = true;
    for (int i = 0; i < count(); ++i) {
      Slot& s = ips_[static_cast<std::size_t>(i)];
      const Registers& r = s.ip.registers();
      const auto status = static_cast<InterpolatorStatus>(r.status);
      const bool moves = moving(s);
      char text[200];
      if (moves && status == InterpolatorStatus::kRunning) {
        const RequestResult stop = s.ip.command(8);
        if (stop.ok()) ++wound_down_;
        std::snprintf(
            text, sizeof text, "tgm-service is stopping: %s at %.0f mm/min on line %d%s%s",
            stop.ok() ? "normal stop on the trajectory (Command 8)" : "could not stop the motion",
            r.act_speed, r.act_line, stop.ok() ? "" : ": ", stop.ok() ? "" : stop.reason.c_str());
      } else if (moves) {
        // An underrun or an emergency ramp is a stop under way already: it runs on.
        std::snprintf(text, sizeof text,
                      "tgm-service is stopping: the stop under way (Status %d) runs to its end, "
                      "on line %d",
                      r.status, r.act_line);
      } else if (status != InterpolatorStatus::kEmpty && status != InterpolatorStatus::kEnded) {
        // A program that stands (an M-function wait, a dwell, M0, a stop, an underrun) is
        // dropped with the service: its HMIs are told too, or a `run` took the silence for a
        // network outage and waited for good (session 76's review).
        char waiting[32] = "";
        if (r.m_func != 0) std::snprintf(waiting, sizeof waiting, ", waiting for M%d", r.m_func);
        std::snprintf(text, sizeof text,
                      "tgm-service is stopping: the motion stands (Status %d%s) on line %d",
                      r.status, waiting, r.act_line);
      } else {
        continue;  // nothing loaded, or the program ended: nobody waits for it
      }
      ++announced_;
      send_message(port, i, MessageOut::Severity::kWarning, text, r.act_line, s.program_id);
    }
  }
  for (const Slot& s : ips_) {
    if (moving(s)) return false;
  }
  return true;
}

}  // namespace tgm::service
