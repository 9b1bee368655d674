// TrackerImpl: the per-frame sequence behind core/tracking/tracker.h, the
// paper's: the valid and occluder masks, the mesh rendered at the predicted
// pose, features inside it, the local map searched by projection, a robust
// pose judged by the quality gates (or confirmed by direct alignment), a
// keyframe with mesh-depth points, and when lost dead reckoning and
// relocalisation; bundle adjustment handed out and applied. It composes
// the parts that hold their own state and tests: LocalMapSearch,
// KeyframeRelocaliser, PoseGates, FastThresholdScaler, BaHandoff. Internal
// header (core/tracking only). Every buffer is sized in configure(); the
// stage functions (tracker_track.cpp, tracker_map.cpp, tracker_reloc.cpp)
// allocate nothing. Thread: the tracking thread.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/mapping/ba_channel.h"
#include "core/geometry/camera.h"
#include "core/contour/outline_search.h"
#include "core/contour/region_modality.h"
#include "core/base/capacity.h"
#include "core/motion/direct_alignment.h"
#include "core/features/feature_grid.h"
#include "core/features/feature_set.h"
#include "core/motion/image_motion.h"
#include "core/mapping/map.h"
#include "core/image/area_scale.h"
#include "core/image/occluder_mask.h"
#include "core/features/orb_extractor.h"
#include "core/features/orb_matcher.h"
#include "core/pose/pnp_ransac.h"
#include "core/pose/pose_solver.h"
#include "core/raster/rasterizer.h"
#include "core/tracking/ba_handoff.h"
#include "core/tracking/fast_threshold_scaler.h"
#include "core/tracking/keyframe_relocaliser.h"
#include "core/tracking/local_map_search.h"
#include "core/tracking/pose_gates.h"
#include "core/tracking/tracker.h"
#include "core/image/valid_mask.h"

namespace st {

class TrackerImpl {
 public:
  Status configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                   const SE3& T_camera_model_init);
  void start();
  void stop() { started_ = false; }
  TrackResult step(GrayView luma, int frame_index, ChromaView chroma);
  const TrackingMap& map() const { return map_; }
  int raster_triangles() const { return raster_.triangle_count(); }
  const CalibrationCheck& calibration_check() const { return ba_.calibration(); }
  const CameraModel& working_camera() const { return camera_; }
  void set_ba_channel(BaChannel* channel) { ba_.set_channel(channel); }

 private:
  // Stages (tracker_track.cpp).
  bool extract(GrayView luma, bool with_organ_mask, TrackResult* r);
  bool weak_first_pass(bool solved, const PoseEstimate& e) const;
  double image_shift_px(const SE3& a, const SE3& b) const;
  double view_difference_px(const SE3& a, const SE3& b) const;
  double view_sigma_px(const Mat6& cov, const SE3& T) const;
  double information_sigma_px(const Mat6& H, const SE3& T) const;
  SE3 motion_prior(GrayView luma, const SE3& T_reference, const SE3& T_predicted);
  bool dead_reckon(SE3* T_camera_model, const SE3& T_alternative, DirectAlignSummary* fit = nullptr);
  bool track_by_outline(const SE3& T_guess, PoseEstimate* e, TrackResult* r);
  bool outline_placed(const TrackResult& r) const;
  bool outline_is_a_guess(const TrackResult& r) const;
  static constexpr int kSearchTried = 4;  // outline search candidates kept per lost frame
  static constexpr int kSearchFits = 2;   // of them fitted and tracked per lost frame (the best, one other in turn)
  int search_round_ = 0;
  int search_outline(TrackResult* r, SE3* fits);
  void relocalise_by_search(int frame_index, TrackResult* r);
  bool outline_refutes(const PoseEstimate& e, TrackResult* r);
  double outline_sigma_px(const SE3& T, const ContourFit& fit, Mat6* H_out = nullptr) const;
  void learn_colours(const SE3& T, float rate, bool force = false);
  int match_local_map(float radius_px);
  bool solve_pose(SE3* T_camera_model, PoseEstimate* e);
  bool track_from(const SE3& T_predicted, float first_radius_px, PoseEstimate* e, TrackResult* r);
  void measure_final(PoseEstimate* e);
  double anchored_share() const;
  double anchor_agreement_px(const SE3& T_guess, const SE3& T_features);
  TrackResult track(GrayView luma, int frame_index);
  void accept(const PoseEstimate& e, int frame_index, TrackState state, TrackResult* r);
  void fill_measures(const PoseEstimate& e, TrackResult* r) const;
  // Map (tracker_map.cpp).
  TrackResult initialise(GrayView luma, int frame_index);
  bool surface_point(const Vec2& px_ideal, Vec3* p_model) const;
  int add_keyframe(const SE3& T_camera_model, int frame_index, bool link_inliers, bool anchored = true);
  bool need_keyframe(const PoseEstimate& e);
  void update_counters(int frame_index);
  // Relocalisation (tracker_reloc.cpp).
  TrackResult relocalise(GrayView luma, int frame_index);
  bool reloc_with_keyframe(int keyframe_id, PoseEstimate* e, TrackResult* r);
  bool track_from_guess(const SE3& T_guess, PoseEstimate* e, TrackResult* r);
  void report_relocalised(const PoseEstimate& e, int frame_index, int strict_frames, TrackResult* r);
  void render_at(const SE3& T_camera_model);
  int remove_occluders_from_valid(GrayView luma, ChromaView chroma, bool* refused);
  double now_ms() const;
  void lap(Stage s, double* t_last_ms, TrackResult* r) const;

