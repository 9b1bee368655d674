// Semi-automatic registration of the first frame (the paper's Eq. 1): a
// person picks a few 2D-3D pairs (a pixel of frame 0, the same anatomical
// point on the pre-operative mesh, in mm) and the tool finds
//   T_camera_model_init = argmin_T sum_i rho(|pi(T f_i) - q_i|)
// with rho a truncated square (a mispicked pair costs a constant, so it
// cannot pull the pose). The paper reaches the global optimum by branch and
// bound; with the handful of pairs a person picks, every minimal subset can
// be tried instead: P3P on each triple (up to 4 poses), scored on all
// pairs, the best refined by LM with Huber loss (core/pose/pose_solver.h). The
// search is exhaustive over the triples, so it does not depend on a
// starting pose.
//
// Host tool library (tests use it); allocates freely.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/geometry/camera.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct RegistrationPair {
  Vec2 px = Vec2::Zero();        // picked pixel of frame 0, distorted (as in the video)
  Vec3 p_model = Vec3::Zero();   // the same point on the mesh, model frame, mm
  int line = 0;                  // line of the pairs file (for messages)
};

inline constexpr int kMinRegistrationPairs = 4;
inline constexpr int kMaxRegistrationPairs = 200;

// Pairs file: one pair per line, "u v x y z" (pixel, then model point in
// mm), whitespace separated; '#' starts a comment; blank lines are skipped.
// Errors name the line: a missing or extra field, a token that is not a
// finite number, more than kMaxRegistrationPairs pairs, a NUL byte.
Result<std::vector<RegistrationPair>> parse_registration_pairs(std::string_view text);

struct RegistrationOptions {
  double inlier_px = 8.0;  // a pair further than this from its pick at the solution is an outlier
};

struct RegistrationResult {
  SE3 T_camera_model;                // model -> camera of frame 0
  std::vector<double> residual_px;   // per pair: |projection - pick|, distorted pixels
  std::vector<bool> inlier;          // per pair: residual_px <= inlier_px
  int inliers = 0;
  double rms_px = 0;                 // over the inliers
  long long triples = 0;             // minimal subsets tried
  long long hypotheses = 0;          // P3P poses scored
  bool refined = false;              // the LM refinement converged and was kept
};

// Exhaustive P3P over the triples of pairs, then LM on the inliers.
// Errors: fewer than kMinRegistrationPairs pairs, a pick outside the image
// or one that does not undistort, fewer than kMinRegistrationPairs inliers
// at the best pose (the picks do not agree on any pose), a bad camera.
Result<RegistrationResult> register_first_frame(const std::vector<RegistrationPair>& pairs,
                                                const CameraModel& camera,
                                                const RegistrationOptions& options = {});

}  // namespace st
