// Mapping between core's plain structs and the generated DDS types (DESIGN.md section 2: one
// place, linked by the service and the clients).
//
// The program stream carries intercode records (`tgm::Segment`) as `tgm::msg::Segment`. Core keeps
// M-function parameters and message texts in side tables of `tgm::Program` and points at them
// with `Segment::aux`; on the wire each record carries its own payload instead (empty when it
// has none), so that chunks can be consumed one by one. The receiver rebuilds the side tables.
//
// Nothing here throws or blocks: results are status codes, because the service maps chunks on
// its receiving thread and the HMI maps while streaming.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/intercode.hpp"
#include "tgm/registers.hpp"
#include "tgm/msg/tgm.h"

namespace tgm::mapping {

//! Largest serialized size of a chunk the chunker produces [bytes]: well under the 64 KiB of a
//! UDP datagram, so a chunk is never fragmented.
inline constexpr std::size_t kChunkByteBudget = 32 * 1024;
//! Records in a chunk at most (the IDL bound).
inline constexpr std::size_t kMaxChunkSegments = TGM_MAX_CHUNK_SEGMENTS;
//! Longest message text on the wire [characters] (the IDL bound).
inline constexpr std::size_t kMaxTextLength = TGM_MAX_TEXT;

//! Outcome of a mapping. `kOk = 0`; every other value is a reason the input is rejected.
enum class MapStatus : std::int8_t {
  kOk = 0,
  kBadType = -1,          //!< segment type, plane, compensation or M kind outside its enum
  kBadAux = -2,           //!< `aux` does not point into the program's side table (core -> IDL)
  kTextTooLong = -3,      //!< message longer than kMaxTextLength (core -> IDL)
  kBadParams = -4,        //!< parameter count neither 0 nor 26, or parameters on a non-M record
  kUnexpectedText = -5,   //!< text on a record that is not a message
  kNotFinite = -6,        //!< NaN or infinity in a coordinate, radius, feed or time
  kTooManySegments = -7,  //!< chunk holds more records than the IDL bound
  kBadAxisCount = -8,     //!< number of axes outside 1..kMaxAxes
  kBadIndex = -9,         //!< first record index beyond the end of the program
  kBadAxisLetters = -10,  //!< axis letters neither empty nor one distinct A..Z per axis
};

//! A short English reason for a status ("ok" for kOk).
std::string_view to_string(MapStatus s);

//! Side-table payload of one record, as the program stream carries it.
struct SegmentPayload {
  bool has_params = false;
  MParams params = unset_params();
  bool has_message = false;
  std::string message;
};

//! Core record -> wire record. `params` / `message` are the record's side-table entries (null
//! when it has none); `out.params` / `out.text` stay empty otherwise.
MapStatus to_idl(const Segment& in, const MParams* params, const std::string* message,
                 msg::Segment& out);

//! Record `index` of `program` -> wire record, resolving `aux` in the program's side tables.
MapStatus to_idl(const Program& program, std::size_t index, msg::Segment& out);

//! Wire record -> core record plus its payload. `out.aux` is set to -1: the caller stores the
//! payload in its own side table and sets `aux`. Validates enums, finiteness and payload shape.
MapStatus from_idl(const msg::Segment& in, Segment& out, SegmentPayload& payload);

//! Wire record appended to `program`, its payload appended to the side tables with `aux` set.
//! On error `program` is unchanged.
MapStatus append_from_idl(const msg::Segment& in, Program& program);

//! Addressing of the chunks of one program.
struct ChunkHeader {
  std::uint16_t interpolator = 0;
  //! Program identity chosen by the sender; non-zero.
  std::uint32_t program_id = 1;
};

//! Fills `out` with records of `program` starting at `first`: at most kMaxChunkSegments and at
//! most kChunkByteBudget bytes serialized (at least one record). `next` receives the index after
//! the last record taken (on error: the record that cannot be sent); `end_of_program` is set on
//! the chunk that takes the last record. An empty program gives one empty chunk with
//! `end_of_program`.
MapStatus fill_chunk(const Program& program, std::size_t first, const ChunkHeader& header,
                     msg::ProgramChunk& out, std::size_t& next);

//! What keeps `program` from being sent, checked before its first record goes out (a sender
//! that finds it later has sent part of a program that may already run): kOk, or the reason
//! and in `index` the record (0 for the program's own axis count and letters). Cheap: no record
//! is serialized.
MapStatus program_problem(const Program& program, std::size_t& index);

//! The whole program as chunks (convenient for small programs and tests; a streaming sender
//! calls fill_chunk as flow control allows). On error `chunks` is empty.
MapStatus to_chunks(const Program& program, const ChunkHeader& header,
                    std::vector<msg::ProgramChunk>& chunks);

//! True when `letters` name `number_axes` axes: one distinct letter A..Z each. (Empty letters,
//! which a chunk may carry when its sender does not know them, are checked by the callers.)
bool valid_axis_letters(std::string_view letters, int number_axes);

//! Appends every record of `chunk` to `program` (and sets `program.number_axes` and
//! `program.axis_letters`, empty when the chunk names none). Validates the
//! whole chunk first: on error `program` is unchanged. Sequence numbers are the caller's business
//! (it knows which one it expects).
MapStatus append_chunk(const msg::ProgramChunk& chunk, Program& program);

//! Where a wire chunk is at fault: the record's index in the chunk (-1 for the chunk's own
//! fields), its source line (0 when unknown), the field's IDL name and, for an array, the
//! element (-1 otherwise).
struct WireProblem {
  int record = -1;
  std::int32_t line = 0;
  std::string_view field;
  int element = -1;
};

//! append_chunk that also says where the chunk is at fault.
MapStatus append_chunk(const msg::ProgramChunk& chunk, Program& program, WireProblem& where);

//! The reason and the place, for a sender to find the record: "NaN or infinity in a record:
//! record 1037 of the program (record 13 of its chunk, source line 57), field end[2]".
//! `first_record` is the chunk's sequence number (the program index of its first record).
std::string describe(MapStatus status, const WireProblem& where, std::uint64_t first_record);

// ---------------------------------------------------------------------------------------------
// State and setpoints.

//! Core registers -> state sample: every register of the manual and the core's extensions;
//! `cycle_counter` = r.cycle, `free_buffer_slots` = r.free_slots, `message_counter` =
//! r.message_count. The service's own fields (service_instance, program_id, next_sequence,
//! buffered_segments, message_text, lateness_*, missed_cycles) are left as they are in `out`.
void to_idl(const Registers& r, std::uint16_t interpolator, msg::InterpolatorState& out);

//! State sample -> core registers (for clients that work with the core struct). `message_slot`
//! is not on the wire and is left as it is.
void from_idl(const msg::InterpolatorState& in, Registers& out);

//! Event registers (tgm::event_registers() of the core registers: Status, Run_Flag, Act_Part,
//! Act_Line, M_Func, Act_M_Func, Last_Cont_M_Func, Command, Command_Status, the M-function
//! count, M_Function_Parameter) -> event sample; `cycle_counter` = r.cycle. The service's own
//! fields (event_counter, service_instance, program_id) are left as they are in `out`.
void to_event(const EventRegisters& r, std::uint16_t interpolator, msg::InterpolatorEvent& out);

//! Event sample -> the event registers of `out` (what to_event writes); every other register is
//! left as it is, so a client can apply an event to the registers of the last state it has.
void from_event(const msg::InterpolatorEvent& in, Registers& out);

//! Core registers -> the cycle's setpoints (Position, PositionInc).
void to_setpoints(const Registers& r, std::uint16_t interpolator, msg::Setpoints& out);

}  // namespace tgm::mapping
