// Latest-value hand-off (triple buffer) from the cycle thread to the publisher thread: the writer
// never waits, the reader always gets the newest complete value, values in between may be skipped
// (DESIGN.md section 3). Lock-free; no allocation after construction.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

namespace tgm::service {

template <class T>
class LatestValue {
 public:
  LatestValue() : slots_(new T[3]) {}
  LatestValue(const LatestValue&) = delete;
  LatestValue& operator=(const LatestValue&) = delete;

  //! Writer: the slot to fill; publish() hands it over.
  T& write_slot() { return slots_[back_]; }
  //! Writer: makes the filled slot the newest value.
  void publish() {
    const std::uint32_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = old & kIndex;
  }
  //! Reader: true (and `out` points at it) when a value newer than the last read exists.
  bool read(const T*& out) {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    const std::uint32_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndex;
    out = &slots_[front_];
    return true;
  }

 private:
  static constexpr std::uint32_t kFresh = 4;
  static constexpr std::uint32_t kIndex = 3;
  std::unique_ptr<T[]> slots_;
  std::uint32_t back_ = 0;               // writer only
  std::atomic<std::uint32_t> middle_{1};  // index | kFresh
  std::uint32_t front_ = 2;              // reader only
};

}  // namespace tgm::service
