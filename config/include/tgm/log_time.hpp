// Time stamps on the log lines of the long-running processes (tgm-service, tgm-plc), which
// write their log to standard output and standard error. Under systemd the journal stamps each
// line itself (it sets JOURNAL_STREAM for the processes whose output it takes); run by hand or
// into a file the lines had no time at all, so a warning could not be put beside anything else.
#pragma once

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace tgm {

enum class LogTime {
  kAuto,  //!< stamped unless JOURNAL_STREAM names the output (the journal stamps it)
  kOn,
  kOff,
};

//! "auto", "on" or "off"; nullopt otherwise.
std::optional<LogTime> parse_log_time(std::string_view text);

//! Room for a stamp and its terminating zero.
inline constexpr std::size_t kLogStampSize = 40;
//! Writes "2026-12-05 12:20:01.123+0100 " (local time to the millisecond, the zone's offset,
//! a space) into `out`; returns its length. No allocation: called inside stdio.
std::size_t format_log_stamp(std::chrono::system_clock::time_point t,
                             char (&out)[kLogStampSize]) noexcept;
std::string log_stamp(std::chrono::system_clock::time_point t);

//! Puts `stamp` before every line of the text written in pieces through add(): a piece may end
//! inside a line, and the next piece goes on with it unstamped.
class LineStamper {
 public:
  //! `piece` as it goes out, with `stamp` before each line that starts in it.
  std::string add(std::string_view piece, std::string_view stamp);
  //! The same, each byte handed to `emit(const char*, std::size_t)` (no allocation).
  template <class Emit>
  void add(std::string_view piece, std::string_view stamp, Emit&& emit) {
    std::size_t from = 0;
    while (from < piece.size()) {
      if (at_line_start_) emit(stamp.data(), stamp.size());
      const std::size_t nl = piece.find('\n', from);
      const std::size_t end = nl == std::string_view::npos ? piece.size() : nl + 1;
      emit(piece.data() + from, end - from);
      at_line_start_ = nl != std::string_view::npos;
      from = end;
    }
  }

 private:
  bool at_line_start_ = true;
};

//! Whether `mode` stamps a descriptor, given the value of JOURNAL_STREAM (nullptr: not set) and
//! the descriptor's device and inode ("<dev>:<ino>", as systemd writes it; empty when unknown).
bool log_time_wanted(LogTime mode, const char* journal_stream, std::string_view fd_id);

//! Replaces stdout (line-buffered) and stderr (unbuffered), and std::cout and std::cerr with
//! them, by streams that stamp each line (format_log_stamp) and write to the same file
//! descriptors, each when `mode` wants it for its descriptor. Before any other thread writes
//! to them. False, with `why`, when a stream could not be made (nothing changed).
bool stamp_standard_streams(LogTime mode, std::string& why);

}  // namespace tgm
