// Seeded random request sweep: between the cycles of a running program, a random stream of every
// request the service forwards from a PLC or an HMI (append in order and out of it, load, start,
// clear, Commands 4 / 5 / 8 / 9 and the stage commands with any parameters, Ratio, Offset,
// Number_Axes, M_Func and Rel_Speed writes, position sets), valid ones and wild ones, at any
// moment: accelerating, in an arc, in an M wait, on a stop ramp, with a stage command pending.
//
// Oracles, after every request and every cycle:
// - a request is accepted, or refused with one of RequestCode's values and a reason;
// - step() and advance() never report an internal error, never clamp at a stop point (hard
//   stops), and leave registers that are finite and within their documented ranges (Status,
//   Command_Status, Run_Flag halves, Rel_Speed, Free_Slots);
// - no axis of Orig_Position moves faster than its velocity limit between two cycles, except
//   across a position set (set_position, Command 2048 / 2049), which jumps by design;
// and at the end of the stream the operator's way back works: acknowledge, emergency stop off
// the trajectory, clear, Rel_Speed 1, Number_Axes back, the position set to the start, and a
// known program of a line, an arc and a normal M-function runs to its programmed end point.
//
// Sweep size: --seed=N --count=N --first=N on the test binary's command line (or TGM_SEED,
// TGM_SWEEP_COUNT, TGM_SWEEP_FIRST; defaults 1, 60, 0), and --machines=random|wide|box, like
// RandomSweep:
//   build/tests/motion/tgm_motion_tests --gtest_filter='RandomRequests.*' --seed=5 --count=2000
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "../support/sweep_progress.hpp"
#include "../support/test_params.hpp"
#include "machine_kind_arg.hpp"
#include "random_program.hpp"
#include "same_registers.hpp"
#include "tgm/command_stage.hpp"
#include "tgm/interpolator.hpp"

namespace tgm {
namespace {

constexpr std::uint64_t kChaosCycles = 4000;

// What a storm did: requests accepted and refused, cycles that ended moving on a path.
struct Tally {
  std::uint64_t accepted = 0, refused = 0, moving = 0;
};

// One case: machine, program, and the random stream of requests.
class RequestStorm {
 public:
  RequestStorm(std::uint64_t seed, std::uint64_t k)
      : rng_(seed * 1000003ull + k + 0x5bd1e995ull),
        axes_(k % 4 == 0 ? 3 : 1 + static_cast<int>(rng_() % 10)),
        machine_(test::machine_of_kind(test::machine_kind_arg(), rng_, axes_)),
        generated_(test::random_program(rng_, axes_, 4 + static_cast<int>(rng_() % 30))) {
    ctx_ = "seed " + std::to_string(seed) + " case " + std::to_string(k) + " (" +
           test::machine_kind_name(test::machine_kind_arg()) + " machine), " +
           std::to_string(axes_) + " axes, " + std::to_string(machine_.cycle_time_us) +
           " us cycle, " + std::to_string(generated_.program.segments.size()) + " records";
  }

