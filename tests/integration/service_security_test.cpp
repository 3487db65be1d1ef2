// DDS Security (DESIGN.md sections 1 and 6): with the material of config/security/tgm-security
// every process authenticates with its role's certificate, the traffic is encrypted, and the
// permissions let each role publish and subscribe only what it needs. The service, the PLC
// emulator and the HMI run the manual's example so; a participant without the material sees
// nothing of them; a role's identity cannot create a writer its permissions do not name (the
// PLC cannot write the program stream, nobody but the service can publish states or replies);
// missing or foreign material is an error that names the file or the identity.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>

#include "hand_request.hpp"
#include "service_test_env.hpp"
#include "tgm/client/client.hpp"
#include "tgm/dds/participant.hpp"
#include "tgm/dds/topics.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm {
namespace {

using namespace std::chrono_literals;
using test::ServiceEnv;

constexpr auto kHang = 60s;
class ServiceSecurity : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!test::have_openssl()) GTEST_SKIP() << "no openssl command (.ci/deps installs it)";
    sec_ = env_.path("security");
    ASSERT_TRUE(test::make_security_material(sec_, env_.path("tgm-security.log")))
        << test::read_text(env_.path("tgm-security.log"));
  }
  DdsConfig secure_dds() const {
    DdsConfig c = env_.dds();
    c.security_dir = sec_;
    return c;
  }
  std::vector<std::string> with_security(std::vector<std::string> args) const {
    args.insert(args.end(), {"--config", env_.config(), "--security", sec_});
    return args;
  }

  ServiceEnv env_;
  std::string sec_;
};

TEST_F(ServiceSecurity, TheThreeProcessesRunTheManualExampleAndOutsidersSeeNothing) {
  ASSERT_TRUE(env_.start_service({"--security", sec_}));
  test::Child plc;
  ASSERT_TRUE(plc.start(with_security({TGM_PLC_BIN, "--quiet"}), env_.path("plc.log")));
  test::Child hmi;
  ASSERT_TRUE(hmi.start(
      with_security({TGM_HMI_BIN, "run", TGM_SOURCE_DIR "/tests/programs/manual_example.ngc"}),
      env_.path("hmi.log")));
  EXPECT_EQ(hmi.wait(kHang), 0) << hmi.log() << "\n--- plc:\n" << plc.log();
  EXPECT_NE(hmi.log().find("3 M-function waits"), std::string::npos) << hmi.log();
  EXPECT_EQ(test::run_end_position(hmi.log())[0], 47.2495) << hmi.log();

  // A client with the material gets the state at once; one without it, on the same domain at
  // the same time, gets nothing: it cannot join (the governance allows no unauthenticated
  // participant), and the traffic it would see is encrypted.
  client::Client insider(secure_dds(), client::Role::kHmi);
  ASSERT_TRUE(insider.wait_for_state(0, kHang));
  EXPECT_EQ(insider.state(0)->status(), 3);
  client::Client outsider(env_.dds(), client::Role::kHmi);
  EXPECT_FALSE(outsider.wait_for_state(0, 3s)) << "an unauthenticated client read the state";
  const client::Reply r = outsider.clear(0);
  EXPECT_TRUE(r.timed_out && !r.sent) << client::describe(r);
  EXPECT_EQ(insider.state(0)->status(), 3) << "the outsider's clear reached the service";

  EXPECT_EQ(plc.interrupt(), 0);
  const std::string log = plc.log();
  EXPECT_EQ(test::count_of(log, ": accepted (cycle"), 3) << log;
}

