// scopetrack --camera / --list-cameras: the tracker on a live libcamera
// stream (hal/capture/libcamera_capture.h). NOT RUN ON HARDWARE: the development
// machine has no camera; the no-camera paths are tested, and run_live (all
// of the run after the camera is open) is tested with a scripted source in
// the camera's place (tests/unit/app/test_live_stop.cpp).
//
// Threads: the calling (owner) thread blocks SIGINT/SIGTERM before any
// thread exists (libcamera's and ours inherit the mask), opens everything,
// starts the tracking thread and waits in sigtimedwait, printing a status
// line each second. On a signal (or when tracking ends by itself) it stops
// the camera, joins the tracking thread and writes the summary. The
// tracking thread runs the frame loop that replays run too
// (firmware_app/frame_loop.h): it converts, tracks, and pushes rows to the
// RunWriter, and allocates nothing after the processor's start() (counted,
// reported).
#include "firmware_app/camera_command.h"

#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>

#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/formats/sequence.h"
#include "core/formats/text_scan.h"
#include "firmware_app/frame_loop.h"
#include "firmware_app/settings_args.h"
#include "firmware_app/tracker_processor.h"
#include "hal/capture/libcamera_capture.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/run_writer.h"
#include "platform/clock.h"

namespace st::app {

namespace {

constexpr std::int64_t kMaxCalibrationBytes = 1 << 20;

struct CameraArgs {
  std::string camera, mesh, calibration, out;
  int ring_slots = 4;
  SettingsArgs settings;  // --config FILE, --set KEY=VALUE (firmware_app/settings_args.h)
};

bool parse_args(Args args, CameraArgs* a) {
  const int argc = static_cast<int>(args.size());
  if (argc > 0) a->camera = args[0];
  for (int i = 1; i < argc; ++i) {
    const char* arg = args[static_cast<std::size_t>(i)];
    const bool has_value = i + 1 < argc;
    bool bad = false;
    if (take_settings_arg(args, &i, &a->settings, &bad)) {
      if (bad) return false;
    } else if (!std::strcmp(arg, "--mesh") && has_value) {
      a->mesh = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--calibration") && has_value) {
      a->calibration = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--out") && has_value) {
      a->out = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--ring") && has_value) {
      long long n = 0;
      if (!parse_int64_in(args[static_cast<std::size_t>(++i)], 2, kMaxRingSlots, &n)) {
        std::fprintf(stderr, "scopetrack: --ring takes a slot count in 2..%d\n", kMaxRingSlots);
        return false;
      }
      a->ring_slots = static_cast<int>(n);
    } else {
      std::fprintf(stderr, "scopetrack: unknown or incomplete argument '%s'\n", arg);
      return false;
    }
  }
  if (a->camera.empty() || a->camera.front() == '-' || a->mesh.empty() || a->calibration.empty()) {
    std::fprintf(stderr, "scopetrack: --camera ID, --mesh FILE and --calibration FILE are required\n");
    return false;
  }
  return true;
}

// Calibration, mesh and camera, in that order (files first: cheap and
// the commonest mistakes). Prints the reason and returns false on failure.
bool open_inputs(const CameraArgs& a, SequenceConfig* cal, Mesh* mesh, LibcameraCapture* capture) {
  auto bytes = read_file(a.calibration, kMaxCalibrationBytes);
  auto parsed = bytes ? parse_calibration_yaml(bytes.value()) : Result<SequenceConfig>(bytes.error());
  if (!parsed) {
    std::fprintf(stderr, "scopetrack: calibration %s: %s\n", a.calibration.c_str(), parsed.message().c_str());
    return false;
  }
  *cal = parsed.value();
  auto loaded = load_mesh_file(a.mesh, nullptr);
  if (!loaded) {
    std::fprintf(stderr, "scopetrack: mesh: %s\n", loaded.message().c_str());
    return false;
  }
  *mesh = std::move(loaded.value());
  if (Status s = capture->open({a.camera, cal->width, cal->height, a.ring_slots}); !s) {
    std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
    return false;
  }
  return true;
}

// Owner thread: until SIGINT/SIGTERM (the signal) or the tracking thread
// ends by itself (0).
int wait_for_stop(const sigset_t& signals, const LoopStatus& status, bool print) {
  const timespec tick{1, 0};
  while (!status.done.load()) {
    const int sig = sigtimedwait(&signals, nullptr, &tick);
    if (sig == SIGINT || sig == SIGTERM) return sig;
    if (print)
      std::fprintf(stderr, "\r%d frames  %d with a pose  %d lost  state %s%s   ", status.frames.load(),
                   status.tracked.load(), status.lost.load(),
                   to_string(static_cast<FrameState>(status.last_state.load())),
                   status.calibration_suspect.load() ? "  CALIBRATION SUSPECT" : "");
  }
  return 0;
}

// Owner thread, after the tracking thread ended: stats, the summary line,
// summary.json with an output folder. The exit status.
int finish_run(const LiveRun& run, const TrackerProcessor& processor, RunWriter* writer, FrameLoop* loop) {
  RunStats& stats = loop->stats;
  loop->fill_timing();
  if (loop->source_error) stats.error = run.source->error();
  const CaptureCounters counters = run.counters ? run.counters() : CaptureCounters{};
  std::fprintf(stderr, "\n%d frames: %d with a pose, %d lost  %.1f fps  latency mean %.2f ms p99 %.2f ms"
               "  skipped %llu  failed %llu  tracking-thread allocations %lld\n",
               stats.frames, stats.tracked, stats.lost, stats.fps, stats.mean_latency_ms, stats.p99_latency_ms,
               static_cast<unsigned long long>(counters.skipped), static_cast<unsigned long long>(counters.failed),
               static_cast<long long>(stats.tracking_thread_allocations));
  if (writer) {
    if (Status s = writer->finish(); !s && stats.error.empty()) stats.error = s.message();
    std::vector<std::pair<std::string, double>> extra = {
        {"width", run.calibration.width}, {"height", run.calibration.height},
        {"camera_skipped_frames", static_cast<double>(counters.skipped)},
        {"camera_failed_frames", static_cast<double>(counters.failed)}};
    processor.append_summary(&extra);
    if (Status s = write_file(std::filesystem::path(run.out_dir) / "summary.json",
                              format_run_summary(stats, true, extra));
        !s) {
      std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
      if (stats.error.empty()) stats.error = s.message();
    }
  }
  if (!stats.error.empty()) std::fprintf(stderr, "scopetrack: capture ended: %s\n", stats.error.c_str());
  if (const CalibrationCheck c = processor.calibration_check(); c.suspect)
    std::fprintf(stderr, "scopetrack: %s\n", describe_calibration(c, run.calibration_path).c_str());
  return stats.error.empty() ? 0 : 1;
}

}  // namespace

int run_list_cameras(Args args) {
  if (!args.empty()) {
    std::fprintf(stderr, "usage: scopetrack --list-cameras\n");
    return 2;
  }
  auto listing = list_cameras();
  if (!listing) {
    std::fprintf(stderr, "scopetrack: %s\n", listing.message().c_str());
    return 1;
  }
  if (listing->ids.empty()) {
    std::fprintf(stderr, "scopetrack: %s\n", describe_cameras(listing.value()).c_str());
    return 1;
  }
  for (const std::string& id : listing->ids) std::printf("%s\n", id.c_str());
  return 0;
}

int run_camera(Args argv) {
  CameraArgs args;
  if (!parse_args(argv, &args)) {
    std::fprintf(stderr, "usage: scopetrack --camera ID --mesh FILE --calibration FILE [--out DIR] [--ring N]"
                         " [--config FILE] [--set KEY=VALUE]...\n");
    return 2;
  }
  TrackerConfig tc;
  if (Status s = apply_settings(args.settings, &tc); !s) {
    std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
    return 2;
  }
  // Before any thread exists, so every thread inherits the blocked mask and
  // only sigtimedwait below receives these signals.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  SequenceConfig cal;
  Mesh mesh;
  auto capture = std::make_unique<LibcameraCapture>();
  if (!open_inputs(args, &cal, &mesh, capture.get())) return 1;
  LiveRun run;
  run.config = tc;
  run.calibration = cal;
  run.mesh = &mesh;
  run.calibration_path = args.calibration;
  run.out_dir = args.out;
  run.source_label = "camera '" + args.camera + "' (" + to_string(capture->pixel_format()) + " " +
                     std::to_string(cal.width) + "x" + std::to_string(cal.height) + ")";
  run.source = capture.get();
  const LibcameraCapture* camera = capture.get();
  run.counters = [camera] { return camera->counters(); };
  return run_live(run, signals);
}

int run_live(const LiveRun& run, const sigset_t& stop_signals) {
  const SequenceConfig& cal = run.calibration;
  TrackerConfig tc = run.config;
  tc.width = cal.width;
  tc.height = cal.height;
  if (!tc.now_ns) tc.now_ns = &platform::monotonic_ns;
  auto processor = std::make_unique<TrackerProcessor>();
  if (Status s = processor->configure(tc, *run.mesh, CameraModel(cal.K, cal.distortion), cal.T_camera_model_init);
      !s) {
    std::fprintf(stderr, "scopetrack: cannot configure the tracker: %s\n", s.message().c_str());
    return 1;
  }
  std::unique_ptr<RunWriter> writer;
  if (!run.out_dir.empty()) {
    writer = std::make_unique<RunWriter>();
    if (Status s = writer->open(run.out_dir); !s) {
      std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
      return 1;
    }
    writer->start({});
  }
  auto status = std::make_unique<LoopStatus>();
  auto loop = std::make_unique<FrameLoop>();
  loop->source = run.source;
  loop->processor = processor.get();
  loop->writer = writer.get();
  loop->status = status.get();
  if (Status s = run.source->start(); !s) {
    std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
    if (writer) (void)writer->finish();
    return 1;
  }
  std::fprintf(stderr, "scopetrack: tracking %s; Ctrl-C stops\n", run.source_label.c_str());
  std::thread tracking([&loop] { loop->run(); });
  const int sig = wait_for_stop(stop_signals, *status, run.print_status);
  run.source->stop();
  tracking.join();
  loop->stats.stop_signal = sig;
  return finish_run(run, *processor, writer.get(), loop.get());
}

}  // namespace st::app