  void run(Tally& tally) {
    std::string error;
    auto made = Interpolator::create(machine_, 0, {}, &error);
    ASSERT_TRUE(made.has_value()) << ctx_ << ": " << error;
    ip_ = &*made;
    // The twin gets the same requests and is stepped where ip_ may be advanced, and rebuilds
    // its LookAheadBuffer table every cycle (the reference of the incremental update): after
    // every cycle its registers must equal ip_'s to the bit.
    InterpolatorOptions twin_options;
    twin_options.full_lookahead_fill = true;
    auto twin = Interpolator::create(machine_, 0, twin_options, &error);
    ASSERT_TRUE(twin.has_value()) << ctx_ << ": " << error;
    twin_ = &*twin;
    ASSERT_TRUE(
        ask("set_position", nullptr, [](Interpolator& x) { return x.set_position({}); }).ok())
        << ctx_;
    remember();
    for (std::uint64_t c = 0; c < kChaosCycles && !::testing::Test::HasFailure(); ++c) {
      if (u() < 0.12) {
        const int n = 1 + static_cast<int>(u() * 3.0);
        for (int i = 0; i < n && !::testing::Test::HasFailure(); ++i) request();
      }
      // The PLC acknowledges a normal M-function after a while.
      const Registers& r = ip_->registers();
      if (r.m_func != 0 && u() < 0.05) {
        const std::int32_t m = r.m_func;
        ask("ack", nullptr, [&](Interpolator& x) { return x.write_m_func(0, m); });
      }
      std::uint64_t done = 1;
      StepResult res;
      if (u() < 0.2) {
        res = ip_->advance(1 + static_cast<std::uint64_t>(u() * 500.0), &done);
        check_cycles(res, done, "advance");
        c += done > 0 ? done - 1 : 0;
      } else {
        res = ip_->step();
        check_cycles(res, 1, "step");
      }
      StepResult twin_res = StepResult::kWorking;
      for (std::uint64_t k = 0; k < done; ++k) twin_res = twin_->step();
      EXPECT_EQ(twin_res, res) << ctx_ << ", cycle " << ip_->registers().cycle;
      expect_twin_equal();
    }
    twin_ = nullptr;
    if (!::testing::Test::HasFailure()) recover();
    ip_ = nullptr;
    tally.accepted += tally_.accepted;
    tally.refused += tally_.refused;
    tally.moving += tally_.moving;
  }

 private:
  double u() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_); }
  std::int32_t any_int() {
    switch (rng_() % 4) {
      case 0:
        return 0;
      case 1:
        return std::numeric_limits<std::int32_t>::min();
      case 2:
        return std::numeric_limits<std::int32_t>::max();
      default:
        return static_cast<std::int32_t>(rng_());
    }
  }
  double any_double() {
    switch (rng_() % 6) {
      case 0:
        return std::numeric_limits<double>::quiet_NaN();
      case 1:
        return std::numeric_limits<double>::infinity();
      case 2:
        return -1e300;
      case 3:
        return 0.0;
      default:
        return (u() - 0.5) * 1e6;
    }
  }
  int axis() {
    return u() < 0.9 ? static_cast<int>(rng_() % static_cast<unsigned>(axes_)) : any_int() % 13;
  }

  // Makes the request `f` of ip_ and of the twin (while there is one): both answer alike, and
  // the answer passes expect_reply (with `before`, the registers before the request).
  template <class F>
  RequestResult ask(const char* what, const Registers* before, const F& f) {
    const RequestResult r = f(*ip_);
    if (twin_ != nullptr) {
      const RequestResult t = f(*twin_);
      EXPECT_TRUE(t.code == r.code && t.reason == r.reason)
          << ctx_ << ", cycle " << ip_->registers().cycle << ": " << what << " answered "
          << static_cast<int>(r.code) << " '" << r.reason << "', the twin "
          << static_cast<int>(t.code) << " '" << t.reason << "'";
    }
    expect_reply(r, what, before);
    return r;
  }

  // ip_'s registers equal the twin's to the bit (advance() == step(), the LookAheadBuffer's
  // update == its rebuild). A difference is named register by register where it is one
  // (same_registers.hpp), else (-0.0 against 0.0, padding) by its first byte.
  void expect_twin_equal() {
    const Registers& a = ip_->registers();
    const Registers& b = twin_->registers();
    if (std::memcmp(&a, &b, sizeof a) == 0) return;
    const std::string at = ctx_ + ", cycle " + std::to_string(a.cycle) + ", against the twin";
    test::expect_same_registers(a, b, at);
    const auto* pa = reinterpret_cast<const unsigned char*>(&a);
    const auto* pb = reinterpret_cast<const unsigned char*>(&b);
    std::size_t off = 0;
    while (off < sizeof a && pa[off] == pb[off]) ++off;
    ADD_FAILURE() << at << ": the registers differ from byte " << off << " of " << sizeof a;
  }

