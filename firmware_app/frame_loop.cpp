#include "firmware_app/frame_loop.h"

#include <algorithm>

#include "core/formats/json_text.h"
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

namespace {

// One frame's result as the writer's row (the pose only when valid and
// finite), counted into stats. Allocates nothing.
FrameRow record_frame(int frame, double timestamp_s, const TrackResult& r, double latency_ms, RunStats* stats) {
  FrameRow row;
  row.record.frame = frame;
  row.record.timestamp_s = timestamp_s;
  row.record.state = frame_state(r.state);
  row.record.inliers = r.inliers;
  row.record.latency_ms = latency_ms;
  row.record.map_points = r.map_points;
  row.record.keyframes = r.keyframes;
  row.pose_valid = r.pose_valid && r.T_camera_model.all_finite();
  if (row.pose_valid) row.T_model_camera = r.T_camera_model.inverse();
  ++stats->frames;
  stats->tracked += row.pose_valid ? 1 : 0;
  stats->lost += r.state == TrackState::kLost ? 1 : 0;
  stats->initialised += r.state == TrackState::kInitialised ? 1 : 0;
  stats->relocalised += r.state == TrackState::kRelocalised ? 1 : 0;
  stats->confirmed += r.confirmed_by_alignment && row.pose_valid ? 1 : 0;
  stats->by_outline += r.by_outline && row.pose_valid ? 1 : 0;
  if (r.outline_tried) ++stats->outline_verdicts[static_cast<std::size_t>(r.agreement)];
  stats->outline_vetoes += r.outline_vetoed ? 1 : 0;
  stats->outline_searches += r.outline_searched ? 1 : 0;
  stats->outline_search_fits += r.outline_search_found ? 1 : 0;
  return row;
}

}  // namespace

void FrameLoop::run() {
  processor->start();
  const std::int64_t t0_ns = platform::monotonic_ns();
  const std::uint64_t allocs0 = platform::thread_allocation_count();
  const bool paced = source->paced();
  std::int64_t t_prev_done_ns = t0_ns;
  int prev_index = -1;
  double prev_timestamp_s = 0;
  for (;;) {
    if (const int sig = stop_signal ? stop_signal->load(std::memory_order_relaxed) : 0; sig != 0) {
      stats.stop_signal = sig;
      break;
    }
    SourceFrame in;
    source->next(&in);
    if (in.kind == SourceFrame::Kind::kEnd) break;
    if (in.kind == SourceFrame::Kind::kError) {
      source_error = true;  // the message is read after the loop (copying it allocates)
      break;
    }
    if (prev_index >= 0) {
      if (in.frame.index > prev_index + 1) stats.dropped_frames += in.frame.index - prev_index - 1;
      if (!(in.timestamp_s > prev_timestamp_s)) ++stats.timestamp_faults;
    }
    prev_index = in.frame.index;
    prev_timestamp_s = in.timestamp_s;
    const TrackResult r = processor->step(in.frame);
    const std::int64_t t_done_ns = platform::monotonic_ns();
    // Read as fast as possible, a file runs ahead on purpose: a frame's
    // latency starts when the tracker could take it, not when it was queued.
    const std::int64_t t_from_ns = paced ? in.t_ready_ns : std::max(in.t_ready_ns, t_prev_done_ns);
    t_prev_done_ns = t_done_ns;
    const double latency_ms = static_cast<double>(t_done_ns - t_from_ns) * 1e-6;
    if (observer) observer->frame_done(in.frame, r, latency_ms);  // the frame is valid until release()
    source->release();
    const FrameRow row = record_frame(in.frame.index, in.timestamp_s, r, latency_ms, &stats);
    latency.add(latency_ms);
    if (writer != nullptr && writer->push(row)) ++stats.writer_stalls;
    if (status) {
      status->frames.store(stats.frames, std::memory_order_relaxed);
      status->tracked.store(stats.tracked, std::memory_order_relaxed);
      status->lost.store(stats.lost, std::memory_order_relaxed);
      status->last_state.store(static_cast<int>(row.record.state), std::memory_order_relaxed);
      if (r.calibration_suspect) status->calibration_suspect.store(true, std::memory_order_relaxed);
    }
  }
  stats.tracking_thread_allocations = static_cast<std::int64_t>(platform::thread_allocation_count() - allocs0);
  stats.wall_s = static_cast<double>(platform::monotonic_ns() - t0_ns) * 1e-9;
  processor->stop();
  if (status) status->done.store(true);
}

void FrameLoop::fill_timing() {
  stats.fps = stats.wall_s > 0 ? stats.frames / stats.wall_s : 0.0;
  stats.mean_latency_ms = latency.mean_ms();
  stats.p99_latency_ms = latency.quantile_ms(0.99);
  stats.max_latency_ms = latency.max_ms();
  stats.peak_rss_mb = platform::peak_rss_mb();
}

std::string format_run_summary(const RunStats& s, bool realtime,
                               const std::vector<std::pair<std::string, double>>& extra) {
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
               {"outline_frames", s.by_outline},
               {"outline_no_outline", s.outline_verdicts[static_cast<std::size_t>(Agreement::kNoOutline)]},
               {"outline_loose", s.outline_verdicts[static_cast<std::size_t>(Agreement::kOutlineLoose)]},
               {"outline_no_shading", s.outline_verdicts[static_cast<std::size_t>(Agreement::kNoShading)]},
               {"outline_disagree", s.outline_verdicts[static_cast<std::size_t>(Agreement::kDisagree)]},
               {"outline_vetoes", s.outline_vetoes},
               {"outline_searches", s.outline_searches},
               {"outline_search_fits", s.outline_search_fits},
               {"max_latency_ms", s.max_latency_ms},
               {"wall_time_s", s.wall_s},
               {"realtime", realtime ? 1.0 : 0.0},
               {"writer_stalls", s.writer_stalls},
               {"dropped_frames", s.dropped_frames},
               {"timestamp_faults", s.timestamp_faults},
               {"stop_signal", s.stop_signal}};
  sum.extra.insert(sum.extra.end(), extra.begin(), extra.end());
  std::string json = format_summary_json(sum);
  if (!s.error.empty()) {
    // The formatter ends with "\n}\n": add the error as the last field.
    const std::size_t close = json.rfind("\n}");
    json.insert(close, ",\n  \"error\": \"" + json_escaped(s.error) + "\"");
  }
  return json;
}

}  // namespace st
