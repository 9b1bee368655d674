// Text inside a JSON string: the one escaper of the project's JSON writers
// (summary.json, the benchmark's --json rows).
#pragma once

#include <string>
#include <string_view>

namespace st {

// s with '"' and '\' escaped and every control character (below 0x20)
// written as a space: the writers' strings are one-line messages and names.
std::string json_escaped(std::string_view s);

}  // namespace st
