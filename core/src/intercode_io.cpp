#include "tgm/intercode_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>

#include "tgm/printable.hpp"

namespace tgm {

namespace {

constexpr char kMagic[4] = {'T', 'G', 'M', 'I'};
// 2: records store only what changed. 3: a CRC-32 trailer. 4: the start point after the header
// (number_axes doubles). Versions 2 and 3 are still read, as compiled from machine zero (the
// only point `tgm-hmi compile` compiled from before version 4).
constexpr std::uint16_t kVersion = 4;
constexpr std::uint16_t kVersionWithoutStart = 3;
constexpr std::uint16_t kVersionWithoutChecksum = 2;
constexpr std::size_t kHeaderBytes = IntercodeEncoder::kCountOffset + 8;

// CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320). `state` starts at 0xFFFFFFFF; the
// checksum is the final state inverted. Slicing by 8: t[k][i] is the CRC of byte i followed by k
// zero bytes, so eight bytes take eight look-ups and one step. Byte at a time, the check was a
// third of loading a file of 6 million records (session 60).
struct Crc32Tables {
  std::uint32_t t[8][256];
  constexpr Crc32Tables() : t() {
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[0][i] = c;
    }
    for (int k = 1; k < 8; ++k) {
      for (std::uint32_t i = 0; i < 256; ++i)
        t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFFu];
    }
  }
};
constexpr Crc32Tables kCrc;

// Four bytes as the little-endian word they are in the stream, on any host.
std::uint32_t le32(const char* p) {
  const auto b = [p](int i) {
    return static_cast<std::uint32_t>(static_cast<unsigned char>(p[i]));
  };
  return b(0) | b(1) << 8 | b(2) << 16 | b(3) << 24;
}

std::uint32_t crc_update(std::uint32_t state, const char* data, std::size_t n) {
  const auto& t = kCrc.t;
  for (; n >= 8; n -= 8, data += 8) {
    const std::uint32_t lo = state ^ le32(data), hi = le32(data + 4);
    state = t[7][lo & 0xFFu] ^ t[6][(lo >> 8) & 0xFFu] ^ t[5][(lo >> 16) & 0xFFu] ^ t[4][lo >> 24] ^
            t[3][hi & 0xFFu] ^ t[2][(hi >> 8) & 0xFFu] ^ t[1][(hi >> 16) & 0xFFu] ^ t[0][hi >> 24];
  }
  for (; n > 0; --n, ++data) {
    state = t[0][(state ^ static_cast<unsigned char>(*data)) & 0xFFu] ^ (state >> 8);
  }
  return state;
}

// The checksum a version 3 file carries in its last 4 bytes: the CRC-32 of every byte before
// them, the header's record count (8 bytes at kCountOffset) hashed last, so that a streaming
// writer, which fixes the count when everything else is written, computes it in one pass.
std::uint32_t file_checksum(std::string_view file) {
  const std::size_t body_end = file.size() - 4;
  std::uint32_t c = crc_update(0xFFFFFFFFu, file.data(), IntercodeEncoder::kCountOffset);
  c = crc_update(c, file.data() + kHeaderBytes, body_end - kHeaderBytes);
  c = crc_update(c, file.data() + IntercodeEncoder::kCountOffset, 8);
  return ~c;
}

}  // namespace

bool has_intercode_magic(std::string_view bytes) {
  return bytes.size() >= 4 && std::memcmp(bytes.data(), kMagic, 4) == 0;
}

std::uint32_t crc32(std::string_view bytes) {
  return ~crc_update(0xFFFFFFFFu, bytes.data(), bytes.size());
}

bool reseal_intercode(std::string& file) {
  if (file.size() < kHeaderBytes + 4 || std::memcmp(file.data(), kMagic, 4) != 0) return false;
  std::uint16_t version = 0;
  std::memcpy(&version, file.data() + 4, sizeof version);
  if (version != kVersion && version != kVersionWithoutStart) return false;
  const std::uint32_t c = file_checksum(file);
  std::memcpy(file.data() + file.size() - 4, &c, sizeof c);
  return true;
}

