// scopetrack --sequence DIR --out DIR [--config FILE] [--set KEY=VALUE]...
//   [--ba-lag N] [--realtime] [--ring N]
//   [--stream ENDPOINT [--stream-wait N] [--texture-every K]]:
// replays a sequence through the tracker (firmware_app/replay.h) into the output
// folder. Exit status: 0 done (with a warning on stderr if the calibration
// was judged suspect: TrackerConfig::check_calibration), 1 the sequence or
// the replay failed (a clear message on stderr; the output written so far
// stays), 2 bad command line or settings, 128 + the signal's number (130,
// 143) when SIGINT or SIGTERM ended it early: the frames tracked until then
// are written, summary.json included (its "stop_signal"). A second signal
// while the first is being handled (a video pipe that stalls) exits at once
// with the same status; the rows written so far stay.

#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <thread>

#include "core/base/capacity.h"
#include "core/formats/text_scan.h"
#include "firmware_app/cli.h"
#include "firmware_app/settings_args.h"
#include "firmware_app/stream_link.h"
#include "firmware_app/tracker_processor.h"
#include "firmware_app/replay.h"
#include "hal/storage/sequence_loader.h"
#include "platform/clock.h"

namespace st::app {

namespace {

struct ReplayArgs {
  std::string sequence, out;
  SettingsArgs settings;    // --config FILE, --set KEY=VALUE, --ba-lag N (last: the key ba_lag_frames)
  bool realtime = false;    // --realtime: paced at the sequence's fps
  int ring_slots = 4;       // --ring N: capture ring slots
  std::string stream;       // --stream ENDPOINT: serve consoles (firmware_app/stream_link.h)
  int stream_wait = 0;      // --stream-wait N: start once N consoles are connected
  int texture_every = 0;    // --texture-every K: 0 keyframes, k every k-th frame with a pose
};

// args: DIR then options. False (with a message) on anything it does not understand.
bool parse_args(Args args, ReplayArgs* a) {
  const int argc = static_cast<int>(args.size());
  if (argc > 0) a->sequence = args[0];
  // The value after option i as a whole number in [lo, hi]; false (with
  // what it wants said) otherwise.
  const auto int_value = [&](int* i, long long lo, long long hi, const char* wants, int* out) {
    long long v = 0;
    if (st::parse_int64_in(args[static_cast<std::size_t>(++*i)], lo, hi, &v)) {
      *out = static_cast<int>(v);
      return true;
    }
    std::fprintf(stderr, "scopetrack: %s takes %s\n", args[static_cast<std::size_t>(*i - 1)], wants);
    return false;
  };
  int ba_lag = 0;  // --ba-lag N: 0 keeps the settings' ba_lag_frames
  for (int i = 1; i < argc; ++i) {
    const char* arg = args[static_cast<std::size_t>(i)];
    const bool has_value = i + 1 < argc;
    bool bad = false;
    if (take_settings_arg(args, &i, &a->settings, &bad)) {
      if (bad) return false;
    } else if (!std::strcmp(arg, "--out") && has_value) {
      a->out = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--realtime")) {
      a->realtime = true;
    } else if (!std::strcmp(arg, "--ba-lag") && has_value) {
      if (!int_value(&i, 1, 1000, "a whole number of frames in 1..1000", &ba_lag)) return false;
    } else if (!std::strcmp(arg, "--ring") && has_value) {
      if (!int_value(&i, 2, kMaxRingSlots, "a slot count in 2..64", &a->ring_slots)) return false;
    } else if (!std::strcmp(arg, "--stream") && has_value) {
      a->stream = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--stream-wait") && has_value) {
      if (!int_value(&i, 0, 64, "a console count in 0..64", &a->stream_wait)) return false;
    } else if (!std::strcmp(arg, "--texture-every") && has_value) {
      if (!int_value(&i, 0, 1000000, "a frame count in 0..1000000 (0: keyframes)", &a->texture_every))
        return false;
    } else {
      std::fprintf(stderr, "scopetrack: unknown or incomplete argument '%s'\n", arg);
      return false;
    }
  }
  if (a->sequence.empty() || a->sequence.front() == '-' || a->out.empty()) {
    std::fprintf(stderr, "scopetrack: --sequence DIR and --out DIR are both required\n");
    return false;
  }
  if (ba_lag > 0) a->settings.sets.emplace_back("ba_lag_frames", std::to_string(ba_lag));
  return true;
}

// The tracker's settings for this replay: defaults, --config, --set, then
// --ba-lag. The error names the key and its range.
Result<TrackerConfig> tracker_config(const LoadedSequence& seq, const ReplayArgs& a) {
  TrackerConfig c;
  if (Status s = apply_settings(a.settings, &c); !s) return Error{s.message()};
  c.width = seq.config.width;
  c.height = seq.config.height;
  c.now_ns = &platform::monotonic_ns;
  return c;
}

void print_result(const RunStats& s, const Pinhole& frames, const Pinhole& working, const std::string& out_dir) {
  std::printf("%d frames of %dx%d, tracked at %dx%d: %d with a pose, %d lost (%d relocalised)  %.1f fps  latency mean"
              " %.2f ms p99 %.2f ms  peak RSS %.0f MB  tracking-thread allocations %lld\n-> %s\n",
              s.frames, frames.width, frames.height, working.width, working.height, s.tracked, s.lost, s.relocalised,
              s.fps, s.mean_latency_ms, s.p99_latency_ms, s.peak_rss_mb,
              static_cast<long long>(s.tracking_thread_allocations), out_dir.c_str());
}

// The console link (--stream): listening before the first frame; nullptr
// (with a message) when it cannot be had.
// frames: the camera of the frames the tracking thread gets.
std::unique_ptr<StreamLink> start_stream_link(const ReplayArgs& a, const LoadedSequence& seq, const CameraModel& frames) {
  StreamLinkConfig lc;
  std::string error;
  if (!platform::parse_endpoint(a.stream, &lc.endpoint, &error)) {
    std::fprintf(stderr, "scopetrack: --stream: %s\n", error.c_str());
    return nullptr;
  }
  lc.wait_consoles = a.stream_wait;
  lc.texture_every = a.texture_every;
  auto link = std::make_unique<StreamLink>();
  Status s = link->configure(lc, seq, frames);
  if (s) {
    std::fprintf(stderr, "scopetrack: streaming to consoles on %s\n", link->endpoint().to_string().c_str());
    s = link->start();
  }
  if (!s) {
    std::fprintf(stderr, "scopetrack: console link: %s\n", s.message().c_str());
    return nullptr;
  }
  return link;
}

// SIGINT and SIGTERM, blocked in every thread (the mask is inherited) and
// taken by one watcher: the first asks the frame loop to stop after the
// current frame, a second exits at once.
class SignalWatcher {
 public:
  // Before any other thread exists.
  SignalWatcher() {
    sigemptyset(&signals_);
    sigaddset(&signals_, SIGINT);
    sigaddset(&signals_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &signals_, nullptr);
    thread_ = std::thread([this] { run(); });
  }
  ~SignalWatcher() {
    done_.store(true);
    thread_.join();
  }
  SignalWatcher(const SignalWatcher&) = delete;
  SignalWatcher& operator=(const SignalWatcher&) = delete;
  const std::atomic<int>* stop_signal() const { return &signal_; }

