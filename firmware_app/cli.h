// The scopetrack command line: one entry per mode in main.cpp's table.
// A mode gets the arguments after its flag and returns the exit status.
#pragma once

#include <span>
#include <string_view>

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

}  // namespace st::app
