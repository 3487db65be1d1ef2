// The cycle interpolator. Design: core/MOTION.md.
//
// Records live in a ring indexed by a 64-bit sequence number q (slot = q % capacity). Every
// record is planned when it is appended (geometry, speed caps, tangential acceleration / jerk
// limits, the speed limit of the junction at its start, next-smaller-element links). step() runs
// five calculation steps of the online jerk-limited path velocity generator; each one checks a
// bounded set of upcoming speed limits (the prefix-minimum chains) and the end of the look-ahead
// window, and chooses the highest end-of-step acceleration from which every one of them can still
// be met.
#include "tgm/interpolator.hpp"
#include "tgm/soft_limits.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <sys/mman.h>

#include "path_geometry.hpp"
#include "tgm/command_stage.hpp"
#include "tgm/jerk_profile.hpp"
#include "tgm/limit_checker.hpp"
#include "tgm/output_stage.hpp"
#include "tgm/printable.hpp"
#include "tgm/smoothing.hpp"

namespace tgm {

const char* limit_factor_name(LimitFactor f) {
  switch (f) {
    case LimitFactor::kNone: return "none";
    case LimitFactor::kFeed: return "feed";
    case LimitFactor::kAxisVelocity: return "axis_velocity";
    case LimitFactor::kAccelJerk: return "accel_jerk";
    case LimitFactor::kCorner: return "corner";
    case LimitFactor::kArc: return "arc";
    case LimitFactor::kLookAhead: return "lookahead";
    case LimitFactor::kStarvation: return "starvation";
    case LimitFactor::kOverride: return "override";
    case LimitFactor::kMStop: return "stop_point";
    case LimitFactor::kStopCommand: return "stop_command";
  }
  return "?";
}

namespace {

using motion::Geometry;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::uint64_t kNoQ = ~std::uint64_t{0};
constexpr double kPi = 3.14159265358979323846;
constexpr int kCalcSteps = 5;             // calculation steps per cycle (manual)
constexpr int kChainMax = 24;             // constraints followed per chain and step
constexpr int kMaxExtendPerStep = 64;     // records scanned for the limits of one calculation step
constexpr int kMaxDecelLimits = 8;        // deceleration limits ahead checked per calculation step
constexpr double kExcessTol = 1e-12;      // [mm] a braking plan longer than its room by this fails
constexpr int kMaxExtendPerCycle = 320;   // records added to the look-ahead window per cycle
constexpr std::uint64_t kMaxSkipCycles = 1'000'000;  // per advance() call (bounds its work)
constexpr std::uint64_t kStiffScan = 4;  // records stiff_stretch scans per speed limit, at most
constexpr double kStiffRatio = 4.0;  // stiff_stretch: lowest jerk before a soft record over its own
constexpr int kMaxCruiseBackoff = 4;  // skip_cruise: at most 2^4 - 1 cycles between failed proofs
constexpr std::size_t kMaxBlockReports = 2048;
constexpr std::size_t kMaxCornerEvents = 2048;
constexpr double kMinLength = 1e-9;       // shorter motions are executed as no-ops [mm]
constexpr double kArcSafety = 0.97;       // margin on the arc bounds (sum-of-terms, spiral)
constexpr double kChordFormRadius = 1000.0;  // arcs of this radius [mm] and more: chord form
// Every limit the planner derives from the axis limits uses 99.9 % of it: the discrete
// generator may overshoot a target by a few 1e-5 (landing on a speed, end-of-step rounding).
constexpr double kLimitSafety = 0.999;
constexpr double kStandstillV = 1e-7;     // [mm/s]
// Braking checks plan with slightly lower limits than the generator may use, so the discrete
// constant-jerk steps can always follow a planned (bang-bang) braking curve.
constexpr double kPlanMargin = 0.98;
// Jerk used by braking plans: 90 % of the limit, so a state that can take its deceleration
// back before standstill stays so when the path enters a record whose jerk limit is lower.
constexpr double kPlanMarginJ = 0.9;
// The floor itself uses a little more jerk than the plans, so a planned final ramp is strictly
// inside it (equal factors would make the two bounds meet and the discrete choice flip).
constexpr double kFloorMarginJ = 0.92;
// Records a release may cross before release_floor stops following it.
constexpr int kReleaseRecords = 64;
constexpr double kArriveD = 1e-9;         // [mm]
constexpr double kArriveV = 1e-3;         // [mm/s]
// A motion that comes to rest this close before its stop point has arrived there (the last
// calculation steps of a braking work at the resolution of the plans, ~1e-9 mm; creeping the
// rest in another cycle would show a standstill before the stop).
constexpr double kRestD = 1e-8;           // [mm]
// An arrival at a stop point still moving counts as a hard stop (a planning defect) above
// kArriveV and above this share of J dt^2, the scale of the speed change of one calculation
// step at the record's jerk limit J (J dt^2 / 2 from zero acceleration). Landing on a point
// with one jerk per step leaves a residual speed at that resolution: 0.2..2.4 % of J dt^2
// (0.001..0.006 mm/s, within every limit) on the stiff axes (1e6..1.4e7 mm/s^3) of the wide
// sweep at 1 ms cycles. On the default machine (J dt^2 about 3e-4 mm/s) kArriveV stays the
// threshold.
constexpr double kArriveStepShare = 1.0 / 16.0;

enum class RecKind : std::uint8_t { kMotion, kStop, kPass };

struct Link {
  std::uint64_t nse = kNoQ;
  double amin = kInf;
  double jmin = kInf;
};

// Planning data of one ring slot.
// The fields the per-step scans read (kind, s0, at, jt) share the first cache line; the
// geometry (over 300 bytes) comes last.
struct Rec {
  RecKind kind = RecKind::kPass;
  double s0 = 0.0;  // cumulative path position of the record's start [mm]
  double f = 0.0;   // feed cap [mm/s] (x Rel_Speed)
  double m = 0.0;   // machine cap [mm/s]
  LimitFactor m_reason = LimitFactor::kAxisVelocity;
  double at = 0.0, jt = 0.0;  // tangential acceleration / jerk limits
  double wg = kInf, wf = kInf;  // junction limits at s0: hard, feed (x Rel_Speed)
  LimitFactor wg_reason = LimitFactor::kNone;
  // Next-smaller-element links of the three chains (0: wg, 1: wf, 2: at) with the minimum
  // tangential acceleration / jerk over the records [this, nse): the limits a braking curve
  // from here to the linked record passes through.
  std::array<Link, 3> link{};
  std::int32_t msg_slot = -1;
  // XY tangent at the start [deg] (LookAheadBuffer; kNotSet: none), NaN until first asked for
  // (start_tangent_deg: an atan2 per record is a twentieth of an offline short-segment run,
  // and records crossed inside a skipped cruise never enter the table).
  double tan0_deg = std::numeric_limits<double>::quiet_NaN();
  Geometry g;
};

// madvise(advice) on the whole `block`-aligned blocks inside [p, p + bytes) (block: a power
// of two). A hint: a failure (an advice the kernel does not know) changes nothing.
void advise_inside(void* p, std::size_t bytes, std::uintptr_t block, int advice) {
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t lo = (a + block - 1) & ~(block - 1);
  const std::uintptr_t hi = (a + bytes) & ~(block - 1);
  if (hi > lo) (void)::madvise(reinterpret_cast<void*>(lo), hi - lo, advice);
}

// Asks the kernel for transparent huge pages on the 2 MB-aligned part of [p, p + bytes): a
// hint that may be ignored. The rings of a 10,000-record buffer are 6.3 MB; written first as
// a program loads, they took 1,500 page faults of 4 kB, which on this VM cost more than the
// motion of a one-lap short-segment circle (with ev_par below: `tgm-hmi simulate` of that
// circle 121..131 -> 219..243 x real time, session 83; tests/bench/BENCHMARKS.md).
// tgm-service writes its rings at create (preallocate_ring), not in the cycle.
void advise_huge_pages(void* p, std::size_t bytes) {
#ifdef MADV_HUGEPAGE
  advise_inside(p, bytes, std::uintptr_t{2} << 20, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

// Maps the whole pages inside [p, p + bytes) in one call, before they are first written. Page
// by page, the first writes of the record rings (6.3 MB at 10,000 records) cost a trap each,
// about 10 us on this project's VMs (the huge pages above are seldom granted there):
// `tgm-hmi simulate` of the ten-lap short-segment circle runs about 15 % faster with the
// rings mapped this way (tests/bench/BENCHMARKS.md, session 87). The data is not touched.
// Without MADV_POPULATE_WRITE (Linux 5.14) the pages fault in as before.
void prefault(void* p, std::size_t bytes) {
#ifdef MADV_POPULATE_WRITE
  advise_inside(p, bytes, 4096, MADV_POPULATE_WRITE);
#else
  (void)p;
  (void)bytes;
#endif
}

// An allocator whose vector(n) leaves trivial elements uninitialised: the deques below are
// sized for the whole ring at create but only written as records enter them, and a large
// allocation that is never written costs no pages (a one-shot `tgm-hmi simulate` of a short
// program used to write their 0.9 MB first). Copies still copy every element.
template <typename T>
struct UninitAllocator {
  using value_type = T;
  UninitAllocator() = default;
  template <typename U>
  explicit UninitAllocator(const UninitAllocator<U>&) {}
  T* allocate(std::size_t count) { return std::allocator<T>{}.allocate(count); }
  void deallocate(T* p, std::size_t count) { std::allocator<T>{}.deallocate(p, count); }
  template <typename U>
  void construct(U* p) {
    ::new (static_cast<void*>(p)) U;  // default-initialised: nothing written
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  bool operator==(const UninitAllocator&) const { return true; }
};

// Fixed-capacity deque of sequence numbers (no allocation after init; an entry is read only
// after it was written).
class QDeque {
 public:
  void init(std::size_t cap) {
    buf_ = std::vector<std::uint64_t, UninitAllocator<std::uint64_t>>(cap);
    clear();
  }
  void clear() {
    head_ = 0;
    size_ = 0;
  }
  bool empty() const { return size_ == 0; }
  std::uint64_t front() const { return buf_[head_]; }
  std::uint64_t back() const { return buf_[idx(size_ - 1)]; }
  void push_back(std::uint64_t q) {
    if (size_ == buf_.size()) pop_front();  // cannot happen with cap >= ring size; stay safe
    buf_[idx(size_)] = q;
    ++size_;
  }
  void pop_back() { --size_; }
  void pop_front() {
    head_ = idx(1);
    --size_;
  }

 private:
  std::size_t idx(std::size_t k) const {
    std::size_t i = head_ + k;
    return i >= buf_.size() ? i - buf_.size() : i;
  }
  std::vector<std::uint64_t, UninitAllocator<std::uint64_t>> buf_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

// Sliding-window minimum of one field over records (a monotone deque of (record, value) with the
// values increasing from front to back; no allocation after init). The values are copied in:
// a record's limits do not change once it is stored, and the pushes compare without reading
// the ring.
class MinWindow {
 public:
  void init(std::size_t cap) {
    buf_ = std::vector<Entry, UninitAllocator<Entry>>(cap);
    clear();
  }
  void clear() {
    head_ = 0;
    size_ = 0;
  }
  bool empty() const { return size_ == 0; }
  std::uint64_t front() const { return buf_[head_].q; }
  //! The window's minimum (the front's value).
  double min() const { return buf_[head_].v; }
  void push(std::uint64_t q, double v) {
    while (size_ > 0 && buf_[idx(size_ - 1)].v >= v) --size_;
    if (size_ == buf_.size()) pop_front();  // cannot happen with cap >= ring size; stay safe
    buf_[idx(size_)] = Entry{q, v};
    ++size_;
  }
  void pop_front() {
    head_ = idx(1);
    --size_;
  }

 private:
  struct Entry {  // trivial: left unwritten until pushed (UninitAllocator)
    std::uint64_t q;
    double v;
  };
  std::size_t idx(std::size_t k) const {
    std::size_t i = head_ + k;
    return i >= buf_.size() ? i - buf_.size() : i;
  }
  std::vector<Entry, UninitAllocator<Entry>> buf_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

enum class Mode : std::uint8_t { kIdle, kMoving, kStopping, kEmergency, kWaitM, kDwell };

// Kinds of the events that leave the smoothing with the motion (SmoothingEvent::kind).
constexpr std::int32_t kEvNormalM = 1;
constexpr std::int32_t kEvContinuousM = 2;
constexpr std::int32_t kEvMessage = 3;

// One limit ahead at distance d [mm]: the path velocity must be at most w [mm/s] there
// (accel = false), or |a| at most w [mm/s^2] (accel = true); A and J are the tangential limits of
// the records before it (what a braking curve to it may use).
struct Constraint {
  double d;
  double w;
  double A;
  double J;
  LimitFactor reason;
  bool accel;
  //! The programmed feed x Rel_Speed (not a machine limit): after an override decrease it may be
  //! crossed faster rather than exceeding an acceleration limit.
  bool soft = false;
  //! Speed limits: the lowest jerk limit of the records after the limit up to the next smaller
  //! one of its chain. A speed limit may be crossed still accelerating (v + a^2/2J <= w); the
  //! acceleration is then taken back after the junction, at this jerk. The chain hides the
  //! larger limits in that range because this ramp keeps them; with a lower jerk there than
  //! before the junction it would overshoot them (TGM_SEED=6 program 835, a corner step).
  //! Deceleration limits (decel_limits): the jerk limit of the record entered, when lower than
  //! J (kInf otherwise); dec_room then keeps a step's reach of room before the junction.
  double Jx = kInf;
  //! How much farther than a stopping distance (with the window's limits) the limit can still
  //! bind: landing on w > 0 with zero acceleration can take longer than stopping, by less than
  //! w times the final jerk phase (A/J); twice that as margin. Set by gather().
  double beyond_stop = 0.0;
  //! Cumulative path position up to which no end-of-step state of this cycle fails this limit:
  //! d minus its braking distance (or acceleration change) from the cycle's fastest state, which
  //! bounds those from every state the cycle's calculation steps evaluate (cycle_bound).
  //! -infinity until the scan first needs it.
  double safe = -kInf;
  //! Speed limits at a junction into a record of lower jerk: the braking must be complete this
  //! far [mm] before it (two calculation steps, junction_reserve), and the speed stays within w
  //! from there on.
  //! The calculation step that can reach the junction already has that record's jerk limit, and
  //! the deceleration it carries in cannot be taken back there before the motion stops.
  double reserve = 0.0;
  //! Deceleration limits: the hard speed limit at the same junction (the record's wg). Braking
  //! to it from above ends with the deceleration taken back, which keeps this limit too
  //! (dec_kept).
  double junction_v = kInf;
  //! The lowest jerk limit before the junction of junction_v: the jerk of the braking to it.
  double junction_j = kInf;
  //! Speed limits behind a record far softer than every record before it (stiff_stretch): the
  //! start of that record [mm], the lowest jerk limit before it, the speed w2 >= w from which
  //! the limit's own plan (at J, from zero acceleration) keeps it within that record, and the
  //! reserve of the record's junction. Until the motion reaches d2 the limit is planned as
  //! (w2, 0) at d2 at J2, from there on as itself. d2 = kInf when there is no such record.
  double d2 = kInf;
  double J2 = kInf;
  double w2 = kInf;
  double reserve2 = 0.0;
};

// Path travelled in time t from speed v and acceleration a at constant jerk j.
double travel(double v, double a, double j, double t) {
  return t * (v + t * (0.5 * a + t * j / 6.0));
}
// Speed after time t from speed v and acceleration a at constant jerk j.
double speed_after(double v, double a, double j, double t) {
  return v + t * (a + 0.5 * j * t);
}

double norm_angle_deg(double rad) {
  double d = rad * 180.0 / kPi;
  d = std::fmod(d, 360.0);
  if (d < 0.0) d += 360.0;
  return d;
}

}  // namespace

struct Interpolator::Impl {
  // ---- configuration ----
  InterpolatorConfig cfg;
  bool soft_limits = false;  // some axis of cfg has one (tgm/soft_limits.hpp)
  InterpolatorOptions opt;
  int number = 0;
  int n = 0;               // axes
  std::size_t cap = 0;     // ring capacity
  double T = 0.0;          // cycle [s]
  double dt = 0.0;         // calculation step [s]
  double quarter_dt2 = 0.0;  // dt^2 / 4: the quantised jerk allowance per unit of peak deceleration
  // Share of that allowance plan_braking adds: 1, or less while a calculation step rides a
  // limit it could not keep with all of it (spend_allowance).
  double allowance = 1.0;
  std::array<double, kMaxAxes> vmax{}, amax{}, jmax{}, rapid{}, tol{};
  std::array<double, kMaxAxes> tol_a{};  // acceleration step accepted at a junction [mm/s^2]
  double rho = 1.0;        // emergency / normal deceleration ratio (min over axes, >= 1)
  // The axes of G17, G18, G19 by the axes' letters (plane_axes), and those of X and Y, whose
  // tangent the LookAheadBuffer shows (kMaxAxes: the letter is not configured).
  std::array<PlaneAxes, 3> planes{};
  int x_axis = kMaxAxes, y_axis = kMaxAxes;
  static std::size_t plane_slot(Plane p) { return p == Plane::kXZ ? 1 : p == Plane::kYZ ? 2 : 0; }
  const PlaneAxes& plane(Plane p) const { return planes[plane_slot(p)]; }

  // ---- ring ----
  // The slot arrays hold `cap` slots when full. They are reserved at create() and grow as
  // records are stored (grow_rings): writing all of them there (8.5 MB for the default 10,000
  // slots) took 2 ms of a 5 ms offline run of the manual's example, in page faults mostly.
  // `par` (M parameters, read for M records only) grows only as far as an M record is stored.
  std::vector<Segment> seg;
  std::vector<Rec> rec;
  std::vector<MParams> par;
  std::vector<std::string> msg;
  std::vector<std::int32_t> msg_line;  // source line of each message slot's M29
  std::size_t msg_next = 0;
  // The slot of each message that came out, by Registers::message_count (mod the ring): a
  // reader once a cycle takes every one of several that came out in the cycle (it took the
  // last, and M29 lines in a row lost all but one: session 75).
  std::array<std::int32_t, kMessageRing> msg_by_count{};
  std::uint64_t tail = 0;     // next q to write
  std::uint64_t cur = 0;      // record being executed (== tail: none)
  std::uint64_t base = 0;     // q of the program's first record (Act_Part = q - base + 1)
  std::uint64_t win_end = 0;  // first record not in the look-ahead window
  bool complete = false;
  MinWindow dq_a, dq_j, dq_wg, dq_wf;
  QDeque st_g, st_f, st_a;

  // ---- planning tail (where the next appended motion starts) ----
  std::array<double, kMaxAxes> pt_end{};
  std::array<double, kMaxAxes> pt_tangent{};
  std::array<double, kMaxAxes> pt_curvature{};  // d^2x/ds^2 at the end of the last motion
  bool pt_have_motion = false;
  bool pt_stop_since = true;
  double pt_f = 0.0, pt_m = 0.0, pt_length = 0.0;
  LimitFactor pt_m_reason = LimitFactor::kAxisVelocity;
  double s_tail = 0.0;
  // The last junctions of the run of motion being planned, for chord_turn_limit: the tangent
  // into each, per axis, and its path position. A ring, newest at jh_head, written twice (at
  // e and e + kTurnHistory) so that the last kTurnHistory lie in one run of memory.
  static constexpr int kTurnHistory = 16;
  std::array<std::array<double, 2 * kTurnHistory>, kMaxAxes> jh_tin{};
  std::array<double, 2 * kTurnHistory> jh_s{};
  int jh_head = 0;
  int jh_count = 0;
  double turn_w = 0.0, inv_turn_w = 0.0;  // the limit checker's mean-acceleration window [s]
  // 2 / A_i, 2 / J_i: the chord-turn share (half of each limit) inverted.
  std::array<double, kMaxAxes> inv_half_a{}, inv_half_j{};
  // A bound on every window's turn at a junction (turn_bound).
  struct TurnBound {
    std::array<double, kMaxAxes> d{};     // per axis: |Delta_i| <= d_i in every window
    double qr = 0.0, qj = 0.0, t2 = 0.0;  // max_i 2 d_i / A_i, max_i 2 d_i / J_i, sum_i d_i^2
  };

  // ---- execution ----
  Mode mode = Mode::kIdle;
  bool on_path = false;  // `cur` is a motion record and the position is on it
  jerk::State st;        // s local to the current motion record
  std::array<double, kMaxAxes> rest{};
  double rel = 1.0;
  std::int64_t dwell_left = 0;
  // Calculation steps until a motion may start after coming to rest: 2 in the step of the
  // arrival (or of a stop ramp's end), 1 in the step after it, where a motion that starts
  // stands instead (calc_step), 0 from then on.
  int rest_phase = 0;
  bool wait_m_first = false;
  bool paused_m0 = false;
  bool resume_wait_m = false;
  // A stop during a dwell (Command 8 / 4) keeps dwell_left: start dwells the rest.
  bool resume_dwell = false;
  bool stop_off = false;       // Command 9 / 5 in progress
  bool resumable_estop = false;
  std::uint64_t hard_stop_count = 0;
  std::uint64_t position_set_count = 0;  // place() calls (Interpolator::position_sets)
  LimitFactor factor = LimitFactor::kNone;
  bool braking_to_stop = false;
  double last_vt = 0.0;
  double cycle_start_v = 0.0;  // st.v when the last cycle began (Run_Flag: did the speed fall?)
  bool lookahead_dirty = true;
  // Limits ahead, gathered once per cycle (distances from cons_here, cumulative path).
  std::array<Constraint, 3 * kChainMax + 4> cons{};
  int ncons = 0;
  double cons_here = 0.0;
  double cons_Aw = 0.0, cons_Jw = 0.0;
  // The fastest state (velocity, acceleration) an end of a calculation step can reach in the
  // rest of the cycle the constraints were gathered in (Constraint::safe).
  double cons_vc = 0.0, cons_ac = 0.0;
  bool cons_bounds = false;  // gathered before the cycle's last step: later steps use the bounds
  bool cons_valid = false;
  double horizon = 0.0;
  // Cruise shortcut: at constant speed the smallest slack over the gathered limits only
  // shrinks by the distance travelled, so it is computed once per gather.
  bool cruise_valid = false;
  double cruise_v = 0.0;
  double cruise_margin = 0.0;
  std::uint64_t lookahead_cur = kNoQ;
  // Record of each LookAheadBuffer entry, and whether the last fill found all kLookAheadEntries
  // (then records appended later cannot change the table, and a move of `cur` only shifts it).
  std::array<std::uint64_t, kLookAheadEntries> lookahead_q{};
  bool lookahead_full = false;
  bool lookahead_appended = false;  // records appended since the last fill
  // Jerk of the last calculation step when it rode a braking limit (largest_passing), else kInf:
  // the next step's first guess.
  double ride_jerk = kInf;
  // The limit that step rode (path position and value): when it is violated again, the root
  // finder starts with it (in a steady ride the same limit binds, not always the one that
  // fails worst at the wanted x).
  double ride_pos = 0.0, ride_w = 0.0;

  // block statistics of the current motion
  double blk_peak = 0.0;
  LimitFactor blk_factor = LimitFactor::kNone;
  double blk_t0 = 0.0;
  double time_s = 0.0;  // time at the start of the current calculation step

  Registers reg;
  std::vector<CornerEvent> events;
  std::size_t n_events = 0;
  std::vector<BlockReport> blocks;
  std::vector<CycleTrace> trace;  // cycles of the last advance() (record_cycle_trace)
  std::size_t n_blocks = 0;

  // ---- smoothing and output (core/SMOOTHING.md, "Wiring") ----
  std::optional<SmoothingStage> smooth;
  std::optional<OutputStage> ostage;
  bool m_pending = false;    // a normal M is inside the spline: the wait starts when it leaves
  // The last M-function dropped unacknowledged with its program: its count and number.
  std::uint32_t dropped_m_count = 0;
  std::int32_t dropped_m = 0;
  // The Status the motion has come to (3 ended, 4 stopped / M0, 7 emergency-stopped, 8 underrun),
  // reported once every axis, delayed or filtered, stands (0: none waits). Meanwhile Status
  // still shows the motion (1, or 6 after an emergency stop).
  std::int32_t settle_status = 0;
  // M parameters of the events in flight, inside the smoothing and waiting in m_deferred (the
  // ring slot may be reused meanwhile).
  static constexpr std::size_t kMaxDeferredM = 64;
  // On the heap, sized at create and left unwritten until events arrive (UninitAllocator): as
  // arrays in Impl they were 0.9 MB that create value-initialised, page by page, for every
  // Interpolator (a third of the 6 ms a one-line `tgm-hmi simulate` took, session 83). A slot
  // is read only by the tag of an event that wrote it.
  static constexpr std::size_t kEventSlots = SmoothingStage::kEventCapacity + kMaxDeferredM + 1;
  std::vector<MParams, UninitAllocator<MParams>> ev_par;
  std::size_t ev_par_next = 0;
  std::vector<std::int32_t, UninitAllocator<std::int32_t>> ev_line;  // by tag
  // At most one M-function reaches M_Func per cycle: a PLC reading the registers once a cycle
  // sees each of two M records with nothing between them (they would otherwise leave the
  // smoothing in the same calculation step, the second overwriting the first). The later ones
  // wait here, in order, and are handed over one per cycle at the cycle's start (beyond
  // kMaxDeferredM in a row, the oldest waiting ones reach M_Func in the same cycle, still in
  // program order: core/MOTION.md).
  bool m_announced = false;  // an M-function reached M_Func in this cycle
  std::array<SmoothingEvent, kMaxDeferredM> m_deferred{};
  int m_deferred_n = 0;
  // Command accepted and waiting for the smoothing (Command_Status 1); 0 = none.
  std::int32_t pend_code = 0;
  // Commands accepted at Command_Status 1 that ended without being executed, and why.
  std::uint64_t unexecuted = 0;
  std::uint64_t early_events = 0;  // events a full smoothing queue released before their sample
  std::string unexecuted_reason;
  std::array<std::int32_t, kCommandParameters> pend_par{};
  std::string cmd_error;
  // skip_cruise: record and path position one calculation step before the end
  std::uint64_t cruise_prev_q = 0;
  double cruise_prev_s = 0.0;
  // skip_cruise: after `cruise_fails` proofs in a row that failed, the next is tried from cycle
  // `cruise_retry` on (2^fails - 1 cycles later, at most kMaxCruiseBackoff).
  std::uint64_t cruise_retry = 0;
  int cruise_fails = 0;

  std::size_t ring_index(std::uint64_t q) const { return static_cast<std::size_t>(q % cap); }
  // Slots [0, k) exist, default records as create() used to make them. Slots fill from 0 up
  // (q counts on from 0 and wraps only at cap), and every slot the code reads, the one at
  // `tail` included, lies below the slot of the last record stored plus kRingHeadroom.
  static constexpr std::size_t kRingHeadroom = 64;
  std::size_t slots_used = 0;  // slots [0, slots_used) have held a record
  void grow_rings(std::size_t k) {
    k = std::min(cap, std::max(k + kRingHeadroom, 2 * rec.size()));
    // create() reserves cap slots (a copy_state_from assigns into them), so the new slots'
    // pages are part of the allocation, and resize writes every one of them next. The checks
    // keep the call inside the allocation should a ring ever hold less.
    if (k <= seg.capacity()) prefault(seg.data() + seg.size(), (k - seg.size()) * sizeof(Segment));
    if (k <= rec.capacity()) prefault(rec.data() + rec.size(), (k - rec.size()) * sizeof(Rec));
    seg.resize(k);
    rec.resize(k);
  }
  Rec& R(std::uint64_t q) { return rec[ring_index(q)]; }
  const Rec& R(std::uint64_t q) const { return rec[ring_index(q)]; }
  Segment& S(std::uint64_t q) { return seg[ring_index(q)]; }
  const Segment& S(std::uint64_t q) const { return seg[ring_index(q)]; }
  // Path position where record q starts (the end of the buffered path for q == tail).
  double start_of(std::uint64_t q) const { return q < tail ? R(q).s0 : s_tail; }

  // ================= planning =================

  double corner_limit(const std::array<double, kMaxAxes>& tin,
                      const std::array<double, kMaxAxes>& tout) const {
    double c = kInf;
    for (int i = 0; i < n; ++i) {
      const double d = std::fabs(tout[i] - tin[i]);
      if (d > 1e-12) c = std::min(c, kLimitSafety * tol[i] / d);
    }
    return c;
  }

  // Speed limit at the junction into a record of geometry g from the curvature step there.
  // Crossed at v, axis i's acceleration steps by v^2 (k_out,i - k_in,i) (k: d^2x/ds^2; an arc's
  // centripetal acceleration starts or ends, or turns the other way), in no time: a jerk the
  // per-cycle limit checker, which takes out the steps at junctions, does not see. Held to the
  // axis' corner acceleration tolerance as the velocity step is to the corner velocity
  // tolerance. Without it a dense CAM program (tgm_gen_cam_program --lines 3000 --seed 7)
  // entered arcs from arcs of the other turn at up to 3.7 x the tolerance (X stepping by
  // 1,277 mm/s^2 within a cycle, which its jerk limit takes 43 ms to build). The tangential part of
  // the step (an acceleration along the path turned with it at a corner) is not planned: a corner
  // crossed at its limit speed is crossed near the end of its braking (core/MOTION.md, Planner).
  double curvature_step_limit(const Geometry& g) const {
    double k0[kMaxAxes];
    motion::geometry_curvature(g, n, 0.0, k0);
    double w = kInf;
    for (int i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const double dk = std::fabs(k0[i] - pt_curvature[u]);
      if (dk > 0.0) w = std::min(w, kLimitSafety * std::sqrt(tol_a[u] / dk));
    }
    return w;
  }

  // A run of short chords turns the path as an arc does, but in steps the corner tolerance
  // accepts one by one: at 200 mm/s, 0.05 mm chords of a circle of 10 mm radius each step
  // X and Y by 1 mm/s, within a 2 mm/s tolerance, 4,000 times a second, and the drives saw
  // 4,000 mm/s^2 against a limit of 1,500 (review of session 82). What adds up is the
  // velocity change over a window of time, the limit checker's mean acceleration: the steps
  // a window W of it covers at speed v are those of the junctions within v W of path, and
  // the run's tangent turns by Delta (the tangent after the last minus the one into the
  // first) across them. Steps that alternate, as the chords of coordinates rounded to 1 um
  // do (0.02 rad each on 0.05 mm chords, twenty times the turn of a circle of 50 mm), cancel
  // there; a turn that keeps its sign adds up (session 84). Held to the share of an arc's
  // centripetal terms (half of each limit, with the arc margin):
  //   - a window of m >= 2 junctions, D of path from the first to the last, binds from v =
  //     D / W on: v |Delta_i| <= A_i W / 2 (one junction alone is the tolerance's);
  //   - below that speed, at its mean curvature as an arc's rate: v^2 |Delta_i| / (D + l)
  //     <= A_i / 2. W does not cover its path at the junction's speed, but the motion
  //     between two junctions may run faster than at either and cover it (a wide sweep's
  //     soft axis took two steps of a 0.015 mm polyline in one window at 1.45 mm/s);
  //   - the curvature over a window, kappa = |Delta| / (D + l), bounds the jerk as an
  //     arc's, v^3 kappa_i kappa <= J_i / 2, at the speeds where it is the widest window
  //     within v W (with m = 1 and D = 0 this is the one junction's |dt| / l);
  //   - beyond the kTurnHistory junctions kept, the widest window's turn is extrapolated at
  //     its rate: v^2 |Delta_i| / (D + l) <= A_i / 2.
  // Scanned from the shortest window: the limit is the speed where one first binds. `w` is
  // the junction's limit from everything else; windows that fit only above it are not read
  // (this runs once per record stored, one per cycle on short chords). The junction at
  // s_tail with tangent `t0` after it must be in the history (note_junction).
  double chord_turn_limit(const TurnBound& tb, const std::array<double, kMaxAxes>& t0, double l,
                          double w) const {
    const double wm = w * (1.0 / kArcSafety);  // the raw limit at which it equals w
    if (!opt.full_turn_scan && turn_is_slack(tb, l, wm)) return w;
    // The windows m = 1..mm start below wm; window m's first junction is at b + 1 - m.
    const std::size_t b = newest_junction();
    const int mm = windows_within(wm * turn_w, /*strict=*/true);
    // Per window of the history, by slot x = kTurnHistory - m (oldest first; the slots below
    // the history's hold an earlier run's tangents, computed along and not read): qr = max_i
    // 2 |Delta_i| / A_i, qj = max_i 2 |Delta_i| / J_i, t2 = |Delta|^2, axis by axis over all
    // the slots (a fixed count: it vectorises without a remainder), then rr = qr / (D + l),
    // the inverse square of the window's rate limit. The first axis sets the arrays, the others
    // fold into them: three fill(0.0) and one loop over all axes ran 1.1 % more instructions on
    // the short-segment benchmark (callgrind, session 86).
    constexpr std::size_t kH = kTurnHistory;
    const std::size_t eh = b + 1 - kH;                               // slot 0's junction
    const std::size_t xh = kH - static_cast<std::size_t>(jh_count);  // the oldest window's slot
    std::array<double, kH> qr, qj, t2, rr;
    {
      const double* tin = jh_tin[0].data() + eh;
      const double ti = t0[0], ca = inv_half_a[0], cj = inv_half_j[0];
      for (std::size_t x = 0; x < kH; ++x) {
        const double d = ti - tin[x];
        const double ad = std::fabs(d);
        qr[x] = ad * ca;
        qj[x] = ad * cj;
        t2[x] = d * d;
      }
    }
    for (int i = 1; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const double* tin = jh_tin[u].data() + eh;
      const double ti = t0[u], ca = inv_half_a[u], cj = inv_half_j[u];
      for (std::size_t x = 0; x < kH; ++x) {
        const double d = ti - tin[x];
        const double ad = std::fabs(d);
        qr[x] = std::max(qr[x], ad * ca);
        qj[x] = std::max(qj[x], ad * cj);
        t2[x] += d * d;
      }
    }
    for (std::size_t x = xh; x < kH; ++x) rr[x] = qr[x] / (s_tail - jh_s[eh + x] + l);
    // rs[x]: max of rr over the windows wider than slot x's (m' > m), those that W does not
    // cover at the speeds of window m's region: the rate of their mean curvature binds there.
    std::array<double, kH> rs;
    double wider = 0.0;
    for (std::size_t x = xh; x < kH; ++x) {
      rs[x] = wider;
      wider = std::max(wider, rr[x]);
    }
    const std::size_t x_mm = kH - static_cast<std::size_t>(mm);  // the widest window's slot
    double inv_a = 0.0;  // max over windows m >= 2 so far of 2 |Delta_i| / (A_i W)
    int m0 = 1;          // the first window the scan below reads
    if (mm >= 3) {
      // Mostly nothing binds in the windows before the widest below w: their speeds lie
      // below its lo (D_mm / W < wm), and with that bound for all of them at once (maxima
      // over the windows) the scan starts at the widest.
      const double lo_mm = (s_tail - jh_s[eh + x_mm]) * inv_turn_w;
      double a_before = 0.0, g = 0.0;  // max qr of m = 2..mm-1; max of jd^2 |Delta|^2 / span^4
      for (std::size_t x = x_mm + 1; x < kH; ++x) {
        const double span = s_tail - jh_s[eh + x] + l, span2 = span * span;
        g = std::max(g, qj[x] * qj[x] * t2[x] / (span2 * span2));
        if (x + 1 < kH) a_before = std::max(a_before, qr[x]);
      }
      a_before *= inv_turn_w;
      const double lo3 = lo_mm * lo_mm * lo_mm;
      if (a_before * lo_mm <= 1.0 && g * lo3 * lo3 <= 1.0 && rs[kH - 1] * lo_mm * lo_mm <= 1.0) {
        inv_a = a_before;
        m0 = mm;
      }
    }
    for (int m = m0; m <= mm; ++m) {
      const std::size_t x = kH - static_cast<std::size_t>(m);  // window m's slot
      const std::size_t e = eh + x;
      if (m >= 2) inv_a = std::max(inv_a, qr[x] * inv_turn_w);
      const bool last = m == jh_count;
      const double hi = last ? kInf : (s_tail - jh_s[e - 1]) * inv_turn_w;
      const double top = std::min(hi, wm);  // the window's speeds below w
      const double span = s_tail - jh_s[e] + l, span2 = span * span;
      // Compared with the top without a root first: 1 / the jerk's limit cubed is jd |Delta|
      // / span^2, 1 / the rate's squared rd.
      const double jd = qj[x], turn2 = t2[x], jt = jd * top * top * top;
      const bool jerk_binds = jt * jt * turn2 > span2 * span2;
      // The wider windows' rates; beyond the history, this one's extrapolated.
      const double rd = last && jh_count == kTurnHistory ? std::max(rs[x], rr[x]) : rs[x];
      const bool rate_binds = rd * top * top > 1.0;
      if (inv_a * top > 1.0 || jerk_binds || rate_binds) {
        // A term that does not bind below the top does not lower the limit (it is below it).
        double f = inv_a * top > 1.0 ? 1.0 / inv_a : kInf;
        if (jerk_binds) f = std::min(f, std::cbrt(span2 / (jd * std::sqrt(turn2))));
        if (rate_binds) f = std::min(f, 1.0 / std::sqrt(rd));
        return std::min(w, kArcSafety * std::max((s_tail - jh_s[e]) * inv_turn_w, f));
      }
      if (hi >= wm) break;  // nothing binds below w
    }
    return w;
  }

  // The turn at a line's start junction, taken as chord_turn_limit takes it, needs of each
  // axis' acceleration at the junction's speed limit wg: wg |Delta_i| / W for the windows
  // within wg W, and wg^2 |Delta_i| / (D + l) for the wider ones (and for the widest kept,
  // when all fit: the rate beyond the history). The line's tangential limit leaves that room,
  // as an arc's leaves room for its centripetal terms. Along a run of chords turning at half
  // of each limit the two could add up to 1.35 x A (a diagonal chord at its tangential limit,
  // the turn's half across it); a lone corner is crossed at the tolerance's speed, where the
  // turn needs nothing. Only the start junction is known when the line is stored; in a run
  // every junction starts a line.
  void leave_room_for_the_turn(const TurnBound& tb, const std::array<double, kMaxAxes>& t0,
                               double l, Rec& r) const {
    if (jh_count < 2) return;
    const double v = r.wg;
    // Windows m = 2..mw fit within v W, mw + 1..jh_count do not.
    const std::size_t b = newest_junction();
    const int mw = windows_within(v * turn_w, /*strict=*/false);
    const std::size_t e_old = b + 1 - static_cast<std::size_t>(jh_count);
    const std::size_t e_fit = b + 1 - static_cast<std::size_t>(mw);  // oldest fitting
    const bool extrapolate = mw == kTurnHistory;
    const double rate_k = extrapolate ? v * v / (s_tail - jh_s[e_fit] + l) : 0.0;
    // The largest v^2 / (D + l) of the windows that do not fit: the newest of them's.
    const double span_k = e_fit > e_old ? v * v / (s_tail - jh_s[e_fit - 1] + l) : 0.0;
    std::array<double, kTurnHistory> inv_span;  // v^2 / (D + l) of the windows that do not fit
    bool have_inv_span = false;
    double at = r.at;
    for (int i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const double du = std::fabs(r.g.dir[i]);
      if (du < 1e-12) continue;
      if (!opt.full_turn_scan) {
        // The need with the axis' turn bound for every window's: an axis it leaves room for is
        // left as it is (TurnBound).
        const double d = tb.d[u];
        const double need = std::max({v * d * inv_turn_w, rate_k * d, span_k * d});
        if (kLimitSafety * (amax[i] - need) >= at * du) continue;
      }
      if (!have_inv_span) {
        for (std::size_t e = e_old; e < e_fit; ++e)
          inv_span[e - e_old] = v * v / (s_tail - jh_s[e] + l);
        have_inv_span = true;
      }
      const double* tin = jh_tin[u].data();
      double turn = 0.0;  // the largest |Delta_i| of the fitting windows
      for (std::size_t e = e_fit; e < b; ++e) turn = std::max(turn, std::fabs(t0[u] - tin[e]));
      double need = std::max(v * turn * inv_turn_w, rate_k * std::fabs(t0[u] - tin[e_fit]));
      for (std::size_t e = e_old; e < e_fit; ++e) {
        need = std::max(need, inv_span[e - e_old] * std::fabs(t0[u] - tin[e]));
      }
      // (A_i - need_i) / u below `at`, compared without the division first.
      const double room = kLimitSafety * (amax[i] - need);
      if (room < at * du) at = room / du;
    }
    r.at = std::max(at, 1e-6);
  }

  // Index of the newest junction in the history; the m-th newest is at newest - (m - 1),
  // for m <= jh_count.
  std::size_t newest_junction() const { return static_cast<std::size_t>(jh_head + kTurnHistory); }
  // The windows m = 1..(the result) of the history: those whose first junction lies less than
  // (`strict`) or at most `reach` of path before s_tail; m = 1, the newest junction alone, is
  // always one.
  int windows_within(double reach, bool strict) const {
    const std::size_t b = newest_junction();
    int m = 1;
    if (strict) {
      while (m < jh_count && s_tail - jh_s[b - static_cast<std::size_t>(m)] < reach) ++m;
    } else {
      while (m < jh_count && s_tail - jh_s[b - static_cast<std::size_t>(m)] <= reach) ++m;
    }
    return m;
  }

  // A bound on the turn of every window of the history, per axis the largest |t0_i - tin_i|
  // over the kTurnHistory slots that end at the newest junction (slots older than the run hold
  // an earlier run's tangents, which only widen it). Floating point rounds monotonically, so a
  // term that chord_turn_limit or leave_room_for_the_turn computes from a window's turn is at
  // most the same expression of the bound: where the bound shows that nothing binds, the scans
  // would find the same, and they are skipped with the results bit for bit the same
  // (InterpolatorOptions::full_turn_scan scans always, for the test that compares). On the
  // exact circle of issue 3 it skips 38 % of chord_turn_limit's scans, about 1,400
  // instructions each, and every exact need of leave_room_for_the_turn (session 85).
  TurnBound turn_bound(const std::array<double, kMaxAxes>& t0) const {
    TurnBound tb;
    const std::size_t eh = newest_junction() + 1 - kTurnHistory;
    for (int i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const double* tin = jh_tin[u].data() + eh;
      double lo = tin[0], hi = tin[0];
      for (std::size_t x = 1; x < kTurnHistory; ++x) {
        lo = std::min(lo, tin[x]);
        hi = std::max(hi, tin[x]);
      }
      const double d = std::max(t0[u] - lo, hi - t0[u]);
      tb.d[u] = d;
      tb.qr = std::max(tb.qr, d * inv_half_a[u]);
      tb.qj = std::max(tb.qj, d * inv_half_j[u]);
      tb.t2 += d * d;
    }
    return tb;
  }

  // True when the bound shows that chord_turn_limit's scan finds nothing binding below wm:
  // every term of every window of the history at the speeds the scan reads it at, with the
  // window's turn replaced by the bound (the windows past where the scan stops are read as
  // well, which only makes this the stricter).
  bool turn_is_slack(const TurnBound& tb, double l, double wm) const {
    constexpr std::size_t kH = kTurnHistory;
    const std::size_t eh = newest_junction() + 1 - kH;
    const std::size_t xh = kH - static_cast<std::size_t>(jh_count);  // the oldest window's slot
    const double qr = tb.qr, qj = tb.qj, t2 = tb.t2;
    if (jh_count >= 2 && qr * inv_turn_w * wm > 1.0) return false;
    {
      // The oldest window: read up to wm; beyond a full history, its rate extrapolated.
      const double span = s_tail - jh_s[eh + xh] + l, span2 = span * span;
      const double jt = qj * wm * wm * wm;
      if (jt * jt * t2 > span2 * span2) return false;
      if (jh_count == kH && qr / span * wm * wm > 1.0) return false;
    }
    // The others up to where the next wider one starts; the rates of the wider windows, whose
    // spans are at least the next wider one's.
    for (std::size_t x = xh + 1; x < kH; ++x) {
      const double d_wider = s_tail - jh_s[eh + x - 1];
      const double top = std::min(d_wider * inv_turn_w, wm);
      const double span = s_tail - jh_s[eh + x] + l, span2 = span * span;
      const double jt = qj * top * top * top;
      if (jt * jt * t2 > span2 * span2 || qr / (d_wider + l) * top * top > 1.0) return false;
    }
    return true;
  }

  // A junction of the run at s_tail, `tin` the tangent into it.
  void note_junction(const std::array<double, kMaxAxes>& tin) {
    jh_head = jh_head + 1 == kTurnHistory ? 0 : jh_head + 1;
    const auto e = static_cast<std::size_t>(jh_head);
    for (int i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      jh_tin[u][e] = jh_tin[u][e + kTurnHistory] = tin[u];
    }
    jh_s[e] = jh_s[e + kTurnHistory] = s_tail;
    jh_count = std::min(jh_count + 1, kTurnHistory);
  }

  // Geometry and caps of a motion record starting at `start`; false = not a motion (too short).
  // r is freshly value-initialised (store): its geometry is all zero.
  bool plan_motion(const Segment& sg, const std::array<double, kMaxAxes>& start, Rec& r) const {
    Geometry& g = r.g;
    g.start = start;
    for (int i = 0; i < n; ++i) g.end[i] = sg.end[i];
    if (!sg.is_arc()) {
      // From the sources, not from g just written (reading it back stalled the loads).
      double l2 = 0.0;
      for (int i = 0; i < n; ++i) l2 += (sg.end[i] - start[i]) * (sg.end[i] - start[i]);
      g.length = std::sqrt(l2);
      if (g.length < kMinLength) return false;
      double m = kInf, at = kInf, jt = kInf, fr = kInf;
      for (int i = 0; i < n; ++i) {
        g.dir[i] = (sg.end[i] - start[i]) / g.length;
        const double c = std::fabs(g.dir[i]);
        if (c < 1e-12) continue;
        m = std::min(m, vmax[i] / c);
        at = std::min(at, amax[i] / c);
        jt = std::min(jt, jmax[i] / c);
        fr = std::min(fr, rapid[i] / c);
      }
      r.f = sg.type == SegmentType::kRapid ? fr : sg.feed_mm_per_min / 60.0;
      r.m = kLimitSafety * m;
      r.m_reason = LimitFactor::kAxisVelocity;
      r.at = kLimitSafety * at;
      r.jt = kLimitSafety * jt;
      return true;
    }
    const PlaneAxes pa = plane(sg.plane);
    g.arc = true;
    g.first = pa.first;
    g.second = pa.second;
    g.cx = sg.center[0];
    g.cy = sg.center[1];
    const double sx = g.start[pa.first] - g.cx, sy = g.start[pa.second] - g.cy;
    const double ex = g.end[pa.first] - g.cx, ey = g.end[pa.second] - g.cy;
    const double r0 = std::hypot(sx, sy), r1 = std::hypot(ex, ey);
    g.r0 = r0;
    g.dr = r1 - r0;
    g.th0 = std::atan2(sy, sx);
    const double th1 = std::atan2(ey, ex);
    // End at the start: a full circle (the compiler's rule, an absolute 1e-9 mm; one relative
    // to the radius made a 0.5 mm arc of a radius of 1e9 mm a full circle of 6e9 mm).
    const bool full = std::hypot(ex - sx, ey - sy) < kFullCircleMm;
    g.chord_form = std::max(r0, r1) >= kChordFormRadius;
    double sweep;
    if (g.chord_form && !full) {
      // The angle between the two radii from their cross and dot products: exact to the last
      // bits for any sweep, where th1 - th0 keeps only 1e-16 rad, r0 x 1e-16 mm at the end.
      const double between = std::atan2(sx * ey - sy * ex, sx * ex + sy * ey);  // (-pi, pi]
      sweep = sg.type == SegmentType::kArcCcw ? between : -between;
      if (sweep <= 0.0) sweep += 2.0 * kPi;
    } else if (sg.type == SegmentType::kArcCcw) {
      sweep = full ? 2.0 * kPi : std::fmod(th1 - g.th0 + 4.0 * kPi, 2.0 * kPi);
      if (sweep <= 0.0) sweep += 2.0 * kPi;
    } else {
      sweep = full ? 2.0 * kPi : std::fmod(g.th0 - th1 + 4.0 * kPi, 2.0 * kPi);
      if (sweep <= 0.0) sweep += 2.0 * kPi;
    }
    sweep += 2.0 * kPi * std::max(0, sg.turns);
    g.phi = sg.type == SegmentType::kArcCcw ? sweep : -sweep;
    const double plane_len = sweep * 0.5 * (r0 + r1);
    double lin2 = 0.0;
    for (int i = 0; i < n; ++i) {
      if (i == pa.first || i == pa.second) continue;
      lin2 += (g.end[i] - g.start[i]) * (g.end[i] - g.start[i]);
    }
    g.length = std::sqrt(plane_len * plane_len + lin2);
    if (g.length < kMinLength) return false;
    for (int i = 0; i < n; ++i) {
      if (i == pa.first || i == pa.second) continue;
      g.dir[i] = (g.end[i] - g.start[i]) / g.length;
    }
    // Upper bound of the share of the path speed the plane takes, (|dr| + r_max sweep m) / L,
    // with m = 1 for the whole plane (k) and m the largest |sin th| or |cos th| for one axis.
    const double r_max = std::max(r0, r1);
    auto plane_share = [&](double m) {
      return std::max((std::fabs(g.dr) + r_max * sweep * m) / g.length, 1e-12);
    };
    const double k = plane_share(1.0);
    const double rmin = std::max(std::min(r0, r1), 1e-9);
    const int p[2] = {pa.first, pa.second};
    // Velocity share of each plane axis: (dr cos th - r phi sin th) / L for the first axis,
    // (dr sin th + r phi cos th) / L for the second (angle and radius linear in s), at most
    // plane_share(max|sin th|) and plane_share(max|cos th|) over the sweep: 1 where the sweep
    // passes the axis' direction, else at one of its ends. (k, which takes 1 for both, held an
    // arc of 20..40 degrees to 62 % of its first axis' velocity limit.)
    double share_max[2] = {1.0, 1.0};  // max |sin th|, max |cos th|
    if (sweep < 2.0 * kPi) {
      const double lo_th = g.phi >= 0.0 ? g.th0 : g.th0 - sweep;
      const double hi_th = lo_th + sweep;
      auto passes = [&](double target) {  // target + j pi within [lo_th, hi_th] for some j
        return target + std::ceil((lo_th - target) / kPi) * kPi <= hi_th;
      };
      auto at_ends = [&](double a0, double a1) {
        return std::max(r0 > 0.0 ? std::fabs(a0) / r0 : 1.0, r1 > 0.0 ? std::fabs(a1) / r1 : 1.0);
      };
      if (!passes(0.5 * kPi)) share_max[0] = std::min(1.0, at_ends(sy, ey));
      if (!passes(0.0)) share_max[1] = std::min(1.0, at_ends(sx, ex));
    }
    double m_vel = kInf, m_arc = kInf;
    for (int i = 0; i < 2; ++i) {
      const int ax = p[i];
      m_vel = std::min(m_vel, vmax[ax] / plane_share(share_max[i]));
      m_arc = std::min(m_arc, std::sqrt(0.5 * amax[ax] * rmin) / k);
      m_arc = std::min(m_arc, std::cbrt(0.5 * jmax[ax] * rmin * rmin) / k);
    }
    for (int i = 0; i < n; ++i) {
      const double c = std::fabs(g.dir[i]);
      if (c > 1e-12) m_vel = std::min(m_vel, vmax[i] / c);
    }
    r.f = sg.feed_mm_per_min / 60.0;
    r.m = kArcSafety * std::min(m_vel, m_arc);
    r.m_reason = m_vel <= m_arc ? LimitFactor::kAxisVelocity : LimitFactor::kArc;
    const double vb = std::min(r.m, 2.0 * r.f);
    double at = kInf, jt = kInf;
    for (int ax : p) {
      const double cent = k * k * vb * vb / rmin;
      at = std::min(at, (amax[ax] - cent) / k);
      at = std::min(at, 0.25 * jmax[ax] * rmin / (3.0 * k * k * vb));
    }
    for (int i = 0; i < n; ++i) {
      const double c = std::fabs(g.dir[i]);
      if (c > 1e-12) {
        at = std::min(at, amax[i] / c);
        jt = std::min(jt, jmax[i] / c);
      }
    }
    at *= kArcSafety;
    for (int ax : p) {
      const double rest_j = jmax[ax] - k * k * k * vb * vb * vb / (rmin * rmin) -
                            3.0 * k * k * vb * at / rmin;
      jt = std::min(jt, rest_j / k);
    }
    jt *= kArcSafety;
    r.at = std::max(at, 1e-6);
    r.jt = std::max(jt, 1e-6);
    return true;
  }

  static double chain_value(const Rec& r, int fam) {
    return fam == 0 ? r.wg : (fam == 1 ? r.wf : (r.kind == RecKind::kMotion ? r.at : kInf));
  }

  // Appends q to the next-smaller-element stack of chain `fam`. While on the stack, a record's
  // link holds the a / j minimum over [record, next stack element) (or [record, tail) on top).
  void push_chain(QDeque& stack, std::uint64_t q, int fam) {
    const auto f = static_cast<std::size_t>(fam);
    const double w = chain_value(R(q), fam);
    while (!stack.empty()) {
      Rec& b = R(stack.back());
      if (chain_value(b, fam) <= w) break;
      Link& done = b.link[f];  // not a copy made after the store below (3 % of a store())
      done.nse = q;            // its range [b, q) is final
      stack.pop_back();
      if (!stack.empty()) {
        Link& below = R(stack.back()).link[f];
        below.amin = std::min(below.amin, done.amin);
        below.jmin = std::min(below.jmin, done.jmin);
      }
    }
    // The new record extends the range of the element below it.
    Rec& r = R(q);
    const bool motion = r.kind == RecKind::kMotion;
    r.link[f].nse = kNoQ;
    r.link[f].amin = motion ? r.at : kInf;
    r.link[f].jmin = motion ? r.jt : kInf;
    stack.push_back(q);
  }

  // What is wrong with record i of p, prefixed with where it is; empty when it can be stored.
  std::string validate(const Program& p, std::size_t i) const {
    const Segment& sg = p.segments[i];
    const RecordProblem bad = record_problem(p, sg);
    if (bad.what == nullptr) return {};
    std::string why =
        "record " + std::to_string(i) + " (line " + std::to_string(sg.line) + "): " + bad.what;
    if (bad.detail >= 0) why += std::to_string(bad.detail) + bad.rest;
    return why;
  }

  // What is wrong with arc record i of p starting at `start` (a motion record's start is where
  // the record before it ends; the first record's is where the interpolator stands): empty when
  // it starts on its circle within the compiler's tolerance. Run from any other point, the arc
  // would turn into a spiral towards its end: a program compiled from another start point.
  std::string arc_start_problem(const Program& p, std::size_t i, const double* start,
                                bool first_motion) const {
    const Segment& sg = p.segments[i];
    const PlaneAxes pa = plane(sg.plane);
    const auto f = static_cast<std::size_t>(pa.first), s2 = static_cast<std::size_t>(pa.second);
    const double r0 = std::hypot(start[f] - sg.center[0], start[s2] - sg.center[1]);
    const double r1 = std::hypot(sg.end[f] - sg.center[0], sg.end[s2] - sg.center[1]);
    const double allowed = arc_radius_tolerance_mm(r0);
    if (std::fabs(r1 - r0) <= allowed * (1.0 + 1e-9)) return {};
    // Short enough for a DDS reason (255 characters) with the service's prefix: only the plane
    // axes' position, which is all the radius depends on.
    std::string why = "record " + std::to_string(i) + " (line " + std::to_string(sg.line) +
                      "): arc does not start on its circle (radius " + number_text(r0) +
                      " mm at the start, " + number_text(r1) + " mm at the end): ";
    if (!first_motion) return why + "the record before it ends elsewhere";
    why += "compiled to start elsewhere than ";
    for (const std::size_t a : {f, s2}) {
      why.push_back(a < p.axis_letters.size() ? p.axis_letters[a] : static_cast<char>('0' + a));
      why += number_text(start[a]);
      why.push_back(a == f ? ' ' : ',');
    }
    return why + " where the interpolator stands";
  }

  // The problem of one record: `what`, then `detail` and `rest` when detail >= 0 (an axis, a
  // plane). No string is made for a good record: this runs for every record appended, one per
  // cycle on a program of short chords.
  struct RecordProblem {
    const char* what = nullptr;
    int detail = -1;
    const char* rest = "";
  };
  RecordProblem record_problem(const Program& p, const Segment& sg) const {
    if (static_cast<int>(sg.type) > 6) return {"unknown record type"};
    if (sg.tool < 0 || sg.tool > kMaxTool) return {"tool number must be 0..99999"};
    for (int a = 0; a < n; ++a) {
      if (!(std::fabs(sg.end[a]) <= kMaxCoordinateMm))
        return {"end point of axis ", a, " is not a number within +-1e9 mm"};
    }
    if (sg.type == SegmentType::kLinear || sg.is_arc()) {
      if (!(sg.feed_mm_per_min > 0.0 && sg.feed_mm_per_min <= kMaxFeedMmPerMin)) {
        return {"feed must be > 0 and <= 1000000 mm/min"};
      }
    }
    if (sg.is_arc()) {
      const PlaneAxes pa = plane(sg.plane);
      if (pa.first >= n || pa.second >= n) {
        return {"arc plane G", static_cast<int>(sg.plane), " needs axes that are not configured"};
      }
      if (!(std::fabs(sg.center[0]) <= kMaxCoordinateMm && std::fabs(sg.center[1]) <= kMaxCoordinateMm)) {
        return {"arc centre is not a point within +-1e9 mm"};
      }
      if (sg.turns < 0 || sg.turns > kMaxArcTurns) return {"arc turns must be 0..1000"};
    }
    if (sg.type == SegmentType::kDwell && (!std::isfinite(sg.dwell_s) || sg.dwell_s < 0.0 || sg.dwell_s > 1e6)) {
      return {"dwell must be 0..1e6 s"};
    }
    if (sg.type == SegmentType::kMFunction) {
      if (sg.m_kind == MKind::kNone) return {"M record without M kind"};
      if (sg.aux >= static_cast<std::int32_t>(p.params.size()))
        return {"M parameter index out of range"};
    }
    if (sg.type == SegmentType::kMessage &&
        (sg.aux < 0 || sg.aux >= static_cast<std::int32_t>(p.messages.size()))) {
      return {"message index out of range"};
    }
    if (sg.type == SegmentType::kMessage &&
        p.messages[static_cast<std::size_t>(sg.aux)].size() > kMaxMessageBytes) {
      return {"message longer than 255 bytes"};
    }
    if (sg.type == SegmentType::kMessage &&
        utf8_invalid_at(p.messages[static_cast<std::size_t>(sg.aux)]) != std::string_view::npos) {
      return {"message is not UTF-8 text"};
    }
    if (sg.type == SegmentType::kMessage &&
        control_char_at(p.messages[static_cast<std::size_t>(sg.aux)]) != std::string_view::npos) {
      return {"message holds a control character"};
    }
    return {};
  }

  // Plans and stores one record at q = tail.
  void store(const Program& p, std::size_t i) {
    const std::uint64_t q = tail;
    const std::size_t slot = ring_index(q);
    if (slot + 1 >= rec.size() && rec.size() < cap) grow_rings(slot + 1);
    const Segment& sg = p.segments[i];
    S(q) = sg;
    Rec& r = R(q);
    // A slot that never held a record is the default record grow_rings made.
    if (slot < slots_used) {
      r = Rec{};
    } else {
      slots_used = slot + 1;
    }
    r.s0 = s_tail;
    // Parameters are read for M records only (execution, events, LookAheadBuffer).
    if (sg.type == SegmentType::kMFunction) {
      if (slot >= par.size()) par.resize(std::min(cap, std::max(slot + 1, 2 * par.size())));
      par[slot] = sg.aux >= 0 ? p.params[static_cast<std::size_t>(sg.aux)] : unset_params();
    }
    if (sg.type == SegmentType::kMessage) {
      msg[msg_next] = p.messages[static_cast<std::size_t>(sg.aux)];
      msg_line[msg_next] = sg.line;
      r.msg_slot = static_cast<std::int32_t>(msg_next);
      msg_next = (msg_next + 1) % kMessageRing;
    }
    const bool stop = sg.type == SegmentType::kDwell ||
                      (sg.type == SegmentType::kMFunction && sg.m_kind != MKind::kContinuous);
    if (sg.is_motion() && plan_motion(sg, pt_end, r)) {
      r.kind = RecKind::kMotion;
      std::array<double, kMaxAxes> t0{};
      motion::geometry_tangent(r.g, n, 0.0, t0.data());
      if (pt_have_motion && !pt_stop_since) {
        const double c = corner_limit(pt_tangent, t0);
        double w = c;
        LimitFactor why = LimitFactor::kCorner;
        auto take = [&](double v, LimitFactor f) {
          if (v < w) {
            w = v;
            why = f;
          }
        };
        take(pt_m, pt_m_reason);
        take(r.m, r.m_reason);
        take(2.0 * pt_f, LimitFactor::kFeed);
        take(2.0 * r.f, LimitFactor::kFeed);
        take(curvature_step_limit(r.g), LimitFactor::kCorner);
        note_junction(pt_tangent);
        const TurnBound tb = turn_bound(t0);
        take(chord_turn_limit(tb, t0, std::min(pt_length, r.g.length), w), LimitFactor::kCorner);
        r.wg = w;
        r.wg_reason = why;
        r.wf = std::min(pt_f, r.f);
        // A line much longer than the record before it ends the run (a lead-out): the turn
        // at its start is one step, which the tolerance takes; held to the room for its whole
        // length, 100 mm after 0.05 mm chords took 8 % longer (review of session 82).
        if (!r.g.arc && r.g.length <= 2.0 * pt_length) {
          leave_room_for_the_turn(tb, t0, std::min(pt_length, r.g.length), r);
        }
      } else {
        r.wg = std::min(r.m, 2.0 * r.f);
        r.wg_reason = r.m_reason;
        r.wf = r.f;
        jh_count = 0;  // a new run starts from rest
      }
      motion::geometry_tangent(r.g, n, r.g.length, pt_tangent.data());
      motion::geometry_curvature(r.g, n, r.g.length, pt_curvature.data());
      pt_end = r.g.end;
      pt_have_motion = true;
      pt_stop_since = false;
      pt_f = r.f;
      pt_m = r.m;
      pt_m_reason = r.m_reason;
      pt_length = r.g.length;
      s_tail += r.g.length;
    } else if (stop) {
      r.kind = RecKind::kStop;
      r.wg = 0.0;
      r.wf = 0.0;
      r.wg_reason = LimitFactor::kMStop;
      pt_stop_since = true;
    } else {
      r.kind = RecKind::kPass;  // continuous M, message, zero-length motion
    }
    push_chain(st_g, q, 0);
    push_chain(st_f, q, 1);
    push_chain(st_a, q, 2);
    ++tail;
  }

  void drop_stale() {
    while (!st_g.empty() && st_g.front() < cur) st_g.pop_front();
    while (!st_f.empty() && st_f.front() < cur) st_f.pop_front();
    while (!st_a.empty() && st_a.front() < cur) st_a.pop_front();
  }

  // ================= execution =================

  void current_position(double* out) const {
    if (on_path) {
      motion::geometry_position(R(cur).g, n, st.s, out);
    } else {
      for (int i = 0; i < n; ++i) out[i] = rest[i];
    }
  }

  void reset_window() {
    cons_valid = false;
    dq_a.clear();
    dq_j.clear();
    dq_wg.clear();
    dq_wf.clear();
    win_end = cur;
  }

  // Look-ahead horizon [mm] from (v, a) with the current record's jerk limit jc and the window
  // minima a0, j0: the stopping distance from the fastest state the cycle can reach (full jerk
  // from here), the distance to take back the acceleration, and one more cycle of travel.
  double horizon_for(double v, double a, double jc, double a0, double j0) const {
    return horizon_bound(v, a, jc, a0, a0, j0);
  }

  // horizon_for with the acceleration limit a_lo in the stopping distance and a_hi in the
  // distance to take the acceleration back. It grows with jc and a_hi and as a_lo and j0 fall:
  // with the highest jc and a_hi and the lowest a_lo and j0 of a set of records it bounds the
  // horizon of every window made of them (skip_cruise).
  double horizon_bound(double v, double a, double jc, double a_lo, double a_hi, double j0) const {
    const double ac = std::max(std::fabs(a) + jc * T, 0.0);
    const double vc = v + std::fabs(a) * T + 0.5 * jc * T * T;
    return jerk::stopping_distance(vc, ac, kPlanMargin * a_lo, kPlanMarginJ * j0) +
           vc * (ac + a_hi) / (kPlanMarginJ * j0) + 2.0 * vc * T + 1e-6;
  }

  // Lowers a0 and j0 to the tangential limits of the motion record at the window's end, if any
  // (update_window's horizon, skip_cruise's bound of it).
  void next_limits(double& a0, double& j0) const {
    if (win_end <= cur || win_end >= tail) return;
    const Rec& r = R(win_end);
    if (r.kind != RecKind::kMotion) return;
    a0 = std::min(a0, r.at);
    j0 = std::min(j0, r.jt);
  }

  void update_window(double& A, double& J) {
    while (!dq_a.empty() && dq_a.front() < cur) dq_a.pop_front();
    while (!dq_j.empty() && dq_j.front() < cur) dq_j.pop_front();
    while (!dq_wg.empty() && dq_wg.front() <= cur) dq_wg.pop_front();
    while (!dq_wf.empty() && dq_wf.front() <= cur) dq_wf.pop_front();
    if (win_end <= cur) {
      dq_a.clear();
      dq_j.clear();
      dq_wg.clear();
      dq_wf.clear();
      win_end = cur;
    }
    const Rec& rc = R(cur);
    const double v = st.v, a = st.a;
    int added = 0;
    // Extend until the window covers the horizon computed with the window's own minima (new
    // records may lower them and so lengthen the horizon).
    double a_prev = -1.0, j_prev = -1.0;
    for (int pass = 0; pass < 3; ++pass) {
      double a0 = dq_a.empty() ? rc.at : dq_a.min();
      double j0 = dq_j.empty() ? rc.jt : dq_j.min();
      // The motion record just beyond the window counts as well: a braking for a limit in or
      // after it may have to start before the horizon of the window's own limits reaches it
      // when its limits are lower. (Wide sweep seed 25 program 255 cruised along a chord of
      // 306,787 mm/s^3 whose horizon ended 0.02 mm ahead, at a chord of 1,516 mm/s^3 and
      // 0.018 mm; the corner after it, 0.92 mm/s below the cruise, came into view 0.039 mm
      // ahead where its braking needed 0.135 mm, and the motion broke a limit either way.)
      next_limits(a0, j0);
      // Minima unchanged by the records the last pass added: the same horizon, and the scan
      // stopped where it would stop again.
      if (a0 == a_prev && j0 == j_prev) break;
      a_prev = a0;
      j_prev = j0;
      // The window and the chains are gathered once per cycle: take the fastest state the
      // cycle can reach (full jerk from here) and one more cycle of travel as margin.
      horizon = horizon_for(v, a, rc.jt, a0, j0);
      const double limit = rc.s0 + st.s + horizon;
      const int before = added;
      std::size_t idx = ring_index(win_end);
      while (win_end < tail && added < kMaxExtendPerCycle) {
        const Rec& r = rec[idx];
        if (++idx == cap) idx = 0;
        if (win_end > cur) {
          if (r.kind == RecKind::kStop) break;
          if (r.s0 > limit) break;
        }
        if (r.kind == RecKind::kMotion) {
          dq_a.push(win_end, r.at);
          dq_j.push(win_end, r.jt);
        }
        if (win_end > cur) {
          dq_wg.push(win_end, r.wg);
          dq_wf.push(win_end, r.wf);
        }
        ++win_end;
        ++added;
      }
      if (added == before) break;
    }
    A = dq_a.empty() ? rc.at : dq_a.min();
    J = dq_j.empty() ? rc.jt : dq_j.min();
  }

  // Constraint::reserve of a speed limit w at the junction into record q: two calculation steps
  // of travel at w plus twice what a step from rest reaches by the jerk of the motion record
  // before q alone (J dt^3 / 6). A step whose reach (step_limits) includes the junction has q's
  // lower jerk. After a stiff record (1.7e6 mm/s^3, 1 ms cycles) that jerk term is 2.3e-6 mm per
  // step, against 2 w dt = 3e-6 mm for w = 0.0075 mm/s: the braking planned at the stiff jerk was
  // still under way when a step could reach the junction, got the soft jerk and crossed at
  // 4 x w (wide sweep seed 1 program 281).
  double junction_reserve(std::uint64_t q, double w) const {
    std::uint64_t b = q - 1;
    while (b > cur && R(b).kind != RecKind::kMotion) --b;
    return reserve_for(w, R(b).jt);
  }
  // junction_reserve for jerk J before the junction: twice a step's reach from (w, 0), i.e.
  // 2 step_reach(w, 0, J), summed in the order it always was (step_reach's order moves
  // trajectories by rounding); grows with J (skip_cruise bounds it).
  double reserve_for(double w, double J) const { return 2.0 * (w * dt + J * dt * dt * dt / 6.0); }
  // Farthest a calculation step goes from (v, a) when its end acceleration is at most a + J dt
  // (step_limits' reach without the tangential cap); 0 when it cannot move forward. Twice it,
  // from the state a limit is planned to be kept in, is the room a junction into a record of
  // lower jerk needs (reserve_for, dec_room): a step that can reach the junction has that jerk.
  double step_reach(double v, double a, double J) const {
    return std::max(0.0, dt * (v + dt * (0.5 * a + J * dt / 6.0)));
  }

  // Constraint::d2 of speed limit ck at the junction into record q, whose chain element before
  // it is q_prev (J_prev: the lowest jerk limit over [cur, q_prev)). When the motion record b
  // before the junction is far softer (kStiffRatio) than every record from cur up to it, the
  // limit is planned in two pieces: to (w2, 0) at b's start at their jerk, then as itself. A
  // plan at the lowest jerk over [cur, q) takes b's jerk for its whole length: behind a G0 of
  // 0.008 mm whose Z axis allowed 39 mm/s^3 along it, chords of about 2,000 mm/s^3 found the
  // corner at its end 3.3 mm ahead and already out of reach at 12.8 mm/s, braked at their full
  // jerk and rode the corner's plan at the G0's jerk, crossing the corner still braking
  // (jerk::braking_plan's case 2) into the arc after it, whose jerk (5.4 mm/s^3) could not take
  // -10.4 mm/s^2 back before the motion stopped: Y and Z at 5.8 x and 169 x their jerk limits
  // (box sweep seed 8 program 222). In two pieces the braking is complete before the soft
  // records. Bounded work: only when at most kStiffScan records lie between q_prev and b.
  void stiff_stretch(Constraint& ck, std::uint64_t q, std::uint64_t q_prev, double J_prev,
                     double here) const {
    std::uint64_t b = q - 1;
    while (b > q_prev && R(b).kind != RecKind::kMotion) --b;
    if (b <= cur || R(b).kind != RecKind::kMotion || b - q_prev > kStiffScan) return;
    double J2 = J_prev;
    for (std::uint64_t u = q_prev; u < b; ++u) {
      const Rec& r = R(u);
      if (r.kind == RecKind::kMotion) J2 = std::min(J2, r.jt);
    }
    const Rec& rb = R(b);
    if (!(J2 >= kStiffRatio * rb.jt)) return;
    ck.d2 = rb.s0 - here;
    ck.J2 = J2;
    // The cut between the two plans is a target in speed and acceleration (MOTION.md, Known
    // gaps): the highest w2 with zero acceleration at d2 from which the limit's own plan fits
    // into the soft stretch, so that it takes over there. Cut at w instead, the braking for a
    // corner of 0.0022 mm/s behind a 0.27 mm line of 92 mm/s^3 was planned to end 0.27 mm
    // early: the chords braked to a crawl in front of the line and reached it still braking (X
    // and B at 6 x and 47 x their jerk limits, box sweep seed 1 program 292).
    const double room = ck.d - ck.d2 - ck.reserve;
    const double A = kPlanMargin * ck.A, J = kPlanMarginJ * ck.J;
    double lo = 0.0, hi = room > 0.0 ? std::cbrt(room * room * J) : 0.0;  // no A cap, w = 0
    for (int i = 0; i < 24 && hi - lo > 1e-6 * (ck.w + hi); ++i) {  // w2 = w + lo: conservative
      const double u = 0.5 * (lo + hi);
      if (jerk::braking_plan(ck.w + u, 0.0, ck.w, A, J).distance <= room) {
        lo = u;
      } else {
        hi = u;
      }
    }
    // Never above the junction limit into b itself: that corner's own plan, at the stiff
    // record's acceleration, then braked at -7,892 mm/s^2 in the last steps before a line of
    // 39 mm/s^2, which was entered at 420 x X's corner tolerance (box sweep seed 3 program
    // 121). (b's limit lies above w on w's chain; on the feed chain it may lie below.)
    ck.w2 = std::min(ck.w + lo, rb.wg);
    ck.reserve2 = junction_reserve(b, ck.w2);
  }

  // Collects the limits ahead into `c`; returns their count. Window minima Aw, Jw apply to the
  // end of the window.
  int gather(Constraint* c, double Aw, double Jw, double reach) const {
    const Rec& rc = R(cur);
    const double here = rc.s0 + st.s;
    int k = 0;
    for (int fam = 0; fam < 3; ++fam) {
      const auto f = static_cast<std::size_t>(fam);
      std::uint64_t q = cur + 1;
      double A = rc.at, J = rc.jt;  // limits over [cur, q)
      // The chain element before q (cur at first) and the lowest jerk limit over [cur, q_prev).
      std::uint64_t q_prev = cur;
      double J_prev = kInf;
      int hops = 0;
      while (q < win_end) {
        const Rec& r = R(q);
        if (r.s0 - here > reach) break;  // beyond any braking or acceleration change from here
        const double w = chain_value(r, fam) * (fam == 1 ? rel : 1.0);
        if (hops == kChainMax) {
          // Not followed further: from here on assume the lowest limit of the whole window
          // (a long monotone run, e.g. the axis projections around a circle of chords).
          if (fam == 0 && !dq_wg.empty()) {
            const Rec& m = R(dq_wg.front());
            c[k] = {r.s0 - here, m.wg, A, J, m.wg_reason, false};
            stiff_stretch(c[k++], q, q_prev, J_prev, here);
          } else if (fam == 1 && !dq_wf.empty()) {
            // A hard limit, unlike the feed limits it stands in for. Placed this early, the
            // window's lowest feed is often out of reach from the start, and a soft limit out of
            // reach is given up (best effort tracks the target): the feeds behind it then came
            // into view out of reach one after another. Chords of 0.1 mm whose feed fell by 2 %
            // from each to the next ran up to 15 % above their programmed feed, chords of
            // 0.01 mm falling by 1 % to F1000 at 61 % above it (session 44; no test had reached
            // this line). Hard, it is kept as far as the machine allows, like the corner
            // chain's: a few percent slower than every feed limit followed one by one.
            c[k] = {r.s0 - here, dq_wf.min() * rel, A, J, LimitFactor::kFeed, false, false};
            stiff_stretch(c[k++], q, q_prev, J_prev, here);
          } else if (fam == 2) {
            c[k++] = {r.s0 - here, Aw, A, J, LimitFactor::kAccelJerk, true};
          }
          break;
        }
        // A feed limit at a junction whose hard limit is no higher is that limit's already,
        // but with the reserve of its own, higher speed (two steps of travel at w): behind a
        // stiff rapid into a corner of 0.0147 mm/s, the feed's 11.65 mm/s asked 0.0049 mm
        // before the junction, failed where the corner's plan fitted, and, being the feed,
        // kept the spent-allowance ride from applying: the best effort crossed the corner at
        // 2.5 mm/s (simulate fuzz, box machine 15, session 41). Not gathered.
        const bool dominated = fam == 1 && r.wg <= w;
        if (w < kInf && !dominated) {
          LimitFactor why = fam == 0 ? r.wg_reason
                                     : (fam == 2 ? LimitFactor::kAccelJerk
                                                 : (rel == 1.0 ? LimitFactor::kFeed : LimitFactor::kOverride));
          Constraint& ck = c[k++];
          ck = {r.s0 - here, w, A, J, why, fam == 2, fam == 1};
          if (fam == 2) {
            // Into a record of lower jerk: the calculation step that can reach the junction has
            // that jerk already (accel_room).
            if (r.kind == RecKind::kMotion && r.jt < J) ck.Jx = r.jt;
          } else {
            // Jerk limit over the records up to the next smaller limit of the chain (the window
            // minimum when that is beyond the window): where an acceleration still positive at
            // this limit is taken back (see Constraint::Jx).
            const std::uint64_t nse = r.link[f].nse;
            ck.Jx = std::min(J, nse != kNoQ && nse < win_end ? r.link[f].jmin : Jw);
            if (r.kind == RecKind::kMotion && r.jt < J) ck.reserve = junction_reserve(q, w);
            stiff_stretch(ck, q, q_prev, J_prev, here);
          }
          ++hops;
        }
        if (r.link[f].nse == kNoQ) break;
        q_prev = q;
        J_prev = J;
        A = std::min(A, r.link[f].amin);
        J = std::min(J, r.link[f].jmin);
        q = r.link[f].nse;
      }
    }
    // End of the window: a stop point, the end of the buffer, or the look-ahead reach.
    if (win_end >= tail) {
      c[k++] = {s_tail - here, 0.0, Aw, Jw, complete ? LimitFactor::kMStop : LimitFactor::kStarvation, false};
    } else {
      const Rec& r = R(win_end);
      c[k++] = {r.s0 - here, 0.0, Aw, Jw,
                r.kind == RecKind::kStop ? LimitFactor::kMStop : LimitFactor::kLookAhead, false};
    }
    for (int i = 0; i < k; ++i) c[i].beyond_stop = 2.0 * c[i].w * c[i].A / (kPlanMarginJ * c[i].J);
    return k;
  }

  // Distance [mm] needed from (v, a) to bring |a| within w at jerk J (0 when it already is).
  static double accel_distance(double v, double a, double w, double J) {
    if (std::fabs(a) <= w) return 0.0;
    const double t = (std::fabs(a) - w) / J;
    const double jj = a > 0.0 ? -J : J;
    return std::max(0.0, travel(v, a, jj, t));
  }

  // Braking distance [mm] of a plan from (v, a) to w, plus what the generator can lose
  // following it. The plan (jerk::braking_distance_from) switches jerk at any instant; the
  // generator holds one jerk per calculation step. A step across a switch of the plan (onset ->
  // peak -> release, onset -> hold at A, hold -> release) that ends at the plan's acceleration
  // is slower than the plan by Jp tau (dt - tau) <= Jp dt^2 / 4 (tau: the switch inside the
  // step), and a larger deceleration to make up for it is only possible up to the no-reversal
  // floor, which lies within a few percent of the plan's release curve. That velocity excess is
  // then carried through the release, which lasts ap / Jp: the distance lost is at most
  // ap dt^2 / 4 (ap: the plan's peak deceleration). Without this allowance a short braking
  // from a crawl (a few calculation steps, the peak inside a step) reached the stop point still
  // moving (TGM_SEED=4 program 97: 0.09 mm/s, override 0.0187, stop 3.5e-7 mm too short).
  double plan_braking(double v, double a, double w, double A, double J, double J_now) const {
    const jerk::Braking b = jerk::braking_plan_from(v, a, w, A, J, J_now);
    return b.distance + allowance * quarter_dt2 * b.peak;
  }

  // True when excess_from judges `ns` against limit `ck` by a plain braking plan (no easing of a
  // deceleration too hard for the limit's A or J; jerk::braking_plan_from's first test).
  static bool regular_for(const jerk::State& ns, const Constraint& ck) {
    if (ns.a >= 0.0) return true;
    const double A = kPlanMargin * ck.A, J = kPlanMarginJ * ck.J;
    // With a margin: braking_plan_from's easing test compares a with -sqrt(2 J v).
    return ns.a >= -A && 2.0 * J * std::max(ns.v, 0.0) >= ns.a * ns.a * (1.0 + 1e-6);
  }

  // An upper bound of what excess_from adds to its room for limit ck, over every end-of-step
  // state (v, a) this cycle can evaluate that is regular_for it: v <= cons_vc, a <= cons_ac. The
  // braking distance of a regular state grows with v and with a (jerk::braking_plan; pinned by
  // a seeded sweep in jerk_profile_test), its peak deceleration is at most A; taking the
  // acceleration back (the Jx case, acceleration limits) needs at most what taking all of
  // cons_ac back to w (or to 0) at the same jerk needs.
  double cycle_bound(const Constraint& ck) const {
    const double J = kPlanMarginJ * ck.J;
    if (ck.accel) {
      // accel_room from the cycle's fastest state; the speed after the taper is at most
      // cons_vc + cons_ac^2 / 2J.
      double d = accel_distance(cons_vc, cons_ac, ck.w, J);
      if (ck.Jx < ck.J && cons_ac > ck.w) {
        d += 2.0 * step_reach(cons_vc + cons_ac * cons_ac / (2.0 * J), ck.w, ck.J);
      }
      return d;
    }
    const double A = kPlanMargin * ck.A;
    double d = jerk::braking_plan(cons_vc, cons_ac, ck.w, A, J).distance + quarter_dt2 * A;
    if (ck.Jx < ck.J) d = std::max(d, accel_distance(cons_vc, cons_ac, 0.0, J));
    return d;
  }
  // True while speed limit ck is kept at its d2 (`moved` [mm] travelled since it was gathered).
  static bool before_d2(const Constraint& ck, double moved) {
    return ck.d2 < kInf && ck.d2 - moved >= 0.0;
  }
  // cycle_bound for the first piece of a speed limit's plan, (w2, 0) at d2 at J2 (excess_from).
  double cycle_bound2(const Constraint& ck) const {
    const double J2 = kPlanMarginJ * ck.J2, A = kPlanMargin * ck.A;
    return std::max(jerk::braking_plan(cons_vc, cons_ac, ck.w2, A, J2).distance + quarter_dt2 * A,
                    accel_distance(cons_vc, cons_ac, 0.0, J2));
  }

  // Lowest jerk limit, at most J, of the motion records that taking acceleration (or
  // deceleration) ap back on the way to the target crosses (within v_max ap / Jw of here, v_max
  // the highest speed on the way, Jw the window's lowest jerk: an upper bound of that distance);
  // Jw when they lie beyond the scan budget.
  double landing_jerk(double ap, double v_max, double J, double Jw) const {
    const Rec& rc = R(cur);
    const double limit = rc.s0 + st.s + v_max * (ap / Jw + dt);
    std::size_t idx = ring_index(cur + 1);
    int scanned = 0;
    for (std::uint64_t q = cur + 1; q < tail; ++q) {
      if (++scanned > kMaxExtendPerStep) return std::min(J, Jw);
      const Rec& r = rec[idx];
      if (++idx == cap) idx = 0;
      if (r.s0 > limit || r.kind == RecKind::kStop) break;
      if (r.kind == RecKind::kMotion) J = std::min(J, r.jt);
    }
    return J;
  }

  // Target speed of record r: the feed x Rel_Speed within the machine cap; `why` is what sets it.
  double target_speed(const Rec& r, LimitFactor& why) const {
    const double fr = r.f * rel;
    if (fr <= r.m) {
      why = rel == 1.0 ? LimitFactor::kFeed : LimitFactor::kOverride;
      return fr;
    }
    why = r.m_reason;
    return r.m;
  }

  // Tangential limits for this calculation step: the records it can reach.
  void step_limits(double& A, double& J) const {
    const Rec& rc = R(cur);
    A = rc.at;
    J = rc.jt;
    // The farthest this step can go: its end acceleration is at most min(a + J dt, A) with the
    // current record's limits (later records only lower them).
    const double x_max = std::min(st.a + rc.jt * dt, std::max(rc.at, st.a));
    const double reach = std::max(0.0, dt * (st.v + dt * (st.a / 3.0 + x_max / 6.0))) + 1e-9;
    const double limit = rc.s0 + st.s + reach;
    int scanned = 0;
    std::size_t idx = ring_index(cur + 1);
    for (std::uint64_t q = cur + 1; q < tail && scanned < kMaxExtendPerStep; ++q, ++scanned) {
      const Rec& r = rec[idx];
      if (++idx == cap) idx = 0;
      if (r.s0 > limit || r.kind == RecKind::kStop) return;
      if (r.kind == RecKind::kMotion) {
        A = std::min(A, r.at);
        J = std::min(J, r.jt);
      }
    }
  }

  // Limits on the deceleration from the records ahead (inside the window). Entering record q,
  // |a| must be within its tangential limit: a deceleration above it has to be taken back on the
  // way, at 90 % of the lowest jerk limit before q (what the braking plans use), so each such q
  // becomes an acceleration point for negative x (collected in `dec`, at most kMaxDecelLimits,
  // from at most kMaxExtendPerStep records). hi is the highest end-of-step acceleration allowed.
  // sc scales the records' limits (the emergency ramp's rho).
  int decel_limits(double v, double a, double J, double A, double hi, double sc,
                   Constraint* dec) const {
    const Rec& rc = R(cur);
    const double here = rc.s0 + st.s;
    const double ds_max = dt * (v + dt * (a / 3.0 + hi / 6.0));
    const double v_end = v + 0.5 * (a + hi) * dt;
    if (!(v_end > 0.0)) return 0;
    const double a_max = std::max(std::fabs(a), A) + J * dt;  // largest |x| this step can have
    double j_before = sc * rc.jt;                             // lowest jerk limit over [cur, q)
    // Farther than this the largest deceleration is taken back completely, with dec_room's two
    // steps after it (changes with j_before).
    auto reach_for = [&](double j) {
      return ds_max + v_end * a_max / (kPlanMarginJ * j) + 2.0 * step_reach(v_end, 0.0, j);
    };
    double reach = reach_for(j_before);
    // A record beyond the reach may have a lower jerk, and the records after it come into reach
    // with it: scanning stops beyond the reach at the window's lowest jerk limit. (Stopping at
    // the first record beyond the reach missed a limit after a short record of lower jerk: wide
    // sweep seed 25 program 255 braked at 306,787 mm/s^3 to 276 mm/s^2 in front of a 0.018 mm
    // chord of 1,516 mm/s^3, which could not take the deceleration down to the 34.7 mm/s^2 of
    // the record after it, and Y exceeded its acceleration limit by 5 %.)
    const double reach_max = reach_for(std::min(j_before, sc * cons_Jw));
    int n_dec = 0;
    int scanned = 0;
    double w_before = kInf;  // lowest hard junction limit over (cur, q]
    double j_w = kInf;       // the lowest jerk limit before w_before's junction
    // Where the jerk limit last fell (-1: not yet), the lowest jerk limit before that place and
    // the lowest hard junction limit up to it, with the jerk before its junction.
    double d_soft = -1.0, j_stiff = j_before, w_stiff = kInf, jw_stiff = kInf;
    std::size_t idx = ring_index(cur + 1);
    for (std::uint64_t q = cur + 1; q < win_end && q < tail && scanned < kMaxExtendPerStep; ++q, ++scanned) {
      const Rec& r = rec[idx];
      if (++idx == cap) idx = 0;
      if (r.kind == RecKind::kStop) break;
      if (r.kind != RecKind::kMotion) continue;
      const double d = r.s0 - here;
      if (d > reach_max) break;
      if (r.wg < w_before) {
        w_before = r.wg;
        j_w = j_before;
      }
      // A record of lower jerk also limits the deceleration its jerk can take back before the
      // motion stops there (dec_target; the entry speed is below v_end while decelerating).
      const bool softer = sc * r.jt < j_before;
      if (d <= reach && (sc * r.at < a_max ||
                         (softer && 2.0 * kFloorMarginJ * sc * r.jt * v_end < a_max * a_max))) {
        Constraint& ck = dec[n_dec++];
        ck = {d, sc * r.at, sc * r.at, j_before, LimitFactor::kAccelJerk, true};
        // Into a record of lower jerk: the calculation step that can reach the junction has
        // that jerk already (dec_room).
        if (softer) ck.Jx = sc * r.jt;
        // A braking to a junction at or before q's (dec_kept) takes the deceleration back there.
        ck.junction_v = w_before;
        ck.junction_j = j_w;
        // Behind a fall of the jerk limit: only the part of the taper inside the softer stretch
        // needs its jerk. Taken back to w2 before that stretch at the jerk before it, the rest
        // fits into the stretch at its own (the stretch less two steps' reach, as dec_room keeps
        // into a softer record; at most v_end the speed there). Planned at the stretch's jerk all
        // the way, the taper held the braking for a corner behind a chord of 0.01 mm and 3,250
        // mm/s^3 to 278 mm/s^2 where the chords before it allowed 441, and the corner was crossed
        // at 4 mm/s against 1.5 (wide sweep seed 277 program 189).
        if (!softer && d_soft >= 0.0) {  // the jerk limit fell from j_stiff to j_before there
          const double room = d - d_soft - 2.0 * step_reach(v_end, 0.0, j_before);
          if (room > 0.0) {
            ck.d = d_soft;
            ck.w = ck.A = ck.w + kPlanMarginJ * j_before * room / v_end;
            ck.J = j_stiff;
            ck.Jx = j_before;  // the softer stretch starts here
            ck.junction_v = w_stiff;
            ck.junction_j = jw_stiff;
          }
        }
        if (n_dec == kMaxDecelLimits) break;
      }
      if (softer) {
        d_soft = d;
        j_stiff = j_before;
        w_stiff = w_before;
        jw_stiff = j_w;
        j_before = sc * r.jt;
        reach = reach_for(j_before);
      }
    }
    return n_dec;
  }

  // Room [mm] that a deceleration a < -w needs before deceleration limit ck (decel_limits): taking
  // it back to w at the plan's jerk and, into a record of lower jerk (ck.Jx < ck.J), twice the
  // farthest a calculation step reaches from the state then, (v', -w) (step_reach). A step that
  // can reach the junction has the lower jerk and takes little deceleration back: without this
  // room wide sweep seed 102 program 776 (X: 20 mm/s^2, 10,000 mm/s^3, 1 ms) entered a chord led
  // by X at 2.8 x its path acceleration limit, the taper planned at the stiff chord's jerk having
  // run out of room. (The speed limits' reserve taken from (v', 0), 2 step_reach(v', 0, J), is far
  // more than a step braking at -w reaches, and made a corner of 0.014 mm/s hopeless: wide seed 4
  // program 118 crossed it at 0.36 mm/s.)
  double dec_room(double v, double a, const Constraint& ck) const {
    return taper_room(v, a, dec_target(v, a, ck), ck);
  }

  // Room [mm] to take |a| back to w at the plan's jerk and, into a record of lower jerk (ck.Jx <
  // ck.J), twice the farthest a calculation step reaches from the state then, (v', +-w):
  // dec_room for a deceleration, accel_room for an acceleration.
  double taper_room(double v, double a, double w, const Constraint& ck) const {
    const double jp = kPlanMarginJ * ck.J;
    double need = accel_distance(v, a, w, jp);
    if (ck.Jx < ck.J) {
      const double toward = a > 0.0 ? -jp : jp;  // jerk that takes |a| back
      const double v_after = std::max(0.0, speed_after(v, a, toward, (std::fabs(a) - w) / jp));
      need += 2.0 * step_reach(v_after, a > 0.0 ? w : -w, ck.J);
    }
    return need;
  }

  // Deceleration [mm/s^2, > 0] that a motion at (v, a), a < 0, may carry into the record of
  // deceleration limit ck: its tangential limit and, into a record of lower jerk, no more than
  // that jerk can take back before the motion stops (a^2 <= 2 jf v at the speed of entry, jf at
  // the no-reversal floor's margin). Taking a back to w at the plan's jerk jp first leaves
  // v - (a^2 - w^2) / 2jp, so w^2 (1 - jf/jp) <= 2 jf v - (jf/jp) a^2; |a| is within that bound
  // exactly when a^2 <= 2 jf v. Without it wide sweep seed 33 program 50 braked for a corner
  // along a chord of 2.2e6 mm/s^3 and entered a chord led by Z (787 mm/s^3 along the path) at
  // its acceleration limit of 393 mm/s^2 and 2.1 mm/s: the motion stopped dead 5 ms later with
  // Z's jerk at 147 x its limit.
  double dec_target(double v, double a, const Constraint& ck) const {
    if (!(ck.Jx < ck.J)) return ck.w;
    const double jf = kFloorMarginJ * ck.Jx, r = jf / (kPlanMarginJ * ck.J);
    if (r >= 1.0) return ck.w;  // this record's own floor is the stricter one
    const double w2 = (2.0 * jf * std::max(v, 0.0) - r * a * a) / (1.0 - r);
    return std::min(ck.w, std::sqrt(std::max(0.0, w2)));
  }

  // Room [mm] that an acceleration a > w needs before acceleration limit ck (gather's acceleration
  // chain): taking it back to w at the plan's jerk and, into a record of lower jerk (ck.Jx <
  // ck.J), twice the farthest a calculation step reaches from the state then, (v', w)
  // (taper_room, as dec_room). A step that can reach the junction has the lower jerk and takes
  // little acceleration back: without this room wide sweep seed 33 program 204 (X: 37,000 mm/s^3
  // along the first line, Y: 15.3 mm/s^2 and 7,600 mm/s^3 leading the second) entered the second
  // line at 20.9 mm/s^2 against its path limit of 17.9 (Y at 1.003 x its limit).
  double accel_room(double v, double a, const Constraint& ck) const {
    return taper_room(v, a, ck.w, ck);
  }

  // True when deceleration limit ck does not bound the deceleration of (v, a) with `room` [mm]
  // left: it can be taken back to -ck.w before the junction now (dec_room), or the motion is
  // braking to the speed limit at the same junction (v above it, and the braking to it an
  // S-curve that ends with zero acceleration: the speed taken back to zero acceleration at the
  // plan's jerk is still above the limit). That braking is the speed limit's own check (its
  // plan and reserve, which the calculation steps keep) and takes the deceleration back before
  // the junction too. dec_room alone takes it back at once and keeps two steps' reach at the
  // speed that leaves, which for a motion braking hard towards a junction of 0.04 mm/s was more
  // room than the braking itself: wide sweep seed 26 program 280 (X: 22.6 mm/s^2, 11,300
  // mm/s^3, 1 ms cycles) eased a braking of 5,000 mm/s^2 at 16 mm/s that was 5e-6 mm short of
  // its plan and crossed the junction at 12.3 mm/s (corner step 37 x the tolerance, then 0.5 s
  // above X's velocity limit). When the braking falls short, the speed limit is then missed by
  // that little, and the deceleration limit by what the braking still carries into the junction.
  // The speed limit may lie at an earlier junction than ck's (junction_v: the lowest hard
  // junction limit up to ck's): braking to it ends with a = 0 there, before ck. Judged by ck's
  // own junction only, wide sweep seed 148 program 290 braked along an arc (3,300 mm/s^2,
  // 9.8e5 mm/s^3) for a corner of 0.13 mm/s into chords led by Y (77 mm/s^2, 3e4 mm/s^3): the
  // chords' deceleration limits wanted the deceleration taken back at the chords' jerk, held the
  // braking to 1,087 mm/s^2 where the corner needed 1,157, and the motion crossed at 12.9 mm/s
  // (corner steps of 100 x the tolerance, then Y at 6.6 x its acceleration limit).
  bool dec_kept(double v, double a, const Constraint& ck, double room) const {
    if (dec_room(v, a, ck) <= room) return true;
    return v > ck.junction_v &&
           jerk::settled_velocity(v, a, kPlanMarginJ * ck.junction_j) > ck.junction_v;
  }

  // Next non-pass record after `q` is a stop, or the buffer ends there.
  // Bounded work: beyond kMaxExtendPerStep pass records it answers true (a standstill at the
  // record's end then counts as an arrival; only reached with that many messages / continuous M
  // in a row).
  bool stop_follows(std::uint64_t q) const {
    for (std::uint64_t k = q + 1; k < tail && k <= q + kMaxExtendPerStep; ++k) {
      const Rec& r = R(k);
      if (r.kind == RecKind::kMotion) return false;
      if (r.kind == RecKind::kStop) return true;
    }
    return true;
  }

  void begin_block() {
    blk_peak = 0.0;
    blk_factor = LimitFactor::kNone;
    blk_t0 = time_s;
  }

  void end_block(std::uint64_t q, double t_end) {
    if (n_blocks >= blocks.size()) return;
    const Segment& sg = S(q);
    const Rec& r = R(q);
    BlockReport& b = blocks[n_blocks++];
    b.act_part = static_cast<std::int32_t>(q - base + 1);
    b.line = sg.line;
    b.g = static_cast<std::int32_t>(sg.type);
    b.length_mm = r.g.length;
    b.programmed_mm_min = r.f * 60.0;
    b.peak_mm_min = blk_peak * 60.0;
    b.duration_s = t_end - blk_t0;
    b.end_s = t_end;
    b.factor = blk_factor;
  }

  void execute_pass(std::uint64_t q) {
    const Segment& sg = S(q);
    if (sg.type == SegmentType::kMFunction) {
      emit(kEvContinuousM, sg.m, q);
    } else if (sg.type == SegmentType::kMessage) {
      emit(kEvMessage, R(q).msg_slot, q);
    } else if (sg.is_motion()) {
      reg.act_g_func = static_cast<std::int32_t>(sg.type);
    }
    reg.tool_number = sg.tool;
  }

  void copy_params(std::uint64_t q) { copy_params_from(par[ring_index(q)]); }

  void copy_params_from(const MParams& p) {
    for (int i = 0; i < kMFunctionParameters; ++i) {
      reg.m_function_parameter[static_cast<std::size_t>(i)] =
          i < kParamLetters ? p[static_cast<std::size_t>(i)] : kNotSet;
    }
  }

  // Executes records from `cur` on until a motion starts, a stop waits, or the buffer ends.
  void process_records() {
    while (cur < tail) {
      const Rec& r = R(cur);
      const Segment& sg = S(cur);
      if (r.kind == RecKind::kPass) {
        execute_pass(cur);
        ++cur;
        continue;
      }
      if (r.kind == RecKind::kMotion) {
        on_path = true;
        st = jerk::State{};
        reset_window();
        mode = Mode::kMoving;
        reg.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
        reg.act_g_func = static_cast<std::int32_t>(sg.type);
        reg.tool_number = sg.tool;
        begin_block();
        return;
      }
      // Stop record.
      on_path = false;
      reg.tool_number = sg.tool;
      if (sg.type == SegmentType::kDwell) {
        mode = Mode::kDwell;
        reg.act_g_func = 4;
        dwell_left = static_cast<std::int64_t>(std::llround(sg.dwell_s / dt));
        if (dwell_left <= 0) {
          ++cur;
          continue;
        }
        reg.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
        return;
      }
      if (sg.m_kind == MKind::kProgramEnd) {
        reg.act_m_func = sg.m;
        copy_params(cur);
        mode = Mode::kIdle;
        ++cur;  // the end record is executed
        end_program();
        return;
      }
      if (sg.m_kind == MKind::kProgramStop) {
        reg.act_m_func = sg.m;
        copy_params(cur);
        mode = Mode::kIdle;
        paused_m0 = true;
        settle_into(InterpolatorStatus::kReady);
        return;
      }
      // Normal M: handed to the PLC (M_Func, Act_M_Func, parameters, Run_Flag WAIT_MFUNC) when
      // it leaves the spline with the motion; the wait for M_Func = 0 starts then.
      mode = Mode::kWaitM;
      m_pending = true;
      emit(kEvNormalM, sg.m, cur);
      reg.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
      return;
    }
    // Buffer exhausted.
    on_path = false;
    mode = Mode::kIdle;
    if (complete) {
      end_program();
    } else {
      settle_into(InterpolatorStatus::kUnderrun);
    }
  }

  // Status 3 only once every axis, delayed or filtered, stands exactly where the program ends
  // (the IIR filter snaps onto its input once the lag is below 1e-12 mm).
  void end_program() { settle_into(InterpolatorStatus::kEnded); }

  // The path generator stands: `s` (3, 4, 7 or 8) becomes Status once the smoothed axes stand
  // too. With the spline on, Status 7 after an emergency stop, 4 after a stop or at M0 and 8 at
  // an underrun used to show up to 50 ms before the axes stood, while they still moved at full
  // feed: a PLC that drops the drive enable at Status 7, or opens a guard at M0, did it
  // mid-motion. Until then an emergency stop shows Status 6 (the axes are still braking).
  void settle_into(InterpolatorStatus s) {
    if (smooth->at_rest()) {
      settle_status = 0;
      reg.status = static_cast<std::int32_t>(s);
      return;
    }
    settle_status = static_cast<std::int32_t>(s);
    if (s == InterpolatorStatus::kEmergencyStopped) {
      reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp);
    } else if (reg.status != static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp)) {
      reg.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
    }
  }

  // The Status the interpolator is in: the one it settles into, or Status.
  InterpolatorStatus status_now() const {
    return static_cast<InterpolatorStatus>(settle_status != 0 ? settle_status : reg.status);
  }

  // Queues an event for the input sample the current calculation step is computing.
  void emit(std::int32_t kind, std::int32_t value, std::uint64_t q) {
    SmoothingEvent e{kind, value, 0};
    if (kind != kEvMessage) {
      e.tag = ev_par_next;
      ev_par[ev_par_next] = par[ring_index(q)];
      ev_line[ev_par_next] = S(q).line;
      ev_par_next = (ev_par_next + 1) % ev_par.size();
    }
    if (!smooth->push_event_next(e)) {
      // More than kEventCapacity events inside the spline: the oldest leaves early, so that
      // they still reach M_Func in program order. The new one used to be handed over at once,
      // ahead of every one queued (M1257 before M1256, and Last_Cont_M_Func ended on M1256
      // where the program's last was M1300: session 75).
      SmoothingEvent oldest;
      if (smooth->pop_oldest(&oldest)) {
        ++early_events;
        apply_event(oldest);
      }
      if (!smooth->push_event_next(e)) apply_event(e);
    }
  }

  // An event leaves the smoothing: the register writes of the hand-over; an M-function after
  // another one in the same cycle waits for the next (m_deferred).
  void apply_event(const SmoothingEvent& e) {
    const bool is_m = e.kind == kEvNormalM || e.kind == kEvContinuousM;
    if (is_m && (m_announced || m_deferred_n > 0)) {
      if (m_deferred_n == static_cast<int>(m_deferred.size())) {
        // Full (more than kMaxDeferredM M-functions in a row): the oldest waiting one reaches
        // M_Func now, in this cycle after the one already there, and the new one queues
        // behind the rest. M_Func shows them in program order and m_func_count counts each;
        // a PLC reading once a cycle misses those overwritten in the cycle. (The new one used
        // to be handed over at once, ahead of the 64 queued before it.)
        const SmoothingEvent oldest = m_deferred[0];
        for (std::size_t i = 1; i < m_deferred.size(); ++i) m_deferred[i - 1] = m_deferred[i];
        m_deferred.back() = e;
        hand_over(oldest);
        return;
      }
      m_deferred[static_cast<std::size_t>(m_deferred_n++)] = e;
      return;
    }
    if (is_m) m_announced = true;
    hand_over(e);
  }

  // At a cycle's start: the oldest deferred M-function reaches M_Func.
  void hand_over_deferred_m() {
    m_announced = false;
    if (m_deferred_n == 0) return;
    const SmoothingEvent e = m_deferred[0];
    for (int i = 1; i < m_deferred_n; ++i)
      m_deferred[static_cast<std::size_t>(i - 1)] = m_deferred[static_cast<std::size_t>(i)];
    --m_deferred_n;
    m_announced = true;
    hand_over(e);
  }

  void hand_over(const SmoothingEvent& e) {
    switch (e.kind) {
      case kEvNormalM:
        if (!m_pending) break;  // the program was cleared meanwhile
        reg.m_func = e.value;
        reg.act_m_func = e.value;
        reg.m_func_count += 1;
        reg.m_func_line = ev_line[static_cast<std::size_t>(e.tag)];
        copy_params_from(ev_par[static_cast<std::size_t>(e.tag)]);
        m_pending = false;
        wait_m_first = mode == Mode::kWaitM || resume_wait_m;
        break;
      case kEvContinuousM:
        reg.m_func = e.value;
        reg.act_m_func = e.value;
        reg.last_cont_m_func = e.value;
        reg.m_func_count += 1;
        reg.m_func_line = ev_line[static_cast<std::size_t>(e.tag)];
        copy_params_from(ev_par[static_cast<std::size_t>(e.tag)]);
        break;
      case kEvMessage:
        reg.message_count += 1;
        reg.message_slot = e.value;
        msg_by_count[reg.message_count % kMessageRing] = e.value;
        break;
      default:
        break;
    }
  }

  // After calculation step k of the path: Orig_Position through the smoothing, events out.
  // With both smoothing stages off only the cycle's last two steps make Position and Speed
  // (the registers read them after the cycle); the others leave out the path position (on an
  // arc a sine and a cosine) and count the step.
  void smooth_step(int k) {
    if (k < kCalcSteps - 2 && smooth->passes_through()) {
      smooth->step_unread();
    } else {
      double p[kMaxAxes];
      for (int i = 0; i < kMaxAxes; ++i) p[i] = rest[static_cast<std::size_t>(i)];
      current_position(p);
      smooth->step(p);
    }
    SmoothingEvent e;
    while (smooth->pop_event(&e)) apply_event(e);
    if (settle_status != 0 && smooth->at_rest()) {
      reg.status = settle_status;
      settle_status = 0;
    }
  }

  // ================= commands =================

  bool standing() const { return mode != Mode::kMoving && mode != Mode::kStopping && mode != Mode::kEmergency; }

  CommandContext command_context() const {
    CommandContext c;
    c.standing = standing();
    const auto s = status_now();
    // While the axes settle into a stop the interpolator counts as idle (a position set or a
    // ratio waits for them at Command_Status 1, as before a stop's Status 4 waited for them).
    c.idle = mode == Mode::kIdle &&
             (s == InterpolatorStatus::kEmpty || s == InterpolatorStatus::kEnded ||
              s == InterpolatorStatus::kReady || s == InterpolatorStatus::kEmergencyStopped ||
              s == InterpolatorStatus::kUnderrun);
    c.number_axes = reg.number_axes;
    c.configured_axes = static_cast<int>(cfg.axes.size());
    c.between_programs =
        s == InterpolatorStatus::kEmpty || s == InterpolatorStatus::kEnded ||
        (s == InterpolatorStatus::kEmergencyStopped && !resumable_estop) ||
        (s == InterpolatorStatus::kReady && reg.move_distance == 0.0 && !paused_m0);
    c.holds_program = s == InterpolatorStatus::kReady || s == InterpolatorStatus::kUnderrun ||
                      (s == InterpolatorStatus::kEmergencyStopped && resumable_estop);
    return c;
  }

  // The smoothing lets the (valid) command execute now; otherwise it waits at Command_Status 1.
  bool stage_ready(std::int32_t code, const std::array<std::int32_t, kCommandParameters>& p) const {
    switch (code) {
      case kCommandSetRatio:
      case kCommandSetPositionOn:
      case kCommandSetPositionOff:
        return smooth->settled() && settle_status == 0;
      case kCommandSpline:
        return smooth->spline().settled() && smooth->pending_events() == 0;
      case kCommandIir: {
        const std::uint32_t now = smooth->iir().mask(), want = static_cast<std::uint32_t>(p[3]);
        for (int i = 0; i < smooth->axes(); ++i) {
          const std::uint32_t bit = 1u << i;
          if ((now & bit) && !(want & bit) && !smooth->iir().settled(i)) return false;
          // An entering axis starts at rest on its input: the input must stand, or its motion
          // behind the spline became a velocity step (34 mm/s to 1.4 in one cycle).
          if (!(now & bit) && (want & bit) && !smooth->spline().settled()) return false;
        }
        return true;
      }
      default:
        return true;
    }
  }

  RequestResult finish_command(const RequestResult& r) {
    command_end(reg, r);
    if (r.ok()) cmd_error.clear();
    else cmd_error = r.reason;
    fill_registers();
    return r;
  }

  RequestResult run_command(std::int32_t code, const std::array<std::int32_t, kCommandParameters>& p) {
    std::array<double, kMaxAxes> pos{};
    const RequestResult r = execute_command(code, p, command_context(), *smooth, *ostage, &pos);
    if (r.ok() && (code == kCommandSetPositionOn || code == kCommandSetPositionOff)) {
      place(pos);
      reg.off_trajectory = code == kCommandSetPositionOff ? 1 : 0;
    }
    return finish_command(r);
  }

  // A command waiting at Command_Status 1: executes when the smoothing lets it, ends with -1
  // when the state no longer allows it (e.g. a program was started meanwhile).
  void poll_pending_command() {
    if (pend_code == 0) return;
    const std::int32_t code = pend_code;
    const RequestResult c = check_command(code, pend_par, command_context());
    if (!c.ok()) {
      pend_code = 0;
      finish_command(c);
      ++unexecuted;
      unexecuted_reason = c.reason;
    } else if (stage_ready(code, pend_par)) {
      pend_code = 0;
      run_command(code, pend_par);
    }
  }

  void cancel_pending_command(std::int32_t by) {
    if (pend_code == 0) return;
    const std::int32_t code = pend_code;
    pend_code = 0;
    command_end(reg, {RequestCode::kWrongState,
                      "Command " + std::to_string(code) + ": cancelled by Command " + std::to_string(by)});
    cmd_error = "Command " + std::to_string(code) + ": cancelled by Command " + std::to_string(by);
    ++unexecuted;
    unexecuted_reason = cmd_error;
  }

  // New position of a standing interpolator without a program (set_position, 2048 / 2049).
  void place(const std::array<double, kMaxAxes>& position_mm) {
    ++position_set_count;
    drop_records_at(position_mm.data());
    double p[kMaxAxes];
    for (int i = 0; i < kMaxAxes; ++i) p[i] = rest[static_cast<std::size_t>(i)];
    smooth->reset(p);
    ostage->reset(p);
    ostage->update(p, 0.0);
    reg.off_trajectory = 0;
    reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmpty);
  }

  // Solves s(tau) = dist inside a calculation step for the crossing time.
  double crossing_time(const jerk::State& b, double j, double dist) const {
    double lo = 0.0, hi = dt;
    double tau = b.v > 1e-12 ? std::clamp(dist / b.v, 0.0, dt) : 0.5 * dt;
    for (int it = 0; it < 60; ++it) {
      const double f = travel(b.v, b.a, j, tau) - dist;
      // On the root (a cruise: tau = dist / v exactly): the Newton step would stay on it and the
      // bracket test below then bisected away from it, 47 halvings down to 1e-18 s, in every
      // junction crossed (the largest cost of a checked short-segment simulation).
      if (f == 0.0) return tau;
      if (f > 0.0) hi = tau; else lo = tau;
      const double fp = speed_after(b.v, b.a, j, tau);
      double nt = fp > 0.0 ? tau - f / fp : 0.5 * (lo + hi);
      if (!(nt > lo && nt < hi)) nt = 0.5 * (lo + hi);
      if (std::fabs(nt - tau) < 1e-18 || hi - lo < 1e-18) {
        tau = nt;
        break;
      }
      tau = nt;
    }
    return tau;
  }

  // An upper bound, closed-form and continuous in the step's end state ns, of the speed at which
  // the calculation step from b passes the point d0 ahead (within the step's travel). The speed
  // is a quadratic in time over the step; with vm its highest value, the point is not reached
  // before d0 / vm, and from there to the step's end the speed is at most the quadratic's
  // largest value on that interval. (Solving for the crossing time, crossing_time, inside the
  // search for the largest passing acceleration raised the worst step() from 3.3 to 5.0 us.)
  double crossing_speed_bound(const jerk::State& b, const jerk::State& ns, double d0) const {
    const double j = (ns.a - b.a) / dt;
    auto v_at = [&](double t) { return speed_after(b.v, b.a, j, t); };
    // Interior maximum: the acceleration turns from positive to negative inside the step.
    const double t_peak = b.a > 0.0 && ns.a < 0.0 ? -b.a / j : -1.0;
    double vm = std::max(b.v, ns.v);
    if (t_peak > 0.0) vm = std::max(vm, v_at(t_peak));
    const double t_lo = vm > 0.0 ? std::min(dt, d0 / vm) : 0.0;
    double v = std::max(v_at(t_lo), ns.v);
    if (t_peak > t_lo) v = std::max(v, v_at(t_peak));
    return v;
  }

  // The acceleration at the earliest time the calculation step from b to ns can pass the point
  // d0 ahead (within the step's travel): d0 / vm, vm the step's highest speed, as in
  // crossing_speed_bound. The acceleration is linear in time over the step, so where it falls
  // this bounds the acceleration at the point from above (crossing_accel_bound), where it rises
  // from below (the deceleration limits, decel_limits). Closed-form and continuous in ns.
  double accel_at_earliest_crossing(const jerk::State& b, const jerk::State& ns, double d0) const {
    const double j = (ns.a - b.a) / dt;
    const double t_peak = b.a > 0.0 && ns.a < 0.0 ? -b.a / j : -1.0;
    double vm = std::max(b.v, ns.v);
    if (t_peak > 0.0) vm = std::max(vm, speed_after(b.v, b.a, j, t_peak));
    const double t_lo = vm > 0.0 ? std::min(dt, d0 / vm) : 0.0;
    return b.a + j * t_lo;
  }

  // An upper bound of the acceleration at which the step from b to ns passes d0: rising over the
  // step, the end's.
  double crossing_accel_bound(const jerk::State& b, const jerk::State& ns, double d0) const {
    return ns.a >= b.a ? ns.a : accel_at_earliest_crossing(b, ns, d0);
  }

  void record_corner(std::uint64_t qin, std::uint64_t qout, const jerk::State& b, double j,
                     double dist, int calc_index) {
    if (!opt.record_corner_events || n_events >= events.size()) return;
    const double tau = crossing_time(b, j, dist);
    const double vj = speed_after(b.v, b.a, j, tau);
    const double aj = b.a + j * tau;
    double t_in[kMaxAxes], t_out[kMaxAxes], k_in[kMaxAxes], k_out[kMaxAxes];
    const Geometry& gi = R(qin).g;
    const Geometry& go = R(qout).g;
    motion::geometry_tangent(gi, n, gi.length, t_in);
    motion::geometry_tangent(go, n, 0.0, t_out);
    motion::geometry_curvature(gi, n, gi.length, k_in);
    motion::geometry_curvature(go, n, 0.0, k_out);
    CornerEvent& e = events[n_events++];
    e.cycle = reg.cycle;
    e.fraction = (calc_index * dt + tau) / T;
    e.line = S(qout).line;
    for (int i = 0; i < kMaxAxes; ++i) {
      if (i < n) {
        e.dv[static_cast<std::size_t>(i)] = vj * (t_out[i] - t_in[i]);
        const auto u = static_cast<std::size_t>(i);
        e.da_curvature[u] = vj * vj * (k_out[i] - k_in[i]);
        e.da[u] = aj * (t_out[i] - t_in[i]) + e.da_curvature[u];
      } else {
        e.dv[static_cast<std::size_t>(i)] = 0.0;
        e.da[static_cast<std::size_t>(i)] = 0.0;
        e.da_curvature[static_cast<std::size_t>(i)] = 0.0;
      }
    }
  }

  // Arrival at a stop point or the end of the buffer while moving, at the end of a record of
  // jerk limit j_rec.
  void arrive(double v_before, double j_rec) {
    if (v_before > std::max(kArriveV, kArriveStepShare * j_rec * dt * dt)) ++hard_stop_count;
    st.v = 0.0;
    st.a = 0.0;
    rest_phase = 2;
  }

  // Finishes a ramp (stop command or emergency) at standstill.
  void finish_ramp() {
    st.v = 0.0;
    st.a = 0.0;
    rest_phase = 2;
    const bool emergency = mode == Mode::kEmergency;
    mode = Mode::kIdle;
    reg.command = 0;
    reg.command_status = 0;
    if (emergency) {
      settle_into(InterpolatorStatus::kEmergencyStopped);
      resumable_estop = !stop_off;
    } else {
      settle_into(InterpolatorStatus::kReady);
    }
    if (stop_off) abandon_program();
    stop_off = false;
  }

  // Drops every record not yet executed while standing (clear, a Number_Axes write): the
  // position stays where it is, on a record's path (a stop on the trajectory) or at rest, and
  // is where whatever is appended next starts. A Number_Axes write that kept the record's
  // position on the path but planned the next program from the last rest point made
  // Orig_Position jump there (RandomRequests, wide seed 10 case 40).
  void drop_records() {
    double p[kMaxAxes];
    current_position(p);
    drop_records_at(p);
  }
  // The same with `at` [mm, n axes] as the rest point (a position set).
  void drop_records_at(const double* at) {
    for (int i = 0; i < n; ++i) rest[static_cast<std::size_t>(i)] = at[i];
    on_path = false;
    mode = Mode::kIdle;
    paused_m0 = false;
    resume_wait_m = false;
    resume_dwell = false;
    resumable_estop = false;
    m_pending = false;
    m_deferred_n = 0;
    settle_status = 0;
    clear_section_registers();
    tail = cur;
    base = cur;
    complete = false;
    st = jerk::State{};
    reset_plan_tail();
    lookahead_dirty = true;
  }

  // Nothing executes now: the registers of the dropped (or ended) program's section go with it
  // (after a clear, Act_Part 0 stood beside that program's line, G, M and feed, so a panel
  // showed "M30" at the first line of the next program; a Command 9 / 5 and a new program
  // loaded after the end kept them too). An M-function of it that the PLC has not acknowledged
  // goes too: M_Func 51 stayed through a clear and two programs, and a PLC started later
  // executed it. Tool_Number (the tool in the spindle) and Last_Cont_M_Func (a "stored value",
  // the manual) stay.
  void clear_section_registers() {
    // An M-function handed over and not acknowledged goes with the program: its PLC's late
    // acknowledgement is told so (it was refused as "acknowledged already: a second PLC").
    if (reg.m_func != 0) {
      dropped_m_count = reg.m_func_count;
      dropped_m = reg.m_func;
    }
    reg.m_func = 0;
    reg.move_distance = 0.0;
    reg.act_part = 0;
    reg.act_line = 0;
    reg.act_g_func = 0;
    reg.act_m_func = 0;
    reg.set_speed = 0.0;
  }

  // Drops the program (off trajectory): the position stays where it is.
  void abandon_program() {
    double p[kMaxAxes];
    current_position(p);
    for (int i = 0; i < n; ++i) rest[i] = p[i];
    on_path = false;
    paused_m0 = false;
    resume_wait_m = false;
    resume_dwell = false;
    tail = cur;
    complete = false;
    reset_plan_tail();
    clear_section_registers();
    reg.off_trajectory = 1;
    // A normal M-function still inside the spline belongs to the dropped program: it must not
    // reach M_Func (it did, 40 ms after the drop, and a PLC took it for a continuous one).
    m_pending = false;
    // Status 0 at once, also while the axes still settle: it says nothing loaded, not where the
    // axes are, and the next program may be loaded at once. Status 7 waits for them.
    if (status_now() != InterpolatorStatus::kEmergencyStopped) {
      settle_status = 0;
      reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmpty);
    }
    lookahead_dirty = true;
  }

  void reset_plan_tail() {
    cons_valid = false;
    st_g.clear();
    st_f.clear();
    st_a.clear();
    dq_a.clear();
    dq_j.clear();
    dq_wg.clear();
    dq_wf.clear();
    win_end = cur;
    pt_end = rest;
    pt_have_motion = false;
    pt_stop_since = true;
    s_tail = 0.0;
    jh_count = 0;
  }

  // Bracket [xs, xu] of a limit's largest passing x: g(xs) <= 0 (when have_gs), g(xu) > 0,
  // with g = excess - kExcessTol.
  struct Bracket {
    double xs, xu, gs, gu;
    bool have_gs;
  };

  // Bisection between an x that passes `ok` and one that fails it (either may be the larger);
  // returns the passing end after n halvings.
  template <class P>
  static double bisect(double pass, double fail, const P& ok, int n) {
    for (int it = 0; it < n; ++it) {
      const double mid = 0.5 * (pass + fail);
      if (ok(mid))
        pass = mid;
      else
        fail = mid;
    }
    return pass;
  }

  // Evaluates g at x inside b and moves the end on x's side there.
  template <class G>
  static void narrow(Bracket& b, double x, const G& g) {
    const double gx = g(x);
    if (gx <= 0.0) {
      b.xs = x;
      b.gs = gx;
      b.have_gs = true;
    } else {
      b.xu = x;
      b.gu = gx;
    }
  }

  // A guess of the root: g at the guess, then at `step` beside it towards the other end. When
  // the root lies within `step` of the guess, that leaves a bracket of width `step`.
  template <class G>
  static void try_guess(Bracket& b, double guess, double step, const G& g) {
    if (!(guess > b.xs + 0.5 * step && guess < b.xu - 0.5 * step)) return;
    narrow(b, guess, g);
    const double other = b.xs == guess ? guess + step : guess - step;
    if (other > b.xs && other < b.xu) narrow(b, other, g);
  }

  // The largest end-of-step acceleration in [xs, xu] that every violated limit accepts, to the
  // resolution of ten bisection steps ((xu - xs) / 1024) or max_tol if finer, given that xs
  // passes and xu fails.
  // One limit almost always binds alone. Start with limit k (excess e_u at xu: the one the
  // previous step rode when it fails again, else the one that failed worst); when another
  // limit rejects the result, that one binds below it: solve for it inside [xs, result] and
  // check again. Each limit's excess is monotone in x, so no passing x above the result is
  // missed; after `rounds` limits, bisection on all decides. On return k is the limit that
  // binds at the result.
  //
  // Per limit, guesses before a regula falsi (Anderson-Bjorck): `boundary(k, out)` (up to two),
  // the x whose end-of-step state just needs no braking for k any more (the velocity after
  // taking the acceleration back equals the limit; for an acceleration limit into a record of
  // lower jerk its w, where the excess jumps), and `ride`, the x of the previous step's
  // jerk. Near that boundary the excess is not smooth: a step when accelerating towards the
  // limit (no braking needed below it, a whole ramp-down above), a square-root cliff at the end
  // of a braking (the plan turns into a pure release); no secant method converges there, and a
  // dozen evaluations per step were common. The boundary guess brackets those roots in two
  // evaluations, the ride guess a steady ride's.
  template <class Excess, class Fails, class Boundary>
  static double largest_passing(double xs, double xu, const Excess& excess, int& k, double e_u,
                                const Fails& first_failing, int rounds, const Boundary& boundary,
                                double ride, double max_tol) {
    const double lo = xs, hi = xu;
    const double tol = std::min((xu - xs) / 1024.0, max_tol);
    for (int round = 0; round < rounds; ++round) {
      const auto g = [&](double x) { return excess(x, k) - kExcessTol; };
      Bracket b{xs, xu, 0.0, e_u - kExcessTol, false};
      double guess[2];
      const int n_guess = boundary(k, guess);
      for (int i = 0; i < n_guess && b.xu - b.xs > tol; ++i) try_guess(b, guess[i], 0.5 * tol, g);
      if (round == 0 && b.xu - b.xs > tol) try_guess(b, ride, 2.0 * tol, g);
      if (!b.have_gs) b.gs = g(b.xs);
      int side = 0;  // the side moved last: -1 passing end, +1 failing end
      bool bisect = false;
      for (int it = 0; it < 12 && b.xu - b.xs > tol; ++it) {
        double xn = 0.5 * (b.xs + b.xu);
        if (!bisect && std::isfinite(b.gs) && std::isfinite(b.gu) && b.gu > b.gs) {
          xn = b.xs + (b.xu - b.xs) * (-b.gs / (b.gu - b.gs));
        }
        xn = std::clamp(xn, b.xs + 0.5 * tol, b.xu - 0.5 * tol);
        const double gn = g(xn);
        // Anderson-Bjorck: when the same end moves twice in a row, the other end's value is
        // scaled by 1 - g_new / g_old (Illinois' fixed 1/2 when that is not positive). A
        // passing end on a plateau (no braking needed: -remain, nearly constant) carries no
        // slope: bisect.
        bisect = false;
        if (gn <= 0.0) {
          if (side == -1) {
            const double m = 1.0 - gn / b.gs;
            if (m < 1e-3) bisect = true;
            b.gu *= m > 0.0 ? m : 0.5;
          }
          b.xs = xn;
          b.gs = gn;
          side = -1;
        } else {
          if (side == +1) {
            const double m = 1.0 - gn / b.gu;
            b.gs *= m > 0.0 ? m : 0.5;
          }
          b.xu = xn;
          b.gu = gn;
          side = +1;
        }
      }
      xs = b.xs;
      double e = 0.0;
      const int f = first_failing(xs, k, &e);
      if (f < 0) return xs;  // k binds
      // Limit f fails at xs: its largest passing x is below xs.
      k = f;
      xu = xs;
      e_u = e;
      xs = lo;
    }
    xs = lo;
    xu = hi;
    for (int it = 0; it < 10; ++it) {
      const double mid = 0.5 * (xs + xu);
      const int f = first_failing(mid, -1, nullptr);
      if (f < 0) {
        xs = mid;
      } else {
        xu = mid;
        k = f;
      }
    }
    return xs;
  }

  // A braking that rode a limit's plan and now fails it at the hardest braking (lo), but only by
  // the quantised jerk allowance (the plan still fits with less of it), has used that much of
  // the allowance on the lag of the steps that followed the plan across its turns, and each
  // check asks for all of it again. It keeps riding the limit with the largest share of the
  // allowance that lo still keeps, instead of falling back to best effort, whose release floor
  // eased a braking that missed by 3e-8 mm into a crossing at 11 x the corner's limit (the
  // simulate fuzz's wide seed 8 input; wide sweep seed 22 program 221 at 8 x). All of it at once
  // was too much for a braking of three steps (wide seed 41 program 284 then crossed at 5.6 x).
  // Only when every limit that fails at lo is a speed limit w > 0 other than the feed x Rel_Speed:
  // stop points need the allowance to arrive at rest (TGM_SEED=4 program 97). When it applies,
  // `allowance` holds that share (the caller sets it back to 1), k the limit that fails at xu
  // and e_k its excess (k = -1: xu passes every limit).
  template <class Excess, class Fails>
  bool spend_allowance(double lo, double xu, const int* viol, int nv, const Excess& excess,
                       const Fails& first_failing, int& k, double& e_k) {
    for (int i = 0; i < nv; ++i) {
      const Constraint& ck = cons[static_cast<std::size_t>(viol[i])];
      if (excess(lo, viol[i]) > kExcessTol && (ck.accel || ck.soft || !(ck.w > 0.0))) return false;
    }
    allowance = 0.0;
    if (first_failing(lo, -1, nullptr) >= 0) {
      allowance = 1.0;
      return false;
    }
    // The largest share of the allowance the hardest braking still keeps (to 1/64).
    double keep = 0.0, fail = 1.0;
    for (int it = 0; it < 6; ++it) {
      allowance = 0.5 * (keep + fail);
      (first_failing(lo, -1, nullptr) < 0 ? keep : fail) = allowance;
    }
    allowance = keep;
    k = first_failing(xu, -1, &e_k);
    return true;
  }

  // One calculation step of motion along the path.
  void motion_step(int calc_index) {
    if (calc_index == 0 || !cons_valid) {
      update_window(cons_Aw, cons_Jw);
      ncons = gather(cons.data(), cons_Aw, cons_Jw, horizon);
      cons_here = R(cur).s0 + st.s;
      cons_valid = true;
      cruise_valid = false;
      // Until the next gather `cur` stays (crossing a junction gathers again), so its jerk
      // limit bounds every step's (step_limits), and no step ends above max(a, its tangential
      // limit) or gains more than J dt of acceleration. The velocity bound ignores the cap.
      const Rec& rc = R(cur);
      const double tr = (kCalcSteps - calc_index) * dt;
      const double ap = std::max(st.a, 0.0);
      cons_ac = std::min(ap + rc.jt * tr, std::max(ap, rc.at));
      cons_vc = (st.v + tr * (ap + 0.5 * rc.jt * tr)) * (1.0 + 1e-12) + 1e-12;
      cons_bounds = calc_index < kCalcSteps - 1;
    }
    const double Aw = cons_Aw, Jw = cons_Jw;
    double A = 0.0, J = 0.0;
    const Rec& rc = R(cur);
    const jerk::State before = st;
    const double v = st.v, a = st.a;
    double x = 0.0;
    const bool was_braking_to_stop = braking_to_stop;
    const double ride_before = ride_jerk;  // stays kInf unless this step rides a limit again
    ride_jerk = kInf;
    braking_to_stop = false;
    double vt = 0.0;
    {
      // A stop command (8/9, 4/5) is a target speed of zero: the limits ahead (corners, arcs,
      // softer records, stop points) still bind while it brakes, as they did before it. Braking
      // towards zero alone, at the window's lowest limits, ran through a corner at 46 mm/s
      // (axis velocity steps of 13 and 48 x the tolerance) when the motion was braking harder
      // for it with the current record's limits (stop sweep seed 1 program 3). The emergency
      // ramp has every tangential acceleration and jerk limit scaled by rho (the emergency /
      // normal deceleration ratio, which the limit checker allows during it).
      const bool stopping = mode == Mode::kEmergency || mode == Mode::kStopping;
      const double sc = mode == Mode::kEmergency ? rho : 1.0;
      step_limits(A, J);
      A *= sc;
      J *= sc;
      LimitFactor target_reason = LimitFactor::kStopCommand;
      if (!stopping) vt = target_speed(rc, target_reason);
      double lo = std::max(a - J * dt, -A);
      double hi = std::min(a + J * dt, A);
      if (lo > hi) {  // |a| above a limit that just dropped: recover at full jerk
        if (a > A) hi = lo = std::max(a - J * dt, -A);
        else lo = hi = std::min(a + J * dt, A);
      }
      Constraint dec[kMaxDecelLimits];
      const int n_dec = decel_limits(v, a, J, A, hi, sc, dec);
      lo = std::max(lo, std::min(jerk::floor_acceleration(v, a, kFloorMarginJ * J, dt), hi));
      const double moved = rc.s0 + before.s - cons_here;  // since the constraints were gathered
      land_below_step_resolution(v, a, J, moved, lo, hi);
      double xd = std::clamp(jerk::track_velocity(v, a, vt, A, J, dt), lo, hi);
      // Landing on vt takes the acceleration back over the records ahead: with a lower jerk
      // limit there than this step's, a landing planned at J overshoots vt (by up to 0.06 % of
      // the feed on chords whose direction turns towards an axis). Not while even a landing at
      // the window's lowest jerk limit would not bind yet (most of an acceleration).
      if (xd > 0.0 && v < vt && Jw < J && jerk::landing_acceleration(v, a, vt, Jw, dt) < xd) {
        const double Jl = landing_jerk(std::max(a, xd), vt, J, Jw);
        // Never above the landing at J: this step may still take acceleration back at J.
        if (Jl < J && jerk::landing_acceleration(v, a, vt, Jl, dt) < xd) {
          double xl = jerk::track_velocity(v, a, vt, A, Jl, dt);
          // Still decelerating: taking that back is not part of the landing and may use this
          // step's jerk; only the acceleration built above zero must come back at Jl.
          if (a < 0.0)
            xl = std::max(xl, std::min(jerk::landing_acceleration(v, a, vt, Jl, dt), hi));
          xd = std::min(xd, std::clamp(xl, lo, hi));
        }
      }
      // The same for a deceleration towards a lower target (an override decrease, a lower feed):
      // released over the records ahead at their lower jerk limit, a deceleration built at J
      // undershoots vt (sweep seed 15 program 529: by 10 % after an override drop from 1.89 to
      // 0.65 on chords whose path jerk falls from 34,000 to 12,400 mm/s^3). The speed stays
      // below v while landing, which bounds the distance the release crosses.
      if (xd < 0.0 && v > vt && sc * Jw < J &&
          jerk::landing_acceleration(v, a, vt, sc * Jw, dt) > xd) {
        const double Jl = landing_jerk(std::max(-a, -xd), v, J, sc * Jw);
        if (Jl < J && jerk::landing_acceleration(v, a, vt, Jl, dt) > xd) {
          double xl = jerk::track_velocity(v, a, vt, A, Jl, dt);
          // Still accelerating: taking that back is not part of the landing (this step's jerk).
          if (a > 0.0)
            xl = std::min(xl, std::max(jerk::landing_acceleration(v, a, vt, Jl, dt), lo));
          xd = std::max(xd, std::clamp(xl, lo, hi));
        }
      }
      // Lowest x from which every deceleration above a record's limit ahead can still be taken
      // back before the record (monotone in x while the motion does not reverse). Tracking the
      // target (an override decrease, a lower feed) never goes below it; braking for a limit
      // ahead does only when that limit cannot be kept otherwise.
      double lo_dec = lo;
      // Distance [mm] to the nearest deceleration limit that x = xx does not keep, kInf when it
      // keeps them all (dec is in path order).
      auto dec_failing_at = [&](double xx) {
        const jerk::State ns = jerk::advance(before, xx, dt);
        const double ds = ns.s - before.s;
        for (int i = 0; i < n_dec; ++i) {
          const Constraint& ck = dec[i];
          if (ck.d - ds <= 0.0) {
            // Entered in this step: the deceleration at the junction itself is within the
            // record's limit (taken back over the step, it is highest at the earliest
            // crossing), as the acceleration is for an acceleration limit.
            if (ns.a > before.a && accel_at_earliest_crossing(before, ns, ck.d) < -ck.w)
              return ck.d;
            continue;
          }
          if (ns.a >= -dec_target(ns.v, ns.a, ck)) continue;  // within (dec_target <= ck.w)
          if (!dec_kept(std::max(ns.v, 0.0), ns.a, ck, ck.d - ds)) return ck.d;
        }
        return kInf;
      };
      if (n_dec > 0) {
        auto dec_ok = [&](double xx) { return dec_failing_at(xx) == kInf; };
        if (!dec_ok(lo)) {
          if (!dec_ok(hi)) {
            lo_dec = hi;  // as much easing as the jerk allows
          } else {
            lo_dec = bisect(hi, lo, dec_ok, 10);
          }
        }
        xd = std::max(xd, lo_dec);
      }

      Constraint* c = cons.data();
      const int nc = ncons;
      int viol[3 * kChainMax + 4];
      int nv = 0;
      int ride_k = -1;  // the limit the last step rode, when violated again
      double ride_e = 0.0;
      double worst = 0.0;
      int worst_k = -1;
      // Where limit ck binds [mm from cons_here]: d2 while the motion is before it (excess_from).
      auto binding_d = [&](const Constraint& ck) { return before_d2(ck, moved) ? ck.d2 : ck.d; };
      // excess_from for a speed limit w with `remain` [mm] left to it after the step (>= 0) and
      // `reserve` kept before it, braking at jerk J and acceleration A; an acceleration still
      // left at the junction is taken back behind it at Jx (kInf: not lower than J).
      auto speed_excess = [&](const jerk::State& ns, double w, double A_, double J_, double Jx,
                              double reserve, double remain) {
        // Inside the reserve there is no room: a state at or below w that is not accelerating
        // keeps w (the speed only falls) and needs none. The plan's step allowance, on the
        // easing plan such a state gets with the step's higher jerk, failed it for any
        // deceleration, so a motion resting there could only creep on (wide sweep seed 1
        // programs 55, 86; with the probes at rest below but not this, 265 left its rest on
        // the lowest passing probe and exceeded an axis acceleration by 8 %).
        if (remain <= reserve && ns.v <= w && ns.a <= 0.0) return 0.0;
        if (ns.a > 0.0 && Jx < J_) {
          // Still accelerating with no braking needed before the limit (v + a^2/2J <= w): the
          // part of a not taken back before the junction is taken back after it at Jx. With a'
          // left at the junction the speed ends at vz + a'^2 (1/2Jx - 1/2J) <= w. vz is
          // computed as braking_plan computes it: just above w it must need braking there too
          // (rounded differently, braking_plan saw vz <= w and let the acceleration stay,
          // wide sweep seed 1 program 281).
          const double jp = kPlanMarginJ * J_, jx = kPlanMarginJ * Jx;
          const double vz = jerk::settled_velocity(std::max(ns.v, 0.0), ns.a, jp);
          if (vz <= w) {
            const double a_ok = std::sqrt((w - vz) / (0.5 / jx - 0.5 / jp));
            return ns.a <= a_ok
                       ? -remain
                       : accel_distance(ns.v, ns.a, a_ok, jp) - std::max(0.0, remain - reserve);
          }
        }
        return plan_braking(std::max(ns.v, 0.0), ns.a, w, kPlanMargin * A_, kPlanMarginJ * J_,
                            kPlanMarginJ * J) -
               std::max(0.0, remain - reserve);
      };
      // Excess [mm] of limit k's braking (or acceleration change) over its room from the
      // end-of-step state ns; > kExcessTol fails. Continuous in x where it can be (no distance
      // needed: -remain), so that largest_passing's secant steps find the root.
      auto excess_from = [&](const jerk::State& ns, int k) {
        const double ds = ns.s - before.s;
        const Constraint& ck = c[k];
        const double remain = ck.d - moved - ds;
        if (remain < 0.0) {  // passed during this step: judge the state where it passed
          // An acceleration limit: the acceleration at the junction itself. Falling over the
          // step it is above ns.a there: ending the step within the limit let the step enter a
          // record of a 5 % lower limit with most of the old acceleration (an axis of
          // 0.4 mm/s^2 and 7,575 mm/s^3, whose acceleration a step can swing over its whole
          // range: box sweep seed 4 program 3).
          if (ck.accel) return crossing_accel_bound(before, ns, std::max(0.0, ck.d - moved)) - ck.w;
          // The speed at the junction itself: still decelerating there it is above the
          // end-of-step speed, by up to a step's worth of deceleration (corner steps of 1.005 to
          // 1.03 x the tolerance on machines with stiff axes and tolerances of 0.02 mm/s, wide
          // sweep seed 1 programs 105, 136, 265).
          double v_lim = ns.v;
          // (Within the step's highest speed, max(before.v, ns.v) while the acceleration does
          // not turn from positive to negative, nothing more is needed.)
          if ((before.a < 0.0 || ns.a < 0.0) &&
              (std::max(before.v, ns.v) > ck.w || (before.a > 0.0 && ns.a < 0.0))) {
            v_lim = std::max(v_lim, crossing_speed_bound(before, ns, std::max(0.0, ck.d - moved)));
          }
          // Still accelerating: the speed this acceleration settles at after the junction (taken
          // back at Jx) must stay within w, as it had to before the step. Judging ns.v alone let
          // the crossing step keep accelerating into a record whose velocity cap is w; its
          // landing then overshot the cap by a step's gain (wide sweep seed 1 programs 124, 147).
          if (ns.a > 0.0) {
            v_lim = std::max(
                v_lim, jerk::settled_velocity(ns.v, ns.a, kPlanMarginJ * std::min(ck.J, ck.Jx)));
          }
          return v_lim - ck.w;
        }
        if (ck.accel)
          return ns.a <= ck.w ? -remain : accel_room(std::max(ns.v, 0.0), ns.a, ck) - remain;
        // Before d2 (Constraint::d2) the first piece of its plan: (w2, 0) at d2 at the jerk
        // before the soft record, with the limit's own acceleration limit (the soft record's
        // among them: a braking carried into it within that), an acceleration taken back
        // before the cut's reserve. Over-braked states pass; the deceleration carried in is the
        // deceleration limits' (decel_limits). Inside the reserve, where a step may reach the
        // soft record and has its jerk, the limit's own plan: it fits from any state the first
        // piece kept. (Taken back behind the cut at the soft jerk, as the own plan lets an
        // acceleration be taken back behind its junction, the acceleration settled above w2
        // inside the soft record and the own plan overshot the corner at its end by 1.85 x
        // the tolerance, wide sweep seed 16 program 61; with no room for it inside the reserve
        // a motion at rest there could not accelerate at all, wide seeds 4/265, 5/239.)
        // The first piece is a plain braking plan, without plan_braking's easing of a
        // deceleration above A first: a motion braking for a stop command at the stiff record's
        // acceleration failed it by the easing alone, 0.8 mm before the soft arc, and the best
        // effort braked harder still (random sweep seed 19 program 378 with stops).
        const double remain2 = ck.d2 - moved - ds;
        if (ck.d2 != kInf && remain2 > ck.reserve2) {
          const double v2 = std::max(ns.v, 0.0), jp2 = kPlanMarginJ * ck.J2;
          double need;
          if (ns.a < 0.0 && ns.a * ns.a > 2.0 * jp2 * v2) {
            // A deceleration too hard for J2 to take back before standstill: eased at the
            // step's jerk to what J2 can take back, then taken back to zero before the cut (the
            // cut is a target in acceleration). A plain plan calls that state a reversal at any
            // distance: a motion starting on a stiff line 56 mm before a soft arc found every
            // deceleration at 0.005 mm/s hopeless, the search took the floor, and the motion
            // swung between +30 and -60 mm/s^2 until its time limit (box sweep seed 5 program
            // 215). Eased as plan_braking eases, with the plan after it allowed to reach w2
            // still braking, a state braking at the stiff line's acceleration 0.08 mm before
            // a short soft line passed, and the arc behind that line was entered at -11.4
            // mm/s^2 and stopped dead inside (wide sweep seed 18 program 278).
            // Eased as jerk::braking_plan_from eases (a ramp, then the check: after a third
            // raise the plan starts from the last ramp's speed, for which that target is
            // regular). Ramping after each raise instead called the no-reversal floor's state a
            // reversal where the step's jerk equals J2 (easing never helps there) and kept the
            // spent-allowance ride off at the hardest braking (wide sweep seed 17 program 25,
            // once dominated feed limits were no longer gathered; session 41).
            const jerk::Easing e = jerk::ease_deceleration(v2, ns.a, ns.a, jp2, kPlanMarginJ * J);
            if (e.reverses) return kInf;
            const double settle = std::max(
                accel_distance(e.v0, e.target, 0.0, jp2),
                jerk::braking_plan(e.v0, e.target, ck.w2, kPlanMargin * ck.A, jp2).distance);
            need = e.d0 + settle + allowance * quarter_dt2 * -ns.a;
          } else {
            const jerk::Braking b = jerk::braking_plan(v2, ns.a, ck.w2, kPlanMargin * ck.A, jp2);
            need = b.distance + allowance * quarter_dt2 * b.peak;
          }
          if (ns.a > 0.0) need = std::max(need, accel_distance(v2, ns.a, 0.0, jp2));
          return need - (remain2 - ck.reserve2);
        }
        return speed_excess(ns, ck.w, ck.A, ck.J, ck.Jx, ck.reserve, remain);
      };
      auto excess = [&](double xx, int k) { return excess_from(jerk::advance(before, xx, dt), k); };
      // x0 raised to the release floor (releasable) as far as `also` holds and every limit (not
      // passed yet) that x0 keeps stays kept; that set is found only when the floor moves x0.
      auto release_keeping = [&](double x0, double sc_, const auto& also) {
        int kept[3 * kChainMax + 4];
        int n_kept = -1;
        auto keeps = [&](double xx) {
          if (!also(xx)) return false;
          if (n_kept < 0) {
            n_kept = 0;
            const jerk::State n0 = jerk::advance(before, x0, dt);
            for (int k = 0; k < nc; ++k) {
              if (c[k].d - moved >= 0.0 && excess_from(n0, k) <= kExcessTol) kept[n_kept++] = k;
            }
          }
          const jerk::State ns = jerk::advance(before, xx, dt);
          for (int i = 0; i < n_kept; ++i) {
            if (excess_from(ns, kept[i]) > kExcessTol) return false;
          }
          return true;
        };
        return releasable(before, x0, hi, sc_, keeps);
      };
      if (a == 0.0 && xd == 0.0) {
        if (!cruise_valid || cruise_v != v) {
          double m = kInf;
          for (int k = 0; k < nc; ++k) {
            // A speed limit at or above the cruise speed needs no braking: it passes in every
            // step of the cruise (excess -max(0, room - reserve), or v - w once passed).
            if (c[k].accel || c[k].d - moved < 0.0 || v <= c[k].w) continue;
            m = std::min(m, c[k].d - c[k].reserve -
                                plan_braking(v, 0.0, c[k].w, kPlanMargin * c[k].A,
                                             kPlanMarginJ * c[k].J, kPlanMarginJ * J));
            // Before d2 also the first piece of a two-piece plan (excess_from).
            if (before_d2(c[k], moved)) {
              m = std::min(m, c[k].d2 - c[k].reserve2 -
                                  plan_braking(v, 0.0, c[k].w2, kPlanMargin * c[k].A,
                                               kPlanMarginJ * c[k].J2, kPlanMarginJ * J));
            }
          }
          cruise_margin = m;
          cruise_v = v;
          cruise_valid = true;
        }
        if (cruise_margin - moved - v * dt > 1e-9) {
          factor = target_reason;
          integrate_step(before, 0.0, vt, J, calc_index);
          return;
        }
      }
      // One stopping distance with the window's lowest limits bounds every braking distance
      // and acceleration change: constraints farther than that need no evaluation.
      const jerk::State nd = jerk::advance(before, xd, dt);
      const double bound = plan_braking(std::max(nd.v, 0.0), nd.a, 0.0, kPlanMargin * Aw,
                                        kPlanMarginJ * Jw, kPlanMarginJ * J) +
                           (nd.s - before.s);
      for (int k = 0; k < nc; ++k) {
        const double dk = c[k].d - moved;
        if (dk < 0.0) continue;  // passed in an earlier calculation step
        // Its room: to d2 while the motion is before it (excess_from), within the reserve.
        const bool stiff = before_d2(c[k], moved);
        const double room_k = stiff ? std::min(dk - c[k].reserve, c[k].d2 - moved - c[k].reserve2)
                                    : dk - c[k].reserve;
        if (room_k > bound + c[k].beyond_stop) continue;
        // Within that limit already, at the step's start and end: passes.
        if (c[k].accel && nd.a <= c[k].w && before.a <= c[k].w) continue;
        if (cons_bounds && regular_for(nd, c[k])) {
          if (c[k].safe == -kInf) {
            c[k].safe = c[k].d - c[k].reserve - cycle_bound(c[k]);
            if (stiff)
              c[k].safe = std::min(c[k].safe, c[k].d2 - c[k].reserve2 - cycle_bound2(c[k]));
          }
          if (moved + (nd.s - before.s) <= c[k].safe) continue;  // passes (see cycle_bound)
        }
        const double e = excess_from(nd, k);
        if (e > kExcessTol) {
          viol[nv++] = k;
          if (worst_k < 0 || e > worst) {
            worst = e;
            worst_k = k;
          }
          if (ride_before < kInf && c[k].w == ride_w &&
              std::fabs(cons_here + c[k].d - ride_pos) <= 1e-9) {
            ride_k = k;
            ride_e = e;
          }
        }
      }
      if (nv == 0) {
        x = xd;
        const double vn = v + 0.5 * (a + x) * dt;
        if (x < 0.0 && vn < vt * (1.0 - 1e-3) - 1e-9) {
          // Still decelerating below the target: the end of the braking that limited the speed
          // so far (the jerk limit or the no-reversal floor takes the deceleration back), which
          // keeps its factor.
          braking_to_stop = was_braking_to_stop;
        } else if (vn >= vt * (1.0 - 1e-3) - 1e-9) {
          factor = target_reason;
        } else if (vn < vt) {
          factor = LimitFactor::kAccelJerk;
        } else {
          factor = target_reason;
        }
      } else {
        // Index into c of a violated limit that fails at xx (skipping `known`, which passes
        // there by construction), with its excess; -1 when all pass.
        auto first_failing = [&](double xx, int known, double* e_out) {
          const jerk::State ns = jerk::advance(before, xx, dt);
          for (int i = 0; i < nv; ++i) {
            if (viol[i] == known) continue;
            const double e = excess_from(ns, viol[i]);
            if (e > kExcessTol) {
              if (e_out) *e_out = e;
              return viol[i];
            }
          }
          return -1;
        };
        auto ok = [&](double xx) { return first_failing(xx, -1, nullptr) < 0; };
        auto ok_hard = [&](double xx) {
          for (int i = 0; i < nv; ++i) {
            if (!c[viol[i]].soft && excess(xx, viol[i]) > kExcessTol) return false;
          }
          return true;
        };
        double xs = lo_dec > lo && ok(lo_dec) ? lo_dec : lo, xu = xd;
        // Failing at xs need not mean failing above it. At rest just before a junction the
        // hardest braking (the no-reversal floor) fails a stop point far ahead, whose plan cannot
        // take that deceleration back before the motion stops, while a little less braking
        // passes every limit. Taking the floor there swings the next step back up, and so on:
        // the motion crept to a corner 1e-5 mm ahead for over an hour (wide sweep seed 1
        // programs 55, 86). So at rest (v <= kArriveV), when every limit failing at xs lies
        // beyond this step's reach and beyond kRestD, probe upwards; a passing probe becomes xs
        // and the search goes on from there. While moving only when each of them fails at xs
        // because its plan cannot take the floor's deceleration back before the motion stops
        // (infinite excess: the floor lies strictly outside the plans): in the last steps of an
        // arrival the floor is the planned ramp, and probes there arrived too fast (hard
        // stops). Starting from rest along a stiff line (2.9e6 mm/s^3) towards an arc of 914
        // mm/s^3 24 mm ahead, the first step accelerated as far as the arc's braking plan
        // allows; the next one found the arc's limits failing at the floor, took the floor as
        // best effort and nearly stopped, and so on every second step: 22 mm at 0.02 mm/s,
        // 1,351 s for a line that now takes 17 s under its override (wide sweep seed 117
        // program 183).
        auto passing_above = [&](double& from, double to) {
          const double reach = std::max(jerk::advance(before, hi, dt).s - before.s, kRestD);
          for (int i = 0; i < nv; ++i) {
            const bool near = binding_d(c[viol[i]]) - moved <= reach;
            if (!near && v <= kArriveV) continue;  // at rest only a near failure stops the probes
            const double e = excess(from, viol[i]);
            if (e > kExcessTol && (near || e < kInf)) return false;
          }
          for (double f : {1.0 / 1024.0, 1.0 / 256.0, 1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0}) {
            const double probe = from + (to - from) * f;
            if (ok(probe)) {
              from = probe;
              return true;
            }
          }
          return false;
        };
        const bool feed_only = xs == lo && lo_dec > lo && ok_hard(lo_dec);
        bool hopeless = !feed_only && !ok(xs) && !passing_above(xs, xu);
        if (hopeless && spend_allowance(lo, xu, viol, nv, excess, first_failing, worst_k, worst)) {
          hopeless = false;
          ride_k = -1;
        }
        if (feed_only) {
          // Only the feed x Rel_Speed cannot be kept within the acceleration limits ahead (an
          // override decrease): keep the machine limits, cross the feed limit faster.
          x = bisect(
              lo_dec, xu, [&](double xx) { return ok_hard(xx) && ok(xx); }, 10);
        } else if (hopeless) {
          // Best effort. A limit that even the hardest braking cannot keep (with the lowest
          // limits of its whole stretch, which is conservative) gets the hardest braking the
          // deceleration limits ahead allow (lo_dec). Braking below lo_dec for a hopeless limit
          // only exceeds an acceleration limit at the next junction (e.g. TGM_SEED=1 program
          // 723). The limits lo can still keep get what they need, except while a hard limit is
          // hopeless and a deceleration limit that this would break lies nearer than every kept
          // limit that needs it: those plans are stretch minima too, judged over a longer
          // stretch. Braking at 414 mm/s^2 for a corner 2.3 mm ahead that its plan still kept,
          // 0.05 mm before a hopeless one of nearly the same speed, entered a chord 0.02 mm ahead
          // that allowed 301 (X at 1.007 x its acceleration limit, wide stop sweep seed 218
          // program 79); at lo_dec every limit was kept.
          // Hopeless limits that are all the feed x Rel_Speed (soft: an override decrease) get
          // the tracking towards the target instead: it brakes as hard as landing on the target
          // allows. The hardest braking undershot the target by far when the jerk limits ahead
          // were lower than here, down to a standstill mid-line (sweep seed 15 program 529).
          int nf = 0;
          bool hard_hopeless = false;
          const jerk::State at_lo = jerk::advance(before, lo, dt);
          for (int i = 0; i < nv; ++i) {
            if (excess_from(at_lo, viol[i]) <= kExcessTol) {
              viol[nf++] = viol[i];
            } else if (!c[viol[i]].soft) {
              hard_hopeless = true;
            }
          }
          nv = nf;
          x = nv > 0 ? bisect(lo, xd, ok, 10) : xd;
          if (hard_hopeless) {
            // When the limits that can be kept need more braking than the deceleration limits
            // ahead allow, the nearer of the two wins. Held to lo_dec, a corner 1.6 mm ahead
            // planned at the current record's limits lost 2 mm/s^2 to deceleration limits 9 mm
            // ahead behind a hopeless corner, and was crossed at 16 x its tolerance (wide sweep
            // seed 204 program 20).
            double d_keep = kInf;  // the nearest kept limit that lo_dec fails
            if (x < lo_dec) {
              const jerk::State at_lo_dec = jerk::advance(before, lo_dec, dt);
              for (int i = 0; i < nv; ++i) {
                if (excess_from(at_lo_dec, viol[i]) > kExcessTol)
                  d_keep = std::min(d_keep, binding_d(c[viol[i]]) - moved);
              }
            }
            if (x >= lo_dec || dec_failing_at(x) < d_keep) x = lo_dec;
          }
          // Never so hard that the deceleration cannot be taken back before the motion stops
          // at the jerk limits of the records the release crosses (the floor in lo has only
          // this record's), as far as the limits that can be kept allow: those kept at lo among
          // the violated ones (ok) and every limit x keeps. The violated ones alone failed when
          // a stop command's braking was the tracking's choice (xd): a corner 0.04 mm ahead
          // passed there, so it was not among them, and the floor, raised step by step while a
          // far corner behind a soft record stayed hopeless, released the braking it needed
          // until it was hopeless too; the line was left at 6.4 mm/s, 84 x X's corner tolerance
          // (simulate fuzz, wide machine 12, session 43).
          if (x < 0.0 && cons_Jw < J) x = release_keeping(x, 1.0, ok);
        } else {
          // x at which limit k's end-of-step state needs no braking any more:
          // v + (a + x) dt / 2 + x |x| / (2 j) = w (increasing in x), with the plan's jerk and,
          // when the acceleration is taken back after the junction at a lower jerk (excess_from,
          // Jx), with that one (x > 0 only).
          // An acceleration limit into a record of lower jerk: its own w. Just above w the
          // excess jumps by accel_room's two steps of reach, so with less room than that left
          // the root is w itself, where no secant converges: twelve evaluations left the
          // result 2.9 mm/s^2 below w (which was 0.25), the step after that stopped below w
          // again, and the step that could reach the junction had the arc's jerk: the motion
          // entered the arc at about -3 mm/s^2 (Y at 5.3 x its acceleration limit, box sweep
          // seed 5 program 244).
          auto boundary = [&](int k, double* out) {
            const Constraint& ck = c[k];
            if (ck.accel) {
              if (!(ck.Jx < ck.J)) return 0;
              out[0] = ck.w;
              return 1;
            }
            int n_out = 0;
            if (before_d2(ck, moved)) {  // the first piece of a two-piece plan (excess_from)
              out[n_out++] = jerk::landing_acceleration(v, a, ck.w2, kPlanMarginJ * ck.J2, dt);
              return n_out;
            }
            out[n_out++] = jerk::landing_acceleration(v, a, ck.w, kPlanMarginJ * ck.J, dt);
            if (ck.Jx < ck.J && v + 0.5 * a * dt < ck.w) {
              out[n_out++] = jerk::landing_acceleration(v, a, ck.w, kPlanMarginJ * ck.Jx, dt);
            }
            return n_out;
          };
          // On return worst_k is the limit that binds at x: it reports the factor below.
          if (ride_k >= 0) {
            worst_k = ride_k;
            worst = ride_e;
          }
          if (worst_k >= 0) {
            // To a sixty-fourth of what a step at the window's lowest jerk changes: a result
            // (xu - xs) / 1024 below the root is a step's worth of jerk there when the window
            // holds a record of far lower jerk (box sweep seed 11 program 11: an arc of 7.9e7
            // mm/s^3 into a line of 668 mm/s^3 and 0.27 mm/s^2, resolved to 7.7 mm/s^2; the
            // line was entered at -28 mm/s^2 and took 42 ms to take it back, C and U at 37 x and
            // 104 x their acceleration limits).
            x = largest_passing(xs, xu, excess, worst_k, worst, first_failing, 3, boundary,
                                ride_before < kInf ? a + ride_before * dt : kInf,
                                sc * Jw * dt / 64.0);
          } else {
            x = xu;  // every limit passes without the allowance
            worst_k = viol[0];
          }
          allowance = 1.0;
          ride_jerk = (x - a) / dt;
          ride_pos = cons_here + c[worst_k].d;
          ride_w = c[worst_k].w;
        }
        factor = c[worst_k].reason;
        braking_to_stop = c[worst_k].w == 0.0;
      }
      if (stopping) {
        braking_to_stop = true;
        // A stop ends at zero speed wherever its braking ends, so it may not build a
        // deceleration that the records its release crosses cannot take back before then (the
        // floor in lo knows this record's jerk only), as far as the limits x keeps allow.
        // Tracking zero released a deceleration built in a stiff record at the jerk of the soft
        // one after it, too slowly: the speed reached zero with 171 mm/s^2 left (stop sweep
        // seed 4 program 160, X jerk 6.8 x its limit). Not in the last steps (v <= kArriveV,
        // where the floor in lo leaves less than 1e-6 mm of release): this floor wants the
        // speed above zero at every step's end and held the landing at 5e-7 mm/s for ever
        // (stop sweep seed 3 program 626).
        if (x < 0.0 && v > kArriveV && sc * cons_Jw < J) {
          x = release_keeping(x, sc, [](double) { return true; });
        }
      }
    }
    integrate_step(before, x, vt, J, calc_index);
  }

  // Landing on a junction limit below the resolution of a calculation step. The braking plans
  // and the no-reversal floor are continuous: they let the jerk turn at any instant. A step has
  // one jerk, and at speeds and limits below J dt^2 (what one step at full jerk changes the
  // speed by) that difference is the whole limit: a reversal at a tolerance of 0.0145 mm/s on
  // an axis where J dt^2 is 0.52 mm/s (wide sweep seed 5 program 212, 1 ms cycles) came to
  // rest 6e-6 mm before its junction with -875 mm/s^2 left, which the next step could only take
  // back by ending at +555 mm/s^2 (the floor), and a step later it crossed at 2.7 x its limit;
  // elsewhere it landed on the limit with acceleration left, and the step that took it back
  // peaked at 1.5 x the limit. So while the speed is below J dt^2 and a speed limit 0 < w <
  // J dt^2 lies within two steps' reach, a step must end in a state whose acceleration the
  // next step can take back linearly (end acceleration 0) with the speed staying in [0, w]:
  // v + (a + x) dt / 2 + x dt / 2 between 0 and w. Stop points (w = 0) keep their arrival
  // (arrive(); held to this, a motion stopped 4e-7 mm short of one and could not hop the
  // rest). `moved`: path travelled since the limits were gathered. Narrows [lo, hi], keeping
  // lo <= hi.
  void land_below_step_resolution(double v, double a, double J, double moved, double& lo,
                                  double& hi) const {
    const double resolution = J * dt * dt;
    if (!(v < resolution)) return;
    const double reach = step_reach(v, a, J) + step_reach(speed_after(v, a, J, dt), a + J * dt, J);
    double w = kInf;
    for (int k = 0; k < ncons; ++k) {
      const Constraint& ck = cons[static_cast<std::size_t>(k)];
      const double remain = ck.d - moved;
      if (ck.accel || remain < 0.0 || remain > reach || !(ck.w > 0.0 && ck.w < resolution))
        continue;
      w = std::min(w, ck.w);
    }
    if (w == kInf) return;
    const double c = v + 0.5 * a * dt;  // end speed of this step at x = 0
    lo = std::max(lo, std::min(-c / dt, hi));
    hi = std::max(lo, std::min(hi, (w - c) / dt));
  }

  // x raised to release_floor as far as `keeps` (true at x) stays true: the floor, or the
  // highest x below it that keeps the limits (bisection).
  template <class K>
  double releasable(const jerk::State& before, double x, double hi, double sc,
                    const K& keeps) const {
    double fl = release_floor(before, x, hi, sc);
    if (fl > x && !keeps(fl)) fl = bisect(x, fl, keeps, 10);
    return std::max(x, fl);
  }

  // Lowest end-of-step acceleration in [x, hi] from which the deceleration can be taken back
  // to zero before the motion stops, at the jerk limits of the records the release crosses (to
  // 1/256 of the range); x itself when x can, or when no x can. The release runs at full jerk,
  // integrated record by record with the no-reversal floor's margin (at the full limits, the
  // steps between best-effort steps, which do not keep this floor, were left too little room:
  // wide sweep seed 8 program 65 still stopped mid-line). A calculation step that reaches a
  // junction already has the next record's limit, so each record's stretch ends one step of
  // travel (at the release's speed there) early and the next one has the lower limit of the
  // record and the one before it. The release is followed up to a stop point or the end of the
  // buffer (braking for those is their own limit's) and over at most kReleaseRecords records.
  // sc scales the records' jerk limits (the emergency ramp's rho).
  double release_floor(const jerk::State& before, double x, double hi, double sc) const {
    // The stretches, read from the ring as far as a release gets (most end in a record or two).
    struct Stretch {
      double end;  // path position where the next stretch begins
      double j;    // jerk available in it
    };
    std::array<Stretch, kReleaseRecords> sk{};
    int n_sk = 0;
    bool all_read = false;  // a stop point, the end of the buffer or kReleaseRecords reached
    std::uint64_t q_next = cur;
    const double shift = before.v * dt;
    double j_prev = R(cur).jt;
    auto stretch = [&](int i) -> const Stretch* {
      while (n_sk <= i && !all_read) {
        if (q_next >= tail || n_sk == kReleaseRecords || R(q_next).kind == RecKind::kStop) {
          all_read = true;
          break;
        }
        const Rec& r = R(q_next++);
        if (r.kind != RecKind::kMotion) continue;
        sk[static_cast<std::size_t>(n_sk++)] = {r.s0 + r.g.length,
                                                kFloorMarginJ * sc * std::min(j_prev, r.jt)};
        j_prev = r.jt;
      }
      return i < n_sk ? &sk[static_cast<std::size_t>(i)] : nullptr;
    };
    // True when the release from the end-of-step state at xx ends before the motion stops.
    auto completes = [&](double xx) {
      const jerk::State ns = jerk::advance(before, xx, dt);
      double v = ns.v, a = ns.a, pos = R(cur).s0 + ns.s;
      if (a >= 0.0) return true;
      if (v <= 0.0) return false;
      // At the window's lowest jerk limit (the window holds a lower bound of every record's
      // in it), a release that ends in time and inside the window ends so at any jerk there.
      const double j_w = kFloorMarginJ * sc * cons_Jw, t_w = -a / j_w;
      if (v >= 0.5 * a * a / j_w && pos + shift + travel(v, a, j_w, t_w) <= start_of(win_end)) {
        return true;
      }
      for (int i = 0;; ++i) {
        const Stretch* e = stretch(i);
        if (e == nullptr) return true;  // a stop point, the end of the buffer, or far enough
        // The stretch ends where a calculation step can reach the junction: one step of travel
        // at the speed the release has there (it only falls), not at the speed it has now. With
        // the current speed, brakings for reversals of about 0.01 mm/s that fell micrometres
        // behind their plan lost a step of travel at 2.4 mm/s of their stiff chord, were eased
        // for a release "into" the softer one that their plan did not make, and crossed at
        // 0.2 mm/s (wide sweep seed 29 program 45, seed 38 program 47; seed 22 program 221,
        // 0.003 mm at 15 mm/s, crossed at 6 mm/s and now at 0.08).
        const double len = e->end - pos;
        if (len <= v * dt) continue;
        const double j = e->j;
        auto dist = [&](double t) { return travel(v, a, j, t); };
        auto reach = [&](double t) {
          return dist(t) + dt * std::max(0.0, speed_after(v, a, j, t));
        };
        const double t_rel = -a / j;
        const double v_rel = v - 0.5 * a * a / j;
        if (v_rel >= 0.0 && reach(t_rel) <= len) return true;  // released inside this stretch
        // Leaves the stretch still decelerating, unless it stops first: v reaches 0 at t_end.
        double t_end = t_rel;
        if (v_rel < 0.0) {
          t_end = (-a - std::sqrt(std::max(0.0, a * a - 2.0 * j * v))) / j;
          if (dist(t_end) <= len) return false;
        }
        // The time a step can reach the junction: the first t with reach(t) = len (reach(0) < len
        // <= reach(t_end)), by bisection.
        const double t = bisect(
            t_end, 0.0, [&](double tt) { return reach(tt) >= len; }, 40);
        pos += dist(t);
        v = speed_after(v, a, j, t);
        a += j * t;
        if (v <= 0.0) return false;
      }
    };
    if (!completes(hi) || completes(x)) return x;  // none completes (no floor helps), or x does
    const double r = bisect(hi, x, completes, 8);
    // Completing need not be monotone in x. Close before a junction into a far softer record,
    // a hard braking releases inside this record at its own jerk and completes, a middling
    // one still moves fast when a step can reach the junction and has to release at the soft
    // jerk (it stops first), and a slight one releases there in time: the bisection found the
    // slight one. A stiff line (X at 1.3e8 mm/s^3) braking for a corner of 0.078 mm/s 3 um
    // before the junction into a Z move (3,757 mm/s^3) was released from -31,000 to -161
    // mm/s^2 and crossed at 9 mm/s, 118 x Z's tolerance (simulate fuzz, box machine 15,
    // session 42: 25 of 1,080 such corners). Probes below the bisection's last interval (where a
    // monotone predicate fails) look for the lower region; its boundary is bisected.
    const double below = r - (hi - x) / 256.0;
    for (double f : {1.0 / 1024.0, 1.0 / 256.0, 1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0}) {
      const double p = x + (below - x) * f;
      if (p < below && completes(p)) return bisect(p, x, completes, 8);
    }
    return r;
  }

  // The end of a calculation step with end acceleration x chosen: integrates the path state
  // (landing exactly on vt), moves along the path crossing junctions (block reports, corner
  // events, pass records, arrival at a stop point) and finishes a stop ramp at standstill.
  // motion_step and the cruise skip (skip_cruise) share it. `before` may be `st` itself: it is
  // read before `st` is written.
  void integrate_step(const jerk::State& before, double x, double vt, double J, int calc_index) {
    last_vt = vt;
    jerk::State ns = jerk::advance(before, x, dt);
    // Landed on the target speed (within 1e-12 of it, acceleration negligible): hold exactly
    // (vt, 0). Otherwise rounding leaves a 1e-10 mm/s^2 dither that keeps every cruise step on
    // the full check and keeps Interpolator::advance from skipping the cruise.
    if (vt > 0.0 && std::fabs(x) * dt <= 1e-12 * vt && std::fabs(ns.v - vt) <= 1e-12 * vt) {
      ns.v = vt;
      ns.a = 0.0;
    }
    if (ns.v < 0.0) ns.v = 0.0;
    double ds = std::max(0.0, ns.s - before.s);
    const double jerk_used = (x - before.a) / dt;
    if (ns.v > blk_peak - 1e-12) {
      blk_peak = ns.v;
      blk_factor = factor;
    }

    // Move along the path, crossing junctions.
    std::uint64_t q = cur;
    double traveled = 0.0;
    double s_local = before.s;
    double remaining = ds;
    bool arrived = false;
    while (true) {
      const double L = R(q).g.length;
      const double room = L - s_local;
      // Short of the record's end, unless coming to rest just before a stop point (arrival).
      // Within kArriveD only when this step, from the deceleration it starts with down to none,
      // stays within the record's jerk limit: the arrival sets a = 0, and on a soft axis the last
      // 1e-9 mm of a braking still carries a deceleration that takes several cycles to release
      // (0.05 mm/s^2 at 126 mm/s^3: cut at once it exceeded the axis jerk by 4..15 % in the
      // cycles around the stop, wide sweep seed 2 program 161, seed 5 program 147 and six more).
      // Judged by the deceleration at the step's end, a step that had used the whole jerk limit
      // could still cut as much again: 1.7 x the limit in one step, and with the next record
      // leaving at once at its limit, X's jerk per cycle came to 1.0006 x its limit (wide sweep
      // seed 148 program 273, 250 us).
      // Standing, within what one calculation step from rest at the record's jerk limit
      // covers (J dt^3 / 6): the motion cannot land there in steps of one jerk each (the plans'
      // step allowance fails every x the search can resolve), so it arrives. A Command 8 ramp
      // ended 3e-8 mm before an M-function's stop point on a path of 1.2e6 mm/s^3 (one step
      // covers 1.7e-6 mm), and after the restart the motion stood there for good (wide stop
      // sweep seed 8 program 126). The jump is far inside every limit: differentiated per
      // cycle (T = 5 dt) it shows a jerk of at most 2 (J T^3 / 750) / T^3 = J / 375.
      const bool standing_short = before.v == 0.0 && before.a == 0.0 && ns.v == 0.0 &&
                                  room - remaining <= R(q).jt * dt * dt * dt / 6.0;
      if (remaining < room &&
          !(((room - remaining <= kArriveD && ns.v <= kArriveV &&
              std::fabs(before.a) <= R(q).jt * dt) ||
             (room - remaining <= kRestD && ns.v <= kStandstillV) || standing_short) &&
            stop_follows(q))) {
        s_local += remaining;
        traveled += remaining;
        break;
      }
      // Cross the end of record q.
      traveled += room;
      remaining = std::max(0.0, remaining - room);
      end_block(q, time_s + dt);
      std::uint64_t k = q + 1;
      while (k < tail && R(k).kind == RecKind::kPass) {
        execute_pass(k);
        ++k;
      }
      if (k < tail && R(k).kind == RecKind::kMotion &&
          (mode == Mode::kMoving || remaining > 0.0 || ns.v > kStandstillV)) {
        record_corner(q, k, before, jerk_used, traveled, calc_index);
        // Limits the passed junction dominated may matter now: gather again.
        cons_valid = false;
        for (int i = 0; i < n; ++i) rest[i] = R(q).g.end[i];
        cur = k;
        q = k;
        s_local = 0.0;
        const Segment& sn = S(k);
        reg.act_g_func = static_cast<std::int32_t>(sn.type);
        reg.tool_number = sn.tool;
        begin_block();
        blk_peak = ns.v;
        blk_factor = factor;
        continue;
      }
      // A stop point or the end of the buffer: standstill at the end of q.
      for (int i = 0; i < n; ++i) rest[i] = R(q).g.end[i];
      arrived = true;
      arrive(ns.v, R(q).jt);
      ns.v = 0.0;
      ns.a = 0.0;
      cur = k;
      on_path = false;
      break;
    }
    reg.move_distance += traveled;
    st.v = ns.v;
    st.a = ns.a;
    st.s = s_local;
    if (arrived) {
      if (mode == Mode::kMoving) {
        process_records();
      } else {
        finish_ramp();
      }
      return;
    }
    if ((mode == Mode::kStopping || mode == Mode::kEmergency) && st.v <= kStandstillV &&
        std::fabs(st.a) <= J * dt * (mode == Mode::kEmergency ? rho : 1.0)) {
      finish_ramp();
    }
  }

  void calc_step(int calc_index) {
    // Coming to rest cuts what is left of the braking (arrive, finish_ramp: up to 1e-8 mm, a
    // residual speed and a deceleration of up to J dt). A motion that starts in the very next
    // calculation step adds its own jerk in the same differentiation window, and Orig_Position
    // differentiated per cycle exceeded the jerk limit (G4 P0 between two moves at 250 us: up
    // to 0.6 %; an M0 restarted in the next cycle after an arrival in its last step: 0.3 %).
    // So it stands for that one step: every stop point stands at least one calculation step.
    if (rest_phase == 1 && mode == Mode::kMoving && st.v == 0.0 && st.a == 0.0) {
      rest_phase = 0;
      time_s += dt;
      return;
    }
    switch (mode) {
      case Mode::kMoving:
      case Mode::kStopping:
      case Mode::kEmergency:
        motion_step(calc_index);
        break;
      case Mode::kDwell:
        if (--dwell_left <= 0) {
          ++cur;
          process_records();
        }
        break;
      case Mode::kWaitM:
        if (!m_pending && reg.m_func == 0) {
          ++cur;
          process_records();
        }
        break;
      case Mode::kIdle:
        if (opt.resume_after_underrun &&
            reg.status == static_cast<std::int32_t>(InterpolatorStatus::kUnderrun) && cur < tail) {
          process_records();
        }
        break;
    }
    time_s += dt;
    if (rest_phase > 0) --rest_phase;
  }

  // ================= offline fast path (Interpolator::advance) =================

  // Adds the calculation steps of k cycles to the block clock, as calc_step does one by one.
  void pass_time(std::uint64_t k) {
    if (k > 0) rest_phase = 0;
    for (std::uint64_t i = 0; i < k * kCalcSteps; ++i) time_s += dt;
  }

  // Whole cycles, at most `max`, in which step() would only let time pass (dwell, M wait,
  // standing) or move at constant speed inside the current record (cruise). Advances them with
  // exactly the arithmetic step() uses and returns their count; 0 = nothing to skip, step().
  std::uint64_t skip_cycles(std::uint64_t max) {
    max = std::min<std::uint64_t>(max, kMaxSkipCycles);
    if (pend_code != 0 || settle_status != 0 || m_pending) return 0;
    if (mode != Mode::kMoving) {
      // Standing: the smoothing must rest exactly and the backlash ramps be done, so the
      // skipped calculation steps change nothing there.
      if (!smooth->at_rest()) return 0;
      for (int i = 0; i < ostage->axes(); ++i) {
        if (!ostage->ramp_settled(i)) return 0;
      }
    } else if (!cruise_stages_pass()) {
      return 0;
    }
    switch (mode) {
      case Mode::kDwell: {
        // Each calculation step decrements dwell_left; the dwell ends when it reaches 0.
        const std::int64_t whole = (dwell_left - 1) / kCalcSteps;
        const std::uint64_t k = std::min<std::uint64_t>(max, whole > 0 ? static_cast<std::uint64_t>(whole) : 0);
        dwell_left -= static_cast<std::int64_t>(k) * kCalcSteps;
        pass_time(k);
        return k;
      }
      case Mode::kWaitM:
        if (m_pending || reg.m_func == 0 || wait_m_first) return 0;
        pass_time(max);
        return max;
      case Mode::kIdle:
        // An ended program is not a standstill to skip: the caller stops at the first cycle
        // that reports it (a program that ended inside start() ran to the time limit).
        if (reg.status == static_cast<std::int32_t>(InterpolatorStatus::kEnded)) return 0;
        if (opt.resume_after_underrun &&
            reg.status == static_cast<std::int32_t>(InterpolatorStatus::kUnderrun) && cur < tail) {
          return 0;
        }
        pass_time(max);
        return max;
      case Mode::kMoving:
        // Traced, each cruise cycle is an entry: at most kMaxTracedCycles of them per call.
        return skip_cruise(opt.record_cycle_trace ? std::min(max, Interpolator::kMaxTracedCycles)
                                                  : max);
      case Mode::kStopping:
      case Mode::kEmergency:
        break;
    }
    return 0;
  }

  // During a cruise the smoothing and output stages may be skipped when they pass the motion
  // through unchanged: spline off, every filtered axis at rest and not moved by the records the
  // cruise runs through, and each axis with backlash either standing or moving on in its
  // detected direction with its ramp done (an arc may reverse its plane axes: not with backlash
  // there). stage_passes(q) is the per-record part.
  bool cruise_stages_pass() const {
    if (!on_path || cur >= tail) return false;
    if (smooth->spline().delay_steps() != 0 || !smooth->iir().at_rest() || smooth->pending_events() != 0) {
      return false;
    }
    return stage_passes(cur);
  }

  bool stage_passes(std::uint64_t q) const {
    const Geometry& g = R(q).g;
    const std::uint32_t mask = smooth->iir().mask();
    for (int i = 0; i < n; ++i) {
      const bool plane = g.arc && (i == g.first || i == g.second);
      const double c = plane ? 1.0 : g.dir[static_cast<std::size_t>(i)];
      if ((mask & (1u << i)) && c != 0.0) return false;
      if (i >= ostage->axes() || ostage->backlash_mm(i) == 0.0) continue;
      if (!ostage->ramp_settled(i)) return false;
      if (plane) return false;
      if (c != 0.0 && ostage->direction(i) != (c > 0.0 ? 1 : -1)) return false;
    }
    return true;
  }

  // Cruise: a = 0 at exactly the target speed, also across junctions into records with the
  // same target speed. Each skipped cycle runs what step() runs in it (update_window at the
  // cycle's start and after each junction, integrate_step with x = 0), leaving out only what
  // cannot change the outcome: gathering the limits, the deceleration and landing checks, the
  // smoothing and output stages and the registers. Before a cycle is run, a read-only check
  // proves that motion_step would take its cruise shortcut in each of the cycle's calculation
  // steps (x = 0 exactly):
  //  (1) every record the cycle may enter is a motion record (no pass record, stop or buffer
  //      end is crossed) with the same target speed, the stages pass it through, and its jerk
  //      over one calculation step stays within every acceleration limit of the window (so no
  //      deceleration limit ahead can raise the step's lowest acceleration);
  //  (2) the window cannot grow in this cycle beyond the records scanned here: the next record
  //      lies farther than a bound of every horizon update_window may compute (scan minima,
  //      and the next record's own limits, which update_window counts once the window ends there);
  //  (3) the slack of every limit gather() could return is larger than the distance travelled,
  //      judged conservatively: each speed limit below v of the scanned records (at its own
  //      position, braking with the scan's lowest acceleration and jerk and the largest reserve),
  //      the chain stand-ins (the scan's lowest limits, at the earliest record a chain can be
  //      cut), and the window end as it stands before the cycle (the window only grows).
  // Limits at or above v take no part in the cruise shortcut (motion_step). Returns the number
  // of cycles run; 0 = step() instead.
  std::uint64_t skip_cruise(std::uint64_t max) {
    if (!on_path || cur >= tail || R(cur).kind != RecKind::kMotion) return 0;
    const double v = st.v;
    // Any speed above zero: an arrival (v <= kArriveV within kArriveD or kRestD of a stop point)
    // cannot happen in a skipped cycle, whose proof keeps every stop point and the buffer's end
    // more than 1e-6 mm beyond the cycle's reach. (Skipping only above kArriveV stepped every
    // cycle of a feed below 0.06 mm/min, or F6 at 1 % override: 1 mm at F0.001 took 31 s.)
    if (st.a != 0.0 || !(v > 0.0)) return 0;
    LimitFactor why = LimitFactor::kFeed;
    if (target_speed(R(cur), why) != v) return 0;
    // A cruise whose proof failed is stepped a while before the next proof. On a dense CAM
    // program 900,000 proofs in cruises between corners failed (the slack to a corner ahead, a
    // record that needs the window to grow) against 2,800 that skipped 790,000 cycles, and the
    // fast-forward was 8 % slower than stepping; whether a cycle is skipped or stepped leaves
    // the registers as they are.
    if (reg.cycle < cruise_retry) return 0;
    const std::uint64_t run = prove_and_run_cruise(max, v, why);
    if (run == 0) {
      cruise_fails = std::min(cruise_fails + 1, kMaxCruiseBackoff);
      cruise_retry = reg.cycle + (std::uint64_t{1} << cruise_fails) - 1;
    } else {
      cruise_fails = 0;
    }
    return run;
  }

  // skip_cruise once the motion cruises at v (`why`: target_speed's factor): the proof and the
  // cycles.
  std::uint64_t prove_and_run_cruise(std::uint64_t max, double v, LimitFactor why) {
    // Speed limits below v among the scanned records (a cruise shortcut sees few of them).
    constexpr int kMaxSlow = 16;
    struct Slow {
      std::uint64_t q;
      double s0, w;
      std::uint64_t b;  // the motion record before q (kNoQ: none within kStiffScan records)
    };
    std::array<Slow, kMaxSlow> slow{};
    int n_slow = 0, first_slow = 0;
    // Scanned records [cur0, qf): bounds of their tangential limits, a_lo <= every at <= a_hi and
    // j_lo <= every jt <= j_hi, and their lowest junction limits (the window's minima and every
    // chain's A and J are at least these). Every check below only grows more cautious as the
    // bounds widen, so a record outside them widens them kScanSlack beyond its own limits: on a
    // circle of chords, whose turning direction makes nearly every record a new extreme, the
    // plans that depend on the bounds were made again for 2 of every 5 records (7 % of an offline
    // short-segment run), now once per few percent of change.
    constexpr double kScanSlack = 0.97;
    std::uint64_t qf = cur + 1;
    double a_lo = kScanSlack * R(cur).at, a_hi = R(cur).at / kScanSlack;
    double j_lo = kScanSlack * R(cur).jt, j_hi = R(cur).jt / kScanSlack;
    double wg_min = kInf, wf_min = kInf;
    bool closed = false;  // qf is the buffer's end or a stop: no window reaches past it
    bool full = false;    // too many slow limits: no further scan
    // Braking distance from the cruise to w bounding every plan_braking of a gathered limit.
    auto braking = [&](double w) {
      return jerk::braking_plan(v, 0.0, w, kPlanMargin * a_lo, kPlanMarginJ * j_lo).distance +
             quarter_dt2 * kPlanMargin * a_hi;
    };
    // What depends on the scan's extremes only: the horizon bound and the braking to a stop.
    double h = 0.0, b_stop = 0.0;
    bool slack_stale = true;  // the slack below must be computed again
    auto extremes_changed = [&] {
      h = horizon_bound(v, 0.0, j_hi, a_lo, a_hi, j_lo);
      b_stop = braking(0.0);
      slack_stale = true;
    };
    extremes_changed();
    auto scan_one = [&]() {
      const Rec& r = R(qf);
      if (r.kind == RecKind::kStop) {
        closed = true;
        return;
      }
      const double w[2] = {r.wg, r.wf * rel};
      if ((w[0] < v) + (w[1] < v) > kMaxSlow - n_slow) {
        full = true;
        return;
      }
      std::uint64_t b = kNoQ;
      for (std::uint64_t u = qf; u > 0 && qf - u <= kStiffScan;) {
        if (R(--u).kind == RecKind::kMotion) {
          b = u;
          break;
        }
      }
      for (double wk : w) {
        if (wk < v) slow[static_cast<std::size_t>(n_slow++)] = {qf, r.s0, wk, b};
      }
      if (r.kind == RecKind::kMotion &&
          (r.at < a_lo || r.at > a_hi || r.jt < j_lo || r.jt > j_hi)) {
        a_lo = std::min(a_lo, kScanSlack * r.at);
        a_hi = std::max(a_hi, r.at / kScanSlack);
        j_lo = std::min(j_lo, kScanSlack * r.jt);
        j_hi = std::max(j_hi, r.jt / kScanSlack);
        extremes_changed();
      }
      wg_min = std::min(wg_min, r.wg);
      wf_min = std::min(wf_min, r.wf);
      if (++qf == tail) closed = true;
    };
    if (qf == tail) closed = true;
    // The slack changes only with the scan's extremes, `cur`, the window end and the slow
    // limits: kept from cycle to cycle.
    double slack = 0.0;
    std::uint64_t slack_cur = kNoQ, slack_end = kNoQ;
    int slack_slow = -1;
    std::uint64_t window_cur = kNoQ;  // `cur` at this skip's last update_window
    const std::uint64_t cycle0 = reg.cycle;
    const double travel = kCalcSteps * v * dt;
    std::uint64_t k = 0;
    while (k < max) {
      const double p0 = R(cur).s0 + st.s;
      const double p1 = p0 + travel;
      const double safety = 1e-6 + 1e-12 * std::fabs(p1);
      // (2) Scan the window (made while the motion was faster it may reach farther than this
      // cruise needs), then until the window cannot pass qf in this cycle.
      // (update_window counts the record just beyond the window: qf's own limits too.)
      auto window_may_pass = [&] {
        if (qf < win_end) return true;
        const Rec& r = R(qf);
        double hq = h;
        if (r.kind == RecKind::kMotion && (r.at < a_lo || r.jt < j_lo)) {
          hq = horizon_bound(v, 0.0, j_hi, std::min(a_lo, r.at), a_hi, std::min(j_lo, r.jt));
        }
        return r.s0 <= p1 + hq + safety;
      };
      while (!closed && !full && window_may_pass()) scan_one();
      if (!closed && window_may_pass()) break;
      // (1) The records this cycle may enter.
      if (j_hi * dt > a_lo) break;
      std::size_t entered = 0;
      bool ok = true;
      for (std::uint64_t q = cur + 1; q < qf && R(q).s0 <= p1 + safety; ++q) {
        const Rec& r = R(q);
        if (r.kind != RecKind::kMotion || target_speed(r, why) != v || !stage_passes(q)) {
          ok = false;
          break;
        }
        ++entered;
      }
      const double scan_end = start_of(qf);  // the end of record qf - 1
      if (!ok || (closed && scan_end <= p1 + safety) || n_blocks + entered >= blocks.size() ||
          (opt.record_corner_events && n_events + entered > events.size())) {
        break;
      }
      // (3) Slack.
      if (slack_stale || cur != slack_cur || win_end != slack_end || n_slow != slack_slow) {
        while (first_slow < n_slow && slow[static_cast<std::size_t>(first_slow)].q <= cur)
          ++first_slow;
        slack = start_of(win_end) - b_stop;
        // A limit gather() plans in two pieces (stiff_stretch) is taken at the start of its
        // soft record, at the scan's lowest jerk (at most the jerk it is planned at), to w (at
        // most the cut's speed w2) and with the reserve of the cut at v (the first piece binds
        // only while v > w2, and its reserve is that of w2).
        for (int i = first_slow; i < n_slow; ++i) {
          const Slow& sl = slow[static_cast<std::size_t>(i)];
          const bool stiff = sl.b != kNoQ && sl.b > cur && kStiffRatio * R(sl.b).jt <= j_hi;
          slack = std::min(slack, stiff ? R(sl.b).s0 - reserve_for(v, j_hi) - braking(sl.w)
                                        : sl.s0 - reserve_for(sl.w, j_hi) - braking(sl.w));
        }
        if (cur + kChainMax + 1 < qf) {
          const double w = std::min(wg_min, wf_min * rel);
          if (w < v) {
            // The stand-in's soft record starts at cur + kChainMax at the earliest.
            const double at = kStiffRatio * j_lo <= j_hi
                                  ? R(cur + kChainMax).s0 - reserve_for(v, j_hi)
                                  : R(cur + kChainMax + 1).s0;
            slack = std::min(slack, at - braking(w));
          }
        }
        slack_cur = cur;
        slack_end = win_end;
        slack_slow = n_slow;
        slack_stale = false;
      }
      if (!(slack - p1 > 1e-9 + safety)) break;
      // Run the cycle as step() would.
      reg.cycle = cycle0 + k + 1;  // corner events carry their cycle
      for (int ci = 0; ci < kCalcSteps; ++ci) {
        if (ci == 0 || !cons_valid) {
          // Left out when it would add nothing and compute what it did last time (same record,
          // same cruise state, same window).
          const bool same =
              window_cur == cur && (win_end >= tail || R(win_end).kind == RecKind::kStop ||
                                    R(win_end).s0 > R(cur).s0 + st.s + horizon);
          if (!same) {
            update_window(cons_Aw, cons_Jw);
            window_cur = cur;
          }
          cons_valid = true;  // not gathered: the next step() gathers at its first step
          cruise_valid = false;
        }
        const Rec& rc = R(cur);
        target_speed(rc, factor);
        ride_jerk = kInf;
        braking_to_stop = false;
        if (ci == kCalcSteps - 1) {
          cruise_prev_q = cur;
          cruise_prev_s = st.s;
        }
        const double ds = std::max(0.0, jerk::advance(st, 0.0, dt).s - st.s);
        if (ds < rc.g.length - st.s) {
          // No junction in this step (and no stop point near: no arrival): integrate_step's
          // arithmetic for x = 0 at exactly the target speed, inline (advance_test compares bit for
          // bit).
          st.s += ds;
          reg.move_distance += ds;
          last_vt = v;
          if (v > blk_peak - 1e-12) {
            blk_peak = v;
            blk_factor = factor;
          }
        } else {
          // `st` itself, not a copy: integrate_step reads it before it writes it, and a copy
          // (read back as one wide load right after this cycle's narrower stores to st.s)
          // cost 7 % of an offline short-segment run.
          integrate_step(st, 0.0, v, rc.jt, ci);
        }
        time_s += dt;
        if (rest_phase > 0) --rest_phase;
      }
      ++k;
      if (opt.record_cycle_trace) {
        // Status is the one advance() leaves in the registers (it does not change in a cruise).
        CycleTrace& t = trace.emplace_back();
        t.cycle = cycle0 + k;
        t.line = S(cur).line;
        current_position(t.orig_position.data());
      }
    }
    reg.cycle = cycle0;  // advance() counts the cycles
    return k;
  }

  // ================= registers =================

  void fill_entry(LookAheadEntry& e, std::uint64_t q, std::uint64_t pending, bool current) {
    const Segment& sg = S(q);
    const Rec& r = R(q);
    e = LookAheadEntry{};
    e.all_params = section_params(q, pending);
    e.plane = static_cast<std::int32_t>(sg.plane);
    e.tool = sg.tool;
    e.line = sg.line;
    for (int i = 0; i < n; ++i) e.end_pos_mm[static_cast<std::size_t>(i)] = sg.end[static_cast<std::size_t>(i)];
    if (sg.type == SegmentType::kMFunction) {
      e.movement_type = 2;
      e.movement_code = sg.m;
      return;
    }
    e.movement_type = 1;
    e.movement_code = static_cast<std::int32_t>(sg.type);
    if (r.kind != RecKind::kMotion) return;
    if (r.g.arc) {
      e.radius_mm = r.g.r0;
      e.start_angle_deg = norm_angle_deg(r.g.th0);
      e.end_angle_deg = norm_angle_deg(r.g.th0 + r.g.phi);
    }
    e.tangent_deg = current && r.g.arc ? tangent_deg(r.g, st.s) : start_tangent_deg(q);
  }

  double start_tangent_deg(std::uint64_t q) {
    Rec& r = R(q);
    if (std::isnan(r.tan0_deg)) r.tan0_deg = tangent_deg(r.g, 0.0);
    return r.tan0_deg;
  }

  double tangent_deg(const Geometry& g, double s) const {
    if (x_axis >= n || y_axis >= n) return kNotSet;
    double t[kMaxAxes];
    motion::geometry_tangent(g, n, s, t);
    const double tx = t[x_axis], ty = t[y_axis];
    if (tx * tx + ty * ty < 1e-24) return kNotSet;
    return norm_angle_deg(std::atan2(ty, tx));
  }

  // A section of the LookAheadBuffer (manual: a G0..G3 motion or an M-function M3..M999):
  // motions and normal M-functions; not dwells, messages, continuous M, M0, M2 / M30.
  bool is_section(const Segment& sg) const {
    if (sg.is_motion()) return true;
    return sg.type == SegmentType::kMFunction && sg.m_kind == MKind::kNormal;
  }

  // The continuous M record just behind `cur`, else kNoQ. A continuous M belongs to the
  // section after it: when that section executes, the M record is just behind `cur`.
  std::uint64_t pending_behind_cur() const {
    for (std::uint64_t b = cur; b > base && cur - b < 64 && tail - (b - 1) <= cap;) {
      --b;
      const Segment& sb = S(b);
      if (sb.type == SegmentType::kMFunction && sb.m_kind == MKind::kContinuous) return b;
      if (is_section(sb) || sb.type == SegmentType::kMFunction || sb.type == SegmentType::kDwell) break;
    }
    return kNoQ;
  }

  // AllParams of section q: the addresses of its own M line (a normal M), with those of the
  // continuous M `pending` before it over them (kNoQ: none). The manual puts a continuous M's
  // number in the M letter of the next section's AllParams; its other addresses (M1005 S3 Q7)
  // come with it, since AllParams holds all the addresses of the M line, and a PLC that looks
  // ahead to prepare the function needs them (they used to be dropped: only M was shown).
  MParams section_params(std::uint64_t q, std::uint64_t pending) const {
    MParams out = S(q).type == SegmentType::kMFunction ? par[ring_index(q)] : unset_params();
    if (pending == kNoQ) return out;
    const MParams& cont = par[ring_index(pending)];
    for (std::size_t k = 0; k < out.size(); ++k) {
      if (!is_not_set(cont[k])) out[k] = cont[k];
    }
    // The number itself, also for a record without parameters (intercode not made by the
    // compiler, whose M lines carry their M letter).
    out[static_cast<std::size_t>('M' - 'A')] = S(pending).m;
    return out;
  }

  // Fills entries e.. from record q on (pending: the continuous M record seen before q, or
  // kNoQ).
  void fill_lookahead_from(int e, std::uint64_t q, std::uint64_t pending) {
    while (e < kLookAheadEntries && q < tail && q - cur < 256) {
      const Segment& sg = S(q);
      if (sg.type == SegmentType::kMFunction && sg.m_kind == MKind::kContinuous) {
        pending = q;
        ++q;
        continue;
      }
      if (!is_section(sg)) {
        ++q;
        continue;
      }
      const auto ue = static_cast<std::size_t>(e);
      fill_entry(reg.lookahead[ue], q, pending, e == 0 && on_path && q == cur);
      lookahead_q[ue] = q;
      pending = kNoQ;
      ++e;
      ++q;
    }
    lookahead_full = e == kLookAheadEntries;
    for (; e < kLookAheadEntries; ++e) reg.lookahead[static_cast<std::size_t>(e)] = LookAheadEntry{};
  }

  void fill_lookahead() { fill_lookahead_from(0, cur, pending_behind_cur()); }

  // `cur` moved on from lookahead_cur or records were appended, and nothing else changed
  // (lookahead_dirty clear): the sections passed leave the table, the rest move up, new ones are
  // filled in behind them. The result equals fill_lookahead's (the first entry's M address and
  // current tangent are written afresh; the kept entries' records are at or after `cur`, so
  // still in the ring), at a fraction of its cost on short segments, where `cur` moves on in
  // most cycles. A table that was not full is filled afresh.
  void shift_lookahead() {
    if (!lookahead_full || lookahead_cur > cur) {
      fill_lookahead();
      return;
    }
    int p = 0;
    while (p < kLookAheadEntries && lookahead_q[static_cast<std::size_t>(p)] < cur) ++p;
    if (p == kLookAheadEntries) {
      fill_lookahead();
      return;
    }
    const std::uint64_t last = lookahead_q[kLookAheadEntries - 1];
    for (int e = p; e < kLookAheadEntries; ++e) {
      const auto ue = static_cast<std::size_t>(e), ud = static_cast<std::size_t>(e - p);
      reg.lookahead[ud] = reg.lookahead[ue];
      lookahead_q[ud] = lookahead_q[ue];
    }
    // The new first entry: its AllParams (as fill_lookahead_from would find the continuous M
    // before it from `cur`) and, when it is the current arc, its tangent.
    const std::uint64_t q0 = lookahead_q[0];
    const Segment& s0 = S(q0);
    std::uint64_t pending = pending_behind_cur();
    for (std::uint64_t q = cur; q < q0; ++q) {
      const Segment& sg = S(q);
      if (sg.type == SegmentType::kMFunction && sg.m_kind == MKind::kContinuous) pending = q;
    }
    LookAheadEntry& e0 = reg.lookahead[0];
    e0.all_params = section_params(q0, pending);
    const Rec& r0 = R(q0);
    if (r0.kind == RecKind::kMotion && s0.type != SegmentType::kMFunction) {
      e0.tangent_deg =
          on_path && q0 == cur && r0.g.arc ? tangent_deg(r0.g, st.s) : start_tangent_deg(q0);
    }
    fill_lookahead_from(kLookAheadEntries - p, last + 1, kNoQ);
  }

  // With record_cycle_trace: one trace entry of `count` cycles ending as the registers do now.
  void trace_registers(std::uint64_t count) {
    if (!opt.record_cycle_trace) return;
    CycleTrace& t = trace.emplace_back();
    t.cycle = reg.cycle + 1 - count;
    t.count = count;
    t.line = reg.act_line;
    t.status = reg.status;
    t.orig_position = reg.orig_position;
  }

  void fill_registers() {
    reg.program_stop = paused_m0 ? 1 : 0;
    double p[kMaxAxes] = {};
    current_position(p);
    const auto& pos = smooth->position();
    const auto& vel = smooth->speed();
    for (int i = 0; i < n; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      reg.orig_position[ui] = p[i];
      reg.position[ui] = pos[ui];
      reg.speed[ui] = vel[ui];
    }
    ostage->fill(reg);
    const SplineStats& ss = smooth->spline().stats();
    reg.spline_deviation_mm = ss.current_pass_mm > 0.0 ? ss.current_pass_mm : ss.last_pass_mm;
    reg.act_speed = st.v * 60.0;
    reg.act_acceleration_mm_s2 = st.a;
    reg.rel_speed = rel;
    const bool have_cur = cur < tail;
    if (have_cur) {
      reg.act_part = static_cast<std::int32_t>(cur - base + 1);
      reg.act_line = S(cur).line;
      if (R(cur).kind == RecKind::kMotion) reg.set_speed = R(cur).f * 60.0;
    }
    reg.free_slots = static_cast<std::int32_t>(cap - (tail - cur));
    // Run_Flag.
    SectionState sec = SectionState::kStop;
    switch (mode) {
      case Mode::kMoving:
      case Mode::kStopping:
      case Mode::kEmergency:
      case Mode::kDwell:
        sec = SectionState::kRun;
        break;
      case Mode::kWaitM:
        // While the M-function is still inside the spline the section is still executing.
        sec = m_pending ? SectionState::kRun
                        : (wait_m_first ? SectionState::kWaitMFunc : SectionState::kWaitMFuncEnd);
        if (!m_pending) wait_m_first = false;
        break;
      case Mode::kIdle:
        // The motion has come to its end (program end, stop, M0, underrun) but the spline /
        // IIR still carry the axes there: Status stays 1 (6) until they stand, and the last
        // section is still executing.
        if (settle_status != 0) sec = SectionState::kRun;
        // Stopped (Command 8, 4) while a normal M-function was inside the spline: it reaches
        // M_Func while the motion stands, and the resumed program waits for it. Without
        // WAIT_MFUNC a PLC took it for a continuous M-function.
        if (resume_wait_m && !m_pending && reg.m_func != 0) {
          sec = wait_m_first ? SectionState::kWaitMFunc : SectionState::kWaitMFuncEnd;
          wait_m_first = false;
        }
        break;
    }
    // The speed half describes the axes. With the spline or the IIR filter on they follow the
    // path generator late (the spline by its delay, the IIR by its lag): once the generator
    // stands, Speed (after smoothing) still moves the axes into the stop, and "no motion" must
    // wait until they stand, or a PLC that takes it as "axes stand" acts up to 50 ms early.
    bool output_moves = false;  // the last step moved an axis, not onto its rest (the IIR's snap)
    if (!smooth->passes_through() && !smooth->at_rest()) {
      for (int i = 0; i < n; ++i)
        output_moves = output_moves || vel[static_cast<std::size_t>(i)] != 0.0;
    }
    const SpeedState before = run_flag_speed(reg.run_flag);
    const bool last_braking = braking_to_stop || before == SpeedState::kDeceleratingLast;
    SpeedState spd = SpeedState::kNoMotion;
    const double small_a = 1e-6 * std::max(1.0, std::fabs(st.a));
    if (mode == Mode::kEmergency) {
      spd = SpeedState::kEmergencyRamp;
    } else if (st.v <= kStandstillV) {
      spd = !output_moves ? SpeedState::kNoMotion
            : settle_status == static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped)
                ? SpeedState::kEmergencyRamp
                : SpeedState::kDeceleratingLast;
    } else if (st.a > small_a && st.a > 1e-3) {
      // A braking's last step lands its deceleration with a slight overshoot: the acceleration
      // ends just above zero while the speed fell over the cycle. Still decelerating.
      if (st.v >= cycle_start_v) {
        spd = SpeedState::kAccelerating;
      } else {
        spd = last_braking ? SpeedState::kDeceleratingLast : SpeedState::kDecelerating;
      }
    } else if (st.a < -1e-3) {
      spd = braking_to_stop ? SpeedState::kDeceleratingLast : SpeedState::kDecelerating;
    } else if (mode == Mode::kMoving && st.v < last_vt * (1.0 - 1e-3)) {
      spd = SpeedState::kNextSection;
    } else {
      spd = SpeedState::kConstant;
    }
    reg.run_flag = make_run_flag(sec, spd);
    reg.limit_factor = (mode == Mode::kMoving || mode == Mode::kStopping || mode == Mode::kEmergency)
                           ? factor
                           : LimitFactor::kNone;
    if (lookahead_dirty || lookahead_cur != cur || lookahead_appended || opt.full_lookahead_fill) {
      if (lookahead_dirty || opt.full_lookahead_fill) {
        fill_lookahead();
      } else {
        shift_lookahead();
      }
      lookahead_dirty = false;
      lookahead_appended = false;
      lookahead_cur = cur;
    } else if (on_path && R(cur).g.arc) {
      reg.lookahead[0].tangent_deg = tangent_deg(R(cur).g, st.s);
    }
  }

