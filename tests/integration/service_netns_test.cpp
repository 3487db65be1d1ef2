// The three processes in three Linux network namespaces joined by veth pairs to a bridge (in a
// fourth namespace), so that every DDS sample crosses a (virtual) network, as between the
// containers of docker/compose.yaml. Addresses 10.231.0.0/24 exist only inside the namespaces
// this test creates; it removes them even when it fails. Needs root and `ip netns`: skipped
// otherwise.
//
// Transport: Fast DDS shared memory does not connect processes in different network namespaces
// (as in containers), so the processes use a UDPv4-only copy of config/fastdds_profiles.xml with
// the three addresses as initial peers (docker/make_udp_profiles.sh; unicast discovery, no
// dependence on multicast routing across the bridge).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "service_test_env.hpp"

namespace tgm {
namespace {

using namespace std::chrono_literals;

std::string ip_binary() {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"}) {
    if (::access(p, X_OK) == 0) return p;
  }
  return {};
}

// Runs a shell command line; true on exit code 0.
bool sh(const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()) == 0; }

// Three namespaces (service, plc, hmi) on a bridge in a fourth; removed by the destructor.
class Namespaces {
 public:
  explicit Namespaces(const std::string& ip) : ip_(ip) {
    const std::string tag = "tgm" + std::to_string(::getpid() % 100000);
    bridge_ = tag + "br";
    names_ = {tag + "svc", tag + "plc", tag + "hmi"};
  }
  ~Namespaces() {
    for (const auto& n : names_) sh(ip_ + " netns del " + n);
    sh(ip_ + " netns del " + bridge_);
  }
  bool create(std::string& error) {
    auto run = [&](const std::string& c) {
      if (sh(ip_ + " " + c)) return true;
      error = "ip " + c + " failed";
      return false;
    };
    if (!run("netns add " + bridge_) || !run("-n " + bridge_ + " link add br0 type bridge") ||
        !run("-n " + bridge_ + " link set br0 type bridge mcast_snooping 0") ||
        !run("-n " + bridge_ + " link set br0 up") || !run("-n " + bridge_ + " link set lo up")) {
      return false;
    }
    for (std::size_t i = 0; i < names_.size(); ++i) {
      const std::string& n = names_[i];
      std::string port = "p";
      port += std::to_string(i);  // not "p" + ...: GCC 12 -O3 warns falsely (-Wrestrict)
      if (!run("netns add " + n) ||
          !run("-n " + bridge_ + " link add " + port + " type veth peer name eth0 netns " + n) ||
          !run("-n " + bridge_ + " link set " + port + " master br0") ||
          !run("-n " + bridge_ + " link set " + port + " up") || !run("-n " + n + " link set lo up") ||
          !run("-n " + n + " addr add " + address(i) + "/24 dev eth0") || !run("-n " + n + " link set eth0 up") ||
          !run("-n " + n + " route add 224.0.0.0/4 dev eth0")) {
        return false;
      }
    }
    return true;
  }
  static std::string address(std::size_t i) { return "10.231.0." + std::to_string(i + 1); }
  const std::string& name(std::size_t i) const { return names_[i]; }
  std::vector<std::string> exec(std::size_t i, std::vector<std::string> args) const {
    std::vector<std::string> out{ip_, "netns", "exec", names_[i]};
    out.insert(out.end(), args.begin(), args.end());
    return out;
  }

 private:
  std::string ip_;
  std::string bridge_;
  std::vector<std::string> names_;
};

// config/fastdds_profiles.xml with the tgm_participant on UDPv4 only and the three namespace
// addresses as initial peers: made by docker/make_udp_profiles.sh, the same script that makes the
// profiles of docker/compose.yaml.
std::string udp_profiles(const std::string& dir) {
  const std::string path = dir + "/fastdds_profiles_udp.xml";
  std::string cmd = "bash " TGM_SOURCE_DIR "/docker/make_udp_profiles.sh";
  for (std::size_t i = 0; i < 3; ++i) (cmd += ' ') += Namespaces::address(i);
  EXPECT_EQ(std::system((cmd + " > " + path).c_str()), 0) << cmd;
  EXPECT_NE(test::read_text(path).find("<useBuiltinTransports>false</useBuiltinTransports>"), std::string::npos);
  return path;
}

TEST(ServiceNetns, ManualExampleAcrossThreeNetworkNamespaces) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to create network namespaces";
  const std::string ip = ip_binary();
  if (ip.empty() || !sh(ip + " netns list")) GTEST_SKIP() << "`ip netns` is not available";
  Namespaces ns(ip);
  std::string error;
  if (!ns.create(error)) GTEST_SKIP() << "cannot create network namespaces here: " << error;

  const std::string dir = std::filesystem::temp_directory_path() / ("tgm_netns_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  test::ConfigEdits edits;
  edits.profiles = udp_profiles(dir);
  test::ServiceEnv env(edits);

  test::Child service, plc, hmi;
  ASSERT_TRUE(service.start(ns.exec(0, {TGM_SERVICE_BIN, "--config", env.config(), "--no-realtime"}),
                            env.path("service.log")));
  ASSERT_TRUE(plc.start(ns.exec(1, {TGM_PLC_BIN, "--config", env.config()}), env.path("plc.log")));
  ASSERT_TRUE(hmi.start(ns.exec(2, {TGM_HMI_BIN, "run", TGM_SOURCE_DIR "/tests/programs/manual_example.ngc",
                                    "--config", env.config()}),
                        env.path("hmi.log")));
  const int code = hmi.wait(120s);
  EXPECT_EQ(code, 0) << hmi.log() << "\n--- plc:\n" << plc.log() << "\n--- service:\n" << service.log();
  EXPECT_EQ(plc.interrupt(), 0);
  EXPECT_EQ(service.interrupt(), 0) << service.log();
  EXPECT_NE(hmi.log().find("done: 13 records"), std::string::npos) << hmi.log();
  EXPECT_EQ(test::count_of(plc.log(), "acknowledged after"), 3) << plc.log();
  std::error_code ec;
  if (!::testing::Test::HasFailure()) std::filesystem::remove_all(dir, ec);
}

}  // namespace
}  // namespace tgm
