// BaJob: one bundle-adjustment problem as a self-contained snapshot of part
// of the map (keyframe poses, the points they observe, the observations),
// solved in place by BundleAdjuster (core/mapping/bundle_adjustment.h).
//
// The tracking thread fills a job from its map and hands it over; the
// mapping thread solves it; the tracking thread applies the result to the
// map at the start of a frame. Ids and stamps (keyframe frame, point
// created_frame) let the applier skip entries whose slot was reused in the
// meantime. Every array is sized once in configure() (allocates); filling
// and clearing allocate nothing.
#pragma once

#include <cstdint>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

// Pose parameter block: T_camera_model as [qx qy qz qw tx ty tz] (Eigen's
// quaternion coefficient order, then the translation in mm).
inline constexpr int kPoseParams = 7;
void pose_to_params(const SE3& T_camera_model, double* params);
SE3 pose_from_params(const double* params);

struct BaKeyframe {
  std::int32_t id = -1;     // map keyframe slot
  std::int32_t frame = -1;  // stamp: the slot still holds this keyframe
  bool fixed = false;       // observes window points but is held constant
  double pose[kPoseParams] = {0, 0, 0, 1, 0, 0, 0};
};

struct BaPoint {
  std::int32_t id = -1;             // map point slot
  std::int32_t created_frame = -1;  // stamp
  double p_model[3] = {0, 0, 0};    // solved in place, mm
  double p_initial[3] = {0, 0, 0};  // as handed over
};

struct BaObservation {
  std::int32_t keyframe = -1;  // index into BaJob::keyframes
  std::int32_t point = -1;     // index into BaJob::points
  double x_ideal = 0, y_ideal = 0;  // undistorted level-0 pixel
  double info = 1;                  // 1 / sigma^2 of the keypoint's octave
};

// kFocalTest: the calibration's focal test alone on the job as given
// (BundleAdjuster::solve(); BaJob::test_focal on a window job runs it after
// the window's solve instead); its solution is not the map's.
enum class BaKind : std::uint8_t { kWindow, kGlobal, kFocalTest };

// A Gaussian prior on one keyframe's pose: the registration of the first
// frame (T_camera_model_init, "the coarse registration" of
// sequence-format.md) with its uncertainty, per axis, as a rotation (rad)
// and a translation (mm) of the camera frame. With a prior, BundleAdjuster
// holds no keyframe for the gauge: the mesh (shape residual) and the prior
// fix the frame, and every pose, the first one too, moves to agree with the
// observations (core/mapping/bundle_adjustment.h).
struct BaPosePrior {
  std::int32_t keyframe = -1;  // index into BaJob::keyframes; -1: no prior
  double pose[kPoseParams] = {0, 0, 0, 1, 0, 0, 0};
  double sigma_rad = 0, sigma_mm = 0;
};
// Both sigmas finite and > 0 (BaJob::set_prior and BundleAdjuster's job check).
bool pose_prior_sigmas_usable(double sigma_rad, double sigma_mm);

// Why BundleAdjuster::solve refused a job before solving (BaSummary::refusal).
enum class BaRefusal : std::uint8_t {
  kNone,           // not refused
  kNotConfigured,  // the adjuster has not been configured
  kEmpty,          // no keyframe or no point
  kTooBig,         // more keyframes, points or observations than the adjuster was configured for
  kBadIndex,       // an observation's keyframe or point index out of range
  kNotFinite,      // a NaN or infinite pose, point, pixel or information
  kBadPrior,       // the pose prior's keyframe, pose or sigmas are not usable
  kNothingToSolve, // no observation passes the caps and the depth test
};
// One line an engineer can act on (static text: allocates nothing).
const char* ba_refusal_text(BaRefusal refusal);

struct BaSummary {
  bool usable = false;         // solved, finite: the tracker may apply it
  BaRefusal refusal = BaRefusal::kNone;
  int keyframes = 0, fixed_keyframes = 0, points = 0, observations = 0;
  int fixed_observations = 0;  // of observations: from fixed keyframes
  int plane_queries = 0;       // closest-point queries for tangent planes (the rest reused)
  int points_skipped = 0;      // observed, but fewer times than min_observations_per_point: left unchanged
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  double solver_ms = 0;        // the solver's own measure of the solve (0 without a clock)
  int points_rejected = 0;     // moved farther than the options allow: not applied
  bool prior_tested = false;   // the job's prior was tested (see BundleAdjusterOptions)
  bool prior_used = false;     // ... and the freed solution kept (the prior's keyframe moved)
  double prior_f = 0;          // the test's F statistic
  bool focal_tested = false;   // the job's focal test ran (BaJob::test_focal)
  double focal_scale = 1;      // the focal lengths' scale the data fits best (1: the calibration's)
  double focal_f = 0;          // F of that fit against the calibration's focal lengths (1 dof)
  double mean_surface_distance_mm = -1;  // of the points after the solve (when a mesh was given)
};

struct BaJob {
  BaKind kind = BaKind::kWindow;
  std::uint32_t version = 0;  // set by the submitter, echoed in the result
  std::vector<BaKeyframe> keyframes;
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
  int keyframe_count = 0, point_count = 0, observation_count = 0;
  BaPosePrior prior;  // cleared by clear()
  // Also test the calibration's focal length (BundleAdjuster::solve);
  // cleared by clear().
  bool test_focal = false;
  BaSummary summary;

  // Sizes the arrays (allocates). Each maximum >= 1.
  Status configure(int max_keyframes, int max_points, int max_observations);
  void clear();
  int keyframe_capacity() const { return static_cast<int>(keyframes.size()); }
  int point_capacity() const { return static_cast<int>(points.size()); }
  int observation_capacity() const { return static_cast<int>(observations.size()); }
  // Appends; -1 when full. Allocate nothing.
  int add_keyframe(int id, int frame, const SE3& T_camera_model, bool fixed);
  int add_point(int id, int created_frame, const Vec3& p_model);
  bool add_observation(int keyframe_index, int point_index, const Vec2& px_ideal, double info);
  // Puts a prior on keyframe keyframe_index (already added); false when the
  // index, pose or sigmas are not usable (sigmas must be finite and > 0).
  bool set_prior(int keyframe_index, const SE3& T_camera_model, double sigma_rad, double sigma_mm);
  Vec3 point(int i) const;
  SE3 pose(int i) const { return pose_from_params(keyframes[static_cast<std::size_t>(i)].pose); }
};

}  // namespace st
