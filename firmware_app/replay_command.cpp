// scopetrack --sequence DIR --out DIR [--realtime] [--no-mask] [--no-occluder-mask]
//   [--no-image-motion] [--no-ba] [--no-shape-ba] [--ba-lag N]
//   [--fast-reference-luma L] [--fast-reference-contrast C] [--no-descriptor-refresh] [--w-shape W]
//   [--max-raster-triangles N] [--registration-sigma-deg D --registration-sigma-mm M]
//   [--registration-keyframes N] [--no-calibration-check] [--ring N]:
// replays a sequence through the tracker (firmware_app/replay.h) into the output
// folder. Exit status: 0 done (with a warning on stderr if the calibration
// was judged suspect: TrackerConfig::check_calibration), 1 the sequence or
// the replay failed (a clear message on stderr; the output written so far
// stays), 2 bad command line.

#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <unistd.h>

#include "core/base/capacity.h"
#include "core/formats/text_scan.h"
#include "firmware_app/cli.h"
#include "firmware_app/stream_link.h"
#include "firmware_app/tracker_processor.h"
#include "firmware_app/replay.h"
#include "hal/storage/sequence_loader.h"
#include "platform/clock.h"

namespace st::app {

namespace {

struct ReplayArgs {
  std::string sequence, out;
  bool realtime = false;
  bool use_mask = true;
  bool use_occluder_mask = true;  // --no-occluder-mask: instruments stay in the valid mask (ablation)
  bool use_image_motion = true;  // --no-image-motion: constant-velocity prediction only, no
                                 // dead reckoning by direct alignment while lost, no confirmed
                                 // poses (ablation)
  bool use_ba = true;       // --no-ba: no bundle adjustment (tracking and mesh-depth points only)
  bool shape_ba = true;     // --no-shape-ba: BA with w_shape = 0
  double w_shape = TrackerConfig{}.w_shape;  // --w-shape W: the shape residual's weight
  int max_raster_triangles = TrackerConfig{}.max_raster_triangles;  // --max-raster-triangles N (0: never simplify)
  int ba_lag = 0;           // --ba-lag N: deterministic BA hand-back (TrackerConfig::ba_lag_frames)
  double fast_reference_luma = TrackerConfig{}.fast_reference_luma;  // --fast-reference-luma L (0: off, the ablation)
  double fast_reference_contrast = TrackerConfig{}.fast_reference_contrast;  // --fast-reference-contrast C (0: off)
  bool refresh_descriptors = true;  // --no-descriptor-refresh: map points keep their first descriptor (ablation)
  bool check_calibration = true;    // --no-calibration-check: no focal-length test of the calibration
  // --registration-sigma-deg D --registration-sigma-mm M (both, or neither: the registration
  // taken as exact), --registration-keyframes N: refining frame 0's registration (TrackerConfig)
  double registration_sigma_deg = TrackerConfig{}.registration_sigma_deg;
  double registration_sigma_mm = TrackerConfig{}.registration_sigma_mm;
  int registration_keyframes = TrackerConfig{}.ba_registration_keyframes;
  int ring_slots = 6;
  std::string stream;           // --stream ENDPOINT: serve consoles (firmware_app/stream_link.h)
  int stream_wait = 0;          // --stream-wait N: start once N consoles are connected
  int texture_every = 0;        // --texture-every K: 0 keyframes, k every k-th frame with a pose
};

// args: DIR then options. False (with a message) on anything it does not understand.
bool parse_args(Args args, ReplayArgs* a) {
  const int argc = static_cast<int>(args.size());
  if (argc > 0) a->sequence = args[0];
  // The value after option i as a whole number in [lo, hi]; false (with
  // what it wants said) otherwise.
  const auto int_value = [&](int* i, long long lo, long long hi, const char* wants, long long* out) {
    if (st::parse_int64_in(args[static_cast<std::size_t>(++*i)], lo, hi, out)) return true;
    std::fprintf(stderr, "scopetrack: %s takes %s\n", args[static_cast<std::size_t>(*i - 1)], wants);
    return false;
  };
  // The same for a number in [lo, hi].
  const auto double_value = [&](int* i, double lo, double hi, const char* wants, double* out) {
    if (st::parse_double_in(args[static_cast<std::size_t>(++*i)], lo, hi, out)) return true;
    std::fprintf(stderr, "scopetrack: %s takes %s\n", args[static_cast<std::size_t>(*i - 1)],
                 wants);
    return false;
  };
  for (int i = 1; i < argc; ++i) {
    const char* arg = args[static_cast<std::size_t>(i)];
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(arg, "--out") && has_value) {
      a->out = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--realtime")) {
      a->realtime = true;
    } else if (!std::strcmp(arg, "--no-mask")) {
      a->use_mask = false;
    } else if (!std::strcmp(arg, "--no-occluder-mask")) {
      a->use_occluder_mask = false;
    } else if (!std::strcmp(arg, "--no-image-motion")) {
      a->use_image_motion = false;
    } else if (!std::strcmp(arg, "--no-ba")) {
      a->use_ba = false;
    } else if (!std::strcmp(arg, "--no-shape-ba")) {
      a->shape_ba = false;
    } else if (!std::strcmp(arg, "--w-shape") && has_value) {
      if (!double_value(&i, 0.0, 1e6, "a weight in 0..1e6 (0: no shape residual)", &a->w_shape))
        return false;
    } else if (!std::strcmp(arg, "--max-raster-triangles") && has_value) {
      const char* wants = "0 (never simplify) or a triangle count in 1000..4000000";
      long long n = 0;
      if (!int_value(&i, 0, st::kMaxMeshTriangles, wants, &n)) return false;
      if (n > 0 && n < 1000) {
        std::fprintf(stderr, "scopetrack: --max-raster-triangles takes %s\n", wants);
        return false;
      }
      a->max_raster_triangles = static_cast<int>(n);
    } else if (!std::strcmp(arg, "--ba-lag") && has_value) {
      long long lag = 0;
      if (!int_value(&i, 1, 1000, "a whole number of frames in 1..1000", &lag)) return false;
      a->ba_lag = static_cast<int>(lag);
    } else if (!std::strcmp(arg, "--fast-reference-luma") && has_value) {
      long long luma = 0;
      if (!int_value(&i, 0, 255, "a luma in 0..255 (0: off)", &luma)) return false;
      a->fast_reference_luma = static_cast<double>(luma);
    } else if (!std::strcmp(arg, "--fast-reference-contrast") && has_value) {
      if (!double_value(&i, 0.0, 255.0, "a contrast in 0..255 (0: off)",
                        &a->fast_reference_contrast))
        return false;
    } else if (!std::strcmp(arg, "--registration-sigma-deg") && has_value) {
      if (!double_value(&i, 0.001, 90.0, "an angle in 0.001..90 degrees",
                        &a->registration_sigma_deg))
        return false;
    } else if (!std::strcmp(arg, "--registration-sigma-mm") && has_value) {
      if (!double_value(&i, 0.001, 1000.0, "a distance in 0.001..1000 mm",
                        &a->registration_sigma_mm))
        return false;
    } else if (!std::strcmp(arg, "--registration-keyframes") && has_value) {
      long long n = 0;
      if (!int_value(&i, 0, 1000, "a keyframe count in 0..1000 (0: no periodic global BA)", &n))
        return false;
      a->registration_keyframes = static_cast<int>(n);
    } else if (!std::strcmp(arg, "--no-descriptor-refresh")) {
      a->refresh_descriptors = false;
    } else if (!std::strcmp(arg, "--no-calibration-check")) {
      a->check_calibration = false;
    } else if (!std::strcmp(arg, "--ring") && has_value) {
      a->ring_slots = std::atoi(args[static_cast<std::size_t>(++i)]);
    } else if (!std::strcmp(arg, "--stream") && has_value) {
      a->stream = args[static_cast<std::size_t>(++i)];
    } else if (!std::strcmp(arg, "--stream-wait") && has_value) {
      a->stream_wait = std::atoi(args[static_cast<std::size_t>(++i)]);
    } else if (!std::strcmp(arg, "--texture-every") && has_value) {
      a->texture_every = std::atoi(args[static_cast<std::size_t>(++i)]);
    } else {
      std::fprintf(stderr, "scopetrack: unknown or incomplete argument '%s'\n", arg);
      return false;
    }
  }
  if ((a->registration_sigma_deg > 0) != (a->registration_sigma_mm > 0)) {
    std::fprintf(stderr,
                 "scopetrack: --registration-sigma-deg and --registration-sigma-mm go together\n");
    return false;
  }
  if (a->sequence.empty() || a->out.empty()) {
    std::fprintf(stderr, "scopetrack: --sequence DIR and --out DIR are both required\n");
    return false;
  }
  return true;
}

TrackerConfig tracker_config(const LoadedSequence& seq, const ReplayArgs& a) {
  TrackerConfig c;
  c.width = seq.config.width;
  c.height = seq.config.height;
  c.use_mask = a.use_mask;
  c.use_occluder_mask = a.use_occluder_mask;
  c.use_ba = a.use_ba;
  c.use_image_motion = a.use_image_motion;
  c.w_shape = a.shape_ba ? a.w_shape : 0.0;
  c.max_raster_triangles = a.max_raster_triangles;
  c.ba_lag_frames = a.ba_lag;
  c.fast_reference_luma = a.fast_reference_luma;
  c.fast_reference_contrast = a.fast_reference_contrast;
  c.refresh_descriptors = a.refresh_descriptors;
  c.check_calibration = a.check_calibration;
  c.registration_sigma_deg = a.registration_sigma_deg;
  c.registration_sigma_mm = a.registration_sigma_mm;
  c.ba_registration_keyframes = a.registration_keyframes;
  c.now_ns = &platform::monotonic_ns;
  return c;
}

void print_result(const ReplayStats& s, const std::string& out_dir) {
  std::printf("%d frames: %d with a pose, %d lost (%d relocalised)  %.1f fps  latency mean %.2f ms p99 %.2f ms"
              "  peak RSS %.0f MB  tracking-thread allocations %lld\n-> %s\n",
              s.frames, s.tracked, s.lost, s.relocalised, s.fps, s.mean_latency_ms, s.p99_latency_ms,
              s.peak_rss_mb, static_cast<long long>(s.tracking_thread_allocations), out_dir.c_str());
}

// The console link (--stream): listening before the first frame; nullptr
// (with a message) when it cannot be had.
std::unique_ptr<StreamLink> start_stream_link(const ReplayArgs& a, const LoadedSequence& seq) {
  StreamLinkConfig lc;
  std::string error;
  if (!platform::parse_endpoint(a.stream, &lc.endpoint, &error)) {
    std::fprintf(stderr, "scopetrack: --stream: %s\n", error.c_str());
    return nullptr;
  }
  lc.wait_consoles = a.stream_wait;
  lc.texture_every = a.texture_every;
  auto link = std::make_unique<StreamLink>();
  Status s = link->configure(lc, seq);
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

}  // namespace

int run_replay(Args argv) {
  ReplayArgs args;
  if (!parse_args(argv, &args)) {
    std::fprintf(
        stderr,
        "usage: scopetrack --sequence DIR --out DIR [--realtime] [--no-mask] [--no-occluder-mask]"
        " [--no-image-motion] [--no-ba]"
        " [--no-shape-ba] [--ba-lag N] [--fast-reference-luma L] [--fast-reference-contrast C]"
        " [--no-descriptor-refresh] [--w-shape W] [--max-raster-triangles N]"
        " [--registration-sigma-deg D --registration-sigma-mm M]"
        " [--registration-keyframes N] [--no-calibration-check]"
        " [--ring N]\n"
        "         [--stream tcp://HOST:PORT|unix:PATH [--stream-wait N] [--texture-every K]]\n");
    return 2;
  }
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
  const SequenceConfig& c = seq->config;
  auto processor = std::make_unique<TrackerProcessor>();
  Status s = processor->configure(tracker_config(seq.value(), args), seq->mesh, CameraModel(c.K, c.distortion),
                                  c.T_camera_model_init);
  if (!s) {
    std::fprintf(stderr, "scopetrack: cannot configure the tracker for %s: %s\n", args.sequence.c_str(),
                 s.message().c_str());
    return 1;
  }
  std::unique_ptr<StreamLink> link;
  if (!args.stream.empty()) {
    link = start_stream_link(args, seq.value());
    if (!link) return 1;
  }
  ReplayOptions opt;
  opt.observer = link.get();
  opt.out_dir = args.out;
  opt.realtime = args.realtime;
  opt.progress = ::isatty(STDERR_FILENO) == 1;
  opt.ring_slots = args.ring_slots;
  opt.summary_extra = {{"use_mask", args.use_mask ? 1.0 : 0.0},
                       {"use_occluder_mask", args.use_occluder_mask ? 1.0 : 0.0}, {"use_ba", args.use_ba ? 1.0 : 0.0},
                       {"use_image_motion", args.use_image_motion ? 1.0 : 0.0},
                       {"w_shape", args.shape_ba ? args.w_shape : 0.0},
                       {"ba_lag_frames", args.ba_lag}, {"fast_reference_luma", args.fast_reference_luma},
                       {"fast_reference_contrast", args.fast_reference_contrast},
                       {"refresh_descriptors", args.refresh_descriptors ? 1.0 : 0.0},
                       {"check_calibration", args.check_calibration ? 1.0 : 0.0},
                       {"width", c.width}, {"height", c.height}};
  auto stats = run_replay(seq.value(), *processor, opt);
  if (!stats) {
    std::fprintf(stderr, "scopetrack: %s\n", stats.message().c_str());
    return 1;
  }
  print_result(stats.value(), args.out);
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
