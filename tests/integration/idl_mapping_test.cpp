// Mapping between core intercode and the generated DDS types (idl/mapping): round trips through
// chunks and through the CDR wire format, chunk bounds, and rejection of bad wire records.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "tgm/idl_mapping.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm {
namespace {

using mapping::MapStatus;

bool same_segment(const Segment& a, const Segment& b) {
  return a.type == b.type && a.plane == b.plane && a.compensation == b.compensation &&
         a.m_kind == b.m_kind && a.line == b.line && a.m == b.m && a.tool == b.tool &&
         a.turns == b.turns && a.aux == b.aux && a.end == b.end && a.center == b.center &&
         a.radius == b.radius && a.feed_mm_per_min == b.feed_mm_per_min &&
         a.dwell_s == b.dwell_s && a.compensation_radius_mm == b.compensation_radius_mm;
}

void expect_same_program(const Program& a, const Program& b) {
  ASSERT_EQ(a.segments.size(), b.segments.size());
  for (std::size_t i = 0; i < a.segments.size(); ++i) {
    ASSERT_TRUE(same_segment(a.segments[i], b.segments[i])) << "record " << i;
  }
  EXPECT_EQ(a.params, b.params);
  EXPECT_EQ(a.messages, b.messages);
  EXPECT_EQ(a.number_axes, b.number_axes);
  EXPECT_EQ(a.axis_letters, b.axis_letters);
}

Segment line_to(double x, double y, int line) {
  Segment s;
  s.type = SegmentType::kLinear;
  s.line = line;
  s.end[0] = x;
  s.end[1] = y;
  s.feed_mm_per_min = 1200.0;
  return s;
}

// A small program with every kind of record, side tables in the order records use them.
Program sample_program() {
  Program p;
  p.number_axes = 4;
  p.axis_letters = "XYZA";
  Segment rapid;
  rapid.type = SegmentType::kRapid;
  rapid.line = 1;
  rapid.end = {1, 2, 3, 4, 0, 0, 0, 0, 0, 0};
  p.segments.push_back(rapid);
  p.segments.push_back(line_to(10.5, -2.25, 2));
  Segment arc;
  arc.type = SegmentType::kArcCcw;
  arc.plane = Plane::kXZ;
  arc.compensation = Compensation::kLeft;
  arc.compensation_radius_mm = 3.0;
  arc.line = 3;
  arc.turns = 2;
  arc.tool = 7;
  arc.end = {0.1, 0.2, 0.3, 0.4, 0, 0, 0, 0, 0, 0};
  arc.center = {-5.5, 6.25};
  arc.radius = 12.5;
  arc.feed_mm_per_min = 800.0;
  p.segments.push_back(arc);
  Segment m;
  m.type = SegmentType::kMFunction;
  m.m_kind = MKind::kNormal;
  m.m = 50;
  m.line = 4;
  m.aux = 0;
  MParams params = unset_params();
  params['S' - 'A'] = 1200.0;
  params['Q' - 'A'] = -0.5;
  p.params.push_back(params);
  p.segments.push_back(m);
  Segment cont = m;
  cont.m = 1005;
  cont.m_kind = MKind::kContinuous;
  cont.aux = -1;  // an M record without parameters
  cont.line = 5;
  p.segments.push_back(cont);
  Segment msg;
  msg.type = SegmentType::kMessage;
  msg.line = 6;
  msg.aux = 0;
  p.messages.emplace_back("tool change: T7 (\xc3\xa9paisseur 3 mm)");
  p.segments.push_back(msg);
  Segment empty_msg = msg;
  empty_msg.aux = 1;
  empty_msg.line = 7;
  p.messages.emplace_back("");
  p.segments.push_back(empty_msg);
  Segment dwell;
  dwell.type = SegmentType::kDwell;
  dwell.dwell_s = 1.5;
  dwell.line = 8;
  p.segments.push_back(dwell);
  Segment end;
  end.type = SegmentType::kMFunction;
  end.m_kind = MKind::kProgramEnd;
  end.m = 30;
  end.line = 9;
  p.segments.push_back(end);
  return p;
}

// Seeded random program: mostly G1, some arcs, M records with random letters, messages of
// random length up to the bound.
Program random_program(std::uint32_t seed, std::size_t count) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(-1000.0, 1000.0);
  std::uniform_int_distribution<int> pick(0, 99);
  std::uniform_int_distribution<int> letter(0, kParamLetters - 1);
  std::uniform_int_distribution<int> len(0, static_cast<int>(mapping::kMaxTextLength));
  Program p;
  p.number_axes = 10;
  p.axis_letters = "XYZABCUVWE";
  for (std::size_t i = 0; i < count; ++i) {
    Segment s;
    s.line = static_cast<std::int32_t>(i + 1);
    for (double& e : s.end) e = coord(rng);
    const int k = pick(rng);
    if (k < 80) {
      s.type = SegmentType::kLinear;
      s.feed_mm_per_min = std::abs(coord(rng));
    } else if (k < 90) {
      s.type = (k % 2 == 0) ? SegmentType::kArcCw : SegmentType::kArcCcw;
      s.plane = static_cast<Plane>(17 + k % 3);
      s.center = {coord(rng), coord(rng)};
      s.radius = std::abs(coord(rng));
      s.feed_mm_per_min = std::abs(coord(rng));
    } else if (k < 96) {
      s.type = SegmentType::kMFunction;
      s.m_kind = MKind::kNormal;
      s.m = 100 + k;
      if (k % 2 == 0) {
        MParams params = unset_params();
        for (int j = 0; j < 3; ++j) params[static_cast<std::size_t>(letter(rng))] = coord(rng);
        s.aux = static_cast<std::int32_t>(p.params.size());
        p.params.push_back(params);
      }
    } else {
      s.type = SegmentType::kMessage;
      s.aux = static_cast<std::int32_t>(p.messages.size());
      std::string text(static_cast<std::size_t>(len(rng)), ' ');
      for (char& c : text) c = static_cast<char>('!' + pick(rng) % 90);
      p.messages.push_back(text);
    }
    p.segments.push_back(s);
  }
  return p;
}

