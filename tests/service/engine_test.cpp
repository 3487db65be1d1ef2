// The cycle engine against a mock port: role rules, request budget, program chunks in bounded
// pieces, sequence checks, the M-function handshake and M29 messages, all without a network.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../motion/soft_axis_cases.hpp"
#include "mock_port.hpp"
#include "tgm/config.hpp"
#include "tgm/service/engine.hpp"
#include "tgm/simulation.hpp"

namespace tgm::service {
namespace {

using test::MockPort;

Program line_program(int moves, bool with_m51 = false, bool with_message = false) {
  Program p;
  p.number_axes = 3;
  p.axis_letters = "XYZ";
  for (int i = 0; i < moves; ++i) {
    Segment s;
    s.type = SegmentType::kLinear;
    s.line = i + 1;
    s.end[0] = 0.1 * (i + 1);
    s.feed_mm_per_min = 6000;
    p.segments.push_back(s);
    if (with_m51 && i == 0) {
      Segment m;
      m.type = SegmentType::kMFunction;
      m.m_kind = MKind::kNormal;
      m.m = 51;
      m.line = 1;
      m.end = s.end;
      m.aux = static_cast<std::int32_t>(p.params.size());
      p.params.push_back(unset_params());
      p.segments.push_back(m);
    }
    if (with_message && i == 0) {
      Segment t;
      t.type = SegmentType::kMessage;
      t.line = 1;
      t.end = s.end;
      t.aux = static_cast<std::int32_t>(p.messages.size());
      p.messages.push_back("hello from M29");
      p.segments.push_back(t);
    }
  }
  Segment end;
  end.type = SegmentType::kMFunction;
  end.m_kind = MKind::kProgramEnd;
  end.m = 2;
  end.line = moves + 1;
  end.end = p.segments.back().end;
  p.segments.push_back(end);
  return p;
}

// Streams p whole into interpolator 0 as program `id`, starts it and cycles until it has ended
// (Status 3, also after an earlier program ended) or `max_cycles` have passed.
void run_to_end(Engine& e, MockPort& port, const Program& p, std::uint32_t id, int max_cycles) {
  port.add_chunk(0, p, 0, p.segments.size(), id, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  int cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.status != 3 && cycles++ < max_cycles);
}

Engine make_engine(EngineOptions o = {}) {
  auto e = Engine::create(MachineConfig::default_machine(), o);
  EXPECT_TRUE(e.has_value());
  return std::move(*e);
}

TEST(Engine, RoleTableFollowsDesignSectionOne) {
  EXPECT_EQ(role_violation(Role::kHmi, RequestKind::kStart, 0), "");
  EXPECT_NE(role_violation(Role::kPlc, RequestKind::kStart, 0).find("only the HMI starts"), std::string::npos);
  EXPECT_NE(role_violation(Role::kHmi, RequestKind::kWriteMFunc, 0), "");
  EXPECT_EQ(role_violation(Role::kPlc, RequestKind::kWriteMFunc, 0), "");
  EXPECT_NE(role_violation(Role::kHmi, RequestKind::kWriteRelSpeed, 0), "");
  EXPECT_NE(role_violation(Role::kPlc, RequestKind::kClear, 0), "");
  for (int code : {4, 5, 8, 9}) {
    EXPECT_EQ(role_violation(Role::kPlc, RequestKind::kCommand, code), "") << code;
    EXPECT_EQ(role_violation(Role::kHmi, RequestKind::kCommand, code), "") << code;
  }
  for (int code : {1024, 2048, 2049, -1, -2}) {
    EXPECT_EQ(role_violation(Role::kPlc, RequestKind::kCommand, code), "") << code;
    EXPECT_NE(role_violation(Role::kHmi, RequestKind::kCommand, code), "") << code;
  }
}

// EngineOptions::require_plc_setup (config plc.setup_before_start): a start and a program are
// refused, saying why, until the PLC reports its setup of that interpolator (a program loaded
// before would keep the PLC's Command 2048 out, review of session 81); the HMI cannot report
// it; the snapshot shows the gate (0 off, 1 waiting, 2 set up) per interpolator.
TEST(Engine, AStartWaitsForThePlcsSetupReportWhereTheConfigWantsIt) {
  EngineOptions o;
  o.require_plc_setup = true;
  Engine e = make_engine(o);
  MockPort port;
  const Program p = line_program(5);
  port.add_chunk(0, p, 0, p.segments.size(), 3, true);
  port.add_request(Role::kHmi, RequestKind::kStart);
  port.add_request(Role::kHmi, RequestKind::kPlcSetupDone);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 3 refused: the PLC has not set interpolator 0 up since tgm-service started "
            "(position, gear ratios): send it once the state shows plc_setup 2 "
            "(plc.setup_before_start)");
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kEmpty));
  ASSERT_EQ(port.replies.size(), 2u);
  EXPECT_EQ(port.replies[0].code, ReplyCode::kWrongState);
  EXPECT_EQ(port.replies[0].reason.view(),
            "the PLC has not set interpolator 0 up since tgm-service started (position, gear "
            "ratios): start tgm-plc or wait for its setup; a PLC of your own reports it with "
            "REQUEST_KIND_PLC_SETUP_DONE (plc.setup_before_start)");
  EXPECT_EQ(port.replies[1].code, ReplyCode::kWrongRole);
  EXPECT_EQ(port.last.ip[0].plc_setup, 1);
  EXPECT_EQ(port.last.ip[1].plc_setup, 1);
  // The report is per interpolator: 1's does not set 0 up.
  port.add_request(Role::kPlc, RequestKind::kPlcSetupDone, 1);
  port.add_request(Role::kHmi, RequestKind::kStart);
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 4u);
  EXPECT_EQ(port.replies[2].code, ReplyCode::kAccepted);
  EXPECT_EQ(port.replies[3].code, ReplyCode::kWrongState);
  EXPECT_EQ(port.last.ip[0].plc_setup, 1);
  EXPECT_EQ(port.last.ip[1].plc_setup, 2);
  // The opened gate is said once, to that interpolator's readers; a repeated report is not.
  ASSERT_EQ(port.messages.size(), 2u);
  EXPECT_EQ(port.messages[1].interpolator, 1);
  EXPECT_EQ(port.messages[1].severity, MessageOut::Severity::kInfo);
  EXPECT_EQ(port.messages[1].text.view(),
            "set up by the PLC 'test': starts and programs are accepted");
  port.add_request(Role::kPlc, RequestKind::kPlcSetupDone, 1);
  port.add_request(Role::kPlc, RequestKind::kPlcSetupDone);
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 6u);
  EXPECT_EQ(port.replies[4].code, ReplyCode::kAccepted);
  ASSERT_EQ(port.messages.size(), 3u);
  EXPECT_EQ(port.messages[2].interpolator, 0);
  port.add_chunk(0, p, 0, p.segments.size(), 4, true);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].program_id, 4u);
  port.add_request(Role::kHmi, RequestKind::kStart);
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 7u);
  EXPECT_EQ(port.replies[5].code, ReplyCode::kAccepted);
  EXPECT_EQ(port.replies[6].code, ReplyCode::kAccepted) << port.replies[6].reason.view();
  EXPECT_EQ(port.messages.size(), 3u);
  EXPECT_EQ(port.last.ip[0].plc_setup, 2);
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kRunning));
  // Without the option the gate is off and shown so.
  Engine plain = make_engine();
  MockPort other;
  other.add_request(Role::kHmi, RequestKind::kStart);
  plain.cycle(other, {});
  EXPECT_EQ(other.last.ip[0].plc_setup, 0);
  ASSERT_EQ(other.replies.size(), 1u);
  EXPECT_EQ(other.replies[0].reason.view().find("the PLC has not set"), std::string::npos);
  other.add_request(Role::kPlc, RequestKind::kPlcSetupDone);
  plain.cycle(other, {});
  EXPECT_TRUE(other.messages.empty());
}

