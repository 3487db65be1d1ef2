#include "rs274_canon.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace tgm::ref {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

bool parse_double(std::string_view s, double& v) {
  s = trim(s);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

//! Splits "a, b, c" into numbers; false if any is not a number.
bool parse_numbers(std::string_view args, std::vector<double>& v) {
  v.clear();
  while (true) {
    const std::size_t comma = args.find(',');
    double d = 0.0;
    if (!parse_double(args.substr(0, comma), d)) return false;
    v.push_back(d);
    if (comma == std::string_view::npos) return true;
    args.remove_prefix(comma + 1);
  }
}

}  // namespace

std::optional<std::string> parse_canon(std::string_view output, CanonProgram& out) {
  out = {};
  std::array<double, 3> g5x{};
  std::array<double, 3> g92{};
  Plane plane = Plane::kXY;
  double feed = 0.0;
  std::vector<double> v;
  int line_no = 0;
  while (!output.empty()) {
    const std::size_t nl = output.find('\n');
    std::string_view line = output.substr(0, nl);
    output.remove_prefix(nl == std::string_view::npos ? output.size() : nl + 1);
    ++line_no;
    // "<counter> <N word or N.....> CALL(args)"
    line = trim(line);
    if (line.empty()) continue;
    const std::size_t sp1 = line.find(' ');
    if (sp1 == std::string_view::npos) continue;
    line = trim(line.substr(sp1));
    // The N field is "N....." or the block's N number padded to 6 characters; a number of
    // six digits or more runs straight into the call ("N100000STRAIGHT_FEED(...)").
    if (line.empty() || line.front() != 'N') continue;
    std::size_t k = 1;
    while (k < line.size() && (line[k] == '.' || (line[k] >= '0' && line[k] <= '9'))) ++k;
    line = trim(line.substr(k));
    const std::size_t open = line.find('(');
    const std::size_t close = line.rfind(')');
    if (open == std::string_view::npos || close == std::string_view::npos || close < open) {
      continue;
    }
    const std::string_view name = line.substr(0, open);
    const std::string_view args = line.substr(open + 1, close - open - 1);
    const auto bad = [&](const char* why) {
      return std::string("rs274 output line ") + std::to_string(line_no) + ": " + why + ": " +
             std::string(line);
    };
    if (name == "SELECT_PLANE") {
      if (args == "CANON_PLANE_XY") {
        plane = Plane::kXY;
      } else if (args == "CANON_PLANE_XZ") {
        plane = Plane::kXZ;
      } else if (args == "CANON_PLANE_YZ") {
        plane = Plane::kYZ;
      } else {
        return bad("plane outside XY/XZ/YZ (UV/UW/VW planes are not in our dialect)");
      }
    } else if (name == "SET_FEED_RATE") {
      if (!parse_numbers(args, v) || v.size() != 1) return bad("bad SET_FEED_RATE");
      feed = v[0];
    } else if (name == "SET_G5X_OFFSET") {
      if (!parse_numbers(args, v) || v.size() < 4) return bad("bad SET_G5X_OFFSET");
      for (int i = 0; i < 3; ++i) g5x[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(i + 1)];
    } else if (name == "SET_G92_OFFSET") {
      if (!parse_numbers(args, v) || v.size() < 3) return bad("bad SET_G92_OFFSET");
      for (int i = 0; i < 3; ++i) g92[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(i)];
    } else if (name == "STRAIGHT_TRAVERSE" || name == "STRAIGHT_FEED") {
      if (out.ended) continue;
      if (!parse_numbers(args, v) || v.size() < 3) return bad("bad straight move");
      CanonMotion m;
      m.type = name == "STRAIGHT_TRAVERSE" ? 0 : 1;
      m.plane = plane;
      for (std::size_t i = 0; i < 3; ++i) m.end[i] = v[i] + g5x[i] + g92[i];
      m.feed_mm_per_min = feed;
      m.output_line = line_no;
      out.motions.push_back(m);
    } else if (name == "ARC_FEED") {
      if (out.ended) continue;
      // first_end, second_end, first_centre, second_centre, rotation, axis_end, a, b, c[, u, v, w]
      if (!parse_numbers(args, v) || v.size() < 6) return bad("bad ARC_FEED");
      const PlaneAxes pa = plane_xyz(plane);
      const auto f = static_cast<std::size_t>(pa.first);
      const auto s = static_cast<std::size_t>(pa.second);
      const auto n = static_cast<std::size_t>(pa.normal);
      CanonMotion m;
      const double rotation = v[4];
      if (rotation == 0.0 || rotation != static_cast<double>(static_cast<int>(rotation))) {
        return bad("ARC_FEED rotation is not a non-zero integer");
      }
      m.type = rotation < 0 ? 2 : 3;
      m.turns = std::abs(static_cast<int>(rotation)) - 1;
      m.plane = plane;
      m.end[f] = v[0] + g5x[f] + g92[f];
      m.end[s] = v[1] + g5x[s] + g92[s];
      m.end[n] = v[5] + g5x[n] + g92[n];
      m.center[0] = v[2] + g5x[f] + g92[f];
      m.center[1] = v[3] + g5x[s] + g92[s];
      m.feed_mm_per_min = feed;
      m.output_line = line_no;
      out.motions.push_back(m);
    } else if (name == "PROGRAM_END") {
      out.ended = true;
    }
  }
  return std::nullopt;
}

std::string find_rs274() {
  if (const char* env = std::getenv("TGM_RS274"); env != nullptr && *env != '\0') {
    return ::access(env, X_OK) == 0 ? std::string(env) : std::string();
  }
  const char* path = std::getenv("PATH");
  std::string_view p = path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin";
  while (true) {
    const std::size_t colon = p.find(':');
    std::string_view dir = p.substr(0, colon);
    if (dir.empty()) dir = ".";
    std::string candidate;
    candidate.reserve(dir.size() + 8);
    candidate.append(dir).append("/rs274");
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    if (colon == std::string_view::npos) break;
    p.remove_prefix(colon + 1);
  }
  return {};
}

Rs274Run run_rs274(const std::string& rs274, const std::string& file) {
  Rs274Run r;
  // rs274 instances running at the same time crash now and then ("Bus error", exit 135: about
  // one pair in five here, they share LinuxCNC state), and ctest -j runs several reference
  // tests at once: one rs274 at a time on this machine, whichever process runs it.
  const int lock_fd = ::open("/tmp/tgm-rs274.lock", O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (lock_fd >= 0) ::flock(lock_fd, LOCK_EX);
  struct Unlock {
    int fd;
    ~Unlock() {
      if (fd >= 0) ::close(fd);  // releases the lock
    }
  } unlock{lock_fd};
  const std::string err_file = file + ".rs274.err";
  // Paths come from the test itself (build tree); single quotes keep spaces safe.
  const std::string cmd = "'" + rs274 + "' -g '" + file + "' 2>'" + err_file + "'";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) {
    r.err = "popen failed for: " + cmd;
    return r;
  }
  char buf[1 << 16];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream ef(err_file);
  std::stringstream ss;
  ss << ef.rdbuf();
  r.err = ss.str();
  std::remove(err_file.c_str());
  return r;
}

}  // namespace tgm::ref