// Write access by role, as the permissions tgm-security signs say (DESIGN.md section 1): the
// writer is refused when it is created, so nothing of it ever reaches the network.
TEST_F(ServiceSecurity, EachRoleCanWriteOnlyWhatItsPermissionsName) {
  const DdsConfig c = secure_dds();
  auto refused = [&](auto& p, auto writer) {
    try {
      writer(p);
    } catch (const dds::SetupError& e) {
      return std::string(e.what()).find(
                 "not allowed by this identity's DDS Security permissions") != std::string::npos;
    }
    return false;
  };
  {
    dds::Participant plc(c, "plc");
    EXPECT_NO_THROW(plc.writer<msg::RequestPubSubType>(dds::kRequestPlcTopic));
    EXPECT_TRUE(refused(plc, [](dds::Participant& p) {
      p.writer<msg::RequestPubSubType>(dds::kRequestHmiTopic);
    })) << "the PLC may not write on the HMI's request topic";
    EXPECT_TRUE(refused(plc, [](dds::Participant& p) {
      p.writer<msg::RequestPubSubType>(dds::kRequestTopic);
    })) << "nor on the one whose samples name their role";
    EXPECT_TRUE(refused(plc, [](dds::Participant& p) {
      p.writer<msg::ProgramChunkPubSubType>(dds::kProgramTopic);
    })) << "the PLC may not fill the buffer";
    EXPECT_TRUE(refused(plc, [](dds::Participant& p) {
      p.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic);
    })) << "the PLC may not pose as the service";
    EXPECT_TRUE(refused(
        plc, [](dds::Participant& p) { p.writer<msg::ReplyPubSubType>(dds::kReplyTopic); }));
  }
  {
    dds::Participant hmi(c, "hmi");
    EXPECT_NO_THROW(hmi.writer<msg::ProgramChunkPubSubType>(dds::kProgramTopic));
    EXPECT_NO_THROW(hmi.writer<msg::RequestPubSubType>(dds::kRequestHmiTopic));
    EXPECT_TRUE(refused(
        hmi, [](dds::Participant& p) { p.writer<msg::RequestPubSubType>(dds::kRequestPlcTopic); }));
    EXPECT_TRUE(refused(hmi, [](dds::Participant& p) {
      p.writer<msg::InterpolatorEventPubSubType>(dds::kEventTopic);
    }));
    EXPECT_TRUE(refused(
        hmi, [](dds::Participant& p) { p.writer<msg::MessagePubSubType>(dds::kMessageTopic); }));
  }
  {
    dds::Participant service(c, "service");
    EXPECT_NO_THROW(service.writer<msg::InterpolatorStatePubSubType>(dds::kStateTopic));
    EXPECT_TRUE(refused(service, [](dds::Participant& p) {
      p.writer<msg::RequestPubSubType>(dds::kRequestPlcTopic);
    })) << "the service answers requests, it does not make them";
  }
  // A role tgm-security made no identity for.
  try {
    dds::Participant rogue(c, "rogue");
    ADD_FAILURE() << "a participant without an identity joined";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find("rogue.pem' is missing"), std::string::npos) << e.what();
  }
}

// A request's role is its topic's: a PLC identity that writes a start request claiming to be
// the HMI (the role field of the sample) is refused as the PLC it is. Without security the
// field is the client's word (README, "Roles").
TEST_F(ServiceSecurity, ARequestsRoleIsThatOfTheIdentityThatWroteIt) {
  ASSERT_TRUE(env_.start_service({"--security", sec_}));
  client::Client hmi(secure_dds(), client::Role::kHmi);
  ASSERT_TRUE(hmi.wait_for_state(0, kHang));
  dds::Participant forger(secure_dds(), "plc");
  auto& requests = forger.writer<msg::RequestPubSubType>(dds::kRequestPlcTopic);
  auto& replies = forger.reader<msg::ReplyPubSubType>(dds::kReplyTopic);
  ASSERT_TRUE(dds::wait_for_match(requests, 1, kHang));
  ASSERT_TRUE(dds::wait_for_match(replies, 1, kHang));
  msg::Request r = test::hand_request(7, msg::CLIENT_ROLE_HMI, "forger", msg::REQUEST_KIND_CLEAR);
  ASSERT_TRUE(requests.write(&r));
  const std::optional<msg::Reply> reply = test::await_reply(replies, "forger", 7, kHang);
  ASSERT_TRUE(reply.has_value()) << "no reply to the forged request";
  EXPECT_FALSE(reply->accepted());
  EXPECT_EQ(reply->code(), msg::REPLY_CODE_WRONG_ROLE) << reply->reason();
  // The HMI's own clear, on its own topic, is its.
  const client::Reply mine = hmi.clear(0);
  EXPECT_TRUE(mine.accepted) << client::describe(mine);
}