TEST(Engine, RepliesSayWhy) {
  Engine e = make_engine();
  MockPort port;
  port.add_request(Role::kPlc, RequestKind::kStart);
  port.add_request(Role::kHmi, RequestKind::kStart);  // nothing loaded
  port.add_request(Role::kPlc, RequestKind::kWriteRelSpeed).value = 5.0;
  port.add_request(Role::kPlc, RequestKind::kWriteRelSpeed).value = 0.5;
  {
    RequestIn& ratio = port.add_request(Role::kPlc, RequestKind::kCommand);
    ratio.command = 1024;  // axis 1: 2000 inc / 1 mm
    ratio.command_parameter[0] = 1;
    ratio.command_parameter[1] = 2000;
    ratio.command_parameter[2] = 1;
  }
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 3;
  {
    RequestIn& offset = port.add_request(Role::kPlc, RequestKind::kWriteOffset);
    offset.axis = 2;
    offset.value = 1234.4;  // rounded to whole increments
  }
  port.add_request(Role::kHmi, RequestKind::kClear, 7);
  port.add_request(Role::kPlc, RequestKind::kWriteNumberAxes).value = 2.5;
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 9u);
  EXPECT_EQ(port.replies[0].code, ReplyCode::kWrongRole);
  EXPECT_EQ(port.replies[1].code, ReplyCode::kWrongState);
  EXPECT_EQ(port.replies[2].code, ReplyCode::kOutOfRange);
  EXPECT_EQ(port.replies[2].reason.view(), "Rel_Speed must be 0.01..2, not 5");
  EXPECT_EQ(port.replies[3].code, ReplyCode::kAccepted);
  EXPECT_EQ(port.replies[4].code, ReplyCode::kAccepted) << port.replies[4].reason.view();
  EXPECT_EQ(port.replies[5].code, ReplyCode::kBadRequest);
  EXPECT_EQ(port.replies[6].code, ReplyCode::kAccepted) << port.replies[6].reason.view();
  EXPECT_EQ(port.replies[7].code, ReplyCode::kBadRequest);
  EXPECT_EQ(port.replies[8].code, ReplyCode::kOutOfRange);
  // With the range and the value received (it said "must be a whole number" of 0 and 11 too).
  EXPECT_EQ(port.replies[8].reason.view(), "Number_Axes must be a whole number 1..10, not 2.5");
  for (int c = 0; c < 5; ++c) e.cycle(port, {});  // a stage command may finish in step()
  EXPECT_DOUBLE_EQ(port.last.ip[0].reg.ratio[1], 2000.0);
  EXPECT_EQ(port.last.ip[0].reg.offset[2], 1234);
  for (const auto& r : port.replies) {
    if (r.code != ReplyCode::kAccepted) {
      EXPECT_FALSE(r.reason.view().empty());
    }
    EXPECT_EQ(r.cycle, 0u);  // handled at the start of the first cycle
    EXPECT_EQ(r.client.view(), "test");
  }
  EXPECT_DOUBLE_EQ(port.last.ip[0].reg.rel_speed, 0.5);
}

// A stage command that has to wait for the smoothing is replied accepted at Command_Status 1;
// when it then ends with -1 (here a stop cancels it) the reason goes out as an error message
// (it stayed in command_error(), and the PLC believed its position set done).
TEST(Engine, AWaitingCommandThatEndsUnexecutedIsSaid) {
  Engine e = make_engine();
  MockPort port;
  {
    RequestIn& spline = port.add_request(Role::kPlc, RequestKind::kCommand);
    spline.command = -2;
    spline.command_parameter[0] = 500;
    spline.command_parameter[1] = 1'000'000;
  }
  e.cycle(port, {});
  const Program p = line_program(200);
  port.add_chunk(0, p, 0, p.segments.size(), 4, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 100; ++c) e.cycle(port, {});
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 8;
  e.cycle(port, {});
  int c = 0;
  while (port.last.ip[0].reg.act_speed != 0.0 && c++ < 10000) e.cycle(port, {});
  // The path stands; the spline still moves the axes (Status 4 once they stand).
  ASSERT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kRunning));
  port.replies.clear();
  {
    RequestIn& spline = port.add_request(Role::kPlc, RequestKind::kCommand);
    spline.command = -2;
    spline.command_parameter[0] = 200;
    spline.command_parameter[1] = 1'000'000;
  }
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 1u);
  EXPECT_EQ(port.replies[0].code, ReplyCode::kAccepted);
  ASSERT_EQ(port.last.ip[0].reg.command_status, 1);  // waits for the spline to drain
  port.messages.clear();
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 8;
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kError);
  EXPECT_EQ(port.messages[0].text.view(),
            "a command that waited for the smoothing was not executed: Command -2: cancelled by "
            "Command 8");
  EXPECT_EQ(port.messages[0].program_id, 4u);
}

// A client that discovery dropped (its lease lapsed) or that left is said to the HMIs: the
// sender of a stream that is not complete (the program will stop at the end of what is
// buffered), a PLC (with the M-function that waits). Nothing watched the clients before: a
// killed streaming tgm-hmi left its program to run dry in an underrun, and a killed tgm-plc an
// M-function waiting, without a word.
TEST(Engine, AClientThatIsGoneIsSaid) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(50, true);
  // Half of the program streamed: the sender is lost, then back.
  port.add_chunk(0, p, 0, 20, 7, false);
  e.cycle(port, {});
  port.messages.clear();
  PeerNotice n;
  n.kind = PeerNotice::Kind::kStreamLost;
  n.client.set("tgm-hmi-12-abcdef01");
  n.interpolator = 0;
  n.program_id = 7;
  port.peer_notices.push_back(n);
  n.kind = PeerNotice::Kind::kStreamBack;
  port.peer_notices.push_back(n);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 2u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kWarning);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 7: its sender 'tgm-hmi-12-abcdef01' gave no sign of life after 20 records "
            "(stopped, or network down): unless it returns, the motion stops at the buffer's end "
            "(Status 8); `tgm-hmi command clear` drops the rest");
  EXPECT_EQ(port.messages[0].program_id, 7u);
  EXPECT_EQ(port.messages[1].severity, MessageOut::Severity::kInfo);
  EXPECT_EQ(port.messages[1].text.view(), "program 7: its sender 'tgm-hmi-12-abcdef01' is back");
  // One that ended (its process left the domain).
  port.messages.clear();
  n.kind = PeerNotice::Kind::kStreamLost;
  n.ended = true;
  port.peer_notices.push_back(n);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 7: its sender 'tgm-hmi-12-abcdef01' ended after 20 records: the rest will not "
            "come, and the motion stops at the buffer's end (Status 8); `tgm-hmi command clear` "
            "drops it");
  // The longest it can be still ends with its advice: a name of 64 characters is cut to 40,
  // within the 255 bytes a message carries.
  port.messages.clear();
  n.client.set(std::string(64, 'n'));
  n.ended = false;
  port.peer_notices.push_back(n);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 7: its sender '" + std::string(37, 'n') +
                "...' gave no sign of life after 20 records (stopped, or network down): unless "
                "it returns, the motion stops at the buffer's end (Status 8); `tgm-hmi command "
                "clear` drops the rest");
  n.client.set("tgm-hmi-12-abcdef01");
  n.ended = false;
  // Another program's sender, or the sender of a complete stream, is not said.
  port.messages.clear();
  n.kind = PeerNotice::Kind::kStreamLost;
  n.program_id = 8;
  port.peer_notices.push_back(n);
  e.cycle(port, {});
  EXPECT_TRUE(port.messages.empty());
  port.add_chunk(0, p, 20, p.segments.size() - 20, 7, true);
  e.cycle(port, {});
  n.program_id = 7;
  port.peer_notices.push_back(n);
  e.cycle(port, {});
  EXPECT_TRUE(port.messages.empty());
  // A PLC: said on every interpolator, with the M-function that waits for it.
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 20000 && port.last.ip[0].reg.m_func == 0; ++c) e.cycle(port, {});
  ASSERT_EQ(port.last.ip[0].reg.m_func, 51);
  port.messages.clear();
  PeerNotice plc;
  plc.kind = PeerNotice::Kind::kPlcLost;
  plc.client.set("tgm-plc-3-0badc0de");
  port.peer_notices.push_back(plc);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 3u);
  EXPECT_EQ(port.messages[0].text.view(),
            "no sign of life from tgm-plc 'tgm-plc-3-0badc0de' (it stopped, or the network is "
            "down): M-functions wait for an acknowledgement until a PLC answers (M51 waits now)");
  EXPECT_EQ(port.messages[0].program_id, 7u);
  EXPECT_EQ(port.messages[1].interpolator, 1);
  EXPECT_EQ(port.messages[1].text.view().find("(M51"), std::string_view::npos);
  // A second PLC (a script run beside the machine's) that ends while the first is there: no
  // warning that M-functions wait, which the first one acknowledges.
  port.messages.clear();
  plc.ended = true;
  plc.client.set("tgm-plc-4-12345678");
  plc.other_plc.set("tgm-plc-3-0badc0de");
  port.peer_notices.push_back(plc);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 3u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kInfo);
  EXPECT_EQ(port.messages[0].text.view(),
            "tgm-plc 'tgm-plc-4-12345678' ended; tgm-plc 'tgm-plc-3-0badc0de' is there and "
            "acknowledges the M-functions");
  // Both names of 64 characters (a long --participant-prefix) are cut to 40 each, as every
  // name in these notices is: the whole text stays within the 255 bytes a message carries.
  port.messages.clear();
  plc.client.set(std::string(64, 'a'));
  plc.other_plc.set(std::string(64, 'b'));
  port.peer_notices.push_back(plc);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 3u);
  EXPECT_EQ(port.messages[0].text.view(), "tgm-plc '" + std::string(37, 'a') +
                                              "...' ended; tgm-plc '" + std::string(37, 'b') +
                                              "...' is there and acknowledges the M-functions");
  plc.client.set("tgm-plc-4-12345678");
  plc.other_plc.set("tgm-plc-3-0badc0de");
  // A second PLC that joins while one is there: a warning on every interpolator, as both
  // acknowledge the M-functions (an old closing-note item: nothing showed it).
  port.messages.clear();
  PeerNotice joined;
  joined.kind = PeerNotice::Kind::kPlcJoined;
  joined.client.set("tgm-plc-5-abcdef01");
  joined.other_plc.set("tgm-plc-3-0badc0de");
  port.peer_notices.push_back(joined);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const auto& m = port.messages[static_cast<std::size_t>(i)];
    EXPECT_EQ(m.interpolator, i);
    EXPECT_EQ(m.severity, MessageOut::Severity::kWarning);
    EXPECT_EQ(m.text.view(),
              "tgm-plc 'tgm-plc-5-abcdef01' joined beside tgm-plc 'tgm-plc-3-0badc0de': both "
              "acknowledge the M-functions (stop one unless that is meant)");
  }
  EXPECT_EQ(port.messages[0].program_id, 7u);
}

