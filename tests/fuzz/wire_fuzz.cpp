// Fuzz target: arbitrary bytes as a DDS sample of one of the seven tgm topics, as Fast DDS hands
// a received payload to the type support (the first byte picks the topic, the rest is the
// payload with its 4-byte encapsulation). Built with DDS only; plain driver, no libFuzzer.
//
// Invariants: the type support every tgm participant registers (dds::CheckedType) reads any
// bytes without throwing (the generated one let fastcdr's BadParamException through: one
// malformed sample ended the process); a program chunk it reads is appended by the mapping in
// whole or not at all, and what it appends is finite and either stored by an interpolator of
// that many axes or refused with a reason; a state or an event it reads maps to registers.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/gcode.hpp"
#include "tgm/idl_mapping.hpp"
#include "tgm/interpolator.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace {

using eprosima::fastrtps::rtps::SerializedPayload_t;
namespace msg = tgm::msg;

enum Topic : std::uint8_t {
  kChunk,
  kRequest,
  kReply,
  kState,
  kEvent,
  kSetpoints,
  kMessage,
  kTopics
};

// Reads `bytes` as a sample of T; false when the type support drops it.
template <class PubSubType, class T>
bool read(const std::string& bytes, T& out) {
  tgm::dds::CheckedType<PubSubType> type;
  SerializedPayload_t payload(static_cast<std::uint32_t>(bytes.size()));
  if (!bytes.empty()) std::memcpy(payload.data, bytes.data(), bytes.size());
  payload.length = static_cast<std::uint32_t>(bytes.size());
  return type.deserialize(&payload, &out);
}

template <class PubSubType, class T>
std::string written(Topic topic, T& sample) {
  PubSubType type;
  SerializedPayload_t payload(type.getSerializedSizeProvider(&sample)());
  TGM_FUZZ_CHECK(type.serialize(&sample, &payload), "serialize a seed");
  return std::string(1, static_cast<char>(topic)) +
         std::string(reinterpret_cast<const char*>(payload.data), payload.length);
}

void check_chunk(const msg::ProgramChunk& c) {
  tgm::Program p;
  tgm::mapping::WireProblem where;
  const tgm::mapping::MapStatus st = tgm::mapping::append_chunk(c, p, where);
  TGM_FUZZ_CHECK(!tgm::mapping::to_string(st).empty(), "a map status without words");
  if (st != tgm::mapping::MapStatus::kOk) {
    // The service's refusal names the field at fault, and the record when it is one.
    TGM_FUZZ_CHECK(!where.field.empty(),
                   "a refusal without its field: " + std::string(tgm::mapping::to_string(st)));
    TGM_FUZZ_CHECK(where.record < static_cast<int>(c.segments().size()),
                   "a refusal names a record beyond the chunk");
    const std::string said = tgm::mapping::describe(st, where, c.sequence_number());
    TGM_FUZZ_CHECK(said.find(where.field) != std::string::npos, "the field is not said: " + said);
    TGM_FUZZ_CHECK(
        p.segments.empty() && p.params.empty() && p.messages.empty(),
        "a refused chunk changed the program: " + std::string(tgm::mapping::to_string(st)));
    return;
  }
  TGM_FUZZ_CHECK(p.segments.size() == c.segments().size(), "records lost or made");
  TGM_FUZZ_CHECK(p.number_axes >= 1 && p.number_axes <= tgm::kMaxAxes, "number_axes");
  std::string why;
  TGM_FUZZ_CHECK(tgm::fuzz::all_finite(p, why), why);
  // What the service does next: append to an interpolator of that many axes (the engine
  // checks the letters first; a chunk without letters is checked by count).
  tgm::MachineConfig m = tgm::MachineConfig::default_machine();
  m.interpolators.resize(1);
  // The smallest ring (1,000 records; append takes what fits): each interpolator made here
  // reserved 10,000 slots, and under AddressSanitizer, whose shadow of every large block is
  // written, the CTest run took over 300 s on a VM where a page fault costs microseconds.
  m.interpolators[0].buffer_size = 1000;
  auto& axes = m.interpolators[0].axes;
  axes.assign(static_cast<std::size_t>(p.number_axes), axes.front());
  for (std::size_t k = 0; k < axes.size(); ++k) axes[k].letter = "XYZABCUVWE"[k];
  std::string error;
  auto ip = tgm::Interpolator::create(m, 0, {}, &error);
  TGM_FUZZ_CHECK(ip.has_value(), "interpolator: " + error);
  const tgm::RequestResult r = ip->append(p, 0, p.segments.size(), c.end_of_program());
  TGM_FUZZ_CHECK(r.ok() || !r.reason.empty(), "a refusal without a reason");
}

}  // namespace

