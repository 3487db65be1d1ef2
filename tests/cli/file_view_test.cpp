// FileView, the way tgm-hmi reads its program files: a file that another program truncates or
// writes while it is being read is an error that check() names, never a SIGBUS; a SIGBUS that
// is not about a guarded mapping keeps its disposition.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "cli_fixture.hpp"

namespace tgm {
namespace {

namespace fs = std::filesystem;
using hmi::FileView;
using FileViewTest = test::CliTest;

constexpr std::size_t kSize = 256 * 1024;  // 64 pages of 4 kB

// Text of `size` bytes, no zero byte in it, different at every offset modulo 251.
std::string pattern(std::size_t size) {
  std::string s(size, ' ');
  for (std::size_t i = 0; i < size; ++i) s[i] = static_cast<char>('!' + i % 251 % 90);
  return s;
}

// Sets the file's modification time an hour back: a write in the test then changes it even
// where timestamps are coarse.
void age(const fs::path& p) {
  struct timespec times[2];
  timespec_get(&times[0], TIME_UTC);
  times[0].tv_sec -= 3600;
  times[1] = times[0];
  ASSERT_EQ(utimensat(AT_FDCWD, p.c_str(), times, 0), 0);
}

// Sums every byte of the view (the reads a compiler does), the zero bytes counted apart.
std::size_t zero_bytes(std::string_view text) {
  std::size_t zeros = 0;
  for (const char c : text) zeros += c == '\0' ? 1 : 0;
  return zeros;
}

TEST_F(FileViewTest, AnUnchangedFileReadsWholeAndChecksOut) {
  const fs::path p = write("prog.ngc", pattern(kSize));
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  EXPECT_EQ(view.text(), pattern(kSize));
  std::string why;
  EXPECT_TRUE(view.check(why)) << why;
  EXPECT_TRUE(why.empty());
}

// "-" reads standard input whatever it is: a pipe, a regular file (`< prog.ngc`), or a socket
// (ssh, inetd, systemd socket units), which cannot be opened by a path: "-" used to open
// /dev/stdin and failed there with "cannot open: No such device or address".
TEST_F(FileViewTest, StandardInputIsReadAlsoWhenItIsASocketOrAFile) {
  // Descriptor 0 as it was, also when an assertion ends the test early.
  struct RestoreStdin {
    int saved = ::dup(0);
    ~RestoreStdin() {
      if (saved < 0) return;
      ::dup2(saved, 0);
      ::close(saved);
    }
  } restore;
  ASSERT_GE(restore.saved, 0);
  const auto read_dash = [](std::string& text, std::string& error) {
    FileView view;
    if (!view.open("-", error)) return false;
    text = std::string(view.text());
    return true;
  };
  int pair[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, pair), 0);
  const std::string program = "G90 G1 X10 F3000\nM2\n";
  ASSERT_EQ(::write(pair[1], program.data(), program.size()), static_cast<ssize_t>(program.size()));
  ::close(pair[1]);
  ASSERT_EQ(::dup2(pair[0], 0), 0);
  ::close(pair[0]);
  std::string text, error;
  const bool from_socket = read_dash(text, error);
  const fs::path p = write("prog.ngc", pattern(kSize));
  const int file = ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(file, 0);
  ASSERT_EQ(::dup2(file, 0), 0);
  ::close(file);
  std::string file_text, file_error;
  const bool from_file = read_dash(file_text, file_error);
  ::close(0);  // no standard input at all
  std::string none_text, none_error;
  const bool from_nothing = read_dash(none_text, none_error);
  ASSERT_TRUE(from_socket) << error;
  EXPECT_EQ(text, program);
  ASSERT_TRUE(from_file) << file_error;
  EXPECT_EQ(file_text, pattern(kSize));
  EXPECT_FALSE(from_nothing);
  EXPECT_EQ(none_error, "cannot read standard input: Bad file descriptor");
}

TEST_F(FileViewTest, AFileTruncatedWhileMappedReadsZerosAndIsCutShort) {
  const fs::path p = write("prog.ngc", pattern(kSize));
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  // What `>` does to a file another program still reads: cut to the first 100 bytes.
  ASSERT_EQ(truncate(p.c_str(), 100), 0);
  const std::string_view text = view.text();
  ASSERT_EQ(text.size(), kSize);
  // Reading on past the cut: without the guard, SIGBUS here ended the process.
  const std::size_t zeros = zero_bytes(text);
  EXPECT_GT(zeros, kSize / 2);
  EXPECT_EQ(text.substr(0, 100), pattern(100));
  EXPECT_EQ(text.back(), '\0');
  std::string why;
  EXPECT_FALSE(view.check(why));
  EXPECT_NE(why.find("cut short while it was read"), std::string::npos) << why;
}

TEST_F(FileViewTest, AGrownFileIsNamedWithBothSizes) {
  const fs::path p = write("prog.ngc", pattern(kSize));
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  std::ofstream(p, std::ios::app) << "M2\n";
  EXPECT_EQ(view.text(), pattern(kSize));
  std::string why;
  EXPECT_FALSE(view.check(why));
  EXPECT_NE(why.find("262144 bytes when it was opened, 262147 now"), std::string::npos) << why;
}

TEST_F(FileViewTest, AFileWrittenInPlaceAtTheSameSizeIsNamed) {
  const fs::path p = write("prog.ngc", pattern(kSize));
  age(p);
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(1000);
    f << "G1 X0";
  }
  ASSERT_EQ(fs::file_size(p), kSize);
  std::string why;
  EXPECT_FALSE(view.check(why));
  EXPECT_NE(why.find("written while it was read"), std::string::npos) << why;
}