// Program id 0 is no program: refused with a message (a refusal of program 0 used to be
// swallowed, the "last refused" mark starting at 0, and it turned off the check for a program
// a position set dropped).
TEST(Engine, ProgramIdZeroIsRefusedAndSaid) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(3);
  port.add_chunk(0, p, 0, p.segments.size(), 0, true);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 0 refused: program id 0 is no program (number programs from 1)");
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kEmpty));
  EXPECT_EQ(port.last.ip[0].program_id, 0u);
  // The same again: counted, said once.
  port.add_chunk(0, p, 0, p.segments.size(), 0, true);
  e.cycle(port, {});
  EXPECT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(e.counters().refused_chunks, 2u);
}

TEST(Engine, RequestsBeyondTheBudgetWaitForTheNextCycle) {
  EngineOptions o;
  o.max_requests_per_cycle = 4;
  Engine e = make_engine(o);
  MockPort port;
  for (int i = 0; i < 10; ++i) port.add_request(Role::kPlc, RequestKind::kWriteRelSpeed).value = 1.0;
  e.cycle(port, {});
  EXPECT_EQ(port.replies.size(), 4u);
  e.cycle(port, {});
  e.cycle(port, {});
  EXPECT_EQ(port.replies.size(), 10u);
  EXPECT_EQ(port.replies.back().cycle, 2u);
}

TEST(Engine, ChunksAreAppliedInBoundedPiecesAndInOrder) {
  EngineOptions o;
  o.max_segments_per_cycle = 10;
  Engine e = make_engine(o);
  MockPort port;
  const Program p = line_program(99);  // 100 records
  port.add_chunk(0, p, 0, 64, 5, false);
  port.add_chunk(0, p, 64, 36, 5, true);
  std::uint64_t last = 0;
  for (int c = 0; c < 10; ++c) {
    e.cycle(port, {});
    const auto& s = port.last.ip[0];
    EXPECT_EQ(s.program_id, 5u);
    EXPECT_LE(s.next_sequence - last, 10u);
    last = s.next_sequence;
  }
  EXPECT_EQ(last, 100u);
  EXPECT_TRUE(port.chunks[0].empty());
  EXPECT_TRUE(port.messages.empty());
  EXPECT_EQ(e.counters().segments, 100u);
}

// The budget bounds the appends of a cycle over all interpolators (the cycle thread plans each
// record), and the interpolator served first rotates, so none starves while others stream.
TEST(Engine, ChunkBudgetIsSharedByAllInterpolatorsAndRotates) {
  EngineOptions o;
  o.max_segments_per_cycle = 10;
  Engine e = make_engine(o);
  ASSERT_EQ(e.count(), 3);
  MockPort port;
  const Program p = line_program(59);  // 60 records
  for (int i = 0; i < 3; ++i) port.add_chunk(i, p, 0, 60, 7 + i, true);
  std::array<std::uint64_t, 3> last{};
  std::array<int, 3> served_first{};
  for (int c = 0; c < 18; ++c) {
    e.cycle(port, {});
    std::uint64_t sum = 0;
    for (int i = 0; i < 3; ++i) {
      const std::uint64_t now = port.last.ip[static_cast<std::size_t>(i)].next_sequence;
      sum += now - last[static_cast<std::size_t>(i)];
      if (now - last[static_cast<std::size_t>(i)] == 10) ++served_first[static_cast<std::size_t>(i)];
      last[static_cast<std::size_t>(i)] = now;
    }
    EXPECT_EQ(sum, 10u) << "cycle " << c;  // the whole budget, never more
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(last[static_cast<std::size_t>(i)], 60u) << "interpolator " << i;
    EXPECT_EQ(served_first[static_cast<std::size_t>(i)], 6) << "interpolator " << i;
  }
  EXPECT_EQ(e.counters().segments, 180u);
}

// An emergency stop on the trajectory (Command 4) while the program still streams: the chunks
// that arrive during the ramp wait for its end instead of being refused, so after the restart
// the program runs to its end. Refused, they broke the stream (every later chunk a gap).
TEST(Engine, ChunksWaitWhileTheEmergencyRampRuns) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(999);  // 0.1 mm moves at F6000 to X99.9, then M2
  port.add_chunk(0, p, 0, 500, 9, false);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 400; ++c) e.cycle(port, {});
  ASSERT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kRunning));
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 4;
  e.cycle(port, {});
  ASSERT_EQ(port.last.ip[0].reg.status,
            static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp));
  port.add_chunk(0, p, 500, 500, 9, true);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].next_sequence, 500u);  // waits
  EXPECT_EQ(port.chunks[0].size(), 1u);
  int cycles = 0;
  while (port.last.ip[0].reg.status !=
             static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped) &&
         cycles++ < 2000) {
    e.cycle(port, {});
  }
  ASSERT_EQ(port.last.ip[0].reg.status,
            static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped));
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].next_sequence, 1000u);  // applied once the ramp ended
  EXPECT_TRUE(port.chunks[0].empty());
  port.add_request(Role::kHmi, RequestKind::kStart);
  cycles = 0;
  while (port.last.ip[0].reg.status != 3 && cycles++ < 100000) e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].reg.status, 3);
  EXPECT_EQ(port.last.ip[0].reg.orig_position[0], 0.1 * 999);
  for (const auto& m : port.messages) {
    EXPECT_NE(m.severity, MessageOut::Severity::kError) << m.text.view();
  }
}

