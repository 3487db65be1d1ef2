// A running tgm-service for one integration test: its own temp directory, a config derived from
// config/default.yaml (domain of this test process, absolute profiles path, faster default
// feed so the manual's example runs in seconds), and helpers to run tgm-plc / tgm-hmi.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "dds_test_util.hpp"
#include "process_util.hpp"

namespace tgm::test {

struct ConfigEdits {
  double default_feed_mm_per_min = 6000;
  //! Buffer_Size of interpolator 0 (the default config has 10000).
  int buffer_size0 = 10000;
  //! How many of the default config's three interpolators the config keeps (1..3).
  int interpolators = 3;
  //! plc.setup_before_start (default.yaml: true). Off unless a test wants it: most tests run
  //! programs without a tgm-plc.
  bool plc_setup_before_start = false;
  std::string profiles = profiles_path();
  int domain = test_domain();
};

class ServiceEnv {
 public:
  explicit ServiceEnv(const ConfigEdits& e = {}) : domain_(e.domain), profiles_(e.profiles) {
    dir_ = std::filesystem::temp_directory_path() /
           ("tgm_it_" + std::to_string(::getpid()) + "_" + std::to_string(counter()++));
    std::filesystem::create_directories(dir_);
    std::string yaml = read_text(TGM_SOURCE_DIR "/config/default.yaml");
    const std::string entry =
        "  - buffer_size: 10000\n    axes: [{letter: X}, {letter: Y}, {letter: Z}]\n";
    bool ok = true;
    for (int k = e.interpolators; k < 3 && ok; ++k) {
      const std::size_t at = yaml.rfind(entry);
      ok = at != std::string::npos;
      if (ok) yaml.erase(at, entry.size());
    }
    ok = ok &&
         replace_first(yaml, "default_feed_mm_per_min: 1000",
                       "default_feed_mm_per_min: " + std::to_string(e.default_feed_mm_per_min));
    ok = ok && replace_first(yaml, "# profiles_file: fastdds_profiles.xml",
                             "profiles_file: " + e.profiles);
    ok = ok && replace_first(yaml, "domain_id: 0", "domain_id: " + std::to_string(e.domain));
    ok = ok && replace_first(yaml, "buffer_size: 10000", "buffer_size: " + std::to_string(e.buffer_size0));
    ok = ok && replace_first(yaml, "setup_before_start: true",
                             std::string("setup_before_start: ") +
                                 (e.plc_setup_before_start ? "true" : "false"));
    EXPECT_TRUE(ok) << "config/default.yaml changed: the test's edits no longer apply";
    config_ = (dir_ / "config.yaml").string();
    std::ofstream(config_) << yaml;
  }
  ~ServiceEnv() {
    service.interrupt();
    std::error_code ec;
    if (!::testing::Test::HasFailure()) std::filesystem::remove_all(dir_, ec);
  }
  ServiceEnv(const ServiceEnv&) = delete;
  ServiceEnv& operator=(const ServiceEnv&) = delete;

  //! Starts tgm-service (no real-time scheduling: tests share the machine) with extra args and
  //! extra environment ("NAME=value"). A `--config` among the extra args replaces this
  //! environment's (a flag may be given once).
  bool start_service(std::vector<std::string> extra = {},
                     const std::vector<std::string>& extra_env = {}) {
    const bool own_config = std::find(extra.begin(), extra.end(), "--config") != extra.end();
    std::vector<std::string> args{TGM_SERVICE_BIN, "--no-realtime", "--stats", stats_path()};
    if (!own_config) args.insert(args.begin() + 1, {"--config", config_});
    args.insert(args.end(), extra.begin(), extra.end());
    return service.start(args, path("service.log"), extra_env);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string stats_path() const { return path("service_stats.json"); }
  const std::string& config() const { return config_; }
  int domain() const { return domain_; }
  DdsConfig dds() const {
    DdsConfig c;
    c.domain_id = domain_;
    c.profiles_file = profiles_;
    c.participant_prefix = "tgm";
    return c;
  }

  Child service;

 private:
  static int& counter() {
    static int n = 0;
    return n;
  }
  std::filesystem::path dir_;
  std::string config_;
  int domain_;
  std::string profiles_;
};

//! "end position X.. Y.. Z.." of `tgm-hmi run`'s summary (four decimals); NaN where missing.
inline std::array<double, 3> run_end_position(const std::string& log) {
  std::array<double, 3> end = {NAN, NAN, NAN};
  if (const auto at = log.find("end position "); at != std::string::npos)
    std::sscanf(log.c_str() + at, "end position X%lf Y%lf Z%lf", &end[0], &end[1], &end[2]);
  return end;
}

//! config/security/tgm-security, which makes DDS Security material.
inline const std::string kSecurityTool = TGM_SOURCE_DIR "/config/security/tgm-security";

//! The openssl command tgm-security needs is there.
inline bool have_openssl() {
  return std::system("command -v openssl >/dev/null 2>&1") == 0;
}

//! Runs tgm-security --out `dir`, its output to `log`; false when it failed.
inline bool make_security_material(const std::string& dir, const std::string& log = "/dev/null") {
  const std::string cmd = "'" + kSecurityTool + "' --out '" + dir + "' >'" + log + "' 2>&1";
  return std::system(cmd.c_str()) == 0;
}

}  // namespace tgm::test