  StepResult result() const {
    if (settle_status != 0 || pend_code != 0) return StepResult::kWorking;
    switch (mode) {
      case Mode::kMoving:
      case Mode::kStopping:
      case Mode::kEmergency:
      case Mode::kDwell:
        return StepResult::kWorking;
      case Mode::kWaitM:
        return StepResult::kWaiting;
      case Mode::kIdle:
        break;
    }
    const auto s = static_cast<InterpolatorStatus>(reg.status);
    if (s == InterpolatorStatus::kEnded) return StepResult::kFinished;
    if (s == InterpolatorStatus::kUnderrun || paused_m0) return StepResult::kWaiting;
    return StepResult::kIdle;
  }
};

// ================= public API =================

std::optional<Interpolator> Interpolator::create(const MachineConfig& machine, int number,
                                                 const InterpolatorOptions& options,
                                                 std::string* error) {
  auto fail = [&](const std::string& why) -> std::optional<Interpolator> {
    if (error) *error = why;
    return std::nullopt;
  };
  const auto problems = machine.validate();
  if (!problems.empty()) return fail("invalid machine config: " + problems.front());
  if (number < 0 || number >= static_cast<int>(machine.interpolators.size())) {
    return fail("interpolator " + std::to_string(number) + " is not configured (0.." +
                std::to_string(machine.interpolators.size() - 1) + ")");
  }
  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  m.cfg = machine.interpolators[static_cast<std::size_t>(number)];
  m.soft_limits = has_soft_limits(m.cfg);
  m.opt = options;
  m.number = number;
  m.n = static_cast<int>(m.cfg.axes.size());
  m.cap = static_cast<std::size_t>(m.cfg.buffer_size);
  m.T = machine.cycle_time_us * 1e-6;
  m.dt = m.T / kCalcSteps;
  m.quarter_dt2 = 0.25 * m.dt * m.dt;
  m.rho = kInf;
  std::string letters;
  for (const AxisConfig& a : m.cfg.axes) letters.push_back(a.letter);
  for (const Plane p : {Plane::kXY, Plane::kXZ, Plane::kYZ}) {
    m.planes[Impl::plane_slot(p)] = plane_axes(p, letters);
  }
  m.x_axis = m.plane(Plane::kXY).first;
  m.y_axis = m.plane(Plane::kXY).second;
  for (int i = 0; i < m.n; ++i) {
    const AxisConfig& a = m.cfg.axes[static_cast<std::size_t>(i)];
    const auto ui = static_cast<std::size_t>(i);
    // An axis with backlash leaves its ramp's share of the limits free (config.hpp,
    // planned_limit_share): planned at the full limits, a reversal's ramp on top of the
    // motion's own acceleration took the drive setpoint to 1.1 x A (session 82's review).
    const double share = planned_limit_share(a);
    m.vmax[ui] = share * a.max_velocity_mm_s;
    m.amax[ui] = share * a.max_acceleration_mm_s2;
    // The generator holds one jerk per calculation step and its braking plans assume it can
    // follow a bang-bang jerk profile; with J dt far above A (J >= 1e8 mm/s^3 at 100 us) a plan's
    // ramps are shorter than a step and corners were crossed up to 30 % too fast. Full
    // acceleration is reached in four steps at the least (a few hundred us, which no machine's
    // cycle time notices; at J = A / (2 dt) the stop at a program's end still clamped).
    m.jmax[ui] = std::min(share * a.max_jerk_mm_s3, m.amax[ui] / (4.0 * m.dt));
    m.inv_half_a[ui] = 2.0 / m.amax[ui];
    m.inv_half_j[ui] = 2.0 / m.jmax[ui];
    m.rapid[ui] = std::min(a.rapid_velocity_mm_s, m.vmax[ui]);
    m.tol[ui] = a.corner_velocity_tolerance_mm_s;
    m.tol_a[ui] = share * corner_acceleration_tolerance(a);
    m.rho = std::min(m.rho, a.emergency_deceleration_mm_s2 / m.amax[ui]);
  }
  m.turn_w = LimitChecker::window_cycles_for(m.T) * m.T;
  m.inv_turn_w = 1.0 / m.turn_w;
  // Smoothing and output stages (allocate here only), started from the config's defaults.
  m.smooth.emplace(m.n, machine.cycle_time_us);
  m.ostage.emplace(m.cfg);
  {
    const SmoothingConfig& sc = machine.smoothing;
    RequestResult r = m.smooth->configure_spline(sc.spline_points, std::llround(sc.spline_jerk_mm_s3));
    if (!r.ok()) return fail("smoothing.spline: " + r.reason);
    r = m.smooth->configure_iir({sc.iir_p_e6, sc.iir_q_e6, sc.iir_f_e6, sc.iir_axis_mask});
    if (!r.ok()) return fail("smoothing.iir: " + r.reason);
    m.smooth->reset(m.rest.data());
    m.ostage->reset(m.rest.data());
  }
  m.cmd_error.reserve(256);
  m.rho = std::max(m.rho, 1.0);
  m.seg.reserve(m.cap);
  m.rec.reserve(m.cap);
  m.par.reserve(m.cap);
  advise_huge_pages(m.seg.data(), m.cap * sizeof(Segment));
  advise_huge_pages(m.rec.data(), m.cap * sizeof(Rec));
  advise_huge_pages(m.par.data(), m.cap * sizeof(MParams));
  m.ev_par.resize(Impl::kEventSlots);
  m.ev_line.resize(Impl::kEventSlots);
  if (options.preallocate_ring) {
    m.grow_rings(m.cap);
    m.par.resize(m.cap);
  } else {
    m.grow_rings(0);
  }
  m.msg.resize(kMessageRing);
  m.msg_line.assign(kMessageRing, 0);
  m.dq_a.init(m.cap + 1);
  m.dq_j.init(m.cap + 1);
  m.dq_wg.init(m.cap + 1);
  m.dq_wf.init(m.cap + 1);
  m.st_g.init(m.cap + 1);
  m.st_f.init(m.cap + 1);
  m.st_a.init(m.cap + 1);
  m.events.resize(options.record_corner_events ? kMaxCornerEvents : 0);
  m.blocks.resize(kMaxBlockReports);
  if (options.record_cycle_trace) m.trace.reserve(kMaxTracedCycles);
  m.reg.number = number;
  m.reg.number_axes = m.n;
  m.reg.buffer_size = m.cfg.buffer_size;
  m.reg.rel_speed = 1.0;
  m.reg.free_slots = m.cfg.buffer_size;
  m.reg.m_function_parameter.fill(kNotSet);
  m.reset_plan_tail();
  m.fill_registers();
  return Interpolator(std::move(impl));
}

Interpolator::Interpolator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Interpolator::Interpolator(Interpolator&&) noexcept = default;
Interpolator& Interpolator::operator=(Interpolator&&) noexcept = default;
Interpolator::~Interpolator() = default;

StepResult Interpolator::step() {
  Impl& m = *impl_;
  m.trace.clear();
  m.n_events = 0;
  m.n_blocks = 0;
  m.reg.cycle += 1;
  m.cycle_start_v = m.st.v;
  m.hand_over_deferred_m();
  for (int k = 0; k < kCalcSteps; ++k) {
    m.calc_step(k);
    m.smooth_step(k);
  }
  m.ostage->update(m.smooth->position().data(), m.T);
  m.poll_pending_command();
  m.fill_registers();
  for (int i = 0; i < m.n; ++i) {
    if (!std::isfinite(m.reg.orig_position[static_cast<std::size_t>(i)])) return StepResult::kErrorInternal;
  }
  return m.result();
}

StepResult Interpolator::advance(std::uint64_t max_cycles, std::uint64_t* advanced) {
  Impl& m = *impl_;
  if (advanced) *advanced = 0;
  if (max_cycles == 0) return m.result();
  m.n_events = 0;  // a cruise skip reports the blocks and corners it runs through
  m.n_blocks = 0;
  m.trace.clear();
  // A deferred M-function is handed over at a cycle's start: step that cycle.
  m.m_announced = false;
  const std::uint64_t k = m.m_deferred_n > 0 ? 0 : m.skip_cycles(max_cycles);
  if (k == 0) {
    if (advanced) *advanced = 1;
    const StepResult r = step();
    m.trace_registers(1);
    return r;
  }
  m.reg.cycle += k;
  m.cycle_start_v = m.st.v;  // a cruise or standing: the speed does not change
  {
    // The smoothing and output stages over the skipped calculation steps (they rest, or pass
    // the cruise through: skip_cycles checked it).
    double last[kMaxAxes], before[kMaxAxes];
    for (int i = 0; i < kMaxAxes; ++i) last[i] = before[i] = m.rest[static_cast<std::size_t>(i)];
    m.current_position(last);
    // A cruise ends on the path with the position of its second to last calculation step in
    // cruise_prev_q / _s. Standing (also on the path after a stop on the trajectory) both are
    // the position: a standing skip on the path once took a long-gone cruise's position there,
    // and Speed showed its difference to the stop point (RandomRequests, seed 1 case 1).
    if (m.mode == Mode::kMoving) {
      motion::geometry_position(m.R(m.cruise_prev_q).g, m.n, m.cruise_prev_s, before);
    } else {
      for (int i = 0; i < kMaxAxes; ++i) before[i] = last[i];
    }
    m.smooth->skip(k * kCalcSteps, before, last);
    m.ostage->update(m.smooth->position().data(), m.T);
  }
  m.fill_registers();
  if (m.trace.empty()) m.trace_registers(k);  // standing: every skipped cycle ended as the last
  for (CycleTrace& t : m.trace) t.status = m.reg.status;
  if (advanced) *advanced = k;
  for (int i = 0; i < m.n; ++i) {
    if (!std::isfinite(m.reg.orig_position[static_cast<std::size_t>(i)])) return StepResult::kErrorInternal;
  }
  return m.result();
}

void Interpolator::copy_state_from(const Interpolator& other) { *impl_ = *other.impl_; }

const Registers& Interpolator::registers() const { return impl_->reg; }

namespace {
RequestResult refuse(RequestCode c, std::string why) { return {c, std::move(why)}; }
}  // namespace

RequestResult Interpolator::append(const Program& program, std::size_t first, std::size_t count,
                                   bool program_complete, std::size_t* accepted) {
  Impl& m = *impl_;
  if (accepted) *accepted = 0;
  if (!takes_records()) return refuse(RequestCode::kWrongState, "emergency ramp in progress");
  if (program.number_axes != m.n) {
    return refuse(RequestCode::kInvalid, "program was compiled for " + std::to_string(program.number_axes) +
                                             " axes, interpolator " + std::to_string(m.number) + " has " +
                                             std::to_string(m.n));
  }
  if (first > program.segments.size() || count > program.segments.size() - first) {
    return refuse(RequestCode::kOutOfRange, "record range outside the program");
  }
  const std::size_t free = m.cap - static_cast<std::size_t>(m.tail - m.cur);
  const std::size_t take = std::min(free, count);
  const auto status = m.status_now();
  const bool fresh = m.mode == Mode::kIdle && m.cur >= m.tail && !m.paused_m0 &&
                     (status == InterpolatorStatus::kEmpty || status == InterpolatorStatus::kEnded ||
                      (status == InterpolatorStatus::kEmergencyStopped && m.reg.off_trajectory));
  // Where each motion record starts, as store() will plan it: a new program where the
  // interpolator stands, more records of one where the records before them end (where it
  // stands while none of them moved).
  const double* start = fresh ? m.rest.data() : m.pt_end.data();
  bool first_motion = fresh || !m.pt_have_motion;
  for (std::size_t i = first; i < first + take; ++i) {
    std::string why = m.validate(program, i);
    const Segment& sg = program.segments[i];
    if (why.empty() && sg.is_arc()) why = m.arc_start_problem(program, i, start, first_motion);
    if (why.empty() && m.soft_limits && sg.is_motion()) {
      if (std::string beyond = soft_limit_problem(sg, start, m.cfg); !beyond.empty()) {
        why = "record " + std::to_string(i) + " (line " + std::to_string(sg.line) + "): " + beyond;
      }
    }
    if (!why.empty()) return refuse(RequestCode::kInvalid, why);
    if (sg.is_motion()) {
      start = sg.end.data();
      first_motion = false;
    }
  }
  if (fresh) {
    m.base = m.tail;
    m.clear_section_registers();
    m.reset_plan_tail();
  }
  m.drop_stale();
  for (std::size_t i = first; i < first + take; ++i) m.store(program, i);
  if (take == count) m.complete = program_complete;
  // Records appended behind a full LookAheadBuffer table do not enter it (but may overwrite the
  // ring slots behind `cur` its first entry's M address was read from: shift_lookahead).
  if (m.lookahead_full) {
    m.lookahead_appended = true;
  } else {
    m.lookahead_dirty = true;
  }
  if (fresh && take > 0) {
    m.settle_status = 0;  // the axes may still settle; the new program waits for its start
    m.reg.status = static_cast<std::int32_t>(InterpolatorStatus::kReady);
    m.reg.off_trajectory = 0;
  }
  m.reg.free_slots = static_cast<std::int32_t>(m.cap - (m.tail - m.cur));
  if (accepted) *accepted = take;
  if (take < count) {
    return refuse(RequestCode::kBufferFull, "ring buffer full: " + std::to_string(take) + " of " +
                                                std::to_string(count) + " records taken");
  }
  return {};
}

RequestResult Interpolator::load(const Program& program) {
  return append(program, 0, program.segments.size(), true);
}

RequestResult Interpolator::start() {
  Impl& m = *impl_;
  if (m.mode != Mode::kIdle) return refuse(RequestCode::kWrongState, "already running");
  const auto s = m.status_now();
  if (s == InterpolatorStatus::kEmergencyStopped && m.settle_status != 0) {
    return refuse(RequestCode::kWrongState,
                  "the axes are still braking after the emergency stop (Status 6): start once "
                  "Status is 7");
  }
  switch (s) {
    case InterpolatorStatus::kEmpty:
      return refuse(RequestCode::kWrongState, m.reg.off_trajectory
                                                  ? "off trajectory: load a new program or set the position"
                                                  : "nothing loaded");
    case InterpolatorStatus::kEnded:
      return refuse(RequestCode::kWrongState, "program ended: clear and load a new program");
    case InterpolatorStatus::kEmergencyStopped:
      if (!m.resumable_estop) {
        return refuse(RequestCode::kWrongState,
                      "off trajectory (Command 5, or an emergency stop with nothing loaded): load "
                      "a new program or set the position");
      }
      break;
    default:
      break;
  }
  if (!m.on_path && m.cur >= m.tail && !m.paused_m0) {
    return refuse(RequestCode::kWrongState, "buffer empty: append segments first");
  }
  m.resumable_estop = false;
  m.settle_status = 0;  // a stop or M0 whose axes still settle: they go on with the motion
  m.reg.status = static_cast<std::int32_t>(InterpolatorStatus::kRunning);
  if (m.paused_m0) {
    m.paused_m0 = false;
    ++m.cur;
    m.process_records();
  } else if (m.resume_wait_m) {
    m.resume_wait_m = false;
    m.mode = Mode::kWaitM;
  } else if (m.resume_dwell) {
    m.resume_dwell = false;
    m.mode = Mode::kDwell;
  } else if (m.on_path) {
    m.mode = Mode::kMoving;
  } else {
    m.process_records();
  }
  m.lookahead_dirty = true;
  return {};
}

RequestResult Interpolator::clear() {
  Impl& m = *impl_;
  // A program that runs is stopped first, also while it stands in a dwell or an M-function
  // wait: a clear there dropped it under the feet of the PLC executing the M-function (M_Func
  // still set) and of the HMI following it (tgm-hmi run waited on for good).
  if (m.mode != Mode::kIdle) {
    return refuse(RequestCode::kWrongState,
                  m.mode == Mode::kWaitM
                      ? "cannot clear while waiting for an M-function: stop first"
                  : m.mode == Mode::kDwell ? "cannot clear during a dwell: stop first"
                                           : "cannot clear while moving: stop first");
  }
  m.drop_records();
  m.reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmpty);
  m.fill_registers();
  return {};
}