  // A request refused (other than a partly taken append: kBufferFull) changes none of the
  // registers a request can write or that say what the interpolator does: Status, the
  // trajectory flag, M_Func and its count, Rel_Speed, Number_Axes, Ratio, Offset and
  // Orig_Position. (Registers a request does not own, Act_Part and the free slots, may catch up
  // with an earlier accepted request, an acknowledgement that moved past its M record, when a
  // refused Command refreshes them; step() refreshes them anyway.)
  void expect_unchanged(const RequestResult& r, const Registers& before, const char* what) {
    if (r.ok() || r.code == RequestCode::kBufferFull) return;
    const Registers& now = ip_->registers();
    const std::string at = ctx_ + ", cycle " + std::to_string(before.cycle) + ": " + what +
                           " was refused (" + r.reason + ") but changed ";
    EXPECT_EQ(now.status, before.status) << at << "Status";
    EXPECT_EQ(now.off_trajectory, before.off_trajectory) << at << "the trajectory flag";
    EXPECT_EQ(now.m_func, before.m_func) << at << "M_Func";
    EXPECT_EQ(now.m_func_count, before.m_func_count) << at << "the M-function count";
    EXPECT_EQ(now.rel_speed, before.rel_speed) << at << "Rel_Speed";
    EXPECT_EQ(now.number_axes, before.number_axes) << at << "Number_Axes";
    EXPECT_EQ(now.ratio, before.ratio) << at << "Ratio";
    EXPECT_EQ(now.offset, before.offset) << at << "Offset";
    EXPECT_EQ(now.orig_position, before.orig_position) << at << "Orig_Position";
  }

  void expect_reply(const RequestResult& r, const char* what, const Registers* before = nullptr) {
    if (before != nullptr) expect_unchanged(r, *before, what);
    ++(r.ok() ? tally_.accepted : tally_.refused);
    const int code = static_cast<int>(r.code);
    EXPECT_TRUE(code <= 0 && code >= static_cast<int>(RequestCode::kUnsupported))
        << ctx_ << ", cycle " << ip_->registers().cycle << ": " << what << " gave code " << code;
    if (!r.ok()) {
      EXPECT_FALSE(r.reason.empty()) << ctx_ << ", cycle " << ip_->registers().cycle << ": " << what
                                     << " refused (code " << code << ") without a reason";
    }
  }

  // One random request.
  void request() {
    const Program& p = generated_.program;
    const std::size_t total = p.segments.size();
    const Registers& r = ip_->registers();
    const Registers before = r;
    const double pick = u();
    if (pick < 0.30) {  // the stream, in order
      const std::size_t count =
          std::min<std::size_t>(total - std::min(next_, total), 1 + rng_() % 64);
      std::size_t took = 0;
      const bool complete = next_ + count == total ? u() < 0.9 : u() < 0.05;
      ask("append", &before,
          [&](Interpolator& x) { return x.append(p, next_, count, complete, &took); });
      EXPECT_LE(took, count) << ctx_;
      next_ += took;
      if (next_ >= total && u() < 0.2) next_ = 0;  // the program again
    } else if (pick < 0.33) {                      // any range, also beyond the program
      const std::size_t first = rng_() % (total + 3), count = rng_() % (total + 3);
      const bool complete = u() < 0.5;
      ask("append (any range)", &before,
          [&](Interpolator& x) { return x.append(p, first, count, complete); });
    } else if (pick < 0.35) {
      ask("load", &before, [&](Interpolator& x) { return x.load(p); });
    } else if (pick < 0.45) {
      ask("start", &before, [&](Interpolator& x) { return x.start(); });
    } else if (pick < 0.48) {
      ask("clear", &before, [&](Interpolator& x) { return x.clear(); });
      if (r.status == static_cast<std::int32_t>(InterpolatorStatus::kEmpty)) next_ = 0;
    } else if (pick < 0.56) {
      static constexpr std::array<std::int32_t, 4> kStops = {4, 5, 8, 9};
      const std::int32_t code = u() < 0.9 ? kStops[rng_() % kStops.size()] : any_int();
      ask("command", &before, [&](Interpolator& x) { return x.command(code); });
    } else if (pick < 0.66) {
      stage_command();
    } else if (pick < 0.70) {
      const double ratio =
          u() < 0.7 ? (u() < 0.5 ? -1.0 : 1.0) * std::pow(10.0, -3.0 + 9.0 * u()) : any_double();
      const int a = axis();
      ask("ratio", &before, [&](Interpolator& x) { return x.write_ratio(a, ratio); });
    } else if (pick < 0.74) {
      const std::int64_t offset = u() < 0.7 ? static_cast<std::int64_t>(rng_() % 2000001) - 1000000
                                            : static_cast<std::int64_t>(rng_());
      const int a = axis();
      ask("offset", &before, [&](Interpolator& x) { return x.write_offset(a, offset); });
    } else if (pick < 0.76) {
      const int n =
          u() < 0.8 ? 1 + static_cast<int>(rng_() % static_cast<unsigned>(axes_)) : any_int() % 12;
      ask("Number_Axes", &before, [&](Interpolator& x) { return x.write_number_axes(n); });
    } else if (pick < 0.86) {
      const std::int32_t value = u() < 0.9 ? 0 : any_int();
      const std::int32_t acked = u() < 0.5 ? r.m_func : (u() < 0.5 ? 0 : any_int());
      const std::uint32_t count =
          u() < 0.5 ? 0u : (u() < 0.5 ? r.m_func_count : static_cast<std::uint32_t>(rng_()));
      ask("M_Func", &before, [&](Interpolator& x) { return x.write_m_func(value, acked, count); });
    } else if (pick < 0.95) {
      const double rel = u() < 0.85 ? 0.01 + 1.99 * u() : any_double();
      ask("Rel_Speed", &before, [&](Interpolator& x) { return x.set_rel_speed(rel); });
    } else {
      std::array<double, kMaxAxes> at = r.orig_position;
      for (int i = 0; i < axes_; ++i) {
        at[static_cast<std::size_t>(i)] = u() < 0.95 ? (u() - 0.5) * 400.0 : any_double();
      }
      ask("set_position", &before, [&](Interpolator& x) { return x.set_position(at); });
    }
  }

