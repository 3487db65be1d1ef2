// Fuzz target: arbitrary bytes as a G-code program.
//
// Invariants (core/GCODE.md): the compiler never crashes or hangs, with block delete refused,
// run or skipped; a program with errors yields no records and every error has a place and a
// reason; a program without errors has finite numbers only and survives encode -> decode ->
// encode unchanged; the dumps do not crash.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "tgm/gcode.hpp"
#include "tgm/intercode_io.hpp"

namespace {

tgm::CompileOptions options(bool ten_axes, bool incremental, std::size_t block_delete) {
  tgm::CompileOptions o;
  // Lines starting with '/': refused, run or skipped (by the input's length).
  o.compiler.block_delete = static_cast<tgm::BlockDelete>(block_delete % 3);
  o.axis_letters = ten_axes ? "XYZABCUVWE" : "XYZ";
  o.compiler.start_incremental = incremental;
  // Small enough that loops (G26/G27 with K) expand quickly, large enough to hit the limit.
  o.compiler.max_program_segments = 100'000;
  o.tools = {{1, 2.0, 10.0}, {2, 0.5, 5.0}, {7, 0.0, 0.0}};
  return o;
}

void check(std::string_view text, const tgm::CompileOptions& opt) {
  const tgm::CompileResult r = tgm::compile_gcode(text, opt);
  if (!r.ok()) {
    TGM_FUZZ_CHECK(r.program.segments.empty(), "a program with errors produced records");
    // Lines end at LF, and at a CR that no LF follows (unless it is the text's last byte).
    std::size_t lines = 1;
    for (std::size_t i = 0; i < text.size(); ++i) {
      const bool lone_cr = text[i] == '\r' && i + 1 < text.size() && text[i + 1] != '\n';
      lines += text[i] == '\n' || lone_cr ? 1 : 0;
    }
    for (const tgm::Diagnostic& d : r.errors) {
      TGM_FUZZ_CHECK(d.line >= 1 && static_cast<std::size_t>(d.line) <= lines + 1,
                     "diagnostic line " + std::to_string(d.line));
      TGM_FUZZ_CHECK(d.column >= 1, "diagnostic column " + std::to_string(d.column));
      TGM_FUZZ_CHECK(!d.reason.empty(), "diagnostic without a reason");
      (void)tgm::format_diagnostic("fuzz.ngc", d);
    }
    return;
  }
  const tgm::Program& p = r.program;
  std::string why;
  TGM_FUZZ_CHECK(p.number_axes == static_cast<int>(opt.axis_letters.size()), "number_axes");
  TGM_FUZZ_CHECK(static_cast<std::int64_t>(p.segments.size()) <=
                     opt.compiler.max_program_segments,
                 "more segments than compiler.max_program_segments");
  TGM_FUZZ_CHECK(tgm::fuzz::all_finite(p, why), why);

  std::string bytes;
  tgm::encode_intercode(p, bytes);
  tgm::Program back;
  std::string error;
  TGM_FUZZ_CHECK(tgm::decode_intercode(bytes, back, error), "decode of fresh encode: " + error);
  TGM_FUZZ_CHECK(tgm::fuzz::same_program(p, back, why), "round trip differs: " + why);
  std::string again;
  tgm::encode_intercode(back, again);
  TGM_FUZZ_CHECK(again == bytes, "re-encoding differs");

  std::string dump;
  tgm::dump_jsonl(p, dump);
  std::size_t records = 0;
  for (char c : dump) records += c == '\n' ? 1 : 0;
  TGM_FUZZ_CHECK(records == p.segments.size(), "dump_jsonl: one line per record");
  dump.clear();
  tgm::dump_text(p, dump);
}

}  // namespace

namespace tgm::fuzz {
void prepare_seeds(std::vector<std::string>&) {}
void prepare_tokens(std::vector<std::string>&) {}
}  // namespace tgm::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  check(text, options(false, true, size));
  check(text, options(true, false, size + 1));
  return 0;
}