TEST_F(FileViewTest, AFileReplacedByRenameIsNotAChangeOfTheOneRead) {
  // Editors and atomic writers put a new file in place: the view keeps the one it opened.
  const fs::path p = write("prog.ngc", pattern(kSize));
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  const fs::path q = write("new.ngc", "G1 X1\nM2\n");
  fs::rename(q, p);
  EXPECT_EQ(view.text(), pattern(kSize));
  std::string why;
  EXPECT_TRUE(view.check(why)) << why;
}

TEST_F(FileViewTest, MoreViewsThanGuardSlotsAreReadInsteadAndStillChecked) {
  std::vector<std::unique_ptr<FileView>> views;
  std::vector<fs::path> paths;
  for (int i = 0; i < 12; ++i) {
    paths.push_back(write("prog" + std::to_string(i) + ".ngc", pattern(kSize - 7 * i)));
    views.push_back(std::make_unique<FileView>());
    std::string error;
    ASSERT_TRUE(views.back()->open(paths.back().string(), error)) << error;
  }
  for (int i = 0; i < 12; ++i) {
    ASSERT_EQ(truncate(paths[static_cast<std::size_t>(i)].c_str(), 10), 0);
    const std::string_view text = views[static_cast<std::size_t>(i)]->text();
    EXPECT_EQ(text.size(), kSize - 7 * static_cast<std::size_t>(i));
    (void)zero_bytes(text);  // a guarded mapping reads zeros, a copy its bytes: no SIGBUS
    std::string why;
    EXPECT_FALSE(views[static_cast<std::size_t>(i)]->check(why)) << "view " << i;
  }
}

TEST_F(FileViewTest, ASlotIsFreeAgainOnceItsViewIsGone) {
  const fs::path p = write("prog.ngc", pattern(kSize));
  for (int round = 0; round < 20; ++round) {
    FileView view;
    std::string error;
    ASSERT_TRUE(view.open(p.string(), error)) << error;
    std::string why;
    EXPECT_TRUE(view.check(why)) << "round " << round << ": " << why;
  }
  // Twenty views came and went; a twenty-first is still guarded (it reads zeros past a cut
  // rather than holding a copy of the old bytes).
  FileView view;
  std::string error;
  ASSERT_TRUE(view.open(p.string(), error)) << error;
  ASSERT_EQ(truncate(p.c_str(), 0), 0);
  EXPECT_EQ(zero_bytes(view.text()), kSize);
}

// A SIGBUS on memory no FileView guards: `before` (a handler, or the default) gets it as it
// would without the guard.
void touch_cut_mapping_of_another_file(const std::string& guarded, const std::string& other,
                                       void (*before)(int)) {
  if (before != nullptr) {
    struct sigaction sa {};
    sa.sa_handler = before;
    sigemptyset(&sa.sa_mask);
    if (sigaction(SIGBUS, &sa, nullptr) != 0) _exit(2);
  }
  FileView view;  // installs the guard over `before`
  std::string error;
  if (!view.open(guarded, error)) _exit(3);
  const int fd = ::open(other.c_str(), O_RDONLY);
  if (fd < 0) _exit(4);
  auto* p = static_cast<volatile const char*>(mmap(nullptr, kSize, PROT_READ, MAP_SHARED, fd, 0));
  if (p == MAP_FAILED) _exit(5);
  if (truncate(other.c_str(), 0) != 0) _exit(6);
  const char c = p[kSize - 1];
  _exit(c == 0 ? 7 : 8);
}

void exit_42(int) {
  _exit(42);
}

TEST_F(FileViewTest, ASigbusElsewhereGoesToTheHandlerBeforeTheGuard) {
  const fs::path guarded = write("guarded.ngc", pattern(kSize));
  const fs::path other = write("other.bin", pattern(kSize));
  EXPECT_EXIT(touch_cut_mapping_of_another_file(guarded.string(), other.string(), exit_42),
              ::testing::ExitedWithCode(42), "");
}

TEST_F(FileViewTest, ASigbusElsewhereStillEndsTheProcess) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own SIGBUS handler is the disposition before the guard";
#else
  const fs::path guarded = write("guarded.ngc", pattern(kSize));
  const fs::path other = write("other.bin", pattern(kSize));
  EXPECT_EXIT(touch_cut_mapping_of_another_file(guarded.string(), other.string(), nullptr),
              ::testing::KilledBySignal(SIGBUS), "");
#endif
}

}  // namespace
}  // namespace tgm
