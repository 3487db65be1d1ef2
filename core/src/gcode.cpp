// G-code compiler: the dialect of core/GCODE.md (DESIGN.md section 4, made precise).
//
// Two passes over the text:
//  1. Lexing and the checks that need no modal state: every line becomes a block of words
//     (letter, value, column); unknown characters, words and numbers, repeated or conflicting
//     words, missing required words and labels are reported for every line, including
//     subroutines that are never called.
//  2. Execution: the blocks run with the modal state and a call stack, subroutines, cycles and
//     jumps are expanded, and every motion, dwell, M-function and message becomes one intercode
//     record with absolute machine coordinates.
// Errors never stop a pass early (up to kMaxErrors); a program with any error yields no records.
// A binary file (a 0x00 byte anywhere) gets one error and no pass.
#include "tgm/gcode.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <unordered_map>

#include "cutter_compensation.hpp"
#include "tgm/intercode_io.hpp"
#include "tgm/printable.hpp"
#include "tgm/soft_limits.hpp"

namespace tgm {

namespace {

constexpr std::size_t kMaxErrors = 10000;
//! Largest magnitude of any number in a program.
constexpr double kMaxValue = kMaxCoordinateMm;
//! Largest feed [mm/min].
constexpr double kMaxFeed = kMaxFeedMmPerMin;
//! Largest dwell [s].
constexpr double kMaxDwell = 1.0e5;
//! Largest M-number.
constexpr int kMaxM = 999999;
//! Largest repeat count of G26/G27.
constexpr double kMaxRepeat = 1.0e9;

constexpr std::uint32_t bit(char letter) { return 1u << (letter - 'A'); }

std::string fmt_num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

//! A code point an editor does not show: C0 and C1 controls, spaces and marks of no width, a
//! byte-order mark inside the text. Named by its number in messages, never printed.
bool invisible_code_point(unsigned cp) {
  return cp <= 0x9F || cp == 0xA0 || cp == 0xAD || cp == 0xFEFF || (cp >= 0x2000 && cp <= 0x200F) ||
         (cp >= 0x2028 && cp <= 0x202F) || (cp >= 0x205F && cp <= 0x206F);
}

//! Source text quoted in a message: printable ASCII and visible UTF-8 characters as they are
//! (an 'ä' reads as in the editor, as in "unexpected character"), every other byte as \xNN,
//! so a binary or mis-encoded file cannot put control codes or broken UTF-8 into the terminal
//! or the log.
std::string quoted_source(std::string_view text) {
  // A word of a hundred thousand digits is quoted by its start and its length, not whole.
  constexpr std::size_t kMaxQuoted = 40;
  const std::size_t full = text.size();
  if (full > kMaxQuoted) text = text.substr(0, kMaxQuoted);
  std::string out;
  out.reserve(text.size() + 32);
  for (std::size_t i = 0; i < text.size();) {
    const auto uc = static_cast<unsigned char>(text[i]);
    if (uc >= 0x20 && uc < 0x7f) {
      out += text[i++];
      continue;
    }
    if (const std::size_t n = utf8_sequence_length(text.substr(i));
        n > 1 && !invisible_code_point(utf8_code_point(text.substr(i, n)))) {
      out += text.substr(i, n);
      i += n;
      continue;
    }
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\x%02X", uc);
    out += buf;
    ++i;
  }
  if (full > kMaxQuoted) out += "... (" + std::to_string(full) + " characters)";
  return out;
}

std::string fmt_mm(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

// ---------------------------------------------------------------------------------------------
// Pass 1: lexing
// ---------------------------------------------------------------------------------------------

struct Word {
  char letter;
  std::uint32_t column;
  double value;
};

// The G-codes of the dialect, with their modal group.
enum class GGroup : std::uint8_t { kNone, kMotion, kPlane, kDistance, kComp, kNonModal, kUnits };

GGroup g_group(int g) {
  switch (g) {
    case 0: case 1: case 2: case 3: return GGroup::kMotion;
    case 17: case 18: case 19: return GGroup::kPlane;
    case 90: case 91: return GGroup::kDistance;
    case 40: case 41: case 42: return GGroup::kComp;
    case 4: case 25: case 26: case 27: case 29: case 53: case 54: case 92: return GGroup::kNonModal;
    case 21: return GGroup::kUnits;
    default: return GGroup::kNone;
  }
}

// A line after lexing. Words live in a shared vector.
// What pass 1 keeps of a line: its span in the source (pass 2 lexes it again instead of keeping
// every word, which keeps a million-line program small in memory).
struct LineRef {
  std::uint32_t begin = 0;
  std::uint32_t end = 0;
  std::int32_t line = 0;
  bool valid = true;  //!< false when pass 1 found an error: pass 2 skips it
};

// A line being looked at: its words are in Compiler::words_.
struct Block {
  std::int32_t line = 0;
  std::uint32_t begin = 0;
  std::uint32_t end = 0;
  std::uint16_t word_count = 0;
  bool valid = true;  //!< false when pass 1 found an error: pass 2 skips it
  //! First comment of the line (M29 text, G29 note), as offset/length into the source.
  std::uint32_t comment_offset = 0;
  std::uint32_t comment_length = 0;
  bool has_comment = false;
  //! Letters present on the line, bit k = 'A' + k (G and M excluded).
  std::uint32_t letters = 0;
};

class Compiler {
 public:
  Compiler(std::string_view src, const CompileOptions& opt, const SegmentSink* sink)
      : src_(src), opt_(opt), sink_(sink) {}

  CompileResult run();

 private:
  // --- diagnostics
  void error(int line, std::uint32_t column, std::string reason) {
    if (!reporting_) return;
    // A line that runs again (a loop, a subroutine called K times) reports its error once, with
    // a count: an end point beyond the bound in each of 100,000 passes was 10,000 lines.
    const std::uint64_t place =
        (static_cast<std::uint64_t>(static_cast<std::uint32_t>(line)) << 32) | column;
    if (running_ != 0) {
      if (const auto it = run_errors_.find(place);
          it != run_errors_.end() && error_run_[it->second] != running_) {
        ++error_repeats_[it->second];
        return;
      }
    }
    if (errors_.size() >= kMaxErrors) {
      ++suppressed_;
      return;
    }
    if (running_ != 0) run_errors_.try_emplace(place, errors_.size());
    errors_.push_back({line, static_cast<int>(column), std::move(reason)});
    error_run_.push_back(running_);
    error_repeats_.push_back(0);
  }

  // Turns the byte columns of errors_ (sorted by line) into character columns, as editors
  // count them: an error after an 'ä' on its line was one column further right than shown.
  // One pass over the source, with lex()'s line ends; a byte that is not UTF-8 is one column.
  void to_character_columns();

  // Where the text starts (after a UTF-8 byte-order mark), and the end of the line that
  // starts at `begin`: at its line feed, or at a carriage return that no line feed follows.
  std::size_t text_begin() const;
  std::size_t line_end(std::size_t begin) const;

  // --- pass 1
  void lex();
  void lex_line(std::size_t begin, std::size_t end, std::int32_t line);
  // Fills words_ (cleared first) and the comment of `b` from the text span of `b`.
  bool lex_words(Block& b);
  bool parse_number(std::size_t& i, std::size_t end, double& out);
  void check_block_static(Block& b);

  // --- pass 2
  void execute();
  // Returns the index of the next block to execute.
  std::size_t execute_block(std::size_t index, bool relex);
  // execute_block with the endless-loop guard, numbered for error().
  std::size_t step(std::size_t index, bool relex);
  std::size_t step_once(std::size_t index, bool relex);

  // Helpers of pass 2.
  bool emit_check(const Block& b);
  std::string too_big_reason() const {
    return "program expands to more than " + std::to_string(opt_.compiler.max_program_segments) +
           " segments (compiler.max_program_segments)";
  }
  // Records go through tool radius compensation while it is on or still holds records.
  void emit(const Segment& s) {
    if (s.compensation_radius_mm > 0 || !comp_stage_.idle()) {
      comp_stage_.push(s, pos_);
    } else {
      out(s);
    }
  }
  void out(const Segment& s) {
    // emit_check() counts what left the compensation, which may still hold a few records and
    // add corner arcs: the limit is kept here (7 records came out under a limit of 6).
    if (emitted_ >= opt_.compiler.max_program_segments) {
      if (!too_big_) error(s.line, 1, too_big_reason());
      too_big_ = true;
      ended_ = true;
      return;
    }
    ++emitted_;
    if (s.is_motion()) {
      // Every record, those cutter compensation makes among them, from where the one before
      // it ended.
      if (!opt_.machine_axes.axes.empty()) {
        if (std::string why = soft_limit_problem(s, out_pos_.data(), opt_.machine_axes);
            !why.empty()) {
          error(s.line, 1, why);
        }
      }
      out_pos_ = s.end;
    }
    if (sink_) {
      (*sink_)(s);
    } else {
      program_.segments.push_back(s);
    }
  }
  Segment base_segment(const Block& b) const;
  //! True when exactly one axis of the active plane is mirrored: G41 and G42 swap sides.
  bool plane_mirrored_once() const {
    const PlaneAxes pa = plane_axes(plane_, opt_.axis_letters);
    const double m0 = pa.first < kMaxAxes ? mirror_[static_cast<std::size_t>(pa.first)] : 1.0;
    const double m1 = pa.second < kMaxAxes ? mirror_[static_cast<std::size_t>(pa.second)] : 1.0;
    return m0 * m1 < 0;
  }
  int axis_index(char letter) const {
    return (letter >= 'A' && letter <= 'Z') ? axis_of_letter_[letter - 'A'] : -1;
  }

  std::string_view src_;
  const CompileOptions& opt_;
  const SegmentSink* sink_;
  std::int64_t emitted_ = 0;
  std::array<double, kMaxAxes> out_pos_ = opt_.start_mm;  // where the last record put out ends
  std::vector<Diagnostic> errors_;
  std::size_t suppressed_ = 0;
  //! Per entry of errors_: the step() that reported it (0: pass 1) and how often a later
  //! step() reported an error at its place again.
  std::vector<std::uint64_t> error_run_;
  std::vector<std::uint64_t> error_repeats_;
  //! (line, column) -> entry of errors_, for the errors of step().
  std::unordered_map<std::uint64_t, std::size_t> run_errors_;
  std::uint64_t steps_ = 0;    //!< step() calls so far
  std::uint64_t running_ = 0;  //!< the step() running (its number), 0 outside step()

  bool reporting_ = true;  //!< false while pass 2 lexes a line again
  bool in_order_ = true;   //!< still executing each line as it is lexed
  std::size_t resume_ = 0;  //!< first block execute() runs
  std::uint64_t max_executed_ = 0;
  //! The line lexed last, whose words are still in words_ (for in-order execution).
  Block cur_block_;
  std::vector<Word> words_;  //!< words of the line being looked at
  std::vector<LineRef> blocks_;
  std::unordered_map<long long, std::size_t> labels_;  // label -> block index
  //! G25 / G26 / G27 of pass 1, checked against the labels once every line is lexed.
  struct LabelRef {
    std::size_t block;
    std::int32_t line;
    std::uint32_t column;
    long long label;
    bool jump_without_k;  //!< G27 without K: must jump forward
  };
  std::vector<LabelRef> label_refs_;
  std::uint32_t axis_mask_ = 0;                        // letters that are axes
  std::array<int, 26> axis_of_letter_{};
  int n_axes_ = 0;
  std::vector<bool> redefined_;  // M-number -> handled by the PLC

  // --- modal state of pass 2
  struct Frame {
    std::size_t return_block;  //!< block to continue with after M17
    std::size_t call_block;    //!< the G25/G26 block (for messages)
    std::size_t sub_block;     //!< first block of the subroutine (the label)
    long long remaining;       //!< further G26 repetitions
  };
  std::vector<Frame> stack_;
  //! Per G27 block with K: jumps still to take; absent when not active.
  std::unordered_map<std::size_t, long long> jump_count_;
  Program program_;
  //! Side-table entries by content: records with equal parameters or equal texts share one
  //! (a G26 loop of `M1005 A1` took 208 bytes per pass in memory and in the intercode file,
  //! 3.9 GB to compile 9 million of them).
  struct ParamsHash {
    std::size_t operator()(const MParams& p) const {
      std::uint64_t h = 1469598103934665603ull;
      for (double v : p) {
        std::uint64_t bits = 0;
        std::memcpy(&bits, &v, sizeof bits);
        h = (h ^ bits) * 1099511628211ull;
      }
      return static_cast<std::size_t>(h ^ (h >> 29));
    }
  };
  struct ParamsEqual {
    bool operator()(const MParams& a, const MParams& b) const {
      return std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
    }
  };
  std::unordered_map<MParams, std::int32_t, ParamsHash, ParamsEqual> params_index_;
  std::unordered_map<std::string, std::int32_t> message_index_;
  std::int32_t intern_params(const MParams& p) {
    const auto [it, added] =
        params_index_.try_emplace(p, static_cast<std::int32_t>(program_.params.size()));
    if (added) program_.params.push_back(p);
    return it->second;
  }
  std::int32_t intern_message(std::string_view text) {
    const auto [it, added] = message_index_.try_emplace(
        std::string(text), static_cast<std::int32_t>(program_.messages.size()));
    if (added) program_.messages.emplace_back(text);
    return it->second;
  }
  std::array<double, kMaxAxes> pos_{};      //!< machine position [mm]
  std::array<double, kMaxAxes> shift_{};    //!< G54 zero-point shift
  std::array<double, kMaxAxes> g92_{};      //!< G92 offset
  std::array<double, kMaxAxes> mirror_{};   //!< +1 or -1 per axis
  int motion_ = -1;                          //!< modal motion G-code, -1 before the first
  bool incremental_ = true;
  Plane plane_ = Plane::kXY;
  Compensation comp_ = Compensation::kOff;
  double comp_radius_ = 0.0;
  double feed_ = 0.0;           //!< modal F, 0 when none is active
  double default_feed_ = 0.0;   //!< M99 / config
  int tool_ = 0;
  detail::CutterCompensation comp_stage_{
      opt_.axis_letters, [this](const Segment& s) { out(s); },
      [this](int line, std::string reason) { error(line, 1, std::move(reason)); }};
  bool ended_ = false;
  bool too_big_ = false;
  std::uint64_t executed_ = 0;
};

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Parses [+-] digits [. digits] with blanks allowed between the characters. Exact for up to 19
// significant digits and 22 decimals (one correctly rounded division); longer numbers go
// through strtod.
bool Compiler::parse_number(std::size_t& i, std::size_t end, double& out) {
  auto skip = [&] {
    while (i < end && (src_[i] == ' ' || src_[i] == '\t')) ++i;
  };
  skip();
  bool neg = false;
  if (i < end && (src_[i] == '+' || src_[i] == '-')) {
    neg = src_[i] == '-';
    ++i;
    skip();
  }
  std::uint64_t mant = 0;
  int digits = 0;       // significant digits kept in mant
  int frac = 0;         // decimals kept in mant
  bool any = false, dot = false, long_form = false;
  char buf[128];
  std::size_t blen = 0;
  while (i < end) {
    const char c = src_[i];
    if (is_digit(c)) {
      any = true;
      if (blen < sizeof buf - 1) buf[blen++] = c;
      if (digits < 19) {
        if (mant != 0 || c != '0') ++digits;
        mant = mant * 10 + static_cast<std::uint64_t>(c - '0');
        if (dot) ++frac;
      } else {
        long_form = true;
      }
      ++i;
    } else if (c == '.' && !dot) {
      dot = true;
      if (blen < sizeof buf - 1) buf[blen++] = c;
      ++i;
    } else if (c == ' ' || c == '\t') {
      // Blanks inside a number are allowed ("X1 0.5" is X10.5) only when a digit follows.
      std::size_t j = i;
      while (j < end && (src_[j] == ' ' || src_[j] == '\t')) ++j;
      if (j < end && (is_digit(src_[j]) || (src_[j] == '.' && !dot))) {
        i = j;
      } else {
        break;
      }
    } else {
      break;
    }
  }
  if (!any) return false;
  double v;
  if (!long_form && frac <= 22) {
    static constexpr double kPow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                          1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                          1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    v = static_cast<double>(mant);
    if (mant >= (1ull << 53)) {
      buf[blen] = '\0';
      v = std::strtod(buf, nullptr);
    } else if (frac) {
      v /= kPow10[frac];
    }
  } else if (blen < sizeof buf - 1) {
    buf[blen] = '\0';
    v = std::strtod(buf, nullptr);
  } else {
    v = HUGE_VAL;  // more than 126 characters of digits: certainly out of range
  }
  out = neg ? -v : v;
  return true;
}

std::size_t Compiler::text_begin() const {
  // A UTF-8 byte-order mark (Windows editors write one) is no part of the program: it was
  // "unexpected byte 0xEF" and cost the first line.
  return src_.size() >= 3 && src_.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
}

std::size_t Compiler::line_end(std::size_t begin) const {
  const std::size_t n = src_.size();
  const void* nl = std::memchr(src_.data() + begin, '\n', n - begin);
  std::size_t end = nl ? static_cast<std::size_t>(static_cast<const char*>(nl) - src_.data()) : n;
  // A carriage return that a line feed does not follow ends a line too (old Mac line ends,
  // or a file pieced together from both): it was read as a blank, and a whole CR file as
  // one line of contradicting words. The CR of a CR LF pair stays the line's last blank.
  if (end - begin > 1) {
    if (const void* cr = std::memchr(src_.data() + begin, '\r', end - begin - 1)) {
      end = static_cast<std::size_t>(static_cast<const char*>(cr) - src_.data());
    }
  }
  return end;
}

void Compiler::lex() {
  std::size_t begin = text_begin();
  std::int32_t line = 1;
  const std::size_t n = src_.size();
  blocks_.reserve(n / 16 + 1);
  words_.reserve(64);
  while (begin < n) {
    const std::size_t end = line_end(begin);
    const std::size_t before = blocks_.size();
    lex_line(begin, end, line);
    // While the program runs straight down, each line executes as soon as it is lexed, with
    // the words at hand. The first call or jump leaves that mode: the rest then waits for every
    // label to be known and runs in execute(), lexing its lines again.
    if (in_order_ && !ended_ && blocks_.size() > before) {
      const std::size_t next = step(before, /*relex=*/false);
      if (next != before + 1) {
        in_order_ = false;
        resume_ = next;
      }
    }
    begin = end + 1;
    ++line;
  }
  if (in_order_) resume_ = blocks_.size();
  // Every call and jump names a label that exists, and a backward jump has its K, also in a
  // subroutine never called (pass 2 says it again where it runs: reported once).
  for (const LabelRef& r : label_refs_) {
    const auto it = labels_.find(r.label);
    if (it == labels_.end()) {
      error(r.line, r.column,
            "unknown label L" + std::to_string(r.label) + " (define it with G29 L" +
                std::to_string(r.label) + ")");
    } else if (r.jump_without_k && it->second <= r.block) {
      error(r.line, r.column,
            "backward jump to L" + std::to_string(r.label) +
                " without K would loop forever (give K<count>)");
    }
  }
}

std::size_t Compiler::step(std::size_t index, bool relex) {
  running_ = ++steps_;
  const std::size_t next = step_once(index, relex);
  running_ = 0;
  return next;
}

std::size_t Compiler::step_once(std::size_t index, bool relex) {
  if (++executed_ > max_executed_) {
    std::string where;
    if (!stack_.empty()) {
      where = ", here in the subroutine called on line " +
              std::to_string(blocks_[stack_.back().call_block].line);
    }
    error(blocks_[index].line, 1,
          "program executes more than " + std::to_string(max_executed_) +
              " blocks (10 x max_program_segments + 1,000,000) without ending" + where +
              ": an endless loop of calls or jumps?");
    ended_ = true;
    return index + 1;
  }
  return execute_block(index, relex);
}

void Compiler::lex_line(std::size_t begin, std::size_t end, std::int32_t line) {
  Block b;
  b.line = line;
  b.begin = static_cast<std::uint32_t>(begin);
  b.end = static_cast<std::uint32_t>(end);
  const bool valid = lex_words(b);
  // An empty or comment-only line is no block: it does nothing, and executed it counted
  // against the guard for endless loops (a loop body of a dozen comment lines and one move,
  // 8.5 million times, was refused as endless; session 76's review).
  if (b.word_count == 0 && valid) return;
  // A line whose words could not be read gets those errors only: its checks would report the
  // unread words as missing ("G29 L99999999999": "G29 needs L<label>").
  if (valid) check_block_static(b);
  blocks_.push_back({b.begin, b.end, b.line, b.valid});
  cur_block_ = b;
}

bool Compiler::lex_words(Block& b) {
  const std::size_t begin = b.begin, end = b.end;
  const std::int32_t line = b.line;
  words_.clear();
  b.has_comment = false;
  std::uint32_t seen = 0;  // letters already on this line (G excluded)
  std::size_t i = begin;
  auto col = [&](std::size_t at) { return static_cast<std::uint32_t>(at - begin + 1); };
  // The line's first character after blanks.
  std::size_t first = begin;
  while (first < end && is_space(src_[first])) ++first;
  // A line holding only '%' (tape start/end marker) is ignored.
  if (first < end && src_[first] == '%') {
    std::size_t k = first + 1;
    while (k < end && is_space(src_[k])) ++k;
    if (k == end) {
      b.word_count = 0;
      return true;
    }
  }
  // Block delete: a '/' first on the line marks an optional block.
  if (opt_.compiler.block_delete != BlockDelete::kRefuse && first < end && src_[first] == '/') {
    if (opt_.compiler.block_delete == BlockDelete::kSkip) {
      b.word_count = 0;
      return true;
    }
    i = first + 1;
  }
  while (i < end) {
    const char c = src_[i];
    if (is_space(c)) {
      ++i;
      continue;
    }
    if (c == ';') break;
    if (c == '(') {
      const std::size_t open = i;
      std::size_t j = i + 1;
      // A nested '(' is an error; the comment still ends where its parentheses balance, so
      // that the rest of it ("((a) b)": " b)") is not read as words.
      int depth = 1;
      bool nested = false;
      for (; j < end; ++j) {
        if (src_[j] == '(') {
          if (!nested) error(line, col(j), "'(' inside a comment: comments do not nest");
          nested = true;
          b.valid = false;
          ++depth;
        } else if (src_[j] == ')' && --depth == 0) {
          break;
        }
      }
      if (j >= end) {
        error(line, col(open), "comment '(' is not closed on this line");
        b.valid = false;
        break;
      }
      if (!b.has_comment) {
        std::size_t s = open + 1, e = j;
        while (s < e && is_space(src_[s])) ++s;
        while (e > s && is_space(src_[e - 1])) --e;
        b.has_comment = true;
        b.comment_offset = static_cast<std::uint32_t>(s);
        b.comment_length = static_cast<std::uint32_t>(e - s);
      }
      i = j + 1;
      continue;
    }
    char L = c;
    if (L >= 'a' && L <= 'z') L = static_cast<char>(L - 'a' + 'A');
    if (L < 'A' || L > 'Z') {
      const auto uc = static_cast<unsigned char>(c);
      char buf[160];
      if (c == '/' && opt_.compiler.block_delete != BlockDelete::kRefuse) {
        std::snprintf(buf, sizeof buf, "block delete '/' must come first on its line");
      } else if (c == '/' && i == first) {
        // RS274's optional block: which lines the switch skips is the operator's, not ours.
        std::snprintf(buf, sizeof buf,
                      "block delete '/': whether such lines run or are skipped is not set "
                      "(compiler.block_delete: run or skip; tgm-hmi --block-delete)");
      } else if (uc >= 0x21 && uc < 0x7f) {
        std::snprintf(buf, sizeof buf, "unexpected character '%c'", c);
      } else if (const std::size_t n = utf8_sequence_length(src_.substr(i, end - i)); n > 1) {
        // A letter of another alphabet or a symbol, named as an editor shows it: it was
        // "unexpected byte 0xC3" for an 'ä'. One an editor does not show (C1 controls, spaces
        // and marks of no width, a byte-order mark inside the text) by its code point alone.
        const unsigned cp = utf8_code_point(src_.substr(i, n));
        if (invisible_code_point(cp)) {
          std::snprintf(buf, sizeof buf, "unexpected invisible character U+%04X", cp);
        } else {
          std::snprintf(buf, sizeof buf, "unexpected character '%.*s' (U+%04X)",
                        static_cast<int>(n), src_.data() + i, cp);
        }
      } else {
        std::snprintf(buf, sizeof buf, "unexpected byte 0x%02X", uc);
      }
      error(line, col(i), buf);
      b.valid = false;
      // Skip to the next letter so that one bad byte gives one error.
      ++i;
      while (i < end) {
        const char d = src_[i];
        if ((d >= 'A' && d <= 'Z') || (d >= 'a' && d <= 'z') || d == '(' || d == ';' || is_space(d))
          break;
        ++i;
      }
      continue;
    }
    const std::size_t wstart = i;
    ++i;
    double v = 0.0;
    if (!parse_number(i, end, v)) {
      const auto letter = [](char d) { return (d >= 'A' && d <= 'Z') || (d >= 'a' && d <= 'z'); };
      // Name what follows the letter, so "XNAN", "X+-1" or "G1X" are clear.
      std::size_t q = wstart + 1;
      while (q < end && is_space(src_[q])) ++q;
      std::string reason = std::string("word ") + L + " needs a number";
      if (q < end && src_[q] != '(' && src_[q] != ';') {
        std::size_t j = q;
        while (j < end && !is_space(src_[j]) && j - q < 16) ++j;
        reason += ", not '" + quoted_source(src_.substr(q, j - q)) + "'";
      }
      error(line, col(wstart), reason);
      b.valid = false;
      // Skip the rest of the bad word: the text written onto the letter ("NAN", "+-1"), or
      // after blanks when it starts with no letter ("X -"); a word after a blank ("Y X1") is a
      // word of its own.
      i = wstart + 1;
      std::size_t k = i;
      while (k < end && (src_[k] == ' ' || src_[k] == '\t')) ++k;
      if (k < end && (k == i || !letter(src_[k]))) {
        i = k;
        while (i < end && !is_space(src_[i]) && src_[i] != '(' && src_[i] != ';') ++i;
      }
      continue;
    }
    if (!std::isfinite(v) || std::fabs(v) > kMaxValue) {
      error(line, col(wstart),
            std::string("value of ") + L + " is out of range (|value| <= 1e9): '" +
                quoted_source(src_.substr(wstart, i - wstart)) + "'");
      b.valid = false;
      continue;
    }
    if (L != 'G' && (seen & bit(L))) {
      error(line, col(wstart), std::string("word ") + L + " appears twice on one line");
      b.valid = false;
      continue;
    }
    if (L != 'G') seen |= bit(L);
    words_.push_back({L, col(wstart), v});
  }
  if (words_.size() > 0xFFFF) {
    error(line, 1, "more than 65535 words on one line");
    words_.clear();
    b.valid = false;
  }
  b.word_count = static_cast<std::uint16_t>(words_.size());
  b.letters = seen & ~(bit('G') | bit('M'));
  return b.valid;
}

bool integral(double v) { return v == std::floor(v); }

// Length of (x, y). Every number of a program is at most 1e9 in size, so the plain formula cannot
// overflow and is several times cheaper than std::hypot.
double norm2(double x, double y) { return std::sqrt(x * x + y * y); }

// Checks that need no modal state; records labels.
void Compiler::check_block_static(Block& b) {
  const Word* w = words_.data();
  const Word* we = w + b.word_count;
  const Word* g_of[7] = {};  // per GGroup: the G word of that group on this line
  const Word* m_word = nullptr;
  const Word* by_letter[26] = {};
  for (const Word* p = w; p != we; ++p) {
    if (p->letter == 'G') {
      const double gv = p->value;
      if (gv == 20.0) {
        error(b.line, p->column, "G20 (inch units) is not supported: programs are in mm (G21)");
        b.valid = false;
        continue;
      }
      const int g = integral(gv) && gv >= 0 && gv < 1000 ? static_cast<int>(gv) : -1;
      const GGroup grp = g >= 0 ? g_group(g) : GGroup::kNone;
      if (grp == GGroup::kNone) {
        error(b.line, p->column, "unknown G-code G" + fmt_num(gv));
        b.valid = false;
        continue;
      }
      const auto gi = static_cast<std::size_t>(grp);
      if (g_of[gi]) {
        error(b.line, p->column,
              "G" + fmt_num(g_of[gi]->value) + " and G" + fmt_num(gv) +
                  " cannot be on one line (same group)");
        b.valid = false;
        continue;
      }
      g_of[gi] = p;
    } else if (p->letter == 'M') {
      m_word = p;
    } else {
      by_letter[p->letter - 'A'] = p;
    }
  }
  auto has = [&](char L) { return by_letter[L - 'A'] != nullptr; };
  auto word = [&](char L) { return by_letter[L - 'A']; };
  auto check_tool = [&] {
    if (const Word* t = word('T');
        t && (!integral(t->value) || t->value < 0 || t->value > kMaxTool)) {
      error(b.line, t->column,
            "tool T must be a whole number 0.." + std::to_string(kMaxTool) + ", not " +
                fmt_num(t->value));
      b.valid = false;
    }
  };
  auto gnum = [&](GGroup grp) {
    const Word* p = g_of[static_cast<std::size_t>(grp)];
    return p ? static_cast<int>(p->value) : -1;
  };
  if (const Word* n = word('N'); n && (!integral(n->value) || n->value < 0)) {
    error(b.line, n->column, "line number N must be a whole number >= 0, not " + fmt_num(n->value));
    b.valid = false;
  }

  if (m_word) {
    const double mv = m_word->value;
    if (!integral(mv) || mv < 0 || mv > kMaxM) {
      error(b.line, m_word->column,
            "M-number must be a whole number 0..999999, not M" + fmt_num(mv));
      b.valid = false;
      return;
    }
    const int m = static_cast<int>(mv);
    if (m == 1000) {
      error(b.line, m_word->column,
            "M1000 is neither a normal (< 1000) nor a continuous (> 1000) M-function");
      b.valid = false;
    }
    // G-words that may share a line with an M-function: the modal settings without words.
    for (std::size_t gi = 0; gi < 7; ++gi) {
      const Word* gp = g_of[gi];
      if (!gp) continue;
      const int g = static_cast<int>(gp->value);
      if (!(g == 17 || g == 18 || g == 19 || g == 90 || g == 91 || g == 53 || g == 21)) {
        error(b.line, gp->column,
              "G" + std::to_string(g) + " cannot share a line with M" + std::to_string(m) +
                  " (the other words of an M line are its parameters)");
        b.valid = false;
      }
    }
    if (const Word* p = word('P')) {
      error(b.line, p->column,
            "P is reserved and cannot be an M-function parameter (reserved: G M N P)");
      b.valid = false;
    }
    const bool plc = m < static_cast<int>(redefined_.size()) && redefined_[static_cast<std::size_t>(m)];
    const bool builtin_no_params =
        !plc && (m == 0 || m == 2 || m == 30 || m == 17 || m == 29 || (m >= 80 && m <= 87));
    if (builtin_no_params) {
      for (int k = 0; k < 26; ++k) {
        const char L = static_cast<char>('A' + k);
        if (by_letter[k] && L != 'N' && L != 'P') {
          error(b.line, by_letter[k]->column,
                "M" + std::to_string(m) + " takes no parameters, but " + L + " is given");
          b.valid = false;
        }
      }
    }
    // T on an M line selects the tool as well (M6 T2), so it obeys the tool's range.
    check_tool();
    if (!plc && m == 99) {
      if (!has('F')) {
        error(b.line, m_word->column, "M99 needs F<mm/min>, the new default feed");
        b.valid = false;
      }
      for (int k = 0; k < 26; ++k) {
        const char L = static_cast<char>('A' + k);
        if (by_letter[k] && L != 'N' && L != 'F' && L != 'P') {
          error(b.line, by_letter[k]->column, std::string("M99 takes only F, not ") + L);
          b.valid = false;
        }
      }
      if (const Word* f = word('F'); f && (f->value <= 0 || f->value > kMaxFeed)) {
        error(b.line, f->column, "feed F must be > 0 and <= 1000000 mm/min, not " + fmt_num(f->value));
        b.valid = false;
      }
    }
    if (!plc && m == 29 && (!b.has_comment || b.comment_length == 0)) {
      error(b.line, m_word->column, "M29 needs its message text in parentheses: M29 (text)");
      b.valid = false;
    }
    // The text goes to every HMI as a DDS string and into JSON, which are UTF-8: a comment of
    // a Windows CAM post in cp1252 ("\xB0" for a degree sign) passed as it was (session 75).
    if (!plc && m == 29 && b.has_comment) {
      const std::string_view text(src_.data() + b.comment_offset, b.comment_length);
      if (const std::size_t bad = utf8_invalid_at(text); bad != std::string_view::npos) {
        char buf[16];
        std::snprintf(buf, sizeof buf, "0x%02X", static_cast<unsigned char>(text[bad]));
        error(b.line, static_cast<std::uint32_t>(b.comment_offset + bad - b.begin + 1),
              std::string("M29 message is not UTF-8 text (byte ") + buf +
                  "): save the program as UTF-8");
        b.valid = false;
      } else if (const std::size_t ctl = control_char_at(text); ctl != std::string_view::npos) {
        char buf[16];
        std::snprintf(buf, sizeof buf, "0x%02X", static_cast<unsigned char>(text[ctl]));
        error(b.line, static_cast<std::uint32_t>(b.comment_offset + ctl - b.begin + 1),
              std::string("M29 message holds the control character ") + buf +
                  ": an HMI shows the text as it is, so only printable text (and tabs) may "
                  "be in it");
        b.valid = false;
      }
    }
    if (!plc && m == 29 && b.has_comment && b.comment_length > kMaxMessageBytes) {
      error(b.line, m_word->column,
            "M29 message is " + std::to_string(b.comment_length) + " bytes long; at most " +
                std::to_string(kMaxMessageBytes) +
                " reach the HMI (split it over several M29 lines)");
      b.valid = false;
    }
    return;
  }

  // Not an M line: every letter must be a word of the dialect or an axis.
  constexpr std::uint32_t kWords =
      bit('D') | bit('F') | bit('I') | bit('J') | bit('K') | bit('L') | bit('N') | bit('P') |
      bit('R') | bit('T');
  const std::uint32_t unknown = b.letters & ~(kWords | axis_mask_);
  for (int k = 0; unknown && k < 26; ++k) {
    const Word* p = by_letter[k];
    if (!p || !(unknown & (1u << k))) continue;
    const char L = static_cast<char>('A' + k);
    error(b.line, p->column,
          std::string("unknown word '") + L + fmt_num(p->value) + "'" +
              (std::strchr("ABCEUVWXYZ", L) ? " (not an axis of this interpolator)" : ""));
    b.valid = false;
  }
  if (const Word* f = word('F'); f && (f->value <= 0 || f->value > kMaxFeed)) {
    error(b.line, f->column, "feed F must be > 0 and <= 1000000 mm/min, not " + fmt_num(f->value));
    b.valid = false;
  }
  check_tool();
  if (const Word* d = word('D'); d && d->value < 0) {
    error(b.line, d->column, "compensation radius D must be >= 0, not " + fmt_num(d->value));
    b.valid = false;
  }
  if (const Word* l = word('L'); l && (!integral(l->value) || l->value < 0)) {
    error(b.line, l->column, "label L must be a whole number >= 0, not " + fmt_num(l->value));
    b.valid = false;
  }
  const int nonmodal = gnum(GGroup::kNonModal);
  const int motion = gnum(GGroup::kMotion);
  // R0 on an arc; off an arc, R is out of place whatever its value (the execution says so).
  if (const Word* r = word('R'); r && r->value == 0) {
    const int mode = motion >= 0 ? motion : motion_;
    if (mode == 2 || mode == 3) {
      error(b.line, r->column, "arc radius R must not be 0");
      b.valid = false;
    }
  }
  const bool axis_words = (b.letters & axis_mask_) != 0;
  const Word* ng = g_of[static_cast<std::size_t>(GGroup::kNonModal)];
  switch (nonmodal) {
    case 4:
      if (!has('P')) {
        error(b.line, ng->column, "G4 needs P<seconds>");
        b.valid = false;
      } else if (word('P')->value < 0 || word('P')->value > kMaxDwell) {
        error(b.line, word('P')->column,
              "dwell P must be 0..100000 s, not " + fmt_num(word('P')->value));
        b.valid = false;
      }
      break;
    case 25: case 26: case 27: case 29:
      if (nonmodal != 29 && !has('L')) {
        error(b.line, ng->column, "G" + std::to_string(nonmodal) + " needs L<label>");
        b.valid = false;
      }
      if (nonmodal == 26 && !has('K')) {
        error(b.line, ng->column, "G26 needs K<count>, the number of calls");
        b.valid = false;
      }
      if ((nonmodal == 26 || nonmodal == 27) && has('K')) {
        const Word* k = word('K');
        if (!integral(k->value) || k->value < 1 || k->value > kMaxRepeat) {
          error(b.line, k->column, "count K must be a whole number 1..1000000000, not " +
                                       fmt_num(k->value));
          b.valid = false;
        }
      }
      if (nonmodal != 29 && has('L') && b.valid) {
        label_refs_.push_back({blocks_.size(), b.line, word('L')->column,
                               static_cast<long long>(word('L')->value),
                               nonmodal == 27 && !has('K')});
      }
      if (nonmodal == 29 && !has('L') && !b.has_comment) {
        error(b.line, ng->column, "G29 needs L<label> or a text note in parentheses");
        b.valid = false;
      }
      if (nonmodal == 29 && has('L') && b.valid) {
        const auto label = static_cast<long long>(word('L')->value);
        auto [it, inserted] = labels_.emplace(label, blocks_.size());
        if (!inserted) {
          error(b.line, word('L')->column,
                "label " + std::to_string(label) + " is defined twice (first on line " +
                    std::to_string(blocks_[it->second].line) + ")");
          b.valid = false;
        }
      }
      if (motion >= 0 || axis_words) {
        const Word* culprit = motion >= 0 ? g_of[static_cast<std::size_t>(GGroup::kMotion)] : ng;
        error(b.line, culprit->column,
              "G" + std::to_string(nonmodal) + " cannot share a line with motion or axis words");
        b.valid = false;
      }
      break;
    case 92:
    case 54:
      if (!axis_words) {
        error(b.line, ng->column,
              nonmodal == 92 ? "G92 needs axis words: the coordinates the current point gets"
                             : "G54 needs axis words: the zero-point shift per axis");
        b.valid = false;
      }
      if (motion >= 0) {
        error(b.line, g_of[static_cast<std::size_t>(GGroup::kMotion)]->column,
              "G" + std::to_string(motion) + " and G" + std::to_string(nonmodal) +
                  " both use the axis words: put them on separate lines");
        b.valid = false;
      }
      break;
    default:
      break;
  }
  // Lines that do not move take no centre offset or radius: under a modal G2 / G3 one ran an
  // arc all the same ("G92 X6 I3" a half circle to the G92 coordinates, "G29 L1 K5" a full
  // circle), and on G25 / G26 / G27 lines the words were dropped. K is G26 / G27's count.
  if (nonmodal == 4 || nonmodal == 25 || nonmodal == 26 || nonmodal == 27 || nonmodal == 29 ||
      nonmodal == 54 || nonmodal == 92) {
    for (const char letter : {'I', 'J', 'K', 'R'}) {
      if (letter == 'K' && (nonmodal == 26 || nonmodal == 27)) continue;
      if (const Word* x = word(letter)) {
        error(b.line, x->column,
              std::string(1, letter) + " is not used by G" + std::to_string(nonmodal) +
                  (letter == 'K' && nonmodal == 25
                       ? " (K, the count of calls, belongs to G26 / G27)"
                       : " (it belongs to an arc move, G2 / G3, on a line of its own)"));
        b.valid = false;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Pass 2: execution
// ---------------------------------------------------------------------------------------------

bool Compiler::emit_check(const Block& b) {
  if (emitted_ < opt_.compiler.max_program_segments) {
    return true;
  }
  if (!too_big_) error(b.line, 1, too_big_reason());
  too_big_ = true;
  ended_ = true;  // stop expanding
  return false;
}

Segment Compiler::base_segment(const Block& b) const {
  Segment s;
  s.line = b.line;
  s.plane = plane_;
  s.compensation = comp_;
  s.compensation_radius_mm = comp_ != Compensation::kOff ? comp_radius_ : 0.0;
  s.tool = tool_;
  s.end = pos_;
  return s;
}

std::size_t Compiler::execute_block(std::size_t index, bool relex) {
  const std::size_t next = index + 1;
  const LineRef& ref = blocks_[index];
  if (!ref.valid) return next;
  Block b;
  if (relex) {
    b.line = ref.line;
    b.begin = ref.begin;
    b.end = ref.end;
    reporting_ = false;  // pass 1 reported this line's lexical errors already
    lex_words(b);
    reporting_ = true;
  } else {
    b = cur_block_;  // lexed just now: words_ still holds its words
  }
  const Word* w = words_.data();
  const Word* we = w + b.word_count;
  const Word* by_letter[26] = {};
  int g_motion = -1, g_plane = -1, g_dist = -1, g_comp = -1, g_nonmodal = -1;
  const Word* motion_word = nullptr;
  const Word* m_word = nullptr;
  for (const Word* p = w; p != we; ++p) {
    if (p->letter == 'G') {
      const int g = static_cast<int>(p->value);
      switch (g_group(g)) {
        case GGroup::kMotion: g_motion = g; motion_word = p; break;
        case GGroup::kPlane: g_plane = g; break;
        case GGroup::kDistance: g_dist = g; break;
        case GGroup::kComp: g_comp = g; break;
        case GGroup::kNonModal: g_nonmodal = g; break;
        default: break;
      }
    } else if (p->letter == 'M') {
      m_word = p;
    } else {
      by_letter[p->letter - 'A'] = p;
    }
  }
  auto word = [&](char L) { return by_letter[L - 'A']; };

  // A call or jump to a label further down runs once every line is lexed, the whole line then:
  // its settings ran twice before, and a G41 on it was "on already" the second time.
  if (!relex && (g_nonmodal == 25 || g_nonmodal == 26 || g_nonmodal == 27) && word('L') &&
      labels_.find(static_cast<long long>(word('L')->value)) == labels_.end()) {
    return index;
  }

  // Modal settings first, so that "G17 G90 G2 ..." works on one line.
  if (g_plane >= 0) {
    const auto plane = static_cast<Plane>(g_plane);
    if (plane != plane_ && comp_ != Compensation::kOff && comp_radius_ > 0 && g_comp != 40) {
      error(b.line, 1,
            "G" + std::to_string(g_plane) +
                ": the plane cannot change while tool radius compensation is on (G40 first)");
    } else {
      plane_ = plane;
    }
  }
  if (g_dist >= 0) incremental_ = g_dist == 91;
  if (g_nonmodal == 53) shift_.fill(0.0);

  if (m_word) {
    const int m = static_cast<int>(m_word->value);
    const bool plc = m < static_cast<int>(redefined_.size()) && redefined_[static_cast<std::size_t>(m)];
    if (!plc) {
      if (m == 17) {
        if (stack_.empty()) {
          error(b.line, m_word->column, "M17 (return) outside a subroutine");
          return next;
        }
        Frame& f = stack_.back();
        if (f.remaining > 0) {
          --f.remaining;
          return f.sub_block;
        }
        const std::size_t ret = f.return_block;
        stack_.pop_back();
        return ret;
      }
      if (m >= 80 && m <= 87) {
        // Mirroring about program zero (manual table): which of X, Y, Z change sign.
        static constexpr const char* kMirrored[8] = {"", "X", "Y", "Z", "XY", "XZ", "YZ", "XYZ"};
        const bool was_swapped = plane_mirrored_once();
        mirror_.fill(1.0);
        for (const char* L = kMirrored[m - 80]; *L; ++L) {
          const int a = axis_index(*L);
          if (a < 0) {
            error(b.line, m_word->column,
                  "M" + std::to_string(m) + " mirrors " + *L + ", which this interpolator has no axis for");
            continue;
          }
          mirror_[static_cast<std::size_t>(a)] = -1.0;
        }
        // The offset side was chosen under the old mirroring; the moves after this would take
        // the contour's other side with it.
        if (comp_ != Compensation::kOff && comp_radius_ > 0 &&
            plane_mirrored_once() != was_swapped) {
          error(b.line, m_word->column,
                "M" + std::to_string(m) +
                    " mirrors one axis of the plane while tool radius "
                    "compensation is on, which would swap its side (G40 first)");
        }
        return next;
      }
      if (m == 99) {
        default_feed_ = word('F')->value;
        feed_ = 0.0;  // the new default is the active feed until the next F word
        return next;
      }
      if (m == 29) {
        if (!emit_check(b)) return next;
        Segment s = base_segment(b);
        s.type = SegmentType::kMessage;
        s.aux = intern_message(src_.substr(b.comment_offset, b.comment_length));
        emit(s);
        return next;
      }
    }
    // M0, M2/M30 and every PLC function become records.
    if (!emit_check(b)) return next;
    Segment s = base_segment(b);
    s.type = SegmentType::kMFunction;
    s.m = m;
    if (!plc && m == 0) {
      s.m_kind = MKind::kProgramStop;
    } else if (!plc && (m == 2 || m == 30)) {
      s.m_kind = MKind::kProgramEnd;
    } else {
      s.m_kind = m > 1000 ? MKind::kContinuous : MKind::kNormal;
    }
    MParams params = unset_params();
    for (int k = 0; k < 26; ++k) {
      const char L = static_cast<char>('A' + k);
      if (by_letter[k] && L != 'N' && L != 'P') params[static_cast<std::size_t>(k)] = by_letter[k]->value;
    }
    // T on an M line (M6 T2) both selects the tool and is a parameter.
    if (const Word* t = word('T')) {
      tool_ = static_cast<int>(t->value);
      s.tool = tool_;
    }
    s.aux = intern_params(params);
    emit(s);
    if (s.m_kind == MKind::kProgramEnd) ended_ = true;
    return next;
  }

  // Words that set state.
  if (const Word* f = word('F')) feed_ = f->value;
  if (const Word* t = word('T')) tool_ = static_cast<int>(t->value);

  if (g_comp >= 0) {
    if (g_comp == 40) {
      comp_ = Compensation::kOff;
      comp_radius_ = 0.0;
      if (const Word* d = word('D')) {
        error(b.line, d->column, "D (compensation radius) belongs to G41/G42, not G40");
      }
    } else if (comp_ != Compensation::kOff) {
      error(b.line, 1,
            "G" + std::to_string(g_comp) +
                ": tool radius compensation is on already; cancel it with G40 first");
    } else {
      double radius = -1.0;
      if (const Word* d = word('D')) {
        radius = d->value;
      } else if (tool_ == 0) {
        radius = 0.0;  // T0: no tool in the spindle, the path is the programmed one
      } else {
        for (const ToolConfig& t : opt_.tools) {
          if (t.number == tool_) radius = t.radius_mm;
        }
        if (radius < 0) {
          error(b.line, 1,
                "G" + std::to_string(g_comp) + " needs a radius: D<mm> on the line, or tool T" +
                    std::to_string(tool_) + " in the tool table");
        }
      }
      // Mirroring one axis of the plane swaps the side of the contour.
      comp_ = (g_comp == 41) != plane_mirrored_once() ? Compensation::kLeft : Compensation::kRight;
      comp_radius_ = std::max(radius, 0.0);
    }
  } else if (const Word* d = word('D')) {
    error(b.line, d->column, "D (compensation radius) is only used with G41/G42");
  }

  if (g_nonmodal == 4) {
    if (emit_check(b)) {
      Segment s = base_segment(b);
      s.type = SegmentType::kDwell;
      s.dwell_s = word('P')->value;
      emit(s);
    }
  } else if (const Word* p = word('P')) {
    error(b.line, p->column, "P (dwell seconds) is only used with G4");
  }

  // Axis words: targets in program coordinates, mirrored.
  bool any_axis = false;
  std::array<bool, kMaxAxes> given{};
  std::array<double, kMaxAxes> value{};
  for (int a = 0; a < n_axes_; ++a) {
    const char L = opt_.axis_letters[static_cast<std::size_t>(a)];
    if (const Word* p = word(L)) {
      given[static_cast<std::size_t>(a)] = true;
      value[static_cast<std::size_t>(a)] = p->value * mirror_[static_cast<std::size_t>(a)];
      any_axis = true;
    }
  }

  if (g_nonmodal == 54) {
    for (int a = 0; a < n_axes_; ++a) {
      if (given[static_cast<std::size_t>(a)]) {
        shift_[static_cast<std::size_t>(a)] =
            word(opt_.axis_letters[static_cast<std::size_t>(a)])->value;
      }
    }
    any_axis = false;  // the axis words were the shift
  } else if (g_nonmodal == 92) {
    // The current point gets the given coordinates: machine = program + shift + g92.
    for (int a = 0; a < n_axes_; ++a) {
      const auto i = static_cast<std::size_t>(a);
      if (given[i]) g92_[i] = pos_[i] - shift_[i] - value[i];
    }
    any_axis = false;
  }

  if (g_motion >= 0) motion_ = g_motion;
  const bool arc_words = word('I') || word('J') || word('K') || word('R');
  const bool flow = g_nonmodal == 25 || g_nonmodal == 26 || g_nonmodal == 27;
  if (!flow) {
    // I/J/K/R only make sense on an arc.
    const bool arc_mode = motion_ == 2 || motion_ == 3;
    // Modal as the axis words are: in G2/G3 a line of centre offsets alone is another full
    // circle (rs274 runs it; it was "I is only used by an arc move" under an active G2).
    if (arc_words && !arc_mode) {
      const Word* p = word('I') ? word('I') : word('J') ? word('J') : word('K') ? word('K') : word('R');
      error(b.line, p->column,
            std::string(1, p->letter) + " is only used by an arc move (G2/G3)");
    }
  }
  if (const Word* l = word('L'); l && !(g_nonmodal >= 25 && g_nonmodal <= 29 && g_nonmodal != 28)) {
    error(b.line, l->column, "L (label) is only used by G25, G26, G27 and G29");
  }

  const bool modal_arc = (motion_ == 2 || motion_ == 3) && arc_words;
  if (any_axis || g_motion >= 0 || (modal_arc && !flow)) {
    if (motion_ < 0) {
      const Word* p = w;
      error(b.line, p->column, "axis words without a motion G-code (G0, G1, G2 or G3) before them");
    } else if (!any_axis && !(motion_ >= 2 && arc_words)) {
      // "G1" alone: selects the mode, moves nowhere.
    } else if (emit_check(b)) {
      std::array<double, kMaxAxes> target = pos_;
      for (int a = 0; a < n_axes_; ++a) {
        const auto i = static_cast<std::size_t>(a);
        if (!given[i]) continue;
        target[i] = incremental_ ? pos_[i] + value[i] : value[i] + shift_[i] + g92_[i];
      }
      Segment s = base_segment(b);
      s.type = static_cast<SegmentType>(motion_);
      s.end = target;
      const double feed = feed_ > 0 ? feed_ : default_feed_;
      s.feed_mm_per_min = motion_ == 0 ? 0.0 : feed;
      bool ok = true;
      if (motion_ >= 2) {
        const PlaneAxes pa = plane_axes(plane_, opt_.axis_letters);
        const PlaneAxes xyz = plane_xyz(plane_);
        const int a0 = pa.first, a1 = pa.second;
        if (a0 >= n_axes_ || a1 >= n_axes_) {
          error(b.line, motion_word ? motion_word->column : 1,
                "arc in plane G" + std::to_string(static_cast<int>(plane_)) + " needs the axes " +
                    "XYZ"[std::min(xyz.first, xyz.second)] + " and " +
                    "XYZ"[std::max(xyz.first, xyz.second)] + ", but this interpolator's axes are " +
                    opt_.axis_letters);
          ok = false;
        } else {
          const auto i0 = static_cast<std::size_t>(a0), i1 = static_cast<std::size_t>(a1);
          const double sx = pos_[i0], sy = pos_[i1];
          const double ex = target[i0], ey = target[i1];
          // Offset letters per axis letter: X->I, Y->J, Z->K.
          static constexpr char kOffsetLetter[3] = {'I', 'J', 'K'};
          const char o0 = kOffsetLetter[xyz.first], o1 = kOffsetLetter[xyz.second];
          const char onormal = kOffsetLetter[xyz.normal];
          const Word* wr = word('R');
          const Word* wo0 = word(o0);
          const Word* wo1 = word(o1);
          if (const Word* wn = word(onormal)) {
            error(b.line, wn->column,
                  std::string(1, onormal) + " is not a centre offset in plane G" +
                      std::to_string(static_cast<int>(plane_)) + " (use " + o0 + " and " + o1 + ")");
            ok = false;
          }
          double cx = 0, cy = 0, radius = 0;
          const bool cw = motion_ == 2;
          // Mirroring one axis of the plane reverses the direction.
          const bool flip = mirror_[i0] * mirror_[i1] < 0;
          if (wr && (wo0 || wo1)) {
            error(b.line, wr->column, "an arc takes either R or centre offsets, not both");
            ok = false;
          } else if (wr) {
            const double r = std::fabs(wr->value);
            const double dx = ex - sx, dy = ey - sy;
            const double d = norm2(dx, dy);
            if (d < kFullCircleMm) {
              error(b.line, wr->column,
                    "an R arc cannot have its end at its start (use I/J/K for a full circle)");
              ok = false;
            } else if (0.5 * d - r > arc_radius_tolerance_mm(r)) {
              // Short of half the chord by more than the arc tolerance. Within it (R rounded
              // by a CAM post) the arc is the half circle over the chord, as in rs274.
              error(b.line, wr->column,
                    "radius R" + fmt_num(r) + " is too small for the distance " + fmt_mm(d) +
                        " mm between start and end");
              ok = false;
            } else {
              const double h2 = r * r - 0.25 * d * d;
              const double h = h2 > 0 ? std::sqrt(h2) : 0.0;
              // Left of the chord (towards `second` from `first`) for a CCW arc of <= 180 deg,
              // in the direction the arc runs: the mirrored one (start and end are mirrored
              // already). With the programmed one a mirrored R arc took the centre on the other
              // side, 270 degrees where its I/J twin turned 90.
              double side = cw != flip ? -1.0 : 1.0;
              if (wr->value < 0) side = -side;
              const double ux = -dy / d, uy = dx / d;
              cx = 0.5 * (sx + ex) + side * h * ux;
              cy = 0.5 * (sy + ey) + side * h * uy;
              radius = std::max(r, 0.5 * d);
            }
          } else if (wo0 || wo1) {
            cx = sx + (wo0 ? wo0->value * mirror_[i0] : 0.0);
            cy = sy + (wo1 ? wo1->value * mirror_[i1] : 0.0);
            const double r0 = norm2(sx - cx, sy - cy);
            const double r1 = norm2(ex - cx, ey - cy);
            radius = r0;
            if (r0 < 1e-9) {
              error(b.line, (wo0 ? wo0 : wo1)->column, "arc centre is at the start point (radius 0)");
              ok = false;
            } else if (std::fabs(r1 - r0) > arc_radius_tolerance_mm(r0)) {
              error(b.line, (wo0 ? wo0 : wo1)->column,
                    "arc end radius " + fmt_mm(r1) + " differs from start radius " + fmt_mm(r0) +
                        " by " + fmt_mm(std::fabs(r1 - r0)) +
                        " mm (allowed: max(0.005 mm, 0.1 % of the radius))");
              ok = false;
            }
          } else {
            error(b.line, motion_word ? motion_word->column : w->column,
                  std::string("arc needs a centre: ") + o0 + "/" + o1 + " offsets or R");
            ok = false;
          }
          if (flip) s.type = cw ? SegmentType::kArcCcw : SegmentType::kArcCw;
          s.center = {cx, cy};
          s.radius = radius;
          s.turns = 0;
        }
      }
      // Incremental moves, offsets and G92 can carry a point beyond what any word may say;
      // the interpolator refuses such a record, so say it here, at its block.
      for (int a = 0; ok && a < n_axes_; ++a) {
        if (std::fabs(target[static_cast<std::size_t>(a)]) <= kMaxValue) continue;
        const char L = opt_.axis_letters[static_cast<std::size_t>(a)];
        const Word* at = word(L) ? word(L) : (motion_word ? motion_word : w);
        error(b.line, at->column,
              std::string("end point ") + L + fmt_num(target[static_cast<std::size_t>(a)]) +
                  " is beyond +-1e9 mm (after incremental moves and offsets)");
        ok = false;
      }
      if (ok && s.is_arc() && !(std::fabs(s.center[0]) <= kMaxValue && std::fabs(s.center[1]) <= kMaxValue)) {
        error(b.line, motion_word ? motion_word->column : w->column, "arc centre is beyond +-1e9 mm");
        ok = false;
      }
      if (ok) {
        emit(s);
      }
      pos_ = target;
    }
  }

  // Flow control last.
  if (g_nonmodal == 25 || g_nonmodal == 26 || g_nonmodal == 27) {
    const Word* lw = word('L');
    const auto label = static_cast<long long>(lw->value);
    const auto it = labels_.find(label);
    if (it == labels_.end()) {  // pass 2 (pass 1 left a line with a later label to it, above)
      error(b.line, lw->column, "unknown label L" + std::to_string(label) +
                                    " (define it with G29 L" + std::to_string(label) + ")");
      return next;
    }
    const std::size_t target = it->second;
    if (g_nonmodal == 27) {
      const Word* kw = word('K');
      if (!kw) {
        if (target <= index) {
          error(b.line, lw->column,
                "backward jump to L" + std::to_string(label) +
                    " without K would loop forever (give K<count>)");
          return next;
        }
        return target;
      }
      auto [it_count, armed] = jump_count_.try_emplace(index, static_cast<long long>(kw->value));
      (void)armed;
      if (it_count->second > 0) {
        --it_count->second;
        return target;
      }
      jump_count_.erase(it_count);  // fall through, re-armed when reached again
      return next;
    }
    if (static_cast<int>(stack_.size()) >= opt_.compiler.max_call_depth) {
      error(b.line, lw->column,
            "subroutine calls nested deeper than " + std::to_string(opt_.compiler.max_call_depth));
      ended_ = true;  // an endless recursion: stop expanding
      return next;
    }
    const long long times = g_nonmodal == 26 ? static_cast<long long>(word('K')->value) : 1;
    stack_.push_back({next, index, target, times - 1});
    return target;
  }
  return next;
}

void Compiler::execute() {
  std::size_t i = resume_;
  while (i < blocks_.size() && !ended_) i = step(i, /*relex=*/true);
  if (!ended_ && !stack_.empty()) {
    const LineRef& call = blocks_[stack_.back().call_block];
    error(call.line, 1, "subroutine called here runs to the end of the program without M17");
  }
}

void Compiler::to_character_columns() {
  std::size_t begin = text_begin();
  const std::size_t n = src_.size();
  std::int32_t line = 1;
  std::size_t end = begin < n ? line_end(begin) : n;  // of line `line`
  for (Diagnostic& d : errors_) {
    if (d.line < line || d.column < 1) continue;  // no place, or not in order
    while (line < d.line && begin < n) {
      begin = end + 1;
      end = begin < n ? line_end(begin) : n;
      ++line;
    }
    if (line != d.line || begin >= n) continue;
    const std::size_t at = begin + static_cast<std::size_t>(d.column) - 1;
    std::size_t chars = 0;
    std::size_t i = begin;
    while (i < at && i < end) {
      const std::size_t len = utf8_sequence_length(src_.substr(i, end - i));
      i += len == 0 ? 1 : len;
      ++chars;
    }
    d.column = static_cast<int>(chars + (at > i ? at - i : 0) + 1);
  }
}

CompileResult Compiler::run() {
  CompileResult result;
  n_axes_ = static_cast<int>(opt_.axis_letters.size());
  if (n_axes_ < 1 || n_axes_ > kMaxAxes) {
    result.errors.push_back({0, 0, "the interpolator must have 1..10 axes, not " +
                                       std::to_string(n_axes_)});
    return result;
  }
  axis_of_letter_.fill(-1);
  for (int a = 0; a < n_axes_; ++a) {
    char L = opt_.axis_letters[static_cast<std::size_t>(a)];
    if (L >= 'a' && L <= 'z') L = static_cast<char>(L - 'a' + 'A');
    if (L < 'A' || L > 'Z' || std::strchr("DFGIJKLMNPRT", L) || (axis_mask_ & bit(L))) {
      result.errors.push_back({0, 0, std::string("bad axis letter '") + L + "'"});
      return result;
    }
    axis_mask_ |= bit(L);
    axis_of_letter_[static_cast<std::size_t>(L - 'A')] = a;
  }
  redefined_.assign(100, false);
  for (int m : opt_.compiler.plc_redefined_m) {
    if (m >= 0 && m < 100) redefined_[static_cast<std::size_t>(m)] = true;
  }
  if (src_.size() > 0xFFFFFFF0u) {
    result.errors.push_back({1, 1, "program text larger than 4 GiB"});
    return result;
  }
  // G-code is text. A 0x00 byte makes it a binary file (intercode, an archive, an image): one
  // error where the first one lies, not "unexpected byte" on nearly every line (an intercode
  // file of 1,351 bytes gave 277 errors of binary garbage).
  if (const void* z = std::memchr(src_.data(), '\0', src_.size())) {
    const auto at = static_cast<std::size_t>(static_cast<const char*>(z) - src_.data());
    int line = 1;
    std::size_t line_start = 0;
    for (std::size_t i = 0; i < at; ++i) {  // line ends as lex() counts them
      const char c = src_[i];
      if (c == '\n' || (c == '\r' && src_[i + 1] != '\n')) {
        ++line;
        line_start = i + 1;
      }
    }
    result.errors.push_back({line, static_cast<int>(at - line_start + 1),
                             has_intercode_magic(src_)
                                 ? "this is binary intercode, not G-code text"
                                 : "a 0x00 byte: this is a binary file, not G-code text"});
    return result;
  }

  incremental_ = opt_.compiler.start_incremental;
  default_feed_ = opt_.compiler.default_feed_mm_per_min;
  tool_ = opt_.compiler.initial_tool;
  mirror_.fill(1.0);
  pos_ = opt_.start_mm;
  program_.number_axes = n_axes_;
  program_.axis_letters = opt_.axis_letters;
  for (int i = 0; i < n_axes_; ++i) {
    program_.start_mm[static_cast<std::size_t>(i)] = opt_.start_mm[static_cast<std::size_t>(i)];
  }
  // Enough for every real program, and a stop for loops that expand to nothing.
  max_executed_ = static_cast<std::uint64_t>(opt_.compiler.max_program_segments) * 10 + 1'000'000;

  // Room for a record per line (most programs have one, loops aside), so that the program does
  // not grow by doubling: each step copies it into memory never touched before, and on a
  // virtual machine a first touch is a page fault of microseconds (a 1.5 M line program
  // touched about twice its size). Unused room is never touched and costs nothing; capped
  // (4 M records, 640 MB of address space) for files of mostly comments.
  if (sink_ == nullptr) {
    const auto lines = static_cast<std::size_t>(std::count(src_.begin(), src_.end(), '\n')) + 1;
    program_.segments.reserve(
        std::min<std::size_t>({lines, static_cast<std::size_t>(opt_.compiler.max_program_segments),
                               std::size_t{1} << 22}));
  }
  lex();  // executes the program as far as it runs straight down
  execute();
  comp_stage_.finish();

  for (std::size_t k = 0; k < errors_.size(); ++k) {
    if (const std::uint64_t n = error_repeats_[k]; n > 0) {
      errors_[k].reason += " (" + std::to_string(n) + (n == 1 ? " more time" : " more times") +
                           ", as the line ran again)";
    }
  }
  std::stable_sort(errors_.begin(), errors_.end(), [](const Diagnostic& a, const Diagnostic& b) {
    return a.line != b.line ? a.line < b.line : a.column < b.column;
  });
  // A subroutine run several times reports its errors once.
  errors_.erase(std::unique(errors_.begin(), errors_.end(),
                            [](const Diagnostic& a, const Diagnostic& b) {
                              return a.line == b.line && a.column == b.column && a.reason == b.reason;
                            }),
                errors_.end());
  to_character_columns();
  result.errors_not_shown = suppressed_;
  if (suppressed_ > 0) {
    // Line 0: no place (format_diagnostic then names the file only).
    errors_.push_back({0, 0, std::to_string(suppressed_) + " further errors not shown"});
  }
  result.errors = std::move(errors_);
  if (result.errors.empty()) result.program = std::move(program_);
  return result;
}

}  // namespace

std::string format_diagnostic(std::string_view file, const Diagnostic& d) {
  if (d.line <= 0) return std::string(file) + ": error: " + d.reason;
  return std::string(file) + ":" + std::to_string(d.line) + ":" + std::to_string(d.column) +
         ": error: " + d.reason;
}

CompileOptions CompileOptions::from_machine(const MachineConfig& m, int n) {
  CompileOptions o;
  o.axis_letters = m.axis_letters(n);
  o.compiler = m.compiler;
  o.tools = m.tools;
  if (tgm::has_soft_limits(m.interpolators[static_cast<std::size_t>(n)])) {
    o.machine_axes = m.interpolators[static_cast<std::size_t>(n)];
  }
  return o;
}

CompileResult compile_gcode(std::string_view source, const CompileOptions& options) {
  Compiler c(source, options, nullptr);
  return c.run();
}

CompileResult compile_gcode(std::string_view source, const CompileOptions& options,
                            const SegmentSink& sink) {
  Compiler c(source, options, &sink);
  CompileResult r = c.run();
  if (!r.ok()) r.program = Program{};
  return r;
}

}  // namespace tgm
