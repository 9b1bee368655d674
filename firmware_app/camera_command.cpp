// scopetrack --camera / --list-cameras: the tracker on a live libcamera
// stream (hal/capture/libcamera_capture.h). NOT RUN ON HARDWARE: the development
// machine has no camera; the no-camera paths are tested.
//
// Threads: the calling (owner) thread blocks SIGINT/SIGTERM before any
// thread exists (libcamera's and ours inherit the mask), opens everything,
// starts the tracking thread and waits in sigtimedwait, printing a status
// line each second. On a signal (or when tracking ends by itself) it stops
// the camera, joins the tracking thread and writes the summary. The
// tracking thread converts, tracks, and pushes rows to the RunWriter; it
// allocates nothing after the processor's start() (counted, reported).
#include "firmware_app/camera_command.h"

#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "core/base/latency_histogram.h"
#include "core/formats/sequence.h"
#include "firmware_app/tracker_processor.h"
#include "hal/storage/file_io.h"
#include "hal/capture/libcamera_capture.h"
#include "hal/storage/mesh_file.h"
#include "firmware_app/replay.h"
#include "hal/storage/run_writer.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"

namespace st::app {

namespace {

constexpr std::int64_t kMaxCalibrationBytes = 1 << 20;

struct CameraArgs {
  std::string camera, mesh, calibration, out;
  int ring_slots = 4;
  bool use_mask = true;
  bool use_occluder_mask = true;
  bool check_calibration = true;
};

bool parse_args(Args args, CameraArgs* a) {
  const int argc = static_cast<int>(args.size());
  if (argc > 0) a->camera = args[0];
  for (int i = 1; i < argc; ++i) {
    const char* arg = args[static_cast<std::size_t>(i)];
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(arg, "--mesh") && has_value) a->mesh = args[static_cast<std::size_t>(++i)];
    else if (!std::strcmp(arg, "--calibration") && has_value) a->calibration = args[static_cast<std::size_t>(++i)];
    else if (!std::strcmp(arg, "--out") && has_value) a->out = args[static_cast<std::size_t>(++i)];
    else if (!std::strcmp(arg, "--ring") && has_value) a->ring_slots = std::atoi(args[static_cast<std::size_t>(++i)]);
    else if (!std::strcmp(arg, "--no-mask")) a->use_mask = false;
    else if (!std::strcmp(arg, "--no-occluder-mask")) a->use_occluder_mask = false;
    else if (!std::strcmp(arg, "--no-calibration-check")) a->check_calibration = false;
    else {
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

// What the owner thread reads while the tracking thread runs.
struct LiveStatus {
  std::atomic<int> frames{0}, tracked{0}, lost{0};
  std::atomic<int> last_state{static_cast<int>(FrameState::kLost)};
  std::atomic<bool> calibration_suspect{false};  // TrackerConfig::check_calibration's verdict
  std::atomic<bool> done{false};
};

// The tracking thread's state, sized before it starts.
struct LiveLoop {
  LibcameraCapture* capture = nullptr;
  FrameProcessor* processor = nullptr;
  RunWriter* writer = nullptr;  // null without --out
  LiveStatus* status = nullptr;
  LatencyHistogram latency;
  ReplayStats stats;
  PixelStatus pixel_error = PixelStatus::kOk;
  std::uint64_t allocations = 0;
  std::int64_t t_first_sensor_ns = -1;

  void run() {
    processor->start();
    const std::uint64_t allocs0 = platform::thread_allocation_count();
    for (;;) {
      LiveFrame in;
      capture->next_frame(&in);
      if (in.kind == LiveFrame::Kind::kEnd) break;
      if (in.kind == LiveFrame::Kind::kError) {
        pixel_error = in.pixel_status;
        break;
      }
      const std::int64_t t_got_ns = platform::monotonic_ns();
      const TrackResult r = processor->step(in.frame);
      const std::int64_t t_done_ns = platform::monotonic_ns();
      // Latency from the sensor timestamp (CLOCK_MONOTONIC on V4L2) when it
      // is plausible, else from the hand-off.
      const std::int64_t age_ns = t_got_ns - in.t_sensor_ns;
      const std::int64_t t_from_ns = age_ns >= 0 && age_ns < 1'000'000'000 ? in.t_sensor_ns : t_got_ns;
      if (t_first_sensor_ns < 0) t_first_sensor_ns = in.t_sensor_ns;
      record(in, r, static_cast<double>(t_done_ns - t_from_ns) * 1e-6);
    }
    allocations = platform::thread_allocation_count() - allocs0;
    processor->stop();
    status->done.store(true);
  }

  void record(const LiveFrame& in, const TrackResult& r, double latency_ms) {
    const double timestamp_s = static_cast<double>(in.t_sensor_ns - t_first_sensor_ns) * 1e-9;
    const FrameRow row = record_frame(in.frame.index, timestamp_s, r, latency_ms, &stats);
    latency.add(latency_ms);
    status->frames.store(stats.frames, std::memory_order_relaxed);
    status->tracked.store(stats.tracked, std::memory_order_relaxed);
    status->lost.store(stats.lost, std::memory_order_relaxed);
    status->last_state.store(static_cast<int>(row.record.state), std::memory_order_relaxed);
    if (r.calibration_suspect) status->calibration_suspect.store(true, std::memory_order_relaxed);
    if (writer != nullptr && writer->push(row)) ++stats.writer_stalls;
  }
};

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

// Owner thread: until SIGINT/SIGTERM or the tracking thread ends by itself.
void wait_for_stop(const sigset_t& signals, const LiveStatus& status, bool print) {
  const timespec tick{1, 0};
  while (!status.done.load()) {
    const int sig = sigtimedwait(&signals, nullptr, &tick);
    if (sig == SIGINT || sig == SIGTERM) return;
    if (print)
      std::fprintf(stderr, "\r%d frames  %d with a pose  %d lost  state %s%s   ", status.frames.load(),
                   status.tracked.load(), status.lost.load(),
                   to_string(static_cast<FrameState>(status.last_state.load())),
                   status.calibration_suspect.load() ? "  CALIBRATION SUSPECT" : "");
  }
}

// Owner thread, after the tracking thread ended: stats, the summary line,
// summary.json with --out. The exit status.
int finish_run(const CameraArgs& args, const SequenceConfig& cal, std::int64_t t0_ns, const LibcameraCapture& capture,
               const TrackerProcessor& processor, RunWriter* writer, LiveLoop* loop) {
  ReplayStats& stats = loop->stats;
  fill_timing(loop->latency, static_cast<double>(platform::monotonic_ns() - t0_ns) * 1e-9, &stats);
  stats.tracking_thread_allocations = static_cast<std::int64_t>(loop->allocations);
  if (loop->pixel_error != PixelStatus::kOk) stats.error = std::string("camera buffer: ") + describe(loop->pixel_error);
  const CaptureCounters counters = capture.counters();
  std::fprintf(stderr, "\n%d frames: %d with a pose, %d lost  %.1f fps  latency mean %.2f ms p99 %.2f ms"
               "  skipped %llu  failed %llu  tracking-thread allocations %lld\n",
               stats.frames, stats.tracked, stats.lost, stats.fps, stats.mean_latency_ms, stats.p99_latency_ms,
               static_cast<unsigned long long>(counters.skipped), static_cast<unsigned long long>(counters.failed),
               static_cast<long long>(stats.tracking_thread_allocations));
  if (writer) {
    if (Status s = writer->finish(); !s && stats.error.empty()) stats.error = s.message();
    ReplayOptions opt;
    opt.out_dir = args.out;
    opt.realtime = true;
    opt.summary_extra = {{"width", cal.width}, {"height", cal.height},
                         {"camera_skipped_frames", static_cast<double>(counters.skipped)},
                         {"camera_failed_frames", static_cast<double>(counters.failed)}};
    processor.append_summary(&opt.summary_extra);
    if (Status s = write_file(std::filesystem::path(args.out) / "summary.json", format_replay_summary(stats, opt)); !s)
      std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
  }
  if (!stats.error.empty()) std::fprintf(stderr, "scopetrack: capture ended: %s\n", stats.error.c_str());
  if (const CalibrationCheck c = processor.calibration_check(); c.suspect)
    std::fprintf(stderr, "scopetrack: %s\n", describe_calibration(c, args.calibration).c_str());
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
    std::fprintf(stderr, "usage: scopetrack --camera ID --mesh FILE --calibration FILE [--out DIR] [--ring N] [--no-mask] [--no-occluder-mask] [--no-calibration-check]\n");
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
  TrackerConfig tc;
  tc.width = cal.width;
  tc.height = cal.height;
  tc.use_mask = args.use_mask;
  tc.use_occluder_mask = args.use_occluder_mask;
  tc.check_calibration = args.check_calibration;
  tc.now_ns = &platform::monotonic_ns;
  auto processor = std::make_unique<TrackerProcessor>();
  if (Status s = processor->configure(tc, mesh, CameraModel(cal.K, cal.distortion), cal.T_camera_model_init); !s) {
    std::fprintf(stderr, "scopetrack: cannot configure the tracker: %s\n", s.message().c_str());
    return 1;
  }
  std::unique_ptr<RunWriter> writer;
  if (!args.out.empty()) {
    writer = std::make_unique<RunWriter>();
    if (Status s = writer->open(args.out); !s) {
      std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
      return 1;
    }
    writer->start({});
  }
  auto status = std::make_unique<LiveStatus>();
  auto loop = std::make_unique<LiveLoop>();
  loop->capture = capture.get();
  loop->processor = processor.get();
  loop->writer = writer.get();
  loop->status = status.get();
  if (Status s = capture->start(); !s) {
    std::fprintf(stderr, "scopetrack: %s\n", s.message().c_str());
    return 1;
  }
  std::fprintf(stderr, "scopetrack: tracking camera '%s' (%s %dx%d); Ctrl-C stops\n", args.camera.c_str(),
               to_string(capture->pixel_format()), cal.width, cal.height);
  const std::int64_t t0_ns = platform::monotonic_ns();
  std::thread tracking([&loop] { loop->run(); });
  wait_for_stop(signals, *status, true);
  capture->stop();
  tracking.join();
  return finish_run(args, cal, t0_ns, *capture, *processor, writer.get(), loop.get());
}

}  // namespace st::app
