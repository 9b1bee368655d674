#include "tools/soak/soak_run.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/evaluation/evaluation.h"
#include "core/formats/sequence.h"
#include "core/formats/trajectory.h"
#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"
#include "platform/clock.h"
#include "platform/socket.h"
#include "tools/console/console_session.h"
#include "tools/eval/eval_report.h"
#include "tools/sim/sim_run.h"

extern char** environ;

namespace st::soak {

namespace {

constexpr std::int64_t kMaxText = 1ll << 30;

template <class T>
T value_or(const Result<T>& r, T fallback) {
  return r ? r.value() : fallback;
}

struct Segment {
  std::string name;
  sim::ScenarioKind kind = sim::ScenarioKind::Orbit;
  double smoke = 0;
  std::filesystem::path dir;
  std::int64_t header_bytes = 0, record_bytes = 0;
  std::vector<TimedPose> groundtruth;
};

// Every scenario the tracker meets in an operation, one segment each. The
// same seed gives every segment the same organ and texture; invivo is left
// out (its prior is a perturbed copy and its lens distorts, so it is
// another sequence, not another moment of this one).
std::vector<Segment> segment_plan() {
  using K = sim::ScenarioKind;
  const std::pair<const char*, K> plan[] = {{"orbit", K::Orbit}, {"fast", K::Fast}, {"outofview", K::OutOfView},
                                            {"manipulation", K::Manipulation}, {"smoke", K::Orbit}};
  std::vector<Segment> out;
  for (const auto& [name, kind] : plan) {
    Segment s;
    s.name = name;
    s.kind = kind;
    s.smoke = s.name == "smoke" ? 0.6 : 0.0;
    out.push_back(s);
  }
  return out;
}

Status make_segments(const SoakOptions& o, std::vector<Segment>* segments) {
  for (Segment& s : *segments) {
    s.dir = o.out_dir / "segments" / s.name;
    const std::string stamp = std::to_string(o.segment_frames) + " " + std::to_string(o.width) + "x" +
                              std::to_string(o.height) + " seed " + std::to_string(o.seed) + "\n";
    auto old = read_file(s.dir / "soak-stamp.txt", 4096);
    if (!old || old.value() != stamp) {
      if (o.progress) std::fprintf(stderr, "scopetrack-soak: simulating the %s segment (%d frames)\n", s.name.c_str(), o.segment_frames);
      std::error_code ec;
      std::filesystem::remove_all(s.dir, ec);
      sim::SimOptions so;
      so.scenario = s.kind;
      so.out_dir = s.dir;
      so.frames = o.segment_frames;
      so.width = o.width;
      so.height = o.height;
      so.seed = o.seed;
      so.smoke = s.smoke;
      auto r = sim::run_simulation(so);
      if (!r) return make_error("simulating the " + s.name + " segment: " + r.message());
      if (Status w = write_file(s.dir / "soak-stamp.txt", stamp); !w) return w;
    }
    auto seq = load_sequence(s.dir);
    if (!seq) return make_error("segment " + s.name + ": " + seq.message());
    if (static_cast<int>(seq->groundtruth.size()) != o.segment_frames)
      return make_error("segment " + s.name + ": ground truth has " + std::to_string(seq->groundtruth.size()) + " poses");
    s.header_bytes = static_cast<std::int64_t>(seq->video_header.header_bytes);
    s.record_bytes = static_cast<std::int64_t>(seq->video_header.frame_bytes()) + 6;
    s.groundtruth = seq->groundtruth;
  }
  // One organ, one camera: the joined sequence is one operation.
  auto first_mesh = read_file((*segments)[0].dir / "organ.ply", kMaxText);
  auto first_yaml = read_file((*segments)[0].dir / "sequence.yaml", kMaxText);
  if (!first_mesh || !first_yaml) return make_error("segment orbit: cannot read organ.ply or sequence.yaml");
  auto first_cfg = parse_sequence_yaml(first_yaml.value());
  if (!first_cfg) return make_error(first_cfg.message());
  for (const Segment& s : *segments) {
    auto mesh = read_file(s.dir / "organ.ply", kMaxText);
    auto cfg = parse_sequence_yaml(value_or(read_file(s.dir / "sequence.yaml", kMaxText), std::string()));
    if (!mesh || mesh.value() != first_mesh.value()) return make_error("segment " + s.name + ": another organ");
    if (!cfg || cfg->K.fx != first_cfg->K.fx || cfg->K.cx != first_cfg->K.cx || cfg->fps != first_cfg->fps ||
        s.record_bytes != (*segments)[0].record_bytes)
      return make_error("segment " + s.name + ": another camera or video format");
  }
  return Status::Ok();
}

// Joined frame j shows frame j % F of segment (j / F) % S.
const Segment& segment_of(const std::vector<Segment>& segs, int frame, int seg_frames, int* local) {
  *local = frame % seg_frames;
  return segs[static_cast<std::size_t>((frame / seg_frames) % static_cast<int>(segs.size()))];
}

Status write_joined_sequence(const SoakOptions& o, const std::vector<Segment>& segs, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir, ec);
  if (ec) return make_error("cannot create " + dir.string() + ": " + ec.message());
  const Segment& first = segs[0];
  for (const char* f : {"sequence.yaml", "organ.ply", "markers.txt"}) {
    std::filesystem::copy_file(first.dir / f, dir / f, ec);
    if (ec) return make_error("cannot copy " + (first.dir / f).string() + ": " + ec.message());
  }
  auto cfg = parse_sequence_yaml(value_or(read_file(dir / "sequence.yaml", kMaxText), std::string()));
  if (!cfg) return make_error(cfg.message());
  std::vector<TimedPose> gt(static_cast<std::size_t>(o.frames));
  for (int j = 0; j < o.frames; ++j) {
    int k = 0;
    const Segment& s = segment_of(segs, j, o.segment_frames, &k);
    gt[static_cast<std::size_t>(j)] = {j / cfg->fps, s.groundtruth[static_cast<std::size_t>(k)].T_model_camera};
  }
  if (Status s = write_file(dir / "groundtruth.txt", format_tum(gt)); !s) return s;
  if (::mkfifo((dir / cfg->video).c_str(), 0644) != 0)
    return make_error("cannot make the FIFO " + (dir / cfg->video).string() + ": " + std::strerror(errno));
  return Status::Ok();
}

// The capture: the first segment's stream header, then the frames in
// order, into the FIFO (blocks while scopetrack does not read: a paced
// tower would drop instead, but a soak wants every frame).
// Gives up when stop is set before scopetrack opens the FIFO (it failed
// before reading), instead of waiting in open() for ever.
void feed(const SoakOptions& o, const std::vector<Segment>& segs, const std::filesystem::path& fifo,
          const std::atomic<bool>& stop, std::atomic<bool>* failed) {
  int out = -1;
  while (out < 0 && !stop.load()) {
    out = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);  // ENXIO while no reader
    if (out < 0) platform::sleep_until_ns(platform::monotonic_ns() + 20'000'000);
  }
  if (out < 0 || ::fcntl(out, F_SETFL, 0) != 0) {  // then blocking writes
    failed->store(true);
    if (out >= 0) ::close(out);
    return;
  }
  std::vector<int> in;
  for (const Segment& s : segs) in.push_back(::open((s.dir / "video.y4m").c_str(), O_RDONLY));
  std::vector<char> buf(static_cast<std::size_t>(std::max(segs[0].header_bytes, segs[0].record_bytes)));
  const auto write_all = [&](const char* p, std::size_t n) {
    while (n > 0) {
      const ssize_t w = ::write(out, p, n);
      if (w <= 0) return false;
      p += w;
      n -= static_cast<std::size_t>(w);
    }
    return true;
  };
  bool ok = ::pread(in[0], buf.data(), static_cast<std::size_t>(segs[0].header_bytes), 0) == segs[0].header_bytes &&
            write_all(buf.data(), static_cast<std::size_t>(segs[0].header_bytes));
  for (int j = 0; ok && j < o.frames; ++j) {
    int k = 0;
    const Segment& s = segment_of(segs, j, o.segment_frames, &k);
    const int fd = in[static_cast<std::size_t>(&s - segs.data())];
    const std::size_t n = static_cast<std::size_t>(s.record_bytes);
    ok = ::pread(fd, buf.data(), n, s.header_bytes + k * s.record_bytes) == static_cast<ssize_t>(n) &&
         write_all(buf.data(), n);
  }
  if (!ok) failed->store(true);
  for (int fd : in) ::close(fd);
  ::close(out);
}