// Serializes and deserializes a chunk with the generated CDR code, as the wire would.
msg::ProgramChunk through_cdr(msg::ProgramChunk& chunk, std::uint32_t* size_out = nullptr) {
  msg::ProgramChunkPubSubType type;
  const std::uint32_t size = type.getSerializedSizeProvider(&chunk)();
  eprosima::fastrtps::rtps::SerializedPayload_t payload(size);
  EXPECT_TRUE(type.serialize(&chunk, &payload));
  msg::ProgramChunk back;
  EXPECT_TRUE(type.deserialize(&payload, &back));
  if (size_out != nullptr) *size_out = payload.length;
  return back;
}

TEST(IdlMapping, SampleProgramRoundTripsThroughChunks) {
  const Program p = sample_program();
  std::vector<msg::ProgramChunk> chunks;
  ASSERT_EQ(mapping::to_chunks(p, {2, 77}, chunks), MapStatus::kOk);
  ASSERT_EQ(chunks.size(), 1u);
  EXPECT_EQ(chunks[0].interpolator(), 2);
  EXPECT_EQ(chunks[0].program_id(), 77u);
  EXPECT_EQ(chunks[0].sequence_number(), 0u);
  EXPECT_TRUE(chunks[0].end_of_program());
  EXPECT_EQ(chunks[0].number_axes(), 4);
  // Payloads ride only on the records that have them.
  EXPECT_EQ(chunks[0].segments()[3].params().size(), 26u);
  EXPECT_DOUBLE_EQ(chunks[0].segments()[3].params()['S' - 'A'], 1200.0);
  EXPECT_TRUE(chunks[0].segments()[4].params().empty());
  EXPECT_EQ(chunks[0].segments()[5].text(), p.messages[0]);
  EXPECT_TRUE(chunks[0].segments()[1].params().empty());
  EXPECT_EQ(chunks[0].segments()[1].text().size(), 0u);

  Program back;
  back.number_axes = 1;
  for (auto& c : chunks) ASSERT_EQ(mapping::append_chunk(through_cdr(c), back), MapStatus::kOk);
  expect_same_program(p, back);
}

