#include "tgm/idl_mapping.hpp"

#include <algorithm>
#include <cmath>

namespace tgm::mapping {

// The IDL bounds and core's sizes are the same registers: a mismatch must not compile.
static_assert(TGM_MAX_AXES == kMaxAxes);
static_assert(TGM_PARAM_LETTERS == kParamLetters);
static_assert(TGM_COMMAND_PARAMETERS == kCommandParameters);
static_assert(TGM_M_FUNCTION_PARAMETERS == kMFunctionParameters);
static_assert(TGM_LOOK_AHEAD_ENTRIES == kLookAheadEntries);
static_assert(TGM_MAX_TEXT == kMaxMessageBytes);

namespace {

// The first element of `values` that is not finite, or -1.
int first_not_finite(const auto& values) {
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (!std::isfinite(values[k])) return static_cast<int>(k);
  }
  return -1;
}

// Checks a wire record before anything of it is used; `where` gets the field at fault.
MapStatus validate(const msg::Segment& in, WireProblem& where) {
  const auto bad = [&where](MapStatus st, std::string_view field, int element = -1) {
    where.field = field;
    where.element = element;
    return st;
  };
  if (in.type() > static_cast<std::uint8_t>(SegmentType::kMessage)) {
    return bad(MapStatus::kBadType, "type");
  }
  if (in.plane() < static_cast<std::uint8_t>(Plane::kXY) ||
      in.plane() > static_cast<std::uint8_t>(Plane::kYZ)) {
    return bad(MapStatus::kBadType, "plane");
  }
  if (in.compensation() < static_cast<std::uint8_t>(Compensation::kOff) ||
      in.compensation() > static_cast<std::uint8_t>(Compensation::kRight)) {
    return bad(MapStatus::kBadType, "compensation");
  }
  if (in.m_kind() > static_cast<std::uint8_t>(MKind::kProgramEnd)) {
    return bad(MapStatus::kBadType, "m_kind");
  }
  const auto type = static_cast<SegmentType>(in.type());
  // The deserializer does not enforce IDL bounds: check them here.
  if (!in.params().empty() &&
      (in.params().size() != kParamLetters || type != SegmentType::kMFunction)) {
    return bad(MapStatus::kBadParams, "params");
  }
  // (A bounded IDL string is a fixed_string that truncates on assignment: it cannot be longer.)
  if (in.text().size() != 0 && type != SegmentType::kMessage) {
    return bad(MapStatus::kUnexpectedText, "text");
  }
  if (const int k = first_not_finite(in.end()); k >= 0) {
    return bad(MapStatus::kNotFinite, "end", k);
  }
  if (const int k = first_not_finite(in.center()); k >= 0) {
    return bad(MapStatus::kNotFinite, "center", k);
  }
  if (const int k = first_not_finite(in.params()); k >= 0) {
    return bad(MapStatus::kNotFinite, "params", k);
  }
  if (!std::isfinite(in.radius())) return bad(MapStatus::kNotFinite, "radius");
  if (!std::isfinite(in.feed_mm_per_min())) return bad(MapStatus::kNotFinite, "feed_mm_per_min");
  if (!std::isfinite(in.dwell_s())) return bad(MapStatus::kNotFinite, "dwell_s");
  if (!std::isfinite(in.compensation_radius_mm())) {
    return bad(MapStatus::kNotFinite, "compensation_radius_mm");
  }
  return MapStatus::kOk;
}

MapStatus validate(const msg::Segment& in) {
  WireProblem unused;
  return validate(in, unused);
}

// Serialized bytes of a chunk with no records (header, sequence length, trailer) plus slack for
// alignment.
std::size_t empty_chunk_bytes() {
  static const std::size_t bytes = msg::ProgramChunk::getCdrSerializedSize(msg::ProgramChunk{}) + 16;
  return bytes;
}

}  // namespace

