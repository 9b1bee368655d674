// Shared test helpers: paths to real data, scratch folders, timing budgets.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace st::test {

// ../shared beside the checkout (real data made by others).
inline std::filesystem::path shared_dir() { return SCOPETRACK_SHARED_DIR; }
inline std::filesystem::path shared_data(const std::string& rel) {
  return shared_dir() / "data" / rel;
}
// build/bin, where the executables land (end-to-end tests run them).
inline std::filesystem::path bin_dir() { return SCOPETRACK_BIN_DIR; }

// A fresh, empty scratch folder for one test, named after the test and the
// process. tests/main.cpp deletes them all when the process's tests pass.
std::filesystem::path scratch_dir(const std::string& name);
// Deletes every folder scratch_dir() made in this process, unless
// SCOPETRACK_KEEP_TEST_TMP is set to something other than 0.
void remove_scratch_dirs();

// Timing budget in seconds for doctest::timeout(): generous ceilings that
// catch gross regressions only. SCOPETRACK_TIME_SCALE multiplies them for
// slow, sanitized or emulated machines (e.g. 10 under ASan or qemu).
inline double budget_s(double seconds) {
  const char* s = std::getenv("SCOPETRACK_TIME_SCALE");
  const double scale = s ? std::atof(s) : 1.0;
  return seconds * (scale > 0 ? scale : 1.0);
}

// Tests that replay or render whole sequences are in the doctest suite
// "long" (CTest label "long"): the sanitizer pass (tools/test.sh --sanitize)
// leaves them to the Release pass, which runs everything.
inline constexpr const char* kLongSuite = "long";

// Test cases that start one of the project's programs (tools/, scopetrack)
// but are short are in the doctest suite "process". All other unit test
// cases carry the CTest label "portable": the aarch64 build runs them under
// qemu-aarch64 (tools/cross-aarch64.sh), where a program of the build
// cannot be started without binfmt. (Host programs such as ffmpeg and flatc
// can: a test that starts only those stays portable.)
inline constexpr const char* kProcessSuite = "process";

// Reads a whole file into bytes (test fixtures).
std::string read_file_bytes(const std::filesystem::path& p);

// A number field of run_dir/summary.json (a run's output folder); the test
// fails (REQUIRE) when the field is missing.
double summary_number(const std::filesystem::path& run_dir, const std::string& key);

}  // namespace st::test