// Command 5 (emergency stop, off the trajectory) while the program streams: the chunk that
// waited for the ramp, and every later one, is refused with the reason once the program has
// been dropped; the rest of the stream does not become a program of its own, and a new
// program loads as usual.
// Streams the first 500 records of p as program 9, starts it and runs 400 cycles: the
// program moves with the rest of its stream still to come.
void start_first_half(Engine& e, MockPort& port, const Program& p) {
  port.add_chunk(0, p, 0, 500, 9, false);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 400; ++c) e.cycle(port, {});
}

TEST(Engine, ChunksOfAProgramDroppedByAnOffTrajectoryStopAreRefused) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(999);
  start_first_half(e, port, p);
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 5;
  e.cycle(port, {});
  port.add_chunk(0, p, 500, 300, 9, false);
  int cycles = 0;
  while (port.last.ip[0].reg.status !=
             static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped) &&
         cycles++ < 2000) {
    e.cycle(port, {});
  }
  e.cycle(port, {});
  port.add_chunk(0, p, 800, 200, 9, true);
  e.cycle(port, {});
  EXPECT_TRUE(port.chunks[0].empty());
  EXPECT_EQ(port.last.ip[0].reg.status,
            static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped));
  EXPECT_EQ(port.last.ip[0].reg.off_trajectory, 1);
  EXPECT_EQ(port.last.ip[0].next_sequence, 500u);
  ASSERT_EQ(port.messages.size(), 1u);  // one message per refused program
  EXPECT_EQ(port.messages[0].program_id, 9u);
  EXPECT_NE(port.messages[0].text.view().find(
                "program 9 refused: program 9 was dropped by an off-trajectory stop"),
            std::string_view::npos)
      << port.messages[0].text.view();
  EXPECT_EQ(e.counters().refused_chunks, 2u);
  port.add_request(Role::kHmi, RequestKind::kStart);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].reg.status,
            static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped));
  // A new program from where the axes stand.
  Program q = line_program(9);
  const double x0 = port.last.ip[0].reg.orig_position[0];
  for (Segment& sg : q.segments) sg.end[0] += x0;
  port.add_chunk(0, q, 0, q.segments.size(), 10, true);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].program_id, 10u);
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
  EXPECT_EQ(port.last.ip[0].next_sequence, q.segments.size());
}

// An emergency stop (Command 4) with nothing loaded leaves no trajectory: the next program's
// stream loads without a clear and runs. Its first chunk was refused ("interpolator 0 still
// holds program 0 (status 7): clear it first").
TEST(Engine, AProgramLoadsAfterAnEmergencyStopWithNothingLoaded) {
  Engine e = make_engine();
  MockPort port;
  port.add_request(Role::kPlc, RequestKind::kCommand).command = 4;
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].reg.status,
            static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped));
  EXPECT_EQ(port.last.ip[0].reg.off_trajectory, 1);
  const Program p = line_program(20);
  run_to_end(e, port, p, 11, 20000);
  EXPECT_TRUE(port.messages.empty()) << port.messages[0].text.view();
  EXPECT_EQ(port.last.ip[0].program_id, 11u);
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
  EXPECT_EQ(port.last.ip[0].reg.orig_position[0], p.segments.back().end[0]);
}

// A position set (Command 2048 / 2049) of a program stopped on the trajectory is refused, with
// what to do: it dropped the program, the PLC's reply said "accepted" and the next start found
// nothing loaded (session 74). The program stays, the rest of its stream loads behind it and a
// start runs it to its end; after an off-trajectory stop the set is accepted.
TEST(Engine, APositionSetIsRefusedWhileAProgramIsLoaded) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(999);
  start_first_half(e, port, p);
  port.add_request(Role::kHmi, RequestKind::kCommand).command = 8;
  int cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.status != static_cast<std::int32_t>(InterpolatorStatus::kReady) &&
           cycles++ < 2000);
  ASSERT_EQ(port.last.ip[0].reg.act_speed, 0.0);
  ASSERT_EQ(port.last.ip[0].next_sequence, 500u);
  const double stopped_at = port.last.ip[0].reg.orig_position[0];
  for (const std::int32_t code : {2048, 2049}) {
    RequestIn& set = port.add_request(Role::kPlc, RequestKind::kCommand);
    set.command = code;
    set.command_parameter[0] = 5000;  // X = 5 mm
    e.cycle(port, {});
    EXPECT_EQ(port.replies.back().code, ReplyCode::kWrongState);
    EXPECT_EQ(port.replies.back().reason.view(),
              "Command " + std::to_string(code) +
                  ": a program is loaded, which a start would run from the new position (stop it "
                  "off the trajectory, Command 9 or 5, or clear it first)");
    EXPECT_EQ(port.last.ip[0].reg.command_status, -1);
  }
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
  EXPECT_EQ(port.last.ip[0].reg.orig_position[0], stopped_at);
  port.add_chunk(0, p, 500, 499, 9, true);
  e.cycle(port, {});
  EXPECT_TRUE(port.messages.empty()) << port.messages[0].text.view();
  EXPECT_EQ(port.last.ip[0].next_sequence, 999u);
  port.add_request(Role::kHmi, RequestKind::kStart);
  cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.status != static_cast<std::int32_t>(InterpolatorStatus::kEnded) &&
           cycles++ < 20000);
  EXPECT_EQ(port.last.ip[0].reg.orig_position[0], p.segments.back().end[0]);

  // Stopped off the trajectory (the program dropped), the set is accepted and puts X there.
  port.add_chunk(0, p, 0, 500, 10, false);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 400; ++c) e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kCommand).command = 9;
  cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.act_speed != 0.0 && cycles++ < 2000);
  RequestIn& set = port.add_request(Role::kPlc, RequestKind::kCommand);
  set.command = 2048;
  set.command_parameter[0] = 5000;
  cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.command_status != 0 && cycles++ < 2000);
  EXPECT_EQ(port.replies.back().code, ReplyCode::kAccepted) << port.replies.back().reason.view();
  EXPECT_EQ(port.last.ip[0].reg.off_trajectory, 0);
  EXPECT_NEAR(port.last.ip[0].reg.orig_position[0], 5.0, 1e-9);
}

// A ratio set at a position other than 0, or an Offset written while the axes move, steps
// PositionInc, which an enabled drive follows: it was only "accepted" (session 75). Now a
// warning names the axis, the step and its cause. The usual setup (a ratio at Position 0, an
// Offset at standstill to reference the axes) says nothing.
TEST(Engine, ARatioOrOffsetThatStepsPositionIncIsWarned) {
  Engine e = make_engine();
  MockPort port;
  const auto settle = [&] {
    int cycles = 0;
    do {
      e.cycle(port, {});
    } while (port.last.ip[0].reg.command_status != 0 && cycles++ < 2000);
  };
  const auto command = [&](std::int32_t code, std::array<std::int32_t, 3> p) {
    RequestIn& r = port.add_request(Role::kPlc, RequestKind::kCommand);
    r.command = code;
    for (std::size_t k = 0; k < p.size(); ++k) r.command_parameter[k] = p[k];
    settle();
    EXPECT_EQ(port.replies.back().code, ReplyCode::kAccepted) << port.replies.back().reason.view();
  };
  e.cycle(port, {});
  command(1024, {1, 2000, 1});     // Y at 0 mm: nothing steps
  command(2049, {10000, 0, 700});  // X at 10 mm, Z at 0.7 mm
  RequestIn& offset = port.add_request(Role::kPlc, RequestKind::kWriteOffset);
  offset.axis = 2;
  offset.value = 250;  // at standstill: referencing, not a step to warn of
  settle();
  EXPECT_TRUE(port.messages.empty()) << port.messages[0].text.view();
  ASSERT_EQ(port.last.ip[0].reg.position_inc[0], 10000);

  command(1024, {0, 2500, 1});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kWarning);
  EXPECT_EQ(port.messages[0].text.view(),
            "axis X: PositionInc stepped by 15000 inc (Ratio 1000 -> 2500 inc/mm at Position 10 "
            "mm): an enabled drive jumps with it (change them with the drive off, or set the "
            "position after, Command 2049)");
  EXPECT_EQ(port.last.ip[0].reg.position_inc[0], 25000);
  command(1024, {0, 2500, 1});  // the same ratio again: no step
  EXPECT_EQ(port.messages.size(), 1u);

  // Moving along X: an Offset of Z is a step in the middle of the motion.
  port.messages.clear();
  Program p = line_program(400);
  for (Segment& s : p.segments) s.end[0] += 10.0;
  port.add_chunk(0, p, 0, p.segments.size(), 3, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 100; ++c) e.cycle(port, {});
  ASSERT_GT(port.last.ip[0].reg.act_speed, 0.0);
  RequestIn& moving = port.add_request(Role::kPlc, RequestKind::kWriteOffset);
  moving.axis = 2;
  moving.value = -50;
  e.cycle(port, {});
  EXPECT_EQ(port.replies.back().code, ReplyCode::kAccepted) << port.replies.back().reason.view();
  ASSERT_EQ(port.messages.size(), 1u) << port.messages[1].text.view();
  const std::string text(port.messages[0].text.view());
  EXPECT_EQ(text.rfind("axis Z: PositionInc stepped by -300 inc (Offset 250 -> -50 inc, while "
                       "moving at ",
                       0),
            0u)
      << text;
  EXPECT_EQ(port.messages[0].program_id, 3u);
}