RequestResult Interpolator::command(std::int32_t code) {
  Impl& m = *impl_;
  switch (code) {
    case 8:
    case 9:
    case 4:
    case 5: {
      m.cancel_pending_command(code);
      const bool emergency = code == 4 || code == 5;
      const bool off = code == 5 || code == 9;
      m.reg.command = code;
      if (m.mode == Mode::kMoving || m.mode == Mode::kStopping || m.mode == Mode::kEmergency) {
        if (emergency) {
          m.mode = Mode::kEmergency;
          m.reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmergencyRamp);
        } else if (m.mode != Mode::kEmergency) {
          m.mode = Mode::kStopping;
        }
        m.stop_off = m.stop_off || off;
        m.reg.command_status = 1;
        return {};
      }
      // Standing (idle, dwell, M wait): the stop takes effect at once.
      if (m.mode == Mode::kWaitM) m.resume_wait_m = true;
      // The rest of a dwell is kept for the start that resumes (it used to be dropped: a stop
      // and start cut a G4 short, the spindle's run-up or a chip break with it).
      if (m.mode == Mode::kDwell) m.resume_dwell = true;
      const bool had_program = m.status_now() != InterpolatorStatus::kEmpty;
      m.mode = Mode::kIdle;
      if (emergency) {
        m.settle_into(InterpolatorStatus::kEmergencyStopped);
        m.resumable_estop = !off && had_program;
      } else if (m.status_now() == InterpolatorStatus::kRunning) {
        m.settle_into(InterpolatorStatus::kReady);
      }
      // An emergency stop with nothing loaded leaves no trajectory to resume: off it, as after
      // Command 5. It stood on one, and a program streamed in next was taken as more records of
      // none: start refused it ("off trajectory after Command 5"), and the service refused the
      // stream until a clear ("still holds program 0").
      if (off || (emergency && !had_program)) m.abandon_program();
      m.reg.command = 0;
      m.reg.command_status = 0;
      m.fill_registers();
      return {};
    }
    default:
      return refuse(RequestCode::kUnsupported,
                    "command " + std::to_string(code) + " is not handled by the motion core");
  }
}

