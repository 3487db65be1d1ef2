// tgm-plc's record of the M-functions it has handled (client/plc/main.cpp), apart so that the
// unit tests can drive it with samples in any order.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

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

}  // namespace tgm::plc
