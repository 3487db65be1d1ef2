// Helpers of the service integration tests: start the real binaries as child processes with
// their output in a log file, stop them with SIGINT like a user would, and write a test config.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace tgm::test {

//! A child process; killed (SIGKILL) by the destructor if it still runs.
class Child {
 public:
  Child() = default;
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      ::waitpid(pid_, &st, 0);
    }
  }
  //! Starts `args[0]` with `args`; stdout and stderr go to `log_path`. `extra_env`
  //! ("NAME=value") is added to this process's environment.
  bool start(const std::vector<std::string>& args, const std::string& log_path,
             const std::vector<std::string>& extra_env = {}) {
    log_ = log_path;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    std::vector<char*> envp;
    for (char** e = environ; *e != nullptr; ++e) envp.push_back(*e);
    for (const auto& e : extra_env) envp.push_back(const_cast<char*>(e.c_str()));
    envp.push_back(nullptr);
    const int rc = posix_spawn(&pid_, argv[0], &fa, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) pid_ = -1;
    return rc == 0;
  }
  //! Waits for the exit; the exit code, 128 + signal when killed by one, -1 on timeout.
  int wait(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return code_;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      int st = 0;
      const pid_t r = ::waitpid(pid_, &st, WNOHANG);
      if (r == pid_) {
        pid_ = -1;
        code_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
        return code_;
      }
      if (std::chrono::steady_clock::now() >= deadline) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  //! SIGINT (or `sig`), then the exit code (SIGKILL and -1 after `timeout`).
  int interrupt(std::chrono::milliseconds timeout = std::chrono::seconds(10), int sig = SIGINT) {
    if (pid_ > 0) ::kill(pid_, sig);
    const int code = wait(timeout);
    if (code == -1 && pid_ > 0) {
      ::kill(pid_, SIGKILL);
      wait(std::chrono::seconds(5));
      return -1;
    }
    return code;
  }
  bool running() const { return pid_ > 0; }
  //! The child's process id while it runs (-1 after the exit was collected).
  pid_t pid() const { return pid_; }
  std::string log() const {
    std::ifstream f(log_);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }
  //! Waits up to `limit` until the log holds `text`, reading it every `poll`; false if it
  //! never came.
  bool wait_for_log(const std::string& text,
                    std::chrono::milliseconds limit = std::chrono::seconds(10),
                    std::chrono::milliseconds poll = std::chrono::milliseconds(25)) const {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (log().find(text) == std::string::npos) {
      if (std::chrono::steady_clock::now() >= until) return false;
      std::this_thread::sleep_for(poll);
    }
    return true;
  }

 private:
  pid_t pid_ = -1;
  int code_ = -1;
  std::string log_;
};

inline std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

//! How a shell command ended and what it printed.
struct ShellRun {
  int exit_code = -1;  // -1: killed by a signal, or the shell could not run
  std::string out, err;
};

//! Runs `command` through the shell, standard input from /dev/null, standard output and error
//! kept apart in `dir`/`name`.out and .err.
inline ShellRun run_shell(const std::string& command, const std::string& dir,
                          const std::string& name) {
  const std::string out = dir + "/" + name + ".out", err = dir + "/" + name + ".err";
  const int status = std::system((command + " >'" + out + "' 2>'" + err + "' </dev/null").c_str());
  ShellRun r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

//! Replaces the first occurrence of `from` (which must exist) in `text`.
inline bool replace_first(std::string& text, const std::string& from, const std::string& to) {
  const auto p = text.find(from);
  if (p == std::string::npos) return false;
  text.replace(p, from.size(), to);
  return true;
}

//! A field of /proc/PID/status in kB (VmRSS, VmHWM, ...); -1 when it cannot be read.
inline long proc_status_kb(pid_t pid, const std::string& field) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind(field + ":", 0) == 0)
      return std::strtol(line.c_str() + field.size() + 1, nullptr, 10);
  }
  return -1;
}

//! Sends SIGSTOP to `pid` and waits until every thread of it is stopped (state T in
//! /proc/PID/task/TID/stat): kill() returns once the signal is queued, and a thread that is
//! running or runnable may still take a sample off the network. (With four tests at once on two
//! cores, a request written right after kill() was accepted at its first send in two of four
//! suite runs, session 93; not reproduced alone, so that window is the likely cause, not a
//! proven one.) False if `pid` does not stop within `timeout` or cannot be read.
inline bool stop_process(pid_t pid, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  if (::kill(pid, SIGSTOP) != 0) return false;
  const std::filesystem::path tasks = "/proc/" + std::to_string(pid) + "/task";
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    std::error_code ec;
    std::filesystem::directory_iterator it(tasks, ec);
    if (ec) return false;  // the process is gone
    bool all = true;
    int seen = 0;
    for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
      const std::string stat = read_text(it->path() / "stat");
      // pid (comm) state ...: comm may hold spaces and parentheses; the state follows the last ')'.
      const auto close = stat.rfind(')');
      if (close == std::string::npos || close + 2 >= stat.size()) continue;  // the thread ended
      ++seen;
      if (stat[close + 2] != 'T' && stat[close + 2] != 't') all = false;
    }
    if (!ec && all && seen > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

//! Counts occurrences of `what` in `text`.
inline int count_of(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

}  // namespace tgm::test
