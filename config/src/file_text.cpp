#include "tgm/file_text.hpp"

#include <cstdio>

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

}  // namespace tgm
