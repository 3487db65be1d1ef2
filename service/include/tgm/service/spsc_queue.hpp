// Bounded single-producer single-consumer queue: the hand-off between a DDS thread and the cycle
// thread (DESIGN.md section 3). Lock-free, no allocation after construction, never blocks: push()
// and pop() return false when the queue is full / empty.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <utility>

namespace tgm::service {

//! Capacity is a power of two, fixed at construction. T must be default-constructible and
//! assignable; elements are moved in and out (slots are reused, so a T with heap storage keeps
//! its capacity).
template <class T>
class SpscQueue {
 public:
  explicit SpscQueue(std::size_t capacity_pow2) : mask_(round_up(capacity_pow2) - 1),
                                                   slots_(new T[mask_ + 1]) {}
  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  //! Producer: false when full (nothing is written).
  bool push(const T& v) {
    const std::size_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_cache_ > mask_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (h - tail_cache_ > mask_) return false;
    }
    slots_[h & mask_] = v;
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  //! Consumer: false when empty.
  bool pop(T& out) {
    T* f = front();
    if (f == nullptr) return false;
    out = std::move(*f);
    pop_front();
    return true;
  }
  //! Consumer: the oldest element (stays in the queue), or null when empty.
  T* front() {
    const std::size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (t == head_cache_) return nullptr;
    }
    return &slots_[t & mask_];
  }
  //! Consumer: drops the element front() returned.
  void pop_front() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  //! Producer: true when push() would fail.
  bool full() const {
    return head_.load(std::memory_order_relaxed) - tail_.load(std::memory_order_acquire) > mask_;
  }
  std::size_t capacity() const { return mask_ + 1; }

 private:
  static std::size_t round_up(std::size_t n) {
    std::size_t c = 1;
    while (c < n) c <<= 1;
    return c;
  }
  const std::size_t mask_;
  std::unique_ptr<T[]> slots_;
  alignas(64) std::atomic<std::size_t> head_{0};
  std::size_t tail_cache_ = 0;  // producer's view of tail_
  alignas(64) std::atomic<std::size_t> tail_{0};
  std::size_t head_cache_ = 0;  // consumer's view of head_
};

}  // namespace tgm::service
