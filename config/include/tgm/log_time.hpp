// Time stamps on the log lines of the long-running processes (tgm-service, tgm-plc), which
// write their log to standard output and standard error. Under systemd the journal stamps each
// line itself (it sets JOURNAL_STREAM for the processes whose output it takes); run by hand or
// into a file the lines had no time at all, so a warning could not be put beside anything else.
#pragma once

#include <chrono>
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

//! "2026-12-05 12:20:01.123 ": local time to the millisecond, and a space.
std::string log_stamp(std::chrono::system_clock::time_point t);

//! Puts `stamp` before every line of the text written in pieces through add(): a piece may end
//! inside a line, and the next piece goes on with it unstamped.
class LineStamper {
 public:
  //! `piece` as it goes out, with `stamp` before each line that starts in it.
  std::string add(std::string_view piece, std::string_view stamp);

 private:
  bool at_line_start_ = true;
};

//! Whether `mode` stamps, given the value of JOURNAL_STREAM (nullptr: not set) and the device and
//! inode of standard error ("<dev>:<ino>", as systemd writes it; empty when unknown).
bool log_time_wanted(LogTime mode, const char* journal_stream, std::string_view stderr_id);

//! Replaces stdout (line-buffered) and stderr (unbuffered) by streams that stamp each line
//! (log_stamp) and write to the same file descriptors, when `mode` wants it. Before any other
//! thread writes to them. False, with `why`, when a stream could not be made (nothing changed).
bool stamp_standard_streams(LogTime mode, std::string& why);

}  // namespace tgm
