// Stage "track": Tracker::step over a whole sequence, per-stage times from
// TrackResult::times_ms (the tracker's injected monotonic clock) and the
// step's wall time measured outside, median and p99 over frames. Frames are
// read between steps (not timed). The sequence is simulated on first use
// (scopetrack-sim beside this binary, orbit 1280x720, 300 frames, cached in
// the temp folder) unless --sequence DIR is given.
//   scopetrack-bench track [--sequence DIR] [--scenario S] [--frames N] [--size WxH]
//                          [--config FILE] [--set KEY=VALUE]... [--prior-subdivide N] [--log N] [--ba-lag N]
// --config and --set are scopetrack's tracker settings (scopetrack --print-config).
// Without --ba-lag no bundle adjustment runs (the tracking thread's own
// work); with it, the mapping thread solves the tracker's jobs and each
// correction lands N frames after its job, as `scopetrack --ba-lag N`
// replays do: the same poses, with --log's per-frame diagnostics.
#include <algorithm>
#include <cstdio>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "bench.h"
#include "core/formats/text_scan.h"
#include "core/tracking/tracker.h"
#include "core/tracking/tracker_settings.h"
#include "firmware_app/mapping_worker.h"
#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"
#include "hal/capture/y4m_reader.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"

namespace st::bench {
namespace {

struct TrackArgs {
  std::string sequence, scenario = "orbit", size = "1280x720";
  int frames = 300;
  int log_frames = 0;  // per-frame diagnostics on stderr for the first N frames
  int ba_lag = 0;      // > 0: the mapping thread's BA, corrections landing this many frames after their job
  TrackerConfig config;  // --config FILE, --set KEY=VALUE: the tracker's settings
  int prior_subdivide = 0;  // the simulated sequence's organ.ply split this many times (scopetrack-sim --prior-subdivide)
};

// A name the simulator's command line can carry unquoted: letters, digits,
// 'x' sizes.
bool plain_word(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)); });
}

bool parse_track_args(const Options& opt, TrackArgs* a) {
  const auto whole = [&](std::size_t* i, long long lo, long long hi, int* out) {
    long long n = 0;
    if (!parse_int64_in(opt.args[++*i], lo, hi, &n)) {
      std::fprintf(stderr, "bench track: %s takes a whole number in %lld..%lld\n", opt.args[*i - 1].c_str(), lo, hi);
      return false;
    }
    *out = static_cast<int>(n);
    return true;
  };
  for (std::size_t i = 0; i < opt.args.size(); ++i) {
    const std::string& k = opt.args[i];
    const bool v = i + 1 < opt.args.size();
    Status setting = Status::Ok();
    if (k == "--sequence" && v) a->sequence = opt.args[++i];
    else if (k == "--scenario" && v) a->scenario = opt.args[++i];
    else if (k == "--size" && v) a->size = opt.args[++i];
    else if (k == "--frames" && v) { if (!whole(&i, 1, 100000, &a->frames)) return false; }
    else if (k == "--log" && v) { if (!whole(&i, 0, 100000, &a->log_frames)) return false; }
    else if (k == "--prior-subdivide" && v) { if (!whole(&i, 0, 3, &a->prior_subdivide)) return false; }
    else if (k == "--ba-lag" && v) { if (!whole(&i, 1, 1000, &a->ba_lag)) return false; }
    else if (k == "--config" && v) {
      auto text = read_file(opt.args[++i], 1 << 20);
      setting = text ? read_tracker_settings(text.value(), &a->config) : Status(text.error());
    } else if (k == "--set" && v) {
      std::string_view key, value;
      setting = split_setting_assignment(opt.args[++i], &key, &value)
                    ? apply_tracker_setting(key, value, &a->config)
                    : Status(make_error("--set takes KEY=VALUE"));
    } else return false;
    if (!setting) {
      std::fprintf(stderr, "bench track: %s: %s\n", k.c_str(), setting.message().c_str());
      return false;
    }
  }
  return plain_word(a->scenario) && plain_word(a->size);
}