std::string_view to_string(MapStatus s) {
  switch (s) {
    case MapStatus::kOk:
      return "ok";
    case MapStatus::kBadType:
      return "segment type, plane, compensation or M kind out of range";
    case MapStatus::kBadAux:
      return "aux does not point into the program's side table";
    case MapStatus::kTextTooLong:
      return "message text longer than 255 characters";
    case MapStatus::kBadParams:
      return "M-function parameters must be 26 values on an M-function record";
    case MapStatus::kUnexpectedText:
      return "text on a record that is not a message";
    case MapStatus::kNotFinite:
      return "NaN or infinity in a record";
    case MapStatus::kTooManySegments:
      return "chunk holds more records than its bound";
    case MapStatus::kBadAxisCount:
      return "number of axes outside 1..10";
    case MapStatus::kBadIndex:
      return "record index beyond the end of the program";
    case MapStatus::kBadAxisLetters:
      return "axis letters must be one distinct letter A..Z per axis";
  }
  return "unknown mapping status";
}

MapStatus to_idl(const Segment& in, const MParams* params, const std::string* message,
                 msg::Segment& out) {
  if (params != nullptr && in.type != SegmentType::kMFunction) return MapStatus::kBadParams;
  if (message != nullptr && in.type != SegmentType::kMessage) return MapStatus::kUnexpectedText;
  if (message != nullptr && message->size() > kMaxTextLength) return MapStatus::kTextTooLong;
  out.type(static_cast<std::uint8_t>(in.type));
  out.plane(static_cast<std::uint8_t>(in.plane));
  out.compensation(static_cast<std::uint8_t>(in.compensation));
  out.m_kind(static_cast<std::uint8_t>(in.m_kind));
  out.line(in.line);
  out.m(in.m);
  out.tool(in.tool);
  out.turns(in.turns);
  out.end() = in.end;
  out.center() = in.center;
  out.radius(in.radius);
  out.feed_mm_per_min(in.feed_mm_per_min);
  out.dwell_s(in.dwell_s);
  out.compensation_radius_mm(in.compensation_radius_mm);
  if (params != nullptr) {
    out.params().assign(params->begin(), params->end());
  } else {
    out.params().clear();
  }
  if (message != nullptr) {
    out.text() = *message;
  } else {
    out.text() = "";
  }
  return MapStatus::kOk;
}

namespace {

// The side-table entries of record `index` of `program` (null when it has none).
MapStatus payload_of(const Program& program, std::size_t index, const MParams*& params,
                     const std::string*& message) {
  params = nullptr;
  message = nullptr;
  if (index >= program.segments.size()) return MapStatus::kBadIndex;
  const Segment& s = program.segments[index];
  if (s.aux >= 0) {
    const auto aux = static_cast<std::size_t>(s.aux);
    if (s.type == SegmentType::kMFunction && aux < program.params.size()) {
      params = &program.params[aux];
    } else if (s.type == SegmentType::kMessage && aux < program.messages.size()) {
      message = &program.messages[aux];
    } else {
      return MapStatus::kBadAux;
    }
  } else if (s.type == SegmentType::kMessage) {
    return MapStatus::kBadAux;  // a message record always has its text
  }
  return MapStatus::kOk;
}

}  // namespace

MapStatus to_idl(const Program& program, std::size_t index, msg::Segment& out) {
  const MParams* params = nullptr;
  const std::string* message = nullptr;
  if (const MapStatus st = payload_of(program, index, params, message); st != MapStatus::kOk)
    return st;
  return to_idl(program.segments[index], params, message, out);
}

MapStatus program_problem(const Program& program, std::size_t& index) {
  index = 0;
  if (program.number_axes < 1 || program.number_axes > kMaxAxes) return MapStatus::kBadAxisCount;
  if (!valid_axis_letters(program.axis_letters, program.number_axes))
    return MapStatus::kBadAxisLetters;
  for (; index < program.segments.size(); ++index) {
    const MParams* params = nullptr;
    const std::string* message = nullptr;
    if (const MapStatus st = payload_of(program, index, params, message); st != MapStatus::kOk)
      return st;
    if (message != nullptr && message->size() > kMaxTextLength) return MapStatus::kTextTooLong;
    if (static_cast<int>(program.segments[index].type) > static_cast<int>(SegmentType::kMessage))
      return MapStatus::kBadType;
  }
  return MapStatus::kOk;
}

