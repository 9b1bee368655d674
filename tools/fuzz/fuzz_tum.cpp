// Fuzzes the TUM trajectory parser; accepted input must round-trip.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto poses = st::parse_tum(std::string_view(reinterpret_cast<const char*>(data), size));
  if (poses) {
    const auto again = st::parse_tum(st::format_tum(poses.value()));
    if (!again || again->size() != poses->size()) __builtin_trap();
  }
  return 0;
}
