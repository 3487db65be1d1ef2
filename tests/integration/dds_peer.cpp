// Helper process of the DDS integration tests: joins a domain with a request writer and waits
// to be killed (or 60 s). Usage: tgm_dds_test_peer <profiles.xml> <domain> <topic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

#include "tgm/cli_numbers.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace {
constexpr const char* kUsage =
    "usage: tgm_dds_test_peer PROFILES DOMAIN TOPIC\n"
    "Test helper (DdsLoopback): joins DOMAIN (0..232) with the Fast DDS PROFILES, writes one\n"
    "Request on TOPIC once a reader matched, and waits 60 s or until killed.\n";
}  // namespace

int main(int argc, char** argv) {
  if (argc == 2 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  tgm::DdsConfig config;
  if (argc != 4 || !tgm::parse_integer(argv[2], 0, 232, config.domain_id)) {
    std::fprintf(stderr, "tgm_dds_test_peer: expected PROFILES DOMAIN(0..232) TOPIC\n%s", kUsage);
    return 2;
  }
  config.profiles_file = argv[1];
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