  TrackerConfig config_;  // at the working resolution (TrackerConfig::working_width)
  CameraModel camera_;    // likewise
  // The frame as it comes (the calibration's size) and its way to the
  // working resolution, when that is smaller.
  int input_width_ = 0, input_height_ = 0;
  double input_px_per_working_px_ = 1.0;
  bool scaling_ = false;
  FrameScaler scaler_;
  Image<std::uint8_t> work_y_, work_u_, work_v_;
  Pinhole K_;
  bool distorted_ = false;
  SE3 T_init_;
  MeshRasterizer raster_;
  bool raster_valid_ = false;  // raster_ holds a render at raster_pose_
  SE3 raster_pose_;
  ValidMaskBuilder valid_mask_;
  OccluderMaskBuilder occluder_;  // near-neutral pixels (instruments) from chroma, at 1/2 like valid_mask_
  std::vector<std::uint8_t> valid_without_occluders_;  // the valid mask minus the occluders (when any)
  // More of the organ's last render than this flagged: the organ's own
  // colour, not an instrument; the mask is not used that frame.
  static constexpr double kMaxOccludedOrganShare = 0.5;
  GrayView valid_view_;           // this frame's valid mask: valid_mask_'s, or valid_without_occluders_
  GrayView valid_scene_;          // valid_mask_'s, occluders kept: the whole-view motion prior's mask
  OrbExtractor orb_;
  OrbMatcher matcher_;
  FeatureGrid grid_;
  ImageMotion motion_;  // whole-view shift between frames: rotation prior under fast turns
  DirectAlignScratch align_scratch_;  // the three aligners' current-image planes (used one at a time)
  DirectAligner aligner_;  // while lost: the camera's motion from the images and the mesh depth
  DirectAligner anchor_;   // the last frame that passed the normal gates: confirms weak poses
  DirectAligner shading_ref_;  // the last reported frame: the shading's measurement without features
  int align_level_ = 0;    // the ORB pyramid level it works on (about 320 pixels wide)
  RegionModality region_;  // the organ's outline: smooth tissue without features
  OutlineSearch outline_search_;  // the organ's silhouette from every side, when lost
  static constexpr int kLearnEvery = 4;
  int frames_since_learn_ = 0;
  GrayView luma_;          // this frame's, for the stages that need it after step()
  ChromaView chroma_;
  PoseSolver solver_;
  PnpRansac ransac_;
  TrackingMap map_;
  std::unique_ptr<FeatureSet> features_;

  // Per frame, sized in configure().
  std::vector<Vec2> kp_ideal_;            // undistorted keypoints
  std::vector<std::uint8_t> kp_inlier_;   // keypoint is a pose inlier this frame
  std::vector<Vec3> corr_p_;
  std::vector<Vec2> corr_px_;
  std::vector<double> corr_info_;
  std::vector<std::int32_t> corr_point_, corr_kp_;
  std::vector<std::uint8_t> corr_inlier_;
  std::vector<double> octave_info_;       // per octave: 1 / sigma^2
  int corr_count_ = 0;

  // Tracking state.
  bool started_ = false, initialised_ = false, lost_ = false;
  SE3 T_last_, velocity_;        // velocity_: T_last * T_previous^-1 (left increment per frame)
  int lost_frames_ = 0;
  int strict_frames_left_ = 0;
  int ref_keyframe_ = -1;
  SE3 T_last_keyframe_;

  // The parts: bundle-adjustment hand-off with the calibration test, the
  // quality gates, the FAST threshold scaling, the local map's search, the
  // relocaliser's keyframe candidates.
  BaHandoff ba_;
  PoseGates gates_;
  FastThresholdScaler fast_scaler_;
  LocalMapSearch local_map_;
  KeyframeRelocaliser reloc_keyframes_;
  int last_inliers_ = 0;            // inliers of the last accepted frame
  double last_depth_mm_ = 100.0;    // mean inlier depth of the last accepted frame
  SE3 lost_velocity_, T_dead_reckoned_;  // while lost: the last velocity, carried forward
  // While lost: how far the view moved since the last frame (level-0 px) by
  // dead reckoning, kUnknownMotion where it could not be measured.
  static constexpr double kUnknownMotion = 1e9;
  double lost_motion_px_ = kUnknownMotion;
  bool reloc_seed_ok_ = false;  // the relocalised frame's pose may seed a keyframe
};

}  // namespace st
