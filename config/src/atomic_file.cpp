#include "tgm/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace tgm {

namespace {

// The temporary files being written, for a signal that ends the process: `tgm-hmi compile
// --out` interrupted by Ctrl-C left "<out>.tmp-<pid>" (24 MB of a half-written program) beside
// its output every time (session 75). A handler for SIGINT, SIGTERM and SIGHUP, installed only
// where the signal's action is the default (a command that handles a signal itself, as
// simulate and tgm-service do, keeps its handler, and an ignored SIGHUP stays ignored), removes
// them and ends the process by the same signal. A slot is 0 free, 1 claimed, 2 named.
constexpr int kTempSlots = 16;
char g_temp_path[kTempSlots][4096];
std::atomic<int> g_temp_state[kTempSlots];
static_assert(std::atomic<int>::is_always_lock_free, "read in a signal handler");

extern "C" void remove_temps_and_end(int sig) {
  for (int i = 0; i < kTempSlots; ++i) {
    if (g_temp_state[i].load() == 2) ::unlink(g_temp_path[i]);
  }
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

// At every open (three system calls, once per output file): an action set back to the default
// since the last one gets the handler again.
void install_temp_cleanup() {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction now {};
    if (::sigaction(sig, nullptr, &now) != 0 || now.sa_handler != SIG_DFL) continue;
    struct sigaction sa {};
    sa.sa_handler = remove_temps_and_end;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);
  }
}

// The slot naming `path` (-1: none free, or a path too long: that file is only not removed).
int claim_temp_slot(const std::string& path) {
  if (path.size() >= sizeof g_temp_path[0]) return -1;
  install_temp_cleanup();
  for (int i = 0; i < kTempSlots; ++i) {
    int free = 0;
    if (!g_temp_state[i].compare_exchange_strong(free, 1)) continue;
    std::memcpy(g_temp_path[i], path.c_str(), path.size() + 1);
    g_temp_state[i].store(2);
    return i;
  }
  return -1;
}

void release_temp_slot(int& slot) {
  if (slot >= 0) g_temp_state[slot].store(0);
  slot = -1;
}

}  // namespace

bool write_file_atomic(const std::string& path, const std::string& bytes, std::string& error) {
  AtomicFile f;  // removes the temporary file on every early return
  return f.open(path, error) && f.write(bytes.data(), bytes.size(), error) && f.commit(error);
}

AtomicFile::~AtomicFile() {
  if (f_) {
    std::fclose(f_);
    std::remove(tmp_.c_str());
  }
  release_temp_slot(slot_);
}

bool AtomicFile::open(const std::string& path, std::string& error) {
  path_ = path;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {  // stat follows links
    if (S_ISDIR(st.st_mode)) {
      error = "is a directory";
      return false;
    }
    // A device or a pipe (/dev/stdout too): renaming a file over it would replace it (as root,
    // /dev/full became a regular file).
    in_place_ = true;
    return true;
  }
  // Renaming over a symbolic link replaces the link: follow it (also when its file does not
  // exist yet) and replace the file it names.
  namespace fs = std::filesystem;
  fs::path p = path;
  std::error_code ec;
  for (int hops = 0; fs::is_symlink(p, ec); ++hops) {
    const fs::path target = fs::read_symlink(p, ec);
    if (ec || hops == 40) {
      error = "cannot follow the symbolic link" + (ec ? ": " + ec.message() : std::string());
      return false;
    }
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  path_ = p.string();
  // A temporary name of our own, created exclusively: a fixed "<path>.tmp" truncated a user's
  // file of that name and removed it after a failed run.
  for (int k = 0;; ++k) {
    // (Appended piece by piece: GCC 12 at -O3 warns of an overlapping memcpy inside
    // `"-" + std::to_string(k)`, a false -Wrestrict.)
    tmp_ = path_;
    tmp_ += ".tmp-";
    tmp_ += std::to_string(::getpid());
    if (k > 0) {
      tmp_ += '-';
      tmp_ += std::to_string(k);
    }
    const int fd = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      slot_ = claim_temp_slot(tmp_);
      // A file replaced keeps its permissions: a program made private (0600) became readable
      // by all (0644) when compiled again.
      struct stat old {};
      if (::stat(path_.c_str(), &old) == 0 && S_ISREG(old.st_mode)) {
        (void)::fchmod(fd, old.st_mode & 07777);
      }
      f_ = ::fdopen(fd, "wb");
      if (f_) break;
      release_temp_slot(slot_);
      ::close(fd);
      std::remove(tmp_.c_str());
    }
    if (fd >= 0 || errno != EEXIST || k == 99) {
      error = std::string("cannot create: ") + std::strerror(errno);
      return false;
    }
  }
  // A buffer of its own: one shared by every file of a thread (thread_local) held the pending
  // bytes of two files open at once in the same place.
  buffer_ = std::make_unique<char[]>(kBufferBytes);
  std::setvbuf(f_, buffer_.get(), _IOFBF, kBufferBytes);
  return true;
}