MapStatus from_idl(const msg::Segment& in, Segment& out, SegmentPayload& payload) {
  if (const MapStatus st = validate(in); st != MapStatus::kOk) return st;
  out.type = static_cast<SegmentType>(in.type());
  out.plane = static_cast<Plane>(in.plane());
  out.compensation = static_cast<Compensation>(in.compensation());
  out.m_kind = static_cast<MKind>(in.m_kind());
  out.line = in.line();
  out.m = in.m();
  out.tool = in.tool();
  out.turns = in.turns();
  out.aux = -1;
  out.end = in.end();
  out.center = in.center();
  out.radius = in.radius();
  out.feed_mm_per_min = in.feed_mm_per_min();
  out.dwell_s = in.dwell_s();
  out.compensation_radius_mm = in.compensation_radius_mm();
  payload.has_params = !in.params().empty();
  if (payload.has_params) {
    std::copy(in.params().begin(), in.params().end(), payload.params.begin());
  }
  payload.has_message = out.type == SegmentType::kMessage;
  if (payload.has_message) {
    payload.message = in.text().to_string();
  } else {
    payload.message.clear();
  }
  return MapStatus::kOk;
}

MapStatus append_from_idl(const msg::Segment& in, Program& program) {
  Segment s;
  SegmentPayload payload;
  if (const MapStatus st = from_idl(in, s, payload); st != MapStatus::kOk) return st;
  if (payload.has_params) {
    s.aux = static_cast<std::int32_t>(program.params.size());
    program.params.push_back(payload.params);
  } else if (payload.has_message) {
    s.aux = static_cast<std::int32_t>(program.messages.size());
    program.messages.push_back(std::move(payload.message));
  }
  program.segments.push_back(s);
  return MapStatus::kOk;
}

MapStatus fill_chunk(const Program& program, std::size_t first, const ChunkHeader& header,
                     msg::ProgramChunk& out, std::size_t& next) {
  const std::size_t total = program.segments.size();
  next = first;
  if (first > total) return MapStatus::kBadIndex;
  if (program.number_axes < 1 || program.number_axes > kMaxAxes) return MapStatus::kBadAxisCount;
  out.interpolator(header.interpolator);
  out.program_id(header.program_id);
  out.sequence_number(first);
  if (!valid_axis_letters(program.axis_letters, program.number_axes))
    return MapStatus::kBadAxisLetters;
  out.number_axes(static_cast<std::uint16_t>(program.number_axes));
  out.axis_letters(program.axis_letters);
  auto& segs = out.segments();
  segs.clear();
  std::size_t bytes = empty_chunk_bytes();
  std::size_t i = first;
  while (i < total && segs.size() < kMaxChunkSegments) {
    msg::Segment& s = segs.emplace_back();
    if (const MapStatus st = to_idl(program, i, s); st != MapStatus::kOk) {
      segs.clear();
      next = i;  // the record that cannot be sent
      return st;
    }
    bytes += msg::Segment::getCdrSerializedSize(s, bytes);
    if (bytes > kChunkByteBudget && segs.size() > 1) {
      segs.pop_back();
      break;
    }
    ++i;
  }
  next = i;
  out.end_of_program(i == total);
  return MapStatus::kOk;
}

MapStatus to_chunks(const Program& program, const ChunkHeader& header,
                    std::vector<msg::ProgramChunk>& chunks) {
  chunks.clear();
  std::size_t first = 0;
  do {
    std::size_t next = first;
    if (const MapStatus st = fill_chunk(program, first, header, chunks.emplace_back(), next);
        st != MapStatus::kOk) {
      chunks.clear();
      return st;
    }
    first = next;
  } while (!chunks.back().end_of_program());
  return MapStatus::kOk;
}

bool valid_axis_letters(std::string_view letters, int number_axes) {
  if (number_axes < 1 || number_axes > kMaxAxes ||
      letters.size() != static_cast<std::size_t>(number_axes)) {
    return false;
  }
  for (std::size_t i = 0; i < letters.size(); ++i) {
    if (letters[i] < 'A' || letters[i] > 'Z' ||
        letters.substr(0, i).find(letters[i]) != std::string_view::npos) {
      return false;
    }
  }
  return true;
}