namespace {

template <typename T>
void put(std::string& out, T v) {
  char buf[sizeof(T)];
  std::memcpy(buf, &v, sizeof(T));
  out.append(buf, sizeof(T));
}

class In {
 public:
  explicit In(std::string_view b) : b_(b) {}
  template <typename T>
  bool get(T& v) {
    if (b_.size() - pos_ < sizeof(T)) return false;
    std::memcpy(&v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool bytes(std::size_t n, std::string& s) {
    if (b_.size() - pos_ < n) return false;
    s.assign(b_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  bool at_end() const { return pos_ == b_.size(); }
  void skip(std::size_t n) { pos_ += n; }
  std::size_t pos() const { return pos_; }

 private:
  std::string_view b_;
  std::size_t pos_ = 0;
};

void num(std::string& out, double v) {
  append_shortest(out, v);
}

// Side-table lookups of the dumps, safe for any record.
char axis_letter(const Program& p, int i) {
  return i < static_cast<int>(p.axis_letters.size()) ? p.axis_letters[static_cast<std::size_t>(i)]
                                                     : '?';
}
const MParams* params_of(const Program& p, const Segment& s) {
  return s.aux >= 0 && s.aux < static_cast<int>(p.params.size())
             ? &p.params[static_cast<std::size_t>(s.aux)]
             : nullptr;
}
std::string_view message_of(const Program& p, const Segment& s) {
  return s.aux >= 0 && s.aux < static_cast<int>(p.messages.size())
             ? std::string_view(p.messages[static_cast<std::size_t>(s.aux)])
             : std::string_view();
}

std::string_view m_kind_name(MKind k) {
  switch (k) {
    case MKind::kNormal: return "normal";
    case MKind::kContinuous: return "continuous";
    case MKind::kProgramStop: return "program_stop";
    case MKind::kProgramEnd: return "program_end";
    case MKind::kNone: break;
  }
  return "none";
}

}  // namespace

std::string_view segment_type_name(SegmentType t) {
  switch (t) {
    case SegmentType::kRapid: return "G0";
    case SegmentType::kLinear: return "G1";
    case SegmentType::kArcCw: return "G2";
    case SegmentType::kArcCcw: return "G3";
    case SegmentType::kDwell: return "G4";
    case SegmentType::kMFunction: return "M";
    case SegmentType::kMessage: return "MSG";
  }
  return "?";
}

IntercodeEncoder::IntercodeEncoder(std::string& out, int number_axes, std::string_view axis_letters,
                                   const std::array<double, kMaxAxes>& start_mm, bool streaming)
    : out_(out), count_offset_(0), streaming_(streaming), n_(number_axes) {
  const std::size_t start = out_.size();
  out_.append(kMagic, 4);
  put<std::uint16_t>(out_, kVersion);
  put<std::uint8_t>(out_, static_cast<std::uint8_t>(n_));
  char letters[kMaxAxes] = {};
  for (int i = 0; i < n_ && i < static_cast<int>(axis_letters.size()); ++i) {
    letters[i] = axis_letters[static_cast<std::size_t>(i)];
  }
  out_.append(letters, kMaxAxes);
  count_offset_ = out_.size();
  crc_ = crc_update(crc_, out_.data() + start, count_offset_ - start);
  put<std::uint64_t>(out_, 0);  // record count, fixed by finish()
  const std::size_t start_at = out_.size();
  for (int i = 0; i < n_; ++i) put<double>(out_, start_mm[static_cast<std::size_t>(i)]);
  crc_ = crc_update(crc_, out_.data() + start_at, out_.size() - start_at);
}

namespace {

// Record flags (format version 2): which delta fields follow.
constexpr std::uint8_t kHasModes = 1u << 0;   // plane / compensation / M kind changed
constexpr std::uint8_t kHasTool = 1u << 1;    // tool changed
constexpr std::uint8_t kHasFeed = 1u << 2;    // feed of a motion record changed
constexpr std::uint8_t kHasLine = 1u << 3;    // line is not the previous line + 1
constexpr std::uint8_t kHasCompRadius = 1u << 4;  // compensation radius changed
constexpr std::uint8_t kKnownFlags = 0x1F;

std::uint8_t pack_modes(const Segment& s) {
  return static_cast<std::uint8_t>((static_cast<int>(s.plane) - 17) |
                                   ((static_cast<int>(s.compensation) - 40) << 2) |
                                   (static_cast<int>(s.m_kind) << 4));
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

void IntercodeEncoder::add(const Segment& s) {
  ++count_;
  // Each record stores what differs from the record before it: a CAM G1 move in one plane
  // takes 20 bytes instead of 44.
  char buf[2 + 2 + 1 + 4 + 4 + 8 * kMaxAxes + 8 * 6 + 16];
  std::size_t k = 0;
  auto w = [&](const auto& v) {
    std::memcpy(buf + k, &v, sizeof v);
    k += sizeof v;
  };
  const std::uint8_t modes = pack_modes(s);
  std::uint8_t flags = 0;
  if (modes != prev_modes_) flags |= kHasModes;
  if (s.tool != prev_tool_) flags |= kHasTool;
  if (s.is_motion() && !same_bits(s.feed_mm_per_min, prev_feed_)) flags |= kHasFeed;
  if (static_cast<std::int64_t>(s.line) != static_cast<std::int64_t>(prev_line_) + 1) {
    flags |= kHasLine;
  }
  if (s.compensation != Compensation::kOff && !same_bits(s.compensation_radius_mm, prev_comp_radius_)) {
    flags |= kHasCompRadius;
  }
  std::uint16_t mask = 0;
  for (int i = 0; i < n_; ++i) {
    const auto a = static_cast<std::size_t>(i);
    if (!same_bits(s.end[a], prev_end_[a])) mask = static_cast<std::uint16_t>(mask | (1u << i));
  }
  w(static_cast<std::uint8_t>(s.type));
  w(flags);
  w(mask);
  if (flags & kHasModes) w(modes);
  if (flags & kHasTool) w(s.tool);
  if (flags & kHasLine) w(s.line);
  for (int i = 0; i < n_; ++i) {
    if (mask & (1u << i)) w(s.end[static_cast<std::size_t>(i)]);
  }
  if (flags & kHasCompRadius) w(s.compensation_radius_mm);
  if (flags & kHasFeed) w(s.feed_mm_per_min);
  if (s.is_arc()) {
    w(s.center[0]);
    w(s.center[1]);
    w(s.radius);
    w(s.turns);
  }
  if (s.type == SegmentType::kDwell) w(s.dwell_s);
  if (s.type == SegmentType::kMFunction) {
    w(s.m);
    w(s.aux);
  }
  if (s.type == SegmentType::kMessage) w(s.aux);
  out_.append(buf, k);
  crc_ = crc_update(crc_, buf, k);
  prev_modes_ = modes;
  prev_tool_ = s.tool;
  prev_line_ = s.line;
  prev_end_ = s.end;
  if (s.is_motion()) prev_feed_ = s.feed_mm_per_min;
  if (s.compensation != Compensation::kOff) prev_comp_radius_ = s.compensation_radius_mm;
}

void IntercodeEncoder::finish(const std::vector<MParams>& params,
                              const std::vector<std::string>& messages) {
  if (!streaming_) std::memcpy(out_.data() + count_offset_, &count_, sizeof count_);
  const std::size_t tables = out_.size();
  put<std::uint32_t>(out_, static_cast<std::uint32_t>(params.size()));
  put<std::uint32_t>(out_, static_cast<std::uint32_t>(messages.size()));
  for (const MParams& mp : params) {
    for (double v : mp) put<double>(out_, v);
  }
  for (const std::string& m : messages) {
    put<std::uint32_t>(out_, static_cast<std::uint32_t>(m.size()));
    out_ += m;
  }
  std::uint32_t c = crc_update(crc_, out_.data() + tables, out_.size() - tables);
  char count[sizeof count_];
  std::memcpy(count, &count_, sizeof count_);
  c = ~crc_update(c, count, sizeof count);
  put<std::uint32_t>(out_, c);
}

void encode_intercode(const Program& p, std::string& out) {
  out.reserve(out.size() + 64 + p.segments.size() * (20 + 8 * static_cast<std::size_t>(p.number_axes) + 8));
  IntercodeEncoder enc(out, p.number_axes, p.axis_letters, p.start_mm);
  for (const Segment& s : p.segments) enc.add(s);
  enc.finish(p.params, p.messages);
}

// The values a record's delta fields apply to, as the encoder starts them.
struct PackedProgram::Cursor::State {
  std::array<double, kMaxAxes> end{};
  std::int32_t line = 0;
  std::int32_t tool = 0;
  double feed = 0.0;
  double comp_radius = 0.0;
  std::uint8_t modes = pack_modes(Segment{});
};

namespace {

using DeltaState = PackedProgram::Cursor::State;

// Why a record does not decode; its text (fault_text) is made only on failure.
enum class RecordFault : std::uint8_t {
  kNone,
  kTruncated,
  kUnknownType,
  kUnknownFlags,
  kAxisBeyond,
  kBadModes,
  kLineOverflow,
  kNonFinite,
  kOutOfRange,
  kMKind
};

std::string fault_text(RecordFault f, std::uint8_t type, int n, std::uint64_t k) {
  const std::string rec = "record " + std::to_string(k);
  switch (f) {
    case RecordFault::kNone:
      return {};
    case RecordFault::kTruncated:
      return "truncated " + rec;
    case RecordFault::kUnknownType:
      return "unknown record type " + std::to_string(type);
    case RecordFault::kUnknownFlags:
      return "unknown flags in " + rec;
    case RecordFault::kAxisBeyond:
      return "axis mask names an axis beyond " + std::to_string(n) + " in " + rec;
    case RecordFault::kBadModes:
      return "bad modes in " + rec;
    case RecordFault::kLineOverflow:
      return "line number overflows in " + rec;
    case RecordFault::kNonFinite:
      return "non-finite coordinate in " + rec;
    case RecordFault::kOutOfRange:
      return "value out of range in " + rec;
    case RecordFault::kMKind:
      return "M-function kind does not match its number in " + rec +
             " (M0 pauses, M2 and M30 end, M1..M999 wait, M1001.. run on)";
  }
  return "bad " + rec;
}

// Decodes the next record from `in` into `s` and moves `st` on; `type` gets the record's type
// byte (for the fault's text). `n`: the header's axis count.
RecordFault decode_fields(In& in, int n, DeltaState& st, Segment& s, std::uint8_t& type) {
  // Every field is set below; those a record may not carry get their defaults here. `s =
  // Segment{}` compiled to a `rep stos`, whose start-up was a third of a record's decoding.
  static_assert(sizeof(Segment) == 152, "a field added to Segment needs its default here");
  s.m = -1;
  s.turns = 0;
  s.aux = -1;
  s.center = {0.0, 0.0};
  s.radius = 0.0;
  s.dwell_s = 0.0;
  s.line = 0;
  std::uint8_t flags = 0;
  std::uint16_t mask = 0;
  if (!in.get(type) || !in.get(flags) || !in.get(mask)) return RecordFault::kTruncated;
  if (type > 6) return RecordFault::kUnknownType;
  if (flags & ~kKnownFlags) return RecordFault::kUnknownFlags;
  if (mask >> n) return RecordFault::kAxisBeyond;
  s.type = static_cast<SegmentType>(type);
  if ((flags & kHasModes) && !in.get(st.modes)) return RecordFault::kTruncated;
  const int plane = 17 + (st.modes & 3), comp = 40 + ((st.modes >> 2) & 3), mkind = st.modes >> 4;
  if (plane > 19 || comp > 42 || mkind > 4) return RecordFault::kBadModes;
  s.plane = static_cast<Plane>(plane);
  s.compensation = static_cast<Compensation>(comp);
  s.m_kind = static_cast<MKind>(mkind);
  s.tool = st.tool;
  if ((flags & kHasTool) && !in.get(s.tool)) return RecordFault::kTruncated;
  if (flags & kHasLine) {
    if (!in.get(s.line)) return RecordFault::kTruncated;
  } else if (st.line == std::numeric_limits<std::int32_t>::max()) {
    return RecordFault::kLineOverflow;
  } else {
    s.line = st.line + 1;
  }
  s.end = st.end;
  for (int i = 0; i < n; ++i) {
    if (!(mask & (1u << i))) continue;
    double& v = s.end[static_cast<std::size_t>(i)];
    if (!in.get(v)) return RecordFault::kTruncated;
    if (!std::isfinite(v)) return RecordFault::kNonFinite;
  }
  bool ok = true;
  if (flags & kHasCompRadius) ok = ok && in.get(st.comp_radius);
  if (flags & kHasFeed) ok = ok && in.get(st.feed);
  s.compensation_radius_mm = s.compensation != Compensation::kOff ? st.comp_radius : 0.0;
  s.feed_mm_per_min = s.is_motion() ? st.feed : 0.0;
  if (s.is_arc()) {
    ok = ok && in.get(s.center[0]) && in.get(s.center[1]) && in.get(s.radius) && in.get(s.turns);
  }
  if (s.type == SegmentType::kDwell) ok = ok && in.get(s.dwell_s);
  if (s.type == SegmentType::kMFunction) ok = ok && in.get(s.m) && in.get(s.aux);
  if (s.type == SegmentType::kMessage) ok = ok && in.get(s.aux);
  if (!ok) return RecordFault::kTruncated;
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(s.compensation_radius_mm) || !finite(s.feed_mm_per_min) || !finite(s.center[0]) ||
      !finite(s.center[1]) || !finite(s.radius) || !finite(s.dwell_s) || s.feed_mm_per_min < 0 ||
      s.radius < 0 || s.dwell_s < 0 || s.turns < 0 || s.turns > kMaxArcTurns ||
      s.compensation_radius_mm < 0 || s.tool < 0 || s.tool > kMaxTool || s.line < 0) {
    return RecordFault::kOutOfRange;
  }
  // A kind the compiler never gives its number: M51 written as a program end ended the
  // program there without a word (session 75). M0, M2 and M30 redefined for the PLC are
  // normal M-functions.
  if (s.type == SegmentType::kMFunction) {
    const bool fits = s.m_kind == MKind::kProgramStop  ? s.m == 0
                      : s.m_kind == MKind::kProgramEnd ? s.m == 2 || s.m == 30
                      : s.m_kind == MKind::kContinuous ? s.m > kMaxNormalM + 1
                      : s.m_kind == MKind::kNormal     ? s.m >= 0 && s.m <= kMaxNormalM
                                                       : false;
    if (!fits) return RecordFault::kMKind;
  }
  st.end = s.end;
  st.line = s.line;
  st.tool = s.tool;
  return RecordFault::kNone;
}

// The header of `file`, checked (magic, version, checksum, axis count, record count, start
// point): `tables` gets the axis count, letters and start point, `count` the record count,
// `body` the file without its checksum and `records_at` where the records begin in it.
bool read_header(std::string_view file, Program& tables, std::uint64_t& count,
                 std::string_view& body, std::size_t& records_at, std::string& error) {
  body = file;
  In in(body);
  auto fail = [&](const std::string& why) {
    error = "intercode at byte " + std::to_string(in.pos()) + ": " + why;
    return false;
  };
  std::string magic;
  if (file.empty()) {
    error = "intercode at byte 0: the file is empty";
    return false;
  }
  if (!in.bytes(4, magic) || std::memcmp(magic.data(), kMagic, 4) != 0) {
    const bool text = std::all_of(file.begin(), file.begin() + std::min<std::size_t>(file.size(), 4),
                                  [](char c) {
                                    const auto u = static_cast<unsigned char>(c);
                                    return (u >= 0x20 && u < 0x7f) || u == '\n' || u == '\r' || u == '\t';
                                  });
    error = std::string("intercode at byte 0: not a tgm intercode file (bad magic") +
            (text ? "; it starts as text: G-code under an intercode name?)" : ")");
    return false;
  }
  std::uint16_t version = 0;
  std::uint8_t n = 0;
  if (!in.get(version)) return fail("truncated header");
  if (version == kVersion || version == kVersionWithoutStart) {
    // The checksum first: a damaged file must not be read as another program.
    if (file.size() < kHeaderBytes + 4) return fail("truncated header");
    std::uint32_t stored = 0;
    std::memcpy(&stored, file.data() + file.size() - 4, sizeof stored);
    if (const std::uint32_t c = file_checksum(file); c != stored) {
      char why[160];
      std::snprintf(why, sizeof why,
                    "checksum mismatch: the file is damaged, cut short or was changed (CRC-32 "
                    "%08x, the file says %08x); compile the program again",
                    static_cast<unsigned>(c), static_cast<unsigned>(stored));
      error = why;
      return false;
    }
    body = file.substr(0, file.size() - 4);
    in = In(body);
    in.skip(6);
  } else if (version != kVersionWithoutChecksum) {
    return fail("unsupported version " + std::to_string(version) + " (this build reads 2 to 4)");
  }
  if (!in.get(n) || n < 1 || n > kMaxAxes) return fail("axis count must be 1..10");
  std::string letters;
  if (!in.bytes(kMaxAxes, letters)) return fail("truncated header");
  if (!in.get(count)) return fail("truncated header");
  // Each record takes at least 4 bytes: reject counts the input cannot hold.
  if (count > body.size() / 4) return fail("record count exceeds the file size");
  // Letters as a config gives them (one upper-case letter per axis, each once): control
  // characters and quotes went into the JSON dump and the error messages as they were.
  for (int i = 0; i < n; ++i) {
    const char c = letters[static_cast<std::size_t>(i)];
    if (c < 'A' || c > 'Z' || letters.find(c) < static_cast<std::size_t>(i)) {
      return fail(std::string("axis letters must be distinct letters A..Z, not '") +
                  printable(letters.substr(0, n)) + "'");
    }
  }
  tables = Program{};
  tables.number_axes = n;
  tables.axis_letters = letters.substr(0, n);
  if (version == kVersion) {
    for (int i = 0; i < n; ++i) {
      double& v = tables.start_mm[static_cast<std::size_t>(i)];
      if (!in.get(v)) return fail("truncated header");
      if (!std::isfinite(v)) return fail("non-finite start point");
    }
  }
  records_at = in.pos();
  return true;
}

// Where a checked file's records lie.
struct RecordsLayout {
  std::uint64_t count = 0;
  std::size_t records_at = 0;  // byte offset of the first record
  std::size_t body_size = 0;   // the file without its checksum
};

// Checks `file` whole, as decode_intercode promises; the records go into `out.segments` when
// `keep`, else only the header and the side tables are kept. `layout` (when given) says where
// the records lie.
bool decode_checked(std::string_view file, Program& out, std::string& error, bool keep,
                    RecordsLayout* layout = nullptr,
                    const std::function<void(const Segment&)>* observe = nullptr) {
  Program p;
  std::uint64_t count = 0;
  std::string_view bytes;
  std::size_t records_at = 0;
  if (!read_header(file, p, count, bytes, records_at, error)) return false;
  if (layout) *layout = {count, records_at, bytes.size()};
  In in(bytes);
  in.skip(records_at);
  auto fail = [&](const std::string& why) {
    error = "intercode at byte " + std::to_string(in.pos()) + ": " + why;
    return false;
  };
  // The M and message records, whose side-table indices are checked once the tables are read.
  struct Indexed {
    SegmentType type;
    std::int32_t line;
    std::int32_t aux;
  };
  std::vector<Indexed> indexed;
  if (keep) p.segments.resize(count);
  DeltaState st;
  Segment scratch;
  for (std::uint64_t k = 0; k < count; ++k) {
    Segment& s = keep ? p.segments[k] : scratch;
    std::uint8_t type = 0;
    if (const RecordFault f = decode_fields(in, p.number_axes, st, s, type);
        f != RecordFault::kNone)
      return fail(fault_text(f, type, p.number_axes, k));
    if (observe) (*observe)(s);
    if (s.type == SegmentType::kMFunction || s.type == SegmentType::kMessage) {
      indexed.push_back({s.type, s.line, s.aux});
    }
  }
  std::uint32_t nparams = 0, nmsg = 0;
  if (!in.get(nparams) || !in.get(nmsg)) return fail("truncated table counts");
  if (nparams > bytes.size() / (8u * kParamLetters) + 1) return fail("bad parameter count");
  if (nmsg > bytes.size() / 4 + 1) return fail("bad message count");
  for (const Indexed& s : indexed) {
    if (s.type == SegmentType::kMFunction && (s.aux < 0 || s.aux >= static_cast<int>(nparams))) {
      return fail("an M record at line " + std::to_string(s.line) +
                  " names a missing parameter set");
    }
    if (s.type == SegmentType::kMessage && (s.aux < 0 || s.aux >= static_cast<int>(nmsg))) {
      return fail("a message record at line " + std::to_string(s.line) + " names a missing text");
    }
  }
  p.params.resize(nparams);
  for (auto& mp : p.params) {
    for (double& v : mp) {
      if (!in.get(v)) return fail("truncated parameter table");
      if (!std::isfinite(v)) return fail("a parameter that is not a finite number");
    }
  }
  p.messages.resize(nmsg);
  for (auto& m : p.messages) {
    std::uint32_t len = 0;
    if (!in.get(len) || !in.bytes(len, m)) return fail("truncated message table");
    if (m.size() > kMaxMessageBytes) {
      return fail("a message is longer than " + std::to_string(kMaxMessageBytes) + " bytes");
    }
    if (utf8_invalid_at(m) != std::string_view::npos) return fail("a message that is not UTF-8 text");
    if (control_char_at(m) != std::string_view::npos) {
      return fail("a message with a control character");
    }
  }
  if (!in.at_end()) return fail("trailing bytes after the message table");
  out = std::move(p);
  return true;
}

}  // namespace

bool decode_intercode(std::string_view file, Program& out, std::string& error) {
  return decode_checked(file, out, error, true);
}

bool PackedProgram::open(std::string file, PackedProgram& out, std::string& error,
                         const std::function<void(const Segment&)>& observe) {
  PackedProgram p;
  RecordsLayout layout;
  if (!decode_checked(file, p.tables_, error, false, &layout, observe ? &observe : nullptr))
    return false;
  p.count_ = layout.count;
  p.records_at_ = layout.records_at;
  p.body_size_ = layout.body_size;
  p.file_ = std::move(file);
  out = std::move(p);
  return true;
}

bool PackedProgram::from_program(const Program& program, PackedProgram& out, std::string& error) {
  std::string file;
  encode_intercode(program, file);
  return open(std::move(file), out, error);
}

bool PackedProgram::Cursor::next(Segment& s) {
  if (program_ == nullptr || read_ >= program_->count_) return false;
  In in(std::string_view(program_->file_).substr(0, program_->body_size_));
  in.skip(at_);
  // Checked when the program was opened: this cannot fail.
  std::uint8_t type = 0;
  if (decode_fields(in, program_->tables_.number_axes, *state_, s, type) != RecordFault::kNone)
    return false;
  at_ = in.pos();
  ++read_;
  return true;
}

const Program& PackedProgram::Window::from(std::uint64_t first, std::uint64_t count) {
  // The records behind `first` are done with: dropped at each call, so that only records asked
  // for and not yet taken (an append the ring refused in part) are moved to the front. (Reading
  // ahead 512 records and dropping the ones behind once they were half of what was held moved
  // every record once more: 10 % of simulating a 628,000-record .tgmi, in memmove.)
  std::vector<Segment>& held = records_.segments;
  const auto behind = static_cast<std::size_t>(std::min<std::uint64_t>(first - base_, held.size()));
  held.erase(held.begin(), held.begin() + static_cast<std::ptrdiff_t>(behind));
  base_ += behind;
  // Decoded in place, from base_ (records skipped over are decoded too: the cursor only reads
  // forward).
  const std::uint64_t need = first - base_ + count;
  while (held.size() < need) {
    held.emplace_back();
    if (!cursor_.next(held.back())) {
      held.pop_back();
      break;
    }
  }
  return records_;
}

PackedProgram::Cursor::Cursor(const PackedProgram& p)
    : program_(&p), state_(std::make_unique<State>()), at_(p.records_at_) {}
PackedProgram::Cursor::~Cursor() = default;
PackedProgram::Cursor::Cursor(Cursor&&) noexcept = default;
PackedProgram::Cursor& PackedProgram::Cursor::operator=(Cursor&&) noexcept = default;

void dump_jsonl_record(const Program& p, const Segment& s, std::string& out) {
  const int n = p.number_axes;
  auto letter = [&](int i) { return axis_letter(p, i); };
  out += "{\"line\":";
  out += std::to_string(s.line);
  out += ",\"type\":\"";
  out += segment_type_name(s.type);
  out += "\",\"end\":{";
  for (int i = 0; i < n; ++i) {
    if (i) out.push_back(',');
    out += '"';
    out += letter(i);
    out += "\":";
    num(out, s.end[static_cast<std::size_t>(i)]);
  }
  out += '}';
  if (s.is_motion()) {
    out += ",\"feed_mm_per_min\":";
    num(out, s.feed_mm_per_min);
    out += ",\"plane\":";
    out += std::to_string(static_cast<int>(s.plane));
  }
  if (s.is_arc()) {
    const PlaneAxes pa = plane_axes(s.plane, p.axis_letters);
    out += ",\"center\":{";
    const int a0 = pa.first < n ? pa.first : -1;
    const int a1 = pa.second < n ? pa.second : -1;
    bool first = true;
    for (int k = 0; k < 2; ++k) {
      const int ax = k == 0 ? a0 : a1;
      if (ax < 0) continue;
      if (!first) out.push_back(',');
      first = false;
      out += '"';
      out += letter(ax);
      out += "\":";
      num(out, s.center[static_cast<std::size_t>(k)]);
    }
    out += "},\"radius\":";
    num(out, s.radius);
    out += ",\"turns\":";
    out += std::to_string(s.turns);
  }
  if (s.type == SegmentType::kDwell) {
    out += ",\"seconds\":";
    num(out, s.dwell_s);
  }
  if (s.type == SegmentType::kMFunction) {
    out += ",\"m\":";
    out += std::to_string(s.m);
    out += ",\"kind\":\"";
    out += m_kind_name(s.m_kind);
    out += "\",\"params\":{";
    if (const MParams* params = params_of(p, s)) {
      bool first = true;
      const MParams& mp = *params;
      for (int k = 0; k < kParamLetters; ++k) {
        if (is_not_set(mp[static_cast<std::size_t>(k)])) continue;
        if (!first) out.push_back(',');
        first = false;
        out += '"';
        out += static_cast<char>('A' + k);
        out += "\":";
        num(out, mp[static_cast<std::size_t>(k)]);
      }
    }
    out += '}';
  }
  if (s.type == SegmentType::kMessage) {
    out += ",\"text\":";
    append_json_string(out, message_of(p, s));
  }
  out += ",\"tool\":";
  out += std::to_string(s.tool);
  if (s.compensation != Compensation::kOff) {
    out += ",\"compensation\":\"G";
    out += std::to_string(static_cast<int>(s.compensation));
    out += "\",\"compensation_radius_mm\":";
    num(out, s.compensation_radius_mm);
  }
  out += "}\n";
}

void dump_jsonl(const Program& p, std::string& out) {
  for (const Segment& s : p.segments) dump_jsonl_record(p, s, out);
}

void dump_text_record(const Program& p, const Segment& s, std::string& out) {
  const int n = p.number_axes;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%6d  %-3s", s.line,
                std::string(segment_type_name(s.type)).c_str());
  out += buf;
  if (s.type == SegmentType::kMFunction) {
    std::snprintf(buf, sizeof buf, " M%d (%s)", s.m, std::string(m_kind_name(s.m_kind)).c_str());
    out += buf;
    if (const MParams* params = params_of(p, s)) {
      const MParams& mp = *params;
      for (int k = 0; k < kParamLetters; ++k) {
        if (is_not_set(mp[static_cast<std::size_t>(k)])) continue;
        std::snprintf(buf, sizeof buf, " %c%.6g", 'A' + k, mp[static_cast<std::size_t>(k)]);
        out += buf;
      }
    }
  } else if (s.type == SegmentType::kMessage) {
    out += " \"";
    out += printable(message_of(p, s));
    out += '"';
  } else if (s.type == SegmentType::kDwell) {
    std::snprintf(buf, sizeof buf, " %.6g s", s.dwell_s);
    out += buf;
  } else {
    for (int i = 0; i < n; ++i) {
      std::snprintf(buf, sizeof buf, " %c%.4f", axis_letter(p, i),
                    s.end[static_cast<std::size_t>(i)]);
      out += buf;
    }
    if (s.is_arc()) {
      // Named by the plane's axes, as the jsonl dump names them: "centre(-1, 5)" of a G18 arc
      // (Z first) read as X-1 (session 75).
      const PlaneAxes pa = plane_axes(s.plane, p.axis_letters);
      out += "  centre(";
      for (int k = 0; k < 2; ++k) {
        const int ax = k == 0 ? pa.first : pa.second;
        std::snprintf(buf, sizeof buf, "%s%c%.4f", k == 0 ? "" : " ",
                      ax < n ? axis_letter(p, ax) : '?', s.center[static_cast<std::size_t>(k)]);
        out += buf;
      }
      std::snprintf(buf, sizeof buf, ") R%.4f G%d", s.radius, static_cast<int>(s.plane));
      out += buf;
      if (s.turns) out += " turns+" + std::to_string(s.turns);
    }
    if (s.type != SegmentType::kRapid) {
      std::snprintf(buf, sizeof buf, "  F%.6g", s.feed_mm_per_min);
      out += buf;
    }
  }
  out += '\n';
}

void dump_text(const Program& p, std::string& out) {
  for (const Segment& s : p.segments) dump_text_record(p, s, out);
}

}  // namespace tgm
