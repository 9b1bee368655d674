// run_simulation (sim_run.h): the frame loop and the sequence files.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <unistd.h>

#include "core/formats/sequence.h"
#include "core/formats/y4m.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/y4m_writer.h"
#include "tools/sim/breathing.h"
#include "tools/sim/sim_run.h"
#include "tools/sim/yuv.h"

namespace st::sim {
namespace {

Status write_text_files(const SimOptions& o, const SimSetup& s, const SimReport& r) {
  namespace fs = std::filesystem;
  SequenceConfig cfg;
  cfg.width = s.render.K.width;
  cfg.height = s.render.K.height;
  cfg.K = s.render.K;
  cfg.distortion = s.render.distortion;
  if (cfg.distortion.count == 0) cfg.distortion.count = 5;  // all zero: ideal pinhole
  cfg.fps = s.fps;
  cfg.T_camera_model_init = r.groundtruth.front().T_model_camera.inverse();
  cfg.video = "video.y4m";
  cfg.mesh = "organ.ply";
  cfg.groundtruth = "groundtruth.txt";
  cfg.markers = "markers.txt";
  if (Status st = write_file(o.out_dir / "sequence.yaml", format_sequence_yaml(cfg)); !st) return st;
  if (Status st = write_file(o.out_dir / "groundtruth.txt", format_tum(r.groundtruth)); !st) return st;
  if (Status st = write_file(o.out_dir / "markers.txt", format_markers(r.markers)); !st) return st;
  return save_mesh_ply(o.out_dir / "organ.ply", s.prior);
}

void show_progress(int done, int total, double fps) {
  const int width = 40, filled = done * width / std::max(total, 1);
  std::fprintf(stderr, "\r[%.*s%*s] %d/%d frames  %.1f frames/s", filled,
               "########################################", width - filled, "", done, total, fps);
  if (done == total) std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace

Result<SimReport> run_simulation(const SimOptions& o, const FrameSink& sink) {
  auto setup = make_setup(o);
  if (!setup) return setup.error();
  SimSetup& s = setup.value();
  std::error_code ec;
  std::filesystem::create_directories(o.out_dir, ec);
  if (ec) return make_error("cannot create " + o.out_dir.string() + ": " + ec.message());
  SceneRenderer renderer;
  if (Status st = renderer.configure(s.scene, s.render); !st) return make_error(st.message());
  const Trajectory traj(o.scenario, s.scene, s.frames, o.seed);
  // Ground truth: the camera in the organ's rigid frame, which moves with
  // the organ while it breathes (breathing.h).
  const BreathingField& breathing = renderer.breathing();
  const int W = s.render.K.width, H = s.render.K.height;
  Y4mHeader header;
  header.width = W;
  header.height = H;
  header.fps_num = 30;
  header.fps_den = 1;
  Y4mWriter video;
  if (Status st = video.open(o.out_dir / "video.y4m", header); !st) return make_error(st.message());
  Image<std::uint8_t> Y(W, H), U((W + 1) / 2, (H + 1) / 2), V((W + 1) / 2, (H + 1) / 2);
  cv::Mat rgb, labels;
  SimReport r;
  const bool bar = o.progress && isatty(2);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < s.frames; ++i) {
    renderer.render(traj, i, rgb, labels);
    rgb_to_yuv420_jpeg(rgb, Y.view(), U.view(), V.view());
    if (Status st = video.write(Y.cview(), U.cview(), V.cview()); !st) return make_error(st.message());
    const WorldState state = traj.at(i);
    r.groundtruth.push_back(TimedPose{i / s.fps, breathing.rigid_motion(state.breath).inverse() * state.T_model_camera()});
    if (i == 0) r.markers = pick_markers(renderer.visible_organ_points(traj.at(0), labels, std::max(6, W / 80), 4));
    if (sink) sink(i, rgb, labels);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (bar && (i % 5 == 4 || i + 1 == s.frames)) show_progress(i + 1, s.frames, (i + 1) / secs);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.frames = s.frames;
  r.fps = r.frames / r.seconds;
  if (Status st = video.close(); !st) return make_error(st.message());
  if (r.markers.size() < 3) return make_error("frame 0 shows too little of the organ to place 3 markers");
  if (Status st = write_text_files(o, s, r); !st) return make_error(st.message());
  return r;
}

}  // namespace st::sim