RequestResult Interpolator::write_m_func(std::int32_t value, std::int32_t acknowledged,
                                         std::uint32_t count) {
  if (value != 0) {
    return refuse(RequestCode::kOutOfRange, "M_Func can only be written with 0 (acknowledge), not " +
                                                std::to_string(value));
  }
  const std::int32_t shown = impl_->reg.m_func;
  if (acknowledged != 0 && shown != 0 && shown != acknowledged) {
    return refuse(RequestCode::kWrongState, "M_Func shows M" + std::to_string(shown) +
                                                " now: the acknowledgement of M" +
                                                std::to_string(acknowledged) + " came after it");
  }
  const std::uint32_t handed = impl_->reg.m_func_count;
  if (count > handed) {
    return refuse(RequestCode::kWrongState, "M-function #" + std::to_string(count) +
                                                " was never handed over (the last is #" +
                                                std::to_string(handed) + ")");
  }
  if (count != 0 && count != handed) {
    return refuse(RequestCode::kWrongState,
                  "M-function #" + std::to_string(handed) + " was handed over since: the " +
                      "acknowledgement of #" + std::to_string(count) + " came after it");
  }
  if (count != 0 && shown == 0 && count == impl_->dropped_m_count) {
    return refuse(RequestCode::kWrongState,
                  "M-function #" + std::to_string(count) + " (M" +
                      std::to_string(impl_->dropped_m) +
                      ") went with its program (an off-trajectory stop, Command 9 / 5, a clear "
                      "or the next program's load): there is nothing to acknowledge");
  }
  // The same M-function acknowledged again: a second PLC, or a repeat whose first copy did
  // arrive. Accepting it told both writers they had released the motion.
  if (count != 0 && shown == 0) {
    return refuse(RequestCode::kWrongState,
                  "M-function #" + std::to_string(count) +
                      " was acknowledged already (by another acknowledgement: a second PLC, "
                      "or a repeat whose first copy arrived)");
  }
  impl_->reg.m_func = 0;
  return {};
}

