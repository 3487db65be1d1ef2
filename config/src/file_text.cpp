#include "tgm/file_text.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace tgm {

ReadResult read_whole_file(const std::string& path, std::size_t limit, std::string& out) {
  out.clear();
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return ReadResult::kCannotOpen;
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

std::string read_settings_file(const std::string& path, std::string_view kind, std::size_t limit,
                               std::string& out) {
  out.clear();
  const std::string k(kind);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    // A directory opens as a file, and reading it gives an empty text: for a config that would
    // be every default. Say what it is.
    return path + ": is a directory, not a " + k + " file";
  }
  switch (read_whole_file(path, limit, out)) {
    case ReadResult::kRead:
      return {};
    case ReadResult::kCannotOpen:
      return path + ": cannot open the " + k + " file: " + std::strerror(errno);
    case ReadResult::kReadError:
      return path + ": cannot read the " + k + " file";
    case ReadResult::kTooLarge:
      break;
  }
  // A whole number of MiB when it is one (the 16 MiB of a config), else bytes.
  const std::string size = limit % (std::size_t{1} << 20) == 0
                               ? std::to_string(limit >> 20) + " MiB"
                               : std::to_string(limit) + " bytes";
  return path + ": more than " + size + ": not a " + k + " file";
}

}  // namespace tgm
