#include "firmware_app/stream_link.h"

#include <algorithm>
#include <cmath>

namespace st::app {

Status StreamLink::configure(const StreamLinkConfig& config, const LoadedSequence& seq, const CameraModel& frames) {
  config_ = config;
  fps_ = seq.config.fps;
  StreamHello hello;
  hello.mesh_triangle_count = static_cast<std::uint32_t>(seq.mesh.triangle_count());
  hello.mesh_checksum = mesh_checksum(seq.mesh);
  hello.image_width = seq.config.width;
  hello.image_height = seq.config.height;
  hello.K = seq.config.K;
  hello.distortion = seq.config.distortion;
  hello.source_fps = static_cast<float>(seq.config.fps);
  StreamSinkConfig sc;
  sc.endpoint = config.endpoint;
  if (Status s = sink_.configure(sc, hello); !s) return s;

  // The console's Hello keeps the sequence's own calibration; the texture
  // thread works on the frames as the tracking thread gets them.
  TextureConfig tc;
  tc.width = frames.pinhole().width;
  tc.height = frames.pinhole().height;
  tc.downscale =
      config.texture_downscale > 0 ? config.texture_downscale : (tc.width <= 960 ? 1 : 2);
  // C420jpeg (and no tag: the Y4M default) is full range; the other 4:2:0 tags are ffmpeg's studio
  // range.
  const std::string& tag = seq.video_header.chroma_tag;
  tc.full_range = tag.empty() || tag == "420jpeg";
  return texture_.configure(seq.mesh, frames, tc, config.texture_slots, &sink_);
}

Status StreamLink::start() {
  sink_.start();
  texture_.start();
  if (config_.wait_consoles > 0 &&
      !sink_.wait_for_consoles(config_.wait_consoles, config_.wait_timeout_s))
    return make_error("no console connected to " + sink_.endpoint().to_string() + " within " +
                      std::to_string(static_cast<int>(config_.wait_timeout_s)) + " s");
  return Status::Ok();
}

PoseSample pose_sample(const FrameRef& frame, const TrackResult& r, double latency_ms, double fps) {
  PoseSample p;
  p.frame = static_cast<std::uint32_t>(std::max(frame.index, 0));
  p.timestamp_ns = fps > 0 ? static_cast<std::int64_t>(std::llround(frame.index * 1e9 / fps)) : 0;
  const bool posed = r.pose_valid && r.T_camera_model.all_finite();
  p.state = posed ? r.state : TrackState::kLost;
  p.inliers = static_cast<std::uint16_t>(std::clamp(r.inliers, 0, 65535));
  p.quality = posed ? static_cast<float>(r.inlier_ratio) : 0.f;
  p.latency_us = static_cast<std::uint32_t>(std::clamp(latency_ms * 1e3, 0.0, 4e9));
  p.by_outline = posed && r.by_outline;
  if (r.outline_tried) {
    // -1: not measured; an uncertainty with a direction left unfixed
    // (infinite) is sent as 1e6.
    const auto px = [](double v) { return std::isnan(v) || v < 0 ? -1.f : static_cast<float>(std::min(v, 1e6)); };
    p.outline_lines = static_cast<std::uint16_t>(std::clamp(r.contour_lines, 0, 65535));
    p.outline_sigma_px = r.contour_lines > 0 ? px(r.contour_sigma_px) : -1.f;
    p.joint_sigma_px = r.contour_lines > 0 && r.modality_agreement_px >= 0 ? px(r.joint_sigma_px) : -1.f;
    p.outline_shading_px = px(r.modality_agreement_px);
  }
  if (posed) set_pose(&p, r.T_camera_model);
  return p;
}

void StreamLink::frame_done(const FrameRef& frame, const TrackResult& r, double latency_ms) {
  const PoseSample p = pose_sample(frame, r, latency_ms, fps_);
  const bool posed = p.state != TrackState::kLost;
  if (r.calibration_suspect) sink_.note_calibration_suspect(r.calibration_focal_scale);
  sink_.push_pose(p);
  if (!posed) return;
  ++posed_frames_;
  const bool wanted = config_.texture_every > 0
                          ? (posed_frames_ - 1) % config_.texture_every == 0
                          : (r.keyframe || r.state == TrackState::kInitialised);
  if (wanted && !texture_.try_submit(frame, r.T_camera_model)) {
    ++texture_skips_;
    sink_.note_overrun();
  }
}

void StreamLink::stop() {
  texture_.stop();  // first: its last deltas must reach the sink before the flush
  sink_.stop(config_.flush_timeout_s);
}

void StreamLink::finish(std::vector<std::pair<std::string, double>>* fields) {
  stop();
  const StreamSinkStats s = sink_.stats();
  fields->emplace_back("stream_poses", static_cast<double>(s.poses));
  fields->emplace_back("stream_pose_overruns", static_cast<double>(s.pose_overruns));
  fields->emplace_back("stream_consoles_accepted", static_cast<double>(s.consoles_accepted));
  fields->emplace_back("stream_dropped_messages", static_cast<double>(s.dropped_messages));
  fields->emplace_back("stream_sink_thread_allocations",
                       static_cast<double>(s.sink_thread_allocations));
  fields->emplace_back("texture_frames", static_cast<double>(texture_.frames_textured()));
  fields->emplace_back("texture_skipped_frames", static_cast<double>(texture_skips_));
  fields->emplace_back("texture_colour_updates", static_cast<double>(texture_.colours_sent()));
  fields->emplace_back("texture_thread_nice", static_cast<double>(texture_.thread_nice()));
  fields->emplace_back("texture_thread_allocations",
                       static_cast<double>(texture_.worker_allocations()));
}

}  // namespace st::app
