// Robust absolute pose without a prior (relocalisation, initialisation
// checks): RANSAC over the P3P solver with a 4th point choosing among P3P's
// solutions, hypotheses ranked by inlier count, the adaptive stopping rule
// (confidence that one all-inlier 4-sample was drawn), then the PoseSolver
// LM on the best hypothesis' inliers.
//
// Inliers: information * |r|^2 < inlier_threshold_px^2, i.e. |r| below the
// threshold scaled by the observation's octave sigma (1.2^octave).
//
// Deterministic: the sampler (PCG32) is reseeded from options.seed at every
// solve(), so equal input gives an equal result. All buffers are sized in
// configure(); solve() allocates nothing and throws nothing.
// Threading: one PnpRansac per thread.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/geometry/camera.h"
#include "core/pose/correspondences.h"
#include "core/pose/pose_solver.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

enum class PnpRansacStatus : std::uint8_t {
  kOk,             // pose written (see summary.refined for the LM outcome)
  kNotConfigured,  // configure() not called or failed
  kTooManyPoints,  // count above the configured capacity
  kTooFewPoints,   // fewer valid correspondences than max(4, min_inliers)
  kInvalidCamera,  // fx, fy <= 0 or not finite
  kNoConsensus,    // no hypothesis reached min_inliers within max_iterations
};
const char* to_string(PnpRansacStatus s);

struct PnpRansacOptions {
  double inlier_threshold_px = 2.447651936;  // at octave 0; sqrt(5.991), ORB-SLAM's test
  double confidence = 0.99;                  // adaptive stop: P(an all-inlier sample was drawn)
  int max_iterations = 1000;                 // hard bound on samples (each gives <= 4 hypotheses)
  int min_iterations = 1;
  int min_inliers = 12;  // below: kNoConsensus
  double min_depth_mm = 0.1;
  std::uint64_t seed = 0x5eed;
  bool refine = true;     // run the PoseSolver on the best hypothesis' inliers
  int refine_passes = 3;  // LM + re-classification of all points, until the set is stable
  PoseSolverOptions refine_options;
};

struct PnpRansacSummary {
  PnpRansacStatus status = PnpRansacStatus::kNotConfigured;
  int num_valid = 0;           // finite input with positive information
  int iterations = 0;          // samples drawn
  int hypotheses = 0;          // P3P poses that passed the 4th-point check and were scored
  int hypothesis_inliers = 0;  // inliers of the best hypothesis
  int best_iteration = -1;     // sample (0-based) that produced the best hypothesis
  int num_inliers = 0;         // inliers of the returned pose
  bool refined = false;        // the returned pose is the LM refinement
  PoseSolverSummary refine;    // the LM's summary (when refine was attempted)
};

class PnpRansac {
 public:
  using Options = PnpRansacOptions;
  using Summary = PnpRansacSummary;

  // Sizes every buffer (allocates), including the refining PoseSolver.
  // max_correspondences in [4, kMaxKeypoints].
  Status configure(int max_correspondences, const Options& opt = {});

  // Estimates *T_camera_model from the correspondences alone (its input
  // value is ignored). Writes it only when status is kOk. No allocation.
  // Returns summary.status == kOk.
  bool solve(const Correspondences& c, const Pinhole& K, SE3* T_camera_model, Summary* summary);

  // Inlier flags (1 = inlier) of the returned pose, one per correspondence.
  std::span<const std::uint8_t> inliers() const {
    return {inlier_.data(), static_cast<std::size_t>(last_count_)};
  }
  const Options& options() const { return options_; }
  int capacity() const { return static_cast<int>(inlier_.size()); }

 private:
  int prepare(const Correspondences& c, const Pinhole& K);
  bool hypothesis(const Correspondences& c, const Pinhole& K, const int sample[4], SE3* T) const;
  int score(const Correspondences& c, const Pinhole& K, const SE3& T, int to_beat) const;
  int classify(const Correspondences& c, const Pinhole& K, const SE3& T);
  bool sample_and_score(const Correspondences& c, const Pinhole& K, SE3* best, Summary* s);
  bool refine_once(const Correspondences& c, const Pinhole& K, SE3* T, Summary* s);
  bool refine(const Correspondences& c, const Pinhole& K, SE3* T, Summary* s);

  Options options_;
  double threshold2_ = 0;                      // inlier_threshold_px^2
  std::vector<Vec3> bearing_;                  // unnormalised rays of the observations
  std::vector<int> valid_index_;               // indices of valid correspondences
  std::vector<std::uint8_t> inlier_;           // result flags
  std::vector<std::uint8_t> previous_inlier_;  // refine: set of the previous pass
  std::vector<Vec3> in_p_model_;               // compacted inliers for the LM
  std::vector<Vec2> in_px_;
  std::vector<double> in_info_;
  PoseSolver solver_;
  int num_valid_ = 0, last_count_ = 0;
  bool configured_ = false;
};

}  // namespace st
