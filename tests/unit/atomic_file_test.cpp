// Output files written whole or not at all (tgm/atomic_file.hpp), shared by every binary.
#include "tgm/atomic_file.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
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

// Two files open at once in one thread: their stdio buffers were one thread_local array, so
// the bytes of the first still pending when the second wrote were the second's.
TEST_F(AtomicFileTest, TwoFilesOpenAtOnceKeepTheirOwnBytes) {
  AtomicFile a, b;
  std::string why;
  ASSERT_TRUE(a.open((dir_ / "a.txt").string(), why)) << why;
  ASSERT_TRUE(b.open((dir_ / "b.txt").string(), why)) << why;
  const std::string as(1000, 'a'), bs(600, 'b');
  ASSERT_TRUE(a.write(as.data(), as.size(), why)) << why;
  ASSERT_TRUE(b.write(bs.data(), bs.size(), why)) << why;
  ASSERT_TRUE(a.write("end a\n", 6, why)) << why;
  ASSERT_TRUE(a.commit(why)) << why;
  ASSERT_TRUE(b.commit(why)) << why;
  EXPECT_EQ(read(dir_ / "a.txt"), as + "end a\n");
  EXPECT_EQ(read(dir_ / "b.txt"), bs);
}

// A file replaced keeps its permissions: a program made private (0600) was readable by all
// (0644) once compiled again.
TEST_F(AtomicFileTest, AReplacedFileKeepsItsPermissions) {
  const fs::path out = dir_ / "private.tgmi";
  std::ofstream(out) << "old\n";
  ASSERT_EQ(::chmod(out.c_str(), 0600), 0);
  std::string why;
  ASSERT_TRUE(write_file_atomic(out.string(), "new\n", why)) << why;
  struct stat st {};
  ASSERT_EQ(::stat(out.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0600u);
  EXPECT_EQ(read(out), "new\n");
}

// Ctrl-C (or SIGTERM, SIGHUP) during a write whose program does not handle the signal itself
// (tgm-hmi compile --out) left "<out>.tmp-<pid>" behind: the temporary file is removed, the
// output left as it was, and the process still ends by the signal.
TEST_F(AtomicFileTest, ASignalRemovesTheTemporaryFileAndStillEndsTheProcess) {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
    const fs::path out = dir_ / ("out" + std::to_string(sig));
    std::ofstream(out) << "old\n";
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      for (const int s : {SIGINT, SIGTERM, SIGHUP}) ::signal(s, SIG_DFL);
      AtomicFile f;
      std::string e;
      if (!f.open(out.string(), e)) ::_exit(3);
      const std::string bytes(3 << 20, 'x');  // beyond the buffer: on disk already
      if (!f.write(bytes.data(), bytes.size(), e)) ::_exit(4);
      ::raise(sig);
      ::_exit(5);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "signal " << sig << ": exit " << WEXITSTATUS(status);
    EXPECT_EQ(WTERMSIG(status), sig);
    EXPECT_EQ(read(out), "old\n");
    int temps = 0;
    for (const auto& e : fs::directory_iterator(dir_)) {
      temps += e.path().filename().string().find(".tmp-") != std::string::npos;
    }
    EXPECT_EQ(temps, 0) << "signal " << sig;
  }
}

}  // namespace
}  // namespace tgm
