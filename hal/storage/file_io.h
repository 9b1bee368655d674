// Whole-file reads and writes for the parsers and formatters in core/.
// Load/save time only (allocates); never on the tracking thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "core/base/result.h"

namespace st {

// Reads a regular file, refusing files above max_bytes before reading them.
Result<std::string> read_file(const std::filesystem::path& path, std::int64_t max_bytes);
// Writes bytes to path.tmp and renames it over path, so a reader never sees
// a half-written file.
Status write_file(const std::filesystem::path& path, std::string_view bytes);

}  // namespace st
