#include "tools/overlay/overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "core/evaluation/evaluation.h"
#include "hal/capture/y4m_reader.h"
#include "tools/overlay/run_output.h"
#include "tools/overlay/video_sink.h"

namespace st::overlay {

Status OverlayRenderer::configure(const LoadedSequence& seq, const OverlayStyle& style) {
  style_ = style;
  const SequenceConfig& c = seq.config;
  if (Status s = CameraModel::validate(c.K, c.distortion); !s) return s;
  camera_ = CameraModel(c.K, c.distortion);
  markers_ = seq.markers;
  width_ = c.width;
  height_ = c.height;
  if (Status s = build_distortion_lookup(); !s) return s;
  raster_ = std::make_unique<MeshRasterizer>();
  RasterConfig rc;
  rc.width = width_ + 2 * pad_x_;
  rc.height = height_ + 2 * pad_y_;
  rc.downscale = 1;
  if (Status s = raster_->configure(seq.mesh, rc); !s) return s;
  K_raster_ = c.K;
  K_raster_.cx += pad_x_;
  K_raster_.cy += pad_y_;
  K_raster_.width = rc.width;
  K_raster_.height = rc.height;
  labels_.allocate(width_, height_);
  labels_.fill(-1);
  layer_.reset(width_, height_);
  return Status::Ok();
}

// Every captured pixel's ideal position, once; the raster is padded to
// contain them all (up to half the image on each side).
Status OverlayRenderer::build_distortion_lookup() {
  std::vector<Vec2> ideal(static_cast<std::size_t>(width_) * height_);
  std::vector<bool> ok(ideal.size());
  double min_x = 0, min_y = 0, max_x = width_ - 1, max_y = height_ - 1;
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * width_ + x;
      ok[i] = camera_.undistort_pixel(Vec2(x, y), &ideal[i]) && ideal[i].allFinite();
      if (!ok[i]) continue;
      min_x = std::min(min_x, ideal[i].x());
      min_y = std::min(min_y, ideal[i].y());
      max_x = std::max(max_x, ideal[i].x());
      max_y = std::max(max_y, ideal[i].y());
    }
  }
  const auto margin = [](double over, int size) {
    return std::clamp(static_cast<int>(std::ceil(over)) + 1, 0, size / 2);
  };
  pad_x_ = margin(std::max(-min_x, max_x - (width_ - 1)), width_);
  pad_y_ = margin(std::max(-min_y, max_y - (height_ - 1)), height_);
  const int rw = width_ + 2 * pad_x_, rh = height_ + 2 * pad_y_;
  raster_index_.assign(ideal.size(), -1);
  for (std::size_t i = 0; i < ideal.size(); ++i) {
    if (!ok[i]) continue;
    const long rx = std::lround(ideal[i].x()) + pad_x_, ry = std::lround(ideal[i].y()) + pad_y_;
    if (rx >= 0 && ry >= 0 && rx < rw && ry < rh) raster_index_[i] = static_cast<std::int32_t>(ry * rw + rx);
  }
  return Status::Ok();
}

void OverlayRenderer::render_labels(const SE3& T_model_camera) {
  raster_->render(T_model_camera.inverse(), K_raster_);
  const ImageView<const std::int32_t> ids = raster_->triangle_id();
  const int rw = width_ + 2 * pad_x_;
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const std::int32_t r = raster_index_[static_cast<std::size_t>(y) * width_ + x];
      labels_(x, y) = r < 0 ? -1 : ids(r % rw, r / rw);
    }
  }
}

void OverlayRenderer::draw_markers(const SE3& T_model_camera, Rgb colour, bool ring) {
  const int radius = std::max(4, width_ / 160);
  for (const Marker& m : markers_) {
    Vec2 px;
    if (!project_marker(camera_, T_model_camera, m.p_model, &px)) continue;
    const cv::Point centre(static_cast<int>(std::lround(px.x())), static_cast<int>(std::lround(px.y())));
    if (ring) {
      cv::circle(layer_.bgra(), centre, radius * 2, OverlayLayer::scalar(colour), 2, cv::LINE_AA);
    } else {
      cv::circle(layer_.bgra(), centre, radius + 1, OverlayLayer::scalar({0, 0, 0}), cv::FILLED, cv::LINE_AA);
      cv::circle(layer_.bgra(), centre, radius, OverlayLayer::scalar(colour), cv::FILLED, cv::LINE_AA);
    }
  }
}

