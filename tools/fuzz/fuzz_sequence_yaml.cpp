// Fuzzes sequence.yaml parsing (our checks on top of cv::FileStorage).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/sequence.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const st::Result<st::SequenceConfig> c =
      st::parse_sequence_yaml(std::string_view(reinterpret_cast<const char*>(data), size));
  if (c) {
    // Whatever was accepted is written back and must parse again.
    if (!st::parse_sequence_yaml(st::format_sequence_yaml(c.value()))) __builtin_trap();
  }
  return 0;
}