  // 1024 ratio, 2048 / 2049 position sets, -1 IIR, -2 spline: mostly plausible parameters.
  void stage_command() {
    static constexpr std::array<std::int32_t, 5> kCodes = {kCommandSetRatio, kCommandSetPositionOn,
                                                           kCommandSetPositionOff, kCommandIir,
                                                           kCommandSpline};
    const std::int32_t code = u() < 0.95 ? kCodes[rng_() % kCodes.size()] : any_int();
    std::array<std::int32_t, kCommandParameters> par{};
    const bool wild = u() < 0.15;
    for (std::size_t i = 0; i < par.size(); ++i) {
      par[i] = wild ? any_int() : static_cast<std::int32_t>(rng_() % 2001) - 1000;
    }
    if (!wild) {
      switch (code) {
        case kCommandSetRatio:
          par[0] = axis();
          par[1] = static_cast<std::int32_t>(1 + rng_() % 100000);
          par[2] = static_cast<std::int32_t>(1 + rng_() % 100);
          break;
        case kCommandIir:
          par[0] = static_cast<std::int32_t>(rng_() % 4);
          par[1] = static_cast<std::int32_t>(rng_() % 4);
          par[2] = static_cast<std::int32_t>(rng_() % 1000000);
          par[3] = static_cast<std::int32_t>(rng_() % 1024);
          break;
        case kCommandSpline:
          par[0] = static_cast<std::int32_t>(rng_() % 40);
          par[1] = static_cast<std::int32_t>(rng_() % 1000000);
          break;
        default:  // position sets: increments near the ratio's scale
          for (int i = 0; i < axes_; ++i) {
            par[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(rng_() % 400001) - 200000;
          }
      }
    }
    const Registers before = ip_->registers();
    ask("stage command", &before, [&](Interpolator& x) { return x.command(code, par); });
  }

  void remember() {
    const Registers& r = ip_->registers();
    last_orig_ = r.orig_position;
    last_pos_ = r.position;
    last_axes_ = r.number_axes;
    last_sets_ = ip_->position_sets();
  }

  // The registers after `cycles` cycles that ended with `res`.
  void check_cycles(StepResult res, std::uint64_t cycles, const char* how) {
    const Registers& r = ip_->registers();
    const std::string at = ctx_ + ", " + how + " to cycle " + std::to_string(r.cycle) + " (line " +
                           std::to_string(r.act_line) + ", Status " + std::to_string(r.status) +
                           ")";
    EXPECT_NE(res, StepResult::kErrorInternal) << at;
    if (r.status == static_cast<std::int32_t>(InterpolatorStatus::kRunning) && r.act_speed > 0.0) {
      tally_.moving += cycles;
    }
    EXPECT_EQ(ip_->hard_stops(), 0u) << at;
    static constexpr std::array<std::int32_t, 7> kStatus = {0, 1, 3, 4, 6, 7, 8};
    EXPECT_NE(std::find(kStatus.begin(), kStatus.end(), r.status), kStatus.end()) << at;
    EXPECT_TRUE(r.command_status >= -1 && r.command_status <= 1)
        << at << ": Command_Status " << r.command_status;
    EXPECT_LE(run_flag_section(r.run_flag), SectionState::kWaitMFuncEnd) << at;
    EXPECT_LE(run_flag_speed(r.run_flag), SpeedState::kEmergencyRamp) << at;
    EXPECT_TRUE(r.rel_speed >= 0.01 && r.rel_speed <= 2.0) << at << ": Rel_Speed " << r.rel_speed;
    EXPECT_TRUE(r.free_slots >= 0 && r.free_slots <= r.buffer_size)
        << at << ": Free_Slots " << r.free_slots;
    EXPECT_TRUE(r.number_axes >= 1 && r.number_axes <= axes_) << at;
    EXPECT_TRUE(std::isfinite(r.act_speed) && std::isfinite(r.set_speed) &&
                std::isfinite(r.move_distance))
        << at << ": Act_Speed " << r.act_speed << ", Set_Speed " << r.set_speed
        << ", Move_Distance " << r.move_distance;
    const double T = ip_->cycle_time_s() * static_cast<double>(cycles);
    const bool jump = ip_->position_sets() != last_sets_;
    const int n = std::min(last_axes_, r.number_axes);
    for (int i = 0; i < axes_; ++i) {
      const auto a = static_cast<std::size_t>(i);
      EXPECT_TRUE(std::isfinite(r.orig_position[a]) && std::isfinite(r.position[a]) &&
                  std::isfinite(r.speed[a]))
          << at << ": axis " << i << " Orig_Position " << r.orig_position[a] << ", Position "
          << r.position[a] << ", Speed " << r.speed[a];
      if (jump || i >= n) continue;
      const double vmax = machine_.interpolators[0].axes[a].max_velocity_mm_s;
      const double moved = std::fabs(r.orig_position[a] - last_orig_[a]);
      EXPECT_LE(moved, vmax * T * (1.0 + 1e-9) + 1e-9)
          << at << ": axis " << i << " moved " << moved << " mm in " << T << " s (limit " << vmax
          << " mm/s)";
      const double smoothed = std::fabs(r.position[a] - last_pos_[a]);
      EXPECT_LE(smoothed, 2.0 * vmax * T + 1e-9)
          << at << ": axis " << i << " Position moved " << smoothed << " mm in " << T
          << " s (limit " << vmax << " mm/s)";
    }
    remember();
  }

  // Steps until `done()` holds, at most `limit_s` of program time; false if it never did.
  template <class Done>
  bool step_until(const Done& done, double limit_s, const char* what) {
    const auto cycles = static_cast<std::uint64_t>(limit_s / ip_->cycle_time_s());
    for (std::uint64_t c = 0; c < cycles; ++c) {
      if (done()) return true;
      const Registers& r = ip_->registers();
      if (r.m_func != 0) (void)ip_->write_m_func(0, r.m_func);
      check_cycles(ip_->step(), 1, what);
      if (::testing::Test::HasFailure()) return false;
    }
    return done();
  }

  // The operator's way back to a known state, and a known program run to its end.
  void recover() {
    const Registers& r = ip_->registers();
    const std::string at = ctx_ + ", recovery";
    if (r.m_func != 0) expect_reply(ip_->write_m_func(0, r.m_func), "ack");
    expect_reply(ip_->command(5), "emergency stop");
    const auto standing = [&] {
      const std::int32_t s = ip_->registers().status;
      return s != static_cast<std::int32_t>(InterpolatorStatus::kRunning) &&
             s != static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp);
    };
    ASSERT_TRUE(step_until(standing, 600.0, "stopping"))
        << at << ": still moving, Status " << r.status;
    ASSERT_TRUE(
        step_until([&] { return ip_->registers().command_status != 1; }, 600.0, "stage command"))
        << at << ": the pending stage command never ended";
    ASSERT_TRUE(step_until([&] { return ip_->clear().ok(); }, 60.0, "clearing"))
        << at << ": clear refused";
    ASSERT_TRUE(ip_->set_rel_speed(1.0).ok()) << at;
    const RequestResult na = ip_->write_number_axes(axes_);
    ASSERT_TRUE(na.ok()) << at << ": Number_Axes " << axes_ << ": " << na.reason;
    ASSERT_TRUE(step_until([&] { return ip_->set_position({}).ok(); }, 600.0, "settling"))
        << at << ": set_position refused: " << ip_->set_position({}).reason;
    remember();

    test::ProgramBuilder b(axes_);
    std::array<double, kMaxAxes> p{};
    p[0] = 10.0;
    b.line_to(p, 3000.0);
    if (axes_ >= 2) b.arc(true, p, {5.0, 0.0}, 2000.0);  // a full circle back to (10, 0)
    b.m(7, MKind::kNormal);
    p[0] = 2.5;
    if (axes_ >= 2) p[1] = -3.0;
    b.line_to(p, 1500.0);
    b.end();
    const RequestResult ld = ip_->load(b.program());
    ASSERT_TRUE(ld.ok()) << at << ": load: " << ld.reason;
    const RequestResult st = ip_->start();
    ASSERT_TRUE(st.ok()) << at << ": start: " << st.reason;
    // The sweep's time limit of the program (a slow axis of a box machine takes hours).
    const double limit_s = test::motion_time_limit(b.program(), machine_, {});
    const bool ended = step_until(
        [&] {
          return ip_->registers().status == static_cast<std::int32_t>(InterpolatorStatus::kEnded);
        },
        limit_s, "known program");
    ASSERT_TRUE(ended) << at << ": the known program did not end, Status "
                       << ip_->registers().status << ", line " << ip_->registers().act_line;
    for (int i = 0; i < axes_; ++i) {
      const auto a = static_cast<std::size_t>(i);
      EXPECT_NEAR(ip_->registers().orig_position[a], p[a], 1e-9) << at << ": axis " << i;
    }
  }

