// Binary encoding of intercode (the `--out` file of `tgm-hmi compile`) and its readable dumps.
// Everything works on memory buffers; files are the callers' business.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "tgm/intercode.hpp"

namespace tgm {

//! Appends the binary intercode of `p` to `out` (little-endian, versioned, compact: a record
//! stores the configured axes and modal fields that differ from the record before it, and only
//! the fields its type uses; since version 3 it ends in a CRC-32 of the file, so that a damaged
//! file is refused instead of being run as another program; version 4 holds the point the
//! program was compiled from, `Program::start_mm`).
void encode_intercode(const Program& p, std::string& out);

//! Writes binary intercode record by record, for programs too long to hold as `Segment`s.
class IntercodeEncoder {
 public:
  //! Byte offset of the record count (uint64) in the header, for writers that stream the records
  //! out before the count is known.
  static constexpr std::size_t kCountOffset = 4 + 2 + 1 + kMaxAxes;

  //! Appends the header to `out`; `out` must outlive the encoder. A `streaming` encoder's caller
  //! empties `out` as it goes and writes the record count at kCountOffset itself. `start_mm`:
  //! the point the program was compiled from (finite; the first `number_axes` are written).
  IntercodeEncoder(std::string& out, int number_axes, std::string_view axis_letters,
                   const std::array<double, kMaxAxes>& start_mm, bool streaming = false);
  //! Appends one record.
  void add(const Segment& s);
  //! Appends the side tables and, unless streaming, fixes the record count in the header.
  void finish(const std::vector<MParams>& params, const std::vector<std::string>& messages);
  //! Records added so far.
  std::uint64_t records() const { return count_; }

 private:
  std::string& out_;
  std::size_t count_offset_;
  bool streaming_;
  std::uint64_t count_ = 0;
  int n_;
  // What the previous record left (the delta base); the decoder starts from the same values.
  std::array<double, kMaxAxes> prev_end_{};
  std::int32_t prev_line_ = 0;
  std::int32_t prev_tool_ = 0;
  std::uint8_t prev_modes_ = 0;  // G17, G40, no M kind
  double prev_feed_ = 0.0;
  double prev_comp_radius_ = 0.0;
  std::uint32_t crc_ = 0xFFFFFFFFu;  // of what was appended so far, but the record count
};

//! Parses binary intercode (versions 3 and 4, checksum checked first, or version 2, which has
//! none; versions 2 and 3 were always compiled from machine zero, and read so). On failure
//! returns false and says why in `error`; never reads out of bounds and never accepts NaN,
//! unknown record types or dangling side-table indices.
bool decode_intercode(std::string_view bytes, Program& out, std::string& error);

//! A program held as checked binary intercode (about 20 bytes a record for a G1 move in one
//! plane, where a Segment takes 152) and read front to back: for programs too long to hold as
//! Segments (`tgm-hmi simulate` of a few million lines held 1.4 GB).
class PackedProgram {
 public:
  //! Checks `file` as decode_intercode does and holds it; false, with the reason, when
  //! decode_intercode would refuse it. `observe` (when given) sees each record as it is checked,
  //! which saves a pass for a caller that needs one; when open fails it may have seen a part of
  //! the records.
  static bool open(std::string file, PackedProgram& out, std::string& error,
                   const std::function<void(const Segment&)>& observe = {});
  //! The same for a program in memory (encoded first).
  static bool from_program(const Program& program, PackedProgram& out, std::string& error);
  //! Everything but the records: axes, letters, start point, parameter and message tables.
  const Program& tables() const { return tables_; }
  //! Number of records.
  std::uint64_t size() const { return count_; }
  //! Bytes held (the intercode file).
  std::size_t bytes() const { return file_.size(); }
  //! The intercode file held, as `tgm-hmi compile --out` writes it.
  std::string_view file() const { return file_; }

  //! Reads the records in order. The program must outlive it.
  class Cursor {
   public:
    explicit Cursor(const PackedProgram& p);
    ~Cursor();
    Cursor(Cursor&&) noexcept;
    Cursor& operator=(Cursor&&) noexcept;
    //! The next record into `s`; false after the last.
    bool next(Segment& s);
    //! Records read so far.
    std::uint64_t read() const { return read_; }
    //! What the records' delta fields apply to (opaque).
    struct State;

   private:
    const PackedProgram* program_;
    std::unique_ptr<State> state_;
    std::size_t at_;
    std::uint64_t read_ = 0;
  };
  Cursor cursor() const { return Cursor(*this); }

  //! The records from a point on as a Program (the side tables whole), which is what
  //! Interpolator::append and the chunk mapping take: decoded as they are asked for (none ahead),
  //! dropped once they lie behind. The program must outlive it.
  class Window {
   public:
    explicit Window(const PackedProgram& p) : cursor_(p), records_(p.tables()) {}
    //! Holds records [first, first + count), fewer at the program's end; they stand from index
    //! first - base() of the returned Program. `first` never moves back.
    const Program& from(std::uint64_t first, std::uint64_t count);
    //! The program's index of the returned Program's first record.
    std::uint64_t base() const { return base_; }

   private:
    Cursor cursor_;
    Program records_;
    std::uint64_t base_ = 0;
  };

 private:
  std::string file_;
  Program tables_;
  std::uint64_t count_ = 0;
  std::size_t records_at_ = 0;
  std::size_t body_size_ = 0;
};

//! True when `bytes` begin as binary intercode does (its magic, "TGMI"). No G-code text begins
//! so: a T word needs a number. Callers decide by this, not by a file's name.
bool has_intercode_magic(std::string_view bytes);

//! CRC-32 (IEEE 802.3, as zlib's crc32) of `bytes`.
std::uint32_t crc32(std::string_view bytes);

//! Writes the checksum that a version 3 or 4 file's other bytes call for into its last 4 bytes
//! (for tests and fuzzers that change a file on purpose). False, and nothing changed, when
//! `file` is not such intercode long enough to have one.
bool reseal_intercode(std::string& file);

//! One JSON object per record, '\n'-terminated (see README "Intercode dump").
void dump_jsonl(const Program& p, std::string& out);

//! One readable line per record.
void dump_text(const Program& p, std::string& out);

//! One record's line of dump_jsonl / dump_text; `tables` gives the axis letters and the
//! parameter and message tables (its records are not read: PackedProgram::tables() will do).
void dump_jsonl_record(const Program& tables, const Segment& s, std::string& out);
void dump_text_record(const Program& tables, const Segment& s, std::string& out);

//! Name of a record type as the dumps print it: G0..G4, M, MSG.
std::string_view segment_type_name(SegmentType t);

}  // namespace tgm
