// Stage "capture": Y4mReader::read_frame() on a 1280x720 4:2:0 video in
// the page cache (the tracker's per-frame input cost), against a bare
// ::read() of the same bytes into one buffer (the syscall + copy floor).
// Rows "scale": the tracker's working resolution, AreaScaler on a 4:2:0
// frame from the tower (1080p, 4K) to 1280x720, luma and chroma, cycling
// over 8 frames so that the input comes from memory as a captured frame
// does; OpenCV's INTER_AREA resize on the same planes as the baseline.
// Row "mesh load" times parse_ply + validate_and_orient of the real CT liver
// (20k triangles): a start-up cost, shown for scale.
#include <cstdio>
#include <fcntl.h>
#include <filesystem>
#include <unistd.h>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "bench.h"
#include "core/image/area_scale.h"
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

Row bench_scale(const Options& opt, int in_w, int in_h, int out_w, int out_h) {
  constexpr int kFrames = 8;
  std::vector<Image<std::uint8_t>> y, u, v;
  for (int f = 0; f < kFrames; ++f) {
    y.emplace_back(in_w, in_h);
    u.emplace_back(in_w / 2, in_h / 2);
    v.emplace_back(in_w / 2, in_h / 2);
    for (int r = 0; r < in_h; ++r)
      for (int c = 0; c < in_w; ++c) y.back()(c, r) = static_cast<std::uint8_t>((c * 7 + r * 3 + f * 11) & 255);
    u.back().fill(120);
    v.back().fill(140);
  }
  FrameScaler scaler;
  Image<std::uint8_t> oy(out_w, out_h), ou(out_w / 2, out_h / 2), ov(out_w / 2, out_h / 2);
  Row row{"scale " + std::to_string(in_w) + "x" + std::to_string(in_h) + " -> " + std::to_string(out_w) + "x" +
              std::to_string(out_h) + " 4:2:0",
          {}, "cv::resize INTER_AREA", {}, ""};
  if (!scaler.configure(in_w, in_h, out_w, out_h).ok()) return row;
  cv::Mat ry, ru, rv;
  const auto mat = [](Image<std::uint8_t>& i) { return cv::Mat(i.height(), i.width(), CV_8U, i.data()); };
  const int n = opt.iterations > 0 ? opt.iterations : 200;
  for (int i = 0; i < n; ++i) {
    const auto f = static_cast<std::size_t>(i % kFrames);
    double t0 = now_ms();
    bool chroma = false;
    scaler.scale(y[f].cview(), u[f].cview(), v[f].cview(), oy.view(), ou.view(), ov.view(), &chroma);
    row.samples_ms.push_back(now_ms() - t0);
    const auto g = static_cast<std::size_t>((i + kFrames / 2) % kFrames);
    t0 = now_ms();
    cv::resize(mat(y[g]), ry, cv::Size(out_w, out_h), 0, 0, cv::INTER_AREA);
    cv::resize(mat(u[g]), ru, cv::Size(out_w / 2, out_h / 2), 0, 0, cv::INTER_AREA);
    cv::resize(mat(v[g]), rv, cv::Size(out_w / 2, out_h / 2), 0, 0, cv::INTER_AREA);
    row.baseline_ms.push_back(now_ms() - t0);
  }
  return row;
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
  report(opt, bench_scale(opt, 1920, 1080, 1280, 720));
  report(opt, bench_scale(opt, 3840, 2160, 1280, 720));

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

SCOPETRACK_BENCH_STAGE("capture", "Y4M frame read (1280x720), scaling to the working size, mesh load", run_capture);

}  // namespace st::bench
