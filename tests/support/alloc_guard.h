// Counts heap allocations of the calling thread inside a scope
// (the counting operator new is linked into the test binary).
#pragma once

#include <cstdint>

#include "platform/alloc_counter.h"

namespace st::test {

class AllocationCounter {
 public:
  AllocationCounter() : start_(platform::thread_allocation_count()) {}
  std::uint64_t count() const { return platform::thread_allocation_count() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace st::test