// A simulated sequence in the temp folder (made once, then reused).
Result<std::filesystem::path> simulated_sequence(const Options& opt, const TrackArgs& a) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("scopetrack-bench-track-" + a.scenario + "-" + a.size + "-" + std::to_string(a.frames) +
                    (a.prior_subdivide > 0 ? "-sub" + std::to_string(a.prior_subdivide) : ""));
  std::error_code ec;
  if (std::filesystem::exists(dir / "sequence.yaml", ec)) return dir;
  const auto sim = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path() / "scopetrack-sim";
  if (!std::filesystem::exists(sim, ec)) return make_error("scopetrack-sim not found beside the bench: " + sim.string());
  const std::string cmd = "'" + sim.string() + "' --scenario " + a.scenario + " --size " + a.size + " --frames " +
                          std::to_string(a.frames) + " --seed 1 --prior-subdivide " + std::to_string(a.prior_subdivide) +
                          " --out '" + dir.string() + "' >/dev/null";
  info(opt, "simulating: " + cmd);
  if (std::system(cmd.c_str()) != 0) {
    std::filesystem::remove_all(dir, ec);
    return make_error("the simulator failed: " + cmd);
  }
  return dir;
}

// One frame's diagnostics; with ground truth, the pose's error against it.
void log_frame(const Options& opt, const LoadedSequence& seq, int index, const TrackResult& r) {
  char line[512];
  int n = std::snprintf(line, sizeof line,
                        "frame %d %s: features %d matches %d inliers %d ratio %.2f rms %.2f px mask %.2f jump %.2f deg"
                        " %.2f mm local map %d, map %d points %d keyframes",
                        index, to_string(r.state), r.features, r.matches, r.inliers, r.inlier_ratio, r.rms_px,
                        r.mask_agreement, r.pose_jump_deg, r.pose_jump_mm, r.local_map, r.map_points, r.keyframes);
  if (r.outline_tried && n > 0 && n < static_cast<int>(sizeof line))
    n += std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n),
                       "; outline %s: %d lines sigma %.2f px (joint %.2f), %.2f px from the shading%s",
                       to_string(r.agreement), r.contour_lines, r.contour_sigma_px, r.joint_sigma_px,
                       r.modality_agreement_px, r.by_outline ? ", reported" : "");
  if (index >= 0 && static_cast<std::size_t>(index) < seq.groundtruth.size()) {
    const SE3 truth = seq.groundtruth[static_cast<std::size_t>(index)].T_model_camera.inverse();
    const auto error = [&](const char* what, const SE3& T) {
      if (n <= 0 || n >= static_cast<int>(sizeof line)) return;
      const PoseDelta d = pose_delta(truth, T);
      const double mm = (truth.inverse().translation() - T.inverse().translation()).norm();
      n += std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n), "; %s %.2f deg %.2f mm", what,
                         d.angle_deg, mm);
    };
    if (r.state != TrackState::kLost) error("error", r.T_camera_model);
    if (r.outline_tried) {
      error("outline's error", r.T_outline);
      error("shading's", r.T_shading);
    }
    if (r.outline_searched) error(r.outline_search_found ? "searched, fit's error" : "searched, best candidate's error", r.T_search);
  }
  info(opt, line);
}

struct TrackRun {
  std::vector<StageTimes> stages;
  std::vector<double> step_ms;
  int lost = 0, frames = 0;
  std::uint64_t allocations = 0;
  int raster_triangles = 0;  // what the tracker rendered every frame
};

Result<TrackRun> run_tracker(const Options& opt, const LoadedSequence& seq, const TrackArgs& a) {
  TrackerConfig cfg = a.config;
  cfg.width = seq.config.width;
  cfg.height = seq.config.height;
  cfg.now_ns = &platform::monotonic_ns;
  auto tracker = std::make_unique<Tracker>();
  const CameraModel cam(seq.config.K, seq.config.distortion);
  if (Status s = tracker->configure(cfg, seq.mesh, cam, seq.config.T_camera_model_init); !s) return Error{s.message()};
  const Pinhole working = tracker->working_camera().pinhole();
  info(opt, "mesh " + std::to_string(seq.mesh.triangle_count()) + " triangles, rendered every frame as " +
                std::to_string(tracker->raster_triangles()) + "; frames " + std::to_string(cfg.width) + "x" +
                std::to_string(cfg.height) + " tracked at " + std::to_string(working.width) + "x" +
                std::to_string(working.height));
  app::MappingWorker mapping;  // --ba-lag: the replay's mapping thread
  if (a.ba_lag > 0 && cfg.use_ba) {
    TrackerConfig ba_cfg = cfg;
    ba_cfg.ba_lag_frames = a.ba_lag;
    if (Status s = mapping.configure(ba_cfg, seq.mesh, working); !s) return Error{s.message()};
    tracker->set_ba_channel(&mapping);
    mapping.start();
  }
  TrackRun run;
  run.raster_triangles = tracker->raster_triangles();
  Y4mReader reader;
  if (Status s = reader.open(seq.video_path, 2); !s) return Error{s.message()};
  run.stages.reserve(100000);
  run.step_ms.reserve(100000);
  tracker->start();
  FrameRef f;
  std::uint64_t allocs = 0;
  while (reader.read_frame(&f) == ReadResult::kFrame && run.step_ms.size() < run.step_ms.capacity()) {
    const std::uint64_t a0 = platform::thread_allocation_count();
    const double t0 = now_ms();
    const TrackResult r = tracker->step(f.y, f.index, ChromaView{f.u, f.v});
    run.step_ms.push_back(now_ms() - t0);
    allocs += platform::thread_allocation_count() - a0;
    run.stages.push_back(r.times_ms);
    run.lost += r.state == TrackState::kLost ? 1 : 0;
    if (f.index < a.log_frames) log_frame(opt, seq, f.index, r);
  }
  tracker->stop();
  mapping.stop();
  if (!reader.error().empty()) return make_error(reader.error());
  run.frames = static_cast<int>(run.step_ms.size());
  run.allocations = allocs;
  return run;
}

