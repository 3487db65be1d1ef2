// Fuzz target: arbitrary bytes as binary intercode (what `tgm-hmi compile --out` writes and the
// service reads).
//
// Invariants: decode_intercode never crashes or reads out of bounds; what it accepts has no
// NaN and finite records, encodes and decodes back to the same program, and dumps. Each input
// is decoded as it is and, resealed with the checksum its bytes call for, once more.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"

namespace tgm::fuzz {

//! Compiles the G-code seeds and encodes them, and adds a hand-built program that uses every
//! record type and side table, so that mutations start from valid intercode.
void prepare_seeds(std::vector<std::string>& seeds) {
  std::vector<std::string> out;
  for (const std::string& text : seeds) {
    for (const char* letters : {"XYZ", "XYZABCUVWE"}) {
      CompileOptions o;
      o.axis_letters = letters;
      o.tools = {{1, 2.0, 10.0}};
      const CompileResult r = compile_gcode(text, o);
      if (!r.ok()) continue;
      std::string bytes;
      encode_intercode(r.program, bytes);
      out.push_back(std::move(bytes));
    }
  }
  Program p;
  p.number_axes = 4;
  p.axis_letters = "XYZA";
  p.start_mm = {0.5, -1.25, 2, 90};
  Segment s;
  s.type = SegmentType::kLinear;
  s.line = 1;
  s.end = {1, 2, 3, 4};
  s.feed_mm_per_min = 600;
  p.segments.push_back(s);
  s.type = SegmentType::kArcCcw;
  s.plane = Plane::kXZ;
  s.compensation = Compensation::kLeft;
  s.compensation_radius_mm = 1.5;
  s.center = {3, 0};
  s.radius = 1;
  s.turns = 2;
  p.segments.push_back(s);
  s = Segment{};
  s.type = SegmentType::kDwell;
  s.dwell_s = 0.5;
  p.segments.push_back(s);
  s.type = SegmentType::kMFunction;
  s.m_kind = MKind::kNormal;
  s.m = 51;
  s.aux = 0;
  p.params.push_back(unset_params());
  p.params[0][0] = 7;
  p.segments.push_back(s);
  s.type = SegmentType::kMessage;
  s.m_kind = MKind::kNone;
  s.aux = 0;
  p.messages.push_back("hello");
  p.segments.push_back(s);
  std::string bytes;
  encode_intercode(p, bytes);
  out.push_back(std::move(bytes));
  seeds = std::move(out);
}

// Binary input: the G-code words and odd numbers mean as much as any bytes.
void prepare_tokens(std::vector<std::string>&) {}

}  // namespace tgm::fuzz

namespace {

void check(std::string_view bytes) {
  tgm::Program p;
  std::string error;
  // PackedProgram accepts what decode_intercode accepts, for the same reason, and reads the
  // same records.
  tgm::PackedProgram packed;
  std::string packed_error;
  const bool packed_ok = tgm::PackedProgram::open(std::string(bytes), packed, packed_error);
  if (!tgm::decode_intercode(bytes, p, error)) {
    TGM_FUZZ_CHECK(!error.empty(), "decode failed without a reason");
    TGM_FUZZ_CHECK(!packed_ok && packed_error == error,
                   "PackedProgram: " + packed_error + " / " + error);
    return;
  }
  TGM_FUZZ_CHECK(packed_ok, "PackedProgram refused: " + packed_error);
  {
    tgm::Program read = packed.tables();
    TGM_FUZZ_CHECK(packed.size() == p.segments.size(), "PackedProgram size");
    auto cursor = packed.cursor();
    tgm::Segment s;
    while (cursor.next(s)) read.segments.push_back(s);
    std::string why;
    TGM_FUZZ_CHECK(tgm::fuzz::same_program(p, read, why), "PackedProgram differs: " + why);
  }
  std::string why;
  TGM_FUZZ_CHECK(p.number_axes >= 1 && p.number_axes <= tgm::kMaxAxes, "number_axes");
  TGM_FUZZ_CHECK(tgm::fuzz::all_finite(p, why), why);
  std::string enc;
  tgm::encode_intercode(p, enc);
  tgm::Program back;
  TGM_FUZZ_CHECK(tgm::decode_intercode(enc, back, error), "re-decode: " + error);
  TGM_FUZZ_CHECK(tgm::fuzz::same_program(p, back, why), "round trip differs: " + why);
  std::string enc2;
  tgm::encode_intercode(back, enc2);
  TGM_FUZZ_CHECK(enc2 == enc, "encoding is not stable");
  std::string dump;
  tgm::dump_jsonl(p, dump);
  dump.clear();
  tgm::dump_text(p, dump);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  check(bytes);
  // Nearly every mutation breaks the checksum, and the decoder stops there: the mutated content
  // is checked again with the checksum it calls for, so that the fuzzer reaches the records.
  std::string sealed(bytes);
  if (tgm::reseal_intercode(sealed) && sealed != bytes) check(sealed);
  return 0;
}
