// Bounded bundle adjustment of a BaJob (core/mapping/ba_job.h): robust
// reprojection residuals (Huber on octave-whitened pixels) for every
// observation, plus the paper's shape residual w_shape * rho(|f - D(f)|)
// (Huber in mm) for every point, D from ClosestPointIndex (as a tangent
// plane taken at the start value, reused across solves while the point
// stays put). Points seen fewer than twice are left out (no pose
// information). Keyframe poses are 6-dim left deltas around the handed-over
// pose (core/mapping/ba_residuals.h); keyframes flagged fixed are held constant
// (when a job has none, the oldest keyframe is fixed to remove the gauge
// freedom left when w_shape = 0): a held pose is no parameter, its
// residuals take the point alone. A job may put a prior on one keyframe's
// pose (the tracker: the registration of frame 0); that keyframe is then
// freed only where the data says the prior is off (prior_release_f).
// Single-threaded, bounded iterations and solver time, and a stop once the
// gradient has fallen to a fraction of its start.
//
// The solver: core/mapping/schur_solver.h, every workspace sized in
// configure(); solve() allocates nothing. The Ceres form of the same
// problem, the reference for tests and the bench, is a BaReferenceSolver
// in core/mapping_ceres/ceres_form.h, outside the product's link.
// Thread: the mapping thread (one BundleAdjuster per thread; the
// closest-point index is read-only).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/mapping/ba_job.h"
#include "core/mapping/ba_options.h"
#include "core/mapping/ba_residuals.h"
#include "core/mapping/schur_solver.h"
#include "core/geometry/camera.h"
#include "core/mesh/closest_point.h"
#include "core/mesh/mesh.h"
#include "core/base/result.h"

namespace st {

class BundleAdjuster;

// Another solver of what BundleAdjuster::select() chose for a solve, used
// instead of the Schur solver (BundleAdjuster::use_reference): the Ceres
// form (core/mapping_ceres/ceres_form.h) that tests and the bench compare
// against. It writes the solution where the Schur form does (the job's
// points, the adjuster's pose deltas and focal scale).
class BaReferenceSolver {
 public:
  struct Run {
    double initial_cost = 0, final_cost = 0, total_s = 0;
    int iterations = 0;
    bool usable = false;
    int residuals = 0, parameters = 0;  // scalar residuals and effective parameters
  };
  virtual ~BaReferenceSolver() = default;
  virtual Run run(BundleAdjuster& ba, BaJob* job, int max_iterations, double max_time_s) = 0;
};

class BundleAdjuster {
 public:
  BundleAdjuster();
  ~BundleAdjuster();
  BundleAdjuster(const BundleAdjuster&) = delete;
  BundleAdjuster& operator=(const BundleAdjuster&) = delete;

  // Builds the closest-point index of the mesh and the solver's workspace
  // for jobs of up to max_keyframes / max_points / max_observations
  // (allocates).
  Status configure(const BundleAdjusterOptions& options, const Mesh& mesh, const Pinhole& K, int max_keyframes,
                   int max_points, int max_observations);
  // Solves the job in place with iteration and time limits (overriding the
  // options' when > 0) and fills job->summary. False (summary.usable false)
  // on a refused job (summary.refusal says why) or a failed solve: the
  // job's values are then not to be applied. A BaKind::kFocalTest job runs
  // the focal test alone (usable: the test ran; the job's values come back
  // as given). The Schur solver allocates nothing here.
  bool solve(BaJob* job, int max_iterations = 0, double max_time_s = 0);
  // Why solve() would refuse the job (BaRefusal::kNone: it would not).
  BaRefusal check(const BaJob& job) const;

  // Drops the tangent planes kept from earlier solves (the bench: every
  // solve pays its closest-point queries).
  void forget_planes();
  // Solves with solver instead of the Schur solver until the next
  // configure() (tests, the bench: core/mapping_ceres/ceres_form.h).
  void use_reference(std::unique_ptr<BaReferenceSolver> solver);

