#include "support/support.h"

#include <doctest/doctest.h>

#include <cstring>
#include <fstream>
#include <mutex>
#include <sstream>
#include <unistd.h>
#include <vector>

#include "tools/eval/eval_report.h"

namespace st::test {
namespace {
std::mutex g_scratch_mutex;
std::vector<std::filesystem::path> g_scratch_dirs;
}  // namespace

std::filesystem::path scratch_dir(const std::string& name) {
  const char* base = std::getenv("SCOPETRACK_TEST_TMP");
  std::filesystem::path root = base ? base : std::filesystem::temp_directory_path() / "scopetrack-test";
  const auto dir = root / (name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::lock_guard<std::mutex> lock(g_scratch_mutex);
  g_scratch_dirs.push_back(dir);
  return dir;
}

void remove_scratch_dirs() {
  const char* keep = std::getenv("SCOPETRACK_KEEP_TEST_TMP");
  if (keep && *keep && std::strcmp(keep, "0") != 0) return;
  std::lock_guard<std::mutex> lock(g_scratch_mutex);
  for (const auto& dir : g_scratch_dirs) {
    std::error_code ec;  // a folder already gone is fine
    std::filesystem::remove_all(dir, ec);
  }
  g_scratch_dirs.clear();
}

std::string read_file_bytes(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

double summary_number(const std::filesystem::path& run_dir, const std::string& key) {
  auto v = json_number(read_file_bytes(run_dir / "summary.json"), key);
  REQUIRE_MESSAGE(v.ok(), key);
  return v.value();
}

}  // namespace st::test
