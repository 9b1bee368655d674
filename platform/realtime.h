// Real-time setup in one place: memory locking, scheduling class, CPU
// affinity. Each call says plainly when it cannot be had (no privileges on
// a development host is normal) and the caller decides whether that is fatal.
#pragma once

#include <string>

namespace st::platform {

struct RealtimeReport {
  bool ok = false;
  std::string message;  // what was done or why not
};

RealtimeReport lock_memory();                      // mlockall(MCL_CURRENT | MCL_FUTURE)
RealtimeReport set_fifo_priority(int priority);    // SCHED_FIFO for the calling thread
RealtimeReport pin_to_cpu(int cpu);                // affinity of the calling thread

}  // namespace st::platform
