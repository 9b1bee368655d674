#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "bench.h"
#include "core/formats/json_text.h"
#include "core/formats/text_scan.h"
#include "platform/clock.h"

namespace st::bench {
namespace {
struct Stage {
  const char* name;
  const char* help;
  StageFn fn;
};
std::vector<Stage>& stages() {
  static std::vector<Stage> s;
  return s;
}
}  // namespace

StageRegistration::StageRegistration(const char* name, const char* help, StageFn fn) {
  stages().push_back({name, help, fn});
}

double now_ms() { return static_cast<double>(platform::monotonic_ns()) * 1e-6; }

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = std::clamp(p, 0.0, 100.0) / 100.0 * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}
double median(std::vector<double> v) { return percentile(std::move(v), 50.0); }


void report(const Options& opt, const Row& row) {
  // p10 next to the median: on a shared, noisy host the fast tail moves
  // less between runs than the median (A/B comparisons).
  const double med = median(row.samples_ms), p99 = percentile(row.samples_ms, 99.0),
               p10 = percentile(row.samples_ms, 10.0);
  const bool has_base = !row.baseline.empty() && !row.baseline_ms.empty();
  const double base_med = has_base ? median(row.baseline_ms) : std::nan("");
  if (opt.json) {
    std::printf(
        "{\"bench\": \"%s\", \"median_ms\": %.4f, \"p99_ms\": %.4f, \"p10_ms\": %.4f, "
        "\"samples\": %zu",
        st::json_escaped(row.name).c_str(), med, p99, p10, row.samples_ms.size());
    if (has_base)
      std::printf(", \"baseline\": \"%s\", \"baseline_median_ms\": %.4f, \"speedup\": %.3f",
                  st::json_escaped(row.baseline).c_str(), base_med, base_med / med);
    if (!row.note.empty()) std::printf(", \"note\": \"%s\"", st::json_escaped(row.note).c_str());
    std::printf("}\n");
  } else {
    std::printf("%-34s median %9.3f ms   p99 %9.3f ms   p10 %9.3f ms   (n=%zu)\n",
                row.name.c_str(), med, p99, p10, row.samples_ms.size());
    if (has_base)
      std::printf("  %-32s median %9.3f ms   -> speedup %.2fx\n", row.baseline.c_str(), base_med,
                  base_med / med);
    if (!row.note.empty()) std::printf("  %s\n", row.note.c_str());
  }
  std::fflush(stdout);
}

void info(const Options& opt, const std::string& line) {
  (void)opt;
  std::fprintf(stderr, "%s\n", line.c_str());
}

}  // namespace st::bench

static void usage() {
  std::printf("usage: scopetrack-bench [--json] [--iterations N] [--shared DIR] STAGE [ARGS...]\n"
              "stages:\n");
  for (const auto& s : st::bench::stages()) std::printf("  %-10s %s\n", s.name, s.help);
}

int main(int argc, char** argv) {
  st::bench::Options opt;
  opt.shared_dir = SCOPETRACK_SHARED_DIR;
  const char* stage = nullptr;
  for (int i = 1; i < argc; ++i) {
    if (stage) {
      opt.args.emplace_back(argv[i]);
    } else if (!std::strcmp(argv[i], "--json")) {
      opt.json = true;
    } else if (!std::strcmp(argv[i], "--iterations") && i + 1 < argc) {
      long long n = 0;
      if (!st::parse_int64_in(argv[++i], 1, 1000000, &n)) {
        std::fprintf(stderr, "scopetrack-bench: --iterations takes a count in 1..1000000\n");
        return 2;
      }
      opt.iterations = static_cast<int>(n);
    } else if (!std::strcmp(argv[i], "--shared") && i + 1 < argc) {
      opt.shared_dir = argv[++i];
    } else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      usage();
      return 0;
    } else {
      stage = argv[i];
    }
  }
  if (!stage) {
    usage();
    return 2;
  }
  for (const auto& s : st::bench::stages())
    if (!std::strcmp(s.name, stage)) return s.fn(opt);
  std::fprintf(stderr, "scopetrack-bench: unknown stage '%s'\n", stage);
  usage();
  return 2;
}
