// Tracker facade, configuration checks and the per-frame dispatch.
#include "core/tracking/tracker.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/base/capacity.h"
#include "core/mesh/mesh_simplify.h"
#include "core/tracking/tracker_impl.h"

namespace st {

namespace {

Status check_frame(const TrackerConfig& c, const CameraModel& camera) {
  const auto err = [](const std::string& m) { return Status(make_error("tracker config: " + m)); };
  if (c.width <= 0 || c.height <= 0 || c.width > kMaxImageWidth || c.height > kMaxImageHeight)
    return err("frame size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
               " outside [1, " + std::to_string(kMaxImageWidth) + "]x[1, " +
               std::to_string(kMaxImageHeight) + "]");
  const Status cam = CameraModel::validate(camera.pinhole(), camera.distortion());
  if (!cam.ok()) return err("camera: " + cam.message());
  if (camera.pinhole().width != c.width || camera.pinhole().height != c.height)
    return err("calibration size " + std::to_string(camera.pinhole().width) + "x" +
               std::to_string(camera.pinhole().height) + " differs from the frame size");
  return Status::Ok();
}

// The result's pixel figures from working pixels to the frame's (-1: not
// measured, stays).
void to_input_pixels(double f, TrackResult* r) {
  for (double* v : {&r->rms_px, &r->whitened_rms_px, &r->contour_rms_px, &r->contour_sigma_px, &r->joint_sigma_px,
                    &r->modality_agreement_px})
    if (*v > 0) *v *= f;
}

}  // namespace

WorkingSize working_size(int width, int height, int working_width) {
  if (working_width <= 0 || width <= working_width) return {width, height};
  const int h = static_cast<int>(std::lround(static_cast<double>(height) * working_width / width));
  return {working_width, std::max(1, h)};
}

Status validate_tracker_settings(const TrackerConfig& c) {
  const auto err = [](const std::string& m) { return Status(make_error("tracker config: " + m)); };
  if (c.features.n_features < 50 || c.features.n_features > kMaxKeypoints)
    return err("features.n_features " + std::to_string(c.features.n_features) + " outside [50, " +
               std::to_string(kMaxKeypoints) + "]");
  if (c.max_keyframes < 2 || c.max_keyframes > kMaxKeyframes)
    return err("max_keyframes " + std::to_string(c.max_keyframes) + " outside [2, " +
               std::to_string(kMaxKeyframes) + "]");
  if (c.max_map_points < c.features.n_features || c.max_map_points > kMaxMapPoints)
    return err("max_map_points " + std::to_string(c.max_map_points) + " outside [features.n_features, " +
               std::to_string(kMaxMapPoints) + "]");
  if (c.working_width < 0 || c.working_width > kMaxImageWidth)
    return err("working_width " + std::to_string(c.working_width) + " outside [0, " + std::to_string(kMaxImageWidth) + "]");
  if (c.raster_downscale != 1 && c.raster_downscale != 2 && c.raster_downscale != 4)
    return err("raster_downscale must be 1, 2 or 4");
  if (c.max_raster_triangles != 0 && (c.max_raster_triangles < 1000 || c.max_raster_triangles > kMaxMeshTriangles))
    return err("max_raster_triangles " + std::to_string(c.max_raster_triangles) + " outside [1000, " +
               std::to_string(kMaxMeshTriangles) + "] (0: never simplify)");
  if (c.min_inliers < 6) return err("min_inliers must be >= 6 (a pose has 6 degrees of freedom)");
  if (!(c.min_inlier_ratio >= 0 && c.min_inlier_ratio <= 1) || !(c.min_mask_agreement >= 0 && c.min_mask_agreement <= 1))
    return err("min_inlier_ratio and min_mask_agreement must be in [0, 1]");
  if (!(c.confirmed_min_inlier_ratio >= 0 && c.confirmed_min_inlier_ratio <= 1) ||
      !(c.confirmed_keyframe_min_anchored >= 0 && c.confirmed_keyframe_min_anchored <= 1) ||
      !(c.anchor_min_inlier_ratio >= 0 && c.anchor_min_inlier_ratio <= 1))
    return err("confirmed_min_inlier_ratio, confirmed_keyframe_min_anchored and anchor_min_inlier_ratio must be in [0, 1]");
  if (c.ba_lag_frames < 0 || c.ba_lag_frames > 1000) return err("ba_lag_frames outside [0, 1000]");
  if (!(c.fast_reference_luma >= 0 && c.fast_reference_luma <= 255))
    return err("fast_reference_luma must be in [0, 255] (0: off)");
  if (!(c.fast_reference_contrast >= 0 && c.fast_reference_contrast <= 255))
    return err("fast_reference_contrast must be in [0, 255] (0: off)");
  if (c.contour_min_lines < 6 || c.contour_min_lines > RegionModality::kMaxLines)
    return err("contour_min_lines must be in [6, " + std::to_string(RegionModality::kMaxLines) + "]");
  if (!(c.contour_max_sigma_px >= 0 && c.contour_max_sigma_px <= 1000))
    return err("contour_max_sigma_px must be in [0, 1000]");
  if (!(c.denoise_noise_ratio >= 0 && c.denoise_noise_ratio <= 1000))
    return err("denoise_noise_ratio must be in [0, 1000]");
  if (!(c.contour_max_joint_sigma_px >= 0 && c.contour_max_joint_sigma_px <= 1000))
    return err("contour_max_joint_sigma_px must be in [0, 1000]");
  if (!(c.contour_agreement_px >= 0 && c.contour_agreement_px <= 1000))
    return err("contour_agreement_px must be in [0, 1000]");
  if (c.contour_check_inliers < 0 || c.contour_check_inliers > kMaxKeypoints)
    return err("contour_check_inliers must be in [0, " + std::to_string(kMaxKeypoints) + "] (0: never)");
  if (!(c.contour_veto_px > 0 && c.contour_veto_px <= 1000)) return err("contour_veto_px must be in (0, 1000]");
  if (!(c.photometric_weight >= 0 && c.photometric_weight <= 1000))
    return err("photometric_weight must be in [0, 1000]");
  if (!(c.confirm_agreement_px >= 0 && c.confirm_agreement_px <= 1000))
    return err("confirm_agreement_px must be in [0, 1000]");
  if (!(c.max_rms_px > 0) || !(c.max_jump_deg > 0) || !(c.max_jump_mm > 0))
    return err("max_rms_px, max_jump_deg and max_jump_mm must be positive");
  if (!(c.search_radius_px > 0.f) || !(c.wide_radius_px >= c.search_radius_px) || !(c.refine_radius_px > 0.f))
    return err("search radii must be positive and wide_radius_px >= search_radius_px");
  if (c.matching.max_distance < 1 || c.matching.max_distance > 256)
    return err("matching.max_distance outside [1, 256]");
  if (!(c.ba.w_shape >= 0) || !std::isfinite(c.ba.w_shape) || c.ba_window_keyframes < 2 ||
      c.ba_window_keyframes > kMaxKeyframes || c.ba.max_iterations < 1 || c.ba_global_max_iterations < 1 ||
      !(c.ba.max_time_s > 0) || !(c.ba_global_max_time_s > 0) || c.ba_max_observations < 1)
    return err("bundle adjustment settings out of range (ba.w_shape >= 0, window in [2, kMaxKeyframes], limits > 0)");
  if (!(c.registration_sigma_deg >= 0) || !std::isfinite(c.registration_sigma_deg) ||
      !(c.registration_sigma_mm >= 0) || !std::isfinite(c.registration_sigma_mm) ||
      (c.registration_sigma_deg > 0) != (c.registration_sigma_mm > 0) ||
      c.ba_registration_keyframes < 0 || !(c.ba.prior_release_f >= 0) ||
      !std::isfinite(c.ba.prior_release_f))
    return err(
        "registration prior out of range (both sigmas 0, or both finite and > 0; keyframes >= 0; "
        "release F >= 0)");
  if (!(c.keyframe_max_motion_px > 0.f)) return err("keyframe_max_motion_px must be positive");
  if (c.reloc_keyframes_per_frame < 1 || c.reloc_min_matches < 4 || c.reloc_min_matches > kMaxKeypoints ||
      c.strict_frames < 0 || !(c.strict_inlier_factor >= 1.0) ||
      c.min_spread_cells < 0 || c.min_spread_cells > 16 || !(c.dead_reckoning_decay > 0.0) ||
      !(c.dead_reckoning_decay <= 1.0))
    return err("relocalisation settings out of range");
  if (c.calibration_test_jobs < 0 || !(c.calibration_min_f > 0) || !std::isfinite(c.calibration_min_f) ||
      !(c.calibration_scale_error > 0) || !(c.calibration_scale_error < 1) || c.calibration_votes < 1)
    return err("calibration test settings out of range");
  return Status::Ok();
}

Status TrackerImpl::configure(const TrackerConfig& input_config, const Mesh& mesh, const CameraModel& input_camera,
                              const SE3& T_camera_model_init) {
  if (Status s = check_frame(input_config, input_camera); !s.ok()) return s;
  if (Status s = validate_tracker_settings(input_config); !s.ok()) return s;
  if (mesh.triangle_count() <= 0) return make_error("tracker: the mesh has no triangles");
  if (!T_camera_model_init.all_finite()) return make_error("tracker: T_camera_model_init is not finite");
  // The working resolution: everything below sees the frame, the
  // calibration and the settings at it.
  input_width_ = input_config.width;
  input_height_ = input_config.height;
  const WorkingSize ws = working_size(input_config.width, input_config.height, input_config.working_width);
  scaling_ = ws.width != input_config.width;
  TrackerConfig config = input_config;
  CameraModel camera = input_camera;
  input_px_per_working_px_ = 1.0;
  if (scaling_) {
    const double sx = static_cast<double>(ws.width) / input_config.width;
    const double sy = static_cast<double>(ws.height) / input_config.height;
    config.width = ws.width;
    config.height = ws.height;
    camera = CameraModel(input_camera.pinhole().scaled(sx, sy, ws.width, ws.height), input_camera.distortion());
    if (Status s = CameraModel::validate(camera.pinhole(), camera.distortion()); !s.ok())
      return make_error("tracker: the calibration at the working size " + std::to_string(ws.width) + "x" +
                        std::to_string(ws.height) + ": " + s.message());
    input_px_per_working_px_ = 1.0 / sx;
    if (Status s = scaler_.configure(input_config.width, input_config.height, ws.width, ws.height); !s.ok())
      return make_error("tracker: working_width: " + s.message());
    work_y_.allocate(ws.width, ws.height);
    work_u_.allocate(FrameScaler::chroma_size(ws.width), FrameScaler::chroma_size(ws.height));
    work_v_.allocate(FrameScaler::chroma_size(ws.width), FrameScaler::chroma_size(ws.height));
  }
  config_ = config;
  camera_ = camera;
  K_ = camera.pinhole();
  distorted_ = !camera.distortion().is_zero();
  T_init_ = T_camera_model_init;
  RasterConfig rc;
  rc.width = config.width;
  rc.height = config.height;
  rc.downscale = config.raster_downscale;
  // The per-frame render draws the mesh, or its simplified copy when it is
  // over budget (TrackerConfig::max_raster_triangles).
  Mesh simplified;
  const Mesh* rendered = &mesh;
  if (config.max_raster_triangles > 0 && mesh.triangle_count() > config.max_raster_triangles) {
    auto s = simplify_to_budget(mesh, config.max_raster_triangles);
    if (!s) return make_error("tracker: " + s.message());
    simplified = std::move(s).value();
    rendered = &simplified;
  }
  if (Status s = raster_.configure(*rendered, rc); !s.ok()) return make_error("tracker: raster: " + s.message());
  if (Status s = region_.configure(*rendered, config.width, config.height); !s.ok())
    return make_error("tracker: " + s.message());
  if (config.outline_search) {
    if (Status s = outline_search_.configure(*rendered, K_); !s.ok()) return make_error("tracker: " + s.message());
  }
  if (Status s = valid_mask_.configure(ValidMaskConfig{}, config.width, config.height); !s.ok())
    return make_error("tracker: valid mask: " + s.message());
  // The occluder mask is at the chroma's resolution, the valid mask's (1/2).
  if (Status s = occluder_.configure(OccluderMaskConfig{}, config.width, config.height); !s.ok())
    return make_error("tracker: occluder mask: " + s.message());
  {
    const GrayView vm = valid_mask_.mask();
    valid_without_occluders_.assign(static_cast<std::size_t>(vm.width) * static_cast<std::size_t>(vm.height), 0);
  }
  if (Status s = orb_.configure(config.features, config.width, config.height); !s.ok())
    return make_error("tracker: ORB: " + s.message());
  if (Status s = matcher_.configure(config.matching); !s.ok()) return make_error("tracker: matcher: " + s.message());
  if (Status s = grid_.configure(config.width, config.height); !s.ok()) return make_error("tracker: grid: " + s.message());
  if (Status s = motion_.configure(config.width, config.height); !s.ok()) return make_error("tracker: " + s.message());
  {
    const ImagePyramid& pyr = orb_.pyramid();
    std::array<int, kMaxPyramidLevels> widths{};
    for (int k = 0; k < pyr.levels(); ++k) widths[static_cast<std::size_t>(k)] = pyr.level(k).width;
    align_level_ = DirectAligner::choose_level(widths.data(), pyr.levels());
    const GrayView l = pyr.level(align_level_);
    if (Status s = align_scratch_.configure(l.width, l.height); !s.ok()) return make_error("tracker: " + s.message());
    if (Status s = aligner_.configure(l.width, l.height, pyr.scale(align_level_), &align_scratch_); !s.ok())
      return make_error("tracker: " + s.message());
    if (Status s = anchor_.configure(l.width, l.height, pyr.scale(align_level_), &align_scratch_); !s.ok())
      return make_error("tracker: " + s.message());
    if (Status s = shading_ref_.configure(l.width, l.height, pyr.scale(align_level_), &align_scratch_); !s.ok())
      return make_error("tracker: " + s.message());
  }
  if (Status s = solver_.configure(kMaxKeypoints); !s.ok()) return make_error("tracker: pose: " + s.message());
  PnpRansacOptions ro;
  ro.min_inliers = config.reloc_min_matches;
  ro.max_iterations = 300;
  if (Status s = ransac_.configure(kMaxKeypoints, ro); !s.ok()) return make_error("tracker: RANSAC: " + s.message());
  // A keyframe links each of its frame's keypoints to one map point at
  // most, and a frame has at most features.n_features keypoints (the
  // extractor's level targets sum to it): 2.3 MB of links at the defaults
  // instead of 6.3 for kMaxKeypoints a keyframe.
  if (Status s = map_.configure(config.max_map_points, config.max_keyframes, config.features.n_features); !s.ok())
    return make_error("tracker: " + s.message());
  features_ = std::make_unique<FeatureSet>();
  const auto nk = static_cast<std::size_t>(kMaxKeypoints);
  kp_ideal_.assign(nk, Vec2::Zero());
  kp_inlier_.assign(nk, 0);
  corr_p_.assign(nk, Vec3::Zero());
  corr_px_.assign(nk, Vec2::Zero());
  corr_info_.assign(nk, 1.0);
  corr_point_.assign(nk, -1);
  corr_kp_.assign(nk, -1);
  corr_inlier_.assign(nk, 0);
  octave_info_.assign(static_cast<std::size_t>(kMaxPyramidLevels), 1.0);
  for (int o = 0; o < kMaxPyramidLevels; ++o) {
    octave_info_[static_cast<std::size_t>(o)] = octave_information(o, static_cast<double>(config.features.scale_factor));
  }
  if (Status s = ba_.configure(config, T_camera_model_init); !s.ok()) return s;
  if (Status s = reloc_keyframes_.configure(config.width, config.height); !s.ok()) return s;
  if (Status s = local_map_.configure(config.max_map_points, camera, config.features.scale_factor,
                                      config.features.levels);
      !s.ok())
    return make_error("tracker: " + s.message());
  gates_.configure(config);
  fast_scaler_.configure(config.fast_reference_luma, config.fast_reference_contrast);
  started_ = false;
  return Status::Ok();
}

void TrackerImpl::start() {
  map_.clear();
  started_ = true;
  initialised_ = false;
  lost_ = false;
  raster_valid_ = false;
  T_last_ = T_init_;
  velocity_ = SE3();
  lost_frames_ = strict_frames_left_ = 0;
  lost_motion_px_ = kUnknownMotion;
  last_inliers_ = 0;
  last_depth_mm_ = 100.0;
  motion_.reset();
  aligner_.forget_reference();
  anchor_.forget_reference();
  shading_ref_.forget_reference();
  region_.reset();
  outline_search_.reset();
  search_round_ = 0;
  frames_since_learn_ = 0;
  ref_keyframe_ = -1;
  reloc_keyframes_.reset();
  ba_.reset();
}

TrackResult TrackerImpl::step(GrayView luma, int frame_index, ChromaView chroma) {
  TrackResult r;
  const double t0 = now_ms();
  // The frame at its own size, or already at the working size (a capture
  // that scales it, Y4mCapture::set_working_size).
  const bool at_working = scaling_ && luma.width == config_.width && luma.height == config_.height;
  if (!started_ || luma.empty() || (!at_working && (luma.width != input_width_ || luma.height != input_height_))) {
    r.map_points = map_.point_count();
    r.keyframes = map_.keyframe_count();
    return r;  // defined degraded state: lost, no pose
  }
  const bool scale_here = scaling_ && !at_working;
  if (scale_here) {
    bool scaled_chroma = false;
    scaler_.scale(luma, chroma.u, chroma.v, work_y_.view(), work_u_.view(), work_v_.view(), &scaled_chroma);
    luma = work_y_.cview();
    // No chroma, or planes of another size: no occluder mask, as at the frame's size.
    chroma = scaled_chroma ? ChromaView{work_u_.cview(), work_v_.cview()} : ChromaView{};
  }
  const double t_scaled = now_ms();
  const bool ba_applied = ba_.apply(&map_);  // safe point: nothing of this frame uses the map yet
  ba_.note_frame(frame_index);
  valid_view_ = valid_scene_ = valid_mask_.build(luma);
  const double t_valid = now_ms();
  bool occluder_refused = false;
  const int occluder_pixels = remove_occluders_from_valid(luma, chroma, &occluder_refused);
  luma_ = luma;
  chroma_ = chroma;
  const double t_occluder = now_ms();
  if (!initialised_) {
    r = initialise(luma, frame_index);
  } else if (lost_) {
    r = relocalise(luma, frame_index);
  } else {
    r = track(luma, frame_index);
  }
  if (scale_here) r.times_ms[static_cast<int>(Stage::kScale)] = t_scaled - t0;
  r.times_ms[static_cast<int>(Stage::kPyramid)] += t_valid - t_scaled;  // valid mask (and BA apply)
  if (occluder_pixels >= 0) r.times_ms[static_cast<int>(Stage::kOccluder)] = t_occluder - t_valid;
  r.occluder_pixels = occluder_pixels;
  r.occluder_refused = occluder_refused;
  ba_.frame_done(map_, r);
  r.ba_applied = ba_applied;
  r.ba_submitted = ba_.submit(map_, initialised_);
  r.map_points = map_.point_count();
  r.keyframes = map_.keyframe_count();
  r.calibration_suspect = ba_.calibration().suspect;
  r.calibration_focal_scale = static_cast<float>(ba_.calibration().focal_scale);
  if (config_.now_ns) r.times_ms[static_cast<int>(Stage::kTotal)] = now_ms() - t0;
  if (scaling_) to_input_pixels(input_px_per_working_px_, &r);
  return r;
}

// The occluder mask of this frame taken out of valid_view_ (which then
// views valid_without_occluders_). Returns the valid pixels removed, -1
// when there is no occluder mask (off, no chroma, or chroma of another size).
int TrackerImpl::remove_occluders_from_valid(GrayView luma, ChromaView chroma, bool* refused) {
  if (!config_.use_occluder_mask || chroma.empty() || valid_view_.empty()) return -1;
  const GrayView occluder = occluder_.build(luma, chroma.u, chroma.v);
  if (occluder.empty()) return -1;
  if (occluder_.candidate_pixels() == 0) return 0;  // then the mask is empty
  // A mask over most of the organ is the organ's own colour (a pale organ,
  // a grey texture, a monochrome render), not an instrument in front of it:
  // taking it out would leave nothing to track. Judged on the last render;
  // before the first one (frame 0) the mask is not used.
  if (!raster_valid_) return 0;
  const GrayView organ = raster_.mask();
  if (organ.width != occluder.width || organ.height != occluder.height) return 0;
  long organ_px = 0, flagged_on_organ = 0;
  for (int y = 0; y < organ.height; ++y) {
    const std::uint8_t* o = occluder.row(y);
    const std::uint8_t* g = organ.row(y);
    for (int x = 0; x < organ.width; ++x) {
      organ_px += g[x] != 0;
      flagged_on_organ += (g[x] != 0) & (o[x] != 0);
    }
  }
  if (organ_px == 0 || flagged_on_organ > kMaxOccludedOrganShare * static_cast<double>(organ_px)) {
    *refused = true;
    return 0;
  }
  ImageView<std::uint8_t> out(valid_without_occluders_.data(), valid_view_.width, valid_view_.height,
                              valid_view_.width);
  const int removed = remove_occluders(valid_view_, occluder, out);
  valid_view_ = out;
  return removed;
}

double TrackerImpl::now_ms() const {
  return config_.now_ns ? static_cast<double>(config_.now_ns()) * 1e-6 : 0.0;
}

void TrackerImpl::lap(Stage s, double* t_last_ms, TrackResult* r) const {
  if (!config_.now_ns) return;
  const double t = now_ms();
  r->times_ms[static_cast<int>(s)] += t - *t_last_ms;
  *t_last_ms = t;
}

void TrackerImpl::render_at(const SE3& T_camera_model) {
  // The same pose renders the same buffers (a lost frame's dead reckoning
  // and the shading's alignment often start from one reference frame).
  if (raster_valid_ && T_camera_model.rotation() == raster_pose_.rotation() &&
      T_camera_model.translation() == raster_pose_.translation())
    return;
  raster_.render(T_camera_model, K_);
  raster_pose_ = T_camera_model;
  raster_valid_ = true;
}

// ---- facade ----

Tracker::Tracker() = default;
Tracker::~Tracker() { delete impl_; }

Status Tracker::configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                          const SE3& T_camera_model_init) {
  delete impl_;
  impl_ = new TrackerImpl();
  Status s = impl_->configure(config, mesh, camera, T_camera_model_init);
  if (!s.ok()) {
    delete impl_;
    impl_ = nullptr;
  }
  return s;
}

void Tracker::set_ba_channel(BaChannel* channel) {
  if (impl_) impl_->set_ba_channel(channel);
}

void Tracker::start() {
  if (impl_) impl_->start();
}

TrackResult Tracker::step(GrayView luma, int frame_index, ChromaView chroma) {
  if (!impl_) return TrackResult{};
  return impl_->step(luma, frame_index, chroma);
}

void Tracker::stop() {
  if (impl_) impl_->stop();
}

int Tracker::raster_triangles() const { return impl_ ? impl_->raster_triangles() : 0; }
CalibrationCheck Tracker::calibration_check() const { return impl_ ? impl_->calibration_check() : CalibrationCheck{}; }
CameraModel Tracker::working_camera() const { return impl_ ? impl_->working_camera() : CameraModel{}; }

int Tracker::map_points(Vec3* p_model, int capacity) const {
  if (!impl_) return 0;
  const TrackingMap& m = impl_->map();
  int n = 0;
  for (int id = 0; id < m.point_high_water() && n < capacity; ++id)
    if (m.point(id).alive) p_model[n++] = m.point(id).p_model;
  return n;
}

}  // namespace st