MapStatus append_chunk(const msg::ProgramChunk& chunk, Program& program, WireProblem& where) {
  where = WireProblem{};
  if (chunk.segments().size() > kMaxChunkSegments) {
    where.field = "segments";
    return MapStatus::kTooManySegments;
  }
  if (chunk.number_axes() < 1 || chunk.number_axes() > kMaxAxes) {
    where.field = "number_axes";
    return MapStatus::kBadAxisCount;
  }
  const std::string_view letters(chunk.axis_letters().c_str(), chunk.axis_letters().size());
  if (!letters.empty() && !valid_axis_letters(letters, chunk.number_axes())) {
    where.field = "axis_letters";
    return MapStatus::kBadAxisLetters;
  }
  for (std::size_t k = 0; k < chunk.segments().size(); ++k) {
    const msg::Segment& s = chunk.segments()[k];
    if (const MapStatus st = validate(s, where); st != MapStatus::kOk) {
      where.record = static_cast<int>(k);
      where.line = s.line();
      return st;
    }
  }
  program.number_axes = chunk.number_axes();
  program.axis_letters = letters;
  program.segments.reserve(program.segments.size() + chunk.segments().size());
  for (const msg::Segment& s : chunk.segments()) {
    (void)append_from_idl(s, program);  // validated above, cannot fail
  }
  return MapStatus::kOk;
}

MapStatus append_chunk(const msg::ProgramChunk& chunk, Program& program) {
  WireProblem unused;
  return append_chunk(chunk, program, unused);
}

std::string describe(MapStatus status, const WireProblem& where, std::uint64_t first_record) {
  // Appends only: GCC 12 at -O3 reports a false -Wrestrict for "literal" + std::string&&
  // (sessions 46, 47 and 74).
  std::string out(to_string(status));
  if (status == MapStatus::kOk) return out;
  if (where.record >= 0) {
    out += ": record ";
    out += std::to_string(first_record + static_cast<std::uint64_t>(where.record));
    out += " of the program (record ";
    out += std::to_string(where.record);
    out += " of its chunk";
    if (where.line > 0) {
      out += ", source line ";
      out += std::to_string(where.line);
    }
    out += ")";
  }
  if (!where.field.empty()) {
    out += where.record >= 0 ? ", field " : ": field ";
    out += where.field;
    if (where.element >= 0) {
      out += "[";
      out += std::to_string(where.element);
      out += "]";
    }
  }
  return out;
}

namespace {

void to_idl(const LookAheadEntry& e, msg::LookAheadEntry& out) {
  out.all_params() = e.all_params;
  out.tangent(e.tangent_deg);
  out.movement_type(e.movement_type);
  out.movement_code(e.movement_code);
  out.plane(e.plane);
  out.tool(e.tool);
  out.end_pos() = e.end_pos_mm;
  out.start_angle(e.start_angle_deg);
  out.end_angle(e.end_angle_deg);
  out.radius(e.radius_mm);
  out.line(e.line);
}

void from_idl(const msg::LookAheadEntry& e, LookAheadEntry& out) {
  out.all_params = e.all_params();
  out.tangent_deg = e.tangent();
  out.movement_type = e.movement_type();
  out.movement_code = e.movement_code();
  out.plane = e.plane();
  out.tool = e.tool();
  out.end_pos_mm = e.end_pos();
  out.start_angle_deg = e.start_angle();
  out.end_angle_deg = e.end_angle();
  out.radius_mm = e.radius();
  out.line = e.line();
}

}  // namespace

void to_idl(const Registers& r, std::uint16_t interpolator, msg::InterpolatorState& out) {
  out.interpolator(interpolator);
  out.number(r.number);
  out.number_axes(r.number_axes);
  out.buffer_size(r.buffer_size);
  out.command(r.command);
  out.command_parameter() = r.command_parameter;
  out.command_status(r.command_status);
  out.status(r.status);
  out.act_part(r.act_part);
  out.address_external_position(r.address_external_position);
  out.m_func(r.m_func);
  out.act_g_func(r.act_g_func);
  out.act_m_func(r.act_m_func);
  out.last_cont_m_func(r.last_cont_m_func);
  out.run_flag(static_cast<std::int32_t>(r.run_flag));
  out.tool_number(r.tool_number);
  out.orig_position() = r.orig_position;
  out.position() = r.position;
  out.position_inc() = r.position_inc;
  out.backlash() = r.backlash;
  out.offset() = r.offset;
  out.speed() = r.speed;
  out.ratio() = r.ratio;
  out.m_function_parameter() = r.m_function_parameter;
  out.rel_speed(r.rel_speed);
  out.set_speed(r.set_speed);
  out.act_speed(r.act_speed);
  out.move_distance(r.move_distance);
  for (std::size_t i = 0; i < r.lookahead.size(); ++i) {
    to_idl(r.lookahead[i], out.look_ahead_buffer()[i]);
  }
  out.act_line(r.act_line);
  out.off_trajectory(r.off_trajectory != 0);
  out.program_stop(r.program_stop != 0);
  out.act_acceleration_mm_s2(r.act_acceleration_mm_s2);
  out.limit_factor(static_cast<std::uint8_t>(r.limit_factor));
  out.m_func_count(r.m_func_count);
  out.m_func_line(r.m_func_line);
  out.free_buffer_slots(r.free_slots);
  out.cycle_counter(r.cycle);
  out.message_counter(r.message_count);
}