// One stage's time in every frame of the run (0 where it did not run).
std::vector<double> stage_samples(const TrackRun& run, Stage stage) {
  std::vector<double> v;
  v.reserve(run.stages.size());
  for (const StageTimes& t : run.stages) v.push_back(t[static_cast<std::size_t>(stage)]);
  return v;
}

void report_stages(const Options& opt, const TrackRun& run) {
  for (int s = 0; s < static_cast<int>(Stage::kCount); ++s) {
    Row row;
    row.name = std::string("track ") + to_string(static_cast<Stage>(s));
    row.samples_ms = stage_samples(run, static_cast<Stage>(s));
    const auto ran = static_cast<int>(std::count_if(row.samples_ms.begin(), row.samples_ms.end(), [](double ms) { return ms > 0; }));
    if (ran == 0) continue;
    if (ran < run.frames) row.note = "ran on " + std::to_string(ran) + " of " + std::to_string(run.frames) + " frames (0 elsewhere)";
    report(opt, row);
  }
  Row wall;
  wall.name = "track step (wall, outside)";
  wall.samples_ms = run.step_ms;
  wall.note = std::to_string(run.frames) + " frames, " + std::to_string(run.lost) + " lost, " +
              std::to_string(run.allocations) + " heap allocations in step()";
  report(opt, wall);
}

int bench_track(const Options& opt) {
  TrackArgs a;
  if (!parse_track_args(opt, &a)) {
    std::fprintf(stderr, "usage: scopetrack-bench track [--sequence DIR] [--scenario S] [--frames N] [--size WxH]"
                         " [--config FILE] [--set KEY=VALUE]... [--prior-subdivide N] [--log N] [--ba-lag N]\n");
    return 2;
  }
  std::filesystem::path dir = a.sequence;
  if (dir.empty()) {
    auto sim = simulated_sequence(opt, a);
    if (!sim) return std::fprintf(stderr, "bench track: %s\n", sim.message().c_str()), 1;
    dir = sim.value();
  }
  auto seq = load_sequence(dir);
  if (!seq) return std::fprintf(stderr, "bench track: %s\n", seq.message().c_str()), 1;
  info(opt, "sequence " + dir.string() + (a.config.use_mask ? "" : " (no mask)"));
  auto run = run_tracker(opt, seq.value(), a);
  if (!run) return std::fprintf(stderr, "bench track: %s\n", run.message().c_str()), 1;
  report_stages(opt, run.value());
  if (run->raster_triangles < seq->mesh.triangle_count()) {
    // A simplified prior (TrackerConfig::max_raster_triangles): the same
    // run rendering every triangle is the baseline, in this process.
    TrackArgs every = a;
    every.config.max_raster_triangles = 0;
    every.log_frames = 0;
    auto base = run_tracker(opt, seq.value(), every);
    if (!base) return std::fprintf(stderr, "bench track: %s\n", base.message().c_str()), 1;
    const std::string tris = std::to_string(run->raster_triangles) + " of " + std::to_string(seq->mesh.triangle_count());
    report(opt, Row{"track raster, simplified prior (" + tris + " triangles)", stage_samples(run.value(), Stage::kRaster),
                    "every triangle", stage_samples(base.value(), Stage::kRaster), ""});
    report(opt, Row{"track step, simplified prior (" + tris + " triangles)", run->step_ms, "every triangle",
                    base->step_ms, std::to_string(base->lost) + " lost rendering every triangle"});
  }
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("track", "Tracker::step per stage over a (simulated) sequence", bench_track);

}  // namespace st::bench
