// scopetrack-soak --out DIR [--frames N (100000)] [--size WxH (640x360)]
//                 [--segment-frames F (500)] [--seed S (1)] [--reconnect-every K (3000)]
//                 [--ba-lag N (live)]
// Hours of operation in one run (tools/soak/soak_run.h): writes
// DIR/soak.csv (a sample every 1,000 frames), DIR/soak.png and
// DIR/report.txt, and keeps the tracker's output in DIR/run. Exit status 0
// passed, 1 a check failed or the soak could not run, 2 bad command line.
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/formats/text_scan.h"
#include "hal/storage/file_io.h"
#include "tools/soak/soak_run.h"

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: scopetrack-soak --out DIR [--frames N (100000)] [--size WxH (640x360)]\n"
               "                       [--segment-frames F (500)] [--seed S (1)] [--reconnect-every K (3000)]\n"
               "                       [--ba-lag N (live)]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // scopetrack gone mid-run: the capture's write fails (EPIPE) and the soak
  // reports it, instead of SIGPIPE ending the soak.
  std::signal(SIGPIPE, SIG_IGN);
  st::soak::SoakOptions o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help") {
      usage();
      return 0;
    }
    if (i + 1 >= argc) return usage();
    const char* v = argv[++i];
    long long n = 0;
    if (a == "--out") {
      o.out_dir = v;
    } else if (a == "--frames" && st::parse_int64_in(v, 8000, 10'000'000, &n)) {
      o.frames = static_cast<int>(n);
    } else if (a == "--segment-frames" && st::parse_int64_in(v, 100, 100'000, &n)) {
      o.segment_frames = static_cast<int>(n);
    } else if (a == "--seed" && st::parse_int64_in(v, 0, 1'000'000'000, &n)) {
      o.seed = static_cast<std::uint64_t>(n);
    } else if (a == "--reconnect-every" && st::parse_int64_in(v, 1, 10'000'000, &n)) {
      o.reconnect_every = static_cast<int>(n);
    } else if (a == "--ba-lag" && st::parse_int64_in(v, 1, 100, &n)) {
      o.ba_lag = static_cast<int>(n);
    } else if (a == "--size" && std::sscanf(v, "%dx%d", &o.width, &o.height) == 2 && o.width >= 160 &&
               o.height >= 120 && o.width <= 3840 && o.height <= 2160 && o.width % 2 == 0 && o.height % 2 == 0) {
    } else {
      std::fprintf(stderr, "scopetrack-soak: bad option %s %s\n", a.c_str(), v);
      return usage();
    }
  }
  if (o.out_dir.empty()) return usage();
  std::error_code ec;
  o.bin_dir = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
  o.progress = true;
  std::filesystem::create_directories(o.out_dir, ec);
  auto r = st::soak::run_soak(o);
  if (!r) {
    std::fprintf(stderr, "scopetrack-soak: %s\n", r.message().c_str());
    return 1;
  }
  const std::string report = st::soak::format_report(r.value());
  std::fputs(report.c_str(), stdout);
  if (!st::write_file(o.out_dir / "soak.csv", st::soak::format_samples_csv(r.value())) ||
      !st::write_file(o.out_dir / "report.txt", report))
    std::fprintf(stderr, "scopetrack-soak: cannot write into %s\n", o.out_dir.c_str());
  if (st::Status s = st::soak::write_plot(r.value(), o.out_dir / "soak.png"); !s)
    std::fprintf(stderr, "scopetrack-soak: %s\n", s.message().c_str());
  return r->failures.empty() ? 0 : 1;
}