void from_idl(const msg::InterpolatorState& in, Registers& out) {
  out.number = in.number();
  out.number_axes = in.number_axes();
  out.buffer_size = in.buffer_size();
  out.command = in.command();
  out.command_parameter = in.command_parameter();
  out.command_status = in.command_status();
  out.status = in.status();
  out.act_part = in.act_part();
  out.address_external_position = in.address_external_position();
  out.m_func = in.m_func();
  out.act_g_func = in.act_g_func();
  out.act_m_func = in.act_m_func();
  out.last_cont_m_func = in.last_cont_m_func();
  out.run_flag = static_cast<std::uint32_t>(in.run_flag());
  out.tool_number = in.tool_number();
  out.orig_position = in.orig_position();
  out.position = in.position();
  out.position_inc = in.position_inc();
  out.backlash = in.backlash();
  out.offset = in.offset();
  out.speed = in.speed();
  out.ratio = in.ratio();
  out.m_function_parameter = in.m_function_parameter();
  out.rel_speed = in.rel_speed();
  out.set_speed = in.set_speed();
  out.act_speed = in.act_speed();
  out.move_distance = in.move_distance();
  for (std::size_t i = 0; i < out.lookahead.size(); ++i) {
    from_idl(in.look_ahead_buffer()[i], out.lookahead[i]);
  }
  out.act_line = in.act_line();
  out.off_trajectory = in.off_trajectory() ? 1 : 0;
  out.program_stop = in.program_stop() ? 1 : 0;
  out.act_acceleration_mm_s2 = in.act_acceleration_mm_s2();
  out.limit_factor = static_cast<LimitFactor>(in.limit_factor());
  out.m_func_count = in.m_func_count();
  out.m_func_line = in.m_func_line();
  out.free_slots = in.free_buffer_slots();
  out.cycle = in.cycle_counter();
  out.message_count = in.message_counter();
}

void to_event(const EventRegisters& r, std::uint16_t interpolator, msg::InterpolatorEvent& out) {
  out.interpolator(interpolator);
  out.cycle_counter(r.cycle);
  out.status(r.status);
  out.run_flag(static_cast<std::int32_t>(r.run_flag));
  out.act_part(r.act_part);
  out.act_line(r.act_line);
  out.m_func(r.m_func);
  out.act_m_func(r.act_m_func);
  out.last_cont_m_func(r.last_cont_m_func);
  out.command(r.command);
  out.command_status(r.command_status);
  out.m_func_count(r.m_func_count);
  out.m_func_line(r.m_func_line);
  out.m_function_parameter() = r.m_function_parameter;
}

void from_event(const msg::InterpolatorEvent& in, Registers& out) {
  out.cycle = in.cycle_counter();
  out.status = in.status();
  out.run_flag = static_cast<std::uint32_t>(in.run_flag());
  out.act_part = in.act_part();
  out.act_line = in.act_line();
  out.m_func = in.m_func();
  out.act_m_func = in.act_m_func();
  out.last_cont_m_func = in.last_cont_m_func();
  out.command = in.command();
  out.command_status = in.command_status();
  out.m_func_count = in.m_func_count();
  out.m_func_line = in.m_func_line();
  out.m_function_parameter = in.m_function_parameter();
}

void to_setpoints(const Registers& r, std::uint16_t interpolator, msg::Setpoints& out) {
  out.interpolator(interpolator);
  out.cycle_counter(r.cycle);
  out.position() = r.position;
  out.position_inc() = r.position_inc;
}

}  // namespace tgm::mapping