RequestResult Interpolator::set_rel_speed(double rel_speed) {
  if (!std::isfinite(rel_speed) || rel_speed < 0.01 || rel_speed > 2.0) {
    return refuse(RequestCode::kOutOfRange,
                  "Rel_Speed must be 0.01..2, not " + number_text(rel_speed));
  }
  impl_->rel = rel_speed;
  impl_->reg.rel_speed = rel_speed;
  return {};
}

RequestResult Interpolator::set_position(const std::array<double, kMaxAxes>& position_mm) {
  Impl& m = *impl_;
  if (m.mode != Mode::kIdle) return refuse(RequestCode::kWrongState, "set position only while standing");
  for (int i = 0; i < m.n; ++i) {
    const double x = position_mm[static_cast<std::size_t>(i)];
    if (!std::isfinite(x)) return refuse(RequestCode::kInvalid, "position is not finite");
    // The bound every record's end point is held to: a start beyond it made the first move's
    // length infinite (Set_Speed inf) or a runaway of 1e21 mm.
    if (std::fabs(x) > kMaxCoordinateMm) {
      return refuse(RequestCode::kOutOfRange,
                    "position of axis " +
                        std::string(1, m.cfg.axes[static_cast<std::size_t>(i)].letter) +
                        " must be within +-1e9 mm, not " + number_text(x));
    }
  }
  if (!m.smooth->settled()) {
    return refuse(RequestCode::kWrongState, "set position: the axes are still moving behind the spline / IIR filter");
  }
  m.place(position_mm);
  m.fill_registers();
  return {};
}

