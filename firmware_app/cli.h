// The scopetrack command line: one entry per mode in main.cpp's table.
// A mode gets the arguments after its flag and returns the exit status.
#pragma once

#include <span>
#include <string_view>

#include "core/base/result.h"
#include "hal/storage/sequence_loader.h"

namespace st::app {

using Args = std::span<char* const>;

struct Command {
  std::string_view flag;   // "--check"
  std::string_view usage;  // "DIR"
  std::string_view help;   // one line
  int (*run)(Args args);
};

// scopetrack --check DIR: validates a sequence folder (firmware_app/check.cpp).
int run_check(Args args);
// The same validation as --check, silent, for a sequence that is about to be
// replayed, except the video scan: a replay reads the video as it goes and
// reports a broken one at the frame where it breaks. The first error, if any.
Status check_sequence_for_replay(const LoadedSequence& sequence);

// scopetrack --sequence DIR --out DIR [...]: replay (firmware_app/replay_command.cpp).
// Options after DIR: --out DIR (required), --config FILE, --set KEY=VALUE, --ba-lag N,
// --realtime, --ring N, --stream ENDPOINT (firmware_app/replay_command.cpp has them all).
int run_replay(Args args);

}  // namespace st::app
