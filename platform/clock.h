// Monotonic time. The only place core/ time comes from is its caller.
#pragma once

#include <cstdint>

namespace st::platform {

// CLOCK_MONOTONIC in nanoseconds.
std::int64_t monotonic_ns();
// Sleeps until the monotonic time reaches t_ns (absolute, no drift).
void sleep_until_ns(std::int64_t t_ns);
// Peak resident set size of this process in MiB (VmHWM), -1 if unknown.
double peak_rss_mb();
// Current resident set size in MiB (VmRSS), -1 if unknown.
double current_rss_mb();

}  // namespace st::platform
