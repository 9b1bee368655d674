#include "platform/realtime.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace st::platform {

RealtimeReport lock_memory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return {true, "memory locked (mlockall)"};
  return {false, std::string("mlockall failed: ") + std::strerror(errno) +
                     " (needs CAP_IPC_LOCK or a raised RLIMIT_MEMLOCK)"};
}

RealtimeReport set_fifo_priority(int priority) {
  sched_param sp{};
  sp.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  if (rc == 0) return {true, "SCHED_FIFO priority " + std::to_string(priority)};
  return {false, std::string("SCHED_FIFO unavailable: ") + std::strerror(rc) +
                     " (needs CAP_SYS_NICE or an rtprio limit); running SCHED_OTHER"};
}

RealtimeReport pin_to_cpu(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
  if (rc == 0) return {true, "pinned to CPU " + std::to_string(cpu)};
  return {false, std::string("cannot pin to CPU ") + std::to_string(cpu) + ": " + std::strerror(rc)};
}

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
