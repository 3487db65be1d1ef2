// Program time by record (tgm/program_times.hpp).
#include "tgm/program_times.hpp"

#include <algorithm>
#include <utility>

namespace tgm {

namespace {

// When record k starts: when the one before it is done (0 for the first).
double start_of(const std::vector<float>& done_s, std::size_t k) {
  return k == 0 ? 0.0 : static_cast<double>(done_s[k - 1]);
}

}  // namespace

double ProgramTimes::elapsed_s(std::int64_t act_part, double in_record_s,
                               double in_record_mm) const {
  if (act_part <= 0 || done_s.empty()) return 0.0;
  const auto k = static_cast<std::uint64_t>(act_part) - 1;
  if (k >= done_s.size()) return total_s;
  const double before = start_of(done_s, k);
  const double own = static_cast<double>(done_s[k]) - before;
  const double length = k < length_mm.size() ? static_cast<double>(length_mm[k]) : 0.0;
  if (length > 0.0 && in_record_mm >= 0.0) {
    return before + own * std::min(in_record_mm / length, 1.0);
  }
  // A NaN (a clock the caller never set) counts as no time in the record.
  const double in = in_record_s > 0.0 ? in_record_s : 0.0;
  return before + std::min(in, own);
}

double ProgramTimes::left_s(std::int64_t act_part, double in_record_s, double in_record_mm,
                            double move_scale) const {
  const double elapsed = elapsed_s(act_part, in_record_s, in_record_mm);
  // The waits still to come: those of the records after record act_part, and what is left of
  // its own time when it does not move. Times made without the waits by record (by hand):
  // every second a move's.
  double waits_left = 0.0;
  const auto k = static_cast<std::uint64_t>(std::max<std::int64_t>(act_part, 1)) - 1;
  if (wait_s.size() == done_s.size() && length_mm.size() == done_s.size() && k < done_s.size()) {
    waits_left = static_cast<double>(wait_s.back()) - static_cast<double>(wait_s[k]);
    if (!(length_mm[k] > 0.0F)) waits_left += static_cast<double>(done_s[k]) - elapsed;
    waits_left = std::max(waits_left, 0.0);
  }
  const double moves_left = std::max(total_s - elapsed - waits_left, 0.0);
  return moves_left * move_scale + waits_left;
}

std::optional<ProgramTimes> program_times(const MachineConfig& machine,
                                          const SimulationOptions& options,
                                          const PackedProgram& program, std::string* error) {
  ProgramTimes t;
  t.done_s.resize(program.size());
  t.length_mm.resize(program.size());
  // Records done so far: [0, filled) hold their time. Block reports come for moves only, in
  // program order (a skip in advance() ends before its reports would overflow); a record
  // between two reports (an M-function, a dwell, a message) is done by the pass in which
  // Act_Part leaves it, or, where a pass crosses it, when the move after it starts.
  std::uint64_t filled = 0;
  const auto fill_to = [&](std::uint64_t end, double at) {
    const float f = std::max(filled == 0 ? 0.0F : t.done_s[filled - 1], static_cast<float>(at));
    for (; filled < end; ++filled) t.done_s[filled] = f;
  };
  // The records Act_Part has left behind are done (at the resolution of a pass: a cycle,
  // where a record that takes no motion ends).
  SimulationOptions o = options;
  o.on_part = [&](std::int32_t act_part, double at) {
    if (options.on_part) options.on_part(act_part, at);
    if (act_part > 1)
      fill_to(std::min<std::uint64_t>(static_cast<std::uint64_t>(act_part) - 1, t.done_s.size()),
              at);
  };
  auto sim = Simulation::create(machine, o, error);
  if (!sim) return std::nullopt;
  const SimulationSummary sum = sim->run(program, {}, [&](const BlockReport& b) {
    if (b.act_part <= 0) return;
    const auto k = static_cast<std::uint64_t>(b.act_part) - 1;
    if (k >= t.done_s.size()) return;
    t.length_mm[k] = static_cast<float>(b.length_mm);
    if (k < filled) return;
    fill_to(k, b.end_s - b.duration_s);
    fill_to(k + 1, b.end_s);
  });
  if (sum.result != StepResult::kFinished) {
    if (error) *error = sum.error.empty() ? "the program did not end" : sum.error;
    return std::nullopt;
  }
  t.total_s = sum.program_time_s;
  fill_to(t.done_s.size(), t.total_s);
  // The program is done when the run ends (Status 3), which may be after its last move's end
  // (the smoothing settles, an M-function's wait).
  if (!t.done_s.empty()) t.done_s.back() = std::max(t.done_s.back(), static_cast<float>(t.total_s));
  // The waits, summed in double: the records that do not move.
  t.wait_s.resize(t.done_s.size());
  double waits = 0.0;
  for (std::size_t k = 0; k < t.done_s.size(); ++k) {
    if (!(t.length_mm[k] > 0.0F)) {
      waits += static_cast<double>(t.done_s[k]) - start_of(t.done_s, k);
    }
    t.wait_s[k] = static_cast<float>(waits);
  }
  return t;
}

}  // namespace tgm
