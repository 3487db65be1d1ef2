#include "tgm/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace tgm {

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