// The console: connects, takes poses until reconnect_every have come, hangs
// up, connects again; until stop.
struct ConsoleStats {
  std::atomic<int> connections{0};
  std::atomic<std::int64_t> poses{0}, rejected{0};
};

void run_console(const SoakOptions& o, const platform::Endpoint& ep, const Mesh& mesh, const std::atomic<bool>& stop,
                 ConsoleStats* stats) {
  std::vector<std::uint8_t> buf(64 * 1024);
  while (!stop.load()) {
    std::string err;
    platform::Fd fd = platform::connect_to(ep, &err);
    if (!fd.valid()) {
      platform::sleep_until_ns(platform::monotonic_ns() + 50'000'000);
      continue;
    }
    ++stats->connections;
    console::ConsoleSession session(&mesh);
    std::size_t counted = 0;
    while (!stop.load() && session.poses().size() < static_cast<std::size_t>(o.reconnect_every)) {
      pollfd p{fd.get(), POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::recv(fd.get(), buf.data(), buf.size(), 0);
      if (n <= 0) break;
      if (!session.feed({buf.data(), static_cast<std::size_t>(n)})) break;
      stats->poses += static_cast<std::int64_t>(session.poses().size() - counted);
      counted = session.poses().size();
    }
    stats->rejected += session.rejected();
  }
}

double rss_mb(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  return 0;
}

// frames.csv as it grows: whole rows only.
class CsvFollower {
 public:
  explicit CsvFollower(std::filesystem::path p) : path_(std::move(p)) {}
  // Appends the rows that are complete now; false once the header is wrong.
  bool poll(std::vector<FrameRecord>* rows) {
    if (fd_ < 0) {
      fd_ = ::open(path_.c_str(), O_RDONLY);
      if (fd_ < 0) return true;
    }
    char chunk[1 << 16];
    for (ssize_t n; (n = ::read(fd_, chunk, sizeof chunk)) > 0;) pending_.append(chunk, static_cast<std::size_t>(n));
    std::size_t start = 0;
    for (std::size_t nl; (nl = pending_.find('\n', start)) != std::string::npos; start = nl + 1) {
      const std::string line = pending_.substr(start, nl - start);
      if (!header_seen_) {
        if (!is_frames_csv_header(line)) return false;
        header_seen_ = true;
        continue;
      }
      FrameRecord r;
      std::istringstream in(line);
      std::string field[7];
      for (auto& f : field) std::getline(in, f, ',');
      r.frame = std::atoi(field[0].c_str());
      r.state = field[2] == "lost" ? FrameState::kLost : FrameState::kTracking;
      r.map_points = std::atoi(field[5].c_str());
      r.keyframes = std::atoi(field[6].c_str());
      rows->push_back(r);
    }
    pending_.erase(0, start);
    return true;
  }
  ~CsvFollower() {
    if (fd_ >= 0) ::close(fd_);
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  bool header_seen_ = false;
  std::string pending_;
};

QuarterResult evaluate_quarter(const LoadedSequence& seq, const std::vector<std::optional<SE3>>& est, int first, int last) {
  EvalInput in;
  in.frames = last - first;
  in.camera = CameraModel(seq.config.K, seq.config.distortion);
  in.markers_model.reserve(seq.markers.size());
  for (const Marker& m : seq.markers) in.markers_model.push_back(m.p_model);
  for (int j = first; j < last; ++j) {
    in.estimated.push_back(est[static_cast<std::size_t>(j)]);
    in.groundtruth.push_back(seq.groundtruth[static_cast<std::size_t>(j)].T_model_camera);
  }
  const EvalResult e = evaluate(in);
  return {e.lost_pct, e.tre_median_px, e.wrong_frames};
}

}  // namespace

Result<SoakResult> run_soak(const SoakOptions& o) {
  if (o.frames < 8000 || o.frames > 10'000'000) return make_error("--frames must be in 8000..10000000 (5,000 frames of warm-up, then a baseline)");
  if (o.segment_frames < 100) return make_error("--segment-frames must be at least 100");
  std::vector<Segment> segs = segment_plan();
  if (Status s = make_segments(o, &segs); !s) return make_error(s.message());
  const auto seq_dir = o.out_dir / "sequence", run_dir = o.out_dir / "run";
  if (Status s = write_joined_sequence(o, segs, seq_dir); !s) return make_error(s.message());
  std::error_code ec;
  std::filesystem::remove_all(run_dir, ec);
  const auto sock = o.out_dir / "console.sock";
  std::filesystem::remove(sock, ec);
  auto mesh_seq = load_sequence(seq_dir);  // the FIFO is not read
  if (!mesh_seq) return mesh_seq.error();

  // scopetrack, with the console link.
  const std::string app = (o.bin_dir / "scopetrack").string(), log = (o.out_dir / "scopetrack.log").string();
  const std::string stream = "unix:" + sock.string();
  platform::Endpoint ep;
  std::string err;
  if (!platform::parse_endpoint(stream, &ep, &err)) return make_error("--out " + o.out_dir.string() + ": " + err);
  std::vector<std::string> args = {app, "--sequence", seq_dir.string(), "--out", run_dir.string(), "--stream", stream};
  if (o.ba_lag > 0) {
    args.push_back("--ba-lag");
    args.push_back(std::to_string(o.ba_lag));
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, app.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (spawned != 0) return make_error("cannot start " + app + ": " + std::strerror(spawned));

  std::atomic<bool> feed_failed{false}, stop_console{false};
  std::thread feeder([&] { feed(o, segs, seq_dir / "video.y4m", stop_console, &feed_failed); });
  ConsoleStats console;
  std::thread console_thread([&] { run_console(o, ep, mesh_seq->mesh, stop_console, &console); });

  SoakResult res;
  CsvFollower follower(run_dir / "frames.csv");
  std::vector<FrameRecord> rows;
  rows.reserve(static_cast<std::size_t>(o.frames));
  const std::int64_t t0 = platform::monotonic_ns();
  int status = 0;
  bool exited = false;
  while (!exited) {
    platform::sleep_until_ns(platform::monotonic_ns() + 20'000'000);
    const pid_t w = ::waitpid(pid, &status, WNOHANG);
    exited = w == pid;
    const double rss = exited ? 0.0 : rss_mb(pid);
    if (!follower.poll(&rows)) res.failures.push_back("frames.csv has no header");
    // The last frame's sample would catch the process tearing down: samples
    // stop 1,000 frames before the end.
    while (!exited && static_cast<int>(res.samples.size() + 1) * 1000 <= std::min<int>(static_cast<int>(rows.size()), o.frames - 1000)) {
      const int end = static_cast<int>(res.samples.size() + 1) * 1000;
      SoakSample s;
      s.frames = end;
      s.rss_mb = rss;
      int lost = 0;
      for (int j = end - 1000; j < end; ++j) lost += rows[static_cast<std::size_t>(j)].state == FrameState::kLost ? 1 : 0;
      s.lost_pct = lost / 10.0;
      s.map_points = rows[static_cast<std::size_t>(end - 1)].map_points;
      s.keyframes = rows[static_cast<std::size_t>(end - 1)].keyframes;
      res.samples.push_back(s);
      if (o.progress && end % 10000 == 0)
        std::fprintf(stderr, "scopetrack-soak: %d frames, RSS %.1f MB, %.1f %% lost in the last 1000\n", end, rss, s.lost_pct);
    }
  }
  follower.poll(&rows);
  res.frames = static_cast<int>(rows.size());
  res.wall_s = static_cast<double>(platform::monotonic_ns() - t0) * 1e-9;
  stop_console.store(true);
  console_thread.join();
  feeder.join();
  res.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  res.console_connections = console.connections.load();
  res.console_poses = console.poses.load();
  res.console_rejected = console.rejected.load();

  // The checks.
  if (res.exit_status != 0) res.failures.push_back("scopetrack exited with status " + std::to_string(res.exit_status) + " (see " + log + ")");
  if (feed_failed.load()) res.failures.push_back("the capture could not write every frame into the FIFO");
  if (res.console_rejected > 0) res.failures.push_back("the console rejected " + std::to_string(res.console_rejected) + " messages");
  if (res.console_connections < 2) res.failures.push_back("the console did not reconnect");
  if (static_cast<int>(rows.size()) != o.frames)
    res.failures.push_back("frames.csv has " + std::to_string(rows.size()) + " rows for " + std::to_string(o.frames) + " frames");
  auto summary = read_file(run_dir / "summary.json", kMaxText);
  if (summary) {
    res.tracking_thread_allocations = static_cast<std::int64_t>(value_or(json_number(summary.value(), "tracking_thread_allocations"), -1.0));
    res.max_map_points = static_cast<int>(value_or(json_number(summary.value(), "max_map_points"), 0.0));
    res.max_keyframes = static_cast<int>(value_or(json_number(summary.value(), "max_keyframes"), 0.0));
    res.fps = value_or(json_number(summary.value(), "fps"), 0.0);
  } else {
    res.failures.push_back("no summary.json");
  }
  if (res.tracking_thread_allocations != 0)
    res.failures.push_back("the tracking thread allocated " + std::to_string(res.tracking_thread_allocations) + " times");
  // RSS: the sample at 5,000 frames is the baseline.
  if (res.samples.size() >= 6) {
    res.rss_baseline_mb = res.samples[4].rss_mb;
    for (std::size_t i = 5; i < res.samples.size(); ++i) res.rss_max_after_mb = std::max(res.rss_max_after_mb, res.samples[i].rss_mb);
    if (res.rss_max_after_mb > res.rss_baseline_mb + 1.0)
      res.failures.push_back("RSS grew from " + format_number(res.rss_baseline_mb) + " MB at 5,000 frames to " +
                             format_number(res.rss_max_after_mb) + " MB");
  }
  // A pool that stays full: full in every sample of the last quarter. The
  // keyframe pool is a ring (TrackingMap::add_keyframe recycles the oldest
  // keyframe): full is its steady state, reported, not a failure. The
  // map-point pool culls only points long unseen: full there means the map
  // cannot take new points.
  int map_full = 0, kf_full = 0, last_quarter_map_full = 0, last_quarter = 0;
  for (std::size_t i = 0; i < res.samples.size(); ++i) {
    const bool mf = res.max_map_points > 0 && res.samples[i].map_points >= res.max_map_points;
    const bool kf = res.max_keyframes > 0 && res.samples[i].keyframes >= res.max_keyframes;
    map_full += mf;
    kf_full += kf;
    if (i >= res.samples.size() * 3 / 4) {
      ++last_quarter;
      last_quarter_map_full += mf;
    }
  }
  if (!res.samples.empty()) {
    res.map_full_pct = 100.0 * map_full / static_cast<double>(res.samples.size());
    res.keyframes_full_pct = 100.0 * kf_full / static_cast<double>(res.samples.size());
  }
  if (last_quarter > 0 && last_quarter_map_full == last_quarter) res.failures.push_back("the map-point pool stayed full");
  // Drift: quarters of the operation, each evaluated against the ground truth.
  auto traj = parse_tum(value_or(read_file(run_dir / "trajectory.txt", kMaxText), std::string()));
  if (traj && static_cast<int>(mesh_seq->groundtruth.size()) == o.frames) {
    std::vector<std::optional<SE3>> est(static_cast<std::size_t>(o.frames));
    for (const TimedPose& p : traj.value()) {
      const int i = frame_for_timestamp(p.timestamp_s, mesh_seq->config.fps, o.frames);
      if (i >= 0) est[static_cast<std::size_t>(i)] = p.T_model_camera;
    }
    for (int q = 0; q < 4; ++q)
      res.quarters[q] = evaluate_quarter(mesh_seq.value(), est, o.frames * q / 4, o.frames * (q + 1) / 4);
    const QuarterResult &a = res.quarters[0], &b = res.quarters[3];
    // The first quarter starts from the registration, every later pass over
    // the segments from a relocalisation after the join: a few points of
    // lost frames apart without any drift.
    if (b.lost_pct > a.lost_pct + 3.0)
      res.failures.push_back("the lost fraction drifted up: " + format_number(a.lost_pct) + " % -> " + format_number(b.lost_pct) + " %");
    // The TRE's median wanders between passes (0.3-1.5 px over the 40
    // passes of a 100,000-frame run, without a trend): drift is a rise
    // beyond half a pixel and half the first quarter's.
    if (b.tre_median_px > a.tre_median_px * 1.5 + 0.5)
      res.failures.push_back("the TRE drifted up: " + format_number(a.tre_median_px) + " -> " + format_number(b.tre_median_px) + " px");
    if (b.wrong_frames > a.wrong_frames) res.failures.push_back("more wrong frames in the last quarter than in the first");
  } else {
    res.failures.push_back("trajectory.txt or the ground truth cannot be read");
  }
  return res;
}

std::string format_samples_csv(const SoakResult& r) {
  std::string out = "frames,rss_mb,lost_pct,map_points,keyframes\n";
  for (const SoakSample& s : r.samples)
    out += std::to_string(s.frames) + ',' + format_number(s.rss_mb) + ',' + format_number(s.lost_pct) + ',' +
           std::to_string(s.map_points) + ',' + std::to_string(s.keyframes) + '\n';
  return out;
}

std::string format_report(const SoakResult& r) {
  char buf[1024];
  std::string out;
  std::snprintf(buf, sizeof buf,
                "frames %d in %.0f s (%.1f fps), exit status %d, tracking-thread allocations %lld\n"
                "RSS %.1f MB at 5,000 frames, largest after %.1f MB\n"
                "pools: map points full in %.0f %% of samples (capacity %d), keyframes full in %.0f %% (capacity %d)\n"
                "console: %d connections, %lld poses, %lld rejected messages\n",
                r.frames, r.wall_s, r.fps, r.exit_status,
                static_cast<long long>(r.tracking_thread_allocations), r.rss_baseline_mb, r.rss_max_after_mb,
                r.map_full_pct, r.max_map_points, r.keyframes_full_pct, r.max_keyframes, r.console_connections,
                static_cast<long long>(r.console_poses), static_cast<long long>(r.console_rejected));
  out += buf;
  for (int q = 0; q < 4; ++q) {
    std::snprintf(buf, sizeof buf, "quarter %d: lost %.2f %%, TRE median %.3f px, wrong %d\n", q + 1,
                  r.quarters[q].lost_pct, r.quarters[q].tre_median_px, r.quarters[q].wrong_frames);
    out += buf;
  }
  out += r.failures.empty() ? "PASSED\n" : "FAILED:\n";
  for (const std::string& f : r.failures) out += "  " + f + "\n";
  return out;
}

Status write_plot(const SoakResult& r, const std::filesystem::path& png) {
  if (r.samples.empty()) return make_error("no samples to plot");
  constexpr int kW = 960, kPanelH = 200, kLeft = 70, kRight = 20, kTop = 30;
  cv::Mat img(kTop + 3 * (kPanelH + 40), kW, CV_8UC3, cv::Scalar(255, 255, 255));
  const double max_frames = std::max(1, r.frames);
  const auto x_of = [&](double f) { return kLeft + static_cast<int>((kW - kLeft - kRight) * f / max_frames); };
  struct Series {
    const char* label;
    std::vector<double> v;
    cv::Scalar colour;
  };
  const auto panel = [&](int p, const char* title, double lo, double hi, const std::vector<Series>& series) {
    const int y0 = kTop + p * (kPanelH + 40), y1 = y0 + kPanelH;
    cv::rectangle(img, {kLeft, y0}, {kW - kRight, y1}, cv::Scalar(0, 0, 0), 1);
    cv::putText(img, title, {kLeft, y0 - 8}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    char t[32];
    for (int i = 0; i <= 4; ++i) {
      const double v = lo + (hi - lo) * i / 4.0;
      const int y = y1 - kPanelH * i / 4;
      std::snprintf(t, sizeof t, "%.4g", v);
      cv::putText(img, t, {4, y + 4}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      cv::line(img, {kLeft, y}, {kW - kRight, y}, cv::Scalar(220, 220, 220), 1);
    }
    int lx = kW - kRight - 230;
    for (const Series& s : series) {
      cv::Point prev;
      for (std::size_t i = 0; i < s.v.size(); ++i) {
        const double f = std::clamp((s.v[i] - lo) / (hi - lo), 0.0, 1.0);
        const cv::Point pt(x_of(r.samples[i].frames), y1 - static_cast<int>(kPanelH * f));
        if (i > 0) cv::line(img, prev, pt, s.colour, 2, cv::LINE_AA);
        prev = pt;
      }
      cv::putText(img, s.label, {lx, y0 - 8}, cv::FONT_HERSHEY_SIMPLEX, 0.45, s.colour, 1, cv::LINE_AA);
      lx += 110;
    }
  };
  std::vector<double> rss, lost, map_fill, kf_fill;
  double rss_hi = 0;
  for (const SoakSample& s : r.samples) {
    rss.push_back(s.rss_mb);
    rss_hi = std::max(rss_hi, s.rss_mb);
    lost.push_back(s.lost_pct);
    map_fill.push_back(r.max_map_points > 0 ? 100.0 * s.map_points / r.max_map_points : 0.0);
    kf_fill.push_back(r.max_keyframes > 0 ? 100.0 * s.keyframes / r.max_keyframes : 0.0);
  }
  panel(0, "scopetrack RSS (MB) against frames", 0, std::ceil(rss_hi / 20.0 + 0.5) * 20.0, {{"RSS", rss, {200, 60, 0}}});
  panel(1, "frames lost (% of each 1,000)", 0, 100, {{"lost", lost, {0, 0, 200}}});
  panel(2, "pool fill (% of capacity)", 0, 100, {{"map points", map_fill, {0, 140, 0}}, {"keyframes", kf_fill, {160, 0, 160}}});
  char t[64];
  std::snprintf(t, sizeof t, "frames (0 .. %d)", r.frames);
  cv::putText(img, t, {kW / 2 - 60, img.rows - 8}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", img, bytes)) return make_error("cannot encode the plot");
  return write_file(png, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace st::soak
