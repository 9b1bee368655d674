// Fuzzes the markers.txt parser; accepted input must round-trip.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto markers = st::parse_markers(std::string_view(reinterpret_cast<const char*>(data), size));
  if (markers) {
    const auto again = st::parse_markers(st::format_markers(markers.value()));
    if (!again || again->size() != markers->size()) __builtin_trap();
  }
  return 0;
}
