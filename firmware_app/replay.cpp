#include "firmware_app/replay.h"

#include <algorithm>
#include <memory>

#include "core/base/latency_histogram.h"
#include "hal/storage/file_io.h"
#include "hal/capture/frame_capture.h"
#include "hal/storage/run_writer.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"

namespace st {

FrameState frame_state(TrackState s) {
  switch (s) {
    case TrackState::kInitialised: return FrameState::kInitialised;
    case TrackState::kTracking: return FrameState::kTracking;
    case TrackState::kRelocalised: return FrameState::kRelocalised;
    case TrackState::kLost: break;
  }
  return FrameState::kLost;
}

FrameRow record_frame(int frame, double timestamp_s, const TrackResult& r, double latency_ms,
                      ReplayStats* stats) {
  FrameRow row;
  row.record.frame = frame;
  row.record.timestamp_s = timestamp_s;
  row.record.state = frame_state(r.state);
  row.record.inliers = r.inliers;
  row.record.latency_ms = latency_ms;
  row.pose_valid = r.pose_valid && r.T_camera_model.all_finite();
  if (row.pose_valid) row.T_model_camera = r.T_camera_model.inverse();
  ++stats->frames;
  stats->tracked += row.pose_valid ? 1 : 0;
  stats->lost += r.state == TrackState::kLost ? 1 : 0;
  stats->initialised += r.state == TrackState::kInitialised ? 1 : 0;
  stats->relocalised += r.state == TrackState::kRelocalised ? 1 : 0;
  stats->confirmed += r.confirmed_by_alignment && row.pose_valid ? 1 : 0;
  return row;
}

namespace {

std::string json_escaped(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

// The tracking thread's state: everything it touches per frame, sized
// before the first frame.
struct TrackingLoop {
  FrameCapture* capture = nullptr;
  RunWriter* writer = nullptr;
  FrameProcessor* processor = nullptr;
  FrameObserver* observer = nullptr;
  double fps = 0;
  bool realtime = false;
  LatencyHistogram latency;
  ReplayStats stats;
  bool read_error = false;

  // Runs until the end of the stream or a read error; allocates nothing.
  void run() {
    std::int64_t t_prev_done_ns = platform::monotonic_ns();
    for (;;) {
      CapturedFrame in;
      capture->pop_wait(&in);
      if (in.kind == CapturedFrame::Kind::kEnd) return;
      if (in.kind == CapturedFrame::Kind::kError) {
        read_error = true;  // the message is copied after the loop (copying allocates)
        return;
      }
      const TrackResult r = processor->step(in.frame);
      const std::int64_t t_done_ns = platform::monotonic_ns();
      // As fast as possible, the capture runs ahead on purpose: a frame's
      // latency starts when the tracker could take it, not when it was queued.
      const std::int64_t t_from_ns = realtime ? in.t_handoff_ns : std::max(in.t_handoff_ns, t_prev_done_ns);
      t_prev_done_ns = t_done_ns;
      const double latency_ms = static_cast<double>(t_done_ns - t_from_ns) * 1e-6;
      if (observer) observer->frame_done(in.frame, r, latency_ms);  // the frame is valid until release()
      capture->release();
      record(in.frame.index, r, latency_ms);
    }
  }

  void record(int index, const TrackResult& r, double latency_ms) {
    const FrameRow row = record_frame(index, fps > 0 ? index / fps : 0.0, r, latency_ms, &stats);
    latency.add(latency_ms);
    if (writer->push(row)) ++stats.writer_stalls;
  }
};

}  // namespace

void fill_timing(const LatencyHistogram& latency, double wall_s, ReplayStats* s) {
  s->wall_s = wall_s;
  s->fps = wall_s > 0 ? s->frames / wall_s : 0.0;
  s->mean_latency_ms = latency.mean_ms();
  s->p99_latency_ms = latency.quantile_ms(0.99);
  s->max_latency_ms = latency.max_ms();
  s->peak_rss_mb = platform::peak_rss_mb();
}

int estimate_frame_count(const LoadedSequence& sequence) {
  if (sequence.video_is_pipe) return 0;
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(sequence.video_path, ec);
  const std::size_t record = sequence.video_header.frame_bytes() + 6;  // "FRAME\n" + planes
  if (ec || record <= 6 || bytes < sequence.video_header.header_bytes) return 0;
  return static_cast<int>((bytes - sequence.video_header.header_bytes) / record);
}

std::string format_replay_summary(const ReplayStats& s, const ReplayOptions& options) {
  RunSummary sum;
  sum.frames = s.frames;
  sum.tracked_frames = s.tracked;
  sum.lost_frames = s.lost;
  sum.mean_latency_ms = s.mean_latency_ms;
  sum.p99_latency_ms = s.p99_latency_ms;
  sum.fps = s.fps;
  sum.peak_rss_mb = s.peak_rss_mb;
  sum.extra = {{"tracking_thread_allocations", static_cast<double>(s.tracking_thread_allocations)},
               {"initialised_frames", s.initialised},
               {"relocalised_frames", s.relocalised},
               {"confirmed_frames", s.confirmed},
               {"max_latency_ms", s.max_latency_ms},
               {"wall_time_s", s.wall_s},
               {"realtime", options.realtime ? 1.0 : 0.0},
               {"writer_stalls", s.writer_stalls}};
  sum.extra.insert(sum.extra.end(), options.summary_extra.begin(), options.summary_extra.end());
  std::string json = format_summary_json(sum);
  if (!s.error.empty()) {
    // The formatter ends with "\n}\n": add the error as the last field.
    const std::size_t close = json.rfind("\n}");
    json.insert(close, ",\n  \"error\": \"" + json_escaped(s.error) + "\"");
  }
  return json;
}

Result<ReplayStats> run_replay(const LoadedSequence& sequence, FrameProcessor& processor,
                               const ReplayOptions& options) {
  auto capture = std::make_unique<FrameCapture>();
  if (Status s = capture->open(sequence.video_path, options.ring_slots); !s) return Error{s.message()};
  const Y4mHeader& h = capture->header();
  if (h.width != sequence.config.width || h.height != sequence.config.height)
    return make_error("video " + sequence.video_path.string() + " is " + std::to_string(h.width) + "x" +
                      std::to_string(h.height) + " but sequence.yaml calibrates " +
                      std::to_string(sequence.config.width) + "x" + std::to_string(sequence.config.height));
  auto writer = std::make_unique<RunWriter>();
  if (Status s = writer->open(options.out_dir); !s) return Error{s.message()};

  auto loop = std::make_unique<TrackingLoop>();
  loop->capture = capture.get();
  loop->writer = writer.get();
  loop->processor = &processor;
  loop->observer = options.observer;
  loop->fps = sequence.config.fps;
  loop->realtime = options.realtime;
  writer->start({options.progress, estimate_frame_count(sequence), 0.25});
  processor.start();
  const std::int64_t t0_ns = platform::monotonic_ns();
  // Spawning the thread allocates its state here: before the count starts.
  capture->start(options.realtime ? sequence.config.fps : 0.0);
  const std::uint64_t allocs0 = platform::thread_allocation_count();
  loop->run();
  const std::uint64_t allocs = platform::thread_allocation_count() - allocs0;
  const double wall_s = static_cast<double>(platform::monotonic_ns() - t0_ns) * 1e-9;
  processor.stop();
  capture->join();

  ReplayOptions summary_options = options;
  processor.append_summary(&summary_options.summary_extra);
  if (options.observer) options.observer->finish(&summary_options.summary_extra);
  ReplayStats& stats = loop->stats;
  stats.tracking_thread_allocations = static_cast<std::int64_t>(allocs);
  if (loop->read_error) stats.error = capture->error();
  if (Status s = writer->finish(); !s && stats.error.empty()) stats.error = s.message();
  fill_timing(loop->latency, wall_s, &stats);
  if (Status s = write_file(options.out_dir / "summary.json", format_replay_summary(stats, summary_options)); !s)
    return Error{s.message()};
  return stats;
}

}  // namespace st
