// Reading a whole input file with a bound on its size, shared by the config loader and the
// programs tgm-hmi reads from pipes: a device without end (/dev/zero) or a huge file given by
// mistake ends in an answer, not in the memory running out.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace tgm {

enum class ReadResult {
  kRead,
  kCannotOpen,  //!< errno says why
  kReadError,
  kTooLarge,  //!< more than the limit (`out` is left empty)
};

//! Reads the whole of `path` into `out`, at most `limit` bytes.
ReadResult read_whole_file(const std::string& path, std::size_t limit, std::string& out);
//! The same from the open `fd`, which it closes: also a socket, which cannot be opened by a
//! path (/dev/stdin of a process whose standard input is a socket).
ReadResult read_whole_fd(int fd, std::size_t limit, std::string& out);

//! Reads a settings file (a config, a PLC script) of at most `limit` bytes into `out`. Only a
//! regular file (or a link to one) is read: a directory, FIFO, device or socket is refused
//! without blocking. Returns "" or what went wrong, naming the path and `kind` ("config",
//! "script"): "PATH: is a directory, not a KIND file" (likewise "a named pipe (FIFO)", "a
//! character device", "a block device", "a socket"), "PATH: cannot open the KIND file: <errno
//! text>", "PATH: cannot read the KIND file", "PATH: more than N MiB: not a KIND file".
std::string read_settings_file(const std::string& path, std::string_view kind, std::size_t limit,
                               std::string& out);

}  // namespace tgm
