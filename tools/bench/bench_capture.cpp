// Stage "capture": Y4mReader::read_frame() on a 1280x720 4:2:0 video in
// the page cache (the tracker's per-frame input cost), against a bare
// ::read() of the same bytes into one buffer (the syscall + copy floor).
// Row "mesh load" times parse_ply + validate_and_orient of the real CT liver
// (20k triangles): a start-up cost, shown for scale.
#include <cstdio>
#include <fcntl.h>
#include <filesystem>
#include <unistd.h>
#include <vector>

#include "bench.h"
#include "core/formats/mesh_io.h"
#include "hal/storage/file_io.h"
#include "hal/capture/y4m_reader.h"
#include "hal/storage/y4m_writer.h"

namespace st::bench {
namespace {

constexpr int kWidth = 1280, kHeight = 720;

bool write_video(const std::filesystem::path& p, int frames) {
  Y4mHeader h;
  h.width = kWidth;
  h.height = kHeight;
  Y4mWriter w;
  if (!w.open(p, h).ok()) return false;
  Image<std::uint8_t> Y(kWidth, kHeight), U(kWidth / 2, kHeight / 2), V(kWidth / 2, kHeight / 2);
  for (int f = 0; f < frames; ++f) {
    Y.fill(static_cast<std::uint8_t>(f));
    U.fill(128);
    V.fill(128);
    if (!w.write(Y.cview(), U.cview(), V.cview()).ok()) return false;
  }
  return w.close().ok();
}

std::vector<double> time_reader(const std::filesystem::path& p) {
  std::vector<double> ms;
  Y4mReader r;
  if (!r.open(p, 3).ok()) return ms;
  FrameRef f;
  for (;;) {
    const double t0 = now_ms();
    if (r.read_frame(&f) != ReadResult::kFrame) break;
    ms.push_back(now_ms() - t0);
  }
  return ms;
}

std::vector<double> time_raw_read(const std::filesystem::path& p, std::size_t frame_bytes) {
  std::vector<double> ms;
  std::vector<char> buf(frame_bytes + 6);
  const int fd = ::open(p.c_str(), O_RDONLY);
  if (fd < 0) return ms;
  char header[128];
  if (::read(fd, header, 32) < 0) return ms;  // skip roughly the header; alignment is irrelevant here
  for (;;) {
    const double t0 = now_ms();
    std::size_t got = 0;
    ssize_t n = 1;
    while (got < buf.size() && (n = ::read(fd, buf.data() + got, buf.size() - got)) > 0) got += static_cast<std::size_t>(n);
    if (got < buf.size()) break;
    ms.push_back(now_ms() - t0);
  }
  ::close(fd);
  return ms;
}

int run_capture(const Options& opt) {
  const int frames = opt.iterations > 0 ? opt.iterations : 200;
  const auto path = std::filesystem::temp_directory_path() / ("scopetrack-bench-capture-" + std::to_string(::getpid()) + ".y4m");
  if (!write_video(path, frames)) {
    std::fprintf(stderr, "capture: cannot write %s\n", path.c_str());
    return 1;
  }
  for (int warm = 0; warm < 2; ++warm) (void)time_reader(path);  // page cache
  Row row{"capture Y4M 1280x720 4:2:0", time_reader(path), "raw read()", {}, ""};
  row.baseline_ms = time_raw_read(path, static_cast<std::size_t>(kWidth) * kHeight * 3 / 2);
  report(opt, row);
  std::filesystem::remove(path);

  const auto liver = std::filesystem::path(opt.shared_dir) / "data/liver/liver.ply";
  Result<std::string> bytes = read_file(liver, 1 << 30);
  if (!bytes) {
    info(opt, "capture: no " + liver.string() + ", mesh row skipped");
    return 0;
  }
  Row mesh{"mesh load (parse+validate, CT liver 20k tri)", {}, "", {}, ""};
  for (int i = 0; i < 20; ++i) {
    const double t0 = now_ms();
    Result<Mesh> m = parse_ply(bytes.value());
    if (!m || !validate_and_orient(m.value(), nullptr).ok()) return 1;
    mesh.samples_ms.push_back(now_ms() - t0);
  }
  report(opt, mesh);
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("capture", "Y4M frame read (1280x720) and mesh load", run_capture);

}  // namespace st::bench
