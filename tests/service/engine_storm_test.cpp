// Seeded storm against the cycle engine (mock port): on all three interpolators at once, random
// requests of every kind from both roles (also unknown kinds and Commands, interpolators that
// do not exist, values that are NaN, huge or not whole), and program chunks in order, repeated,
// with gaps, from a foreign program and undecodable, under random request and record budgets,
// while an emulated PLC acknowledges M-functions and an HMI starts the programs. (It goes on from
// Engine.RandomRequestsAreEachAnsweredOnceAndNeverBreakTheCycle, one fixed seed of requests on a
// streamed program with its floors per reply code: chunks, budgets, motion and the way back.)
//
// Oracles:
// - every request gets exactly one reply, with its own id and interpolator, none lost, none
//   twice; a refusal carries a reply code and a reason; every message has a text;
// - after every cycle the snapshot's positions and speeds are finite;
// - at the end the operator's way back works on each interpolator: emergency stop off the
//   trajectory, clear, Rel_Speed, Number_Axes, Ratio and Offset back, the position set to zero
//   by Command 2048, and a known program streamed and started runs to its end point.
//
// Sweep size: --seed=N --count=N on the test binary's command line (or TGM_SEED,
// TGM_SWEEP_COUNT; defaults 1 and 12):
//   build/tests/service/tgm_service_tests --gtest_filter='EngineStorm.*' --seed=3 --count=200
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "../motion/random_program.hpp"
#include "../support/sweep_progress.hpp"
#include "../support/test_params.hpp"
#include "mock_port.hpp"
#include "tgm/config.hpp"
#include "tgm/service/engine.hpp"

namespace tgm::service {
namespace {

constexpr int kStormCycles = 6000;

// What the storms did, for the activity floor and the test's properties.
struct Tally {
  std::uint64_t accepted = 0, refused = 0, segments = 0, refused_chunks = 0, moving = 0;
};

class EngineStorm {
 public:
  EngineStorm(std::uint64_t seed, std::uint64_t k)
      : rng_(seed * 1000003ull + k + 0x2545f491ull), machine_(MachineConfig::default_machine()) {
    EngineOptions o;
    o.max_requests_per_cycle = 1 + static_cast<int>(rng_() % 32);
    o.max_segments_per_cycle = 1 + rng_() % 1024;
    ctx_ = "seed " + std::to_string(seed) + " case " + std::to_string(k) + " (budgets " +
           std::to_string(o.max_requests_per_cycle) + " requests, " +
           std::to_string(o.max_segments_per_cycle) + " records a cycle)";
    std::string error;
    auto e = Engine::create(machine_, o, &error);
    if (!e) {
      ADD_FAILURE() << ctx_ << ": " << error;
      return;
    }
    engine_.emplace(std::move(*e));
    for (int i = 0; i < kIps; ++i) new_program(i);
  }

  void run(Tally& tally) {
    if (!engine_) return;
    for (int c = 0; c < kStormCycles && !::testing::Test::HasFailure(); ++c) {
      if (u() < 0.15) {
        for (int n = 1 + static_cast<int>(rng_() % 6); n > 0; --n) random_request();
      }
      for (int i = 0; i < kIps; ++i) {
        const InterpolatorSnapshot& s = port_.last.ip[static_cast<std::size_t>(i)];
        if (s.reg.m_func != 0 && u() < 0.1) ack(i);
        if (u() < 0.01) add(Role::kHmi, RequestKind::kStart, i);
        if (u() < 0.05) chunk(i);
      }
      cycle();
    }
    // Every request still queued is answered within a few cycles of the smallest budget.
    for (int c = 0; c < 2000 && !open_.empty() && !::testing::Test::HasFailure(); ++c) cycle();
    EXPECT_TRUE(open_.empty()) << ctx_ << ": " << open_.size()
                               << " requests never answered, the first id "
                               << (open_.empty() ? 0 : open_.begin()->first);
    EXPECT_EQ(engine_->counters().lost_replies, 0u) << ctx_;
    tally.accepted += accepted_;
    tally.refused += refused_;
    tally.segments += engine_->counters().segments;
    tally.refused_chunks +=
        engine_->counters().refused_chunks + engine_->counters().duplicate_chunks;
    tally.moving += moving_;
    for (int i = 0; i < kIps && !::testing::Test::HasFailure(); ++i) recover(i);
  }