TEST(IdlMapping, SeededRandomProgramsRoundTripThroughCdr) {
  const std::uint32_t seeds = 20;
  for (std::uint32_t seed = 1; seed <= seeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Program p = random_program(seed, 1000 + seed * 37);
    std::vector<msg::ProgramChunk> chunks;
    ASSERT_EQ(mapping::to_chunks(p, {1, seed}, chunks), MapStatus::kOk);
    Program back;
    std::uint64_t expected_sequence = 0;
    for (std::size_t i = 0; i < chunks.size(); ++i) {
      std::uint32_t bytes = 0;
      const msg::ProgramChunk wire = through_cdr(chunks[i], &bytes);
      EXPECT_LE(bytes, mapping::kChunkByteBudget);
      EXPECT_GE(wire.segments().size(), 1u);
      EXPECT_LE(wire.segments().size(), mapping::kMaxChunkSegments);
      EXPECT_EQ(wire.sequence_number(), expected_sequence);
      EXPECT_EQ(wire.end_of_program(), i + 1 == chunks.size());
      expected_sequence += wire.segments().size();
      ASSERT_EQ(mapping::append_chunk(wire, back), MapStatus::kOk);
    }
    EXPECT_EQ(expected_sequence, p.segments.size());
    expect_same_program(p, back);
  }
}

TEST(IdlMapping, PlainMovesFillAChunkAndStaySmall) {
  Program p;
  for (int i = 0; i < 1000; ++i) p.segments.push_back(line_to(i * 0.05, 0.0, i + 1));
  msg::ProgramChunk chunk;
  std::size_t next = 0;
  ASSERT_EQ(mapping::fill_chunk(p, 0, {}, chunk, next), MapStatus::kOk);
  EXPECT_EQ(next, mapping::kMaxChunkSegments);
  EXPECT_FALSE(chunk.end_of_program());
  std::uint32_t bytes = 0;
  (void)through_cdr(chunk, &bytes);
  // 128 records of 10 doubles + 4 more doubles + 4 ints + 4 octets + 2 empty payloads.
  EXPECT_LE(bytes, 128u * 176u + 64u);
}

TEST(IdlMapping, LongMessagesSplitChunksByBytes) {
  Program p;
  for (int i = 0; i < 300; ++i) {
    Segment s;
    s.type = SegmentType::kMessage;
    s.aux = i;
    p.messages.emplace_back(mapping::kMaxTextLength, 'x');
    Segment m;
    m.type = SegmentType::kMFunction;
    m.m_kind = MKind::kNormal;
    m.m = 10;
    m.aux = i;
    p.params.push_back(unset_params());
    p.segments.push_back(s);
    p.segments.push_back(m);
  }
  std::vector<msg::ProgramChunk> chunks;
  ASSERT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kOk);
  ASSERT_GT(chunks.size(), p.segments.size() / mapping::kMaxChunkSegments + 1);
  Program back;
  for (auto& c : chunks) {
    std::uint32_t bytes = 0;
    const auto wire = through_cdr(c, &bytes);
    EXPECT_LE(bytes, mapping::kChunkByteBudget);
    ASSERT_EQ(mapping::append_chunk(wire, back), MapStatus::kOk);
  }
  back.number_axes = p.number_axes;
  expect_same_program(p, back);
}

TEST(IdlMapping, EmptyProgramIsOneFinalChunk) {
  Program p;
  std::vector<msg::ProgramChunk> chunks;
  ASSERT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kOk);
  ASSERT_EQ(chunks.size(), 1u);
  EXPECT_TRUE(chunks[0].end_of_program());
  EXPECT_TRUE(chunks[0].segments().empty());
}

TEST(IdlMapping, CoreSideErrors) {
  Program p = sample_program();
  p.messages[0] = std::string(mapping::kMaxTextLength + 1, 'y');
  std::vector<msg::ProgramChunk> chunks;
  EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kTextTooLong);
  EXPECT_TRUE(chunks.empty());

  p = sample_program();
  p.segments[3].aux = 5;  // no such params entry
  EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kBadAux);
  p = sample_program();
  p.segments[5].aux = -1;  // a message without text
  EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kBadAux);
  p = sample_program();
  p.segments[1].aux = 0;  // a G1 pointing into a side table
  EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kBadAux);
  p = sample_program();
  p.number_axes = 11;
  EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kBadAxisCount);

  msg::ProgramChunk chunk;
  std::size_t next = 0;
  EXPECT_EQ(mapping::fill_chunk(sample_program(), 100, {}, chunk, next), MapStatus::kBadIndex);
}

