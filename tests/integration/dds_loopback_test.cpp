// Samples over real Fast DDS participants (in this process, and one helper process): the
// program stream delivers every chunk once and in order, a late state reader gets the current
// state of each interpolator, requests get replies, and a killed peer is noticed by liveliness
// before the participant lease expires. Timeouts only guard against hangs; nothing is timed.
#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <string>
#include <thread>

#include "dds_test_util.hpp"
#include "raw_sample.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/idl_mapping.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

extern char** environ;

namespace tgm {
namespace {

using namespace std::chrono_literals;
namespace fdds = eprosima::fastdds::dds;

constexpr auto kHang = 20s;  // guards against a hang, never a performance limit

Program long_program(std::size_t count) {
  Program p;
  p.number_axes = 3;
  for (std::size_t i = 0; i < count; ++i) {
    Segment s;
    s.line = static_cast<std::int32_t>(i + 1);
    s.end[0] = static_cast<double>(i) * 0.05;
    s.end[1] = static_cast<double>(i % 7);
    s.feed_mm_per_min = 3000.0;
    if (i % 500 == 250) {
      s.type = SegmentType::kMFunction;
      s.m_kind = MKind::kNormal;
      s.m = 50;
      s.aux = static_cast<std::int32_t>(p.params.size());
      MParams params = unset_params();
      params[0] = static_cast<double>(i);
      p.params.push_back(params);
    } else if (i % 500 == 499) {
      s.type = SegmentType::kMessage;
      s.aux = static_cast<std::int32_t>(p.messages.size());
      p.messages.push_back("message at " + std::to_string(i));
    }
    p.segments.push_back(s);
  }
  return p;
}

// A sample the generated code cannot read (a bool of 2: fastcdr throws BadParamException, which
// the generated type support does not catch) terminated the reading process. It is dropped
// (dds::CheckedType), counted, and the samples after it arrive.
TEST(DdsLoopback, AMalformedSampleIsDroppedAndTheNextOneArrives) {
  const auto t = test::test_topic(dds::kProgramTopic);
  dds::Participant rogue(test::test_config(), "hmi");
  dds::Participant service(test::test_config(), "service");
  auto& w = rogue.writer(rogue.topic<test::RawBytesType<msg::ProgramChunkPubSubType>>(t.spec.name),
                         t.spec.writer_profile);
  auto& r = service.reader<msg::ProgramChunkPubSubType>(t.spec);
  ASSERT_TRUE(dds::wait_for_match(w, 1, kHang));

  std::string bad = test::chunk_with_a_bool_of_2(1, 7);
  ASSERT_FALSE(bad.empty()) << "the generated layout of ProgramChunk changed";
  const std::uint64_t dropped = dds::malformed_samples();
  ASSERT_EQ(w.write(&bad), true);
  msg::ProgramChunk chunk;
  chunk.interpolator(1);
  chunk.program_id(8);
  std::string good = test::serialized<msg::ProgramChunkPubSubType>(chunk);
  ASSERT_EQ(w.write(&good), true);

  msg::ProgramChunk got;
  bool seen = false;
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  while (!seen && std::chrono::steady_clock::now() < deadline) {
    while (dds::take_next(r, got)) {
      EXPECT_EQ(got.program_id(), 8u);
      seen = true;
    }
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_TRUE(seen);
  EXPECT_GT(dds::malformed_samples(), dropped);  // reads, not samples (Fast DDS may retry)
}

// A state of an older version's layout (a service not yet upgraded) ends before the fields
// appended since. The generated code drops such a sample, so a client upgraded first read no
// state at all (session 92: a 0.2.0 state written by Cyclone DDS, tests/interop). Cut at every
// length from eight bytes before the end of 0.2.0's last field (plc_setup) to the whole: from
// that end on the state reads, every field it holds whole as written and the rest at 0 (0.2.1's
// machine_digest, 0.2.2's smoothing); shorter, it is dropped as malformed.
TEST(DdsLoopback, AStateOfAnOlderLayoutReadsWithTheFieldsItLacksAtZero) {
  msg::InterpolatorState full;
  full.interpolator(2);
  full.status(3);
  full.axis_letters("XYZ");
  full.cycle_counter(77);
  full.plc_setup(2);
  full.machine_digest(0x0123456789abcdefULL);
  full.spline_points(120);
  full.iir_p_e6(3'000'000);
  full.iir_axis_mask(6);
  const std::string bytes = test::serialized<msg::InterpolatorStatePubSubType>(full);
  // Where a field ends: one past the last byte that differs between two serializations with
  // other values of it (little endian: the most significant byte is the last).
  const auto end_of = [&](auto set) {
    msg::InterpolatorState other = full;
    set(other);
    const std::string o = test::serialized<msg::InterpolatorStatePubSubType>(other);
    std::size_t end = 0;
    for (std::size_t i = 0; i < o.size() && i < bytes.size(); ++i) {
      if (o[i] != bytes[i]) end = i + 1;
    }
    return end;
  };
  const std::size_t end_of_0_2_0 = end_of([](msg::InterpolatorState& s) { s.plc_setup(1); });
  const std::size_t end_of_0_2_1 =
      end_of([](msg::InterpolatorState& s) { s.machine_digest(0xff23456789abcdefULL); });
  const std::size_t end_of_spline_points =
      end_of([](msg::InterpolatorState& s) { s.spline_points(0x7f000078); });
  ASSERT_GT(end_of_0_2_1, end_of_0_2_0);
  ASSERT_GT(end_of_spline_points, end_of_0_2_1);
  ASSERT_EQ(end_of([](msg::InterpolatorState& s) { s.iir_axis_mask(0xff000006u); }), bytes.size())
      << "iir_axis_mask is not the last field any more";

  dds::CheckedType<msg::InterpolatorStatePubSubType> type;
  for (std::size_t length = end_of_0_2_0 - 8; length <= bytes.size(); ++length) {
    eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<std::uint32_t>(bytes.size()));
    std::memcpy(payload.data, bytes.data(), length);
    payload.length = static_cast<std::uint32_t>(length);
    msg::InterpolatorState got;
    got.machine_digest(99);  // values the read must not leave behind
    got.iir_axis_mask(99);
    const std::uint64_t malformed = dds::malformed_samples();
    const bool read = type.deserialize(&payload, &got);
    if (length < end_of_0_2_0) {
      EXPECT_FALSE(read) << length;
      EXPECT_EQ(dds::malformed_samples(), malformed + 1) << length;
      continue;
    }
    ASSERT_TRUE(read) << length << " of " << bytes.size();
    EXPECT_EQ(dds::malformed_samples(), malformed) << length;
    EXPECT_EQ(got.interpolator(), 2);
    EXPECT_EQ(got.status(), 3);
    EXPECT_EQ(got.axis_letters().to_string(), "XYZ");
    EXPECT_EQ(got.cycle_counter(), 77u);
    EXPECT_EQ(got.plc_setup(), 2);
    EXPECT_EQ(got.machine_digest(), length >= end_of_0_2_1 ? full.machine_digest() : 0u) << length;
    EXPECT_EQ(got.spline_points(), length >= end_of_spline_points ? 120 : 0) << length;
    EXPECT_EQ(got.iir_axis_mask(), length == bytes.size() ? 6u : 0u) << length;
  }
}

TEST(DdsLoopback, ProgramStreamDeliversEveryChunkOnceInOrder) {
  const Program program = long_program(20'000);
  const auto t = test::test_topic(dds::kProgramTopic);
  dds::Participant hmi(test::test_config(), "hmi");
  dds::Participant service(test::test_config(), "service");
  auto& writer = hmi.writer<msg::ProgramChunkPubSubType>(t.spec);
  auto& reader = service.reader<msg::ProgramChunkPubSubType>(t.spec);
  ASSERT_TRUE(dds::wait_for_match(writer, 1, kHang));

  // The service side: take chunks, check sequence numbers, rebuild the program.
  Program received;
  std::uint64_t expected_sequence = 0;
  bool order_ok = true;
  std::atomic<bool> done{false};
  // Chunks taken so far: stands in for InterpolatorState.next_sequence, the sender's window.
  std::atomic<std::size_t> taken{0};
  std::thread consumer([&] {
    dds::DataWaiter waiter({&reader});
    msg::ProgramChunk chunk;
    const auto deadline = std::chrono::steady_clock::now() + kHang;
    while (!done && std::chrono::steady_clock::now() < deadline) {
      waiter.wait(100ms);
      while (dds::take_next(reader, chunk)) {
        order_ok = order_ok && chunk.sequence_number() == expected_sequence &&
                   chunk.program_id() == 9 && chunk.interpolator() == 0;
        expected_sequence += chunk.segments().size();
        if (mapping::append_chunk(chunk, received) != mapping::MapStatus::kOk) order_ok = false;
        if (chunk.end_of_program()) done = true;
        ++taken;
        // A consumer slower than the sender, so that the window is what limits the stream.
        if (taken % 16 == 0) std::this_thread::sleep_for(1ms);
      }
    }
  });

  msg::ProgramChunk chunk;
  std::size_t first = 0;
  std::size_t chunks = 0;
  bool writes_ok = true;
  const auto window_deadline = std::chrono::steady_clock::now() + kHang;
  do {
    std::size_t next = 0;
    ASSERT_EQ(mapping::fill_chunk(program, first, {0, 9}, chunk, next), mapping::MapStatus::kOk);
    while (chunks >= taken + dds::kProgramChunksInFlight &&
           std::chrono::steady_clock::now() < window_deadline) {
      std::this_thread::sleep_for(100us);
    }
    writes_ok = writes_ok && writer.write(&chunk);
    first = next;
    ++chunks;
  } while (!chunk.end_of_program());
  consumer.join();
  fdds::SampleRejectedStatus rejected;
  fdds::SampleLostStatus lost;
  reader.get_sample_rejected_status(rejected);
  reader.get_sample_lost_status(lost);
  EXPECT_EQ(rejected.total_count, 0) << "the window did not keep the reader history from filling";
  EXPECT_EQ(lost.total_count, 0);
  // Where a stream that stalled stopped: chunks written and taken, records in order so far.
  const std::string where = "written " + std::to_string(chunks) + " chunks, taken " +
                            std::to_string(taken.load()) + ", records in order " +
                            std::to_string(expected_sequence) + " of " +
                            std::to_string(program.segments.size());
  EXPECT_TRUE(writes_ok) << where;
  EXPECT_TRUE(done) << where;
  EXPECT_TRUE(order_ok) << where;
  EXPECT_GT(chunks, program.segments.size() / mapping::kMaxChunkSegments);
  EXPECT_EQ(expected_sequence, program.segments.size());
  ASSERT_EQ(received.segments.size(), program.segments.size());
  EXPECT_EQ(received.params, program.params);
  EXPECT_EQ(received.messages, program.messages);
  for (std::size_t i = 0; i < program.segments.size(); i += 997) {
    EXPECT_EQ(received.segments[i].end, program.segments[i].end) << i;
  }
}

TEST(DdsLoopback, LateStateReaderGetsCurrentStateOfEachInterpolator) {
  const auto t = test::test_topic(dds::kStateTopic);
  dds::Participant service(test::test_config(), "service");
  auto& writer = service.writer<msg::InterpolatorStatePubSubType>(t.spec);
  msg::InterpolatorState s;
  // Every interpolator, 0 included: Fast DDS 2.3/2.4 dropped samples whose key serialized to
  // all zeros (eProsima/Fast-DDS#2306, seen in 2.3 and 2.4).
  for (std::uint16_t n = 0; n < 3; ++n) {
    for (int k = 1; k <= 5; ++k) {  // only the last of these counts (KEEP_LAST 1)
      s.interpolator(n);
      s.number(n);
      s.cycle_counter(static_cast<std::uint64_t>(k));
      s.position()[0] = 10.0 * n + k;
      s.look_ahead_buffer()[7].radius(n + 0.5);
      s.message_text("state " + std::to_string(n));
      ASSERT_TRUE(writer.write(&s));
    }
  }
  // The HMI starts after the state was published.
  dds::Participant hmi(test::test_config(), "hmi");
  auto& reader = hmi.reader<msg::InterpolatorStatePubSubType>(t.spec);
  dds::DataWaiter waiter({&reader});
  bool seen[3] = {false, false, false};
  int samples = 0;
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  while (!(seen[0] && seen[1] && seen[2]) && std::chrono::steady_clock::now() < deadline) {
    waiter.wait(100ms);
    msg::InterpolatorState got;
    while (dds::take_next(reader, got)) {
      ++samples;
      ASSERT_LT(got.interpolator(), 3);
      EXPECT_EQ(got.cycle_counter(), 5u);
      EXPECT_DOUBLE_EQ(got.position()[0], 10.0 * got.interpolator() + 5);
      EXPECT_DOUBLE_EQ(got.look_ahead_buffer()[7].radius(), got.interpolator() + 0.5);
      EXPECT_EQ(got.message_text(), "state " + std::to_string(got.interpolator()));
      seen[got.interpolator()] = true;
    }
  }
  EXPECT_TRUE(seen[0] && seen[1] && seen[2]);
  EXPECT_EQ(samples, 3);
}

TEST(DdsLoopback, RequestGetsItsReply) {
  const auto req_t = test::test_topic(dds::kRequestTopic);
  const auto rep_t = test::test_topic(dds::kReplyTopic);
  dds::Participant plc(test::test_config(), "plc");
  dds::Participant service(test::test_config(), "service");
  auto& req_w = plc.writer<msg::RequestPubSubType>(req_t.spec);
  auto& rep_r = plc.reader<msg::ReplyPubSubType>(rep_t.spec);
  auto& req_r = service.reader<msg::RequestPubSubType>(req_t.spec);
  auto& rep_w = service.writer<msg::ReplyPubSubType>(rep_t.spec);
  ASSERT_TRUE(dds::wait_for_match(req_w, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(rep_w, 1, kHang));

  std::thread responder([&] {
    dds::DataWaiter waiter({&req_r});
    msg::Request req;
    const auto deadline = std::chrono::steady_clock::now() + kHang;
    int answered = 0;
    while (answered < 2 && std::chrono::steady_clock::now() < deadline) {
      waiter.wait(100ms);
      while (dds::take_next(req_r, req)) {
        msg::Reply rep;
        rep.request_id(req.request_id());
        rep.client_name(req.client_name());
        rep.interpolator(req.interpolator());
        const bool ok = req.kind() == msg::REQUEST_KIND_WRITE_REL_SPEED && req.value() >= 0.01 &&
                        req.value() <= 2.0;
        rep.accepted(ok);
        rep.code(ok ? msg::REPLY_CODE_ACCEPTED : msg::REPLY_CODE_OUT_OF_RANGE);
        if (!ok) rep.reason("Rel_Speed " + std::to_string(req.value()) + " outside 0.01..2");
        rep_w.write(&rep);
        ++answered;
      }
    }
  });

  msg::Request req;
  req.role(msg::CLIENT_ROLE_PLC);
  req.client_name(plc.name());
  req.interpolator(2);
  req.kind(msg::REQUEST_KIND_WRITE_REL_SPEED);
  req.request_id(41);
  req.value(0.5);
  ASSERT_TRUE(req_w.write(&req));
  req.request_id(42);
  req.value(3.0);
  ASSERT_TRUE(req_w.write(&req));

  dds::DataWaiter waiter({&rep_r});
  msg::Reply replies[2];
  int got = 0;
  const auto deadline = std::chrono::steady_clock::now() + kHang;
  while (got < 2 && std::chrono::steady_clock::now() < deadline) {
    waiter.wait(100ms);
    while (got < 2 && dds::take_next(rep_r, replies[got])) ++got;
  }
  responder.join();
  ASSERT_EQ(got, 2);
  EXPECT_EQ(replies[0].request_id(), 41u);
  EXPECT_TRUE(replies[0].accepted());
  EXPECT_EQ(replies[0].code(), msg::REPLY_CODE_ACCEPTED);
  EXPECT_EQ(replies[0].client_name(), "tgmtest-plc");
  EXPECT_EQ(replies[0].interpolator(), 2);
  EXPECT_EQ(replies[1].request_id(), 42u);
  EXPECT_FALSE(replies[1].accepted());
  EXPECT_EQ(replies[1].code(), msg::REPLY_CODE_OUT_OF_RANGE);
  EXPECT_NE(replies[1].reason().to_string().find("outside"), std::string::npos);
}

// A client announces its name in its participant's USER_DATA; anything on the domain may write
// those bytes, so only a printable name within the topics' bound counts.
TEST(DdsLoopback, AnnouncedClientNamesArePrintableAndBounded) {
  auto bytes = [](std::string_view s) { return std::vector<unsigned char>(s.begin(), s.end()); };
  EXPECT_EQ(dds::participant_client_name(bytes("tgm-plc-12873-f69fb842")),
            "tgm-plc-12873-f69fb842");
  EXPECT_EQ(dds::participant_client_name(bytes(std::string(64, 'p'))), std::string(64, 'p'));
  EXPECT_EQ(dds::participant_client_name(bytes(std::string(65, 'p'))), "");
  EXPECT_EQ(dds::participant_client_name({}), "");
  EXPECT_EQ(dds::participant_client_name(bytes("tgm-plc\n")), "");
  EXPECT_EQ(dds::participant_client_name(bytes(std::string("a\0b", 3))), "");
  EXPECT_EQ(dds::participant_client_name({'t', 0xc3, 0xa4}), "");
  EXPECT_EQ(dds::participant_client_name(bytes("a~ b")), "a~ b");
}

// A socket of another program on the domain's discovery port (7400 + 250 x domain), bound
// without SO_REUSEADDR as an outgoing socket the kernel handed that port is, made Fast DDS's
// bind fail without a word: the participant was created and never matched anything (two
// participants of this suite on a domain in the ephemeral range, CI session 69). Such a
// participant is refused with the port and the reason; once the port is free, it is created.
TEST(DdsLoopback, AParticipantWhoseDiscoveryPortIsTakenIsRefusedWithThePort) {
  const int domain = test::test_domain();
  const int port = test::discovery_port(domain);
  test::HeldUdpPort held(port);
  ASSERT_EQ(held.error(), "");
  try {
    dds::Participant deaf(test::test_config(), "plc");
    ADD_FAILURE() << "a participant was created although its discovery port is taken";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find("DDS domain " + std::to_string(domain) +
                                         ": its discovery port, UDP " + std::to_string(port) +
                                         ", is held by another program"),
              std::string::npos)
        << e.what();
  }
  held.release();
  const auto t = test::test_topic(dds::kRequestTopic);
  dds::Participant plc(test::test_config(), "plc");
  dds::Participant service(test::test_config(), "service");
  auto& w = plc.writer<msg::RequestPubSubType>(t.spec);
  service.reader<msg::RequestPubSubType>(t.spec);
  EXPECT_TRUE(dds::wait_for_match(w, 1, kHang));
}

// A PLC process killed with SIGKILL cannot say goodbye. Its request writer must be reported
// not alive by the 100 ms liveliness lease while it is still matched, i.e. before the 1 s
// participant lease removes it: liveliness, not discovery, is what notices the death.
TEST(DdsLoopback, KilledPeerIsNoticedByLivelinessBeforeTheParticipantLease) {
  const auto t = test::test_topic(dds::kRequestTopic);
  dds::Participant service(test::test_config(), "service");
  auto& reader = service.reader<msg::RequestPubSubType>(t.spec);

  const std::string domain = std::to_string(test::test_domain());
  const std::string profiles = test::profiles_path();
  const char* argv[] = {TGM_DDS_TEST_PEER, profiles.c_str(), domain.c_str(), t.name.c_str(),
                        nullptr};
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, TGM_DDS_TEST_PEER, nullptr, nullptr, const_cast<char**>(argv),
                        environ),
            0);
  ASSERT_TRUE(dds::wait_for_match(reader, 1, kHang));
  // Alive once the first sample or assertion arrived.
  fdds::LivelinessChangedStatus live;
  msg::Request r;
  auto deadline = std::chrono::steady_clock::now() + kHang;
  do {
    std::this_thread::sleep_for(1ms);
    reader.get_liveliness_changed_status(live);
  } while (live.alive_count < 1 && std::chrono::steady_clock::now() < deadline);
  ASSERT_EQ(live.alive_count, 1);
  {
    dds::DataWaiter waiter({&reader});
    bool got = false;
    for (int i = 0; i < 200 && !(got = dds::take_next(reader, r)); ++i) waiter.wait(100ms);
    EXPECT_TRUE(got);
    EXPECT_EQ(r.client_name(), "peer");
  }

  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  const auto killed = std::chrono::steady_clock::now();
  fdds::SubscriptionMatchedStatus matched;
  deadline = killed + kHang;
  do {
    std::this_thread::sleep_for(1ms);
    reader.get_subscription_matched_status(matched);
    reader.get_liveliness_changed_status(live);
  } while (live.alive_count > 0 && matched.current_count > 0 &&
           std::chrono::steady_clock::now() < deadline);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::steady_clock::now() - killed);
  std::printf("dead peer noticed after %lld ms (alive %d, not alive %d, matched %d)\n",
              static_cast<long long>(ms.count()), live.alive_count, live.not_alive_count,
              matched.current_count);
  EXPECT_EQ(live.alive_count, 0);
  EXPECT_EQ(live.not_alive_count, 1);
  EXPECT_EQ(matched.current_count, 1) << "the participant lease noticed it first";
}

}  // namespace
}  // namespace tgm
