// Heap allocation counting. Linking the object library
// scopetrack_alloc_counter into an executable replaces the global
// operator new/delete with versions that count calls per thread; the
// tracking thread reads its own count to prove it allocates nothing after
// start-up (architecture.md, rule 1). The count costs one thread-local
// increment per allocation.
#pragma once

#include <cstdint>

namespace st::platform {

// Calls of operator new (any form) made by the calling thread so far.
std::uint64_t thread_allocation_count();
// True when the counting operator new is linked into this executable.
bool allocation_counting_enabled();

}  // namespace st::platform
