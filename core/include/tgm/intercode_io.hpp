// Binary encoding of intercode (the `--out` file of `tgm-hmi compile`) and its readable dumps.
// Everything works on memory buffers; files are the callers' business.
#pragma once

#include <string>
#include <string_view>

#include "tgm/intercode.hpp"

namespace tgm {

//! Appends the binary intercode of `p` to `out` (little-endian, versioned, compact: only the
//! configured axes and the fields a record type uses are stored).
void encode_intercode(const Program& p, std::string& out);

//! Parses binary intercode. On failure returns false and says why in `error`; never reads out
//! of bounds and never accepts NaN, unknown record types or dangling side-table indices.
bool decode_intercode(std::string_view bytes, Program& out, std::string& error);

//! One JSON object per record, '\n'-terminated (see README "Intercode dump").
void dump_jsonl(const Program& p, std::string& out);

//! One readable line per record.
void dump_text(const Program& p, std::string& out);

//! Name of a record type as the dumps print it: G0..G4, M, MSG.
std::string_view segment_type_name(SegmentType t);

}  // namespace tgm
