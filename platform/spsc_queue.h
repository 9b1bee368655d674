// Fixed-capacity single-producer single-consumer queue (lock-free ring).
// One thread pushes, one thread pops; neither ever allocates (the slots are
// a member array) and neither takes a lock. The blocking variants park the
// thread on a futex (std::atomic::wait) after a short spin, so a consumer
// that waits for the next frame costs no CPU and wakes as soon as it comes.
// Used between the capture, tracking and writer threads of a replay.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace st::platform {

template <class T, std::size_t Capacity>
class SpscQueue {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0,
                "capacity must be a power of two");
  static_assert(Capacity <= (std::size_t{1} << 31), "indices are 32-bit");

 public:
  static constexpr std::size_t capacity() { return Capacity; }

  // Producer thread. False when full (nothing is written).
  bool try_push(const T& item) {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (tail - head_.load(std::memory_order_acquire) >= Capacity) return false;
    slots_[tail & kMask] = item;
    tail_.store(tail + 1, std::memory_order_release);
    tail_.notify_one();
    return true;
  }

  // Consumer thread. False when empty.
  bool try_pop(T* out) {
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    if (tail_.load(std::memory_order_acquire) == head) return false;
    *out = slots_[head & kMask];
    head_.store(head + 1, std::memory_order_release);
    head_.notify_one();
    return true;
  }

  // Producer thread: waits while the queue is full. Returns true when it
  // had to wait (the caller may count stalls).
  bool push_wait(const T& item) {
    bool waited = false;
    for (int spin = 0; !try_push(item); ++spin) {
      waited = true;
      if (spin < kSpins) continue;
      const std::uint32_t head = head_.load(std::memory_order_acquire);
      if (tail_.load(std::memory_order_relaxed) - head >= Capacity)
        head_.wait(head, std::memory_order_acquire);
    }
    return waited;
  }

  // Consumer thread: waits while the queue is empty.
  void pop_wait(T* out) {
    for (int spin = 0; !try_pop(out); ++spin) {
      if (spin < kSpins) continue;
      const std::uint32_t tail = tail_.load(std::memory_order_acquire);
      if (tail == head_.load(std::memory_order_relaxed)) tail_.wait(tail, std::memory_order_acquire);
    }
  }

  // Either thread; exact only when the other side is idle.
  std::size_t size() const {
    return tail_.load(std::memory_order_acquire) - head_.load(std::memory_order_acquire);
  }

 private:
  static constexpr std::uint32_t kMask = static_cast<std::uint32_t>(Capacity - 1);
  static constexpr int kSpins = 64;
  // Separate cache lines: the producer writes tail_, the consumer head_.
  alignas(64) std::atomic<std::uint32_t> head_{0};  // next slot to pop
  alignas(64) std::atomic<std::uint32_t> tail_{0};  // next slot to push
  alignas(64) std::array<T, Capacity> slots_{};
};

}  // namespace st::platform