// M29 lines in a row come out in one cycle: each is sent, in order, with its line. Only the
// last was (review of the HMI, session 75: "first" of `M29 (first)` `M29 (second)` never
// reached any HMI, and the compiler's advice to split a long text over several M29 lines lost
// all but one piece).
TEST(Engine, MessagesInARowAreEachSent) {
  Engine e = make_engine();
  MockPort port;
  Program p = line_program(3);
  Segment last = p.segments.back();  // the end
  p.segments.pop_back();
  for (const char* text : {"first", "second", "third"}) {
    Segment t;
    t.type = SegmentType::kMessage;
    t.line = static_cast<std::int32_t>(10 + p.messages.size());
    t.end = p.segments.back().end;
    t.aux = static_cast<std::int32_t>(p.messages.size());
    p.messages.push_back(text);
    p.segments.push_back(t);
  }
  p.segments.push_back(last);
  run_to_end(e, port, p, 5, 20000);
  ASSERT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kEnded));
  std::vector<std::pair<std::string, std::int32_t>> said;
  for (const MessageOut& m : port.messages) said.emplace_back(m.text.view(), m.source_line);
  EXPECT_EQ(said, (std::vector<std::pair<std::string, std::int32_t>>{
                      {"first", 10}, {"second", 11}, {"third", 12}}));
  EXPECT_EQ(port.last.ip[0].message_counter, 3u);
  EXPECT_EQ(port.last.ip[0].message_text.view(), "third");
}

// A gap (chunks lost on the way: a sender the service's reader dropped and matched again) is
// said once, as a warning, and the program stays where it stands: the sender writes from there
// again, and a copy that overlaps what was taken gives its rest. An error here ended the run
// half-executed (the freeze test, session 92).
TEST(Engine, DuplicatesAreDroppedGapsWaitForTheRecordsBetweenForeignProgramsRefused) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(9);
  ASSERT_EQ(p.segments.size(), 10u);
  port.add_chunk(0, p, 0, 5, 5, false);
  port.add_chunk(0, p, 0, 5, 5, false);   // duplicate
  port.add_chunk(0, p, 7, 3, 5, true);    // gap (5, 6 missing)
  port.add_chunk(0, p, 8, 2, 5, true);    // behind the same gap: not said again
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].next_sequence, 5u);
  EXPECT_EQ(port.last.ip[0].program_id, 5u);
  EXPECT_EQ(e.counters().duplicate_chunks, 1u);
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kWarning);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 5: chunk 7 skips records 5..6 (lost on the way): dropped; the sender must "
            "write from record 5 again");
  EXPECT_EQ(port.messages[0].program_id, 5u);
  port.add_chunk(0, p, 3, 5, 5, false);  // records 3..7 written again: 5..7 are new
  port.add_chunk(0, p, 8, 2, 5, true);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].next_sequence, 10u);
  EXPECT_EQ(port.messages.size(), 1u);
  // Another program while program 5 is loaded: refused with a reason, program 5 untouched.
  port.add_chunk(0, p, 0, 10, 6, true);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 2u);
  // Whose it may be: a run that lost a race with another HMI was told to clear the winner's.
  EXPECT_EQ(port.messages[1].text.view(),
            "program 6 refused: interpolator 0 still holds program 5 (status 4), another "
            "sender's (an HMI may have loaded it just now): clear it first only if it is not "
            "wanted");
  EXPECT_EQ(port.last.ip[0].program_id, 5u);
  // After clear, the new program loads.
  port.add_request(Role::kHmi, RequestKind::kClear);
  port.add_chunk(0, p, 0, 10, 6, true);
  e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].program_id, 6u);
  EXPECT_EQ(port.last.ip[0].next_sequence, 10u);
  EXPECT_EQ(port.last.ip[0].reg.status, static_cast<std::int32_t>(InterpolatorStatus::kReady));
}

// Records hold positions by axis index: a program compiled for XYC, streamed to an XYZ
// interpolator, would drive Z as C. The service refuses it; a chunk that names no letters is
// checked only by its axis count. The snapshot names the letters for the state topic.
TEST(Engine, AProgramCompiledForOtherAxisLettersIsRefused) {
  Engine e = make_engine();
  MockPort port;
  Program rotary = line_program(4);
  rotary.axis_letters = "XYC";
  port.add_chunk(0, rotary, 0, rotary.segments.size(), 3, true);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.messages[0].severity, MessageOut::Severity::kError);
  EXPECT_EQ(port.messages[0].text.view(),
            "program 3 refused: compiled for axes XYC, interpolator 0 drives XYZ (the service's "
            "config): compile with that config");
  EXPECT_EQ(port.last.ip[0].program_id, 0u);
  EXPECT_EQ(port.last.ip[0].next_sequence, 0u);
  EXPECT_EQ(port.last.ip[0].axis_letters.view(), "XYZ");

  Program unnamed = line_program(4);
  unnamed.axis_letters.clear();
  port.add_chunk(0, unnamed, 0, unnamed.segments.size(), 4, true);
  const Program right = line_program(4);
  port.add_chunk(1, right, 0, right.segments.size(), 5, true);
  e.cycle(port, {});
  EXPECT_EQ(port.messages.size(), 1u);
  EXPECT_EQ(port.last.ip[0].program_id, 4u);
  EXPECT_EQ(port.last.ip[0].next_sequence, unnamed.segments.size());
  EXPECT_EQ(port.last.ip[1].program_id, 5u);
  EXPECT_EQ(port.last.ip[1].next_sequence, right.segments.size());

  // Number_Axes 2 (written by the PLC): the first two letters, and a 3-axis program is refused
  // by its count as before.
  port.add_request(Role::kHmi, RequestKind::kClear, 1);
  port.add_request(Role::kPlc, RequestKind::kWriteNumberAxes, 1).value = 2;
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 2u);
  EXPECT_EQ(port.replies[1].code, ReplyCode::kAccepted) << port.replies[1].reason.view();
  EXPECT_EQ(port.last.ip[1].axis_letters.view(), "XY");
  Program two = line_program(2);
  two.number_axes = 2;
  two.axis_letters = "XZ";
  port.add_chunk(1, two, 0, two.segments.size(), 6, true);
  e.cycle(port, {});
  ASSERT_EQ(port.messages.size(), 2u);
  EXPECT_NE(port.messages[1].text.view().find("compiled for axes XZ, interpolator 1 drives XY"),
            std::string_view::npos)
      << port.messages[1].text.view();
}

