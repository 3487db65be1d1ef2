#include "cli_common.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace tgm::hmi {

Args::Args(int argc, char** argv, const char* command, const char* usage)
    : ArgReader(argc, argv, std::string("tgm-hmi ") + command), usage_(usage) {}

bool Args::common() {
  return help_flag() || flag("--config", config_path_) ||
         flag("--interpolator", interpolator_text_);
}

bool Args::help() const {
  if (help_given()) std::fputs(usage_, stdout);
  return help_given();
}

std::optional<AppConfig> Args::load_app() {
  std::optional<AppConfig> config = load_config_or_report(config_path_, program());
  if (!config) return std::nullopt;
  const int count = static_cast<int>(config->machine.interpolators.size());
  if (!interpolator_text_.empty()) {
    if (!parse_integer(interpolator_text_, 0, count - 1, interpolator_)) {
      usage_error("--interpolator must be 0.." + std::to_string(count - 1) + " (the config has " +
                  std::to_string(count) + "), not '" + interpolator_text_ + "'");
      return std::nullopt;
    }
  }
  return config;
}

std::optional<MachineConfig> Args::load_machine() {
  auto app = load_app();
  if (!app) return std::nullopt;
  return app->machine;
}

void CompensationNote::print(const std::string& file) const {
  if (!seen_) return;
  std::fprintf(stderr,
               "%s:%d: note: G%d (tool radius compensation, radius %g mm) is recorded in the "
               "intercode but not applied: the tool centre follows the programmed contour\n",
               file.c_str(), static_cast<int>(first_.line), static_cast<int>(first_.compensation),
               first_.compensation_radius_mm);
}

bool write_file_atomic(const std::string& path, const std::string& bytes, std::string& error) {
  AtomicFile f;  // removes the temporary file on every early return
  return f.open(path, error) && f.write(bytes.data(), bytes.size(), error) && f.commit(error);
}

AtomicFile::~AtomicFile() {
  if (f_) {
    std::fclose(f_);
    std::remove(tmp_.c_str());
  }
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
    tmp_ = path_ + ".tmp-" + std::to_string(::getpid()) + (k > 0 ? "-" + std::to_string(k) : "");
    const int fd = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      f_ = ::fdopen(fd, "wb");
      if (f_) break;
      ::close(fd);
      std::remove(tmp_.c_str());
    }
    if (fd >= 0 || errno != EEXIST || k == 99) {
      error = std::string("cannot create: ") + std::strerror(errno);
      return false;
    }
  }
  static thread_local char buffer[1 << 20];
  std::setvbuf(f_, buffer, _IOFBF, sizeof buffer);
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
    return false;
  }
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    error = std::string("cannot rename into place: ") + std::strerror(errno);
    std::remove(tmp_.c_str());
    return false;
  }
  return true;
}

FileView::~FileView() {
  if (map_) munmap(map_, map_size_);
}

bool FileView::open(const std::string& path, std::string& error) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    error = std::string("cannot open: ") + std::strerror(errno);
    return false;
  }
  struct stat st {};
  const bool have_stat = fstat(fd, &st) == 0;
  if (have_stat && S_ISDIR(st.st_mode)) {
    ::close(fd);
    error = "is a directory";
    return false;
  }
  // A device other than a terminal (/dev/zero, /dev/urandom) is no program: its bytes never
  // end. A pipe and a terminal are read (up to kMaxStreamedInput).
  if (have_stat && S_ISCHR(st.st_mode) && ::isatty(fd) == 0) {
    ::close(fd);
    error = "is a device, not a file";
    return false;
  }
  if (have_stat && S_ISREG(st.st_mode) && st.st_size > 0) {
    void* p = mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ,
                   MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (p != MAP_FAILED) {
      ::close(fd);
      map_ = p;
      map_size_ = static_cast<std::size_t>(st.st_size);
      text_ = std::string_view(static_cast<const char*>(p), map_size_);
      return true;
    }
  }
  ::close(fd);
  switch (read_whole_file(path, kMaxStreamedInput, copy_)) {
    case ReadResult::kRead:
      break;
    case ReadResult::kCannotOpen:
      error = std::string("cannot open: ") + std::strerror(errno);
      return false;
    case ReadResult::kReadError:
      error = "read error";
      return false;
    case ReadResult::kTooLarge:
      error = "more than " + std::to_string(kMaxStreamedInput >> 20) +
              " MiB to read (an input without end?)";
      return false;
  }
  text_ = copy_;
  return true;
}

bool progress_interval_flag(Args& args, double& out) {
  return args.number_flag("--progress-interval", out, "seconds in (0, 86400]",
                          [](double v) { return v > 0.0 && v <= 86400.0; });
}

}  // namespace tgm::hmi