// What cannot be sent is found before anything is: a long program whose record 400 holds a
// message beyond the bound streamed its first 399 records, which the service ran, and then
// stopped with the machine moving. program_problem names that record at once; fill_chunk names
// it too (it said the chunk's first record).
TEST(IdlMapping, ProgramProblemNamesTheRecordBeforeAnythingIsSent) {
  Program p;
  p.number_axes = 1;
  p.axis_letters = "X";
  for (int i = 0; i < 500; ++i) {
    Segment s;
    s.type = SegmentType::kLinear;
    s.line = i + 1;
    s.end[0] = i;
    s.feed_mm_per_min = 100.0;
    p.segments.push_back(s);
  }
  std::size_t index = 99;
  EXPECT_EQ(mapping::program_problem(p, index), MapStatus::kOk);
  p.segments[400].type = SegmentType::kMessage;
  p.segments[400].aux = 0;
  p.messages.emplace_back(mapping::kMaxTextLength, 'x');
  EXPECT_EQ(mapping::program_problem(p, index), MapStatus::kOk);
  p.messages[0].push_back('y');
  EXPECT_EQ(mapping::program_problem(p, index), MapStatus::kTextTooLong);
  EXPECT_EQ(index, 400u);
  p.segments[7].aux = 3;  // a G1 pointing into a side table: found first
  EXPECT_EQ(mapping::program_problem(p, index), MapStatus::kBadAux);
  EXPECT_EQ(index, 7u);
  p.segments[7].aux = -1;
  p.axis_letters = "XX";
  EXPECT_EQ(mapping::program_problem(p, index), MapStatus::kBadAxisLetters);
  EXPECT_EQ(index, 0u);
  p.axis_letters = "X";

  // The chunker stops at the same record and says which one.
  msg::ProgramChunk chunk;
  std::size_t next = 0, first = 0;
  MapStatus st = MapStatus::kOk;
  while ((st = mapping::fill_chunk(p, first, {}, chunk, next)) == MapStatus::kOk && next < 500)
    first = next;
  EXPECT_EQ(st, MapStatus::kTextTooLong);
  EXPECT_EQ(next, 400u);
  EXPECT_TRUE(chunk.segments().empty());
}