// The snapshot carries the digest of what shapes each interpolator's motion, over the axes in
// use (InterpolatorState.machine_digest): a client simulating with its own config compares it.
TEST(Engine, TheSnapshotCarriesTheMachineDigestOfTheAxesInUse) {
  const MachineConfig m = MachineConfig::default_machine();
  Engine e = make_engine();
  MockPort port;
  e.cycle(port, {});
  for (int i = 0; i < e.count(); ++i) {
    EXPECT_EQ(port.last.ip[static_cast<std::size_t>(i)].machine_digest, machine_digest(m, i, 3))
        << i;
  }
  port.add_request(Role::kPlc, RequestKind::kWriteNumberAxes, 2).value = 2;
  e.cycle(port, {});
  ASSERT_EQ(port.replies.size(), 1u);
  EXPECT_EQ(port.replies[0].code, ReplyCode::kAccepted) << port.replies[0].reason.view();
  EXPECT_EQ(port.last.ip[2].machine_digest, machine_digest(m, 2, 2));
  EXPECT_NE(port.last.ip[2].machine_digest, machine_digest(m, 2, 3));
  EXPECT_EQ(port.last.ip[0].machine_digest, machine_digest(m, 0, 3));
}

TEST(Engine, NormalMFunctionWaitsForTheAckAndResumesInTheSameCycle) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(3, /*with_m51=*/true, /*with_message=*/true);
  port.add_chunk(0, p, 0, p.segments.size(), 9, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  int cycles = 0;
  while (port.last.ip[0].reg.m_func != 51 && cycles++ < 20000) e.cycle(port, {});
  ASSERT_EQ(port.last.ip[0].reg.m_func, 51);
  const std::int32_t part = port.last.ip[0].reg.act_part;
  for (int i = 0; i < 1000; ++i) e.cycle(port, {});  // 0.5 s without an ack
  EXPECT_EQ(port.last.ip[0].reg.m_func, 51);
  EXPECT_EQ(port.last.ip[0].reg.act_part, part);
  // An acknowledgement naming another M-function (a late note of a continuous one) is refused
  // and leaves M51 waiting; the one naming M51 releases it.
  // So does one naming M51 by another m_func_count (a delayed acknowledgement of an M51 of a
  // program cleared meanwhile).
  const std::uint32_t count = port.last.ip[0].reg.m_func_count;
  EXPECT_EQ(count, 1u);
  auto acknowledge = [&](std::int32_t m, std::uint32_t c = 0) {
    RequestIn& ack = port.add_request(Role::kPlc, RequestKind::kWriteMFunc);
    ack.value = 0;
    ack.m_func_acknowledged = m;
    ack.m_func_count_acknowledged = c;
    e.cycle(port, {});
    return port.replies.back().code;
  };
  EXPECT_EQ(acknowledge(1001), ReplyCode::kWrongState);
  EXPECT_EQ(acknowledge(51, count + 7), ReplyCode::kWrongState);
  EXPECT_EQ(port.last.ip[0].reg.m_func, 51);
  EXPECT_EQ(port.last.ip[0].reg.act_part, part);
  EXPECT_EQ(acknowledge(51, count), ReplyCode::kAccepted);
  EXPECT_EQ(port.last.ip[0].reg.m_func, 0);
  EXPECT_GT(port.last.ip[0].reg.act_part, part) << "resumes in the cycle the ack is applied in";
  cycles = 0;
  while (port.last.ip[0].reg.status != 3 && cycles++ < 20000) e.cycle(port, {});
  EXPECT_EQ(port.last.ip[0].reg.status, 3);
  // The M29 text went out as a message and into the state.
  // It names its program, its own line and the cycle it went out in.
  const MessageOut* m29 = nullptr;
  for (const auto& m : port.messages) {
    if (m.text.view() == "hello from M29") m29 = &m;
  }
  ASSERT_NE(m29, nullptr);
  EXPECT_EQ(m29->program_id, 9u);
  EXPECT_EQ(m29->source_line, 1);
  EXPECT_GT(m29->cycle, 0u);
  EXPECT_LT(m29->cycle, e.cycles());
  EXPECT_EQ(port.last.ip[0].message_text.view(), "hello from M29");
  EXPECT_EQ(port.last.ip[0].message_counter, 1u);
}

// A program with two equal continuous M-functions in a row and a normal one after them, as
// the engine receives it: line, M1001, M1001, line, M50, line, M2.
Program equal_m_program() {
  Program p;
  p.number_axes = 3;
  p.axis_letters = "XYZ";
  auto line = [&](double x) {
    Segment s;
    s.type = SegmentType::kLinear;
    s.line = static_cast<std::int32_t>(p.segments.size()) + 1;
    s.end[0] = x;
    s.feed_mm_per_min = 3000;
    p.segments.push_back(s);
  };
  auto m = [&](std::int32_t number, MKind kind) {
    Segment s;
    s.type = SegmentType::kMFunction;
    s.m_kind = kind;
    s.m = number;
    s.line = static_cast<std::int32_t>(p.segments.size()) + 1;
    s.end = p.segments.back().end;
    if (kind != MKind::kProgramEnd) {
      s.aux = static_cast<std::int32_t>(p.params.size());
      p.params.push_back(unset_params());
    }
    p.segments.push_back(s);
  };
  line(5.0);
  m(1001, MKind::kContinuous);
  m(1001, MKind::kContinuous);
  line(10.0);
  m(50, MKind::kNormal);
  line(15.0);
  m(2, MKind::kProgramEnd);
  return p;
}

// Runs equal_m_program() to its end, acknowledging M50 at once; returns every cycle's snapshot
// registers of interpolator 0 as events see them.
std::vector<EventRegisters> run_equal_m(Engine& e, MockPort& port) {
  const Program p = equal_m_program();
  port.add_chunk(0, p, 0, p.segments.size(), 3, true);
  std::vector<EventRegisters> cycles;
  auto cycle = [&] {
    e.cycle(port, {});
    cycles.push_back(event_registers(port.last.ip[0].reg));
  };
  cycle();
  port.add_request(Role::kHmi, RequestKind::kStart);
  for (int c = 0; c < 40000 && port.last.ip[0].reg.status != 3; ++c) {
    cycle();
    const Registers& r = port.last.ip[0].reg;
    if (r.m_func == 50 && run_flag_waits_for_m(r.run_flag)) {
      RequestIn& ack = port.add_request(Role::kPlc, RequestKind::kWriteMFunc);
      ack.m_func_acknowledged = 50;
    }
  }
  EXPECT_EQ(port.last.ip[0].reg.status, 3);
  return cycles;
}

// Every cycle whose M-function handshake or status registers differ from the cycle before
// queues one event with them, in order, numbered without gaps: the event topic shows what the
// newest-value snapshot merges (M1001 twice in successive cycles, told apart by the count).
TEST(Engine, EveryEventRegisterChangeIsQueuedInItsCycle) {
  Engine e = make_engine();
  MockPort port;
  const std::vector<EventRegisters> cycles = run_equal_m(e, port);
  // The idle interpolators 1 and 2 have their first cycle's event only.
  std::vector<EventOut> events;
  std::array<int, 3> per_interpolator{};
  for (const EventOut& ev : port.events) {
    ++per_interpolator[static_cast<std::size_t>(ev.interpolator)];
    if (ev.interpolator == 0) events.push_back(ev);
  }
  EXPECT_EQ(per_interpolator[1], 1);
  EXPECT_EQ(per_interpolator[2], 1);
  ASSERT_FALSE(events.empty());
  std::map<std::uint64_t, const EventOut*> by_cycle;
  for (std::size_t k = 0; k < events.size(); ++k) {
    const EventOut& ev = events[k];
    EXPECT_EQ(ev.counter, k + 1);
    if (k > 0) {
      EXPECT_GT(ev.reg.cycle, events[k - 1].reg.cycle);
    }
    by_cycle[ev.reg.cycle] = &ev;
  }
  int changes = 0;
  for (std::size_t k = 1; k < cycles.size(); ++k) {
    const EventRegisters& a = cycles[k - 1];
    const EventRegisters& b = cycles[k];
    if (a.status == b.status && a.run_flag == b.run_flag && a.m_func == b.m_func &&
        a.m_func_count == b.m_func_count && a.command_status == b.command_status) {
      continue;
    }
    ++changes;
    const auto it = by_cycle.find(b.cycle);
    ASSERT_NE(it, by_cycle.end()) << "no event for the change in cycle " << b.cycle;
    EXPECT_EQ(it->second->reg.status, b.status);
    EXPECT_EQ(it->second->reg.run_flag, b.run_flag);
    EXPECT_EQ(it->second->reg.m_func, b.m_func);
    EXPECT_EQ(it->second->reg.m_func_count, b.m_func_count);
  }
  EXPECT_GT(changes, 5);
  // The M-functions as a PLC sees them on the events: one per count.
  std::vector<std::pair<std::uint32_t, std::int32_t>> ms;
  std::vector<std::uint64_t> at;
  for (const EventOut& ev : events) {
    if (ev.reg.m_func != 0 && (ms.empty() || ms.back().first != ev.reg.m_func_count)) {
      ms.emplace_back(ev.reg.m_func_count, ev.reg.m_func);
      at.push_back(ev.reg.cycle);
    }
  }
  using M = std::pair<std::uint32_t, std::int32_t>;
  ASSERT_EQ(ms, (std::vector<M>{{1u, 1001}, {2u, 1001}, {3u, 50}}));
  EXPECT_EQ(at[1], at[0] + 1);
  EXPECT_EQ(e.counters().lost_events, 0u);

  // A queue that takes only 4: the rest are counted as lost, not queued out of order.
  Engine small = make_engine();
  MockPort full;
  full.event_capacity = 4;
  run_equal_m(small, full);
  ASSERT_EQ(full.events.size(), 4u);
  EXPECT_EQ(full.events.back().interpolator, 0);
  EXPECT_EQ(full.events.back().counter, 2u);
  EXPECT_EQ(small.counters().lost_events, port.events.size() - 4);
}

