#include "platform/realtime.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace st::platform {

RealtimeReport set_thread_nice(int nice_value) {
  if (nice_value < 0 || nice_value > 19)
    return {false, "nice value " + std::to_string(nice_value) + " outside 0..19"};
  // On Linux PRIO_PROCESS with a thread id sets that thread alone.
  const auto tid = static_cast<id_t>(gettid());
  if (setpriority(PRIO_PROCESS, tid, nice_value) == 0) return {true, "nice " + std::to_string(nice_value)};
  return {false, std::string("cannot set nice ") + std::to_string(nice_value) + ": " + std::strerror(errno) +
                     " (raising a thread's priority needs CAP_SYS_NICE); keeping nice " +
                     std::to_string(thread_nice())};
}

int become_background_thread() {
  set_thread_nice(kBackgroundWorkerNice);
  return thread_nice();
}

int thread_nice() {
  errno = 0;
  const int v = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
  return errno == 0 ? v : 0;
}

}  // namespace st::platform