TEST(IdlMapping, WireSideErrorsLeaveTheProgramUnchangedAndSayWhere) {
  const Program p = sample_program();
  std::vector<msg::ProgramChunk> chunks;
  ASSERT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kOk);
  msg::ProgramChunk good = chunks[0];
  // As if this chunk continued a program at its record 1000.
  good.sequence_number(1000);

  struct Case {
    const char* what;
    void (*spoil)(msg::ProgramChunk&);
    MapStatus expected;
    const char* place;  // what describe() appends to the reason
  };
  const std::string line2 = ": record 1001 of the program (record 1 of its chunk, source line 2)";
  const Case cases[] = {
      {"type 7", [](msg::ProgramChunk& c) { c.segments()[1].type(7); }, MapStatus::kBadType,
       ", field type"},
      {"plane 20", [](msg::ProgramChunk& c) { c.segments()[1].plane(20); }, MapStatus::kBadType,
       ", field plane"},
      {"compensation 39", [](msg::ProgramChunk& c) { c.segments()[1].compensation(39); },
       MapStatus::kBadType, ", field compensation"},
      {"m kind 5", [](msg::ProgramChunk& c) { c.segments()[1].m_kind(5); }, MapStatus::kBadType,
       ", field m_kind"},
      {"NaN end", [](msg::ProgramChunk& c) { c.segments()[1].end()[9] = std::nan(""); },
       MapStatus::kNotFinite, ", field end[9]"},
      {"NaN center", [](msg::ProgramChunk& c) { c.segments()[1].center()[1] = std::nan(""); },
       MapStatus::kNotFinite, ", field center[1]"},
      {"inf radius",
       [](msg::ProgramChunk& c) {
         c.segments()[1].radius(-std::numeric_limits<double>::infinity());
       },
       MapStatus::kNotFinite, ", field radius"},
      {"inf feed",
       [](msg::ProgramChunk& c) {
         c.segments()[1].feed_mm_per_min(std::numeric_limits<double>::infinity());
       },
       MapStatus::kNotFinite, ", field feed_mm_per_min"},
      {"NaN dwell", [](msg::ProgramChunk& c) { c.segments()[1].dwell_s(std::nan("")); },
       MapStatus::kNotFinite, ", field dwell_s"},
      {"NaN compensation radius",
       [](msg::ProgramChunk& c) { c.segments()[1].compensation_radius_mm(std::nan("")); },
       MapStatus::kNotFinite, ", field compensation_radius_mm"},
      {"NaN param", [](msg::ProgramChunk& c) { c.segments()[3].params()[18] = std::nan(""); },
       MapStatus::kNotFinite,
       ": record 1003 of the program (record 3 of its chunk, source line 4), field params[18]"},
      {"5 params", [](msg::ProgramChunk& c) { c.segments()[3].params().resize(5); },
       MapStatus::kBadParams,
       ": record 1003 of the program (record 3 of its chunk, source line 4), field params"},
      {"params on G1", [](msg::ProgramChunk& c) { c.segments()[1].params().assign(26, 0.0); },
       MapStatus::kBadParams, ", field params"},
      {"text on G1", [](msg::ProgramChunk& c) { c.segments()[1].text("hi"); },
       MapStatus::kUnexpectedText, ", field text"},
      {"no line", [](msg::ProgramChunk& c) { c.segments()[0].end()[0] = std::nan(""); },
       MapStatus::kNotFinite,
       ": record 1000 of the program (record 0 of its chunk, source line 1), field end[0]"},
      {"0 axes", [](msg::ProgramChunk& c) { c.number_axes(0); }, MapStatus::kBadAxisCount,
       ": field number_axes"},
      {"3 letters for 4 axes", [](msg::ProgramChunk& c) { c.axis_letters("XYZ"); },
       MapStatus::kBadAxisLetters, ": field axis_letters"},
      {"a letter twice", [](msg::ProgramChunk& c) { c.axis_letters("XYZX"); },
       MapStatus::kBadAxisLetters, ": field axis_letters"},
      {"lower case", [](msg::ProgramChunk& c) { c.axis_letters("XYZa"); },
       MapStatus::kBadAxisLetters, ": field axis_letters"},
      {"a digit", [](msg::ProgramChunk& c) { c.axis_letters("XY1A"); }, MapStatus::kBadAxisLetters,
       ": field axis_letters"},
      {"129 records",
       [](msg::ProgramChunk& c) { c.segments().resize(mapping::kMaxChunkSegments + 1); },
       MapStatus::kTooManySegments, ": field segments"},
  };
  for (const Case& k : cases) {
    SCOPED_TRACE(k.what);
    msg::ProgramChunk bad = good;
    k.spoil(bad);
    Program target = sample_program();
    const Program before = target;
    mapping::WireProblem where;
    EXPECT_EQ(mapping::append_chunk(bad, target, where), k.expected);
    expect_same_program(before, target);
    EXPECT_FALSE(mapping::to_string(k.expected).empty());
    // A place that starts with ", field" is a field of record 1 (source line 2).
    const std::string place = k.place[0] == ',' ? line2 + k.place : std::string(k.place);
    EXPECT_EQ(mapping::describe(k.expected, where, bad.sequence_number()),
              std::string(mapping::to_string(k.expected)) + place);
    // The plain overload agrees.
    Program again = sample_program();
    EXPECT_EQ(mapping::append_chunk(bad, again), k.expected);
  }
}

// The letters travel with every chunk, so the service can refuse a program compiled for other
// axes; a sender that does not know them sends none, and only the axis count is checked.
TEST(IdlMapping, AxisLettersTravelWithTheChunksAndBadOnesAreRefused) {
  Program p = sample_program();
  std::vector<msg::ProgramChunk> chunks;
  ASSERT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kOk);
  EXPECT_EQ(chunks[0].axis_letters().to_string(), "XYZA");
  Program back;
  ASSERT_EQ(mapping::append_chunk(through_cdr(chunks[0]), back), MapStatus::kOk);
  EXPECT_EQ(back.axis_letters, "XYZA");

  msg::ProgramChunk unnamed = chunks[0];
  unnamed.axis_letters("");
  Program none;
  ASSERT_EQ(mapping::append_chunk(through_cdr(unnamed), none), MapStatus::kOk);
  EXPECT_EQ(none.axis_letters, "");
  EXPECT_EQ(none.number_axes, 4);

  // The sender refuses letters that do not name its axes, rather than send what the service
  // would refuse.
  for (const char* letters : {"XYZ", "XYZAB", "XYZX", "", "XYZ-"}) {
    SCOPED_TRACE(letters);
    p.axis_letters = letters;
    EXPECT_EQ(mapping::to_chunks(p, {}, chunks), MapStatus::kBadAxisLetters);
    EXPECT_TRUE(chunks.empty());
  }
  EXPECT_TRUE(mapping::valid_axis_letters("XYZABCUVWE", 10));
  EXPECT_FALSE(mapping::valid_axis_letters("XYZABCUVWEQ", 11));
}

