// Helper process of the DDS integration tests: joins a domain with a request writer and waits
// to be killed (or 60 s). Usage: tgm_dds_test_peer <profiles.xml> <domain> <topic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s PROFILES DOMAIN TOPIC\n", argv[0]);
    return 2;
  }
  tgm::DdsConfig config;
  config.profiles_file = argv[1];
  config.domain_id = std::atoi(argv[2]);
  config.participant_prefix = "tgmtest";
  try {
    tgm::dds::Participant p(config, "peer");
    tgm::dds::TopicSpec spec = tgm::dds::kRequestTopic;
    const std::string topic = argv[3];
    spec.name = topic;
    auto& writer = p.writer<tgm::msg::RequestPubSubType>(spec);
    tgm::dds::wait_for_match(writer, 1, std::chrono::seconds(30));
    tgm::msg::Request r;
    r.client_name("peer");
    writer.write(&r);
    std::this_thread::sleep_for(std::chrono::seconds(60));
  } catch (const tgm::dds::SetupError& e) {
    std::fprintf(stderr, "tgm_dds_test_peer: %s\n", e.what());
    return 1;
  }
  return 0;
}
