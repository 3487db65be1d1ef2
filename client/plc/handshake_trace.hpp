// tgm-plc --handshake-trace: one CSV row per acknowledgement of a normal M-function and per note
// of a continuous one that the PLC wrote, with its time stamps on the steady clock, which
// M-function it was and how the service answered. Header-only, no DDS (unit-tested).
// tests/bench/service/handshake_trace.py joins the rows with tgm-service's trace.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace tgm::plc {

//! One acknowledgement (or note) as written to the trace.
struct AckTrace {
  using Time = std::chrono::steady_clock::time_point;
  int interpolator = 0;
  std::int32_t act_part = 0;
  //! When the PLC woke for the sample that showed the M-function, saw it, called the write,
  //! the write returned, and the reply came (or, without a reply, when the PLC gave up).
  Time woke{}, seen{}, ack_call{}, ack_written{}, reply{};
  //! Who wrote it: "event" (the event callback), "loop" (the main loop, when due) or "repeat"
  //! (the main loop again, after one was left unanswered).
  const char* path = "loop";
  std::int32_t m = 0;
  std::uint32_t m_func_count = 0;
  //! A normal M-function (the interpolator waits) or a continuous one (a note).
  bool normal = true;
  //! The reply's code (msg::REPLY_CODE_*: 0 accepted), or -1 when none came.
  int reply_code = -1;
};

//! The header row. The first eight columns are those of the traces before session 76; `reply`
//! is "accepted", "refused" (reply_code says why: 3 is WRONG_STATE, a note after the next
//! M-function was handed over, or a repeat of one that arrived) or "none" (no reply: reply_ns
//! is when the PLC gave up).
inline constexpr const char* kAckTraceHeader =
    "interpolator,act_part,woke_ns,seen_ns,ack_call_ns,ack_written_ns,reply_ns,path,m,"
    "m_func_count,kind,reply_code,reply\n";

//! One row of `t`, with its line end.
inline std::string ack_trace_row(const AckTrace& t) {
  const auto ns = [](AckTrace::Time at) {
    return static_cast<long long>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(at.time_since_epoch()).count());
  };
  char row[320];
  std::snprintf(row, sizeof row, "%d,%d,%lld,%lld,%lld,%lld,%lld,%s,%d,%u,%s,%d,%s\n",
                t.interpolator, t.act_part, ns(t.woke), ns(t.seen), ns(t.ack_call),
                ns(t.ack_written), ns(t.reply), t.path, t.m, t.m_func_count,
                t.normal ? "normal" : "continuous", t.reply_code,
                t.reply_code < 0    ? "none"
                : t.reply_code == 0 ? "accepted"
                                    : "refused");
  return row;
}

}  // namespace tgm::plc