namespace tgm::fuzz {

//! Every topic's sample as the generated code writes it; the chunks of the G-code seeds.
void prepare_seeds(std::vector<std::string>& seeds) {
  std::vector<std::string> out;
  for (const std::string& text : seeds) {
    const CompileResult r =
        compile_gcode(text, CompileOptions::from_machine(MachineConfig::default_machine(), 0));
    if (!r.ok()) continue;
    std::vector<msg::ProgramChunk> chunks;
    mapping::ChunkHeader h;
    h.program_id = 3;
    if (mapping::to_chunks(r.program, h, chunks) != mapping::MapStatus::kOk) continue;
    for (std::size_t k = 0; k < chunks.size() && k < 4; ++k) {
      chunks[k].axis_letters("XYZ");
      out.push_back(written<msg::ProgramChunkPubSubType>(kChunk, chunks[k]));
    }
  }
  msg::Request q;
  q.client_name("tgm-hmi-42");
  q.kind(msg::REQUEST_KIND_COMMAND);
  q.command(8);
  out.push_back(written<msg::RequestPubSubType>(kRequest, q));
  msg::Reply y;
  y.client_name("tgm-hmi-42");
  y.accepted(false);
  y.code(msg::REPLY_CODE_WRONG_STATE);
  y.reason("nothing loaded");
  out.push_back(written<msg::ReplyPubSubType>(kReply, y));
  auto ip = Interpolator::create(MachineConfig::default_machine(), 0);
  msg::InterpolatorState s;
  mapping::to_idl(ip->registers(), 0, s);
  s.axis_letters("XYZ");
  s.message_text("hello");
  out.push_back(written<msg::InterpolatorStatePubSubType>(kState, s));
  msg::InterpolatorEvent e;
  mapping::to_event(event_registers(ip->registers()), 0, e);
  out.push_back(written<msg::InterpolatorEventPubSubType>(kEvent, e));
  msg::Setpoints sp;
  mapping::to_setpoints(ip->registers(), 0, sp);
  out.push_back(written<msg::SetpointsPubSubType>(kSetpoints, sp));
  msg::Message mm;
  mm.text("tool change");
  out.push_back(written<msg::MessagePubSubType>(kMessage, mm));
  seeds = std::move(out);
}

// Binary input: the G-code words and odd numbers mean as much as any bytes.
void prepare_tokens(std::vector<std::string>&) {}

}  // namespace tgm::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto topic = static_cast<Topic>(data[0] % kTopics);
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  tgm::Registers regs;
  switch (topic) {
    case kChunk: {
      msg::ProgramChunk c;
      if (read<msg::ProgramChunkPubSubType>(bytes, c)) check_chunk(c);
      break;
    }
    case kRequest: {
      msg::Request r;
      (void)read<msg::RequestPubSubType>(bytes, r);
      break;
    }
    case kReply: {
      msg::Reply r;
      (void)read<msg::ReplyPubSubType>(bytes, r);
      break;
    }
    case kState: {
      msg::InterpolatorState s;
      if (read<msg::InterpolatorStatePubSubType>(bytes, s)) tgm::mapping::from_idl(s, regs);
      break;
    }
    case kEvent: {
      msg::InterpolatorEvent e;
      if (read<msg::InterpolatorEventPubSubType>(bytes, e)) tgm::mapping::from_event(e, regs);
      break;
    }
    case kSetpoints: {
      msg::Setpoints s;
      (void)read<msg::SetpointsPubSubType>(bytes, s);
      break;
    }
    case kMessage:
    case kTopics: {
      msg::Message m;
      (void)read<msg::MessagePubSubType>(bytes, m);
      break;
    }
  }
  return 0;
}