// tgm-service --check-limits: the live checker reports, as HMI warnings, exactly the excesses
// the offline simulation's checker finds in the same program (axis, quantity, size, limit,
// line), the first max_limit_messages of them in detail, and counts them all.
TEST(Engine, CheckLimitsReportsWhatTheOfflineCheckerFinds) {
  // Y's jerk limit 700 x below X's (soft_axis_cases.hpp): kept at the full limits; at 99 % of
  // them (--limit-share 0.99) the planner's rides at 99.9 % are hundreds of excesses.
  const tgm::test::SoftAxisCase soft = tgm::test::soft_axis_cases().front();
  const MachineConfig m = soft.machine();
  const Program p = soft.program();
  auto offline = [&](double share) {
    SimulationOptions so;
    so.check_limits = true;
    so.limit_share = share;
    auto sim = Simulation::create(m, so);
    EXPECT_TRUE(sim);
    return sim->run(p);
  };
  const SimulationSummary kept = offline(1.0), tight = offline(0.99);
  ASSERT_EQ(kept.result, StepResult::kFinished);
  ASSERT_EQ(kept.violation_count, 0u);
  ASSERT_EQ(tight.result, StepResult::kFinished);
  ASSERT_GT(tight.violation_count, static_cast<std::uint64_t>(EngineOptions{}.max_limit_messages));

  struct Run {
    bool check;
    double share;
    int cap;
    const SimulationSummary* expect;
  };
  for (const Run& run : {Run{false, 0.99, 16, nullptr}, Run{true, 1.0, 16, &kept},
                         Run{true, 0.99, 16, &tight}, Run{true, 0.99, 1, &tight}}) {
    SCOPED_TRACE(::testing::Message()
                 << "check " << run.check << " share " << run.share << " cap " << run.cap);
    EngineOptions o;
    o.check_limits = run.check;
    o.limit_share = run.share;
    o.max_limit_messages = run.cap;
    auto e = Engine::create(m, o);
    ASSERT_TRUE(e);
    MockPort port;
    run_to_end(*e, port, p, 3, 400000);
    ASSERT_EQ(port.last.ip[0].reg.status, 3);
    std::vector<MessageOut> warnings;
    for (const auto& msg : port.messages) {
      if (msg.severity == MessageOut::Severity::kWarning) warnings.push_back(msg);
    }
    if (!run.check) {
      EXPECT_TRUE(warnings.empty());
      EXPECT_EQ(e->counters().limit_violations, 0u);
      continue;
    }
    const SimulationSummary& expect = *run.expect;
    EXPECT_EQ(e->counters().limit_violations, expect.violation_count);
    const std::size_t detail =
        std::min<std::size_t>(expect.violation_count, static_cast<std::size_t>(run.cap));
    const bool more = expect.violation_count > detail;
    ASSERT_EQ(warnings.size(), detail + (more ? 1 : 0));
    if (more) {
      EXPECT_NE(std::string(warnings.back().text.view())
                    .find("more in this program are counted, not reported"),
                std::string::npos);
    }
    for (std::size_t k = 0; k < detail; ++k) {
      const LimitViolation& v = expect.violations[k];
      char text[160];
      std::snprintf(text, sizeof text, "limit excess: axis %c %s %.6g > %.6g mm/s",
                    v.axis == 0 ? 'X' : 'Y', limit_quantity_name(v.quantity), v.value, v.limit);
      EXPECT_EQ(std::string(warnings[k].text.view()).rfind(text, 0), 0u) << warnings[k].text.view();
      EXPECT_EQ(warnings[k].source_line, v.line);
      EXPECT_EQ(warnings[k].interpolator, 0);
    }
  }
}

// A position set (Command 2048) moves Orig_Position by design between two checked programs: the
// live checker does not report the jump as motion (here 100 mm in one cycle, 200 m/s on X, which
// every limit of the machine flags), and it checks the motion after it as before.
TEST(Engine, CheckLimitsIgnoresAPositionSetBetweenPrograms) {
  EngineOptions o;
  o.check_limits = true;
  Engine e = make_engine(o);
  MockPort port;
  const Program p = line_program(40);
  run_to_end(e, port, p, 1, 100000);
  ASSERT_EQ(port.last.ip[0].reg.status, 3);
  ASSERT_EQ(e.counters().limit_violations, 0u);
  const double x_end = port.last.ip[0].reg.orig_position[0];
  EXPECT_NEAR(x_end, 4.0, 1e-9);

  const double ratio = port.last.ip[0].reg.ratio[0];  // inc per mm
  RequestIn& set = port.add_request(Role::kPlc, RequestKind::kCommand);
  set.command = 2048;
  set.command_parameter[0] = static_cast<std::int32_t>(std::lround((x_end + 100.0) * ratio));
  double largest_jump = 0.0;
  for (int c = 0; c < 10; ++c) {
    const double before = port.last.ip[0].reg.orig_position[0];
    e.cycle(port, {});
    largest_jump = std::max(largest_jump, std::fabs(port.last.ip[0].reg.orig_position[0] - before));
  }
  ASSERT_EQ(port.replies.back().code, ReplyCode::kAccepted) << port.replies.back().reason.view();
  EXPECT_NEAR(port.last.ip[0].reg.orig_position[0], x_end + 100.0, 1.0 / ratio);
  EXPECT_GT(largest_jump, 99.0);  // in one cycle: no motion could do that
  EXPECT_EQ(e.counters().limit_violations, 0u);

  // The next program starts at the new position (a 100 mm move back to its first point) and is
  // checked across its whole run.
  run_to_end(e, port, p, 2, 100000);
  ASSERT_EQ(port.last.ip[0].reg.status, 3);
  EXPECT_EQ(e.counters().limit_violations, 0u);
  for (const auto& msg : port.messages)
    EXPECT_NE(msg.severity, MessageOut::Severity::kWarning) << msg.text.view();
}