RequestResult Interpolator::command(std::int32_t code,
                                    const std::array<std::int32_t, kCommandParameters>& parameter) {
  Impl& m = *impl_;
  if (code == 4 || code == 5 || code == 8 || code == 9) {
    m.reg.command_parameter = parameter;
    return command(code);
  }
  if (m.pend_code != 0) {
    return refuse(RequestCode::kWrongState, "Command " + std::to_string(m.pend_code) +
                                                " is still executing (Command_Status 1): wait until it is done");
  }
  m.reg.command_parameter = parameter;
  command_begin(m.reg, code);
  const RequestResult c = check_command(code, parameter, m.command_context());
  if (!c.ok()) return m.finish_command(c);
  if (!m.stage_ready(code, parameter)) {
    // Valid, but motion is still inside the smoothing: Command_Status stays 1, step() executes it.
    m.pend_code = code;
    m.pend_par = parameter;
    return {};
  }
  return m.run_command(code, parameter);
}

const std::string& Interpolator::command_error() const { return impl_->cmd_error; }
std::uint64_t Interpolator::unexecuted_commands() const {
  return impl_->unexecuted;
}
std::uint64_t Interpolator::early_smoothing_events() const {
  return impl_->early_events;
}
const std::string& Interpolator::unexecuted_reason() const {
  return impl_->unexecuted_reason;
}

