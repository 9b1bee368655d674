// scopetrack-bench: one executable, one stage per source file.
// A stage registers itself with SCOPETRACK_BENCH_STAGE and reports rows
// through report(); the harness prints a table for people or, with --json,
// one JSON object per line for machines:
//   {"bench": NAME, "median_ms": .., "p99_ms": .., "baseline": NAME,
//    "baseline_median_ms": .., "speedup": baseline_median_ms / median_ms}
#pragma once

#include <string>
#include <vector>

namespace st::bench {

struct Options {
  bool json = false;
  int iterations = 0;        // 0: the stage's own default
  std::string shared_dir;    // ../shared (real data)
  std::vector<std::string> args;  // stage-specific arguments after the stage name
};

struct Row {
  std::string name;
  std::vector<double> samples_ms;
  std::string baseline;                // empty: no baseline
  std::vector<double> baseline_ms;
  std::string note;                    // free text shown in the table, "note" in JSON
};

double median(std::vector<double> v);
double percentile(std::vector<double> v, double p);  // p in [0, 100]
void report(const Options& opt, const Row& row);
// Prints a line to stderr (progress, context); never to stdout under --json.
void info(const Options& opt, const std::string& line);

using StageFn = int (*)(const Options&);
struct StageRegistration {
  StageRegistration(const char* name, const char* help, StageFn fn);
};

// Monotonic milliseconds (for timing loops).
double now_ms();

}  // namespace st::bench

#define SCOPETRACK_BENCH_STAGE(name, help, fn) \
  static ::st::bench::StageRegistration scopetrack_bench_reg_##fn(name, help, fn)
