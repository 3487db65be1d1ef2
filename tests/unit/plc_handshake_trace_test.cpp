// tgm-plc --handshake-trace: the CSV row of one acknowledgement or note
// (client/plc/handshake_trace.hpp). Which rows the PLC writes is tested with the processes in
// tests/integration (PlcTracesEveryAcknowledgementAndNoteAlikeWithAndWithoutEvents).
#include "handshake_trace.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <string>

namespace tgm::plc {
namespace {

AckTrace::Time at_ns(long long ns) {
  return AckTrace::Time(std::chrono::nanoseconds(ns));
}

AckTrace stamped() {
  AckTrace t;
  t.interpolator = 1;
  t.act_part = 12;
  t.woke = at_ns(100);
  t.seen = at_ns(200);
  t.ack_call = at_ns(300);
  t.ack_written = at_ns(400);
  t.reply = at_ns(5000);
  return t;
}

// The first eight columns stay those of the older traces; the M-function and the answer follow,
// so that a refusal or a note cannot be taken for a completed handshake (four rows of one trace
// read "0,10,...,event" alike, refused notes among them).
TEST(AckTrace, ARowNamesTheMFunctionAndTheAnswer) {
  EXPECT_STREQ(kAckTraceHeader,
               "interpolator,act_part,woke_ns,seen_ns,ack_call_ns,ack_written_ns,reply_ns,path,m,"
               "m_func_count,kind,reply_code,reply\n");
  AckTrace t = stamped();
  t.path = "event";
  t.m = 51;
  t.m_func_count = 7;
  t.reply_code = 0;
  EXPECT_EQ(ack_trace_row(t), "1,12,100,200,300,400,5000,event,51,7,normal,0,accepted\n");
  // A note the service refused (WRONG_STATE: M_Func shows the next M-function already).
  t.path = "loop";
  t.m = 1234;
  t.m_func_count = 8;
  t.normal = false;
  t.reply_code = 3;
  EXPECT_EQ(ack_trace_row(t), "1,12,100,200,300,400,5000,loop,1234,8,continuous,3,refused\n");
  // No reply: reply_ns is when the PLC gave up.
  t.path = "repeat";
  t.m = 51;
  t.normal = true;
  t.reply_code = -1;
  EXPECT_EQ(ack_trace_row(t), "1,12,100,200,300,400,5000,repeat,51,8,normal,-1,none\n");
}

}  // namespace
}  // namespace tgm::plc
