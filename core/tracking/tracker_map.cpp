// Map building: initialisation from one frame and the mesh depth, keyframe
// decision and insertion (new points from the mesh depth at the tracked
// pose), usage counters for culling. Tracking thread; allocates nothing.
#include <algorithm>
#include <cmath>

#include "core/tracking/tracker_impl.h"

namespace st {

namespace {
Vec3 centre_of(const SE3& T_camera_model) { return -(T_camera_model.rotation().transpose() * T_camera_model.translation()); }
}  // namespace

// Frame 0: the pose is given (T_camera_model_init); every keypoint on the
// rendered organ with a clean depth becomes a metric map point. No parallax
// is needed: the depth comes from the registered mesh.
TrackResult TrackerImpl::initialise(GrayView luma, int frame_index) {
  TrackResult r;
  double t = now_ms();
  render_at(T_init_);
  lap(Stage::kRaster, &t, &r);
  // The filter for the whole run, from the organ at the registered pose.
  bool denoise = config_.features.denoise;
  if (!denoise && config_.denoise_noise_ratio > 0) {
    r.noise_ratio = FastThresholdScaler::organ_noise_ratio(luma, config_.use_mask ? raster_.mask() : GrayView{},
                                                           valid_view_);
    denoise = r.noise_ratio >= config_.denoise_noise_ratio;
  }
  orb_.set_denoise(denoise);
  r.denoise = denoise;
  extract(luma, true, &r);
  lap(Stage::kDetect, &t, &r);
  map_.clear();
  ref_keyframe_ = -1;
  const int kf = add_keyframe(T_init_, frame_index, false);
  ba_.map_initialised(map_, kf);
  lap(Stage::kMap, &t, &r);
  initialised_ = true;
  lost_ = false;
  T_last_ = T_init_;
  velocity_ = SE3();
  if (config_.use_image_motion) {  // the registered pose: dead reckoning's and confirmation's first reference
    aligner_.keep_reference(orb_.pyramid().level(align_level_), valid_view_, T_init_);
    anchor_.keep_reference(orb_.pyramid().level(align_level_), valid_view_, T_init_);
    if (config_.use_contour) shading_ref_.keep_reference(orb_.pyramid().level(align_level_), valid_view_, T_init_);
  }
  learn_colours(T_init_, 1.0f, true);  // the registered pose: the outline's first colour models
  r.state = TrackState::kInitialised;
  r.pose_valid = true;
  r.T_camera_model = T_init_;
  r.keyframe = kf >= 0;
  return r;
}

// The model point seen at an ideal pixel, from the raster (which must hold
// the render at the pose of interest): only where the pixel and its 4
// neighbours are organ at one surface (no depth discontinuity).
bool TrackerImpl::surface_point(const Vec2& px_ideal, Vec3* p_model) const {
  const Vec2 rp = raster_.full_to_raster(px_ideal);
  const int x = static_cast<int>(std::lround(rp.x())), y = static_cast<int>(std::lround(rp.y()));
  const ImageView<const float> depth = raster_.depth();
  if (x < 1 || y < 1 || x >= depth.width - 1 || y >= depth.height - 1) return false;
  const float d0 = depth(x, y);
  if (!(d0 > 0.f)) return false;
  const float tol = static_cast<float>(MeshRasterizer::kSameSurfaceRelDepth) * d0;
  const float n[4] = {depth(x - 1, y), depth(x + 1, y), depth(x, y - 1), depth(x, y + 1)};
  for (float d : n)
    if (!(d > 0.f) || std::abs(d - d0) > tol) return false;
  float d = 0.f;
  if (!raster_.depth_at(rp, &d)) return false;
  *p_model = raster_.model_point(rp, static_cast<double>(d));
  return p_model->allFinite();
}

// Inserts a keyframe at T_camera_model: links to this frame's inliers (when
// tracking) and new map points, from the mesh depth at exactly this pose,
// for the keypoints that matched nothing, marked anchored or not
// (MapPoint::anchored). With refresh_descriptors, each linked inlier's
// reference observation (descriptor, angle, octave, distance, viewing
// direction) becomes this keyframe's: the tissue's appearance changes
// with the view (the light rides on the scope, an instrument turns the
// organ), and a point still matched by the descriptor it was made with
// loses more and more often to a look-alike corner nearby. Returns the
// keyframe id or -1.
int TrackerImpl::add_keyframe(const SE3& T_camera_model, int frame_index, bool link_inliers, bool anchored) {
  const int kf = map_.add_keyframe(T_camera_model, frame_index, ref_keyframe_);
  if (kf < 0) return -1;
  render_at(T_camera_model);  // (a no-op when the last render was at this pose)
  const FeatureSet& f = *features_;
  const auto link_of = [&](int k, int point) {
    const Keypoint& kp = f.keypoints[static_cast<std::size_t>(k)];
    KeyframeLink l;
    l.point = point;
    l.point_created_frame = map_.point(point).created_frame;
    l.x = kp.x;
    l.y = kp.y;
    l.x_ideal = static_cast<float>(kp_ideal_[static_cast<std::size_t>(k)].x());
    l.y_ideal = static_cast<float>(kp_ideal_[static_cast<std::size_t>(k)].y());
    l.angle_deg = kp.angle_deg;
    l.octave = static_cast<std::int16_t>(kp.octave);
    return l;
  };
  const Vec3 centre = centre_of(T_camera_model);
  // The reference observation of a point: the one its descriptor came from.
  const auto set_reference = [&](int k, MapPoint* p) {
    const Keypoint& kp = f.keypoints[static_cast<std::size_t>(k)];
    const Vec3 ray = p->p_model - centre;
    p->ref_distance_mm = static_cast<float>(ray.norm());
    p->view_dir_model = ray.normalized();
    p->descriptor = f.descriptors[static_cast<std::size_t>(k)];
    p->ref_angle_deg = kp.angle_deg;
    p->ref_octave = static_cast<std::int16_t>(kp.octave);
  };
  if (link_inliers)
    for (int i = 0; i < corr_count_; ++i) {
      const auto is = static_cast<std::size_t>(i);
      if (!corr_inlier_[is]) continue;
      map_.add_link(kf, link_of(corr_kp_[is], corr_point_[is]));
      if (config_.refresh_descriptors) set_reference(corr_kp_[is], &map_.point(corr_point_[is]));
    }
  for (int k = 0; k < f.count; ++k) {
    if (kp_inlier_[static_cast<std::size_t>(k)] != 0) continue;  // matched (inlier or outlier)
    MapPoint p;
    if (!surface_point(kp_ideal_[static_cast<std::size_t>(k)], &p.p_model)) continue;
    set_reference(k, &p);
    p.visible = p.found = 1;
    p.last_seen_frame = p.created_frame = frame_index;
    p.anchored = anchored;
    const int id = map_.add_point(p, frame_index);
    if (id < 0) break;
    if (!map_.add_link(kf, link_of(k, id))) break;
  }
  // The reference count is taken at the next tracked frame, once the new
  // points had a chance to be matched (see need_keyframe()).
  map_.keyframe(kf).tracked_at_insertion = -1;
  ref_keyframe_ = kf;
  T_last_keyframe_ = T_camera_model;
  return kf;
}

bool TrackerImpl::need_keyframe(const PoseEstimate& e) {
  if (ref_keyframe_ < 0 || !map_.keyframe(ref_keyframe_).alive) return true;
  Keyframe& ref = map_.keyframe(ref_keyframe_);
  if (ref.tracked_at_insertion < 0) {
    ref.tracked_at_insertion = e.inliers;
    return false;
  }
  if (e.inliers < config_.keyframe_tracked_ratio * ref.tracked_at_insertion) return true;
  const PoseDelta d = pose_delta(T_last_keyframe_, e.T_camera_model);
  if (d.angle_deg > config_.keyframe_angle_deg) return true;
  const double travel = (centre_of(T_last_keyframe_) - centre_of(e.T_camera_model)).norm();
  return travel > config_.keyframe_distance_ratio * e.mean_depth_mm;
}

// Points of the local map at the final pose were visible; inliers were found.
void TrackerImpl::update_counters(int frame_index) {
  for (int i = 0; i < local_map_.size(); ++i) ++map_.point(local_map_.point_id(i)).visible;
  for (int i = 0; i < corr_count_; ++i) {
    if (!corr_inlier_[static_cast<std::size_t>(i)]) continue;
    MapPoint& p = map_.point(corr_point_[static_cast<std::size_t>(i)]);
    ++p.found;
    p.last_seen_frame = frame_index;
  }
}

}  // namespace st