  const ClosestPointIndex& surface() const { return surface_; }
  const BundleAdjusterOptions& options() const { return options_; }
  // Mean distance of the job's points to the mesh (mm) over at most
  // max_samples evenly spaced points (0: all); -1 for no points.
  double mean_surface_distance(const BaJob& job, int max_samples = 0) const;

 private:
  friend class CeresForm;  // core/mapping_ceres: reads the selection, writes the solution
  struct SolveStats {
    int residuals = 0, parameters = 0;  // scalar residuals and effective parameters
  };
  using SolverRun = BaReferenceSolver::Run;  // what one solver run reports
  bool solve_tested_prior(BaJob* job, int max_iterations, double max_time_s);
  void test_focal(BaJob* job, int max_iterations, double max_time_s);
  // The focal test's solves (test_focal): no keyframe held and no prior,
  // the focal lengths held (kHeld) or scaled by one more parameter (kFree).
  enum class FocalTest { kNone, kHeld, kFree };
  bool solve_once(BaJob* job, bool free_prior, int max_iterations, double max_time_s,
                  SolveStats* stats, FocalTest focal = FocalTest::kNone);
  void save_solution(const BaJob& job);
  void restore_solution(BaJob* job) const;
  int select(BaJob* job, bool free_prior, FocalTest focal);
  SolverRun run_schur(BaJob* job, int max_iterations, double max_time_s);
  bool load_schur(const BaJob& job);
  void newest_frames_per_point(const BaJob& job, int cap, bool fixed_only, std::vector<std::int32_t>* rows) const;
  bool keep_observation(const BaJob& job, const BaObservation& o) const;
  bool usable_observation(const BaJob& job, const BaObservation& o) const;
  void select_points(BaJob* job);
  void select_shapes(BaJob* job);
  double* pose_delta_block(int keyframe);  // the 6-dim pose delta of a job keyframe
  void apply_pose_deltas(BaJob* job);
  void finish(BaJob* job, double initial_cost, double final_cost, double total_s, int iterations, bool usable);

  BundleAdjusterOptions options_;
  Pinhole K_;
  ClosestPointIndex surface_;
  std::unique_ptr<BaReferenceSolver> reference_;  // tests and the bench: solves instead of schur_
  SchurSolver schur_;                             // configured for the maxima
  std::vector<SE3> T0_;          // per job keyframe: the handed-over pose of this solve
  std::vector<double> deltas_;   // 6 per job keyframe: the solved left deltas
  std::vector<std::uint8_t> observation_used_;  // per job observation: in this solve
  std::vector<std::uint8_t> shape_used_;        // per job point: has a shape residual in this solve
  bool use_prior_ = false;                     // this solve: the prior residual is on
  FocalTest focal_ = FocalTest::kNone;         // this solve's focal mode
  double focal_scale_[1] = {1.0};              // the focal test's parameter (FocalTest::kFree)
  std::vector<std::uint8_t> point_observed_;  // per job point: in the problem (a count while building)
  std::vector<std::uint8_t> held_;            // per job keyframe: pose held constant (fixed or gauge), not a block
  std::vector<std::int32_t> newest_frames_;   // per job point: max_observations_per_point newest frames, descending
  std::vector<std::int32_t> newest_fixed_frames_;  // the same over fixed keyframes, max_fixed_observations_per_point
  // The held solution while the freed one is tested (kPoseParams per keyframe, 3 per point).
  std::vector<double> saved_poses_;
  std::vector<double> saved_points_;
  std::vector<ShapePlane> planes_;            // per job point: tangent plane at the start value
  // Per map point slot (BaPoint::id < max_points): the plane, where it was
  // taken and the point's stamp; sized in configure().
  struct CachedPlane {
    bool valid = false;
    std::int32_t created_frame = -1;
    Vec3 at = Vec3::Zero();
    ShapePlane plane;
  };
  std::vector<CachedPlane> plane_cache_;
  bool plane_for(const BaPoint& p, ShapePlane* plane, int* queries);
  int max_keyframes_ = 0, max_points_ = 0, max_observations_ = 0;
  bool configured_ = false;
};

}  // namespace st
