// The soak (tools/soak/soak_run.h) at 10,000 frames: one scopetrack process
// over every scenario joined, the console reconnecting, every check of the
// 100,000-frame run (tools/soak.sh) applied. --ba-lag 3 makes the run
// repeatable (BA corrections land at fixed frames), so its quarters'
// figures do not depend on the machine's load.
#include <doctest/doctest.h>

#include <string>

#include "support/shell.h"
#include "support/support.h"

using namespace st;

TEST_CASE("soak: 10,000 frames of every scenario joined: no growth, no full pool, no drift, no allocation" *
          doctest::timeout(test::budget_s(900)) * doctest::test_suite(test::kLongSuite)) {
  const auto dir = test::scratch_dir("soak");
  const std::string cmd = test::bin_command("scopetrack-soak") + " --frames 10000 --segment-frames 500 --ba-lag 3 --out " +
                          test::shell_quoted(dir) + " > " + test::shell_quoted(dir / "stdout.txt") + " 2>&1";
  const int code = test::run_shell(cmd);
  const std::string report = test::read_file_bytes(dir / "stdout.txt");
  MESSAGE(report);
  CHECK(code == 0);
  CHECK(report.find("PASSED") != std::string::npos);
  CHECK(report.find("tracking-thread allocations 0") != std::string::npos);
  const std::string csv = test::read_file_bytes(dir / "soak.csv");
  CHECK(csv.rfind("frames,rss_mb,lost_pct,map_points,keyframes\n", 0) == 0);
  CHECK(csv.find("\n9000,") != std::string::npos);  // a sample every 1,000 frames but the last
  CHECK(test::read_file_bytes(dir / "soak.png").rfind("\x89PNG", 0) == 0);
}
