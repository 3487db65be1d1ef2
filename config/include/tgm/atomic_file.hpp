// Output files written whole or not at all, shared by every binary (tgm-hmi's --out / --csv /
// --plot, tgm-service's --stats and --handshake-trace, tgm-plc's --handshake-trace): opened when
// the command line is read, so a path that cannot be written is an error before any work, and
// renamed into place at the end, so a failed run never leaves half a file.
#pragma once

#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>

namespace tgm {

//! Writes `path` through a temporary file and rename, so a failed run leaves nothing half-written.
bool write_file_atomic(const std::string& path, const std::string& bytes, std::string& error);

//! A file written in pieces through "<path>.tmp-<pid>" (created exclusively, so no file of the
//! user's is touched) and renamed into place by commit(); destroyed
//! without commit() it removes the temporary file, so an error never leaves a partial output.
//! A path that names a symbolic link is written through it (the file it points to is replaced,
//! not the link). A file replaced keeps its permission bits (a new inode: hard links to the old
//! one keep the old content). SIGINT, SIGTERM or SIGHUP while the action is the default
//! removes the temporary files of every AtomicFile open and ends the process by the signal. A path
//! that names a device or a pipe (/dev/stdout, a FIFO) is never renamed over: the output is held in
//! memory and written into it by commit().
class AtomicFile {
 public:
  AtomicFile() = default;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();
  bool open(const std::string& path, std::string& error);
  bool write(const void* data, std::size_t size, std::string& error);
  //! Overwrites bytes already written at `offset`.
  bool patch(long offset, const void* data, std::size_t size, std::string& error);
  bool commit(std::string& error);
  bool is_open() const { return f_ != nullptr || in_place_; }

 private:
  std::string path_, tmp_;
  static constexpr std::size_t kBufferBytes = 1 << 20;
  std::FILE* f_ = nullptr;
  std::unique_ptr<char[]> buffer_;  // f_'s stdio buffer
  int slot_ = -1;                   // its slot among the temporary files a signal removes
  bool in_place_ = false;  // a device or a pipe: `held_` is written into it by commit()
  std::string held_;
};

//! A report written with fprintf at the end of a run (tgm-service --stats, the handshake
//! traces): open() when the command line is read, so that a path that cannot be written fails
//! the start and not the end of a run of hours; the text goes to a memory stream, and finish()
//! writes it whole through an AtomicFile (a full disk is an error, not a truncated file).
class ReportFile {
 public:
  ReportFile() = default;
  ReportFile(const ReportFile&) = delete;
  ReportFile& operator=(const ReportFile&) = delete;
  ~ReportFile();
  bool open(const std::string& path, std::string& error);
  bool is_open() const { return file_.is_open(); }
  //! Where the report is printed (null when nothing was opened or the memory stream cannot be
  //! made).
  std::FILE* stream();
  bool finish(std::string& error);

 private:
  AtomicFile file_;
  std::FILE* memory_ = nullptr;
  char* text_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace tgm
