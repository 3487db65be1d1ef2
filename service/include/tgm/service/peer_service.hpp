// Which of two tgm-services on one DDS domain gives way. A service looks for another one
// before it serves (tgm-service --service-check-ms); two started within each other's look both
// serve, and then, in its first cycles, each decides by the rule below from what it sees of the
// other: its own cycle count now and the other's in the other's last state sample.
#pragma once

#include <cstdint>

namespace tgm::service {

//! True while a service that has run `mine` cycles may still give way: within the first `window`
//! cycles (0: never).
inline bool in_yield_window(std::uint64_t mine, std::uint64_t window) {
  return window > 0 && mine < window;
}

//! True when this service (cycle count `mine`, instance `my_instance`) gives way to another
//! whose last sample showed `theirs` cycles and instance `their_instance`. Only within the
//! first `window` cycles (0: never): to one that has run a fifth of the window longer, or,
//! closer in age, to the lower instance. A sample shows the other's count of some moments ago,
//! never a later one, and two counts at one cycle time grow alike: so, whenever each decides,
//! never both give way, and of two that decide young from fresh samples exactly one does
//! (tests/service/peer_service_test.cpp). At different cycle times the counts are no ages; the
//! rule still orders them, only the moments of the decisions then matter.
inline bool gives_way(std::uint64_t mine, std::uint64_t my_instance, std::uint64_t theirs,
                      std::uint64_t their_instance, std::uint64_t window) {
  if (!in_yield_window(mine, window)) return false;
  const std::uint64_t margin = window / 5;
  return theirs > mine + margin || (theirs + margin >= mine && their_instance < my_instance);
}

}  // namespace tgm::service
