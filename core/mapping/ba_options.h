// The window bundle adjuster's options (core/mapping/bundle_adjustment.h),
// apart from the solver so that the tracker's settings can hold them
// without its headers.
#pragma once

#include <cstdint>

namespace st {

struct BundleAdjusterOptions {
  // The clock behind max_time_s and BaSummary::solver_ms for the Schur
  // solver (core/ has none: the caller injects it); nullptr: iterations
  // alone bound a solve. Ceres uses its own clock. Not a settings key.
  std::int64_t (*now_ns)() = nullptr;
  double w_shape = 100.0;           // paper: 100; 0 drops the shape residual (ablation)
  double shape_huber_mm = 1.0;      // Huber threshold of the point-to-mesh distance
  bool exact_shape = false;         // true: D(f) re-queried at every evaluation; false: tangent
                                    // plane at the start value (core/mapping/ba_residuals.h)
  double reprojection_huber = 2.447651936;  // on whitened pixels: sqrt(chi2 95%, 2 DoF)
  int max_iterations = 10;
  double relative_gradient_tolerance = 1e-4;  // stop once max|gradient| fell below this fraction of
                                              // its start value (0: Ceres' own tests only)
  double max_time_s = 0.05;         // the solver stops after this much time (see now_ns)
  double min_depth_mm = 1.0;        // observations at a smaller depth are left out
  double max_point_shift_mm = 10.0; // a point moved farther is marked rejected (the
                                    // tracker keeps its old position)
  int max_observations_per_point = 0;  // 0: all; else only the newest (keyframe frame)
                                       // this many per point, <= kMaxObservationsPerPointCap:
                                       // bounds the Schur work per point (quadratic in it)
  int min_observations_per_point = 2;  // points with fewer usable observations are left out
                                       // (unchanged): one view carries no pose information
  int max_fixed_observations_per_point = 0;  // 0: all; else only the newest this many
                                             // observations from fixed keyframes per point
                                             // (<= kMaxObservationsPerPointCap): a tracker window
                                             // pulls in every older keyframe seeing its points
  double plane_reuse_mm = 0.2;  // a point's tangent plane from an earlier solve is reused while the
                                // point (same map slot and stamp) stays within this distance of where
                                // the plane was taken (curvature error <= d^2 / 2R: ~4 um at R = 5 mm);
                                // 0: one closest-point query per point and solve
  // A job's pose prior (BaJob::prior, the tracker's registration of frame
  // 0) is tested, not simply applied: the job is solved with the prior's
  // keyframe held (the registration as given), then again from there with
  // it free under the prior. The free solution is kept only if it fits the
  // data significantly better: F = ((C_held - C_free) / 6) / (C_free / dof)
  // above this (C: final cost, dof: residuals - parameters). Under a right
  // registration and Gaussian noise F follows F(6, dof): P(F > 6.3) ~ 1e-6
  // for the thousands of residuals of a window. Why: freed, the first pose
  // also drifts with the noise along the directions the organ's shape
  // barely fixes (a smooth patch), which costs accuracy when the
  // registration was right; a coarse registration stands out by far
  // (tests: F ~ 300 at 1 deg / 4 mm, ~ 1.7 when exact). 0: always free.
  double prior_release_f = 6.3;
  // A job asking for it (BaJob::test_focal) is solved twice more from its
  // solution, every keyframe free (the mesh fixing the gauge), with the
  // focal lengths held and with one more parameter, a common scale s of
  // them (principal point kept), and the solution restored after: the
  // summary then tells how much better the data fits another focal length
  // (BaSummary::focal_scale, focal_f; only with the shape residual on, which
  // ties the structure to the metric mesh: without it a focal change is
  // absorbed by depth). Costs two more solves.
  int surface_distance_samples = 128;  // summary.mean_surface_distance_mm over at most this
                                       // many evenly spaced points (0: all); one exact
                                       // closest-point query each (~1.6 us)
};

inline constexpr int kMaxObservationsPerPointCap = 16;

}  // namespace st