TEST(IdlMapping, SingleRecordPayloadIsReported) {
  msg::Segment wire;
  MParams params = unset_params();
  params[25] = 3.0;
  Segment m;
  m.type = SegmentType::kMFunction;
  m.m_kind = MKind::kContinuous;
  m.m = 1500;
  ASSERT_EQ(mapping::to_idl(m, &params, nullptr, wire), MapStatus::kOk);
  Segment back;
  mapping::SegmentPayload payload;
  ASSERT_EQ(mapping::from_idl(wire, back, payload), MapStatus::kOk);
  EXPECT_TRUE(payload.has_params);
  EXPECT_FALSE(payload.has_message);
  EXPECT_EQ(payload.params, params);
  EXPECT_EQ(back.m, 1500);
  EXPECT_EQ(back.aux, -1);
  // The same wire object reused for a plain move loses the payload.
  ASSERT_EQ(mapping::to_idl(line_to(1, 2, 3), nullptr, nullptr, wire), MapStatus::kOk);
  EXPECT_TRUE(wire.params().empty());
  ASSERT_EQ(mapping::from_idl(wire, back, payload), MapStatus::kOk);
  EXPECT_FALSE(payload.has_params);
  // A payload the record type cannot have is refused on the core side too.
  const std::string text = "x";
  EXPECT_EQ(mapping::to_idl(line_to(1, 2, 3), &params, nullptr, wire), MapStatus::kBadParams);
  EXPECT_EQ(mapping::to_idl(line_to(1, 2, 3), nullptr, &text, wire), MapStatus::kUnexpectedText);
}

}  // namespace
}  // namespace tgm