RequestResult Interpolator::write_ratio(int axis, double ratio_inc_per_mm) {
  Impl& m = *impl_;
  if (axis < 0 || axis >= m.reg.number_axes) {
    return refuse(RequestCode::kOutOfRange, "Ratio: axis " + std::to_string(axis) + " is not 0.." +
                                                std::to_string(m.reg.number_axes - 1));
  }
  if (!ratio_may_change(m.command_context())) {
    return refuse(RequestCode::kWrongState,
                  "Ratio can only be written while no program is executing (PositionInc jumps by "
                  "Position x the change)");
  }
  if (!m.smooth->settled()) {
    return refuse(RequestCode::kWrongState, "Ratio: the axes are still moving behind the spline / IIR filter");
  }
  RequestResult r = m.ostage->write_ratio(axis, ratio_inc_per_mm);
  if (r.ok()) m.fill_registers();
  return r;
}

RequestResult Interpolator::write_offset(int axis, std::int64_t offset_inc) {
  Impl& m = *impl_;
  if (axis < 0 || axis >= m.reg.number_axes) {
    return refuse(RequestCode::kOutOfRange, "Offset: axis " + std::to_string(axis) + " is not 0.." +
                                                std::to_string(m.reg.number_axes - 1));
  }
  RequestResult r = m.ostage->write_offset(axis, offset_inc);
  if (r.ok()) m.fill_registers();
  return r;
}