 private:
  void run() {
    const timespec tick{0, 100'000'000};
    while (!done_.load()) {
      const int sig = sigtimedwait(&signals_, nullptr, &tick);
      if (sig != SIGINT && sig != SIGTERM) continue;
      if (signal_.load() != 0) _exit(128 + signal_.load());
      signal_.store(sig);
    }
  }
  sigset_t signals_;
  std::atomic<int> signal_{0};
  std::atomic<bool> done_{false};
  std::thread thread_;
};

}  // namespace

int run_replay(Args argv) {
  ReplayArgs args;
  if (!parse_args(argv, &args)) {
    std::fprintf(stderr,
                 "usage: scopetrack --sequence DIR --out DIR [--config FILE] [--set KEY=VALUE]..."
                 " [--ba-lag N] [--realtime] [--ring N]\n"
                 "         [--stream tcp://HOST:PORT|unix:PATH [--stream-wait N] [--texture-every K]]\n");
    return 2;
  }
  SignalWatcher signals;
  auto seq = load_sequence(args.sequence);
  if (!seq) {
    std::fprintf(stderr, "scopetrack: cannot use sequence %s: %s\n", args.sequence.c_str(), seq.message().c_str());
    return 1;
  }
  if (Status s = check_sequence_for_replay(seq.value()); !s) {
    std::fprintf(stderr, "scopetrack: sequence %s is not usable (see scopetrack --check): %s\n",
                 args.sequence.c_str(), s.message().c_str());
    return 1;
  }
  const auto config = tracker_config(seq.value(), args);
  if (!config) {
    std::fprintf(stderr, "scopetrack: %s\n", config.message().c_str());
    return 2;
  }
  const TrackerConfig& tc = config.value();
  const SequenceConfig& c = seq->config;
  auto processor = std::make_unique<TrackerProcessor>();
  Status s = processor->configure(tc, seq->mesh, CameraModel(c.K, c.distortion), c.T_camera_model_init);
  if (!s) {
    std::fprintf(stderr, "scopetrack: cannot configure the tracker for %s: %s\n", args.sequence.c_str(),
                 s.message().c_str());
    return 1;
  }
  std::unique_ptr<StreamLink> link;
  if (!args.stream.empty()) {
    // The capture hands on frames at the working size (run_replay).
    link = start_stream_link(args, seq.value(), processor->working_camera());
    if (!link) return 1;
  }
  ReplayOptions opt;
  opt.observer = link.get();
  opt.out_dir = args.out;
  opt.realtime = args.realtime;
  opt.progress = ::isatty(STDERR_FILENO) == 1;
  opt.ring_slots = args.ring_slots;
  opt.stop_signal = signals.stop_signal();
  opt.summary_extra = {{"use_mask", tc.use_mask ? 1.0 : 0.0},
                       {"use_occluder_mask", tc.use_occluder_mask ? 1.0 : 0.0}, {"use_ba", tc.use_ba ? 1.0 : 0.0},
                       {"use_image_motion", tc.use_image_motion ? 1.0 : 0.0},
                       {"use_contour", tc.use_contour ? 1.0 : 0.0},
                       {"w_shape", tc.ba.w_shape},
                       {"ba_lag_frames", tc.ba_lag_frames}, {"fast_reference_luma", tc.fast_reference_luma},
                       {"fast_reference_contrast", tc.fast_reference_contrast},
                       {"refresh_descriptors", tc.refresh_descriptors ? 1.0 : 0.0},
                       {"check_calibration", tc.check_calibration ? 1.0 : 0.0},
                       {"max_map_points", tc.max_map_points}, {"max_keyframes", tc.max_keyframes},
                       {"width", c.width}, {"height", c.height}};
  opt.working_width = processor->working_pinhole().width;
  opt.working_height = processor->working_pinhole().height;
  auto stats = run_replay(seq.value(), *processor, opt);
  if (!stats) {
    std::fprintf(stderr, "scopetrack: %s\n", stats.message().c_str());
    return 1;
  }
  print_result(stats.value(), c.K, processor->working_pinhole(), args.out);
  if (const int sig = stats->stop_signal; sig != 0) {
    std::fprintf(stderr, "scopetrack: stopped by %s after %d frames (their output is in %s)\n",
                 sig == SIGINT ? "SIGINT" : "SIGTERM", stats->frames, args.out.c_str());
    return 128 + sig;
  }
  if (!stats->error.empty()) {
    std::fprintf(stderr, "scopetrack: replay stopped after %d frames: %s (output so far is in %s)\n",
                 stats->frames, stats->error.c_str(), args.out.c_str());
    return 1;
  }
  const CalibrationCheck cal = processor->calibration_check();
  if (cal.suspect)
    std::fprintf(stderr, "scopetrack: %s\n", describe_calibration(cal, args.sequence + "/sequence.yaml").c_str());
  return 0;
}

}  // namespace st::app