namespace tgm {
namespace {

Registers random_registers(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> real(-1e6, 1e6);
  std::uniform_int_distribution<std::int32_t> integer(-100000, 100000);
  std::uniform_int_distribution<std::int64_t> inc(-(std::int64_t{1} << 40), std::int64_t{1} << 40);
  Registers r;
  r.number = 2;
  r.number_axes = integer(rng);
  r.buffer_size = integer(rng);
  r.command = integer(rng);
  for (auto& v : r.command_parameter) v = integer(rng);
  r.command_status = -1;
  r.status = 8;
  r.act_part = integer(rng);
  r.address_external_position = integer(rng);
  r.m_func = integer(rng);
  r.act_g_func = integer(rng);
  r.act_m_func = integer(rng);
  r.last_cont_m_func = integer(rng);
  r.run_flag = make_run_flag(SectionState::kWaitMFuncEnd, SpeedState::kEmergencyRamp);
  r.tool_number = integer(rng);
  for (auto& v : r.orig_position) v = real(rng);
  for (auto& v : r.position) v = real(rng);
  for (auto& v : r.position_inc) v = inc(rng);
  for (auto& v : r.backlash) v = inc(rng);
  for (auto& v : r.offset) v = inc(rng);
  for (auto& v : r.speed) v = real(rng);
  for (auto& v : r.ratio) v = real(rng);
  for (auto& v : r.m_function_parameter) v = real(rng);
  r.m_function_parameter[3] = kNotSet;
  r.rel_speed = real(rng);
  r.set_speed = real(rng);
  r.act_speed = real(rng);
  r.move_distance = real(rng);
  for (auto& e : r.lookahead) {
    for (auto& v : e.all_params) v = real(rng);
    e.tangent_deg = real(rng);
    e.movement_type = integer(rng);
    e.movement_code = integer(rng);
    e.plane = integer(rng);
    e.tool = integer(rng);
    for (auto& v : e.end_pos_mm) v = real(rng);
    e.start_angle_deg = real(rng);
    e.end_angle_deg = kNotSet;
    e.radius_mm = real(rng);
    e.line = integer(rng);
  }
  r.cycle = (std::uint64_t{1} << 50) + seed;
  r.act_line = integer(rng);
  r.free_slots = integer(rng);
  r.message_count = 7;
  r.m_func_count = 4'000'000'000u + static_cast<std::uint32_t>(integer(rng) + 100000);  // > 2^31
  r.m_func_line = integer(rng);
  r.off_trajectory = 1;
  r.program_stop = 1;
  r.act_acceleration_mm_s2 = real(rng);
  r.limit_factor = LimitFactor::kStopCommand;
  return r;
}

void expect_same_registers(const Registers& a, const Registers& b) {
  EXPECT_EQ(a.number, b.number);
  EXPECT_EQ(a.number_axes, b.number_axes);
  EXPECT_EQ(a.buffer_size, b.buffer_size);
  EXPECT_EQ(a.command, b.command);
  EXPECT_EQ(a.command_parameter, b.command_parameter);
  EXPECT_EQ(a.command_status, b.command_status);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.act_part, b.act_part);
  EXPECT_EQ(a.address_external_position, b.address_external_position);
  EXPECT_EQ(a.m_func, b.m_func);
  EXPECT_EQ(a.act_g_func, b.act_g_func);
  EXPECT_EQ(a.act_m_func, b.act_m_func);
  EXPECT_EQ(a.last_cont_m_func, b.last_cont_m_func);
  EXPECT_EQ(a.run_flag, b.run_flag);
  EXPECT_EQ(a.tool_number, b.tool_number);
  EXPECT_EQ(a.orig_position, b.orig_position);
  EXPECT_EQ(a.position, b.position);
  EXPECT_EQ(a.position_inc, b.position_inc);
  EXPECT_EQ(a.backlash, b.backlash);
  EXPECT_EQ(a.offset, b.offset);
  EXPECT_EQ(a.speed, b.speed);
  EXPECT_EQ(a.ratio, b.ratio);
  EXPECT_EQ(a.m_function_parameter, b.m_function_parameter);
  EXPECT_EQ(a.rel_speed, b.rel_speed);
  EXPECT_EQ(a.set_speed, b.set_speed);
  EXPECT_EQ(a.act_speed, b.act_speed);
  EXPECT_EQ(a.move_distance, b.move_distance);
  for (std::size_t i = 0; i < a.lookahead.size(); ++i) {
    SCOPED_TRACE("look-ahead entry " + std::to_string(i));
    const auto& x = a.lookahead[i];
    const auto& y = b.lookahead[i];
    EXPECT_EQ(x.all_params, y.all_params);
    EXPECT_EQ(x.tangent_deg, y.tangent_deg);
    EXPECT_EQ(x.movement_type, y.movement_type);
    EXPECT_EQ(x.movement_code, y.movement_code);
    EXPECT_EQ(x.plane, y.plane);
    EXPECT_EQ(x.tool, y.tool);
    EXPECT_EQ(x.end_pos_mm, y.end_pos_mm);
    EXPECT_EQ(x.start_angle_deg, y.start_angle_deg);
    EXPECT_EQ(x.end_angle_deg, y.end_angle_deg);
    EXPECT_EQ(x.radius_mm, y.radius_mm);
    EXPECT_EQ(x.line, y.line);
  }
  EXPECT_EQ(a.cycle, b.cycle);
  EXPECT_EQ(a.act_line, b.act_line);
  EXPECT_EQ(a.free_slots, b.free_slots);
  EXPECT_EQ(a.message_count, b.message_count);
  EXPECT_EQ(a.m_func_count, b.m_func_count);
  EXPECT_EQ(a.m_func_line, b.m_func_line);
  EXPECT_EQ(a.off_trajectory, b.off_trajectory);
  EXPECT_EQ(a.program_stop, b.program_stop);
  EXPECT_EQ(a.act_acceleration_mm_s2, b.act_acceleration_mm_s2);
  EXPECT_EQ(a.limit_factor, b.limit_factor);
}

TEST(IdlMapping, RegistersRoundTripThroughCdr) {
  for (std::uint32_t seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Registers r = random_registers(seed);
    msg::InterpolatorState state;
    state.program_id(5);  // a service field: the mapping leaves it alone
    state.lateness_max_ns(1234);
    mapping::to_idl(r, 2, state);
    EXPECT_EQ(state.interpolator(), 2);
    EXPECT_EQ(state.program_id(), 5u);
    EXPECT_EQ(state.lateness_max_ns(), 1234);
    EXPECT_EQ(static_cast<std::uint32_t>(state.run_flag()) >> 16, 7u);

    msg::InterpolatorStatePubSubType type;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&state)());
    ASSERT_TRUE(type.serialize(&state, &payload));
    msg::InterpolatorState wire;
    ASSERT_TRUE(type.deserialize(&payload, &wire));
    Registers back;
    mapping::from_idl(wire, back);
    expect_same_registers(r, back);

