// The cycle thread never allocates: Engine::cycle() with programs streaming into three
// interpolators in chunks, M-functions acknowledged, Rel_Speed changed, a stop and a restart,
// messages and events, counted by replacing the global operator new in this binary (a separate
// test executable for that reason). The mock port records into storage reserved up front, so
// that every allocation counted is the engine's or core's. malloc inside a 250 us cycle can
// take a lock another thread holds (the DDS threads allocate) and fault pages in: a delay of
// the cycle the DDS threads cause, which DESIGN.md rules out ("A DDS hiccup must never delay a
// cycle").
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <vector>

#include "mock_port.hpp"
#include "tgm/config.hpp"
#include "tgm/service/engine.hpp"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    // TGM_ALLOC_ABORT=1: stop at the first allocation counted (run under gdb for its stack).
    static const bool abort_first = std::getenv("TGM_ALLOC_ABORT") != nullptr;
    if (abort_first) std::abort();
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace tgm::service {
namespace {

using test::MockPort;

// A flat zig-zag of short lines (corners of 2.3 degrees) with a normal M-function every 400 records, an M29 message and a
// continuous M-function now and then, and a program end.
Program zigzag(int records, double step_mm) {
  Program p;
  p.number_axes = 3;
  p.axis_letters = "XYZ";
  p.messages.push_back("layer");
  std::array<double, kMaxAxes> at{};
  for (int i = 0; i < records; ++i) {
    Segment s;
    s.line = i + 1;
    if (i % 400 == 399 || i % 400 == 150) {
      s.type = SegmentType::kMFunction;
      s.m_kind = i % 400 == 399 ? MKind::kNormal : MKind::kContinuous;
      s.m = i % 400 == 399 ? 51 : 8;
      s.aux = static_cast<std::int32_t>(p.params.size());
      p.params.push_back(unset_params());
    } else if (i % 1000 == 500) {
      s.type = SegmentType::kMessage;
      s.aux = 0;
    } else {
      s.type = SegmentType::kLinear;
      at[0] += step_mm;
      at[1] = (i % 2 == 0) ? 0.0 : 0.02 * step_mm;
      s.feed_mm_per_min = 6000;
    }
    s.end = at;
    p.segments.push_back(s);
  }
  Segment end;
  end.type = SegmentType::kMFunction;
  end.m_kind = MKind::kProgramEnd;
  end.m = 2;
  end.line = records + 1;
  end.end = at;
  p.segments.push_back(end);
  return p;
}

// Runs the scenario on an engine made with `options`; every allocation inside a cycle fails.
void run_counted(const EngineOptions& options) {
  auto made = Engine::create(MachineConfig::default_machine(), options);
  ASSERT_TRUE(made.has_value());
  Engine& e = *made;
  // Nor does an append write ring slots that were never used: they are all built at create.
  for (int i = 0; i < e.count(); ++i) {
    EXPECT_EQ(e.interpolator(i).ring_slots(),
              static_cast<std::size_t>(e.interpolator(i).config().buffer_size));
  }
  // The mock port records into storage reserved before the count starts (its queues only
  // shrink inside a cycle: a freed block is no allocation).
  MockPort port;
  constexpr std::size_t kRecorded = 100'000;
  port.replies.reserve(kRecorded);
  port.messages.reserve(kRecorded);
  port.events.reserve(kRecorded);
  port.event_capacity = kRecorded;
  constexpr int kIps = 3;
  constexpr std::size_t kChunk = 128;
  // Each interpolator gets more records than its 10,000-slot ring holds, so that the stream
  // refills it while it runs (the rings fill up to the last slot).
  const Program p = zigzag(12'000, 0.3);
  for (int i = 0; i < kIps; ++i) {
    for (std::size_t first = 0; first < p.segments.size(); first += kChunk) {
      const std::size_t n = std::min(kChunk, p.segments.size() - first);
      port.add_chunk(i, p, first, n, 7, first + n == p.segments.size());
    }
  }
  // Warm-up: the first cycles set the engine up (first events, first snapshot, the first
  // chunks in the rings). Counted from then on: the basic parameters as tgm-plc sends them
  // (Command -2 spline, -1 IIR, 1024 gear ratio per axis), then the starts.
  for (int c = 0; c < 4; ++c) e.cycle(port, {});
  for (int i = 0; i < kIps; ++i) {
    RequestIn& spline = port.add_request(Role::kPlc, RequestKind::kCommand, i);
    spline.command = -2;
    spline.command_parameter[0] = 50;
    spline.command_parameter[1] = 20000;
    RequestIn& iir = port.add_request(Role::kPlc, RequestKind::kCommand, i);
    iir.command = -1;
    iir.command_parameter = {2'000'000, 1'000'000, 5'000'000, 0b011};
    for (int a = 0; a < 3; ++a) {
      RequestIn& ratio = port.add_request(Role::kPlc, RequestKind::kCommand, i);
      ratio.command = 1024;
      ratio.command_parameter = {a, 1000, 1000};
    }
  }

  long allocations = 0;
  std::vector<std::uint32_t> acked(kIps, 0);
  int stops = 0, overrides = 0;
  for (int c = 0; c < 400'000; ++c) {
    // Requests for this cycle, queued before the count (the receiving thread's part).
    for (int i = 0; i < kIps; ++i) {
      const Registers& r = port.last.ip[static_cast<std::size_t>(i)].reg;
      if (r.m_func == 51 && run_flag_waits_for_m(r.run_flag) && acked[static_cast<std::size_t>(i)] != r.m_func_count) {
        acked[static_cast<std::size_t>(i)] = r.m_func_count;
        RequestIn& ack = port.add_request(Role::kPlc, RequestKind::kWriteMFunc, i);
        ack.m_func_acknowledged = 51;
      }
    }
    if (c == 2) {
      ASSERT_TRUE(port.requests.empty()) << "the basic parameters were not all applied";
      for (int i = 0; i < kIps; ++i) port.add_request(Role::kHmi, RequestKind::kStart, i);
    }
    if (c == 3000) {
      RequestIn& rs = port.add_request(Role::kPlc, RequestKind::kWriteRelSpeed, 1);
      rs.value = 0.5;
      ++overrides;
    }
    if (c == 6000) {
      RequestIn& stop = port.add_request(Role::kHmi, RequestKind::kCommand, 2);
      stop.command = 8;
      ++stops;
    }
    if (c == 7000) port.add_request(Role::kHmi, RequestKind::kStart, 2);
    if (c == 9000) {
      RequestIn& estop = port.add_request(Role::kHmi, RequestKind::kCommand, 0);
      estop.command = 4;  // emergency ramp on the trajectory
      ++stops;
    }
    if (c == 11000) port.add_request(Role::kHmi, RequestKind::kStart, 0);
    g_allocations.store(0);
    g_counting.store(true);
    e.cycle(port, {});
    g_counting.store(false);
    const long n = g_allocations.load();
    if (n > 0 && allocations == 0) {
      ADD_FAILURE() << "cycle " << c << " allocated " << n << " times (status "
                    << port.last.ip[0].reg.status << ", part " << port.last.ip[0].reg.act_part << ")";
    }
    allocations += n;
    bool ended = true;
    for (int i = 0; i < kIps; ++i) ended = ended && port.last.ip[static_cast<std::size_t>(i)].reg.status == 3;
    if (ended) break;
  }
  for (int i = 0; i < kIps; ++i) {
    const Registers& r = port.last.ip[static_cast<std::size_t>(i)].reg;
    EXPECT_EQ(r.status, 3) << "interpolator " << i << ": part " << r.act_part << ", cycle "
                           << r.cycle << ", M_Func " << r.m_func << ", run_flag " << std::hex
                           << r.run_flag << std::dec << ", acknowledged "
                           << acked[static_cast<std::size_t>(i)];
  }
  EXPECT_EQ(allocations, 0);
  // What the run went through (the count above would be empty words without it).
  EXPECT_EQ(stops, 2);
  EXPECT_EQ(overrides, 1);
  EXPECT_GE(acked[0], 30u);
  EXPECT_FALSE(port.messages.empty());
  EXPECT_GT(port.events.size(), 100u);
  EXPECT_EQ(e.counters().refused_requests, 0u);
  for (const ReplyOut& r : port.replies) {
    EXPECT_EQ(r.code, ReplyCode::kAccepted)
        << "request " << r.request_id << ": " << r.reason.view();
  }
  EXPECT_EQ(e.counters().segments, 3 * p.segments.size());
}

TEST(CycleThread, NeverAllocatesWhileProgramsStreamRunAndStop) { run_counted({}); }

// tgm-service --check-limits: the live limit checker runs in the cycle too (it words a
// message only for an excess, and this program has none).
TEST(CycleThread, NeverAllocatesWithTheLimitCheckerOn) {
  EngineOptions o;
  o.check_limits = true;
  run_counted(o);
}

}  // namespace
}  // namespace tgm::service
