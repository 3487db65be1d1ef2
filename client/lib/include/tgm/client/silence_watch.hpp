// SilenceWatch: when the service stopped publishing (no DDS here: tgm-plc and tgm-hmi use it
// with Client::state_samples, the unit tests drive it with plain numbers).
#pragma once

#include <chrono>
#include <cstdint>

namespace tgm::client {

//! Whether the service still publishes. It writes every state at least every 20 ms
//! (`--state-period-ms`), so no new state sample for `limit` means it stopped or the network
//! is down. Feed update() the state samples received so far (Client::state_samples); it says
//! when a silence begins and when it ends, once each. The first call only takes the count.
class SilenceWatch {
 public:
  enum class Change { kNone, kSilent, kBack };
  explicit SilenceWatch(std::chrono::steady_clock::duration limit) : limit_(limit) {}
  Change update(std::uint64_t samples, std::chrono::steady_clock::time_point now) {
    if (!started_ || samples != samples_) {
      const bool back = silent_;
      started_ = true;
      samples_ = samples;
      at_ = now;
      silent_ = false;
      long_said_ = false;
      return back ? Change::kBack : Change::kNone;
    }
    if (silent_ || now - at_ <= limit_) return Change::kNone;
    silent_ = true;
    return Change::kSilent;
  }
  //! True from the update that said kSilent until one that says kBack.
  bool silent() const { return silent_; }
  //! True once per silence: at the first call when it has lasted `after` (tgm-hmi run and
  //! watch join DDS again then, Client::rejoin).
  bool lasted(std::chrono::steady_clock::duration after,
              std::chrono::steady_clock::time_point now) {
    if (!silent_ || long_said_ || since_last(now) < after) return false;
    long_said_ = true;
    return true;
  }
  //! Time from the last new sample to `now` (0 before the first update).
  std::chrono::steady_clock::duration since_last(std::chrono::steady_clock::time_point now) const {
    return started_ ? now - at_ : std::chrono::steady_clock::duration{};
  }
  //! since_last in whole seconds, for "no state for N s".
  std::int64_t seconds_since_last(std::chrono::steady_clock::time_point now) const {
    return std::chrono::duration_cast<std::chrono::seconds>(since_last(now)).count();
  }

 private:
  std::chrono::steady_clock::duration limit_;
  bool started_ = false;
  bool silent_ = false;
  bool long_said_ = false;  // lasted() said this silence
  std::uint64_t samples_ = 0;
  std::chrono::steady_clock::time_point at_{};
};

}  // namespace tgm::client