 private:
  static constexpr int kIps = 3;
  double u() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_); }
  const Registers& reg(int i) const { return port_.last.ip[static_cast<std::size_t>(i)].reg; }

  RequestIn& add(Role role, RequestKind kind, int i) {
    RequestIn& r = port_.add_request(role, kind, i);
    open_[r.request_id] = i;
    return r;
  }
  void ack(int i) {
    RequestIn& r = add(Role::kPlc, RequestKind::kWriteMFunc, i);
    r.value = 0.0;
    r.m_func_acknowledged = reg(i).m_func;
    r.m_func_count_acknowledged = u() < 0.5 ? reg(i).m_func_count : 0u;
  }

  double any_value() {
    switch (rng_() % 8) {
      case 0:
        return std::numeric_limits<double>::quiet_NaN();
      case 1:
        return -std::numeric_limits<double>::infinity();
      case 2:
        return 1e300;
      case 3:
        return 0.5;
      case 4:
        return 0.0;
      default:
        return std::floor((u() - 0.5) * 2e4);
    }
  }

  void random_request() {
    static constexpr std::array<RequestKind, 10> kKinds = {
        RequestKind::kCommand,     RequestKind::kWriteMFunc, RequestKind::kWriteRelSpeed,
        RequestKind::kWriteOffset, RequestKind::kWriteRatio, RequestKind::kWriteNumberAxes,
        RequestKind::kStart,       RequestKind::kStop,       RequestKind::kClear,
        RequestKind::kUnknown};
    const RequestKind kind =
        u() < 0.97 ? kKinds[rng_() % kKinds.size()] : static_cast<RequestKind>(rng_() % 256);
    const int i = u() < 0.95 ? static_cast<int>(rng_() % kIps) : static_cast<int>(rng_() % 9) - 3;
    RequestIn& r = add(u() < 0.5 ? Role::kPlc : Role::kHmi, kind, i);
    static constexpr std::array<std::int32_t, 11> kCommands = {4,    5,  8,  9, 1024, 2048,
                                                               2049, -1, -2, 0, 7};
    r.command =
        u() < 0.95 ? kCommands[rng_() % kCommands.size()] : static_cast<std::int32_t>(rng_());
    for (auto& p : r.command_parameter) p = static_cast<std::int32_t>(rng_() % 2001) - 1000;
    if (r.command == 1024) {  // mostly a plausible ratio: axis, inc, mm
      r.command_parameter[0] = static_cast<std::int32_t>(rng_() % 4);
      r.command_parameter[1] = static_cast<std::int32_t>(100 + rng_() % 100000);
      r.command_parameter[2] = static_cast<std::int32_t>(1 + rng_() % 100);
    } else if (r.command == -1) {
      r.command_parameter[2] = static_cast<std::int32_t>(rng_() % 1000000);
      r.command_parameter[3] = static_cast<std::int32_t>(rng_() % 8);
    }
    if (u() < 0.1) {
      for (auto& p : r.command_parameter) p = static_cast<std::int32_t>(rng_());
    }
    r.axis = u() < 0.9 ? static_cast<int>(rng_() % 3) : static_cast<int>(rng_() % 40) - 20;
    switch (kind) {
      case RequestKind::kWriteRelSpeed:
        r.value = u() < 0.8 ? 0.01 + 1.99 * u() : any_value();
        break;
      case RequestKind::kWriteRatio:
        r.value = u() < 0.8 ? 100.0 + 1e5 * u() : any_value();
        break;
      case RequestKind::kWriteNumberAxes:
        r.value = u() < 0.8 ? 1.0 + static_cast<double>(rng_() % 3) : any_value();
        break;
      case RequestKind::kWriteMFunc:
        r.value = u() < 0.9 ? 0.0 : any_value();
        break;
      default:
        r.value = any_value();
    }
    r.m_func_acknowledged = u() < 0.5 ? reg(std::max(0, std::min(i, kIps - 1))).m_func
                                      : static_cast<std::int32_t>(rng_());
    r.m_func_count_acknowledged = static_cast<std::uint32_t>(u() < 0.5 ? 0 : rng_());
  }

  // A new random program for interpolator i, streamed from record 0 under a new id.
  void new_program(int i) {
    auto& s = streams_[static_cast<std::size_t>(i)];
    s.program = tgm::test::random_program(rng_, 3, 3 + static_cast<int>(rng_() % 20)).program;
    s.id = ++last_id_;
    s.next = 0;
  }

