#include "tgm/log_time.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <mutex>

namespace tgm {

std::optional<LogTime> parse_log_time(std::string_view text) {
  if (text == "auto") return LogTime::kAuto;
  if (text == "on") return LogTime::kOn;
  if (text == "off") return LogTime::kOff;
  return std::nullopt;
}

std::string log_stamp(std::chrono::system_clock::time_point t) {
  const std::time_t secs = std::chrono::system_clock::to_time_t(t);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                      t - std::chrono::system_clock::from_time_t(secs))
                      .count();
  std::tm local{};
  ::localtime_r(&secs, &local);
  char text[48];
  const std::size_t n = std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", &local);
  std::snprintf(text + n, sizeof text - n, ".%03d ", static_cast<int>(ms < 0 ? 0 : ms));
  return text;
}

std::string LineStamper::add(std::string_view piece, std::string_view stamp) {
  std::string out;
  out.reserve(piece.size() + stamp.size());
  for (const char c : piece) {
    if (at_line_start_) out += stamp;
    out += c;
    at_line_start_ = c == '\n';
  }
  return out;
}

bool log_time_wanted(LogTime mode, const char* journal_stream, std::string_view stderr_id) {
  if (mode != LogTime::kAuto) return mode == LogTime::kOn;
  // systemd sets JOURNAL_STREAM to the journal stream's "<dev>:<ino>"; a child that inherited
  // it but writes elsewhere (redirected by hand) is not in the journal.
  return journal_stream == nullptr || stderr_id.empty() || stderr_id != journal_stream;
}

namespace {

struct StampedStream {
  int fd = -1;
  std::mutex mutex;  // one stream's writes come in one by one already; stamper state guarded
  LineStamper stamper;
};

ssize_t write_stamped(void* cookie, const char* data, std::size_t size) {
  auto& s = *static_cast<StampedStream*>(cookie);
  std::string out;
  {
    const std::lock_guard lock(s.mutex);
    out = s.stamper.add(std::string_view(data, size), log_stamp(std::chrono::system_clock::now()));
  }
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::write(s.fd, out.data() + done, out.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return -1;  // EPIPE and the like: the caller's stream reports the error
    done += static_cast<std::size_t>(n);
  }
  return static_cast<ssize_t>(size);
}

std::FILE* open_stamped(int fd, int buffering) {
  // Lives as long as the process: the standard streams are written until exit.
  auto* s = new StampedStream;
  s->fd = fd;
  cookie_io_functions_t io{};
  io.write = write_stamped;
  std::FILE* f = ::fopencookie(s, "w", io);
  if (f == nullptr) {
    delete s;
    return nullptr;
  }
  std::setvbuf(f, nullptr, buffering, buffering == _IONBF ? 0 : BUFSIZ);
  return f;
}

}  // namespace

bool stamp_standard_streams(LogTime mode, std::string& why) {
  std::string stderr_id;
  if (struct stat st{}; ::fstat(2, &st) == 0) {
    stderr_id = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  }
  if (!log_time_wanted(mode, std::getenv("JOURNAL_STREAM"), stderr_id)) return true;
  std::FILE* out = open_stamped(1, _IOLBF);
  std::FILE* err = out != nullptr ? open_stamped(2, _IONBF) : nullptr;
  if (out == nullptr || err == nullptr) {
    why = std::string("time stamps on the log: ") + std::strerror(errno);
    return false;  // the stream already made stays unused
  }
  std::fflush(stdout);
  std::fflush(stderr);
  stdout = out;  // glibc's standard streams are plain variables
  stderr = err;
  return true;
}

}  // namespace tgm