RequestResult Interpolator::write_number_axes(int number_axes) {
  Impl& m = *impl_;
  RequestResult r = check_number_axes(number_axes, m.command_context());
  if (!r.ok()) return r;
  if (number_axes == m.n) return {};
  if (m.settle_status != 0 || !m.smooth->settled()) {
    return refuse(RequestCode::kWrongState, "Number_Axes " + std::to_string(number_axes) +
                                                ": the axes are still moving behind the spline / "
                                                "IIR filter");
  }
  // Records planned for the old axis count are dropped (only the idle states get here), the
  // position taken on the old axes.
  m.drop_records();
  m.n = number_axes;
  m.reg.number_axes = number_axes;
  if (m.reg.status != static_cast<std::int32_t>(InterpolatorStatus::kEmergencyStopped)) {
    m.reg.status = static_cast<std::int32_t>(InterpolatorStatus::kEmpty);
  }
  m.lookahead_dirty = true;
  m.fill_registers();
  return {};
}

std::size_t Interpolator::free_slots() const { return impl_->cap - (impl_->tail - impl_->cur); }
std::size_t Interpolator::ring_slots() const {
  return impl_->rec.size();
}
bool Interpolator::takes_records() const {
  return impl_->mode != Mode::kEmergency;
}

std::int32_t Interpolator::message_slot_of(std::uint32_t count) const {
  const std::uint32_t now = impl_->reg.message_count;
  if (count == 0 || count > now || now - count >= kMessageRing) return -1;
  return impl_->msg_by_count[count % kMessageRing];
}

std::string_view Interpolator::message_text(std::int32_t slot) const {
  if (slot < 0 || static_cast<std::size_t>(slot) >= impl_->msg.size()) return {};
  return impl_->msg[static_cast<std::size_t>(slot)];
}

std::int32_t Interpolator::message_line(std::int32_t slot) const {
  if (slot < 0 || static_cast<std::size_t>(slot) >= impl_->msg_line.size()) return 0;
  return impl_->msg_line[static_cast<std::size_t>(slot)];
}

std::span<const CornerEvent> Interpolator::corner_events() const {
  return {impl_->events.data(), impl_->n_events};
}

std::span<const BlockReport> Interpolator::block_reports() const {
  return {impl_->blocks.data(), impl_->n_blocks};
}

std::span<const CycleTrace> Interpolator::cycle_trace() const {
  return impl_->trace;
}

std::uint64_t Interpolator::hard_stops() const { return impl_->hard_stop_count; }
std::uint64_t Interpolator::position_sets() const {
  return impl_->position_set_count;
}
double Interpolator::cycle_time_s() const { return impl_->T; }
double Interpolator::calc_step_s() const { return impl_->dt; }
const InterpolatorConfig& Interpolator::config() const { return impl_->cfg; }
const SmoothingStage& Interpolator::smoothing() const { return *impl_->smooth; }
const OutputStage& Interpolator::output() const { return *impl_->ostage; }

}  // namespace tgm