  void chunk(int i) {
    auto& s = streams_[static_cast<std::size_t>(i)];
    const InterpolatorSnapshot& snap = port_.last.ip[static_cast<std::size_t>(i)];
    // The engine forgot the program (cleared, or refused it): stream a new one.
    if (s.next > 0 && snap.program_id != s.id && u() < 0.5) new_program(i);
    if (s.next >= s.program.segments.size()) {
      if (reg(i).status == static_cast<std::int32_t>(InterpolatorStatus::kEnded) && u() < 0.3) {
        add(Role::kHmi, RequestKind::kClear, i);
      }
      return;
    }
    const std::size_t total = s.program.segments.size();
    const std::size_t count = std::min<std::size_t>(total - s.next, 1 + rng_() % 128);
    const double pick = u();
    if (pick < 0.8) {
      port_.add_chunk(i, s.program, s.next, count, s.id, s.next + count == total);
      s.next += count;
    } else if (pick < 0.85 && s.next > 0) {  // a repeat of records already sent
      const std::size_t first = rng_() % s.next;
      port_.add_chunk(i, s.program, first, std::min(count, total - first), s.id, false);
    } else if (pick < 0.9 && s.next + count < total) {  // a gap
      port_.add_chunk(i, s.program, s.next + count, std::min(count, total - s.next - count), s.id,
                      false);
    } else if (pick < 0.95) {  // another program's records
      port_.add_chunk(i, s.program, 0, count, s.id + 1000, false);
    } else {  // undecodable
      port_.add_chunk(i, s.program, s.next, count, s.id, false);
      port_.chunks[static_cast<std::size_t>(i)].back()->decode_status = 1;
      port_.chunks[static_cast<std::size_t>(i)].back()->error.set("CDR: not enough data");
    }
  }

  void cycle() {
    engine_->cycle(port_, {});
    for (; seen_replies_ < port_.replies.size(); ++seen_replies_) {
      const ReplyOut& r = port_.replies[seen_replies_];
      const auto it = open_.find(r.request_id);
      if (it == open_.end()) {
        ADD_FAILURE() << ctx_ << ": reply to request " << r.request_id
                      << " that is not waiting for one";
        continue;
      }
      EXPECT_EQ(r.interpolator, it->second) << ctx_ << ": request " << r.request_id;
      EXPECT_LE(static_cast<int>(r.code), static_cast<int>(ReplyCode::kBusy)) << ctx_;
      ++(r.code == ReplyCode::kAccepted ? accepted_ : refused_);
      if (r.code != ReplyCode::kAccepted) {
        EXPECT_FALSE(r.reason.view().empty())
            << ctx_ << ": request " << r.request_id << " refused without a reason";
      }
      open_.erase(it);
    }
    for (; seen_messages_ < port_.messages.size(); ++seen_messages_) {
      EXPECT_FALSE(port_.messages[seen_messages_].text.view().empty())
          << ctx_ << ": a message without text";
    }
    for (int i = 0; i < kIps; ++i) {
      const Registers& r = reg(i);
      const auto ui = static_cast<std::size_t>(i);
      // No axis moves faster than its velocity limit between two cycles, except across a
      // position set (Command 2048 / 2049), which jumps by design.
      const std::uint64_t sets = engine_->interpolator(i).position_sets();
      const bool jump = sets != last_sets_[ui] || r.number_axes != last_axes_[ui];
      for (int a = 0; a < 3; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        EXPECT_TRUE(std::isfinite(r.orig_position[ua]) && std::isfinite(r.position[ua]) &&
                    std::isfinite(r.speed[ua]))
            << ctx_ << ", cycle " << r.cycle << ": interpolator " << i << " axis " << a;
        if (jump || a >= r.number_axes) continue;
        const double vmax = machine_.interpolators[ui].axes[ua].max_velocity_mm_s;
        const double moved = std::fabs(r.orig_position[ua] - last_orig_[ui][ua]);
        EXPECT_LE(moved, vmax * engine_->cycle_time_s() * (1.0 + 1e-9) + 1e-9)
            << ctx_ << ", cycle " << r.cycle << ": interpolator " << i << " axis " << a << " moved "
            << moved << " mm in one cycle";
      }
      last_sets_[ui] = sets;
      last_axes_[ui] = r.number_axes;
      last_orig_[ui] = r.orig_position;
      if (r.status == static_cast<std::int32_t>(InterpolatorStatus::kRunning) && r.act_speed > 0.0)
        ++moving_;
      EXPECT_TRUE(std::isfinite(r.act_speed) && std::isfinite(r.set_speed))
          << ctx_ << ", cycle " << r.cycle << ": interpolator " << i;
    }
  }

