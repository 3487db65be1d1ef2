// config/fastdds_profiles.xml: loads in Fast DDS, has every profile topics.hpp names, with the
// QoS DESIGN.md section 6 asks for, and each topic's writer and reader profiles match each other.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>

#include "dds_test_util.hpp"
#include "process_util.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm {
namespace {

namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::Duration_t;
using eprosima::fastrtps::types::ReturnCode_t;

const Duration_t k100ms(0, 100'000'000u);

TEST(DdsProfiles, FileLoadsInFastDds) {
  EXPECT_EQ(fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(
                test::profiles_path()),
            ReturnCode_t::RETCODE_OK);
}

// docker/fastdds_profiles_udp.xml is what docker/make_udp_profiles.sh makes of this file for
// docker/compose.yaml's addresses. It had fallen behind by two changes, one of them the request
// reader's instance limit, so that the containers still lost replies that had been fixed.
TEST(DdsProfiles, TheDockerUdpProfilesAreUpToDate) {
  const std::string made = ::testing::TempDir() + "/tgm_udp_profiles.xml";
  const std::string cmd = "bash " TGM_SOURCE_DIR
                          "/docker/make_udp_profiles.sh 10.231.1.10 10.231.1.11 10.231.1.12 > " +
                          made;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  EXPECT_EQ(test::read_text(made),
            test::read_text(TGM_SOURCE_DIR "/docker/fastdds_profiles_udp.xml"))
      << "regenerate it: bash docker/make_udp_profiles.sh 10.231.1.10 10.231.1.11 10.231.1.12 > "
         "docker/fastdds_profiles_udp.xml";
}

TEST(DdsProfiles, ParticipantLeaseIsShort) {
  dds::load_profiles(test::profiles_path());
  fdds::DomainParticipantQos qos;
  ASSERT_EQ(fdds::DomainParticipantFactory::get_instance()->get_participant_qos_from_profile(
                std::string(dds::kParticipantProfile), qos),
            ReturnCode_t::RETCODE_OK);
  const auto& disc = qos.wire_protocol().builtin.discovery_config;
  EXPECT_LE(disc.leaseDuration, Duration_t(1, 0));
  EXPECT_LT(disc.leaseDuration_announcementperiod, disc.leaseDuration);
}

struct Expected {
  const dds::TopicSpec& spec;
  fdds::ReliabilityQosPolicyKind reliability;
  fdds::DurabilityQosPolicyKind durability;
  fdds::HistoryQosPolicyKind history;
  int depth;  // KEEP_LAST only
};

TEST(DdsProfiles, EveryTopicHasTheDesignedQos) {
  dds::Participant p(test::test_config(), "profiles");
  fdds::Publisher* pub = p.get().create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::Subscriber* sub = p.get().create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  ASSERT_NE(pub, nullptr);
  ASSERT_NE(sub, nullptr);
  const Expected expected[] = {
      {dds::kStateTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::TRANSIENT_LOCAL_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 1},
      {dds::kEventTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 100},
      {dds::kSetpointsTopic, fdds::BEST_EFFORT_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 1},
      {dds::kRequestTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 100},
      {dds::kReplyTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 100},
      {dds::kProgramTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS,
       fdds::KEEP_ALL_HISTORY_QOS, 0},
      {dds::kMessageTopic, fdds::RELIABLE_RELIABILITY_QOS, fdds::TRANSIENT_LOCAL_DURABILITY_QOS,
       fdds::KEEP_LAST_HISTORY_QOS, 32},
  };
  ASSERT_EQ(std::size(expected), dds::kAllTopics.size());
  for (const Expected& e : expected) {
    SCOPED_TRACE(std::string(e.spec.name));
    fdds::DataWriterQos w;
    fdds::DataReaderQos r;
    ASSERT_EQ(pub->get_datawriter_qos_from_profile(std::string(e.spec.writer_profile), w),
              ReturnCode_t::RETCODE_OK);
    ASSERT_EQ(sub->get_datareader_qos_from_profile(std::string(e.spec.reader_profile), r),
              ReturnCode_t::RETCODE_OK);
    EXPECT_EQ(w.reliability().kind, e.reliability);
    EXPECT_EQ(r.reliability().kind, e.reliability);
    EXPECT_EQ(w.durability().kind, e.durability);
    EXPECT_EQ(r.durability().kind, e.durability);
    EXPECT_EQ(w.history().kind, e.history);
    EXPECT_EQ(r.history().kind, e.history);
    if (e.history == fdds::KEEP_LAST_HISTORY_QOS) {
      EXPECT_EQ(w.history().depth, e.depth);
      EXPECT_EQ(r.history().depth, e.depth);
    }
    // A dead writer is noticed within about 100 ms (DESIGN.md section 6).
    EXPECT_EQ(w.liveliness().kind, fdds::AUTOMATIC_LIVELINESS_QOS);
    EXPECT_LE(w.liveliness().lease_duration, k100ms);
    EXPECT_LT(w.liveliness().announcement_period, w.liveliness().lease_duration);
    EXPECT_LE(r.liveliness().lease_duration, k100ms);
  }
  // The state is published at least every 100 ms per interpolator.
  fdds::DataWriterQos state;
  ASSERT_EQ(pub->get_datawriter_qos_from_profile(std::string(dds::kStateTopic.writer_profile),
                                                 state),
            ReturnCode_t::RETCODE_OK);
  EXPECT_LE(state.deadline().period, k100ms);
}

// Creating every writer and reader checks the QoS is consistent; matching checks each topic's
// writer and reader profiles are compatible (incompatible QoS never match).
TEST(DdsProfiles, WriterAndReaderOfEveryTopicMatch) {
  dds::Participant p(test::test_config(), "match");
  const auto check = [&p]<class PubSubType>(const dds::TopicSpec& spec, PubSubType*) {
    const auto t = test::test_topic(spec);
    auto& w = p.writer<PubSubType>(t.spec);
    auto& r = p.reader<PubSubType>(t.spec);
    EXPECT_TRUE(dds::wait_for_match(w, 1, std::chrono::seconds(10))) << spec.name;
    EXPECT_TRUE(dds::wait_for_match(r, 1, std::chrono::seconds(10))) << spec.name;
  };
  check(dds::kStateTopic, static_cast<msg::InterpolatorStatePubSubType*>(nullptr));
  check(dds::kEventTopic, static_cast<msg::InterpolatorEventPubSubType*>(nullptr));
  check(dds::kSetpointsTopic, static_cast<msg::SetpointsPubSubType*>(nullptr));
  check(dds::kRequestTopic, static_cast<msg::RequestPubSubType*>(nullptr));
  check(dds::kReplyTopic, static_cast<msg::ReplyPubSubType*>(nullptr));
  check(dds::kProgramTopic, static_cast<msg::ProgramChunkPubSubType*>(nullptr));
  check(dds::kMessageTopic, static_cast<msg::MessagePubSubType*>(nullptr));
}

TEST(DdsProfiles, SetupErrorsNameTheCause) {
  DdsConfig missing = test::test_config();
  missing.profiles_file = "/nonexistent/profiles.xml";
  try {
    dds::Participant p(missing, "x");
    FAIL() << "no exception";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/profiles.xml"), std::string::npos);
  }
  try {
    dds::Participant p(test::test_config(), "x", "no_such_participant_profile");
    FAIL() << "no exception";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_participant_profile"), std::string::npos);
  }
  dds::Participant p(test::test_config(), "x");
  auto& topic = p.topic<msg::RequestPubSubType>("tgm_request_" + std::to_string(::getpid()));
  try {
    (void)p.writer(topic, "no_such_writer_profile");
    FAIL() << "no exception";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_writer_profile"), std::string::npos);
  }
  // Same topic name with another type.
  EXPECT_THROW(
      (void)p.topic<msg::ReplyPubSubType>("tgm_request_" + std::to_string(::getpid())),
      dds::SetupError);
  // Same topic name and type: the same topic.
  EXPECT_EQ(&p.topic<msg::RequestPubSubType>("tgm_request_" + std::to_string(::getpid())),
            &topic);
}

}  // namespace
}  // namespace tgm
