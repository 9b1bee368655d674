// Thread priorities in one place. Each call says plainly when it cannot be
// had (no privileges on a development host is normal) and the caller
// decides whether that is fatal.
#pragma once

#include <string>

namespace st::platform {

struct RealtimeReport {
  bool ok = false;
  std::string message;  // what was done or why not
};

// Background workers (mapping, texturing) lower their own priority so that
// the tracking thread wins whenever they share a core: Linux nice value of
// the calling thread only (setpriority on its thread id), 0..19. Lowering
// needs no privileges; a value below the current one is refused by an
// unprivileged process and reported as such.
inline constexpr int kBackgroundWorkerNice = 10;
RealtimeReport set_thread_nice(int nice_value);
int thread_nice();                                 // the calling thread's nice value
// What a background worker calls first: set_thread_nice(kBackgroundWorkerNice),
// then the nice value the thread has (the process's own when that is
// already lower in priority and raising is not allowed). Allocates (the
// report's message): call it before counting a thread's allocations.
int become_background_thread();

}  // namespace st::platform
