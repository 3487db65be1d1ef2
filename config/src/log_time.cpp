#include "tgm/log_time.hpp"

#include <sys/stat.h>
#include <unistd.h>
#include <ext/stdio_sync_filebuf.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <iostream>
#include <new>

namespace tgm {

std::optional<LogTime> parse_log_time(std::string_view text) {
  if (text == "auto") return LogTime::kAuto;
  if (text == "on") return LogTime::kOn;
  if (text == "off") return LogTime::kOff;
  return std::nullopt;
}

std::size_t format_log_stamp(std::chrono::system_clock::time_point t,
                             char (&out)[kLogStampSize]) noexcept {
  const std::time_t secs = std::chrono::system_clock::to_time_t(t);
  auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                t - std::chrono::system_clock::from_time_t(secs))
                .count();
  if (ms < 0 || ms > 999) ms = 0;  // to_time_t rounds on some libraries; never "1000"
  std::tm local{};
  if (::localtime_r(&secs, &local) == nullptr) {
    out[0] = '\0';
    return 0;
  }
  std::size_t n = std::strftime(out, sizeof out, "%Y-%m-%d %H:%M:%S", &local);
  n += static_cast<std::size_t>(
      std::snprintf(out + n, sizeof out - n, ".%03d", static_cast<int>(ms)));
  n += std::strftime(out + n, sizeof out - n, "%z ", &local);
  return n;
}

std::string log_stamp(std::chrono::system_clock::time_point t) {
  char text[kLogStampSize];
  return std::string(text, format_log_stamp(t, text));
}

std::string LineStamper::add(std::string_view piece, std::string_view stamp) {
  std::string out;
  add(piece, stamp, [&](const char* p, std::size_t n) { out.append(p, n); });
  return out;
}

bool log_time_wanted(LogTime mode, const char* journal_stream, std::string_view fd_id) {
  if (mode != LogTime::kAuto) return mode == LogTime::kOn;
  // systemd sets JOURNAL_STREAM to the journal stream's "<dev>:<ino>"; a child that inherited
  // it but writes elsewhere (redirected by hand) is not in the journal.
  return journal_stream == nullptr || fd_id.empty() || fd_id != journal_stream;
}

namespace {

// One stamped standard stream. Its FILE's lock is held around every call of write_stamped
// (stdio locks a stream for each call), so the stamper needs no lock of its own.
struct StampedStream {
  int fd = -1;
  LineStamper stamper;
};

// Writes all of `n` bytes at `p` to `fd`; false on an error (EPIPE and the like).
bool write_all(int fd, const char* p, std::size_t n) noexcept {
  while (n > 0) {
    const ssize_t k = ::write(fd, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;
    p += k;
    n -= static_cast<std::size_t>(k);
  }
  return true;
}

// Called inside stdio: no allocation, no exception, errno kept on success.
ssize_t write_stamped(void* cookie, const char* data, std::size_t size) noexcept {
  auto& s = *static_cast<StampedStream*>(cookie);
  const int saved_errno = errno;
  char stamp[kLogStampSize];
  const std::size_t stamp_size = format_log_stamp(std::chrono::system_clock::now(), stamp);
  char buf[4096];
  std::size_t used = 0;
  bool ok = true;
  s.stamper.add(std::string_view(data, size), std::string_view(stamp, stamp_size),
                [&](const char* p, std::size_t n) {
                  while (ok && n > 0) {
                    if (used == sizeof buf) {
                      ok = write_all(s.fd, buf, used);
                      used = 0;
                    }
                    const std::size_t k = std::min(n, sizeof buf - used);
                    std::memcpy(buf + used, p, k);
                    used += k;
                    p += k;
                    n -= k;
                  }
                });
  if (ok && used > 0) ok = write_all(s.fd, buf, used);
  if (!ok) return -1;  // the caller's stream records the error; errno says which
  errno = saved_errno;
  return static_cast<ssize_t>(size);
}

// Static storage for the two streams: they are written until the very end of the process
// (exit() flushes stdout after every destructor), so they are never freed nor destroyed.
StampedStream g_streams[2];

std::FILE* open_stamped(int fd, int buffering) {
  StampedStream& s = g_streams[fd == 1 ? 0 : 1];
  s.fd = fd;
  cookie_io_functions_t io{};
  io.write = write_stamped;
  std::FILE* f = ::fopencookie(&s, "w", io);
  if (f == nullptr) return nullptr;
  std::setvbuf(f, nullptr, buffering, buffering == _IONBF ? 0 : BUFSIZ);
  return f;
}

// A stream buffer for std::cout / std::cerr that is never destroyed: the library flushes
// std::cout at exit, after the destructors of function-local statics have run.
__gnu_cxx::stdio_sync_filebuf<char>* lasting_filebuf(std::FILE* f, int slot) {
  using Buf = __gnu_cxx::stdio_sync_filebuf<char>;
  alignas(Buf) static unsigned char storage[2][sizeof(Buf)];
  return ::new (static_cast<void*>(storage[slot])) Buf(f);
}

std::string fd_id(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return {};
  return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
}

}  // namespace

bool stamp_standard_streams(LogTime mode, std::string& why) {
  const char* journal = std::getenv("JOURNAL_STREAM");
  const bool out_wanted = log_time_wanted(mode, journal, fd_id(1));
  const bool err_wanted = log_time_wanted(mode, journal, fd_id(2));
  std::FILE* out = out_wanted ? open_stamped(1, _IOLBF) : nullptr;
  std::FILE* err = err_wanted ? open_stamped(2, _IONBF) : nullptr;
  if ((out_wanted && out == nullptr) || (err_wanted && err == nullptr)) {
    why = std::string("time stamps on the log: ") + std::strerror(errno);
    return false;  // a stream already made stays unused
  }
  // std::cout and std::cerr (Fast DDS's own log lines) write through the same streams.
  if (out != nullptr) {
    std::fflush(stdout);
    std::cout.flush();
    stdout = out;  // glibc's standard streams are plain variables
    std::cout.rdbuf(lasting_filebuf(out, 0));
  }
  if (err != nullptr) {
    std::fflush(stderr);
    stderr = err;
    auto* err_buf = lasting_filebuf(err, 1);
    std::cerr.rdbuf(err_buf);
    std::clog.rdbuf(err_buf);
  }
  return true;
}

}  // namespace tgm