  std::mt19937_64 rng_;
  int axes_;
  MachineConfig machine_;
  test::Generated generated_;
  std::string ctx_;
  Interpolator* ip_ = nullptr;
  Interpolator* twin_ = nullptr;
  std::size_t next_ = 0;
  std::array<double, kMaxAxes> last_orig_{};
  std::array<double, kMaxAxes> last_pos_{};
  int last_axes_ = 0;
  std::uint64_t last_sets_ = 0;
  Tally tally_;
};

TEST(RandomRequests, AnyRequestStreamKeepsTheRegistersSaneAndTheWayBackOpen) {
  const std::uint64_t seed = test::param_u64("seed", "TGM_SEED", 1);
  const std::uint64_t count = test::param_u64("count", "TGM_SWEEP_COUNT", 60);
  const std::uint64_t first = test::param_u64("first", "TGM_SWEEP_FIRST", 0);
  Tally tally;
  test::SweepProgress progress("RandomRequests seed " + std::to_string(seed), count, "storms");
  for (std::uint64_t k = first; k < first + count && !::testing::Test::HasFailure(); ++k) {
    progress.update(k - first);
    RequestStorm(seed, k).run(tally);
  }
  // The storm must reach the states it is about: requests taken and motion under way.
  EXPECT_GT(tally.accepted, count * 20) << "accepted requests";
  EXPECT_GT(tally.moving, count * 500) << "cycles moving on a path";
  RecordProperty("accepted", std::to_string(tally.accepted));
  RecordProperty("refused", std::to_string(tally.refused));
  RecordProperty("moving_cycles", std::to_string(tally.moving));
}

}  // namespace
}  // namespace tgm