    msg::Setpoints sp;
    mapping::to_setpoints(r, 1, sp);
    EXPECT_EQ(sp.interpolator(), 1);
    EXPECT_EQ(sp.cycle_counter(), r.cycle);
    EXPECT_EQ(sp.position(), r.position);
    EXPECT_EQ(sp.position_inc(), r.position_inc);
  }
}

// The event sample carries the event registers of the state, nothing else: the same registers
// through the event and through the state give the same values (the state is the reference), and
// applying an event to registers changes only the event registers.
TEST(IdlMapping, EventCarriesTheEventRegistersOfTheState) {
  for (std::uint32_t seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Registers r = random_registers(seed);
    msg::InterpolatorEvent event;
    event.event_counter(77);  // service fields: the mapping leaves them alone
    event.program_id(5);
    mapping::to_event(event_registers(r), 2, event);
    EXPECT_EQ(event.interpolator(), 2);
    EXPECT_EQ(event.event_counter(), 77u);
    EXPECT_EQ(event.program_id(), 5u);

    msg::InterpolatorEventPubSubType type;
    const std::uint32_t size = type.getSerializedSizeProvider(&event)();
    eprosima::fastrtps::rtps::SerializedPayload_t payload(size);
    ASSERT_TRUE(type.serialize(&event, &payload));
    // Small on purpose: a tenth of the state (BENCHMARKS.md "Service").
    EXPECT_LE(payload.length, 400u);
    msg::InterpolatorEvent wire;
    ASSERT_TRUE(type.deserialize(&payload, &wire));

    msg::InterpolatorState state;
    mapping::to_idl(r, 2, state);
    EXPECT_EQ(wire.interpolator(), state.interpolator());
    EXPECT_EQ(wire.cycle_counter(), state.cycle_counter());
    EXPECT_EQ(wire.status(), state.status());
    EXPECT_EQ(wire.run_flag(), state.run_flag());
    EXPECT_EQ(wire.act_part(), state.act_part());
    EXPECT_EQ(wire.act_line(), state.act_line());
    EXPECT_EQ(wire.m_func(), state.m_func());
    EXPECT_EQ(wire.act_m_func(), state.act_m_func());
    EXPECT_EQ(wire.last_cont_m_func(), state.last_cont_m_func());
    EXPECT_EQ(wire.command(), state.command());
    EXPECT_EQ(wire.command_status(), state.command_status());
    EXPECT_EQ(wire.m_func_count(), state.m_func_count());
    EXPECT_EQ(wire.m_func_count(), r.m_func_count);
    EXPECT_EQ(wire.m_func_line(), state.m_func_line());
    EXPECT_EQ(wire.m_func_line(), r.m_func_line);
    EXPECT_EQ(wire.m_function_parameter(), state.m_function_parameter());
    EXPECT_TRUE(is_not_set(wire.m_function_parameter()[3]));

    // Applied to other registers: the event registers become r's, the rest stays.
    Registers other = random_registers(seed + 100);
    other.status = 1;  // random_registers fixes these: make them differ from r's
    other.run_flag = make_run_flag(SectionState::kRun, SpeedState::kConstant);
    other.command_status = 0;
    Registers applied = other;
    mapping::from_event(wire, applied);
    Registers expected = other;
    expected.cycle = r.cycle;
    expected.status = r.status;
    expected.run_flag = r.run_flag;
    expected.act_part = r.act_part;
    expected.act_line = r.act_line;
    expected.m_func = r.m_func;
    expected.act_m_func = r.act_m_func;
    expected.last_cont_m_func = r.last_cont_m_func;
    expected.command = r.command;
    expected.command_status = r.command_status;
    expected.m_func_count = r.m_func_count;
    expected.m_func_line = r.m_func_line;
    expected.m_function_parameter = r.m_function_parameter;
    expect_same_registers(expected, applied);
  }
}

}  // namespace
}  // namespace tgm
