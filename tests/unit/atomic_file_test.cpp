// Output files written whole or not at all (tgm/atomic_file.hpp), shared by every binary.
#include "tgm/atomic_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace tgm {
namespace {

namespace fs = std::filesystem;

class AtomicFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tgm_atomic_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string read(const fs::path& p) const {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  //! Files in the directory other than `keep`: temporaries left behind.
  int others(const std::string& keep) const {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir_)) n += e.path().filename() != keep;
    return n;
  }
  fs::path dir_;
};

TEST_F(AtomicFileTest, AReportIsWrittenWholeAtFinishAndTheOldFileKeptUntilThen) {
  const fs::path out = dir_ / "stats.json";
  std::ofstream(out) << "old figures\n";
  {
    ReportFile r;
    std::string why;
    ASSERT_TRUE(r.open(out.string(), why)) << why;
    std::fprintf(r.stream(), "{\"cycles\": %d}\n", 42);
    EXPECT_EQ(read(out), "old figures\n");  // nothing replaced before finish()
    ASSERT_TRUE(r.finish(why)) << why;
  }
  EXPECT_EQ(read(out), "{\"cycles\": 42}\n");
  EXPECT_EQ(others("stats.json"), 0);
}

TEST_F(AtomicFileTest, AReportNeverFinishedLeavesNothingBehind) {
  const fs::path out = dir_ / "trace.csv";
  {
    ReportFile r;
    std::string why;
    ASSERT_TRUE(r.open(out.string(), why)) << why;
    std::fprintf(r.stream(), "interpolator,act_part\n");
    EXPECT_EQ(others(""), 1);  // the temporary file, created exclusively
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(others(""), 0);
}

TEST_F(AtomicFileTest, PathsThatCannotBeWrittenFailAtOpen) {
  std::string why;
  ReportFile none;  // nothing opened: nothing to print into
  EXPECT_EQ(none.stream(), nullptr);
  ReportFile dir;
  EXPECT_FALSE(dir.open(dir_.string(), why));
  EXPECT_EQ(why, "is a directory");
  ReportFile missing;
  EXPECT_FALSE(missing.open((dir_ / "no" / "such.csv").string(), why));
  EXPECT_EQ(why, "cannot create: No such file or directory");
  // A device takes the bytes only at finish(): /dev/full refuses them there.
  ReportFile full;
  ASSERT_TRUE(full.open("/dev/full", why)) << why;
  std::fprintf(full.stream(), "x\n");
  EXPECT_FALSE(full.finish(why));
  EXPECT_EQ(why, "cannot write: No space left on device");
}

TEST_F(AtomicFileTest, ALinkIsWrittenThroughAndAUsersTmpFileLeftAlone) {
  const fs::path target = dir_ / "real.csv", link = dir_ / "link.csv",
                 users = dir_ / "real.csv.tmp";
  fs::create_symlink(target, link);
  std::ofstream(users) << "mine\n";
  std::string why;
  ASSERT_TRUE(write_file_atomic(link.string(), "a,b\n", why)) << why;
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(read(target), "a,b\n");
  EXPECT_EQ(read(users), "mine\n");
}

}  // namespace
}  // namespace tgm