// Whatever a client sends (any kind, role, interpolator, Command code, parameter, axis and
// value, NaN and infinities included), in the middle of a running program: every request is
// answered exactly once, a refusal says why, and the registers stay finite. Seeded sweep.
TEST(Engine, RandomRequestsAreEachAnsweredOnceAndNeverBreakTheCycle) {
  Engine e = make_engine();
  MockPort port;
  std::mt19937_64 rng(20261121);
  auto any = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  const Program p = line_program(400, true, true);
  port.add_chunk(0, p, 0, p.segments.size(), 1, true);
  port.add_request(Role::kHmi, RequestKind::kStart);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double values[] = {std::nan(""), kInf, -kInf, 0.0, 1.0, 0.5, 2.5, -1.0, 1e300, -1e300, 1e-300, 1234.4};
  const std::int32_t codes[] = {4, 5, 8, 9, 1024, 2048, 2049, -1, -2, 0, 3, 7, 1025, -3, 4096,
                                std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()};
  const std::int32_t params[] = {0, 1, -1, 2, 3, 50, 500, 1000000, std::numeric_limits<std::int32_t>::min(),
                                 std::numeric_limits<std::int32_t>::max()};
  const int interpolators[] = {0, 0, 0, 1, 2, 3, -1, 1000};
  const RequestKind kinds[] = {RequestKind::kCommand,       RequestKind::kWriteMFunc,  RequestKind::kWriteRelSpeed,
                               RequestKind::kWriteOffset,   RequestKind::kWriteRatio,  RequestKind::kWriteNumberAxes,
                               RequestKind::kStart,         RequestKind::kStop,        RequestKind::kClear,
                               RequestKind::kUnknown};
  std::uint64_t sent = 1;
  for (int c = 0; c < 3000; ++c) {
    const int n = any(4);
    for (int k = 0; k < n; ++k) {
      RequestIn& r = port.add_request(any(2) ? Role::kPlc : Role::kHmi, kinds[any(10)], interpolators[any(8)]);
      r.command = codes[any(17)];
      for (auto& q : r.command_parameter) q = params[any(10)];
      r.axis = any(14) - 2;
      r.value = values[any(12)];
      ++sent;
    }
    e.cycle(port, {});
    for (int i = 0; i < e.count(); ++i) {
      const Registers& reg = port.last.ip[static_cast<std::size_t>(i)].reg;
      for (int a = 0; a < reg.number_axes; ++a) {
        ASSERT_TRUE(std::isfinite(reg.orig_position[static_cast<std::size_t>(a)])) << "cycle " << c;
        ASSERT_TRUE(std::isfinite(reg.position[static_cast<std::size_t>(a)])) << "cycle " << c;
      }
      ASSERT_TRUE(std::isfinite(reg.act_speed)) << "cycle " << c;
      ASSERT_TRUE(std::isfinite(reg.rel_speed) && reg.rel_speed > 0.0 && reg.rel_speed <= 2.0) << "cycle " << c;
    }
  }
  for (int c = 0; c < 100 && !port.requests.empty(); ++c) e.cycle(port, {});
  ASSERT_TRUE(port.requests.empty());
  ASSERT_EQ(port.replies.size(), sent);
  std::map<std::uint64_t, int> answered;
  std::map<ReplyCode, int> by_code;
  for (const ReplyOut& r : port.replies) {
    ++answered[r.request_id];
    ++by_code[r.code];
    EXPECT_LE(static_cast<int>(r.code), static_cast<int>(ReplyCode::kBusy));
    if (r.code != ReplyCode::kAccepted) {
      EXPECT_FALSE(r.reason.view().empty()) << r.request_id;
    }
  }
  EXPECT_EQ(answered.size(), sent);
  for (const auto& [id, times] : answered) EXPECT_EQ(times, 1) << "request " << id;
  // The sweep reached acceptance and the refusals (not only one kind of answer).
  EXPECT_GT(by_code[ReplyCode::kAccepted], 100);
  EXPECT_GT(by_code[ReplyCode::kWrongRole], 100);
  EXPECT_GT(by_code[ReplyCode::kOutOfRange] + by_code[ReplyCode::kBadRequest], 100);
}

// The shutdown of tgm-service (Engine::wind_down): an interpolator in motion gets a normal stop
// on the trajectory and the HMIs a warning that says why; wind_down() is true once the motion
// and its smoothing stand, and the program stays resumable (Status 4). Idle interpolators get
// neither a stop nor a message.
TEST(Engine, WindDownStopsTheMotionOnTheTrajectoryAndSaysWhy) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(2000);  // 200 mm at F6000
  port.add_chunk(0, p, 0, p.segments.size(), 7, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart);
  int cycles = 0;
  do {
    e.cycle(port, {});
  } while (port.last.ip[0].reg.act_speed < 5990.0 && ++cycles < 100000);
  ASSERT_GE(port.last.ip[0].reg.act_speed, 5990.0);  // at the feed (0.1 mm chords)
  const double x_at_stop = port.last.ip[0].reg.orig_position[0];
  char expected[160];
  std::snprintf(expected, sizeof expected,
                "tgm-service is stopping: normal stop on the trajectory (Command 8) at %.0f mm/min "
                "on line %d",
                port.last.ip[0].reg.act_speed, port.last.ip[0].reg.act_line);
  const std::size_t messages_before = port.messages.size();
  EXPECT_FALSE(e.wind_down(port));
  EXPECT_EQ(e.wound_down(), 1);
  ASSERT_EQ(port.messages.size(), messages_before + 1);
  const MessageOut& m = port.messages.back();
  EXPECT_EQ(m.interpolator, 0);
  EXPECT_EQ(m.severity, MessageOut::Severity::kWarning);
  EXPECT_EQ(m.program_id, 7u);
  EXPECT_EQ(std::string(m.text.view()), expected);
  cycles = 0;
  bool rest = false;
  while (!rest && ++cycles < 100000) {
    e.cycle(port, {});
    rest = e.wind_down(port);
  }
  ASSERT_TRUE(rest);
  EXPECT_EQ(port.messages.size(), messages_before + 1);  // said once
  EXPECT_EQ(e.wound_down(), 1);
  const Registers& r = port.last.ip[0].reg;
  EXPECT_EQ(r.act_speed, 0.0);
  EXPECT_EQ(r.status, 4);  // on the trajectory: resumable
  EXPECT_GT(r.orig_position[0], x_at_stop);
  EXPECT_LT(r.orig_position[0], 200.0);
  // Interpolators 1 and 2 stood idle throughout: nothing was sent for them.
  for (const MessageOut& each : port.messages) EXPECT_EQ(each.interpolator, 0);
}

// A program that stands (here at an M-function the PLC has not acknowledged) is not stopped,
// but its HMIs are told the service goes: without the warning a `tgm-hmi run` waiting at M51
// took the silence for a network outage and waited for good (session 76's review).
TEST(Engine, WindDownOfAStandingProgramIsAtOnceAndSaidToItsHmis) {
  Engine e = make_engine();
  MockPort port;
  const Program p = line_program(20, true);
  port.add_chunk(1, p, 0, p.segments.size(), 9, true);
  e.cycle(port, {});
  port.add_request(Role::kHmi, RequestKind::kStart, 1);
  for (int c = 0; c < 20000 && port.last.ip[1].reg.m_func == 0; ++c) e.cycle(port, {});
  ASSERT_EQ(port.last.ip[1].reg.m_func, 51);
  for (int c = 0; c < 100; ++c) e.cycle(port, {});  // the smoothing settles
  const std::size_t before = port.messages.size();
  EXPECT_TRUE(e.wind_down(port));
  EXPECT_EQ(e.wound_down(), 0);
  EXPECT_EQ(e.announced(), 1);
  ASSERT_EQ(port.messages.size(), before + 1);
  const MessageOut& m = port.messages.back();
  EXPECT_EQ(m.interpolator, 1);
  EXPECT_EQ(m.severity, MessageOut::Severity::kWarning);
  EXPECT_EQ(m.program_id, 9u);
  EXPECT_EQ(std::string(m.text.view()),
            "tgm-service is stopping: the motion stands (Status 1, waiting for M51) on line 1");
  EXPECT_TRUE(e.wind_down(port));
  EXPECT_EQ(port.messages.size(), before + 1);  // said once
}

TEST(Engine, WindDownOfStandingInterpolatorsIsAtOnceAndSilent) {
  Engine e = make_engine();
  MockPort port;
  e.cycle(port, {});
  EXPECT_TRUE(e.wind_down(port));
  EXPECT_EQ(e.wound_down(), 0);
  EXPECT_EQ(e.announced(), 0);
  EXPECT_TRUE(port.messages.empty());
}

}  // namespace
}  // namespace tgm::service