void OverlayRenderer::draw_state(const FrameAnnotations& a) {
  const bool lost = a.state ? *a.state == FrameState::kLost : a.T_model_camera == nullptr;
  const bool reloc = a.state && *a.state == FrameState::kRelocalised;
  const int border = std::max(4, width_ / 128);
  if (lost || reloc)
    cv::rectangle(layer_.bgra(), cv::Rect(0, 0, width_, height_),
                  OverlayLayer::scalar(lost ? style_.lost_border : style_.relocalised_border), 2 * border);
  if (!style_.text) return;
  char text[96];
  std::snprintf(text, sizeof text, "frame %d  %s", a.index,
                a.state ? to_string(*a.state) : (a.T_model_camera ? "pose" : "no pose"));
  const double scale = std::max(0.4, width_ / 1600.0);
  const cv::Point at(border + 6, border + static_cast<int>(24 * scale) + 6);
  cv::putText(layer_.bgra(), text, at + cv::Point(1, 1), cv::FONT_HERSHEY_SIMPLEX, scale,
              OverlayLayer::scalar({0, 0, 0}), 2, cv::LINE_AA);
  cv::putText(layer_.bgra(), text, at, cv::FONT_HERSHEY_SIMPLEX, scale, OverlayLayer::scalar({255, 255, 255}), 1,
              cv::LINE_AA);
}

const OverlayLayer& OverlayRenderer::draw_layer(const FrameAnnotations& a) {
  layer_.clear();
  if (a.T_model_camera) {
    render_labels(*a.T_model_camera);
    if (style_.fill_alpha > 0) {
      for (int y = 0; y < height_; ++y)
        for (int x = 0; x < width_; ++x)
          if (labels_(x, y) >= 0) layer_.set(x, y, style_.silhouette, style_.fill_alpha);
    }
    if (style_.wireframe) draw_wireframe(labels_.cview(), style_.silhouette, style_.wireframe_alpha, &layer_);
    draw_silhouette(labels_.cview(), style_.silhouette, std::max(1, width_ / 640), &layer_);
  }
  if (style_.markers && a.T_model_camera_gt) draw_markers(*a.T_model_camera_gt, style_.truth_marker, true);
  if (style_.markers && a.T_model_camera) draw_markers(*a.T_model_camera, style_.tracked_marker, false);
  if (style_.state) draw_state(a);
  return layer_;
}

void OverlayRenderer::draw(const FrameAnnotations& a, ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
                           ImageView<std::uint8_t> v) {
  draw_layer(a).composite(y, u, v);
}

namespace {

// Copies a captured frame into owned 4:2:0 planes (mono gets neutral chroma).
void copy_frame(const FrameRef& f, Image<std::uint8_t>* y, Image<std::uint8_t>* u, Image<std::uint8_t>* v) {
  for (int r = 0; r < f.y.height; ++r) std::copy_n(f.y.row(r), f.y.width, y->view().row(r));
  if (f.u.empty()) {
    u->fill(128);
    v->fill(128);
    return;
  }
  for (int r = 0; r < f.u.height; ++r) {
    std::copy_n(f.u.row(r), f.u.width, u->view().row(r));
    std::copy_n(f.v.row(r), f.v.width, v->view().row(r));
  }
}

const SE3* pose_at(const std::vector<std::optional<SE3>>& poses, int i) {
  return i < static_cast<int>(poses.size()) && poses[static_cast<std::size_t>(i)] ? &*poses[static_cast<std::size_t>(i)]
                                                                                  : nullptr;
}

}  // namespace

Result<OverlayReport> render_overlay(const OverlayOptions& o) {
  auto seq = load_sequence(o.sequence_dir);
  if (!seq) return seq.error();
  auto run = read_run_output(o.run_dir, seq->config.fps);
  if (!run) return run.error();
  auto gt = poses_by_frame(seq->groundtruth, seq->config.fps);
  if (!gt) return make_error("groundtruth: " + gt.message());
  OverlayRenderer renderer;
  if (Status s = renderer.configure(seq.value(), o.style); !s) return Error{s.message()};
  Y4mReader reader;
  if (Status s = reader.open(seq->video_path, 2); !s) return Error{s.message()};
  const Y4mHeader& h = reader.header();
  VideoSink sink;
  if (Status s = sink.open(o.video_out, h.width, h.height, h.fps_num, h.fps_den); !s) return Error{s.message()};
  Image<std::uint8_t> Y(h.width, h.height), U((h.width + 1) / 2, (h.height + 1) / 2), V(U.width(), U.height());
  OverlayReport report;
  report.through_ffmpeg = sink.through_ffmpeg();
  FrameRef frame;
  for (int i = 0; o.max_frames < 0 || i < o.max_frames; ++i) {
    const ReadResult r = reader.read_frame(&frame);
    if (r == ReadResult::kEndOfStream) break;
    if (r == ReadResult::kError) {
      report.error = reader.error();
      break;
    }
    copy_frame(frame, &Y, &U, &V);
    FrameAnnotations a{i, run->pose(i), pose_at(gt.value(), i), run->state_of(i)};
    renderer.draw(a, Y.view(), U.view(), V.view());
    if (Status s = sink.write(Y.cview(), U.cview(), V.cview()); !s) return Error{s.message()};
    ++report.frames;
    report.frames_with_pose += a.T_model_camera ? 1 : 0;
    report.frames_with_groundtruth += a.T_model_camera_gt ? 1 : 0;
  }
  if (Status s = sink.close(); !s) return Error{s.message()};
  return report;
}

}  // namespace st::overlay