TEST_F(ServiceSecurity, MissingOrForeignMaterialIsAnErrorNamingIt) {
  // No such directory: a config error (exit 2) before any DDS.
  test::Child service;
  ASSERT_TRUE(service.start({TGM_SERVICE_BIN, "--config", env_.config(), "--no-realtime",
                             "--security", env_.path("nowhere")},
                            env_.path("service.log")));
  EXPECT_EQ(service.wait(kHang), 2) << service.log();
  EXPECT_NE(service.log().find("the DDS Security directory '" + env_.path("nowhere") +
                               "' does not exist"),
            std::string::npos)
      << service.log();

  // A file of the role missing.
  std::filesystem::remove(sec_ + "/plc.key");
  test::Child plc;
  ASSERT_TRUE(plc.start(with_security({TGM_PLC_BIN}), env_.path("plc.log")));
  EXPECT_EQ(plc.wait(kHang), 2) << plc.log();
  EXPECT_NE(plc.log().find("DDS Security: '" + sec_ + "/plc.key' is missing"), std::string::npos)
      << plc.log();

  // An identity of another installation (another CA): Fast DDS refuses it, and the HMI says
  // which identity and where.
  const std::string other = env_.path("other");
  ASSERT_TRUE(test::make_security_material(other, env_.path("other.log")));
  std::filesystem::copy_file(other + "/hmi.pem", sec_ + "/hmi.pem",
                             std::filesystem::copy_options::overwrite_existing);
  std::filesystem::copy_file(other + "/hmi.key", sec_ + "/hmi.key",
                             std::filesystem::copy_options::overwrite_existing);
  test::Child hmi;
  ASSERT_TRUE(hmi.start(with_security({TGM_HMI_BIN, "status"}), env_.path("hmi.log")));
  EXPECT_NE(hmi.wait(kHang), 0) << hmi.log();
  EXPECT_NE(hmi.log().find("DDS Security refused the hmi identity or permissions in '" + sec_),
            std::string::npos)
      << hmi.log();

  // The tool refuses to overwrite material, and says how.
  EXPECT_FALSE(test::make_security_material(other, env_.path("again.log")));
  EXPECT_NE(test::read_text(env_.path("again.log")).find("--force overwrites it"),
            std::string::npos);
}

// tgm-security's arguments: each bad one is named (exit 2); permissions for other domains than
// the participant's are refused by Fast DDS, and the binary says so.
TEST_F(ServiceSecurity, TheToolsArgumentsAndTheDomainsItsPermissionsAllow) {
  auto tool = [&](const std::string& args, const std::string& log) {
    const int rc =
        std::system(("'" + test::kSecurityTool + "' " + args + " >'" + log + "' 2>&1").c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  };
  const std::string log = env_.path("tool.log");
  const std::string dir = env_.path("narrow");
  // --version, as every binary has it, the same as tgm-service's.
  EXPECT_EQ(tool("--version", log), 0);
  EXPECT_EQ(std::system(("'" + std::string(TGM_SERVICE_BIN) + "' --version >'" +
                         env_.path("service_version.log") + "' 2>&1")
                            .c_str()),
            0);
  std::string service_version = test::read_text(env_.path("service_version.log"));
  ASSERT_EQ(service_version.rfind("tgm-service ", 0), 0u) << service_version;
  EXPECT_EQ(test::read_text(log), "tgm-security " + service_version.substr(12));
  EXPECT_EQ(tool("", log), 2);
  EXPECT_NE(test::read_text(log).find("--out DIR is required"), std::string::npos);
  EXPECT_EQ(tool("--out " + dir + " --days 0", log), 2);
  EXPECT_NE(test::read_text(log).find("--days takes 1..36500, not '0'"), std::string::npos);
  EXPECT_EQ(tool("--out " + dir + " --domains 9-3", log), 2);
  EXPECT_NE(test::read_text(log).find("--domains takes MIN-MAX within 0..232, not '9-3'"),
            std::string::npos);
  EXPECT_EQ(tool("--out " + dir + " --bogus", log), 2);
  EXPECT_NE(test::read_text(log).find("unknown argument '--bogus'"), std::string::npos);
  // A missing value is named, not taken from the next option (a directory named --force) and
  // not said by the shell with the script's line number.
  EXPECT_EQ(tool("--out --force", log), 2);
  EXPECT_EQ(test::read_text(log), "tgm-security: --out needs a directory (see --help)\n");
  EXPECT_EQ(tool("--out " + dir + " --days", log), 2);
  EXPECT_EQ(test::read_text(log), "tgm-security: --days needs a number of days (see --help)\n");
  EXPECT_EQ(tool("--out /dev/null", log), 2);
  EXPECT_EQ(test::read_text(log), "tgm-security: '/dev/null' exists and is not a directory\n");
  EXPECT_EQ(tool("--help", log), 0);
  EXPECT_NE(test::read_text(log).find("usage: tgm-security --out DIR"), std::string::npos);

  // Permissions for domains 0-9: the test's domain (10..99) is not among them, and no topic
  // may be read or written there.
  ASSERT_EQ(tool("--out " + dir + " --domains 0-9", log), 0) << test::read_text(log);
  DdsConfig c = env_.dds();
  c.security_dir = dir;
  ASSERT_GE(c.domain_id, 10);
  try {
    client::Client hmi(c, client::Role::kHmi);
    ADD_FAILURE() << "a client worked on a domain its permissions do not name";
  } catch (const dds::SetupError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "not allowed by this identity's DDS Security permissions for this topic on "
                  "domain " +
                  std::to_string(c.domain_id) + " (tgm-security --domains)"),
              std::string::npos)
        << e.what();
  }
  c.domain_id = 9;  // within them
  EXPECT_NO_THROW(client::Client(c, client::Role::kHmi));
}

}  // namespace
}  // namespace tgm
