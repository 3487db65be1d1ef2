#include "reference_compare.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace tgm::ref {

bool rs274_required() {
#ifdef TGM_REQUIRE_RS274_DEFAULT
  if (TGM_REQUIRE_RS274_DEFAULT) return true;
#endif
  const char* v = std::getenv("TGM_REQUIRE_RS274");
  return v != nullptr && std::string(v) == "1";
}

fs::path work_dir() {
  fs::path d = fs::path(TGM_BINARY_DIR) / "tests" / "reference" / "work";
  fs::create_directories(d);
  return d;
}

std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream ss(text);
  std::string l;
  while (std::getline(ss, l)) lines.push_back(l);
  return lines;
}

bool first_line_incremental(const std::string& text) {
  std::string first = text.substr(0, text.find('\n'));
  for (char& c : first) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return first.find("G91") != std::string::npos;
}

std::string fmt(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  return buf;
}

std::string compare(const CanonProgram& ref, const Program& ours, const std::string& source,
                    std::size_t max_reports) {
  const std::vector<std::string> src = split_lines(source);
  std::vector<const Segment*> motions;
  for (const Segment& s : ours.segments) {
    if (s.is_motion()) motions.push_back(&s);
  }
  std::ostringstream report;
  std::size_t reports = 0;
  const auto where = [&](std::size_t k) {
    std::ostringstream w;
    w << "motion #" << k;
    if (k < motions.size()) {
      const int line = motions[k]->line;
      w << " (our line " << line;
      if (line >= 1 && static_cast<std::size_t>(line) <= src.size()) {
        w << ": `" << src[static_cast<std::size_t>(line - 1)] << "`";
      }
      w << ")";
    }
    if (k < ref.motions.size()) w << " [rs274 output line " << ref.motions[k].output_line << "]";
    return w.str();
  };
  const auto mismatch = [&](std::size_t k, const std::string& what) {
    if (reports < max_reports) report << "  " << where(k) << ": " << what << "\n";
    ++reports;
  };
  if (ref.motions.size() != motions.size()) {
    report << "  motion count: ours " << motions.size() << ", rs274 " << ref.motions.size() << "\n";
  }
  const std::size_t n = std::min(ref.motions.size(), motions.size());
  for (std::size_t k = 0; k < n; ++k) {
    const CanonMotion& r = ref.motions[k];
    const Segment& s = *motions[k];
    const int type = static_cast<int>(s.type);
    if (type != r.type) {
      mismatch(k, "type: ours G" + std::to_string(type) + ", rs274 G" + std::to_string(r.type));
      continue;
    }
    if (s.plane != r.plane) {
      mismatch(k, "plane: ours G" + std::to_string(static_cast<int>(s.plane)) + ", rs274 G" +
                      std::to_string(static_cast<int>(r.plane)));
    }
    for (std::size_t i = 0; i < 3; ++i) {
      if (!(std::fabs(s.end[i] - r.end[i]) <= kTolerance)) {
        mismatch(k, std::string("end ") + "XYZ"[i] + ": ours " + fmt(s.end[i]) + ", rs274 " +
                        fmt(r.end[i]));
      }
    }
    if (s.is_arc()) {
      const PlaneAxes pa = plane_xyz(s.plane);
      for (std::size_t i = 0; i < 2; ++i) {
        if (!(std::fabs(s.center[i] - r.center[i]) <= kTolerance)) {
          const int axis = i == 0 ? pa.first : pa.second;
          mismatch(k, std::string("centre ") + "XYZ"[axis] + ": ours " + fmt(s.center[i]) +
                          ", rs274 " + fmt(r.center[i]));
        }
      }
      if (s.turns != r.turns) {
        mismatch(k, "extra turns: ours " + std::to_string(s.turns) + ", rs274 " +
                        std::to_string(r.turns));
      }
    }
    if (type != 0 && !(std::fabs(s.feed_mm_per_min - r.feed_mm_per_min) <= kTolerance)) {
      mismatch(k, "feed: ours " + fmt(s.feed_mm_per_min) + ", rs274 " + fmt(r.feed_mm_per_min));
    }
  }
  if (reports > max_reports) report << "  ... " << reports - max_reports << " more\n";
  return report.str();
}

}  // namespace tgm::ref