bool AtomicFile::write(const void* data, std::size_t size, std::string& error) {
  if (in_place_) {
    held_.append(static_cast<const char*>(data), size);
    return true;
  }
  if (std::fwrite(data, 1, size, f_) != size) {
    error = std::string("cannot write: ") + std::strerror(errno);
    return false;
  }
  return true;
}

bool AtomicFile::patch(long offset, const void* data, std::size_t size, std::string& error) {
  if (in_place_) {
    const auto at = static_cast<std::size_t>(offset);
    if (offset < 0 || at > held_.size() || size > held_.size() - at) {
      error = "cannot patch beyond the output written";
      return false;
    }
    held_.replace(at, size, static_cast<const char*>(data), size);
    return true;
  }
  const long here = std::ftell(f_);
  if (here < 0 || std::fseek(f_, offset, SEEK_SET) != 0 || !write(data, size, error) ||
      std::fseek(f_, here, SEEK_SET) != 0) {
    if (error.empty()) error = std::string("cannot seek: ") + std::strerror(errno);
    return false;
  }
  return true;
}

bool AtomicFile::commit(std::string& error) {
  if (in_place_) {
    in_place_ = false;
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (!f) {
      error = std::string("cannot open: ") + std::strerror(errno);
      return false;
    }
    const bool written = std::fwrite(held_.data(), 1, held_.size(), f) == held_.size();
    const int saved = errno;
    if (std::fclose(f) != 0 || !written) {
      error = std::string("cannot write: ") + std::strerror(written ? errno : saved);
      return false;
    }
    return true;
  }
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0) {
    error = std::string("cannot write: ") + std::strerror(errno);
    std::remove(tmp_.c_str());
    release_temp_slot(slot_);
    return false;
  }
  // Released before the rename: a signal between the two leaves the output whole rather than
  // removing the file just renamed into place under its temporary name's slot.
  release_temp_slot(slot_);
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    error = std::string("cannot rename into place: ") + std::strerror(errno);
    std::remove(tmp_.c_str());
    return false;
  }
  return true;
}

ReportFile::~ReportFile() {
  if (memory_) std::fclose(memory_);
  std::free(text_);
}

bool ReportFile::open(const std::string& path, std::string& error) {
  return file_.open(path, error);
}

std::FILE* ReportFile::stream() {
  if (!is_open()) return nullptr;
  if (memory_ == nullptr) memory_ = ::open_memstream(&text_, &size_);
  return memory_;
}

bool ReportFile::finish(std::string& error) {
  if (stream() == nullptr) {
    error = std::string("cannot make a memory stream: ") + std::strerror(errno);
    return false;
  }
  const bool printed = std::ferror(memory_) == 0;
  std::fclose(memory_);  // sets text_ and size_
  memory_ = nullptr;
  if (!printed) {
    error = "cannot print the report (out of memory?)";
    return false;
  }
  return file_.write(text_, size_, error) && file_.commit(error);
}

}  // namespace tgm
