// tgm-plc's record of the M-functions it has handled and of those it refuses to acknowledge
// (client/plc/main.cpp), apart so that the unit tests can drive them with samples in any order.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <set>

#include "tgm/intercode.hpp"

namespace tgm::plc {

// Which M-functions have been handled, for the two threads that see them (event callback and
// main loop; the caller holds the mutex). The service numbers every M-function it hands to
// M_Func (m_func_count: 1, 2, ... per service instance), so two equal M-functions in a row are
// two, a state sample older than an event says nothing new, and an M-function is claimed once
// whichever topic shows it first. A new service instance (a restarted service) starts afresh; a
// sample of an instance it replaced (the main loop may hold one while the event callback
// already saw the new service) says nothing.
class MTracker {
 public:
  //! True when the sample (service instance, m_func_count, M_Func) of `interpolator` shows an
  //! M-function nobody claimed yet; it is then claimed.
  bool claim(int interpolator, std::uint64_t instance, std::uint32_t count, std::int32_t m) {
    Seen& d = seen_[static_cast<std::size_t>(interpolator)];
    if (instance != d.instance) {
      if (std::find(d.replaced.begin(), d.replaced.end(), instance) != d.replaced.end()) {
        return false;
      }
      Seen next{instance};
      next.replaced = d.replaced;
      next.replaced[d.next_replaced] = d.instance;
      next.next_replaced = (d.next_replaced + 1) % next.replaced.size();
      d = next;
    }
    if (m == 0 || count == 0) return false;
    if (!d.any || count > d.newest) {
      const std::uint32_t up = d.any ? count - d.newest : 64;
      d.recent = up >= 64 ? 0 : d.recent << up;
      d.recent |= 1;
      d.newest = count;
      d.any = true;
      return true;
    }
    const std::uint32_t back = d.newest - count;
    if (back >= 64 || ((d.recent >> back) & 1U) != 0) return false;
    d.recent |= std::uint64_t{1} << back;
    return true;
  }

 private:
  struct Seen {
    std::uint64_t instance = 0;
    bool any = false;
    std::uint32_t newest = 0;  // highest count claimed
    std::uint64_t recent = 0;  // bit k: count newest - k claimed (older ones count as claimed)
    std::array<std::uint64_t, 4> replaced{};  // the last instances this one followed
    std::size_t next_replaced = 0;
  };
  std::array<Seen, kMaxInterpolators> seen_{};
};

// The normal M-functions not acknowledged, per interpolator (the caller holds the mutex the
// event callback and the main loop share): --refuse-ack refuses them on every interpolator, a
// script step's refuse_ack on the one the step names only (a step for interpolator 1 refused
// M51 on all three).
class RefusedM {
 public:
  //! `m` is not acknowledged on any interpolator from now on.
  void refuse_everywhere(int m) {
    for (std::set<int>& r : refused_) r.insert(m);
  }
  //! `m` is not acknowledged on `interpolator` from now on (one that does not exist: nothing).
  void refuse(int interpolator, int m) {
    if (interpolator >= 0 && interpolator < kMaxInterpolators)
      refused_[static_cast<std::size_t>(interpolator)].insert(m);
  }
  bool refused(int interpolator, int m) const {
    return interpolator >= 0 && interpolator < kMaxInterpolators &&
           refused_[static_cast<std::size_t>(interpolator)].count(m) != 0;
  }

 private:
  std::array<std::set<int>, kMaxInterpolators> refused_{};
};

}  // namespace tgm::plc
