#include "support/support.h"

#include <fstream>
#include <sstream>
#include <unistd.h>

namespace st::test {

std::filesystem::path scratch_dir(const std::string& name) {
  const char* base = std::getenv("SCOPETRACK_TEST_TMP");
  std::filesystem::path root = base ? base : std::filesystem::temp_directory_path() / "scopetrack-test";
  const auto dir = root / (name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string read_file_bytes(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace st::test