  // Cycles until request `id` (queued) is answered; the reply.
  ReplyOut answer(std::uint64_t id) {
    for (int c = 0; c < 100; ++c) {
      const std::size_t from = port_.replies.size();
      cycle();
      for (std::size_t k = from; k < port_.replies.size(); ++k) {
        if (port_.replies[k].request_id == id) return port_.replies[k];
      }
    }
    ADD_FAILURE() << ctx_ << ": no reply to request " << id;
    return {};
  }
  template <class Fill>
  ReplyOut ask(Role role, RequestKind kind, int i, const Fill& fill) {
    RequestIn& r = add(role, kind, i);
    fill(r);
    return answer(r.request_id);
  }
  // Asks until accepted, at most `tries` cycles apart; false if it never was.
  template <class Fill>
  bool insist(Role role, RequestKind kind, int i, const Fill& fill, int tries, ReplyOut* last) {
    for (int t = 0; t < tries; ++t) {
      *last = ask(role, kind, i, fill);
      if (last->code == ReplyCode::kAccepted) return true;
      cycle();
    }
    return false;
  }

  void recover(int i) {
    const std::string at = ctx_ + ", recovery of interpolator " + std::to_string(i);
    const auto nothing = [](RequestIn&) {};
    // The stream stops: what the storm queued is applied or refused first (a small record
    // budget takes a while), or it would load behind the clear below.
    auto& queued = port_.chunks[static_cast<std::size_t>(i)];
    for (int c = 0; c < 100000 && !queued.empty(); ++c) cycle();
    ASSERT_TRUE(queued.empty()) << at << ": the storm's chunks were never taken";
    if (reg(i).m_func != 0) ack(i);
    (void)ask(Role::kHmi, RequestKind::kCommand, i, [](RequestIn& r) { r.command = 5; });
    ReplyOut last;
    const int tries = 1'200'000;  // ten minutes of 500 us cycles for the slowest stop
    int c = 0;
    for (; c < tries && (reg(i).status == 1 || reg(i).status == 6 || reg(i).command_status == 1);
         ++c) {
      if (reg(i).m_func != 0) ack(i);
      cycle();
    }
    ASSERT_LT(c, tries) << at << ": never came to a stand, Status " << reg(i).status;
    ASSERT_TRUE(insist(Role::kHmi, RequestKind::kClear, i, nothing, 100, &last))
        << at << ": " << last.reason.view();
    ASSERT_TRUE(insist(
        Role::kPlc, RequestKind::kWriteRelSpeed, i, [](RequestIn& r) { r.value = 1.0; }, 10, &last))
        << at << ": " << last.reason.view();
    ASSERT_TRUE(insist(
        Role::kPlc, RequestKind::kWriteNumberAxes, i, [](RequestIn& r) { r.value = 3.0; }, 10,
        &last))
        << at << ": " << last.reason.view();
    Params inc{};
    for (int a = 0; a < 3; ++a) {
      const double ratio = machine_.interpolators[static_cast<std::size_t>(i)]
                               .axes[static_cast<std::size_t>(a)]
                               .ratio_inc_per_mm;
      ASSERT_TRUE(insist(
          Role::kPlc, RequestKind::kWriteRatio, i,
          [&](RequestIn& r) {
            r.axis = a;
            r.value = ratio;
          },
          100000, &last))
          << at << ": Ratio of axis " << a << ": " << last.reason.view();
      ASSERT_TRUE(insist(
          Role::kPlc, RequestKind::kWriteOffset, i,
          [&](RequestIn& r) {
            r.axis = a;
            r.value = 0.0;
          },
          10, &last))
          << at << ": Offset of axis " << a << ": " << last.reason.view();
    }
    // Position 0 = (inc - Offset - Backlash) / Ratio: inc = Backlash.
    for (int a = 0; a < 3; ++a)
      inc[static_cast<std::size_t>(a)] =
          static_cast<std::int32_t>(reg(i).backlash[static_cast<std::size_t>(a)]);
    ASSERT_TRUE(insist(
        Role::kPlc, RequestKind::kCommand, i,
        [&](RequestIn& r) {
          r.command = 2048;
          r.command_parameter = inc;
        },
        100000, &last))
        << at << ": Command 2048: " << last.reason.view();
    for (c = 0; c < 1000 && reg(i).command_status == 1; ++c) cycle();
    ASSERT_EQ(reg(i).command_status, 0)
        << at << ": Command 2048 ended with " << reg(i).command_status;
    for (int a = 0; a < 3; ++a)
      ASSERT_EQ(reg(i).orig_position[static_cast<std::size_t>(a)], 0.0) << at << ": axis " << a;

    tgm::test::ProgramBuilder b(3);
    b.line({10.0, 0.0, 0.0}, 3000.0).m(7, MKind::kNormal).line({2.5, -3.0, 1.0}, 1500.0).end();
    const std::uint32_t id = ++last_id_;
    port_.add_chunk(i, b.program(), 0, b.program().segments.size(), id, true);
    for (c = 0; c < 100 && !queued.empty(); ++c) cycle();
    ASSERT_EQ(port_.last.ip[static_cast<std::size_t>(i)].program_id, id)
        << at << ": the known program was not taken";
    ASSERT_TRUE(insist(Role::kHmi, RequestKind::kStart, i, nothing, 10, &last))
        << at << ": start: " << last.reason.view();
    for (c = 0;
         c < 200000 && reg(i).status != static_cast<std::int32_t>(InterpolatorStatus::kEnded);
         ++c) {
      if (reg(i).m_func != 0) ack(i);
      cycle();
    }
    ASSERT_EQ(reg(i).status, static_cast<std::int32_t>(InterpolatorStatus::kEnded))
        << at << ": the known program did not end, line " << reg(i).act_line;
    const std::array<double, 3> end = {2.5, -3.0, 1.0};
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(reg(i).orig_position[static_cast<std::size_t>(a)],
                  end[static_cast<std::size_t>(a)], 1e-9)
          << at << ": axis " << a;
    }
  }

  using Params = std::array<std::int32_t, kCommandParameters>;
  struct Stream {
    Program program;
    std::uint32_t id = 0;
    std::size_t next = 0;
  };

  std::mt19937_64 rng_;
  MachineConfig machine_;
  std::optional<Engine> engine_;
  test::MockPort port_;
  std::array<Stream, kIps> streams_;
  std::uint32_t last_id_ = 0;
  std::map<std::uint64_t, int> open_;  // request id -> interpolator, waiting for the reply
  std::size_t seen_replies_ = 0, seen_messages_ = 0;
  std::uint64_t accepted_ = 0, refused_ = 0, moving_ = 0;
  std::array<std::uint64_t, kIps> last_sets_{};
  std::array<int, kIps> last_axes_{};
  std::array<std::array<double, kMaxAxes>, kIps> last_orig_{};
  std::string ctx_;
};

TEST(EngineStorm, EveryRequestIsAnsweredOnceAndEveryInterpolatorComesBack) {
  const std::uint64_t seed = tgm::test::param_u64("seed", "TGM_SEED", 1);
  const std::uint64_t count = tgm::test::param_u64("count", "TGM_SWEEP_COUNT", 12);
  Tally t;
  tgm::test::SweepProgress progress("EngineStorm seed " + std::to_string(seed), count, "storms");
  for (std::uint64_t k = 0; k < count && !::testing::Test::HasFailure(); ++k) {
    progress.update(k);
    EngineStorm(seed, k).run(t);
  }
  // The storm must reach what it is about: requests taken, records streamed, motion under way.
  EXPECT_GT(t.accepted, count * 50);
  EXPECT_GT(t.segments, count * 100);
  EXPECT_GT(t.moving, count * 1000);
  RecordProperty("accepted", std::to_string(t.accepted));
  RecordProperty("refused", std::to_string(t.refused));
  RecordProperty("segments", std::to_string(t.segments));
  RecordProperty("refused_or_duplicate_chunks", std::to_string(t.refused_chunks));
  RecordProperty("moving_cycles", std::to_string(t.moving));
}

}  // namespace
}  // namespace tgm::service
