// Shared setup of the DDS integration tests: a config on a domain and with topic names of this
// test process only, so that concurrently running tests (ctest -j) and a running tgm never
// see each other's samples.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <string>
#include <string_view>

#include "tgm/dds/topics.hpp"
#include "tgm/yaml_config.hpp"

namespace tgm::test {

//! config/fastdds_profiles.xml, or $TGM_TEST_PROFILES (to try QoS variants without editing it).
inline std::string profiles_path() {
  const char* env = std::getenv("TGM_TEST_PROFILES");
  return env != nullptr && *env != '\0' ? env : TGM_SOURCE_DIR "/config/fastdds_profiles.xml";
}

//! Domain 100..199, chosen by process id.
inline int test_domain() { return 100 + static_cast<int>(::getpid() % 100); }

inline DdsConfig test_config() {
  DdsConfig c;
  c.domain_id = test_domain();
  c.profiles_file = profiles_path();
  c.participant_prefix = "tgmtest";
  return c;
}

//! The spec of a tgm topic, renamed to "<name>_<pid>" (same profiles).
struct TestTopic {
  std::string name;
  dds::TopicSpec spec;
};
inline TestTopic test_topic(const dds::TopicSpec& spec) {
  TestTopic t{std::string(spec.name) + "_" + std::to_string(::getpid()), spec};
  t.spec.name = t.name;
  return t;
}

}  // namespace tgm::test
