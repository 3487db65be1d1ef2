#include "tgm/file_text.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace tgm {

namespace {

// Reads the rest of the open `f` into `out`, at most `limit` bytes; closes `f`.
ReadResult read_stream(std::FILE* f, std::size_t limit, std::string& out) {
  // One read of the known size; a pipe or a growing file is read to its end in blocks.
  if (std::fseek(f, 0, SEEK_END) == 0) {
    const long size = std::ftell(f);
    if (size > 0) out.resize(static_cast<std::size_t>(size));
    std::rewind(f);
  }
  if (out.size() > limit) out.resize(limit + 1);
  const std::size_t got = out.empty() ? 0 : std::fread(out.data(), 1, out.size(), f);
  out.resize(got);
  char buf[65536];
  for (std::size_t n; out.size() <= limit && (n = std::fread(buf, 1, sizeof buf, f)) > 0;) {
    out.append(buf, n);
  }
  const bool bad = std::ferror(f) != 0;
  std::fclose(f);
  if (bad) return ReadResult::kReadError;
  if (out.size() > limit) {
    out.clear();
    return ReadResult::kTooLarge;
  }
  return ReadResult::kRead;
}

// What a file of mode `mode` is, for "PATH: is ..., not a KIND file"; "" for a regular file.
const char* not_regular(mode_t mode) {
  if (S_ISREG(mode)) return "";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a named pipe (FIFO)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

}  // namespace

ReadResult read_whole_file(const std::string& path, std::size_t limit, std::string& out) {
  out.clear();
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return ReadResult::kCannotOpen;
  return read_stream(f, limit, out);
}

ReadResult read_whole_fd(int fd, std::size_t limit, std::string& out) {
  out.clear();
  std::FILE* f = ::fdopen(fd, "rb");
  if (!f) {
    const int e = errno;
    ::close(fd);
    errno = e;
    return ReadResult::kCannotOpen;
  }
  return read_stream(f, limit, out);
}

std::string read_settings_file(const std::string& path, std::string_view kind, std::size_t limit,
                               std::string& out) {
  out.clear();
  const std::string k(kind);
  const auto refused = [&](const char* what) {
    // A directory opens as a file, and reading it gives an empty text: for a config that would
    // be every default. A FIFO without a writer blocked the start in open() for good, and a
    // device is no file of settings (/dev/zero has no end). Each is said as what it is.
    return path + ": is " + what + ", not a " + k + " file";
  };
  // Looked at before it is opened (opening a device can do something), then again once open
  // (the path may name something else by then). O_NONBLOCK: a FIFO opens at once (on a
  // regular file it changes nothing).
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && *not_regular(st.st_mode) != '\0') {
    return refused(not_regular(st.st_mode));
  }
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return path + ": cannot open the " + k + " file: " + std::strerror(errno);
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    return path + ": cannot read the " + k + " file: " + std::strerror(e);
  }
  if (const char* what = not_regular(st.st_mode); *what != '\0') {
    ::close(fd);
    return refused(what);
  }
  std::FILE* f = ::fdopen(fd, "rb");
  if (f == nullptr) {
    ::close(fd);
    return path + ": cannot read the " + k + " file";
  }
  switch (read_stream(f, limit, out)) {
    case ReadResult::kRead:
      return {};
    case ReadResult::kCannotOpen:
    case ReadResult::kReadError:
      return path + ": cannot read the " + k + " file";
    case ReadResult::kTooLarge:
      break;
  }
  // A whole number of MiB when it is one (the 1 MiB of a config), else bytes.
  const std::string size = limit % (std::size_t{1} << 20) == 0
                               ? std::to_string(limit >> 20) + " MiB"
                               : std::to_string(limit) + " bytes";
  return path + ": more than " + size + ": not a " + k + " file";
}

}  // namespace tgm
